//! Cascaded PID flight control: position → velocity → attitude → rate → mixer → battery compensation →
//! motor duty.
//!
//! Job: turn a [`Setpoint`] and the [`StateEstimate`] into the four motor duties, at 1 kHz, with the
//! structure and gains of the stock Crazyflie PID controller (`controller_pid.c`,
//! `position_controller_pid.c`, `attitude_pid_controller.c`, `docs/hardware.md` §3), adapted
//! to cfnav's SI API and right-hand attitude convention.
//!
//! Non-goals: state estimation, deciding whether the motors may run (that is [`crate::flight::supervisor`]),
//! trajectory generation or smoothing of setpoints (the mission's job), rate setpoints (the [`Setpoint`]
//! enum has none; [`Setpoint::Attitude`] is angles and thrust), thrust-vectoring/INDI/Mellinger controllers.
//!
//! # Rates
//! [`Controller::update`] must be called at **1 kHz** (the gyro's data-ready, stock `RATE_MAIN_LOOP`). A
//! tick counter runs, like stock `RATE_DO_EXECUTE`:
//! - the position and velocity loops on every 10th call (**100 Hz**, dt = 10 ms),
//! - the attitude (angle) and rate loops on every 2nd call (**500 Hz**, dt = 2 ms),
//! - the mixer, capping, battery filter and compensation on every call (1 kHz).
//!
//! The first call after [`Controller::new`], [`Controller::reset`] or a [`Setpoint::Stop`] runs all loops.
//! The loops use these fixed `dt`s (as stock); `now` only detects gaps: if it runs backwards or jumps by
//! more than 20 ms the derivative histories are dropped (no derivative spike after a stall).
//!
//! # Units and frames
//! The API is SI (types.rs): positions m (arena frame), velocities m/s (arena frame), attitude
//! `[roll, pitch, yaw]` rad (right-hand rule: positive pitch = nose down, positive roll = right side down,
//! positive yaw = counter-clockwise from above), body rates rad/s, battery V. Inside, the loops keep the
//! stock legacy units so the stock gains apply unchanged: angles in degrees, rates in deg/s, thrust and
//! torque commands in 16-bit counts (0..65535 ↔ 0..[`mixer::THRUST_MAX_N`] per motor), velocity-loop
//! thrust in counts/1000 (`thrust_scale`).
//!
//! # Sign decisions (our convention, not stock's)
//! - **Velocity → tilt.** The velocity loop works in the *heading frame* (arena frame rotated by the
//!   measured yaw, as stock). A positive forward (heading-frame x) velocity error needs a forward
//!   acceleration, i.e. the nose down, i.e. **positive pitch**: `pitch = +PID_vx`. A positive leftward
//!   (heading-frame y) error needs acceleration to +y, i.e. the left side down, i.e. **negative roll**:
//!   `roll = −PID_vy`. (Stock writes `pitch = −PID_vx` because its pitch is nose-up positive, and
//!   `roll = −PID_vy` like us.)
//! - **Angle and rate loops** compare our angles and our gyro rates directly: `rate_target = PID(angle
//!   target − angle)`, `torque = PID(rate target − gyro)`. No sign flips: the gyro and the Euler angles
//!   share the right-hand convention (stock negates gyro y and the yaw output to fix its legacy frame).
//! - **Torque commands** are positive about the body axes: +roll lowers the right side, +pitch lowers the
//!   nose, +yaw turns counter-clockwise from above. The mixer table in our convention is in [`mixer`].
//! - **Yaw** error is wrapped to (−180°, 180°], so 170° → −170° turns +20° (the short way).
//!
//! # Anti-windup
//! Integral clamps are the stock i-limits (on `∫e dt`, as stock). Where stock leaves its default limit of
//! 5000 (horizontal and vertical velocity) cfnav uses `output_limit / ki`, so the integral alone can use
//! the whole output range and no more. In addition (not stock) an integral does not grow:
//! - further into its own output saturation;
//! - in the direction of a saturated downstream stage: the velocity integrators when the tilt is limited,
//!   the vertical-speed integrator when the thrust hit its maximum (or the mixer had to cap) or its
//!   minimum, an angle integrator when its rate loop is saturated, the yaw-angle and yaw-rate integrators
//!   when the mixer had no yaw headroom, the roll/pitch-rate integrators (towards zero only) when a motor
//!   was floored at 0;
//! - **on the ground** (height above the surface below < `ground_clearance_m`): every integrator may only
//!   decay towards zero. (So the vertical-speed integrator unwinds after touchdown, which lowers the thrust
//!   that the supervisor's touchdown detector looks for.)
//!
//! Integrators are kept across switches between Position, Velocity and Descend (they share the inner
//! loops; stock resets everything on a mode change, which with a heavier drone than the thrust base
//! expects would drop the thrust for a moment at the start of every landing); the outer loop that a mode
//! does not use is reset. [`Setpoint::Attitude`] uses only the angle and rate loops (the position, velocity
//! and height loops are reset). [`Setpoint::Stop`] resets everything.
//!
//! # Garbage in
//! A non-finite setpoint or state component gives zero error on that axis (the loop holds its output);
//! a non-finite gyro axis falls back to `state.rates_rad_s`, then 0; a non-finite setpoint yaw keeps the
//! previous yaw target; a battery reading outside 0..10 V or non-finite is ignored. Outputs are always
//! finite. `state.valid` is not looked at: whether to fly on an invalid estimate is the supervisor's and
//! mission's call. Flags in [`ControlOutput::flags`] report what happened.
//!
//! # Deviations from stock (each measured in host-tests/tests/control.rs)
//! - Height loop 2/0/0.5 (Kd on the measured vertical speed) instead of stock 2/0.5/0: the stock
//!   integrator on top of the vertical-speed PI gives a closed-loop pole near −0.18 rad/s (linearised:
//!   `s⁴ + 5.55s³ + 14.4s² + 9.4s + 1.7`), i.e. a 2–5 cm tail for more than 8 s after a height step.
//! - `thrust_base` = the hover command of the vehicle's mass (33 g by default) instead of 36000 (a bare
//!   27 g CF2.1's hover).
//! - Tilt compensation on (stock: available, off by default).
//! - Yaw-rate target limited to 180°/s; yaw added in the mixer only within the motors' headroom.
//! - Conditional-integration anti-windup (above); D on the measurement (gyro for the yaw-angle loop).
//! - No PID reset on a change between Position, Velocity and Descend (above).
//! - The tilt limit applies to the norm of (roll, pitch), not to each axis.
//!
//! # Memory and cost
//! [`Controller`] is 656 bytes (12 PID axes, 3 differentiators, the config, the latest targets, flags);
//! nothing else, no heap, no recursion. Every call: the mixer (≈ 40 flops) and the compensation of four
//! motors (each a safeguarded Newton solve of the cubic, ≈ 3–4 iterations of ≈ 10 flops and a division).
//! Every 2nd call add 6 PID updates and a `fmodf` (yaw wrap); every 10th call add 6 PID updates, `sinf`,
//! `cosf` of the yaw, two `cosf` (tilt compensation) and two `sqrtf` (norm clamps). Estimated worst tick
//! ≈ 2–3 k cycles (≈ 15 µs at 168 MHz) with libm's software trigonometry; not yet measured on the MCU.

