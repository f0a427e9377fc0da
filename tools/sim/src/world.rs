//! The simulator's world: world files (docs/formats.md, world files), the built-in default world, random
//! worlds, and the geometry the simulator needs (ray casts for the rangers, the body's clearance for
//! collisions, the surface under the drone, the pads).
//!
//! # World files
//!
//! TOML, in metres, in the arena frame (origin at the arena's lower-left corner on the floor, z up). The
//! fields are those of docs/formats.md (world files); unknown fields are errors. Defaults and limits:
//!
//! | field | default | accepted |
//! |---|---|---|
//! | `name` | the file's stem | 1 to 64 printable characters |
//! | `arena.size` | required | 0.5 ≤ x ≤ 6.4, 0.5 ≤ y ≤ 3.2 ([`MAX_ARENA_M`]: `cfnav::nav::map`'s widest and deepest grid), multiples of 0.05 m (whole 5 cm map cells) |
//! | `arena.ceiling` | 2.5 | 0 < ceiling ≤ 10 |
//! | `arena.walls` | all four | a list of distinct side names `"south"` (y = 0), `"east"` (x = max), `"north"` (y = max), `"west"` (x = 0); stored as [`Arena::walls`] (bits 1, 2, 4, 8) |
//! | `mission.placed` | `start`, yaw 0 | `[x, y, yaw_deg]`: strictly inside the arena, \|yaw\| ≤ 180, the body clear as at `start` |
//! | `mission.start`, `.goal` | required | strictly inside the arena; the body disc at `start` clears the walls, boxes and cylinders, and it stands either on a pad's top or clear of the pads' sides |
//! | `mission.height` | 0.5 | 0.2 ≤ height < ceiling |
//! | `mission.speed` | 0.5 | 0 < speed ≤ 2 |
//! | `[[pads]]`, `[[boxes]]` `yaw` | 0 | finite, degrees counter-clockwise about the centre; overlap and inside-the-arena rules read a turned footprint's bounding rectangle |
//! | `[[polygons]]` `points` | required | 3 to 64 corners inside the arena, counter-clockwise, no two edges crossing or touching but neighbours at their shared corner; at most 64 polygons |
//! | `[[polygons]]` `height` | the ceiling | 0 < height ≤ ceiling |
//! | `[[movers]]` `radius`, `speed`, `path` | required | 0 < radius ≤ 1 m; 0 ≤ speed ≤ 0.5 m/s; 1 to 64 points inside the arena, the first clear of the body at `start`; at most 64 movers |
//! | `[[movers]]` `height` | 1.8 (at most the ceiling) | 0 < height ≤ ceiling |
//! | `[[floor]]` `min`, `max` | required | min < max, inside the arena; at most 64 patches |
//! | `[[floor]]` `squal`, `flow_dropout` | the sensor's own | 0..255; 0..1 |
//! | `[[pads]]` `size`, `height` | required | each side 0.2..0.4 m ([`PAD_SIDE_M`]), 0.05..0.2 m high ([`PAD_HEIGHT_M`]) and below `mission.height` |
//! | `[[pads]]` `center`, `size`, `height` | required | 2 to 16 pads, the first is home, the last the goal pad; footprints inside the arena, not overlapping each other or any obstacle; 0 < height < `mission.height`; home within 0.35 m of `start`, goal pad within 0.35 m of `goal` (centre to centre) |
//! | `[[boxes]]` `min`, `max` | required | min < max, inside the arena; at most 256 |
//! | `[[boxes]]`, `[[cylinders]]` `height` | the ceiling | 0 < height ≤ ceiling |
//! | `[[cylinders]]` `center`, `radius` | required | centre inside the arena, radius > 0; at most 256 |
//! | `sim.seed` | 0 | any `u64` |
//! | `sim.time_limit` | 300 | 0 < seconds ≤ 3600 |
//! | `sim.expect` | `"completed"` | **schema addition**: `"completed"`, `"no_path"` or `"pad_not_found"` |
//! | `[sensors]`, `[disturbances]` | the simulator's own | every key optional; keys, units and ranges in [`super::stress`] |
//!
//! `sim.expect` says how a run of the world should end: `"completed"` names the report's `outcome`, any other
//! value its `reason` (docs/formats.md, report format). Failure worlds shipped in `worlds/` also carry a `fail-` file-name
//! prefix so that scripts can tell them apart without parsing them.
//!
//! Errors are one line: `FILE: line N: FIELD: what was wrong; what was expected` (the line and field when
//! known). Nothing here panics on any input.
//!
//! # Arena size and the firmware's capacity
//!
//! Worlds up to 6.4 × 3.2 m (128 × 64 cells, the largest grid the firmware maps) load. The default firmware
//! build holds 120 × 60 = 7200 cells; a world with more cells ([`World::needs_large_arena`]) needs the
//! `large-arena` build of the firmware. The simulator always flies the `large-arena` grid capacity and says
//! so in each report (`needs_large_arena`) and in a batch's summary (`large_arena_runs`).
//!
//! # Shipped worlds (`worlds/`)
//!
//! `default` (= [`World::default_world`]), `two-walls` (the world-file example of docs/formats.md), `slalom`, `boxes`,
//! `corridor`, `cylinders`, `low-box`, `far-pads`; failure worlds `fail-enclosed-goal` and `fail-narrow-gap`
//! (`expect = "no_path"`). Each file's header comment says what it tests.
//!
//! # Random worlds
//!
//! Three generators (`cfnav sim --random N --generator wide|classic|rooms`; `rooms` is described in its own
//! module, `world/rooms.rs`); a candidate is kept only if it validates
//! and [`World::is_solvable`] with [`SOLVABILITY_INFLATION_M`], otherwise the generator draws again from
//! the same random stream, so a seed always gives the same world.
//!
//! [`World::random`] (`wide`, the default) draws what real arenas have: a 4–6.4 × 2–3.2 m
//! arena ([`WIDE_ARENA_MIN_M`]..[`WIDE_ARENA_MAX_M`]); the take-off point 0.5–0.9 m from one end and the
//! nominal goal 0.5–0.9 m from the other; the home pad under the take-off point (within 5 cm) or, one world
//! in six, beside it (0.25–0.35 m, the drone starting on the floor [`START_PAD_GAP_M`] or more from its sides); the goal pad 0.05–0.35 m from the
//! nominal goal, or (one world in three) 0.1–0.25 m from a side or end wall with the nominal goal within
//! 0.35 m of it. Then either a zig-zag corridor (about one world in three: 2–4 walls across the arena whose
//! 0.6–0.9 m gaps alternate between the two side walls, so every turn lies next to an arena wall) or 0–3
//! walls with a 0.6–1 m gap anywhere; one world in three an obstacle (box or cylinder) 0.1–0.25 m from the
//! goal pad ([`NEAR_PAD_GAP_M`]); one world in three a forest of 4–9 thin cylinders (radius
//! [`FOREST_RADIUS_M`]) 0.3–1.1 m from the goal pad's centre, 0.1 m or more from the pad and 0.5–0.7 m apart;
//! and up to three boxes and three cylinders anywhere. Everything keeps [`KEEP_OUT_M`] from the take-off
//! point and the home pad; the walls and the free obstacles keep it from the goal end too.
//!
//! [`World::random_classic`] (`classic`) is the older generator of the earlier figures, kept seed for seed:
//! a 4.5–6 × 2.4–3 m arena, the home pad within 5 cm of the take-off point and the goal pad 5–30 cm from the
//! nominal goal, one to three walls with a 0.6–1 m gap, up to four boxes and four cylinders 1 m tall up to
//! the ceiling, every obstacle [`KEEP_OUT_M`] from the pads, the take-off point and the nominal goal.
//!
//! Arenas larger than the default firmware build's 120 × 60 cells (about 6 % of the wide worlds) are flown,
//! like every world, on the `large-arena` build's grid (the simulator's `cfnav_tools::sim::runner::SIM_CELLS`);
//! their reports say `needs_large_arena`, and the batch summary counts them (`large_arena_runs`). The default
//! firmware build would refuse them at the start (`StartRefusal::BadArena`), so with that build such a world
//! cannot be flown at all, never flown on a grid too small.

//! # Geometry
//!
//! The solid world is everything outside the arena's interior box `(0, W) × (0, H) × (0, ceiling)` (the four
//! walls, the floor and the ceiling), plus boxes and pads (boxes from the floor to their height, possibly
//! turned about their centre), vertical cylinders, prisms over polygons, and the movers where they stand now
//! (cylinders; [`World::step_movers`] walks them). Solids are closed sets: a point on a surface is inside.
//!
//! An open side (`arena.walls`) has no wall: the floor and the ceiling go on beyond it, rays pass out to
//! their range, the body may cross it (the simulator then ends the run, `left_arena`), and each wall that
//! exists is its side's segment, not a half-plane. Floor patches change only the flow sensor's readings
//! ([`crate::physics::Geometry::flow_floor`]).

