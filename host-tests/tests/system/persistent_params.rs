//! The persistent-parameter records in the EEPROM (src/system/persistent_params.rs), against a mock 24AA64
//! that loses power at any byte of a write: after every cut a reboot reads either the record set before the
//! write or the one after it, never a mixture, never garbage, and never loses the other stored records.

use std::collections::BTreeMap;

use cfnav::system::persistent_params::{
    FORMAT_VERSION, LoadReport, MAGIC, MAX_RECORDS, PAGE_LEN, PendingWrite, PersistentParams, READ_CHUNK_LEN,
    REGION_LEN, REGION_START, Record, SLOT_LEN, SlotStatus, StoreError, param_key, read_chunks, slot_address,
};

/// What a power cut does to the page being written.
#[derive(Clone, Copy, Debug)]
enum Tear {
    /// Bytes before the cut are written, the rest of the page keeps its old bytes.
    Clean,
    /// The byte at the cut is garbage.
    GarbledByte,
    /// Everything from the cut to the end of its page is garbage (an interrupted page write).
    GarbledPage,
}

/// An 8 KB EEPROM, blank (0xFF), that can lose power after `budget` more bytes.
#[derive(Clone)]
struct MockEeprom {
    mem: Vec<u8>,
    budget: Option<usize>,
    tear: Tear,
}

impl MockEeprom {
    fn new() -> Self {
        Self {
            mem: vec![0xFF; 8192],
            budget: None,
            tear: Tear::Clean,
        }
    }

    /// Writes `w` page by page; `Err` if power was lost on the way.
    fn write(&mut self, w: &PendingWrite) -> Result<(), ()> {
        self.write_pages(w.pages())
    }

    /// Writes `pages` in order; `Err` if power was lost on the way.
    fn write_pages<'a>(&mut self, pages: impl Iterator<Item = (u16, &'a [u8])>) -> Result<(), ()> {
        for (addr, page) in pages {
            assert!(page.len() <= PAGE_LEN);
            let a = usize::from(addr);
            assert_eq!(
                a / PAGE_LEN,
                (a + page.len() - 1) / PAGE_LEN,
                "a page write crosses a page"
            );
            for (i, &b) in page.iter().enumerate() {
                if self.budget == Some(0) {
                    match self.tear {
                        Tear::Clean => {}
                        Tear::GarbledByte => self.mem[a + i] ^= 0x5A,
                        Tear::GarbledPage => {
                            for (k, m) in self.mem[a + i..a + page.len()].iter_mut().enumerate() {
                                *m = (k as u8).wrapping_mul(37) ^ 0xC3;
                            }
                        }
                    }
                    return Err(());
                }
                self.mem[a + i] = b;
                if let Some(n) = self.budget.as_mut() {
                    *n -= 1;
                }
            }
        }
        Ok(())
    }

    fn region(&self) -> &[u8] {
        let a = usize::from(REGION_START);
        &self.mem[a..a + REGION_LEN]
    }

    /// A reboot: the store as the firmware rebuilds it from the EEPROM.
    fn boot(&self) -> (PersistentParams, LoadReport) {
        PersistentParams::load(self.region())
    }
}

/// The records as a key → (type, value) map (order does not matter).
fn set(p: &PersistentParams) -> BTreeMap<u32, (u8, [u8; 4])> {
    p.records().map(|r| (r.key, (r.type_code, r.value))).collect()
}

fn f32_rec(group: &str, name: &str, v: f32) -> (u32, u8, [u8; 4]) {
    (param_key(group, name), 0x06, v.to_le_bytes())
}

/// Stores through the mock without a cut and commits.
fn store(e: &mut MockEeprom, p: &mut PersistentParams, (key, ty, value): (u32, u8, [u8; 4])) {
    let w = p.prepare_store(key, ty, value).unwrap();
    e.write(&w).unwrap();
    assert!(p.commit(w));
}

