//! The measurement updates: optical flow (the stock Kalman filter's flow model), the downward range through
//! the surface tracker, and the wall anchors of the horizontal beams; each one a sequential scalar update
//! with a 3σ gate and a Joseph-form covariance step.

use super::map_fix::MapFixes;
use super::surface::Entry;
use super::{
    COVARIANCE_MAX, COVARIANCE_MIN, Estimator, FLOW_RESOLUTION, FLOW_SCALE_MAX, FLOW_SCALE_MAX_STEP, N, NO_JUMP, SD,
    SS, SV, SZ, V3, VecN, dot_n, euler_from_rot, mul_m3t_v3, mul_mat_vec, quat_from_rotvec, quat_mul, quat_normalize,
    quat_to_rot, scale3, skew, sq,
};
use crate::types::{FlowSample, MultiRangerSample, RangeReading};

/// Attitude corrections below this are not worth rotating the covariance for (stock kalmanCoreFinalize).
const ATTITUDE_FOLD_MIN_RAD: f32 = 1e-4;
/// Longest flow interval accepted, s (the driver reads every 10 ms).
const FLOW_MAX_DT_S: f32 = 0.1;
/// Height floor of the flow model, m (stock: z below 0.1 m is replaced by 0.1).
const FLOW_MIN_HEIGHT_M: f32 = 0.1;
/// The flow model needs the camera to look roughly down: R22 ≥ 0.5 (tilt ≤ 60°).
const FLOW_MIN_R22: f32 = 0.5;
/// Pixels across the PMW3901 (stock `Npix`, mm_flow.c).
const FLOW_NPIX: f32 = 35.0;
/// `2·sin(42°/2)`: the PMW3901's aperture (stock `thetapix`).
const FLOW_THETAPIX: f32 = 0.71674;
/// Ranges older than this are not kept in the surface tracker's ring, µs.
const RING_MAX_AGE_US: u64 = 200_000;

impl Estimator {
    /// One optical-flow sample (100 Hz).
    pub fn on_flow(&mut self, sample: &FlowSample) {
        self.samples_without_imu = self.samples_without_imu.saturating_add(1);
        // Mean gyro over the interval the sensor integrated.
        let omega = if self.flow_dt > 1e-4 {
            scale3(self.flow_rot, 1.0 / self.flow_dt)
        } else {
            self.omega
        };
        self.flow_rot = [0.0; 3];
        self.flow_dt = 0.0;

        let dt = sample.dt_s;
        let limit = i32::from(self.cfg.flow_outlier_counts);
        if !(dt.is_finite() && dt > 0.0 && dt <= FLOW_MAX_DT_S)
            || i32::from(sample.dpixel_x).abs() >= limit
            || i32::from(sample.dpixel_y).abs() >= limit
        {
            self.diag.flow_rejected_outlier = self.diag.flow_rejected_outlier.saturating_add(1);
            return;
        }
        if !sample.motion_valid || sample.squal < self.cfg.flow_squal_min {
            self.diag.flow_rejected_invalid = self.diag.flow_rejected_invalid.saturating_add(1);
            return;
        }
        self.last_flow_us = Some(self.now_us);
        if !(self.calibrated && self.airborne) {
            self.diag.flow_unused = self.diag.flow_unused.saturating_add(1);
            return;
        }
        self.predict_covariance();
        let r_var = sq(self.cfg.flow_std_counts * FLOW_RESOLUTION);
        let measured = [
            f32::from(sample.dpixel_x) * FLOW_RESOLUTION,
            f32::from(sample.dpixel_y) * FLOW_RESOLUTION,
        ];

        // Gate on both axes with the state before either update.
        let mut d2 = 0.0;
        let mut innov = [0.0; 2];
        for axis in 0..2 {
            let Some((pred, h)) = self.flow_model(axis, dt, omega) else {
                self.diag.flow_unused = self.diag.flow_unused.saturating_add(1);
                return;
            };
            innov[axis] = measured[axis] - pred;
            d2 += sq(innov[axis]) / self.innovation_variance(&h, r_var);
        }
        self.diag.flow_innovation_px = innov;
        self.diag.flow_mahalanobis_sq = d2;
        if (d2.is_nan() || d2 > sq(self.cfg.flow_gate_sigma))
            && self.flow_reject_streak < self.cfg.flow_max_gate_rejections
        {
            self.flow_reject_streak = self.flow_reject_streak.saturating_add(1);
            self.diag.flow_rejected_gate = self.diag.flow_rejected_gate.saturating_add(1);
            return;
        }
        self.flow_reject_streak = 0;
        // Sequential scalar updates, each against the state the previous one left (stock does the same).
        for (axis, &m) in measured.iter().enumerate() {
            if let Some((pred, h)) = self.flow_model(axis, dt, omega) {
                self.scalar_update(&h, m - pred, r_var);
            }
        }
        self.diag.flow_fused = self.diag.flow_fused.saturating_add(1);
        self.supervise(true);
    }

