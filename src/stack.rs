//! The firmware's step functions: estimator, supervisor, controller and mission wired together exactly as
//! the MCU runs them. The simulator calls the same functions at the same rates, so what flies in SITL is
//! what flies on the drone.
//!
//! The stack is two objects that never share a reference, only small `Copy` messages:
//!
//! * [`Stabilizer`], the fast part: estimator, supervisor, controller, the setpoint in force and the sensor
//!   updates that feed the estimator. On the MCU it is owned by the interrupt-priority executor and runs at
//!   the gyro's data-ready rate; it must never wait for the mission.
//! * [`Navigator`], the slow part: the mission (map, planner, pad detector) and the deck check. On the MCU it
//!   is owned by the thread-mode task, where a planner slice may take milliseconds.
//!
//! Messages: the stabilizer publishes a [`FastStatus`] (estimate, supervisor verdict, whether the motors are
//! stopped, when the commander last spoke: ~120 bytes) for the navigator; the navigator answers with a
//! [`MissionCommand`] (a setpoint, "a mission started here", or a sweep's map fixes). On the MCU each side copies a message in or
//! out under a critical section of a few microseconds; here [`FlightCore`] hands them over directly.
//!
//! [`FlightCore`] is that composition for the simulator and the tests:
//!
//! | call | rate | does |
//! |---|---|---|
//! | [`FlightCore::on_imu`] | 1 kHz (gyro data-ready) | estimator prediction, supervisor, controller → motor duties |
//! | [`FlightCore::on_flow`] | 100 Hz | estimator flow update |
//! | [`FlightCore::on_zrange`] | 40 Hz | estimator height update, pad detector |
//! | [`FlightCore::on_multiranger`] | 10 Hz | wall anchors while holding a place, map fixes (cast, then mapped), avoidance input |
//! | [`FlightCore::on_battery`] | 100 Hz | battery voltage |
//! | [`FlightCore::mission_tick`] | 50 Hz | mission state machine → setpoint (bounded planner slice) |
//!
//! On the MCU the first, second and fifth run in the interrupt-priority executor (control must never wait),
//! the height update too, which then forwards the reading with the new estimate to the navigator; the
//! Multi-ranger reading and the mission tick run in thread mode, so a long planner slice delays only the
//! next mission tick.
//!
//! Non-goals: drivers, radio, timing (the caller owns the clock and passes `now`), locking (the caller picks
//! how messages cross between priorities).
//! Memory: the navigator's mission dominates (grid + planner, see [`crate::mission`]); the stabilizer is
//! under 2 KB; a [`FastStatus`] is about 120 bytes, a [`MissionCommand`] about 100 (the map fixes of a
//! sweep, four of 24 bytes; before them about 40). The navigator's map-fix landmarks take 48 × 16 bytes.

use crate::drivers::vl53l1x::RangingConfig;
use crate::flight::control::{ControlOutput, Controller, ControllerConfig};
use crate::flight::estimator::map_fix::{CONFIRMED_LOG_ODDS, Landmarks, MapFixes, RayGrid, cast_fixes};
use crate::flight::estimator::{Estimator, EstimatorConfig};
use crate::flight::high_level::{HighLevel, HlCommand, HlPhase, HlRefusal};
use crate::flight::supervisor::{
    Supervisor, SupervisorConfig, SupervisorInput, SupervisorOutput, SupervisorState, clamp_min_height,
};
use crate::mission::link_loss::{LinkLossConfig, LinkWatch};
use crate::mission::ranger_watch::RangerWatch;
use crate::mission::{
    Mission, MissionConfig, MissionInputs, MissionNote, MissionPadDetector, MissionParams, MissionState,
    PositionRefusal, StartRefusal, start,
};
use crate::nav::avoidance::ReactiveAvoidance;
use crate::nav::map::{CELL_SIZE_M, Cell};
use crate::types::{
    FlowSample, ImuSample, Micros, MotorDuty, MultiRangerSample, RangeReading, Setpoint, StateEstimate,
};

/// Wall anchors are used only while the vertical speed is below this, m/s: a climbing or descending beam
/// passes the tops of boxes, and its range jumps.
const HOLD_MAX_CLIMB_M_S: f32 = 0.15;

/// How long commander setpoints keep the idle mission from writing its own (the supervisor's 2 s shutdown
/// timeout, stock `commander.h` `COMMANDER_WDT_TIMEOUT_SHUTDOWN`), µs.
pub const COMMANDER_HOLD_US: Micros = 2_000_000;

/// How long after the last good IMU sample [`Stabilizer::on_imu_missed`] keeps the motors level before
/// it stops them, µs (5 control periods).
pub const IMU_LEVEL_US: Micros = 5_000;

