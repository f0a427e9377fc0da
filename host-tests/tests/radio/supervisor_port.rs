//! The supervisor port 9: requests built the way cflib 0.1.34 `cflib/crazyflie/supervisor.py` builds them
//! (`pk.data = [CMD_GET_STATE_BITFIELD]`, `(CMD_ARM_SYSTEM, do_arm)`, `(CMD_RECOVER_SYSTEM,)`, …), replies
//! checked against the stock layouts of docs/hardware.md §4 (`crtp_supervisor.c`: reply command =
//! `0x80 | cmd`, bitfield u16 little-endian, arm reply `[success, isArmed]`, recover reply
//! `[success, recovered]`) and the emergency-stop watchdog rule of §10.1 (1000 ms after the first keepalive).

use cfnav::flight::supervisor::{Reason, SupervisorFlags, SupervisorOutput, SupervisorState};
use cfnav::radio::crtp::{CrtpPacket, PlatformService, Router, Service};
use cfnav::radio_binding::supervisor_port::{
    ESTOP_WATCHDOG_US, SupervisorPortConfig, SupervisorPortService, SupervisorRequests, SupervisorStatus,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

// cflib 0.1.34 supervisor.py constants, written out as the protocol's definition.
const CH_INFO: u8 = 0;
const CH_COMMAND: u8 = 1;
const BIT_CAN_BE_ARMED: u32 = 0;
const BIT_IS_ARMED: u32 = 1;
const BIT_IS_AUTO_ARMED: u32 = 2;
const BIT_CAN_FLY: u32 = 3;
const BIT_IS_FLYING: u32 = 4;
const BIT_IS_TUMBLED: u32 = 5;
const BIT_IS_LOCKED: u32 = 6;
const BIT_IS_CRASHED: u32 = 7;
const BIT_HL_CONTROL_ACTIVE: u32 = 8;
const BIT_HL_TRAJ_FINISHED: u32 = 9;
const BIT_HL_CONTROL_DISABLED: u32 = 10;
const BIT_DECK_FAULT: u32 = 11; // firmware only (docs/hardware.md §4); cflib 0.1.34 has no name for it
const CMD_GET_STATE_BITFIELD: u8 = 0x0C;
const CMD_ARM_SYSTEM: u8 = 0x01;
const CMD_RECOVER_SYSTEM: u8 = 0x02;
const CMD_EMERGENCY_STOP: u8 = 0x03;
const CMD_EMERGENCY_STOP_WATCHDOG: u8 = 0x04;

fn pk(channel: u8, data: &[u8]) -> CrtpPacket {
    CrtpPacket::new(9, channel, data).unwrap()
}

/// What cflib's `_supervisor_callback` makes of a bitfield reply: `int.from_bytes(pk.data[1:], 'little')`.
fn cflib_bitfield(reply: &CrtpPacket) -> u32 {
    assert_eq!(reply.port, 9);
    assert_eq!(reply.channel, CH_INFO);
    assert_eq!(
        reply.data[0],
        0x80 | CMD_GET_STATE_BITFIELD,
        "reply command has bit 7 set"
    );
    assert_eq!(reply.data.len(), 3, "stock sends the u16 bitfield: 1 + 2 bytes");
    reply.data[1..]
        .iter()
        .rev()
        .fold(0u32, |acc, &b| (acc << 8) | u32::from(b))
}

/// The data of the reply to a command-channel packet carrying `data` (which must get one).
fn command(s: &mut SupervisorPortService, data: &[u8]) -> Vec<u8> {
    s.handle(&pk(CH_COMMAND, data)).expect("a reply").data.to_vec()
}

fn bit(field: u32, n: u32) -> bool {
    field >> n & 1 == 1
}

fn status(state: SupervisorState, reason: Reason) -> SupervisorStatus {
    SupervisorStatus {
        output: SupervisorOutput {
            state,
            motors_allowed: matches!(state, SupervisorState::Armed | SupervisorState::Flying),
            flying: state == SupervisorState::Flying,
            reason,
            ..Default::default()
        },
        mission_running: false,
        mission_finished: false,
        decks_ok: true,
    }
}

fn bitfield_of(s: &mut SupervisorPortService) -> u32 {
    let reply = s
        .handle(&pk(CH_INFO, &[CMD_GET_STATE_BITFIELD]))
        .expect("a bitfield reply");
    cflib_bitfield(&reply)
}

#[test]
fn bitfield_reply_layout_and_mapping() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig::default());
    // Flying under auto-arming, no mission.
    s.set_status(status(SupervisorState::Flying, Reason::None));
    let f = bitfield_of(&mut s);
    assert!(bit(f, BIT_IS_ARMED) && bit(f, BIT_IS_AUTO_ARMED) && bit(f, BIT_CAN_FLY) && bit(f, BIT_IS_FLYING));
    assert!(!bit(f, BIT_CAN_BE_ARMED) && !bit(f, BIT_IS_TUMBLED) && !bit(f, BIT_IS_LOCKED) && !bit(f, BIT_IS_CRASHED));
    assert!(bit(f, BIT_HL_CONTROL_DISABLED) && !bit(f, BIT_HL_CONTROL_ACTIVE) && !bit(f, BIT_DECK_FAULT));

    // Crashed after a tumble, mission running, deck fault.
    let mut st = status(SupervisorState::Crashed, Reason::Tumbled);
    st.output.flags = SupervisorFlags::from_bits(SupervisorFlags::TUMBLED);
    st.mission_running = true;
    st.decks_ok = false;
    s.set_status(st);
    let f = bitfield_of(&mut s);
    assert!(bit(f, BIT_IS_CRASHED) && bit(f, BIT_IS_TUMBLED) && !bit(f, BIT_CAN_FLY) && !bit(f, BIT_IS_FLYING));
    assert!(bit(f, BIT_HL_CONTROL_ACTIVE) && !bit(f, BIT_HL_CONTROL_DISABLED) && bit(f, BIT_DECK_FAULT));

    // Locked by the setpoint watchdog, mission finished.
    let mut st = status(SupervisorState::Locked, Reason::SetpointTimeout);
    st.mission_finished = true;
    s.set_status(st);
    let f = bitfield_of(&mut s);
    assert!(bit(f, BIT_IS_LOCKED) && bit(f, BIT_HL_TRAJ_FINISHED) && !bit(f, BIT_IS_CRASHED));
    assert!(f < 1 << 12, "only bits 0..11 are defined");
}

