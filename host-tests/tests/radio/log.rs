//! The log-variable table and the log service, port 5 (docs/hardware.md §4 and its connect sequence,
//! docs/radio.md, connect sequence and probe trace): byte-exact replies against the
//! trace, the flight table's TOC, block limits and error codes, the stock type conversion, period 0, the data
//! schedule with its 24-bit timestamp, the TOC CRC, and a seeded random-bytes loop.

use super::{hex, send, wire};
use cfnav::mission::MissionParams;
use cfnav::radio::crtp::{PlatformService, Router, Service};
use cfnav::radio::log::{
    E2BIG, EEXIST, EINVAL, ENOENT, ENOMEM, LogService, MAX_BLOCK_DATA, MAX_BLOCKS, MAX_OPS, PORT_LOG,
};
use cfnav::radio::log_decl::{LOG_CRC_SEED, LogEntry, LogSource, LogType, LogValue, log_toc_crc, single_to_half};
use cfnav::radio::param::ParamService;
use cfnav::radio::param_decl::{PARAM_CRC_SEED, ParamType, toc_crc};
use cfnav::radio::toc::Value;
use cfnav::radio_binding::log_table::{
    FlightLogState, ID_MISSION_STATE, ID_RANGE_FRONT, ID_RANGE_ZRANGE, ID_VBAT, ID_X, ID_Y, ID_Z, LOG_TABLE,
};
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::PARAM_TABLE;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Sends `data` on 5/1 and returns the reply's payload.
fn ctl<S: LogSource>(s: &mut LogService<S>, data: &[u8]) -> Vec<u8> {
    let mut bytes = vec![0x5D];
    bytes.extend_from_slice(data);
    let r = send(s, &bytes).expect("a control reply");
    assert_eq!(r[0], 0x5D, "control replies on 5/1");
    assert_eq!(r.len(), 4, "control replies are exactly 3 bytes");
    r[1..].to_vec()
}

// ---------------------------------------------------------------------------------------------------------
// The trace's table: three variables, the first `sim.t` float.
// ---------------------------------------------------------------------------------------------------------

const SIM_TABLE: &[LogEntry] = &[
    LogEntry::new("sim", "t", LogType::F32),
    LogEntry::new("sim", "n", LogType::U16),
    // group + name = 24 characters: the longest that fits a TOC item (30 bytes), checked at compile time.
    LogEntry::new("abcdefghijkl", "mnopqrstuvwx", LogType::I32),
];

#[derive(Debug, Clone, Copy, Default)]
struct Sim {
    t: f32,
}

impl LogSource for Sim {
    const TABLE: &'static [LogEntry] = SIM_TABLE;
    fn value(&self, id: u16) -> Option<LogValue> {
        match id {
            0 => Some(LogValue::F32(self.t)),
            1 => Some(LogValue::U16(513)),
            2 => Some(LogValue::I32(-2)),
            _ => None,
        }
    }
}

#[test]
fn trace_reset_toc_info_and_items() {
    let mut s = LogService::<Sim>::new();
    // RX 5/1 hdr=5D [05] -> TX 5/1 [05 00 00]
    assert_eq!(send(&mut s, &hex("5D 05")), Some(hex("5D 05 00 00")));
    // RX 5/0 [03] -> TX 5/0 [03 <count u16> <crc u32> 10 80] (trace: 03 03 00 9E 66 23 3D 10 80; the CRC is ours)
    let k = LogService::<Sim>::CRC.to_le_bytes();
    let mut info = hex("5C 03 03 00");
    info.extend_from_slice(&k);
    info.extend_from_slice(&[0x10, 0x80]);
    assert_eq!(send(&mut s, &hex("5C 03")), Some(info.clone()));
    assert_eq!(info.len(), 1 + 9);
    // RX 5/0 [02 00 00] -> TX 5/0 [02 00 00 07 's' 'i' 'm' 00 't' 00]
    assert_eq!(
        send(&mut s, &hex("5C 02 00 00")),
        Some(hex("5C 02 00 00 07 73 69 6D 00 74 00"))
    );
    assert_eq!(
        send(&mut s, &hex("5C 02 01 00")),
        Some(hex("5C 02 01 00 02 73 69 6D 00 6E 00"))
    );
    let longest = send(&mut s, &hex("5C 02 02 00")).unwrap();
    assert_eq!(longest.len(), 31);
    assert_eq!(longest[4], 6);
    // Out of range → [2]; truncated id → nothing; unknown TOC command → nothing.
    assert_eq!(send(&mut s, &hex("5C 02 03 00")), Some(hex("5C 02")));
    assert_eq!(send(&mut s, &hex("5C 02 00")), None);
    assert_eq!(send(&mut s, &hex("5C 01")), None);
    assert_eq!(send(&mut s, &hex("5C")), None);
}

