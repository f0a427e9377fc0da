//! The drone's sensors as the firmware's drivers deliver them (`cfnav::types`), computed from the simulated
//! truth ([`Quadrotor`]) and the world ([`Geometry`]).
//!
//! Every sensor has a `sample(...)` method; the runner calls each at its rate (the stock rates are in the
//! constants below) and owns the timestamps. All randomness comes from the `SmallRng` passed in, so a run
//! is deterministic for a seed as long as the calls come in the same order. No method panics or returns a
//! non-finite value, whatever the state.
//!
//! | sensor | rate | model |
//! |--------|------|-------|
//! | [`Imu`] (BMI088) | 1 kHz | truth + per-seed bias + bias random walk + white noise, 16-bit ±2000 °/s, ±24 g |
//! | [`FlowSensor`] (PMW3901) | 100 Hz | stock `mm_flow.c` model on the true state × (1 + scale error) + noise, i16 counts, optional dropouts |
//! | [`ZRanger`] (VL53L1x, Flow deck) | 40 Hz | ray along body −z, stock noise model, `None` beyond 4 m, optional outliers |
//! | [`MultiRanger`] (5 × VL53L1x) | 10 Hz | rays along body ±x, ±y, +z (optionally 27° cones for ±x, ±y), 1 % noise, `None` beyond 4 m, dropouts, optional outliers |
//! | [`BatterySensor`] (nRF VBAT) | 100 Hz | loaded battery voltage + noise |
//!
//! All sensors sit at the body origin (the stock flow-deck position parameters default to 0 too); the
//! Multi-ranger's ~1.5 cm offset from the centre to its sensors is neglected.

use cfnav::math::finite3;
use cfnav::types::{FlowSample, ImuSample, MultiRangerSample, RangeReading};
use rand::Rng;
use rand::rngs::SmallRng;
use rand_distr::StandardNormal;

use super::physics::{Geometry, Quadrotor};

/// Stock IMU rate (gyro data-ready), Hz.
pub const IMU_RATE_HZ: u32 = 1000;
/// Stock flow-deck read rate, Hz.
pub const FLOW_RATE_HZ: u32 = 100;
/// Stock z-ranger rate (25 ms timing budget), Hz.
pub const ZRANGER_RATE_HZ: u32 = 40;
/// Stock Multi-ranger rate, Hz.
pub const MULTIRANGER_RATE_HZ: u32 = 10;
/// Battery state packets from the nRF, Hz.
pub const BATTERY_RATE_HZ: u32 = 100;

/// Pixels across the PMW3901 (stock `Npix`).
pub const FLOW_NPIX: f32 = 35.0;
/// The PMW3901's aperture term (stock `thetapix` = 2·sin(42°/2)), rad.
pub const FLOW_THETAPIX: f32 = 0.716_74;
/// Counts per pixel: the stock model uses `N = 0.1·dpixel` (`FLOW_RESOLUTION`).
pub const FLOW_COUNTS_PER_PIXEL: f32 = 10.0;

fn gauss(rng: &mut SmallRng) -> f32 {
    rng.sample::<f32, _>(StandardNormal)
}

// ---------------------------------------------------------------------------------------------------------
// IMU
// ---------------------------------------------------------------------------------------------------------

