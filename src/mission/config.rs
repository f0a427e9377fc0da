//! What a mission is given: the radio parameters ([`MissionParams`], validated against the grid's capacity
//! before a start), the tuning that is not a radio parameter ([`MissionConfig`]), the supervisor flags read
//! each tick ([`MissionInputs`]), and why a start or a configuration is refused.
//!
//! Units: metres, seconds, radians, arena frame. Memory: a few hundred bytes, all `Copy`.

use crate::landing::pad::PadConfig;
use crate::landing::sweep::SweepConfig;
use crate::nav::avoidance::{AvoidanceConfig, SpeedClamp};
use crate::nav::map::GridShape;

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
    /// The hover time or the coverage target of the mission modes is outside its range.
    BadModeSetting,
}

/// What the mission does (`mission.mode`, see the README's mode table).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(u8)]
pub enum MissionMode {
    /// 0: the round trip (take off, goal pad, home pad), the default.
    #[default]
    RoundTrip = 0,
    /// 1: take off, hold `mission.hoverTime` s over the take-off point, land there; the worst deviation is
    /// logged.
    HoverTest = 1,
    /// 2: frontier exploration until the coverage target or no reachable frontier, then home to its pad.
    Explore = 2,
}

impl MissionMode {
    /// The mode of a `mission.mode` value; `None` for values no mode has.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::RoundTrip),
            1 => Some(Self::HoverTest),
            2 => Some(Self::Explore),
            _ => None,
        }
    }

    /// The `mission.mode` value.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// Every mode, in `mission.mode` order.
    pub const ALL: [Self; 3] = [Self::RoundTrip, Self::HoverTest, Self::Explore];

    /// The mode's name (as `cfnav sim --mode` spells it) and what it does, for the README's mode table.
    pub const fn describe(self) -> (&'static str, &'static str) {
        match self {
            Self::RoundTrip => (
                "round-trip",
                "take off, map and plan to `mission.goalX/goalY`, find the goal pad, land, take off, fly home, \
                 find the home pad, land (states 10–24)",
            ),
            Self::HoverTest => (
                "hover",
                "take off to `mission.height`, hold over the take-off point for `mission.hoverTime` s (state 50), \
                 land there (51); the worst deviation is logged as `mission.hoverDevXY`, `mission.hoverDevZ`",
            ),
            Self::Explore => (
                "explore",
                "fly to the nearest reachable frontier (60), look around there and choose the next (61), until \
                 `mission.coverage` of the arena's cells is known, no frontier is left (also at the narrow \
                 margin `plan.narrowInfl`), or the battery no longer covers `mission.batReserve` times the \
                 flight home (a console line says so); then fly home, find the home pad, land (21–24); \
                 `mission.covered` logs the coverage",
            ),
        }
    }
}

/// Writes the README's mode table: one Markdown row per [`MissionMode`].
pub fn write_mode_table(out: &mut impl core::fmt::Write) -> core::fmt::Result {
    writeln!(out, "| `mission.mode` | `cfnav sim --mode` | what the mission does |")?;
    writeln!(out, "|---|---|---|")?;
    for mode in MissionMode::ALL {
        let (name, doc) = mode.describe();
        writeln!(out, "| {} | `{name}` | {doc} |", mode.code())?;
    }
    Ok(())
}

/// Shortest and longest hover test accepted, s.
pub const HOVER_TIME_RANGE_S: (f32, f32) = (1.0, 60.0);
/// Smallest and largest exploration coverage target accepted (fraction of the arena's cells known).
pub const COVERAGE_RANGE: (f32, f32) = (0.05, 1.0);

