//! The supervisor: a sans-IO state machine that decides whether the motors may run.
//!
//! Job: once per tick take the time, the accelerometer, the estimate, the controller's last motor
//! commands, the current setpoint and its age, the battery voltage and an arm request; return whether the
//! motors may run, whether the drone is flying, and flags and a reason for the logs. It follows the stock
//! rules of stock `supervisor.c` and `commander.h` (setpoint watchdog, tumble detection, battery thresholds,
//! auto-arming), adapted to cfnav's setpoints.
//!
//! Non-goals: it never lands the drone or chooses a setpoint by itself: the mission does (a low battery or
//! a stale setpoint is *reported*); [`Supervisor::guard_setpoint`] is a filter the firmware applies
//! between the mission and the controller. No radio commands, no LEDs.
//!
//! # States
//! ```text
//! Idle   ──(checks pass, armed, setpoint is Stop)──────────────────────▶ Armed
//! Armed  ──(a motor command > 0)───────────────────────────────────────▶ Flying
//! Armed  ──(a check fails, or disarm)──────────────────────────────────▶ Idle
//! Flying ──(tumble, or no usable accelerometer sample for > 1 s)───────▶ Crashed  (latched until reset)
//! Flying ──(setpoint older than 2 s)───────────────────────────────────▶ Locked   (latched until reset)
//! Flying ──(touchdown for > 0.3 s, or all motor commands 0 for > 2 s)──▶ Landed
//! Flying ──(disarm)────────────────────────────────────────────────────▶ Idle
//! Landed ──(setpoint is Stop: the Idle rules apply at once)────────────▶ Idle or Armed
//! ```
//! - **Idle** (stock PreFlChecksNotPassed/Passed): motors off. Arms when the pre-flight checks pass (an
//!   accelerometer sample ≤ 1 s old says upright, acc.z ≥ 0.5 g, and no tumble timer has fired; the
//!   estimate is `valid`), the system is armed, and the setpoint is Stop (or none was ever received):
//!   the stock commander's "thrust lock", so a take-off setpoint left over from before never starts the
//!   motors by surprise.
//! - **Arming**: CF2.1 stock is **auto-arming** (`CONFIG_MOTORS_REQUIRE_ARMING` = n): with
//!   [`SupervisorConfig::auto_arm`] (default) `arm_request` is ignored. Without it `arm_request` is a
//!   level: true arms, false disarms, and disarming while flying stops the motors (an emergency stop).
//! - **Armed** (stock ReadyToFly): motors allowed, none running yet. A failing check or a disarm → Idle.
//! - **Flying**: entered when any motor command is above 0 (stock "is flying" with idle thrust 0).
//! - **Landed**: touchdown detected (or the motors were all at 0 for > 2 s): motors off. Leaves to Idle
//!   when the setpoint is Stop (the mission acknowledged the landing); from there the usual arming.
//! - **Crashed**: tumbled while flying, or the accelerometer gave nothing usable for > 1 s while flying.
//!   Motors off, **latched until [`Supervisor::reset`]**.
//! - **Locked**: the setpoint watchdog timed out (> 2 s) while flying (stock: ExceptFreeFall → Locked,
//!   "reboot required"). Motors off, latched until [`Supervisor::reset`].
//!
//! # Rules
//! - **Setpoint watchdog** (Flying only): age > 500 ms → `level_out` (report;
//!   [`Supervisor::guard_setpoint`] turns it into "zero velocity at the last height", for an Attitude
//!   setpoint, which has none, the estimated height and heading when it went stale); > 2000 ms →
//!   Locked, unless the setpoint in force is Stop (the motors-off rule makes that a landing). No setpoint ever = infinitely old.
//! - **Tumble** (stock `isTumbledCheck`): acc.z < 0.5 g continuously for > 1 s, or acc.z < −0.2 g
//!   continuously for > 100 ms (two separate timers; stock shares one timer, which can fire the upside-down
//!   rule as soon as the drone is upside down after 100 ms of any tilt). A free-fall sample (|acc| < 0.1 g
//!   on all axes) resets both timers: falling is allowed. Before flight a tumble blocks arming; in flight
//!   it is a crash.
//! - **Garbage accelerometer samples** (non-finite or any axis beyond 40 g) are skipped: they neither
//!   start nor stop a tumble timer, so a timer that is running keeps running and a tumble still fires on
//!   time — a NaN cannot mask a tumble, and cannot cause one either. If no usable sample arrives for more
//!   than 1 s, `accel_fault` is raised and counts as a tumble (the attitude estimate is blind too; cutting
//!   the motors limits the damage), so a dead IMU cannot mask a tumble forever.
//! - **Touchdown** (Flying): the setpoint does not ask to be higher than the touchdown height (a Descend
//!   with vz ≤ 0, a Position/Velocity at most `touchdown_height_m` above the surface, or an Attitude (its
//!   thrust is the pilot's: the thrust and height conditions decide)), the estimate's
//!   height above the surface below is < 3 cm, |vz| < 0.1 m/s, and the mean motor command is < 90 % of the
//!   hover command, all continuously for > 0.3 s → Landed. The hover command is learned (mean command
//!   low-passed with τ = 2 s while flying above 10 cm with |vz| < 0.2 m/s), starting from
//!   [`SupervisorConfig::hover_cmd`]; learning needs all four motors running). A garbage estimate never
//!   counts as touchdown.
//! - **Battery**: the voltage is low-passed (τ = 1 s; it sags under load); `battery_low` when the filtered
//!   voltage stays below 3.2 V for > 5 s, or below 3.0 V (stock's critical level) for > 0.5 s (a cell that
//!   far down is collapsing, not sagging: under the 6× drain of the battery scenario the loaded voltage fell
//!   from 3.0 to 2.4 V in 3 s and the drone dropped from 0.5 m before the 5 s had passed), **latched until
//!   reset** (the voltage recovers once the motors stop; the mission must not take that as a charged
//!   battery). Readings outside 0..10 V or non-finite
//!   are ignored. The mission decides to land.
//! - **Minimum height**: [`clamp_min_height`] raises a Position/Velocity setpoint's height to ≥ 0.2 m
//!   (above the arena floor); Descend and Stop are left alone (landing is a Descend).
//!
//! Time: `now` in µs; durations use saturating differences, so time running backwards only delays timers.
//! Call at any rate ≥ 100 Hz (the 100 ms rule needs it; stock runs at 25 Hz); the firmware calls it at
//! 1 kHz with the controller.
//!
//! Memory: [`Supervisor`] is 280 bytes (half of it the configuration). Cost: O(1), a few dozen
//! comparisons and flops, no transcendental functions.