    /// The stock flow model for one axis (0 = x, 1 = y): predicted pixels and the Jacobian row.
    pub(super) fn flow_model(&self, axis: usize, dt: f32, omega: V3) -> Option<(f32, VecN)> {
        let r = quat_to_rot(self.quat);
        let r22 = r[2][2];
        if r22.is_nan() || r22 < FLOW_MIN_R22 {
            return None;
        }
        let h = (self.pos[SZ] - self.surface.flow_surface()).max(FLOW_MIN_HEIGHT_M);
        let c = dt * FLOW_NPIX / FLOW_THETAPIX;
        let vb = mul_m3t_v3(&r, self.vel);
        // The translational flow, `c·R22/h·v_b`, is what the scale error multiplies (a height or lens
        // error); the rotational `c·ω` comes from the gyro (module docs, "Flow scale").
        let scale = 1.0 + self.flow_scale;
        let k_model = c * r22 / h;
        let k = k_model * scale;
        let mut jac = [0.0; N];
        // d v_b / d δv = Rᵀ (row `axis` of Rᵀ = column `axis` of R).
        for i in 0..3 {
            jac[SV + i] = k * r[i][axis];
        }
        // d v_b / d δθ = [v_b]×; d R22 / d δθ = (−R21, R20, 0).
        let vx = skew(vb);
        let dr22 = [-r[2][1], r[2][0], 0.0];
        let (v_axis, row) = if axis == 0 { (vb[0], vx[0]) } else { (vb[1], vx[1]) };
        for j in 0..3 {
            jac[SD + j] = scale * c / h * (r22 * row[j] + v_axis * dr22[j]);
        }
        if self.cfg.initial_std_flow_scale > 0.0 {
            jac[SS] = k_model * v_axis;
        }
        let pred = if axis == 0 {
            k * vb[0] - c * omega[1]
        } else {
            k * vb[1] + c * omega[0]
        };
        if pred.is_finite() && jac.iter().all(|x| x.is_finite()) {
            Some((pred, jac))
        } else {
            None
        }
    }

    /// One reading of the Multi-ranger (10 Hz). While `hold` (the caller's judgement that the drone is told
    /// to stay where it is; the stabilizer says so while the commander holds a position) the four horizontal
    /// beams are fused against the walls they saw when the hold began (module `wall_hold`); otherwise the
    /// anchors are dropped.
    pub fn on_multiranger(&mut self, sample: &MultiRangerSample, hold: bool) {
        if !(hold && self.cfg.wall_hold && self.calibrated && self.airborne) {
            self.walls.clear();
            return;
        }
        let ranges = sample.horizontal();
        let yaw = euler_from_rot(&quat_to_rot(self.quat))[2];
        let anchors = self.walls.begin(ranges, yaw, [self.pos[0], self.pos[1]]);
        if anchors.iter().all(Option::is_none) {
            return;
        }
        self.predict_covariance();
        for (beam, anchor) in anchors.into_iter().enumerate() {
            let (Some(anchor), Some(range)) = (anchor, ranges[beam]) else {
                continue;
            };
            let here = [self.pos[0], self.pos[1]];
            let innovation = range - anchor.expected_range_m(here);
            let mut h = [0.0; N];
            h[0] = -anchor.direction[0];
            h[1] = -anchor.direction[1];
            let r_var = sq(self.cfg.wall_std_floor_m + self.cfg.wall_std_relative * range);
            let s = self.innovation_variance(&h, r_var);
            // (A NaN innovation or variance is rejected too.)
            let within_gate = sq(innovation) <= sq(self.cfg.wall_gate_sigma) * s;
            if !within_gate {
                self.walls.rejected(beam, range, here);
                self.diag.wall_rejected = self.diag.wall_rejected.saturating_add(1);
                continue;
            }
            if matches!(
                self.scalar_update_bounded(&h, innovation, r_var, f32::INFINITY, false),
                Update::Applied { .. }
            ) {
                self.walls.accepted(beam);
                self.diag.wall_fused = self.diag.wall_fused.saturating_add(1);
            }
        }
        self.supervise(true);
    }

