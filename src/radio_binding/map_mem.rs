//! The drone's map as a read-only CRTP memory (port 4): the occupancy grid, the current path and the pad
//! estimates, serialised on demand in a versioned byte layout that cflib's memory subsystem reads unmodified.
//!
//! Job: answer "the `len` bytes at `addr`" of the map memory deterministically from the live map
//! ([`MapView`]), computing each byte from the grid, path and pad records on the spot: nothing is copied or
//! buffered, and any offset and length is answered (bytes past the used part read 0, a read past the memory
//! or longer than [`MAX_READ_LEN`] is refused) without panicking.
//!
//! Non-goals: writes (the memory is read-only: writes are refused with status `EIO`), transport and the
//! memory protocol's packets (see [`crate::radio::mem`]), decoding (the host tool `cfnav map` and
//! `tools/e2e/cflib_map.py` decode it).
//!
//! # Layout, version 1 (all little-endian; `docs/map-memory.md` has the full description)
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | `[u8; 4]` | magic `"CFNM"` |
//! | 4 | u8 | version, 1 |
//! | 5 | u8 | header length, 32 |
//! | 6 | u8 | bits per cell, 2 |
//! | 7 | u8 | `mission.state` code |
//! | 8 | u32 | CRC-32 (IEEE, as zlib's `crc32`) of bytes `12 .. total_len` |
//! | 12 | u32 | `total_len`: bytes used (header + cells + path + pads) |
//! | 16 | u16, u16 | grid width, height, cells |
//! | 20 | u16 | cell size, mm (50) |
//! | 22 | i16, i16 | grid origin in the arena frame, mm (0, 0: the arena's lower-left corner) |
//! | 26 | u16 | path points |
//! | 28 | u8 | pad records |
//! | 29 | u8 | flags: bit 0 a mission runs, bit 1 the path was cut to [`MAX_PATH_POINTS`] |
//! | 30 | u16 | 0 |
//! | 32 | | cells, 2 bits each, row-major from cell (0, 0) (row 0 at y = 0): cell `i` is bits `2(i mod 4) ..` of byte `32 + i / 4`; 0 unknown, 1 free, 2 blocked (inflated, not occupied), 3 occupied |
//! | … | `[u16; 2]` × path points | the current shortened path, cells `(x, y)`, start first |
//! | … | 12 bytes × pad records | `x_m` f32, `y_m` f32 (arena frame), confidence u8 (0–255 ↔ 0–1), kind u8 (0 live estimate, 1 goal pad lock, 2 home pad lock), flags u8 (bit 0 locked), 0 |
//!
//! Consistency rule: the map changes while it is read, so a reader reads `0 .. total_len` (the header
//! first) and accepts it only if the CRC-32 of the bytes it got for `12 .. total_len` equals the CRC field
//! it got; otherwise the map changed mid-download and it reads again. The CRC is computed (O(`total_len`))
//! only for reads that touch bytes 8..12.
//!
//! Units and frames: cells are [`CELL_SIZE_M`] squares of the arena frame ([`crate::nav::map`]); pad
//! centres are arena-frame metres.
//!
//! Memory: [`MapView`] holds three references and a few scalars; nothing is allocated. The memory's size
//! ([`map_memory_size`]) is fixed for a build (the cell capacity), so cflib's `GET_INFO` answer never changes.
//!
//! Sources: the memory protocol as the stock firmware serves it (`src/modules/src/crtp_mem.c`: read reply
//! `[id, addr u32, status, data…]`, `EIO` on failure, at most 24 data bytes per reply) and as cflib 0.1.34
//! reads it (`cflib/crazyflie/mem/__init__.py` `_ReadRequest.MAX_DATA_LENGTH = 24`).

use crate::mission::Mission;
use crate::nav::grid::OccupancyGrid;
use crate::nav::map::{CELL_SIZE_M, Cell, GridShape};
use crate::radio::crtp::CrtpPacket;
use crate::radio::mem::{CH_READ, MAP_MEMORY_ID, MapRead, MemService, PORT_MEM, STATUS_EIO};