pub mod mixer;
pub mod pid;

use super::flags::Flags;
use crate::math::{finite_or, wrap_angle};
use crate::types::{GRAVITY_M_S2, Micros, MotorDuty, Setpoint, StateEstimate};
use mixer::Mix;
use pid::Differentiator;
pub use pid::{Gate, Pid, PidGains};

const RAD2DEG: f32 = 180.0 / core::f32::consts::PI;
const DEG2RAD: f32 = core::f32::consts::PI / 180.0;

/// Main loop rate the controller must be called at, Hz.
pub const MAIN_RATE_HZ: u32 = 1000;
/// Attitude (angle) and rate loop rate, Hz.
pub const ATTITUDE_RATE_HZ: u32 = 500;
/// Position and velocity loop rate, Hz.
pub const POSITION_RATE_HZ: u32 = 100;
const ATT_DIV: u32 = MAIN_RATE_HZ / ATTITUDE_RATE_HZ;
const POS_DIV: u32 = MAIN_RATE_HZ / POSITION_RATE_HZ;
const ATT_DT: f32 = 1.0 / ATTITUDE_RATE_HZ as f32;
const POS_DT: f32 = 1.0 / POSITION_RATE_HZ as f32;
/// A jump of `now` larger than this (or backwards) drops the derivative histories.
const MAX_GAP_US: Micros = 20_000;
/// Rate-loop outputs saturate to ±32767, as stock `saturateSignedInt16`.
const I16_LIMIT: f32 = 32767.0;
/// Battery readings outside [0, this] are ignored, V.
const MAX_PLAUSIBLE_VBAT: f32 = 10.0;
/// Tilt compensation never multiplies the thrust by more than 1/this.
const MIN_TILT_COS: f32 = 0.7;

/// Default vehicle mass: a Crazyflie 2.1 with the Flow deck v2, the Multi-ranger deck and its battery, kg.
pub const DEFAULT_MASS_KG: f32 = 0.033;

/// The collective command (counts per motor) that holds `mass_kg` in a hover with battery compensation
/// (65535 ↔ [`mixer::THRUST_MAX_N`] per motor): `m·g/4 / THRUST_MAX · 65535`, clamped to 0..=65535.
pub fn hover_thrust_cmd(mass_kg: f32) -> f32 {
    let c = mass_kg * GRAVITY_M_S2 / 4.0 / mixer::THRUST_MAX_N * mixer::CMD_MAX;
    if c.is_finite() {
        c.clamp(0.0, mixer::CMD_MAX)
    } else {
        0.0
    }
}

