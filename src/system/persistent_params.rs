//! Persistent parameters: the values `persistent_store` saved, kept in the on-board EEPROM beside the
//! config block, in a layout that survives a bad write and a power cut at any byte of a write.
//!
//! Job: hold the stored `(key, type, value)` records; parse them from the EEPROM's bytes at boot
//! ([`PersistentParams::load`]) and, for a store or a clear, build the bytes to write
//! ([`PersistentParams::prepare_store`], [`PersistentParams::prepare_clear`]): sans-IO, the caller does
//! the writes (the board over I2C, the simulator into a file, the tests into a mock that loses power) and
//! then [`PersistentParams::commit`]s what it wrote.
//!
//! Non-goals: no I2C, no knowledge of which parameters exist or their bounds (the caller applies stored
//! values through the same checks as a radio write), no compatibility with the stock firmware's KVE
//! format (only the radio protocol is stock's; a stock KVE partition found here reads as blank).
//!
//! # Layout
//! The region starts at EEPROM offset [`REGION_START`] (1024, where stock keeps its KVE partition:
//! `docs/hardware.md` §1, stock `storage.c` `KVE_PARTITION_START`; the config block at 0..21 is
//! never touched) and holds two slots of [`SLOT_LEN`] bytes. A slot, little-endian:
//!
//! | offset | field |
//! |---|---|
//! | 0 | magic u32 = [`MAGIC`] (`"CFNP"`) |
//! | 4 | format version u16 = [`FORMAT_VERSION`] |
//! | 6 | record count u16 (≤ [`MAX_RECORDS`]) |
//! | 8 | sequence number u32 (the newer slot has the larger one, compared with wrap-around) |
//! | 12 | reserved u32 = 0 |
//! | 16 | records, [`RECORD_LEN`] bytes each: key u32 ([`param_key`]), type code u8 (param protocol `docs/hardware.md` §4), value 4 bytes (little-endian, zero-padded) |
//! | … | zeros up to the CRC |
//! | `SLOT_LEN − 4` | CRC-32 (reflected 0xEDB88320, init/xorout 0xFFFFFFFF) of bytes 0 .. `SLOT_LEN − 4` |
//!
//! # Why a cut never loses data
//! A change writes a whole new image, with the next sequence number, into the slot that does *not* hold the
//! newest valid image, from its first byte to its CRC (written last). Until the last CRC byte is written
//! the new slot's CRC does not match (the sequence number it covers changed; a match would be a 1 in 2³²
//! coincidence), so [`PersistentParams::load`]
//! after a cut at any byte finds the untouched older slot and reads the previous record set; after the
//! last byte it reads the new one. A failed or torn write (even one that garbles the rest of its
//! EEPROM page, as an interrupted 24AA64 page write may) touches only the target slot. A bit flip in the
//! newest slot falls back to the older one. Either way the result is one complete record set that was
//! stored, never a mixture.
//!
//! Writes go in EEPROM pages ([`PAGE_LEN`] = 32 bytes, 24AA64 datasheet DS21189 §6.2 "Page Write": a
//! write must not cross a 32-byte page boundary, the slots are page-aligned), each followed by the write
//! cycle (≤ 5 ms, DS21189 Table 1-2 `TWC`): a store costs 20 pages, ≈ 100 ms of EEPROM time.
//!
//! Memory: [`PersistentParams`] is one slot image (640 bytes) and a few words; a [`PendingWrite`] another.

use crate::crc::crc32;

/// EEPROM offset of the first slot (stock's KVE partition start, 1024).
pub const REGION_START: u16 = 0x0400;
/// EEPROM page size of the 24AA64, bytes (DS21189 §6.2).
pub const PAGE_LEN: usize = 32;
/// Bytes of one slot: 20 pages.
pub const SLOT_LEN: usize = 20 * PAGE_LEN;
/// Bytes of the whole region (two slots), read at boot from [`REGION_START`].
pub const REGION_LEN: usize = 2 * SLOT_LEN;
/// Most bytes one EEPROM read transfer asks for: [`read_chunks`] cuts the boot read and the read-back into
/// pieces of this size. Why: every deck-bus transfer has a deadline (the board's I2C guard, 10 ms), and one
/// sequential read of the whole region (1280 bytes, ≈ 29 ms at 400 kHz) or of a slot (640 bytes, ≈ 15 ms)
/// overruns it, so the store could never be read. 128 bytes plus the addressing is ≈ 3 ms at 400 kHz.
pub const READ_CHUNK_LEN: usize = 128;
/// Bytes of the slot header.
pub const HEADER_LEN: usize = 16;
/// Bytes of one record: key u32, type u8, value 4 bytes.
pub const RECORD_LEN: usize = 9;
/// Most records a slot holds.
pub const MAX_RECORDS: usize = (SLOT_LEN - HEADER_LEN - 4) / RECORD_LEN;
/// `"CFNP"` read as a little-endian u32.
pub const MAGIC: u32 = u32::from_le_bytes(*b"CFNP");
/// The layout's version; a slot of any other version is not read.
pub const FORMAT_VERSION: u16 = 1;

const CRC_AT: usize = SLOT_LEN - 4;