/// How long before its data-ready flag a height reading was measured, µs: half the Flow deck ranger's
/// timing budget (`RangingConfig::integration_midpoint_us`). The navigator's pad detector places a reading
/// at the pose that long ago (plus the read delay on the MCU), not at the current one: 10 ms at 0.5 m/s
/// is 5 mm of pad edge.
pub const ZRANGE_MIDPOINT_US: Micros = RangingConfig::FLOW_DECK_Z.integration_midpoint_us();

/// The same for a Multi-ranger beam, µs (half its 50 ms budget): a sweep is mapped and cast for map fixes
/// from the pose that long ago. Placed at the current pose instead, a beam's return lands 1.25 cm ahead at
/// 0.5 m/s, and the map fixes pull the estimate back along the travel by as much every sweep. Measured on
/// the default world, seeds 1–6, estimate RMS per mission: 1.1–1.5 cm without any latency, 1.5–2.4 cm with
/// it modelled and not compensated, 1.0–1.7 cm compensated (and the emulated image's pad searches, which
/// never locked with the beams' latency uncompensated, lock: docs/pil.md).
pub const BEAM_MIDPOINT_US: Micros = RangingConfig::MULTI_RANGER.integration_midpoint_us();

/// `us` as seconds.
fn seconds(us: Micros) -> f32 {
    us as f32 * 1e-6
}

/// Why the flight core could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlightConfigError {
    /// The controller's configuration is invalid.
    Controller,
    /// The mission's configuration is invalid.
    Mission,
}

/// Why a high-level command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HighLevelError {
    /// A mission runs: it owns the setpoint.
    MissionRunning,
    /// The trajectory follower refused it (see [`HlRefusal`]).
    Refused(HlRefusal),
}

/// Why a mission start was refused (on top of the mission's own parameter checks).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StartError {
    /// A parameter makes no sense (see [`StartRefusal`]).
    Params(StartRefusal),
    /// The drone is flying (under radio control).
    Flying,
    /// The Flow deck or the Multi-ranger deck is missing or failed.
    DeckMissing,
    /// Where the drone stands does not allow this mode's start ([`crate::mission::start`]).
    Position(PositionRefusal),
}

impl core::fmt::Display for StartError {
    /// The console line's reason (after `mission.start refused: `).
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Params(e) => write!(f, "{e:?}"),
            Self::Flying => f.write_str("the drone is flying"),
            Self::DeckMissing => f.write_str("a deck is missing"),
            Self::Position(e) => write!(f, "{e}"),
        }
    }
}

/// All the tuning of the flight stack.
#[derive(Clone, Copy, Debug, Default)]
pub struct FlightConfig {
    /// Estimator tuning.
    pub estimator: EstimatorConfig,
    /// Controller tuning.
    pub controller: ControllerConfig,
    /// Supervisor rules.
    pub supervisor: SupervisorConfig,
    /// Mission tuning.
    pub mission: MissionConfig,
}

/// What the stabilizer tells the navigator: a snapshot taken after its latest step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FastStatus {
    /// The state estimate.
    pub estimate: StateEstimate,
    /// The supervisor's latest verdict.
    pub supervisor: SupervisorOutput,
    /// The duties written at the latest IMU step were all zero.
    pub motors_stopped: bool,
    /// When the radio commander last sent a setpoint (cleared when a mission starts).
    pub commander_time: Option<Micros>,
    /// What the map-relative fixes have moved the position so far (arena x, y), m
    /// ([`crate::flight::estimator::Diagnostics::map_fix_shift_m`]).
    pub map_fix_shift_m: [f32; 2],
}

/// What the navigator asks of the stabilizer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MissionCommand {
    /// Fly `setpoint`, issued at `time` (its age feeds the supervisor's setpoint watchdog).
    Setpoint {
        /// The setpoint.
        setpoint: Setpoint,
        /// When the mission issued it, µs.
        time: Micros,
    },
    /// A mission started with the drone standing at `start_m` (arena frame, m), or `kalman.resetEstimation`
    /// put it there: anchor the estimator there (a fresh filter on the ground, heading kept) and forget the
    /// commander.
    Started {
        /// The take-off point, arena frame, m.
        start_m: (f32, f32),
    },
    /// The map-relative fixes of a Multi-ranger sweep (module `estimator::map_fix`), cast against the map
    /// as it was before the sweep was written into it.
    MapFixes(MapFixes),
}

/// The fast part: estimator, supervisor and controller, and the setpoint in force. See the module docs.
pub struct Stabilizer {
    estimator: Estimator,
    controller: Controller,
    supervisor: Supervisor,
    setpoint: Setpoint,
    setpoint_time: Option<Micros>,
    last_imu_time: Option<Micros>,
    battery_v: f32,
    last_control: ControlOutput,
    last_supervisor: SupervisorOutput,
    duty: MotorDuty,
    /// When the commander last sent a setpoint.
    commander_time: Option<Micros>,
    /// The high-level commander's trajectory (port 8), in control while active.
    high_level: HighLevel,
}

