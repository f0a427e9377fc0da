//! The prediction step: IMU samples integrated into the nominal state (strapdown, 1 kHz), the error-state
//! covariance propagated at 100 Hz, and the rest windows that calibrate the gyro and level the attitude
//! before take-off.

use super::calib::RestWindow;
use super::{
    COVARIANCE_MAX, COVARIANCE_MIN, Estimator, FLOW_SCALE_WALK_PER_SQRT_S, M3, N, SD, SS, SV, V3, VecN, add3, dot3,
    finite3, mul_m3, mul_m3_v3, norm3, quat_from_euler, quat_from_rotvec, quat_mul, quat_normalize, quat_to_rot,
    scale3, skew, sq, sub3,
};
use crate::types::{GRAVITY_M_S2, ImuSample};

const ACCEL_RANGE_M_S2: f32 = 24.0 * GRAVITY_M_S2;
/// BMI088 ranges as configured by stock (`docs/hardware.md` §2): ±2000 °/s, ±24 g. Anything beyond is clamped.
const GYRO_RANGE_RAD_S: f32 = 34.9;
/// Longest IMU step integrated, s; a longer gap is integrated as this (and is a fault upstream).
const MAX_IMU_DT_S: f32 = 0.05;
/// Steps up to this are remembered as the IMU's period (a longer one is a gap, not a period), s.
const NOMINAL_DT_MAX_S: f32 = 0.005;
/// The stock covariance is propagated at 100 Hz (estimator_kalman.c L119).
const PREDICT_PERIOD_S: f32 = 0.01;
/// Weight of a new rest window in the bias and scale once calibrated.
const REFINE_WEIGHT: f32 = 0.25;
/// The largest horizontal accelerometer reading at the first rest taken as the sensor's offset rather than
/// a tilt, m/s² (≈ 2°; the BMI088's zero-g offset is ±20 mg typical per axis, datasheet BST-BMI088-DS001 §1).
const LEVEL_OFFSET_MAX_M_S2: f32 = 0.35;
const REST_ACCEL_M_S2: f32 = 0.5;
/// Per-sample rest test on the ground: |ω| and ||f| − g| below these.
const REST_GYRO_RAD_S: f32 = 0.1;

impl Estimator {
    /// One IMU sample (body frame) and the time since the previous one, s (1 kHz).
    pub fn on_imu(&mut self, sample: &ImuSample, dt_s: f32) {
        // A nonsensical step still came with a sample (the IMU's data-ready paces the calls): integrate it
        // over the last sane period rather than lose it.
        let dt = if dt_s.is_finite() && dt_s > 0.0 {
            if dt_s <= NOMINAL_DT_MAX_S {
                self.last_dt = dt_s;
            }
            dt_s.min(MAX_IMU_DT_S)
        } else {
            self.diag.imu_bad_dt = self.diag.imu_bad_dt.saturating_add(1);
            self.last_dt
        };
        // Through u32: the FPU converts to 32 bits; a float → u64 conversion is a software routine.
        self.now_us = self.now_us.saturating_add(u64::from((dt * 1e6 + 0.5) as u32));
        self.samples_without_imu = 0;

        let fresh = finite3(sample.gyro_rad_s) && finite3(sample.accel_m_s2);
        if fresh {
            self.last_gyro = sample.gyro_rad_s.map(|g| g.clamp(-GYRO_RANGE_RAD_S, GYRO_RANGE_RAD_S));
            self.last_accel = sample.accel_m_s2.map(|a| a.clamp(-ACCEL_RANGE_M_S2, ACCEL_RANGE_M_S2));
            self.have_imu = true;
            self.bad_imu_streak = 0;
        } else {
            self.diag.imu_rejected = self.diag.imu_rejected.saturating_add(1);
            self.bad_imu_streak = self.bad_imu_streak.saturating_add(1);
            if !self.have_imu {
                return;
            }
        }
        let (gyro, accel) = (self.last_gyro, self.last_accel);
        for ((out, lpf), (&g, &b)) in self
            .rates
            .iter_mut()
            .zip(self.rates_lpf.iter_mut())
            .zip(gyro.iter().zip(self.gyro_bias.iter()))
        {
            *out = lpf.apply(g) - b;
        }

        // Calibration at rest: only on the ground, only on real samples.
        if self.airborne {
            self.calib.restart();
        } else if fresh && let Some(window) = self.calib.push(gyro, accel) {
            self.on_rest_window(&window);
        }
        if !self.calibrated {
            return;
        }

        // Strapdown integration of this sample.
        let w = sub3(gyro, self.gyro_bias);
        let f = scale3(accel, self.accel_scale);
        let f = [f[0] - self.accel_offset_xy[0], f[1] - self.accel_offset_xy[1], f[2]];
        self.omega = w;
        let rot = scale3(w, dt);
        self.quat = quat_normalize(quat_mul(self.quat, quat_from_rotvec(rot)));
        let r = quat_to_rot(self.quat);
        let mut a = mul_m3_v3(&r, f);
        a[2] -= GRAVITY_M_S2;
        self.pos = add3(self.pos, add3(scale3(self.vel, dt), scale3(a, 0.5 * dt * dt)));
        self.vel = add3(self.vel, scale3(a, dt));
        self.blk_dt += dt;
        self.blk_f = add3(self.blk_f, scale3(f, dt));
        self.blk_rot = add3(self.blk_rot, rot);
        // |ω| < REST_GYRO and ||f| − g| < REST_ACCEL, compared squared (no square root at 1 kHz).
        let f2 = dot3(f, f);
        self.blk_rest &= dot3(w, w) < sq(REST_GYRO_RAD_S)
            && f2 > sq(GRAVITY_M_S2 - REST_ACCEL_M_S2)
            && f2 < sq(GRAVITY_M_S2 + REST_ACCEL_M_S2);
        self.flow_rot = add3(self.flow_rot, rot);
        self.flow_dt += dt;

        if self.blk_dt >= PREDICT_PERIOD_S {
            let (f_mean, rest) = (scale3(self.blk_f, 1.0 / self.blk_dt), self.blk_rest);
            self.predict_covariance();
            self.update_airborne();
            if !self.airborne && rest {
                self.rest_update(f_mean);
            }
            self.supervise(true);
        } else {
            // The state bounds every sample (cheap), so that no output ever leaves them.
            self.supervise(false);
        }
    }

