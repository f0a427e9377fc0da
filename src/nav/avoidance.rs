//! Reactive obstacle avoidance from the Multi-ranger deck's four horizontal rangers.
//!
//! Job: turn the path follower's desired velocity into a safe velocity command. Each step takes the four
//! horizontal ranges, the yaw, the desired arena-frame velocity and the time step; it returns the velocity
//! to command plus diagnostics. The pipeline is
//!
//! 1. **repulsion** from every ranger that sees something inside the danger distance `d0`, by one of two
//!    methods chosen by [`AvoidanceMethod`]:
//!    * [`AvoidanceMethod::PotentialField`], the seed's law: per ranger `((d0 − d)/d0)²`, pushing opposite
//!      to the beam;
//!    * [`AvoidanceMethod::VirtualForceField`]: per ranger `tanh(k·(d0 − d)/d)`, which grows like `1/d`
//!      near the obstacle but saturates smoothly at 1, **plus velocity damping**: the part of the desired
//!      velocity that points at a near obstacle is reduced in proportion to the proximity `(d0 − d)/d0`;
//! 2. **dead band and hysteresis** (both methods): the repulsion engages once the net force exceeds the
//!    dead band, and releases only when every ranger reads more than `d0 + hysteresis`. While engaged it
//!    acts in full, so it stays continuous and fades to zero at `d0`; the only jump (at engagement) is
//!    small and smoothed. Grazing readings near `d0` therefore neither wobble the drone nor make the
//!    `active` flag chatter;
//! 3. the repulsion (times the gain, m/s) is rotated body → arena with the yaw and added to the desired
//!    velocity;
//! 4. **exponential smoothing** with time constant `τ` (`α = 1 − e^(−dt/τ)`, exact for any `dt`);
//! 5. a **speed clamp**: the allowed speed falls linearly from the cruise speed at the slow-down distance
//!    to the minimum speed at `d0`, judged on the nearest valid range ([`SpeedClamp::Nearest`]), or, per
//!    ranger, on the speed towards that ranger's obstacle ([`SpeedClamp::TowardsEachRange`]). The clamp
//!    comes last, so the command never exceeds it (up to f32 rounding); the filter's state is the clamped
//!    command.
//!
//! Non-goals: planning around obstacles (the planner does that on the map), vertical avoidance (the up
//! ranger is not used), and detecting obstacles the beams miss: four beams see four directions only.
//!
//! Units and frames: metres, seconds, m/s, radians. Ranges are in the body frame (x forward, y left;
//! the front ranger looks along +x, back −x, left +y, right −y). Velocities in and out are in the arena
//! frame (x right, y up); `arena = R(yaw)·body` with yaw counter-clockwise positive, 0 looking along +x.
//!
//! Robustness: a range that is `None`, NaN, infinite, negative or beyond [`AvoidanceConfig::max_range_m`]
//! counts as "no return". A non-finite desired velocity component is taken as 0. A non-finite yaw is
//! replaced by the last finite yaw; before any finite yaw was seen, no repulsion is applied (its
//! direction would be a guess) but the speed clamp still is. A `dt` that is not a positive finite
//! number advances no time: the previous command is held (and re-clamped). The output is always finite.
//!
//! Memory: [`ReactiveAvoidance`] is 68 bytes (the config, an engaged flag, the last yaw and command).
//! Complexity: O(1) per step (four rangers, one `expf`, a few `tanhf`/`sinf`/`cosf`).

use crate::types::MultiRangerSample;

/// Body-frame unit vectors of the beams, in the order of [`RangerReadings`]' fields: front, back, left,
/// right. They form two opposite pairs along orthogonal axes, which the damping relies on.
const BEAMS: [(f32, f32); 4] = MultiRangerSample::HORIZONTAL_BEAMS_BODY;

/// Desired speeds above this are scaled down before any arithmetic, so no intermediate can overflow.
/// It is far above anything a Crazyflie flies; the final clamp brings the command down to cruise anyway.
const SANE_SPEED_MPS: f32 = 100.0;

/// Smallest range used in a division (the VFF law divides by the range), metres.
const MIN_DIVISOR_M: f32 = 1e-3;

/// Which repulsion law [`ReactiveAvoidance`] uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AvoidanceMethod {
    /// The seed's potential field: `((d0 − d)/d0)²` per ranger, with dead band and hysteresis.
    #[default]
    PotentialField,
    /// Virtual force field: `tanh(k·(d0 − d)/d)` per ranger plus damping of the velocity towards
    /// near obstacles.
    VirtualForceField,
}

