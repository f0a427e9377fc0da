//! The commander ports (3 RPYT, 7 generic setpoints and meta commands): packets are built here byte by byte
//! the way cflib 0.1.34 `cflib/crazyflie/commander.py` packs them (struct layouts written out below), decoded
//! by the service, and checked against the firmware rules of docs/hardware.md §4 (signs, thrust
//! limits, thrust lock) and `crtp_commander_generic.c` (types, packed sizes, legacy yaw negation).

use cfnav::radio::commander::{
    Command, CommanderError, CommanderService, MetaCommand, SetpointFollower, THRUST_RELOCK_US,
};
use cfnav::radio::crtp::{CrtpPacket, PlatformService, Router, Service};
use cfnav::types::{Setpoint, StateEstimate};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Little-endian packer standing in for Python's `struct.pack('<…')`.
#[derive(Default)]
struct Pack(Vec<u8>);

impl Pack {
    fn b(mut self, v: u8) -> Self {
        self.0.push(v);
        self
    }
    fn bytes(mut self, v: &[u8]) -> Self {
        self.0.extend_from_slice(v);
        self
    }
    fn f(self, v: f32) -> Self {
        self.bytes(&v.to_le_bytes())
    }
    fn h(self, v: u16) -> Self {
        self.bytes(&v.to_le_bytes())
    }
    fn i16(self, v: i16) -> Self {
        self.bytes(&v.to_le_bytes())
    }
    fn i(self, v: u32) -> Self {
        self.bytes(&v.to_le_bytes())
    }
}

/// cflib `send_setpoint(roll, pitch, yawrate, thrust)`: port 3 ch 0, `<fffH` of (roll, −pitch, yawrate, thrust).
fn cflib_send_setpoint(roll: f32, pitch: f32, yawrate: f32, thrust: u16) -> CrtpPacket {
    let data = Pack::default().f(roll).f(-pitch).f(yawrate).h(thrust).0;
    assert_eq!(data.len(), 14, "cflib's RPYT packet is 14 bytes");
    CrtpPacket::new(3, 0, &data).unwrap()
}

/// cflib's `<Bffff` generic setpoints (port 7 ch 0).
fn cflib_four(kind: u8, a: f32, b: f32, c: f32, d: f32) -> CrtpPacket {
    let data = Pack::default().b(kind).f(a).f(b).f(c).f(d).0;
    assert_eq!(data.len(), 17);
    CrtpPacket::new(7, 0, &data).unwrap()
}

/// cflib `send_setpoint_manual`: `<BfffHB` of (11, roll, −pitch, yawrate, thrust_16, rate).
fn cflib_manual(roll: f32, pitch: f32, yawrate: f32, thrust_percentage: f32, rate: bool) -> (CrtpPacket, u16) {
    let thrust = (10001.0 + 0.01 * thrust_percentage * (60000.0 - 10001.0)) as u16;
    let data = Pack::default()
        .b(11)
        .f(roll)
        .f(-pitch)
        .f(yawrate)
        .h(thrust)
        .b(rate as u8)
        .0;
    assert_eq!(data.len(), 16);
    (CrtpPacket::new(7, 0, &data).unwrap(), thrust)
}

fn deg(v: f32) -> f32 {
    v.to_radians()
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-5 * (1.0 + b.abs())
}

fn attitude(c: Command) -> (f32, f32, f32, u16, bool) {
    match c {
        Command::Attitude {
            roll_rad,
            pitch_rad,
            yaw_rate_rad_s,
            thrust,
            rate_mode,
        } => (roll_rad, pitch_rad, yaw_rate_rad_s, thrust, rate_mode),
        other => panic!("expected an attitude command, got {other:?}"),
    }
}

fn latest(s: &CommanderService) -> Command {
    s.latest().expect("a command").0
}

// ---------------------------------------------------------------------------------------------------------
// Port 3: RPYT
// ---------------------------------------------------------------------------------------------------------