/// BMI088 model parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuParams {
    /// Gyro white noise per sample, rad/s. Default 0.005: the datasheet's 0.014 °/s/√Hz over the stock
    /// 116 Hz filter bandwidth is 0.15 °/s ≈ 0.0026 rad/s; doubled for motor vibration.
    pub gyro_noise_rad_s: f32,
    /// Constant gyro bias per axis, drawn uniformly in ±this per seed, rad/s. Default 0.02.
    pub gyro_bias_max_rad_s: f32,
    /// Gyro bias random walk, rad/s per √s. Default 2e-5 (≈ 2e-4 rad/s, 0.01 °/s, after 100 s): the
    /// BMI088 datasheet gives a bias stability of 2 °/h (≈ 1e-5 rad/s); the margin stands for the motors
    /// warming the board in flight. (Unobservable in yaw with flow alone, so it sets the heading drift.)
    pub gyro_bias_walk_rad_s_sqrt_s: f32,
    /// Accelerometer white noise per sample, m/s². Default 0.04: the datasheet's 175 µg/√Hz over the stock
    /// ~145 Hz bandwidth is ≈ 0.021 m/s²; doubled for vibration.
    pub accel_noise_m_s2: f32,
    /// Constant accelerometer bias per axis, uniform in ±this per seed, m/s². Default 0.05 (the BMI088's
    /// typical ±20 mg offset, partly trimmed by the factory calibration).
    pub accel_bias_max_m_s2: f32,
    /// Accelerometer bias random walk, m/s² per √s. Default 1e-3.
    pub accel_bias_walk_m_s2_sqrt_s: f32,
    /// Sample period, s (for the random walk). Default 0.001.
    pub period_s: f32,
    /// Quantise to the stock ranges (±2000 °/s and ±24 g, 16 bit), which also saturates crashes.
    pub quantise: bool,
}

impl Default for ImuParams {
    fn default() -> Self {
        Self {
            gyro_noise_rad_s: 0.005,
            gyro_bias_max_rad_s: 0.02,
            gyro_bias_walk_rad_s_sqrt_s: 2e-5,
            accel_noise_m_s2: 0.04,
            accel_bias_max_m_s2: 0.05,
            accel_bias_walk_m_s2_sqrt_s: 1e-3,
            period_s: 0.001,
            quantise: true,
        }
    }
}

impl ImuParams {
    /// No noise, no bias, no quantisation: the truth.
    pub fn ideal() -> Self {
        Self {
            gyro_noise_rad_s: 0.0,
            gyro_bias_max_rad_s: 0.0,
            gyro_bias_walk_rad_s_sqrt_s: 0.0,
            accel_noise_m_s2: 0.0,
            accel_bias_max_m_s2: 0.0,
            accel_bias_walk_m_s2_sqrt_s: 0.0,
            period_s: 0.001,
            quantise: false,
        }
    }
}

/// Gyro LSB at ±2000 °/s, 16 bit, rad/s.
pub const GYRO_LSB_RAD_S: f32 = 4000.0 / 65536.0 * core::f32::consts::PI / 180.0;
/// Accelerometer LSB at ±24 g, 16 bit, m/s².
pub const ACCEL_LSB_M_S2: f32 = 48.0 / 65536.0 * cfnav::types::GRAVITY_M_S2;

/// The BMI088 gyro + accelerometer.
#[derive(Clone, Debug)]
pub struct Imu {
    params: ImuParams,
    gyro_bias: [f32; 3],
    accel_bias: [f32; 3],
    gyro_walk_step: f32,
    accel_walk_step: f32,
    count: u32,
}

const WALK_EVERY: u32 = 10;

impl Imu {
    /// An IMU with its biases drawn from `rng`.
    pub fn new(params: ImuParams, rng: &mut SmallRng) -> Self {
        let clean = |v: f32| if v.is_finite() { v.abs() } else { 0.0 };
        let gb = clean(params.gyro_bias_max_rad_s);
        let ab = clean(params.accel_bias_max_m_s2);
        let mut draw = |m: f32| if m > 0.0 { rng.random_range(-m..=m) } else { 0.0 };
        let gyro_bias = [draw(gb), draw(gb), draw(gb)];
        let accel_bias = [draw(ab), draw(ab), draw(ab)];
        let sp = (clean(params.period_s) * WALK_EVERY as f32).sqrt();
        Self {
            gyro_walk_step: clean(params.gyro_bias_walk_rad_s_sqrt_s) * sp,
            accel_walk_step: clean(params.accel_bias_walk_m_s2_sqrt_s) * sp,
            count: 0,
            params,
            gyro_bias,
            accel_bias,
        }
    }

    /// The present gyro bias, rad/s (truth, for tests and plots).
    pub fn gyro_bias(&self) -> [f32; 3] {
        self.gyro_bias
    }