impl Stabilizer {
    /// A stabilizer at power-on, standing at `start_m` (arena frame) with heading `yaw_rad`.
    pub fn new(config: &FlightConfig, start_m: (f32, f32), yaw_rad: f32) -> Result<Self, FlightConfigError> {
        let mut estimator = Estimator::new(config.estimator);
        estimator.reset([start_m.0, start_m.1, 0.0], yaw_rad);
        Ok(Self {
            estimator,
            controller: Controller::new(config.controller).map_err(|_| FlightConfigError::Controller)?,
            supervisor: Supervisor::new(config.supervisor),
            setpoint: Setpoint::Stop,
            setpoint_time: None,
            last_imu_time: None,
            // No report yet (the nRF's first comes about 1 s after boot): ignored, not 0 V, which the
            // supervisor's 0.5 s critical-voltage rule would latch as a dead battery.
            battery_v: f32::NAN,
            last_control: ControlOutput::default(),
            last_supervisor: SupervisorOutput::default(),
            duty: MotorDuty::default(),
            commander_time: None,
            high_level: HighLevel::new(),
        })
    }

    /// Controller gains and the flow measurement std (tuning parameters), in effect from the next step,
    /// integrators kept. An invalid controller configuration is refused and changes nothing.
    pub fn set_tuning(&mut self, controller: ControllerConfig, flow_std_counts: f32) -> Result<(), FlightConfigError> {
        self.controller
            .set_config(controller)
            .map_err(|_| FlightConfigError::Controller)?;
        self.estimator.set_flow_std(flow_std_counts);
        Ok(())
    }

    /// 1 kHz: a gyro/accelerometer sample. Returns the motor duties to write now (all zero unless the
    /// supervisor allows the motors and a setpoint other than [`Setpoint::Stop`] is in force).
    pub fn on_imu(&mut self, sample: &ImuSample, now: Micros) -> MotorDuty {
        let dt_s = match self.last_imu_time {
            Some(t) if now > t => ((now - t) as f32 * 1e-6).min(0.01),
            _ => 0.001,
        };
        self.last_imu_time = Some(now);
        // The high-level commander keeps its setpoint fresh while it is in control, as stock's planner
        // does: the watchdog then only guards the low-level commander and the mission.
        if let Some(setpoint) = self.high_level.setpoint(now) {
            self.setpoint = setpoint;
            self.setpoint_time = Some(now);
            self.commander_time = Some(now);
        }
        self.estimator.on_imu(sample, dt_s);
        let state = self.estimator.state();

        let age = self.setpoint_time.map(|t| now.saturating_sub(t));
        let verdict = self.supervisor.update(&SupervisorInput {
            now,
            accel_m_s2: sample.accel_m_s2,
            estimate: state,
            thrust_cmd: self.last_control.thrust_cmd,
            setpoint: self.setpoint,
            setpoint_age_us: age,
            battery_v: self.battery_v,
            arm_request: false,
        });
        let setpoint = if verdict.motors_allowed {
            let guarded = self.supervisor.guard_setpoint(self.setpoint);
            if verdict.flying {
                clamp_min_height(guarded, crate::mission::MIN_HEIGHT_M)
            } else {
                guarded
            }
        } else {
            Setpoint::Stop
        };
        // The estimator flies only while thrust is commanded. The supervisor keeps `flying` for 2 s after
        // the motors stop (stock's is-flying window); a drone stopped in the air falls, and its impact is
        // not in the IMU (a crash exceeds the accelerometer's range, or lasts less than a sample), so the
        // estimator must be free to apply its on-the-ground rest update as soon as the drone lies still,
        // or it integrates the fall speed on for those 2 s (−2.8 m/s: z swung to −4 m after a drop from
        // 0.5 m).
        self.estimator.set_flying(verdict.flying && setpoint != Setpoint::Stop);
        let output = self
            .controller
            .update(&setpoint, &state, sample.gyro_rad_s, self.battery_v, now);
        self.duty = if verdict.motors_allowed && setpoint != Setpoint::Stop {
            output.duty
        } else {
            MotorDuty::default()
        };
        self.last_control = output;
        self.last_supervisor = verdict;
        // A high-level landing ends at the touchdown; a crash or a lock ends any trajectory.
        let landed = matches!(verdict.state, SupervisorState::Landed) && self.high_level.phase() == HlPhase::Landing;
        if self.high_level.is_active()
            && (landed || matches!(verdict.state, SupervisorState::Crashed | SupervisorState::Locked))
        {
            self.high_level.disable();
            self.setpoint = Setpoint::Stop;
            self.setpoint_time = Some(now);
        }
        self.duty
    }

