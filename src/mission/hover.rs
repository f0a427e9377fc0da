//! The hover test (`mission.mode = 1`): take off from where the drone stands (the home pad or anywhere in
//! the arena, `super::start`) to `mission.height`, hold position over the take-off point for
//! `mission.hoverTime` s, land there and end with [`MissionState::Completed`]. While
//! holding, the worst horizontal distance of the estimate from the take-off point and the worst
//! |estimated height − `mission.height`| are kept ([`super::MissionStats::hover_dev_xy_m`], `hover_dev_z_m`;
//! logged as `mission.hoverDevXY`, `mission.hoverDevZ`).
//!
//! Job: a short check of the flight stack before an autonomous mission (CFPilot's `basic` mission): does the
//! drone climb, hold and land where it took off. Non-goals: no mapping decisions (the beams still map, as in
//! any flying phase), no pad search (it lands where it took off, on the estimate). The deviations are the
//! estimate's view (tracking error); how far the estimate itself drifted is only known to the simulator,
//! which reports the true deviations beside them.
//!
//! Units: arena frame, metres, seconds. Memory: two floats in the stats. Cost: O(1) per tick.
//!
//! The safety rules are the other phases': the battery, estimator and supervisor checks of
//! [`super::Mission::tick`] run before this phase, and an abort lands where the drone is.

use super::{Mission, MissionState, Phase};
use crate::types::{Micros, Setpoint, StateEstimate};

impl<const CELLS: usize, const QUEUE: usize> Mission<CELLS, QUEUE> {
    /// The climb has reached the cruise height: the hold begins over `(x, y)`, the take-off point.
    pub(super) fn begin_hover_hold(&mut self, now: Micros, (x, y): (f32, f32)) -> Setpoint {
        self.stats.hover_dev_xy_m = 0.0;
        self.stats.hover_dev_z_m = 0.0;
        self.phase = Phase::HoverHold { x, y, since: now };
        self.hold_at(x, y)
    }

    /// Holding over the take-off point; after `mission.hoverTime` s the landing there begins.
    pub(super) fn hover_hold(
        &mut self,
        now: Micros,
        state: &StateEstimate,
        (x, y): (f32, f32),
        since: Micros,
    ) -> Setpoint {
        let p = state.position_m;
        let dev_xy = libm::hypotf(p[0] - x, p[1] - y);
        let dev_z = libm::fabsf(p[2] - self.params.height_m);
        // A NaN never raises the maximum (f32::max ignores it): an invalid estimate ends the phase anyway.
        self.stats.hover_dev_xy_m = self.stats.hover_dev_xy_m.max(dev_xy);
        self.stats.hover_dev_z_m = self.stats.hover_dev_z_m.max(dev_z);
        if now.saturating_sub(since) as f32 * 1e-6 >= self.params.hover_time_s {
            // The landing's state is [`MissionState::HoverLand`]; its touchdown ends the mission.
            self.phase = Phase::Land { x, y };
            debug_assert!(self.state() == MissionState::HoverLand);
        }
        self.hold_at(x, y)
    }

    /// Position hold at `(x, y)` and the cruise height, keeping the heading.
    pub(super) fn hold_at(&self, x: f32, y: f32) -> Setpoint {
        Setpoint::Position {
            x_m: x,
            y_m: y,
            z_m: self.params.height_m,
            yaw_rad: self.heading,
        }
    }
}
