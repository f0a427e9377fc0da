//! The surface tracker: decides, for every downward range, whether it measures the drone's height or a step
//! in the surface below (the "pad step", anchors-peers-planning-style.md §A.4).
//!
//! Each range becomes an *implied surface height* `u = z − r·cos α` (the height of whatever the beam hits,
//! given the current height estimate `z`). `u` is computed with the IMU-propagated `z`, so a real climb or
//! descent moves `z` and `r` together and leaves `u` unchanged; only what the IMU did not see moves `u`: a
//! height error (slowly: the drift the range is there to correct) or the surface itself (in a step, as the
//! drone flies onto or off an object). Every later correction of `z` shifts the stored `u`s by the same
//! amount ([`SurfaceTracker::shift`]), so they stay referred to the current estimate.
//!
//! The last [`RING`] values are kept: each value is judged together with the two after it (a 50 ms delay at
//! 40 Hz). The ring is *flat* when its spread is within `flat_sigma` standard deviations of the range noise
//! plus the drift the vertical-velocity uncertainty allows over its time span (at least `flat_min`) and it
//! does not *trend* (monotonic, end to end more than two standard deviations of a difference); a *plateau*
//! is a flat ring of consecutive ranges (a span of at most 3.2 periods: values separated by rejected
//! readings can agree by accident).
//!
//! `Settled` mode:
//! * the ring is flat and every value agrees with the current surface `s` (|u − s| within
//!   `max(gate_sigma·√(P_zz + σ²), gate_min)`): its oldest value is an ordinary height measurement and goes
//!   to the Kalman filter (so a slow ramp *is* followed as height);
//! * right after a step (`settle` ranges), a plateau within `step_min` of `s` that still moves moves `s`
//!   (the tail of a step blurred by the ranger's cone) and nothing reaches the filter; a plateau that stopped
//!   moving ends the settling at once (a sharp step has no tail); any other plateau while settling is the
//!   rest of the step too (the height coasted meanwhile, so its grown σ_z proves nothing);
//! * the implied surface's least-squares slope over the last 6 ranges (150 ms) beyond 3σ of its noise and
//!   the vertical-velocity uncertainty (a ramp: a blurred step crossed slowly) also stops fusion;
//! * a plateau away from `s` (after a gap in the ranges) is classified at once, as below;
//! * anything else: `Transition`. Nothing from a transition reaches the filter; the height coasts on the IMU.
//!
//! In `Transition` the ring slides until it forms a plateau, whose mean `level` is then classified
//! ([`SurfaceEvent`]), and its values that agree with the outcome go to the filter:
//!
//! | condition | verdict |
//! |---|---|
//! | \|level − s\| within the gate | a glitch (single wild readings end here): back to normal |
//! | level < −`floor_tol` | the floor is the lowest surface there is, so `z` is wrong: `s = 0`, re-anchor `z` |
//! | \|level − s\| ≥ `step_min` and ≥ `step_sigma`·σ_z, or settling | a step: `s = level` (0 within `snap`) |
//! | otherwise (a jump `z` could explain) | a height error: re-anchor `z` |
//!
//! (`step_sigma`·σ_z: a height error that large is improbable, so the jump is the surface; right after a
//! step the height has coasted and its grown σ_z proves nothing, so any plateau continues the step — except
//! a clear step the other way, which is a new step: a 30 cm pad crossed at 0.5 m/s is left within the
//! settling time.)
//!
//! **Levels.** The tracker remembers the surfaces it stepped *up* from (at most `LEVELS`, never two
//! within `return_tol` of each other or of the floor). A step down to within `return_tol` of the floor
//! or of a remembered level lands on that level exactly, and what the plateau says beyond it re-anchors
//! the height like a height error (else the next plateau would say the same and the height would never be
//! corrected). Without this, each crossing's blurred edges left a few millimetres in the surface, and a
//! pad search's dozens of crossings added them up until the drone flew a pad's height lower than asked.
//!
//! "Re-anchor" inflates `P_zz` by the jump² and the vertical-velocity variance by (jump / 1 s)², so that the
//! plateau's values pull `z` onto the new level at once, and a velocity error behind the jump is corrected
//! too — except for a plateau below the floor: that is the drone flying off the raised surface it took off
//! from, a jump in the reference, not a velocity. A plateau also needs no significant slope over its last 4
//! ranges. A transition without a plateau after `max_transition` ranges is decided: values still moving one
//! way at a rate the filter's vertical-velocity uncertainty explains are an unseen vertical motion — the
//! slope of the implied surface *is* the vertical-velocity error, so it is measured (least squares over 150
//! ms) and subtracted, and `z` re-anchored on the newest value (what saves the filter after a divergence
//! reset with a wrong velocity; replaying values taken at different times as if simultaneous carries no
//! rate); moving faster than that (a healthy filter under a slowly crossed blurred edge) the tracker waits
//! for the plateau up to 4 × `max_transition`; flickering values (hovering over an edge) are classified on
//! their median, nothing fused.
//!
//! The flow model needs the same surface (the camera sees the surface, not the floor); during a transition
//! [`SurfaceTracker::flow_surface`] gives the median of the ring, the best guess of what is below now.