    /// Sets the gyro bias, rad/s (tests: a bias that changes after the at-rest calibration, e.g. with the
    /// temperature, turns into a heading drift only map-relative fixes can see).
    pub fn set_gyro_bias(&mut self, bias_rad_s: [f32; 3]) {
        self.gyro_bias = bias_rad_s;
    }

    /// The present accelerometer bias, m/s².
    pub fn accel_bias(&self) -> [f32; 3] {
        self.accel_bias
    }

    /// One reading (call at [`IMU_RATE_HZ`]).
    pub fn sample(&mut self, truth: &Quadrotor, rng: &mut SmallRng) -> ImuSample {
        let p = &self.params;
        let gmax = 2.0 * p.gyro_bias_max_rad_s.abs().max(0.01);
        let amax = 2.0 * p.accel_bias_max_m_s2.abs().max(0.05);
        // The biases wander every WALK_EVERY samples (same statistics, fewer random draws).
        self.count = self.count.wrapping_add(1);
        if self.count.is_multiple_of(WALK_EVERY) {
            if self.gyro_walk_step > 0.0 {
                for b in &mut self.gyro_bias {
                    *b = (*b + self.gyro_walk_step * gauss(rng)).clamp(-gmax, gmax);
                }
            }
            if self.accel_walk_step > 0.0 {
                for b in &mut self.accel_bias {
                    *b = (*b + self.accel_walk_step * gauss(rng)).clamp(-amax, amax);
                }
            }
        }
        let w = truth.rates();
        let f = truth.specific_force();
        let (w, f) = if finite3(w) && finite3(f) {
            (w, f)
        } else {
            ([0.0; 3], [0.0, 0.0, cfnav::types::GRAVITY_M_S2])
        };
        let mut out = ImuSample::default();
        for i in 0..3 {
            let mut g = w[i] + self.gyro_bias[i];
            let mut a = f[i] + self.accel_bias[i];
            if p.gyro_noise_rad_s > 0.0 {
                g += p.gyro_noise_rad_s * gauss(rng);
            }
            if p.accel_noise_m_s2 > 0.0 {
                a += p.accel_noise_m_s2 * gauss(rng);
            }
            if p.quantise {
                g = quantise(g, GYRO_LSB_RAD_S);
                a = quantise(a, ACCEL_LSB_M_S2);
            }
            out.gyro_rad_s[i] = if g.is_finite() { g } else { 0.0 };
            out.accel_m_s2[i] = if a.is_finite() { a } else { 0.0 };
        }
        out
    }
}

fn quantise(v: f32, lsb: f32) -> f32 {
    // Saturating float → int casts round towards zero and map NaN to 0: cheaper than `round()`.
    let n = v / lsb;
    ((n + 0.5f32.copysign(n)) as i32).clamp(-32768, 32767) as f32 * lsb
}

// ---------------------------------------------------------------------------------------------------------
// Deck faults
// ---------------------------------------------------------------------------------------------------------

/// How a deck sensor fails from a given time on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorFault {
    /// No more readings (the bus or the chip died): `sample` returns `None` (flow) / `None` ranges.
    Stopped,
    /// Readings keep coming but are invalid (flow: `motion_valid` false, squal 0; rangers: `None`).
    Invalid,
    /// The reading freezes at its last value (rangers only; the flow sensor treats it as `Invalid`).
    Stuck,
}

// ---------------------------------------------------------------------------------------------------------
// Optical flow
// ---------------------------------------------------------------------------------------------------------

/// PMW3901 model parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlowParams {
    /// White noise on each axis, counts. Default 1.0 (the stock filter assumes std 2.0 counts).
    pub noise_counts: f32,
    /// Below this camera height the sensor reports no valid motion (out of focus), m. Default 0.08.
    pub min_height_m: f32,
    /// Above this it reports no valid motion (features too small), m. Default 4.0.
    pub max_height_m: f32,
    /// The world is dark (no features): never valid.
    pub dark: bool,
    /// Surface quality at zero height, before the height falloff. Default 150.
    pub squal_nominal: f32,
    /// Surface quality lost per metre of height. Default 15 (≈ 140 at 0.5 m, 90 at 4 m).
    pub squal_per_m: f32,
    /// Period assumed for the first reading, s. Default 0.01.
    pub nominal_period_s: f32,
    /// Scale error: the sensor reads `(1 + this)` × the model's flow (floor texture, lens, a height the
    /// model gets wrong). Default 0. (`[sensors] flow_scale_error`.)
    pub scale_error: f32,
    /// Probability that a reading is invalid (`motion_valid` false, squal 0), per reading. Default 0.
    /// (`[sensors] flow_dropout`.)
    pub dropout_probability: f32,
}