/// Magic at offset 0.
pub const MAGIC: [u8; 4] = *b"CFNM";
/// Layout version.
pub const VERSION: u8 = 1;
/// Header length, bytes.
pub const HEADER_LEN: usize = 32;
/// Bits per cell.
pub const CELL_BITS: u8 = 2;
/// Longest path carried, points (the mission's shortened path holds at most 48).
pub const MAX_PATH_POINTS: usize = 64;
/// Most pad records carried: the live estimate and the two locks.
pub const MAX_PADS: usize = 3;
/// Bytes per path point.
pub const PATH_POINT_LEN: usize = 4;
/// Bytes per pad record.
pub const PAD_RECORD_LEN: usize = 12;
/// Longest read answered (the stock firmware's 30-byte payload minus the 6-byte reply header).
pub const MAX_READ_LEN: usize = 24;
/// Offset of the CRC field.
pub const CRC_OFFSET: usize = 8;
/// Flag: a mission runs.
pub const FLAG_RUNNING: u8 = 1;
/// Flag: the path was cut to [`MAX_PATH_POINTS`].
pub const FLAG_PATH_TRUNCATED: u8 = 2;

/// Cell code: no evidence.
pub const CELL_UNKNOWN: u8 = 0;
/// Cell code: seen free, not blocked.
pub const CELL_FREE: u8 = 1;
/// Cell code: blocked by inflation (an obstacle or the wall within the inflation radius), not occupied.
pub const CELL_BLOCKED: u8 = 2;
/// Cell code: occupied.
pub const CELL_OCCUPIED: u8 = 3;

/// Size of the map memory for a grid of `cells` capacity, bytes: the header, the cells, the longest path
/// and all pad records.
pub const fn map_memory_size(cells: usize) -> usize {
    HEADER_LEN + cells.div_ceil(4) + MAX_PATH_POINTS * PATH_POINT_LEN + MAX_PADS * PAD_RECORD_LEN
}

/// What a pad record is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PadKind {
    /// The pad detector's current estimate.
    Estimate = 0,
    /// The centre the drone locked on for the goal pad (outbound leg).
    GoalLock = 1,
    /// The centre the drone locked on for the home pad (return leg).
    HomeLock = 2,
}

/// One pad record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PadRecord {
    /// Centre, arena frame, m.
    pub x_m: f32,
    /// Centre, arena frame, m.
    pub y_m: f32,
    /// Confidence, 0–1 (clamped; NaN reads 0).
    pub confidence: f32,
    /// What the record is.
    pub kind: PadKind,
    /// Whether the estimate is good enough to land on.
    pub locked: bool,
}

impl PadRecord {
    fn byte(&self, k: usize) -> u8 {
        match k {
            0..=3 => self.x_m.to_le_bytes()[k],
            4..=7 => self.y_m.to_le_bytes()[k - 4],
            8 => {
                let c = if self.confidence.is_nan() {
                    0.0
                } else {
                    self.confidence.clamp(0.0, 1.0)
                };
                libm::roundf(c * 255.0) as u8
            }
            9 => self.kind as u8,
            10 => u8::from(self.locked),
            _ => 0,
        }
    }
}

/// Why a read is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapReadError {
    /// Longer than [`MAX_READ_LEN`].
    TooLong,
    /// Reaches past the memory's size.
    OutOfRange,
}

/// The live map as the memory serves it: borrowed, read byte by byte.
pub struct MapView<'a, const CELLS: usize> {
    grid: &'a OccupancyGrid<CELLS>,
    path: &'a [Cell],
    pads: [Option<PadRecord>; MAX_PADS],
    mission_state: u8,
    running: bool,
}

impl<'a, const CELLS: usize> MapView<'a, CELLS> {
    /// A view of `grid`, `path` (cut to [`MAX_PATH_POINTS`]), up to [`MAX_PADS`] pad records, the
    /// `mission.state` code and whether a mission runs.
    pub fn new(
        grid: &'a OccupancyGrid<CELLS>,
        path: &'a [Cell],
        pads: [Option<PadRecord>; MAX_PADS],
        mission_state: u8,
        running: bool,
    ) -> Self {
        Self {
            grid,
            path,
            pads,
            mission_state,
            running,
        }
    }