use std::collections::HashMap;
use std::fmt;
use std::ops::Range;
use std::path::Path;

use cfnav::nav::map::{GridShape, MAX_HEIGHT_CELLS, MAX_WIDTH_CELLS};

use super::stress::{Disturbances, RawDisturbances, RawSensors, SensorStress, Stress};
use serde::Deserialize;
use toml::Spanned;

mod geometry;
mod random;
mod rooms;

pub use random::{
    FOREST_PAD_GAP_M, FOREST_RADIUS_M, Generator, KEEP_OUT_M, NEAR_PAD_GAP_M, SOLVABILITY_INFLATION_M, START_PAD_GAP_M,
    WIDE_ARENA_MAX_M, WIDE_ARENA_MIN_M,
};
pub use rooms::{ROOM_MIN_M, room_capacity};

impl Stress {
    /// Read a `--stress FILE`: either a whole world file (its `[sensors]` and `[disturbances]` are taken) or
    /// a file with only those tables (and an optional `name`). Errors are one line naming the file, the line
    /// and the key.
    pub fn load(path: impl AsRef<Path>) -> Result<Stress, String> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| format!("{file}: cannot read: {e}"))?;
        Self::from_toml_str(&text, &file)
    }

    /// [`Stress::load`] on a text.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Stress, String> {
        if Self::is_world_file(text, file)? {
            return World::from_toml_str(text, file)
                .map(|w| w.stress)
                .map_err(|e| e.to_string());
        }
        Self::from_tables_toml_str(text, file)
    }
}

/// Radius of the drone's body disc: touching an obstacle with it is a collision (docs/formats.md, world files).
pub const BODY_RADIUS_M: f32 = 0.06;
/// Largest arena the firmware maps (`cfnav::nav::map`'s widest and deepest grid at 5 cm cells), metres.
pub const MAX_ARENA_M: [f32; 2] = [
    MAX_WIDTH_CELLS as f32 * cfnav::nav::map::CELL_SIZE_M,
    MAX_HEIGHT_CELLS as f32 * cfnav::nav::map::CELL_SIZE_M,
];
/// Smallest arena side accepted, metres.
pub const MIN_ARENA_M: f32 = 0.5;
/// Cells of the default firmware build's grid (120 × 60, a 6 × 3 m arena).
pub const DEFAULT_FIRMWARE_CELLS: usize = 120 * 60;
/// Cells of the `large-arena` firmware build's grid (128 × 64, 6.4 × 3.2 m).
pub const LARGE_ARENA_CELLS: usize = 128 * 64;
/// Ceiling when `arena.ceiling` is absent, metres.
pub const DEFAULT_CEILING_M: f32 = 2.5;
/// Highest ceiling accepted, metres.
pub const MAX_CEILING_M: f32 = 10.0;
/// Cruise height when `mission.height` is absent, metres.
pub const DEFAULT_HEIGHT_M: f32 = 0.5;
/// Lowest cruise height (the firmware refuses lower ones), metres.
pub const MIN_HEIGHT_M: f32 = 0.2;
/// Cruise speed when `mission.speed` is absent, m/s.
pub const DEFAULT_SPEED_MPS: f32 = 0.5;
/// Fastest cruise speed accepted, m/s.
pub const MAX_SPEED_MPS: f32 = 2.0;
/// Farthest a pad may lie from its nominal point (`mission.start` for home, `mission.goal` for the goal
/// pad), centre to centre, metres.
pub const MAX_PAD_OFFSET_M: f32 = 0.35;
/// Simulated-time limit when `sim.time_limit` is absent, seconds.
pub const DEFAULT_TIME_LIMIT_S: f32 = 300.0;
/// Longest simulated-time limit accepted, seconds.
pub const MAX_TIME_LIMIT_S: f32 = 3600.0;
/// Most pads a world may have.
pub const MAX_PADS: usize = 16;
/// Most boxes, and most cylinders, a world may have.
pub const MAX_OBSTACLES: usize = 256;
/// Smallest and largest pad side accepted, metres.
pub const PAD_SIDE_M: [f32; 2] = [0.2, 0.4];
/// Lowest and highest pad accepted, metres.
pub const PAD_HEIGHT_M: [f32; 2] = [0.05, 0.2];
/// Most corners of a polygon, and most points of a mover's path.
pub const MAX_POLYGON_POINTS: usize = 64;
/// Most polygons, movers and floor patches a world may have (each).
pub const MAX_ROOM_ITEMS: usize = 64;
/// Fastest mover accepted, m/s.
pub const MAX_MOVER_SPEED_MPS: f32 = 0.5;
/// A mover pauses while its next step would bring its side within this of the drone's body, metres.
pub const MOVER_GIVE_WAY_M: f32 = 0.25;
/// Height of a mover when `height` is absent (a person; at most the ceiling), metres.
pub const DEFAULT_MOVER_HEIGHT_M: f32 = 1.8;
/// Obstacles taller than this count as occupied in [`World::true_occupancy`], metres.
pub const OCCUPANCY_MIN_HEIGHT_M: f32 = 0.3;

/// Slack for comparisons against limits written in the file (f32 rounding), metres.
const EPS: f32 = 1e-4;

/// A world: the arena, the mission, the pads and obstacles, the simulation settings.
#[derive(Clone, Debug, PartialEq)]
pub struct World {
    /// Shown in reports (`world`).
    pub name: String,
    /// The walled arena.
    pub arena: Arena,
    /// What the drone is told.
    pub mission: Mission,
    /// Landing pads; the first is home, the last the goal pad. At least two.
    pub pads: Vec<Pad>,
    /// Solid boxes standing on the floor, possibly turned about their centre.
    pub boxes: Vec<BoxObstacle>,
    /// Vertical solid cylinders standing on the floor.
    pub cylinders: Vec<Cylinder>,
    /// Solid prisms over simple polygons standing on the floor.
    pub polygons: Vec<Polygon>,
    /// People walking: vertical cylinders moving back and forth along a path.
    pub movers: Vec<Mover>,
    /// Floor patches the flow sensor reads poorly.
    pub floor: Vec<FloorPatch>,
    /// Seed, time limit, expected outcome.
    pub sim: SimSettings,
    /// `[sensors]` and `[disturbances]` (stress testing; empty: the simulator's defaults).
    pub stress: Stress,
}

/// `[arena]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arena {
    /// Extent along x and y, metres; the arena spans `[0, size[0]] × [0, size[1]]`.
    pub size: [f32; 2],
    /// Height of the ceiling, metres.
    pub ceiling: f32,
    /// The sides that have a wall, a bitmask of [`WALL_SOUTH`], [`WALL_EAST`], [`WALL_NORTH`] and
    /// [`WALL_WEST`] (`walls = ["south", ...]`); [`ALL_WALLS`] by default. An open side has no wall: the floor
    /// and the ceiling go on beyond it and nothing stands there.
    pub walls: u8,
}

/// `walls` bit of the side y = 0.
pub const WALL_SOUTH: u8 = 1;
/// `walls` bit of the side x = `size[0]`.
pub const WALL_EAST: u8 = 2;
/// `walls` bit of the side y = `size[1]`.
pub const WALL_NORTH: u8 = 4;
/// `walls` bit of the side x = 0.
pub const WALL_WEST: u8 = 8;
/// Every side walled (the default).
pub const ALL_WALLS: u8 = 15;
/// The side names of `arena.walls`, with their bits.
pub const WALL_NAMES: [(&str, u8); 4] = [
    ("south", WALL_SOUTH),
    ("east", WALL_EAST),
    ("north", WALL_NORTH),
    ("west", WALL_WEST),
];

impl Arena {
    /// Whether the side with bit `side` has a wall.
    pub fn has_wall(&self, side: u8) -> bool {
        self.walls & side != 0
    }

    /// Whether a true position lies beyond an open side (outside the arena where it has no wall).
    pub fn left_through_open_side(&self, x: f32, y: f32) -> bool {
        let [w, h] = self.size;
        (!self.has_wall(WALL_SOUTH) && y < 0.0)
            || (!self.has_wall(WALL_EAST) && x > w)
            || (!self.has_wall(WALL_NORTH) && y > h)
            || (!self.has_wall(WALL_WEST) && x < 0.0)
    }
}

/// `[mission]`: the parameters the drone is given (`mission.startX/Y`, `goalX/Y`, `height`, `speed`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mission {
    /// Where the drone stands at power-on, metres.
    pub start: [f32; 2],
    /// The nominal goal; the goal pad lies near it, metres.
    pub goal: [f32; 2],
    /// Cruise height, metres.
    pub height: f32,
    /// Cruise speed, m/s.
    pub speed: f32,
    /// Where the drone truly stands at power-on, `[x, y, yaw_deg]` (yaw counter-clockwise from +x); `None`:
    /// `start`, yaw 0. The drone is told `start` and believes yaw 0 either way.
    pub placed: Option<[f32; 3]>,
}