#[test]
fn trace_create_start_data_stop_delete() {
    let mut s = LogService::<Sim>::new();
    let src = Sim { t: 1.5 };
    // RX 5/1 [06 01 77 00 00] -> TX 5/1 [06 01 00]
    assert_eq!(send(&mut s, &hex("5D 06 01 77 00 00")), Some(hex("5D 06 01 00")));
    // Created but not started: no data.
    assert_eq!(s.tick(0, &src), None);
    // RX 5/1 [03 01 0A] -> TX 5/1 [03 01 00]; then 5/2 [01 ts0 ts1 ts2 f32] every 100 ms
    assert_eq!(send(&mut s, &hex("5D 03 01 0A")), Some(hex("5D 03 01 00")));
    assert_eq!(s.running_period_ms(1), Some(100));
    let p = s.tick(1000, &src).unwrap();
    let mut expect = hex("5E 01 E8 03 00");
    expect.extend_from_slice(&1.5f32.to_le_bytes());
    assert_eq!(wire(&p), expect);
    assert_eq!(s.tick(1000, &src), None);
    assert_eq!(s.tick(1099, &src), None);
    assert!(s.tick(1100, &src).is_some());
    // 24-bit timestamp: the low three bytes of the millisecond clock, LE.
    let mut s2 = LogService::<Sim>::new();
    ctl(&mut s2, &hex("06 07 77 00 00"));
    ctl(&mut s2, &hex("03 07 01"));
    let p = s2.tick(0x0123_4567, &src).unwrap();
    assert_eq!(&wire(&p)[..5], &hex("5E 07 67 45 23"));
    // RX 5/1 [04 01], [02 01] -> [04 01 00], [02 01 00]; a stopped block sends nothing.
    assert_eq!(send(&mut s, &hex("5D 04 01")), Some(hex("5D 04 01 00")));
    assert_eq!(s.running_period_ms(1), None);
    assert_eq!(s.tick(5000, &src), None);
    assert_eq!(send(&mut s, &hex("5D 02 01")), Some(hex("5D 02 01 00")));
    assert_eq!(s.block_count(), 0);
    assert_eq!(send(&mut s, &hex("5D 02 01")), Some(hex("5D 02 01 02")));
}

#[test]
fn one_float_at_100ms_for_2s_gives_21_samples() {
    let mut s = LogService::<Sim>::new();
    ctl(&mut s, &hex("06 01 77 00 00"));
    ctl(&mut s, &hex("03 01 0A"));
    let mut stamps = Vec::new();
    for now in 10_000u32..=12_000 {
        let src = Sim { t: now as f32 };
        while let Some(p) = s.tick(now, &src) {
            assert_eq!(p.data.len(), 8);
            stamps.push(u32::from_le_bytes([p.data[1], p.data[2], p.data[3], 0]));
            assert_eq!(f32::from_le_bytes(p.data[4..8].try_into().unwrap()), now as f32);
        }
    }
    assert_eq!(stamps.len(), 21);
    assert!(stamps.windows(2).all(|w| w[1] - w[0] == 100));
    // A late tick sends one packet, not a burst, and the schedule restarts from it.
    assert!(s.tick(13_000, &Sim::default()).is_some());
    assert!(s.tick(13_000, &Sim::default()).is_none());
    assert!(s.tick(13_099, &Sim::default()).is_none());
    assert!(s.tick(13_100, &Sim::default()).is_some());
}

#[test]
fn timestamp_schedule_survives_clock_wrap() {
    let mut s = LogService::<Sim>::new();
    ctl(&mut s, &hex("06 01 77 00 00"));
    ctl(&mut s, &hex("08 01 32 00")); // start v2, 50 ms
    assert_eq!(s.running_period_ms(1), Some(50));
    let mut n = 0;
    let start = u32::MAX - 120;
    for k in 0..=300u32 {
        if s.tick(start.wrapping_add(k), &Sim::default()).is_some() {
            n += 1;
        }
    }
    assert_eq!(n, 7); // k = 0, 50, ..., 300
}