use super::flags::Flags;
use crate::types::{GRAVITY_M_S2, Micros, Setpoint, StateEstimate};

/// Tunable thresholds. [`Default`] is stock (`supervisor.c`, `commander.h`) where stock has a value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisorConfig {
    /// Arm automatically when the checks pass (CF2.1 stock).
    pub auto_arm: bool,
    /// Setpoint age that raises `level_out`, µs (stock 500 ms).
    pub setpoint_stale_us: u64,
    /// Setpoint age that cuts the motors (Locked), µs (stock 2000 ms).
    pub setpoint_timeout_us: u64,
    /// Tilt rule threshold on acc.z, g (stock 0.5).
    pub tilt_acc_z_g: f32,
    /// Tilt rule duration, µs (stock 1000 ms).
    pub tilt_time_us: u64,
    /// Upside-down rule threshold on acc.z, g (stock −0.2).
    pub upside_down_acc_z_g: f32,
    /// Upside-down rule duration, µs (stock 100 ms).
    pub upside_down_time_us: u64,
    /// Free fall: every axis below this, g (stock 0.1).
    pub free_fall_g: f32,
    /// No usable accelerometer sample for longer than this → `accel_fault`, µs.
    pub accel_fault_us: u64,
    /// Touchdown: height above the surface below, m.
    pub touchdown_height_m: f32,
    /// Touchdown: maximum |vz|, m/s.
    pub touchdown_speed_m_s: f32,
    /// Touchdown: mean motor command below this fraction of the hover command.
    pub touchdown_thrust_ratio: f32,
    /// Touchdown: duration, µs.
    pub touchdown_time_us: u64,
    /// Initial hover command (mean of the four, counts): 33 g at 0.12 N full scale ≈ 44 200.
    pub hover_cmd: f32,
    /// Flying with all motor commands at 0 for longer than this → Landed, µs (stock is-flying window).
    pub motors_off_landed_us: u64,
    /// Low-battery threshold, V (stock 3.2).
    pub battery_low_v: f32,
    /// Low-battery duration, µs (stock 5 s).
    pub battery_low_time_us: u64,
    /// Critical battery threshold, V (stock `PM_BAT_CRITICAL_LOW_VOLTAGE`, `src/hal/interface/pm.h`: 3.0).
    pub battery_critical_v: f32,
    /// Critical battery duration, µs: a voltage this far down is collapsing, not sagging (see the module
    /// documentation), so the low-battery latch does not wait [`Self::battery_low_time_us`].
    pub battery_critical_time_us: u64,
    /// Battery low-pass time constant, s.
    pub battery_tau_s: f32,
    /// Minimum height of Position/Velocity setpoints, m above the arena floor.
    pub min_height_m: f32,
}

