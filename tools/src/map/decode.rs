//! Decoding the map memory (layout version 1, `cfnav::radio_binding::map_mem`, `docs/map-memory.md`) into a
//! [`MapSnapshot`], to compare cell for cell with the simulator's own map in the same JSON form
//! (`crate::sim::map_dump`).
//!
//! The decoder reads the documented offsets itself (it does not call the firmware's serialiser), so a
//! download decoded here and the simulator's grid read through `OccupancyGrid`'s queries are two
//! independent routes to the same cells.

use serde::{Deserialize, Serialize};

/// Magic at offset 0.
pub const MAGIC: &[u8; 4] = b"CFNM";
/// The only layout version this decoder reads.
pub const VERSION: u8 = 1;
/// Header bytes.
pub const HEADER_LEN: usize = 32;

/// One pad record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PadRecord {
    /// `estimate`, `goal_lock` or `home_lock`.
    pub kind: String,
    /// Centre, arena frame, m.
    pub x_m: f32,
    /// Centre, arena frame, m.
    pub y_m: f32,
    /// Confidence 0–1 (in 1/255 steps in the memory).
    pub confidence: f32,
    /// Good enough to land on.
    pub locked: bool,
}

/// The map: cells as codes 0 unknown, 1 free, 2 blocked (inflated), 3 occupied; row-major, row 0 at y = 0.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapSnapshot {
    /// Columns.
    pub width: u16,
    /// Rows.
    pub height: u16,
    /// Cell edge, m.
    pub cell_size_m: f32,
    /// Grid origin in the arena frame, m.
    pub origin_m: [f32; 2],
    /// `mission.state` code.
    pub mission_state: u8,
    /// A mission runs.
    pub mission_running: bool,
    /// CRC-32 of the snapshot (the memory's CRC field).
    pub crc32: u32,
    /// Cell codes, `width × height`.
    pub cells: Vec<u8>,
    /// The current path, cells `(x, y)`, start first.
    pub path: Vec<[u16; 2]>,
    /// Whether the drone cut the path to the memory's capacity.
    pub path_truncated: bool,
    /// Pad records.
    pub pads: Vec<PadRecord>,
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// CRC-32 as zlib's `crc32` (reflected 0xEDB88320, initial and final XOR 0xFFFFFFFF).
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 { (c >> 1) ^ 0xEDB8_8320 } else { c >> 1 };
        }
    }
    !c
}

/// What the header says: the bytes used (`total_len`), checked for the magic and version.
pub fn header_total_len(header: &[u8]) -> Result<usize, String> {
    if header.len() < HEADER_LEN {
        return Err(format!("a map header is {HEADER_LEN} bytes, got {}", header.len()));
    }
    if &header[..4] != MAGIC {
        return Err(format!(
            "not a cfnav map memory: magic {:02x?}, expected \"CFNM\"",
            &header[..4]
        ));
    }
    if header[4] != VERSION {
        return Err(format!(
            "map layout version {} (this tool reads version {VERSION})",
            header[4]
        ));
    }
    let total = u32_at(header, 12) as usize;
    if total < HEADER_LEN {
        return Err(format!("map total length {total} is shorter than its header"));
    }
    Ok(total)
}

/// Decodes `bytes` (the memory from offset 0, at least `total_len` bytes). `Err` names what is wrong,
/// `ChangedWhileRead` in particular when the CRC does not match (the map changed during the download).
pub fn decode(bytes: &[u8]) -> Result<MapSnapshot, DecodeError> {
    let total = header_total_len(bytes).map_err(DecodeError::Bad)?;
    if bytes.len() < total {
        return Err(DecodeError::Bad(format!(
            "the map says {total} bytes, only {} were read",
            bytes.len()
        )));
    }
    let b = &bytes[..total];
    let stored = u32_at(b, 8);
    let computed = crc32(&b[12..]);
    if stored != computed {
        return Err(DecodeError::ChangedWhileRead { stored, computed });
    }
    if b[5] as usize != HEADER_LEN || b[6] != 2 {
        return Err(DecodeError::Bad(format!(
            "header length {} / {} bits per cell: version 1 has 32 / 2",
            b[5], b[6]
        )));
    }
    let width = u16_at(b, 16);
    let height = u16_at(b, 18);
    let cell_mm = u16_at(b, 20);
    let origin = [i16::from_le_bytes([b[22], b[23]]), i16::from_le_bytes([b[24], b[25]])];
    let path_points = usize::from(u16_at(b, 26));
    let pad_count = usize::from(b[28]);
    let flags = b[29];
    let n = usize::from(width) * usize::from(height);
    let cells_len = n.div_ceil(4);
    let expected = HEADER_LEN + cells_len + path_points * 4 + pad_count * 12;
    if expected != total {
        return Err(DecodeError::Bad(format!(
            "{width} × {height} cells, {path_points} path points and {pad_count} pads make {expected} bytes, \
             the header says {total}"
        )));
    }
    let cells: Vec<u8> = (0..n).map(|i| (b[HEADER_LEN + i / 4] >> (2 * (i % 4))) & 3).collect();
    let path_at = HEADER_LEN + cells_len;
    let path = (0..path_points)
        .map(|k| [u16_at(b, path_at + 4 * k), u16_at(b, path_at + 4 * k + 2)])
        .collect();
    let pads_at = path_at + path_points * 4;
    let mut pads = Vec::new();
    for k in 0..pad_count {
        let r = &b[pads_at + 12 * k..pads_at + 12 * (k + 1)];
        let kind = match r[9] {
            0 => "estimate",
            1 => "goal_lock",
            2 => "home_lock",
            other => return Err(DecodeError::Bad(format!("pad record {k} has unknown kind {other}"))),
        };
        pads.push(PadRecord {
            kind: kind.to_string(),
            x_m: f32::from_le_bytes([r[0], r[1], r[2], r[3]]),
            y_m: f32::from_le_bytes([r[4], r[5], r[6], r[7]]),
            confidence: f32::from(r[8]) / 255.0,
            locked: r[10] & 1 != 0,
        });
    }
    Ok(MapSnapshot {
        width,
        height,
        cell_size_m: f32::from(cell_mm) / 1000.0,
        origin_m: [f32::from(origin[0]) / 1000.0, f32::from(origin[1]) / 1000.0],
        mission_state: b[7],
        mission_running: flags & 1 != 0,
        crc32: stored,
        cells,
        path,
        path_truncated: flags & 2 != 0,
        pads,
    })
}

/// Why a download does not decode.
#[derive(Clone, Debug, PartialEq)]
pub enum DecodeError {
    /// The CRC does not match: the map changed during the download (read it again).
    ChangedWhileRead {
        /// The CRC field read.
        stored: u32,
        /// The CRC of the bytes read.
        computed: u32,
    },
    /// Not a map of this layout, or inconsistent.
    Bad(String),
}

impl std::fmt::Display for DecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DecodeError::ChangedWhileRead { stored, computed } => write!(
                f,
                "the map changed during the download (CRC {stored:#010x} in the header, {computed:#010x} read)"
            ),
            DecodeError::Bad(s) => f.write_str(s),
        }
    }
}
