//! The round-trip mission: take off from the home pad, map and plan to the goal, find the goal pad, land on
//! it, take off again, fly home, find the home pad, land, stop.
//!
//! Job: a sans-IO state machine. Each [`Mission::tick`] (20–50 Hz) takes the state estimate and a few
//! supervisor flags and returns the [`Setpoint`] the controller should fly, plus a [`MissionState`] code for
//! the `mission.state` log variable. Range data arrive through [`Mission::on_ranges`] (Multi-ranger, 10 Hz:
//! mapping and avoidance) and [`Mission::on_zrange`] (downward ranger, 40 Hz: the pad detector).
//!
//! Non-goals: estimation, control and motor safety (the supervisor cuts motors on touchdown, tumble and
//! timeouts; the mission only reacts to what it reports).
//!
//! Units and frames: arena frame, metres, seconds, radians. While navigating the drone turns to face its
//! direction of travel, so the front ranger sees what it flies into (four beams are blind diagonally);
//! elsewhere it keeps the last heading.
//!
//! How each phase works:
//! - **Navigate**: the four horizontal ranges update the [`OccupancyGrid`] (freed along each beam, the end
//!   cell marked); the cells whose inflated state changed go to D\* Lite, which repairs its plan with an
//!   expansion budget per tick; the path is shortened by line of sight, and the drone flies towards its
//!   first waypoint at cruise speed (slowing into the goal, and into a waypoint where the path turns
//!   sharply), through [`ReactiveAvoidance`] (repulsion, smoothing, and a speed clamp on the approach
//!   towards each ranger's obstacle: flying along a wall is not slowed, flying into one is). The planner
//!   treats unknown space as free, so a path may graze a box no beam has seen: where the path ahead passes
//!   within 0.15 m of an *unobserved region* (an unknown cell among unknown or occupied neighbours, see
//!   [`OccupancyGrid::is_unobserved_region`]), the drone slows (0.2 m/s there, 1 m/s more per metre of
//!   observed path before it) and, instead of sweeping its heading, turns the front, left or right beam
//!   (whichever needs the least turn) towards the first such cell until a beam has looked into it. The
//!   heading slows the drone only when it lags the actual velocity by more than the sweep's amplitude.
//!   A nominal goal inside the inflated margin of something mapped is replaced by the nearest free cell
//!   within 0.3 m (the search starts there).
//! - **No path**: once per leg, plan again with [`MissionConfig::narrow_inflation_radius_m`] and fly at
//!   [`MissionConfig::narrow_speed_m_s`]; if that fails too, hover and keep mapping (false obstacles clear,
//!   the plan repairs itself) for [`MissionConfig::no_path_wait_s`]; then land where it is and end with
//!   [`MissionState::NoPath`].
//! - **Search** (the detector already listens on the last 0.8 m of navigation; every search line stops
//!   0.18 m short of mapped obstacles and the arena walls; navigation hands over 0.35 m before the nominal
//!   goal): a coarse lawnmower pass around the nominal goal, its first lines along the arrival direction
//!   (a drone already on that line flies on along it instead of turning back to its start), until the
//!   [`PadDetector`] has a first crossing; then short refinement stages centred on the latest estimate —
//!   lines across the first crossing (which fix the other coordinate), then lines along it, four rounds
//!   in all with a fresh detector every round (the estimate drifts) — until the detector locks (three
//!   inlier crossings covering both directions: usually the first crossing and two lines across it). A
//!   line ends as soon as it gave a crossing (its rest only costs time), and in the first round a stage
//!   ends once its direction has two inlier crossings; later rounds fly all three lines of a stage.
//!   If the pattern ends without a
//!   lock the drone lands on the best estimate (or the nominal point) and the mission ends with
//!   [`MissionState::PadNotFound`] after flying the rest of the round trip.
//! - **Take-off**: climb at [`MissionConfig::climb_speed_m_s`]; navigation takes over 0.1 m above the
//!   minimum height, and the rest of the climb overlaps the first metres of travel.
//! - **Land**: fly back over the pad centre (a velocity profile down to 6 cm from it, then position hold),
//!   until within [`MissionConfig::settle_tolerance_m`] and slow, descend at
//!   [`MissionConfig::high_descent_speed_m_s`] down to 0.2 m above the surface and slower below it (the
//!   flow-only position drifts ≈ 1 cm/√s, so the time from the last crossing to touchdown is landing
//!   error); the supervisor detects the touchdown and stops the motors, which the mission sees as `landed`.
//!
//! Memory: the grid (`CELLS + 12` B), the planner (`4·CELLS + 10·QUEUE` B), a path buffer and the small
//! detectors: about 50 KB for the 6 × 3 m arena. Cost per tick: one bounded planner slice
//! ([`MissionConfig::planner_budget`] expansions) plus a path read-off (O(path length)).

use heapless::Vec;

use crate::avoidance::{AvoidanceConfig, RangerReadings, ReactiveAvoidance, SpeedClamp};
use crate::dstar::{DStarLite, PlanError, PlanStatus};
use crate::grid::{ChangedCells, OccupancyGrid};
use crate::map::{CELL_SIZE_M, Cell, GridShape, Traversability};
use crate::pad::{PadConfig, PadDetector};
use crate::path::{extract_path, simplify};
use crate::sweep::{ArenaBounds, LawnmowerSweep, SweepAxis, SweepConfig};
use crate::types::{Micros, MultiRangerSample, RangeReading, Setpoint, StateEstimate, body_to_arena, wrap_angle};

/// The `mission.state` codes (interfaces.md §5): 0 idle, 1..99 phases, 100 completed, ≥ 200 ended without
/// completing (the value says why).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum MissionState {
    /// Idle and ready for `mission.start`.
    Idle = 0,
    /// Started; waiting for a valid state estimate before the motors spin.
    Preflight = 1,
    /// Climbing off the home pad.
    TakeOffOutbound = 10,
    /// Mapping and planning towards the goal.
    NavigateToGoal = 11,
    /// Sweeping around the nominal goal for the goal pad.
    SearchGoalPad = 12,
    /// Moving over the goal pad's centre.
    ApproachGoalPad = 13,
    /// Descending onto the goal pad.
    LandOnGoalPad = 14,
    /// Landed on the goal pad, motors off, pausing.
    OnGoalPad = 15,
    /// Climbing off the goal pad.
    TakeOffReturn = 20,
    /// Mapping and planning back to the start.
    NavigateHome = 21,
    /// Sweeping around the start for the home pad.
    SearchHomePad = 22,
    /// Moving over the home pad's centre.
    ApproachHomePad = 23,
    /// Descending onto the home pad.
    LandOnHomePad = 24,
    /// No path: hovering while the map may still change.
    NoPathHover = 30,
    /// Landing where it is, because the mission cannot go on (the final code follows on touchdown).
    EmergencyLanding = 40,
    /// Landed on both pads, motors off.
    Completed = 100,
    /// Aborted by the user (`mission.start = 0`): landed where it was.
    Aborted = 200,
    /// No path to the goal (or home): landed where it was.
    NoPath = 201,
    /// A pad was not found: landed on the best estimate or the nominal point, round trip finished.
    PadNotFound = 202,
    /// Battery low: landed where it was.
    BatteryLow = 203,
    /// The state estimate became unusable (flow or height lost): landed or motors cut.
    EstimatorFault = 204,
    /// The supervisor cut the motors (tumble or timeout).
    Crashed = 205,
    /// The planner could not run (grid or queue capacity).
    PlannerFault = 206,
}