    /// The map-relative fixes of one Multi-ranger sweep (module `map_fix`), cast by the navigator from
    /// the estimate it was given with the sweep. Each is a scalar measurement of the distance to a surface
    /// along its normal `n`, `c − p·n` (Jacobian `−n` on x, y), gated at `map_fix_gate_sigma`. The
    /// innovation is the one computed at the cast (`measured − expected`, less what the sweep's earlier
    /// fixes already moved the estimate along `n`): the reading and the expected
    /// distance belong to the same moment, so a fix applied a few milliseconds later (the navigator runs
    /// in thread mode) still corrects by the error the estimate had then, which the flow's slow drift
    /// keeps nearly unchanged. Used only in flight; nothing happens without `map_fix` configured.
    pub fn on_map_fixes(&mut self, fixes: &MapFixes) {
        if !(self.cfg.map_fix && self.calibrated && self.airborne) || fixes.is_empty() {
            return;
        }
        self.predict_covariance();
        self.map_sweeps = self.map_sweeps.wrapping_add(1);
        // The fixes before this one moved the estimate by `p − start` and turned it by `turned`:
        // the expected distance moves with the position, the measured one with the heading.
        let start = [self.pos[0], self.pos[1]];
        let heading = self.cfg.map_fix_heading;
        // How far this sweep's updates turned the heading so far, rad.
        let mut turned = 0.0;
        for fix in fixes.fixes.iter().flatten() {
            let shift = (self.pos[0] - start[0]) * fix.normal[0] + (self.pos[1] - start[1]) * fix.normal[1];
            let lever = if heading && fix.yaw_lever_m.is_finite() {
                fix.yaw_lever_m
            } else {
                0.0
            };
            let innovation = fix.measured_m + lever * turned - (fix.expected_m - shift);
            let mut h = [0.0; N];
            h[0] = -fix.normal[0];
            h[1] = -fix.normal[1];
            if lever != 0.0 {
                // The arena-frame heading error is R[2]·δθ (δθ in the body frame): the third row of R.
                let row = quat_to_rot(self.quat)[2];
                for k in 0..3 {
                    h[SD + k] = -lever * row[k];
                }
            }
            let r_var = sq(fix.std_m);
            let s = self.innovation_variance(&h, r_var);
            // (A NaN innovation, std or variance is rejected too.)
            let within_gate = r_var > 0.0 && sq(innovation) <= sq(self.cfg.map_fix_gate_sigma) * s;
            if !within_gate {
                self.diag.map_rejected = self.diag.map_rejected.saturating_add(1);
                continue;
            }
            // A jump needs a second sweep's word (see `EstimatorConfig::map_fix_jump_m`).
            if innovation.abs() > self.cfg.map_fix_jump_m {
                let slot = usize::from(fix.normal[1].abs() > fix.normal[0].abs()) * 2
                    + usize::from(fix.normal[0] + fix.normal[1] > 0.0);
                let (before_mm, sweep) = (self.map_jump_mm[slot], self.map_jump_sweep[slot]);
                let confirmed = before_mm != NO_JUMP
                    && self.map_sweeps.wrapping_sub(sweep) <= 2
                    && self.map_sweeps != sweep
                    && (innovation - f32::from(before_mm) * 1e-3).abs() <= self.cfg.map_fix_jump_agree_m;
                // (The pre-gate keeps |innovation| well inside ±32 m.)
                self.map_jump_mm[slot] = (innovation * 1e3).clamp(-32_000.0, 32_000.0) as i16;
                self.map_jump_sweep[slot] = self.map_sweeps;
                if !confirmed {
                    self.diag.map_jumps_held = self.diag.map_jumps_held.saturating_add(1);
                    continue;
                }
            }
            let max_yaw = if lever != 0.0 {
                self.cfg.map_fix_max_yaw_step_rad
            } else {
                f32::INFINITY
            };
            match self.scalar_update_bounded(&h, innovation, r_var, max_yaw, fix.yaw_lever_m != 0.0) {
                Update::Applied { turn_rad } => {
                    turned += turn_rad;
                    self.diag.map_fused = self.diag.map_fused.saturating_add(1);
                    if lever != 0.0 {
                        self.diag.map_heading_fused = self.diag.map_heading_fused.saturating_add(1);
                    }
                }
                Update::TurnTooLarge => {
                    self.diag.map_rejected = self.diag.map_rejected.saturating_add(1);
                }
                Update::Unusable => {}
            }
        }
        for (axis, from) in start.iter().enumerate() {
            let moved = self.pos[axis] - from;
            if moved.is_finite() {
                self.diag.map_fix_shift_m[axis] += moved;
            }
        }
        self.supervise(true);
    }

