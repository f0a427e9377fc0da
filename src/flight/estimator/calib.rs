//! Gyro-bias and accelerometer-scale calibration at rest (the stock `processGyroBias` /
//! `processAccScale`, \[FW\] src/hal/src/sensors_bmi088_bmp3xx.c L83-91, `docs/hardware.md` §2).
//!
//! Samples are gathered in windows of [`WINDOW`] (stock: a 512-sample buffer, ~0.5 s at 1 kHz). A window
//! whose gyro variance is below the stock threshold on every axis (100 LSB² at 0.061 °/s per LSB) and whose
//! accelerometer is quiet and near 1 g was taken at rest: its mean gyro is the bias, its mean specific force
//! gives the accelerometer scale (|f| must read g) and the level attitude. Otherwise the window is thrown
//! away and the next one starts. Sums are kept relative to each window's first sample so that the f32
//! variance does not cancel catastrophically.

use crate::math::{V3, add3, finite3, norm3, scale3, sub3};
use crate::types::GRAVITY_M_S2;

/// Samples per calibration window (stock `SENSORS_NBR_OF_BIAS_SAMPLES` = 512).
pub(crate) const WINDOW: u32 = 512;

/// Gyro variance threshold per axis, (rad/s)²: the stock 100 LSB² with 4000/65536 °/s per LSB
/// (`GYRO_VARIANCE_THRESHOLD_X/Y/Z`): (10 · 0.061035 °/s)² = (0.010653 rad/s)².
pub(crate) const GYRO_VARIANCE_MAX: f32 = 1.135e-4;

/// Accelerometer variance threshold per axis, (m/s²)² (not in stock, which trusts a still gyro): a
/// drone carried smoothly can have a quiet gyro but a moving accelerometer. 0.3 m/s² RMS is well above
/// the BMI088's noise and the rest vibration of a disarmed Crazyflie.
pub(crate) const ACCEL_VARIANCE_MAX: f32 = 0.09;

/// The mean specific force of a rest window must be within 15 % of g (else the accelerometer is broken or
/// the drone is in free fall / being swung; stock's scale calibration has no such check).
const ACCEL_NORM_TOLERANCE: f32 = 0.15;

/// What a completed rest window measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RestWindow {
    /// Mean gyro, rad/s: the bias.
    pub gyro_mean: V3,
    /// Mean specific force, m/s² (unscaled).
    pub accel_mean: V3,
}

impl RestWindow {
    /// Accelerometer scale making |f| read g, limited to ±10 % (stock clamps nothing, but a scale beyond
    /// that is a fault, not a calibration).
    pub(crate) fn accel_scale(&self) -> f32 {
        let n = norm3(self.accel_mean);
        if n > 1e-3 {
            (GRAVITY_M_S2 / n).clamp(0.9, 1.1)
        } else {
            1.0
        }
    }
}

/// The running window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Calibrator {
    count: u32,
    gyro_ref: V3,
    accel_ref: V3,
    gyro_sum: V3,
    gyro_sq: V3,
    accel_sum: V3,
    accel_sq: V3,
}

impl Calibrator {
    pub(crate) const fn new() -> Self {
        Self {
            count: 0,
            gyro_ref: [0.0; 3],
            accel_ref: [0.0; 3],
            gyro_sum: [0.0; 3],
            gyro_sq: [0.0; 3],
            accel_sum: [0.0; 3],
            accel_sq: [0.0; 3],
        }
    }

    /// Drop the current window (the drone took off or the samples were bad).
    pub(crate) fn restart(&mut self) {
        *self = Self::new();
    }

    /// Add one sample; returns the window's result when a window completes at rest.
    pub(crate) fn push(&mut self, gyro: V3, accel: V3) -> Option<RestWindow> {
        if !(finite3(gyro) && finite3(accel)) {
            self.restart();
            return None;
        }
        if self.count == 0 {
            self.gyro_ref = gyro;
            self.accel_ref = accel;
        }
        let dg = sub3(gyro, self.gyro_ref);
        let da = sub3(accel, self.accel_ref);
        self.gyro_sum = add3(self.gyro_sum, dg);
        self.accel_sum = add3(self.accel_sum, da);
        for i in 0..3 {
            self.gyro_sq[i] += dg[i] * dg[i];
            self.accel_sq[i] += da[i] * da[i];
        }
        self.count += 1;
        if self.count < WINDOW {
            return None;
        }
        let n = self.count as f32;
        let g_mean = scale3(self.gyro_sum, 1.0 / n);
        let a_mean = scale3(self.accel_sum, 1.0 / n);
        let mut still = true;
        for i in 0..3 {
            let g_var = self.gyro_sq[i] / n - g_mean[i] * g_mean[i];
            let a_var = self.accel_sq[i] / n - a_mean[i] * a_mean[i];
            still &= g_var < GYRO_VARIANCE_MAX && a_var < ACCEL_VARIANCE_MAX;
        }
        let result = RestWindow {
            gyro_mean: add3(self.gyro_ref, g_mean),
            accel_mean: add3(self.accel_ref, a_mean),
        };
        let norm = norm3(result.accel_mean);
        still &= (norm - GRAVITY_M_S2).abs() < ACCEL_NORM_TOLERANCE * GRAVITY_M_S2;
        self.restart();
        if still && finite3(result.gyro_mean) && finite3(result.accel_mean) {
            Some(result)
        } else {
            None
        }
    }
}
