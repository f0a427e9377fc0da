//! Frontier exploration (`mission.mode = 2`, CFPilot's `sensor` mission): map the arena with the same
//! occupancy grid, D\* Lite planning and reactive avoidance as the round trip, then fly home, find the home
//! pad with the round trip's search and land on it.
//!
//! Job: choose where to fly next. After the climb, and at every frontier reached, the drone holds and turns
//! a quarter turn (the four beams then have looked all round), then scans the grid for the **nearest
//! frontier**: a cell that is known free (beams crossed it), not blocked by the inflated margin, not within
//! [`EXCLUDE_RADIUS_CELLS`] of a frontier already visited or given up, and next (4-neighbourhood) to an
//! *unobserved region* (an unknown cell among unknown, occupied or wall neighbours,
//! [`OccupancyGrid::is_unobserved_region`](crate::nav::grid::OccupancyGrid::is_unobserved_region), the
//! navigation's own notion: the one-cell gaps four beams leave between their traces in open space are not
//! frontiers). "Nearest" is the straight-line distance; reachability is the planner's: the frontier becomes
//! the leg's goal, and if D\* Lite reports no path (or the drone has not got there within
//! [`FRONTIER_TIMEOUT_S`]) the frontier is dropped and the next nearest one chosen. A frontier that stops
//! being one on the way (its region was seen, or it became blocked) triggers a new scan without the turn.
//! The exploration ends, and the drone flies home ([`super::MissionState::NavigateHome`], then the home
//! pad's search and landing), when the known fraction of the arena's cells reaches `mission.coverage`
//! ([`ExploreEnd::Coverage`]) or no frontier is left ([`ExploreEnd::NoFrontier`]), or the battery asks
//! ([`ExploreEnd::Battery`]).
//!
//! No frontier left at the full inflation margin is not the end yet: as the round trip's no-path rule does,
//! the exploration switches to the narrow margin (`plan.narrowInfl`, flown at `plan.narrowSpeed`), forgets
//! the frontiers it gave up (it keeps those it reached) and scans again; only no frontier at the narrow
//! margin ends it. A gap the full margin closes is explored through.
//!
//! Battery reserve: the drone measures its discharge rate in flight ([`super::reserve`]) and, after each
//! scan, plans the way home with the same D\* Lite (its length is the reserve's distance; between two looks
//! the distance flown since is added: a route back that exists). Whenever the battery, at that rate, no
//! longer lasts `mission.batReserve` times the flight home (home path at cruise speed plus the home pad's
//! search and landing, [`super::reserve::needed_s`]) down to the supervisor's battery-low threshold, the
//! exploration ends and the drone flies home ([`MissionNote::BatteryReserve`] says why on the console).
//! The other safety rules are the round trip's: battery low lands where the drone is (the supervisor's
//! latch: the last resort), the estimator and supervisor checks, the abort; the way home has the round
//! trip's no-path handling.
//!
//! Non-goals: no information-gain or path-length ranking of frontiers (straight-line nearest, as
//! `docs/mission.md` specifies), no revisiting of dropped frontiers, no 3-D exploration.
//!
//! Units: arena frame, metres, seconds; cells of [`CELL_SIZE_M`].
//!
//! Memory: [`Explorer`] is about 500 B (a list of [`DROPPED_CAPACITY`] cells, the scan's cursor, the
//! discharge watch's 16 samples); no queue, no second grid. Cost: the scan runs in slices of [`SCAN_ROWS_PER_TICK`] grid rows per 50 Hz tick
//! (4 ticks for the 128 × 64 grid). Per cell: one byte read (unknown? for the coverage count), and for a
//! known-free, unblocked cell up to four [`is_unobserved_region`] tests (one byte each unless the
//! neighbour is unknown, then nine); the dropped list is searched only for a candidate nearer than the best
//! so far. Worst case per slice 16 × 128 × (1 + 4 × 9) ≈ 76 k byte reads, typically ≈ 10 k (most cells
//! fail the first test); not yet counted under QEMU (tools/qemu-bench has no figure for it).
//!
//! [`is_unobserved_region`]: crate::nav::grid::OccupancyGrid::is_unobserved_region

