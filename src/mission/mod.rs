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
//!   towards each ranger's obstacle: flying along a wall is not slowed, flying into one is), and the
//!   speed towards each beam's return the arena's walls do not explain is bounded by what the beam reads
//!   now, as on a search line but with a 0.13 m stop distance. The planner
//!   treats unknown space as free, so a path may graze a box no beam has seen: where the path ahead passes
//!   within 0.22 m of an *unobserved region* (a cell not yet seen free, i.e. unknown or holding a hit below
//!   the occupied threshold, among such or occupied neighbours; next to a *contested* cell, a hit and a
//!   miss, a cell needs two net misses to count as seen free: a wall's end or a box's corner that grazing
//!   beams left as such a mix is still unobserved, see [`OccupancyGrid::is_doubtful_region`]; within
//!   0.12 m of the path, the width the body sweeps, three such neighbours suffice instead of five, so a
//!   thin post whose surroundings the beams have swept is not taken for a gap between their traces), the drone
//!   slows (0.2 m/s there, 1 m/s more per metre of observed path before it) and, instead of sweeping its
//!   heading, turns the front, left or right beam (whichever needs the least turn) towards the first such
//!   cell until a beam has looked into it; a beam with no return maps nothing, so when that beam has
//!   returned nothing two sweeps in a row (open space beyond its 4 m) the heading sweeps for 2 s instead,
//!   turning the beams onto what lies beside the path. The heading slows the drone only when it lags the
//!   actual velocity by more than the sweep's amplitude.
//!   A nominal goal inside the inflated margin of something mapped is replaced by the nearest free cell
//!   within 0.3 m (the search starts there).
//! - **Open sides** (`mission.walls` without a side's bit): the grid blocks the cells within
//!   [`GEOFENCE_M`] of that side instead of the wall's inflation, so goals and paths stay 0.3 m inside it;
//!   the reactive layer sees each beam shortened to where it crosses the open edge (a virtual wall); an
//!   estimate past the edge lands where it is and ends with [`MissionState::LeftArena`].
//! - **No path**: once per leg, plan again with [`MissionConfig::narrow_inflation_radius_m`] and fly at
//!   [`MissionConfig::narrow_speed_m_s`]; if that fails too, hover and keep mapping (false obstacles clear,
//!   the plan repairs itself) for [`MissionConfig::no_path_wait_s`]; then land where it is and end with
//!   [`MissionState::NoPath`].
//! - **Search** (the detector already listens on the last 0.8 m of navigation; every search line stops
//!   0.18 m short of mapped obstacles and the arena walls; navigation hands over 0.35 m before the nominal
//!   goal): a coarse lawnmower pass around the nominal goal, its first lines along the arrival direction
//!   (a drone already on that line flies on along it instead of turning back to its start), until the
//!   [`PadDetector`] has a first crossing (on every line, and on the approach back to a locked centre, the
//!   speed towards each horizontal beam's return the arena's walls do not explain is bounded by what that
//!   beam reads now, and a line ends where such a beam within 45° of its direction reads closer than 0.2 m;
//!   a line that passes within 0.22 m of an unobserved region (0.12 m: the same corridor rule) slows
//!   before it like navigation, and the
//!   beam nearest to the region's first cell turns onto it: a line may run diagonally to all four beams);
//!   then short refinement stages
//!   centred on the latest estimate —
//!   lines across the first crossing (which fix the other coordinate), then lines along it, four rounds
//!   in all with a fresh detector every round (the estimate drifts) — until the detector locks (three
//!   inlier crossings covering both directions: usually the first crossing and two lines across it), or
//!   two crossings, one each way, agree on a square pad (confidence ≥ 0.8, no outlier: a pad boxed in by a
//!   wall and an obstacle gives no third, and elsewhere it saves a line). A
//!   line ends as soon as it gave a crossing (its rest only costs time), and in the first round a stage
//!   ends once its direction has two inlier crossings; later rounds fly all three lines of a stage.
//!   A line cut short by the clearance while the drone is on the pad (a wall or an obstacle 0.1–0.25 m
//!   beyond it) cannot see the far side: when the drone reaches that end, the detector takes the
//!   entry edge alone, half a pad from the centre, as a half crossing.
//!   If the pattern ends without a
//!   lock the search widens and re-centres on the best estimate once; if that fails too, the drone lands
//!   on the estimate only where the descent gate allows it, else clear of the pad, and the mission ends
//!   with [`MissionState::PadNotFound`] after flying the rest of the round trip (see `landing`).
//! - **Take-off**: the first 0.13 m fast (0.8 m/s, so that the lift-off's sideways slide stays under a
//!   millimetre until the body has passed a pad's top beside the start), then at
//!   [`MissionConfig::climb_speed_m_s`], first stepping away (up to 0.1 m) from
//!   any horizontal beam's return within 0.14 m on the ground (a start beside the home pad's side, one body
//!   radius away, is valid); navigation takes over 0.1 m above the
//!   minimum height, and the rest of the climb overlaps the first metres of travel.
//! - **Land**: fly back over the pad centre (a velocity profile down to 6 cm from it, then position hold),
//!   until within [`MissionConfig::settle_tolerance_m`] and slow and the
//!   [descent gate](crate::landing::gate) agrees (clearance rule, the pad's level under the drone), descend at
//!   [`MissionConfig::high_descent_speed_m_s`] down to 0.2 m above the surface and slower below it (the
//!   flow-only position drifts ≈ 1 cm/√s, so the time from the last crossing to touchdown is landing
//!   error); the supervisor detects the touchdown and stops the motors, which the mission sees as `landed`.
//!
//! Files: [`config`] (parameters, tuning, refusals), `navigate` (legs, planning, avoidance, no-path),
//! `search` (coarse and refinement lines), `landing` (approach, descent); this file holds the phases and
//! their transitions.
//!
//! Memory: the grid (`CELLS + 12` B), the planner (`4·CELLS + 10·QUEUE` B), a path buffer and the small
//! detectors: about 50 KB for the 6 × 3 m arena. Cost per tick: one bounded planner slice
//! ([`MissionConfig::planner_budget`] expansions) plus a path read-off (O(path length)).