impl Default for FlowParams {
    fn default() -> Self {
        Self {
            noise_counts: 1.0,
            min_height_m: 0.08,
            max_height_m: 4.0,
            dark: false,
            squal_nominal: 150.0,
            squal_per_m: 15.0,
            nominal_period_s: 0.01,
            scale_error: 0.0,
            dropout_probability: 0.0,
        }
    }
}

/// The PMW3901 on the Flow deck, already mapped to the body axes as the stock driver does.
///
/// For each reading, with `dt` the time since the previous one (from the truth's clock), `h` the height of
/// the camera above the surface it actually sees (ray cast along body −z, times `R22`, so pads and box tops
/// count), `v_b` the true body velocity and `ω` the true rates:
/// `dpixel_x = 10·dt·(35/0.71674)·(v_bx·R22/h − ω_y)`, `dpixel_y = 10·dt·(35/0.71674)·(v_by·R22/h + ω_x)`,
/// times `1 + scale_error`, plus Gaussian noise, rounded to counts with the fractional remainder carried to the next reading (as the
/// sensor's internal accumulator does) and saturated to i16.
#[derive(Clone, Debug)]
pub struct FlowSensor {
    params: FlowParams,
    last_time_s: Option<f64>,
    residual: [f32; 2],
    fault: Option<(f64, SensorFault)>,
}

impl FlowSensor {
    /// A flow sensor.
    pub fn new(params: FlowParams) -> Self {
        Self {
            params,
            last_time_s: None,
            residual: [0.0; 2],
            fault: None,
        }
    }

    /// The parameters.
    pub fn params_mut(&mut self) -> &mut FlowParams {
        &mut self.params
    }

    /// Makes the sensor fail from simulated time `at_time_s` on (`None` clears the fault).
    pub fn inject_fault(&mut self, fault: Option<(f64, SensorFault)>) {
        self.fault = fault;
    }

    /// The noise-free flow the stock model predicts, counts (not rounded): `None` when the geometry gives no
    /// usable height. Exposed so tests can compare.
    pub fn model_counts<G: Geometry + ?Sized>(truth: &Quadrotor, geometry: &G, dt_s: f32) -> Option<[f32; 2]> {
        let h = Self::camera_height(truth, geometry, 100.0)?;
        Self::model_at_height(truth, h, dt_s)
    }