#[test]
fn rpyt_signs_follow_cflib_and_the_firmware() {
    let s = CommanderService::new();
    s.set_now(1_000);
    s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, 0)).unwrap(); // unlock
    s.set_now(11_000);
    s.handle_packet(&cflib_send_setpoint(10.0, 5.0, 20.0, 30000)).unwrap();
    let (roll, pitch, yaw_rate, thrust, rate) = attitude(latest(&s));
    // Roll as sent; the pitch cflib negated comes back as the user's pitch (cfnav: positive = nose down, the
    // direction cfclient's forward stick means); the firmware negates the legacy yaw rate.
    assert!(close(roll, deg(10.0)), "{roll}");
    assert!(close(pitch, deg(5.0)), "{pitch}");
    assert!(close(yaw_rate, -deg(20.0)), "{yaw_rate}");
    assert_eq!(thrust, 30000);
    assert!(!rate);
    assert_eq!(
        s.latest().unwrap().1,
        11_000,
        "the arrival time is the time set before the packet"
    );
}

#[test]
fn rpyt_thrust_lock_until_a_zero_thrust_packet() {
    let s = CommanderService::new();
    assert!(s.thrust_locked(), "locked at boot");
    let mut t = 0;
    let mut send = |thrust: u16| {
        t += 10_000;
        s.set_now(t);
        s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, thrust)).unwrap();
        attitude(latest(&s)).3
    };
    assert_eq!(send(40000), 0, "locked: thrust forced to 0");
    assert_eq!(send(20000), 0);
    assert_eq!(send(0), 0, "the unlock packet itself");
    assert_eq!(send(40000), 40000, "unlocked");
    assert!(!s.thrust_locked());
    assert_eq!(s.stats().thrust_locked, 2, "two packets had their thrust forced to 0");
}

#[test]
fn rpyt_thrust_limits() {
    let s = CommanderService::new();
    let cases = [
        (0u16, 0u16),
        (1, 0),
        (999, 0),
        (1000, 1000),
        (1001, 1001),
        (59999, 59999),
        (60000, 60000),
        (60001, 60000),
        (65535, 60000),
    ];
    s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, 0)).unwrap();
    for (i, (raw, expected)) in cases.into_iter().enumerate() {
        s.set_now(1_000 * (i as u64 + 1));
        s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, raw)).unwrap();
        assert_eq!(attitude(latest(&s)).3, expected, "raw thrust {raw}");
    }
}

#[test]
fn rpyt_thrust_relocks_after_the_stabilize_timeout() {
    let s = CommanderService::new();
    s.set_now(0);
    s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, 0)).unwrap();
    // Within 500 ms: still unlocked.
    s.set_now(THRUST_RELOCK_US);
    s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, 30000)).unwrap();
    assert_eq!(attitude(latest(&s)).3, 30000);
    // More than 500 ms of silence (stock: priority falls to "disabled"): locked again.
    s.set_now(2 * THRUST_RELOCK_US + 1);
    s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, 30000)).unwrap();
    assert_eq!(attitude(latest(&s)).3, 0);
    assert!(s.thrust_locked());
    assert_eq!(s.age_us(2 * THRUST_RELOCK_US + 1 + 700), Some(700));
}

