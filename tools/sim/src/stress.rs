//! Stress settings: the `[sensors]` and `[disturbances]` tables of world files (docs/formats.md, world files)
//! and of `--stress FILE`, and how the simulator applies them.
//!
//! Job: hold the optional keys, check their ranges (a bad value names its key), merge a `--stress` file over
//! a world's own tables, and turn them into sensor and physics parameters plus the gust process. Non-goals:
//! the models themselves (in [`super::sensors`] and [`super::physics`]). Units are those of the keys (counts,
//! fractions, rad/s, m/s², m/s, V); frames: `wind` in the arena frame.
//!
//! | key | unit | accepted | when absent (the simulator's default) | modelled as |
//! |---|---|---|---|---|
//! | `sensors.flow_noise_counts` | counts, 1σ | ≥ 0 (finite) | 1.0 | white noise on each flow axis per 10 ms reading |
//! | `sensors.flow_scale_error` | fraction | −0.3..0.3 | 0 | the flow reads (1 + this) × truth |
//! | `sensors.flow_scale_error_max` | fraction | 0..0.3, and `|flow_scale_error| + this ≤ 0.3` | 0 | **schema addition**: a further scale error drawn per seed uniformly in ± this (a batch over floors that differ) |
//! | `sensors.flow_dropout` | probability | 0..0.5 | 0 | a reading has `motion_valid` false |
//! | `sensors.zrange_outlier_rate` | probability | 0..0.5 | 0 | a z-ranger reading is uniform in 0..4 m |
//! | `sensors.ranger_outlier_rate` | probability | 0..0.5 | 0 | each Multi-ranger beam reading is uniform in 0..4 m |
//! | `sensors.ranger_dropout` | probability | 0..0.5 | 0.005 | each beam reading is missing (`None`) |
//! | `sensors.gyro_bias_max` | rad/s | ≥ 0 (finite) | 0.02 | constant per-axis gyro bias, uniform in ± this per seed |
//! | `sensors.accel_bias_max` | m/s² | ≥ 0 (finite) | 0.05 | the same for the accelerometer |
//! | `disturbances.wind` | m/s, [x, y] | finite, each ≤ 2 in magnitude | [0, 0] | steady air velocity; drag acts on the air-relative velocity |
//! | `disturbances.gust_m_s` | m/s, 1σ | ≥ 0 (finite) | 0 | per horizontal axis a first-order (Ornstein–Uhlenbeck) air velocity, τ = 1 s, stationary std this, updated every 10 ms |
//! | `disturbances.mass_scale` | factor | 0.8..1.3 | 1 | the body's mass (not its inertia: a payload at the centre) |
//! | `disturbances.motor_scale` | factor ×4 | each 0.7..1.1 | [1, 1, 1, 1] | thrust of motors M1..M4 |
//! | `disturbances.battery_start_v` | V | 3.3..4.2 | 4.2 (full) | the battery's open-circuit (resting) voltage at power-on, through the battery's OCV table |
//!
//! The wind limit (2 m/s per axis) is this simulator's choice: the spec gives none, and a Crazyflie cannot
//! hold its position in much more. Every random draw a key adds comes from its own stream or happens only
//! when the key is set, so a world flown without these tables flies exactly as before they existed.
//!
//! Memory: a few dozen bytes per world; host only.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use serde::Deserialize;
use toml::Spanned;

use super::physics::{BatteryParams, QuadParams};
use super::sensors::{FlowParams, ImuParams, MultiRangerParams, ZRangerParams};

/// Largest steady wind accepted on each axis, m/s.
pub const MAX_WIND_M_S: f32 = 2.0;
/// Time constant of the gusts, s (docs/formats.md, world files).
pub const GUST_TAU_S: f32 = 1.0;
/// Gusts are updated this often, s.
pub const GUST_PERIOD_S: f32 = 0.01;