    /// One reading of the downward ranger (40 Hz), metres along body −z.
    pub fn on_zrange(&mut self, range: RangeReading) {
        self.samples_without_imu = self.samples_without_imu.saturating_add(1);
        let r = match range {
            Some(r) if r.is_finite() && r >= 0.0 && r < self.cfg.tof_max_range_m => r,
            _ => {
                self.diag.tof_rejected_range = self.diag.tof_rejected_range.saturating_add(1);
                return;
            }
        };
        if !self.calibrated {
            return;
        }
        let r22 = quat_to_rot(self.quat)[2][2];
        if r22.is_nan() || r22 < self.cfg.tof_min_r22 {
            self.diag.tof_rejected_tilt = self.diag.tof_rejected_tilt.saturating_add(1);
            return;
        }
        if let Some(last) = self.last_range_us
            && self.now_us.saturating_sub(last) > RING_MAX_AGE_US
        {
            // The ring's values are too old to be compared with this one.
            self.surface.clear();
        }
        self.last_range_us = Some(self.now_us);
        self.predict_covariance();

        // Stock mm_tof.c: the cone's nearest edge is 7.5° less tilted than the drone (so below 7.5° of tilt
        // the range is the height: no trigonometry in the common case).
        let cos_alpha = if r22 >= libm::cosf(self.cfg.tof_cone_half_angle_rad) {
            1.0
        } else {
            let tilt = libm::acosf(r22.clamp(-1.0, 1.0));
            libm::cosf((tilt - self.cfg.tof_cone_half_angle_rad).max(0.0))
        };
        // zranger2.c: std grows exponentially beyond ~2.5 m (r < 5 m keeps exp() finite).
        let sigma = 0.0025 * (1.0 + libm::expf(2.9214 * (r - 2.5)));
        // Truncated to 32 bits on purpose: the tracker only compares nearby times (wrapping_sub).
        let t_us = self.now_us as u32;
        let u = self.pos[SZ] - r * cos_alpha;
        let entry = Entry {
            u,
            var: sq(sigma * cos_alpha),
            t_us,
        };
        self.diag.tof_innovation_m = entry.u - self.surface.surface();

        let plan = self.surface.push(
            entry,
            self.cov[SZ][SZ],
            self.cov[SV + 2][SV + 2],
            &self.cfg.surface_params(),
        );
        if plan.concluded || plan.n_apply > 0 {
            self.last_tof_us = Some(self.now_us);
        }
        if let Some((err, var)) = plan.vz_error
            && err.is_finite()
            && var.is_finite()
        {
            // A measured vertical-velocity error: correct it and restart its covariance row (no longer
            // correlated with anything; a diagonal-only row keeps P positive definite).
            self.vel[2] -= err;
            for (i, row) in self.cov.iter_mut().enumerate() {
                if i != SV + 2 {
                    row[SV + 2] = 0.0;
                }
            }
            self.cov[SV + 2] = [0.0; N];
            self.cov[SV + 2][SV + 2] = var.clamp(COVARIANCE_MIN, COVARIANCE_MAX);
        }
        if plan.inflate_var > 0.0 {
            self.cov[SZ][SZ] = (self.cov[SZ][SZ] + plan.inflate_var).min(COVARIANCE_MAX);
            self.cov[SV + 2][SV + 2] = (self.cov[SV + 2][SV + 2] + plan.inflate_vz).min(COVARIANCE_MAX);
        }
        let z_at_plan = self.pos[SZ];
        let mut h = [0.0; N];
        h[SZ] = 1.0;
        for e in plan.entries() {
            // The entry's u was referred to z_at_plan; the updates before it moved z since.
            let u = e.u + (self.pos[SZ] - z_at_plan);
            // Measurement: height above the surface r·cos α = z − u; prediction z − s.
            self.scalar_update(&h, self.surface.surface() - u, e.var);
            self.diag.tof_fused = self.diag.tof_fused.saturating_add(1);
        }
        self.diag.tof_discarded = self.surface.discarded;
        self.supervise(true);
    }

    /// `h P hᵀ + r`.
    pub(super) fn innovation_variance(&self, h: &VecN, r_var: f32) -> f32 {
        dot_n(h, &mul_mat_vec(&self.cov, h)) + r_var
    }

