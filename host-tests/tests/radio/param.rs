//! The parameter registry and service, port 2 (docs/hardware.md §4 and its connect sequence,
//! docs/radio.md, connect sequence and probe trace): byte-exact replies against
//! the trace, the connect sequence through the router, the refusal rule, set-by-name, VALUE_UPDATED, the TOC
//! CRC, and a seeded random-bytes loop.

use super::{hex, send, wire};
use cfnav::crc::{crc32, crc32_update};
use cfnav::mission::MissionParams;
use cfnav::radio::crtp::{CrtpPacket, PlatformService, Router, Service};
use cfnav::radio::param::{EACCES, EINVAL, ENOENT, ParamService, RefusalNote};
use cfnav::radio::param_decl::{
    FLAG_EXTENDED, FLAG_READ_ONLY, PARAM_CRC_SEED, ParamEntry, ParamStore, ParamType, Refusal, toc_crc,
};
use cfnav::radio::toc::Value;
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::{
    ID_GOAL_X, ID_GOAL_Y, ID_HEIGHT, ID_SPEED, ID_START, ID_START_X, ID_START_Y, PARAM_TABLE,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const CAPACITY: usize = 128 * 64;

pub(super) type Mission = ParamService<MissionParamState>;

/// The mission's parameter service over the seed parameters (also the mode tests').
pub(super) fn service() -> Mission {
    ParamService::new(MissionParamState::new(MissionParams::SEED, CAPACITY))
}

fn f32_le(v: f32) -> [u8; 4] {
    v.to_le_bytes()
}

/// `[hdr, id u16, value]` for a float write on 2/2.
pub(super) fn write_f32(id: u16, v: f32) -> Vec<u8> {
    let mut out = vec![0x2E];
    out.extend_from_slice(&id.to_le_bytes());
    out.extend_from_slice(&f32_le(v));
    out
}

// ---------------------------------------------------------------------------------------------------------
// A second store: every type, a read-only and an extended entry, and a three-entry table like the trace's.
// ---------------------------------------------------------------------------------------------------------

const TEST_TABLE: &[ParamEntry] = &[
    ParamEntry::new("t", "u8", ParamType::U8, 0),
    ParamEntry::new("t", "u16", ParamType::U16, 0),
    ParamEntry::new("t", "u32", ParamType::U32, FLAG_EXTENDED),
    ParamEntry::new("t", "i8", ParamType::I8, 0),
    ParamEntry::new("t", "i16", ParamType::I16, 0),
    ParamEntry::new("t", "i32", ParamType::I32, 0),
    ParamEntry::new("t", "f32", ParamType::F32, 0),
    ParamEntry::new("fw", "rev", ParamType::U32, FLAG_READ_ONLY),
    // group + name = 24 characters: the longest that fits a TOC item (30 bytes), checked at compile time.
    ParamEntry::new("abcdefghijkl", "mnopqrstuvwx", ParamType::U8, 0),
];

#[derive(Debug, Clone, Copy, PartialEq)]
struct TestStore {
    v: [Option<Value>; 9],
}

impl TestStore {
    fn new() -> Self {
        Self {
            v: [
                Some(Value::U8(1)),
                Some(Value::U16(0x0203)),
                Some(Value::U32(0x0405_0607)),
                Some(Value::I8(-2)),
                Some(Value::I16(-300)),
                Some(Value::I32(-70_000)),
                Some(Value::F32(1.5)),
                Some(Value::U32(0xDEAD_BEEF)),
                Some(Value::U8(9)),
            ],
        }
    }
}

impl ParamStore for TestStore {
    const TABLE: &'static [ParamEntry] = TEST_TABLE;

    fn read(&self, id: u16) -> Option<Value> {
        *self.v.get(usize::from(id))?
    }

    fn write(&mut self, id: u16, value: Value) -> Result<(), Refusal> {
        let slot = self.v.get_mut(usize::from(id)).ok_or(Refusal::UnknownId)?;
        if TEST_TABLE[usize::from(id)].ty != value.ty() {
            return Err(Refusal::WrongType);
        }
        *slot = Some(value);
        Ok(())
    }
}

const TRACE_TABLE: &[ParamEntry] = &[
    ParamEntry::new("mission", "start", ParamType::U8, 0),
    ParamEntry::new("mission", "goalX", ParamType::F32, 0),
    ParamEntry::new("mission", "goalY", ParamType::F32, 0),
];

struct TraceStore(MissionParamState);

impl ParamStore for TraceStore {
    const TABLE: &'static [ParamEntry] = TRACE_TABLE;
    fn read(&self, id: u16) -> Option<Value> {
        if usize::from(id) < TRACE_TABLE.len() {
            self.0.read(id)
        } else {
            None
        }
    }
    fn write(&mut self, id: u16, value: Value) -> Result<(), Refusal> {
        if usize::from(id) < TRACE_TABLE.len() {
            self.0.write(id, value)
        } else {
            Err(Refusal::UnknownId)
        }
    }
}

/// The probe's fake firmware state: `mission.start` 0, goalX 0.5, goalY with bits 0x00C0FFEE.
fn trace_state() -> MissionParamState {
    let mut s = MissionParamState::new(MissionParams::SEED, CAPACITY);
    s.params.goal_m = (0.5, f32::from_bits(0x00C0_FFEE));
    s
}

// ---------------------------------------------------------------------------------------------------------
// Byte-exact replies (docs/radio.md probe trace)
// ---------------------------------------------------------------------------------------------------------

#[test]
fn toc_info_layout_matches_the_trace() {
    // Trace: `RX 2/0 hdr=2C [03] -> TX 2/0 [03 03 00 16 EA 06 16]`: cmd, count u16, CRC u32 (the fake's CRC is
    // its own; ours is `toc_crc`, checked below). Three entries as in the trace:
    let mut s = ParamService::new(TraceStore(trace_state()));
    let crc = toc_crc(TRACE_TABLE).to_le_bytes();
    let mut expected = hex("2C 03 03 00");
    expected.extend_from_slice(&crc);
    assert_eq!(send(&mut s, &[0x2C, 0x03]), Some(expected));
    // The whole table, 7-byte payload; bits 2-3 of the request header ignored.
    let mut m = service();
    let crc = Mission::CRC.to_le_bytes();
    let mut expected = vec![0x2C, 0x03];
    expected.extend_from_slice(&(PARAM_TABLE.len() as u16).to_le_bytes());
    expected.extend_from_slice(&crc);
    assert_eq!(send(&mut m, &[0x2C, 0x03]), Some(expected.clone()));
    assert_eq!(send(&mut m, &[0x20, 0x03]), Some(expected));
    assert_eq!(Mission::CRC, toc_crc(PARAM_TABLE));
}

#[test]
fn toc_items_match_the_trace() {
    let mut m = service();
    // Trace: `RX 2/0 [02 00 00] -> TX 2/0 [02 00 00 08 'mission' 00 'start' 00]`.
    let mut expected = hex("2C 02 00 00 08");
    expected.extend_from_slice(b"mission\0start\0");
    assert_eq!(send(&mut m, &hex("2C 02 00 00")), Some(expected));
    let names = ["start", "goalX", "goalY", "startX", "startY", "height", "speed"];
    for (i, name) in names.iter().enumerate() {
        let reply = send(&mut m, &[0x2C, 0x02, i as u8, 0]).unwrap();
        let ty = if i == 0 { 0x08 } else { 0x06 };
        let mut expected = vec![0x2C, 0x02, i as u8, 0, ty];
        expected.extend_from_slice(b"mission\0");
        expected.extend_from_slice(name.as_bytes());
        expected.push(0);
        assert_eq!(reply, expected);
    }
    // Out of range: `[02]` only (param_logic.c L289-324); high id byte honoured.
    let past = (PARAM_TABLE.len() as u16).to_le_bytes();
    assert_eq!(send(&mut m, &[0x2C, 0x02, past[0], past[1]]), Some(hex("2C 02")));
    assert_eq!(send(&mut m, &hex("2C 02 00 01")), Some(hex("2C 02")));
    // Truncated id, empty request, V1 commands: no reply.
    assert_eq!(send(&mut m, &hex("2C 02 00")), None);
    assert_eq!(send(&mut m, &hex("2C")), None);
    assert_eq!(send(&mut m, &hex("2C 00 00")), None);
    assert_eq!(send(&mut m, &hex("2C 01")), None);
}

#[test]
fn toc_item_type_bytes_and_longest_name() {
    let mut s = ParamService::new(TestStore::new());
    let codes = [0x08, 0x09, 0x0A | 0x10, 0x00, 0x01, 0x02, 0x06, 0x0A | 0x40, 0x08];
    for (i, code) in codes.iter().enumerate() {
        let reply = send(&mut s, &[0x2C, 0x02, i as u8, 0]).unwrap();
        assert_eq!(reply[4], *code, "id {i}");
    }
    // 24 characters of names: exactly 30 payload bytes.
    let reply = send(&mut s, &hex("2C 02 08 00")).unwrap();
    assert_eq!(reply.len(), 31);
    assert_eq!(&reply[5..], b"abcdefghijkl\0mnopqrstuvwx\0");
}

#[test]
fn reads_match_the_trace() {
    let mut s = ParamService::new(TraceStore(trace_state()));
    // Trace: `RX 2/1 [00 00] [01 00] [02 00] -> TX 2/1 [00 00 00 00] [01 00 00 00 00 00 3F] [02 00 00 EE FF C0 00]`.
    assert_eq!(send(&mut s, &hex("2D 00 00")), Some(hex("2D 00 00 00 00")));
    assert_eq!(send(&mut s, &hex("2D 01 00")), Some(hex("2D 01 00 00 00 00 00 3F")));
    assert_eq!(send(&mut s, &hex("2D 02 00")), Some(hex("2D 02 00 00 EE FF C0 00")));
    // Unknown id: `<id> 02` (ENOENT).
    assert_eq!(send(&mut s, &hex("2D 03 00")), Some(hex("2D 03 00 02")));
    assert_eq!(send(&mut s, &hex("2D FF FF")), Some(hex("2D FF FF 02")));
    // Truncated: no reply.
    assert_eq!(send(&mut s, &hex("2D 00")), None);
    assert_eq!(send(&mut s, &hex("2D")), None);
}

#[test]
fn reads_of_every_type_are_3_plus_size_bytes() {
    let mut s = ParamService::new(TestStore::new());
    assert_eq!(send(&mut s, &hex("2D 00 00")), Some(hex("2D 00 00 00 01")));
    assert_eq!(send(&mut s, &hex("2D 01 00")), Some(hex("2D 01 00 00 03 02")));
    assert_eq!(send(&mut s, &hex("2D 02 00")), Some(hex("2D 02 00 00 07 06 05 04")));
    assert_eq!(send(&mut s, &hex("2D 03 00")), Some(hex("2D 03 00 00 FE")));
    assert_eq!(send(&mut s, &hex("2D 04 00")), Some(hex("2D 04 00 00 D4 FE")));
    assert_eq!(send(&mut s, &hex("2D 05 00")), Some(hex("2D 05 00 00 90 EE FE FF")));
    assert_eq!(send(&mut s, &hex("2D 06 00")), Some(hex("2D 06 00 00 00 00 C0 3F")));
    // Read-only parameters are readable.
    assert_eq!(send(&mut s, &hex("2D 07 00")), Some(hex("2D 07 00 00 EF BE AD DE")));
}

#[test]
fn write_matches_the_trace() {
    let mut m = service();
    // Trace: `RX 2/2 [00 00 01] -> TX 2/2 [00 00 01]` (mission.start := 1).
    assert_eq!(send(&mut m, &hex("2E 00 00 01")), Some(hex("2E 00 00 01")));
    assert_eq!(m.store().start, 1);
    assert_eq!(send(&mut m, &hex("2D 00 00")), Some(hex("2D 00 00 00 01")));
    // A float write is echoed and read back.
    let req = write_f32(ID_GOAL_X, 4.25);
    assert_eq!(send(&mut m, &req), Some(req.clone()));
    assert_eq!(m.store().params.goal_m.0, 4.25);
    assert!(m.take_refusal().is_none());
}

#[test]
fn write_errors_change_nothing() {
    let mut s = ParamService::new(TestStore::new());
    let before = *s.store();
    // Unknown id: `[id, 2]`.
    assert_eq!(send(&mut s, &hex("2E 09 00 01")), Some(hex("2E 09 00 02")));
    // Read-only: no reply at all.
    assert_eq!(send(&mut s, &hex("2E 07 00 01 02 03 04")), None);
    // Wrong value sizes and truncated packets: no reply.
    assert_eq!(send(&mut s, &hex("2E 00 00")), None);
    assert_eq!(send(&mut s, &hex("2E 00 00 01 02")), None);
    assert_eq!(send(&mut s, &hex("2E 02 00 01 02 03")), None);
    assert_eq!(send(&mut s, &hex("2E 00")), None);
    assert_eq!(send(&mut s, &hex("2E")), None);
    assert_eq!(*s.store(), before);
    // Every type writes back exactly.
    assert_eq!(
        send(&mut s, &hex("2E 05 00 01 02 03 84")),
        Some(hex("2E 05 00 01 02 03 84"))
    );
    assert_eq!(s.store().v[5], Some(Value::I32(i32::from_le_bytes([1, 2, 3, 0x84]))));
    assert_eq!(send(&mut s, &hex("2E 04 00 FF 7F")), Some(hex("2E 04 00 FF 7F")));
    assert_eq!(s.store().v[4], Some(Value::I16(i16::MAX)));
}

// ---------------------------------------------------------------------------------------------------------
// The connect sequence (docs/hardware.md §4; docs/radio.md, connect sequence) through the router
// ---------------------------------------------------------------------------------------------------------

#[test]
fn connect_sequence_param_steps_through_the_router() {
    let mut router: Router<4> = Router::new(PlatformService::new("cfnav-test"));
    let mut m = service();
    let mut up = |bytes: &[u8], m: &mut Mission| router.handle_uplink(bytes, &mut [m]).map(|p| wire(&p));

    // Step 7: TOC info.
    let info = up(&[0x2C, 0x03], &mut m).unwrap();
    assert_eq!(info.len(), 8);
    assert_eq!(info[..2], [0x2C, 0x03]);
    let count = u16::from_le_bytes([info[2], info[3]]);
    assert_eq!(usize::from(count), PARAM_TABLE.len());
    assert_eq!(u32::from_le_bytes(info[4..8].try_into().unwrap()), Mission::CRC);

    // Step 8: every item, one at a time; parse them as cflib does (toc.py / param.py).
    let mut toc = Vec::new();
    for id in 0..count {
        let b = id.to_le_bytes();
        let item = up(&[0x2C, 0x02, b[0], b[1]], &mut m).unwrap();
        assert_eq!(item[..4], [0x2C, 0x02, b[0], b[1]]);
        let ty = item[4];
        // Extended type (cflib then asks misc 7, step 8b) exactly for the persistent parameters.
        assert_eq!(ty & 0x10 != 0, PARAM_TABLE[usize::from(id)].is_persistent(), "id {id}");
        let strings: Vec<&[u8]> = item[5..].split(|&c| c == 0).collect();
        assert_eq!(strings.len(), 3, "group\\0name\\0");
        assert!(strings[2].is_empty());
        let name = format!(
            "{}.{}",
            std::str::from_utf8(strings[0]).unwrap(),
            std::str::from_utf8(strings[1]).unwrap()
        );
        toc.push((id, ty, name));
    }
    let names: Vec<&str> = toc.iter().map(|t| t.2.as_str()).collect();
    // docs/radio.md's parameters keep ids 0..=6.
    assert_eq!(
        names[..7],
        [
            "mission.start",
            "mission.goalX",
            "mission.goalY",
            "mission.startX",
            "mission.startY",
            "mission.height",
            "mission.speed"
        ]
    );

    // Step 10: read every parameter; length exactly 3 + size, status 0 (cflib's struct.unpack).
    let seed = MissionParams::SEED;
    let expected = [
        Value::U8(0),
        Value::F32(seed.goal_m.0),
        Value::F32(seed.goal_m.1),
        Value::F32(seed.start_m.0),
        Value::F32(seed.start_m.1),
        Value::F32(seed.height_m),
        Value::F32(seed.speed_m_s),
    ];
    for (id, ty, _) in &toc {
        let b = id.to_le_bytes();
        let reply = up(&[0x2D, b[0], b[1]], &mut m).unwrap();
        let size = ParamType::from_param_code(*ty).unwrap().size();
        assert_eq!(reply.len(), 1 + 3 + size);
        assert_eq!(reply[..4], [0x2D, b[0], b[1], 0]);
        let v = Value::from_le(ParamType::from_param_code(*ty).unwrap(), &reply[4..]).unwrap();
        if let Some(want) = expected.get(usize::from(*id)) {
            assert_eq!(v, *want);
        }
    }
    // After fully_connected: set mission.start = 1, echo.
    assert_eq!(up(&hex("2E 00 00 01"), &mut m), Some(hex("2E 00 00 01")));
    assert_eq!(m.store().start, 1);
}

// ---------------------------------------------------------------------------------------------------------
// Refusals (docs/radio.md)
// ---------------------------------------------------------------------------------------------------------

/// Sends a write, checks the echo carries the value in effect, the state is unchanged and the reason (also
/// the mode tests').
pub(super) fn assert_refused(m: &mut Mission, req: &[u8], refusal: Refusal, line: &str) {
    let before = *m.store();
    let id = u16::from_le_bytes([req[1], req[2]]);
    let mut echo = req[..3].to_vec();
    let (bytes, n) = before.read(id).unwrap().to_le();
    echo.extend_from_slice(&bytes[..n]);
    assert_eq!(send(m, req), Some(echo), "echo carries the value in effect");
    assert_eq!(*m.store(), before, "state unchanged");
    let note = m.take_refusal().expect("a refusal is recorded");
    assert_eq!(note, RefusalNote { id, refusal });
    assert_eq!(Mission::console_line(&note).as_str(), line);
    assert!(m.take_refusal().is_none());
}

#[test]
fn goal_outside_the_arena_is_refused() {
    let mut m = service();
    let line = "param mission.goalX refused: goal outside the arena\n";
    assert_refused(&mut m, &write_f32(ID_GOAL_X, 7.0), Refusal::GoalOutsideArena, line);
    assert_refused(&mut m, &write_f32(ID_GOAL_X, -1.0), Refusal::GoalOutsideArena, line);
    assert_refused(&mut m, &write_f32(ID_GOAL_X, f32::NAN), Refusal::GoalOutsideArena, line);
    assert_refused(&mut m, &write_f32(ID_GOAL_X, 5.95), Refusal::GoalOutsideArena, line);
    let line = "param mission.goalY refused: goal outside the arena\n";
    assert_refused(&mut m, &write_f32(ID_GOAL_Y, 3.5), Refusal::GoalOutsideArena, line);
    let line = "param mission.startY refused: start outside the arena\n";
    assert_refused(
        &mut m,
        &write_f32(ID_START_Y, f32::INFINITY),
        Refusal::StartOutsideArena,
        line,
    );
    let line = "param mission.startX refused: start outside the arena\n";
    assert_refused(&mut m, &write_f32(ID_START_X, 0.05), Refusal::StartOutsideArena, line);
    // Inside: accepted.
    let req = write_f32(ID_GOAL_Y, 2.5);
    assert_eq!(send(&mut m, &req), Some(req));
    assert_eq!(m.store().params.goal_m, (5.0, 2.5));
}

#[test]
fn height_below_0_2_and_negative_speed_are_refused() {
    let mut m = service();
    let line = "param mission.height refused: height not in 0.2..2 m\n";
    assert_refused(&mut m, &write_f32(ID_HEIGHT, 0.1), Refusal::BadHeight, line);
    assert_refused(&mut m, &write_f32(ID_HEIGHT, f32::NAN), Refusal::BadHeight, line);
    let line = "param mission.speed refused: speed not in (0, 1] m/s\n";
    assert_refused(&mut m, &write_f32(ID_SPEED, -0.5), Refusal::BadSpeed, line);
    assert_refused(&mut m, &write_f32(ID_SPEED, 0.0), Refusal::BadSpeed, line);
    // Boundaries accepted.
    let req = write_f32(ID_HEIGHT, 0.2);
    assert_eq!(send(&mut m, &req), Some(req));
    let req = write_f32(ID_SPEED, 1.0);
    assert_eq!(send(&mut m, &req), Some(req));
    assert_eq!((m.store().params.height_m, m.store().params.speed_m_s), (0.2, 1.0));
}

/// `mission.linkLoss` (0..2) and `mission.linkTimeout` (0.5..60 s): out-of-range writes refused with the
/// declared range on the console, nothing changed; values in range read back and reach the link-loss config.
#[test]
fn link_loss_parameters_are_bounded() {
    use cfnav::mission::link_loss::LinkLossPolicy;
    use cfnav::radio_binding::param_table::{ID_LINK_LOSS, ID_LINK_TIMEOUT};
    let mut m = service();
    assert_eq!(m.store().read(ID_LINK_LOSS), Some(Value::U8(0)), "default: go on");
    assert_eq!(m.store().read(ID_LINK_TIMEOUT), Some(Value::F32(2.0)), "default: 2 s");
    // `[hdr, id u16, u8]` on 2/2.
    let write_u8 = |v: u8| [&[0x2E][..], &ID_LINK_LOSS.to_le_bytes()[..], &[v][..]].concat();
    let req = write_u8(3);
    assert_refused(
        &mut m,
        &req,
        Refusal::OutOfRange,
        "param mission.linkLoss refused: not in [0, 2]\n",
    );
    let line = "param mission.linkTimeout refused: not in [0.5, 60] s\n";
    assert_refused(&mut m, &write_f32(ID_LINK_TIMEOUT, 0.4), Refusal::OutOfRange, line);
    assert_refused(&mut m, &write_f32(ID_LINK_TIMEOUT, 60.5), Refusal::OutOfRange, line);
    assert_refused(&mut m, &write_f32(ID_LINK_TIMEOUT, f32::NAN), Refusal::OutOfRange, line);
    let req = write_u8(2);
    assert_eq!(send(&mut m, &req), Some(req.clone()));
    let req = write_f32(ID_LINK_TIMEOUT, 0.5);
    assert_eq!(send(&mut m, &req), Some(req));
    let cfg = m.store().link_loss;
    assert_eq!((cfg.policy, cfg.timeout_s), (LinkLossPolicy::ReturnHome, 0.5));
}

#[test]
fn start_while_flying_or_with_a_deck_missing_is_refused() {
    let mut m = service();
    m.store_mut().flying = true;
    let line = "param mission.start refused: start while flying\n";
    assert_refused(&mut m, &hex("2E 00 00 01"), Refusal::StartWhileFlying, line);
    m.store_mut().flying = false;
    m.store_mut().decks_ok = false;
    let line = "param mission.start refused: a deck is missing\n";
    assert_refused(&mut m, &hex("2E 00 00 01"), Refusal::DeckMissing, line);
    m.store_mut().decks_ok = true;
    // Other values than 0/1, a second start.
    let line = "param mission.start refused: start takes 0 or 1\n";
    assert_refused(&mut m, &hex("2E 00 00 02"), Refusal::BadStartValue, line);
    assert_eq!(send(&mut m, &hex("2E 00 00 01")), Some(hex("2E 00 00 01")));
    let line = "param mission.start refused: mission already running\n";
    assert_refused(&mut m, &hex("2E 00 00 01"), Refusal::AlreadyRunning, line);
    // 0 aborts (always accepted), even while flying.
    m.store_mut().flying = true;
    assert_eq!(send(&mut m, &hex("2E 00 00 00")), Some(hex("2E 00 00 00")));
    assert_eq!(m.store().start, 0);
}

#[test]
fn start_validates_the_whole_parameter_set() {
    // A start position made invalid by the firmware (not by a radio write) refuses the start.
    let mut m = service();
    m.store_mut().params.start_m = (9.0, 1.0);
    let line = "param mission.start refused: start outside the arena\n";
    assert_refused(&mut m, &hex("2E 00 00 01"), Refusal::StartOutsideArena, line);
    let mut m = service();
    m.store_mut().capacity_cells = 10;
    let line = "param mission.start refused: arena too large for the map\n";
    assert_refused(&mut m, &hex("2E 00 00 01"), Refusal::BadArena, line);
}

#[test]
fn refusal_queue_is_bounded() {
    let mut m = service();
    for _ in 0..6 {
        send(&mut m, &write_f32(ID_HEIGHT, 0.1));
    }
    assert_eq!(m.dropped_refusals(), 2);
    let mut n = 0;
    while m.take_refusal().is_some() {
        n += 1;
    }
    assert_eq!(n, 4);
}

// ---------------------------------------------------------------------------------------------------------
// Misc channel: set-by-name, extended type, VALUE_UPDATED
// ---------------------------------------------------------------------------------------------------------

fn set_by_name(group: &str, name: &str, ty: u8, value: &[u8]) -> Vec<u8> {
    let mut out = vec![0x2F, 0x00];
    out.extend_from_slice(group.as_bytes());
    out.push(0);
    out.extend_from_slice(name.as_bytes());
    out.push(0);
    out.push(ty);
    out.extend_from_slice(value);
    out
}

fn set_by_name_reply(group: &str, name: &str, err: u8) -> Vec<u8> {
    let mut out = vec![0x2F, 0x00];
    out.extend_from_slice(group.as_bytes());
    out.push(0);
    out.extend_from_slice(name.as_bytes());
    out.push(0);
    out.push(err);
    out
}

#[test]
fn set_by_name_sets_refuses_and_reports() {
    let mut m = service();
    // Success: err 0.
    let reply = send(&mut m, &set_by_name("mission", "height", 0x06, &f32_le(1.25)));
    assert_eq!(reply, Some(set_by_name_reply("mission", "height", 0)));
    assert_eq!(m.store().params.height_m, 1.25);
    assert_eq!(
        send(&mut m, &set_by_name("mission", "start", 0x08, &[1])),
        Some(set_by_name_reply("mission", "start", 0))
    );
    assert_eq!(m.store().start, 1);
    let before = *m.store();
    // Unknown name: ENOENT.
    assert_eq!(
        send(&mut m, &set_by_name("mission", "nope", 0x06, &f32_le(1.0))),
        Some(set_by_name_reply("mission", "nope", ENOENT))
    );
    // Type mismatch: EINVAL.
    assert_eq!(
        send(&mut m, &set_by_name("mission", "height", 0x08, &[1])),
        Some(set_by_name_reply("mission", "height", EINVAL))
    );
    // Wrong value size: EINVAL.
    assert_eq!(
        send(&mut m, &set_by_name("mission", "height", 0x06, &[0, 0])),
        Some(set_by_name_reply("mission", "height", EINVAL))
    );
    assert!(m.take_refusal().is_none());
    // Refused value: EINVAL, and the console reason.
    assert_eq!(
        send(&mut m, &set_by_name("mission", "speed", 0x06, &f32_le(-1.0))),
        Some(set_by_name_reply("mission", "speed", EINVAL))
    );
    assert_eq!(
        m.take_refusal(),
        Some(RefusalNote {
            id: ID_SPEED,
            refusal: Refusal::BadSpeed
        })
    );
    // Truncated: fewer than two NULs, or no type byte: no reply.
    assert_eq!(send(&mut m, &hex("2F 00")), None);
    assert_eq!(send(&mut m, b"\x2F\x00mission\x00height"), None);
    assert_eq!(send(&mut m, b"\x2F\x00mission\x00height\x00"), None);
    assert_eq!(*m.store(), before);

    // Read-only: EACCES.
    let mut s = ParamService::new(TestStore::new());
    let before = *s.store();
    assert_eq!(
        send(&mut s, &set_by_name("fw", "rev", 0x0A, &[1, 2, 3, 4])),
        Some(set_by_name_reply("fw", "rev", EACCES))
    );
    // The flag bits in the type byte are ignored when comparing types.
    assert_eq!(
        send(&mut s, &set_by_name("t", "u32", 0x1A, &[1, 0, 0, 0])),
        Some(set_by_name_reply("t", "u32", 0))
    );
    assert_ne!(*s.store(), before);
    assert_eq!(s.store().v[2], Some(Value::U32(1)));
}

#[test]
fn extended_type_v2() {
    let mut s = ParamService::new(TestStore::new());
    // `[7, id u16]` → `[7, id u16, 0, ext_type]` (docs/hardware.md §4; docs/radio.md, connect sequence).
    assert_eq!(send(&mut s, &hex("2F 07 02 00")), Some(hex("2F 07 02 00 00 01")));
    assert_eq!(send(&mut s, &hex("2F 07 00 00")), Some(hex("2F 07 00 00 00 00")));
    assert_eq!(send(&mut s, &hex("2F 07 09 00")), Some(hex("2F 07 09 00 02")));
    assert_eq!(send(&mut s, &hex("2F 07 00")), None);
    // Unknown misc commands, VALUE_UPDATED sent uplink: no reply.
    assert_eq!(send(&mut s, &hex("2F 01 00 00 05")), None);
    // Misc 5 is persistent_clear: a store without persistence answers ENOENT, as stock for a non-persistent id.
    assert_eq!(send(&mut s, &hex("2F 05 00 00")), Some(hex("2F 05 00 00 02")));
    // Default value: the test store declares none (ENOENT, v1 and v2 layouts).
    assert_eq!(send(&mut s, &hex("2F 08 00 00")), Some(hex("2F 08 00 00 02")));
    assert_eq!(send(&mut s, &hex("2F 06 00 00")), Some(hex("2F 06 00 00 02")));
    assert_eq!(send(&mut s, &hex("2F")), None);
}

#[test]
fn firmware_changes_queue_value_updated() {
    let mut router: Router<4> = Router::new(PlatformService::new("cfnav-test"));
    let mut m = service();
    assert_eq!(send(&mut m, &hex("2E 00 00 01")), Some(hex("2E 00 00 01")));
    // The mission ends: the firmware puts mission.start back to 0 and announces it.
    m.store_mut().start = 0;
    assert!(m.notify(ID_START));
    assert!(m.notify(ID_START), "already queued: not twice");
    m.store_mut().params.goal_m.0 = 3.0;
    assert!(m.notify(ID_GOAL_X));
    assert!(!m.notify(PARAM_TABLE.len() as u16), "unknown id");
    // `[1, id u16, value]` on 2/3 (docs/radio.md "Firmware-side param change").
    let p = m.next_notification().unwrap();
    assert_eq!(wire(&p), hex("2F 01 00 00 00"));
    router.enqueue(p).unwrap();
    let p = m.next_notification().unwrap();
    let mut expected = hex("2F 01 01 00");
    expected.extend_from_slice(&f32_le(3.0));
    assert_eq!(wire(&p), expected);
    assert_eq!(m.next_notification(), None);
    // It rides down on the next uplink (a null packet here).
    assert_eq!(
        router.handle_uplink(&[0xFF], &mut [&mut m]).map(|p| wire(&p)),
        Some(hex("2F 01 00 00 00"))
    );
    // The queue holds 8 distinct ids.
    let mut s = ParamService::new(TestStore::new());
    for id in 0..9 {
        assert_eq!(s.notify(id), id < 8);
    }
}

// ---------------------------------------------------------------------------------------------------------
// CRC and values
// ---------------------------------------------------------------------------------------------------------

/// A log-TOC CRC as the stock firmware computes one (log.c L185-210): CRC-32 chained over each entry's type
/// and name, no seed.
fn stock_style_crc(table: &[ParamEntry]) -> u32 {
    let mut crc = 0u32;
    for e in table {
        crc = crc32_update(crc ^ 0xFFFF_FFFF, &[e.type_byte()]) ^ 0xFFFF_FFFF;
        crc = crc32_update(crc ^ 0xFFFF_FFFF, e.name.as_bytes()) ^ 0xFFFF_FFFF;
    }
    crc
}

/// A log CRC with our layout but without the param seed (or with a log seed).
fn layout_crc(seed: &[u8], table: &[ParamEntry]) -> u32 {
    let mut crc = crc32_update(0xFFFF_FFFF, seed);
    for e in table {
        crc = crc32_update(crc, &[e.type_byte()]);
        crc = crc32_update(crc, e.group.as_bytes());
        crc = crc32_update(crc, &[0]);
        crc = crc32_update(crc, e.name.as_bytes());
        crc = crc32_update(crc, &[0]);
    }
    crc ^ 0xFFFF_FFFF
}

#[test]
fn crc32_check_value_and_algorithm() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
    assert_eq!(toc_crc(PARAM_TABLE), layout_crc(PARAM_CRC_SEED, PARAM_TABLE));
    assert_eq!(toc_crc(&[]), crc32(PARAM_CRC_SEED));
}