impl Default for SupervisorConfig {
    fn default() -> Self {
        Self {
            auto_arm: true,
            setpoint_stale_us: 500_000,
            setpoint_timeout_us: 2_000_000,
            tilt_acc_z_g: 0.5,
            tilt_time_us: 1_000_000,
            upside_down_acc_z_g: -0.2,
            upside_down_time_us: 100_000,
            free_fall_g: 0.1,
            accel_fault_us: 1_000_000,
            touchdown_height_m: 0.03,
            touchdown_speed_m_s: 0.1,
            touchdown_thrust_ratio: 0.9,
            touchdown_time_us: 300_000,
            hover_cmd: 0.033 * GRAVITY_M_S2 / 4.0 / 0.12 * 65535.0,
            motors_off_landed_us: 2_000_000,
            battery_low_v: 3.2,
            battery_low_time_us: 5_000_000,
            battery_critical_v: 3.0,
            battery_critical_time_us: 500_000,
            battery_tau_s: 1.0,
            min_height_m: 0.2,
        }
    }
}

/// The supervisor's state (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SupervisorState {
    /// Pre-flight: motors off until the checks pass and the system is armed.
    #[default]
    Idle,
    /// Ready: motors allowed, not running yet.
    Armed,
    /// Motors running.
    Flying,
    /// Touchdown detected: motors off until the setpoint is Stop.
    Landed,
    /// Tumble (or a dead accelerometer) in flight: motors off, latched until reset.
    Crashed,
    /// Setpoint watchdog timeout in flight: motors off, latched until reset.
    Locked,
}

/// Why the motors are not allowed (or [`Reason::None`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Reason {
    /// The motors are allowed.
    #[default]
    None,
    /// Not armed (auto-arm off and no arm request, or a disarm).
    NotArmed,
    /// Armed, but waiting for a Stop setpoint before allowing the motors (thrust lock).
    WaitingForStop,
    /// No recent upright accelerometer sample (acc.z < tilt threshold, or none yet).
    NotUpright,
    /// A tumble rule fired.
    Tumbled,
    /// No usable accelerometer sample for too long.
    AccelFault,
    /// The estimate is not valid (pre-flight only).
    EstimateInvalid,
    /// The setpoint watchdog timed out in flight.
    SetpointTimeout,
    /// Touchdown detected.
    Touchdown,
    /// The motors were all at 0 for a long time while flying.
    MotorsStopped,
}

/// The owner of [`SupervisorFlags`]'s bits (a marker, never built).
#[derive(Debug)]
pub enum SupervisorBits {}

/// Bit flags describing one tick, for logs.
pub type SupervisorFlags = Flags<SupervisorBits>;

impl SupervisorFlags {
    /// The tilt timer is running (acc.z below the tilt threshold).
    pub const TILTED: u16 = 1 << 0;
    /// The upside-down timer is running.
    pub const UPSIDE_DOWN: u16 = 1 << 1;
    /// A tumble rule has fired (this tick's condition, not the latch).
    pub const TUMBLED: u16 = 1 << 2;
    /// This sample looked like free fall.
    pub const FREE_FALL: u16 = 1 << 3;
    /// This accelerometer sample was garbage and was skipped.
    pub const ACCEL_INVALID: u16 = 1 << 4;
    /// No usable accelerometer sample for longer than `accel_fault_us`.
    pub const ACCEL_FAULT: u16 = 1 << 5;
    /// The setpoint is older than `setpoint_stale_us` (level out).
    pub const SETPOINT_STALE: u16 = 1 << 6;
    /// The setpoint is older than `setpoint_timeout_us`.
    pub const SETPOINT_TIMEOUT: u16 = 1 << 7;
    /// The touchdown conditions hold (timer running).
    pub const TOUCHDOWN: u16 = 1 << 8;
    /// The battery is low (latched).
    pub const BATTERY_LOW: u16 = 1 << 9;
    /// This battery reading was garbage and was skipped.
    pub const BATTERY_INVALID: u16 = 1 << 10;
    /// The estimate is not valid.
    pub const ESTIMATE_INVALID: u16 = 1 << 11;
}