    /// The control loop got no IMU sample this period (no data-ready edge, or the read failed or timed
    /// out). Returns the duties to write now: for up to [`IMU_LEVEL_US`] after the last good sample the
    /// four motors get the mean of the last duties (the collective without torque: level, no attitude
    /// loop is possible blind; zero if they were off); after that all zero, and the supervisor latches
    /// Crashed if it was flying ([`Supervisor::imu_lost`]). A good sample resumes normal steps
    /// (except from Crashed, which stays until reset).
    pub fn on_imu_missed(&mut self, now: Micros) -> MotorDuty {
        let within = self
            .last_imu_time
            .is_some_and(|t| now.saturating_sub(t) <= IMU_LEVEL_US);
        let running = self.duty != MotorDuty::default();
        self.duty = if !within {
            self.last_supervisor = self.supervisor.imu_lost();
            self.estimator.set_flying(false);
            MotorDuty::default()
        } else if running && self.last_supervisor.motors_allowed {
            let sum: u32 = self.duty.0.iter().map(|&d| u32::from(d)).sum();
            let mean = u8::try_from(sum.div_ceil(4)).unwrap_or(u8::MAX);
            MotorDuty([mean; 4])
        } else {
            MotorDuty::default()
        };
        self.duty
    }

    /// 100 Hz: an optical-flow sample.
    pub fn on_flow(&mut self, sample: &FlowSample) {
        self.estimator.on_flow(sample);
    }

    /// 40 Hz: a downward-range sample. Returns the estimate after the update (the navigator's pad detector
    /// wants the reading together with it).
    pub fn on_zrange(&mut self, range: RangeReading) -> StateEstimate {
        self.estimator.on_zrange(range);
        self.estimator.state()
    }

    /// 10 Hz: the Multi-ranger's beams. While the commander holds the drone at a place (a position setpoint
    /// in flight, not climbing or descending) the estimator ties the position to the walls the beams saw
    /// when the hold began (module `estimator::wall_hold`): hovering, the flow-only estimate would wander
    /// ≈ 1 cm/√s. The mission's holds (over a pad before landing) last a second or two, and its landings
    /// measured no better with the anchors in simulation, so a running mission does not use them.
    pub fn on_multiranger(&mut self, sample: &MultiRangerSample) {
        let vz = self.estimator.state().velocity_m_s[2];
        let hold = self.last_supervisor.flying
            && self.commander_time.is_some()
            && vz.abs() < HOLD_MAX_CLIMB_M_S
            && matches!(self.setpoint, Setpoint::Position { .. });
        self.estimator.on_multiranger(sample, hold);
    }

    /// 100 Hz: the battery voltage reported by the power controller, V. Non-finite readings are ignored.
    pub fn on_battery(&mut self, volts: f32) {
        if volts.is_finite() {
            self.battery_v = volts;
        }
    }

    /// A setpoint from the radio commander. The caller checks that no mission runs
    /// ([`Navigator::is_running`]): the stabilizer flies whatever it is given last.
    /// A low-level setpoint outranks the high-level commander (stock priorities), which gives up control.
    pub fn commander_setpoint(&mut self, setpoint: Setpoint, now: Micros) {
        self.high_level.disable();
        self.setpoint = setpoint;
        self.setpoint_time = Some(now);
        self.commander_time = Some(now);
    }

    /// A high-level command (port 8) received at `now`. The caller checks that no mission runs, as for
    /// [`Stabilizer::commander_setpoint`]. A stop cuts the motors at once; a refused command changes nothing.
    pub fn high_level_command(&mut self, command: HlCommand, now: Micros) -> Result<(), HlRefusal> {
        let estimate = self.estimator.state();
        self.high_level.command(command, now, &estimate)?;
        self.commander_time = Some(now);
        self.setpoint_time = Some(now);
        self.setpoint = self.high_level.setpoint(now).unwrap_or(Setpoint::Stop);
        Ok(())
    }

    /// The high-level commander's state.
    pub fn high_level(&self) -> &HighLevel {
        &self.high_level
    }

    /// Applies a message from the navigator.
    pub fn apply(&mut self, command: MissionCommand) {
        match command {
            MissionCommand::Setpoint { setpoint, time } => {
                self.setpoint = setpoint;
                self.setpoint_time = Some(time);
            }
            MissionCommand::Started { start_m } => {
                self.commander_time = None;
                self.high_level.disable();
                // The drone stands at `start_m`: a mission's take-off point (where its estimate already was,
                // or the home pad for a round trip: `mission::start`) or the home pad
                // (`kalman.resetEstimation`).
                let yaw = self.estimator.state().attitude_rad[2];
                self.estimator.reset([start_m.0, start_m.1, 0.0], yaw);
            }
            MissionCommand::MapFixes(fixes) => self.estimator.on_map_fixes(&fixes),
        }
    }

    /// The snapshot the navigator works from.
    pub fn status(&self) -> FastStatus {
        FastStatus {
            estimate: self.estimator.state(),
            supervisor: self.last_supervisor,
            motors_stopped: self.duty == MotorDuty::default(),
            commander_time: self.commander_time,
            map_fix_shift_m: self.estimator.map_fix_shift_m(),
        }
    }

    /// The state estimate.
    pub fn estimate(&self) -> StateEstimate {
        self.estimator.state()
    }