    fn model_at_height(truth: &Quadrotor, h: f32, dt_s: f32) -> Option<[f32; 2]> {
        let r = truth.rotation();
        let r22 = r[2][2];
        let vb = truth.body_velocity();
        let w = truth.rates();
        let k = dt_s * (FLOW_NPIX / FLOW_THETAPIX) * FLOW_COUNTS_PER_PIXEL;
        let out = [k * (vb[0] * r22 / h - w[1]), k * (vb[1] * r22 / h + w[0])];
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// Height of the camera above the surface along its axis (distance × R22), m.
    fn camera_height<G: Geometry + ?Sized>(truth: &Quadrotor, geometry: &G, max_m: f32) -> Option<f32> {
        let r = truth.rotation();
        let r22 = r[2][2];
        if r22.is_nan() || r22 <= 0.1 {
            return None;
        }
        let dir = [-r[0][2], -r[1][2], -r[2][2]];
        let pos = truth.position();
        if !finite3(pos) || !finite3(dir) {
            return None;
        }
        let d = geometry.ray_cast(pos, dir, max_m / r22)?;
        let h = d * r22;
        (h.is_finite() && h > 0.0).then_some(h)
    }

    /// One reading (call at [`FLOW_RATE_HZ`]); `None` when the sensor has [`SensorFault::Stopped`].
    pub fn sample<G: Geometry + ?Sized>(
        &mut self,
        truth: &Quadrotor,
        geometry: &G,
        rng: &mut SmallRng,
    ) -> Option<FlowSample> {
        let now = truth.time_s();
        let nominal = if self.params.nominal_period_s > 0.0 {
            self.params.nominal_period_s
        } else {
            0.01
        };
        let dt = match self.last_time_s {
            Some(t) if now > t && (now - t) < 10.0 => (now - t) as f32,
            _ => nominal,
        };
        self.last_time_s = Some(now);
        let fault = self.fault.and_then(|(t, f)| (now >= t).then_some(f));
        if fault == Some(SensorFault::Stopped) {
            self.residual = [0.0; 2];
            return None;
        }
        let invalid = FlowSample {
            dpixel_x: 0,
            dpixel_y: 0,
            squal: 0,
            motion_valid: false,
            dt_s: dt,
        };
        if fault.is_some() || self.params.dark {
            self.residual = [0.0; 2];
            return Some(invalid);
        }
        let p = self.params;
        let valid = Self::camera_height(truth, geometry, p.max_height_m + 0.5)
            .filter(|h| *h >= p.min_height_m && *h <= p.max_height_m);
        let Some((h, model)) = valid.and_then(|h| Some((h, Self::model_at_height(truth, h, dt)?))) else {
            self.residual = [0.0; 2];
            return Some(invalid);
        };
        // A dropped reading: the chip flags no valid motion; its accumulator keeps what it had (no draw, so
        // no change to the noise stream, when the probability is 0).
        if p.dropout_probability > 0.0 && rng.random::<f32>() < p.dropout_probability {
            return Some(invalid);
        }
        // A poor floor patch under the camera: its own dropout (drawn only over a patch, so the stream is
        // unchanged elsewhere) and SQUAL.
        let pos = truth.position();
        let patch = geometry.flow_floor(pos[0], pos[1]);
        if let Some((_, Some(q))) = patch
            && q > 0.0
            && rng.random::<f32>() < q
        {
            return Some(invalid);
        }
        let scale = 1.0 + if p.scale_error.is_finite() { p.scale_error } else { 0.0 };
        let mut counts = [0i16; 2];
        for i in 0..2 {
            let mut v = model[i] * scale + self.residual[i];
            if p.noise_counts > 0.0 {
                v += p.noise_counts * gauss(rng);
            }
            let c = v.round().clamp(i16::MIN as f32, i16::MAX as f32);
            self.residual[i] = (v - c).clamp(-0.5, 0.5);
            counts[i] = c as i16;
        }
        let squal = match patch {
            Some((Some(q), _)) => (f32::from(q) + 3.0 * gauss(rng)).round().clamp(0.0, 255.0) as u8,
            _ => (p.squal_nominal - p.squal_per_m * h + 3.0 * gauss(rng))
                .round()
                .clamp(20.0, 255.0) as u8,
        };
        Some(FlowSample {
            dpixel_x: counts[0],
            dpixel_y: counts[1],
            squal,
            motion_valid: true,
            dt_s: dt,
        })
    }
}

// ---------------------------------------------------------------------------------------------------------
// Rangers (VL53L1x)
// ---------------------------------------------------------------------------------------------------------

/// The Flow deck's downward VL53L1x.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZRangerParams {
    /// Beyond this true range there is no valid return, m. Default 4.0 (the noise model below gives 0.2 m std
    /// there; the stock driver's own limit, readings ≥ 5 m dropped, is applied on top).
    pub max_range_m: f32,
    /// Readings at or above this are dropped (stock `RANGE_OUTLIER_LIMIT` 5000 mm), m.
    pub outlier_limit_m: f32,
    /// Probability that a reading is invalid (range status not VALID), per reading. Default 0.005.
    pub invalid_probability: f32,
    /// Scale of the noise model `std(d) = a·(1 + exp(b·(d − c)))`; 0 = noise-free. Default 1.
    pub noise_scale: f32,
    /// Probability that a reading is a wrong range, uniform in `0..max_range_m` (a multipath or
    /// cross-talk return), per reading. Default 0. (`[sensors] zrange_outlier_rate`.)
    pub outlier_probability: f32,
}