/// Ranges kept for a decision: the newest value is judged together with the two after it (50 ms at 40 Hz).
pub(crate) const RING: usize = 3;

/// Ranges kept (fused or not) for the slope test: 150 ms at 40 Hz.
const HISTORY: usize = 6;

/// A plateau's own slope is tested over this many of the latest ranges.
const PLATEAU_SLOPE_N: usize = 4;

const EMPTY: Entry = Entry {
    u: 0.0,
    var: 0.0,
    t_us: 0,
};

/// One range, as the surface it implies.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Entry {
    /// Implied surface height `z − r·cos α`, referred to the current height estimate, m.
    pub u: f32,
    /// Variance of the range's height component `(σ_r·cos α)²`, m².
    pub var: f32,
    /// Arrival time, µs, wrapping every 71 min (only differences are used): a plateau must be made of
    /// consecutive ranges.
    pub t_us: u32,
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
    /// A step down to within this of a level the tracker stepped up from returns to that level exactly.
    pub return_tol: f32,
    pub floor_tol: f32,
    pub gate_sigma: f32,
    pub gate_min: f32,
    pub flat_sigma: f32,
    pub flat_min: f32,
    pub step_sigma: f32,
    pub max_transition: u16,
    /// Longest time span of a ring that counts as consecutive ranges, µs.
    pub max_span_us: u32,
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
    /// The vertical velocity is off by this (m/s, estimate − truth) with this variance: subtract it and
    /// restart its covariance row.
    pub vz_error: Option<(f32, f32)>,
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
    /// The latest ranges, newest last, whatever became of them (the slope test).
    history: [Entry; HISTORY],
    hist_len: usize,
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
    /// The surfaces the tracker stepped *up* from, oldest first (the floor, 0, is implicit): flying off an
    /// object returns to the level the drone came from, exactly, so the errors of a step's blurred edges do
    /// not add up over many crossings of a pad.
    levels: [f32; LEVELS],
    n_levels: usize,
}

/// Remembered levels (objects on objects, nested this deep, are rare).
const LEVELS: usize = 4;

impl SurfaceTracker {
    pub(crate) const fn new(s: f32) -> Self {
        Self {
            s,
            ring: [EMPTY; RING],
            len: 0,
            history: [EMPTY; HISTORY],
            hist_len: 0,
            mode: SurfaceMode::Settled,
            transition_len: 0,
            settle_left: 0,
            steps: 0,
            last_step_m: 0.0,
            discarded: 0,
            last_event: SurfaceEvent::None,
            levels: [0.0; LEVELS],
            n_levels: 0,
        }
    }

    /// Where a surface stepping down to `level` lands: the nearest level it stepped up from within
    /// `return_tol` (the latest such, forgetting the ones above it), the floor within `max(snap,
    /// return_tol)`, else `level` itself. Returns the surface and the remembered levels left.
    fn returned_level(&self, level: f32, p: &Params) -> (f32, usize) {
        // The floor first, then the oldest level: a level is only remembered when none within the
        // tolerance is (see `remember_level`), so at most one matches, and the lowest is the one that
        // cannot have crept.
        if level <= p.snap.max(p.return_tol) {
            return (0.0, 0);
        }
        for i in 0..self.n_levels.min(LEVELS) {
            if (level - self.levels[i]).abs() <= p.return_tol {
                return (self.levels[i], i);
            }
        }
        (level.max(0.0), self.n_levels)
    }