    /// The estimator (diagnostics).
    pub fn estimator(&self) -> &Estimator {
        &self.estimator
    }

    /// The supervisor's latest verdict.
    pub fn supervisor(&self) -> &SupervisorOutput {
        &self.last_supervisor
    }

    /// The controller's latest output.
    pub fn control(&self) -> &ControlOutput {
        &self.last_control
    }

    /// The setpoint in force (the mission's or the commander's), before the supervisor's guard.
    pub fn setpoint(&self) -> Setpoint {
        self.setpoint
    }

    /// The duties written at the latest [`Stabilizer::on_imu`].
    pub fn duty(&self) -> MotorDuty {
        self.duty
    }
}

/// The slow part: the mission and the deck check. See the module docs.
pub struct Navigator<const CELLS: usize, const QUEUE: usize> {
    mission: Mission<CELLS, QUEUE>,
    decks_ok: bool,
    /// The obstacle surfaces the map fixes measure against (module `estimator::map_fix`), per mission.
    landmarks: Landmarks,
    /// Mission tuning written by the radio, in force from the next start.
    next_config: Option<MissionConfig>,
    /// The link-loss watch (`mission.linkLoss`, `mission.linkTimeout`).
    link: LinkWatch,
    /// The Multi-ranger watch (a running mission without sweeps lands).
    rangers: RangerWatch,
    /// The supervisor's battery-low threshold, V (explore's battery reserve counts down to it).
    battery_low_v: f32,
}

impl<const CELLS: usize, const QUEUE: usize> Navigator<CELLS, QUEUE> {
    /// An idle navigator (decks assumed present until told otherwise).
    pub fn new(config: &FlightConfig) -> Result<Self, FlightConfigError> {
        let (avoidance, pad) =
            Mission::<CELLS, QUEUE>::checked_parts(config.mission).map_err(|_| FlightConfigError::Mission)?;
        Ok(Self::from_parts(config, avoidance, pad))
    }

    /// A navigator from the mission's checked parts ([`Mission::checked_parts`]): infallible and returned
    /// directly, so the firmware builds it in place in CCM (see [`Mission::from_parts`]).
    /// Writes a navigator from the mission's checked parts straight into `slot`, field by field (see
    /// [`Mission::init_at`]): how the firmware builds it in CCM without a stack-sized temporary.
    ///
    /// # Safety
    /// `slot` must be valid for writes and aligned for `Self`; its old contents are overwritten without being
    /// dropped. After the call `*slot` is a fully initialised `Self`.
    pub unsafe fn init_at(
        slot: *mut Self,
        config: &FlightConfig,
        avoidance: ReactiveAvoidance,
        pad: MissionPadDetector,
    ) {
        // A field added to `Self` and not written below must not compile: this pattern names every field.
        let _every_field_written = |n: &Self| {
            let Self {
                mission: _,
                decks_ok: _,
                landmarks: _,
                next_config: _,
                link: _,
                rangers: _,
                battery_low_v: _,
            } = n;
        };
        // SAFETY: the caller guarantees `slot` is valid and aligned; `addr_of_mut!` makes no reference to the
        // uninitialised fields; `Mission::init_at` gets the same guarantees for its field, and every field is
        // written exactly once.
        unsafe {
            Mission::init_at(core::ptr::addr_of_mut!((*slot).mission), config.mission, avoidance, pad);
            core::ptr::addr_of_mut!((*slot).decks_ok).write(true);
            core::ptr::addr_of_mut!((*slot).landmarks).write(Landmarks::new());
            core::ptr::addr_of_mut!((*slot).next_config).write(None);
            core::ptr::addr_of_mut!((*slot).link).write(LinkWatch::new());
            core::ptr::addr_of_mut!((*slot).rangers).write(RangerWatch::new());
            core::ptr::addr_of_mut!((*slot).battery_low_v).write(config.supervisor.battery_low_v);
        }
    }

    /// A navigator from the mission's checked parts (see [`Self::init_at`] for the firmware's way).
    pub fn from_parts(config: &FlightConfig, avoidance: ReactiveAvoidance, pad: MissionPadDetector) -> Self {
        Self {
            mission: Mission::from_parts(config.mission, avoidance, pad),
            decks_ok: true,
            landmarks: Landmarks::new(),
            next_config: None,
            link: LinkWatch::new(),
            rangers: RangerWatch::new(),
            battery_low_v: config.supervisor.battery_low_v,
        }
    }

    /// New mission tuning (the tuning parameters): in force from the next start (a running mission keeps
    /// the map inflation and speeds it started with). The latest call before a start wins.
    pub fn set_mission_config(&mut self, config: MissionConfig) {
        self.next_config = Some(config);
    }

    /// Whether both decks (Flow v2, Multi-ranger) are present and working.
    pub fn set_decks_ok(&mut self, ok: bool) {
        self.decks_ok = ok;
    }

