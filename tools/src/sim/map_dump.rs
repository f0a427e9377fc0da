//! The simulator's own map, read through the grid's queries, in the JSON form `cfnav sim --serve --map-json
//! FILE` writes; a download decoded by `cfnav map` compares with it cell for cell. Memory: one
//! `bool` per cell per layer, host only.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use cfnav::mission::Mission;
use cfnav::nav::map::Cell;

/// The simulator's own map, read through the grid's queries (not through the memory's serialiser): what
/// `cfnav sim --serve --map-json FILE` writes. `crc32` is the memory's CRC of the same moment, so that a
/// download can be matched with the dump of its snapshot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimMapDump {
    /// Simulated ms since power-on.
    pub time_ms: u64,
    /// The memory's CRC field at this moment.
    pub crc32: u32,
    /// Columns.
    pub width: u16,
    /// Rows.
    pub height: u16,
    /// `mission.state` code.
    pub mission_state: u8,
    /// Per cell, row-major: occupied (after hysteresis).
    pub occupied: Vec<bool>,
    /// Per cell: blocked (inflated layer).
    pub blocked: Vec<bool>,
    /// Per cell: no evidence.
    pub unknown: Vec<bool>,
    /// The mission's shortened path, cells.
    pub path: Vec<[u16; 2]>,
    /// The pad detector's estimate `(x, y, confidence, locked)`.
    pub pad_estimate: Option<(f32, f32, f32, bool)>,
    /// The pad locks of the outbound and return legs.
    pub pad_locks: [Option<(f32, f32)>; 2],
}

impl SimMapDump {
    /// The dump of `mission` at `time_ms`; `crc32` from the memory's view of the same moment.
    pub fn of_mission<const CELLS: usize, const QUEUE: usize>(
        mission: &Mission<CELLS, QUEUE>,
        time_ms: u64,
        crc32: u32,
    ) -> Self {
        let grid = mission.grid();
        let shape = grid.shape();
        let cells: Vec<Cell> = (0..shape.cells()).map(|i| shape.cell(i)).collect();
        let detector = mission.pad_detector();
        Self {
            time_ms,
            crc32,
            width: shape.width,
            height: shape.height,
            mission_state: mission.state().code(),
            occupied: cells.iter().map(|&c| grid.is_occupied(c)).collect(),
            blocked: cells.iter().map(|&c| grid.is_blocked(c)).collect(),
            unknown: cells.iter().map(|&c| grid.is_unknown(c)).collect(),
            path: mission.waypoints().iter().map(|c| [c.x, c.y]).collect(),
            pad_estimate: detector.estimate().map(|e| (e.x, e.y, e.confidence, detector.locked())),
            pad_locks: mission.stats().pad_centres,
        }
    }
}

/// Writes the simulator's own map (`SimMapDump`) to `path` atomically (a temporary file renamed over it).
pub fn write_sim_dump<const CELLS: usize, const QUEUE: usize>(
    path: &Path,
    mission: &Mission<CELLS, QUEUE>,
    time_ms: u64,
    crc32: u32,
) -> Result<(), String> {
    let dump = SimMapDump::of_mission(mission, time_ms, crc32);
    let text = serde_json::to_string(&dump).map_err(|e| format!("cannot encode the map: {e}"))?;
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, text).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display()))
}