#[test]
fn crc_changes_when_the_table_changes_and_differs_from_a_log_crc() {
    let base = toc_crc(PARAM_TABLE);
    let mut variants: Vec<Vec<ParamEntry>> = Vec::new();
    let renamed = {
        let mut t = PARAM_TABLE.to_vec();
        t[1] = ParamEntry::new("mission", "goalx", ParamType::F32, 0);
        t
    };
    variants.push(renamed);
    let regrouped = {
        let mut t = PARAM_TABLE.to_vec();
        t[6] = ParamEntry::new("mission2", "speed", ParamType::F32, 0);
        t
    };
    variants.push(regrouped);
    let retyped = {
        let mut t = PARAM_TABLE.to_vec();
        t[0] = ParamEntry::new("mission", "start", ParamType::U16, 0);
        t
    };
    variants.push(retyped);
    let flagged = {
        let mut t = PARAM_TABLE.to_vec();
        t[0] = ParamEntry::new("mission", "start", ParamType::U8, FLAG_READ_ONLY);
        t
    };
    variants.push(flagged);
    let reordered = {
        let mut t = PARAM_TABLE.to_vec();
        t.swap(1, 2);
        t
    };
    variants.push(reordered);
    // Moving a character between group and name (the NUL separators keep these apart).
    variants.push(vec![ParamEntry::new("ab", "c", ParamType::U8, 0)]);
    variants.push(vec![ParamEntry::new("a", "bc", ParamType::U8, 0)]);
    let mut added = PARAM_TABLE.to_vec();
    added.push(ParamEntry::new("mission", "extra", ParamType::U8, 0));
    variants.push(added);
    variants.push(PARAM_TABLE[..6].to_vec());
    variants.push(Vec::new());
    let mut crcs = vec![base];
    for v in &variants {
        crcs.push(toc_crc(v));
    }
    let mut unique = crcs.clone();
    unique.sort_unstable();
    unique.dedup();
    assert_eq!(
        unique.len(),
        crcs.len(),
        "every table change changes the CRC: {crcs:08X?}"
    );
    // Same table, same CRC (it is a pure function of the table).
    let copy = PARAM_TABLE.to_vec();
    assert_eq!(toc_crc(&copy), base);

    // The log TOC's CRC for the very same entries must differ (cflib's cache key, docs/radio.md).
    for table in [PARAM_TABLE, TEST_TABLE, TRACE_TABLE] {
        let p = toc_crc(table);
        assert_ne!(p, stock_style_crc(table));
        assert_ne!(p, layout_crc(b"", table));
        assert_ne!(p, layout_crc(b"cfnav/log-toc/v1", table));
    }
}