    /// A rest window completed on the ground: first calibration, or a refinement.
    pub(super) fn on_rest_window(&mut self, w: &RestWindow) {
        if !self.calibrated {
            self.gyro_bias = w.gyro_mean;
            self.accel_scale = w.accel_scale();
            self.calibrated = true;
            // At rest f_b = g·(−sin θ, cos θ sin φ, cos θ cos φ) + offset: the level calibration (module
            // docs) takes a small horizontal reading as the offset, a large one as a tilt.
            let a = scale3(w.accel_mean, self.accel_scale);
            let (roll, pitch) = if libm::hypotf(a[0], a[1]) <= LEVEL_OFFSET_MAX_M_S2 && a[2] > 0.0 {
                self.accel_offset_xy = [a[0], a[1]];
                (0.0, 0.0)
            } else {
                self.accel_offset_xy = [0.0; 2];
                (
                    libm::atan2f(a[1], a[2]),
                    libm::atan2f(-a[0], libm::sqrtf(a[1] * a[1] + a[2] * a[2])),
                )
            };
            self.quat = quat_from_euler(roll, pitch, self.home_yaw);
            self.pos = self.home_pos;
            self.vel = [0.0; 3];
            self.cov = self.initial_covariance();
            self.surface.reset(self.home_pos[2]);
            self.clear_blocks();
            self.sane_pos = self.pos;
            self.sane_quat = self.quat;
        } else {
            let k = REFINE_WEIGHT;
            self.gyro_bias = add3(self.gyro_bias, scale3(sub3(w.gyro_mean, self.gyro_bias), k));
            self.accel_scale += k * (w.accel_scale() - self.accel_scale);
        }
    }

    /// `P = F P Fᵀ + Q` over the IMU samples since the last call (see the module docs).
    ///
    /// `F = [[I, I·dt, A], [0, I, B], [0, 0, Θ]]` with `B = −dt·R[f]×` (`δv̇ = −R[f]×δθ`), `A = dt/2·B`
    /// (its integral into δp) and `Θ = exp(−[ω dt]×)` to second order. Applied by blocks, `F·P` and then
    /// `(F·P)·Fᵀ` cost 297 multiply-adds each instead of 729 for a dense product.
    pub(super) fn predict_covariance(&mut self) {
        let dt = self.blk_dt;
        if dt.is_nan() || dt <= 0.0 {
            return;
        }
        let f_mean = scale3(self.blk_f, 1.0 / dt);
        let r = quat_to_rot(self.quat);
        let rf = mul_m3(&r, &skew(f_mean));
        let phi = skew(self.blk_rot);
        let phi2 = mul_m3(&phi, &phi);
        let mut b: M3 = [[0.0; 3]; 3];
        let mut a: M3 = [[0.0; 3]; 3];
        let mut th: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for i in 0..3 {
            for j in 0..3 {
                b[i][j] = -dt * rf[i][j];
                a[i][j] = 0.5 * dt * b[i][j];
                th[i][j] += -phi[i][j] + 0.5 * phi2[i][j];
            }
        }
        // x ↦ F·x for one 9-vector x (a column of P, then a row of F·P).
        let apply = |x: &VecN| -> VecN {
            let (v, t) = ([x[SV], x[SV + 1], x[SV + 2]], [x[SD], x[SD + 1], x[SD + 2]]);
            let mut y = [0.0; N];
            for i in 0..3 {
                y[i] = x[i] + dt * v[i] + dot3(a[i], t);
                y[SV + i] = v[i] + dot3(b[i], t);
                y[SD + i] = dot3(th[i], t);
            }
            y[SS] = x[SS];
            y
        };
        // F·P, column by column (P is symmetric, so its rows are its columns).
        let mut fp = [[0.0; N]; N];
        for (c, col) in self.cov.iter().enumerate() {
            let y = apply(col);
            for (row, &v) in fp.iter_mut().zip(y.iter()) {
                row[c] = v;
            }
        }
        // (F·P)·Fᵀ: row r is F applied to row r of F·P.
        for (out, row) in self.cov.iter_mut().zip(fp.iter()) {
            *out = apply(row);
        }
        let c = &self.cfg;
        let q_vel = [sq(c.accel_noise_xy), sq(c.accel_noise_xy), sq(c.accel_noise_z)];
        let q_att = [
            sq(c.gyro_noise_roll_pitch),
            sq(c.gyro_noise_roll_pitch),
            sq(c.gyro_noise_yaw),
        ];
        for i in 0..3 {
            self.cov[SV + i][SV + i] += q_vel[i] * PREDICT_PERIOD_S * dt;
            self.cov[SD + i][SD + i] += q_att[i] * PREDICT_PERIOD_S * dt;
        }
        if c.initial_std_flow_scale > 0.0 {
            self.cov[SS][SS] += sq(FLOW_SCALE_WALK_PER_SQRT_S) * dt;
        }
        self.condition_covariance();
        self.blk_dt = 0.0;
        self.blk_f = [0.0; 3];
        self.blk_rot = [0.0; 3];
        self.blk_rest = true;
    }