#[test]
fn rpyt_wrong_sizes_and_channels_are_refused_without_state_change() {
    let s = CommanderService::new();
    s.handle_packet(&cflib_send_setpoint(0.0, 0.0, 0.0, 0)).unwrap();
    s.handle_packet(&cflib_send_setpoint(1.0, 2.0, 3.0, 20000)).unwrap();
    let before = s.latest();
    let full = cflib_send_setpoint(9.0, 9.0, 9.0, 50000);
    for n in [0usize, 1, 13] {
        let p = CrtpPacket::new(3, 0, &full.data[..n]).unwrap();
        assert!(s.handle_packet(&p).is_err(), "{n} bytes");
    }
    let mut long = full.data.to_vec();
    long.push(0);
    assert_eq!(
        s.handle_packet(&CrtpPacket::new(3, 0, &long).unwrap()),
        Err(CommanderError::WrongLength {
            kind: 0xFF,
            expected: 14,
            got: 15
        })
    );
    assert_eq!(
        s.handle_packet(&CrtpPacket::new(3, 1, &full.data).unwrap()),
        Err(CommanderError::UnknownChannel(1))
    );
    let nan = Pack::default().f(f32::NAN).f(0.0).f(0.0).h(30000).0;
    assert_eq!(
        s.handle_packet(&CrtpPacket::new(3, 0, &nan).unwrap()),
        Err(CommanderError::NonFinite)
    );
    assert_eq!(s.latest(), before, "refused packets leave the latest command alone");
    assert!(!s.thrust_locked());
    assert_eq!(s.stats().refused, 6);
}

// ---------------------------------------------------------------------------------------------------------
// Port 7: generic setpoints and meta commands
// ---------------------------------------------------------------------------------------------------------

#[test]
fn generic_types_decode_as_cflib_packs_them() {
    let s = CommanderService::new();
    // send_stop_setpoint: '<B', 0.
    s.handle_packet(&CrtpPacket::new(7, 0, &[0]).unwrap()).unwrap();
    assert_eq!(latest(&s), Command::Stop);

    // send_velocity_world_setpoint (protocol ≥ 9): type 8, (vx, vy, vz, yawrate).
    s.handle_packet(&cflib_four(8, 0.5, -0.25, 0.1, 30.0)).unwrap();
    assert_eq!(
        latest(&s),
        Command::VelocityWorld {
            velocity_m_s: [0.5, -0.25, 0.1],
            yaw_rate_rad_s: deg(30.0)
        }
    );
    // Legacy (protocol ≤ 8): type 1 with −yawrate; the firmware negates it back.
    s.handle_packet(&cflib_four(1, 0.5, -0.25, 0.1, -30.0)).unwrap();
    assert_eq!(
        latest(&s),
        Command::VelocityWorld {
            velocity_m_s: [0.5, -0.25, 0.1],
            yaw_rate_rad_s: deg(30.0)
        }
    );

    // send_zdistance_setpoint: type 9 (roll, pitch, yawrate, z); pitch is sent unnegated, so the firmware's
    // legacy pitch sign shows as a negated cfnav pitch.
    // The legacy type 2 carries the same with the yaw rate negated: both decode to one command.
    for (kind, yaw_rate_deg) in [(9, 10.0), (2, -10.0)] {
        s.handle_packet(&cflib_four(kind, 2.0, 3.0, yaw_rate_deg, 0.4)).unwrap();
        assert_eq!(
            latest(&s),
            Command::ZDistance {
                roll_rad: deg(2.0),
                pitch_rad: -deg(3.0),
                yaw_rate_rad_s: deg(10.0),
                z_m: 0.4
            },
            "type {kind}"
        );
    }

    // send_hover_setpoint: type 10 (vx, vy body, yawrate, z); legacy type 5 with −yawrate.
    let hover = Command::Hover {
        vx_body_m_s: 0.3,
        vy_body_m_s: 0.1,
        yaw_rate_rad_s: deg(-15.0),
        z_m: 0.5,
    };
    s.handle_packet(&cflib_four(10, 0.3, 0.1, -15.0, 0.5)).unwrap();
    assert_eq!(latest(&s), hover);
    s.handle_packet(&cflib_four(5, 0.3, 0.1, 15.0, 0.5)).unwrap();
    assert_eq!(latest(&s), hover);

    // send_position_setpoint: type 7 (x, y, z, yaw deg).
    s.handle_packet(&cflib_four(7, 1.5, 2.0, 0.6, 90.0)).unwrap();
    assert_eq!(
        latest(&s),
        Command::Position {
            position_m: [1.5, 2.0, 0.6],
            yaw_rad: deg(90.0)
        }
    );

    // send_setpoint_manual: '<BfffHB' (11, roll, −pitch, yawrate, thrust_16, rate).
    let (p, thrust) = cflib_manual(4.0, 6.0, 12.0, 50.0, true);
    s.handle_packet(&p).unwrap();
    let (roll, pitch, yaw_rate, t, rate) = attitude(latest(&s));
    assert!(close(roll, deg(4.0)) && close(pitch, deg(6.0)) && close(yaw_rate, deg(12.0)));
    assert_eq!((t, rate), (thrust, true));
    assert_eq!(thrust, 35000, "10001 + 0.5 × 49999, truncated");
    let (p, _) = cflib_manual(4.0, 6.0, 12.0, 0.0, false);
    s.handle_packet(&p).unwrap();
    assert_eq!(attitude(latest(&s)).3, 10001);
    assert!(!attitude(latest(&s)).4);
    assert_eq!(s.stats().accepted, 10);
}