impl MissionState {
    /// The `mission.state` value.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// Whether the mission has ended (completed or not).
    pub fn is_final(self) -> bool {
        self.code() >= 100
    }
}

/// A sub-config of [`MissionConfig`] is invalid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MissionConfigError {
    /// [`MissionConfig::avoidance`] failed its validation.
    Avoidance,
    /// [`MissionConfig::pad`] failed its validation.
    PadDetector,
}

/// Why a start request was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StartRefusal {
    /// A mission is already running.
    AlreadyRunning,
    /// The arena does not fit the grid capacity, or is not finite and positive.
    BadArena,
    /// The start or goal lies outside the arena (or too close to its walls).
    OutsideArena,
    /// Cruise height below 0.2 m or above the limit.
    BadHeight,
    /// Cruise speed not in (0, 1] m/s.
    BadSpeed,
}

/// The mission's parameters (the `mission.*` radio parameters and the arena).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MissionParams {
    /// Arena size, m (x, y): the grid the drone maps.
    pub arena_m: (f32, f32),
    /// Where the drone stands at power-on (the home pad), m.
    pub start_m: (f32, f32),
    /// The nominal goal, m.
    pub goal_m: (f32, f32),
    /// Cruise height above the arena floor, m (≥ 0.2).
    pub height_m: f32,
    /// Cruise speed, m/s.
    pub speed_m_s: f32,
}

/// Minimum height in flight phases (interfaces.md §5, the supervisor's floor too).
pub const MIN_HEIGHT_M: f32 = 0.2;
/// Highest cruise height accepted, m.
pub const MAX_HEIGHT_M: f32 = 2.0;
/// Highest cruise speed accepted, m/s.
pub const MAX_SPEED_M_S: f32 = 1.0;

impl MissionParams {
    /// The seed scenario's values.
    pub const SEED: Self = Self {
        arena_m: (6.0, 3.0),
        start_m: (0.6, 1.3),
        goal_m: (5.0, 1.5),
        height_m: 0.5,
        speed_m_s: 0.5,
    };

    /// Check the parameters against each other and a grid capacity.
    pub fn validate(&self, capacity_cells: usize) -> Result<GridShape, StartRefusal> {
        let shape =
            GridShape::for_arena(self.arena_m.0, self.arena_m.1, capacity_cells).ok_or(StartRefusal::BadArena)?;
        let inside = |p: (f32, f32)| {
            p.0.is_finite()
                && p.1.is_finite()
                && p.0 > 0.1
                && p.1 > 0.1
                && p.0 < self.arena_m.0 - 0.1
                && p.1 < self.arena_m.1 - 0.1
        };
        if !inside(self.start_m) || !inside(self.goal_m) {
            return Err(StartRefusal::OutsideArena);
        }
        if !(self.height_m >= MIN_HEIGHT_M && self.height_m <= MAX_HEIGHT_M) {
            return Err(StartRefusal::BadHeight);
        }
        if !(self.speed_m_s > 0.0 && self.speed_m_s <= MAX_SPEED_M_S) {
            return Err(StartRefusal::BadSpeed);
        }
        Ok(shape)
    }
}

/// Tuning of the mission (not radio parameters).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MissionConfig {
    /// Obstacles are inflated by the drone's radius (0.06 m) plus a margin, m.
    pub inflation_radius_m: f32,
    /// When no path exists at [`MissionConfig::inflation_radius_m`], the planner tries once more with this
    /// smaller margin (a gap the full margin closes may still be wide enough), and the drone flies the
    /// leg at [`MissionConfig::narrow_speed_m_s`]. Equal to the full radius: no fallback. m.
    pub narrow_inflation_radius_m: f32,
    /// Speed cap while the narrow margin is in use, m/s.
    pub narrow_speed_m_s: f32,
    /// Horizontal ranges beyond this map only free space, m (the VL53L1x gets noisy beyond ~3–4 m).
    pub max_mapping_range_m: f32,
    /// Cells around the drone that are its own body and cannot be an obstacle, m.
    pub body_clearance_m: f32,
    /// Planner expansions per tick (bounds the tick's cost on the MCU).
    pub planner_budget: u32,
    /// Hover this long with no path before giving up, s.
    pub no_path_wait_s: f32,
    /// Distance to the goal at which navigation hands over to the pad search, m.
    pub goal_tolerance_m: f32,
    /// Speed along sweep lines, m/s.
    pub search_speed_m_s: f32,
    /// Climb rate for take-off, m/s.
    pub climb_speed_m_s: f32,
    /// Descent rate for landing in the last 0.2 m above the surface, m/s (positive number; three times it
    /// in the last 4 cm, so the touchdown is detected without a hover in ground contact).
    pub descent_speed_m_s: f32,
    /// Descent rate for landing higher than 0.2 m above the surface, m/s (at least `descent_speed_m_s`).
    pub high_descent_speed_m_s: f32,
    /// Settle over the pad this long before descending, s (0: descend as soon as within the tolerance and
    /// slower than 5 cm/s; the descent's position hold finishes the centring above 0.2 m).
    pub settle_s: f32,
    /// Horizontal error to the pad centre accepted before descending, m.
    pub settle_tolerance_m: f32,
    /// Pause on the goal pad, motors off, s.
    pub pause_s: f32,
    /// The coarse search pattern.
    pub sweep: SweepConfig,
    /// Length of each refinement line, m.
    pub refine_line_m: f32,
    /// Offset between parallel refinement lines, m.
    pub refine_offset_m: f32,
    /// The pad detector.
    pub pad: PadConfig,
    /// Reactive avoidance.
    pub avoidance: AvoidanceConfig,
}