    /// The view of a mission: its grid, its current shortened path, the pad detector's estimate and the
    /// pad locks of both legs.
    pub fn of_mission<const QUEUE: usize>(mission: &'a Mission<CELLS, QUEUE>) -> Self {
        let detector = mission.pad_detector();
        let estimate = detector.estimate().map(|e| PadRecord {
            x_m: e.x,
            y_m: e.y,
            confidence: e.confidence,
            kind: PadKind::Estimate,
            locked: detector.locked(),
        });
        let locks = mission.stats().pad_centres;
        let lock = |c: Option<(f32, f32)>, kind| {
            c.map(|(x_m, y_m)| PadRecord {
                x_m,
                y_m,
                confidence: 1.0,
                kind,
                locked: true,
            })
        };
        Self::new(
            mission.grid(),
            mission.waypoints(),
            [
                estimate,
                lock(locks[0], PadKind::GoalLock),
                lock(locks[1], PadKind::HomeLock),
            ],
            mission.state().code(),
            mission.is_running(),
        )
    }

    /// The memory's size, bytes ([`map_memory_size`] of the grid's capacity).
    pub const fn size(&self) -> usize {
        map_memory_size(CELLS)
    }

    fn shape(&self) -> GridShape {
        self.grid.shape()
    }

    fn path_points(&self) -> usize {
        self.path.len().min(MAX_PATH_POINTS)
    }

    fn pad_count(&self) -> usize {
        self.pads.iter().flatten().count()
    }

    fn cells_len(&self) -> usize {
        self.shape().cells().min(CELLS).div_ceil(4)
    }

    /// Bytes used: header, cells, path and pad records.
    pub fn total_len(&self) -> usize {
        HEADER_LEN + self.cells_len() + self.path_points() * PATH_POINT_LEN + self.pad_count() * PAD_RECORD_LEN
    }

    /// The 2-bit code of the cell at row-major `index` (see the module docs).
    pub fn cell_code(&self, index: usize) -> u8 {
        let shape = self.shape();
        if index >= shape.cells() {
            return CELL_UNKNOWN;
        }
        let cell = shape.cell(index);
        if self.grid.is_occupied(cell) {
            CELL_OCCUPIED
        } else if self.grid.is_blocked(cell) {
            CELL_BLOCKED
        } else if self.grid.is_unknown(cell) {
            CELL_UNKNOWN
        } else {
            CELL_FREE
        }
    }

    fn flags(&self) -> u8 {
        let mut f = 0;
        if self.running {
            f |= FLAG_RUNNING;
        }
        if self.path.len() > MAX_PATH_POINTS {
            f |= FLAG_PATH_TRUNCATED;
        }
        f
    }

    /// The byte at `offset` (0 past the used part), the CRC field included.
    pub fn byte_at(&self, offset: usize) -> u8 {
        if (CRC_OFFSET..CRC_OFFSET + 4).contains(&offset) {
            return self.crc32().to_le_bytes()[offset - CRC_OFFSET];
        }
        self.plain_byte(offset)
    }

    /// CRC-32 (IEEE 802.3, reflected, as zlib's `crc32`) of bytes `12 .. total_len`.
    pub fn crc32(&self) -> u32 {
        let mut crc = Crc32::new();
        for offset in CRC_OFFSET + 4..self.total_len() {
            crc.update(self.plain_byte(offset));
        }
        crc.finish()
    }

    /// Every byte but the CRC field's (which reads 0 here).
    fn plain_byte(&self, offset: usize) -> u8 {
        if offset < HEADER_LEN {
            return self.header_byte(offset);
        }
        let cells_end = HEADER_LEN + self.cells_len();
        if offset < cells_end {
            let first = (offset - HEADER_LEN) * 4;
            let mut b = 0;
            for k in 0..4 {
                b |= self.cell_code(first + k) << (2 * k);
            }
            return b;
        }
        let path_end = cells_end + self.path_points() * PATH_POINT_LEN;
        if offset < path_end {
            let k = offset - cells_end;
            let Some(c) = self.path.get(k / PATH_POINT_LEN) else {
                return 0;
            };
            let v = if k % PATH_POINT_LEN < 2 { c.x } else { c.y };
            return v.to_le_bytes()[k % 2];
        }
        let pads_end = path_end + self.pad_count() * PAD_RECORD_LEN;
        if offset < pads_end {
            let k = offset - path_end;
            return self
                .pads
                .iter()
                .flatten()
                .nth(k / PAD_RECORD_LEN)
                .map_or(0, |p| p.byte(k % PAD_RECORD_LEN));
        }
        0
    }