#[test]
fn single_bit_info_commands_answer_bit_n_minus_one() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig::default());
    s.set_status(status(SupervisorState::Flying, Reason::None));
    let field = bitfield_of(&mut s);
    for cmd in 1..=0x0Bu8 {
        let reply = s.handle(&pk(CH_INFO, &[cmd])).expect("a reply");
        assert_eq!(
            reply.data.as_slice(),
            &[0x80 | cmd, bit(field, u32::from(cmd) - 1) as u8],
            "cmd {cmd}"
        );
    }
    for cmd in [0u8, 0x0D, 0x7F, 0x8C, 0xFF] {
        assert_eq!(s.handle(&pk(CH_INFO, &[cmd])), None, "cmd {cmd:#x}");
    }
    assert_eq!(s.handle(&pk(CH_INFO, &[])), None);
}

#[test]
fn arming_under_auto_arm() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig::default());
    s.set_status(status(SupervisorState::Armed, Reason::None));
    // cflib send_arming_request(True): data = (CMD_ARM_SYSTEM, True) → [1, 1].
    let r = s.handle(&pk(CH_COMMAND, &[CMD_ARM_SYSTEM, 1])).unwrap();
    assert_eq!((r.channel, r.data.as_slice()), (CH_COMMAND, &[0x81, 1, 1][..]));
    // Disarming cannot be honoured with auto-arming: refused, still armed.
    let r = s.handle(&pk(CH_COMMAND, &[CMD_ARM_SYSTEM, 0])).unwrap();
    assert_eq!(r.data.as_slice(), &[0x81, 0, 1]);
    assert_eq!(
        s.take_requests(),
        SupervisorRequests::default(),
        "nothing for the caller to do"
    );
}