use heapless::Vec;

use super::reserve::{self, DischargeWatch};
use super::{Leg, Mission, MissionInputs, Phase};
use crate::math::wrap_angle;
use crate::nav::map::{CELL_SIZE_M, Cell};
use crate::types::{Micros, Setpoint, StateEstimate};

/// Grid rows scanned per mission tick.
pub const SCAN_ROWS_PER_TICK: u16 = 16;
/// Frontiers visited or given up that are remembered (and excluded); when full the exploration ends.
pub const DROPPED_CAPACITY: usize = 48;
/// A frontier within this many cells (Chebyshev) of a visited or dropped one is not chosen: 0.3 m.
pub const EXCLUDE_RADIUS_CELLS: i32 = 6;
/// A frontier closer than this to the drone counts as reached, m.
pub const FRONTIER_REACHED_M: f32 = 0.15;
/// A frontier not reached within this time is dropped, s.
pub const FRONTIER_TIMEOUT_S: f32 = 30.0;
/// Yaw rate of the look-around turn at a frontier, rad/s (a quarter turn in ≈ 2 s, as the no-path hover).
const LOOK_TURN_RATE_RAD_S: f32 = 0.8;
/// An unknown cell belongs to an unobserved region with at least this many unknown, occupied or wall
/// neighbours (the navigation's threshold).
const UNOBSERVED_MIN_NEIGHBOURS: u8 = 5;
/// Ticks the home plan after a scan may take (4000 expansions each; a 128 × 64 grid needs at most 3).
const HOME_PLAN_MAX_TICKS: u8 = 10;

/// Why the exploration ended (the drone then flew home).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExploreEnd {
    /// The known fraction of the arena reached `mission.coverage`.
    Coverage,
    /// No reachable frontier was left, at the narrow margin too (or the list of dropped ones was full).
    NoFrontier,
    /// The battery no longer covered `mission.batReserve` times the flight home.
    Battery,
}

/// A mission decision for the console (see [`super::Mission::take_note`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MissionNote {
    /// Explore turned home for its battery reserve.
    BatteryReserve {
        /// Filtered battery voltage at the decision, V.
        battery_v: f32,
        /// Measured discharge, mV/s.
        rate_mv_s: f32,
        /// Until the battery-low threshold at that rate, s.
        remaining_s: f32,
        /// The home path (planned, plus the distance flown since), m.
        home_m: f32,
        /// What the flight home needs with the reserve factor, s.
        needed_s: f32,
    },
}

impl core::fmt::Display for MissionNote {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::BatteryReserve {
                battery_v,
                rate_mv_s,
                remaining_s,
                home_m,
                needed_s,
            } => write!(
                f,
                "explore: battery reserve, flying home: {battery_v:.2} V, -{rate_mv_s:.1} mV/s, {remaining_s:.0} s \
                 left < {needed_s:.0} s needed for {home_m:.1} m home"
            ),
        }
    }
}

/// The scan's cursor and its running results.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Scan {
    row: u16,
    known: u32,
    /// The drone's cell when the scan began.
    from: Cell,
    /// Nearest candidate so far: squared distance in cells, the cell.
    best: Option<(i32, Cell)>,
}

/// The exploration's state (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Explorer {
    target: Option<Cell>,
    target_since: Micros,
    /// Frontiers reached (`true`) or given up (`false`).
    dropped: Vec<(Cell, bool), DROPPED_CAPACITY>,
    scan: Scan,
    /// The scan of this look is done (the home plan and the choice follow).
    scan_done: bool,
    /// Ticks spent on this look's home plan; `None` once it is done.
    home_plan_ticks: Option<u8>,
    /// The planned home path's length at the latest look, m.
    home_path_m: Option<f32>,
    /// Distance flown since that plan, m.
    odometer_m: f32,
    last_xy: Option<(f32, f32)>,
    /// The narrow margin is in use (no frontier was left at the full one).
    narrow: bool,
    discharge: DischargeWatch,
    pub(super) note: Option<MissionNote>,
}

