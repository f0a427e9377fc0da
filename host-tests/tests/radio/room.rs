//! The room as parameters: `mission.arenaX`, `mission.arenaY` (float, m) and `mission.walls` (uint8
//! bitmask), appended to the table, persistent, checked against the map's capacity with the other side in
//! effect; a refused write leaves the value in effect, which the echo carries, and queues a console line.

use super::send;
use cfnav::mission::{ALL_WALLS, MissionParams, WALL_NORTH, WALL_SOUTH};
use cfnav::nav::map::{CELL_SIZE_M, GridShape};
use cfnav::radio::param::ParamService;
use cfnav::radio::param_decl::{ParamStore, Refusal};
use cfnav::radio::toc::Value;
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::{ID_ARENA_X, ID_ARENA_Y, ID_FW_MODIFIED, ID_WALLS, PARAM_TABLE};
use cfnav::system::persistent_params::{PersistentParams, SLOT_LEN};

type Svc = ParamService<MissionParamState>;

/// 128 × 64 cells: 8 192.
const CAPACITY: usize = 128 * 64;

fn service() -> Svc {
    ParamService::new(MissionParamState::new(MissionParams::SEED, CAPACITY))
}

fn write_f32(id: u16, v: f32) -> Vec<u8> {
    let mut b = vec![0x2E];
    b.extend_from_slice(&id.to_le_bytes());
    b.extend_from_slice(&v.to_le_bytes());
    b
}

fn write_u8(id: u16, v: u8) -> Vec<u8> {
    let mut b = vec![0x2E];
    b.extend_from_slice(&id.to_le_bytes());
    b.push(v);
    b
}

/// The write is refused: the echo carries the value in effect, the state is unchanged, one console line.
fn refused(s: &mut Svc, req: &[u8], refusal: Refusal, line: &str) {
    let before = *s.store();
    let id = u16::from_le_bytes([req[1], req[2]]);
    let (bytes, n) = before.read(id).unwrap().to_le();
    let mut echo = req[..3].to_vec();
    echo.extend_from_slice(&bytes[..n]);
    assert_eq!(send(s, req), Some(echo), "echo of the value in effect");
    assert_eq!(*s.store(), before);
    let note = s.take_refusal().expect("a refusal note");
    assert_eq!(note.refusal, refusal);
    assert_eq!(Svc::console_line(&note).as_str(), line);
    assert!(s.take_refusal().is_none());
}

#[test]
fn appended_after_every_older_parameter_persistent_with_the_seed_defaults() {
    // The three ids follow the last parameter of the table before them, in this order.
    assert_eq!(
        (ID_ARENA_X, ID_ARENA_Y, ID_WALLS),
        (ID_FW_MODIFIED + 1, ID_FW_MODIFIED + 2, ID_FW_MODIFIED + 3)
    );
    assert_eq!(usize::from(ID_WALLS), PARAM_TABLE.len() - 1);
    for id in [ID_ARENA_X, ID_ARENA_Y, ID_WALLS] {
        let e = &PARAM_TABLE[usize::from(id)];
        assert!(e.is_persistent() && !e.read_only(), "{}.{}", e.group, e.name);
    }
    let s = service();
    assert_eq!(s.store().read(ID_ARENA_X), Some(Value::F32(6.0)));
    assert_eq!(s.store().read(ID_ARENA_Y), Some(Value::F32(3.0)));
    assert_eq!(s.store().read(ID_WALLS), Some(Value::U8(15)));
    assert_eq!(s.store().default_value(ID_WALLS), Some(Value::U8(ALL_WALLS)));
}

#[test]
fn accepted_writes_land_in_the_mission_parameters() {
    let mut s = service();
    for req in [
        write_f32(ID_ARENA_X, 4.0),
        write_f32(ID_ARENA_Y, 4.0),
        write_u8(ID_WALLS, WALL_SOUTH | WALL_NORTH),
    ] {
        assert_eq!(
            send(&mut s, &req),
            Some(req.clone()),
            "accepted: the echo is the value written"
        );
    }
    assert!(s.take_refusal().is_none());
    let p = s.store().params;
    assert_eq!((p.arena_m, p.walls), ((4.0, 4.0), 5));
    // The bounds of the walls: 0 (an open floor) and 15.
    for v in [0, 15] {
        let req = write_u8(ID_WALLS, v);
        assert_eq!(send(&mut s, &req), Some(req));
    }
    // A start takes them (the endpoint hands `params` to the flight core).
    s.store_mut().params.goal_m = (3.0, 3.0);
    assert_eq!(send(&mut s, &[0x2E, 0, 0, 1]), Some(vec![0x2E, 0, 0, 1]));
    assert_eq!(s.store().params.arena_m, (4.0, 4.0));
}