// ---------------------------------------------------------------------------------------------------------
// The flight table (docs/radio.md).
// ---------------------------------------------------------------------------------------------------------

type Flight = LogService<FlightLogState>;

#[test]
fn flight_table_has_the_required_variables() {
    let want: &[(&str, &str, LogType, u16)] = &[
        ("mission", "state", LogType::U8, ID_MISSION_STATE),
        ("stateEstimate", "x", LogType::F32, ID_X),
        ("stateEstimate", "y", LogType::F32, ID_Y),
        ("stateEstimate", "z", LogType::F32, ID_Z),
        ("range", "front", LogType::U16, ID_RANGE_FRONT),
        ("range", "back", LogType::U16, ID_RANGE_FRONT + 1),
        ("range", "left", LogType::U16, ID_RANGE_FRONT + 2),
        ("range", "right", LogType::U16, ID_RANGE_FRONT + 3),
        ("range", "up", LogType::U16, ID_RANGE_FRONT + 4),
        ("range", "zrange", LogType::U16, ID_RANGE_ZRANGE),
        ("pm", "vbat", LogType::F32, ID_VBAT),
    ];
    // docs/radio.md's variables keep ids 0..=10; the table goes on after them.
    assert_eq!(
        &LOG_TABLE[..want.len()]
            .iter()
            .map(|e| (e.group, e.name, e.ty))
            .collect::<Vec<_>>(),
        &want.iter().map(|&(g, n, t, _)| (g, n, t)).collect::<Vec<_>>()
    );
    assert_eq!(usize::from(Flight::COUNT), LOG_TABLE.len());
    let state = FlightLogState {
        mission_state: 42,
        position_m: [1.0, 2.0, 0.5],
        ranges_mm: [100, 200, 300, 400, 500, 600],
        vbat_v: 3.9,
        ..FlightLogState::default()
    };
    for &(g, n, ty, id) in want {
        assert_eq!(Flight::find(g, n), Some(id), "{g}.{n}");
        assert_eq!(Flight::entry(id).unwrap().ty, ty);
    }
    assert_eq!(state.value(ID_MISSION_STATE), Some(LogValue::U8(42)));
    assert_eq!(state.value(ID_Y), Some(LogValue::F32(2.0)));
    assert_eq!(state.value(ID_RANGE_FRONT + 2), Some(LogValue::U16(300)));
    assert_eq!(state.value(ID_RANGE_ZRANGE), Some(LogValue::U16(600)));
    assert_eq!(state.value(ID_VBAT), Some(LogValue::F32(3.9)));
    // The simulator has no CPU to measure: the cfnav.* load variables have no value (sent as zeros).
    assert_eq!(state.value(11), None);
    assert_eq!(state.value(LOG_TABLE.len() as u16), None);
}

#[test]
fn flight_toc_items_byte_exact() {
    let mut s = Flight::new();
    let mut info = vec![0x5C, 0x03];
    info.extend_from_slice(&(LOG_TABLE.len() as u16).to_le_bytes());
    info.extend_from_slice(&Flight::CRC.to_le_bytes());
    info.extend_from_slice(&[16, 128]);
    assert_eq!(send(&mut s, &hex("5C 03")), Some(info));
    let item = |id: u16, ty: u8, g: &str, n: &str| {
        let mut v = vec![0x5C, 0x02];
        v.extend_from_slice(&id.to_le_bytes());
        v.push(ty);
        v.extend_from_slice(g.as_bytes());
        v.push(0);
        v.extend_from_slice(n.as_bytes());
        v.push(0);
        v
    };
    assert_eq!(
        send(&mut s, &hex("5C 02 00 00")),
        Some(hex("5C 02 00 00 01 6D 69 73 73 69 6F 6E 00 73 74 61 74 65 00"))
    );
    assert_eq!(
        send(&mut s, &hex("5C 02 01 00")),
        Some(item(1, 7, "stateEstimate", "x"))
    );
    assert_eq!(send(&mut s, &hex("5C 02 04 00")), Some(item(4, 2, "range", "front")));
    assert_eq!(send(&mut s, &hex("5C 02 09 00")), Some(item(9, 2, "range", "zrange")));
    assert_eq!(send(&mut s, &hex("5C 02 0A 00")), Some(item(10, 7, "pm", "vbat")));
    let past = (LOG_TABLE.len() as u16).to_le_bytes();
    assert_eq!(send(&mut s, &[0x5C, 0x02, past[0], past[1]]), Some(hex("5C 02")));
}