/// `[sensors]`: every key optional (`None` keeps the simulator's default).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SensorStress {
    pub flow_noise_counts: Option<f32>,
    pub flow_scale_error: Option<f32>,
    pub flow_scale_error_max: Option<f32>,
    pub flow_dropout: Option<f32>,
    pub zrange_outlier_rate: Option<f32>,
    pub ranger_outlier_rate: Option<f32>,
    pub ranger_dropout: Option<f32>,
    pub gyro_bias_max: Option<f32>,
    pub accel_bias_max: Option<f32>,
}

/// `[disturbances]`: every key optional.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Disturbances {
    pub wind: Option<[f32; 2]>,
    pub gust_m_s: Option<f32>,
    pub mass_scale: Option<f32>,
    pub motor_scale: Option<[f32; 4]>,
    pub battery_start_v: Option<f32>,
}

/// Both tables.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stress {
    pub sensors: SensorStress,
    pub disturbances: Disturbances,
}

/// A bad stress value: the key (`sensors.flow_dropout`) and what was expected.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StressInvalid {
    pub field: String,
    pub message: String,
}

// ---------------------------------------------------------------------------------------------------------
// Parsing (shared with world files)

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSensors {
    flow_noise_counts: Option<Spanned<f32>>,
    flow_scale_error: Option<Spanned<f32>>,
    flow_scale_error_max: Option<Spanned<f32>>,
    flow_dropout: Option<Spanned<f32>>,
    zrange_outlier_rate: Option<Spanned<f32>>,
    ranger_outlier_rate: Option<Spanned<f32>>,
    ranger_dropout: Option<Spanned<f32>>,
    gyro_bias_max: Option<Spanned<f32>>,
    accel_bias_max: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDisturbances {
    wind: Option<Spanned<Vec<f32>>>,
    gust_m_s: Option<Spanned<f32>>,
    mass_scale: Option<Spanned<f32>>,
    motor_scale: Option<Spanned<Vec<f32>>>,
    battery_start_v: Option<Spanned<f32>>,
}

/// Where a key was written (byte range), reported back to the caller so errors can name the line.
pub(crate) type SpanSink<'a> = &'a mut dyn FnMut(&str, std::ops::Range<usize>);

fn take<T>(sink: SpanSink<'_>, field: &str, v: Option<Spanned<T>>) -> Option<T> {
    v.map(|v| {
        sink(field, v.span());
        v.into_inner()
    })
}

fn take_array<const N: usize>(
    sink: SpanSink<'_>,
    field: &str,
    v: Option<Spanned<Vec<f32>>>,
    what: &str,
) -> Result<Option<[f32; N]>, StressInvalid> {
    let Some(v) = take(sink, field, v) else {
        return Ok(None);
    };
    <[f32; N]>::try_from(v.as_slice()).map(Some).map_err(|_| StressInvalid {
        field: field.to_string(),
        message: format!("expected {N} numbers {what}, found an array of {}", v.len()),
    })
}

impl SensorStress {
    pub(crate) fn from_raw(raw: RawSensors, sink: SpanSink<'_>) -> Self {
        Self {
            flow_noise_counts: take(sink, "sensors.flow_noise_counts", raw.flow_noise_counts),
            flow_scale_error: take(sink, "sensors.flow_scale_error", raw.flow_scale_error),
            flow_scale_error_max: take(sink, "sensors.flow_scale_error_max", raw.flow_scale_error_max),
            flow_dropout: take(sink, "sensors.flow_dropout", raw.flow_dropout),
            zrange_outlier_rate: take(sink, "sensors.zrange_outlier_rate", raw.zrange_outlier_rate),
            ranger_outlier_rate: take(sink, "sensors.ranger_outlier_rate", raw.ranger_outlier_rate),
            ranger_dropout: take(sink, "sensors.ranger_dropout", raw.ranger_dropout),
            gyro_bias_max: take(sink, "sensors.gyro_bias_max", raw.gyro_bias_max),
            accel_bias_max: take(sink, "sensors.accel_bias_max", raw.accel_bias_max),
        }
    }
}

impl Disturbances {
    pub(crate) fn from_raw(raw: RawDisturbances, sink: SpanSink<'_>) -> Result<Self, StressInvalid> {
        Ok(Self {
            wind: take_array::<2>(sink, "disturbances.wind", raw.wind, "[x, y] (m/s)")?,
            gust_m_s: take(sink, "disturbances.gust_m_s", raw.gust_m_s),
            mass_scale: take(sink, "disturbances.mass_scale", raw.mass_scale),
            motor_scale: take_array::<4>(sink, "disturbances.motor_scale", raw.motor_scale, "[M1, M2, M3, M4]")?,
            battery_start_v: take(sink, "disturbances.battery_start_v", raw.battery_start_v),
        })
    }
}

/// A `--stress FILE` that is not a whole world: only these tables (and an optional `name`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStressFile {
    #[allow(dead_code)]
    name: Option<String>,
    sensors: Option<RawSensors>,
    disturbances: Option<RawDisturbances>,
}

