//! The map memory on port 4 (`radio::mem`, `radio::map_mem`): the memory protocol's packets as cflib 0.1.34
//! and the stock `crtp_mem.c` lay them out, and the map's byte layout checked against a decoder written here
//! from the documented offsets (not the serialiser's code) and against the grid's own queries.

use cfnav::nav::grid::{ChangedCells, OccupancyGrid};
use cfnav::nav::map::{Cell, GridShape};
use cfnav::radio::crtp::CrtpPacket;
use cfnav::radio::mem::{MAP_MEMORY_TYPE, MemService, STATUS_EIO};
use cfnav::radio_binding::map_mem::{
    Crc32, MAX_PADS, MAX_PATH_POINTS, MapReadError, MapView, PadKind, PadRecord, map_memory_size,
};
use proptest::prelude::*;

use super::{hex, send, wire};

const CELLS: usize = 40 * 30;

/// zlib's `crc32`, table-driven (a different algorithm from the bitwise one under test).
fn zlib_crc32(bytes: &[u8]) -> u32 {
    let mut table = [0u32; 256];
    for (n, t) in table.iter_mut().enumerate() {
        let mut c = n as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
        *t = c;
    }
    let mut c = !0u32;
    for &b in bytes {
        c = table[((c ^ u32::from(b)) & 0xFF) as usize] ^ (c >> 8);
    }
    !c
}

/// A 40 × 30 grid with a wall segment, a freed disc and some unknown rest; a 5-point path; two pads.
fn sample_grid() -> OccupancyGrid<CELLS> {
    let mut g = OccupancyGrid::<CELLS>::new();
    assert!(g.reset(GridShape::new(40, 30, CELLS).unwrap(), 2));
    let mut changed = ChangedCells::<4096>::new();
    g.mark_free_disc((1.0, 0.75), 0.4, &mut changed);
    for y in 5..20 {
        g.set_occupied(Cell::new(25, y), &mut changed);
    }
    g
}

const PATH: [Cell; 5] = [
    Cell::new(3, 3),
    Cell::new(10, 4),
    Cell::new(20, 22),
    Cell::new(30, 25),
    Cell::new(38, 28),
];

fn pads() -> [Option<PadRecord>; MAX_PADS] {
    [
        Some(PadRecord {
            x_m: 1.75,
            y_m: 1.25,
            confidence: 0.5,
            kind: PadKind::Estimate,
            locked: false,
        }),
        None,
        Some(PadRecord {
            x_m: 0.25,
            y_m: -0.5,
            confidence: 1.0,
            kind: PadKind::HomeLock,
            locked: true,
        }),
    ]
}

/// The whole memory, read as cflib does: 24-byte chunks from 0.
fn download<const C: usize>(view: &MapView<'_, C>) -> Vec<u8> {
    let size = view.size();
    let mut out = vec![0u8; size];
    for start in (0..size).step_by(24) {
        let end = (start + 24).min(size);
        view.read(start as u32, &mut out[start..end]).unwrap();
    }
    out
}

/// The 2-bit code the docs define, from the grid's queries.
fn expected_code(g: &OccupancyGrid<CELLS>, c: Cell) -> u8 {
    if g.is_occupied(c) {
        3
    } else if g.is_blocked(c) {
        2
    } else if g.is_unknown(c) {
        0
    } else {
        1
    }
}

#[test]
fn crc32_matches_the_standard_check_value() {
    let mut c = Crc32::new();
    for &b in b"123456789" {
        c.update(b);
    }
    assert_eq!(c.finish(), 0xCBF4_3926);
    assert_eq!(zlib_crc32(b"123456789"), 0xCBF4_3926);
}