/// The storage key of `group.name`: CRC-32 of the bytes `group`, `.`, `name` (the stock key without its
/// `prm/` prefix, hashed to fit a fixed record). Keys, not ids, so a stored value survives a firmware whose
/// table has other ids; the host tests check that no two parameters share a key.
pub const fn param_key(group: &str, name: &str) -> u32 {
    use crate::crc::crc32_update;
    let crc = crc32_update(0xFFFF_FFFF, group.as_bytes());
    let crc = crc32_update(crc, b".");
    crc32_update(crc, name.as_bytes()) ^ 0xFFFF_FFFF
}

/// One stored value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Record {
    /// [`param_key`] of the parameter.
    pub key: u32,
    /// Its wire type code (`docs/hardware.md` §4), so a value stored for another type is never applied.
    pub type_code: u8,
    /// The value, little-endian, zero-padded to 4 bytes.
    pub value: [u8; 4],
}

/// What [`PersistentParams::load`] found in one slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotStatus {
    /// No magic number (blank EEPROM, or something else lives here).
    Blank,
    /// Magic right, CRC wrong: a write was cut or the bytes were corrupted.
    BadCrc,
    /// CRC right but a format version this firmware does not read.
    Version(u16),
    /// CRC right but the record count is impossible.
    BadCount(u16),
    /// Valid, with this sequence number and record count.
    Valid {
        /// Sequence number.
        seq: u32,
        /// Records.
        count: u16,
    },
}

/// What [`PersistentParams::load`] found: each slot's status and which one is in use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadReport {
    /// Slot 0 and slot 1.
    pub slots: [SlotStatus; 2],
    /// The slot whose records are in use (the newer valid one), `None` if neither is valid.
    pub used: Option<u8>,
}

/// Why a store was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoreError {
    /// Every record is taken by another parameter.
    Full,
}

/// The bytes of one change, to write at [`Self::address`] in order ([`Self::pages`]), then hand back to
/// [`PersistentParams::commit`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PendingWrite {
    slot: u8,
    seq: u32,
    image: [u8; SLOT_LEN],
}

impl PendingWrite {
    /// EEPROM address of the first byte.
    pub fn address(&self) -> u16 {
        slot_address(self.slot)
    }

    /// The slot written (0 or 1).
    pub fn slot(&self) -> u8 {
        self.slot
    }

    /// Every byte, in writing order (the CRC last).
    pub fn bytes(&self) -> &[u8; SLOT_LEN] {
        &self.image
    }

    /// The write as 32-byte page writes `(address, bytes)`, in order (none crosses a page boundary).
    pub fn pages(&self) -> impl Iterator<Item = (u16, &[u8])> {
        let base = self.address();
        self.image
            .chunks(PAGE_LEN)
            .enumerate()
            .map(move |(i, c)| (base + (i * PAGE_LEN) as u16, c))
    }
}

/// The pieces of a sequential read of `len` bytes from EEPROM address `start`: `(address, range in the
/// caller's buffer)`, each at most [`READ_CHUNK_LEN`] bytes, in order, covering `0..len` exactly. A read that
/// would run past the 16-bit address space stops there (the 24AA64 has 8 KiB; nothing here reads near it).
pub fn read_chunks(start: u16, len: usize) -> impl Iterator<Item = (u16, core::ops::Range<usize>)> {
    let len = len.min(usize::from(u16::MAX - start) + 1);
    (0..len)
        .step_by(READ_CHUNK_LEN)
        .map(move |at| (start + at as u16, at..(at + READ_CHUNK_LEN).min(len)))
}

/// EEPROM address of slot 0 or 1.
pub const fn slot_address(slot: u8) -> u16 {
    REGION_START + (slot as u16 & 1) * SLOT_LEN as u16
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// The status of one slot's bytes (fewer than [`SLOT_LEN`] bytes read as blank).
pub fn slot_status(bytes: &[u8]) -> SlotStatus {
    let Some(b) = bytes.get(..SLOT_LEN) else {
        return SlotStatus::Blank;
    };
    if u32_at(b, 0) != MAGIC {
        return SlotStatus::Blank;
    }
    if crc32(&b[..CRC_AT]) != u32_at(b, CRC_AT) {
        return SlotStatus::BadCrc;
    }
    let version = u16_at(b, 4);
    if version != FORMAT_VERSION {
        return SlotStatus::Version(version);
    }
    let count = u16_at(b, 6);
    if usize::from(count) > MAX_RECORDS {
        return SlotStatus::BadCount(count);
    }
    SlotStatus::Valid {
        seq: u32_at(b, 8),
        count,
    }
}

/// The stored records: the newest valid slot's, or none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PersistentParams {
    /// The image in use (an empty valid image when nothing is stored).
    image: [u8; SLOT_LEN],
    /// The slot it came from or was last written to; `None`: nothing valid in the EEPROM.
    slot: Option<u8>,
    /// Its sequence number.
    seq: u32,
}

impl Default for PersistentParams {
    fn default() -> Self {
        Self::empty()
    }
}

