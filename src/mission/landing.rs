//! Approach and touchdown: back over the pad centre on a velocity profile, position hold close to it, then
//! a descent that is fast high up and soft near the surface, until the supervisor reports the touchdown.
//!
//! No descent without the [descent gate](crate::landing::gate)'s consent: over a pad, the clearance rule
//! (offset + the estimate's uncertainty within the pad's top, with a margin) and a run of downward readings
//! at the pad's level; over the floor (the pad was not found), a run at the floor's level. A refusal over a
//! pad starts the refinement afresh around the estimate (at most [`MAX_REFUSALS`] times, then the search
//! gives up and lands clear of the pad); a refusal over the floor moves to the next floor spot. A descent
//! whose readings turn to the floor while still above the pad's height climbs back and counts as a refusal.

use super::{Leg, Mission, MissionInputs, MissionState, Phase, Search};
use crate::landing::gate::{self, Clearance, SurfaceVotes, Target, Verdict};
use crate::types::{Micros, Setpoint, StateEstimate};

/// Descents refused over a pad (each followed by a fresh refinement) before the search gives up, per leg.
pub(super) const MAX_REFUSALS: u8 = 2;
/// Floor spots refused (a pad top under each) before the drone lands where it is.
const MAX_FLOOR_REFUSALS: u8 = 4;
/// The body's centre keeps this far inside the pad's edge, beyond the estimate's uncertainty, m.
const PAD_EDGE_MARGIN_M: f32 = 0.04;
/// Pad height assumed before the detector has measured one, m (the pads are ~10 cm high).
const PAD_HEIGHT_FALLBACK_M: f32 = 0.1;
/// Pad centres remembered across the detector's restarts on one leg (see [`Touchdown::glimpses`]): a leg
/// restarts it at most a few times (two refusals, two widenings, a refinement round each).
const GLIMPSES: usize = 6;
/// An estimate that moves farther than this between two readings leaves a glimpse behind, m.
const GLIMPSE_SPACING_M: f32 = 0.1;
/// An approach that has not descended after this long is refused, s (readings missing or undecided).
const APPROACH_TIMEOUT_S: f32 = 6.0;

/// The descent gate's state for the current leg (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Touchdown {
    /// What the current approach lands on.
    pub target: Target,
    /// Downward readings over the target since the drone settled there.
    pub votes: SurfaceVotes,
    /// Descents refused over a pad on this leg.
    pub refusals: u8,
    /// Searches widened and re-centred on this leg.
    pub widenings: u8,
    /// Floor spots refused on this leg.
    pub floor_refusals: u8,
    /// When the current approach began.
    pub since: Option<Micros>,
    /// Pad centres the detector had estimated on this leg before it started afresh (a refused descent, a
    /// refinement round, a widened search) or that it refit elsewhere ([`Touchdown::note_estimate`]),
    /// newest first: a landing clear of the pad keeps clear of each,
    /// since the detector's current estimate (if any) knows nothing of them (measured: a pad next to a
    /// wall, three rounds without a lock, then a floor spot 5 cm beside the pad's side, touched).
    pub glimpses: [Option<(f32, f32)>; GLIMPSES],
    /// The detector's latest centre estimate since it last started afresh ([`Touchdown::note_estimate`]):
    /// kept when a refit drops the estimate itself (its outlier loop can leave none), so that the restart
    /// still leaves it as a glimpse, and compared with each new estimate to keep the ones refit elsewhere.
    pub latest: Option<(f32, f32)>,
}

impl Touchdown {
    pub(super) const fn new() -> Self {
        Self {
            target: Target::PadTop,
            votes: SurfaceVotes::new(),
            refusals: 0,
            widenings: 0,
            floor_refusals: 0,
            since: None,
            glimpses: [None; GLIMPSES],
            latest: None,
        }
    }

    /// Keep `centre` as the newest glimpse (the oldest one is forgotten when all slots are full).
    pub(super) fn remember_glimpse(&mut self, centre: (f32, f32)) {
        if centre.0.is_finite() && centre.1.is_finite() {
            self.glimpses.rotate_right(1);
            self.glimpses[0] = Some(centre);
        }
    }