#[test]
fn the_layout_decodes_from_the_documented_offsets_to_the_grid_path_and_pads() {
    let g = sample_grid();
    let view = MapView::new(&g, &PATH, pads(), 11, true);
    let b = download(&view);
    assert_eq!(b.len(), map_memory_size(CELLS));
    assert_eq!(&b[0..4], b"CFNM");
    assert_eq!((b[4], b[5], b[6], b[7]), (1, 32, 2, 11));
    let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
    let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    let total = u32_at(12) as usize;
    assert_eq!(total, 32 + 300 + 5 * 4 + 2 * 12);
    assert_eq!((u16_at(16), u16_at(18), u16_at(20)), (40, 30, 50));
    assert_eq!((u16_at(22), u16_at(24)), (0, 0), "origin");
    assert_eq!((u16_at(26), b[28], b[29]), (5, 2, 1));
    assert_eq!(u32_at(8), zlib_crc32(&b[12..total]));
    assert!(b[total..].iter().all(|&x| x == 0), "unused bytes read 0");

    let mut seen = [0usize; 4];
    for i in 0..1200 {
        let code = (b[32 + i / 4] >> (2 * (i % 4))) & 3;
        let c = Cell::new((i % 40) as u16, (i / 40) as u16);
        assert_eq!(code, expected_code(&g, c), "cell {c:?}");
        seen[code as usize] += 1;
    }
    assert!(seen.iter().all(|&n| n > 0), "every code occurs: {seen:?}");
    assert_eq!(seen[3], 15, "the wall segment");

    let path_at = 32 + 300;
    for (k, c) in PATH.iter().enumerate() {
        assert_eq!((u16_at(path_at + 4 * k), u16_at(path_at + 4 * k + 2)), (c.x, c.y));
    }
    let pad_at = path_at + 20;
    let f32_at = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    assert_eq!((f32_at(pad_at), f32_at(pad_at + 4)), (1.75, 1.25));
    assert_eq!(
        &b[pad_at + 8..pad_at + 12],
        &[128, 0, 0, 0],
        "confidence 0.5 → 128, estimate"
    );
    assert_eq!((f32_at(pad_at + 12), f32_at(pad_at + 16)), (0.25, -0.5));
    assert_eq!(&b[pad_at + 20..pad_at + 24], &[255, 2, 1, 0], "home lock, locked");
}

#[test]
fn a_change_between_header_and_body_is_caught_by_the_crc() {
    let mut g = sample_grid();
    let header = {
        let view = MapView::new(&g, &PATH, pads(), 11, true);
        let mut h = [0u8; 24];
        view.read(0, &mut h).unwrap();
        h
    };
    let mut changed = ChangedCells::<4096>::new();
    g.set_occupied(Cell::new(2, 28), &mut changed);
    let view = MapView::new(&g, &PATH, pads(), 11, true);
    let mut b = download(&view);
    b[..24].copy_from_slice(&header);
    let total = u32::from_le_bytes([b[12], b[13], b[14], b[15]]) as usize;
    let stored = u32::from_le_bytes([b[8], b[9], b[10], b[11]]);
    assert_ne!(stored, zlib_crc32(&b[12..total]), "the mixed download is detected");
    // Read again: consistent.
    let b = download(&view);
    let stored = u32::from_le_bytes([b[8], b[9], b[10], b[11]]);
    assert_eq!(stored, zlib_crc32(&b[12..total]));
}

#[test]
fn an_empty_grid_and_an_overlong_path_are_served() {
    let g = OccupancyGrid::<CELLS>::new();
    let long: Vec<Cell> = (0..100).map(|i| Cell::new(i, i)).collect();
    let view = MapView::new(&g, &long, [None; MAX_PADS], 0, false);
    let b = download(&view);
    let total = u32::from_le_bytes([b[12], b[13], b[14], b[15]]) as usize;
    assert_eq!(total, 32 + MAX_PATH_POINTS * 4);
    assert_eq!((b[16], b[18], b[26], b[28], b[29]), (0, 0, MAX_PATH_POINTS as u8, 0, 2));
    assert_eq!(u16::from_le_bytes([b[32 + 4 * 63], b[33 + 4 * 63]]), 63);
}