/// One tick's inputs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SupervisorInput {
    /// Time, µs since boot.
    pub now: Micros,
    /// Latest accelerometer sample (specific force, body frame, m/s²; level at rest `[0, 0, 9.81]`).
    pub accel_m_s2: [f32; 3],
    /// Latest estimate.
    pub estimate: StateEstimate,
    /// The controller's latest per-motor commands (`ControlOutput::thrust_cmd`).
    pub thrust_cmd: [u16; 4],
    /// The setpoint currently fed to the controller (before [`Supervisor::guard_setpoint`]); Stop if
    /// none.
    pub setpoint: Setpoint,
    /// Age of that setpoint, µs; `None` if none was ever received.
    pub setpoint_age_us: Option<u64>,
    /// Battery voltage, V.
    pub battery_v: f32,
    /// Arm request (level); ignored with auto-arming.
    pub arm_request: bool,
}

/// One tick's verdict.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SupervisorOutput {
    /// State after this tick.
    pub state: SupervisorState,
    /// The motors may run (Armed or Flying). When false the firmware feeds Stop to the controller.
    pub motors_allowed: bool,
    /// In the Flying state.
    pub flying: bool,
    /// Flying with a setpoint older than 500 ms: level out and hold the height.
    pub level_out: bool,
    /// Battery low (latched).
    pub battery_low: bool,
    /// Low-passed battery voltage, V (0 before the first valid reading).
    pub battery_v_filtered: f32,
    /// Why the motors are not allowed.
    pub reason: Reason,
    /// Details, see [`SupervisorFlags`].
    pub flags: SupervisorFlags,
}

/// Raise a Position/Velocity setpoint's height to at least `min_z_m`; Stop and Descend are returned as
/// they are. A non-finite height becomes `min_z_m`.
pub fn clamp_min_height(setpoint: Setpoint, min_z_m: f32) -> Setpoint {
    let lift = |z: f32| if z.is_finite() { z.max(min_z_m) } else { min_z_m };
    match setpoint {
        Setpoint::Position { x_m, y_m, z_m, yaw_rad } => Setpoint::Position {
            x_m,
            y_m,
            z_m: lift(z_m),
            yaw_rad,
        },
        Setpoint::Velocity {
            vx_m_s,
            vy_m_s,
            z_m,
            yaw_rad,
        } => Setpoint::Velocity {
            vx_m_s,
            vy_m_s,
            z_m: lift(z_m),
            yaw_rad,
        },
        other => other,
    }
}

/// The supervisor. See the module documentation.
#[derive(Clone, Debug)]
pub struct Supervisor {
    cfg: SupervisorConfig,
    state: SupervisorState,
    reason: Reason,
    /// Start of the current tilt (acc.z < 0.5 g), µs.
    tilt_since: Option<Micros>,
    /// Start of the current upside-down phase (acc.z < −0.2 g), µs.
    upside_down_since: Option<Micros>,
    /// Time of the last usable accelerometer sample and whether it was upright.
    last_accel: Option<(Micros, bool)>,
    /// First tick (for the accel fault timer before any sample).
    first_now: Option<Micros>,
    touchdown_since: Option<Micros>,
    motors_off_since: Option<Micros>,
    hover_cmd: f32,
    vbat: Option<f32>,
    battery_low_since: Option<Micros>,
    battery_critical_since: Option<Micros>,
    battery_low: bool,
    last_now: Option<Micros>,
    /// Height and heading to hold while levelling out.
    hold: Option<(f32, f32)>,
    /// Last fresh setpoint's height and heading.
    last_target: Option<(f32, f32)>,
    level_out: bool,
}

impl Supervisor {
    /// A supervisor in Idle.
    pub fn new(config: SupervisorConfig) -> Self {
        Self {
            cfg: config,
            state: SupervisorState::Idle,
            reason: Reason::NotUpright,
            tilt_since: None,
            upside_down_since: None,
            last_accel: None,
            first_now: None,
            touchdown_since: None,
            motors_off_since: None,
            hover_cmd: config.hover_cmd,
            vbat: None,
            battery_low_since: None,
            battery_critical_since: None,
            battery_low: false,
            last_now: None,
            hold: None,
            last_target: None,
            level_out: false,
        }
    }