#[test]
fn full_state_is_refused_after_its_length_check() {
    let s = CommanderService::new();
    // cflib send_full_state_setpoint: '<BhhhhhhhhhIhhh' = 1 + 9×2 + 4 + 3×2 = 29 bytes.
    let mut pk = Pack::default().b(6);
    for v in [1000i16, 2000, 500, 0, 0, 0, 0, 0, 0] {
        pk = pk.i16(v);
    }
    let data = pk.i(0).i16(0).i16(0).i16(0).0;
    assert_eq!(data.len(), 29);
    let p = CrtpPacket::new(7, 0, &data).unwrap();
    assert_eq!(s.handle_packet(&p), Err(CommanderError::Unsupported(6)));
    let short = CrtpPacket::new(7, 0, &data[..28]).unwrap();
    assert_eq!(
        s.handle_packet(&short),
        Err(CommanderError::WrongLength {
            kind: 6,
            expected: 28,
            got: 27
        })
    );
    assert_eq!(s.latest(), None);
}

#[test]
fn generic_truncated_oversized_unknown_and_nan_are_refused() {
    let s = CommanderService::new();
    s.handle_packet(&cflib_four(7, 1.0, 1.0, 0.5, 0.0)).unwrap();
    let before = s.latest();
    // Payload sizes after the type byte (packed structs of crtp_commander_generic.c).
    let sizes = [
        (1u8, 16usize),
        (2, 16),
        (5, 16),
        (7, 16),
        (8, 16),
        (9, 16),
        (10, 16),
        (11, 15),
        (6, 28),
    ];
    for (kind, size) in sizes {
        for n in [0, size - 1, size + 1] {
            let mut data = vec![kind];
            data.extend(std::iter::repeat_n(0u8, n));
            let r = s.handle_packet(&CrtpPacket::new(7, 0, &data).unwrap());
            assert_eq!(
                r,
                Err(CommanderError::WrongLength {
                    kind,
                    expected: size,
                    got: n
                }),
                "type {kind} with {n} bytes"
            );
        }
    }
    for kind in 12..=255u8 {
        let mut data = vec![kind];
        data.extend([0u8; 16]);
        assert_eq!(
            s.handle_packet(&CrtpPacket::new(7, 0, &data).unwrap()),
            Err(CommanderError::UnknownType(kind))
        );
    }
    for kind in [3u8, 4] {
        assert_eq!(
            s.handle_packet(&CrtpPacket::new(7, 0, &[kind, 0, 0, 0, 0]).unwrap()),
            Err(CommanderError::Unsupported(kind))
        );
    }
    assert_eq!(
        s.handle_packet(&CrtpPacket::new(7, 0, &[]).unwrap()),
        Err(CommanderError::Empty)
    );
    assert_eq!(
        s.handle_packet(&cflib_four(7, f32::INFINITY, 0.0, 0.5, 0.0)),
        Err(CommanderError::NonFinite)
    );
    assert_eq!(
        s.handle_packet(&cflib_four(8, 0.0, 0.0, f32::NAN, 0.0)),
        Err(CommanderError::NonFinite)
    );
    for ch in [2u8, 3] {
        assert_eq!(
            s.handle_packet(&CrtpPacket::new(7, ch, &[0]).unwrap()),
            Err(CommanderError::UnknownChannel(ch))
        );
    }
    assert_eq!(s.latest(), before);
    assert_eq!(
        s.take_fresh(),
        before,
        "the one accepted command is still the fresh one"
    );
}

