//! Where a mission takes off: from where the drone stands, as its estimate says.
//!
//! Job: decide, at `mission.start`, the take-off point of the mission, or refuse the start. The position
//! estimate is continuous from power-on (anchored at `mission.startX/Y`) through whatever the user flew
//! before (commander setpoints, the high-level commander); only `kalman.resetEstimation` re-anchors it at
//! `mission.startX/Y` (the drone stands on the home pad, as stock re-anchors at its initial position).
//! - The hover test and the exploration take off from the estimate, wherever in the arena it is, and the
//!   start leaves it there (the exploration still flies home to the home pad at `mission.startX/Y`).
//! - The round trip starts from the home pad: an estimate within [`HOME_TOLERANCE_M`] of
//!   `mission.startX/Y` says the drone stands on it, and the start puts the estimate on `mission.startX/Y`
//!   (what `kalman.resetEstimation` does: the flights before left it a few centimetres off); farther, the
//!   start is refused, and the refusal says where the drone is ([`PositionRefusal`]'s `Display` is the
//!   console line). Taking the current estimate as home instead would send the drone home to a spot with
//!   no pad under it, to search for 85 s and end "pad not found".
//!
//! Every mode refuses a start whose estimate is not finite or lies outside the arena (0.1 m from its
//! walls, the rule `mission.startX/Y` itself follows).
//!
//! Non-goals: no estimator reset (the stabilizer re-anchors its filter at the point returned here, keeping
//! the position), no check of the truth (the drone knows only its estimate).
//! Units: arena frame, metres. Memory: none. Cost: O(1).

use super::{MissionMode, MissionParams};

/// A round trip starts only with the estimate this close to `mission.startX/Y`, m: half the side of the
/// 0.3 m home pad, i.e. the estimate says the drone stands on it.
pub const HOME_TOLERANCE_M: f32 = 0.15;

/// A wall margin the take-off point keeps, m (the rule of `mission.startX/Y`, [`MissionParams::validate`]).
const WALL_MARGIN_M: f32 = 0.1;

/// Why the drone's position refuses a start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PositionRefusal {
    /// The estimate is not finite (no position to take off from).
    Unknown,
    /// The estimate lies outside the arena or within 0.1 m of a wall.
    OutsideArena {
        /// The estimate, arena frame, m.
        at: (f32, f32),
    },
    /// A round trip with the estimate farther than [`HOME_TOLERANCE_M`] from the home pad.
    OffHomePad {
        /// The estimate, arena frame, m.
        at: (f32, f32),
        /// `mission.startX/Y`, m.
        home: (f32, f32),
    },
}

impl core::fmt::Display for PositionRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Unknown => write!(f, "position unknown: write kalman.resetEstimation = 1 on the home pad"),
            Self::OutsideArena { at } => write!(f, "drone at ({:.2}, {:.2}): outside the arena", at.0, at.1),
            Self::OffHomePad { at, home } => write!(
                f,
                "drone at ({:.2}, {:.2}), {:.2} m from the home pad ({:.2}, {:.2}): fly it there, or place it \
                 there and write kalman.resetEstimation = 1",
                at.0,
                at.1,
                libm::hypotf(at.0 - home.0, at.1 - home.1),
                home.0,
                home.1
            ),
        }
    }
}

/// The take-off point of a mission `params` asks for, with the drone's estimate at `estimate_xy` (arena
/// frame, m): the estimate itself, or for a round trip `mission.startX/Y`; or why the start is refused
/// (module docs).
pub fn take_off_point(params: &MissionParams, estimate_xy: (f32, f32)) -> Result<(f32, f32), PositionRefusal> {
    let (x, y) = estimate_xy;
    if !(x.is_finite() && y.is_finite()) {
        return Err(PositionRefusal::Unknown);
    }
    let (ax, ay) = params.arena_m;
    let inside = x > WALL_MARGIN_M && y > WALL_MARGIN_M && x < ax - WALL_MARGIN_M && y < ay - WALL_MARGIN_M;
    if !inside {
        return Err(PositionRefusal::OutsideArena { at: estimate_xy });
    }
    let home = params.start_m;
    // A NaN distance (a non-finite home, which validation refuses anyway) is off the pad too.
    let on_pad = libm::hypotf(x - home.0, y - home.1) <= HOME_TOLERANCE_M;
    if params.mode == MissionMode::RoundTrip && !on_pad {
        return Err(PositionRefusal::OffHomePad { at: estimate_xy, home });
    }
    Ok(if params.mode == MissionMode::RoundTrip {
        home
    } else {
        estimate_xy
    })
}
