//! The surface tracker: decides, for every downward range, whether it measures the drone's height or a step
//! in the surface below (the "pad step", anchors-peers-planning-style.md §A.4).
//!
//! Each range becomes an *implied surface height* `u = z − r·cos α` (the height of whatever the beam hits,
//! given the current height estimate `z`). `u` is computed with the IMU-propagated `z`, so a real climb or
//! descent moves `z` and `r` together and leaves `u` unchanged; only what the IMU did not see moves `u`: a
//! height error (slowly, the drift the range is there to correct) or the surface itself (in a step, as
//! the drone flies onto or off an object). Every later correction of `z` shifts the stored `u`s by the same
//! amount ([`SurfaceTracker::shift`]), so they stay referred to the current estimate.
//!
//! The last [`RING`] values are kept (a 50 ms decision delay at 40 Hz). In the `Settled` mode:
//!
//! * the ring is *flat* (spread ≤ `max(flat_sigma·σ, flat_min)`) and its oldest value agrees with the
//!   current surface `s` (|u − s| ≤ `max(gate_sigma·√(P_zz + σ²), gate_min)`): that value is an ordinary
//!   height measurement and goes to the Kalman filter (so a slow ramp *is* followed as height);
//! * the ring is not flat: something moved faster than noise allows → `Transition`. Nothing from the
//!   transition reaches the filter; the height coasts on the IMU;
//! * the ring is flat but away from `s` (only after a gap in the ranges): classified as below.
//!
//! In `Transition` the ring slides until it is flat again (a plateau); the plateau's mean `level` is then
//! classified ([`SurfaceEvent`]):
//!
//! | condition | verdict |
//! |---|---|
//! | \|level − s\| within the gate | a glitch (single wild readings end here): back to normal |
//! | level < −`floor_tol` | the floor is the lowest surface there is, so `z` is wrong: `s = 0`, re-anchor `z` |
//! | \|level − s\| ≥ `step_min` and ≥ `step_sigma`·σ_z | a surface step: `s = level`, snapped to exactly 0 when \|level\| ≤ `snap` |
//! | otherwise (a small jump, or `z` itself uncertain) | a height error: re-anchor `z` |
//!
//! "Re-anchor" inflates `P_zz` by the jump², so that the plateau's values pull `z` onto the new level at
//! once instead of dragging it there over many samples. A transition that finds no plateau within
//! `max_transition` samples is classified on its median.
//!
//! The same mean surface is what the flow model needs (the camera sees the surface, not the floor); during a
//! transition [`SurfaceTracker::flow_surface`] gives the median of the ring, the best guess of what is
//! below right now.

/// Ranges kept for a decision: the newest value is judged together with the two after it (50 ms at 40 Hz).
pub(crate) const RING: usize = 3;

/// One range, as the surface it implies.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Entry {
    /// Implied surface height `z − r·cos α`, referred to the current height estimate, m.
    pub u: f32,
    /// Variance of the range's height component `(σ_r·cos α)²`, m².
    pub var: f32,
    /// Arrival time, ms (wrapping): a plateau must be made of consecutive ranges.
    pub t_ms: u32,
}

/// Whether the tracker is following the surface or waiting for a step to settle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SurfaceMode {
    /// Ranges are height measurements.
    #[default]
    Settled,
    /// The range jumped; the height coasts on the IMU until a plateau is found.
    Transition,
}

/// The last classification of a plateau.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SurfaceEvent {
    /// Nothing classified yet.
    #[default]
    None,
    /// The range jumped and came back (a wild reading): no change.
    Glitch,
    /// A step in the surface: `surface_height_m` changed, the height did not.
    Step,
    /// A step down onto the floor: the surface snapped to exactly 0.
    StepToFloor,
    /// The range implied a surface below the floor: the height estimate was re-anchored instead.
    BelowFloor,
    /// A jump too small for a step, or with the height itself uncertain: the height was re-anchored.
    HeightError,
}

/// Thresholds, from [`super::EstimatorConfig`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Params {
    pub step_min: f32,
    pub snap: f32,
    pub floor_tol: f32,
    pub gate_sigma: f32,
    pub gate_min: f32,
    pub flat_sigma: f32,
    pub flat_min: f32,
    pub step_sigma: f32,
    pub max_transition: u16,
    /// Longest time span of a ring that counts as consecutive ranges, ms.
    pub max_span_ms: u32,
    /// Ranges after a step during which the surface, not the height, follows the plateau.
    pub settle: u16,
}

