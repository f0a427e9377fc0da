//! Fuzz target: a stream of CRTP datagrams through the router with every service cfnav serves (link,
//! platform, parameters, log, memory, commander ports 3 and 7, supervisor port 9, console), in the one
//! `radio::endpoint::Endpoint` the drone and the simulator use.
//!
//! Input: a sequence of `[len, time_step, bytes…]` records (len taken modulo 33, so over-long uplinks occur
//! too). Checks: no panic; every downlink packet is a valid CRTP packet (port ≤ 15, channel ≤ 3, ≤ 30 bytes);
//! the commander's setpoint mapping stays finite; log ticks and console output stay within their limits.
#![no_main]

use cfnav::mission::MissionParams;
use cfnav::radio::commander::SetpointFollower;
use cfnav::radio::crtp::{CrtpPacket, MAX_DATA};
use cfnav::radio::param::ParamService;
use cfnav::radio_binding::endpoint::Endpoint;
use cfnav::radio_binding::log_table::FlightLogState;
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::supervisor_port::SupervisorPortConfig;
use cfnav::types::StateEstimate;
use libfuzzer_sys::fuzz_target;

fn valid(p: &CrtpPacket) {
    assert!(p.port <= 15 && p.channel <= 3 && p.data.len() <= MAX_DATA, "{p:?}");
}

fuzz_target!(|data: &[u8]| {
    // The same services, ports and order as the drone and the simulator (one list: `Endpoint`).
    let mut ep: Endpoint<MissionParamState, FlightLogState, 8, 8> = Endpoint::new(
        "fuzz",
        MissionParamState::new(MissionParams::SEED, 128 * 64),
        SupervisorPortConfig {
            auto_arm: false,
            can_recover: true,
        },
    );
    let mut follower = SetpointFollower::new();
    let state = FlightLogState::default();
    let estimate = StateEstimate::default();
    let mut now_ms: u32 = 0;
    let mut rest = data;
    while let [len, step, tail @ ..] = rest {
        let n = usize::from(*len % 33).min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        now_ms = now_ms.saturating_add(u32::from(*step));
        let now_us = u64::from(now_ms) * 1000;
        if let Some(p) = ep.handle_uplink(bytes, now_us) {
            valid(&p);
        }
        if let Some((cmd, t)) = ep.commander.take_fresh()
            && let Some(setpoint) = follower.to_setpoint(&cmd, t, &estimate)
        {
            assert!(setpoint.is_finite(), "{setpoint:?}");
        }
        let _ = ep.commander.take_meta();
        let requests = ep.supervisor.take_requests();
        if requests.emergency_stop {
            assert!(ep.supervisor.emergency_stopped());
        }
        ep.supervisor.poll(now_us);
        while let Some(p) = ep.param.next_notification() {
            valid(&p);
        }
        while let Some(note) = ep.param.take_refusal() {
            ep.console
                .print(&ParamService::<MissionParamState>::console_line(&note));
        }
        while let Some(p) = ep.log.tick(now_ms, &state) {
            valid(&p);
        }
        while let Some(p) = ep.console.next_packet() {
            valid(&p);
            assert!(!p.data.is_empty());
        }
    }
});