impl Default for MissionConfig {
    fn default() -> Self {
        Self {
            inflation_radius_m: 0.25,
            // Drone radius 0.06 m + 0.09 m for estimate and tracking errors at the slower speed.
            narrow_inflation_radius_m: 0.15,
            narrow_speed_m_s: 0.2,
            max_mapping_range_m: 3.0,
            body_clearance_m: 0.07,
            planner_budget: 4000,
            no_path_wait_s: 5.0,
            goal_tolerance_m: 0.35,
            search_speed_m_s: 0.5,
            climb_speed_m_s: 0.4,
            descent_speed_m_s: 0.2,
            high_descent_speed_m_s: 0.4,
            settle_s: 0.0,
            settle_tolerance_m: 0.05,
            pause_s: 2.0,
            sweep: SweepConfig {
                size_x_m: 1.0,
                size_y_m: 1.0,
                spacing_m: 0.2,
                crosshatch: true,
                ..SweepConfig::default()
            },
            refine_line_m: 0.5,
            refine_offset_m: 0.08,
            // Three inlier crossings (6 edges) covering both directions lock: the first crossing and the two
            // lines across it. Waiting for a second crossing along (8 edges) cost ~2 s per pad and landed no
            // more accurately: the flow-only estimate drifts ≈ 1 cm/√s, so the longer search loses what the
            // extra crossing gains (600 worlds: median 2.53 cm, p95 5.49 cm either way, BENCHMARKS.md §5).
            pad: PadConfig {
                min_edges: 6,
                min_crossings_per_direction: 1,
                fit_tolerance_m: 0.08,
                ..PadConfig::default()
            },
            // The planner keeps paths 0.2 m (inflation) from what it has mapped, so avoidance acts only
            // inside that, and slows the drone only close to an obstacle (the nearest range decides).
            avoidance: AvoidanceConfig {
                danger_distance_m: 0.2,
                slow_down_distance_m: 0.4,
                min_speed_mps: 0.2,
                clamp: SpeedClamp::TowardsEachRange,
                smoothing_tau_s: 0.1,
                ..AvoidanceConfig::default()
            },
        }
    }
}

/// What the mission needs to know each tick besides the estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MissionInputs {
    /// The supervisor detected a touchdown and stopped the motors.
    pub landed: bool,
    /// The supervisor cut the motors for safety (tumble, timeout): the flight is over.
    pub crashed: bool,
    /// The battery has been low long enough to land now.
    pub battery_low: bool,
    /// The supervisor allows the motors (armed or flying). It arms only while it sees a Stop setpoint
    /// (the thrust lock), so the mission keeps sending Stop until then.
    pub armed: bool,
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

/// Which way the round trip is going.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Leg {
    Outbound,
    Return,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Idle,
    Preflight,
    TakeOff {
        x: f32,
        y: f32,
        z_target: f32,
    },
    Navigate,
    NoPath {
        since: Micros,
        x: f32,
        y: f32,
    },
    Search(Search),
    Approach {
        x: f32,
        y: f32,
        settled_since: Option<Micros>,
    },
    Land {
        x: f32,
        y: f32,
    },
    OnPad {
        since: Micros,
    },
    EmergencyLand {
        x: f32,
        y: f32,
        then: MissionState,
    },
    Ended(MissionState),
}

/// Where the pad search is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Search {
    /// Flying the coarse lawnmower's lines centre-out: `step` counts line ends flown (two per line),
    /// `reverse` flies the current line from its second waypoint.
    Coarse { step: usize, reverse: bool },
    /// Refinement: stage 0 = lines across the first crossing, stage 1 = lines along it; `line` of 3,
    /// `end` = 0 going to the line's start, 1 to its end; `crossings_before` = the detector's crossings
    /// when the line began (a new one ends the line early).
    Refine {
        stage: u8,
        line: u8,
        end: u8,
        centre: (f32, f32),
        first_along_x: bool,
        crossings_before: u8,
    },
}

const PATH_CAPACITY: usize = 512;
const WAYPOINT_CAPACITY: usize = 48;
const CHANGED_CAPACITY: usize = 512;
const PAD_EDGES: usize = 48;
const REFINE_LINES: u8 = 3;
const REFINE_STAGES: u8 = 8;
/// Yaw rate while hovering with no path, rad/s (a quarter turn, all four beams' gaps, in 2 s).
const NO_PATH_TURN_RATE_RAD_S: f32 = 0.8;
/// Over the pad, within this of its centre the approach holds position; farther it flies a velocity
/// profile towards it, m.
const APPROACH_HOLD_RADIUS_M: f32 = 0.06;
/// Search lines stop this far from mapped obstacles and arena walls, m: the drone's radius (0.06 m), the
/// estimate's drift over a search (≈ 5 cm) and tracking overshoot at a line's end.
const SEARCH_CLEARANCE_M: f32 = 0.18;
/// Take-off hands over to navigation this far above [`MIN_HEIGHT_M`] (or 5 cm below the cruise height if that
/// is lower), m.
const TAKEOFF_HANDOVER_MARGIN_M: f32 = 0.1;
/// A drone this close to a coarse line, between its ends, flies on along it rather than back to its start, m.
const ON_LINE_TOLERANCE_M: f32 = 0.1;
/// Speed at a waypoint where the path turns by 90° or more, m/s.
const CORNER_MIN_SPEED_M_S: f32 = 0.15;
/// Speed allowed per metre of distance before a waypoint, on top of its corner speed, 1/s. (1.5 rounded a
/// wall end in the `slalom` world at 0.4 m/s with 20 cm of drift and grazed it; 1.2 did not, in 20 noise
/// seeds, and cost nothing measurable elsewhere: BENCHMARKS.md §5.)
const CORNER_APPROACH_GAIN: f32 = 1.2;
/// Descent rate of an emergency landing without a usable estimate, m/s.
const FAULT_DESCENT_SPEED_M_S: f32 = 0.5;
/// Within this distance of the leg's target the navigating drone already feeds the pad detector, m.
const PAD_LOOKOUT_RADIUS_M: f32 = 0.8;
/// How far [`Mission::clearance`] looks, m.
const CLEARANCE_HORIZON_M: f32 = 0.3;
/// Sampling step along a search line for the clearance check, m.
const CLEARANCE_STEP_M: f32 = 0.025;
/// Look this far along the path for regions no beam has looked into, m.
const UNOBSERVED_LOOKAHEAD_M: f32 = 0.6;
/// A path point counts as next to an unobserved region when such a cell lies within this distance, m: the
/// drone's radius (0.06 m) plus the estimate's drift and tracking error.
const UNOBSERVED_CLEARANCE_M: f32 = 0.15;
/// An unknown cell belongs to an unobserved region with at least this many unknown or occupied
/// neighbours (see [`OccupancyGrid::is_unobserved_region`]).
const UNOBSERVED_MIN_NEIGHBOURS: u8 = 5;
/// Speed next to an unobserved region, m/s: slow enough that the sweeping beams look into it before the
/// drone is there.
const UNOBSERVED_MIN_SPEED_M_S: f32 = 0.2;
/// Speed allowed per metre of observed path before an unobserved region, 1/s.
const UNOBSERVED_APPROACH_GAIN: f32 = 1.0;
/// Largest turn away from the direction of travel to look at an unobserved region, rad.
const LOOK_MAX_OFFSET_RAD: f32 = 0.8;
/// Heading sweep while navigating: amplitude, rad, and period, s.
const SCAN_AMPLITUDE_RAD: f32 = 0.6;
const SCAN_PERIOD_S: f32 = 2.0;

/// See the module documentation.
pub struct Mission<const CELLS: usize, const QUEUE: usize> {
    config: MissionConfig,
    params: MissionParams,
    shape: GridShape,
    grid: OccupancyGrid<CELLS>,
    planner: DStarLite<CELLS, QUEUE>,
    changed: ChangedCells<CHANGED_CAPACITY>,
    path: Vec<Cell, PATH_CAPACITY>,
    waypoints: Vec<Cell, WAYPOINT_CAPACITY>,
    avoidance: ReactiveAvoidance,
    pad: PadDetector<PAD_EDGES>,
    sweep: Option<LawnmowerSweep>,
    phase: Phase,
    leg: Leg,
    last_ranges: RangerReadings,
    last_tick: Option<Micros>,
    pad_not_found: bool,
    planner_needs_reset: bool,
    /// The heading the drone holds, rad: it turns to face its direction of travel while navigating, so the
    /// front ranger looks where it is going (four beams see nothing diagonal to them).
    heading: f32,
    stats: MissionStats,
}