#[test]
fn values_round_trip_with_their_type_codes() {
    let values = [
        (Value::U8(0xAB), 0x08, 1),
        (Value::U16(0xABCD), 0x09, 2),
        (Value::U32(0x89AB_CDEF), 0x0A, 4),
        (Value::I8(-5), 0x00, 1),
        (Value::I16(-1234), 0x01, 2),
        (Value::I32(-123_456), 0x02, 4),
        (Value::F32(-2.5), 0x06, 4),
    ];
    for (v, code, size) in values {
        assert_eq!(v.ty().param_code(), code);
        assert_eq!(v.ty().size(), size);
        assert_eq!(ParamType::from_param_code(code), Some(v.ty()));
        assert_eq!(ParamType::from_param_code(code | 0x50), Some(v.ty()));
        let (bytes, n) = v.to_le();
        assert_eq!(n, size);
        assert_eq!(Value::from_le(v.ty(), &bytes[..n]), Some(v));
        assert_eq!(Value::from_le(v.ty(), &bytes[..n - 1]), None);
        assert_eq!(Value::from_le(v.ty(), &bytes[..]).is_some(), size == 4);
    }
    for code in [0x03, 0x04, 0x05, 0x07, 0x0B, 0x0C, 0x0F] {
        assert_eq!(ParamType::from_param_code(code), None);
    }
}