#[test]
fn stop_accepts_trailing_bytes_like_the_stock_decoder() {
    let s = CommanderService::new();
    s.handle_packet(&CrtpPacket::new(7, 0, &[0, 1, 2, 3]).unwrap()).unwrap();
    assert_eq!(latest(&s), Command::Stop);
}

#[test]
fn meta_notify_setpoint_stop() {
    let s = CommanderService::new();
    s.set_now(5_000);
    // cflib send_notify_setpoint_stop(250): port 7 ch 1, '<BI' (0, 250).
    let data = Pack::default().b(0).i(250).0;
    s.handle_packet(&CrtpPacket::new(7, 1, &data).unwrap()).unwrap();
    assert_eq!(
        s.take_meta(),
        Some((MetaCommand::NotifySetpointStop { remain_valid_ms: 250 }, 5_000))
    );
    assert_eq!(s.take_meta(), None, "taken once");
    assert_eq!(s.latest(), None, "a meta command is not a setpoint");
    assert!(s.handle_packet(&CrtpPacket::new(7, 1, &data[..4]).unwrap()).is_err());
    assert_eq!(
        s.handle_packet(&CrtpPacket::new(7, 1, &[1, 0, 0, 0, 0]).unwrap()),
        Err(CommanderError::UnknownMeta(1))
    );
}

#[test]
fn router_dispatches_both_ports_without_replies() {
    let s = CommanderService::new();
    let mut router: Router<4> = Router::new(PlatformService::new("t"));
    let [mut rpyt, mut generic] = s.ports();
    assert_eq!((rpyt.port(), generic.port()), (3, 7));
    let mut wire = [0u8; 32];
    let p = cflib_four(7, 1.0, 2.0, 0.5, 0.0);
    let n = p.to_bytes(&mut wire);
    {
        let mut services: [&mut dyn Service; 2] = [&mut rpyt, &mut generic];
        assert_eq!(
            router.handle_uplink(&wire[..n], &mut services),
            None,
            "setpoints get no reply"
        );
        let p = cflib_send_setpoint(0.0, 0.0, 0.0, 0);
        let n = p.to_bytes(&mut wire);
        assert_eq!(router.handle_uplink(&wire[..n], &mut services), None);
    }
    assert_eq!(router.stats().dispatched, 2);
    assert_eq!(router.stats().unknown_port, 0);
    assert_eq!(s.stats().accepted, 2);
    assert!(!s.thrust_locked());
    assert_eq!(attitude(latest(&s)).3, 0);
}

#[test]
fn take_fresh_reports_each_command_once() {
    let s = CommanderService::new();
    assert_eq!(s.take_fresh(), None);
    s.set_now(7);
    s.handle_packet(&CrtpPacket::new(7, 0, &[0]).unwrap()).unwrap();
    assert_eq!(s.take_fresh(), Some((Command::Stop, 7)));
    assert_eq!(s.take_fresh(), None);
    assert_eq!(s.latest(), Some((Command::Stop, 7)), "latest stays");
}

// ---------------------------------------------------------------------------------------------------------
// Commands → cfnav setpoints
// ---------------------------------------------------------------------------------------------------------

fn estimate(z: f32, yaw: f32) -> StateEstimate {
    StateEstimate {
        position_m: [1.0, 1.0, z],
        attitude_rad: [0.0, 0.0, yaw],
        valid: true,
        ..Default::default()
    }
}