/// What the speed clamp (step 5 of the pipeline) limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SpeedClamp {
    /// The whole speed, by the nearest valid range in any direction (the seed's clamp): a wall beside or
    /// behind the drone slows it as much as one ahead.
    #[default]
    Nearest,
    /// The speed towards each ranger's obstacle, by that ranger's range: the command is scaled down
    /// (direction kept) until, for every valid range `d`, its component along that beam is at most
    /// [`AvoidanceConfig::speed_limit`]`(d)`, and its norm at most the cruise speed. Flying along a wall at
    /// cruise is then allowed, flying into it is not. Needs the yaw; before a finite yaw was seen it falls
    /// back to [`SpeedClamp::Nearest`].
    TowardsEachRange,
}

/// Tuning of [`ReactiveAvoidance`]. [`Default`] gives the values below; all must be finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AvoidanceConfig {
    /// Repulsion law. Default: [`AvoidanceMethod::PotentialField`] (the seed's, flight-proven).
    pub method: AvoidanceMethod,
    /// Danger distance `d0`, metres: rangers closer than this repel. Default 0.4 m: about two drone
    /// diameters plus the ranger's ±2–3 cm error; the planner's inflation keeps planned paths further away,
    /// so this only fires for obstacles the map missed.
    pub danger_distance_m: f32,
    /// Hysteresis, metres: once engaged, avoidance stays engaged until every ranger reads more than
    /// `d0 + hysteresis`. Default 0.05 m (the seed's), well above the ranger noise, so the engaged flag
    /// and the dead-band jump do not chatter when hovering near `d0`.
    pub hysteresis_m: f32,
    /// Dead band on the net (dimensionless, before gain) force: smaller forces do not engage avoidance.
    /// Default 0.05 (the seed's): with the potential field this is a ranger at ~0.78·d0, so grazing
    /// readings near `d0` do not make the drone wobble.
    pub dead_band: f32,
    /// Gain, m/s per unit force. Default 0.5 m/s (seed range 0.3–0.7): a wall at d0/2 then pushes back at
    /// 0.125 m/s (potential field) or 0.38 m/s (VFF), enough to beat the 0.3–0.4 m/s cruise only close in.
    pub gain_mps: f32,
    /// Steepness `k` of the VFF law `tanh(k·(d0 − d)/d)`. Default 1.0: force 0.25 at 0.8·d0, 0.76 at d0/2,
    /// ≥ 0.99 closer than d0/4.
    pub vff_steepness: f32,
    /// VFF damping factor in [0, 1]: the fraction of the velocity component towards an obstacle removed
    /// per unit proximity. Default 1.0: that component is gone when touching, halved at d0/2.
    pub vff_damping: f32,
    /// Smoothing time constant `τ`, seconds (0 = no smoothing). Default 0.2 s: removes the ranger's
    /// sample-to-sample jitter (it updates at ~10–20 Hz) without a lag that matters at 0.4 m/s (8 cm).
    pub smoothing_tau_s: f32,
    /// Speed allowed when nothing is near, m/s. Default 0.4 m/s: a safe Crazyflie indoor cruise speed.
    pub cruise_speed_mps: f32,
    /// Speed allowed at or inside the danger distance, m/s. Default 0.1 m/s: slow enough to stop within a
    /// few cm, fast enough to back off.
    pub min_speed_mps: f32,
    /// Range at which slowing down starts, metres (≥ `d0`). Default 0.8 m: 0.4 m of ramp at ≤ 0.4 m/s
    /// is a second of reaction time.
    pub slow_down_distance_m: f32,
    /// Ranges above this are "no return", metres. Default 4.0 m: the VL53L1x's long-distance limit.
    pub max_range_m: f32,
    /// What the speed clamp limits. Default [`SpeedClamp::Nearest`] (the seed's).
    pub clamp: SpeedClamp,
}

impl Default for AvoidanceConfig {
    fn default() -> Self {
        Self {
            method: AvoidanceMethod::PotentialField,
            danger_distance_m: 0.4,
            hysteresis_m: 0.05,
            dead_band: 0.05,
            gain_mps: 0.5,
            vff_steepness: 1.0,
            vff_damping: 1.0,
            smoothing_tau_s: 0.2,
            cruise_speed_mps: 0.4,
            min_speed_mps: 0.1,
            slow_down_distance_m: 0.8,
            max_range_m: 4.0,
            clamp: SpeedClamp::Nearest,
        }
    }
}