#[test]
fn flight_block_end_to_end_through_router() {
    let mut router: Router<8> = Router::new(PlatformService::new("cfnav-test"));
    let mut log = Flight::new();
    let up = |router: &mut Router<8>, log: &mut Flight, bytes: &[u8]| {
        let mut services: [&mut dyn Service; 1] = [log];
        router.handle_uplink(bytes, &mut services).map(|p| wire(&p))
    };
    assert_eq!(up(&mut router, &mut log, &hex("5D 05")), Some(hex("5D 05 00 00")));
    // x, y, z float; front, zrange u16; state u8; vbat float stored, sent as FP16.
    let create = hex("5D 06 03 77 01 00 77 02 00 77 03 00 22 04 00 22 09 00 11 00 00 78 0A 00");
    assert_eq!(up(&mut router, &mut log, &create), Some(hex("5D 06 03 00")));
    assert_eq!(log.block_data_len(3), Some(12 + 4 + 1 + 2));
    assert_eq!(up(&mut router, &mut log, &hex("5D 03 03 05")), Some(hex("5D 03 03 00")));
    let state = FlightLogState {
        mission_state: 7,
        position_m: [1.25, -0.5, 0.75],
        ranges_mm: [1000, 0, 0, 0, 0, 320],
        vbat_v: 4.0,
        ..FlightLogState::default()
    };
    let p = log.tick(0x00AB_CDEF, &state).unwrap();
    let mut expect = hex("5E 03 EF CD AB");
    for v in [1.25f32, -0.5, 0.75] {
        expect.extend_from_slice(&v.to_le_bytes());
    }
    expect.extend_from_slice(&hex("E8 03 40 01 07 00 44"));
    assert_eq!(wire(&p), expect);
    router.enqueue(p).unwrap();
    // The queued data packet rides down on the next uplink (a null packet here).
    assert_eq!(up(&mut router, &mut log, &hex("FF")), Some(expect));
}

#[test]
fn wire_types_carry_both_protocols_codes() {
    // One enum serves both TOCs: §4.6's log codes and §4.5's param type nibble, written out here by hand.
    let want: [(LogType, u8, Option<u8>, usize, &str); 8] = [
        (LogType::U8, 1, Some(0x08), 1, "uint8"),
        (LogType::U16, 2, Some(0x09), 2, "uint16"),
        (LogType::U32, 3, Some(0x0A), 4, "uint32"),
        (LogType::I8, 4, Some(0x00), 1, "int8"),
        (LogType::I16, 5, Some(0x01), 2, "int16"),
        (LogType::I32, 6, Some(0x02), 4, "int32"),
        (LogType::F32, 7, Some(0x06), 4, "float"),
        (LogType::Fp16, 8, None, 2, "fp16"),
    ];
    for (t, log_code, param_code, size, name) in want {
        assert_eq!(t.log_code(), log_code, "{t:?}");
        assert_eq!(LogType::from_log_code(log_code), Some(t));
        assert_eq!(t.size(), size, "{t:?}");
        assert_eq!(t.name(), name);
        if let Some(code) = param_code {
            assert_eq!(t.param_code(), code, "{t:?}");
            assert_eq!(ParamType::from_param_code(code | 0x40), Some(t));
        }
    }
    // FP16 is a fetch type only: no parameter decodes as it, and no value is decoded from it.
    assert_eq!(ParamType::from_param_code(LogType::Fp16.param_code()), None);
    assert_eq!(Value::from_le(LogType::Fp16, &[0, 0x3C]), None);
    for code in (0..=255u8).filter(|c| !(1..=8).contains(c)) {
        assert_eq!(LogType::from_log_code(code), None, "{code}");
    }
}