use core::ptr::addr_of_mut;

/// Open sides nearer than this along a beam are a virtual reading for the reactive layer, m (the
/// Multi-ranger's reach).
const FENCE_RANGE_M: f32 = 4.0;

use heapless::Vec;

pub mod config;
mod explore;
mod hover;
mod landing;
pub mod link_loss;
pub mod mode_states;
mod navigate;
pub mod ranger_watch;
pub mod reserve;
mod search;
pub mod start;

pub use config::{
    ALL_WALLS, COVERAGE_RANGE, GEOFENCE_M, HOVER_TIME_RANGE_S, MAX_HEIGHT_M, MAX_SPEED_M_S, MIN_HEIGHT_M,
    MissionConfig, MissionConfigError, MissionInputs, MissionMode, MissionParams, StartRefusal, WALL_EAST, WALL_NORTH,
    WALL_SOUTH, WALL_WEST, wall_bit, write_mode_table,
};
pub use explore::{ExploreEnd, MissionNote};
pub use start::{HOME_TOLERANCE_M, PositionRefusal};

use crate::landing::pad::{EdgeKind, PadDetector};
use crate::landing::sweep::LawnmowerSweep;
use crate::math::{body_to_arena, wrap_angle};
use crate::nav::avoidance::{AvoidanceConfig, RangerReadings, ReactiveAvoidance};
use crate::nav::dstar::DStarLite;
use crate::nav::grid::{ChangedCells, OccupancyGrid};
use crate::nav::map::{CELL_SIZE_M, Cell, GridShape};
use crate::types::{Micros, MultiRangerSample, RangeReading, Setpoint, StateEstimate};

/// The `mission.state` codes (`docs/radio.md`): 0 idle, 1..99 phases, 100 completed, ≥ 200 ended without
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
    /// Hover test: holding over the take-off point for `mission.hoverTime` s.
    HoverHold = 50,
    /// Hover test: descending onto the take-off point.
    HoverLand = 51,
    /// Exploring: flying to the nearest reachable frontier.
    Explore = 60,
    /// Exploring: at a frontier, turning a quarter turn to look around, then choosing the next frontier.
    ExploreLook = 61,
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
    /// The radio link was lost with `mission.linkLoss = 1`: landed where it was.
    LinkLost = 207,
    /// The radio link was lost on the outbound leg with `mission.linkLoss = 2`: flew home, landed on the
    /// home pad (or its best estimate).
    LinkLostHome = 208,
    /// The Multi-ranger stopped reporting in flight ([`ranger_watch`]): landed where it was.
    RangerLost = 209,
    /// The estimate crossed an open side of the arena (`mission.walls`, [`GEOFENCE_M`]): landed where it
    /// was.
    LeftArena = 210,
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