/// Why an [`AvoidanceConfig`] was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AvoidanceConfigError {
    /// A field is NaN or infinite.
    NonFinite,
    /// `danger_distance_m` or `vff_steepness` is not positive, or `max_range_m ≤ danger_distance_m`.
    NonPositive,
    /// `hysteresis_m`, `dead_band`, `gain_mps`, `smoothing_tau_s` or `min_speed_mps` is negative, or
    /// `vff_damping` is outside [0, 1].
    OutOfRange,
    /// `min_speed_mps > cruise_speed_mps` or `slow_down_distance_m < danger_distance_m`.
    Inconsistent,
}

impl AvoidanceConfig {
    /// Checks the config; [`ReactiveAvoidance::new`] calls this.
    pub fn validate(&self) -> Result<(), AvoidanceConfigError> {
        let all = [
            self.danger_distance_m,
            self.hysteresis_m,
            self.dead_band,
            self.gain_mps,
            self.vff_steepness,
            self.vff_damping,
            self.smoothing_tau_s,
            self.cruise_speed_mps,
            self.min_speed_mps,
            self.slow_down_distance_m,
            self.max_range_m,
        ];
        if all.iter().any(|v| !v.is_finite()) {
            return Err(AvoidanceConfigError::NonFinite);
        }
        if self.danger_distance_m <= 0.0 || self.vff_steepness <= 0.0 || self.max_range_m <= self.danger_distance_m {
            return Err(AvoidanceConfigError::NonPositive);
        }
        let non_negative = [
            self.hysteresis_m,
            self.dead_band,
            self.gain_mps,
            self.smoothing_tau_s,
            self.min_speed_mps,
        ];
        if non_negative.iter().any(|&v| v < 0.0) || !(0.0..=1.0).contains(&self.vff_damping) {
            return Err(AvoidanceConfigError::OutOfRange);
        }
        if self.min_speed_mps > self.cruise_speed_mps || self.slow_down_distance_m < self.danger_distance_m {
            return Err(AvoidanceConfigError::Inconsistent);
        }
        Ok(())
    }

    /// The speed the clamp allows when the nearest valid range is `nearest_m` (`None`: nothing seen).
    ///
    /// Linear from `min_speed_mps` at `d0` (and closer) to `cruise_speed_mps` at the slow-down distance
    /// (and further).
    pub fn speed_limit(&self, nearest_m: Option<f32>) -> f32 {
        let Some(d) = nearest_m else {
            return self.cruise_speed_mps;
        };
        let ramp = self.slow_down_distance_m - self.danger_distance_m;
        // A zero-length ramp is a step at d0; avoid dividing by zero.
        let t = if ramp > 1e-6 {
            ((d - self.danger_distance_m) / ramp).clamp(0.0, 1.0)
        } else if d >= self.danger_distance_m {
            1.0
        } else {
            0.0
        };
        self.min_speed_mps + (self.cruise_speed_mps - self.min_speed_mps) * t
    }
}

/// The four horizontal ranges of one step, metres; `None` means no return. Invalid values (NaN, ±∞,
/// negative, beyond the configured maximum) are also treated as no return.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct RangerReadings {
    /// Front ranger (body +x).
    pub front: Option<f32>,
    /// Back ranger (body −x).
    pub back: Option<f32>,
    /// Left ranger (body +y).
    pub left: Option<f32>,
    /// Right ranger (body −y).
    pub right: Option<f32>,
}

impl RangerReadings {
    /// Readings from front, back, left, right.
    pub const fn new(front: Option<f32>, back: Option<f32>, left: Option<f32>, right: Option<f32>) -> Self {
        Self {
            front,
            back,
            left,
            right,
        }
    }

    /// No ranger sees anything.
    pub const NONE: Self = Self::new(None, None, None, None);

    fn as_array(&self) -> [Option<f32>; 4] {
        [self.front, self.back, self.left, self.right]
    }
}

/// The result of one [`ReactiveAvoidance::step`].
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AvoidanceCommand {
    /// Velocity to command along arena x, m/s (smoothed and clamped; always finite).
    pub vx: f32,
    /// Velocity to command along arena y, m/s (smoothed and clamped; always finite).
    pub vy: f32,
    /// The repulsion added this step along arena x, m/s (before smoothing; 0 when not engaged).
    pub repulsion_x: f32,
    /// The repulsion added this step along arena y, m/s (before smoothing; 0 when not engaged).
    pub repulsion_y: f32,
    /// Nearest valid horizontal range, metres.
    pub nearest_m: Option<f32>,
    /// Whether avoidance is engaged (a repulsion or damping acts on the command).
    pub active: bool,
    /// The speed the clamp allowed this step, m/s ([`SpeedClamp::TowardsEachRange`]: in the command's
    /// direction).
    pub speed_limit_mps: f32,
}