// ---------------------------------------------------------------------------------------------------------
// Limits and error codes.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn block_count_limit_and_eexist() {
    let mut s = Flight::new();
    for id in 0..MAX_BLOCKS as u8 {
        assert_eq!(ctl(&mut s, &[6, id * 3, 0x11, 0, 0]), vec![6, id * 3, 0]);
    }
    assert_eq!(s.block_count(), 16);
    assert_eq!(ctl(&mut s, &[6, 200, 0x11, 0, 0]), vec![6, 200, ENOMEM]);
    assert_eq!(ctl(&mut s, &[6, 3, 0x11, 0, 0]), vec![6, 3, EEXIST]);
    assert_eq!(ctl(&mut s, &[2, 3]), vec![2, 3, 0]);
    assert_eq!(ctl(&mut s, &[6, 200, 0x11, 0, 0]), vec![6, 200, 0]);
    // Reset deletes everything.
    assert_eq!(ctl(&mut s, &[5]), vec![5, 0, 0]);
    assert_eq!(s.block_count(), 0);
    assert_eq!(s.ops_used(), 0);
    // Block id 255 is an ordinary id.
    assert_eq!(ctl(&mut s, &[6, 255]), vec![6, 255, 0]);
    assert_eq!(ctl(&mut s, &[6, 255]), vec![6, 255, EEXIST]);
}

#[test]
fn block_data_limit_e2big() {
    let mut s = Flight::new();
    // Seven floats = 28 bytes: E2BIG and no block is left behind.
    let mut seven = vec![6, 1];
    for _ in 0..7 {
        seven.extend_from_slice(&[0x77, 1, 0]);
    }
    assert_eq!(ctl(&mut s, &seven), vec![6, 1, E2BIG]);
    assert_eq!(s.block_count(), 0);
    // Six floats + one u16 = 26 bytes: fits exactly (split over create + append, as cflib does).
    assert_eq!(
        ctl(&mut s, &hex("06 01 77 01 00 77 02 00 77 03 00 77 0A 00")),
        vec![6, 1, 0]
    );
    assert_eq!(ctl(&mut s, &hex("07 01 77 01 00 77 02 00 22 04 00")), vec![7, 1, 0]);
    assert_eq!(s.block_data_len(1), Some(MAX_BLOCK_DATA));
    // One more byte does not fit; the failed append changes nothing.
    assert_eq!(ctl(&mut s, &hex("07 01 11 00 00")), vec![7, 1, E2BIG]);
    assert_eq!(s.block_data_len(1), Some(MAX_BLOCK_DATA));
    assert_eq!(s.ops_used(), 7);
    // The conversion target counts, not the storage type: a float sent as u8 is one byte.
    assert_eq!(ctl(&mut s, &hex("06 02 71 01 00")), vec![6, 2, 0]);
    assert_eq!(s.block_data_len(2), Some(1));
    // Data packet of the full block is 4 + 26 = 30 bytes.
    ctl(&mut s, &[3, 1, 1]);
    assert_eq!(s.tick(0, &FlightLogState::default()).unwrap().data.len(), 30);
}

#[test]
fn total_ops_limit_enomem() {
    let mut s = Flight::new();
    let nine_u8 = |cmd: u8, id: u8| {
        let mut v = vec![cmd, id];
        for _ in 0..9 {
            v.extend_from_slice(&[0x11, 0, 0]);
        }
        v
    };
    // 14 blocks × 9 u8 ops = 126 ops.
    for id in 0..14 {
        assert_eq!(ctl(&mut s, &nine_u8(6, id)), vec![6, id, 0]);
    }
    assert_eq!(s.ops_used(), 126);
    // Two more fit, a third does not.
    assert_eq!(ctl(&mut s, &hex("06 0E 11 00 00 11 00 00")), vec![6, 14, 0]);
    assert_eq!(s.ops_used(), MAX_OPS);
    assert_eq!(ctl(&mut s, &hex("07 0E 11 00 00")), vec![7, 14, ENOMEM]);
    assert_eq!(ctl(&mut s, &hex("06 0F 11 00 00")), vec![6, 15, ENOMEM]);
    assert_eq!(s.block_count(), 15);
    assert_eq!(s.ops_used(), MAX_OPS);
    // An empty block takes no op.
    assert_eq!(ctl(&mut s, &hex("06 0F")), vec![6, 15, 0]);
    // Deleting frees the ops.
    assert_eq!(ctl(&mut s, &[2, 0]), vec![2, 0, 0]);
    assert_eq!(s.ops_used(), 119);
    assert_eq!(ctl(&mut s, &nine_u8(7, 15)), vec![7, 15, 0]);
    assert_eq!(s.ops_used(), MAX_OPS);
}