impl Explorer {
    pub(super) const fn new() -> Self {
        Self {
            target: None,
            target_since: 0,
            dropped: Vec::new(),
            scan: Scan {
                row: 0,
                known: 0,
                from: Cell::new(0, 0),
                best: None,
            },
            scan_done: false,
            home_plan_ticks: None,
            home_path_m: None,
            odometer_m: 0.0,
            last_xy: None,
            narrow: false,
            discharge: DischargeWatch::new(),
            note: None,
        }
    }
}

impl<const CELLS: usize, const QUEUE: usize> Mission<CELLS, QUEUE> {
    /// The frontier being flown to (its cell's centre); the drone's home while none is chosen.
    pub(super) fn explore_target(&self) -> (f32, f32) {
        self.explorer
            .target
            .map_or(self.params.start_m, |c| self.shape.center_of(c))
    }

    /// At the cruise height (after the climb, or at a frontier): hold and turn a quarter turn, then scan.
    pub(super) fn begin_explore_look(&mut self, now: Micros, state: &StateEstimate) -> Setpoint {
        self.enter_look(now, state, false)
    }

    fn enter_look(&mut self, now: Micros, state: &StateEstimate, scanning: bool) -> Setpoint {
        let (x, y) = (state.position_m[0], state.position_m[1]);
        self.explorer.target = None;
        if scanning {
            self.begin_scan(state);
        }
        self.phase = Phase::ExploreLook {
            x,
            y,
            since: now,
            heading_start: self.heading,
            scanning,
        };
        self.hold_at(x, y)
    }

    fn begin_scan(&mut self, state: &StateEstimate) {
        self.explorer.scan = Scan {
            row: 0,
            known: 0,
            from: self.cell_of((state.position_m[0], state.position_m[1])),
            best: None,
        };
        self.explorer.scan_done = false;
        self.explorer.home_plan_ticks = Some(0);
    }

    /// Holding at `(x, y)`: the quarter turn, then the scan's slices, then the choice.
    pub(super) fn explore_look(
        &mut self,
        now: Micros,
        state: &StateEstimate,
        (x, y): (f32, f32),
        since: Micros,
        heading_start: f32,
        scanning: bool,
    ) -> Setpoint {
        if !scanning {
            let turned = LOOK_TURN_RATE_RAD_S * now.saturating_sub(since) as f32 * 1e-6;
            if turned < core::f32::consts::FRAC_PI_2 {
                self.heading = wrap_angle(heading_start + turned);
            } else {
                self.heading = wrap_angle(heading_start + core::f32::consts::FRAC_PI_2);
                self.begin_scan(state);
                self.phase = Phase::ExploreLook {
                    x,
                    y,
                    since,
                    heading_start,
                    scanning: true,
                };
            }
            return self.hold_at(x, y);
        }
        if !self.explorer.scan_done {
            if !self.scan_slice() {
                return self.hold_at(x, y);
            }
            self.explorer.scan_done = true;
            let cells = self.shape.cells().max(1);
            self.stats.coverage = self.explorer.scan.known as f32 / cells as f32;
            if self.stats.coverage >= self.params.coverage_target {
                return self.end_exploration(now, state, super::ExploreEnd::Coverage);
            }
        }
        // The way home from here, for the battery reserve: planned by the same D* Lite (no frontier is the
        // target while looking, so the leg's target is home), a budgeted slice per tick.
        if let Some(ticks) = self.explorer.home_plan_ticks {
            match self.plan(state) {
                Ok(Some(_)) => {
                    let length = self.path_length_m();
                    self.explorer.home_path_m = Some(length);
                    self.explorer.odometer_m = 0.0;
                    self.explorer.home_plan_ticks = None;
                }
                Err(()) if ticks < HOME_PLAN_MAX_TICKS => {
                    self.explorer.home_plan_ticks = Some(ticks + 1);
                    return self.hold_at(x, y);
                }
                // No way home at this margin, or the plan did not finish: keep the last figure (plus the
                // distance flown since), or the straight line.
                Ok(None) | Err(()) => self.explorer.home_plan_ticks = None,
            }
        }
        match self.explorer.scan.best {
            None if !self.explorer.narrow && self.narrow_inflation_cells() < self.full_inflation_cells() => {
                // No frontier at the full margin: try the narrow one (as the round trip's no-path rule), with
                // the frontiers given up so far back in play; scan again.
                self.explorer.narrow = true;
                self.explorer.dropped.retain(|(_, reached)| *reached);
                let narrow = self.narrow_inflation_cells();
                self.grid.set_inflation_radius(narrow, &mut self.changed);
                self.enter_look(now, state, true)
            }
            None => self.end_exploration(now, state, super::ExploreEnd::NoFrontier),
            Some((_, cell)) => {
                self.explorer.target = Some(cell);
                self.explorer.target_since = now;
                self.avoidance.reset();
                self.phase = Phase::Navigate;
                self.hold_at(x, y)
            }
        }
    }