/// Reactive avoidance state machine; see the module docs.
#[derive(Clone, Debug)]
pub struct ReactiveAvoidance {
    config: AvoidanceConfig,
    /// Engaged state of the dead band / hysteresis (see [`AvoidanceConfig::hysteresis_m`]).
    engaged: bool,
    /// Last finite yaw, for steps whose yaw is NaN.
    last_yaw: Option<f32>,
    /// Last command (after the clamp): the smoothing filter's state.
    last: (f32, f32),
}

impl ReactiveAvoidance {
    /// An avoider with a validated config, at rest (last command zero).
    pub fn new(config: AvoidanceConfig) -> Result<Self, AvoidanceConfigError> {
        config.validate()?;
        Ok(Self {
            config,
            engaged: false,
            last_yaw: None,
            last: (0.0, 0.0),
        })
    }

    /// The config in use.
    pub fn config(&self) -> &AvoidanceConfig {
        &self.config
    }

    /// Forgets the filter state, the engaged flag and the last yaw (e.g. after landing).
    pub fn reset(&mut self) {
        self.engaged = false;
        self.last_yaw = None;
        self.last = (0.0, 0.0);
    }

    /// A range as the config sees it: `Some(d)` only for a finite `0 ≤ d ≤ max_range_m`.
    fn valid_range(&self, r: Option<f32>) -> Option<f32> {
        r.filter(|d| d.is_finite() && *d >= 0.0 && *d <= self.config.max_range_m)
    }