#[test]
fn without_the_map_no_memory_is_listed_and_reads_and_writes_are_refused() {
    let mut m = MemService::new();
    assert_eq!(send(&mut m, &hex("4C 01")), Some(hex("4C 01 00")));
    assert_eq!(send(&mut m, &hex("4C 02 00")), None);
    // Read memory 0, addr 0x10, 4 bytes → [id, addr, EIO].
    assert_eq!(
        send(&mut m, &hex("4D 00 10 00 00 00 04")),
        Some(hex("4D 00 10 00 00 00 05"))
    );
    assert_eq!(
        send(&mut m, &hex("4E 00 10 00 00 00 AA")),
        Some(hex("4E 00 10 00 00 00 05"))
    );
    assert_eq!(m.take_map_read(), None);
    // Short packets get nothing.
    assert_eq!(send(&mut m, &hex("4D 00 10")), None);
    assert_eq!(send(&mut m, &hex("4C")), None);
}

#[test]
fn with_the_map_cflib_lists_it_and_its_reads_are_answered_from_the_view() {
    let mut m = MemService::with_map(CELLS);
    assert_eq!(send(&mut m, &hex("4C 01")), Some(hex("4C 01 01")));
    // GET_INFO: [2, id, type, size u32 LE, 8 serial bytes] (crtp_mem.c createInfoResponse).
    let size = map_memory_size(CELLS) as u32;
    let mut info = vec![0x4C, 2, 0, MAP_MEMORY_TYPE];
    info.extend_from_slice(&size.to_le_bytes());
    info.extend_from_slice(&[0; 8]);
    assert_eq!(send(&mut m, &hex("4C 02 00")), Some(info));
    assert_eq!(send(&mut m, &hex("4C 02 01")), None, "no memory 1");

    let g = sample_grid();
    let view = MapView::new(&g, &PATH, pads(), 11, true);
    let all = download(&view);
    // cflib `_ReadRequest`: `<BIB` id, addr, len; the reply `[id, addr, 0, data…]`.
    assert_eq!(send(&mut m, &hex("4D 00 28 00 00 00 18")), None, "held for the owner");
    let read = m.take_map_read().unwrap();
    assert_eq!((read.addr, read.len), (0x28, 24));
    let mut expect = hex("4D 00 28 00 00 00 00");
    expect.extend_from_slice(&all[0x28..0x28 + 24]);
    assert_eq!(wire(&read.answer(&view)), expect);
    assert_eq!(m.take_map_read(), None, "taken once");

    // Past the end, or longer than 24 bytes: EIO, no data.
    let past = size - 2;
    send(&mut m, &[0x4D, 0, past as u8, (past >> 8) as u8, 0, 0, 4]);
    let r = wire(&m.take_map_read().unwrap().answer(&view));
    assert_eq!(r.len(), 7);
    assert_eq!(r[6], STATUS_EIO);
    send(&mut m, &hex("4D 00 00 00 00 00 19"));
    let r = wire(&m.take_map_read().unwrap().answer(&view));
    assert_eq!(r, hex("4D 00 00 00 00 00 05"));
    // Other memory ids and writes: EIO at once.
    assert_eq!(
        send(&mut m, &hex("4D 03 00 00 00 00 04")),
        Some(hex("4D 03 00 00 00 00 05"))
    );
    assert_eq!(
        send(&mut m, &hex("4E 00 00 00 00 00 01 02")),
        Some(hex("4E 00 00 00 00 00 05"))
    );
}