    /// Whether both decks were reported present.
    pub fn decks_ok(&self) -> bool {
        self.decks_ok
    }

    /// Starts the mission `params.mode` names, from where the estimate in `status` says the drone stands
    /// ([`start::take_off_point`]: a round trip only from the home pad). Refused while flying (per
    /// `status`) or while a mission runs, without both decks, with parameters that make no sense, or from a
    /// position the mode cannot start from; nothing changes then. On success the returned
    /// [`MissionCommand::Started`] (the take-off point: the estimate's own position, or for a round trip
    /// the home pad's) must reach the stabilizer before the next mission tick.
    pub fn start(&mut self, params: MissionParams, status: &FastStatus) -> Result<MissionCommand, StartError> {
        if status.supervisor.flying || self.mission.is_running() {
            return Err(StartError::Flying);
        }
        if !self.decks_ok {
            return Err(StartError::DeckMissing);
        }
        params.validate(CELLS).map_err(StartError::Params)?;
        let p = status.estimate.position_m;
        let take_off = start::take_off_point(&params, (p[0], p[1])).map_err(StartError::Position)?;
        if let Some(config) = self.next_config.take() {
            // Validated by the parameter store; an invalid one keeps the configuration in force.
            let _ = self.mission.set_config(config);
        }
        self.mission.start(params).map_err(StartError::Params)?;
        self.landmarks.clear();
        Ok(MissionCommand::Started { start_m: take_off })
    }

    /// Abort (`mission.start = 0` during a mission): land where the estimate says the drone is.
    pub fn abort(&mut self, status: &FastStatus) {
        self.mission.abort(&status.estimate);
    }

    /// A downward-range reading with the estimate of the pose it was measured from (pad detector,
    /// touchdown votes): the stabilizer's estimate after it used the reading, backdated by the reading's
    /// age ([`StateEstimate::backdated`], [`ZRANGE_MIDPOINT_US`] plus the read delay).
    pub fn on_zrange(&mut self, range: RangeReading, estimate: &StateEstimate) {
        self.mission.on_zrange(range, estimate);
    }

    /// The Multi-ranger's five beams with the estimate of the pose they were measured from (the current
    /// one backdated by the sweep's age: [`BEAM_MIDPOINT_US`] plus the read delay) for mapping and
    /// avoidance. Returns the sweep's
    /// map-relative fixes for the stabilizer, if any: cast first, against the map as it was, then the sweep
    /// is written (module `estimator::map_fix`). Fixes are cast only while the mission maps (a flying phase
    /// at mapping height, the estimate valid), so the map and the fixes see the same beams.
    pub fn on_multiranger(&mut self, sample: &MultiRangerSample, estimate: &StateEstimate) -> Option<MissionCommand> {
        self.rangers.on_sweep();
        let fixes = self.map_fixes(sample, estimate);
        self.mission.on_ranges(sample, estimate);
        fixes.map(MissionCommand::MapFixes)
    }

    /// Casts the sweep's fixes against the mission's map (see [`Navigator::on_multiranger`]).
    fn map_fixes(&mut self, sample: &MultiRangerSample, estimate: &StateEstimate) -> Option<MapFixes> {
        use MissionState as S;
        let mapping = matches!(
            self.mission.state(),
            S::TakeOffOutbound
                | S::TakeOffReturn
                | S::NavigateToGoal
                | S::NavigateHome
                | S::SearchGoalPad
                | S::SearchHomePad
                | S::ApproachGoalPad
                | S::ApproachHomePad
                | S::NoPathHover
        );
        let params = self.mission.params();
        if !(mapping && estimate.valid && estimate.position_m[2] >= 0.8 * params.height_m) {
            return None;
        }
        let map = self.mission.grid();
        let shape = map.shape();
        let grid = RayGrid {
            width: i32::from(shape.width),
            height: i32::from(shape.height),
            cell_m: CELL_SIZE_M,
            arena_m: params.arena_m,
            walls: params.walls,
        };
        // (The ray cast asks only cells inside the grid.)
        let cell = |x: i32, y: i32| Cell::new(x as u16, y as u16);
        let fixes = cast_fixes(
            &grid,
            sample,
            [estimate.position_m[0], estimate.position_m[1]],
            estimate.attitude_rad[2],
            &mut self.landmarks,
            |x, y| map.log_odds(cell(x, y)) >= CONFIRMED_LOG_ODDS,
            |x, y| shape.contains(x, y) && map.is_occupied(cell(x, y)),
        );
        (!fixes.is_empty()).then_some(fixes)
    }

    /// A radio packet (any port, null packets too) arrived at `now` (the link-loss watch's input).
    pub fn on_radio_packet(&mut self, now: Micros) {
        self.link.on_packet(now);
    }

    /// `mission.linkLoss` and `mission.linkTimeout` (they may change at any time).
    pub fn set_link_loss(&mut self, config: LinkLossConfig) {
        self.link.set_config(config);
    }