#[test]
fn follower_maps_what_setpoint_can_express() {
    let mut f = SetpointFollower::new();
    let est = estimate(0.5, 0.0);
    assert_eq!(f.to_setpoint(&Command::Stop, 0, &est), Some(Setpoint::Stop));
    let position = Command::Position {
        position_m: [2.0, 1.0, 0.7],
        yaw_rad: deg(90.0),
    };
    match f.to_setpoint(&position, 10, &est) {
        Some(Setpoint::Position {
            x_m: 2.0,
            y_m: 1.0,
            z_m: 0.7,
            yaw_rad,
        }) => assert!(close(yaw_rad, deg(90.0))),
        other => panic!("{other:?}"),
    }
    let att = |thrust| Command::Attitude {
        roll_rad: 0.1,
        pitch_rad: 0.0,
        yaw_rate_rad_s: 0.0,
        thrust,
        rate_mode: false,
    };
    assert_eq!(
        f.to_setpoint(&att(0), 20, &est),
        Some(Setpoint::Stop),
        "RPYT thrust 0 stops the motors"
    );
    assert_eq!(
        f.to_setpoint(&att(30000), 30, &est),
        Some(Setpoint::Attitude {
            roll_rad: 0.1,
            pitch_rad: 0.0,
            yaw_rate_rad_s: 0.0,
            thrust: 30000
        }),
        "RPYT with thrust flies as stock: attitude and thrust"
    );
    let rates = Command::Attitude {
        roll_rad: 0.1,
        pitch_rad: 0.0,
        yaw_rate_rad_s: 0.0,
        thrust: 30000,
        rate_mode: true,
    };
    assert_eq!(
        f.to_setpoint(&rates, 35, &est),
        None,
        "no roll/pitch-rate setpoint in cfnav"
    );
    let tilted = Command::ZDistance {
        roll_rad: 0.1,
        pitch_rad: 0.0,
        yaw_rate_rad_s: 0.0,
        z_m: 0.5,
    };
    assert_eq!(f.to_setpoint(&tilted, 40, &est), None);
    let level = Command::ZDistance {
        roll_rad: 0.0,
        pitch_rad: 0.0,
        yaw_rate_rad_s: 0.0,
        z_m: 0.5,
    };
    assert!(matches!(
        f.to_setpoint(&level, 50, &est),
        Some(Setpoint::Velocity {
            vx_m_s: 0.0,
            vy_m_s: 0.0,
            z_m: 0.5,
            ..
        })
    ));
}