impl PersistentParams {
    /// Nothing stored (a blank EEPROM, or no EEPROM: the simulator without a file).
    pub fn empty() -> Self {
        Self {
            image: encode(0, &mut core::iter::empty()),
            slot: None,
            seq: 0,
        }
    }

    /// Parses the region's bytes ([`REGION_LEN`] from [`REGION_START`]; fewer bytes leave the missing
    /// slots blank) and keeps the newer valid slot's records.
    pub fn load(region: &[u8]) -> (Self, LoadReport) {
        let slot_bytes = |i: usize| region.get(i * SLOT_LEN..(i + 1) * SLOT_LEN).unwrap_or(&[]);
        let slots = [slot_status(slot_bytes(0)), slot_status(slot_bytes(1))];
        let seq = |s: SlotStatus| match s {
            SlotStatus::Valid { seq, .. } => Some(seq),
            _ => None,
        };
        let used = match (seq(slots[0]), seq(slots[1])) {
            (Some(a), Some(b)) => Some(if (b.wrapping_sub(a) as i32) > 0 { 1 } else { 0 }),
            (Some(_), None) => Some(0),
            (None, Some(_)) => Some(1),
            (None, None) => None,
        };
        let store = match used {
            Some(i) => {
                let mut image = [0u8; SLOT_LEN];
                image.copy_from_slice(slot_bytes(usize::from(i)));
                Self {
                    seq: u32_at(&image, 8),
                    image,
                    slot: Some(i),
                }
            }
            None => Self::empty(),
        };
        (store, LoadReport { slots, used })
    }

    /// Number of stored records.
    pub fn len(&self) -> usize {
        usize::from(u16_at(&self.image, 6)).min(MAX_RECORDS)
    }

    /// True if nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The slot in use (`None` before anything valid was read or written).
    pub fn slot(&self) -> Option<u8> {
        self.slot
    }

    /// The sequence number of the records in use.
    pub fn seq(&self) -> u32 {
        self.seq
    }

    /// Every stored record, in storage order.
    pub fn records(&self) -> impl Iterator<Item = Record> + '_ {
        (0..self.len()).map(|i| {
            let at = HEADER_LEN + i * RECORD_LEN;
            let r = &self.image[at..at + RECORD_LEN];
            Record {
                key: u32_at(r, 0),
                type_code: r[4],
                value: [r[5], r[6], r[7], r[8]],
            }
        })
    }

    /// The record stored under `key`.
    pub fn get(&self, key: u32) -> Option<Record> {
        self.records().find(|r| r.key == key)
    }

    /// The write that stores `value` (type `type_code`) under `key`, replacing what `key` had; every other
    /// record is kept. Refused when `key` is new and [`MAX_RECORDS`] are taken.
    pub fn prepare_store(&self, key: u32, type_code: u8, value: [u8; 4]) -> Result<PendingWrite, StoreError> {
        let new = Record { key, type_code, value };
        if self.get(key).is_none() && self.len() >= MAX_RECORDS {
            return Err(StoreError::Full);
        }
        let mut records = self
            .records()
            .map(|r| if r.key == key { new } else { r })
            .chain(self.get(key).is_none().then_some(new));
        Ok(self.pending(&mut records))
    }

    /// The write that forgets `key`; `None` if it is not stored (nothing to write).
    pub fn prepare_clear(&self, key: u32) -> Option<PendingWrite> {
        self.get(key)?;
        let mut records = self.records().filter(|r| r.key != key);
        Some(self.pending(&mut records))
    }

    fn pending(&self, records: &mut dyn Iterator<Item = Record>) -> PendingWrite {
        let seq = self.seq.wrapping_add(1);
        PendingWrite {
            slot: match self.slot {
                Some(s) => 1 - s,
                None => 0,
            },
            seq,
            image: encode(seq, records),
        }
    }

    /// `write`'s bytes are in the EEPROM: its records are the ones in use now. A write prepared from an
    /// older state (another was committed since) is ignored: returns false.
    pub fn commit(&mut self, write: PendingWrite) -> bool {
        if write.seq != self.seq.wrapping_add(1) {
            return false;
        }
        self.image = write.image;
        self.slot = Some(write.slot);
        self.seq = write.seq;
        true
    }
}

/// A slot image with `seq` and `records` (at most [`MAX_RECORDS`] are taken), CRC last.
fn encode(seq: u32, records: &mut dyn Iterator<Item = Record>) -> [u8; SLOT_LEN] {
    let mut b = [0u8; SLOT_LEN];
    b[0..4].copy_from_slice(&MAGIC.to_le_bytes());
    b[4..6].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    b[8..12].copy_from_slice(&seq.to_le_bytes());
    let mut count = 0usize;
    for r in records.take(MAX_RECORDS) {
        let at = HEADER_LEN + count * RECORD_LEN;
        b[at..at + 4].copy_from_slice(&r.key.to_le_bytes());
        b[at + 4] = r.type_code;
        b[at + 5..at + 9].copy_from_slice(&r.value);
        count += 1;
    }
    b[6..8].copy_from_slice(&(count as u16).to_le_bytes());
    let crc = crc32(&b[..CRC_AT]);
    b[CRC_AT..].copy_from_slice(&crc.to_le_bytes());
    b
}