/// What the estimator must do with the filter after a range: inflate `P_zz`, then apply these values as
/// ordinary height updates, oldest first.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Plan {
    /// Add to the height variance: the height is being re-anchored.
    pub inflate_var: f32,
    /// Add to the vertical-velocity variance: a sudden height error means an unseen vertical velocity.
    pub inflate_vz: f32,
    pub apply: [Entry; RING],
    pub n_apply: usize,
    /// A plateau was classified (the ranges said something about the height or the surface).
    pub concluded: bool,
}

impl Plan {
    pub(crate) fn entries(&self) -> impl Iterator<Item = &Entry> {
        self.apply.iter().take(self.n_apply)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SurfaceTracker {
    /// Current surface height above the arena floor, m (≥ 0).
    s: f32,
    ring: [Entry; RING],
    len: usize,
    mode: SurfaceMode,
    transition_len: u16,
    /// Ranges left in the settling period after a step (module docs).
    settle_left: u16,
    /// Steps attributed to the surface so far.
    pub steps: u32,
    /// Size of the last step (new − old surface height), m.
    pub last_step_m: f32,
    /// Ranges that never reached the filter (inside transitions).
    pub discarded: u32,
    pub last_event: SurfaceEvent,
}

impl SurfaceTracker {
    pub(crate) const fn new(s: f32) -> Self {
        Self {
            s,
            ring: [Entry { u: 0.0, var: 0.0, t_ms: 0 }; RING],
            len: 0,
            mode: SurfaceMode::Settled,
            transition_len: 0,
            settle_left: 0,
            steps: 0,
            last_step_m: 0.0,
            discarded: 0,
            last_event: SurfaceEvent::None,
        }
    }

    /// Start over on a known surface (a reset on the pad): counters are kept.
    pub(crate) fn reset(&mut self, s: f32) {
        self.s = if s.is_finite() { s.max(0.0) } else { 0.0 };
        self.clear();
    }

    /// Forget the ring (after a gap in the ranges or a filter reset); the surface is kept.
    pub(crate) fn clear(&mut self) {
        self.len = 0;
        self.mode = SurfaceMode::Settled;
        self.transition_len = 0;
        self.settle_left = 0;
    }

    pub(crate) fn surface(&self) -> f32 {
        self.s
    }

    pub(crate) fn mode(&self) -> SurfaceMode {
        self.mode
    }

    /// The height estimate was corrected by `dz`: the stored implied surfaces move with it.
    pub(crate) fn shift(&mut self, dz: f32) {
        if dz.is_finite() {
            for e in self.ring.iter_mut() {
                e.u += dz;
            }
        }
    }

    /// The surface the flow camera most likely sees now (see the module docs).
    pub(crate) fn flow_surface(&self) -> f32 {
        if self.mode == SurfaceMode::Transition && self.len == RING {
            median3(&self.ring).max(0.0)
        } else {
            self.s
        }
    }

    /// One new range; `p_zz` and `p_vz` are the filter's current height and vertical-velocity variances.
    pub(crate) fn push(&mut self, e: Entry, p_zz: f32, p_vz: f32, p: &Params) -> Plan {
        if !(e.u.is_finite() && e.var.is_finite() && e.var >= 0.0) {
            return Plan::default();
        }
        self.push_ring(e);
        if self.len < RING {
            return Plan::default();
        }
        let flat = self.is_flat(p, p_vz) && !self.is_trending(p_vz);
        // A plateau is three *consecutive* ranges: values spread out in time by rejected readings between
        // them (garbage, dropouts) can agree by accident and must not move the surface.
        let consecutive = self.ring[RING - 1].t_ms.wrapping_sub(self.ring[0].t_ms) <= p.max_span_ms;
        let settling = self.settle_left > 0;
        self.settle_left = self.settle_left.saturating_sub(1);
        match self.mode {
            SurfaceMode::Settled => {
                let level = self.mean();
                // Two standard deviations of a mean of three: the level has stopped moving.
                let still = (level - self.s).abs() <= (2.0 * libm::sqrtf(self.mean_var() / 3.0)).max(SETTLED_M);
                if settling && flat && consecutive && still {
                    // The step is complete (at once for a sharp one): back to height updates.
                    self.settle_left = 0;
                } else if settling && flat && consecutive && (level - self.s).abs() < p.step_min {
                    // The tail of a blurred step: the surface follows, the height is left alone (it coasts on
                    // the IMU, so this must not last long).
                    self.s = level.max(0.0);
                    if self.s <= p.snap {
                        self.s = 0.0;
                        self.settle_left = 0;
                    }
                    self.pop_oldest();
                    self.discarded = self.discarded.saturating_add(1);
                    return Plan { concluded: true, ..Plan::default() };
                }
                let settling = self.settle_left > 0;
                let agree = self.ring.iter().all(|e| (e.u - self.s).abs() <= gate(p, p_zz, e.var));
                if flat && agree && !settling {
                    let mut plan = Plan::default();
                    plan.apply[0] = self.ring[0];
                    plan.n_apply = 1;
                    self.pop_oldest();
                    return plan;
                }
                if flat && consecutive {
                    let level = self.mean();
                    return self.conclude(level, p_zz, p, Conclusion::Plateau);
                }
                self.mode = SurfaceMode::Transition;
                self.transition_len = 0;
                Plan::default()
            }
            SurfaceMode::Transition => {
                self.transition_len = self.transition_len.saturating_add(1);
                if flat && consecutive {
                    let level = self.mean();
                    self.conclude(level, p_zz, p, Conclusion::Plateau)
                } else if self.transition_len >= p.max_transition && consecutive {
                    let (a, b, c) = (self.ring[0].u, self.ring[1].u, self.ring[2].u);
                    if (a <= b && b <= c) || (a >= b && b >= c) {
                        // Still moving the same way after max_transition ranges: not a step but a vertical
                        // motion the IMU did not see (or a slope): the height follows the newest value.
                        self.conclude(c, p_zz, p, Conclusion::Drift)
                    } else {
                        // Flickering (hovering over an edge): decide on the median, fuse nothing.
                        let level = median3(&self.ring);
                        self.conclude(level, p_zz, p, Conclusion::Undecided)
                    }
                } else {
                    Plan::default()
                }
            }
        }
    }

    fn pop_oldest(&mut self) {
        self.ring.copy_within(1.., 0);
        self.len = self.len.saturating_sub(1);
    }

    fn push_ring(&mut self, e: Entry) {
        if let Some(slot) = self.ring.get_mut(self.len) {
            *slot = e;
            self.len += 1;
        } else {
            // Full: the oldest leaves unused (only in a transition; a settled ring always has room).
            self.ring.copy_within(1.., 0);
            self.ring[RING - 1] = e;
            self.discarded = self.discarded.saturating_add(1);
        }
    }

    /// The ring's values agree: their spread is within `flat_sigma` standard deviations of what the range
    /// noise and the vertical-velocity uncertainty over the ring's time span allow (or `flat_min`).
    fn is_flat(&self, p: &Params, p_vz: f32) -> bool {
        let (mut lo, mut hi, mut var) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f32);
        for e in self.ring.iter().take(self.len) {
            lo = lo.min(e.u);
            hi = hi.max(e.u);
            var = var.max(e.var);
        }
        let span_s = self.ring[self.len.clamp(1, RING) - 1].t_ms.wrapping_sub(self.ring[0].t_ms) as f32 * 1e-3;
        let drift_var = p_vz.max(0.0) * span_s * span_s;
        hi - lo <= (p.flat_sigma * libm::sqrtf(var + drift_var)).max(p.flat_min)
    }

    /// The ring moves one way by more than two standard deviations of a difference of two values: the
    /// middle of a ramp, even if its spread is small (a blurred step crossed slowly).
    fn is_trending(&self, p_vz: f32) -> bool {
        let (a, b, c) = (self.ring[0], self.ring[1], self.ring[2]);
        let monotonic = (a.u <= b.u && b.u <= c.u) || (a.u >= b.u && b.u >= c.u);
        let span_s = c.t_ms.wrapping_sub(a.t_ms) as f32 * 1e-3;
        let diff_var = a.var + c.var + p_vz.max(0.0) * span_s * span_s;
        monotonic && (c.u - a.u).abs() > (2.0 * libm::sqrtf(diff_var)).max(TREND_MIN_M)
    }

    fn mean(&self) -> f32 {
        let n = self.len.max(1) as f32;
        self.ring.iter().take(self.len).map(|e| e.u).sum::<f32>() / n
    }

    fn mean_var(&self) -> f32 {
        let n = self.len.max(1) as f32;
        self.ring.iter().take(self.len).map(|e| e.var).sum::<f32>() / n
    }

    /// Classify a plateau at `level` (module docs), empty the ring and say what the filter must do.
    fn conclude(&mut self, level: f32, p_zz: f32, p: &Params, how: Conclusion) -> Plan {
        let var = self.mean_var();
        let jump = level - self.s;
        let settling = self.settle_left > 0;
        // A height error of this size would be improbable (≥ step_sigma·σ_z): it is the surface.
        let z_known = jump.abs() >= p.step_sigma * libm::sqrtf(p_zz.max(0.0));
        let mut plan = Plan { concluded: true, ..Plan::default() };
        if how == Conclusion::Drift {
            self.last_event = SurfaceEvent::HeightError;
            let floor_jump = if level < 0.0 { level } else { 0.0 };
            self.s = if level < 0.0 { 0.0 } else { self.s };
            let e = if floor_jump != 0.0 { floor_jump } else { jump };
            plan.inflate_var = e * e;
            plan.inflate_vz = e * e / (REANCHOR_TIME_S * REANCHOR_TIME_S);
        } else if jump.abs() <= gate(p, p_zz, var) && !settling {
            self.last_event = SurfaceEvent::Glitch;
        } else if level < -p.floor_tol {
            self.last_event = SurfaceEvent::BelowFloor;
            self.s = 0.0;
            plan.inflate_var = level * level;
            plan.inflate_vz = level * level / (REANCHOR_TIME_S * REANCHOR_TIME_S);
        } else if z_known && (jump.abs() >= p.step_min || settling) {
            // A step, or (while settling) the rest of the last one.
            let new_s = if level.abs() <= p.snap { 0.0 } else { level.max(0.0) };
            self.last_event = if new_s == 0.0 { SurfaceEvent::StepToFloor } else { SurfaceEvent::Step };
            if !settling {
                self.steps = self.steps.saturating_add(1);
                self.last_step_m = new_s - self.s;
            } else {
                self.last_step_m += new_s - self.s;
            }
            self.s = new_s;
        } else {
            self.last_event = SurfaceEvent::HeightError;
            plan.inflate_var = jump * jump;
            plan.inflate_vz = jump * jump / (REANCHOR_TIME_S * REANCHOR_TIME_S);
        }
        let settle = if self.last_event == SurfaceEvent::Step { p.settle } else { 0 };
        if how != Conclusion::Undecided && settle == 0 {
            // Only the values that agree with the surface now reach the filter (a ramp's first values do
            // not).
            let g = gate(p, p_zz + plan.inflate_var, var);
            for e in self.ring.iter().take(self.len) {
                if (e.u - self.s).abs() <= g {
                    if let Some(slot) = plan.apply.get_mut(plan.n_apply) {
                        *slot = *e;
                        plan.n_apply += 1;
                    }
                } else {
                    self.discarded = self.discarded.saturating_add(1);
                }
            }
        } else {
            self.discarded = self.discarded.saturating_add(self.len as u32);
        }
        self.clear();
        self.settle_left = settle;
        plan
    }
}

/// How a transition ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Conclusion {
    /// Three consecutive values agree.
    Plateau,
    /// No plateau, the values kept moving one way.
    Drift,
    /// No plateau, the values flicker.
    Undecided,
}

/// A settling surface within this of the plateau (or 2σ of its mean) has stopped moving, m.
const SETTLED_M: f32 = 0.002;

/// Smallest end-to-end change of a monotonic ring that counts as a trend, m.
const TREND_MIN_M: f32 = 0.004;

/// A sudden height error is taken to have built up over about this long when the vertical-velocity
/// variance is inflated with it, s.
const REANCHOR_TIME_S: f32 = 1.0;

/// The acceptance gate for a value against the surface: `gate_sigma` standard deviations of the innovation,
/// at least `gate_min`.
fn gate(p: &Params, p_zz: f32, var: f32) -> f32 {
    (p.gate_sigma * libm::sqrtf((p_zz + var).max(0.0))).max(p.gate_min)
}

fn median3(r: &[Entry; RING]) -> f32 {
    let (a, b, c) = (r[0].u, r[1].u, r[2].u);
    a.max(b).min(a.min(b).max(c))
}