    /// One slice of the scan; `true` once the whole grid is done.
    fn scan_slice(&mut self) -> bool {
        let (w, h) = (self.shape.width, self.shape.height);
        let end = self.explorer.scan.row.saturating_add(SCAN_ROWS_PER_TICK).min(h);
        let from = self.explorer.scan.from;
        let reached_cells = FRONTIER_REACHED_M / CELL_SIZE_M;
        let reached_sq = (reached_cells * reached_cells) as i32;
        for y in self.explorer.scan.row..end {
            for x in 0..w {
                let c = Cell::new(x, y);
                if self.grid.is_unknown(c) {
                    continue;
                }
                self.explorer.scan.known += 1;
                let dx = i32::from(x) - i32::from(from.x);
                let dy = i32::from(y) - i32::from(from.y);
                let d2 = dx * dx + dy * dy;
                if d2 <= reached_sq || self.explorer.scan.best.is_some_and(|(b, _)| d2 >= b) {
                    continue;
                }
                if self.is_frontier(c) && !self.is_excluded(c) {
                    self.explorer.scan.best = Some((d2, c));
                }
            }
        }
        self.explorer.scan.row = end;
        end >= h
    }

    /// Known free, not blocked, next to an unobserved region (4-neighbourhood).
    fn is_frontier(&self, c: Cell) -> bool {
        if self.grid.is_blocked(c) || self.grid.is_occupied(c) || self.grid.is_unknown(c) {
            return false;
        }
        let (x, y) = (i32::from(c.x), i32::from(c.y));
        [(1, 0), (-1, 0), (0, 1), (0, -1)].into_iter().any(|(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            self.shape.contains(nx, ny)
                && self
                    .grid
                    .is_unobserved_region(Cell::new(nx as u16, ny as u16), UNOBSERVED_MIN_NEIGHBOURS)
        })
    }

    fn is_excluded(&self, c: Cell) -> bool {
        self.explorer
            .dropped
            .iter()
            .any(|(d, _)| i32::from(d.chebyshev(c)) <= EXCLUDE_RADIUS_CELLS)
    }

    /// The planner's latest path, m (cell centres; diagonal steps count √2 cells).
    fn path_length_m(&self) -> f32 {
        self.path
            .windows(2)
            .map(|w| {
                let dx = f32::from(w[0].x.abs_diff(w[1].x));
                let dy = f32::from(w[0].y.abs_diff(w[1].y));
                libm::hypotf(dx, dy) * CELL_SIZE_M
            })
            .sum()
    }