// ---------------------------------------------------------------------------------------------------------
// Validation

fn bad<T>(field: &str, message: String) -> Result<T, StressInvalid> {
    Err(StressInvalid {
        field: field.to_string(),
        message,
    })
}

fn check_range(field: &str, v: Option<f32>, lo: f32, hi: f32, unit: &str) -> Result<(), StressInvalid> {
    match v {
        Some(x) if !(x.is_finite() && x >= lo && x <= hi) => {
            bad(field, format!("{x}{unit}; expected {lo} ≤ value ≤ {hi}{unit}"))
        }
        _ => Ok(()),
    }
}

fn check_non_negative(field: &str, v: Option<f32>, unit: &str) -> Result<(), StressInvalid> {
    match v {
        Some(x) if !(x.is_finite() && x >= 0.0) => bad(field, format!("{x}{unit}; expected a finite value ≥ 0{unit}")),
        _ => Ok(()),
    }
}

impl Stress {
    /// Check every key against its range (module table); the error names the first bad key.
    pub fn check(&self) -> Result<(), StressInvalid> {
        let s = &self.sensors;
        check_non_negative("sensors.flow_noise_counts", s.flow_noise_counts, " counts")?;
        check_range("sensors.flow_scale_error", s.flow_scale_error, -0.3, 0.3, "")?;
        check_range("sensors.flow_scale_error_max", s.flow_scale_error_max, 0.0, 0.3, "")?;
        if let Some(m) = s.flow_scale_error_max {
            let e = s.flow_scale_error.unwrap_or(0.0).abs();
            if e + m > 0.3 + 1e-6 {
                return bad(
                    "sensors.flow_scale_error_max",
                    format!("{m} with flow_scale_error {e}; expected |flow_scale_error| + flow_scale_error_max ≤ 0.3"),
                );
            }
        }
        check_range("sensors.flow_dropout", s.flow_dropout, 0.0, 0.5, "")?;
        check_range("sensors.zrange_outlier_rate", s.zrange_outlier_rate, 0.0, 0.5, "")?;
        check_range("sensors.ranger_outlier_rate", s.ranger_outlier_rate, 0.0, 0.5, "")?;
        check_range("sensors.ranger_dropout", s.ranger_dropout, 0.0, 0.5, "")?;
        check_non_negative("sensors.gyro_bias_max", s.gyro_bias_max, " rad/s")?;
        check_non_negative("sensors.accel_bias_max", s.accel_bias_max, " m/s²")?;
        let d = &self.disturbances;
        if let Some(w) = d.wind {
            for (axis, v) in ["x", "y"].iter().zip(w) {
                if !(v.is_finite() && v.abs() <= MAX_WIND_M_S) {
                    return bad(
                        "disturbances.wind",
                        format!("{v} m/s along {axis}; expected -{MAX_WIND_M_S} ≤ each ≤ {MAX_WIND_M_S} m/s"),
                    );
                }
            }
        }
        check_non_negative("disturbances.gust_m_s", d.gust_m_s, " m/s")?;
        check_range("disturbances.mass_scale", d.mass_scale, 0.8, 1.3, "")?;
        if let Some(m) = d.motor_scale {
            for (i, v) in m.iter().enumerate() {
                if !(v.is_finite() && (0.7..=1.1).contains(v)) {
                    return bad(
                        "disturbances.motor_scale",
                        format!("{v} for M{}; expected 0.7 ≤ each ≤ 1.1", i + 1),
                    );
                }
            }
        }
        check_range("disturbances.battery_start_v", d.battery_start_v, 3.3, 4.2, " V")?;
        Ok(())
    }