#[test]
fn out_of_range_or_unmappable_rooms_are_refused_with_a_console_line() {
    let mut s = service();
    refused(
        &mut s,
        &write_u8(ID_WALLS, 16),
        Refusal::OutOfRange,
        "param mission.walls refused: not in [0, 15]\n",
    );
    let line_x = "param mission.arenaX refused: arena too large for the map\n";
    let line_y = "param mission.arenaY refused: arena too large for the map\n";
    for bad in [f32::NAN, f32::INFINITY, -1.0, 0.0, 0.01] {
        refused(&mut s, &write_f32(ID_ARENA_X, bad), Refusal::BadArena, line_x);
    }
    // The oracle: whether GridShape holds the arena at 5 cm cells within the capacity.
    assert!(GridShape::for_arena(7.0, 3.0, CAPACITY).is_none() && 140 * 60 > CAPACITY);
    refused(&mut s, &write_f32(ID_ARENA_X, 7.0), Refusal::BadArena, line_x);
    refused(&mut s, &write_f32(ID_ARENA_Y, 4.5), Refusal::BadArena, line_y);
    // The same x fits once y has shrunk: each side is checked against the other in effect.
    assert!(GridShape::for_arena(7.0, 2.0, CAPACITY).is_some());
    for req in [write_f32(ID_ARENA_Y, 2.0), write_f32(ID_ARENA_X, 7.0)] {
        assert_eq!(send(&mut s, &req), Some(req.clone()));
    }
    // Largest x at y = 2 m: 8 192 / 40 rows = 204 columns (10.2 m); 205 is refused.
    let x = 204.0 * CELL_SIZE_M;
    let req = write_f32(ID_ARENA_X, x);
    assert_eq!(send(&mut s, &req), Some(req));
    refused(
        &mut s,
        &write_f32(ID_ARENA_X, 205.0 * CELL_SIZE_M),
        Refusal::BadArena,
        line_x,
    );
}

#[test]
fn the_room_cannot_change_under_a_running_mission() {
    let mut s = service();
    assert_eq!(send(&mut s, &[0x2E, 0, 0, 1]), Some(vec![0x2E, 0, 0, 1]));
    let line = "param mission.arenaX refused: mission already running\n";
    refused(&mut s, &write_f32(ID_ARENA_X, 4.0), Refusal::AlreadyRunning, line);
    let line = "param mission.walls refused: mission already running\n";
    refused(&mut s, &write_u8(ID_WALLS, 3), Refusal::AlreadyRunning, line);
}

/// The EEPROM a test keeps: the service's pending write copied in.
fn finish_write(s: &mut Svc, eeprom: &mut [u8]) {
    let w = *s.eeprom_write().expect("a write waits");
    let at = usize::from(w.address()) - 0x400;
    eeprom[at..at + SLOT_LEN].copy_from_slice(w.bytes());
    assert_eq!(s.eeprom_write_done(true).map(|p| p.data[3]), Some(0), "stored");
}

#[test]
fn a_stored_room_comes_back_at_boot_whatever_order_its_records_are_in() {
    let mut s = service();
    let mut eeprom = vec![0xFFu8; 2 * SLOT_LEN];
    // 9 × 2 m fits (180 × 40 cells), 9 × 3 m does not: x is stored first, so at boot it meets the default
    // y = 3 m before the stored y = 2 m is applied.
    for req in [
        write_f32(ID_ARENA_Y, 2.0),
        write_f32(ID_ARENA_X, 9.0),
        write_u8(ID_WALLS, 7),
    ] {
        assert_eq!(send(&mut s, &req), Some(req.clone()));
    }
    for id in [ID_ARENA_X, ID_ARENA_Y, ID_WALLS] {
        let b = id.to_le_bytes();
        assert_eq!(send(&mut s, &[0x2F, 3, b[0], b[1]]), None, "answered once written");
        finish_write(&mut s, &mut eeprom);
    }
    let (stored, _) = PersistentParams::load(&eeprom);
    let keys: Vec<u32> = stored.records().map(|r| r.key).collect();
    assert_eq!(keys.len(), 3);
    let mut rebooted = service();
    let summary = rebooted.load_persistent(stored);
    assert_eq!((summary.applied, summary.unknown, summary.refused), (3, 0, 0));
    assert!(rebooted.take_refusal().is_none(), "no console line for the retried x");
    let p = rebooted.store().params;
    assert_eq!((p.arena_m, p.walls), ((9.0, 2.0), 7));
    // A stored room the map cannot hold (a smaller build) is refused with its line, the defaults stay.
    let (stored, _) = PersistentParams::load(&eeprom);
    let mut small = ParamService::new(MissionParamState::new(MissionParams::SEED, 100 * 60));
    let summary = small.load_persistent(stored);
    assert_eq!((summary.applied, summary.refused), (2, 1));
    assert_eq!(small.store().params.arena_m, (6.0, 2.0));
    let note = small.take_refusal().unwrap();
    assert_eq!(
        Svc::console_line(&note).as_str(),
        "param mission.arenaX refused: arena too large for the map\n"
    );
}