#[test]
fn enoent_einval_and_truncated_requests() {
    let mut s = Flight::new();
    // Unknown variable: ENOENT, nothing created; raw-memory id 0xFFFF is not implemented.
    let past = (LOG_TABLE.len() as u16).to_le_bytes();
    assert_eq!(ctl(&mut s, &[6, 1, 0x77, past[0], past[1]]), vec![6, 1, ENOENT]);
    assert_eq!(ctl(&mut s, &hex("06 01 77 FF FF")), vec![6, 1, ENOENT]);
    assert_eq!(s.block_count(), 0);
    // Unknown block for append, start, start v2, stop, delete.
    assert_eq!(ctl(&mut s, &hex("07 09 11 00 00")), vec![7, 9, ENOENT]);
    assert_eq!(ctl(&mut s, &hex("03 09 0A")), vec![3, 9, ENOENT]);
    assert_eq!(ctl(&mut s, &hex("08 09 64 00")), vec![8, 9, ENOENT]);
    assert_eq!(ctl(&mut s, &hex("04 09")), vec![4, 9, ENOENT]);
    assert_eq!(ctl(&mut s, &hex("02 09")), vec![2, 9, ENOENT]);
    // Unknown fetch type (0 and 9..15): EINVAL. The stored-type nibble is ignored.
    assert_eq!(ctl(&mut s, &hex("06 01 70 01 00")), vec![6, 1, EINVAL]);
    assert_eq!(ctl(&mut s, &hex("06 01 79 01 00")), vec![6, 1, EINVAL]);
    assert_eq!(ctl(&mut s, &hex("06 01 07 01 00")), vec![6, 1, 0]);
    // An append failing on its second op adds nothing.
    assert_eq!(ctl(&mut s, &hex("07 01 11 00 00 11 00 7F")), vec![7, 1, ENOENT]);
    assert_eq!(s.ops_used(), 1);
    // Trailing bytes short of a whole op are ignored.
    assert_eq!(ctl(&mut s, &hex("07 01 11 00 00 11 00")), vec![7, 1, 0]);
    assert_eq!(s.ops_used(), 2);
    // Truncated: no block id, or start without its period → no reply. Unknown commands and V1 → no reply.
    for bad in [
        "5D 06",
        "5D 03 01",
        "5D 08 01 0A",
        "5D 04",
        "5D",
        "5D 00 01 01 00",
        "5D 09 01",
        "5E 01",
        "5F 00",
    ] {
        assert_eq!(send(&mut s, &hex(bad)), None, "{bad}");
    }
    assert_eq!(s.ops_used(), 2);
}

#[test]
fn period_zero_is_refused() {
    let mut s = Flight::new();
    ctl(&mut s, &hex("06 01 77 01 00"));
    assert_eq!(ctl(&mut s, &hex("03 01 00")), vec![3, 1, EINVAL]);
    assert_eq!(ctl(&mut s, &hex("08 01 00 00")), vec![8, 1, EINVAL]);
    assert_eq!(s.running_period_ms(1), None);
    assert_eq!(s.tick(0, &FlightLogState::default()), None);
    // A running block keeps its period when a period-0 start is refused.
    assert_eq!(ctl(&mut s, &hex("03 01 FE")), vec![3, 1, 0]);
    assert_eq!(s.running_period_ms(1), Some(2540));
    assert_eq!(ctl(&mut s, &hex("03 01 00")), vec![3, 1, EINVAL]);
    assert_eq!(s.running_period_ms(1), Some(2540));
    // Restart with a new period.
    assert_eq!(ctl(&mut s, &hex("08 01 E8 03")), vec![8, 1, 0]);
    assert_eq!(s.running_period_ms(1), Some(1000));
    // Unknown block with period 0: the block check comes first.
    assert_eq!(ctl(&mut s, &hex("03 02 00")), vec![3, 2, ENOENT]);
}

// ---------------------------------------------------------------------------------------------------------
// Type conversion (stock log.c logRunBlock / single2half).
// ---------------------------------------------------------------------------------------------------------

fn conv(v: LogValue, fetch: LogType) -> Vec<u8> {
    let (b, n) = v.convert(fetch);
    b[..n].to_vec()
}