    /// The link-loss watch (when the latest packet came, whether and when the timeout fired).
    pub fn link_watch(&self) -> &LinkWatch {
        &self.link
    }

    /// 50 Hz: one mission step (at most one bounded planner slice). Returns the setpoint for the stabilizer,
    /// or `None` while no mission runs and the commander has spoken within [`COMMANDER_HOLD_US`] (the idle
    /// mission must not overwrite the commander's setpoint with Stop). A running mission that has heard no
    /// radio packet for `mission.linkTimeout` gets the link-loss policy first ([`crate::mission::link_loss`]).
    pub fn tick(&mut self, now: Micros, status: &FastStatus) -> Option<MissionCommand> {
        if let Some(policy) = self.link.check(now, self.mission.is_running()) {
            self.mission.on_link_lost(policy, now, &status.estimate);
        }
        if self.rangers.check(now, self.mission.is_running()) {
            self.mission.on_ranger_lost(&status.estimate);
        }
        if !self.mission.is_running()
            && status
                .commander_time
                .is_some_and(|t| now.saturating_sub(t) < COMMANDER_HOLD_US)
        {
            return None;
        }
        let sup = &status.supervisor;
        let inputs = MissionInputs {
            landed: matches!(sup.state, SupervisorState::Landed) || (!sup.flying && status.motors_stopped),
            crashed: matches!(sup.state, SupervisorState::Crashed | SupervisorState::Locked),
            battery_low: sup.battery_low,
            armed: sup.motors_allowed,
            battery_v: sup.battery_v_filtered,
            battery_low_v: self.battery_low_v,
        };
        self.mission.on_map_fix_shift(status.map_fix_shift_m);
        let setpoint = self.mission.tick(now, &status.estimate, &inputs);
        Some(MissionCommand::Setpoint { setpoint, time: now })
    }

    /// Whether a mission runs (commander setpoints are refused then).
    pub fn is_running(&self) -> bool {
        self.mission.is_running()
    }

    /// A decision of the mission the user should hear about on the console, once (see
    /// [`Mission::take_note`]).
    pub fn take_mission_note(&mut self) -> Option<MissionNote> {
        self.mission.take_note()
    }

    /// The mission.
    pub fn mission(&self) -> &Mission<CELLS, QUEUE> {
        &self.mission
    }

    /// The `mission.state` code.
    pub fn state(&self) -> MissionState {
        self.mission.state()
    }
}

/// The stabilizer and the navigator composed on one thread, messages handed over at once: what the
/// simulator flies. See the module documentation.
pub struct FlightCore<const CELLS: usize, const QUEUE: usize> {
    stabilizer: Stabilizer,
    navigator: Navigator<CELLS, QUEUE>,
}

impl<const CELLS: usize, const QUEUE: usize> FlightCore<CELLS, QUEUE> {
    /// A flight stack at power-on, standing at `start_m` (arena frame) with heading `yaw_rad`.
    pub fn new(config: &FlightConfig, start_m: (f32, f32), yaw_rad: f32) -> Result<Self, FlightConfigError> {
        Ok(Self {
            stabilizer: Stabilizer::new(config, start_m, yaw_rad)?,
            navigator: Navigator::new(config)?,
        })
    }

    /// Tell the core whether both decks (Flow v2, Multi-ranger) are present and working.
    pub fn set_decks_ok(&mut self, ok: bool) {
        self.navigator.set_decks_ok(ok);
    }

    /// Start the mission (`mission.start = 1`) from where the drone stands ([`Navigator::start`]). Refused
    /// while flying, without both decks, with parameters that make no sense, or (a round trip) off the home
    /// pad; nothing changes then.
    pub fn start_mission(&mut self, params: MissionParams) -> Result<(), StartError> {
        let command = self.navigator.start(params, &self.stabilizer.status())?;
        self.stabilizer.apply(command);
        Ok(())
    }

    /// `kalman.resetEstimation`: re-anchor the estimate's horizontal position at `xy_m` (arena frame, m),
    /// heading kept, as a mission start does. Ignored while a mission runs.
    pub fn reset_estimate(&mut self, xy_m: (f32, f32)) {
        if !self.navigator.is_running() {
            self.stabilizer.apply(MissionCommand::Started { start_m: xy_m });
        }
    }

    /// The tuning parameters: controller gains and the flow std from the next step (in
    /// flight too, as stock), the mission's tuning from the next start. An invalid controller configuration
    /// is refused and changes nothing.
    pub fn set_tuning(
        &mut self,
        controller: ControllerConfig,
        flow_std_counts: f32,
        mission: MissionConfig,
    ) -> Result<(), FlightConfigError> {
        self.stabilizer.set_tuning(controller, flow_std_counts)?;
        self.navigator.set_mission_config(mission);
        Ok(())
    }

    /// A radio packet arrived at `now` (see [`Navigator::on_radio_packet`]).
    pub fn on_radio_packet(&mut self, now: Micros) {
        self.navigator.on_radio_packet(now);
    }