    /// Back to Idle, clearing the latches (Crashed, Locked, battery low) and every timer. The stock
    /// equivalent of a reboot or a "recover" command.
    pub fn reset(&mut self) {
        *self = Self::new(self.cfg);
    }

    /// The state.
    pub fn state(&self) -> SupervisorState {
        self.state
    }

    /// The configuration.
    pub fn config(&self) -> &SupervisorConfig {
        &self.cfg
    }

    /// The learned hover command (mean of the four motors, counts).
    pub fn hover_cmd(&self) -> f32 {
        self.hover_cmd
    }

    /// One tick.
    pub fn update(&mut self, input: &SupervisorInput) -> SupervisorOutput {
        let now = input.now;
        let dt_s = match self.last_now {
            Some(t) => (now.saturating_sub(t) as f32 * 1e-6).min(0.1),
            None => 0.0,
        };
        self.last_now = Some(now);
        let first = *self.first_now.get_or_insert(now);
        let mut flags = SupervisorFlags::default();

        // Accelerometer: tumble timers.
        let g = GRAVITY_M_S2;
        let a = input.accel_m_s2;
        let usable = a.iter().all(|v| v.is_finite() && v.abs() <= 40.0 * g);
        if usable {
            let free_fall = a.iter().all(|v| v.abs() < self.cfg.free_fall_g * g);
            flags.set(SupervisorFlags::FREE_FALL, free_fall);
            let az = a[2] / g;
            if free_fall {
                self.tilt_since = None;
                self.upside_down_since = None;
            } else {
                if az < self.cfg.tilt_acc_z_g {
                    self.tilt_since.get_or_insert(now);
                } else {
                    self.tilt_since = None;
                }
                if az < self.cfg.upside_down_acc_z_g {
                    self.upside_down_since.get_or_insert(now);
                } else {
                    self.upside_down_since = None;
                }
            }
            self.last_accel = Some((now, !free_fall && az >= self.cfg.tilt_acc_z_g));
        } else {
            flags.set(SupervisorFlags::ACCEL_INVALID, true);
        }
        let elapsed = |since: Option<Micros>| since.map(|t| now.saturating_sub(t));
        let tilt_fired = elapsed(self.tilt_since).is_some_and(|d| d > self.cfg.tilt_time_us);
        let flip_fired = elapsed(self.upside_down_since).is_some_and(|d| d > self.cfg.upside_down_time_us);
        let tumbled = tilt_fired || flip_fired;
        let last_usable = self.last_accel.map_or(first, |(t, _)| t);
        let accel_fault = now.saturating_sub(last_usable) > self.cfg.accel_fault_us;
        let upright = self
            .last_accel
            .is_some_and(|(t, up)| up && now.saturating_sub(t) <= self.cfg.accel_fault_us);
        flags.set(SupervisorFlags::TILTED, self.tilt_since.is_some());
        flags.set(SupervisorFlags::UPSIDE_DOWN, self.upside_down_since.is_some());
        flags.set(SupervisorFlags::TUMBLED, tumbled);
        flags.set(SupervisorFlags::ACCEL_FAULT, accel_fault);

        // Battery.
        let v = input.battery_v;
        if v.is_finite() && (0.0..=10.0).contains(&v) {
            self.vbat = Some(match self.vbat {
                Some(f) => f + dt_s / (self.cfg.battery_tau_s + dt_s) * (v - f),
                None => v,
            });
        } else {
            flags.set(SupervisorFlags::BATTERY_INVALID, true);
        }
        match self.vbat {
            Some(f) if f < self.cfg.battery_low_v => {
                let since = *self.battery_low_since.get_or_insert(now);
                if now.saturating_sub(since) > self.cfg.battery_low_time_us {
                    self.battery_low = true;
                }
                if f < self.cfg.battery_critical_v {
                    let since = *self.battery_critical_since.get_or_insert(now);
                    if now.saturating_sub(since) > self.cfg.battery_critical_time_us {
                        self.battery_low = true;
                    }
                } else {
                    self.battery_critical_since = None;
                }
            }
            Some(_) => {
                self.battery_low_since = None;
                self.battery_critical_since = None;
            }
            None => {}
        }
        flags.set(SupervisorFlags::BATTERY_LOW, self.battery_low);

        // Setpoint age and the height/heading to hold when it goes stale.
        let age = input.setpoint_age_us.unwrap_or(u64::MAX);
        let stale = age > self.cfg.setpoint_stale_us;
        let timed_out = age > self.cfg.setpoint_timeout_us;
        if !stale {
            self.last_target = match input.setpoint {
                // As flown: the guard raised it to the minimum height.
                Setpoint::Position { z_m, yaw_rad, .. } | Setpoint::Velocity { z_m, yaw_rad, .. } => {
                    Some((z_m.max(self.cfg.min_height_m), yaw_rad))
                }
                _ => None,
            };
        }
        flags.set(SupervisorFlags::SETPOINT_STALE, stale);
        flags.set(SupervisorFlags::SETPOINT_TIMEOUT, timed_out);
        let est = &input.estimate;
        flags.set(SupervisorFlags::ESTIMATE_INVALID, !est.valid);

        // Touchdown and hover learning.
        let mean_cmd = input.thrust_cmd.iter().map(|&c| f32::from(c)).sum::<f32>() / 4.0;
        let h = est.position_m[2] - est.surface_height_m;
        let vz = est.velocity_m_s[2];
        let landing_intent = match input.setpoint {
            Setpoint::Descend { vz_m_s, .. } => vz_m_s <= 0.0,
            Setpoint::Position { z_m, .. } | Setpoint::Velocity { z_m, .. } => {
                z_m - est.surface_height_m <= self.cfg.touchdown_height_m
            }
            // The thrust and the height decide (below): a pilot lowering the thrust near the floor lands.
            Setpoint::Attitude { .. } => true,
            Setpoint::Stop => false,
        };
        let touching = self.state == SupervisorState::Flying
            && landing_intent
            && h.is_finite()
            && vz.is_finite()
            && h < self.cfg.touchdown_height_m
            && vz.abs() < self.cfg.touchdown_speed_m_s
            && mean_cmd < self.cfg.touchdown_thrust_ratio * self.hover_cmd;
        if touching {
            self.touchdown_since.get_or_insert(now);
        } else {
            self.touchdown_since = None;
        }
        let touchdown = elapsed(self.touchdown_since).is_some_and(|d| d > self.cfg.touchdown_time_us);
        flags.set(SupervisorFlags::TOUCHDOWN, touching);
        let all_running = input.thrust_cmd.iter().all(|&c| c > 0);
        if self.state == SupervisorState::Flying
            && all_running
            && h.is_finite()
            && vz.is_finite()
            && h > 0.1
            && vz.abs() < 0.2
        {
            let k = dt_s / (2.0 + dt_s);
            self.hover_cmd = (self.hover_cmd + k * (mean_cmd - self.hover_cmd)).clamp(10_000.0, 65_535.0);
        }
        let motors_running = input.thrust_cmd.iter().any(|&c| c > 0);
        if motors_running {
            self.motors_off_since = None;
        } else {
            self.motors_off_since.get_or_insert(now);
        }
        let motors_off_long = elapsed(self.motors_off_since).is_some_and(|d| d > self.cfg.motors_off_landed_us);

        // Transitions (one per tick).
        let armed = self.cfg.auto_arm || input.arm_request;
        let setpoint_stop = matches!(input.setpoint, Setpoint::Stop) || input.setpoint_age_us.is_none();
        let preflight = if !armed {
            Reason::NotArmed
        } else if accel_fault {
            Reason::AccelFault
        } else if tumbled {
            Reason::Tumbled
        } else if !upright {
            Reason::NotUpright
        } else if !est.valid {
            Reason::EstimateInvalid
        } else {
            Reason::None
        };
        use SupervisorState as S;
        let from_idle = match preflight {
            Reason::None if setpoint_stop => (S::Armed, Reason::None),
            Reason::None => (S::Idle, Reason::WaitingForStop),
            r => (S::Idle, r),
        };
        let (state, reason) = match self.state {
            S::Idle => from_idle,
            S::Armed => match preflight {
                Reason::None if motors_running => (S::Flying, Reason::None),
                Reason::None => (S::Armed, Reason::None),
                r => (S::Idle, r),
            },
            S::Flying => {
                if !armed {
                    (S::Idle, Reason::NotArmed)
                } else if tumbled {
                    (S::Crashed, Reason::Tumbled)
                } else if accel_fault {
                    (S::Crashed, Reason::AccelFault)
                } else if timed_out && !matches!(input.setpoint, Setpoint::Stop) {
                    // A stop that ages has nothing left to time out (the motors are already off): the motors-off
                    // rule lands it. cflib's MotionCommander.land ends with one stop setpoint and nothing more;
                    // locking then (when the touchdown was not seen first) refused the next take-off.
                    (S::Locked, Reason::SetpointTimeout)
                } else if touchdown {
                    (S::Landed, Reason::Touchdown)
                } else if motors_off_long {
                    (S::Landed, Reason::MotorsStopped)
                } else {
                    (S::Flying, Reason::None)
                }
            }
            // The mission acknowledged the landing: the pre-flight rules apply again (arming included).
            S::Landed if setpoint_stop => from_idle,
            s => (s, self.reason),
        };
        if state != self.state {
            self.touchdown_since = None;
            self.motors_off_since = None;
        }
        self.state = state;
        self.reason = reason;

        // Level out: latch the height and heading when the setpoint first goes stale in flight.
        self.level_out = state == S::Flying && stale;
        if self.level_out {
            if self.hold.is_none() {
                let z_now = est.position_m[2];
                let yaw_now = est.attitude_rad[2];
                self.hold = Some(match self.last_target {
                    Some((z, yaw)) if z.is_finite() && yaw.is_finite() => (z, yaw),
                    _ => (z_now, yaw_now),
                });
            }
        } else {
            self.hold = None;
        }

        SupervisorOutput {
            state,
            motors_allowed: matches!(state, S::Armed | S::Flying),
            flying: state == S::Flying,
            level_out: self.level_out,
            battery_low: self.battery_low,
            battery_v_filtered: self.vbat.unwrap_or(0.0),
            reason,
            flags,
        }
    }

