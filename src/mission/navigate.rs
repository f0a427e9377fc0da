//! The navigation leg, from take-off to the pad search: the drone's cell and the map's changes go to D\* Lite
//! one bounded slice per tick, the path is shortened, and the next waypoint becomes a velocity through the
//! reactive avoidance, slowed into corners and next to regions no beam has looked into. Also the no-path
//! fallbacks (the narrow margin, the escape from an inflated cell). The rules are in the
//! [mission's documentation](super); this file holds their arithmetic.

use super::{Leg, Mission, Phase};
use crate::math::wrap_angle;
use crate::nav::dstar::{PlanError, PlanStatus};
use crate::nav::map::{CELL_SIZE_M, Cell, GridShape, Traversability};
use crate::nav::path::{extract_path, simplify};
use crate::types::{Micros, MultiRangerSample, Setpoint, StateEstimate};

/// Speed at a waypoint where the path turns by 90° or more, m/s.
const CORNER_MIN_SPEED_M_S: f32 = 0.15;
/// Speed allowed per metre of distance before a waypoint, on top of its corner speed, 1/s. (1.5 rounded a
/// wall end in the `slalom` world at 0.4 m/s with 20 cm of drift and grazed it; 1.2 did not, in 20 noise
/// seeds, and cost nothing measurable elsewhere in simulator batches.)
const CORNER_APPROACH_GAIN: f32 = 1.2;
/// Look this far along the path for regions no beam has looked into, m.
const UNOBSERVED_LOOKAHEAD_M: f32 = 0.6;
/// A path point counts as next to an unobserved region when such a cell lies within this distance, m: the
/// drone's radius (0.06 m) plus the estimate's drift and tracking error, and a cell of the map's own error at
/// a surface. (0.15 m missed the unseen end of a wall 0.17 m beside the path, whose face row beams passing a
/// centimetre off had marked free; the drone, 6 cm inside the path's corner, touched it in simulation.)
const UNOBSERVED_CLEARANCE_M: f32 = 0.22;
/// Within this distance of the path ahead (the body's radius, 0.06 m, and as much again of tracking and
/// estimate error: the width the drone sweeps), a cell not seen free needs only
/// [`CORRIDOR_MIN_NEIGHBOURS`] such neighbours to count as unobserved, m. The region test's five is meant
/// for the one-cell gaps four beams leave between their traces in open space; a post of 2 × 2 cells whose
/// surroundings the beams have already swept has only three, so it would pass as a gap, and a drone turning
/// at 0.5 m/s onto such a post (about 10 cm across) with every beam pointing elsewhere would meet it.
const CORRIDOR_M: f32 = 0.12;
/// See [`CORRIDOR_M`]: a gap between beam traces has at most two unseen neighbours along it.
const CORRIDOR_MIN_NEIGHBOURS: u8 = 3;
/// A cell not seen free belongs to an unobserved region with at least this many such or occupied
/// neighbours (see [`OccupancyGrid::is_weakly_observed_region`]).
const UNOBSERVED_MIN_NEIGHBOURS: u8 = 5;
/// A cell counts as seen free at this log-odds or below: its misses (−3 each) outweigh its hits (+8 each),
/// so one miss alone, or three after a hit. A cell a beam hit once and then missed (8 − 3 = 5), below the
/// occupied threshold, is evidence of something, not free space: to
/// [`OccupancyGrid::is_unobserved_region`] it would be "seen": a wall's end or a thin cylinder the map holds
/// as such sub-threshold cells would be flown at. (−6, two misses net, slowed the median mission by 2.5 s on
/// 4 000 simulated runs for no fewer contacts.)
const SEEN_FREE_LOG_ODDS: i8 = -1;
/// Next to a contested cell (a hit and a miss), a cell counts as seen free only at this log-odds or below
/// (two net misses): see [`OccupancyGrid::is_doubtful_region`].
const CONTESTED_SEEN_FREE_LOG_ODDS: i8 = -6;
/// Speed next to an unobserved region, m/s: slow enough that the sweeping beams look into it before the
/// drone is there.
const UNOBSERVED_MIN_SPEED_M_S: f32 = 0.2;
/// Speed allowed per metre of observed path before an unobserved region, 1/s.
const UNOBSERVED_APPROACH_GAIN: f32 = 1.0;
/// Largest turn away from the direction of travel to look at an unobserved region, rad.
const LOOK_MAX_OFFSET_RAD: f32 = 0.8;
/// A beam keeps looking at an unobserved region while its turn is within this much of the least turn any
/// beam needs, rad. (With the least turn alone, a cell about 45° off the travel direction made the front
/// and side beams trade places every few ticks: the heading flipped by 90°, reached neither, and the box's
/// end between them was never seen.)
const LOOK_CHOICE_HYSTERESIS_RAD: f32 = 0.35;
/// See [`UNOBSERVED_MIN_SPEED_M_S`] and [`UNOBSERVED_APPROACH_GAIN`]: the search lines use the same rule.
pub(super) const SEARCH_UNOBSERVED_MIN_SPEED_M_S: f32 = UNOBSERVED_MIN_SPEED_M_S;
pub(super) const SEARCH_UNOBSERVED_APPROACH_GAIN: f32 = UNOBSERVED_APPROACH_GAIN;
/// The live beams' stop distance while navigating, m: the body's radius (0.06 m), 5 cm of the velocity
/// loop's lag at the 0.2 m/s the drone flies near what the map does not hold, 2 cm of ranger noise. Less
/// than a search line's [`LIVE_BEAM_STOP_M`](super::search::LIVE_BEAM_STOP_M): the legs thread gaps the
/// search lines keep out of (0.2 m would close a 0.4 m gap).
const NAVIGATION_LIVE_BEAM_STOP_M: f32 = 0.13;
/// Heading sweep while navigating: amplitude, rad, and period, s.
const SCAN_AMPLITUDE_RAD: f32 = 0.6;
const SCAN_PERIOD_S: f32 = 2.0;