    /// After folding `δθ` into `q` the attitude error is re-expressed about the new reference:
    /// `P ← G P Gᵀ`, `G = I − [δθ/2]×` on the attitude block (stock kalmanCoreFinalize).
    pub(super) fn rotate_attitude_covariance(&mut self, dtheta: V3) {
        let s = skew(scale3(dtheta, 0.5));
        let mut g: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for i in 0..3 {
            for j in 0..3 {
                g[i][j] -= s[i][j];
            }
        }
        // Rows: P[SD.., :] ← G · P[SD.., :].
        for col in 0..N {
            let v = [self.cov[SD][col], self.cov[SD + 1][col], self.cov[SD + 2][col]];
            let nv = mul_m3_v3(&g, v);
            for (row, &x) in self.cov[SD..SD + 3].iter_mut().zip(nv.iter()) {
                row[col] = x;
            }
        }
        // Columns: P[:, SD..] ← P[:, SD..] · Gᵀ.
        for row in self.cov.iter_mut() {
            let v = [row[SD], row[SD + 1], row[SD + 2]];
            let nv = mul_m3_v3(&g, v);
            row[SD..SD + 3].copy_from_slice(&nv);
        }
    }

    /// At rest on the ground: zero velocity, and gravity gives roll and pitch.
    pub(super) fn rest_update(&mut self, f_mean: V3) {
        let vr = sq(self.cfg.rest_velocity_std_m_s);
        for i in 0..3 {
            let mut h = [0.0; N];
            h[SV + i] = 1.0;
            self.scalar_update(&h, -self.vel[i], vr);
        }
        let n = norm3(f_mean);
        if n > 0.5 * GRAVITY_M_S2 {
            // Predicted specific force g·Rᵀe_z = g·(R20, R21, R22); its error Jacobian is g·[g_b]×.
            let f_dir = scale3(f_mean, GRAVITY_M_S2 / n);
            let ar = sq(self.cfg.rest_accel_std_m_s2);
            for axis in 0..2 {
                let r = quat_to_rot(self.quat);
                let gb = scale3(r[2], GRAVITY_M_S2);
                let sk = skew(gb);
                let mut h = [0.0; N];
                h[SD..SD + 3].copy_from_slice(&sk[axis]);
                self.scalar_update(&h, f_dir[axis] - gb[axis], ar);
            }
        }
        self.diag.rest_updates = self.diag.rest_updates.saturating_add(1);
    }

    /// Symmetrise, bound the diagonal (stock), and keep every correlation below 1 so that rounding can
    /// never make `P` indefinite.
    pub(super) fn condition_covariance(&mut self) {
        for i in 0..N {
            self.cov[i][i] = self.cov[i][i].clamp(COVARIANCE_MIN, COVARIANCE_MAX);
        }
        for i in 0..N {
            for j in (i + 1)..N {
                let mut v = 0.5 * (self.cov[i][j] + self.cov[j][i]);
                // |correlation| ≤ 0.999, compared squared: the square root only when it must clamp (rare).
                let bound2 = 0.998 * self.cov[i][i] * self.cov[j][j];
                if v * v > bound2 {
                    v = libm::sqrtf(bound2).copysign(v);
                }
                self.cov[i][j] = v;
                self.cov[j][i] = v;
            }
        }
    }
}
