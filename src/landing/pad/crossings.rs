//! Pipeline stage 6 of the pad detector (see [`super`]): an entry and an exit paired into a crossing
//! (6), a line that turned back on the pad (6b) and a line that ended on it (6c, [`PadDetector::line_ended`]).

use super::{Crossing, Detection, PadDetector, RING, median};

/// A crossing's chord must be within 20° of the drone's heading at both edges: straight flight.
const COS_MAX_HEADING_ERROR: f32 = 0.9397;
/// Travel between the edges of a crossing may exceed the chord by 5 % + 2 cm (position noise) at most.
const TRAVEL_SLACK_RATIO: f32 = 1.05;
const TRAVEL_SLACK_M: f32 = 0.02;
/// A crossing's top, between its edges less this at each end, must be flat (see `flat_between`), m.
const FLAT_TOP_INSET_M: f32 = 0.04;
/// Largest spread (10th to 90th percentile of the bins) of a flat top, m: ten times the VL53L1x's noise at
/// 0.4 m, a third of a 10 cm pad's height.
const FLAT_TOP_SPREAD_M: f32 = 0.03;
/// A half crossing (a line that ends on the pad, [`PadDetector::line_ended`]) needs the drone this far onto
/// the top past the entry edge, m: beyond the footprint's blur, so the level read is the top's.
const HALF_CROSSING_MIN_TOP_M: f32 = 0.06;
/// Fewest bins the flatness check needs (fewer: the ring no longer holds the top, the check passes).
const FLAT_TOP_MIN_BINS: usize = 5;
/// A turn-back's two edges must lie on one pad side: their separation along the travel direction, m.
const TURN_BACK_SIDE_TOLERANCE_M: f32 = 0.05;

impl<const EDGES: usize> PadDetector<EDGES> {
    /// The crossing made by `enter` then `exit`, if it is one (module docs, step 6).
    pub(super) fn pair(&self, enter: &Detection, exit: &Detection) -> Option<Crossing> {
        let cfg = &self.config;
        let (dx, dy) = (exit.edge.x - enter.edge.x, exit.edge.y - enter.edge.y);
        let chord = libm::hypotf(dx, dy);
        let lo = cfg.pad_size_m * cfg.min_chord_ratio;
        let hi = cfg.pad_size_m * cfg.max_chord_ratio;
        if !(chord >= lo && chord <= hi) {
            return None;
        }
        let dir = (dx / chord, dy / chord);
        let along = |h: (f32, f32)| dir.0 * h.0 + dir.1 * h.1 >= COS_MAX_HEADING_ERROR;
        if !(along(enter.heading) && along(exit.heading)) {
            return None;
        }
        if exit.odo - enter.odo > TRAVEL_SLACK_RATIO * chord + TRAVEL_SLACK_M {
            return None;
        }
        // Levels: the floor before entering and the pad while on it are window medians; the floor after
        // leaving is the median of the exit run's last bins. The pad must be lower than the floor by at
        // least a minimum step, and the floor must be the same on both sides.
        let floor_before = enter.level_before;
        let pad_level = exit.level_before;
        let floor_after = exit.level_after;
        let height = floor_before - pad_level;
        if height.is_nan() || height < cfg.min_step_m {
            return None;
        }
        if libm::fabsf(floor_after - floor_before) > cfg.step_match_m + 0.5 * height {
            return None;
        }
        if !self.flat_between(enter.odo, exit.odo) {
            return None;
        }
        Some(Crossing {
            enter: (enter.edge.x, enter.edge.y),
            exit: (exit.edge.x, exit.edge.y),
            step_m: height,
            inlier: true,
            turn_back: false,
        })
    }

    /// Whether the binned ranges between two edges (travel `from_odo` to `to_odo`, less
    /// [`FLAT_TOP_INSET_M`] at each end where the footprint blurs the step) form a flat top: the spread
    /// between their 10th and 90th percentiles is at most [`FLAT_TOP_SPREAD_M`] (module docs, step 6).
    /// A pad's top is flat; a beam grazing a cylinder's curved side, or sliding down an obstacle's foot,
    /// reads a range that keeps changing. Passes when the ring no longer holds enough of those bins.
    pub(super) fn flat_between(&self, from_odo: f32, to_odo: f32) -> bool {
        let (lo, hi) = (from_odo + FLAT_TOP_INSET_M, to_odo - FLAT_TOP_INSET_M);
        let mut values = [0.0f32; RING];
        let mut n = 0usize;
        let newest = self.bins.wrapping_sub(1);
        for back in 0..RING as u32 {
            let Some(serial) = newest.checked_sub(back) else { break };
            let Some(b) = self.ring_bin(serial) else { break };
            if b.odo < lo {
                break;
            }
            if b.odo <= hi
                && let Some(slot) = values.get_mut(n)
            {
                *slot = b.range;
                n += 1;
            }
        }
        if n < FLAT_TOP_MIN_BINS {
            return true;
        }
        let values = values.get_mut(..n).unwrap_or(&mut []);
        values.sort_unstable_by(f32::total_cmp);
        let p10 = values.get(n / 10).copied().unwrap_or(0.0);
        let p90 = values.get(n - 1 - n / 10).copied().unwrap_or(0.0);
        p90 - p10 <= FLAT_TOP_SPREAD_M
    }