impl Mission {
    /// The true power-on pose: `(x, y, yaw rad)`.
    pub fn true_start(&self) -> ([f32; 2], f32) {
        match self.placed {
            Some([x, y, yaw_deg]) => ([x, y], yaw_deg.to_radians()),
            None => (self.start, 0.0),
        }
    }
}

/// `[[pads]]`: a landing pad, a box standing on the floor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pad {
    /// Centre of its footprint, metres.
    pub center: [f32; 2],
    /// Extent along x and y, metres.
    pub size: [f32; 2],
    /// Height of its top, metres.
    pub height: f32,
    /// Turned by this about its centre, degrees counter-clockwise (0: sides along x and y).
    pub yaw_deg: f32,
}

/// `[[boxes]]`: a solid box from the floor up: `min`..`max` turned by `yaw_deg` about its centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxObstacle {
    /// Lower-left corner of its footprint before the turn, metres.
    pub min: [f32; 2],
    /// Upper-right corner of its footprint before the turn, metres.
    pub max: [f32; 2],
    /// Height of its top, metres.
    pub height: f32,
    /// Turned by this about its centre, degrees counter-clockwise (0: axis-aligned).
    pub yaw_deg: f32,
}

/// `[[polygons]]`: a solid prism from the floor up over a simple polygon (corners counter-clockwise).
#[derive(Clone, Debug, PartialEq)]
pub struct Polygon {
    /// Corners, counter-clockwise, metres; 3 to [`MAX_POLYGON_POINTS`].
    pub points: Vec<[f32; 2]>,
    /// Height of its top, metres.
    pub height: f32,
}

/// `[[movers]]`: a person walking, a vertical solid cylinder that walks its path to the end, turns and walks
/// back, at `speed`, pausing while its next step would bring it within [`MOVER_GIVE_WAY_M`] of the drone's
/// body (see [`World::step_movers`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Mover {
    /// Radius, metres.
    pub radius: f32,
    /// Height of its top, metres.
    pub height: f32,
    /// Walking speed, m/s (0..[`MAX_MOVER_SPEED_MPS`]; 0 stands still at the path's first point).
    pub speed: f32,
    /// The polyline walked back and forth, metres; 1 to [`MAX_POLYGON_POINTS`] points.
    pub path: Vec<[f32; 2]>,
    /// State, not read from files: how far it has walked along the back-and-forth cycle since power-on, m.
    pub walked_m: f32,
}

/// `[[floor]]`: a floor patch the flow sensor reads poorly (glossy tiles, a plain rug).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloorPatch {
    /// Lower-left corner, metres.
    pub min: [f32; 2],
    /// Upper-right corner, metres.
    pub max: [f32; 2],
    /// The PMW3901's SQUAL over it (0..255), in place of the height model's; `None`: unchanged.
    pub squal: Option<u8>,
    /// Probability that a reading over it is invalid (0..1); `None`: the sensor's own.
    pub flow_dropout: Option<f32>,
}

/// `[[cylinders]]`: a vertical solid cylinder from the floor up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    /// Centre of its footprint, metres.
    pub center: [f32; 2],
    /// Radius, metres.
    pub radius: f32,
    /// Height of its top, metres.
    pub height: f32,
}

/// `[sim]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSettings {
    /// Seed of the sensor noise, drift and start-up jitter.
    pub seed: u64,
    /// Simulated time allowed, seconds.
    pub time_limit: f32,
    /// How a run of this world should end.
    pub expect: Expect,
}

/// `sim.expect` (a schema addition): how a run of the world should end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Expect {
    /// The report's `outcome` is `completed`.
    #[default]
    Completed,
    /// The mission ends without completing, `reason` `no_path` (e.g. the goal lies in a closed room).
    NoPath,
    /// The mission ends without completing, `reason` `pad_not_found`.
    PadNotFound,
}

impl Expect {
    /// The word as written in world files and reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Expect::Completed => "completed",
            Expect::NoPath => "no_path",
            Expect::PadNotFound => "pad_not_found",
        }
    }
}

/// A world that could not be loaded or is not valid: which file, which line and field, what was expected.
/// Its `Display` is one line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorldError {
    /// The file (as given), or `world "NAME"` for a world built in code.
    pub file: String,
    /// 1-based line of the offending text, when known.
    pub line: Option<usize>,
    /// The offending field (`mission.start`, `pads[1].center`, ...), when known.
    pub field: Option<String>,
    /// What was wrong and what was expected.
    pub message: String,
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut text = one_line(&self.file);
        if let Some(line) = self.line {
            text.push_str(&format!(": line {line}"));
        }
        if let Some(field) = &self.field {
            text.push_str(": ");
            text.push_str(&one_line(field));
        }
        text.push_str(": ");
        text.push_str(&one_line(&self.message));
        f.write_str(&text)
    }
}

impl std::error::Error for WorldError {}

/// Collapse any line breaks and control characters so that a message stays on one line.
fn one_line(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '\n' | '\r' | '\t' => {
                if !out.ends_with(' ') {
                    out.push(' ');
                }
            }
            c if c.is_control() => out.push_str(&c.escape_default().to_string()),
            c => out.push(c),
        }
    }
    out.trim_end().to_string()
}

/// A validation failure before it is placed in a file.
#[derive(Debug)]
struct Invalid {
    field: String,
    message: String,
}

fn invalid<T>(field: impl Into<String>, message: impl Into<String>) -> Result<T, Invalid> {
    Err(Invalid {
        field: field.into(),
        message: message.into(),
    })
}

