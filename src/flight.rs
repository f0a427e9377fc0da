//! The firmware's step functions: estimator, supervisor, controller and mission wired together exactly as
//! the MCU runs them. The simulator calls the same functions at the same rates, so what flies in SITL is
//! what flies on the drone.
//!
//! | call | rate | does |
//! |---|---|---|
//! | [`FlightCore::on_imu`] | 1 kHz (gyro data-ready) | estimator prediction, supervisor, controller → motor duties |
//! | [`FlightCore::on_flow`] | 100 Hz | estimator flow update |
//! | [`FlightCore::on_zrange`] | 40 Hz | estimator height update, pad detector |
//! | [`FlightCore::on_multiranger`] | 10 Hz | mapping, avoidance input |
//! | [`FlightCore::on_battery`] | 100 Hz | battery voltage |
//! | [`FlightCore::mission_tick`] | 50 Hz | mission state machine → setpoint (bounded planner slice) |
//!
//! On the MCU the first four run in the interrupt-priority executor (control must never wait), the mission
//! tick in thread mode, so a long planner slice delays only the next mission tick.
//!
//! Non-goals: drivers, radio, timing (the caller owns the clock and passes `now`).
//! Memory: the mission dominates (grid + planner, see [`crate::mission`]); the rest is under 2 KB.

use crate::control::{ControlOutput, Controller, ControllerConfig};
use crate::estimator::{Estimator, EstimatorConfig};
use crate::mission::{Mission, MissionConfig, MissionInputs, MissionParams, MissionState, StartRefusal};
use crate::supervisor::{
    Supervisor, SupervisorConfig, SupervisorInput, SupervisorOutput, SupervisorState, clamp_min_height,
};
use crate::types::{
    FlowSample, ImuSample, Micros, MotorDuty, MultiRangerSample, RangeReading, Setpoint, StateEstimate,
};

/// Why the flight core could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlightConfigError {
    /// The controller's configuration is invalid.
    Controller,
    /// The mission's configuration is invalid.
    Mission,
}

/// Why a mission start was refused (on top of the mission's own parameter checks).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StartError {
    /// A parameter makes no sense (see [`StartRefusal`]).
    Params(StartRefusal),
    /// The drone is flying (under radio control).
    Flying,
    /// The Flow deck or the Multi-ranger deck is missing or failed.
    DeckMissing,
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

/// See the module documentation.
pub struct FlightCore<const CELLS: usize, const QUEUE: usize> {
    estimator: Estimator,
    controller: Controller,
    supervisor: Supervisor,
    mission: Mission<CELLS, QUEUE>,
    mission_setpoint: Setpoint,
    mission_setpoint_time: Option<Micros>,
    last_imu: ImuSample,
    last_imu_time: Option<Micros>,
    battery_v: f32,
    last_control: ControlOutput,
    last_supervisor: SupervisorOutput,
    duty: MotorDuty,
    decks_ok: bool,
    /// When the commander last sent a setpoint.
    commander_time: Option<Micros>,
}

impl<const CELLS: usize, const QUEUE: usize> FlightCore<CELLS, QUEUE> {
    /// A flight stack at power-on, standing at `start_m` (arena frame) with heading `yaw_rad`.
    pub fn new(config: &FlightConfig, start_m: (f32, f32), yaw_rad: f32) -> Result<Self, FlightConfigError> {
        let mut estimator = Estimator::new(config.estimator);
        estimator.reset([start_m.0, start_m.1, 0.0], yaw_rad);
        Ok(Self {
            estimator,
            controller: Controller::new(config.controller).map_err(|_| FlightConfigError::Controller)?,
            supervisor: Supervisor::new(config.supervisor),
            mission: Mission::new(config.mission).map_err(|_| FlightConfigError::Mission)?,
            mission_setpoint: Setpoint::Stop,
            mission_setpoint_time: None,
            last_imu: ImuSample::default(),
            last_imu_time: None,
            battery_v: 0.0,
            last_control: ControlOutput::default(),
            last_supervisor: SupervisorOutput::default(),
            duty: MotorDuty::default(),
            decks_ok: true,
            commander_time: None,
        })
    }

    /// Tell the core whether both decks (Flow v2, Multi-ranger) are present and working.
    pub fn set_decks_ok(&mut self, ok: bool) {
        self.decks_ok = ok;
    }

    /// Start the round-trip mission (`mission.start = 1`). Refused while flying, without both decks, or
    /// with parameters that make no sense; nothing changes then.
    pub fn start_mission(&mut self, params: MissionParams) -> Result<(), StartError> {
        if self.last_supervisor.flying || self.mission.is_running() {
            return Err(StartError::Flying);
        }
        if !self.decks_ok {
            return Err(StartError::DeckMissing);
        }
        self.mission.start(params).map_err(StartError::Params)?;
        self.commander_time = None;
        // The drone stands where the parameters say: that is the arena frame's anchor for the flight.
        let yaw = self.estimator.state().attitude_rad[2];
        self.estimator.reset([params.start_m.0, params.start_m.1, 0.0], yaw);
        Ok(())
    }