/// Which way the round trip is going (or which mode's flight this is).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Leg {
    Outbound,
    Return,
    /// The hover test (take-off, hold, landing at the take-off point).
    Hover,
    /// Exploring frontiers (then [`Leg::Return`] flies home).
    Explore,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Phase {
    Idle,
    Preflight,
    TakeOff {
        x: f32,
        y: f32,
        z_target: f32,
        /// Below this height (arena frame, m) the climb is the fast lift-off (`navigate::TAKE_OFF_HOP_SPEED_M_S`).
        hop_until_m: f32,
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
    /// Hover test: holding position over the take-off point since `since`.
    HoverHold {
        x: f32,
        y: f32,
        since: Micros,
    },
    /// Exploring: holding at `(x, y)`, turning from `heading_start` by a quarter turn since `since`, then
    /// scanning the grid for the next frontier (`scanning`).
    ExploreLook {
        x: f32,
        y: f32,
        since: Micros,
        heading_start: f32,
        scanning: bool,
    },
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
/// Yaw rate while hovering with no path, rad/s (a quarter turn, all four beams' gaps, in 2 s).
const NO_PATH_TURN_RATE_RAD_S: f32 = 0.8;
/// Take-off hands over to navigation this far above [`MIN_HEIGHT_M`] (or 5 cm below the cruise height if that
/// is lower), m.
const TAKEOFF_HANDOVER_MARGIN_M: f32 = 0.1;
/// A landing where the drone is (abort, battery low, no path, link loss) closer than this to a known pad
/// centre lands on that centre, m: the pads of the worlds are up to 0.3 × 0.3 m, plus the body's radius
/// (0.06 m) and margin.
const PAD_SNAP_M: f32 = 0.3;
/// The drone's body radius (`docs/formats.md`, world files: the disc whose contact is a collision), m.
const BODY_RADIUS_M: f32 = 0.06;
/// Kept between the body and the square an unlocked pad estimate may cover, m: the estimate's error
/// after one or two crossings (a few cm) and the landing's own drift.
const UNLOCKED_PAD_MARGIN_M: f32 = 0.06;
/// A landing where the drone is descends once within this of its landing point, m; farther, it first flies
/// there at its height.
const EMERGENCY_MOVE_TOLERANCE_M: f32 = 0.05;
/// The smallest and largest change of the map fixes' shift sum between two ticks that moves the pad
/// search's records ([`Mission::on_map_fix_shift`]), m: a jump, not the fixes' steady pull; and not a
/// filter reset's.
const MIN_MAP_FIX_SHIFT_STEP_M: f32 = 0.02;
const MAX_MAP_FIX_SHIFT_STEP_M: f32 = 0.5;
/// Within this distance of the leg's target the navigating drone already feeds the pad detector, m.
const PAD_LOOKOUT_RADIUS_M: f32 = 0.8;
/// The hover test's hold and the exploration's first look begin once the climb is this close below the
/// cruise height, m.
const MODE_HANDOVER_BELOW_M: f32 = 0.03;

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
    /// Height above the surface below in the last valid estimate, m (bounds a blind descent).
    last_valid_height_m: f32,
    /// A descent without a valid estimate stops the motors at this time if nothing saw the touchdown.
    blind_descent_until: Option<Micros>,
    pad_not_found: bool,
    /// The link-loss policy turned the drone home: the home landing ends with [`MissionState::LinkLostHome`].
    link_lost_home: bool,
    planner_needs_reset: bool,
    /// The heading the drone holds, rad: it turns to face its direction of travel while navigating, so the
    /// front ranger looks where it is going (four beams see nothing diagonal to them).
    heading: f32,
    stats: MissionStats,
    /// The descent gate's state and the search's retries for this leg (`landing`).
    touchdown: landing::Touchdown,
    explorer: explore::Explorer,
    /// The estimator's map-fix shift sum at the previous tick ([`Self::on_map_fix_shift`]).
    last_map_fix_shift_m: Option<[f32; 2]>,
    /// Which beams return nothing, for the navigation's look at unobserved regions (`navigate`).
    blind_look: navigate::BlindLook,
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
    /// Hover test: the worst horizontal distance of the position estimate from the take-off point during
    /// the hold, m (`mission.hoverDevXY`).
    pub hover_dev_xy_m: f32,
    /// Hover test: the worst |estimated height − `mission.height`| during the hold, m (`mission.hoverDevZ`).
    pub hover_dev_z_m: f32,
    /// Explore: the fraction of the arena's cells known at the latest frontier scan (`mission.covered`).
    pub coverage: f32,
    /// Explore: frontiers reached.
    pub frontiers_reached: u32,
    /// Explore: frontiers given up (no path, or not reached in time).
    pub frontiers_dropped: u32,
    /// Explore: why the exploration ended (then the drone flew home).
    pub explore_end: Option<ExploreEnd>,
}

/// The mission's pad detector (its edge capacity).
pub type MissionPadDetector = PadDetector<PAD_EDGES>;

impl<const CELLS: usize, const QUEUE: usize> Mission<CELLS, QUEUE> {
    /// An idle mission, if the avoidance and pad-detector configs are valid.
    pub fn new(config: MissionConfig) -> Result<Self, MissionConfigError> {
        let (avoidance, pad) = Self::checked_parts(config)?;
        Ok(Self::from_parts(config, avoidance, pad))
    }

    /// The two parts of a mission whose configurations can be invalid, checked (see [`Self::from_parts`]).
    pub fn checked_parts(config: MissionConfig) -> Result<(ReactiveAvoidance, MissionPadDetector), MissionConfigError> {
        let avoidance = ReactiveAvoidance::new(config.avoidance).map_err(|_| MissionConfigError::Avoidance)?;
        let pad = PadDetector::new(config.pad).map_err(|_| MissionConfigError::PadDetector)?;
        Ok((avoidance, pad))
    }

    /// An idle mission from parts [`Self::checked_parts`] made (the firmware writes it in place instead:
    /// [`Self::init_at`]).
    pub fn from_parts(config: MissionConfig, avoidance: ReactiveAvoidance, pad: MissionPadDetector) -> Self {
        Self {
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
            last_valid_height_m: 0.0,
            blind_descent_until: None,
            pad_not_found: false,
            link_lost_home: false,
            planner_needs_reset: false,
            heading: 0.0,
            stats: MissionStats::default(),
            touchdown: landing::Touchdown::new(),
            explorer: explore::Explorer::new(),
            last_map_fix_shift_m: None,
            blind_look: navigate::BlindLook::NEW,
        }
    }

    /// Writes an idle mission from parts [`Self::checked_parts`] made straight into `slot`, field by field,
    /// so no ≈ 50 KB temporary is ever built on the stack (the firmware's navigator lives in CCM; built by
    /// value, the compiler gave the boot task a 66 KB and [`Self::from_parts`] a 56 KB frame, more than the
    /// stack). The same fields as [`Self::from_parts`].
    ///
    /// # Safety
    /// `slot` must be valid for writes and aligned for `Self`; its old contents are overwritten without being
    /// dropped (the mission owns no resources). After the call `*slot` is a fully initialised `Self`.
    pub unsafe fn init_at(
        slot: *mut Self,
        config: MissionConfig,
        avoidance: ReactiveAvoidance,
        pad: MissionPadDetector,
    ) {
        // A field added to `Self` and not written below must not compile: this pattern names every field.
        let _every_field_written = |m: &Self| {
            let Self {
                config: _,
                params: _,
                shape: _,
                grid: _,
                planner: _,
                changed: _,
                path: _,
                waypoints: _,
                avoidance: _,
                pad: _,
                sweep: _,
                phase: _,
                leg: _,
                last_ranges: _,
                last_tick: _,
                last_valid_height_m: _,
                blind_descent_until: _,
                pad_not_found: _,
                link_lost_home: _,
                planner_needs_reset: _,
                heading: _,
                stats: _,
                touchdown: _,
                explorer: _,
                last_map_fix_shift_m: _,
                blind_look: _,
            } = m;
        };
        // SAFETY: the caller guarantees `slot` is valid and aligned; `addr_of_mut!` makes no reference to the
        // uninitialised fields, and every field of `Self` is written exactly once below.
        unsafe {
            addr_of_mut!((*slot).config).write(config);
            addr_of_mut!((*slot).params).write(MissionParams::SEED);
            addr_of_mut!((*slot).shape).write(GridShape { width: 1, height: 1 });
            addr_of_mut!((*slot).grid).write(OccupancyGrid::new());
            addr_of_mut!((*slot).planner).write(DStarLite::new());
            addr_of_mut!((*slot).changed).write(ChangedCells::new());
            addr_of_mut!((*slot).path).write(Vec::new());
            addr_of_mut!((*slot).waypoints).write(Vec::new());
            addr_of_mut!((*slot).avoidance).write(avoidance);
            addr_of_mut!((*slot).pad).write(pad);
            addr_of_mut!((*slot).sweep).write(None);
            addr_of_mut!((*slot).phase).write(Phase::Idle);
            addr_of_mut!((*slot).leg).write(Leg::Outbound);
            addr_of_mut!((*slot).last_ranges).write(RangerReadings::NONE);
            addr_of_mut!((*slot).last_tick).write(None);
            addr_of_mut!((*slot).last_valid_height_m).write(0.0);
            addr_of_mut!((*slot).blind_descent_until).write(None);
            addr_of_mut!((*slot).pad_not_found).write(false);
            addr_of_mut!((*slot).link_lost_home).write(false);
            addr_of_mut!((*slot).planner_needs_reset).write(false);
            addr_of_mut!((*slot).heading).write(0.0);
            addr_of_mut!((*slot).stats).write(MissionStats::default());
            addr_of_mut!((*slot).touchdown).write(landing::Touchdown::new());
            addr_of_mut!((*slot).explorer).write(explore::Explorer::new());
            addr_of_mut!((*slot).last_map_fix_shift_m).write(None);
            addr_of_mut!((*slot).blind_look).write(navigate::BlindLook::NEW);
        }
    }

    /// New tuning (the tuning parameters), for the next [`Self::start`]; call it while idle (the
    /// navigator does, just before a start: a running mission's grid is inflated with the margins it
    /// started with). Refused if the avoidance or pad-detector config is invalid; nothing changes then.
    pub fn set_config(&mut self, config: MissionConfig) -> Result<(), MissionConfigError> {
        let avoidance = ReactiveAvoidance::new(config.avoidance).map_err(|_| MissionConfigError::Avoidance)?;
        let pad = PadDetector::new(config.pad).map_err(|_| MissionConfigError::PadDetector)?;
        self.config = config;
        self.avoidance = avoidance;
        self.pad = pad;
        Ok(())
    }

    /// The tuning in force.
    pub fn config(&self) -> &MissionConfig {
        &self.config
    }

    /// The `mission.state` code right now.
    pub fn state(&self) -> MissionState {
        match self.phase {
            Phase::Idle => MissionState::Idle,
            Phase::Preflight => MissionState::Preflight,
            Phase::HoverHold { .. } => MissionState::HoverHold,
            Phase::Land { .. } if self.leg == Leg::Hover => MissionState::HoverLand,
            Phase::ExploreLook { .. } => MissionState::ExploreLook,
            Phase::Navigate if self.leg == Leg::Explore => MissionState::Explore,
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

    /// A decision the user should hear about on the console (explore turned home for its battery
    /// reserve), once: the firmware's radio task and `cfnav sim --serve` print it.
    pub fn take_note(&mut self) -> Option<MissionNote> {
        self.explorer.note.take()
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
        // An open side is no wall: the planner keeps the geofence from it instead (at least the inflation).
        let fence_cells = libm::ceilf(GEOFENCE_M / CELL_SIZE_M - 1e-3) as u8;
        self.grid.set_open_sides(!params.walls & ALL_WALLS, fence_cells);
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
        self.link_lost_home = false;
        self.blind_descent_until = None;
        self.last_valid_height_m = 0.0;
        self.planner_needs_reset = true;
        self.stats = MissionStats::default();
        self.explorer = explore::Explorer::new();
        self.last_tick = None;
        self.phase = Phase::Preflight;
        self.heading = 0.0;
        self.touchdown = landing::Touchdown::new();
        self.last_map_fix_shift_m = None;
        Ok(())
    }

    /// The estimator's running sum of what its map fixes moved the position (arena x, y, m; see
    /// [`crate::flight::estimator::Diagnostics::map_fix_shift_m`]), given before every tick. A jump since
    /// the previous tick of [`MIN_MAP_FIX_SHIFT_STEP_M`] to [`MAX_MAP_FIX_SHIFT_STEP_M`] moves what the pad
    /// search recorded in the old frame (the detector's edges and estimate, the refinement's centre, the
    /// approach and landing points) with the estimate. Smaller changes are left alone: they are the fixes'
    /// steady pull against the flow's drift, which the records should keep (moving them with every fix
    /// undid that pull: landings 1.77 / 3.96 → 2.72 / 5.79 cm median / p95 on stressed seeds 140–149
    /// in simulation).
    pub fn on_map_fix_shift(&mut self, shift_m: [f32; 2]) {
        let previous = self.last_map_fix_shift_m.replace(shift_m);
        let Some(previous) = previous else { return };
        let (dx, dy) = (shift_m[0] - previous[0], shift_m[1] - previous[1]);
        let step = libm::hypotf(dx, dy);
        if !(MIN_MAP_FIX_SHIFT_STEP_M..=MAX_MAP_FIX_SHIFT_STEP_M).contains(&step) {
            return;
        }
        // (The detector is also fed while navigating near the leg's target, `PAD_LOOKOUT_RADIUS_M`.)
        self.pad.translate(dx, dy);
        match &mut self.phase {
            Phase::Search(Search::Refine { centre, .. }) => {
                centre.0 += dx;
                centre.1 += dy;
            }
            Phase::Approach { x, y, .. } | Phase::Land { x, y } => {
                *x += dx;
                *y += dy;
            }
            _ => {}
        }
    }

    /// Abort (`mission.start = 0` during a mission): land where it is, then end with
    /// [`MissionState::Aborted`]. Does nothing when no mission runs.
    pub fn abort(&mut self, state: &StateEstimate) {
        match self.phase {
            Phase::Idle | Phase::Ended(_) => {}
            Phase::Preflight | Phase::OnPad { .. } => self.phase = Phase::Ended(MissionState::Aborted),
            _ => self.land_where_it_is(state, MissionState::Aborted),
        }
    }

    /// Ends the flight with a landing where the drone is, then `then`, by the one rule every such landing
    /// (abort, battery low, no path, link loss) shares: over a pad it is approaching or descending onto, on
    /// that pad's centre; else on a known pad's centre within [`PAD_SNAP_M`]
    /// ([`Self::pad_snap_landing_point`]); where the leg's pad (goal or home) may lie and is not yet located,
    /// on the nearest floor spot clear of wherever it can be ([`Self::floor_spot_clear_of_pad`]; measured
    /// before: aborts every 0.1 s through the default world's goal search, 81 of 808 touched the pad's side;
    /// a battery running low during a long home search, over the home pad's edge, touched it); else where
    /// it is, moved off any pad edge seen ([`Self::off_pad_edges`]). A moved point is flown to at the
    /// drone's height before the descent.
    fn land_where_it_is(&mut self, state: &StateEstimate, then: MissionState) {
        // Above half the pad's height, the estimator's surface under the drone is a pad's top, not the floor.
        let over_raised_surface = state.surface_height_m > 0.5 * self.pad_height();
        let (x, y) = match self.phase {
            Phase::Approach { x, y, .. } | Phase::Land { x, y } => (x, y),
            Phase::NoPath { x, y, .. } => self.landing_point_near((x, y), over_raised_surface),
            _ => self.landing_point_near((state.position_m[0], state.position_m[1]), over_raised_surface),
        };
        self.phase = Phase::EmergencyLand { x, y, then };
    }

    /// [`Self::land_where_it_is`]'s landing point for a drone at `here` that is not over a pad it was
    /// landing on: a known pad's centre within [`PAD_SNAP_M`], kept as it is (a pad's centre is where the
    /// body is farthest from its rim; moving it off the detector's estimate of that pad, measured, put it
    /// 21 cm from the home pad's centre, across the rim); else where the leg's pad may lie and is not
    /// located, a floor spot clear of anywhere it can be, as a search that gives up lands; else `here`
    /// moved off the pad edges seen.
    fn landing_point_near(&self, here: (f32, f32), over_raised_surface: bool) -> (f32, f32) {
        let snapped = self.pad_snap_landing_point(here);
        if snapped != here {
            snapped
        } else if self.leg_pad_may_lie_under(here) {
            self.floor_spot_clear_of_pad(here, 0)
                .unwrap_or_else(|| self.off_pad_edges(here, over_raised_surface))
        } else {
            self.off_pad_edges(here, over_raised_surface)
        }
    }

    /// The radio link was lost (see [`link_loss`]): apply `policy`. Does nothing when no mission runs or
    /// while it already lands where it is (abort, battery, estimator fault: that landing stays, with its
    /// code). Latched: nothing here is undone when the link comes back.
    pub fn on_link_lost(&mut self, policy: link_loss::LinkLossPolicy, now: Micros, state: &StateEstimate) {
        use link_loss::LinkLossPolicy;
        match (policy, self.phase) {
            (LinkLossPolicy::Continue, _) | (_, Phase::Idle | Phase::Ended(_) | Phase::EmergencyLand { .. }) => {}
            // On the ground with the motors off: it has landed already.
            (LinkLossPolicy::Land, Phase::Preflight | Phase::OnPad { .. }) => {
                self.phase = Phase::Ended(MissionState::LinkLost)
            }
            // Over a pad (approaching or descending onto it): finish on its centre; near a known pad, on
            // that pad's centre; else where it is.
            (LinkLossPolicy::Land, _) => self.land_where_it_is(state, MissionState::LinkLost),
            // Still standing on the home pad.
            (LinkLossPolicy::ReturnHome, Phase::Preflight) => self.phase = Phase::Ended(MissionState::LinkLostHome),
            // On the goal pad, or on the way home already: the mission goes home anyway.
            (LinkLossPolicy::ReturnHome, Phase::OnPad { .. }) => {}
            (LinkLossPolicy::ReturnHome, _) if self.leg == Leg::Return => {}
            // The hover test's home is its take-off point: land there (it never searches a pad).
            (LinkLossPolicy::ReturnHome, _) if self.leg == Leg::Hover => {
                self.link_lost_home = true;
                match self.phase {
                    Phase::TakeOff { x, y, .. } | Phase::HoverHold { x, y, .. } => self.phase = Phase::Land { x, y },
                    _ => {}
                }
            }
            (LinkLossPolicy::ReturnHome, _) => {
                // Turn back where it is: the return leg climbs to the cruise height if it was lower (over the
                // goal pad), plans home on the map built so far, searches the home pad and lands on it.
                self.link_lost_home = true;
                self.begin_leg(now, state, Leg::Return);
            }
        }
    }

    /// The Multi-ranger stopped reporting (see [`ranger_watch`]): in the air, land where it is and end with
    /// [`MissionState::RangerLost`]; on a pad with the motors off, end there. Does nothing when no mission
    /// runs or while it already lands where it is (that landing keeps its code).
    pub fn on_ranger_lost(&mut self, state: &StateEstimate) {
        match self.phase {
            Phase::Idle | Phase::Ended(_) | Phase::EmergencyLand { .. } => {}
            Phase::Preflight | Phase::OnPad { .. } => self.phase = Phase::Ended(MissionState::RangerLost),
            _ => self.land_where_it_is(state, MissionState::RangerLost),
        }
    }

    /// Whether the estimate `(x, y)` lies beyond an open side of the arena (past its edge: the planner
    /// keeps [`GEOFENCE_M`] inside it, so only a drift or an avoidance push gets there).
    fn beyond_open_side(&self, x: f32, y: f32) -> bool {
        let (w, h) = self.params.arena_m;
        let open = |bit: u8| self.params.walls & bit == 0;
        (open(WALL_WEST) && x < 0.0)
            || (open(WALL_EAST) && x > w)
            || (open(WALL_SOUTH) && y < 0.0)
            || (open(WALL_NORTH) && y > h)
    }

    /// Whether the pad this leg flies to, not yet located, may lie under a drone at `p`: within
    /// [`search::PAD_REACH_M`] of the leg's nominal point (the goal pad lies within 0.35 m of the nominal
    /// goal, the home pad within 0.35 m of the take-off point, which need not be on it).
    fn leg_pad_may_lie_under(&self, p: (f32, f32)) -> bool {
        let nominal = match self.leg {
            Leg::Outbound | Leg::Return => self.leg_target(),
            Leg::Hover | Leg::Explore => return false,
        };
        self.stats.pad_centres[self.leg_index()].is_none()
            && libm::hypotf(p.0 - nominal.0, p.1 - nominal.1) < search::PAD_REACH_M
    }

    /// Where a landing where the drone is goes down: where it is, unless that lies within
    /// [`PAD_SNAP_M`] of a pad whose centre the mission knows (the home pad at the start point, a pad
    /// once locked): a drone coming down across a pad's edge lands tilted on its rim (measured: lost
    /// 2 s after take-off, 15 cm from the home pad's centre, the body touched the pad's side), so it lands on
    /// that pad's centre instead.
    fn pad_snap_landing_point(&self, (x, y): (f32, f32)) -> (f32, f32) {
        let [goal, home] = self.stats.pad_centres;
        let pads = [Some(self.params.start_m), goal, home];
        pads.into_iter()
            .flatten()
            .map(|p| (p, libm::hypotf(p.0 - x, p.1 - y)))
            .filter(|(_, d)| *d < PAD_SNAP_M)
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or((x, y), |(p, _)| p)
    }

    /// A landing point moved off a pad being searched for (not yet locked, so [`Self::pad_snap_landing_point`]
    /// cannot put it on the centre): a body coming down across a pad's rim touches its side (measured: an
    /// abort 3 cm beside the goal pad's edge during its search, the edge just crossed and not yet reported).
    /// Without a pad estimate but with an entry edge as the last one seen, closer than the pad's diagonal
    /// with the body and a margin: first back behind that edge along the line from the drone when over a
    /// raised surface (the floor flown over before it), else on along that line until that far from the
    /// edge (past the pad it crossed). Then out of the square the pad estimate's centre may cover with the body (half the pad size, the
    /// body radius and [`UNLOCKED_PAD_MARGIN_M`]), across its nearer side; then straight away from any edge
    /// seen within [`search::PAD_EDGE_REACH_M`], up to three times. Kept only if it then clears the square
    /// and every edge, keeps the search's floor-spot clearance from what is mapped and is reachable in a
    /// straight line; else the point is returned unchanged. O(edges) per push.
    fn off_pad_edges(&self, p: (f32, f32), over_raised_surface: bool) -> (f32, f32) {
        let reach = search::PAD_EDGE_REACH_M;
        let nearest = |q: (f32, f32)| {
            self.pad
                .edges()
                .iter()
                .map(|e| ((e.x, e.y), libm::hypotf(q.0 - e.x, q.1 - e.y)))
                .filter(|(_, d)| *d < reach)
                .min_by(|a, b| a.1.total_cmp(&b.1))
        };
        let half = 0.5 * self.config.pad.pad_size_m + BODY_RADIUS_M + UNLOCKED_PAD_MARGIN_M;
        let centre = self.pad.estimate().map(|e| (e.x, e.y));
        let inside =
            |q: (f32, f32)| centre.is_some_and(|c| libm::fabsf(q.0 - c.0) < half && libm::fabsf(q.1 - c.1) < half);
        let mut q = p;
        // The last edge an entry with no exit after it and no pad estimate: nothing tells how far the pad
        // reaches to either side. Over its top still, go back along the line from the drone, behind that
        // edge by its reach (the floor flown over before it). Over the floor, the drone has crossed it
        // (its exit not reported yet) or the edge was false: go on along that line until the whole pad the
        // edge may belong to lies behind (its diagonal, the body and a margin from the edge).
        let past_entry = core::f32::consts::SQRT_2 * self.config.pad.pad_size_m + BODY_RADIUS_M + UNLOCKED_PAD_MARGIN_M;
        if centre.is_none()
            && let Some(enter) = self.pad.edges().last().filter(|e| e.kind == EdgeKind::Enter)
        {
            let (dx, dy) = (q.0 - enter.x, q.1 - enter.y);
            let d = libm::hypotf(dx, dy);
            if d > 1e-3 && d < past_entry {
                let to = if over_raised_surface {
                    -(reach + 0.001)
                } else {
                    past_entry + 0.001
                };
                q = (enter.x + dx * to / d, enter.y + dy * to / d);
            }
        }
        if let Some(c) = centre
            && inside(q)
        {
            // A millimetre past the bound, so the pushed point is not "inside" it by rounding.
            let (dx, dy) = (q.0 - c.0, q.1 - c.1);
            if libm::fabsf(dx) >= libm::fabsf(dy) {
                q.0 = c.0 + libm::copysignf(half + 0.001, dx);
            } else {
                q.1 = c.1 + libm::copysignf(half + 0.001, dy);
            }
        }
        for _ in 0..3 {
            let Some((e, d)) = nearest(q) else {
                break;
            };
            if d <= 1e-3 {
                return p;
            }
            let to = reach + 0.001;
            q = (e.0 + (q.0 - e.0) * to / d, e.1 + (q.1 - e.1) * to / d);
        }
        if q != p
            && (inside(q)
                || nearest(q).is_some()
                || self.clearance(q) < search::FLOOR_SPOT_CLEARANCE_M
                || self.clip_to_clearance(p, q) != q)
        {
            return p;
        }
        q
    }

    /// The readings the reactive layer sees: each beam's range, shortened to where the beam crosses an
    /// open side of the arena (a virtual wall on an edge nothing stands on, so avoidance pushes back from
    /// it as from a wall; within the ranger's 4 m). With every side a wall: the readings as measured.
    pub(crate) fn fenced_ranges(&self, state: &StateEstimate) -> RangerReadings {
        let open = !self.params.walls & ALL_WALLS;
        if open == 0 {
            return self.last_ranges;
        }
        let (x, y) = (state.position_m[0], state.position_m[1]);
        let (w, h) = self.params.arena_m;
        let (sn, cs) = (libm::sinf(state.attitude_rad[2]), libm::cosf(state.attitude_rad[2]));
        let r = &self.last_ranges;
        let mut out = [r.front, r.back, r.left, r.right];
        for (k, (bx, by)) in MultiRangerSample::HORIZONTAL_BEAMS_BODY.iter().enumerate() {
            let u = (cs * bx - sn * by, sn * bx + cs * by);
            let mut edge = f32::INFINITY;
            if open & WALL_EAST != 0 && u.0 > 1e-3 {
                edge = edge.min((w - x) / u.0);
            }
            if open & WALL_WEST != 0 && u.0 < -1e-3 {
                edge = edge.min(-x / u.0);
            }
            if open & WALL_NORTH != 0 && u.1 > 1e-3 {
                edge = edge.min((h - y) / u.1);
            }
            if open & WALL_SOUTH != 0 && u.1 < -1e-3 {
                edge = edge.min(-y / u.1);
            }
            if edge.is_finite() && edge <= FENCE_RANGE_M {
                let edge = edge.max(0.0);
                out[k] = Some(out[k].map_or(edge, |m| m.min(edge)));
            }
        }
        RangerReadings::new(out[0], out[1], out[2], out[3])
    }

    /// A Multi-ranger reading (10 Hz): map it while flying, keep it for avoidance.
    pub fn on_ranges(&mut self, ranges: &MultiRangerSample, state: &StateEstimate) {
        self.last_ranges = RangerReadings::new(ranges.front_m, ranges.back_m, ranges.left_m, ranges.right_m);
        self.blind_look.on_ranges(ranges);
        let airborne = matches!(
            self.phase,
            Phase::TakeOff { .. }
                | Phase::Navigate
                | Phase::NoPath { .. }
                | Phase::Search(_)
                | Phase::Approach { .. }
                | Phase::HoverHold { .. }
                | Phase::ExploreLook { .. }
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
            && matches!(self.leg, Leg::Outbound | Leg::Return)
            && libm::hypotf(state.position_m[0] - tx, state.position_m[1] - ty) < PAD_LOOKOUT_RADIUS_M;
        let searching = near_target || matches!(self.phase, Phase::Search(_) | Phase::Approach { .. });
        if let (true, Some(r)) = (searching, range) {
            let down = body_to_arena([0.0, 0.0, -1.0], state.attitude_rad);
            let (sx, sy) = (state.position_m[0] + r * down[0], state.position_m[1] + r * down[1]);
            if sx.is_finite() && sy.is_finite() {
                self.pad.update(r, sx, sy);
                if let Some(e) = self.pad.estimate() {
                    self.touchdown.note_estimate((e.x, e.y));
                }
            }
        }
        if let (true, Some(r)) = (matches!(self.phase, Phase::Approach { .. } | Phase::Land { .. }), range) {
            self.touchdown_reading(r, -body_to_arena([0.0, 0.0, -1.0], state.attitude_rad)[2], state);
        }
    }

    /// One mission step (20–50 Hz): returns the setpoint to fly. In debug builds it checks that the state
    /// reached is one of the mode's ([`mode_states`]).
    pub fn tick(&mut self, now: Micros, state: &StateEstimate, inputs: &MissionInputs) -> Setpoint {
        let setpoint = self.step(now, state, inputs);
        debug_assert!(
            mode_states::may_reach(self.params.mode, self.state()),
            "mode {:?} reached state {:?}",
            self.params.mode,
            self.state()
        );
        setpoint
    }

    fn step(&mut self, now: Micros, state: &StateEstimate, inputs: &MissionInputs) -> Setpoint {
        let dt_s = match self.last_tick {
            Some(t) if now > t => ((now - t) as f32 * 1e-6).min(0.2),
            _ => 0.02,
        };
        self.last_tick = Some(now);
        let (x, y, z) = (state.position_m[0], state.position_m[1], state.position_m[2]);
        if self.leg == Leg::Explore && self.is_running() {
            self.explore_battery(now, state, inputs);
        }

        // Conditions that end or divert any flying phase.
        if self.is_running() && !matches!(self.phase, Phase::Preflight | Phase::OnPad { .. }) {
            if inputs.crashed {
                self.phase = Phase::Ended(MissionState::Crashed);
                return Setpoint::Stop;
            }
            if state.valid {
                self.last_valid_height_m = state.position_m[2] - state.surface_height_m;
            }
            if !state.valid && !matches!(self.phase, Phase::EmergencyLand { .. }) {
                // Without a usable estimate nothing can be flown safely; descend blind at the last known spot
                // and let the supervisor's touchdown stop the motors, or the time bound below when the
                // touchdown cannot be seen (no height reading: the whole Flow deck lost).
                self.phase = Phase::EmergencyLand {
                    x,
                    y,
                    then: MissionState::EstimatorFault,
                };
                self.blind_descent_until = Some(now.saturating_add(self.blind_descent_bound_us()));
            } else if inputs.battery_low && !matches!(self.phase, Phase::EmergencyLand { .. } | Phase::Land { .. }) {
                self.land_where_it_is(state, MissionState::BatteryLow);
            } else if self.beyond_open_side(x, y)
                && !matches!(self.phase, Phase::EmergencyLand { .. } | Phase::Land { .. })
            {
                self.land_where_it_is(state, MissionState::LeftArena);
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
                let first = match self.params.mode {
                    MissionMode::RoundTrip => Leg::Outbound,
                    MissionMode::HoverTest => Leg::Hover,
                    MissionMode::Explore => Leg::Explore,
                };
                self.begin_leg(now, state, first)
            }
            Phase::TakeOff {
                x: tx,
                y: ty,
                z_target,
                hop_until_m,
            } => {
                // The hover test and the exploration start at the cruise height: the hold is measured there,
                // and the first look around must map (beams map only near the cruise height).
                if matches!(self.leg, Leg::Hover | Leg::Explore) && z >= self.params.height_m - MODE_HANDOVER_BELOW_M {
                    return match self.leg {
                        Leg::Hover => self.begin_hover_hold(now, (tx, ty)),
                        _ => self.begin_explore_look(now, state),
                    };
                }
                // Navigation takes over once the drone is safely above the minimum height: its setpoints
                // carry the cruise height, so the last part of the climb overlaps the first metres of travel.
                if !matches!(self.leg, Leg::Hover | Leg::Explore)
                    && z >= (self.params.height_m - 0.05).min(MIN_HEIGHT_M + TAKEOFF_HANDOVER_MARGIN_M)
                {
                    self.phase = Phase::Navigate;
                    self.avoidance.reset();
                    return self.navigate(now, state, dt_s);
                }
                // The lift-off: the first centimetres are climbed fast. Until flow and ranges settle the drone
                // tilts by its attitude reference's error (the accelerometer's bias, the floor's slope: a few
                // tenths of a degree), which moves it sideways by ~½·g·tilt·t²; a start beside a pad's side is
                // clear of it only while that stays below a few millimetres.
                if z < hop_until_m && z < self.params.height_m {
                    self.phase = Phase::TakeOff {
                        x: tx,
                        y: ty,
                        z_target: z.max(z_target),
                        hop_until_m,
                    };
                    return Setpoint::Descend {
                        x_m: tx,
                        y_m: ty,
                        vz_m_s: navigate::TAKE_OFF_HOP_SPEED_M_S,
                        yaw_rad: self.heading,
                    };
                }
                let target = (z_target + self.config.climb_speed_m_s * dt_s).min(self.params.height_m);
                self.phase = Phase::TakeOff {
                    x: tx,
                    y: ty,
                    z_target: target,
                    hop_until_m,
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
                    self.land_where_it_is(state, MissionState::NoPath);
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
            Phase::HoverHold { x: hx, y: hy, since } => self.hover_hold(now, state, (hx, hy), since),
            Phase::ExploreLook {
                x: hx,
                y: hy,
                since,
                heading_start,
                scanning,
            } => self.explore_look(now, state, (hx, hy), since, heading_start, scanning),
            Phase::Approach {
                x: px,
                y: py,
                settled_since,
            } => self.approach(now, state, (px, py), settled_since),
            Phase::Land { x: px, y: py } => self.land(state, inputs, (px, py), now),
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
                // The supervisor never counts a touchdown on an invalid estimate, so a descent that stays
                // blind would keep the motors turning on the floor: after the time the descent can take,
                // stop them (the drone is down or within a few cm of it).
                if then == MissionState::EstimatorFault
                    && !state.valid
                    && self.blind_descent_until.is_some_and(|t| now >= t)
                {
                    self.phase = Phase::Ended(then);
                    return Setpoint::Stop;
                }
                // A landing point moved away from where the drone was (off a pad's rim, onto a known pad's
                // centre) is flown to at the height the drone has, then descended onto: a descent on the
                // way would cross a pad's rim low, where its side can be touched.
                let err = libm::hypotf(lx - x, ly - y);
                if state.valid && err > EMERGENCY_MOVE_TOLERANCE_M && z - state.surface_height_m > 0.15 {
                    return self.velocity_towards(state, (lx, ly), EMERGENCY_MOVE_TOLERANCE_M, z);
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
            Leg::Outbound | Leg::Hover | Leg::Explore => outbound,
            Leg::Return => back,
        }
    }

    fn leg_index(&self) -> usize {
        match self.leg {
            Leg::Outbound | Leg::Hover | Leg::Explore => 0,
            Leg::Return => 1,
        }
    }
}