    /// `mission.linkLoss` and `mission.linkTimeout` (see [`Navigator::set_link_loss`]).
    pub fn set_link_loss(&mut self, config: LinkLossConfig) {
        self.navigator.set_link_loss(config);
    }

    /// Abort (`mission.start = 0` during a mission): land where it is.
    pub fn abort_mission(&mut self) {
        self.navigator.abort(&self.stabilizer.status());
    }

    /// 1 kHz: a gyro/accelerometer sample. Returns the motor duties to write now.
    pub fn on_imu(&mut self, sample: &ImuSample, now: Micros) -> MotorDuty {
        self.stabilizer.on_imu(sample, now)
    }

    /// 100 Hz: an optical-flow sample.
    pub fn on_flow(&mut self, sample: &FlowSample) {
        self.stabilizer.on_flow(sample);
    }

    /// 40 Hz: a downward-range sample, handed over at its data-ready flag (measured
    /// [`ZRANGE_MIDPOINT_US`] earlier, as the simulator models it).
    pub fn on_zrange(&mut self, range: RangeReading) {
        let estimate = self.stabilizer.on_zrange(range).backdated(seconds(ZRANGE_MIDPOINT_US));
        self.navigator.on_zrange(range, &estimate);
    }

    /// 10 Hz: the Multi-ranger's five beams, handed over at their data-ready flags (measured
    /// [`BEAM_MIDPOINT_US`] earlier); the sweep's map fixes go to the stabilizer at once.
    pub fn on_multiranger(&mut self, sample: &MultiRangerSample) {
        self.stabilizer.on_multiranger(sample);
        let estimate = self.stabilizer.estimate().backdated(seconds(BEAM_MIDPOINT_US));
        if let Some(command) = self.navigator.on_multiranger(sample, &estimate) {
            self.stabilizer.apply(command);
        }
    }

    /// 100 Hz: the battery voltage reported by the power controller, V.
    pub fn on_battery(&mut self, volts: f32) {
        self.stabilizer.on_battery(volts);
    }

    /// A setpoint from outside the mission (the radio commander, or a test script). Flown only while no
    /// mission runs; like the stock commander it must keep coming, or the supervisor's setpoint timeout
    /// levels out and then stops the motors.
    pub fn commander_setpoint(&mut self, setpoint: Setpoint, now: Micros) {
        if !self.navigator.is_running() {
            self.stabilizer.commander_setpoint(setpoint, now);
        }
    }

    /// A high-level command (port 8): refused while a mission runs, or when the trajectory follower
    /// refuses it (nothing changes then).
    pub fn high_level_command(&mut self, command: HlCommand, now: Micros) -> Result<(), HighLevelError> {
        if self.navigator.is_running() {
            return Err(HighLevelError::MissionRunning);
        }
        self.stabilizer
            .high_level_command(command, now)
            .map_err(HighLevelError::Refused)
    }

    /// 50 Hz: one mission step; its setpoint is flown by the next [`FlightCore::on_imu`] calls. Does
    /// nothing while no mission runs and the commander flies (the commander's setpoint stays in force).
    pub fn mission_tick(&mut self, now: Micros) {
        if let Some(command) = self.navigator.tick(now, &self.stabilizer.status()) {
            self.stabilizer.apply(command);
        }
    }

    /// The state estimate.
    pub fn estimate(&self) -> StateEstimate {
        self.stabilizer.estimate()
    }

    /// The mission.
    pub fn mission(&self) -> &Mission<CELLS, QUEUE> {
        self.navigator.mission()
    }

    /// The `mission.state` code.
    pub fn mission_state(&self) -> MissionState {
        self.navigator.state()
    }

    /// A decision of the mission for the console, once ([`Navigator::take_mission_note`]).
    pub fn take_mission_note(&mut self) -> Option<MissionNote> {
        self.navigator.take_mission_note()
    }

    /// The estimator (diagnostics).
    pub fn estimator(&self) -> &Estimator {
        self.stabilizer.estimator()
    }

    /// The supervisor's latest verdict.
    pub fn supervisor(&self) -> &SupervisorOutput {
        self.stabilizer.supervisor()
    }

    /// The controller's latest output.
    pub fn control(&self) -> &ControlOutput {
        self.stabilizer.control()
    }

    /// The setpoint the mission asks for.
    pub fn setpoint(&self) -> Setpoint {
        self.stabilizer.setpoint()
    }

    /// The duties written at the latest [`FlightCore::on_imu`].
    pub fn duty(&self) -> MotorDuty {
        self.stabilizer.duty()
    }

    /// The fast part (the firmware runs it on its own in the control executor).
    pub fn stabilizer(&self) -> &Stabilizer {
        &self.stabilizer
    }

    /// The slow part (the firmware runs it on its own in thread mode).
    pub fn navigator(&self) -> &Navigator<CELLS, QUEUE> {
        &self.navigator
    }
}