/// A horizontal beam reading closer than this on the ground moves the take-off point away from its return,
/// m: the body's radius (0.06 m) and 8 cm for the lift-off's drift and the estimate's.
const TAKE_OFF_CLEAR_M: f32 = 0.14;
/// Longest such step, m.
const TAKE_OFF_MAX_STEP_M: f32 = 0.1;
/// The fast lift-off's height above the take-off height, m: clear of a pad's top (0.1 m) beside the start.
const TAKE_OFF_HOP_M: f32 = 0.13;
/// The fast lift-off's climb rate, m/s.
pub(super) const TAKE_OFF_HOP_SPEED_M_S: f32 = 0.8;

/// A look at an unobserved cell is given up after its beam returned nothing this many sweeps in a row (one
/// is a dropout: 3–5 % per beam in the stress settings).
const BLIND_LOOK_SWEEPS: u8 = 2;
/// A look given up stays given up this long, µs: one whole heading sweep, so the sweep's phase cannot flip
/// the heading back and forth between the two.
const BLIND_LOOK_SCAN_US: Micros = (SCAN_PERIOD_S * 1e6) as Micros;
/// The look's beam points at its cell when the bearing lies this close to the beam's axis, rad (otherwise
/// the look is clamped at [`LOOK_MAX_OFFSET_RAD`] and its beam's returns say nothing about the cell).
const BLIND_LOOK_ON_AXIS_RAD: f32 = 0.1;

/// Which horizontal beams return nothing, and whether a look at an unobserved cell was given up for that
/// reason (see [`Mission::navigate`]). Four counters and a time: 24 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct BlindLook {
    /// Consecutive sweeps without a return, per beam: front, back, left, right (saturating).
    no_return_sweeps: [u8; 4],
    /// The heading sweeps instead of looking until then.
    scan_until: Option<Micros>,
}

impl BlindLook {
    pub(super) const NEW: Self = Self {
        no_return_sweeps: [0; 4],
        scan_until: None,
    };

    /// One Multi-ranger sweep.
    pub(super) fn on_ranges(&mut self, ranges: &MultiRangerSample) {
        for (count, reading) in self.no_return_sweeps.iter_mut().zip(ranges.horizontal()) {
            *count = if reading.is_some_and(|d| d.is_finite() && d > 0.02) {
                0
            } else {
                count.saturating_add(1)
            };
        }
    }