#[test]
fn mission_store_rejects_wrong_types_and_ids_directly() {
    let mut s = MissionParamState::new(MissionParams::SEED, CAPACITY);
    let before = s;
    assert_eq!(s.write(ID_START, Value::F32(1.0)), Err(Refusal::WrongType));
    assert_eq!(s.write(ID_HEIGHT, Value::U8(1)), Err(Refusal::WrongType));
    let past = PARAM_TABLE.len() as u16;
    assert_eq!(s.write(past, Value::F32(1.0)), Err(Refusal::UnknownId));
    assert_eq!(s.write(past, Value::U8(1)), Err(Refusal::UnknownId));
    assert_eq!(s.read(past), None);
    // Read-only declarations refuse every write (deck.bcFlow2 is id 8).
    assert_eq!(s.write(8, Value::U8(1)), Err(Refusal::ReadOnly));
    assert_eq!(s, before);
}

// ---------------------------------------------------------------------------------------------------------
// Random bytes
// ---------------------------------------------------------------------------------------------------------

/// True if `p` is a well-formed write that may legitimately change the state: 2/2 with a known, writable id
/// and exactly the value's size, or a set-by-name naming a writable entry with its type and size.
fn may_change<S: ParamStore>(p: &CrtpPacket) -> bool {
    let d = &p.data;
    match p.channel {
        2 if d.len() >= 2 => {
            let id = usize::from(u16::from_le_bytes([d[0], d[1]]));
            S::TABLE
                .get(id)
                .is_some_and(|e| !e.read_only() && d.len() == 2 + e.ty.size())
        }
        3 if d.first() == Some(&0) => {
            let mut parts = d[1..].splitn(3, |&c| c == 0);
            let (Some(g), Some(n), Some(rest)) = (parts.next(), parts.next(), parts.next()) else {
                return false;
            };
            S::TABLE.iter().any(|e| {
                e.group.as_bytes() == g
                    && e.name.as_bytes() == n
                    && !e.read_only()
                    && rest.first().and_then(|&t| ParamType::from_param_code(t)) == Some(e.ty)
                    && rest.len() == 1 + e.ty.size()
            })
        }
        _ => false,
    }
}