    /// The IMU gave no sample for longer than the stabilizer's level window (a hung bus, a dead chip):
    /// [`Supervisor::update`] cannot run without one, so its accelerometer timer would never fire. Flying
    /// → Crashed (latched, [`Reason::AccelFault`]); Armed → Idle; the other states are kept. The motors
    /// are not allowed in the returned verdict whatever the state.
    pub fn imu_lost(&mut self) -> SupervisorOutput {
        use SupervisorState as S;
        match self.state {
            S::Flying => (self.state, self.reason) = (S::Crashed, Reason::AccelFault),
            S::Armed => (self.state, self.reason) = (S::Idle, Reason::AccelFault),
            _ => {}
        }
        self.level_out = false;
        self.hold = None;
        let mut flags = SupervisorFlags::from_bits(0);
        flags.set(SupervisorFlags::ACCEL_FAULT, true);
        flags.set(SupervisorFlags::BATTERY_LOW, self.battery_low);
        SupervisorOutput {
            state: self.state,
            motors_allowed: false,
            flying: false,
            level_out: false,
            battery_low: self.battery_low,
            battery_v_filtered: self.vbat.unwrap_or(0.0),
            reason: if self.reason == Reason::None {
                Reason::AccelFault
            } else {
                self.reason
            },
            flags,
        }
    }