    /// Whether looking from `here` at `cell` with the heading `look` would map nothing: the front, left
    /// or right beam that points at it has returned nothing for [`BLIND_LOOK_SWEEPS`] sweeps (it then stays
    /// given up for [`BLIND_LOOK_SCAN_US`]).
    pub(super) fn is_futile(&mut self, now: Micros, look: f32, here: (f32, f32), cell: (f32, f32)) -> bool {
        if self.scan_until.is_some_and(|until| now < until) {
            return true;
        }
        self.scan_until = None;
        let bearing = libm::atan2f(cell.1 - here.1, cell.0 - here.0);
        // (index into `no_return_sweeps`, the beam's axis in the body frame)
        let beams = [
            (0, 0.0),
            (2, core::f32::consts::FRAC_PI_2),
            (3, -core::f32::consts::FRAC_PI_2),
        ];
        let blind = beams.into_iter().any(|(beam, axis)| {
            libm::fabsf(wrap_angle(bearing - look - axis)) <= BLIND_LOOK_ON_AXIS_RAD
                && self.no_return_sweeps[beam] >= BLIND_LOOK_SWEEPS
        });
        if blind {
            self.scan_until = Some(now.saturating_add(BLIND_LOOK_SCAN_US));
        }
        blind
    }
}

/// A map whose blocked cells grow by one cell (8-neighbourhood): the margin shortcuts keep.
struct Dilated<'a, M: Traversability>(&'a M);

impl<M: Traversability> Traversability for Dilated<'_, M> {
    fn shape(&self) -> GridShape {
        self.0.shape()
    }

    fn is_blocked(&self, x: i32, y: i32) -> bool {
        (-1..=1).any(|dy| (-1..=1).any(|dx| self.0.is_blocked(x + dx, y + dy)))
    }
}

impl<const CELLS: usize, const QUEUE: usize> Mission<CELLS, QUEUE> {
    /// The leg's target: the nominal goal going out, the start coming back.
    pub(super) fn leg_target(&self) -> (f32, f32) {
        match self.leg {
            Leg::Outbound => self.params.goal_m,
            Leg::Return | Leg::Hover => self.params.start_m,
            Leg::Explore => self.explore_target(),
        }
    }

    pub(super) fn begin_leg(&mut self, _now: Micros, state: &StateEstimate, leg: Leg) -> Setpoint {
        self.leg = leg;
        self.restore_full_inflation();
        self.planner_needs_reset = true;
        self.pad.reset();
        self.sweep = None;
        self.avoidance.reset();
        let (x, y) = (state.position_m[0], state.position_m[1]);
        // Something beside the drone on the ground (a generated start may lie one body radius from the home
        // pad's side): the climb first steps away from it, so the lift-off's drift cannot touch it.
        let (x, y) = if matches!(leg, Leg::Outbound | Leg::Return) {
            let (dx, dy) = self.take_off_step_away(state.attitude_rad[2]);
            (x + dx, y + dy)
        } else {
            (x, y)
        };
        let z_target = state.position_m[2].max(0.0);
        let hop_until_m = z_target + TAKE_OFF_HOP_M;
        self.phase = Phase::TakeOff {
            x,
            y,
            z_target,
            hop_until_m,
        };
        Setpoint::Position {
            x_m: x,
            y_m: y,
            z_m: z_target,
            yaw_rad: self.heading,
        }
    }

    /// The step away from what the horizontal beams read within [`TAKE_OFF_CLEAR_M`] while the drone stands
    /// on the ground, arena frame, m (at most [`TAKE_OFF_MAX_STEP_M`] long; zero when nothing is that close).
    /// Each such return pushes the take-off point away along its beam by the shortfall.
    pub(super) fn take_off_step_away(&self, yaw: f32) -> (f32, f32) {
        if !yaw.is_finite() {
            return (0.0, 0.0);
        }
        let (c, s) = (libm::cosf(yaw), libm::sinf(yaw));
        let ranges = [
            self.last_ranges.front,
            self.last_ranges.back,
            self.last_ranges.left,
            self.last_ranges.right,
        ];
        let mut step = (0.0f32, 0.0f32);
        for (range, (bx, by)) in ranges.into_iter().zip(MultiRangerSample::HORIZONTAL_BEAMS_BODY) {
            let Some(d) = range.filter(|d| d.is_finite() && *d >= 0.0 && *d < TAKE_OFF_CLEAR_M) else {
                continue;
            };
            let (ux, uy) = (c * bx - s * by, s * bx + c * by);
            step = (
                step.0 - (TAKE_OFF_CLEAR_M - d) * ux,
                step.1 - (TAKE_OFF_CLEAR_M - d) * uy,
            );
        }
        let length = libm::hypotf(step.0, step.1);
        if length > TAKE_OFF_MAX_STEP_M {
            (
                step.0 * TAKE_OFF_MAX_STEP_M / length,
                step.1 * TAKE_OFF_MAX_STEP_M / length,
            )
        } else {
            step
        }
    }

