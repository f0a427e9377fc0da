//! Fuzz target: the parameter (port 2) and log (port 5) services driven directly, packet by packet.
//!
//! Input: records `[selector, len, bytes…]`: selector bit 0 picks the service, bits 1–2 the channel, bits 3–7
//! the time step (ms) of the log clock. Checks: no panic; replies, VALUE_UPDATED notifications and log data
//! packets are valid CRTP packets (log data on channel 2); refusal console lines fit their 64-byte buffer; a
//! log reset leaves no block and no operation behind.
#![no_main]

use cfnav::mission::MissionParams;
use cfnav::radio::crtp::{CrtpPacket, MAX_DATA, Service};
use cfnav::radio::log::LogService;
use cfnav::radio::param::ParamService;
use cfnav::radio_binding::log_table::FlightLogState;
use cfnav::radio_binding::param_state::MissionParamState;
use libfuzzer_sys::fuzz_target;

fn valid(p: &CrtpPacket) {
    assert!(p.port <= 15 && p.channel <= 3 && p.data.len() <= MAX_DATA, "{p:?}");
}

fuzz_target!(|data: &[u8]| {
    let mut param = ParamService::new(MissionParamState::new(MissionParams::SEED, 128 * 64));
    let mut log: LogService<FlightLogState> = LogService::new();
    let state = FlightLogState {
        mission_state: 3,
        position_m: [1.0, 2.0, 0.5],
        ranges_mm: [100, 200, 300, 400, 500, 600],
        vbat_v: 3.9,
        ..FlightLogState::default()
    };
    let mut now_ms: u32 = 0;
    let mut rest = data;
    while let [selector, len, tail @ ..] = rest {
        let n = usize::from(*len % 31).min(tail.len());
        let (bytes, next) = tail.split_at(n);
        rest = next;
        let channel = (selector >> 1) & 0x03;
        now_ms = now_ms.saturating_add(u32::from(selector >> 3));
        let reply = if selector & 1 == 0 {
            let p = CrtpPacket::new(2, channel, bytes).expect("≤ 30 bytes");
            param.handle(&p)
        } else {
            let p = CrtpPacket::new(5, channel, bytes).expect("≤ 30 bytes");
            log.handle(&p)
        };
        if let Some(p) = reply {
            valid(&p);
        }
        while let Some(p) = param.next_notification() {
            valid(&p);
        }
        while let Some(note) = param.take_refusal() {
            let line = ParamService::<MissionParamState>::console_line(&note);
            assert!(line.len() <= 64);
        }
        while let Some(p) = log.tick(now_ms, &state) {
            valid(&p);
            assert_eq!(p.channel, 2, "log data channel");
        }
    }
    log.reset();
    assert_eq!(log.block_count(), 0);
    assert_eq!(log.ops_used(), 0);
});