#[test]
fn follower_rotates_hover_velocity_from_body_to_arena() {
    let mut f = SetpointFollower::new();
    // Heading +90°: body x points along arena +y, body y (left) along arena −x.
    let est = estimate(0.5, deg(90.0));
    let cmd = Command::Hover {
        vx_body_m_s: 1.0,
        vy_body_m_s: 0.5,
        yaw_rate_rad_s: 0.0,
        z_m: 0.6,
    };
    match f.to_setpoint(&cmd, 0, &est) {
        Some(Setpoint::Velocity {
            vx_m_s,
            vy_m_s,
            z_m,
            yaw_rad,
        }) => {
            assert!(close(vx_m_s, -0.5) && close(vy_m_s, 1.0), "({vx_m_s}, {vy_m_s})");
            assert_eq!(z_m, 0.6);
            assert!(close(yaw_rad, deg(90.0)));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn follower_integrates_rates_between_packets_with_a_capped_gap() {
    let mut f = SetpointFollower::new();
    let est = estimate(0.5, 0.0);
    let cmd = Command::VelocityWorld {
        velocity_m_s: [0.2, 0.0, 0.5],
        yaw_rate_rad_s: 1.0,
    };
    let z_yaw = |sp: Option<Setpoint>| match sp {
        Some(Setpoint::Velocity {
            z_m, yaw_rad, vx_m_s, ..
        }) => {
            assert_eq!(vx_m_s, 0.2);
            (z_m, yaw_rad)
        }
        other => panic!("{other:?}"),
    };
    assert_eq!(
        z_yaw(f.to_setpoint(&cmd, 1_000_000, &est)),
        (0.5, 0.0),
        "starts from the estimate"
    );
    let (z, yaw) = z_yaw(f.to_setpoint(&cmd, 1_050_000, &est));
    assert!(
        close(z, 0.525) && close(yaw, 0.05),
        "50 ms at 0.5 m/s and 1 rad/s: ({z}, {yaw})"
    );
    // A 3 s gap integrates only the 500 ms cap (stock's stabilize timeout).
    let (z, yaw) = z_yaw(f.to_setpoint(&cmd, 4_050_000, &est));
    assert!(close(z, 0.775) && close(yaw, 0.55), "({z}, {yaw})");
}

// ---------------------------------------------------------------------------------------------------------
// Random bytes
// ---------------------------------------------------------------------------------------------------------

#[test]
fn random_packets_never_panic_and_refusals_change_nothing() {
    let mut rng = SmallRng::seed_from_u64(0xC0FF_EE03);
    let s = CommanderService::new();
    let mut follower = SetpointFollower::new();
    let est = estimate(0.4, 0.3);
    for i in 0..200_000u64 {
        let port = if rng.random_bool(0.5) { 3 } else { 7 };
        let channel = rng.random_range(0..4u8);
        let len = rng.random_range(0..=30usize);
        let mut data: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        if port == 7 && channel == 0 && !data.is_empty() && rng.random_bool(0.5) {
            data[0] = rng.random_range(0..12); // valid types more often
        }
        let p = CrtpPacket::new(port, channel, &data).unwrap();
        s.set_now(i * 1_000);
        let before = (s.latest(), s.thrust_locked());
        match s.handle_packet(&p) {
            Ok(()) => {
                if let Some((cmd, t)) = s.take_fresh()
                    && let Some(setpoint) = follower.to_setpoint(&cmd, t, &est)
                {
                    assert!(setpoint.is_finite(), "{setpoint:?}");
                }
            }
            Err(_) => assert_eq!((s.latest(), s.thrust_locked()), before, "packet {i}: {p:?}"),
        }
    }
    let st = s.stats();
    assert!(st.accepted > 1000 && st.refused > 1000, "{st:?}");
}

/// cflib's `MotionCommander.turn_left(90, rate=60)`: hover setpoints every 200 ms (its `_SetPointThread`
/// period) with yaw rate 60 deg/s for 1.5 s, then rate 0. The held heading must end within one packet
/// interval (12 deg) of 90 deg (with rates integrated over at most 100 ms it ended at 45 deg).
#[test]
fn motion_commander_turn_at_its_200_ms_packet_period_reaches_the_angle() {
    let mut f = SetpointFollower::new();
    let est = estimate(0.5, 0.0);
    let hover = |rate_deg_s: f32| Command::Hover {
        vx_body_m_s: 0.0,
        vy_body_m_s: 0.0,
        yaw_rate_rad_s: rate_deg_s.to_radians(),
        z_m: 0.5,
    };
    let mut yaw = 0.0;
    let mut t_us = 0;
    f.to_setpoint(&hover(0.0), t_us, &est);
    // The turn starts between two packets (cflib sends the new setpoint at once, then every 200 ms).
    t_us += 50_000;
    while t_us <= 50_000 + 1_500_000 {
        if let Some(Setpoint::Velocity { yaw_rad, .. }) = f.to_setpoint(&hover(60.0), t_us, &est) {
            yaw = yaw_rad;
        }
        t_us += 200_000;
    }
    if let Some(Setpoint::Velocity { yaw_rad, .. }) = f.to_setpoint(&hover(0.0), 50_000 + 1_500_000, &est) {
        yaw = yaw_rad;
    }
    let deg = yaw.to_degrees();
    assert!((deg - 90.0).abs() <= 12.0, "turned {deg} deg");
}