    /// The half crossing made by entering the pad and leaving it over the same side after turning back
    /// (module docs, step 6b), if `enter` then `exit` is one: the headings are opposite, both edges lie on one
    /// line across the travel direction, the travel in between is at most a pad width there and back, and
    /// the levels are those of a pad on a flat floor.
    pub(super) fn turn_back(&self, enter: &Detection, exit: &Detection) -> Option<Crossing> {
        let cfg = &self.config;
        let d = enter.heading;
        let back = exit.heading;
        if d.0 * back.0 + d.1 * back.1 > -COS_MAX_HEADING_ERROR {
            return None;
        }
        let (dx, dy) = (exit.edge.x - enter.edge.x, exit.edge.y - enter.edge.y);
        if libm::fabsf(d.0 * dx + d.1 * dy) > TURN_BACK_SIDE_TOLERANCE_M {
            return None;
        }
        // In, to the line's end, across to the next line (at most a pad width) and back out.
        if exit.odo - enter.odo > (2.0 * cfg.max_chord_ratio + 1.0) * cfg.pad_size_m + TRAVEL_SLACK_M {
            return None;
        }
        let height = enter.level_before - exit.level_before;
        if height.is_nan() || height < cfg.min_step_m {
            return None;
        }
        if libm::fabsf(exit.level_after - enter.level_before) > cfg.step_match_m + 0.5 * height {
            return None;
        }
        let side = (0.5 * (enter.edge.x + exit.edge.x), 0.5 * (enter.edge.y + exit.edge.y));
        let inwards = (side.0 + cfg.pad_size_m * d.0, side.1 + cfg.pad_size_m * d.1);
        (inwards.0.is_finite() && inwards.1.is_finite()).then_some(Crossing {
            enter: side,
            exit: inwards,
            step_m: height,
            inlier: true,
            turn_back: true,
        })
    }

    /// The line being flown ends here, short of where it was laid out (a wall or an obstacle ahead; the
    /// caller turns back next). A drone that entered the pad on this line and is still on its top will
    /// never see the far side: the entry edge alone fixes the centre along the travel, half of
    /// `pad_size_m` inwards (module docs, step 6c). Returns whether such a half crossing was added.
    pub fn line_ended(&mut self) -> bool {
        self.flush();
        let cfg = self.config;
        let Some(enter) = self.pending_enter else {
            return false;
        };
        // Where the drone is now: the newest bins (the median of up to three, one stray reading is not
        // the level).
        let newest = self.bins.wrapping_sub(1);
        let Some(now) = self.ring_bin(newest).copied() else {
            return false;
        };
        let mut levels = [0.0f32; 3];
        let mut n = 0usize;
        for back in 0..3u32 {
            if let Some(b) = newest.checked_sub(back).and_then(|s| self.ring_bin(s))
                && let Some(slot) = levels.get_mut(n)
            {
                *slot = b.range;
                n += 1;
            }
        }
        let level_now = median(levels.get_mut(..n).unwrap_or(&mut []));
        let d = enter.heading;
        let (dx, dy) = (now.x - enter.edge.x, now.y - enter.edge.y);
        let along = d.0 * dx + d.1 * dy;
        let across = libm::fabsf(d.0 * dy - d.1 * dx);
        // Straight on from the entry, far enough onto the top to have seen it, not past its far side.
        if !(along >= HALF_CROSSING_MIN_TOP_M && along <= cfg.pad_size_m && across <= TURN_BACK_SIDE_TOLERANCE_M) {
            return false;
        }
        if now.odo - enter.odo > TRAVEL_SLACK_RATIO * along + TRAVEL_SLACK_M {
            return false;
        }
        let height = enter.level_before - enter.level_after;
        if height.is_nan() || height < cfg.min_step_m {
            return false;
        }
        // Still on the top: the level now is the level the entry stepped to, and the top is flat.
        let off_level = libm::fabsf(level_now - enter.level_after);
        if off_level.is_nan() || off_level > cfg.step_match_m + 0.25 * height {
            return false;
        }
        if !self.flat_between(enter.odo, now.odo + FLAT_TOP_INSET_M) {
            return false;
        }
        let side = (enter.edge.x, enter.edge.y);
        let inwards = (side.0 + cfg.pad_size_m * d.0, side.1 + cfg.pad_size_m * d.1);
        if !(inwards.0.is_finite() && inwards.1.is_finite()) {
            return false;
        }
        self.pending_enter = None;
        let half = Crossing {
            enter: side,
            exit: inwards,
            step_m: height,
            inlier: true,
            turn_back: true,
        };
        if self.crossings.push(half).is_err() {
            self.dropped = self.dropped.saturating_add(1);
            return false;
        }
        self.refit();
        true
    }
}