    /// The surface stepped up from `from`: remember it, unless the floor or a remembered level is within the
    /// return tolerance of it (a creeping blurred edge must not stack near-copies); drops the oldest if full.
    fn remember_level(&mut self, from: f32, p: &Params) {
        let known = from <= p.return_tol
            || self.levels[..self.n_levels.min(LEVELS)]
                .iter()
                .any(|l| (l - from).abs() <= p.return_tol);
        if known {
            return;
        }
        if self.n_levels >= LEVELS {
            self.levels.copy_within(1.., 0);
            self.n_levels = LEVELS - 1;
        }
        self.levels[self.n_levels] = from;
        self.n_levels += 1;
    }

    /// Start over on a known surface (a reset on the pad): counters are kept.
    pub(crate) fn reset(&mut self, s: f32) {
        self.s = if s.is_finite() { s.max(0.0) } else { 0.0 };
        self.n_levels = 0;
        self.clear();
    }

    /// Forget the ring (after a gap in the ranges or a filter reset); the surface is kept.
    pub(crate) fn clear(&mut self) {
        self.len = 0;
        self.hist_len = 0;
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
            for e in self.ring.iter_mut().chain(self.history.iter_mut()) {
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
        self.push_history(e);
        if self.len < RING {
            return Plan::default();
        }
        let flat = self.is_flat(p, p_vz) && !self.is_trending(p_vz);
        // A plateau is three *consecutive* ranges: values spread out in time by rejected readings between
        // them (garbage, dropouts) can agree by accident and must not move the surface.
        let consecutive = self.ring[RING - 1].t_us.wrapping_sub(self.ring[0].t_us) <= p.max_span_us;
        let plateau = flat && consecutive && !self.slope_significant(PLATEAU_SLOPE_N, p_vz, p);
        let settling = self.settle_left > 0;
        self.settle_left = self.settle_left.saturating_sub(1);
        match self.mode {
            SurfaceMode::Settled => {
                let level = self.mean();
                // Two standard deviations of a mean of three: the level has stopped moving.
                let still = (level - self.s).abs() <= (2.0 * libm::sqrtf(self.mean_var() / 3.0)).max(SETTLED_M);
                if settling && plateau && still {
                    // The step is complete (at once for a sharp one): back to height updates.
                    self.settle_left = 0;
                } else if settling && plateau && (level - self.s).abs() < p.step_min {
                    // The tail of a blurred step: the surface follows, the height is left alone (it coasts on
                    // the IMU, so this must not last long).
                    self.s = level.max(0.0);
                    if self.s <= p.snap {
                        self.s = 0.0;
                        self.n_levels = 0;
                        self.settle_left = 0;
                    } else if self.last_step_m < 0.0 {
                        // The tail of a step down: back on a level the drone came from ends it.
                        let (back, n) = self.returned_level(level, p);
                        if n < self.n_levels || back == 0.0 {
                            self.s = back;
                            self.n_levels = n;
                            self.settle_left = 0;
                        }
                    }
                    self.pop_oldest();
                    self.discarded = self.discarded.saturating_add(1);
                    return Plan {
                        concluded: true,
                        ..Plan::default()
                    };
                }
                let settling = self.settle_left > 0;
                let agree = self.ring.iter().all(|e| (e.u - self.s).abs() <= gate(p, p_zz, e.var));
                // The implied surface moving faster than noise and the vertical-velocity uncertainty allow over
                // the last 150 ms: a ramp (a blurred step crossed slowly) whose start still looks flat.
                let moving = self.slope_significant(HISTORY, p_vz, p);
                if flat && agree && !settling && !moving {
                    let mut plan = Plan::default();
                    plan.apply[0] = self.ring[0];
                    plan.n_apply = 1;
                    self.pop_oldest();
                    return plan;
                }
                if plateau && !agree {
                    let level = self.mean();
                    return self.conclude(level, p_zz, p, Conclusion::Plateau);
                }
                self.mode = SurfaceMode::Transition;
                self.transition_len = 0;
                Plan::default()
            }
            SurfaceMode::Transition => {
                self.transition_len = self.transition_len.saturating_add(1);
                if plateau {
                    let level = self.mean();
                    self.conclude(level, p_zz, p, Conclusion::Plateau)
                } else if self.transition_len >= p.max_transition && consecutive {
                    let (a, b, c) = (self.ring[0].u, self.ring[1].u, self.ring[2].u);
                    if (a <= b && b <= c) || (a >= b && b >= c) {
                        // Still moving the same way after max_transition ranges. If the filter's own
                        // vertical-velocity uncertainty explains the rate (after a reset it is wide), it is a
                        // vertical motion the IMU did not see: the height follows the newest value. If not (a
                        // healthy filter), it is the surface moving (a blurred step crossed slowly): wait for
                        // its plateau, up to four times as long.
                        let plausible = !self.slope_significant(HISTORY, p_vz, p);
                        if plausible || self.transition_len >= p.max_transition.saturating_mul(4) {
                            self.conclude(c, p_zz, p, Conclusion::Drift)
                        } else {
                            Plan::default()
                        }
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

    fn push_history(&mut self, e: Entry) {
        if let Some(slot) = self.history.get_mut(self.hist_len) {
            *slot = e;
            self.hist_len += 1;
        } else {
            self.history.copy_within(1.., 0);
            self.history[HISTORY - 1] = e;
        }
    }

    /// Least-squares slope of the latest `n` ranges (at least 3, consecutive) beyond three standard
    /// deviations of its noise combined with the vertical-velocity uncertainty: the implied surface is moving
    /// faster than an unseen vertical velocity would explain.
    fn slope_significant(&self, n: usize, p_vz: f32, p: &Params) -> bool {
        match self.history_slope(n, p) {
            Some((slope, var)) => slope * slope > 9.0 * (var + p_vz.max(0.0)),
            None => false,
        }
    }

    /// Least-squares slope of the latest `n` ranges' implied surface, m/s, and its variance (from the range
    /// noise), when there are at least 3 consecutive ones. The implied surface's slope is the filter's
    /// vertical-velocity error (or the surface moving).
    fn history_slope(&self, n: usize, p: &Params) -> Option<(f32, f32)> {
        let n = n.min(self.hist_len);
        let w = self.history.get(self.hist_len - n..self.hist_len)?;
        let (first, last) = (w.first()?, w.last()?);
        // Consecutive: at most 1.6 periods per interval, as for the ring (max_span covers two intervals).
        if n < 3 || last.t_us.wrapping_sub(first.t_us) > p.max_span_us / 2 * (n as u32 - 1) {
            return None;
        }
        let t = |e: &Entry| e.t_us.wrapping_sub(first.t_us) as f32 * 1e-6;
        let nf = n as f32;
        let t_mean = w.iter().map(t).sum::<f32>() / nf;
        let u_mean = w.iter().map(|e| e.u).sum::<f32>() / nf;
        let (mut sxx, mut sxy, mut var) = (0.0f32, 0.0f32, 0.0f32);
        for e in w {
            let dt = t(e) - t_mean;
            sxx += dt * dt;
            sxy += dt * (e.u - u_mean);
            var = var.max(e.var);
        }
        if sxx <= 0.0 {
            return None;
        }
        Some((sxy / sxx, var / sxx))
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
        let span_s = self.ring[self.len.clamp(1, RING) - 1]
            .t_us
            .wrapping_sub(self.ring[0].t_us) as f32
            * 1e-6;
        let drift_var = p_vz.max(0.0) * span_s * span_s;
        hi - lo <= (p.flat_sigma * libm::sqrtf(var + drift_var)).max(p.flat_min)
    }

    /// The ring moves one way by more than two standard deviations of a difference of two values: the
    /// middle of a ramp, even if its spread is small (a blurred step crossed slowly).
    fn is_trending(&self, p_vz: f32) -> bool {
        let (a, b, c) = (self.ring[0], self.ring[1], self.ring[2]);
        let monotonic = (a.u <= b.u && b.u <= c.u) || (a.u >= b.u && b.u >= c.u);
        let span_s = c.t_us.wrapping_sub(a.t_us) as f32 * 1e-6;
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
        let mut stepped_down = false;
        let var = self.mean_var();
        let jump = level - self.s;
        let settling = self.settle_left > 0;
        // A height error of this size would be improbable (≥ step_sigma·σ_z): it is the surface.
        let z_known = jump.abs() >= p.step_sigma * libm::sqrtf(p_zz.max(0.0));
        let mut plan = Plan {
            concluded: true,
            ..Plan::default()
        };
        if how == Conclusion::Drift {
            self.last_event = SurfaceEvent::HeightError;
            let floor_jump = if level < 0.0 { level } else { 0.0 };
            self.s = if level < 0.0 { 0.0 } else { self.s };
            let e = if floor_jump != 0.0 { floor_jump } else { jump };
            plan.inflate_var = e * e;
            // The drift rate is the vertical-velocity error: measure it instead of hoping that values
            // replayed at one instant (which carry no rate) would.
            if let Some((slope, var)) = self.history_slope(HISTORY, p) {
                plan.vz_error = Some((slope, var + VZ_RESET_FLOOR_VAR));
            }
        } else if jump.abs() <= gate(p, p_zz, var) && !settling {
            self.last_event = SurfaceEvent::Glitch;
        } else if level < -p.floor_tol {
            self.last_event = SurfaceEvent::BelowFloor;
            self.s = 0.0;
            plan.inflate_var = level * level;
            // A plateau below the floor is a jump, not a drift: the drone flew off the raised surface it took
            // off from (the home pad's top counted as the floor), which says nothing about the vertical
            // velocity. Inflating it there let the re-anchoring range pull it 0.15 m/s off (world 24 000 264
            // stressed), and the next steps then read the unseen descent as a surface rising until the drone
            // sat on the floor believing it held 0.5 m.
            if how != Conclusion::Plateau {
                plan.inflate_vz = level * level / (REANCHOR_TIME_S * REANCHOR_TIME_S);
            }
        } else if (z_known && jump.abs() >= p.step_min) || settling {
            // A step; or, right after one, the rest of it (the height coasted meanwhile, so its grown
            // uncertainty says nothing about this jump). A clear step the other way is a new step, not the
            // rest of the last one: a pad crossed at 0.5 m/s is left within the settling time.
            let reverses = z_known && jump.abs() >= p.step_min && jump * self.last_step_m < 0.0;
            let level_before = self.s;
            let continues = settling && !reverses;
            let new_s = if level.abs() <= p.snap {
                0.0
            } else if level < self.s && !(continues && self.last_step_m > 0.0) {
                // A step down (not the tail of a step up settling lower): back to a level it came from?
                let (back, n) = self.returned_level(level, p);
                self.n_levels = n;
                back
            } else {
                if !continues && level > self.s {
                    self.remember_level(self.s, p);
                }
                level.max(0.0)
            };
            if new_s == 0.0 {
                self.n_levels = 0;
            }
            self.last_event = if new_s == 0.0 {
                SurfaceEvent::StepToFloor
            } else {
                SurfaceEvent::Step
            };
            if !continues {
                self.steps = self.steps.saturating_add(1);
                self.last_step_m = new_s - self.s;
            } else {
                self.last_step_m += new_s - self.s;
            }
            self.s = new_s;
            // A step down (onto the floor, back onto a level it came from, or onto a new lower level) is
            // complete at once: no settling tail follows it. When it snapped onto a known level, what the
            // plateau says beyond that level is a height error and re-anchors the height (else the next
            // plateau would say the same again and the height would never be corrected); onto a new level
            // the residual is zero.
            let residual = level - new_s;
            if new_s != level_before && (new_s == 0.0 || new_s < level_before) {
                stepped_down = true;
                plan.inflate_var = residual * residual;
                plan.inflate_vz = residual * residual / (REANCHOR_TIME_S * REANCHOR_TIME_S);
            }
        } else {
            self.last_event = SurfaceEvent::HeightError;
            plan.inflate_var = jump * jump;
            plan.inflate_vz = jump * jump / (REANCHOR_TIME_S * REANCHOR_TIME_S);
        }
        let settle = if self.last_event == SurfaceEvent::Step && !stepped_down {
            p.settle
        } else {
            0
        };
        // A glitch's values are not fused either: a transition means something was off, and fusing a ramp's
        // first values would bend the vertical velocity; fresh values follow within 75 ms.
        let fuse = how != Conclusion::Undecided && settle == 0;
        if how == Conclusion::Drift {
            // Only the newest value: the older ones describe where the drift was, not where it is.
            let newest = self.ring[self.len.clamp(1, RING) - 1];
            plan.apply[0] = newest;
            plan.n_apply = 1;
            self.discarded = self.discarded.saturating_add(self.len.saturating_sub(1) as u32);
        } else if fuse {
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
        // The plateau is the new reference of the slope test (the jump before it is not a slope).
        let (ring, n) = (self.ring, self.len);
        self.clear();
        if let (Some(dst), Some(src)) = (self.history.get_mut(..n), ring.get(..n)) {
            dst.copy_from_slice(src);
            self.hist_len = n;
        }
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

/// Variance added to a measured vertical-velocity error, (m/s)² (its estimate ignores the IMU's own noise
/// over the window).
const VZ_RESET_FLOOR_VAR: f32 = 1e-4;

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