    /// A scalar Kalman update with Jacobian `h`, innovation `innov` and noise variance `r_var`; the
    /// correction is folded into the nominal state at once. Returns false (and changes nothing) if the
    /// numbers are not usable. The flow scale is a *consider* state here (see
    /// [`Self::scalar_update_bounded`]).
    pub(super) fn scalar_update(&mut self, h: &VecN, innov: f32, r_var: f32) -> bool {
        matches!(
            self.scalar_update_bounded(h, innov, r_var, f32::INFINITY, false),
            Update::Applied { .. }
        )
    }

    /// [`Self::scalar_update`] that changes nothing when the correction would turn the heading (the
    /// arena-frame yaw, `R[2]·δθ`) by more than `max_yaw_rad`; says how far it turned it.
    ///
    /// Only with `learns_scale` (a map fix against the arena's exact walls) may it move the flow scale
    /// error. Every other update treats the scale as a *consider* state (Schmidt): its uncertainty enters
    /// the innovation variance and the cross-covariances, but the update's gain on it is zero and its
    /// variance stays. Through the flow and the accelerometer alone the scale is barely observable, and
    /// what little they say comes with the vibration's noise and the accelerometer's bias: learning from them
    /// walked it to −3 % on a 3 m transit with motor vibration (82 mm off at its end instead of 30).
    pub(super) fn scalar_update_bounded(
        &mut self,
        h: &VecN,
        innov: f32,
        r_var: f32,
        max_yaw_rad: f32,
        learns_scale: bool,
    ) -> Update {
        let ph = mul_mat_vec(&self.cov, h);
        let s = dot_n(h, &ph) + r_var;
        if !(s.is_finite() && s > 0.0 && innov.is_finite()) {
            return Update::Unusable;
        }
        let mut dx = [0.0; N];
        for (d, &p) in dx.iter_mut().zip(ph.iter()) {
            *d = p / s * innov;
        }
        if !learns_scale {
            dx[SS] = 0.0;
        }
        if !dx.iter().all(|d| d.is_finite()) {
            return Update::Unusable;
        }
        let row = quat_to_rot(self.quat)[2];
        let turn_rad = row[0] * dx[SD] + row[1] * dx[SD + 1] + row[2] * dx[SD + 2];
        if turn_rad.abs() > max_yaw_rad {
            return Update::TurnTooLarge;
        }
        // P − P hᵀ h P / s, computed symmetric (equal to the Joseph form in exact arithmetic for the
        // optimal gain; the conditioning below keeps it positive).
        // (With the scale a consider state the Joseph form with its gain row zero gives the same
        // expression for every entry but the scale's own variance, which stays.)
        let keep_scale_variance = self.cov[SS][SS];
        for i in 0..N {
            for j in i..N {
                let v = self.cov[i][j] - ph[i] * ph[j] / s;
                self.cov[i][j] = v;
                self.cov[j][i] = v;
            }
        }
        if !learns_scale {
            self.cov[SS][SS] = keep_scale_variance;
        }
        for i in 0..N {
            self.cov[i][i] = self.cov[i][i].clamp(COVARIANCE_MIN, COVARIANCE_MAX);
        }
        for i in 0..3 {
            self.pos[i] += dx[i];
            self.vel[i] += dx[SV + i];
        }
        self.surface.shift(dx[SZ]);
        self.flow_scale = (self.flow_scale + dx[SS].clamp(-FLOW_SCALE_MAX_STEP, FLOW_SCALE_MAX_STEP))
            .clamp(-FLOW_SCALE_MAX, FLOW_SCALE_MAX);
        let dtheta = [dx[SD], dx[SD + 1], dx[SD + 2]];
        self.quat = quat_normalize(quat_mul(self.quat, quat_from_rotvec(dtheta)));
        if dtheta.iter().any(|d| d.abs() > ATTITUDE_FOLD_MIN_RAD) {
            // (Smaller corrections are still folded into q, just not worth rotating P for.)
            self.rotate_attitude_covariance(dtheta);
        }
        Update::Applied { turn_rad }
    }
}

/// What [`Estimator::scalar_update_bounded`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Update {
    /// Folded into the state; it turned the heading by this much, rad.
    Applied {
        /// `R[2]·δθ`.
        turn_rad: f32,
    },
    /// Rejected: it would have turned the heading by more than allowed.
    TurnTooLarge,
    /// Rejected: non-finite or degenerate numbers.
    Unusable,
}