    /// Abort (`mission.start = 0` during a mission): land where it is.
    pub fn abort_mission(&mut self) {
        let state = self.estimator.state();
        self.mission.abort(&state);
    }

    /// 1 kHz: a gyro/accelerometer sample. Returns the motor duties to write now.
    pub fn on_imu(&mut self, sample: &ImuSample, now: Micros) -> MotorDuty {
        let dt_s = match self.last_imu_time {
            Some(t) if now > t => ((now - t) as f32 * 1e-6).min(0.01),
            _ => 0.001,
        };
        self.last_imu_time = Some(now);
        self.last_imu = *sample;
        self.estimator.on_imu(sample, dt_s);
        let state = self.estimator.state();

        let age = self.mission_setpoint_time.map(|t| now.saturating_sub(t));
        let verdict = self.supervisor.update(&SupervisorInput {
            now,
            accel_m_s2: sample.accel_m_s2,
            estimate: state,
            thrust_cmd: self.last_control.thrust_cmd,
            setpoint: self.mission_setpoint,
            setpoint_age_us: age,
            battery_v: self.battery_v,
            arm_request: false,
        });
        self.estimator.set_flying(verdict.flying);
        let setpoint = if verdict.motors_allowed {
            let guarded = self.supervisor.guard_setpoint(self.mission_setpoint);
            if verdict.flying {
                clamp_min_height(guarded, crate::mission::MIN_HEIGHT_M)
            } else {
                guarded
            }
        } else {
            Setpoint::Stop
        };
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
        self.duty
    }

    /// 100 Hz: an optical-flow sample.
    pub fn on_flow(&mut self, sample: &FlowSample) {
        self.estimator.on_flow(sample);
    }

    /// 40 Hz: a downward-range sample.
    pub fn on_zrange(&mut self, range: RangeReading) {
        self.estimator.on_zrange(range);
        let state = self.estimator.state();
        self.mission.on_zrange(range, &state);
    }

    /// 10 Hz: the Multi-ranger's five beams.
    pub fn on_multiranger(&mut self, sample: &MultiRangerSample) {
        let state = self.estimator.state();
        self.mission.on_ranges(sample, &state);
    }

    /// 100 Hz: the battery voltage reported by the power controller, V.
    pub fn on_battery(&mut self, volts: f32) {
        if volts.is_finite() {
            self.battery_v = volts;
        }
    }

    /// A setpoint from outside the mission (the radio commander, or a test script). Flown only while no
    /// mission runs; like the stock commander it must keep coming, or the supervisor's setpoint timeout
    /// levels out and then stops the motors.
    pub fn commander_setpoint(&mut self, setpoint: Setpoint, now: Micros) {
        if !self.mission.is_running() {
            self.mission_setpoint = setpoint;
            self.mission_setpoint_time = Some(now);
            self.commander_time = Some(now);
        }
    }

    /// 50 Hz: one mission step; its setpoint is flown by the next [`FlightCore::on_imu`] calls. Does
    /// nothing while no mission runs (the commander's setpoint stays in force).
    pub fn mission_tick(&mut self, now: Micros) {
        // While the commander flies (setpoints within the supervisor's 2 s shutdown timeout) the idle
        // mission must not overwrite its setpoint with Stop.
        if !self.mission.is_running() && self.commander_time.is_some_and(|t| now.saturating_sub(t) < 2_000_000) {
            return;
        }
        let state = self.estimator.state();
        let sup = self.last_supervisor.state;
        let inputs = MissionInputs {
            landed: matches!(sup, SupervisorState::Landed)
                || (!self.last_supervisor.flying && self.duty == MotorDuty::default()),
            crashed: matches!(sup, SupervisorState::Crashed | SupervisorState::Locked),
            battery_low: self.last_supervisor.battery_low,
            armed: self.last_supervisor.motors_allowed,
        };
        self.mission_setpoint = self.mission.tick(now, &state, &inputs);
        self.mission_setpoint_time = Some(now);
    }

    /// The state estimate.
    pub fn estimate(&self) -> StateEstimate {
        self.estimator.state()
    }

    /// The mission.
    pub fn mission(&self) -> &Mission<CELLS, QUEUE> {
        &self.mission
    }

    /// The `mission.state` code.
    pub fn mission_state(&self) -> MissionState {
        self.mission.state()
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

    /// The setpoint the mission asks for.
    pub fn setpoint(&self) -> Setpoint {
        self.mission_setpoint
    }

    /// The duties written at the latest [`FlightCore::on_imu`].
    pub fn duty(&self) -> MotorDuty {
        self.duty
    }
}
