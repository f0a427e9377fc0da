//! What one horizontal Multi-ranger return means: the nearest surface somewhere in the sensor's cone, not
//! the end of a ray along its axis.
//!
//! Job: the geometry the mapper, the map-relative fixes and the live-beam guards share to read a VL53L1X
//! return. The sensor has a 27° full field of view (VL53L1X datasheet, DocID031281 Rev 3, "Typical full
//! field-of-view (FoV): 27°") and reports one distance for what the cone holds, the nearest target that
//! returns enough light. So a return `d` says: nothing (wide enough to be seen) lies nearer than `d` in the
//! cone, and something lies at `d` at *some* bearing within ±[`HALF_FOV_RAD`] of the axis. A flat wall at
//! incidence θ to its normal reads `D / cos(max(θ − 13.5°, 0))`, shorter than the axis's `D / cos θ`.
//!
//! * [`wall_in_cone`]: the arena's exact walls as the cone sees them: the shortest distance within the
//!   cone and the bearing it lies at (to tell a wall's return from an obstacle's, and to place it).
//! * [`nearest_bearing`]: the bearing within the cone nearest a surface's normal (where a plane is
//!   nearest).
//!
//! Non-goals: the sensor's partial-fill behaviour (how small a target it reports) is the simulator's
//! (`tools/src/sim/sensors.rs`); this side only assumes "nearest in the cone".
//!
//! Units and frames: metres, radians, arena frame (walls at x = 0, x = X, y = 0, y = Y). No memory.

use crate::types::MultiRangerSample;

/// Half the VL53L1X's typical full field of view (27°), rad ([`MultiRangerSample::HALF_FOV_RAD`]).
pub const HALF_FOV_RAD: f32 = MultiRangerSample::HALF_FOV_RAD;

/// The unit vector within ±[`HALF_FOV_RAD`] of the beam axis `axis` (unit, arena frame) nearest the unit
/// normal `n`, and its cosine to `n` ([`crate::math::nearest_bearing_in_cone`]).
pub fn nearest_bearing(axis: (f32, f32), n: (f32, f32)) -> ((f32, f32), f32) {
    crate::math::nearest_bearing_in_cone(axis, n, HALF_FOV_RAD)
}

/// The arena's walls as a cone along `axis` (unit, arena frame) from `p` sees them: the shortest distance
/// to a wall within the cone, and the unit bearing it lies along (`None` outside the arena or for
/// non-finite input). Exact for a convex box: the cone's shortest exit distance is the shortest over the
/// walls of each wall plane's shortest distance within the cone.
pub fn wall_in_cone(p: (f32, f32), axis: (f32, f32), arena_m: (f32, f32)) -> Option<(f32, (f32, f32))> {
    let (w, h) = arena_m;
    let finite = [p.0, p.1, axis.0, axis.1, w, h].iter().all(|v| v.is_finite());
    if !finite || !(p.0 > 0.0 && p.1 > 0.0 && p.0 < w && p.1 < h) {
        return None;
    }
    let walls = [
        (w - p.0, (1.0, 0.0)),
        (p.0, (-1.0, 0.0)),
        (h - p.1, (0.0, 1.0)),
        (p.1, (0.0, -1.0)),
    ];
    let mut best: Option<(f32, (f32, f32))> = None;
    for (dist, n) in walls {
        let (u, cos_n) = nearest_bearing(axis, n);
        if cos_n <= 1e-3 {
            continue;
        }
        let d = dist / cos_n;
        if best.is_none_or(|(b, _)| d < b) {
            best = Some((d, u));
        }
    }
    best
}