    /// Whether no key is set.
    pub fn is_empty(&self) -> bool {
        *self == Stress::default()
    }

    /// `self` with every key that `over` sets replaced by `over`'s value (a `--stress` file over a world).
    pub fn overlaid(&self, over: &Stress) -> Stress {
        let (a, b) = (&self.sensors, &over.sensors);
        let (c, d) = (&self.disturbances, &over.disturbances);
        Stress {
            sensors: SensorStress {
                flow_noise_counts: b.flow_noise_counts.or(a.flow_noise_counts),
                flow_scale_error: b.flow_scale_error.or(a.flow_scale_error),
                flow_scale_error_max: b.flow_scale_error_max.or(a.flow_scale_error_max),
                flow_dropout: b.flow_dropout.or(a.flow_dropout),
                zrange_outlier_rate: b.zrange_outlier_rate.or(a.zrange_outlier_rate),
                ranger_outlier_rate: b.ranger_outlier_rate.or(a.ranger_outlier_rate),
                ranger_dropout: b.ranger_dropout.or(a.ranger_dropout),
                gyro_bias_max: b.gyro_bias_max.or(a.gyro_bias_max),
                accel_bias_max: b.accel_bias_max.or(a.accel_bias_max),
            },
            disturbances: Disturbances {
                wind: d.wind.or(c.wind),
                gust_m_s: d.gust_m_s.or(c.gust_m_s),
                mass_scale: d.mass_scale.or(c.mass_scale),
                motor_scale: d.motor_scale.or(c.motor_scale),
                battery_start_v: d.battery_start_v.or(c.battery_start_v),
            },
        }
    }