proptest! {
    /// Any address and length: no panic; an accepted read is exactly that slice of the whole memory; a
    /// refused one is `EIO` with no data, and only when it is too long or reaches past the memory.
    #[test]
    fn any_read_is_answered_deterministically(addr in prop_oneof![0u32..1600, any::<u32>()], len in any::<u8>()) {
        let g = sample_grid();
        let view = MapView::new(&g, &PATH, pads(), 11, true);
        let all = download(&view);
        let mut m = MemService::with_map(CELLS);
        let mut req = vec![0x4D, 0];
        req.extend_from_slice(&addr.to_le_bytes());
        req.push(len);
        prop_assert_eq!(send(&mut m, &req), None);
        let reply = wire(&m.take_map_read().unwrap().answer(&view));
        prop_assert_eq!(&reply[..6], &req[..6]);
        let end = u64::from(addr) + u64::from(len);
        let ok = len <= 24 && end <= all.len() as u64;
        if ok {
            prop_assert_eq!(reply[6], 0);
            prop_assert_eq!(&reply[7..], &all[addr as usize..end as usize]);
        } else {
            prop_assert_eq!(reply.len(), 7);
            prop_assert_eq!(reply[6], STATUS_EIO);
        }
        let mut out = vec![0u8; usize::from(len)];
        let direct = view.read(addr, &mut out);
        prop_assert_eq!(direct.is_ok(), ok);
        if len > 24 {
            prop_assert_eq!(direct, Err(MapReadError::TooLong));
        }
    }

    /// Any packet on port 4 (any channel, any bytes): no panic, and a reply is always a valid packet.
    #[test]
    fn any_port_4_packet_is_handled(channel in 0u8..4, data in proptest::collection::vec(any::<u8>(), 0..31)) {
        let g = sample_grid();
        let view = MapView::new(&g, &PATH, pads(), 11, true);
        for mut m in [MemService::new(), MemService::with_map(CELLS)] {
            let p = CrtpPacket::new(4, channel, &data).unwrap();
            use cfnav::radio::crtp::Service;
            let _ = m.handle(&p);
            if let Some(read) = m.take_map_read() {
                let r = read.answer(&view);
                prop_assert!(r.data.len() == 6 || r.data.len() == 6 + usize::from(read.len));
            }
        }
    }
}

/// A real mission in the simulator: every 2 s of flight the memory is read in cflib's chunks, decoded by the
/// host tool's decoder and compared with the simulator's own map read through the grid's queries (the dump
/// `cfnav sim --serve --map-json` writes), cell for cell, with path and pads.
#[test]
fn a_flying_mission_map_downloads_equal_to_the_simulators_own_map() {
    use cfnav_sim::world::World;
    use cfnav_tools::map::decode::decode;
    use cfnav_tools::sim::map_dump::SimMapDump;
    use cfnav_tools::sim::runner::{Faults, SimDrone, mission_params};

    let world = World::default_world();
    let mut drone = SimDrone::new(&world, 3, &Faults::default()).unwrap();
    let params = mission_params(&world);
    let mut compared = 0;
    let mut max_occupied = 0;
    for tick in 0..60_000u64 {
        if tick == 1000 {
            drone.core.start_mission(params).expect("starts");
        }
        drone.step(&world);
        if tick % 2000 != 1999 {
            continue;
        }
        let mission = drone.core.mission();
        let view = MapView::of_mission(mission);
        let bytes = download(&view);
        let got = decode(&bytes).expect("a consistent download decodes");
        let sim = SimMapDump::of_mission(mission, drone.tick(), view.crc32());
        assert_eq!((got.width, got.height, got.crc32), (sim.width, sim.height, sim.crc32));
        assert_eq!(got.mission_state, sim.mission_state);
        for (i, &code) in got.cells.iter().enumerate() {
            let want = if sim.occupied[i] {
                3
            } else if sim.blocked[i] {
                2
            } else if sim.unknown[i] {
                0
            } else {
                1
            };
            assert_eq!(code, want, "cell {i} at {} ms", drone.tick());
        }
        assert_eq!(got.path, sim.path);
        let locks = sim.pad_locks.iter().flatten().count();
        assert_eq!(got.pads.len(), usize::from(sim.pad_estimate.is_some()) + locks);
        if let Some((x, y, c, locked)) = sim.pad_estimate {
            let p = &got.pads[0];
            assert_eq!((p.kind.as_str(), p.x_m, p.y_m, p.locked), ("estimate", x, y, locked));
            assert!((p.confidence - c.clamp(0.0, 1.0)).abs() <= 0.5 / 255.0 + 1e-6);
        }
        max_occupied = max_occupied.max(got.cells.iter().filter(|&&c| c == 3).count());
        compared += 1;
    }
    assert_eq!(compared, 30);
    assert!(
        max_occupied > 50,
        "the drone mapped walls and obstacles: {max_occupied} occupied cells"
    );
}
