//! The records the simulator and the emulator both write: a [`Landing`] (in `cfnav sim --json`'s report,
//! docs/formats.md, report format; and in the emulator's `--sim-json` counterpart) and the emulator's `--track` file
//! ([`Track`], [`TrackPoint`]), which `cfnav pil --plot` reads back to draw with the simulator's figure.
//! One definition for the writer and the reader, so a renamed field cannot pass unnoticed.
//!
//! Units: SI, arena frame; times in seconds.

use serde::{Deserialize, Serialize};

/// One landing: where the drone came to rest.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Landing {
    /// The pad it landed on, or the nearest pad (0 = home).
    pub pad: usize,
    /// Horizontal distance from where it rests to that pad's centre, m.
    pub error_m: f32,
    /// Its centre lies over the pad.
    pub on_pad: bool,
}

/// One point of the emulator's track: what the image believed, paired with the truth at the same instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackPoint {
    /// The image's time stamp, s.
    pub t_s: f64,
    /// The true position at that time, arena frame, m.
    pub truth: [f32; 3],
    /// The image's position estimate, arena frame, m.
    pub estimate: [f32; 3],
    /// The body was off the ground (the truth's contact model).
    pub airborne: bool,
    /// `mission.state`.
    pub state: u8,
}

/// The file the emulator's `--track` writes.
#[derive(Debug, Serialize, Deserialize)]
pub struct Track {
    /// The world file flown, or `None` for the default world.
    pub world_path: Option<String>,
    pub world: String,
    pub seed: u64,
    /// `round_trip` or `hover`.
    pub mode: String,
    pub outcome: String,
    pub reason: Option<String>,
    pub mission_time_s: Option<f64>,
    pub mission_state: Option<u32>,
    pub collisions: u32,
    pub min_clearance_m: Option<f32>,
    pub landings: Vec<Landing>,
    pub distance_m: f64,
    pub virtual_s: f64,
    pub wall_s: f64,
    pub points: Vec<TrackPoint>,
}