/// An EEPROM after a few stores, so that both slots hold images (the target slot is not blank).
fn populated() -> (MockEeprom, PersistentParams) {
    let mut e = MockEeprom::new();
    let mut p = PersistentParams::empty();
    store(&mut e, &mut p, f32_rec("pid_rate", "roll_kp", 250.0));
    store(&mut e, &mut p, f32_rec("pid_rate", "pitch_kp", 250.0));
    store(&mut e, &mut p, f32_rec("posCtlPid", "zKp", 2.0));
    store(&mut e, &mut p, (param_key("mission", "avoidMode"), 0x08, [1, 0, 0, 0]));
    store(&mut e, &mut p, f32_rec("pid_rate", "roll_kp", 240.0));
    let (booted, report) = e.boot();
    assert_eq!(set(&booted), set(&p));
    assert!(matches!(report.slots[0], SlotStatus::Valid { .. }));
    assert!(matches!(report.slots[1], SlotStatus::Valid { .. }));
    (e, p)
}

/// One change prepared from the populated state.
type Change = fn(&PersistentParams) -> PendingWrite;

fn changes() -> [(&'static str, Change); 3] {
    [
        ("replace a value", |p| {
            let (k, t, v) = f32_rec("pid_rate", "pitch_kp", 300.0);
            p.prepare_store(k, t, v).unwrap()
        }),
        ("add a value", |p| {
            let (k, t, v) = f32_rec("flow", "stdCounts", 3.0);
            p.prepare_store(k, t, v).unwrap()
        }),
        ("clear a value", |p| {
            p.prepare_clear(param_key("posCtlPid", "zKp")).unwrap()
        }),
    ]
}

#[test]
fn a_power_cut_at_every_byte_of_a_write_leaves_the_old_or_the_new_set() {
    let (base_eeprom, base) = populated();
    let old = set(&base);
    for (what, change) in changes() {
        let w = change(&base);
        let mut after = base;
        assert!(after.commit(w));
        let new = set(&after);
        assert_ne!(old, new, "{what}");
        for tear in [Tear::Clean, Tear::GarbledByte, Tear::GarbledPage] {
            let mut outcomes = [0usize; 2];
            for cut in 0..=SLOT_LEN {
                let mut e = base_eeprom.clone();
                e.budget = Some(cut);
                e.tear = tear;
                let done = e.write(&w).is_ok();
                assert_eq!(done, cut == SLOT_LEN, "{what} {tear:?} cut {cut}");
                let (booted, report) = e.boot();
                let got = set(&booted);
                assert!(got == old || got == new, "{what} {tear:?} cut at byte {cut}: {got:?}");
                outcomes[usize::from(got == new)] += 1;
                if cut < SLOT_LEN - 4 {
                    // The CRC is written last: no earlier cut can make the new slot valid.
                    assert_eq!(got, old, "{what} {tear:?} cut at byte {cut}");
                    assert_ne!(report.used, Some(w.slot()), "{what} {tear:?} cut at byte {cut}");
                }
                if cut == SLOT_LEN {
                    assert_eq!(got, new, "{what}: the completed write");
                }
                // Life goes on after the reboot: the next store lands on top of what was read, and a cut in
                // *that* write still keeps everything read at this boot.
                let mut next = booted;
                let (k, t, v) = f32_rec("pid_attitude", "yaw_kp", 7.0);
                let w2 = next.prepare_store(k, t, v).unwrap();
                let mut e2 = e.clone();
                e2.budget = Some(cut / 2);
                e2.tear = tear;
                let _ = e2.write(&w2);
                let got2 = set(&e2.boot().0);
                let mut expect2 = got.clone();
                expect2.insert(k, (t, v));
                assert!(
                    got2 == got || got2 == expect2,
                    "{what} {tear:?} cuts {cut}, {}",
                    cut / 2
                );
                e.budget = None;
                e.write(&w2).unwrap();
                assert!(next.commit(w2));
                assert_eq!(
                    set(&e.boot().0),
                    expect2,
                    "{what} {tear:?} cut {cut}: the write after reboot"
                );
                assert_eq!(set(&next), expect2);
            }
            assert!(
                outcomes[0] >= SLOT_LEN - 4 && outcomes[1] >= 1,
                "{what} {tear:?}: {outcomes:?}"
            );
        }
    }
}

#[test]
fn a_corrupted_newest_slot_falls_back_to_the_older_one_and_two_corrupted_slots_to_nothing() {
    let (mut e, p) = populated();
    let newest = p.slot().unwrap();
    // The set the older slot holds: the state before the last store (roll_kp was 250 then).
    let mut older = set(&p);
    let (k, t, v) = f32_rec("pid_rate", "roll_kp", 250.0);
    older.insert(k, (t, v));
    for at in [20usize, 100, SLOT_LEN - 1] {
        let mut bad = e.clone();
        bad.mem[usize::from(slot_address(newest)) + at] ^= 0x01;
        let (booted, report) = bad.boot();
        assert_eq!(report.slots[usize::from(newest)], SlotStatus::BadCrc, "byte {at}");
        assert_eq!(report.used, Some(1 - newest));
        assert_eq!(set(&booted), older, "byte {at}");
    }
    e.mem[usize::from(slot_address(0)) + 30] ^= 0x80;
    e.mem[usize::from(slot_address(1)) + 30] ^= 0x80;
    let (booted, report) = e.boot();
    assert_eq!(report.slots, [SlotStatus::BadCrc; 2]);
    assert_eq!(report.used, None);
    assert!(booted.is_empty());
}

/// A slot image with a valid CRC, `version` and `seq`, holding `records`.
fn raw_slot(version: u16, seq: u32, records: &[Record]) -> Vec<u8> {
    let mut b = vec![0u8; SLOT_LEN];
    b[0..4].copy_from_slice(&MAGIC.to_le_bytes());
    b[4..6].copy_from_slice(&version.to_le_bytes());
    b[6..8].copy_from_slice(&(records.len() as u16).to_le_bytes());
    b[8..12].copy_from_slice(&seq.to_le_bytes());
    for (i, r) in records.iter().enumerate() {
        let at = 16 + i * 9;
        b[at..at + 4].copy_from_slice(&r.key.to_le_bytes());
        b[at + 4] = r.type_code;
        b[at + 5..at + 9].copy_from_slice(&r.value);
    }
    let crc = cfnav::crc::crc32(&b[..SLOT_LEN - 4]);
    b[SLOT_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn a_slot_of_another_format_version_is_not_read() {
    let r = Record {
        key: param_key("pid_rate", "roll_kp"),
        type_code: 0x06,
        value: 100f32.to_le_bytes(),
    };
    // The hand-built v1 slot is what the store itself writes: the oracle agrees with the encoder.
    let mut region = raw_slot(FORMAT_VERSION, 3, &[r]);
    region.extend(raw_slot(FORMAT_VERSION + 1, 9, &[]));
    let (p, report) = PersistentParams::load(&region);
    assert_eq!(report.slots[0], SlotStatus::Valid { seq: 3, count: 1 });
    assert_eq!(report.slots[1], SlotStatus::Version(FORMAT_VERSION + 1));
    assert_eq!(report.used, Some(0));
    assert_eq!(p.records().collect::<Vec<_>>(), vec![r]);
    // Only a future version present: nothing is applied.
    let mut future = raw_slot(FORMAT_VERSION + 1, 9, &[r]);
    future.extend(vec![0xFF; SLOT_LEN]);
    let (p, report) = PersistentParams::load(&future);
    assert_eq!(
        report.slots,
        [SlotStatus::Version(FORMAT_VERSION + 1), SlotStatus::Blank]
    );
    assert!(p.is_empty());
    // An impossible record count with a valid CRC is not trusted either.
    let mut bad = raw_slot(FORMAT_VERSION, 1, &[]);
    bad[6..8].copy_from_slice(&(MAX_RECORDS as u16 + 1).to_le_bytes());
    let crc = cfnav::crc::crc32(&bad[..SLOT_LEN - 4]);
    bad[SLOT_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(
        PersistentParams::load(&bad).1.slots[0],
        SlotStatus::BadCount(MAX_RECORDS as u16 + 1)
    );
}

#[test]
fn a_full_store_refuses_a_new_key_and_still_replaces_a_stored_one() {
    let mut e = MockEeprom::new();
    let mut p = PersistentParams::empty();
    for i in 0..MAX_RECORDS as u32 {
        store(&mut e, &mut p, (0x1000 + i, 0x0A, i.to_le_bytes()));
    }
    assert_eq!(p.len(), MAX_RECORDS);
    let before = p;
    assert_eq!(p.prepare_store(0xDEAD, 0x0A, [1, 2, 3, 4]), Err(StoreError::Full));
    assert_eq!(p, before, "a refused store changes nothing");
    store(&mut e, &mut p, (0x1000, 0x0A, 99u32.to_le_bytes()));
    assert_eq!(p.len(), MAX_RECORDS);
    let booted = e.boot().0;
    assert_eq!(booted.get(0x1000).unwrap().value, 99u32.to_le_bytes());
    assert_eq!(set(&booted), set(&p));
    // Clearing one makes room again.
    let w = p.prepare_clear(0x1001).unwrap();
    e.write(&w).unwrap();
    p.commit(w);
    assert!(p.prepare_store(0xDEAD, 0x0A, [1, 2, 3, 4]).is_ok());
}

#[test]
fn blank_eeprom_reads_empty_and_writes_stay_inside_the_region_away_from_the_config_block() {
    let e = MockEeprom::new();
    let (p, report) = e.boot();
    assert!(p.is_empty());
    assert_eq!(report.slots, [SlotStatus::Blank; 2]);
    assert_eq!(report.used, None);
    // A stock KVE partition (or anything without our magic) reads as blank too.
    let mut kve = vec![0u8; REGION_LEN];
    kve[0..4].copy_from_slice(b"KVE\0");
    assert_eq!(PersistentParams::load(&kve).1.slots, [SlotStatus::Blank; 2]);
    let w = p.prepare_store(1, 0x08, [1, 0, 0, 0]).unwrap();
    for (addr, bytes) in w.pages() {
        assert!(addr >= REGION_START && usize::from(addr) + bytes.len() <= usize::from(REGION_START) + REGION_LEN);
        assert!(usize::from(addr) >= 21, "the config block lives at 0..21");
        assert_eq!(usize::from(addr) % PAGE_LEN, 0);
    }
    assert_eq!(w.bytes().len(), SLOT_LEN);
    // Clearing what is not stored writes nothing.
    assert!(p.prepare_clear(1).is_none());
}

#[test]
fn the_newer_slot_wins_across_sequence_wrap_around() {
    let a = Record {
        key: 1,
        type_code: 0x08,
        value: [1, 0, 0, 0],
    };
    let b = Record {
        value: [2, 0, 0, 0],
        ..a
    };
    let mut region = raw_slot(FORMAT_VERSION, u32::MAX, &[a]);
    region.extend(raw_slot(FORMAT_VERSION, 0, &[b]));
    let (p, report) = PersistentParams::load(&region);
    assert_eq!(report.used, Some(1));
    assert_eq!(p.get(1), Some(b));
    // The next write goes to the other slot with the next number.
    let w = p.prepare_store(1, 0x08, [3, 0, 0, 0]).unwrap();
    assert_eq!(w.slot(), 0);
    let mut e = MockEeprom::new();
    let start = usize::from(REGION_START);
    e.mem[start..start + REGION_LEN].copy_from_slice(&region);
    e.write(&w).unwrap();
    assert_eq!(e.boot().0.get(1).unwrap().value, [3, 0, 0, 0]);
}

#[test]
fn a_write_prepared_before_another_commit_is_not_committed() {
    let p0 = PersistentParams::empty();
    let w1 = p0.prepare_store(1, 0x08, [1, 0, 0, 0]).unwrap();
    let w2 = p0.prepare_store(2, 0x08, [2, 0, 0, 0]).unwrap();
    let mut p = p0;
    assert!(p.commit(w1));
    assert!(!p.commit(w2), "a stale write would drop record 1");
    assert_eq!(p.len(), 1);
}

#[test]
fn the_mock_catches_an_in_place_rewrite_that_a_cut_would_break() {
    // Negative control of the power-cut test: the same new image written over the slot in use (instead of
    // the other one) loses the latest set for most cut points, so the cut model does detect the hazard the
    // two-slot layout exists for.
    let (base_eeprom, base) = populated();
    let old = set(&base);
    let (k, t, v) = f32_rec("pid_rate", "pitch_kp", 300.0);
    let w = base.prepare_store(k, t, v).unwrap();
    let in_use = slot_address(base.slot().unwrap());
    let mut lost = 0;
    for cut in 0..SLOT_LEN {
        let mut e = base_eeprom.clone();
        e.budget = Some(cut);
        let pages = w
            .bytes()
            .chunks(PAGE_LEN)
            .enumerate()
            .map(|(i, c)| (in_use + (i * PAGE_LEN) as u16, c));
        assert!(e.write_pages(pages).is_err());
        let got = set(&e.boot().0);
        let mut new = old.clone();
        new.insert(k, (t, v));
        if got != old && got != new {
            lost += 1;
        }
    }
    assert!(
        lost > SLOT_LEN / 2,
        "an in-place rewrite lost the latest set at {lost} cut points"
    );
}

/// Bus time of one 24AA64 random-address sequential read of `n` bytes at `hz` (DS21189 §8.3): device
/// address (write), two memory address bytes, repeated start, device address (read), `n` data bytes; 9
/// clocks a byte (8 bits + ACK) and ≈ 3 clocks for the start, the repeated start and the stop.
fn i2c_read_us(n: usize, hz: u64) -> u64 {
    let clocks = (4 + n as u64) * 9 + 3;
    (clocks * 1_000_000).div_ceil(hz)
}

#[test]
fn read_chunks_cover_the_region_in_order_with_matching_addresses() {
    for (start, len) in [
        (REGION_START, REGION_LEN),
        (slot_address(1), SLOT_LEN),
        (0, 1),
        (0x1f00, 300),
        (7, 0),
    ] {
        let chunks: Vec<_> = read_chunks(start, len).collect();
        let mut next = 0usize;
        for (addr, range) in &chunks {
            assert_eq!(range.start, next, "chunks are contiguous");
            assert!(!range.is_empty() && range.len() <= READ_CHUNK_LEN);
            assert_eq!(
                usize::from(*addr),
                usize::from(start) + range.start,
                "address follows the offset"
            );
            next = range.end;
        }
        assert_eq!(next, len, "chunks cover the whole read");
    }
}

#[test]
fn every_eeprom_read_transfer_fits_the_deck_bus_deadline() {
    // The deck bus guard's per-transfer deadline (src/board/sensors.rs DECK_GUARD.timeout_us) at the deck
    // bus's 400 kHz (src/main.rs). One read of the whole region (≈ 29 ms) or of a slot (≈ 15 ms) did not fit:
    // the boot log said "EEPROM read failed (Timeout)" in the emulator and the store never loaded.
    const DECK_DEADLINE_US: u64 = 10_000;
    assert!(
        i2c_read_us(REGION_LEN, 400_000) > DECK_DEADLINE_US,
        "the oracle sees the old single read fail"
    );
    for (start, len) in [
        (REGION_START, REGION_LEN),
        (slot_address(0), SLOT_LEN),
        (slot_address(1), SLOT_LEN),
    ] {
        for (_, range) in read_chunks(start, len) {
            let us = i2c_read_us(range.len(), 400_000);
            assert!(us * 2 < DECK_DEADLINE_US, "a {}-byte read takes {us} µs", range.len());
        }
    }
}

#[test]
fn read_chunks_stop_at_the_end_of_the_address_space() {
    let chunks: Vec<_> = read_chunks(0xfff0, 100).collect();
    let total: usize = chunks.iter().map(|(_, r)| r.len()).sum();
    assert_eq!(total, 16);
}