fn random_packet(rng: &mut SmallRng, names: &[&[u8]]) -> CrtpPacket {
    let channel = rng.random_range(0..4u8);
    let len = rng.random_range(0..=30usize);
    let mut data: Vec<u8> = (0..len)
        .map(|_| {
            if rng.random_bool(0.5) {
                rng.random_range(0..12)
            } else {
                rng.random()
            }
        })
        .collect();
    // Sometimes a plausible set-by-name prefix.
    if channel == 3 && rng.random_bool(0.3) {
        let name = names[rng.random_range(0..names.len())];
        let mut d = vec![0];
        d.extend_from_slice(name);
        d.extend_from_slice(&data);
        d.truncate(30);
        data = d;
    }
    CrtpPacket::new(2, channel, &data).unwrap()
}

fn fuzz<S: ParamStore + Clone + PartialEq + core::fmt::Debug>(store: S, seed: u64, names: &[&[u8]]) -> usize {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut s = ParamService::new(store);
    let mut changed = 0;
    for _ in 0..50_000 {
        let p = random_packet(&mut rng, names);
        let before = s.store().clone();
        let reply = s.handle(&p);
        if let Some(r) = &reply {
            assert_eq!(r.port, 2);
            assert_eq!(r.channel, p.channel);
            assert!(r.data.len() <= 30);
        }
        if *s.store() != before {
            assert!(may_change::<S>(&p), "malformed {p:?} changed the state");
            changed += 1;
        }
        while s.take_refusal().is_some() {}
    }
    changed
}