    /// Whether a `--stress` text is a whole world file (it has `[arena]` or `[mission]`): then its tables are
    /// read through the world file's reader ([`Stress::from_toml_str`], in `crate::world`). Errors are one
    /// line naming the file, the line and the key.
    pub(crate) fn is_world_file(text: &str, file: &str) -> Result<bool, String> {
        let table: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| format!("{file}: {}", locate(text, &e)))?;
        Ok(table.contains_key("arena") || table.contains_key("mission"))
    }

    /// A file with only the `[sensors]` and `[disturbances]` tables (and an optional `name`).
    pub(crate) fn from_tables_toml_str(text: &str, file: &str) -> Result<Stress, String> {
        let raw: RawStressFile = toml::from_str(text).map_err(|e| format!("{file}: {}", locate(text, &e)))?;
        let mut spans: Vec<(String, std::ops::Range<usize>)> = Vec::new();
        let mut sink = |f: &str, r: std::ops::Range<usize>| spans.push((f.to_string(), r));
        let sensors = raw
            .sensors
            .map(|s| SensorStress::from_raw(s, &mut sink))
            .unwrap_or_default();
        let disturbances = match raw.disturbances.map(|d| Disturbances::from_raw(d, &mut sink)) {
            Some(Ok(d)) => d,
            Some(Err(e)) => return Err(stress_error(text, file, &spans, &e)),
            None => Disturbances::default(),
        };
        let stress = Stress { sensors, disturbances };
        stress.check().map_err(|e| stress_error(text, file, &spans, &e))?;
        Ok(stress)
    }

    /// The flow sensor's parameters under these settings; `seed_rng` draws the per-seed scale error.
    pub fn flow_params(&self, seed_rng: &mut SmallRng) -> FlowParams {
        let s = &self.sensors;
        let mut p = FlowParams::default();
        if let Some(v) = s.flow_noise_counts {
            p.noise_counts = v;
        }
        p.scale_error = s.flow_scale_error.unwrap_or(0.0);
        if let Some(m) = s.flow_scale_error_max.filter(|m| *m > 0.0) {
            p.scale_error += seed_rng.random_range(-m..=m);
        }
        p.dropout_probability = s.flow_dropout.unwrap_or(0.0);
        p
    }

    /// The z-ranger's parameters.
    pub fn zranger_params(&self) -> ZRangerParams {
        ZRangerParams {
            outlier_probability: self.sensors.zrange_outlier_rate.unwrap_or(0.0),
            ..ZRangerParams::default()
        }
    }

    /// The Multi-ranger's parameters.
    pub fn multiranger_params(&self) -> MultiRangerParams {
        let d = MultiRangerParams::default();
        MultiRangerParams {
            invalid_probability: self.sensors.ranger_dropout.unwrap_or(d.invalid_probability),
            outlier_probability: self.sensors.ranger_outlier_rate.unwrap_or(0.0),
            ..d
        }
    }

    /// The IMU's parameters.
    pub fn imu_params(&self) -> ImuParams {
        let d = ImuParams::default();
        ImuParams {
            gyro_bias_max_rad_s: self.sensors.gyro_bias_max.unwrap_or(d.gyro_bias_max_rad_s),
            accel_bias_max_m_s2: self.sensors.accel_bias_max.unwrap_or(d.accel_bias_max_m_s2),
            ..d
        }
    }

    /// The vehicle's parameters (mass, motors).
    pub fn quad_params(&self) -> QuadParams {
        let mut p = QuadParams::default();
        if let Some(k) = self.disturbances.mass_scale {
            p.mass_kg *= k;
        }
        if let Some(m) = self.disturbances.motor_scale {
            p.motor_thrust_scale = m;
        }
        p
    }

    /// The state of charge whose open-circuit voltage is `battery_start_v` (`None` when the key is absent).
    pub fn battery_state_of_charge(&self, battery: &BatteryParams) -> Option<f32> {
        self.disturbances
            .battery_start_v
            .map(|v| state_of_charge_for_ocv(&battery.ocv_table_v, v))
    }

    /// The steady wind, arena frame, m/s.
    pub fn wind_m_s(&self) -> [f32; 2] {
        self.disturbances.wind.unwrap_or([0.0; 2])
    }

    /// The `[sensors]`/`[disturbances]` tables as TOML (empty when nothing is set).
    pub fn to_toml_string(&self) -> String {
        fn num(v: f32) -> String {
            format!("{v:?}")
        }
        let mut out = String::new();
        let s = &self.sensors;
        let sensors: [(&str, Option<f32>); 9] = [
            ("flow_noise_counts", s.flow_noise_counts),
            ("flow_scale_error", s.flow_scale_error),
            ("flow_scale_error_max", s.flow_scale_error_max),
            ("flow_dropout", s.flow_dropout),
            ("zrange_outlier_rate", s.zrange_outlier_rate),
            ("ranger_outlier_rate", s.ranger_outlier_rate),
            ("ranger_dropout", s.ranger_dropout),
            ("gyro_bias_max", s.gyro_bias_max),
            ("accel_bias_max", s.accel_bias_max),
        ];
        if sensors.iter().any(|(_, v)| v.is_some()) {
            out.push_str("\n[sensors]\n");
            for (k, v) in sensors {
                if let Some(v) = v {
                    out.push_str(&format!("{k} = {}\n", num(v)));
                }
            }
        }
        let d = &self.disturbances;
        if *d != Disturbances::default() {
            out.push_str("\n[disturbances]\n");
            if let Some(w) = d.wind {
                out.push_str(&format!("wind = [{}, {}]\n", num(w[0]), num(w[1])));
            }
            for (k, v) in [
                ("gust_m_s", d.gust_m_s),
                ("mass_scale", d.mass_scale),
                ("battery_start_v", d.battery_start_v),
            ] {
                if let Some(v) = v {
                    out.push_str(&format!("{k} = {}\n", num(v)));
                }
            }
            if let Some(m) = d.motor_scale {
                let m: Vec<String> = m.iter().map(|v| num(*v)).collect();
                out.push_str(&format!("motor_scale = [{}]\n", m.join(", ")));
            }
        }
        out
    }
}