#[test]
fn arming_without_auto_arm_follows_can_be_armed() {
    let cfg = SupervisorPortConfig {
        auto_arm: false,
        can_recover: false,
    };
    let mut s = SupervisorPortService::new(cfg);
    s.set_status(status(SupervisorState::Idle, Reason::NotUpright));
    assert!(!bit(bitfield_of(&mut s), BIT_CAN_BE_ARMED));
    assert_eq!(command(&mut s, &[CMD_ARM_SYSTEM, 1]), &[0x81, 0, 0]);
    assert_eq!(s.take_requests().arm, None);

    s.set_status(status(SupervisorState::Idle, Reason::NotArmed));
    assert!(bit(bitfield_of(&mut s), BIT_CAN_BE_ARMED));
    assert_eq!(command(&mut s, &[CMD_ARM_SYSTEM, 1]), &[0x81, 1, 1]);
    assert_eq!(s.take_requests().arm, Some(true));
    assert!(s.arm_level());
    // Arming again: already armed → success (stock `doArm == isArmingActivated`).
    assert_eq!(command(&mut s, &[CMD_ARM_SYSTEM, 7]), &[0x81, 1, 1]);
    assert_eq!(command(&mut s, &[CMD_ARM_SYSTEM, 0]), &[0x81, 1, 0]);
    assert_eq!(s.take_requests().arm, Some(false));
}

#[test]
fn recovery_answers() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig {
        auto_arm: true,
        can_recover: true,
    });
    s.set_status(status(SupervisorState::Idle, Reason::None));
    // cflib send_crash_recovery_request(): data = (CMD_RECOVER_SYSTEM,).
    assert_eq!(command(&mut s, &[CMD_RECOVER_SYSTEM]), &[0x82, 1, 1]);
    assert!(!s.take_requests().recover, "nothing to recover");
    let mut crashed = status(SupervisorState::Crashed, Reason::Tumbled);
    crashed.output.flags = SupervisorFlags::from_bits(SupervisorFlags::TUMBLED);
    s.set_status(crashed);
    assert_eq!(command(&mut s, &[CMD_RECOVER_SYSTEM]), &[0x82, 0, 0]);
    assert!(!s.take_requests().recover, "still tumbled: refused");
    s.set_status(status(SupervisorState::Crashed, Reason::None));
    assert_eq!(command(&mut s, &[CMD_RECOVER_SYSTEM]), &[0x82, 1, 1]);
    assert!(s.take_requests().recover);

    let mut no_reset = SupervisorPortService::new(SupervisorPortConfig::default());
    no_reset.set_status(status(SupervisorState::Crashed, Reason::None));
    assert_eq!(
        command(&mut no_reset, &[CMD_RECOVER_SYSTEM]),
        &[0x82, 0, 0],
        "a caller that cannot reset the supervisor must not claim success"
    );
}

#[test]
fn emergency_stop_latches_and_blocks_arming() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig::default());
    s.set_status(status(SupervisorState::Flying, Reason::None));
    // cflib send_emergency_stop(): (CMD_EMERGENCY_STOP,) → no reply.
    assert_eq!(s.handle(&pk(CH_COMMAND, &[CMD_EMERGENCY_STOP])), None);
    assert!(s.take_requests().emergency_stop);
    assert!(!s.take_requests().emergency_stop, "requested once");
    let f = bitfield_of(&mut s);
    assert!(bit(f, BIT_IS_LOCKED) && !bit(f, BIT_CAN_FLY) && !bit(f, BIT_IS_ARMED));
    assert_eq!(command(&mut s, &[CMD_ARM_SYSTEM, 1]), &[0x81, 0, 0]);
    s.clear_emergency_stop();
    assert!(!bit(bitfield_of(&mut s), BIT_IS_LOCKED));
}