// ---------------------------------------------------------------------------------------------------------
// Parsing

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawWorld {
    name: Option<Spanned<String>>,
    arena: Spanned<RawArena>,
    mission: Spanned<RawMission>,
    #[serde(default)]
    pads: Vec<Spanned<RawPad>>,
    #[serde(default)]
    boxes: Vec<Spanned<RawBox>>,
    #[serde(default)]
    cylinders: Vec<Spanned<RawCylinder>>,
    #[serde(default)]
    polygons: Vec<Spanned<RawPolygon>>,
    #[serde(default)]
    movers: Vec<Spanned<RawMover>>,
    #[serde(default)]
    floor: Vec<Spanned<RawFloor>>,
    sim: Option<Spanned<RawSim>>,
    sensors: Option<Spanned<RawSensors>>,
    disturbances: Option<Spanned<RawDisturbances>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawArena {
    size: Spanned<Vec<f32>>,
    ceiling: Option<Spanned<f32>>,
    walls: Option<Spanned<Vec<String>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMission {
    start: Spanned<Vec<f32>>,
    goal: Spanned<Vec<f32>>,
    height: Option<Spanned<f32>>,
    speed: Option<Spanned<f32>>,
    placed: Option<Spanned<Vec<f32>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPad {
    center: Spanned<Vec<f32>>,
    size: Spanned<Vec<f32>>,
    height: Spanned<f32>,
    yaw: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBox {
    min: Spanned<Vec<f32>>,
    max: Spanned<Vec<f32>>,
    height: Option<Spanned<f32>>,
    yaw: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPolygon {
    points: Spanned<Vec<Vec<f32>>>,
    height: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMover {
    radius: Spanned<f32>,
    height: Option<Spanned<f32>>,
    speed: Spanned<f32>,
    path: Spanned<Vec<Vec<f32>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFloor {
    min: Spanned<Vec<f32>>,
    max: Spanned<Vec<f32>>,
    squal: Option<Spanned<i64>>,
    flow_dropout: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCylinder {
    center: Spanned<Vec<f32>>,
    radius: Spanned<f32>,
    height: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSim {
    seed: Option<Spanned<u64>>,
    time_limit: Option<Spanned<f32>>,
    expect: Option<Spanned<Expect>>,
}

/// Where each field of a parsed file was written (byte ranges), by field path.
#[derive(Default)]
struct Spans(HashMap<String, Range<usize>>);

impl Spans {
    fn add(&mut self, field: &str, span: Range<usize>) {
        self.0.insert(field.to_string(), span);
    }

    /// The span of `field`, or of the nearest enclosing table that has one.
    fn find(&self, mut field: &str) -> Option<&Range<usize>> {
        loop {
            if let Some(span) = self.0.get(field) {
                return Some(span);
            }
            let cut = field.rfind(['.', '['])?;
            field = &field[..cut];
        }
    }

    fn value<T>(&mut self, field: &str, v: Spanned<T>) -> T {
        self.add(field, v.span());
        v.into_inner()
    }

    fn optional<T>(&mut self, field: &str, v: Option<Spanned<T>>) -> Option<T> {
        v.map(|v| self.value(field, v))
    }

    fn points(&mut self, field: &str, v: Spanned<Vec<Vec<f32>>>) -> Result<Vec<[f32; 2]>, Invalid> {
        let v = self.value(field, v);
        if v.len() > MAX_POLYGON_POINTS {
            return invalid(
                field,
                format!("{} points; expected at most {MAX_POLYGON_POINTS}", v.len()),
            );
        }
        v.iter()
            .enumerate()
            .map(|(i, p)| match p.as_slice() {
                &[x, y] => Ok([x, y]),
                other => invalid(
                    format!("{field}[{i}]"),
                    format!("expected 2 numbers [x, y], found an array of {}", other.len()),
                ),
            })
            .collect()
    }

    fn pair(&mut self, field: &str, v: Spanned<Vec<f32>>) -> Result<[f32; 2], Invalid> {
        match self.value(field, v).as_slice() {
            &[x, y] => Ok([x, y]),
            other => invalid(
                field,
                format!("expected 2 numbers [x, y], found an array of {}", other.len()),
            ),
        }
    }
}

/// 1-based line of a byte offset.
fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    1 + text.as_bytes()[..end].iter().filter(|&&b| b == b'\n').count()
}

/// The table header (`[arena]`, `[[pads]]`) written on a 1-based line, if that line is one.
fn header_on(text: &str, line: usize) -> Option<String> {
    let l = text.lines().nth(line.checked_sub(1)?)?.trim();
    if !l.starts_with('[') {
        return None;
    }
    let end = l.rfind(']')?;
    Some(l[..=end].to_string())
}

/// Turn a TOML/serde error into one line naming the line and what was expected.
fn toml_error(text: &str, file: &str, e: &toml::de::Error) -> WorldError {
    let mut message = one_line(e.message())
        .replace("expected f32", "expected a number")
        .replace("expected u64", "expected a whole number ≥ 0")
        .replace("expected a sequence", "expected an array")
        .replace("expected a string", "expected a quoted string");
    let mut line = e.span().map(|s| line_of(text, s.start));
    if let Some(field) = message
        .strip_prefix("missing field `")
        .and_then(|rest| rest.strip_suffix('`'))
        .map(str::to_string)
    {
        if field == "arena" || field == "mission" {
            message = format!(
                "missing table [{field}]; every world needs [arena] and [mission] (docs/formats.md, world files)"
            );
            line = None;
        } else if let Some(header) = line.and_then(|l| header_on(text, l)) {
            message = format!("missing field `{field}` in {header}");
        }
    }
    WorldError {
        file: file.to_string(),
        line,
        field: None,
        message,
    }
}

fn convert(raw: RawWorld, default_name: &str, spans: &mut Spans) -> Result<World, Invalid> {
    let name = spans
        .optional("name", raw.name)
        .unwrap_or_else(|| default_name.to_string());

    spans.add("arena", raw.arena.span());
    let a = raw.arena.into_inner();
    let size = spans.pair("arena.size", a.size)?;
    let ceiling = spans.optional("arena.ceiling", a.ceiling).unwrap_or(DEFAULT_CEILING_M);
    let mut walls = ALL_WALLS;
    if let Some(names) = spans.optional("arena.walls", a.walls) {
        walls = 0;
        for name in &names {
            let Some(&(_, bit)) = WALL_NAMES.iter().find(|(n, _)| n == name) else {
                return invalid(
                    "arena.walls",
                    format!("{name:?} is not a side; expected a list of \"south\", \"east\", \"north\", \"west\""),
                );
            };
            if walls & bit != 0 {
                return invalid(
                    "arena.walls",
                    format!("{name:?} is listed twice; expected each side once"),
                );
            }
            walls |= bit;
        }
    }

    spans.add("mission", raw.mission.span());
    let m = raw.mission.into_inner();
    let mission = Mission {
        start: spans.pair("mission.start", m.start)?,
        goal: spans.pair("mission.goal", m.goal)?,
        height: spans.optional("mission.height", m.height).unwrap_or(DEFAULT_HEIGHT_M),
        speed: spans.optional("mission.speed", m.speed).unwrap_or(DEFAULT_SPEED_MPS),
        placed: match spans.optional("mission.placed", m.placed) {
            None => None,
            Some(v) => match v.as_slice() {
                &[x, y, yaw] => Some([x, y, yaw]),
                other => {
                    return invalid(
                        "mission.placed",
                        format!("expected 3 numbers [x, y, yaw_deg], found an array of {}", other.len()),
                    );
                }
            },
        },
    };

    if let Some(first) = raw.pads.first() {
        spans.add("pads", first.span());
    }
    let mut pads = Vec::with_capacity(raw.pads.len().min(MAX_PADS + 1));
    for (i, p) in raw.pads.into_iter().enumerate() {
        let f = format!("pads[{i}]");
        spans.add(&f, p.span());
        let p = p.into_inner();
        pads.push(Pad {
            center: spans.pair(&format!("{f}.center"), p.center)?,
            size: spans.pair(&format!("{f}.size"), p.size)?,
            height: spans.value(&format!("{f}.height"), p.height),
            yaw_deg: spans.optional(&format!("{f}.yaw"), p.yaw).unwrap_or(0.0),
        });
    }

    let mut boxes = Vec::with_capacity(raw.boxes.len().min(MAX_OBSTACLES + 1));
    for (i, b) in raw.boxes.into_iter().enumerate() {
        let f = format!("boxes[{i}]");
        spans.add(&f, b.span());
        let b = b.into_inner();
        boxes.push(BoxObstacle {
            min: spans.pair(&format!("{f}.min"), b.min)?,
            max: spans.pair(&format!("{f}.max"), b.max)?,
            height: spans.optional(&format!("{f}.height"), b.height).unwrap_or(ceiling),
            yaw_deg: spans.optional(&format!("{f}.yaw"), b.yaw).unwrap_or(0.0),
        });
    }

    let mut polygons = Vec::with_capacity(raw.polygons.len().min(MAX_ROOM_ITEMS + 1));
    for (i, q) in raw.polygons.into_iter().enumerate() {
        let f = format!("polygons[{i}]");
        spans.add(&f, q.span());
        let q = q.into_inner();
        polygons.push(Polygon {
            points: spans.points(&format!("{f}.points"), q.points)?,
            height: spans.optional(&format!("{f}.height"), q.height).unwrap_or(ceiling),
        });
    }

    let mut movers = Vec::with_capacity(raw.movers.len().min(MAX_ROOM_ITEMS + 1));
    for (i, m) in raw.movers.into_iter().enumerate() {
        let f = format!("movers[{i}]");
        spans.add(&f, m.span());
        let m = m.into_inner();
        movers.push(Mover {
            radius: spans.value(&format!("{f}.radius"), m.radius),
            height: spans
                .optional(&format!("{f}.height"), m.height)
                .unwrap_or(DEFAULT_MOVER_HEIGHT_M.min(ceiling)),
            speed: spans.value(&format!("{f}.speed"), m.speed),
            path: spans.points(&format!("{f}.path"), m.path)?,
            walked_m: 0.0,
        });
    }

    let mut floor = Vec::with_capacity(raw.floor.len().min(MAX_ROOM_ITEMS + 1));
    for (i, p) in raw.floor.into_iter().enumerate() {
        let f = format!("floor[{i}]");
        spans.add(&f, p.span());
        let p = p.into_inner();
        let squal = match spans.optional(&format!("{f}.squal"), p.squal) {
            None => None,
            Some(q) => match u8::try_from(q) {
                Ok(q) => Some(q),
                Err(_) => return invalid(format!("{f}.squal"), format!("{q}; expected 0 ≤ squal ≤ 255")),
            },
        };
        floor.push(FloorPatch {
            min: spans.pair(&format!("{f}.min"), p.min)?,
            max: spans.pair(&format!("{f}.max"), p.max)?,
            squal,
            flow_dropout: spans.optional(&format!("{f}.flow_dropout"), p.flow_dropout),
        });
    }

    let mut cylinders = Vec::with_capacity(raw.cylinders.len().min(MAX_OBSTACLES + 1));
    for (i, c) in raw.cylinders.into_iter().enumerate() {
        let f = format!("cylinders[{i}]");
        spans.add(&f, c.span());
        let c = c.into_inner();
        cylinders.push(Cylinder {
            center: spans.pair(&format!("{f}.center"), c.center)?,
            radius: spans.value(&format!("{f}.radius"), c.radius),
            height: spans.optional(&format!("{f}.height"), c.height).unwrap_or(ceiling),
        });
    }

    let mut sim = SimSettings {
        seed: 0,
        time_limit: DEFAULT_TIME_LIMIT_S,
        expect: Expect::Completed,
    };
    if let Some(s) = raw.sim {
        spans.add("sim", s.span());
        let s = s.into_inner();
        sim.seed = spans.optional("sim.seed", s.seed).unwrap_or(0);
        sim.time_limit = spans
            .optional("sim.time_limit", s.time_limit)
            .unwrap_or(DEFAULT_TIME_LIMIT_S);
        sim.expect = spans.optional("sim.expect", s.expect).unwrap_or_default();
    }

    let mut stress = Stress::default();
    let mut sink = |f: &str, r: Range<usize>| spans.add(f, r);
    if let Some(t) = raw.sensors {
        sink("sensors", t.span());
        stress.sensors = SensorStress::from_raw(t.into_inner(), &mut sink);
    }
    if let Some(t) = raw.disturbances {
        sink("disturbances", t.span());
        stress.disturbances = Disturbances::from_raw(t.into_inner(), &mut sink).map_err(|e| Invalid {
            field: e.field,
            message: e.message,
        })?;
    }

    Ok(World {
        name,
        arena: Arena { size, ceiling, walls },
        mission,
        pads,
        boxes,
        cylinders,
        polygons,
        movers,
        floor,
        sim,
        stress,
    })
}

// ---------------------------------------------------------------------------------------------------------
// Validation

fn finite2(v: [f32; 2]) -> bool {
    v[0].is_finite() && v[1].is_finite()
}

/// Whether `v` is a whole number of 5 cm cells.
fn whole_cells(v: f32) -> bool {
    let cells = f64::from(v) / f64::from(cfnav::nav::map::CELL_SIZE_M);
    (cells - cells.round()).abs() < 1e-3
}

/// Distance between two axis-aligned rectangles (0 when they touch or overlap).
fn rect_rect_distance(a: ([f32; 2], [f32; 2]), b: ([f32; 2], [f32; 2])) -> f32 {
    let dx = (a.0[0] - b.1[0]).max(b.0[0] - a.1[0]).max(0.0);
    let dy = (a.0[1] - b.1[1]).max(b.0[1] - a.1[1]).max(0.0);
    dx.hypot(dy)
}

/// Whether the interiors of two rectangles overlap.
fn rects_overlap(a: ([f32; 2], [f32; 2]), b: ([f32; 2], [f32; 2])) -> bool {
    a.0[0] < b.1[0] - EPS && b.0[0] < a.1[0] - EPS && a.0[1] < b.1[1] - EPS && b.0[1] < a.1[1] - EPS
}

/// Distance from a point to a rectangle (0 inside).
fn rect_point_distance(r: ([f32; 2], [f32; 2]), p: [f32; 2]) -> f32 {
    rect_rect_distance(r, (p, p))
}

fn dist(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// The four corners, counter-clockwise, of a `size` rectangle centred on `c` and turned by `yaw_deg`.
fn turned_corners(c: [f32; 2], size: [f32; 2], yaw_deg: f32) -> [[f32; 2]; 4] {
    let (s, co) = yaw_deg.to_radians().sin_cos();
    let h = [size[0] / 2.0, size[1] / 2.0];
    [[-h[0], -h[1]], [h[0], -h[1]], [h[0], h[1]], [-h[0], h[1]]]
        .map(|[x, y]| [c[0] + co * x - s * y, c[1] + s * x + co * y])
}

/// The axis-aligned bounding rectangle of some points.
fn polygon_bounds(points: &[[f32; 2]]) -> ([f32; 2], [f32; 2]) {
    let mut lo = [f32::INFINITY; 2];
    let mut hi = [f32::NEG_INFINITY; 2];
    for p in points {
        for i in 0..2 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    (lo, hi)
}

/// Twice the signed area of a polygon (positive counter-clockwise).
fn twice_area(points: &[[f32; 2]]) -> f64 {
    let n = points.len();
    (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            f64::from(a[0]) * f64::from(b[1]) - f64::from(b[0]) * f64::from(a[1])
        })
        .sum()
}

/// Whether segments `ab` and `cd` share a point (touching counts).
fn segments_meet(a: [f32; 2], b: [f32; 2], c: [f32; 2], d: [f32; 2]) -> bool {
    let p = |v: [f32; 2]| [f64::from(v[0]), f64::from(v[1])];
    let (a, b, c, d) = (p(a), p(b), p(c), p(d));
    let orient = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
    let on = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        r[0] >= p[0].min(q[0]) && r[0] <= p[0].max(q[0]) && r[1] >= p[1].min(q[1]) && r[1] <= p[1].max(q[1])
    };
    let (o1, o2, o3, o4) = (orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b));
    if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
        return true;
    }
    (o1 == 0.0 && on(a, b, c)) || (o2 == 0.0 && on(a, b, d)) || (o3 == 0.0 && on(c, d, a)) || (o4 == 0.0 && on(c, d, b))
}

/// The first pair of non-adjacent edges `(i, j)` of a closed polygon that meet, if any.
fn self_crossing(points: &[[f32; 2]]) -> Option<(usize, usize)> {
    let n = points.len();
    for i in 0..n {
        for j in i + 1..n {
            if j == i + 1 || (i == 0 && j == n - 1) {
                continue;
            }
            if segments_meet(points[i], points[(i + 1) % n], points[j], points[(j + 1) % n]) {
                return Some((i, j));
            }
        }
    }
    None
}

/// Distance from a point to a polygon's area (0 inside or on it).
fn polygon_point_distance(points: &[[f32; 2]], p: [f32; 2]) -> f32 {
    geometry::polygon_signed_distance(points, [f64::from(p[0]), f64::from(p[1])]).max(0.0) as f32
}

impl Pad {
    /// The footprint's lower-left and upper-right corners (of its bounding rectangle when turned).
    pub fn footprint(&self) -> ([f32; 2], [f32; 2]) {
        if self.yaw_deg != 0.0 {
            return polygon_bounds(&self.corners());
        }
        let h = [self.size[0] / 2.0, self.size[1] / 2.0];
        (
            [self.center[0] - h[0], self.center[1] - h[1]],
            [self.center[0] + h[0], self.center[1] + h[1]],
        )
    }

    /// The top's four corners, counter-clockwise.
    pub fn corners(&self) -> [[f32; 2]; 4] {
        turned_corners(self.center, self.size, self.yaw_deg)
    }
}

impl BoxObstacle {
    /// The footprint's lower-left and upper-right corners (of its bounding rectangle when turned).
    pub fn footprint(&self) -> ([f32; 2], [f32; 2]) {
        if self.yaw_deg != 0.0 {
            return polygon_bounds(&self.corners());
        }
        (self.min, self.max)
    }

    /// The centre of the footprint.
    pub fn center(&self) -> [f32; 2] {
        [(self.min[0] + self.max[0]) / 2.0, (self.min[1] + self.max[1]) / 2.0]
    }

    /// The footprint's four corners after the turn, counter-clockwise.
    pub fn corners(&self) -> [[f32; 2]; 4] {
        let size = [self.max[0] - self.min[0], self.max[1] - self.min[1]];
        turned_corners(self.center(), size, self.yaw_deg)
    }
}

impl Mover {
    /// Length of the path, m.
    pub fn path_length(&self) -> f32 {
        self.path.windows(2).map(|w| dist(w[0], w[1])).sum()
    }

    /// Where it stands after walking `walked_m` along its back-and-forth cycle.
    pub fn position_after(&self, walked_m: f32) -> [f32; 2] {
        let length = self.path_length();
        let Some(&first) = self.path.first() else {
            return [f32::NAN; 2];
        };
        if length.is_nan() || length <= 0.0 || !walked_m.is_finite() {
            return first;
        }
        let mut s = walked_m.rem_euclid(2.0 * length);
        if s > length {
            s = 2.0 * length - s;
        }
        for w in self.path.windows(2) {
            let l = dist(w[0], w[1]);
            if s <= l && l > 0.0 {
                let k = s / l;
                return [w[0][0] + k * (w[1][0] - w[0][0]), w[0][1] + k * (w[1][1] - w[0][1])];
            }
            s -= l;
        }
        *self.path.last().unwrap_or(&first)
    }

    /// Where it stands now.
    pub fn position(&self) -> [f32; 2] {
        self.position_after(self.walked_m)
    }
}

impl FloorPatch {
    /// Whether `(x, y)` lies on the patch (edges included).
    pub fn contains(&self, x: f32, y: f32) -> bool {
        x >= self.min[0] && x <= self.max[0] && y >= self.min[1] && y <= self.max[1]
    }
}

impl World {
    /// The rules of `[[polygons]]`, `[[movers]]` and `[[floor]]`.
    fn check_room_items(&self, in_arena: impl Fn(([f32; 2], [f32; 2])) -> bool) -> Result<(), Invalid> {
        let [w, h] = self.arena.size;
        let c = self.arena.ceiling;
        for (key, n) in [
            ("polygons", self.polygons.len()),
            ("movers", self.movers.len()),
            ("floor", self.floor.len()),
        ] {
            if n > MAX_ROOM_ITEMS {
                return invalid(key, format!("{n} entries; expected at most {MAX_ROOM_ITEMS}"));
            }
        }
        for (i, q) in self.polygons.iter().enumerate() {
            let f = format!("polygons[{i}].points");
            if q.points.len() < 3 || !q.points.iter().all(|p| finite2(*p)) {
                return invalid(
                    f,
                    format!("{} corners; expected 3 or more finite [x, y] corners", q.points.len()),
                );
            }
            if !in_arena(polygon_bounds(&q.points)) {
                return invalid(
                    f,
                    format!("a corner lies outside the {w} × {h} m arena; expected every corner inside"),
                );
            }
            if let Some((a, b)) = self_crossing(&q.points) {
                return invalid(
                    f,
                    format!("edges {a} and {b} cross; expected a simple polygon (edges meet only at shared corners)"),
                );
            }
            if twice_area(&q.points) <= 0.0 {
                return invalid(
                    f,
                    "the corners run clockwise (or enclose no area); expected them counter-clockwise",
                );
            }
            if !(q.height.is_finite() && q.height > 0.0 && q.height <= c + EPS) {
                return invalid(
                    format!("polygons[{i}].height"),
                    format!("{} m; expected 0 < height ≤ the ceiling ({c} m)", q.height),
                );
            }
        }
        for (i, m) in self.movers.iter().enumerate() {
            if !(m.radius.is_finite() && m.radius > 0.0 && m.radius <= 1.0) {
                return invalid(
                    format!("movers[{i}].radius"),
                    format!("{} m; expected 0 < radius ≤ 1 m", m.radius),
                );
            }
            if !(m.height.is_finite() && m.height > 0.0 && m.height <= c + EPS) {
                return invalid(
                    format!("movers[{i}].height"),
                    format!("{} m; expected 0 < height ≤ the ceiling ({c} m)", m.height),
                );
            }
            if !(m.speed.is_finite() && m.speed >= 0.0 && m.speed <= MAX_MOVER_SPEED_MPS + EPS) {
                return invalid(
                    format!("movers[{i}].speed"),
                    format!("{} m/s; expected 0 ≤ speed ≤ {MAX_MOVER_SPEED_MPS} m/s", m.speed),
                );
            }
            let inside = |p: &[f32; 2]| finite2(*p) && p[0] >= 0.0 && p[0] <= w && p[1] >= 0.0 && p[1] <= h;
            if m.path.is_empty() || !m.path.iter().all(inside) {
                return invalid(
                    format!("movers[{i}].path"),
                    format!(
                        "{} points; expected 1 or more points inside the {w} × {h} m arena",
                        m.path.len()
                    ),
                );
            }
        }
        for (i, p) in self.floor.iter().enumerate() {
            if !finite2(p.min) || !finite2(p.max) || p.min[0] >= p.max[0] || p.min[1] >= p.max[1] {
                return invalid(
                    format!("floor[{i}]"),
                    format!(
                        "min [{}, {}], max [{}, {}]; expected min < max in both x and y",
                        p.min[0], p.min[1], p.max[0], p.max[1]
                    ),
                );
            }
            if !in_arena((p.min, p.max)) {
                return invalid(
                    format!("floor[{i}]"),
                    format!("leaves the {w} × {h} m arena; expected 0 ≤ min, max ≤ [{w}, {h}]"),
                );
            }
            if let Some(d) = p.flow_dropout
                && !(d.is_finite() && (0.0..=1.0).contains(&d))
            {
                return invalid(
                    format!("floor[{i}].flow_dropout"),
                    format!("{d}; expected 0 ≤ flow_dropout ≤ 1"),
                );
            }
        }
        Ok(())
    }

    /// Check every rule of the schema (see the module documentation).
    fn check(&self) -> Result<(), Invalid> {
        let name_len = self.name.chars().count();
        if self.name.trim().is_empty() || name_len > 64 || self.name.chars().any(char::is_control) {
            return invalid("name", "expected 1 to 64 printable characters");
        }

        let [w, h] = self.arena.size;
        if !finite2(self.arena.size)
            || w < MIN_ARENA_M - EPS
            || h < MIN_ARENA_M - EPS
            || w > MAX_ARENA_M[0] + EPS
            || h > MAX_ARENA_M[1] + EPS
        {
            return invalid(
                "arena.size",
                format!(
                    "[{w}, {h}] m is out of range; expected {MIN_ARENA_M} ≤ x ≤ {} and {MIN_ARENA_M} ≤ y ≤ {} m (the largest grid the firmware maps: {MAX_WIDTH_CELLS} × {MAX_HEIGHT_CELLS} cells of 5 cm)",
                    MAX_ARENA_M[0], MAX_ARENA_M[1]
                ),
            );
        }
        if !whole_cells(w) || !whole_cells(h) {
            return invalid(
                "arena.size",
                format!("[{w}, {h}] m; expected multiples of 0.05 m (whole 5 cm map cells)"),
            );
        }
        let c = self.arena.ceiling;
        if !(c.is_finite() && c > 0.0 && c <= MAX_CEILING_M + EPS) {
            return invalid(
                "arena.ceiling",
                format!("{c} m; expected 0 < ceiling ≤ {MAX_CEILING_M} m"),
            );
        }

        let inside = |p: [f32; 2]| finite2(p) && p[0] > 0.0 && p[0] < w && p[1] > 0.0 && p[1] < h;
        for (field, p) in [
            ("mission.start", self.mission.start),
            ("mission.goal", self.mission.goal),
        ] {
            if !inside(p) {
                return invalid(
                    field,
                    format!(
                        "[{}, {}] is outside the {w} × {h} m arena; expected 0 < x < {w} and 0 < y < {h}",
                        p[0], p[1]
                    ),
                );
            }
        }
        let height = self.mission.height;
        if !(height.is_finite() && height >= MIN_HEIGHT_M - EPS && height < c) {
            return invalid(
                "mission.height",
                format!("{height} m; expected {MIN_HEIGHT_M} m ≤ height < the ceiling ({c} m)"),
            );
        }
        let speed = self.mission.speed;
        if !(speed.is_finite() && speed > 0.0 && speed <= MAX_SPEED_MPS + EPS) {
            return invalid(
                "mission.speed",
                format!("{speed} m/s; expected 0 < speed ≤ {MAX_SPEED_MPS} m/s"),
            );
        }

        if self.pads.len() < 2 || self.pads.len() > MAX_PADS {
            return invalid(
                "pads",
                format!(
                    "{} [[pads]]; expected 2 to {MAX_PADS} (the first is home, the last the goal pad)",
                    self.pads.len()
                ),
            );
        }
        let in_arena =
            |r: ([f32; 2], [f32; 2])| r.0[0] >= -EPS && r.0[1] >= -EPS && r.1[0] <= w + EPS && r.1[1] <= h + EPS;
        for (i, p) in self.pads.iter().enumerate() {
            if !finite2(p.center) {
                return invalid(format!("pads[{i}].center"), "expected finite numbers");
            }
            let [lo, hi] = PAD_SIDE_M;
            let side_ok = |v: f32| v.is_finite() && v >= lo - EPS && v <= hi + EPS;
            if !(side_ok(p.size[0]) && side_ok(p.size[1])) {
                return invalid(
                    format!("pads[{i}].size"),
                    format!(
                        "[{}, {}] m; expected both sides within {lo}..{hi} m",
                        p.size[0], p.size[1]
                    ),
                );
            }
            let [lo, hi] = PAD_HEIGHT_M;
            if !(p.height.is_finite() && p.height >= lo - EPS && p.height <= hi + EPS) {
                return invalid(
                    format!("pads[{i}].height"),
                    format!("{} m; expected {lo}..{hi} m", p.height),
                );
            }
            if p.height >= height {
                return invalid(
                    format!("pads[{i}].height"),
                    format!("{} m; expected below the cruise height ({height} m)", p.height),
                );
            }
            if !p.yaw_deg.is_finite() {
                return invalid(format!("pads[{i}].yaw"), "expected a finite angle in degrees");
            }
            if !in_arena(p.footprint()) {
                return invalid(
                    format!("pads[{i}]"),
                    format!("the pad's footprint leaves the {w} × {h} m arena; expected it inside"),
                );
            }
            for (j, q) in self.pads.iter().enumerate().take(i) {
                if rects_overlap(p.footprint(), q.footprint()) {
                    return invalid(format!("pads[{i}]"), format!("overlaps pads[{j}]; expected pads apart"));
                }
            }
        }

        if self.boxes.len() > MAX_OBSTACLES {
            return invalid(
                "boxes",
                format!("{} boxes; expected at most {MAX_OBSTACLES}", self.boxes.len()),
            );
        }
        for (i, b) in self.boxes.iter().enumerate() {
            if !finite2(b.min) || !finite2(b.max) || b.min[0] >= b.max[0] || b.min[1] >= b.max[1] {
                return invalid(
                    format!("boxes[{i}]"),
                    format!(
                        "min [{}, {}], max [{}, {}]; expected min < max in both x and y",
                        b.min[0], b.min[1], b.max[0], b.max[1]
                    ),
                );
            }
            if !b.yaw_deg.is_finite() {
                return invalid(format!("boxes[{i}].yaw"), "expected a finite angle in degrees");
            }
            if !in_arena(b.footprint()) {
                return invalid(
                    format!("boxes[{i}]"),
                    format!("leaves the {w} × {h} m arena; expected 0 ≤ min, max ≤ [{w}, {h}]"),
                );
            }
            if !(b.height.is_finite() && b.height > 0.0 && b.height <= c + EPS) {
                return invalid(
                    format!("boxes[{i}].height"),
                    format!("{} m; expected 0 < height ≤ the ceiling ({c} m)", b.height),
                );
            }
        }

        if self.cylinders.len() > MAX_OBSTACLES {
            return invalid(
                "cylinders",
                format!("{} cylinders; expected at most {MAX_OBSTACLES}", self.cylinders.len()),
            );
        }
        for (i, cy) in self.cylinders.iter().enumerate() {
            let p = cy.center;
            if !(finite2(p) && p[0] >= 0.0 && p[0] <= w && p[1] >= 0.0 && p[1] <= h) {
                return invalid(
                    format!("cylinders[{i}].center"),
                    format!("[{}, {}]; expected a point inside the {w} × {h} m arena", p[0], p[1]),
                );
            }
            if !(cy.radius.is_finite() && cy.radius > 0.0 && cy.radius <= MAX_ARENA_M[0]) {
                return invalid(
                    format!("cylinders[{i}].radius"),
                    format!("{} m; expected 0 < radius ≤ {} m", cy.radius, MAX_ARENA_M[0]),
                );
            }
            if !(cy.height.is_finite() && cy.height > 0.0 && cy.height <= c + EPS) {
                return invalid(
                    format!("cylinders[{i}].height"),
                    format!("{} m; expected 0 < height ≤ the ceiling ({c} m)", cy.height),
                );
            }
        }

        self.check_room_items(in_arena)?;

        for (i, p) in self.pads.iter().enumerate() {
            if let Some(j) = self
                .polygons
                .iter()
                .position(|q| rects_overlap(p.footprint(), polygon_bounds(&q.points)))
            {
                return invalid(
                    format!("pads[{i}]"),
                    format!("overlaps polygons[{j}]; expected pads clear of obstacles"),
                );
            }
            if let Some(j) = self
                .boxes
                .iter()
                .position(|b| rects_overlap(p.footprint(), b.footprint()))
            {
                return invalid(
                    format!("pads[{i}]"),
                    format!("overlaps boxes[{j}]; expected pads clear of obstacles"),
                );
            }
            if let Some(j) = self
                .cylinders
                .iter()
                .position(|cy| rect_point_distance(p.footprint(), cy.center) < cy.radius - EPS)
            {
                return invalid(
                    format!("pads[{i}]"),
                    format!("overlaps cylinders[{j}]; expected pads clear of obstacles"),
                );
            }
        }

        let s = self.mission.start;
        let wall = s[0].min(w - s[0]).min(s[1]).min(h - s[1]);
        if wall < BODY_RADIUS_M {
            return invalid(
                "mission.start",
                format!(
                    "the drone's body (radius {BODY_RADIUS_M} m) at [{}, {}] touches the arena wall; expected {BODY_RADIUS_M} m of clearance",
                    s[0], s[1]
                ),
            );
        }
        let hits_box = self
            .boxes
            .iter()
            .position(|b| rect_point_distance(b.footprint(), s) < BODY_RADIUS_M);
        let hits_cylinder = self
            .cylinders
            .iter()
            .position(|cy| dist(cy.center, s) < cy.radius + BODY_RADIUS_M);
        if let Some(what) = hits_box
            .map(|j| format!("boxes[{j}]"))
            .or_else(|| hits_cylinder.map(|j| format!("cylinders[{j}]")))
        {
            return invalid(
                "mission.start",
                format!(
                    "the drone's body (radius {BODY_RADIUS_M} m) at [{}, {}] touches {what}; expected {BODY_RADIUS_M} m of clearance",
                    s[0], s[1]
                ),
            );
        }
        if self.pad_index_at(s[0], s[1]).is_none()
            && let Some(j) = self
                .pads
                .iter()
                .position(|p| rect_point_distance(p.footprint(), s) < BODY_RADIUS_M)
        {
            return invalid(
                "mission.start",
                format!(
                    "the drone's body at [{}, {}] straddles the side of pads[{j}]; expected it on a pad's top or {BODY_RADIUS_M} m clear of it",
                    s[0], s[1]
                ),
            );
        }

        if let Some(j) = self
            .polygons
            .iter()
            .position(|q| polygon_point_distance(&q.points, s) < BODY_RADIUS_M)
        {
            return invalid(
                "mission.start",
                format!(
                    "the drone's body (radius {BODY_RADIUS_M} m) at [{}, {}] touches polygons[{j}]; expected {BODY_RADIUS_M} m of clearance",
                    s[0], s[1]
                ),
            );
        }
        if let Some(j) = self
            .movers
            .iter()
            .position(|m| dist(m.path[0], s) < m.radius + BODY_RADIUS_M)
        {
            return invalid(
                format!("movers[{j}].path"),
                format!(
                    "its first point touches the drone's body at mission.start [{}, {}]; expected the mover to start clear of it",
                    s[0], s[1]
                ),
            );
        }
        if let Some([x, y, yaw]) = self.mission.placed {
            if !(inside([x, y]) && yaw.is_finite() && yaw.abs() <= 180.0) {
                return invalid(
                    "mission.placed",
                    format!("[{x}, {y}, {yaw}]; expected a point inside the {w} × {h} m arena and a yaw within ±180°"),
                );
            }
            let on = self.pad_index_at(x, y).map_or(0.0, |k| self.pads[k].height);
            let c = self.clearance(x, y, on);
            let walls = x.min(w - x).min(y).min(h - y);
            if c < BODY_RADIUS_M || walls < BODY_RADIUS_M {
                return invalid(
                    "mission.placed",
                    format!(
                        "the drone's body (radius {BODY_RADIUS_M} m) at [{x}, {y}] touches an obstacle, a pad's side or the arena's edge; expected {BODY_RADIUS_M} m of clearance"
                    ),
                );
            }
        }

        let last = self.pads.len() - 1;
        for (i, nominal, what) in [
            (0, self.mission.start, "mission.start"),
            (last, self.mission.goal, "mission.goal"),
        ] {
            let d = dist(self.pads[i].center, nominal);
            if d > MAX_PAD_OFFSET_M + EPS {
                let role = if i == 0 { "home pad" } else { "goal pad" };
                return invalid(
                    format!("pads[{i}].center"),
                    format!(
                        "the {role} lies {d:.3} m from {what} [{}, {}]; expected at most {MAX_PAD_OFFSET_M} m (centre to centre)",
                        nominal[0], nominal[1]
                    ),
                );
            }
        }

        let t = self.sim.time_limit;
        if !(t.is_finite() && t > 0.0 && t <= MAX_TIME_LIMIT_S) {
            return invalid(
                "sim.time_limit",
                format!("{t} s; expected 0 < time_limit ≤ {MAX_TIME_LIMIT_S} s"),
            );
        }
        self.stress.check().map_err(|e| Invalid {
            field: e.field,
            message: e.message,
        })
    }

    /// Check a world built in code (e.g. by a test or a generator) against the rules world files obey.
    pub fn validate(&self) -> Result<(), WorldError> {
        self.check().map_err(|e| WorldError {
            file: format!("world {:?}", self.name),
            line: None,
            field: Some(e.field),
            message: e.message,
        })
    }

    /// Parse and validate the text of a world file. `file_name` names the file in errors, and its stem is
    /// the world's name when the file has no `name`.
    pub fn from_toml_str(text: &str, file_name: &str) -> Result<World, WorldError> {
        let error = |line, field, message: String| WorldError {
            file: file_name.to_string(),
            line,
            field,
            message,
        };
        let blank = text.lines().all(|l| {
            let l = l.trim();
            l.is_empty() || l.starts_with('#')
        });
        if blank {
            return Err(error(
                None,
                None,
                "the file is empty; expected a TOML world with [arena], [mission] and [[pads]] (docs/formats.md, world files)"
                    .into(),
            ));
        }
        // Syntax first, so that a file that is not TOML at all says so.
        if let Err(e) = text.parse::<toml::Table>() {
            let mut e = toml_error(text, file_name, &e);
            e.message = format!("not valid TOML: {}", e.message);
            return Err(e);
        }
        let raw: RawWorld = toml::from_str(text).map_err(|e| toml_error(text, file_name, &e))?;
        let default_name = Path::new(file_name)
            .file_stem()
            .and_then(|s| s.to_str())
            .filter(|s| !s.is_empty())
            .unwrap_or("world");
        let mut spans = Spans::default();
        let located = |spans: &Spans, e: Invalid| {
            let line = spans.find(&e.field).map(|s| line_of(text, s.start));
            error(line, Some(e.field), e.message)
        };
        let world = match convert(raw, default_name, &mut spans) {
            Ok(w) => w,
            Err(e) => return Err(located(&spans, e)),
        };
        match world.check() {
            Ok(()) => Ok(world),
            Err(e) => Err(located(&spans, e)),
        }
    }

    /// Read, parse and validate a world file.
    pub fn load(path: impl AsRef<Path>) -> Result<World, WorldError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| WorldError {
            file: file.clone(),
            line: None,
            field: None,
            message: format!("cannot read: {e}"),
        })?;
        let text = String::from_utf8(bytes).map_err(|e| {
            let at = e.utf8_error().valid_up_to();
            let line = 1 + e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count();
            WorldError {
                file: file.clone(),
                line: Some(line),
                field: None,
                message: format!("byte {at} is not UTF-8; expected a UTF-8 TOML text"),
            }
        })?;
        Self::from_toml_str(&text, &file)
    }

    /// The built-in world flown by `cfnav sim` without `--world` (also shipped as `worlds/default.toml`):
    /// a 6 × 3 m arena, take-off at (0.6, 1.3), nominal goal (5.0, 1.5) with the goal pad at (5.12, 1.41); a
    /// wall from the floor side at x 2.0–2.2 up to y 2.0, a cylinder, a wall from the far side at x 4.0–4.2
    /// down to y 1.0, and a 1.2 m box. Every gap is at least 0.6 m wide.
    pub fn default_world() -> World {
        let pad = |center| Pad {
            center,
            size: [0.3, 0.3],
            height: 0.1,
            yaw_deg: 0.0,
        };
        World {
            name: "default".into(),
            arena: Arena {
                size: [6.0, 3.0],
                ceiling: DEFAULT_CEILING_M,
                walls: ALL_WALLS,
            },
            mission: Mission {
                start: [0.6, 1.3],
                goal: [5.0, 1.5],
                height: DEFAULT_HEIGHT_M,
                speed: DEFAULT_SPEED_MPS,
                placed: None,
            },
            pads: vec![pad([0.6, 1.3]), pad([5.12, 1.41])],
            boxes: vec![
                BoxObstacle {
                    min: [2.0, 0.0],
                    max: [2.2, 2.0],
                    height: DEFAULT_CEILING_M,
                    yaw_deg: 0.0,
                },
                BoxObstacle {
                    min: [4.0, 1.0],
                    max: [4.2, 3.0],
                    height: DEFAULT_CEILING_M,
                    yaw_deg: 0.0,
                },
                BoxObstacle {
                    min: [2.8, 0.8],
                    max: [3.1, 1.2],
                    height: 1.2,
                    yaw_deg: 0.0,
                },
            ],
            cylinders: vec![Cylinder {
                center: [3.2, 2.0],
                radius: 0.15,
                height: DEFAULT_CEILING_M,
            }],
            polygons: Vec::new(),
            movers: Vec::new(),
            floor: Vec::new(),
            sim: SimSettings {
                seed: 7,
                time_limit: DEFAULT_TIME_LIMIT_S,
                expect: Expect::Completed,
            },
            stress: Stress::default(),
        }
    }

    /// The home pad (the first).
    pub fn home_pad(&self) -> Option<&Pad> {
        self.pads.first()
    }

    /// The goal pad (the last).
    pub fn goal_pad(&self) -> Option<&Pad> {
        self.pads.last()
    }

    /// Index of the goal pad in [`World::pads`].
    pub fn goal_pad_index(&self) -> usize {
        self.pads.len().saturating_sub(1)
    }

    /// The grid the drone maps this arena on (5 cm cells), or `None` when the arena is beyond the largest
    /// grid the firmware supports (never for a validated world).
    pub fn grid_shape(&self) -> Option<GridShape> {
        GridShape::for_arena(self.arena.size[0], self.arena.size[1], LARGE_ARENA_CELLS)
            .filter(|s| s.width <= MAX_WIDTH_CELLS && s.height <= MAX_HEIGHT_CELLS)
    }

    /// Whether the arena has more cells than the default firmware build holds (120 × 60), so that only the
    /// `large-arena` build can fly it.
    pub fn needs_large_arena(&self) -> bool {
        self.grid_shape().is_none_or(|s| s.cells() > DEFAULT_FIRMWARE_CELLS)
    }

    /// The world as a world file that [`World::from_toml_str`] reads back (every default written out).
    pub fn to_toml_string(&self) -> String {
        fn num(v: f32) -> String {
            format!("{v:?}")
        }
        fn pair(v: [f32; 2]) -> String {
            format!("[{}, {}]", num(v[0]), num(v[1]))
        }
        let mut s = String::new();
        s.push_str(&format!("name = {}\n", toml::Value::String(self.name.clone())));
        s.push_str(&format!(
            "\n[arena]\nsize = {}\nceiling = {}\n",
            pair(self.arena.size),
            num(self.arena.ceiling)
        ));
        if self.arena.walls != ALL_WALLS {
            let names: Vec<String> = WALL_NAMES
                .iter()
                .filter(|(_, bit)| self.arena.has_wall(*bit))
                .map(|(n, _)| format!("\"{n}\""))
                .collect();
            s.push_str(&format!("walls = [{}]\n", names.join(", ")));
        }
        let m = &self.mission;
        s.push_str(&format!(
            "\n[mission]\nstart = {}\ngoal = {}\nheight = {}\nspeed = {}\n",
            pair(m.start),
            pair(m.goal),
            num(m.height),
            num(m.speed)
        ));
        if let Some([x, y, yaw]) = m.placed {
            s.push_str(&format!("placed = [{}, {}, {}]\n", num(x), num(y), num(yaw)));
        }
        for p in &self.pads {
            s.push_str(&format!(
                "\n[[pads]]\ncenter = {}\nsize = {}\nheight = {}\n",
                pair(p.center),
                pair(p.size),
                num(p.height)
            ));
            if p.yaw_deg != 0.0 {
                s.push_str(&format!("yaw = {}\n", num(p.yaw_deg)));
            }
        }
        for b in &self.boxes {
            s.push_str(&format!(
                "\n[[boxes]]\nmin = {}\nmax = {}\nheight = {}\n",
                pair(b.min),
                pair(b.max),
                num(b.height)
            ));
            if b.yaw_deg != 0.0 {
                s.push_str(&format!("yaw = {}\n", num(b.yaw_deg)));
            }
        }
        for c in &self.cylinders {
            s.push_str(&format!(
                "\n[[cylinders]]\ncenter = {}\nradius = {}\nheight = {}\n",
                pair(c.center),
                num(c.radius),
                num(c.height)
            ));
        }
        let points = |v: &[[f32; 2]]| v.iter().map(|p| pair(*p)).collect::<Vec<_>>().join(", ");
        for q in &self.polygons {
            s.push_str(&format!(
                "\n[[polygons]]\npoints = [{}]\nheight = {}\n",
                points(&q.points),
                num(q.height)
            ));
        }
        for m in &self.movers {
            s.push_str(&format!(
                "\n[[movers]]\nradius = {}\nheight = {}\nspeed = {}\npath = [{}]\n",
                num(m.radius),
                num(m.height),
                num(m.speed),
                points(&m.path)
            ));
        }
        for f in &self.floor {
            s.push_str(&format!("\n[[floor]]\nmin = {}\nmax = {}\n", pair(f.min), pair(f.max)));
            if let Some(q) = f.squal {
                s.push_str(&format!("squal = {q}\n"));
            }
            if let Some(d) = f.flow_dropout {
                s.push_str(&format!("flow_dropout = {}\n", num(d)));
            }
        }
        s.push_str(&format!(
            "\n[sim]\nseed = {}\ntime_limit = {}\n",
            self.sim.seed,
            num(self.sim.time_limit)
        ));
        if self.sim.expect != Expect::Completed {
            s.push_str(&format!("expect = \"{}\"\n", self.sim.expect.as_str()));
        }
        s.push_str(&self.stress.to_toml_string());
        s
    }
}
