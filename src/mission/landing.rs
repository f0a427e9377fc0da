//! Approach and touchdown: back over the pad centre on a velocity profile, position hold close to it, then
//! a descent that is fast high up and soft near the surface, until the supervisor reports the touchdown.

use super::{Leg, Mission, MissionInputs, MissionState, Phase};
use crate::types::{Micros, Setpoint, StateEstimate};

/// Descent rate of an emergency landing without a usable estimate, m/s.
const FAULT_DESCENT_SPEED_M_S: f32 = 0.5;
/// Over the pad, within this of its centre the approach holds position; farther it flies a velocity
/// profile towards it, m.
const APPROACH_HOLD_RADIUS_M: f32 = 0.06;

impl<const CELLS: usize, const QUEUE: usize> Mission<CELLS, QUEUE> {
    /// Fast from cruise height, slower close to the surface below, for a soft touchdown; once (nearly) down,
    /// ask for a fast descent, which the controller can only answer by dropping the thrust well below hover:
    /// that is what the supervisor's touchdown detection waits for. The time spent descending is time the
    /// flow-only position drifts off the pad centre (≈ 1 cm/√s), so only the last centimetres are slow.
    pub(super) fn descent_speed(&self, state: &StateEstimate) -> f32 {
        let above = state.position_m[2] - state.surface_height_m;
        let d = self.config.descent_speed_m_s;
        if above < 0.04 {
            3.0 * d
        } else if above < 0.2 {
            d
        } else {
            self.config.high_descent_speed_m_s.max(d)
        }
    }

    /// Descent rate after the estimate was lost, m/s: [`FAULT_DESCENT_SPEED_M_S`] down to 0.1 m above the
    /// surface, then the normal soft touchdown.
    pub(super) fn fault_descent_speed(&self, state: &StateEstimate) -> f32 {
        let above = state.position_m[2] - state.surface_height_m;
        if above > 0.1 {
            FAULT_DESCENT_SPEED_M_S
        } else {
            self.descent_speed(state)
        }
    }

    /// Over the pad: a velocity profile towards its centre, position hold within
    /// [`APPROACH_HOLD_RADIUS_M`]; once settled, the descent begins.
    pub(super) fn approach(
        &mut self,
        now: Micros,
        state: &StateEstimate,
        (px, py): (f32, f32),
        settled_since: Option<Micros>,
    ) -> Setpoint {
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let err = libm::hypotf(x - px, y - py);
        let slow = libm::hypotf(state.velocity_m_s[0], state.velocity_m_s[1]) < 0.05;
        let settled_since = if err < self.config.settle_tolerance_m && slow {
            Some(settled_since.unwrap_or(now))
        } else {
            None
        };
        if let Some(t0) = settled_since
            && (now - t0) as f32 * 1e-6 >= self.config.settle_s
        {
            self.phase = Phase::Land { x: px, y: py };
        } else {
            self.phase = Phase::Approach {
                x: px,
                y: py,
                settled_since,
            };
        }
        if err > APPROACH_HOLD_RADIUS_M {
            // Far from the centre (the lock comes mid-line, the drone still moving away): a firm
            // velocity profile brings it back faster than the position loop's gentle step response.
            let speed = self
                .config
                .search_speed_m_s
                .min(2.0 * (err - 0.5 * APPROACH_HOLD_RADIUS_M));
            return Setpoint::Velocity {
                vx_m_s: speed * (px - x) / err,
                vy_m_s: speed * (py - y) / err,
                z_m: self.params.height_m,
                yaw_rad: self.heading,
            };
        }
        Setpoint::Position {
            x_m: px,
            y_m: py,
            z_m: self.params.height_m,
            yaw_rad: self.heading,
        }
    }

    /// Descending onto the pad until the supervisor reports the touchdown.
    pub(super) fn land(
        &mut self,
        state: &StateEstimate,
        inputs: &MissionInputs,
        (px, py): (f32, f32),
        now: Micros,
    ) -> Setpoint {
        if inputs.landed {
            return match self.leg {
                Leg::Outbound => {
                    self.phase = Phase::OnPad { since: now };
                    Setpoint::Stop
                }
                Leg::Return => {
                    let end = if self.link_lost_home {
                        MissionState::LinkLostHome
                    } else if self.pad_not_found {
                        MissionState::PadNotFound
                    } else {
                        MissionState::Completed
                    };
                    self.phase = Phase::Ended(end);
                    Setpoint::Stop
                }
            };
        }
        Setpoint::Descend {
            x_m: px,
            y_m: py,
            vz_m_s: -self.descent_speed(state),
            yaw_rad: self.heading,
        }
    }
}