    /// The setpoint to feed the controller, given the mission's: Stop when the motors are not allowed or
    /// the setpoint is Stop; while levelling out, zero velocity at the held height and heading (stock WarningLevelOut: level,
    /// hold z); otherwise the mission's with [`clamp_min_height`] applied. Uses the state of the last
    /// [`Supervisor::update`].
    pub fn guard_setpoint(&self, setpoint: Setpoint) -> Setpoint {
        if !matches!(self.state, SupervisorState::Armed | SupervisorState::Flying) {
            return Setpoint::Stop;
        }
        // A Stop stays a Stop, stale or not: stock's level-out keeps the setpoint's z mode, and a stop
        // setpoint has none (thrust 0), so a drone told to stop in the air falls instead of climbing back to
        // the height it held before the stop.
        if self.level_out && setpoint != Setpoint::Stop {
            // The held height is not raised to the minimum: a landing that loses its setpoints holds
            // where it is instead of climbing.
            let (z, yaw) = self.hold.unwrap_or((self.cfg.min_height_m, 0.0));
            let z = if z.is_finite() { z } else { self.cfg.min_height_m };
            let yaw = if yaw.is_finite() { yaw } else { 0.0 };
            return Setpoint::Velocity {
                vx_m_s: 0.0,
                vy_m_s: 0.0,
                z_m: z,
                yaw_rad: yaw,
            };
        }
        clamp_min_height(setpoint, self.cfg.min_height_m)
    }
}