    pub(super) fn full_inflation_cells(&self) -> u8 {
        libm::ceilf(self.config.inflation_radius_m / CELL_SIZE_M).clamp(0.0, 16.0) as u8
    }

    pub(super) fn narrow_inflation_cells(&self) -> u8 {
        libm::ceilf(self.config.narrow_inflation_radius_m / CELL_SIZE_M).clamp(0.0, 16.0) as u8
    }

    /// Whether the planner currently uses the narrow no-path fallback margin.
    pub(super) fn narrow(&self) -> bool {
        self.grid.inflation_radius_cells() < self.full_inflation_cells()
    }

    /// Back to the full margin (a new leg plans with it first).
    pub(super) fn restore_full_inflation(&mut self) {
        let full = self.full_inflation_cells();
        if self.grid.inflation_radius_cells() != full {
            self.grid.set_inflation_radius(full, &mut self.changed);
        }
    }

    pub(super) fn cell_of(&self, p: (f32, f32)) -> Cell {
        let max_x = (self.shape.width.saturating_sub(1)) as f32;
        let max_y = (self.shape.height.saturating_sub(1)) as f32;
        let cx = libm::floorf(p.0 / CELL_SIZE_M).clamp(0.0, max_x);
        let cy = libm::floorf(p.1 / CELL_SIZE_M).clamp(0.0, max_y);
        // NaN clamps to NaN; `as` turns it into 0, a valid cell.
        Cell::new(cx as u16, cy as u16)
    }