    /// The detector's estimate after a new reading: an estimate that moved more than
    /// [`GLIMPSE_SPACING_M`] from the previous one is a different hypothesis (a crossing that refit it
    /// elsewhere), and the previous one is kept as a glimpse, so a landing clear of the pad keeps clear of
    /// both (an estimate over the pad can refit 29 cm away, off it, and a floor spot 35 cm from the new
    /// one can then lie on the real pad's rim).
    pub(super) fn note_estimate(&mut self, centre: (f32, f32)) {
        if let Some(previous) = self.latest
            && libm::hypotf(previous.0 - centre.0, previous.1 - centre.1) > GLIMPSE_SPACING_M
        {
            self.remember_glimpse(previous);
        }
        self.latest = Some(centre);
    }
}

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

    /// The longest a descent without a valid estimate may take, µs: from the last valid height above the
    /// surface (clamped to 0..3 m) plus 0.2 m for a pad edge or a height error, at the slowest rate
    /// [`Self::fault_descent_speed`] may command, plus 1 s. From 0.6 m: 5 s.
    pub(super) fn blind_descent_bound_us(&self) -> u64 {
        let height_m = if self.last_valid_height_m.is_finite() {
            self.last_valid_height_m.clamp(0.0, 3.0)
        } else {
            3.0
        };
        let slowest_m_s = self.config.descent_speed_m_s.clamp(0.05, FAULT_DESCENT_SPEED_M_S);
        (((height_m + 0.2) / slowest_m_s + 1.0) * 1e6) as u64
    }

    /// Start the pad detector afresh within a leg, remembering its estimate (or, when a refit has dropped
    /// that, its latest one) as a glimpse.
    pub(super) fn restart_pad_detector(&mut self) {
        if let Some(centre) = self.pad.estimate().map(|e| (e.x, e.y)).or(self.touchdown.latest) {
            self.touchdown.remember_glimpse(centre);
        }
        self.touchdown.latest = None;
        self.pad.reset();
    }

    /// The pad's height as the detector measured it (median of its crossings' steps), m.
    pub(super) fn pad_height(&self) -> f32 {
        let mut steps = [0.0f32; 8];
        let mut n = 0;
        for (slot, c) in steps.iter_mut().zip(self.pad.crossings().iter().filter(|c| c.inlier)) {
            *slot = c.step_m;
            n += 1;
        }
        let steps = steps.get_mut(..n).unwrap_or(&mut []);
        steps.sort_unstable_by(f32::total_cmp);
        match steps.get(n / 2) {
            Some(h) if h.is_finite() && *h > 0.0 => *h,
            _ => PAD_HEIGHT_FALLBACK_M,
        }
    }

    /// A downward reading while approaching or descending: the gate's surface votes.
    pub(super) fn touchdown_reading(&mut self, range_m: f32, cos_tilt: f32, state: &StateEstimate) {
        let pad_height = self.pad_height();
        self.touchdown
            .votes
            .update(range_m, cos_tilt, state.position_m[2], pad_height);
    }

    /// Start an approach to `(x, y)`, landing on `target`.
    pub(super) fn begin_approach(&mut self, (x, y): (f32, f32), target: Target) -> Setpoint {
        self.touchdown.target = target;
        self.touchdown.votes.clear();
        self.touchdown.since = None;
        self.phase = Phase::Approach {
            x,
            y,
            settled_since: None,
        };
        Setpoint::Position {
            x_m: x,
            y_m: y,
            z_m: self.params.height_m,
            yaw_rad: self.heading,
        }
    }

    /// The clearance rule (module docs) for a drone `offset_m` from the pad estimate, `age_s` after the
    /// approach began.
    fn clearance_allows(&self, offset_m: f32, age_s: f32) -> bool {
        let rule = Clearance {
            pad_size_m: self.config.pad.pad_size_m,
            margin_m: PAD_EDGE_MARGIN_M,
        };
        let Some(e) = self.pad.estimate() else {
            return false;
        };
        let both = e.min_direction_crossings >= 0.8;
        rule.allows(offset_m, rule.uncertainty_m(e.rms_residual_m, age_s, both))
    }

    /// The gate refused a descent: over a pad, refine afresh around the estimate (or give up after
    /// [`MAX_REFUSALS`]); over the floor, try the next floor spot.
    fn refuse_descent(&mut self, state: &StateEstimate, (px, py): (f32, f32)) -> Setpoint {
        match self.touchdown.target {
            Target::PadTop => {
                self.touchdown.refusals = self.touchdown.refusals.saturating_add(1);
                if self.touchdown.refusals > MAX_REFUSALS {
                    return self.give_up_search(state);
                }
                let centre = self.pad.estimate().map_or((px, py), |e| (e.x, e.y));
                self.restart_pad_detector();
                let refine = Search::Refine {
                    stage: 0,
                    line: 0,
                    end: 0,
                    centre,
                    first_along_x: self.touchdown.refusals % 2 == 1,
                    crossings_before: 0,
                };
                self.phase = Phase::Search(refine);
                self.search(refine, state, 0.02)
            }
            Target::Floor => {
                self.touchdown.floor_refusals = self.touchdown.floor_refusals.saturating_add(1);
                if self.touchdown.floor_refusals > MAX_FLOOR_REFUSALS {
                    // Every spot had a pad under it: the centre is over a pad's top, where no side is touched.
                    self.phase = Phase::Land { x: px, y: py };
                    return self.land_setpoint(state, (px, py));
                }
                self.land_clear_of_pad(state)
            }
        }
    }

    /// Over the target: a velocity profile towards it, position hold within [`APPROACH_HOLD_RADIUS_M`];
    /// once settled there and the [descent gate](crate::landing::gate) agrees, the descent begins.
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
        let settled = err < self.config.settle_tolerance_m && slow;
        let settled_since = if settled {
            Some(settled_since.unwrap_or(now))
        } else {
            // Only readings taken over the target count.
            self.touchdown.votes.clear();
            None
        };
        let since = *self.touchdown.since.get_or_insert(now);
        let age_s = now.saturating_sub(since) as f32 * 1e-6;
        let rule_ok = self.touchdown.target == Target::Floor || self.clearance_allows(err, age_s);
        let verdict = gate::verdict(self.touchdown.target, rule_ok, settled, &self.touchdown.votes);
        if verdict == Verdict::Refuse || age_s > APPROACH_TIMEOUT_S {
            return self.refuse_descent(state, (px, py));
        }
        if let Some(t0) = settled_since
            && verdict == Verdict::Descend
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
            return self.velocity_towards(state, (px, py), APPROACH_HOLD_RADIUS_M, self.params.height_m);
        }
        Setpoint::Position {
            x_m: px,
            y_m: py,
            z_m: self.params.height_m,
            yaw_rad: self.heading,
        }
    }

    /// A firm velocity profile at height `z_m` towards `target`, from farther than `hold_radius_m` (where a
    /// position hold takes over): at most the search speed, 2 m/s per metre of distance beyond half that
    /// radius, bounded by the live beams as on a search line (a pad beside an obstacle the map missed).
    pub(super) fn velocity_towards(
        &self,
        state: &StateEstimate,
        (px, py): (f32, f32),
        hold_radius_m: f32,
        z_m: f32,
    ) -> Setpoint {
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let err = libm::hypotf(x - px, y - py);
        if err.is_nan() || err <= 1e-3 {
            return Setpoint::Position {
                x_m: px,
                y_m: py,
                z_m,
                yaw_rad: self.heading,
            };
        }
        let speed = self.config.search_speed_m_s.min(2.0 * (err - 0.5 * hold_radius_m));
        let ((vx, vy), _) = self.live_beam_guard(state, (speed * (px - x) / err, speed * (py - y) / err));
        Setpoint::Velocity {
            vx_m_s: vx,
            vy_m_s: vy,
            z_m,
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
                Leg::Hover => {
                    let end = if self.link_lost_home {
                        MissionState::LinkLostHome
                    } else {
                        MissionState::Completed
                    };
                    self.phase = Phase::Ended(end);
                    Setpoint::Stop
                }
                // The exploration always ends on the return leg; a landing in it is the home landing.
                Leg::Return | Leg::Explore => {
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
        // The floor under a pad landing while still above the pad's height: the drone is beside the pad
        // (drift during the descent, or a wrong lock); climb back and refine instead of touching its side.
        // The hover test lands on its take-off point, whatever lies under it (it took off from the floor
        // or from a pad): it has no pad to refine, and a search is not its mode's (`mode_states`).
        let above_floor = state.position_m[2];
        if self.leg != Leg::Hover
            && self.touchdown.target == Target::PadTop
            && self.touchdown.votes.floor_run() >= 2 * gate::DECIDING_READINGS
            && above_floor > self.pad_height() + 0.08
        {
            self.touchdown.votes.clear();
            return self.refuse_descent(state, (px, py));
        }
        self.land_setpoint(state, (px, py))
    }

    fn land_setpoint(&self, state: &StateEstimate, (px, py): (f32, f32)) -> Setpoint {
        Setpoint::Descend {
            x_m: px,
            y_m: py,
            vz_m_s: -self.descent_speed(state),
            yaw_rad: self.heading,
        }
    }
}