/// The state of charge (0..1) at which the table's open-circuit voltage (0 %, 10 %, …, 100 %) equals `v`,
/// linearly interpolated; clamped to the table's ends.
pub fn state_of_charge_for_ocv(table: &[f32; 11], v: f32) -> f32 {
    if !v.is_finite() || v <= table[0] {
        return 0.0;
    }
    for i in 0..10 {
        let (a, b) = (table[i], table[i + 1]);
        if v <= b {
            let f = if b > a { (v - a) / (b - a) } else { 1.0 };
            return (i as f32 + f.clamp(0.0, 1.0)) / 10.0;
        }
    }
    1.0
}

fn locate(text: &str, e: &toml::de::Error) -> String {
    let line = e.span().map(|s| {
        1 + text.as_bytes()[..s.start.min(text.len())]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    });
    let msg: String = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
    match line {
        Some(l) => format!("line {l}: {msg}"),
        None => msg,
    }
}

fn stress_error(text: &str, file: &str, spans: &[(String, std::ops::Range<usize>)], e: &StressInvalid) -> String {
    let line = spans.iter().find(|(f, _)| *f == e.field).map(|(_, r)| {
        1 + text.as_bytes()[..r.start.min(text.len())]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    });
    match line {
        Some(l) => format!("{file}: line {l}: {}: {}", e.field, e.message),
        None => format!("{file}: {}: {}", e.field, e.message),
    }
}

/// The gusts: per horizontal axis a first-order random air velocity with time constant [`GUST_TAU_S`] and
/// stationary standard deviation `sigma_m_s`, advanced in steps of [`GUST_PERIOD_S`] by the exact discrete
/// form `g ← a·g + σ·√(1 − a²)·n`, `a = e^(−dt/τ)`, `n` standard normal. Starts from a draw of the
/// stationary distribution. Its own random stream.
#[derive(Clone, Debug)]
pub struct Gusts {
    sigma_m_s: f32,
    a: f32,
    b: f32,
    value: [f32; 2],
    rng: SmallRng,
}

impl Gusts {
    /// Gusts of `sigma_m_s` (0: still air), seeded.
    pub fn new(sigma_m_s: f32, seed: u64) -> Self {
        let sigma = if sigma_m_s.is_finite() { sigma_m_s.max(0.0) } else { 0.0 };
        let a = (-GUST_PERIOD_S / GUST_TAU_S).exp();
        let mut rng = SmallRng::seed_from_u64(seed);
        let value = if sigma > 0.0 {
            [
                sigma * rng.sample::<f32, _>(StandardNormal),
                sigma * rng.sample::<f32, _>(StandardNormal),
            ]
        } else {
            [0.0; 2]
        };
        Self {
            sigma_m_s: sigma,
            a,
            b: sigma * (1.0 - a * a).sqrt(),
            value,
            rng,
        }
    }

    /// Advance by one [`GUST_PERIOD_S`].
    pub fn step(&mut self) {
        if self.sigma_m_s <= 0.0 {
            return;
        }
        for v in &mut self.value {
            *v = self.a * *v + self.b * self.rng.sample::<f32, _>(StandardNormal);
        }
    }

    /// Whether there are gusts at all (σ > 0).
    pub fn is_active(&self) -> bool {
        self.sigma_m_s > 0.0
    }

    /// The gust's air velocity now, arena frame, m/s.
    pub fn value(&self) -> [f32; 2] {
        self.value
    }
}
