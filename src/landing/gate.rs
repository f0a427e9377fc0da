//! Descent gate: decides whether the drone, hovering over its landing target, may descend there.
//!
//! Job: a landing that comes down at a pad's edge with the body's centre just beside the pad touches the
//! pad's side (a collision: the body disc is 6 cm wide). Where the drone believes it is, relative to the pad
//! estimate, is not enough: both drift, and a wrong lock (a turn-back from a wall-side pad, crossings
//! minutes apart) can sit 15–25 cm off. So the gate asks two things before a descent:
//!
//! 1. **Clearance rule, in the estimate frame**: the drone's offset from the pad estimate plus the
//!    estimate's uncertainty must keep the body's centre on the pad's top with a margin:
//!    `offset + uncertainty ≤ half_size − margin`. The uncertainty is the detector's RMS residual (how
//!    much the crossings disagree) plus the flow drift since they were measured (≈ 1 cm/√s), plus one
//!    pad-width term when a coordinate rests on a turn-back or one direction only.
//! 2. **What is under the drone now** (independent of the estimate): the downward ranger's ray gives the
//!    height of the surface under it, `z − range·cos(tilt)`. A pad landing needs a run of readings at the
//!    pad's level; a run at the floor's level refuses (the drone is not over the pad, whatever the
//!    estimate says). A landing clear of the pad (the pad was not found) needs the floor's level, and
//!    refuses a pad top under the drone (the pad's edge may be a few cm away).
//!
//! The mission refines or widens its search after a refusal; the gate never moves the drone.
//!
//! Non-goals: finding the pad ([`crate::landing::pad`]), flying ([`crate::mission`]).
//!
//! Units and frames: metres, seconds, arena frame; heights above the arena floor. Memory: a few bytes;
//! O(1) per reading.

/// Readings at one level, in a row, that decide (40 Hz: 0.1 s).
pub const DECIDING_READINGS: u8 = 4;

/// Flow drift rate the uncertainty assumes, m/√s (the simulated and measured PMW3901 random walk).
pub const DRIFT_M_PER_SQRT_S: f32 = 0.01;

/// What the gate says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Descend now.
    Descend,
    /// Not yet decided: keep hovering over the target.
    Wait,
    /// Do not descend here: the rule failed or the surface under the drone is the wrong one.
    Refuse,
}

/// What the drone means to land on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// A pad's top: the surface under the drone must be the pad.
    PadTop,
    /// The floor beside a pad that was not found: the surface must be the floor.
    Floor,
}

/// Counts the latest surface readings under the drone (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfaceVotes {
    /// Readings in a row at the pad's level (saturating).
    pad_run: u8,
    /// Readings in a row at the floor's level (saturating).
    floor_run: u8,
}

impl SurfaceVotes {
    /// No readings yet.
    pub const fn new() -> Self {
        Self {
            pad_run: 0,
            floor_run: 0,
        }
    }

    /// Forget the readings (the drone moved to a new target).
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// One downward-range reading: `range_m` along the body's −z axis, `cos_tilt` the cosine of the angle
    /// between that axis and the vertical, `height_m` the drone's height above the floor, `pad_height_m`
    /// the pad's height. A surface above half the pad's height is the pad, below it the floor; bad input
    /// (non-finite, negative, a surface above the drone) is ignored.
    pub fn update(&mut self, range_m: f32, cos_tilt: f32, height_m: f32, pad_height_m: f32) {
        let surface = height_m - range_m * cos_tilt;
        let valid = surface.is_finite()
            && range_m > 0.0
            && cos_tilt > 0.5
            && pad_height_m.is_finite()
            && pad_height_m > 0.0
            && surface < height_m - 0.02
            // A wrong range (a VL53L1x stray) far from both levels says nothing.
            && surface > -0.5 * pad_height_m
            && surface < 2.0 * pad_height_m;
        if !valid {
            return;
        }
        if surface > 0.5 * pad_height_m {
            self.pad_run = self.pad_run.saturating_add(1);
            self.floor_run = 0;
        } else {
            self.floor_run = self.floor_run.saturating_add(1);
            self.pad_run = 0;
        }
    }

    /// Readings in a row at the pad's level.
    pub fn pad_run(&self) -> u8 {
        self.pad_run
    }

    /// Readings in a row at the floor's level.
    pub fn floor_run(&self) -> u8 {
        self.floor_run
    }
}

/// The clearance rule's inputs (module docs, item 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clearance {
    /// Pad side, m (square pad).
    pub pad_size_m: f32,
    /// Margin kept between the body's centre and the pad's edge, m.
    pub margin_m: f32,
}

impl Clearance {
    /// The pad estimate's uncertainty, m: its RMS residual, the drift since its crossings
    /// (`age_s`), and a pad width's worth when a coordinate was not measured by two-sided crossings.
    pub fn uncertainty_m(&self, rms_residual_m: f32, age_s: f32, both_directions: bool) -> f32 {
        if !(rms_residual_m.is_finite() && age_s.is_finite()) {
            return f32::INFINITY;
        }
        let drift = DRIFT_M_PER_SQRT_S * libm::sqrtf(age_s.max(0.0));
        let unmeasured = if both_directions { 0.0 } else { 0.5 * self.pad_size_m };
        rms_residual_m.max(0.0) + drift + unmeasured
    }

    /// Whether a drone `offset_m` from the pad estimate (in the estimate frame), with `uncertainty_m`,
    /// keeps its centre on the pad's top with the margin. NaN anywhere is `false`.
    pub fn allows(&self, offset_m: f32, uncertainty_m: f32) -> bool {
        offset_m + uncertainty_m <= 0.5 * self.pad_size_m - self.margin_m
    }
}

/// The verdict over a target: the clearance rule (pads only, `rule_ok`) and, once the drone hovers there
/// (`settled`; the caller clears the votes while it does not), the surface votes.
pub fn verdict(target: Target, rule_ok: bool, settled: bool, votes: &SurfaceVotes) -> Verdict {
    let (wanted, wrong) = match target {
        Target::PadTop => (votes.pad_run(), votes.floor_run()),
        Target::Floor => (votes.floor_run(), votes.pad_run()),
    };
    if !settled {
        return Verdict::Wait;
    }
    if target == Target::PadTop && !rule_ok {
        return Verdict::Refuse;
    }
    if wrong >= 2 * DECIDING_READINGS {
        return Verdict::Refuse;
    }
    if wanted >= DECIDING_READINGS {
        return Verdict::Descend;
    }
    Verdict::Wait
}