    fn header_byte(&self, offset: usize) -> u8 {
        let shape = self.shape();
        let u16_at = |v: u16, base: usize| v.to_le_bytes()[offset - base];
        match offset {
            0..=3 => MAGIC[offset],
            4 => VERSION,
            5 => HEADER_LEN as u8,
            6 => CELL_BITS,
            7 => self.mission_state,
            12..=15 => (self.total_len() as u32).to_le_bytes()[offset - 12],
            16..=17 => u16_at(shape.width, 16),
            18..=19 => u16_at(shape.height, 18),
            20..=21 => u16_at(libm::roundf(CELL_SIZE_M * 1000.0) as u16, 20),
            26..=27 => u16_at(self.path_points() as u16, 26),
            28 => self.pad_count() as u8,
            29 => self.flags(),
            // CRC (8..12, see `byte_at`), origin (22..26: 0, 0) and the reserved bytes.
            _ => 0,
        }
    }

    /// Fills `out` with the bytes at `addr ..`; refused when `out` is longer than [`MAX_READ_LEN`] or the
    /// range reaches past [`Self::size`]. The CRC is computed once, only when the range touches it.
    pub fn read(&self, addr: u32, out: &mut [u8]) -> Result<(), MapReadError> {
        if out.len() > MAX_READ_LEN {
            return Err(MapReadError::TooLong);
        }
        let start = usize::try_from(addr).map_err(|_| MapReadError::OutOfRange)?;
        let end = start.checked_add(out.len()).ok_or(MapReadError::OutOfRange)?;
        if end > self.size() {
            return Err(MapReadError::OutOfRange);
        }
        let crc = (start < CRC_OFFSET + 4 && end > CRC_OFFSET).then(|| self.crc32().to_le_bytes());
        for (k, b) in out.iter_mut().enumerate() {
            let offset = start + k;
            *b = match crc {
                Some(c) if (CRC_OFFSET..CRC_OFFSET + 4).contains(&offset) => c[offset - CRC_OFFSET],
                _ => self.plain_byte(offset),
            };
        }
        Ok(())
    }
}

/// CRC-32 (polynomial 0xEDB88320 reflected, initial and final XOR 0xFFFFFFFF) fed a byte at a time, over
/// [`crate::crc::crc32_update`]: no table, 4 bytes of state.
#[derive(Clone, Copy, Debug)]
pub struct Crc32(u32);

impl Crc32 {
    /// A fresh CRC.
    pub const fn new() -> Self {
        Self(0xFFFF_FFFF)
    }

    /// Folds one byte in.
    pub fn update(&mut self, byte: u8) {
        // The one CRC-32 register of the crate (the TOC and persistent-parameter CRCs use it too).
        self.0 = crate::crc::crc32_update(self.0, &[byte]);
    }

    /// The CRC of the bytes folded in.
    pub const fn finish(self) -> u32 {
        !self.0
    }
}

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

/// The map as memory 0 of the memory service: the service learns the map's size here, and a held read is
/// answered from a view of the live map.
impl MemService {
    /// A service listing the map memory of a grid of `cells` capacity (its size is
    /// [`map_memory_size`]`(cells)`). The caller must answer every
    /// [`take_map_read`](MemService::take_map_read).
    pub fn with_map(cells: usize) -> Self {
        Self::with_map_size(u32::try_from(map_memory_size(cells)).unwrap_or(u32::MAX))
    }
}

impl MapRead {
    /// The read reply from `view`: the bytes, or status `EIO` when the range is refused.
    pub fn answer<const CELLS: usize>(&self, view: &MapView<'_, CELLS>) -> CrtpPacket {
        let mut buf = [0u8; 6 + MAX_READ_LEN];
        buf[0] = MAP_MEMORY_ID;
        buf[1..5].copy_from_slice(&self.addr.to_le_bytes());
        let len = usize::from(self.len);
        let ok = buf
            .get_mut(6..6 + len)
            .is_some_and(|out| view.read(self.addr, out).is_ok());
        buf[5] = if ok { 0 } else { STATUS_EIO };
        let n = if ok { 6 + len } else { 6 };
        // `n` ≤ 30 bytes and the port and channel are in range: `new` cannot fail.
        CrtpPacket::new(PORT_MEM, CH_READ, &buf[..n]).unwrap_or_else(|_| CrtpPacket {
            port: PORT_MEM,
            channel: CH_READ,
            data: heapless::Vec::new(),
        })
    }
}