#[test]
fn type_conversion_follows_stock() {
    use LogValue as V;
    use cfnav::radio::wire_type::WireType::*;
    // Same type: plain LE.
    assert_eq!(conv(V::F32(1.5), F32), 1.5f32.to_le_bytes());
    assert_eq!(conv(V::U16(0x1234), U16), [0x34, 0x12]);
    // float → integers: toward zero through int32, then the low bytes.
    assert_eq!(conv(V::F32(3.7), U16), [3, 0]);
    assert_eq!(conv(V::F32(-3.7), I16), [0xFD, 0xFF]);
    assert_eq!(conv(V::F32(-1.5), U16), [0xFF, 0xFF]);
    assert_eq!(conv(V::F32(-1.5), U8), [0xFF]);
    assert_eq!(conv(V::F32(70_000.0), U16), [0x70, 0x11]);
    assert_eq!(conv(V::F32(1234.9), U32), [0xD2, 0x04, 0, 0]);
    // Out of int32 range saturates, NaN gives 0 (Cortex-M4 VCVT, Rust `as`).
    assert_eq!(conv(V::F32(1e10), I32), i32::MAX.to_le_bytes());
    assert_eq!(conv(V::F32(-1e10), I32), i32::MIN.to_le_bytes());
    assert_eq!(conv(V::F32(f32::NAN), U32), [0, 0, 0, 0]);
    // Integer narrowing keeps the low bytes; widening sign-extends through int32.
    assert_eq!(conv(V::U16(300), U8), [0x2C]);
    assert_eq!(conv(V::U16(65535), I16), [0xFF, 0xFF]);
    assert_eq!(conv(V::U8(200), I8), [0xC8]);
    assert_eq!(conv(V::I8(-2), U32), [0xFE, 0xFF, 0xFF, 0xFF]);
    assert_eq!(conv(V::I16(-2), U16), [0xFE, 0xFF]);
    // Integers → float through int32 (a uint32 above 2^31 wraps negative, as stock).
    assert_eq!(conv(V::U16(1234), F32), 1234.0f32.to_le_bytes());
    assert_eq!(conv(V::U32(u32::MAX), F32), (-1.0f32).to_le_bytes());
    // FP16.
    assert_eq!(conv(V::U8(1), Fp16), [0x00, 0x3C]);
    assert_eq!(conv(V::F32(0.5), Fp16), [0x00, 0x38]);
    assert_eq!(conv(V::F32(-2.0), Fp16), [0x00, 0xC0]);
    assert_eq!(conv(V::F32(4.0), Fp16), [0x00, 0x44]);
    assert_eq!(single_to_half(65504.0), 0x7BFF);
    assert_eq!(single_to_half(1e6), 0x7C00);
    assert_eq!(single_to_half(-1e6), 0xFC00);
    assert_eq!(single_to_half(f32::INFINITY), 0x7C00);
    assert_eq!(single_to_half(f32::NAN), 0x7E00);
    assert_eq!(single_to_half(1e-5), 0); // no subnormals
    assert_eq!(single_to_half(0.0), 0);
    assert_eq!(single_to_half(6.1035156e-5), 0x0400); // 2^-14, the smallest normal
    assert_eq!(single_to_half(-0.25), 0xB400);
    // Every bit pattern converts without panicking, to any fetch type.
    let mut rng = SmallRng::seed_from_u64(16);
    for _ in 0..200_000 {
        let x = f32::from_bits(rng.random());
        for t in [U8, U16, U32, I8, I16, I32, F32, Fp16] {
            assert_eq!(conv(V::F32(x), t).len(), t.size());
        }
    }
    // Within its 11 bits, FP16 round-trips small integers.
    for k in 0..=2048u16 {
        let h = single_to_half(f32::from(k));
        let e = i32::from((h >> 10) & 0x1F) - 15;
        let m = f32::from((h & 0x3FF) | 0x400) / 1024.0;
        let back = if h == 0 { 0.0 } else { m * 2f32.powi(e) };
        assert_eq!(back, f32::from(k), "{k}");
    }
}

#[test]
fn conversion_in_a_data_packet() {
    let mut s = Flight::new();
    // x (float) as u16, as i8, as FP16; front (u16) as float, as u8; state (u8) as i32.
    let create = hex("06 04 72 01 00 74 01 00 78 01 00 27 04 00 21 04 00 16 00 00");
    assert_eq!(ctl(&mut s, &create), vec![6, 4, 0]);
    ctl(&mut s, &hex("03 04 01"));
    let state = FlightLogState {
        mission_state: 201,
        position_m: [-2.75, 0.0, 0.0],
        ranges_mm: [300, 0, 0, 0, 0, 0],
        vbat_v: 0.0,
        ..FlightLogState::default()
    };
    let p = s.tick(5, &state).unwrap();
    let mut expect = hex("04 05 00 00 FE FF FE");
    expect.extend_from_slice(&single_to_half(-2.75).to_le_bytes());
    expect.extend_from_slice(&300.0f32.to_le_bytes());
    expect.extend_from_slice(&hex("2C C9 00 00 00"));
    assert_eq!(p.data.to_vec(), expect);
    assert_eq!(single_to_half(-2.75), 0xC180);
}