    /// One control step.
    ///
    /// `ranges`: the horizontal ranges; `yaw_rad`: heading (arena frame); `desired_vx/vy_mps`: the path
    /// follower's arena-frame velocity; `dt_s`: time since the previous step.
    pub fn step(
        &mut self,
        ranges: &RangerReadings,
        yaw_rad: f32,
        desired_vx_mps: f32,
        desired_vy_mps: f32,
        dt_s: f32,
    ) -> AvoidanceCommand {
        let cfg = self.config;
        let d0 = cfg.danger_distance_m;
        let valid = ranges.as_array().map(|r| self.valid_range(r));
        let nearest_m = valid.iter().flatten().copied().reduce(f32::min);

        if yaw_rad.is_finite() {
            // Keep it in [-π, π] so sin/cos stay accurate however many turns the estimator has counted.
            self.last_yaw = Some(libm::remainderf(yaw_rad, 2.0 * core::f32::consts::PI));
        }
        let rotation = self.last_yaw.map(|yaw| (libm::cosf(yaw), libm::sinf(yaw)));

        let mut desired = sanitize_velocity(desired_vx_mps, desired_vy_mps);

        // Per-ranger force magnitudes (dimensionless, ≥ 0) and the net body-frame force.
        // Proximity (d0 − d)/d0 ∈ (0, 1] of each ranger inside d0, else 0.
        let proximity = valid.map(|d| match d {
            Some(d) if d < d0 => (d0 - d) / d0,
            _ => 0.0,
        });
        let forces = valid.map(|d| match d {
            Some(d) if d < d0 => match cfg.method {
                AvoidanceMethod::PotentialField => ((d0 - d) / d0) * ((d0 - d) / d0),
                AvoidanceMethod::VirtualForceField => libm::tanhf(cfg.vff_steepness * (d0 - d) / d.max(MIN_DIVISOR_M)),
            },
            _ => 0.0,
        });
        let (mut fx, mut fy) = (0.0f32, 0.0f32);
        for (f, (bx, by)) in forces.iter().zip(BEAMS) {
            fx -= f * bx;
            fy -= f * by;
        }
        let net = libm::hypotf(fx, fy);

        // Engage when the net force leaves the dead band; release only when nothing is inside d0 + hysteresis.
        // While engaged, the force is applied without the dead band, so it stays continuous and goes to
        // zero smoothly as the obstacle recedes to d0.
        let release_at = d0 + cfg.hysteresis_m;
        if self.engaged {
            if nearest_m.is_none_or(|d| d > release_at) {
                self.engaged = false;
            }
        } else if net > cfg.dead_band {
            self.engaged = true;
        }

        let mut repulsion = (0.0f32, 0.0f32);
        if let Some((c, s)) = rotation {
            if self.engaged {
                let (bx, by) = (fx * cfg.gain_mps, fy * cfg.gain_mps);
                repulsion = (c * bx - s * by, s * bx + c * by);
            }
            if cfg.method == AvoidanceMethod::VirtualForceField {
                // Damping is proportional to proximity, hence continuous at d0: no dead band needed.
                // The beams are two opposite pairs on orthogonal axes, so at most one beam per axis has a
                // positive component of the velocity along it, and the reductions do not interact.
                for (p, (bx, by)) in proximity.iter().zip(BEAMS) {
                    if *p <= 0.0 {
                        continue;
                    }
                    let (ux, uy) = (c * bx - s * by, s * bx + c * by);
                    let towards = desired.0 * ux + desired.1 * uy;
                    if towards > 0.0 {
                        let cut = cfg.vff_damping * p * towards;
                        desired = (desired.0 - cut * ux, desired.1 - cut * uy);
                    }
                }
            }
        }
        let damping_acts = cfg.method == AvoidanceMethod::VirtualForceField && proximity.iter().any(|p| *p > 0.0);

        let raw = (desired.0 + repulsion.0, desired.1 + repulsion.1);

        // Exponential smoothing; α = 1 − e^(−dt/τ) is the exact discretisation of a first-order lag, so
        // the response does not depend on the step rate. Invalid dt: hold.
        let alpha = if !(dt_s.is_finite() && dt_s > 0.0) {
            0.0
        } else if cfg.smoothing_tau_s <= 0.0 {
            1.0
        } else {
            1.0 - libm::expf(-dt_s / cfg.smoothing_tau_s)
        };
        let smoothed = (
            self.last.0 + alpha * (raw.0 - self.last.0),
            self.last.1 + alpha * (raw.1 - self.last.1),
        );

        let (out, speed_limit_mps) = match (cfg.clamp, rotation) {
            (SpeedClamp::TowardsEachRange, Some((c, s))) => {
                // The largest scale k ≤ 1 of the smoothed command that keeps its norm within cruise and
                // its component along every beam with a return within that beam's limit.
                let smoothed = if smoothed.0.is_finite() && smoothed.1.is_finite() {
                    smoothed
                } else {
                    (0.0, 0.0)
                };
                let speed = libm::hypotf(smoothed.0, smoothed.1);
                let mut k = if speed > cfg.cruise_speed_mps && speed > 0.0 {
                    cfg.cruise_speed_mps / speed
                } else {
                    1.0
                };
                for (d, (bx, by)) in valid.iter().zip(BEAMS) {
                    let Some(d) = d else { continue };
                    let (ux, uy) = (c * bx - s * by, s * bx + c * by);
                    let towards = smoothed.0 * ux + smoothed.1 * uy;
                    let limit = cfg.speed_limit(Some(*d));
                    if towards > limit {
                        k = k.min(limit / towards);
                    }
                }
                let out = (smoothed.0 * k, smoothed.1 * k);
                // The speed this direction was allowed: the command itself when the clamp cut it.
                let allowed = if k < 1.0 {
                    libm::hypotf(out.0, out.1)
                } else {
                    cfg.cruise_speed_mps
                };
                (out, allowed)
            }
            _ => {
                let limit = cfg.speed_limit(nearest_m);
                (clamp_speed(smoothed, limit), limit)
            }
        };
        self.last = out;

        AvoidanceCommand {
            vx: out.0,
            vy: out.1,
            repulsion_x: repulsion.0,
            repulsion_y: repulsion.1,
            nearest_m,
            active: (self.engaged || damping_acts) && rotation.is_some(),
            speed_limit_mps,
        }
    }
}

/// Non-finite components become 0; absurd speeds are scaled down to [`SANE_SPEED_MPS`].
fn sanitize_velocity(vx: f32, vy: f32) -> (f32, f32) {
    let vx = if vx.is_finite() { vx } else { 0.0 };
    let vy = if vy.is_finite() { vy } else { 0.0 };
    // Scale each component first so the norm cannot overflow.
    let big = vx.abs().max(vy.abs());
    if big > SANE_SPEED_MPS {
        let (sx, sy) = (vx / big, vy / big);
        let n = libm::hypotf(sx, sy);
        (sx / n * SANE_SPEED_MPS, sy / n * SANE_SPEED_MPS)
    } else {
        (vx, vy)
    }
}

/// Scales `v` down (direction kept) so its norm is at most `limit`; a non-finite `v` becomes zero.
fn clamp_speed(v: (f32, f32), limit: f32) -> (f32, f32) {
    if !(v.0.is_finite() && v.1.is_finite()) {
        return (0.0, 0.0);
    }
    let speed = libm::hypotf(v.0, v.1);
    if speed > limit && speed > 0.0 {
        let k = limit / speed;
        (v.0 * k, v.1 * k)
    } else {
        v
    }
}