impl Default for ZRangerParams {
    fn default() -> Self {
        Self {
            max_range_m: 4.0,
            outlier_limit_m: 5.0,
            invalid_probability: 0.005,
            noise_scale: 1.0,
            outlier_probability: 0.0,
        }
    }
}

/// Stock zranger2.c noise: std(d) = 0.0025·(1 + exp(2.9214·(d − 2.5))) m.
pub fn zranger_noise_std_m(d: f32) -> f32 {
    0.0025 * (1.0 + (2.9214 * (d.min(10.0) - 2.5)).exp())
}

/// The Flow deck's z-ranger: the distance along body −z to whatever is below (floor, pad or box top).
#[derive(Clone, Debug)]
pub struct ZRanger {
    params: ZRangerParams,
    fault: Option<(f64, SensorFault)>,
    last: RangeReading,
}

impl ZRanger {
    /// A z-ranger.
    pub fn new(params: ZRangerParams) -> Self {
        Self {
            params,
            fault: None,
            last: None,
        }
    }

    /// Makes the sensor fail from `at_time_s` on (`None` clears the fault). `Stopped` and `Invalid` both
    /// give `None`; `Stuck` repeats the last reading.
    pub fn inject_fault(&mut self, fault: Option<(f64, SensorFault)>) {
        self.fault = fault;
    }

    /// One reading (call at [`ZRANGER_RATE_HZ`]).
    pub fn sample<G: Geometry + ?Sized>(
        &mut self,
        truth: &Quadrotor,
        geometry: &G,
        rng: &mut SmallRng,
    ) -> RangeReading {
        match self.fault.and_then(|(t, f)| (truth.time_s() >= t).then_some(f)) {
            Some(SensorFault::Stuck) => return self.last,
            Some(_) => return None,
            None => {}
        }
        let r = truth.rotation();
        let dir = [-r[0][2], -r[1][2], -r[2][2]];
        let p = self.params;
        let noisy = range(geometry, truth.position(), dir, p.max_range_m).and_then(|d| {
            let d = d + p.noise_scale * zranger_noise_std_m(d) * gauss(rng);
            (d.is_finite() && d < p.outlier_limit_m).then_some(d.max(0.0))
        });
        let mut out = if rng.random::<f32>() < p.invalid_probability {
            None
        } else {
            noisy
        };
        // Drawn only when enabled, so that the default noise stream stays as it was.
        if p.outlier_probability > 0.0 && rng.random::<f32>() < p.outlier_probability {
            out = Some(rng.random::<f32>() * p.max_range_m.max(0.0));
        }
        if out.is_some() {
            self.last = out;
        }
        out
    }
}

fn range<G: Geometry + ?Sized>(geometry: &G, origin: [f32; 3], dir: [f32; 3], max_m: f32) -> Option<f32> {
    if !finite3(origin) || !finite3(dir) || max_m.is_nan() || max_m <= 0.0 {
        return None;
    }
    geometry
        .ray_cast(origin, dir, max_m)
        .filter(|d| d.is_finite() && *d >= 0.0 && *d <= max_m)
}

/// The range a horizontal cone reports (see [`MultiRanger`]): the nearest ray range that a neighbouring
/// ray confirms (within 2 cm + 10 %), `None` when no two neighbouring rays return.
fn cone_range<G: Geometry + ?Sized>(
    geometry: &G,
    origin: [f32; 3],
    axis: [f32; 3],
    up: [f32; 3],
    half_angle_rad: f32,
    max_m: f32,
) -> Option<f32> {
    // The axis turned about the body's z axis: u(φ) = axis·cos φ + (up × axis)·sin φ.
    let side = [
        up[1] * axis[2] - up[2] * axis[1],
        up[2] * axis[0] - up[0] * axis[2],
        up[0] * axis[1] - up[1] * axis[0],
    ];
    let mut ranges = [None; CONE_RAYS];
    for (k, r) in ranges.iter_mut().enumerate() {
        let phi = half_angle_rad * (2.0 * k as f32 / (CONE_RAYS - 1) as f32 - 1.0);
        let (s, c) = phi.sin_cos();
        let dir = [
            axis[0] * c + side[0] * s,
            axis[1] * c + side[1] * s,
            axis[2] * c + side[2] * s,
        ];
        *r = range(geometry, origin, dir, max_m);
    }
    let confirmed = |k: usize| {
        let d = ranges[k]?;
        let agrees = |j: usize| ranges[j].is_some_and(|e| (e - d).abs() <= 0.02 + 0.1 * d);
        ((k > 0 && agrees(k - 1)) || (k + 1 < CONE_RAYS && agrees(k + 1))).then_some(d)
    };
    (0..CONE_RAYS).filter_map(confirmed).min_by(f32::total_cmp)
}

