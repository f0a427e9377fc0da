//! Wall anchors: while the drone holds a position, the four horizontal Multi-ranger beams tie the estimate
//! to the walls they saw when the hold began.
//!
//! Why: flow-only position is a random walk of the flow noise (≈ 1 cm/√s on the simulated PMW3901),
//! so a drone told to hover wanders even though its controller holds the *estimate*
//! within millimetres. A wall a beam sees does not move: if the range to it changes, the drone moved.
//!
//! Model: when a beam is anchored it remembers its range `r₀`, the estimated position `p₀` and its
//! arena-frame direction `u` (from the estimated yaw). Later the expected range is `r₀ − (p − p₀)·u`, exact
//! for a flat surface square to the beam and for any movement; for a surface at an angle α to that, a
//! movement along its normal reads `1/cos α` larger, which changes the fix's gain, not where it holds the
//! drone (the ranges are back to `r₀` exactly when the drone is back where it was). The estimator fuses the
//! difference as a scalar measurement of position along `u` (Jacobian `−u` on x, y).
//!
//! Rules: anchors exist only during a hold (the caller says when: a position or descend setpoint in
//! flight) and only for readings within [`MAX_RANGE_M`]; a beam without an anchor is anchored by its next
//! valid reading and fused from the one after. A turn of more than [`MAX_YAW_CHANGE_RAD`] since the anchors
//! were taken re-anchors every beam (the beams now hit other points). A reading the estimator's gate
//! rejects counts as an outlier (a box came into the beam as the drone descended, a person walked by);
//! [`REANCHOR_AFTER_OUTLIERS`] in a row re-anchor that beam at its new reading.
//!
//! Non-goals: mapping, loop closure, anything while the drone travels (the anchors are cleared as soon as
//! the hold ends: surfaces at changing angles would need a map, which the mission owns).
//!
//! Units and frames: metres, radians, arena frame. Memory: four anchors, 80 bytes. Cost: O(1) per reading.

use crate::math::wrap_angle;
use crate::types::MultiRangerSample;

/// Readings beyond this are not anchored, m: the ranger's noise grows with the range, and a far reading
/// is likelier to be a wall the beam only grazes.
pub const MAX_RANGE_M: f32 = 2.5;
/// Readings below this are not anchored, m (the beam is blocked by something at the drone).
pub const MIN_RANGE_M: f32 = 0.05;
/// A turn of more than this since the anchors were taken re-anchors every beam, rad (5°).
pub const MAX_YAW_CHANGE_RAD: f32 = 0.087;
/// Consecutive rejected readings after which a beam is re-anchored at its new reading.
pub const REANCHOR_AFTER_OUTLIERS: u8 = 3;

/// Beams more than this off the arena's axes are not anchored, rad (20°). The walls of an arena (and the
/// boxes of the simulator's worlds) run along its axes; a beam at an angle α to a wall's normal reads
/// `1/cos α` times the movement along the normal, and a gain much above 1 would make the correction
/// overshoot (at 20°, 6 %).
pub const MAX_AXIS_OFFSET_RAD: f32 = 0.35;

/// One beam's anchor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallAnchor {
    /// The range when anchored, m.
    pub range0_m: f32,
    /// The estimated position (x, y) when anchored, m.
    pub position0_m: [f32; 2],
    /// The beam's arena-frame direction when anchored (unit).
    pub direction: [f32; 2],
    outliers: u8,
}

impl WallAnchor {
    /// The range this anchor expects with the drone at `position_m`, m.
    pub fn expected_range_m(&self, position_m: [f32; 2]) -> f32 {
        self.range0_m
            - ((position_m[0] - self.position0_m[0]) * self.direction[0]
                + (position_m[1] - self.position0_m[1]) * self.direction[1])
    }
}

/// The anchors of the four horizontal beams.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WallHold {
    anchors: [Option<WallAnchor>; 4],
    yaw0_rad: Option<f32>,
}

/// A reading worth anchoring: finite and within the anchoring range.
fn usable(range: Option<f32>) -> Option<f32> {
    range.filter(|r| r.is_finite() && (MIN_RANGE_M..=MAX_RANGE_M).contains(r))
}

impl WallHold {
    /// No anchors (the hold ended).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// Starts a reading (`ranges` in the order of [`MultiRangerSample::horizontal`]): re-anchors everything
    /// after a turn, anchors the beams that have none, and returns the anchors to fuse this reading against
    /// (beams anchored before it that have a valid reading now).
    pub fn begin(&mut self, ranges: [Option<f32>; 4], yaw_rad: f32, position_m: [f32; 2]) -> [Option<WallAnchor>; 4] {
        if !(yaw_rad.is_finite() && position_m.iter().all(|p| p.is_finite())) {
            self.clear();
            return [None; 4];
        }
        let turned = self
            .yaw0_rad
            .is_none_or(|y0| wrap_angle(yaw_rad - y0).abs() > MAX_YAW_CHANGE_RAD);
        if turned {
            self.anchors = [None; 4];
            self.yaw0_rad = Some(yaw_rad);
        }
        let (s, c) = (libm::sinf(yaw_rad), libm::cosf(yaw_rad));
        let mut fuse = [None; 4];
        // All four beams are 90° apart, so they are all square to the axes or all oblique.
        let quarter = core::f32::consts::FRAC_PI_2;
        let off_axis = wrap_angle(yaw_rad - quarter * libm::roundf(yaw_rad / quarter)).abs();
        if off_axis > MAX_AXIS_OFFSET_RAD {
            self.anchors = [None; 4];
            return fuse;
        }
        for (beam, range) in ranges.into_iter().enumerate() {
            let reading = usable(range);
            match (self.anchors[beam], reading) {
                (Some(anchor), Some(_)) => fuse[beam] = Some(anchor),
                (None, Some(r)) => {
                    let (bx, by) = MultiRangerSample::HORIZONTAL_BEAMS_BODY[beam];
                    self.anchors[beam] = Some(WallAnchor {
                        range0_m: r,
                        position0_m: position_m,
                        direction: [c * bx - s * by, s * bx + c * by],
                        outliers: 0,
                    });
                }
                // No reading this time: keep the anchor for the next one.
                (_, None) => {}
            }
        }
        fuse
    }

    /// The estimator fused `beam`'s reading.
    pub fn accepted(&mut self, beam: usize) {
        if let Some(Some(anchor)) = self.anchors.get_mut(beam) {
            anchor.outliers = 0;
        }
    }

    /// The estimator's gate rejected `beam`'s reading `range_m`, taken at `position_m`; after
    /// [`REANCHOR_AFTER_OUTLIERS`] in a row the beam is re-anchored there.
    pub fn rejected(&mut self, beam: usize, range_m: f32, position_m: [f32; 2]) {
        let Some(Some(anchor)) = self.anchors.get_mut(beam) else {
            return;
        };
        anchor.outliers = anchor.outliers.saturating_add(1);
        if anchor.outliers >= REANCHOR_AFTER_OUTLIERS {
            anchor.range0_m = range_m;
            anchor.position0_m = position_m;
            anchor.outliers = 0;
        }
    }
}