#[test]
fn emergency_stop_watchdog_fires_1000_ms_after_the_last_keepalive() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig::default());
    // Never started: never fires.
    assert!(!s.poll(0));
    assert!(!s.poll(60_000_000));
    s.set_now(60_000_000);
    assert_eq!(
        s.handle(&pk(CH_COMMAND, &[CMD_EMERGENCY_STOP_WATCHDOG])),
        None,
        "keepalive has no reply"
    );
    assert!(s.watchdog_started());
    let t0 = 60_000_000;
    assert!(!s.poll(t0 + ESTOP_WATCHDOG_US), "exactly 1000 ms: not yet");
    s.set_now(t0 + 900_000);
    s.handle(&pk(CH_COMMAND, &[CMD_EMERGENCY_STOP_WATCHDOG]));
    assert!(!s.poll(t0 + 1_800_000), "the keepalive at 900 ms renewed it");
    assert!(!s.emergency_stopped());
    assert!(s.poll(t0 + 1_900_001), "1000 ms + 1 µs after the last keepalive");
    assert!(s.emergency_stopped());
    assert!(s.take_requests().emergency_stop);
    assert!(!s.poll(t0 + 5_000_000), "fires once");
    assert_eq!(ESTOP_WATCHDOG_US, 1_000_000);
}

#[test]
fn malformed_packets_get_no_reply_and_change_nothing() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig {
        auto_arm: false,
        can_recover: true,
    });
    s.set_status(status(SupervisorState::Idle, Reason::NotArmed));
    let field = bitfield_of(&mut s);
    // Arm without its doArm byte (stock would read past the payload).
    assert_eq!(s.handle(&pk(CH_COMMAND, &[CMD_ARM_SYSTEM])), None);
    assert_eq!(s.handle(&pk(CH_COMMAND, &[])), None);
    assert_eq!(s.handle(&pk(CH_COMMAND, &[0x05])), None);
    assert_eq!(s.handle(&pk(CH_COMMAND, &[0x00, 1])), None);
    assert_eq!(s.handle(&pk(2, &[CMD_GET_STATE_BITFIELD])), None);
    assert_eq!(s.handle(&pk(3, &[CMD_EMERGENCY_STOP])), None);
    assert_eq!(s.stats().refused, 6);
    assert_eq!(bitfield_of(&mut s), field);
    assert_eq!(s.take_requests(), SupervisorRequests::default());
    assert!(!s.emergency_stopped());
}

#[test]
fn router_carries_the_reply() {
    let mut s = SupervisorPortService::new(SupervisorPortConfig::default());
    s.set_status(status(SupervisorState::Armed, Reason::None));
    let mut router: Router<4> = Router::new(PlatformService::new("t"));
    // cflib header: port 9 << 4 | 0x0C | channel 0.
    let reply = router
        .handle_uplink(&[0x9C, CMD_GET_STATE_BITFIELD], &mut [&mut s as &mut dyn Service])
        .expect("reply");
    let f = cflib_bitfield(&reply);
    assert!(bit(f, BIT_CAN_FLY) && bit(f, BIT_IS_ARMED) && !bit(f, BIT_IS_FLYING));
}

#[test]
fn random_packets_never_panic() {
    let mut rng = SmallRng::seed_from_u64(0x5EED_0909);
    let mut s = SupervisorPortService::new(SupervisorPortConfig {
        auto_arm: false,
        can_recover: true,
    });
    let states = [
        SupervisorState::Idle,
        SupervisorState::Armed,
        SupervisorState::Flying,
        SupervisorState::Landed,
        SupervisorState::Crashed,
        SupervisorState::Locked,
    ];
    let mut estops = 0;
    for i in 0..100_000u64 {
        let st = states[rng.random_range(0..states.len())];
        s.set_status(status(
            st,
            if rng.random_bool(0.5) {
                Reason::NotArmed
            } else {
                Reason::None
            },
        ));
        s.set_now(i * 100);
        let len = rng.random_range(0..=30usize);
        let mut data: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        if !data.is_empty() && rng.random_bool(0.7) {
            data[0] = rng.random_range(0..=0x0C);
        }
        let channel = rng.random_range(0..4u8);
        let reply = s.handle(&pk(channel, &data));
        if let Some(r) = reply {
            assert_eq!(r.port, 9);
            assert_eq!(r.channel, channel);
            assert!(channel <= 1);
            assert_eq!(r.data[0], 0x80 | data[0], "the reply echoes the command with bit 7");
            assert!(r.data.len() <= 3);
        }
        if s.take_requests().emergency_stop {
            estops += 1;
            assert!(s.emergency_stopped());
            s.clear_emergency_stop();
        }
        s.poll(i * 100);
    }
    assert!(estops > 0);
}