#[test]
fn random_bytes_never_panic_and_malformed_input_never_changes_state() {
    let mission_names: Vec<&[u8]> = vec![
        b"mission\0start\0\x08",
        b"mission\0height\0\x06",
        b"mission\0goalX\0\x06",
    ];
    let test_names: Vec<&[u8]> = vec![b"t\0u8\0\x08", b"t\0i16\0\x01", b"fw\0rev\0\x0A"];
    let mut changed = 0;
    for seed in 0..4 {
        changed += fuzz(
            MissionParamState::new(MissionParams::SEED, CAPACITY),
            seed,
            &mission_names,
        );
        changed += fuzz(TestStore::new(), seed, &test_names);
    }
    // The loop does exercise accepted writes too.
    assert!(changed > 100, "{changed}");
    // Raw bytes through the router: any length, any header.
    let mut router: Router<2> = Router::new(PlatformService::new("x"));
    let mut m = service();
    let before = *m.store();
    let mut rng = SmallRng::seed_from_u64(99);
    for _ in 0..20_000 {
        let len = rng.random_range(0..40usize);
        let mut bytes: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        if let Some(h) = bytes.first_mut() {
            // Port 2, channels 0, 1 and 3 only: nothing here may write.
            *h = 0x20 | (*h & 0x0C) | [0, 1, 3][rng.random_range(0..3)];
        }
        let _ = router.handle_uplink(&bytes, &mut [&mut m]);
        while m.take_refusal().is_some() {}
    }
    // Random bytes on channels 0, 1 and 3 never name a parameter with its exact type and size here (the seeded
    // loop above checks such packets with `may_change`): the state is unchanged.
    assert_eq!(*m.store(), before);
}