/// Everything tunable. [`Default`] is the stock CF2 PID tuning (from the stock files the module docs name).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerConfig {
    /// Roll-rate PID: deg/s in, 16-bit torque counts out. Stock 250/500/2.5, i-limit 33.3.
    pub roll_rate: PidGains,
    /// Pitch-rate PID, same units. Stock 250/500/2.5, i-limit 33.3.
    pub pitch_rate: PidGains,
    /// Yaw-rate PID, same units. Stock 120/16.7/0, i-limit 166.7.
    pub yaw_rate: PidGains,
    /// Roll-angle PID: deg in, deg/s out. Stock 6/3/0, i-limit 20.
    pub roll: PidGains,
    /// Pitch-angle PID: deg in, deg/s out. Stock 6/3/0, i-limit 20.
    pub pitch: PidGains,
    /// Yaw-angle PID: deg in (wrapped), deg/s out; its D acts on the gyro's yaw rate. Stock 6/1/0.35,
    /// i-limit 360. Output limit replaced by `max_yaw_rate_rad_s`.
    pub yaw: PidGains,
    /// Horizontal velocity PID (heading frame): m/s in, degrees of tilt out. Stock 25/1/0. Its output
    /// limit is replaced by `max_tilt_rad`.
    pub vel_xy: PidGains,
    /// Vertical velocity PID: m/s in, thrust/`thrust_scale` out. Stock 25/15/0; output limit
    /// 65535/2/`thrust_scale` as stock.
    pub vel_z: PidGains,
    /// Horizontal position PID (arena frame): m in, m/s out. Stock 2/0/0. Output limit replaced by
    /// `max_xy_speed_m_s`.
    pub pos_xy: PidGains,
    /// Height PID: m in, m/s out, D on the measured vertical speed. cfnav 2/0/0.5 (stock 2/0.5/0: its
    /// integrator on top of the vertical-speed integrator gives a closed-loop pole near −0.18 rad/s, a
    /// 2–5 cm tail lasting > 8 s after a height step in the model). Output limit replaced by `max_vz_m_s`.
    pub pos_z: PidGains,
    /// Maximum tilt (the norm of roll and pitch targets), rad. Stock `rpLimit` 20° × overhead 1.1 = 22°.
    pub max_tilt_rad: f32,
    /// Maximum horizontal speed target (position-loop output and Velocity setpoints), m/s. Stock 1.
    pub max_xy_speed_m_s: f32,
    /// Maximum vertical speed target (height-loop output and Descend setpoints), m/s. Stock 1.
    pub max_vz_m_s: f32,
    /// Maximum yaw-rate target (the yaw-angle loop's output limit), rad/s. Stock has none; cfnav uses
    /// 180°/s so a large heading change saturates the angle loop (which then stops integrating) instead of
    /// asking for rates the mixer's yaw headroom cannot give, which left a slow tail.
    pub max_yaw_rate_rad_s: f32,
    /// Thrust feed-forward, counts: the hover command of the vehicle ([`hover_thrust_cmd`]). Default: the
    /// hover of [`DEFAULT_MASS_KG`] (≈ 44 200); set it with [`ControllerConfig::with_mass`]. Stock uses
    /// 36000, which is the hover of a bare ≈ 27 g CF2.1 at 0.12 N full scale; with the 33 g deck-laden
    /// drone the vertical-speed integrator must then supply 8200 counts and a take-off to 0.5 m settles
    /// (±2.5 cm) in 4.4 s instead of 2.4 s (model numbers, host-tests/tests/control.rs).
    pub thrust_base: f32,
    /// Minimum collective thrust while flying, counts. Stock 20000.
    pub thrust_min: f32,
    /// Counts per vertical-speed-PID unit. Stock 1000.
    pub thrust_scale: f32,
    /// Divide the collective by `cos(roll)·cos(pitch)` (stock has this off by default).
    pub tilt_compensation: bool,
    /// Low-pass cut-off of the rate loops' D term, Hz; 0 = unfiltered (stock default).
    pub rate_d_filter_hz: f32,
    /// Below this height above the surface below the drone counts as on the ground, m.
    pub ground_clearance_m: f32,
    /// Battery-voltage compensation (stock default on).
    pub battery_compensation: bool,
    /// Low-pass factor of the battery voltage per 1 kHz tick (stock 0.01).
    pub battery_lpf: f32,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        let max_tilt_deg = 20.0 * 1.1;
        Self {
            roll_rate: PidGains::new(250.0, 500.0, 2.5, 33.3).with_output_limit(I16_LIMIT),
            pitch_rate: PidGains::new(250.0, 500.0, 2.5, 33.3).with_output_limit(I16_LIMIT),
            yaw_rate: PidGains::new(120.0, 16.7, 0.0, 166.7).with_output_limit(I16_LIMIT),
            roll: PidGains::new(6.0, 3.0, 0.0, 20.0),
            pitch: PidGains::new(6.0, 3.0, 0.0, 20.0),
            yaw: PidGains::new(6.0, 1.0, 0.35, 360.0),
            vel_xy: PidGains::new(25.0, 1.0, 0.0, max_tilt_deg / 1.0),
            vel_z: PidGains::new(25.0, 15.0, 0.0, 65535.0 / 2.0 / 1000.0 / 15.0)
                .with_output_limit(65535.0 / 2.0 / 1000.0),
            pos_xy: PidGains::new(2.0, 0.0, 0.0, f32::INFINITY),
            pos_z: PidGains::new(2.0, 0.0, 0.5, 2.0),
            max_tilt_rad: max_tilt_deg * DEG2RAD,
            max_xy_speed_m_s: 1.0,
            max_vz_m_s: 1.0,
            max_yaw_rate_rad_s: core::f32::consts::PI,
            thrust_base: hover_thrust_cmd(DEFAULT_MASS_KG),
            thrust_min: 20000.0,
            thrust_scale: 1000.0,
            tilt_compensation: true,
            rate_d_filter_hz: 0.0,
            ground_clearance_m: 0.03,
            battery_compensation: true,
            battery_lpf: 0.01,
        }
    }
}