/// One of the Multi-ranger's beams, in [`MultiRangerSample`] order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Beam {
    /// Body +x.
    Front = 0,
    /// Body −x.
    Back = 1,
    /// Body +y.
    Left = 2,
    /// Body −y.
    Right = 3,
    /// Body +z.
    Up = 4,
}

/// Multi-ranger model parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MultiRangerParams {
    /// Beyond this there is no valid return, m. Default 4.0 (VL53L1x long mode).
    pub max_range_m: f32,
    /// Noise std as a fraction of the range. Default 0.01.
    pub noise_relative: f32,
    /// Noise std floor, m. Default 0.003. The total std is `√(floor² + (rel·d)²)`.
    pub noise_floor_m: f32,
    /// Probability that a reading is invalid, per beam and reading. Default 0.005.
    /// (`[sensors] ranger_dropout` replaces it.)
    pub invalid_probability: f32,
    /// Probability that a beam's reading is a wrong range, uniform in `0..max_range_m`, per beam and
    /// reading. Default 0. (`[sensors] ranger_outlier_rate`.)
    pub outlier_probability: f32,
    /// Half of a horizontal beam's field of view, rad; 0 (the default) models a single ray along the
    /// axis. The real sensor's is 13.5° ([`VL53L1X_HALF_FOV_RAD`]), but the firmware does not read its
    /// returns as cones yet (BENCHMARKS.md §5: the cone model with today's firmware, and with a
    /// first cone-aware map, grows the mission time and the no-path aborts), so the simulator's default
    /// stays the ray until it does. No world or `[sensors]` key sets it (the world-file format in docs/formats.md has none).
    pub cone_half_angle_rad: f32,
}

/// Half the VL53L1X's field of view, rad: the datasheet's "typical full field-of-view (FoV): 27°"
/// (DocID031281 Rev 3, features).
pub const VL53L1X_HALF_FOV_RAD: f32 = 13.5 * std::f32::consts::PI / 180.0;

/// Rays across a horizontal beam's cone (odd, so one lies on the axis): 9 over 27° are 3.4° apart.
pub const CONE_RAYS: usize = 9;

impl Default for MultiRangerParams {
    fn default() -> Self {
        Self {
            max_range_m: 4.0,
            noise_relative: 0.01,
            noise_floor_m: 0.003,
            invalid_probability: 0.005,
            outlier_probability: 0.0,
            cone_half_angle_rad: 0.0,
        }
    }
}

/// The Multi-ranger deck: five VL53L1x along body +x, −x, +y, −y, +z from the body origin.
///
/// With [`MultiRangerParams::cone_half_angle_rad`] > 0 the four horizontal sensors are cones, not rays (by
/// default they are rays): a VL53L1X sees a 27° (full) field of view and reports
/// one distance for what its cone holds. Each is modelled as a fan of [`CONE_RAYS`] rays across the cone in
/// the body's x–y plane (obstacles are vertical prisms, so the plane is where the cone meets them first),
/// and reports the nearest target that *fills enough of the cone*: the nearest ray's range counts only when
/// a neighbouring ray also returns within 2 cm + 10 % of it (a target ≥ one ray spacing, 3.4°, wide: a
/// thin cylinder grazed by the cone's edge ray alone is not seen, nor a corner a single ray touches);
/// otherwise the next such pair decides. The datasheet allows a partially filled cone to be reported (the
/// nearest target dominates the return when close); demanding two rays is at least as hard as that. A
/// flat wall at incidence θ reads `D / cos(max(θ − 13.5°, 0))` (the cone's edge ray and its neighbour
/// agree within the tolerance up to ≈ 70°), shorter than the axis ray's `D / cos θ`. The upward sensor
/// stays a single ray (the ceiling is a plane square to it).
#[derive(Clone, Debug)]
pub struct MultiRanger {
    params: MultiRangerParams,
    faults: [Option<(f64, SensorFault)>; 5],
    last: [RangeReading; 5],
}

