//! One PID axis in the stock Crazyflie form, with conditional-integration anti-windup.
//!
//! `output = kp·e + ki·∫e dt − kd·(d measured/dt)`, clamped to `±output_limit`; the integral state `∫e dt`
//! is clamped to `±i_limit` exactly like stock `pid.c` (the limit applies to the integral of the error,
//! not to the I term). The derivative acts on the measurement, not on the error, so a setpoint step gives
//! no derivative kick; the caller hands in the measurement's derivative (the gyro for the angle loops, a
//! finite difference for the rate loops, see [`Differentiator`]).
//!
//! Anti-windup (not in stock): the integral does not move in a direction that the caller's [`Gate`]
//! forbids (downstream saturation, on the ground), nor further into this axis' own output saturation.
//!
//! Units are whatever the caller uses (the controller keeps the stock legacy units: degrees, deg/s,
//! 16-bit thrust counts, m, m/s). Memory: 32 bytes per axis. Cost: about 15 flops per update.

/// Gains and limits of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PidGains {
    /// Proportional gain.
    pub kp: f32,
    /// Integral gain.
    pub ki: f32,
    /// Derivative gain (on the measurement).
    pub kd: f32,
    /// Clamp of the integral state `∫e dt` (error units × s), as stock `iLimit`. `f32::INFINITY` = none.
    pub i_limit: f32,
    /// Clamp of the output. `f32::INFINITY` = none.
    pub output_limit: f32,
}

impl PidGains {
    /// Gains with no output limit.
    pub const fn new(kp: f32, ki: f32, kd: f32, i_limit: f32) -> Self {
        Self {
            kp,
            ki,
            kd,
            i_limit,
            output_limit: f32::INFINITY,
        }
    }

    /// The same gains with an output limit.
    pub const fn with_output_limit(self, output_limit: f32) -> Self {
        Self { output_limit, ..self }
    }

    /// All gains finite and non-negative, limits positive (infinity allowed).
    pub fn is_valid(&self) -> bool {
        let gain_ok = |g: f32| g.is_finite() && g >= 0.0;
        gain_ok(self.kp)
            && gain_ok(self.ki)
            && gain_ok(self.kd)
            && !self.i_limit.is_nan()
            && self.i_limit > 0.0
            && !self.output_limit.is_nan()
            && self.output_limit > 0.0
    }
}

/// Which way the integral may move this step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Gate {
    /// The integral may increase.
    pub up: bool,
    /// The integral may decrease.
    pub down: bool,
    /// The integral may only shrink towards zero and never crosses it (on the ground).
    pub toward_zero: bool,
}

impl Gate {
    /// Integrate freely.
    pub const FREE: Gate = Gate {
        up: true,
        down: true,
        toward_zero: false,
    };
    /// Only let the integral decay towards zero (used on the ground).
    pub const TOWARD_ZERO: Gate = Gate {
        up: true,
        down: true,
        toward_zero: true,
    };

    /// Forbid the direction that would push a saturated downstream stage further: `dir > 0` = the stage
    /// is saturated high, `dir < 0` = low, `0` = not saturated.
    pub fn block(self, dir: i8) -> Gate {
        Gate {
            up: self.up && dir <= 0,
            down: self.down && dir >= 0,
            ..self
        }
    }
}

/// One step's result.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PidStep {
    /// The clamped output.
    pub output: f32,
    /// `+1` when the output hit `+output_limit`, `−1` at `−output_limit`, else 0.
    pub saturated: i8,
}

/// The state of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pid {
    /// Gains and limits.
    pub gains: PidGains,
    integ: f32,
}

impl Pid {
    /// A fresh axis.
    pub const fn new(gains: PidGains) -> Self {
        Self { gains, integ: 0.0 }
    }

    /// New gains; the integral is kept, clamped to the new i-limit.
    pub fn set_gains(&mut self, gains: PidGains) {
        self.gains = gains;
        self.integ = self.integ.clamp(-gains.i_limit, gains.i_limit);
    }

    /// Clear the integral.
    pub fn reset(&mut self) {
        self.integ = 0.0;
    }

    /// The integral state `∫e dt`.
    pub fn integral(&self) -> f32 {
        self.integ
    }

    /// One update: `error` = desired − measured, `measured_rate` = d(measured)/dt, `dt_s` > 0.
    /// Non-finite inputs count as zero; a non-finite result resets the axis and outputs 0.
    pub fn update(&mut self, error: f32, measured_rate: f32, dt_s: f32, gate: Gate) -> PidStep {
        let g = &self.gains;
        let e = if error.is_finite() { error } else { 0.0 };
        let dm = if measured_rate.is_finite() { measured_rate } else { 0.0 };
        let dt = if dt_s.is_finite() && dt_s > 0.0 { dt_s } else { 0.0 };
        let p = g.kp * e;
        let d = -g.kd * dm;

        let mut integ = (self.integ + e * dt).clamp(-g.i_limit, g.i_limit);
        if (integ > self.integ && !gate.up) || (integ < self.integ && !gate.down) {
            integ = self.integ;
        }
        if gate.toward_zero && (integ.abs() > self.integ.abs() || integ * self.integ < 0.0) {
            integ = if integ * self.integ < 0.0 { 0.0 } else { self.integ };
        }
        // Do not integrate further into this axis' own saturation.
        let unclamped = p + d + g.ki * integ;
        if (unclamped > g.output_limit && integ > self.integ) || (unclamped < -g.output_limit && integ < self.integ) {
            integ = self.integ;
        }
        let raw = p + d + g.ki * integ;
        if !raw.is_finite() || !integ.is_finite() {
            self.integ = 0.0;
            return PidStep {
                output: 0.0,
                saturated: 0,
            };
        }
        self.integ = integ;
        let saturated = if raw >= g.output_limit {
            1
        } else if raw <= -g.output_limit {
            -1
        } else {
            0
        };
        PidStep {
            output: raw.clamp(-g.output_limit, g.output_limit),
            saturated,
        }
    }
}

/// Finite-difference derivative of a measurement with an optional first-order low-pass (for the rate
/// loops' D term). Stock differentiates unfiltered (`ATTITUDE_RATE_LPF_ENABLE` false), which is the
/// default (`cutoff_hz` = 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Differentiator {
    prev: Option<f32>,
    filtered: f32,
}

impl Differentiator {
    /// No history yet: the first derivative is 0.
    pub const fn new() -> Self {
        Self {
            prev: None,
            filtered: 0.0,
        }
    }

    /// Forget the history.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// d(x)/dt since the previous call; `alpha` ∈ (0, 1] is the low-pass factor (1 = no filter).
    pub fn update(&mut self, x: f32, dt_s: f32, alpha: f32) -> f32 {
        if !(x.is_finite() && dt_s.is_finite() && dt_s > 0.0) {
            return self.filtered;
        }
        let raw = match self.prev {
            Some(p) => (x - p) / dt_s,
            None => 0.0,
        };
        self.prev = Some(x);
        self.filtered += alpha * (raw - self.filtered);
        if !self.filtered.is_finite() {
            self.filtered = 0.0;
        }
        self.filtered
    }
}

impl Default for Differentiator {
    fn default() -> Self {
        Self::new()
    }
}