/// Counters for logs and the simulator's report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MissionStats {
    /// Planner repairs after map changes.
    pub replans: u32,
    /// Full re-plans (planner resets).
    pub plans_from_scratch: u32,
    /// Expansions of the latest repair.
    pub last_expansions: u32,
    /// Pad locks: the centre the drone aimed at, per leg (outbound, return).
    pub pad_centres: [Option<(f32, f32)>; 2],
}

impl<const CELLS: usize, const QUEUE: usize> Mission<CELLS, QUEUE> {
    /// An idle mission, if the avoidance and pad-detector configs are valid.
    pub fn new(config: MissionConfig) -> Result<Self, MissionConfigError> {
        let avoidance = ReactiveAvoidance::new(config.avoidance).map_err(|_| MissionConfigError::Avoidance)?;
        let pad = PadDetector::new(config.pad).map_err(|_| MissionConfigError::PadDetector)?;
        Ok(Self {
            config,
            params: MissionParams::SEED,
            shape: GridShape { width: 1, height: 1 },
            grid: OccupancyGrid::new(),
            planner: DStarLite::new(),
            changed: ChangedCells::new(),
            path: Vec::new(),
            waypoints: Vec::new(),
            avoidance,
            pad,
            sweep: None,
            phase: Phase::Idle,
            leg: Leg::Outbound,
            last_ranges: RangerReadings::NONE,
            last_tick: None,
            pad_not_found: false,
            planner_needs_reset: false,
            heading: 0.0,
            stats: MissionStats::default(),
        })
    }

    /// The `mission.state` code right now.
    pub fn state(&self) -> MissionState {
        match self.phase {
            Phase::Idle => MissionState::Idle,
            Phase::Preflight => MissionState::Preflight,
            Phase::TakeOff { .. } => self.by_leg(MissionState::TakeOffOutbound, MissionState::TakeOffReturn),
            Phase::Navigate => self.by_leg(MissionState::NavigateToGoal, MissionState::NavigateHome),
            Phase::NoPath { .. } => MissionState::NoPathHover,
            Phase::Search(_) => self.by_leg(MissionState::SearchGoalPad, MissionState::SearchHomePad),
            Phase::Approach { .. } => self.by_leg(MissionState::ApproachGoalPad, MissionState::ApproachHomePad),
            Phase::Land { .. } => self.by_leg(MissionState::LandOnGoalPad, MissionState::LandOnHomePad),
            Phase::OnPad { .. } => MissionState::OnGoalPad,
            Phase::EmergencyLand { .. } => MissionState::EmergencyLanding,
            Phase::Ended(s) => s,
        }
    }

    /// Whether a mission is running (started, not ended).
    pub fn is_running(&self) -> bool {
        !matches!(self.phase, Phase::Idle | Phase::Ended(_))
    }

    /// The parameters of the current (or last) mission.
    pub fn params(&self) -> MissionParams {
        self.params
    }

    /// Counters.
    pub fn stats(&self) -> MissionStats {
        self.stats
    }

    /// The occupancy grid the drone has built.
    pub fn grid(&self) -> &OccupancyGrid<CELLS> {
        &self.grid
    }

    /// The current shortened path (cells), start first.
    pub fn waypoints(&self) -> &[Cell] {
        &self.waypoints
    }

    /// The pad detector (edges and estimate, for logs and plots).
    pub fn pad_detector(&self) -> &PadDetector<PAD_EDGES> {
        &self.pad
    }

    /// Start a mission from idle (or after a previous one ended). Refused while one runs or when the
    /// parameters make no sense; nothing changes then.
    pub fn start(&mut self, params: MissionParams) -> Result<(), StartRefusal> {
        if self.is_running() {
            return Err(StartRefusal::AlreadyRunning);
        }
        let shape = params.validate(CELLS)?;
        if !self.grid.reset(shape, self.full_inflation_cells()) {
            return Err(StartRefusal::BadArena);
        }
        // Avoidance clamps to the cruise speed the user asked for.
        let avoidance_config = AvoidanceConfig {
            cruise_speed_mps: params.speed_m_s,
            min_speed_mps: self.config.avoidance.min_speed_mps.min(params.speed_m_s),
            ..self.config.avoidance
        };
        self.avoidance = ReactiveAvoidance::new(avoidance_config).map_err(|_| StartRefusal::BadSpeed)?;
        self.params = params;
        self.shape = shape;
        self.changed.clear();
        self.path.clear();
        self.waypoints.clear();
        self.avoidance.reset();
        self.pad.reset();
        self.sweep = None;
        self.leg = Leg::Outbound;
        self.pad_not_found = false;
        self.planner_needs_reset = true;
        self.stats = MissionStats::default();
        self.last_tick = None;
        self.phase = Phase::Preflight;
        self.heading = 0.0;
        Ok(())
    }

    /// Abort (`mission.start = 0` during a mission): land where it is, then end with
    /// [`MissionState::Aborted`]. Does nothing when no mission runs.
    pub fn abort(&mut self, state: &StateEstimate) {
        match self.phase {
            Phase::Idle | Phase::Ended(_) => {}
            Phase::Preflight | Phase::OnPad { .. } => self.phase = Phase::Ended(MissionState::Aborted),
            _ => {
                self.phase = Phase::EmergencyLand {
                    x: state.position_m[0],
                    y: state.position_m[1],
                    then: MissionState::Aborted,
                }
            }
        }
    }

    /// A Multi-ranger reading (10 Hz): map it while flying, keep it for avoidance.
    pub fn on_ranges(&mut self, ranges: &MultiRangerSample, state: &StateEstimate) {
        self.last_ranges = RangerReadings::new(ranges.front_m, ranges.back_m, ranges.left_m, ranges.right_m);
        let airborne = matches!(
            self.phase,
            Phase::TakeOff { .. } | Phase::Navigate | Phase::NoPath { .. } | Phase::Search(_) | Phase::Approach { .. }
        );
        // Beams only map the arena once the drone flies above pads and low clutter.
        if !airborne || state.position_m[2] < 0.8 * self.params.height_m || !state.valid {
            return;
        }
        let (x, y, yaw) = (state.position_m[0], state.position_m[1], state.attitude_rad[2]);
        self.grid
            .mark_free_disc((x, y), self.config.body_clearance_m, &mut self.changed);
        let beams = [
            (ranges.front_m, 0.0),
            (ranges.back_m, core::f32::consts::PI),
            (ranges.left_m, core::f32::consts::FRAC_PI_2),
            (ranges.right_m, -core::f32::consts::FRAC_PI_2),
        ];
        for (range, offset) in beams {
            let Some(d) = range.filter(|d| d.is_finite() && *d > 0.02) else {
                continue;
            };
            let (length, hit) = if d <= self.config.max_mapping_range_m {
                (d, true)
            } else {
                (self.config.max_mapping_range_m, false)
            };
            let heading = yaw + offset;
            let end = (x + length * libm::cosf(heading), y + length * libm::sinf(heading));
            self.grid.integrate_beam((x, y), end, hit, &mut self.changed);
        }
    }