/// The mission's parameters (the `mission.*` radio parameters and the arena).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MissionParams {
    /// Arena size, m (x, y): the grid the drone maps (`mission.arenaX`, `mission.arenaY`).
    pub arena_m: (f32, f32),
    /// Which sides of the arena are walls (`mission.walls`): [`WALL_SOUTH`] | [`WALL_EAST`] |
    /// [`WALL_NORTH`] | [`WALL_WEST`]; a side without its bit is open (nothing stands on the arena's
    /// edge there: the map fixes do not measure against it, and the drone keeps [`GEOFENCE_M`] from it).
    pub walls: u8,
    /// Where the drone stands at power-on (the home pad), m.
    pub start_m: (f32, f32),
    /// The nominal goal, m.
    pub goal_m: (f32, f32),
    /// Cruise height above the arena floor, m (≥ 0.2).
    pub height_m: f32,
    /// Cruise speed, m/s.
    pub speed_m_s: f32,
    /// What the mission does (`mission.mode`).
    pub mode: MissionMode,
    /// The hover test's hold time, s (`mission.hoverTime`, [`HOVER_TIME_RANGE_S`]).
    pub hover_time_s: f32,
    /// Exploration ends once this fraction of the arena's cells is known (`mission.coverage`,
    /// [`COVERAGE_RANGE`]).
    pub coverage_target: f32,
}

/// `mission.walls` bit: the south wall, y = 0.
pub const WALL_SOUTH: u8 = 1;
/// `mission.walls` bit: the east wall, x = arena x.
pub const WALL_EAST: u8 = 2;
/// `mission.walls` bit: the north wall, y = arena y.
pub const WALL_NORTH: u8 = 4;
/// `mission.walls` bit: the west wall, x = 0.
pub const WALL_WEST: u8 = 8;
/// A walled box: every side a wall (the default).
pub const ALL_WALLS: u8 = WALL_SOUTH | WALL_EAST | WALL_NORTH | WALL_WEST;
/// How far the drone keeps inside an open side of the arena, m: the planner's goal and paths stay this far
/// from it, the reactive layer pushes back inside it, and an estimate beyond the open edge ends the
/// mission (land where it is).
pub const GEOFENCE_M: f32 = 0.3;

/// The `mission.walls` bit of the side a ray leaves the arena through: along x (`axis` 0) or y (1),
/// towards the far side (`positive`) or the origin.
pub const fn wall_bit(axis: usize, positive: bool) -> u8 {
    match (axis, positive) {
        (0, true) => WALL_EAST,
        (0, false) => WALL_WEST,
        (_, true) => WALL_NORTH,
        (_, false) => WALL_SOUTH,
    }
}

/// Minimum height in flight phases (`docs/radio.md`, the supervisor's floor too).
pub const MIN_HEIGHT_M: f32 = 0.2;
/// Highest cruise height accepted, m.
pub const MAX_HEIGHT_M: f32 = 2.0;
/// Highest cruise speed accepted, m/s.
pub const MAX_SPEED_M_S: f32 = 1.0;

impl MissionParams {
    /// The seed scenario's values.
    pub const SEED: Self = Self {
        arena_m: (6.0, 3.0),
        walls: ALL_WALLS,
        start_m: (0.6, 1.3),
        goal_m: (5.0, 1.5),
        height_m: 0.5,
        speed_m_s: 0.5,
        mode: MissionMode::RoundTrip,
        hover_time_s: 5.0,
        coverage_target: 0.8,
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
        let within = |v: f32, (lo, hi): (f32, f32)| v >= lo && v <= hi;
        if !within(self.hover_time_s, HOVER_TIME_RANGE_S) || !within(self.coverage_target, COVERAGE_RANGE) {
            return Err(StartRefusal::BadModeSetting);
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
    /// Explore's battery reserve (`mission.batReserve`): it turns home once the battery, at the discharge
    /// rate measured in flight, no longer lasts this many times the flight home (planned path at cruise
    /// speed, plus the home pad's search and landing; `super::reserve`). ≥ 1.
    pub battery_reserve: f32,
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
            // extra crossing gains (600 simulated worlds: median 2.53 cm, p95 5.49 cm either way).
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
            battery_reserve: 1.5,
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
    /// The supervisor's filtered battery voltage, V (0: no reading yet; explore's reserve ignores it).
    pub battery_v: f32,
    /// The supervisor's battery-low threshold, V (below it for its hold time, it lands where it is).
    pub battery_low_v: f32,
}