/// A configuration [`Controller::new`] refuses, naming the field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlConfigError {
    /// Gains not finite and ≥ 0, or a limit not > 0.
    Gains(&'static str),
    /// A limit, thrust or filter setting out of range.
    Value(&'static str),
}

impl ControllerConfig {
    /// The same configuration with the thrust feed-forward set to the hover command of `mass_kg`.
    pub fn with_mass(self, mass_kg: f32) -> Self {
        Self {
            thrust_base: hover_thrust_cmd(mass_kg),
            ..self
        }
    }

    /// Check every field; see [`ControlConfigError`].
    pub fn validate(&self) -> Result<(), ControlConfigError> {
        let gains: [(&'static str, &PidGains); 10] = [
            ("roll_rate", &self.roll_rate),
            ("pitch_rate", &self.pitch_rate),
            ("yaw_rate", &self.yaw_rate),
            ("roll", &self.roll),
            ("pitch", &self.pitch),
            ("yaw", &self.yaw),
            ("vel_xy", &self.vel_xy),
            ("vel_z", &self.vel_z),
            ("pos_xy", &self.pos_xy),
            ("pos_z", &self.pos_z),
        ];
        for (name, g) in gains {
            if !g.is_valid() {
                return Err(ControlConfigError::Gains(name));
            }
        }
        let pos = |x: f32| x.is_finite() && x > 0.0;
        if !(pos(self.max_tilt_rad) && self.max_tilt_rad < 1.2) {
            return Err(ControlConfigError::Value("max_tilt_rad"));
        }
        if !pos(self.max_xy_speed_m_s) {
            return Err(ControlConfigError::Value("max_xy_speed_m_s"));
        }
        if !pos(self.max_vz_m_s) {
            return Err(ControlConfigError::Value("max_vz_m_s"));
        }
        if !pos(self.max_yaw_rate_rad_s) {
            return Err(ControlConfigError::Value("max_yaw_rate_rad_s"));
        }
        if !(self.thrust_min.is_finite() && self.thrust_min >= 0.0 && self.thrust_min <= mixer::CMD_MAX) {
            return Err(ControlConfigError::Value("thrust_min"));
        }
        if !(self.thrust_base.is_finite() && self.thrust_base >= 0.0 && self.thrust_base <= mixer::CMD_MAX) {
            return Err(ControlConfigError::Value("thrust_base"));
        }
        if !pos(self.thrust_scale) {
            return Err(ControlConfigError::Value("thrust_scale"));
        }
        if !(self.rate_d_filter_hz.is_finite() && self.rate_d_filter_hz >= 0.0) {
            return Err(ControlConfigError::Value("rate_d_filter_hz"));
        }
        if !(self.ground_clearance_m.is_finite() && self.ground_clearance_m >= 0.0) {
            return Err(ControlConfigError::Value("ground_clearance_m"));
        }
        if !(pos(self.battery_lpf) && self.battery_lpf <= 1.0) {
            return Err(ControlConfigError::Value("battery_lpf"));
        }
        Ok(())
    }
}

/// The owner of [`ControlFlags`]'s bits (a marker, never built).
#[derive(Debug)]
pub enum ControlBits {}

/// Bit flags describing one [`Controller::update`], for logs and tests.
pub type ControlFlags = Flags<ControlBits>;

impl ControlFlags {
    /// The setpoint was Stop: motors off, everything reset.
    pub const STOPPED: u16 = 1 << 0;
    /// On the ground: integrators only decay.
    pub const ON_GROUND: u16 = 1 << 1;
    /// The tilt target was limited to `max_tilt_rad`.
    pub const TILT_LIMITED: u16 = 1 << 2;
    /// The collective hit 65535 (or the mixer capped).
    pub const THRUST_HIGH: u16 = 1 << 3;
    /// The collective hit `thrust_min`.
    pub const THRUST_LOW: u16 = 1 << 4;
    /// The mixer capped a motor at 65535 (collective reduced).
    pub const CAPPED: u16 = 1 << 5;
    /// The mixer floored a motor at 0 (roll/pitch torque lost).
    pub const CLIPPED_LOW: u16 = 1 << 6;
    /// The yaw command did not fit in the motors' headroom.
    pub const YAW_LIMITED: u16 = 1 << 7;
    /// A state or gyro component was not finite.
    pub const STATE_GARBAGE: u16 = 1 << 8;
    /// A setpoint component was not finite.
    pub const SETPOINT_GARBAGE: u16 = 1 << 9;
    /// Battery compensation inactive (disabled, no reading yet, or below 2 V).
    pub const NO_BATTERY_COMP: u16 = 1 << 10;
}

/// The result of one [`Controller::update`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ControlOutput {
    /// The 8-bit duties to write to the timers, M1..M4.
    pub duty: MotorDuty,
    /// Per-motor 16-bit thrust commands after mixing and capping (0..65535 ↔ 0..0.12 N), M1..M4.
    pub thrust_cmd: [u16; 4],
    /// Per-motor 16-bit ratios after battery compensation (what stock hands to `motorsSetRatio`).
    pub motor_ratio: [u16; 4],
    /// Collective thrust before mixing, counts.
    pub collective: f32,
    /// Rate-loop outputs `[roll, pitch, yaw]`, 16-bit torque counts, cfnav signs.
    pub torque_cmd: [i16; 3],
    /// Attitude target `[roll, pitch, yaw]`, rad.
    pub attitude_target_rad: [f32; 3],
    /// Body-rate target, rad/s.
    pub rate_target_rad_s: [f32; 3],
    /// Velocity target, arena frame, m/s.
    pub velocity_target_m_s: [f32; 3],
    /// Low-passed battery voltage, V (0 before the first valid reading).
    pub battery_v_filtered: f32,
    /// What happened, see [`ControlFlags`].
    pub flags: ControlFlags,
}

/// The cascaded controller. See the module documentation.
#[derive(Clone, Debug)]
pub struct Controller {
    cfg: ControllerConfig,
    /// Since when the estimate has been invalid.
    invalid_since: Option<Micros>,
    roll_rate: Pid,
    pitch_rate: Pid,
    yaw_rate: Pid,
    d_roll: Differentiator,
    d_pitch: Differentiator,
    d_yaw: Differentiator,
    roll: Pid,
    pitch: Pid,
    yaw: Pid,
    vx: Pid,
    vy: Pid,
    vz: Pid,
    x: Pid,
    y: Pid,
    z: Pid,
    tick: u32,
    /// Attitude target, degrees.
    att_target: [f32; 3],
    /// Rate target, deg/s.
    rate_target: [f32; 3],
    vel_target: [f32; 3],
    collective: f32,
    torque: [i16; 3],
    /// Whether the yaw target has been set since the last reset.
    yaw_target_set: bool,
    /// Direction each velocity PID was limited by the tilt clamp at the last outer loop.
    tilt_sat: [i8; 2],
    tilt_limited: bool,
    /// Thrust saturation direction at the last outer loop.
    thrust_sat: i8,
    /// The mixer capped since the last outer loop.
    capped_recent: bool,
    /// The mixer floored a motor since the last attitude loop.
    clipped_recent: bool,
    /// Yaw headroom shortfall direction since the last attitude loop.
    yaw_limited_recent: i8,
    /// Saturation direction of each rate PID at the last attitude loop.
    rate_sat: [i8; 3],
    vbat: Option<f32>,
    last_now: Option<Micros>,
    garbage_setpoint: bool,
}

/// The state with garbage replaced, in the legacy units the loops use.
struct Sane {
    pos: [f32; 3],
    vel: [f32; 3],
    /// Degrees; NaN where the input was garbage (gives zero error via [`err`]).
    att_deg: [f32; 3],
    /// Gyro, deg/s.
    gyro_deg: [f32; 3],
    on_ground: bool,
    garbage: bool,
    /// The estimate is not valid: its horizontal position and velocity cannot be trusted.
    blind: bool,
}

/// How long an invalid estimate is still flown on (its IMU-propagated velocity), µs.
const BLIND_AFTER_US: u64 = 1_500_000;

/// `target − measured`, or 0 if either is not finite.
fn err(target: f32, measured: f32) -> f32 {
    let e = target - measured;
    if e.is_finite() { e } else { 0.0 }
}

fn sign(x: f32) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

/// Scale `(a, b)` down to the norm `max` if longer; returns whether it did.
fn clamp_norm(a: &mut f32, b: &mut f32, max: f32) -> bool {
    let n = libm::sqrtf(*a * *a + *b * *b);
    if n > max && n.is_finite() {
        let k = max / n;
        *a *= k;
        *b *= k;
        true
    } else {
        false
    }
}

impl Controller {
    /// A controller with this configuration, or why the configuration is unusable.
    pub fn new(config: ControllerConfig) -> Result<Self, ControlConfigError> {
        let cfg = Self::derived(config)?;
        Ok(Self {
            cfg,
            roll_rate: Pid::new(cfg.roll_rate),
            pitch_rate: Pid::new(cfg.pitch_rate),
            yaw_rate: Pid::new(cfg.yaw_rate),
            d_roll: Differentiator::new(),
            d_pitch: Differentiator::new(),
            d_yaw: Differentiator::new(),
            roll: Pid::new(cfg.roll),
            pitch: Pid::new(cfg.pitch),
            yaw: Pid::new(cfg.yaw),
            vx: Pid::new(cfg.vel_xy),
            vy: Pid::new(cfg.vel_xy),
            vz: Pid::new(cfg.vel_z),
            x: Pid::new(cfg.pos_xy),
            y: Pid::new(cfg.pos_xy),
            z: Pid::new(cfg.pos_z),
            tick: 0,
            att_target: [0.0; 3],
            rate_target: [0.0; 3],
            vel_target: [0.0; 3],
            collective: 0.0,
            torque: [0; 3],
            yaw_target_set: false,
            tilt_sat: [0; 2],
            tilt_limited: false,
            thrust_sat: 0,
            capped_recent: false,
            clipped_recent: false,
            yaw_limited_recent: 0,
            rate_sat: [0; 3],
            vbat: None,
            last_now: None,
            invalid_since: None,
            garbage_setpoint: false,
        })
    }

    /// The configuration in effect (with the output limits derived from the `max_*` fields).
    pub fn config(&self) -> &ControllerConfig {
        &self.cfg
    }

    /// `config`, validated, with the output limits derived from its `max_*` fields.
    fn derived(config: ControllerConfig) -> Result<ControllerConfig, ControlConfigError> {
        config.validate()?;
        let mut cfg = config;
        let max_tilt_deg = cfg.max_tilt_rad * RAD2DEG;
        cfg.vel_xy.output_limit = max_tilt_deg;
        cfg.pos_xy.output_limit = cfg.max_xy_speed_m_s;
        cfg.pos_z.output_limit = cfg.max_vz_m_s;
        cfg.yaw.output_limit = cfg.max_yaw_rate_rad_s * RAD2DEG;
        Ok(cfg)
    }

    /// New gains and limits (the tuning parameters), in effect from the next call: integrators,
    /// derivative histories and targets are kept (as stock, whose parameters write the gains in place,
    /// in flight too), each integral clamped to its new i-limit. An invalid configuration is refused and
    /// nothing changes.
    pub fn set_config(&mut self, config: ControllerConfig) -> Result<(), ControlConfigError> {
        let cfg = Self::derived(config)?;
        self.cfg = cfg;
        let axes: [(&mut Pid, PidGains); 12] = [
            (&mut self.roll_rate, cfg.roll_rate),
            (&mut self.pitch_rate, cfg.pitch_rate),
            (&mut self.yaw_rate, cfg.yaw_rate),
            (&mut self.roll, cfg.roll),
            (&mut self.pitch, cfg.pitch),
            (&mut self.yaw, cfg.yaw),
            (&mut self.vx, cfg.vel_xy),
            (&mut self.vy, cfg.vel_xy),
            (&mut self.vz, cfg.vel_z),
            (&mut self.x, cfg.pos_xy),
            (&mut self.y, cfg.pos_xy),
            (&mut self.z, cfg.pos_z),
        ];
        for (pid, gains) in axes {
            pid.set_gains(gains);
        }
        Ok(())
    }

    /// Clear every integrator, derivative history and target; the next call runs all loops. The battery
    /// filter is kept (it is the same battery).
    pub fn reset(&mut self) {
        for p in [
            &mut self.roll_rate,
            &mut self.pitch_rate,
            &mut self.yaw_rate,
            &mut self.roll,
            &mut self.pitch,
            &mut self.yaw,
            &mut self.vx,
            &mut self.vy,
            &mut self.vz,
            &mut self.x,
            &mut self.y,
            &mut self.z,
        ] {
            p.reset();
        }
        self.d_roll.reset();
        self.d_pitch.reset();
        self.d_yaw.reset();
        self.tick = 0;
        self.att_target = [0.0; 3];
        self.rate_target = [0.0; 3];
        self.vel_target = [0.0; 3];
        self.collective = 0.0;
        self.torque = [0; 3];
        self.yaw_target_set = false;
        self.tilt_sat = [0; 2];
        self.tilt_limited = false;
        self.thrust_sat = 0;
        self.capped_recent = false;
        self.clipped_recent = false;
        self.yaw_limited_recent = 0;
        self.rate_sat = [0; 3];
    }

    /// The integral states `[roll_rate, pitch_rate, yaw_rate, roll, pitch, yaw, vx, vy, vz, x, y, z]`
    /// (legacy units × s), for logs and tests.
    pub fn integrals(&self) -> [f32; 12] {
        [
            self.roll_rate.integral(),
            self.pitch_rate.integral(),
            self.yaw_rate.integral(),
            self.roll.integral(),
            self.pitch.integral(),
            self.yaw.integral(),
            self.vx.integral(),
            self.vy.integral(),
            self.vz.integral(),
            self.x.integral(),
            self.y.integral(),
            self.z.integral(),
        ]
    }

    /// One 1 kHz step. `gyro_rad_s` is the body-rate measurement for the rate loop (the filtered gyro;
    /// non-finite axes fall back to `state.rates_rad_s`), `battery_v` the latest battery voltage.
    pub fn update(
        &mut self,
        setpoint: &Setpoint,
        state: &StateEstimate,
        gyro_rad_s: [f32; 3],
        battery_v: f32,
        now: Micros,
    ) -> ControlOutput {
        self.update_battery(battery_v);
        let gap = match self.last_now {
            Some(t) => now < t || now - t > MAX_GAP_US,
            None => true,
        };
        self.last_now = Some(now);
        if gap {
            self.d_roll.reset();
            self.d_pitch.reset();
            self.d_yaw.reset();
        }

        if matches!(setpoint, Setpoint::Stop) {
            self.reset();
            let yaw = finite_or(state.attitude_rad[2], 0.0);
            let mut flags = ControlFlags::from_bits(ControlFlags::STOPPED);
            flags.set(ControlFlags::NO_BATTERY_COMP, !self.battery_comp_active());
            return ControlOutput {
                attitude_target_rad: [0.0, 0.0, wrap_angle(yaw)],
                battery_v_filtered: self.vbat.unwrap_or(0.0),
                flags,
                ..ControlOutput::default()
            };
        }

        let mut s = self.sanitize(state, gyro_rad_s);
        // The IMU carries the velocity estimate for a while after the flow deck stops helping: brake on it
        // first, and hold the attitude level only once it is too old to trust.
        if state.valid {
            self.invalid_since = None;
        } else if self.invalid_since.is_none() {
            self.invalid_since = Some(now);
        }
        s.blind = self
            .invalid_since
            .is_some_and(|t| now.saturating_sub(t) > BLIND_AFTER_US);
        let tick = self.tick;
        self.tick = (self.tick + 1) % POS_DIV;
        if tick.is_multiple_of(POS_DIV) {
            self.outer_loops(setpoint, &s);
        }
        if tick.is_multiple_of(ATT_DIV) {
            self.inner_loops(setpoint, &s);
        }

        let mix: Mix = mixer::mix(self.collective, self.torque[0], self.torque[1], self.torque[2]);
        self.capped_recent |= mix.capped;
        self.clipped_recent |= mix.clipped_low;
        if mix.yaw_limited != 0 {
            self.yaw_limited_recent = mix.yaw_limited;
        }
        // Stock: compensate each motor, then cap the four together; a reading below 2 V turns the motors
        // off. Before the first reading (or with compensation off) the ratio is the command.
        let (motor_ratio, duty) = match self.vbat {
            Some(v) if self.cfg.battery_compensation => mixer::compensate(mix.cmd, v),
            _ => mixer::uncompensated(mix.cmd),
        };

        let mut flags = ControlFlags::default();
        flags.set(ControlFlags::ON_GROUND, s.on_ground);
        flags.set(ControlFlags::TILT_LIMITED, self.tilt_limited);
        flags.set(ControlFlags::THRUST_HIGH, self.thrust_sat > 0 || mix.capped);
        flags.set(ControlFlags::THRUST_LOW, self.thrust_sat < 0);
        flags.set(ControlFlags::CAPPED, mix.capped);
        flags.set(ControlFlags::CLIPPED_LOW, mix.clipped_low);
        flags.set(ControlFlags::YAW_LIMITED, mix.yaw_limited != 0);
        flags.set(ControlFlags::STATE_GARBAGE, s.garbage);
        flags.set(ControlFlags::SETPOINT_GARBAGE, self.garbage_setpoint);
        flags.set(ControlFlags::NO_BATTERY_COMP, !self.battery_comp_active());
        ControlOutput {
            duty,
            thrust_cmd: mix.cmd,
            motor_ratio,
            collective: self.collective,
            torque_cmd: self.torque,
            attitude_target_rad: [
                self.att_target[0] * DEG2RAD,
                self.att_target[1] * DEG2RAD,
                wrap_angle(self.att_target[2] * DEG2RAD),
            ],
            rate_target_rad_s: [
                self.rate_target[0] * DEG2RAD,
                self.rate_target[1] * DEG2RAD,
                self.rate_target[2] * DEG2RAD,
            ],
            velocity_target_m_s: self.vel_target,
            battery_v_filtered: self.vbat.unwrap_or(0.0),
            flags,
        }
    }

    fn battery_comp_active(&self) -> bool {
        self.cfg.battery_compensation && self.vbat.is_some_and(|v| v >= mixer::BATTERY_COMP_MIN_V)
    }

    fn update_battery(&mut self, v: f32) {
        if !(v.is_finite() && (0.0..=MAX_PLAUSIBLE_VBAT).contains(&v)) {
            return;
        }
        self.vbat = Some(match self.vbat {
            Some(f) => f + self.cfg.battery_lpf * (v - f),
            None => v,
        });
    }

    fn sanitize(&self, state: &StateEstimate, gyro_rad_s: [f32; 3]) -> Sane {
        let mut garbage = false;
        let mut gyro_deg = [0.0f32; 3];
        for ((g, &a), &b) in gyro_deg.iter_mut().zip(&gyro_rad_s).zip(&state.rates_rad_s) {
            *g = if a.is_finite() {
                a * RAD2DEG
            } else {
                garbage = true;
                if b.is_finite() { b * RAD2DEG } else { 0.0 }
            };
        }
        let mut att_deg = [0.0f32; 3];
        for (a, &rad) in att_deg.iter_mut().zip(&state.attitude_rad) {
            *a = rad * RAD2DEG;
            garbage |= !a.is_finite();
        }
        garbage |= state
            .position_m
            .iter()
            .chain(state.velocity_m_s.iter())
            .any(|v| !v.is_finite());
        let h = state.position_m[2] - state.surface_height_m;
        let on_ground = h.is_finite() && h < self.cfg.ground_clearance_m;
        garbage |= !h.is_finite();
        Sane {
            pos: state.position_m,
            vel: state.velocity_m_s,
            att_deg,
            gyro_deg,
            on_ground,
            garbage,
            blind: false,
        }
    }

    /// Position (100 Hz) and velocity loops: attitude targets (roll, pitch) and the collective.
    fn outer_loops(&mut self, setpoint: &Setpoint, s: &Sane) {
        let ground = if s.on_ground { Gate::TOWARD_ZERO } else { Gate::FREE };
        let max_xy = self.cfg.max_xy_speed_m_s;
        let max_vz = self.cfg.max_vz_m_s;
        let mut garbage = false;
        if let Setpoint::Attitude {
            roll_rad,
            pitch_rad,
            thrust,
            ..
        } = *setpoint
        {
            self.attitude_thrust(roll_rad, pitch_rad, thrust);
            return;
        }

        // Position loop → velocity target (arena frame).
        let (mut vxt, mut vyt, vzt) = match *setpoint {
            Setpoint::Position { x_m, y_m, z_m, .. } => {
                garbage |= !(x_m.is_finite() && y_m.is_finite() && z_m.is_finite());
                let (vx, vy) = self.xy_position(x_m, y_m, s, ground);
                (vx, vy, self.height(z_m, s, ground))
            }
            Setpoint::Velocity {
                vx_m_s, vy_m_s, z_m, ..
            } => {
                garbage |= !(vx_m_s.is_finite() && vy_m_s.is_finite() && z_m.is_finite());
                self.x.reset();
                self.y.reset();
                (
                    finite_or(vx_m_s, 0.0),
                    finite_or(vy_m_s, 0.0),
                    self.height(z_m, s, ground),
                )
            }
            Setpoint::Descend { x_m, y_m, vz_m_s, .. } => {
                garbage |= !(x_m.is_finite() && y_m.is_finite() && vz_m_s.is_finite());
                let (vx, vy) = self.xy_position(x_m, y_m, s, ground);
                self.z.reset();
                (vx, vy, finite_or(vz_m_s, 0.0).clamp(-max_vz, max_vz))
            }
            Setpoint::Stop | Setpoint::Attitude { .. } => (0.0, 0.0, 0.0),
        };
        self.garbage_setpoint = garbage;
        clamp_norm(&mut vxt, &mut vyt, max_xy);
        self.vel_target = [vxt, vyt, vzt];

        // Velocity loop in the heading frame → tilt targets.
        let yaw = s.att_deg[2] * DEG2RAD;
        let (sy, cy) = if yaw.is_finite() {
            (libm::sinf(yaw), libm::cosf(yaw))
        } else {
            (0.0, 1.0)
        };
        let ex = err(vxt, s.vel[0]);
        let ey = err(vyt, s.vel[1]);
        let ehx = cy * ex + sy * ey;
        let ehy = -sy * ex + cy * ey;
        let (ax, ay) = if s.blind {
            // Without a valid estimate the horizontal loops would chase a drifting integral of the
            // accelerometer: hold the attitude level instead (an emergency descent drifts only with the air).
            self.vx.reset();
            self.vy.reset();
            self.x.reset();
            self.y.reset();
            (pid::PidStep::default(), pid::PidStep::default())
        } else {
            (
                self.vx.update(ehx, 0.0, POS_DT, ground.block(self.tilt_sat[0])),
                self.vy.update(ehy, 0.0, POS_DT, ground.block(self.tilt_sat[1])),
            )
        };
        // Our convention: nose down (+pitch) accelerates forward, right side down (+roll) accelerates to −y.
        let mut pitch = ax.output;
        let mut roll = -ay.output;
        self.tilt_limited = clamp_norm(&mut pitch, &mut roll, self.cfg.max_tilt_rad * RAD2DEG);
        self.tilt_sat = if self.tilt_limited {
            [sign(ax.output), sign(ay.output)]
        } else {
            [ax.saturated, ay.saturated]
        };
        self.att_target[0] = roll;
        self.att_target[1] = pitch;

        // Vertical speed → collective.
        let thrust_block = if self.capped_recent { 1 } else { self.thrust_sat };
        self.capped_recent = false;
        let vz = self
            .vz
            .update(err(vzt, s.vel[2]), 0.0, POS_DT, ground.block(thrust_block));
        let mut thrust = vz.output * self.cfg.thrust_scale + self.cfg.thrust_base;
        if self.cfg.tilt_compensation {
            let r = s.att_deg[0] * DEG2RAD;
            let p = s.att_deg[1] * DEG2RAD;
            if r.is_finite() && p.is_finite() {
                let c = (libm::cosf(r) * libm::cosf(p)).max(MIN_TILT_COS);
                thrust /= c;
            }
        }
        let (lo, hi) = (self.cfg.thrust_min, mixer::CMD_MAX);
        self.thrust_sat = if thrust >= hi {
            1
        } else if thrust <= lo {
            -1
        } else {
            vz.saturated
        };
        self.collective = if thrust.is_finite() { thrust.clamp(lo, hi) } else { lo };
    }

    /// Attitude and thrust (stock `controller_pid.c` with roll/pitch in absolute mode and no z mode, what
    /// cflib's `send_setpoint` asks for): the roll and pitch targets straight from the setpoint (limited to
    /// the maximum tilt), the collective straight from its thrust (no tilt compensation, as stock); the
    /// position and velocity loops, which this mode does not use, are reset.
    fn attitude_thrust(&mut self, roll_rad: f32, pitch_rad: f32, thrust: u16) {
        self.x.reset();
        self.y.reset();
        self.z.reset();
        self.vx.reset();
        self.vy.reset();
        self.vz.reset();
        self.vel_target = [0.0; 3];
        self.garbage_setpoint = !(roll_rad.is_finite() && pitch_rad.is_finite());
        let mut roll = finite_or(roll_rad, 0.0) * RAD2DEG;
        let mut pitch = finite_or(pitch_rad, 0.0) * RAD2DEG;
        self.tilt_limited = clamp_norm(&mut pitch, &mut roll, self.cfg.max_tilt_rad * RAD2DEG);
        self.tilt_sat = [0; 2];
        self.att_target[0] = roll;
        self.att_target[1] = pitch;
        let thrust = f32::from(thrust).min(mixer::CMD_MAX);
        self.thrust_sat = i8::from(thrust >= mixer::CMD_MAX);
        self.capped_recent = false;
        self.collective = thrust;
    }

    fn xy_position(&mut self, x_m: f32, y_m: f32, s: &Sane, gate: Gate) -> (f32, f32) {
        let vx = self.x.update(err(x_m, s.pos[0]), s.vel[0], POS_DT, gate);
        let vy = self.y.update(err(y_m, s.pos[1]), s.vel[1], POS_DT, gate);
        (vx.output, vy.output)
    }

    fn height(&mut self, z_m: f32, s: &Sane, gate: Gate) -> f32 {
        self.z.update(err(z_m, s.pos[2]), s.vel[2], POS_DT, gate).output
    }

    /// Attitude (angle) and rate loops, 500 Hz: torque commands.
    fn inner_loops(&mut self, setpoint: &Setpoint, s: &Sane) {
        let ground = if s.on_ground { Gate::TOWARD_ZERO } else { Gate::FREE };
        let yaw_sp = match *setpoint {
            Setpoint::Position { yaw_rad, .. }
            | Setpoint::Velocity { yaw_rad, .. }
            | Setpoint::Descend { yaw_rad, .. } => yaw_rad,
            // Stock: the heading target moves at the commanded rate (from the current heading when none is
            // held yet).
            Setpoint::Attitude { yaw_rate_rad_s, .. } => {
                let held = if self.yaw_target_set {
                    self.att_target[2]
                } else {
                    finite_or(s.att_deg[2], 0.0)
                };
                (held + finite_or(yaw_rate_rad_s, 0.0) * RAD2DEG * ATT_DT) * DEG2RAD
            }
            Setpoint::Stop => f32::NAN,
        };
        if yaw_sp.is_finite() {
            self.att_target[2] = wrap_angle(yaw_sp) * RAD2DEG;
            self.yaw_target_set = true;
        } else if !self.yaw_target_set {
            // No usable heading yet: hold the current one.
            self.att_target[2] = finite_or(s.att_deg[2], 0.0);
            self.yaw_target_set = true;
        }

        let g = s.gyro_deg;
        // Cascade anti-windup: an angle integrator does not push into a saturated rate loop (the yaw one
        // also not into a yaw command the mixer could not deliver).
        let yaw_sat = if self.yaw_limited_recent != 0 {
            self.yaw_limited_recent
        } else {
            self.rate_sat[2]
        };
        let rr = self.roll.update(
            err(self.att_target[0], s.att_deg[0]),
            g[0],
            ATT_DT,
            ground.block(self.rate_sat[0]),
        );
        let pr = self.pitch.update(
            err(self.att_target[1], s.att_deg[1]),
            g[1],
            ATT_DT,
            ground.block(self.rate_sat[1]),
        );
        let yaw_err = wrap_angle(err(self.att_target[2], s.att_deg[2]) * DEG2RAD) * RAD2DEG;
        let yr = self.yaw.update(yaw_err, g[2], ATT_DT, ground.block(yaw_sat));
        self.rate_target = [rr.output, pr.output, yr.output];

        let alpha = if self.cfg.rate_d_filter_hz > 0.0 {
            let rc = 1.0 / (2.0 * core::f32::consts::PI * self.cfg.rate_d_filter_hz);
            ATT_DT / (ATT_DT + rc)
        } else {
            1.0
        };
        let dr = self.d_roll.update(g[0], ATT_DT, alpha);
        let dp = self.d_pitch.update(g[1], ATT_DT, alpha);
        let dy = self.d_yaw.update(g[2], ATT_DT, alpha);
        let rp_gate = if self.clipped_recent {
            Gate {
                toward_zero: true,
                ..ground
            }
        } else {
            ground
        };
        let yaw_gate = ground.block(self.yaw_limited_recent);
        self.clipped_recent = false;
        self.yaw_limited_recent = 0;
        let ro = self
            .roll_rate
            .update(err(self.rate_target[0], g[0]), dr, ATT_DT, rp_gate);
        let po = self
            .pitch_rate
            .update(err(self.rate_target[1], g[1]), dp, ATT_DT, rp_gate);
        let yo = self
            .yaw_rate
            .update(err(self.rate_target[2], g[2]), dy, ATT_DT, yaw_gate);
        self.torque = [to_i16(ro.output), to_i16(po.output), to_i16(yo.output)];
        self.rate_sat = [ro.saturated, po.saturated, yo.saturated];
    }
}

/// Saturate to ±32767 (stock `saturateSignedInt16`: never −32768, so negation is safe).
fn to_i16(x: f32) -> i16 {
    if x.is_finite() {
        x.clamp(-I16_LIMIT, I16_LIMIT) as i16
    } else {
        0
    }
}