    /// A downward-range reading (40 Hz): the pad detector's input while searching and approaching.
    ///
    /// The ranger looks along body −z, so a tilted drone measures a spot beside itself (at 0.4 m and 4° of
    /// pitch, 3 cm away); the detector is given that spot, computed from the attitude estimate, so edges
    /// land where the step really is.
    pub fn on_zrange(&mut self, range: RangeReading, state: &StateEstimate) {
        // The pad lies near the leg's target, so the last stretch of navigation often flies straight over
        // it: feeding the detector from there on can give the first crossing before the search begins.
        let (tx, ty) = self.leg_target();
        let near_target = matches!(self.phase, Phase::Navigate)
            && libm::hypotf(state.position_m[0] - tx, state.position_m[1] - ty) < PAD_LOOKOUT_RADIUS_M;
        let searching = near_target || matches!(self.phase, Phase::Search(_) | Phase::Approach { .. });
        if let (true, Some(r)) = (searching, range) {
            let down = body_to_arena([0.0, 0.0, -1.0], state.attitude_rad);
            let (sx, sy) = (state.position_m[0] + r * down[0], state.position_m[1] + r * down[1]);
            if sx.is_finite() && sy.is_finite() {
                self.pad.update(r, sx, sy);
            }
        }
    }

    /// One mission step (20–50 Hz): returns the setpoint to fly.
    pub fn tick(&mut self, now: Micros, state: &StateEstimate, inputs: &MissionInputs) -> Setpoint {
        let dt_s = match self.last_tick {
            Some(t) if now > t => ((now - t) as f32 * 1e-6).min(0.2),
            _ => 0.02,
        };
        self.last_tick = Some(now);
        let (x, y, z) = (state.position_m[0], state.position_m[1], state.position_m[2]);

        // Conditions that end or divert any flying phase.
        if self.is_running() && !matches!(self.phase, Phase::Preflight | Phase::OnPad { .. }) {
            if inputs.crashed {
                self.phase = Phase::Ended(MissionState::Crashed);
                return Setpoint::Stop;
            }
            if !state.valid && !matches!(self.phase, Phase::EmergencyLand { .. }) {
                // Without a usable estimate nothing can be flown safely; descend blind at the last known spot
                // and let the supervisor's touchdown or timeout stop the motors.
                self.phase = Phase::EmergencyLand {
                    x,
                    y,
                    then: MissionState::EstimatorFault,
                };
            } else if inputs.battery_low && !matches!(self.phase, Phase::EmergencyLand { .. } | Phase::Land { .. }) {
                self.phase = Phase::EmergencyLand {
                    x,
                    y,
                    then: MissionState::BatteryLow,
                };
            }
        }

        match self.phase {
            Phase::Idle | Phase::Ended(_) => Setpoint::Stop,
            Phase::Preflight => {
                if inputs.crashed {
                    self.phase = Phase::Ended(MissionState::Crashed);
                    return Setpoint::Stop;
                }
                if !state.valid || !inputs.armed {
                    return Setpoint::Stop;
                }
                self.begin_leg(now, state, Leg::Outbound)
            }
            Phase::TakeOff { x: tx, y: ty, z_target } => {
                // Navigation takes over once the drone is safely above the minimum height: its setpoints
                // carry the cruise height, so the last part of the climb overlaps the first metres of travel.
                if z >= (self.params.height_m - 0.05).min(MIN_HEIGHT_M + TAKEOFF_HANDOVER_MARGIN_M) {
                    self.phase = Phase::Navigate;
                    self.avoidance.reset();
                    return self.navigate(now, state, dt_s);
                }
                let target = (z_target + self.config.climb_speed_m_s * dt_s).min(self.params.height_m);
                self.phase = Phase::TakeOff {
                    x: tx,
                    y: ty,
                    z_target: target,
                };
                Setpoint::Position {
                    x_m: tx,
                    y_m: ty,
                    z_m: target,
                    yaw_rad: self.heading,
                }
            }
            Phase::Navigate => self.navigate(now, state, dt_s),
            Phase::NoPath { since, x: hx, y: hy } => {
                match self.plan(state) {
                    Ok(Some(_)) => {
                        self.phase = Phase::Navigate;
                        return self.navigate(now, state, dt_s);
                    }
                    Ok(None) => {}
                    Err(()) => {}
                }
                if (now.saturating_sub(since)) as f32 * 1e-6 > self.config.no_path_wait_s {
                    self.phase = Phase::EmergencyLand {
                        x: hx,
                        y: hy,
                        then: MissionState::NoPath,
                    };
                } else {
                    // Turn while waiting: the four beams sweep all round, and a beam through an opening frees
                    // the cells that an obstacle mapped from a drifted estimate still blocks there.
                    self.heading = wrap_angle(self.heading + NO_PATH_TURN_RATE_RAD_S * dt_s);
                }
                Setpoint::Position {
                    x_m: hx,
                    y_m: hy,
                    z_m: self.params.height_m,
                    yaw_rad: self.heading,
                }
            }
            Phase::Search(search) => self.search(search, state, dt_s),
            Phase::Approach {
                x: px,
                y: py,
                settled_since,
            } => {
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
            Phase::Land { x: px, y: py } => {
                if inputs.landed {
                    return match self.leg {
                        Leg::Outbound => {
                            self.phase = Phase::OnPad { since: now };
                            Setpoint::Stop
                        }
                        Leg::Return => {
                            let end = if self.pad_not_found {
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
            Phase::OnPad { since } => {
                if inputs.crashed {
                    self.phase = Phase::Ended(MissionState::Crashed);
                    return Setpoint::Stop;
                }
                if (now.saturating_sub(since)) as f32 * 1e-6 >= self.config.pause_s && inputs.armed && state.valid {
                    return self.begin_leg(now, state, Leg::Return);
                }
                Setpoint::Stop
            }
            Phase::EmergencyLand { x: lx, y: ly, then } => {
                if inputs.landed {
                    self.phase = Phase::Ended(then);
                    return Setpoint::Stop;
                }
                // Without a usable estimate the horizontal velocity is no longer observed and drifts (a few
                // cm/s after the brake): the sooner the drone is down, the less it slides.
                let descent = if then == MissionState::EstimatorFault {
                    self.fault_descent_speed(state)
                } else {
                    self.descent_speed(state)
                };
                Setpoint::Descend {
                    x_m: lx,
                    y_m: ly,
                    vz_m_s: -descent,
                    yaw_rad: self.heading,
                }
            }
        }
    }

    fn by_leg(&self, outbound: MissionState, back: MissionState) -> MissionState {
        match self.leg {
            Leg::Outbound => outbound,
            Leg::Return => back,
        }
    }

    /// Fast from cruise height, slower close to the surface below, for a soft touchdown; once (nearly) down,
    /// ask for a fast descent, which the controller can only answer by dropping the thrust well below hover:
    /// that is what the supervisor's touchdown detection waits for. The time spent descending is time the
    /// flow-only position drifts off the pad centre (≈ 1 cm/√s), so only the last centimetres are slow.
    fn descent_speed(&self, state: &StateEstimate) -> f32 {
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
    fn fault_descent_speed(&self, state: &StateEstimate) -> f32 {
        let above = state.position_m[2] - state.surface_height_m;
        if above > 0.1 {
            FAULT_DESCENT_SPEED_M_S
        } else {
            self.descent_speed(state)
        }
    }

    /// The leg's target: the nominal goal going out, the start coming back.
    fn leg_target(&self) -> (f32, f32) {
        match self.leg {
            Leg::Outbound => self.params.goal_m,
            Leg::Return => self.params.start_m,
        }
    }

    fn begin_leg(&mut self, _now: Micros, state: &StateEstimate, leg: Leg) -> Setpoint {
        self.leg = leg;
        self.restore_full_inflation();
        self.planner_needs_reset = true;
        self.pad.reset();
        self.sweep = None;
        self.avoidance.reset();
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let z_target = state.position_m[2].max(0.0);
        self.phase = Phase::TakeOff { x, y, z_target };
        Setpoint::Position {
            x_m: x,
            y_m: y,
            z_m: z_target,
            yaw_rad: self.heading,
        }
    }

    fn full_inflation_cells(&self) -> u8 {
        libm::ceilf(self.config.inflation_radius_m / CELL_SIZE_M).clamp(0.0, 16.0) as u8
    }

    fn narrow_inflation_cells(&self) -> u8 {
        libm::ceilf(self.config.narrow_inflation_radius_m / CELL_SIZE_M).clamp(0.0, 16.0) as u8
    }

    /// Whether the planner currently uses the narrow no-path fallback margin.
    fn narrow(&self) -> bool {
        self.grid.inflation_radius_cells() < self.full_inflation_cells()
    }

    /// Back to the full margin (a new leg plans with it first).
    fn restore_full_inflation(&mut self) {
        let full = self.full_inflation_cells();
        if self.grid.inflation_radius_cells() != full {
            self.grid.set_inflation_radius(full, &mut self.changed);
        }
    }

    fn cell_of(&self, p: (f32, f32)) -> Cell {
        let max_x = (self.shape.width.saturating_sub(1)) as f32;
        let max_y = (self.shape.height.saturating_sub(1)) as f32;
        let cx = libm::floorf(p.0 / CELL_SIZE_M).clamp(0.0, max_x);
        let cy = libm::floorf(p.1 / CELL_SIZE_M).clamp(0.0, max_y);
        // NaN clamps to NaN; `as` turns it into 0, a valid cell.
        Cell::new(cx as u16, cy as u16)
    }

    /// The drone's cell for planning: itself, or, when inflation has swallowed it (it flew a little close to
    /// a wall), the nearest free cell within 0.3 m, so the plan leads out instead of reporting no path.
    fn escape_cell(&self, here: Cell) -> Cell {
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
    fn plan(&mut self, state: &StateEstimate) -> Result<Option<(f32, f32)>, ()> {
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

    fn navigate(&mut self, now: Micros, state: &StateEstimate, dt_s: f32) -> Setpoint {
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let target_leg = self.leg_target();
        let to_goal = libm::hypotf(target_leg.0 - x, target_leg.1 - y);
        let planned_goal = self.planner.goal();
        let at_substitute_goal = planned_goal != self.cell_of(target_leg) && {
            let (gx, gy) = self.shape.center_of(planned_goal);
            libm::hypotf(gx - x, gy - y) < self.config.goal_tolerance_m
        };
        if to_goal < self.config.goal_tolerance_m || (at_substitute_goal && !self.planner_needs_reset) {
            return self.begin_search(state);
        }
        let target = match self.plan(state) {
            Ok(Some(t)) => Some(t),
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
                    self.heading = match unobserved_cell {
                        // An unobserved region beside the path ahead: instead of sweeping (whose phase may
                        // look the other way all along the approach), point the beam that needs the least
                        // turn (front, left or right) at it, so it is seen before the drone is there.
                        Some(cell) => Self::look_at_heading(travel, (x, y), cell),
                        None => wrap_angle(travel + SCAN_AMPLITUDE_RAD * libm::sinf(phase)),
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
            .step(&self.last_ranges, state.attitude_rad[2], dvx, dvy, dt_s);
        Setpoint::Velocity {
            vx_m_s: cmd.vx,
            vy_m_s: cmd.vy,
            z_m: self.params.height_m,
            yaw_rad: self.heading,
        }
    }

    /// How fast to pass the waypoint `target` (reached from `here`), m/s: the cruise speed if the path goes on
    /// straight, down to [`CORNER_MIN_SPEED_M_S`] for a turn of 90° or more. A path turns where it rounds an
    /// obstacle (usually a wall end the four beams saw late), so a fast corner overshoots towards it.
    fn corner_speed(&self, cruise: f32, here: (f32, f32), target: (f32, f32)) -> f32 {
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
    /// Also returns the centre of the unobserved cell found first, if any, for a beam to look at.
    fn observed_ahead_m(&self, here: (f32, f32), target: (f32, f32)) -> (f32, Option<(f32, f32)>) {
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
            for y in cy.saturating_sub(reach)..=cy.saturating_add(reach) {
                for x in cx.saturating_sub(reach)..=cx.saturating_add(reach) {
                    if !self.shape.contains(x, y) {
                        continue;
                    }
                    let (x0, y0) = (x as f32 * CELL_SIZE_M, y as f32 * CELL_SIZE_M);
                    let dx = (x0 - p.0).max(p.0 - (x0 + CELL_SIZE_M)).max(0.0);
                    let dy = (y0 - p.1).max(p.1 - (y0 + CELL_SIZE_M)).max(0.0);
                    if dx * dx + dy * dy <= UNOBSERVED_CLEARANCE_M * UNOBSERVED_CLEARANCE_M
                        && ahead(x, y)
                        && self
                            .grid
                            .is_unobserved_region(Cell::new(x as u16, y as u16), UNOBSERVED_MIN_NEIGHBOURS)
                    {
                        return Some(self.shape.center_of(Cell::new(x as u16, y as u16)));
                    }
                }
            }
            None
        };
        let corners = core::iter::once(target).chain(self.waypoints.iter().skip(2).map(|c| self.shape.center_of(*c)));
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

    /// The heading within [`LOOK_MAX_OFFSET_RAD`] of `travel` that points the front, left or right beam
    /// (whichever needs the least turn away from `travel`) from `here` at `point`, rad.
    fn look_at_heading(travel: f32, here: (f32, f32), point: (f32, f32)) -> f32 {
        let bearing = libm::atan2f(point.1 - here.1, point.0 - here.0);
        let offset = [0.0, core::f32::consts::FRAC_PI_2, -core::f32::consts::FRAC_PI_2]
            .into_iter()
            .map(|beam| wrap_angle(bearing - beam - travel))
            .fold(core::f32::consts::PI, |best, o| {
                if libm::fabsf(o) < libm::fabsf(best) { o } else { best }
            });
        wrap_angle(travel + offset.clamp(-LOOK_MAX_OFFSET_RAD, LOOK_MAX_OFFSET_RAD))
    }

    fn begin_search(&mut self, state: &StateEstimate) -> Setpoint {
        let centre = self.leg_target();
        let arena = ArenaBounds::new(self.params.arena_m.0, self.params.arena_m.1, 0.15);
        let here = (state.position_m[0], state.position_m[1]);
        // The first pass's lines run along the arrival direction: its middle line, through the nominal
        // point, then starts just behind the drone instead of off to its side.
        let mut sweep = self.config.sweep;
        let (vx, vy) = (state.velocity_m_s[0], state.velocity_m_s[1]);
        if libm::hypotf(vx, vy) > 0.1 {
            sweep.axis = if libm::fabsf(vx) >= libm::fabsf(vy) {
                SweepAxis::AlongX
            } else {
                SweepAxis::AlongY
            };
        }
        self.sweep = LawnmowerSweep::new(centre, here, &sweep, &arena).ok();
        // The detector keeps what it saw on the approach (it was reset when the leg began).
        let search = Search::Coarse {
            step: 0,
            reverse: false,
        };
        self.phase = Phase::Search(search);
        self.search(search, state, 0.02)
    }

    /// Distance from `p` to the nearest mapped obstacle cell (the cell's square, not its centre) or arena
    /// wall, m, capped at [`CLEARANCE_HORIZON_M`]. Looks at a (2·3+1)² window of cells: O(49).
    fn clearance(&self, p: (f32, f32)) -> f32 {
        let (w, h) = self.params.arena_m;
        let mut best = CLEARANCE_HORIZON_M.min(p.0).min(w - p.0).min(p.1).min(h - p.1);
        let cx = libm::floorf(p.0 / CELL_SIZE_M) as i32;
        let cy = libm::floorf(p.1 / CELL_SIZE_M) as i32;
        let reach = libm::ceilf(CLEARANCE_HORIZON_M / CELL_SIZE_M) as i32;
        for y in (cy - reach)..=(cy + reach) {
            for x in (cx - reach)..=(cx + reach) {
                if !self.shape.contains(x, y) || !self.grid.is_occupied(Cell::new(x as u16, y as u16)) {
                    continue;
                }
                let (x0, y0) = (x as f32 * CELL_SIZE_M, y as f32 * CELL_SIZE_M);
                let dx = (x0 - p.0).max(p.0 - (x0 + CELL_SIZE_M)).max(0.0);
                let dy = (y0 - p.1).max(p.1 - (y0 + CELL_SIZE_M)).max(0.0);
                best = best.min(libm::hypotf(dx, dy));
            }
        }
        best
    }

    /// The point where the straight flight `from → to` must stop to keep [`SEARCH_CLEARANCE_M`] from what
    /// the drone has mapped: the search pattern is laid out blind around the nominal point, and its lines
    /// may run into a wall or box beside the pad. Moving while the clearance grows (leaving a tight spot) is
    /// always allowed; the first sample where it drops below the minimum and keeps shrinking ends the line.
    fn clip_to_clearance(&self, from: (f32, f32), to: (f32, f32)) -> (f32, f32) {
        let length = libm::hypotf(to.0 - from.0, to.1 - from.1);
        if !(length.is_finite() && length > 1e-3) {
            return to;
        }
        let steps = libm::ceilf(length / CLEARANCE_STEP_M).min(400.0) as u32;
        let mut previous = (from, self.clearance(from));
        for i in 1..=steps {
            let t = i as f32 / steps as f32;
            let p = (from.0 + t * (to.0 - from.0), from.1 + t * (to.1 - from.1));
            let c = self.clearance(p);
            if c < SEARCH_CLEARANCE_M && c < previous.1 - 1e-4 {
                return previous.0;
            }
            previous = (p, c);
        }
        to
    }

    /// Fly towards `target` at the search speed (stopping short of mapped obstacles, see
    /// [`Self::clip_to_clearance`]); `true` once within 3 cm of where it can get.
    fn fly_to(&self, state: &StateEstimate, target: (f32, f32)) -> (Setpoint, bool) {
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let target = self.clip_to_clearance((x, y), target);
        let (dx, dy) = (target.0 - x, target.1 - y);
        let d = libm::hypotf(dx, dy);
        // Line ends lie off the pad, so they need no precision; a firm approach (about 2.5 m/s² of
        // deceleration demand, 4 cm tolerance) keeps each line short in time, and with it the drift
        // between the crossings the detector compares.
        let reached = d < 0.04;
        let speed = self.config.search_speed_m_s.min(0.05 + 2.5 * d);
        let (vx, vy) = if d > 1e-3 {
            (speed * dx / d, speed * dy / d)
        } else {
            (0.0, 0.0)
        };
        (
            Setpoint::Velocity {
                vx_m_s: vx,
                vy_m_s: vy,
                z_m: self.params.height_m,
                yaw_rad: self.heading,
            },
            reached,
        )
    }

    fn search(&mut self, search: Search, state: &StateEstimate, _dt_s: f32) -> Setpoint {
        if let Some((px, py)) = self.pad.locked_centre() {
            self.stats.pad_centres[self.leg_index()] = Some((px, py));
            self.phase = Phase::Approach {
                x: px,
                y: py,
                settled_since: None,
            };
            return Setpoint::Position {
                x_m: px,
                y_m: py,
                z_m: self.params.height_m,
                yaw_rad: self.heading,
            };
        }
        match search {
            Search::Coarse { step, reverse } => {
                // The first crossing switches to the refinement around it.
                if let Some(first) = self.pad.crossings().first() {
                    let (dx, dy) = first.direction();
                    let centre = first.midpoint();
                    let refine = Search::Refine {
                        stage: 0,
                        line: 0,
                        end: 0,
                        centre,
                        first_along_x: libm::fabsf(dx) >= libm::fabsf(dy),
                        crossings_before: self.crossing_count(),
                    };
                    self.phase = Phase::Search(refine);
                    return self.search(refine, state, _dt_s);
                }
                let Some((a, b)) = self.coarse_line(step / 2) else {
                    return self.give_up_search(state);
                };
                // Enter each line at the end nearer the drone.
                let reverse = if step % 2 == 0 {
                    let here = (state.position_m[0], state.position_m[1]);
                    libm::hypotf(b.0 - here.0, b.1 - here.1) < libm::hypotf(a.0 - here.0, a.1 - here.1)
                } else {
                    reverse
                };
                let (first, second) = if reverse { (b, a) } else { (a, b) };
                let here = (state.position_m[0], state.position_m[1]);
                // Already on the line between its ends (the first line runs along the arrival, through the
                // nominal point, and navigation hands over short of it): fly on to its far end instead of
                // turning back to its start; the stretch behind was covered by the detector on the approach.
                let step = if step % 2 == 0 && Self::lies_on_segment(here, first, second, ON_LINE_TOLERANCE_M) {
                    step + 1
                } else {
                    step
                };
                let wp = if step % 2 == 0 { first } else { second };
                let (sp, reached) = self.fly_to(state, wp);
                self.phase = Phase::Search(Search::Coarse {
                    step: if reached { step + 1 } else { step },
                    reverse,
                });
                sp
            }
            Search::Refine {
                stage,
                line,
                end,
                centre,
                first_along_x,
                crossings_before,
            } => {
                if stage >= REFINE_STAGES {
                    self.pad.flush();
                    return self.give_up_search(state);
                }
                // Even stages fly across the first crossing's direction, odd stages along it; after the first
                // two, more passes re-centred on the latest estimate give the detector more crossings.
                let along_x = if stage % 2 == 0 { !first_along_x } else { first_along_x };
                let offset = (f32::from(line) - 1.0) * self.config.refine_offset_m;
                // The first stage crosses a pad whose centre may lie up to a pad width to either side of the
                // first crossing's line, so its lines are longer; later stages are centred on the estimate.
                // The same holds while every inlier crossing runs one way: the estimate's other coordinate
                // is then only the lines' offset, anywhere within half a pad of the centre.
                let one_direction_only = self.pad.estimate().is_none_or(|e| e.min_direction_crossings < 0.5);
                let length = if stage == 0 || one_direction_only {
                    self.config.refine_line_m + 0.3
                } else {
                    self.config.refine_line_m
                };
                let half = 0.5 * length;
                let (a, b) = if along_x {
                    (
                        (centre.0 - half, centre.1 + offset),
                        (centre.0 + half, centre.1 + offset),
                    )
                } else {
                    (
                        (centre.0 + offset, centre.1 - half),
                        (centre.0 + offset, centre.1 + half),
                    )
                };
                // Alternate directions so consecutive lines join up like a lawnmower.
                let (first, second) = if line % 2 == 0 { (a, b) } else { (b, a) };
                let wp = if end == 0 { first } else { second };
                let (sp, reached) = self.fly_to(state, wp);
                let crossings_now = self.crossing_count();
                // A line has done its job once it gave a crossing: its remaining length only costs time.
                let line_done = end == 1 && (reached || crossings_now > crossings_before);
                let next = if !reached && !line_done {
                    Search::Refine {
                        stage,
                        line,
                        end,
                        centre,
                        first_along_x,
                        crossings_before,
                    }
                } else if end == 0 {
                    Search::Refine {
                        stage,
                        line,
                        end: 1,
                        centre,
                        first_along_x,
                        crossings_before: crossings_now,
                    }
                } else if line + 1 < REFINE_LINES && (stage >= 2 || self.inlier_crossings(along_x) < 2) {
                    Search::Refine {
                        stage,
                        line: line + 1,
                        end: 0,
                        centre,
                        first_along_x,
                        crossings_before: crossings_now,
                    }
                } else {
                    // Next stage (this direction has its two crossings, or its lines are flown), centred on
                    // the detector's best estimate so far. After the first round the detector starts
                    // afresh: the position estimate drifts (≈ 1 cm/√s on flow alone), so crossings half a
                    // minute apart disagree by more than the pad detection error.
                    self.pad.flush();
                    let c = self.pad.estimate().map(|e| (e.x, e.y)).unwrap_or(centre);
                    if (stage + 1) % 2 == 0 {
                        self.pad.reset();
                    }
                    Search::Refine {
                        stage: stage + 1,
                        line: 0,
                        end: 0,
                        centre: c,
                        first_along_x,
                        crossings_before: self.crossing_count(),
                    }
                };
                self.phase = Phase::Search(next);
                sp
            }
        }
    }

    /// Whether `p` lies within `tolerance` of the segment `a → b`, between its ends.
    fn lies_on_segment(p: (f32, f32), a: (f32, f32), b: (f32, f32), tolerance: f32) -> bool {
        let (ux, uy) = (b.0 - a.0, b.1 - a.1);
        let length = libm::hypotf(ux, uy);
        // Also false for a NaN length.
        if length.is_nan() || length <= 1e-3 {
            return false;
        }
        let (ux, uy) = (ux / length, uy / length);
        let (px, py) = (p.0 - a.0, p.1 - a.1);
        let along = px * ux + py * uy;
        let across = libm::fabsf(px * uy - py * ux);
        (0.0..length).contains(&along) && across <= tolerance
    }

    /// Crossings the detector holds (saturating at 255): a line that adds one has done its job.
    fn crossing_count(&self) -> u8 {
        u8::try_from(self.pad.crossings().len()).unwrap_or(u8::MAX)
    }

    /// Inlier crossings the detector holds that run along x (`along_x`) or along y.
    fn inlier_crossings(&self, along_x: bool) -> usize {
        self.pad
            .crossings()
            .iter()
            .filter(|c| {
                let (dx, dy) = c.direction();
                c.inlier && (libm::fabsf(dx) >= libm::fabsf(dy)) == along_x
            })
            .count()
    }

    /// The `k`-th line of the coarse pattern, lines taken centre-out within each pass of the lawnmower
    /// (the pad lies near the nominal point, so the middle lines are the likeliest to cross it).
    fn coarse_line(&self, k: usize) -> Option<((f32, f32), (f32, f32))> {
        let sweep = self.sweep.as_ref()?;
        let [first, second] = sweep.lines_per_pass();
        let (pass_start, lines, j) = if k < first {
            (0, first, k)
        } else {
            (2 * first, second, k.checked_sub(first)?)
        };
        if j >= lines {
            return None;
        }
        // Centre-out: mid, mid+1, mid−1, mid+2, …
        let mid = (lines - 1) / 2;
        let offset = j.div_ceil(2);
        let line = if j % 2 == 1 {
            mid + offset
        } else {
            mid.checked_sub(offset)?
        };
        let line = if line < lines {
            line
        } else {
            mid.checked_sub(offset + 1)?
        };
        let a = sweep.waypoint(pass_start + 2 * line)?;
        let b = sweep.waypoint(pass_start + 2 * line + 1)?;
        Some((a, b))
    }

    /// No lock: land on the best estimate, or the nominal point, and remember it for the final code.
    fn give_up_search(&mut self, state: &StateEstimate) -> Setpoint {
        self.pad_not_found = true;
        let (px, py) = self
            .pad
            .estimate()
            .map(|e| (e.x, e.y))
            .unwrap_or_else(|| self.leg_target());
        self.stats.pad_centres[self.leg_index()] = None;
        let _ = state;
        self.phase = Phase::Approach {
            x: px,
            y: py,
            settled_since: None,
        };
        Setpoint::Position {
            x_m: px,
            y_m: py,
            z_m: self.params.height_m,
            yaw_rad: self.heading,
        }
    }

    fn leg_index(&self) -> usize {
        match self.leg {
            Leg::Outbound => 0,
            Leg::Return => 1,
        }
    }
}
