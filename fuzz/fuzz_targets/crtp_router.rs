//! Fuzz target: a stream of CRTP datagrams through the router with every service cfnav serves (link,
//! platform, parameters, log, memory, commander ports 3 and 7, supervisor port 9, console).
//!
//! Input: a sequence of `[len, time_step, bytes…]` records (len taken modulo 33, so over-long uplinks occur
//! too). Checks: no panic; every downlink packet is a valid CRTP packet (port ≤ 15, channel ≤ 3, ≤ 30 bytes);
//! the commander's setpoint mapping stays finite; log ticks and console output stay within their limits.
#![no_main]

use cfnav::mission::MissionParams;
use cfnav::radio::commander::{CommanderService, SetpointFollower};
use cfnav::radio::console::ConsoleService;
use cfnav::radio::crtp::{CrtpPacket, MAX_DATA, PlatformService, Router, Service};
use cfnav::radio::log::LogService;
use cfnav::radio::log_registry::FlightLogState;
use cfnav::radio::mem::MemService;
use cfnav::radio::param::ParamService;
use cfnav::radio::registry::MissionParamState;
use cfnav::radio::supervisor_port::{SupervisorPortConfig, SupervisorPortService};
use cfnav::types::{Setpoint, StateEstimate};
use libfuzzer_sys::fuzz_target;

fn valid(p: &CrtpPacket) {
    assert!(p.port <= 15 && p.channel <= 3 && p.data.len() <= MAX_DATA, "{p:?}");
}

fuzz_target!(|data: &[u8]| {
    let mut router: Router<8> = Router::new(PlatformService::new("fuzz"));
    let mut param = ParamService::new(MissionParamState::new(MissionParams::SEED, 128 * 64));
    let mut log: LogService<FlightLogState> = LogService::new();
    let mut mem = MemService;
    let commander = CommanderService::new();
    let mut follower = SetpointFollower::new();
    let mut supervisor = SupervisorPortService::new(SupervisorPortConfig {
        auto_arm: false,
        can_recover: true,
    });
    let mut console: ConsoleService<8> = ConsoleService::new();
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
        commander.set_now(now_us);
        supervisor.set_now(now_us);
        let reply = {
            let [mut rpyt, mut generic] = commander.ports();
            let mut services: [&mut dyn Service; 7] = [
                &mut param,
                &mut log,
                &mut mem,
                &mut rpyt,
                &mut generic,
                &mut supervisor,
                &mut console,
            ];
            router.handle_uplink(bytes, &mut services)
        };
        if let Some(p) = reply {
            valid(&p);
        }
        if let Some((cmd, t)) = commander.take_fresh()
            && let Some(
                Setpoint::Position { x_m, y_m, z_m, yaw_rad }
                | Setpoint::Velocity {
                    vx_m_s: x_m,
                    vy_m_s: y_m,
                    z_m,
                    yaw_rad,
                },
            ) = follower.to_setpoint(&cmd, t, &estimate)
        {
            assert!(x_m.is_finite() && y_m.is_finite() && z_m.is_finite() && yaw_rad.is_finite());
        }
        let _ = commander.take_meta();
        let requests = supervisor.take_requests();
        if requests.emergency_stop {
            assert!(supervisor.emergency_stopped());
        }
        supervisor.poll(now_us);
        while let Some(p) = param.next_notification() {
            valid(&p);
        }
        while let Some(note) = param.take_refusal() {
            console.print(&ParamService::<MissionParamState>::console_line(&note));
        }
        while let Some(p) = log.tick(now_ms, &state) {
            valid(&p);
        }
        while let Some(p) = console.next_packet() {
            valid(&p);
            assert!(!p.data.is_empty());
        }
    }
});