// ---------------------------------------------------------------------------------------------------------
// CRC.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn log_crc_differs_from_param_crc_and_tracks_the_toc() {
    assert_ne!(LOG_CRC_SEED, PARAM_CRC_SEED);
    let log = Flight::CRC;
    let param = ParamService::<MissionParamState>::CRC;
    assert_ne!(log, param);
    assert_eq!(log, log_toc_crc(LOG_TABLE));
    assert_eq!(param, toc_crc(PARAM_TABLE));
    // Same names on both sides still give different CRCs (the seeds differ).
    let same: Vec<LogEntry> = PARAM_TABLE
        .iter()
        .map(|e| LogEntry::new(e.group, e.name, LogType::F32))
        .collect();
    assert_ne!(log_toc_crc(&same), toc_crc(PARAM_TABLE));
    // The CRC changes with a name, a type or the order.
    let mut t = LOG_TABLE.to_vec();
    t[10] = LogEntry::new("pm", "vbaT", LogType::F32);
    assert_ne!(log_toc_crc(&t), log);
    let mut t = LOG_TABLE.to_vec();
    t[0] = LogEntry::new("mission", "state", LogType::U16);
    assert_ne!(log_toc_crc(&t), log);
    let mut t = LOG_TABLE.to_vec();
    t.swap(1, 2);
    assert_ne!(log_toc_crc(&t), log);
    assert_ne!(log_toc_crc(&LOG_TABLE[..10]), log);
    assert_ne!(LogService::<Sim>::CRC, log);
    let _ = MissionParams::SEED;
}

// ---------------------------------------------------------------------------------------------------------
// Robustness.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn random_bytes_never_panic_and_keep_invariants() {
    let mut rng = SmallRng::seed_from_u64(0x05EE_D106);
    let mut router: Router<16> = Router::new(PlatformService::new("cfnav-test"));
    let mut log = Flight::new();
    let mut now: u32 = u32::MAX - 50_000;
    let state = FlightLogState {
        mission_state: 3,
        position_m: [f32::NAN, f32::INFINITY, -1e30],
        ranges_mm: [u16::MAX; 6],
        vbat_v: 3.7,
        ..FlightLogState::default()
    };
    for i in 0..200_000u32 {
        let len = rng.random_range(0..=33usize);
        let mut bytes: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        // Mostly log traffic with plausible commands, so the block logic is exercised.
        if !bytes.is_empty() && rng.random_bool(0.8) {
            bytes[0] = (PORT_LOG << 4) | 0x0C | rng.random_range(0..4u8);
            if bytes.len() > 1 && rng.random_bool(0.7) {
                bytes[1] = rng.random_range(0..10u8);
            }
            if bytes.len() > 2 && rng.random_bool(0.7) {
                bytes[2] = rng.random_range(0..20u8);
            }
            if bytes.len() > 3 && rng.random_bool(0.5) {
                bytes[3] = rng.random_range(0..3u8); // short periods, small fetch types
            }
        }
        let mut services: [&mut dyn Service; 1] = [&mut log];
        if let Some(p) = router.handle_uplink(&bytes, &mut services) {
            assert!(p.data.len() <= 30);
            if p.port == PORT_LOG && p.channel == 1 {
                assert_eq!(p.data.len(), 3);
            }
        }
        now = now.wrapping_add(rng.random_range(0..5));
        while let Some(p) = log.tick(now, &state) {
            assert_eq!(p.port, PORT_LOG);
            assert_eq!(p.channel, 2);
            assert!(p.data.len() >= 4 && p.data.len() <= 4 + MAX_BLOCK_DATA);
            let _ = router.enqueue(p);
        }
        assert!(log.block_count() <= MAX_BLOCKS);
        assert!(log.ops_used() <= MAX_OPS);
        for id in 0..=255u8 {
            if let Some(n) = log.block_data_len(id) {
                assert!(n <= MAX_BLOCK_DATA);
            }
        }
        if i % 50_000 == 0 {
            log.reset();
        }
    }
}