    /// Every tick of the exploration: the discharge watch's sample, the distance flown, and the reserve's
    /// verdict (flying to a frontier or looking: turn home when the battery no longer covers the way).
    pub(super) fn explore_battery(&mut self, now: Micros, state: &StateEstimate, inputs: &MissionInputs) {
        let (x, y) = (state.position_m[0], state.position_m[1]);
        // The drone's own climb and the sag of take-off are not the discharge: sample from the first look.
        let cruising = matches!(self.phase, Phase::Navigate | Phase::ExploreLook { .. });
        if !cruising || !state.valid {
            return;
        }
        self.explorer.discharge.on_sample(now, inputs.battery_v);
        if let Some((lx, ly)) = self.explorer.last_xy {
            let step = libm::hypotf(x - lx, y - ly);
            if step.is_finite() {
                self.explorer.odometer_m += step;
            }
        }
        self.explorer.last_xy = Some((x, y));
        let Some(rate) = self.explorer.discharge.rate_v_per_s() else {
            return;
        };
        if !(inputs.battery_v > 0.0 && inputs.battery_low_v > 0.0) {
            return;
        }
        let (hx, hy) = self.params.start_m;
        let home_m = self
            .explorer
            .home_path_m
            .map_or(libm::hypotf(hx - x, hy - y), |m| m + self.explorer.odometer_m);
        let remaining_s = reserve::remaining_s(inputs.battery_v, inputs.battery_low_v, rate);
        let needed_s = reserve::needed_s(home_m, self.params.speed_m_s, self.config.battery_reserve);
        if remaining_s < needed_s {
            self.explorer.note = Some(MissionNote::BatteryReserve {
                battery_v: inputs.battery_v,
                rate_mv_s: rate * 1e3,
                remaining_s,
                home_m,
                needed_s,
            });
            self.end_exploration(now, state, super::ExploreEnd::Battery);
        }
    }

    /// While flying to a frontier: reached (look around there), stale (scan again at once) or late (drop
    /// it); `None` to fly on.
    pub(super) fn explore_progress(&mut self, now: Micros, state: &StateEstimate) -> Option<Setpoint> {
        let Some(target) = self.explorer.target else {
            return Some(self.enter_look(now, state, true));
        };
        let (tx, ty) = self.shape.center_of(target);
        let d = libm::hypotf(tx - state.position_m[0], ty - state.position_m[1]);
        if d < FRONTIER_REACHED_M {
            self.stats.frontiers_reached += 1;
            if self.explorer.dropped.push((target, true)).is_err() {
                return Some(self.end_exploration(now, state, super::ExploreEnd::NoFrontier));
            }
            return Some(self.enter_look(now, state, false));
        }
        if !self.is_frontier(target) {
            return Some(self.enter_look(now, state, true));
        }
        if now.saturating_sub(self.explorer.target_since) as f32 * 1e-6 > FRONTIER_TIMEOUT_S {
            return Some(self.drop_frontier(now, state));
        }
        None
    }

    /// The planner found no path to the frontier (or it took too long): remember it, choose another.
    pub(super) fn drop_frontier(&mut self, now: Micros, state: &StateEstimate) -> Setpoint {
        self.stats.frontiers_dropped += 1;
        if !self.explorer.narrow {
            self.restore_full_inflation();
        }
        if let Some(t) = self.explorer.target
            && self.explorer.dropped.push((t, false)).is_err()
        {
            return self.end_exploration(now, state, super::ExploreEnd::NoFrontier);
        }
        self.enter_look(now, state, true)
    }

    fn end_exploration(&mut self, now: Micros, state: &StateEstimate, why: super::ExploreEnd) -> Setpoint {
        self.stats.explore_end = Some(why);
        self.explorer.target = None;
        self.begin_leg(now, state, Leg::Return)
    }
}