    /// The drone's cell for planning: itself, or, when inflation has swallowed it (it flew a little close to
    /// a wall), the nearest free cell within 0.3 m, so the plan leads out instead of reporting no path.
    pub(super) fn escape_cell(&self, here: Cell) -> Cell {
        if !self.grid.is_blocked(here) {
            return here;
        }
        let (hx, hy) = (i32::from(here.x), i32::from(here.y));
        for radius in 1..=6i32 {
            let mut best: Option<(i32, Cell)> = None;
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    if dx.abs() != radius && dy.abs() != radius {
                        continue;
                    }
                    let (x, y) = (hx + dx, hy + dy);
                    if !self.shape.contains(x, y) {
                        continue;
                    }
                    let c = Cell::new(x as u16, y as u16);
                    let d = dx * dx + dy * dy;
                    if !self.grid.is_blocked(c) && best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, c));
                    }
                }
            }
            if let Some((_, c)) = best {
                return c;
            }
        }
        here
    }

    /// Feed map changes and the drone's cell to the planner and run one budgeted slice.
    /// `Ok(Some(target))`: a path exists, fly towards `target`; `Ok(None)`: no path; `Err(())`: the slice
    /// did not finish (keep flying the previous target).
    pub(super) fn plan(&mut self, state: &StateEstimate) -> Result<Option<(f32, f32)>, ()> {
        let here = self.escape_cell(self.cell_of((state.position_m[0], state.position_m[1])));
        // A nominal goal inside the inflated margin of something mapped (a box beside the pad, a stray
        // return) would end the leg with no path: plan to the nearest free cell instead; the pad search
        // starts from there (see [`Self::navigate`]). A goal that moves needs a fresh plan.
        let goal = self.escape_cell(self.cell_of(self.leg_target()));
        if self.planner_needs_reset || self.changed.overflowed() || goal != self.planner.goal() {
            if self.planner.reset(self.shape, here, goal).is_err() {
                return Err(());
            }
            self.changed.clear();
            self.planner_needs_reset = false;
            self.stats.plans_from_scratch += 1;
        } else {
            if self.planner.set_start(here).is_err() {
                self.planner_needs_reset = true;
                return Err(());
            }
            if !self.changed.is_empty() {
                if self.planner.cells_changed(&self.grid, self.changed.as_slice()).is_err() {
                    self.planner_needs_reset = true;
                    return Err(());
                }
                self.changed.clear();
                self.stats.replans += 1;
            }
        }
        match self.planner.compute(&self.grid, self.config.planner_budget) {
            Ok(PlanStatus::Found { .. }) => {
                self.stats.last_expansions = self.planner.expansions();
                if extract_path(&self.planner, &self.grid, &mut self.path).is_err() {
                    self.planner_needs_reset = true;
                    return Err(());
                }
                // Shortcuts must keep one more cell from the inflated obstacles than the path itself: a
                // straight leg hugging an inflated corner leaves no room for tracking and estimate errors.
                simplify(&Dilated(&self.grid), &self.path, &mut self.waypoints);
                // From an escape cell, first fly to it.
                let target = if here != self.cell_of((state.position_m[0], state.position_m[1])) {
                    self.shape.center_of(here)
                } else {
                    match self.waypoints.get(1) {
                        Some(c) => self.shape.center_of(*c),
                        None => self.leg_target(),
                    }
                };
                Ok(Some(target))
            }
            Ok(PlanStatus::NoPath) => {
                self.stats.last_expansions = self.planner.expansions();
                self.waypoints.clear();
                Ok(None)
            }
            Ok(PlanStatus::Incomplete) => Err(()),
            Err(PlanError::QueueFull) | Err(_) => {
                self.planner_needs_reset = true;
                Err(())
            }
        }
    }

    pub(super) fn navigate(&mut self, now: Micros, state: &StateEstimate, dt_s: f32) -> Setpoint {
        // Exploring: a frontier reached, gone stale or not reached in time ends this flight (see `explore`).
        if self.leg == Leg::Explore
            && let Some(setpoint) = self.explore_progress(now, state)
        {
            return setpoint;
        }
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let target_leg = self.leg_target();
        let to_goal = libm::hypotf(target_leg.0 - x, target_leg.1 - y);
        let planned_goal = self.planner.goal();
        let at_substitute_goal = planned_goal != self.cell_of(target_leg) && {
            let (gx, gy) = self.shape.center_of(planned_goal);
            libm::hypotf(gx - x, gy - y) < self.config.goal_tolerance_m
        };
        if self.leg != Leg::Explore
            && (to_goal < self.config.goal_tolerance_m || (at_substitute_goal && !self.planner_needs_reset))
        {
            return self.begin_search(state);
        }
        let target = match self.plan(state) {
            Ok(Some(t)) => Some(t),
            // No path to a frontier: drop it and choose another (the no-path rules are for the way home).
            Ok(None) if self.leg == Leg::Explore => return self.drop_frontier(now, state),
            Ok(None) if !self.narrow() && self.narrow_inflation_cells() < self.full_inflation_cells() => {
                // The full margin closes every way: try the narrow one (next tick plans with it), holding
                // position meanwhile.
                let narrow = self.narrow_inflation_cells();
                self.grid.set_inflation_radius(narrow, &mut self.changed);
                return Setpoint::Position {
                    x_m: x,
                    y_m: y,
                    z_m: self.params.height_m,
                    yaw_rad: self.heading,
                };
            }
            Ok(None) => {
                self.phase = Phase::NoPath { since: now, x, y };
                return Setpoint::Position {
                    x_m: x,
                    y_m: y,
                    z_m: self.params.height_m,
                    yaw_rad: self.heading,
                };
            }
            // An unfinished repair: keep heading for the previous waypoint, if any.
            Err(()) => self.waypoints.get(1).map(|c| self.shape.center_of(*c)),
        };
        let (dvx, dvy) = match target {
            Some((tx, ty)) => {
                let (dx, dy) = (tx - x, ty - y);
                let d = libm::hypotf(dx, dy);
                // Slow into the goal (stop within ~0.5 s at 1 m/s²) and never overshoot a waypoint hard.
                let cruise = if self.narrow() {
                    self.params.speed_m_s.min(self.config.narrow_speed_m_s)
                } else {
                    self.params.speed_m_s
                };
                let mut speed = cruise
                    .min(libm::sqrtf(2.0 * 0.8 * to_goal))
                    .min(self.corner_speed(cruise, (x, y), (tx, ty)) + CORNER_APPROACH_GAIN * d);
                let (observed, unobserved_cell) = self.observed_ahead_m((x, y), (tx, ty));
                speed = speed.min(UNOBSERVED_MIN_SPEED_M_S + UNOBSERVED_APPROACH_GAIN * observed);
                if d > 0.05 {
                    // Face the direction of travel, sweeping the heading ±SCAN_AMPLITUDE so the front ranger also
                    // sees obstacles diagonally ahead (a wall's end beside the path is otherwise invisible to
                    // four beams until the drone is abeam of it); fly only as fast as the ranger looks ahead.
                    let phase = 2.0 * core::f32::consts::PI * (now as f32 * 1e-6) / SCAN_PERIOD_S;
                    let travel = libm::atan2f(dy, dx);
                    let sweep = || wrap_angle(travel + SCAN_AMPLITUDE_RAD * libm::sinf(phase));
                    self.heading = match unobserved_cell {
                        // An unobserved region beside the path ahead: instead of sweeping (whose phase may
                        // look the other way all along the approach), point the beam that needs the least
                        // turn (front, left or right) at it, so it is seen before the drone is there.
                        // Unless the beam that would look returns nothing: with no return a beam maps
                        // nothing, so the region would stay unobserved however long it looked (open space
                        // beyond the ranger's 4 m straight ahead: a box's corner 4 cm beside the path was
                        // met by the drone still looking along it). The sweep then
                        // turns the beams onto what they can return from, beside the path.
                        Some(cell) => {
                            let look = Self::look_at_heading(travel, self.heading, (x, y), cell);
                            if self.blind_look.is_futile(now, look, (x, y), cell) {
                                sweep()
                            } else {
                                look
                            }
                        }
                        None => sweep(),
                    };
                    // The front beam must look where the drone actually goes: judge the heading against the
                    // velocity (which turns smoothly) rather than the new target's direction.
                    let (vx, vy) = (state.velocity_m_s[0], state.velocity_m_s[1]);
                    let moving = if libm::hypotf(vx, vy) > 0.1 {
                        libm::atan2f(vy, vx)
                    } else {
                        travel
                    };
                    let misalignment = wrap_angle(moving - state.attitude_rad[2]);
                    let excess = (libm::fabsf(misalignment) - SCAN_AMPLITUDE_RAD).max(0.0);
                    speed *= libm::cosf(excess).max(0.0);
                }
                if d > 1e-3 {
                    (speed * dx / d, speed * dy / d)
                } else {
                    (0.0, 0.0)
                }
            }
            None => (0.0, 0.0),
        };
        let cmd = self
            .avoidance
            .step(&self.fenced_ranges(state), state.attitude_rad[2], dvx, dvy, dt_s);
        // The avoidance smooths its command over 0.2 s, and at its least speed still moves towards a return:
        // a post the map missed, read 17 cm ahead, is met 0.2 s later. The live beams
        // bound the command itself, as on a search line.
        let ((vx, vy), _) = self.live_beam_guard_at(state, (cmd.vx, cmd.vy), NAVIGATION_LIVE_BEAM_STOP_M);
        Setpoint::Velocity {
            vx_m_s: vx,
            vy_m_s: vy,
            z_m: self.params.height_m,
            yaw_rad: self.heading,
        }
    }

    /// How fast to pass the waypoint `target` (reached from `here`), m/s: the cruise speed if the path goes on
    /// straight, down to [`CORNER_MIN_SPEED_M_S`] for a turn of 90° or more. A path turns where it rounds an
    /// obstacle (usually a wall end the four beams saw late), so a fast corner overshoots towards it.
    pub(super) fn corner_speed(&self, cruise: f32, here: (f32, f32), target: (f32, f32)) -> f32 {
        let Some(next) = self.waypoints.get(2).map(|c| self.shape.center_of(*c)) else {
            return cruise;
        };
        let a = (target.0 - here.0, target.1 - here.1);
        let b = (next.0 - target.0, next.1 - target.1);
        let (la, lb) = (libm::hypotf(a.0, a.1), libm::hypotf(b.0, b.1));
        if !(la > 1e-3 && lb > 1e-3) {
            return cruise;
        }
        let cos_turn = ((a.0 * b.0 + a.1 * b.1) / (la * lb)).clamp(0.0, 1.0);
        CORNER_MIN_SPEED_M_S + (cruise - CORNER_MIN_SPEED_M_S).max(0.0) * cos_turn
    }

    /// How far the drone can fly along its path (from `here` to `target`, then the later waypoints) before
    /// the path passes within [`UNOBSERVED_CLEARANCE_M`] of a region no beam has looked into, m (at most
    /// [`UNOBSERVED_LOOKAHEAD_M`]). The planner treats unknown space as free, so a path may graze a box the
    /// four beams have not seen yet; the drone slows there until the sweep has looked.
    /// Also returns, for a beam to look at, the centre of the unobserved cell nearest the first path sample
    /// that has one (the nearest is what the drone would graze; a raster-order pick was often a cell on the
    /// far side of the path).
    pub(super) fn observed_ahead_m(&self, here: (f32, f32), target: (f32, f32)) -> (f32, Option<(f32, f32)>) {
        self.observed_along(here, target, true)
    }

    /// [`Self::observed_ahead_m`] along the straight line `here → target` only (`follow_path` false: a
    /// search line), or on along the planned path's later waypoints (`follow_path` true).
    /// Along a path, a cell next to a contested one (a hit and a miss) needs two net misses to count as seen
    /// ([`CONTESTED_SEEN_FREE_LOG_ODDS`]): grazing beams leave a wall's end as single misses around a hit,
    /// and a drone rounding it at 0.3–0.45 m/s on the plain test touches it. A search line keeps the plain
    /// test (not measured there).
    pub(super) fn observed_along(
        &self,
        here: (f32, f32),
        target: (f32, f32),
        follow_path: bool,
    ) -> (f32, Option<(f32, f32)>) {
        const STEP_M: f32 = CELL_SIZE_M;
        let reach = libm::ceilf(UNOBSERVED_CLEARANCE_M / CELL_SIZE_M) as i32;
        // Only what lies ahead matters: regions beside and behind the drone were passed already.
        let (ux, uy) = {
            let (dx, dy) = (target.0 - here.0, target.1 - here.1);
            let d = libm::hypotf(dx, dy);
            if d > 1e-3 { (dx / d, dy / d) } else { (0.0, 0.0) }
        };
        let ahead = |x: i32, y: i32| {
            let (cx, cy) = self.shape.center_of(Cell::new(x as u16, y as u16));
            (cx - here.0) * ux + (cy - here.1) * uy >= 0.0
        };
        let suspicious = |p: (f32, f32)| -> Option<(f32, f32)> {
            let cx = libm::floorf(p.0 / CELL_SIZE_M) as i32;
            let cy = libm::floorf(p.1 / CELL_SIZE_M) as i32;
            // (squared distance from `p` to the cell's centre, the cell's centre)
            let mut nearest: Option<(f32, (f32, f32))> = None;
            for y in cy.saturating_sub(reach)..=cy.saturating_add(reach) {
                for x in cx.saturating_sub(reach)..=cx.saturating_add(reach) {
                    if !self.shape.contains(x, y) {
                        continue;
                    }
                    let (x0, y0) = (x as f32 * CELL_SIZE_M, y as f32 * CELL_SIZE_M);
                    let dx = (x0 - p.0).max(p.0 - (x0 + CELL_SIZE_M)).max(0.0);
                    let dy = (y0 - p.1).max(p.1 - (y0 + CELL_SIZE_M)).max(0.0);
                    if dx * dx + dy * dy > UNOBSERVED_CLEARANCE_M * UNOBSERVED_CLEARANCE_M {
                        continue;
                    }
                    let centre = self.shape.center_of(Cell::new(x as u16, y as u16));
                    let d2 = (centre.0 - p.0) * (centre.0 - p.0) + (centre.1 - p.1) * (centre.1 - p.1);
                    // The region test reads nine cells: only for a cell that would be nearer.
                    if nearest.is_some_and(|(best, _)| best <= d2) {
                        continue;
                    }
                    // The swept corridor's own test: see [`CORRIDOR_M`].
                    let in_corridor = dx * dx + dy * dy <= CORRIDOR_M * CORRIDOR_M;
                    if ahead(x, y)
                        && ((in_corridor
                            && self.grid.is_weakly_observed_region(
                                Cell::new(x as u16, y as u16),
                                CORRIDOR_MIN_NEIGHBOURS,
                                SEEN_FREE_LOG_ODDS,
                            ))
                            || if follow_path {
                                self.grid.is_doubtful_region(
                                    Cell::new(x as u16, y as u16),
                                    UNOBSERVED_MIN_NEIGHBOURS,
                                    SEEN_FREE_LOG_ODDS,
                                    CONTESTED_SEEN_FREE_LOG_ODDS,
                                )
                            } else {
                                self.grid.is_weakly_observed_region(
                                    Cell::new(x as u16, y as u16),
                                    UNOBSERVED_MIN_NEIGHBOURS,
                                    SEEN_FREE_LOG_ODDS,
                                )
                            })
                    {
                        nearest = Some((d2, centre));
                    }
                }
            }
            nearest.map(|(_, centre)| centre)
        };
        let later = if follow_path {
            self.waypoints.get(2..).unwrap_or(&[])
        } else {
            &[]
        };
        let corners = core::iter::once(target).chain(later.iter().map(|c| self.shape.center_of(*c)));
        let mut from = here;
        let mut travelled = 0.0f32;
        // Distance along the current segment of the next sample.
        let mut offset = 0.0f32;
        for to in corners {
            let length = libm::hypotf(to.0 - from.0, to.1 - from.1);
            if !length.is_finite() {
                break;
            }
            while offset <= length {
                let s = travelled + offset;
                if s > UNOBSERVED_LOOKAHEAD_M {
                    return (UNOBSERVED_LOOKAHEAD_M, None);
                }
                let t = if length > 1e-6 { offset / length } else { 0.0 };
                if let Some(cell) = suspicious((from.0 + t * (to.0 - from.0), from.1 + t * (to.1 - from.1))) {
                    return (s, Some(cell));
                }
                offset += STEP_M;
            }
            offset -= length;
            travelled += length;
            from = to;
        }
        (UNOBSERVED_LOOKAHEAD_M, None)
    }

    /// The heading nearest `heading` that points one of the four beams from `here` at `point`, rad (the
    /// search holds no heading of its own, so the least turn wins).
    pub(super) fn look_with_nearest_beam(heading: f32, here: (f32, f32), point: (f32, f32)) -> f32 {
        let bearing = libm::atan2f(point.1 - here.1, point.0 - here.0);
        let offset = [
            0.0,
            core::f32::consts::FRAC_PI_2,
            -core::f32::consts::FRAC_PI_2,
            core::f32::consts::PI,
        ]
        .into_iter()
        .map(|beam| wrap_angle(bearing - beam - heading))
        .fold(core::f32::consts::PI, |best, o| {
            if libm::fabsf(o) < libm::fabsf(best) { o } else { best }
        });
        wrap_angle(heading + offset)
    }

    /// The heading within [`LOOK_MAX_OFFSET_RAD`] of `travel` that points the front, left or right beam from
    /// `here` at `point`, rad. The beam is the one whose heading lies nearest `previous` (the heading
    /// commanded last) among those whose turn away from `travel` is within [`LOOK_CHOICE_HYSTERESIS_RAD`] of
    /// the least turn, so a beam keeps the region until it has looked.
    pub(super) fn look_at_heading(travel: f32, previous: f32, here: (f32, f32), point: (f32, f32)) -> f32 {
        let bearing = libm::atan2f(point.1 - here.1, point.0 - here.0);
        let offsets = [0.0, core::f32::consts::FRAC_PI_2, -core::f32::consts::FRAC_PI_2]
            .map(|beam| wrap_angle(bearing - beam - travel));
        let least = offsets
            .iter()
            .fold(core::f32::consts::PI, |best, o| best.min(libm::fabsf(*o)));
        let mut chosen: Option<(f32, f32)> = None; // (distance from `previous`, heading)
        for offset in offsets {
            if libm::fabsf(offset) > least + LOOK_CHOICE_HYSTERESIS_RAD {
                continue;
            }
            let heading = wrap_angle(travel + offset.clamp(-LOOK_MAX_OFFSET_RAD, LOOK_MAX_OFFSET_RAD));
            let from_previous = libm::fabsf(wrap_angle(heading - previous));
            if chosen.is_none_or(|(best, _)| from_previous < best) {
                chosen = Some((from_previous, heading));
            }
        }
        chosen.map_or(travel, |(_, heading)| heading)
    }
}