impl MultiRanger {
    /// A Multi-ranger deck.
    pub fn new(params: MultiRangerParams) -> Self {
        Self {
            params,
            faults: [None; 5],
            last: [None; 5],
        }
    }

    /// Makes one beam fail from `at_time_s` on (`None` clears it): `Stopped`/`Invalid` give `None`, `Stuck`
    /// repeats the beam's last valid reading.
    pub fn inject_fault(&mut self, beam: Beam, fault: Option<(f64, SensorFault)>) {
        self.faults[beam as usize] = fault;
    }

    /// One reading of all five beams (call at [`MULTIRANGER_RATE_HZ`]).
    pub fn sample<G: Geometry + ?Sized>(
        &mut self,
        truth: &Quadrotor,
        geometry: &G,
        rng: &mut SmallRng,
    ) -> MultiRangerSample {
        let r = truth.rotation();
        let pos = truth.position();
        let x = [r[0][0], r[1][0], r[2][0]];
        let y = [r[0][1], r[1][1], r[2][1]];
        let z = [r[0][2], r[1][2], r[2][2]];
        let dirs = [x, x.map(|v| -v), y, y.map(|v| -v), z];
        let p = self.params;
        let now = truth.time_s();
        let mut out = [None; 5];
        for (i, dir) in dirs.iter().enumerate() {
            match self.faults[i].and_then(|(t, f)| (now >= t).then_some(f)) {
                Some(SensorFault::Stuck) => {
                    out[i] = self.last[i];
                    continue;
                }
                Some(_) => continue,
                None => {}
            }
            let hit = if i < 4 && p.cone_half_angle_rad > 0.0 {
                cone_range(geometry, pos, *dir, z, p.cone_half_angle_rad, p.max_range_m)
            } else {
                range(geometry, pos, *dir, p.max_range_m)
            };
            let reading = hit.and_then(|d| {
                let rel = p.noise_relative * d;
                let std = (p.noise_floor_m * p.noise_floor_m + rel * rel).sqrt();
                let d = d + std * gauss(rng);
                d.is_finite().then_some(d.max(0.0))
            });
            out[i] = if rng.random::<f32>() < p.invalid_probability {
                None
            } else {
                reading
            };
            // Drawn only when enabled, so that the default noise stream stays as it was.
            if p.outlier_probability > 0.0 && rng.random::<f32>() < p.outlier_probability {
                out[i] = Some(rng.random::<f32>() * p.max_range_m.max(0.0));
            }
            if out[i].is_some() {
                self.last[i] = out[i];
            }
        }
        MultiRangerSample {
            front_m: out[0],
            back_m: out[1],
            left_m: out[2],
            right_m: out[3],
            up_m: out[4],
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Battery voltage
// ---------------------------------------------------------------------------------------------------------

/// The nRF51's VBAT measurement, sent to the STM32 in `PM_BATTERY_STATE` at 100 Hz.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatterySensor {
    /// Noise std, V. Default 0.005.
    pub noise_v: f32,
}

impl Default for BatterySensor {
    fn default() -> Self {
        Self { noise_v: 0.005 }
    }
}

impl BatterySensor {
    /// One reading, V (call at [`BATTERY_RATE_HZ`]).
    pub fn sample(&self, truth: &Quadrotor, rng: &mut SmallRng) -> f32 {
        let v = truth.battery_voltage() + self.noise_v * gauss(rng);
        if v.is_finite() { v.max(0.0) } else { 0.0 }
    }
}
