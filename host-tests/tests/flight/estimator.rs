//! State-estimator tests against a kinematic truth generated here.
//!
//! Truth: smooth trajectories (quintic smoothstep velocity ramps, so acceleration and tilt are continuous)
//! for a drag-free quadrotor: the thrust, and with it the accelerometer, points along body z, the tilt is
//! what the acceleration needs (`tan θ = a/g`), the heading is commanded separately. Body rates come from
//! the Euler-angle rates (central differences). Sensors, per types.rs and docs/hardware.md §2:
//! * IMU at 1 kHz: gyro = ω + bias + N(0, 0.005 rad/s), accel = f + N(0, 0.05 m/s²);
//! * flow at 100 Hz: the stock model's pixels accumulated over the 10 ms at 1 kHz from the true body
//!   velocity, rates and height of the camera above the surface *where its axis hits*, × 10 counts, plus
//!   N(0, 0.5 count) sensor noise, rounded to integers; `motion_valid` false below 8 cm;
//! * range at 40 Hz: along the body −z axis to the surface, noise σ = 0.0025·(1 + exp(2.9214·(d − 2.5))),
//!   either at a point (sharp steps) or averaged over the stock 7.5° cone (steps blurred into ramps).
//!
//! Every test prints its measured errors (`cargo test -p host-tests --test flight estimator:: -- --nocapture`).

use cfnav::flight::estimator::{Estimator, EstimatorConfig};
use cfnav::math::{mul_m3t_v3, sub3};
use cfnav::types::{FlowSample, ImuSample, RangeReading, StateEstimate};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const G: f64 = 9.81;
const DT: f64 = 0.001;
const FLOW_EVERY: u64 = 10;
const TOF_EVERY: u64 = 25;
/// Stock flow scale: Npix / thetapix.
const FLOW_K: f64 = 35.0 / 0.71674;
const CONE_HALF_ANGLE: f64 = 7.5 * std::f64::consts::PI / 180.0;

type V3 = [f64; 3];

// ---------------------------------------------------------------------------------------------------------
// Truth
// ---------------------------------------------------------------------------------------------------------

/// The true vehicle state at one instant.
#[derive(Clone, Copy, Debug)]
struct Truth {
    p: V3,
    v: V3,
    /// roll, pitch, yaw.
    att: V3,
    /// Body rates.
    omega: V3,
    /// Specific force, body frame.
    f: V3,
}

trait Motion {
    fn at(&self, t: f64) -> Truth;
}

/// Quintic smoothstep and its derivative and integral on [0, 1].
fn smooth(tau: f64) -> (f64, f64, f64) {
    let t = tau.clamp(0.0, 1.0);
    let s = t * t * t * (10.0 + t * (-15.0 + 6.0 * t));
    let ds = 30.0 * t * t * (1.0 - t) * (1.0 - t);
    let is = t * t * t * t * (2.5 + t * (-3.0 + t));
    (s, ds, is)
}

#[derive(Clone, Copy, Debug)]
struct Segment {
    t0: f64,
    dur: f64,
    p0: V3,
    v0: V3,
    dv: V3,
    yaw0: f64,
    dyaw: f64,
}

impl Segment {
    fn end(&self) -> (V3, V3, f64) {
        let mut p = self.p0;
        let mut v = self.v0;
        for i in 0..3 {
            p[i] += self.v0[i] * self.dur + self.dv[i] * self.dur * 0.5;
            v[i] += self.dv[i];
        }
        (p, v, self.yaw0 + self.dyaw)
    }

    /// Position, velocity, acceleration, yaw, yaw rate.
    fn eval(&self, t: f64) -> (V3, V3, V3, f64, f64) {
        let tl = (t - self.t0).clamp(0.0, self.dur);
        let tau = if self.dur > 0.0 { tl / self.dur } else { 1.0 };
        let (s, ds, is) = smooth(tau);
        let (mut p, mut v, mut a) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        for i in 0..3 {
            p[i] = self.p0[i] + self.v0[i] * tl + self.dv[i] * self.dur * is;
            v[i] = self.v0[i] + self.dv[i] * s;
            a[i] = if self.dur > 0.0 {
                self.dv[i] * ds / self.dur
            } else {
                0.0
            };
        }
        let yaw = self.yaw0 + self.dyaw * s;
        let yaw_rate = if self.dur > 0.0 { self.dyaw * ds / self.dur } else { 0.0 };
        (p, v, a, yaw, yaw_rate)
    }
}

/// A piecewise-smooth trajectory built from velocity ramps, holds and turns.
#[derive(Clone, Debug)]
struct Trajectory {
    segs: Vec<Segment>,
    start: V3,
    yaw: f64,
}

impl Trajectory {
    fn new(start: V3, yaw: f64) -> Self {
        Self {
            segs: Vec::new(),
            start,
            yaw,
        }
    }

    fn end_state(&self) -> (f64, V3, V3, f64) {
        match self.segs.last() {
            Some(s) => {
                let (p, v, y) = s.end();
                (s.t0 + s.dur, p, v, y)
            }
            None => (0.0, self.start, [0.0; 3], self.yaw),
        }
    }

    /// Change the velocity by `dv` over `dur` seconds while turning by `dyaw`.
    fn seg(mut self, dur: f64, dv: V3, dyaw: f64) -> Self {
        let (t0, p0, v0, yaw0) = self.end_state();
        self.segs.push(Segment {
            t0,
            dur,
            p0,
            v0,
            dv,
            yaw0,
            dyaw,
        });
        self
    }

    fn hold(self, dur: f64) -> Self {
        self.seg(dur, [0.0; 3], 0.0)
    }

    fn ramp(self, dur: f64, dv: V3) -> Self {
        self.seg(dur, dv, 0.0)
    }

    fn turn(self, dur: f64, dyaw: f64) -> Self {
        self.seg(dur, [0.0; 3], dyaw)
    }

    /// Move vertically by `dz` at a peak speed of about `speed` (accelerate, cruise, decelerate).
    fn climb(self, dz: f64, speed: f64) -> Self {
        self.travel([0.0, 0.0, dz], speed, 0.6)
    }

    /// Move by `d` (a straight line) with a cruise speed and ramps of `ramp` seconds.
    fn travel(self, d: V3, speed: f64, ramp: f64) -> Self {
        let len = norm(d);
        let u = [d[0] / len, d[1] / len, d[2] / len];
        // Each ramp covers speed·ramp/2.
        let cruise = (len - speed * ramp) / speed;
        assert!(cruise >= 0.0, "travel too short for its ramps");
        let v = [u[0] * speed, u[1] * speed, u[2] * speed];
        self.ramp(ramp, v).hold(cruise).ramp(ramp, [-v[0], -v[1], -v[2]])
    }

    fn duration(&self) -> f64 {
        self.end_state().0
    }

    fn kin(&self, t: f64) -> (V3, V3, V3, f64, f64) {
        for s in &self.segs {
            if t < s.t0 + s.dur {
                return s.eval(t);
            }
        }
        let (t_end, p, v, yaw) = self.end_state();
        let dt = t - t_end;
        (
            [p[0] + v[0] * dt, p[1] + v[1] * dt, p[2] + v[2] * dt],
            v,
            [0.0; 3],
            yaw,
            0.0,
        )
    }

    /// Roll, pitch, yaw of a drag-free quadrotor: body z along the thrust `a + g·e_z`.
    fn attitude(&self, t: f64) -> V3 {
        let (_, _, a, yaw, _) = self.kin(t);
        let thrust = [a[0], a[1], a[2] + G];
        let (s, c) = yaw.sin_cos();
        // Rz(−ψ)·thrust.
        let tx = c * thrust[0] + s * thrust[1];
        let ty = -s * thrust[0] + c * thrust[1];
        let tz = thrust[2];
        let pitch = tx.atan2(tz);
        let roll = (-ty).atan2((tx * tx + tz * tz).sqrt());
        [roll, pitch, yaw]
    }
}

impl Motion for Trajectory {
    fn at(&self, t: f64) -> Truth {
        let (p, v, a, _, _) = self.kin(t);
        let att = self.attitude(t);
        let h = 1e-5;
        let (a1, a0) = (self.attitude(t + h), self.attitude((t - h).max(0.0)));
        let span = t + h - (t - h).max(0.0);
        let rate = |i: usize| (a1[i] - a0[i]) / span;
        let (dphi, dtheta, dpsi) = (rate(0), rate(1), wrap(a1[2] - a0[2]) / span);
        let (sphi, cphi) = att[0].sin_cos();
        let (sth, cth) = att[1].sin_cos();
        // Body rates of R = Rz(ψ)Ry(θ)Rx(φ).
        let omega = [
            dphi - dpsi * sth,
            dtheta * cphi + dpsi * sphi * cth,
            -dtheta * sphi + dpsi * cphi * cth,
        ];
        let thrust = norm([a[0], a[1], a[2] + G]);
        Truth {
            p,
            v,
            att,
            omega,
            f: [0.0, 0.0, thrust],
        }
    }
}

/// Standing still with a fixed attitude (on the ground, possibly on a slope).
struct Still {
    p: V3,
    att: V3,
}

impl Motion for Still {
    fn at(&self, _t: f64) -> Truth {
        let f = rot_t_mul(self.att, [0.0, 0.0, G]);
        Truth {
            p: self.p,
            v: [0.0; 3],
            att: self.att,
            omega: [0.0; 3],
            f,
        }
    }
}

/// Still, but shaken about all axes (a hand-held drone) until `until`.
struct Shaken {
    still: Still,
    until: f64,
}

impl Motion for Shaken {
    fn at(&self, t: f64) -> Truth {
        let mut tr = self.still.at(t);
        if t < self.until {
            let w = 0.5 * (2.0 * std::f64::consts::PI * 1.3 * t).sin();
            tr.omega = [w, -0.7 * w, 0.3 * w];
        }
        tr
    }
}

// ---------------------------------------------------------------------------------------------------------
// World and sensors
// ---------------------------------------------------------------------------------------------------------

/// An axis-aligned box on the floor.
#[derive(Clone, Copy, Debug)]
struct Block {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    h: f64,
}

impl Block {
    fn square(cx: f64, cy: f64, side: f64, h: f64) -> Self {
        Self {
            x0: cx - side / 2.0,
            x1: cx + side / 2.0,
            y0: cy - side / 2.0,
            y1: cy + side / 2.0,
            h,
        }
    }
}

/// A wedge rising linearly along x from `x0` (height 0) to `x1` (height `h`), flat after.
#[derive(Clone, Copy, Debug)]
struct Wedge {
    x0: f64,
    x1: f64,
    h: f64,
}

#[derive(Clone, Debug, Default)]
struct World {
    blocks: Vec<Block>,
    wedge: Option<Wedge>,
}

impl World {
    fn surface(&self, x: f64, y: f64) -> f64 {
        let mut s: f64 = 0.0;
        for b in &self.blocks {
            if x >= b.x0 && x <= b.x1 && y >= b.y0 && y <= b.y1 {
                s = s.max(b.h);
            }
        }
        if let Some(w) = self.wedge {
            s = s.max(w.h * ((x - w.x0) / (w.x1 - w.x0)).clamp(0.0, 1.0));
        }
        s
    }

    /// Mean surface height over a disk (the ranger's footprint), area-weighted.
    fn surface_disk(&self, x: f64, y: f64, r: f64) -> f64 {
        const RINGS: usize = 8;
        const SPOKES: usize = 32;
        if r <= 0.0 {
            return self.surface(x, y);
        }
        // Midpoint rule in polar coordinates: ring i covers radii ((i − ½)·Δr, (i + ½)·Δr), the centre
        // point the disk of radius Δr/2.
        let dr = r / RINGS as f64;
        let w0 = std::f64::consts::PI * (dr / 2.0) * (dr / 2.0);
        let (mut sum, mut wsum) = (self.surface(x, y) * w0, w0);
        for i in 1..=RINGS {
            let rr = dr * i as f64 - if i == RINGS { dr / 4.0 } else { 0.0 };
            let width = if i == RINGS { dr / 2.0 } else { dr };
            for j in 0..SPOKES {
                let a = 2.0 * std::f64::consts::PI * (j as f64 + 0.5 * (i % 2) as f64) / SPOKES as f64;
                let w = rr * width * 2.0 * std::f64::consts::PI / SPOKES as f64;
                sum += w * self.surface(x + rr * a.cos(), y + rr * a.sin());
                wsum += w;
            }
        }
        sum / wsum
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Footprint {
    /// The range hits one point (sharp steps).
    Point,
    /// The range is the area-weighted mean over the stock 7.5° cone (steps become ramps).
    Cone,
}

/// Sensor faults injected over a time window.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Fault {
    FlowMotionInvalid,
    FlowSqualZero,
    TofNone,
    /// A new kind of garbage every sample in the window (NaN, inf, absurd, zero/negative dt...).
    Garbage,
    /// Absurd but finite accelerometer (forces a divergence).
    AccelAbsurd,
    /// No IMU samples at all.
    ImuSilent,
}

#[derive(Clone, Debug)]
struct Scenario {
    world: World,
    footprint: Footprint,
    gyro_bias: V3,
    /// Constant accelerometer offset, body frame, m/s².
    accel_offset: V3,
    gyro_sigma: f64,
    accel_sigma: f64,
    flow_sigma_counts: f64,
    tof_noise: bool,
    faults: Vec<(f64, f64, Fault)>,
    /// Extra IMU noise while flying (motor vibration): accel σ m/s², gyro σ rad/s.
    vibration: Option<(f64, f64)>,
    /// set_flying(true) during these windows.
    flying: Vec<(f64, f64)>,
    /// The pose passed to reset().
    start: V3,
    start_yaw: f64,
    seed: u64,
}

impl Scenario {
    fn new(start: V3, yaw: f64, flying: (f64, f64)) -> Self {
        Self {
            world: World::default(),
            footprint: Footprint::Point,
            gyro_bias: [0.012, -0.008, 0.005],
            accel_offset: [0.0; 3],
            gyro_sigma: 0.005,
            accel_sigma: 0.05,
            flow_sigma_counts: 0.5,
            tof_noise: true,
            faults: Vec::new(),
            vibration: None,
            flying: vec![flying],
            start,
            start_yaw: yaw,
            seed: 1,
        }
    }

    fn fault_at(&self, t: f64) -> Option<Fault> {
        self.faults.iter().find(|(t0, t1, _)| t >= *t0 && t < *t1).map(|f| f.2)
    }
}

/// One logged instant.
#[derive(Clone, Copy, Debug)]
struct Record {
    t: f64,
    truth: Truth,
    est: StateEstimate,
    calibrated: bool,
}

fn gauss(rng: &mut SmallRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-12);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

fn tof_sigma(d: f64) -> f64 {
    0.0025 * (1.0 + (2.9214 * (d - 2.5)).exp())
}

/// Garbage samples, cycling through every kind of bad value.
fn garbage_imu(k: u64, good: ImuSample) -> (ImuSample, f32) {
    let mut s = good;
    match k % 8 {
        0 => s.gyro_rad_s[0] = f32::NAN,
        1 => s.accel_m_s2[2] = f32::INFINITY,
        2 => s.gyro_rad_s[2] = f32::NEG_INFINITY,
        3 => return (s, 0.0),
        4 => return (s, -0.001),
        5 => return (s, f32::NAN),
        6 => s.accel_m_s2 = [f32::NAN; 3],
        _ => return (s, f32::INFINITY),
    }
    (s, DT as f32)
}

fn garbage_flow(k: u64, good: FlowSample) -> FlowSample {
    let mut s = good;
    match k % 6 {
        0 => s.dt_s = f32::NAN,
        1 => s.dt_s = 0.0,
        2 => s.dt_s = -0.01,
        3 => s.dpixel_x = i16::MAX,
        4 => s.dpixel_y = i16::MIN,
        _ => s.dt_s = f32::INFINITY,
    }
    s
}

fn garbage_tof(k: u64) -> RangeReading {
    match k % 6 {
        0 => Some(f32::NAN),
        1 => Some(f32::INFINITY),
        2 => Some(-1.0),
        3 => Some(1e30),
        4 => Some(f32::NEG_INFINITY),
        _ => Some(0.0),
    }
}

/// Run `motion` through the sensors into a fresh estimator for `duration` seconds.
fn simulate(motion: &dyn Motion, sc: &Scenario, duration: f64) -> (Estimator, Vec<Record>) {
    simulate_with(motion, sc, duration, EstimatorConfig::default())
}

fn simulate_with(motion: &dyn Motion, sc: &Scenario, duration: f64, cfg: EstimatorConfig) -> (Estimator, Vec<Record>) {
    let mut rng = SmallRng::seed_from_u64(sc.seed);
    let mut est = Estimator::new(cfg);
    est.reset(
        [sc.start[0] as f32, sc.start[1] as f32, sc.start[2] as f32],
        sc.start_yaw as f32,
    );
    let mut flow_acc = [0.0f64; 2];
    let mut records = Vec::with_capacity((duration / DT) as usize + 1);
    let mut flying = false;
    let steps = (duration / DT).round() as u64;
    for k in 1..=steps {
        let t = k as f64 * DT;
        let tr = motion.at(t);
        let fault = sc.fault_at(t);
        let r = rot(tr.att);

        // Flying flag as the controller would set it.
        let want = sc.flying.iter().any(|w| t >= w.0 && t < w.1);
        if want != flying {
            est.set_flying(want);
            flying = want;
        }

        // IMU.
        let mut imu = ImuSample::default();
        let (vib_a, vib_g) = if flying {
            sc.vibration.unwrap_or((0.0, 0.0))
        } else {
            (0.0, 0.0)
        };
        let (sig_a, sig_g) = (sc.accel_sigma.hypot(vib_a), sc.gyro_sigma.hypot(vib_g));
        for i in 0..3 {
            imu.gyro_rad_s[i] = (tr.omega[i] + sc.gyro_bias[i] + sig_g * gauss(&mut rng)) as f32;
            imu.accel_m_s2[i] = (tr.f[i] + sc.accel_offset[i] + sig_a * gauss(&mut rng)) as f32;
        }
        match fault {
            Some(Fault::Garbage) => {
                let (s, dt) = garbage_imu(k, imu);
                est.on_imu(&s, dt);
            }
            Some(Fault::AccelAbsurd) => {
                imu.accel_m_s2 = [200.0, -150.0, 230.0];
                est.on_imu(&imu, DT as f32);
            }
            Some(Fault::ImuSilent) => {}
            _ => est.on_imu(&imu, DT as f32),
        }

        // Where the camera and ranger axis (body −z) hits the floor.
        let down = [-r[0][2], -r[1][2], -r[2][2]];
        let h_floor = tr.p[2];
        let reach = if down[2] < -0.1 { h_floor / -down[2] } else { 0.0 };
        let hit = [tr.p[0] + down[0] * reach, tr.p[1] + down[1] * reach];
        let surface_hit = sc.world.surface(hit[0], hit[1]);
        let h_cam = tr.p[2] - surface_hit;

        // Flow: integrate the stock model's pixel rate.
        let vb = rot_t_mul(tr.att, tr.v);
        let r22 = r[2][2];
        if h_cam > 0.02 {
            flow_acc[0] += DT * FLOW_K * (vb[0] * r22 / h_cam - tr.omega[1]);
            flow_acc[1] += DT * FLOW_K * (vb[1] * r22 / h_cam + tr.omega[0]);
        }
        if k.is_multiple_of(FLOW_EVERY) {
            let valid = h_cam >= 0.08;
            let counts = |n: f64, rng: &mut SmallRng| {
                (n / 0.1 + sc.flow_sigma_counts * gauss(rng))
                    .round()
                    .clamp(-32768.0, 32767.0) as i16
            };
            let mut s = FlowSample {
                dpixel_x: if valid { counts(flow_acc[0], &mut rng) } else { 0 },
                dpixel_y: if valid { counts(flow_acc[1], &mut rng) } else { 0 },
                squal: if valid { 80 } else { 0 },
                motion_valid: valid,
                dt_s: (FLOW_EVERY as f64 * DT) as f32,
            };
            flow_acc = [0.0; 2];
            match fault {
                Some(Fault::FlowMotionInvalid) => s.motion_valid = false,
                Some(Fault::FlowSqualZero) => s.squal = 0,
                Some(Fault::Garbage) => s = garbage_flow(k / FLOW_EVERY, s),
                _ => {}
            }
            est.on_flow(&s);
        }

        // Range.
        if k.is_multiple_of(TOF_EVERY) {
            let surface_tof = match sc.footprint {
                Footprint::Point => surface_hit,
                Footprint::Cone => sc
                    .world
                    .surface_disk(hit[0], hit[1], h_cam.max(0.0) * CONE_HALF_ANGLE.tan()),
            };
            let d = ((tr.p[2] - surface_tof) / r22.max(0.1)).max(0.0);
            let noise = if sc.tof_noise {
                tof_sigma(d) * gauss(&mut rng)
            } else {
                0.0
            };
            let mut reading: RangeReading = Some((d + noise).max(0.0) as f32);
            match fault {
                Some(Fault::TofNone) => reading = None,
                Some(Fault::Garbage) => reading = garbage_tof(k / TOF_EVERY),
                _ => {}
            }
            est.on_zrange(reading);
        }

        records.push(Record {
            t,
            truth: tr,
            est: est.state(),
            calibrated: est.is_calibrated(),
        });
    }
    (est, records)
}

// ---------------------------------------------------------------------------------------------------------
// Small math and metrics
// ---------------------------------------------------------------------------------------------------------

fn norm(v: V3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn wrap(a: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    (a + std::f64::consts::PI).rem_euclid(two_pi) - std::f64::consts::PI
}

/// `R = Rz(ψ)·Ry(θ)·Rx(φ)` in `f64` (the truth model's precision; `cfnav::math::rotation` is `f32`).
fn rot(att: V3) -> [[f64; 3]; 3] {
    let (sr, cr) = att[0].sin_cos();
    let (sp, cp) = att[1].sin_cos();
    let (sy, cy) = att[2].sin_cos();
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

fn rot_t_mul(att: V3, v: V3) -> V3 {
    mul_m3t_v3(&rot(att), v)
}

fn f64s(v: [f32; 3]) -> V3 {
    [f64::from(v[0]), f64::from(v[1]), f64::from(v[2])]
}

/// Angle of the rotation between the estimated and the true attitude, degrees.
fn attitude_error_deg(est: &StateEstimate, truth: &Truth) -> f64 {
    let a = rot(f64s(est.attitude_rad));
    let b = rot(truth.att);
    let mut tr = 0.0;
    for i in 0..3 {
        for k in 0..3 {
            tr += a[k][i] * b[k][i];
        }
    }
    ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

/// Tilt error only (angle between the estimated and true body z axes), degrees.
fn tilt_error_deg(est: &StateEstimate, truth: &Truth) -> f64 {
    let a = rot(f64s(est.attitude_rad));
    let b = rot(truth.att);
    let d = a[0][2] * b[0][2] + a[1][2] * b[1][2] + a[2][2] * b[2][2];
    d.clamp(-1.0, 1.0).acos().to_degrees()
}

fn pos_err(r: &Record) -> V3 {
    let e = f64s(r.est.position_m);
    [e[0] - r.truth.p[0], e[1] - r.truth.p[1], e[2] - r.truth.p[2]]
}

fn vel_err(r: &Record) -> V3 {
    let e = f64s(r.est.velocity_m_s);
    [e[0] - r.truth.v[0], e[1] - r.truth.v[1], e[2] - r.truth.v[2]]
}

fn xy_err(r: &Record) -> f64 {
    let e = pos_err(r);
    (e[0] * e[0] + e[1] * e[1]).sqrt()
}

fn rms(it: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in it {
        s += x * x;
        n += 1;
    }
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

fn max_abs(it: impl Iterator<Item = f64>) -> f64 {
    it.fold(0.0, |m, x| m.max(x.abs()))
}

fn at(records: &[Record], t: f64) -> &Record {
    let i = ((t / DT).round() as usize).saturating_sub(1).min(records.len() - 1);
    &records[i]
}

fn window(records: &[Record], t0: f64, t1: f64) -> impl Iterator<Item = &Record> {
    records.iter().filter(move |r| r.t >= t0 && r.t < t1)
}

fn all_finite(r: &Record) -> bool {
    let s = &r.est;
    s.position_m
        .iter()
        .chain(&s.velocity_m_s)
        .chain(&s.attitude_rad)
        .chain(&s.rates_rad_s)
        .all(|x| x.is_finite())
        && s.surface_height_m.is_finite()
}

/// The standard flight: 1.5 s on the ground (calibration), take-off to `height`, hover, then `mission`.
fn flight(start: V3, yaw: f64, height: f64) -> Trajectory {
    Trajectory::new(start, yaw).hold(1.5).climb(height, 0.3).hold(1.5)
}

// ---------------------------------------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------------------------------------

#[test]
fn memory_size() {
    let size = std::mem::size_of::<Estimator>();
    println!("estimator: size_of::<Estimator>() = {size} B");
    assert!(size <= 1504, "the estimator grew to {size} B");
}

#[test]
fn static_on_ground_calibrates_and_holds() {
    // Standing on a slightly sloped pad, heading 40°.
    let att = [2.0f64.to_radians(), -1.5f64.to_radians(), 40.0f64.to_radians()];
    let motion = Still {
        p: [1.0, 2.0, 0.0],
        att,
    };
    let mut sc = Scenario::new([1.0, 2.0, 0.0], att[2], (1e9, 1e9));
    sc.gyro_bias = [0.03, -0.02, 0.015];
    let (est, rec) = simulate(&motion, &sc, 20.0);
    assert!(rec.iter().all(all_finite));

    let t_cal = rec
        .iter()
        .find(|r| r.calibrated)
        .map(|r| r.t)
        .expect("never calibrated");
    let t_valid = rec.iter().find(|r| r.est.valid).map(|r| r.t).expect("never valid");
    let bias = est.diagnostics().gyro_bias_rad_s;
    let bias_err = max_abs((0..3).map(|i| f64::from(bias[i]) - sc.gyro_bias[i]));
    let after = |t0: f64| window(&rec, t0, 21.0);
    let att_max = after(t_cal)
        .map(|r| attitude_error_deg(&r.est, &r.truth))
        .fold(0.0, f64::max);
    let z_max = max_abs(after(t_cal).map(|r| pos_err(r)[2]));
    // Drift: mean z over the last second minus the mean over the second after calibration (the absolute
    // error at rest includes the truth's clamping of range noise at 0: a range cannot be negative).
    let mean_z = |t0: f64| {
        window(&rec, t0, t0 + 1.0)
            .map(|r| f64::from(r.est.position_m[2]))
            .sum::<f64>()
            / 1000.0
    };
    let z_drift = mean_z(19.0) - mean_z(t_cal + 0.5);
    let xy_max = after(t_cal).map(xy_err).fold(0.0, f64::max);
    let v_max = after(t_cal).map(|r| norm(vel_err(r))).fold(0.0, f64::max);
    let last = rec.last().expect("records");
    println!(
        "estimator static: calibrated at {t_cal:.3} s, valid at {t_valid:.3} s, gyro bias error {:.2e} rad/s, \
         attitude error max {att_max:.3}° (final {:.3}°), z error max {:.2} mm, z drift over 18 s {:.3} mm, \
         xy drift max {:.2} mm, |v| max {:.2} mm/s",
        bias_err,
        attitude_error_deg(&last.est, &last.truth),
        z_max * 1e3,
        z_drift * 1e3,
        xy_max * 1e3,
        v_max * 1e3
    );
    assert!(t_cal <= 0.6, "calibration took {t_cal} s at rest");
    assert!(t_valid <= 0.7, "valid only at {t_valid} s");
    assert!(bias_err < 5e-4, "gyro bias error {bias_err} rad/s");
    assert!(att_max < 1.0, "attitude error {att_max}°");
    assert!(z_max < 0.003, "z error {z_max} m at rest");
    assert!(z_drift.abs() < 0.0005, "z drifted {z_drift} m at rest");
    assert!(xy_max < 0.005, "xy drifted {xy_max} m at rest");
    assert!(last.est.valid);
    assert_eq!(last.est.surface_height_m, 0.0);
}

/// The level calibration: standing level with an accelerometer offset of 0.3°, the estimate starts level and
/// stays so through a take-off and a hover (levelled on the accelerometer, it would be off by the offset,
/// and the controller would tilt the drone by as much at lift-off); standing on a 4° slope, it is levelled
/// on gravity (that is no offset).
#[test]
fn an_accelerometer_offset_at_rest_is_calibrated_out_a_slope_is_not() {
    let offset = [0.04, -0.03, 0.0];
    let start = [1.0, 1.0, 0.0];
    let mut sc = Scenario::new(start, 0.3, (2.0, 1e9));
    sc.accel_offset = offset;
    let motion = Trajectory::new(start, 0.3).hold(2.0).climb(0.5, 0.3).hold(6.0);
    let (est, rec) = simulate(&motion, &sc, motion.duration());
    let tilt_at = |t: f64| tilt_error_deg(&at(&rec, t).est, &at(&rec, t).truth);
    let tilt_air = window(&rec, 2.0, motion.duration())
        .map(|r| tilt_error_deg(&r.est, &r.truth))
        .fold(0.0, f64::max);
    let got = est.diagnostics().accel_offset_m_s2;
    println!(
        "estimator level calibration: offset {:?} m/s² measured {got:?}; tilt error at lift-off {:.3}°, in the air \
         max {tilt_air:.3}° (the offset alone would be {:.3}°)",
        [offset[0], offset[1]],
        tilt_at(1.99),
        offset[0].hypot(offset[1]).atan2(G).to_degrees()
    );
    for i in 0..2 {
        assert!(
            (f64::from(got[i]) - offset[i]).abs() < 0.01,
            "offset {got:?}, expected {offset:?}"
        );
    }
    assert!(tilt_at(1.99) < 0.08, "tilt error {}° at lift-off", tilt_at(1.99));
    assert!(tilt_air < 0.15, "tilt error {tilt_air}° in the air");

    let att = [3.0f64.to_radians(), -2.5f64.to_radians(), 0.3];
    let motion = Still { p: start, att };
    let sc = Scenario::new(start, att[2], (1e9, 1e9));
    let (est, rec) = simulate(&motion, &sc, 3.0);
    let got = est.diagnostics().accel_offset_m_s2;
    let tilt = tilt_error_deg(&at(&rec, 2.9).est, &at(&rec, 2.9).truth);
    println!("estimator on a 3.9° slope: offset {got:?}, tilt error {tilt:.3}°");
    assert_eq!(got, [0.0; 2]);
    assert!(tilt < 0.2, "tilt error {tilt}° on a slope");
}

#[test]
fn calibration_waits_for_stillness() {
    let still = Still {
        p: [0.5, 0.5, 0.0],
        att: [0.0; 3],
    };
    let motion = Shaken { still, until: 3.0 };
    let sc = Scenario::new([0.5, 0.5, 0.0], 0.0, (1e9, 1e9));
    let (_, rec) = simulate(&motion, &sc, 5.0);
    let t_cal = rec
        .iter()
        .find(|r| r.calibrated)
        .map(|r| r.t)
        .expect("never calibrated");
    println!("estimator calibration: shaken until 3.0 s, calibrated at {t_cal:.3} s");
    assert!(t_cal > 3.0, "calibrated while shaken ({t_cal} s)");
    assert!(t_cal < 4.1, "calibration took {t_cal} s after the shaking stopped");
    assert!(rec.iter().filter(|r| !r.calibrated).all(|r| !r.est.valid));
}

#[test]
fn hover() {
    let traj = flight([1.0, 1.0, 0.0], 0.0, 0.5).hold(20.0).climb(-0.5, 0.3).hold(1.0);
    let sc = Scenario::new([1.0, 1.0, 0.0], 0.0, (1.5, traj.duration() - 0.5));
    let (_, rec) = simulate(&traj, &sc, traj.duration());
    assert!(rec.iter().all(all_finite));
    let air = || window(&rec, 3.5, 23.5);
    let att_max = air().map(|r| attitude_error_deg(&r.est, &r.truth)).fold(0.0, f64::max);
    let tilt_max = air().map(|r| tilt_error_deg(&r.est, &r.truth)).fold(0.0, f64::max);
    let z_rms = rms(air().map(|r| pos_err(r)[2]));
    let z_late = window(&rec, 22.5, 23.5).map(|r| pos_err(r)[2]).sum::<f64>() / 1000.0;
    let xy_end = xy_err(at(&rec, 23.5));
    let v_rms = rms(air().map(|r| norm(vel_err(r))));
    let valid = air().all(|r| r.est.valid);
    println!(
        "estimator hover 20 s at 0.5 m: attitude error max {att_max:.3}° (tilt {tilt_max:.3}°), z RMS {:.2} mm, \
         z bias (last s) {:.2} mm, xy drift {:.1} mm, |v| RMS {:.1} mm/s, valid throughout: {valid}",
        z_rms * 1e3,
        z_late * 1e3,
        xy_end * 1e3,
        v_rms * 1e3
    );
    assert!(att_max < 1.0);
    assert!(z_rms < 0.005);
    assert!(z_late.abs() < 0.003);
    // The flow noise (0.5 count) alone makes the position a random walk of ≈ 2.6 cm per axis (1σ) in 20 s.
    assert!(xy_end < 0.1);
    assert!(v_rms < 0.02);
    assert!(valid);
}

/// Take off, 3 m transit along x at 0.5 m/s, hover, land.
fn transit_trajectory() -> Trajectory {
    flight([0.5, 1.5, 0.0], 0.0, 0.5)
        .travel([3.0, 0.0, 0.0], 0.5, 1.5)
        .hold(2.0)
        .climb(-0.5, 0.3)
        .hold(1.5)
}

/// What the transit measured.
struct TransitErrors {
    pos_arrive: f64,
    v_rms: f64,
    z_rms: f64,
    att_max: f64,
    landed_z: f64,
    valid_in_flight: bool,
    landed_valid: bool,
}

/// Take off, 3 m along x at 0.5 m/s, hover, land; `vibration` adds motor-vibration IMU noise in flight.
fn transit_case(vibration: Option<(f64, f64)>) -> TransitErrors {
    let traj = transit_trajectory();
    let t_end = traj.duration();
    let mut sc = Scenario::new([0.5, 1.5, 0.0], 0.0, (1.5, t_end - 1.0));
    sc.vibration = vibration;
    let (_, rec) = simulate(&traj, &sc, t_end);
    assert!(rec.iter().all(all_finite));
    // Phases: ground 1.5, climb ~2.27, hover 1.5, transit 7.5, hover 2, descent, ground.
    let t_transit = 1.5 + 0.5 / 0.3 + 0.6 + 1.5;
    let t_arrive = t_transit + 7.5;
    let air = || window(&rec, 2.0, t_end - 2.0);
    let moving = || window(&rec, t_transit, t_arrive);
    let pos_arrive = norm(pos_err(at(&rec, t_arrive + 1.0)));
    let xy_arrive = xy_err(at(&rec, t_arrive + 1.0));
    let v_rms = rms(air().map(|r| norm(vel_err(r))));
    let v_rms_moving = rms(moving().map(|r| norm(vel_err(r))));
    let z_rms = rms(air().map(|r| pos_err(r)[2]));
    let z_max = max_abs(air().map(|r| pos_err(r)[2]));
    let att_max = air().map(|r| attitude_error_deg(&r.est, &r.truth)).fold(0.0, f64::max);
    let att_rms = rms(air().map(|r| attitude_error_deg(&r.est, &r.truth)));
    let rate_rms = rms(air().map(|r| norm(sub3(f64s(r.est.rates_rad_s), r.truth.omega))));
    let tilt_truth_max = moving().map(|r| r.truth.att[1].to_degrees().abs()).fold(0.0, f64::max);
    let landed = rec.last().expect("records");
    let errors = TransitErrors {
        pos_arrive,
        v_rms,
        z_rms,
        att_max,
        landed_z: pos_err(landed)[2],
        valid_in_flight: air().all(|r| r.est.valid),
        landed_valid: landed.est.valid,
    };
    println!(
        "estimator transit 3 m at 0.5 m/s (tilt up to {tilt_truth_max:.1}°, vibration {vibration:?}): position error \
         after 3 m {:.1} mm (xy {:.1} mm), |v| error RMS {:.1} mm/s (while moving {:.1} mm/s), z RMS {:.2} mm, z max \
         {:.2} mm, attitude error max {att_max:.3}° RMS {att_rms:.3}°, rates error RMS {:.4} rad/s, landed z error \
         {:.1} mm, valid in flight: {}",
        pos_arrive * 1e3,
        xy_arrive * 1e3,
        v_rms * 1e3,
        v_rms_moving * 1e3,
        z_rms * 1e3,
        z_max * 1e3,
        rate_rms,
        errors.landed_z * 1e3,
        errors.valid_in_flight
    );
    errors
}

#[test]
fn transit_3m() {
    let e = transit_case(None);
    assert!(e.pos_arrive < 0.10, "position error {} m after 3 m", e.pos_arrive);
    assert!(e.v_rms < 0.05, "velocity RMS {} m/s", e.v_rms);
    assert!(e.z_rms < 0.02, "height RMS {} m", e.z_rms);
    assert!(e.att_max < 1.0);
    assert!(e.landed_z.abs() < 0.01);
    assert!(e.valid_in_flight && e.landed_valid);
}

#[test]
fn transit_3m_with_motor_vibration() {
    // In flight the BMI088 sees the motors: 1 m/s² and 0.05 rad/s of white noise at 1 kHz (20× and 10× the
    // bench noise). The process noise is chosen to hold this too.
    let e = transit_case(Some((1.0, 0.05)));
    assert!(e.pos_arrive < 0.10, "position error {} m after 3 m", e.pos_arrive);
    assert!(e.v_rms < 0.05, "velocity RMS {} m/s", e.v_rms);
    assert!(e.z_rms < 0.02, "height RMS {} m", e.z_rms);
    assert!(e.att_max < 1.5);
    assert!(e.valid_in_flight && e.landed_valid);
}

#[test]
fn square_with_yaw_turns() {
    // Nose-first around a 1.5 m square: turn 90° at every corner, then fly along the new heading.
    let half_pi = std::f64::consts::FRAC_PI_2;
    let mut traj = flight([1.0, 1.0, 0.0], 0.0, 0.6);
    let legs = [[1.5, 0.0, 0.0], [0.0, 1.5, 0.0], [-1.5, 0.0, 0.0], [0.0, -1.5, 0.0]];
    for (i, leg) in legs.iter().enumerate() {
        if i > 0 {
            traj = traj.turn(2.0, half_pi);
        }
        traj = traj.travel(*leg, 0.5, 1.2).hold(0.5);
    }
    let traj = traj.turn(3.0, -1.5 * half_pi).hold(1.0);
    let t_end = traj.duration();
    let sc = Scenario::new([1.0, 1.0, 0.0], 0.0, (1.5, 1e9));
    let (_, rec) = simulate(&traj, &sc, t_end);
    assert!(rec.iter().all(all_finite));
    let air = || window(&rec, 4.0, t_end);
    let end = rec.last().expect("records");
    let xy_end = xy_err(end);
    let v_rms = rms(air().map(|r| norm(vel_err(r))));
    let z_rms = rms(air().map(|r| pos_err(r)[2]));
    let att_max = air().map(|r| attitude_error_deg(&r.est, &r.truth)).fold(0.0, f64::max);
    let yaw_err = wrap(f64::from(end.est.attitude_rad[2]) - end.truth.att[2]).to_degrees();
    println!(
        "estimator square 4 × 1.5 m with 90° turns ({t_end:.1} s): xy error at the end {:.1} mm, |v| error RMS \
         {:.1} mm/s, z RMS {:.2} mm, attitude error max {att_max:.3}°, final yaw error {yaw_err:.3}°",
        xy_end * 1e3,
        v_rms * 1e3,
        z_rms * 1e3
    );
    assert!(xy_end < 0.15, "xy error {xy_end} m after 6 m");
    assert!(v_rms < 0.05);
    assert!(z_rms < 0.02);
    assert!(att_max < 1.0);
    assert!(air().all(|r| r.est.valid));
}

/// Fly at 0.5 m over an object centred on the path (x from 0.5 to 3.5 at y = 1.5).
fn pad_case(side: f64, height: f64, footprint: Footprint, speed: f64) -> (f64, f64, f64, f64) {
    pad_case_seed(side, height, footprint, speed, 1)
}

fn pad_case_seed(side: f64, height: f64, footprint: Footprint, speed: f64, seed: u64) -> (f64, f64, f64, f64) {
    let ramp = 1.5;
    let traj = flight([0.5, 1.5, 0.0], 0.0, 0.5)
        .travel([3.0, 0.0, 0.0], speed, ramp)
        .hold(2.0);
    let t_end = traj.duration();
    let mut sc = Scenario::new([0.5, 1.5, 0.0], 0.0, (1.5, 1e9));
    sc.world.blocks.push(Block::square(2.0, 1.5, side, height));
    sc.footprint = footprint;
    sc.seed = seed;
    let (est, rec) = simulate(&traj, &sc, t_end);
    assert!(rec.iter().all(all_finite));
    let air = || window(&rec, 4.0, t_end);
    let z_dev = max_abs(air().map(|r| pos_err(r)[2]));
    // Only while the ranger can see the object (within 0.3 m of it).
    let z_dev_near = max_abs(
        air()
            .filter(|r| (r.truth.p[0] - 2.0).abs() < side / 2.0 + 0.3)
            .map(|r| pos_err(r)[2]),
    );
    // Surface estimate while the drone is well inside the pad (its centre ± a third of the side).
    let on_pad: Vec<f64> = air()
        .filter(|r| (r.truth.p[0] - 2.0).abs() < side / 6.0)
        .map(|r| f64::from(r.est.surface_height_m))
        .collect();
    let s_on = on_pad.iter().sum::<f64>() / on_pad.len().max(1) as f64;
    let end = rec.last().expect("records");
    let s_end = f64::from(end.est.surface_height_m);
    let xy_end = xy_err(end);
    let d = est.diagnostics();
    if seed != 1 {
        assert!(air().all(|r| r.est.valid), "seed {seed}: invalid over the object");
        return (z_dev, s_on, s_end, xy_end);
    }
    println!(
        "estimator pad {:.0} cm high, {:.0} cm wide, {footprint:?} range, {speed} m/s: z deviation max {:.2} mm \
         (near the object {:.2} mm), surface on the pad {:.1} mm, after {:.1} mm, steps {}, xy error after 3 m \
         {:.1} mm, ranges discarded {}",
        height * 100.0,
        side * 100.0,
        z_dev * 1e3,
        z_dev_near * 1e3,
        s_on * 1e3,
        s_end * 1e3,
        d.surface_steps,
        xy_end * 1e3,
        d.tof_discarded
    );
    assert!(air().all(|r| r.est.valid), "seed {seed}: invalid over the object");
    (z_dev, s_on, s_end, xy_end)
}

#[test]
fn pad_step_10cm() {
    for footprint in [Footprint::Point, Footprint::Cone] {
        let (z_dev, s_on, s_end, xy_end) = pad_case(0.3, 0.10, footprint, 0.5);
        assert!(z_dev < 0.015, "{footprint:?}: z deviated {z_dev} m over the pad");
        assert!((s_on - 0.10).abs() < 0.01, "{footprint:?}: surface {s_on} m on the pad");
        assert_eq!(s_end, 0.0, "{footprint:?}: surface must return to exactly 0");
        assert!(xy_end < 0.10);
    }
}

#[test]
fn box_step_20cm() {
    for footprint in [Footprint::Point, Footprint::Cone] {
        let (z_dev, s_on, s_end, xy_end) = pad_case(0.3, 0.20, footprint, 0.5);
        assert!(z_dev < 0.015, "{footprint:?}: z deviated {z_dev} m over the box");
        assert!((s_on - 0.20).abs() < 0.01, "{footprint:?}: surface {s_on} m on the box");
        assert_eq!(s_end, 0.0);
        assert!(xy_end < 0.10);
    }
}

#[test]
fn pad_step_slow_crossing() {
    // 0.3 m/s: a blurred step is a slower ramp (≈ 7 mm per range at the steepest).
    for footprint in [Footprint::Point, Footprint::Cone] {
        let (z_dev, s_on, s_end, _) = pad_case(0.3, 0.10, footprint, 0.3);
        assert!(z_dev < 0.015, "{footprint:?}: z deviated {z_dev} m over the pad");
        assert!((s_on - 0.10).abs() < 0.015);
        assert_eq!(s_end, 0.0);
    }
}

#[test]
fn mission_round_trip() {
    // The mission's legs: take off from a 10 cm home pad, fly 2.5 m, land on a 20 cm box, rest, take off
    // again, fly home, land on the home pad. Ranges through the blurring cone.
    let out = Trajectory::new([0.6, 1.3, 0.1], 0.0)
        .hold(1.5)
        .climb(0.4, 0.3)
        .hold(1.0)
        .travel([2.5, 0.2, 0.0], 0.4, 1.5)
        .hold(1.5)
        .climb(-0.3, 0.2);
    let t_land1 = out.duration();
    let rest = out.hold(3.0);
    let t_takeoff2 = rest.duration();
    let back = rest
        .climb(0.3, 0.3)
        .hold(1.0)
        .travel([-2.5, -0.2, 0.0], 0.4, 1.5)
        .hold(1.5)
        .climb(-0.4, 0.2);
    let t_land2 = back.duration();
    let traj = back.hold(1.5);
    let t_end = traj.duration();
    let mut sc = Scenario::new([0.6, 1.3, 0.1], 0.0, (1.5, t_land1 + 0.5));
    sc.flying.push((t_takeoff2, t_land2 + 0.5));
    sc.world.blocks.push(Block::square(0.6, 1.3, 0.3, 0.10));
    sc.world.blocks.push(Block::square(3.1, 1.5, 0.3, 0.20));
    sc.footprint = Footprint::Cone;
    let (est, rec) = simulate(&traj, &sc, t_end);
    assert!(rec.iter().all(all_finite));
    let z_max = max_abs(rec.iter().map(|r| pos_err(r)[2]));
    let s_mid = f64::from(at(&rec, 7.0).est.surface_height_m);
    let on_box = at(&rec, t_takeoff2 - 0.1);
    let home = rec.last().expect("records");
    println!(
        "estimator mission round trip: z error max {:.2} mm; surface mid-way {:.1} mm; on the box: z error {:.1} mm, \
         surface {:.1} mm, xy error {:.1} mm; back on the home pad: z error {:.1} mm, surface {:.1} mm, xy error \
         {:.1} mm; steps {}",
        z_max * 1e3,
        s_mid * 1e3,
        pos_err(on_box)[2] * 1e3,
        f64::from(on_box.est.surface_height_m) * 1e3,
        xy_err(on_box) * 1e3,
        pos_err(home)[2] * 1e3,
        f64::from(home.est.surface_height_m) * 1e3,
        xy_err(home) * 1e3,
        est.diagnostics().surface_steps
    );
    assert!(z_max < 0.015);
    assert_eq!(s_mid, 0.0);
    assert!((f64::from(on_box.est.surface_height_m) - 0.2).abs() < 0.01);
    assert!(pos_err(on_box)[2].abs() < 0.015);
    assert!((f64::from(home.est.surface_height_m) - 0.1).abs() < 0.01);
    assert!(pos_err(home)[2].abs() < 0.015);
    assert!(xy_err(home) < 0.15);
    assert!(on_box.est.valid && home.est.valid);
    assert!(window(&rec, 2.0, t_land1).all(|r| r.est.valid));
    assert!(window(&rec, t_takeoff2, t_land2).all(|r| r.est.valid));
}

#[test]
fn slow_ramp_is_followed_as_height() {
    // A documented limit: a 10 cm rise spread over 1 m of travel cannot be told from a height change.
    let traj = flight([0.5, 1.5, 0.0], 0.0, 0.5)
        .travel([3.0, 0.0, 0.0], 0.5, 1.5)
        .hold(1.0);
    let mut sc = Scenario::new([0.5, 1.5, 0.0], 0.0, (1.5, 1e9));
    sc.world.wedge = Some(Wedge {
        x0: 1.5,
        x1: 2.5,
        h: 0.10,
    });
    let (_, rec) = simulate(&traj, &sc, traj.duration());
    let end = rec.last().expect("records");
    let z_err = pos_err(end)[2];
    println!(
        "estimator slow ramp (10 cm over 1 m): z error on top {:.1} mm, surface {:.1} mm (followed as height)",
        z_err * 1e3,
        f64::from(end.est.surface_height_m) * 1e3
    );
    assert!(rec.iter().all(all_finite));
    assert!(z_err < -0.08, "expected the height to follow the ramp");
}

/// Hover-and-transit flight with a fault window in the middle of the transit.
fn fault_flight(fault: Fault, t0: f64, t1: f64) -> (Estimator, Vec<Record>, f64) {
    let traj = transit_trajectory();
    let t_end = traj.duration();
    let mut sc = Scenario::new([0.5, 1.5, 0.0], 0.0, (1.5, t_end - 1.0));
    sc.faults.push((t0, t1, fault));
    let (est, rec) = simulate(&traj, &sc, t_end);
    (est, rec, t_end)
}

#[test]
fn flow_lost_for_one_second() {
    for fault in [Fault::FlowMotionInvalid, Fault::FlowSqualZero] {
        // During the cruise at 0.5 m/s.
        let (t0, t1) = (8.0, 9.0);
        let (est, rec, _) = fault_flight(fault, t0, t1);
        assert!(rec.iter().all(all_finite));
        let drift = xy_err(at(&rec, t1)) - xy_err(at(&rec, t0));
        let invalid_at = window(&rec, t0, t1 + 1.0).find(|r| !r.est.valid).map(|r| r.t - t0);
        let valid_again = window(&rec, t1, t1 + 2.0).find(|r| r.est.valid).map(|r| r.t - t1);
        let xy_arrive = xy_err(at(&rec, 14.0));
        let d = est.diagnostics();
        println!(
            "estimator {fault:?} for 1 s at 0.5 m/s: xy drift during the gap {:.1} mm, invalid after {:.3} s, \
             valid again {:.3} s after the flow returned, xy error after the transit {:.1} mm, flow rejected {} \
             (invalid)",
            drift * 1e3,
            invalid_at.unwrap_or(f64::NAN),
            valid_again.unwrap_or(f64::NAN),
            xy_arrive * 1e3,
            d.flow_rejected_invalid
        );
        let invalid_at = invalid_at.expect("never invalid");
        assert!((0.45..=0.56).contains(&invalid_at), "invalid after {invalid_at} s");
        assert!(window(&rec, t0, t0 + 0.45).all(|r| r.est.valid));
        assert!(valid_again.expect("never valid again") < 0.05);
        assert!(drift.abs() < 0.15, "drift {drift} m");
        assert!(xy_arrive < 0.2);
    }
}

#[test]
fn range_lost_for_one_second() {
    // While hovering after the transit, then during the transit.
    for (t0, t1) in [(13.5, 14.5), (8.0, 9.0)] {
        let (est, rec, _) = fault_flight(Fault::TofNone, t0, t1);
        assert!(rec.iter().all(all_finite));
        let z_gap = max_abs(window(&rec, t0, t1).map(|r| pos_err(r)[2]));
        let z_after = max_abs(window(&rec, t1 + 0.5, t1 + 1.5).map(|r| pos_err(r)[2]));
        let invalid_at = window(&rec, t0, t1 + 1.0).find(|r| !r.est.valid).map(|r| r.t - t0);
        let valid_again = window(&rec, t1, t1 + 2.0).find(|r| r.est.valid).map(|r| r.t - t1);
        let s_max = max_abs(rec.iter().map(|r| f64::from(r.est.surface_height_m)));
        let d = est.diagnostics();
        println!(
            "estimator range None for 1 s from {t0} s: z error max in the gap {:.2} mm, after {:.2} mm, invalid \
             after {:.3} s, valid again after {:.3} s, surface max {:.1} mm, ranges rejected {}",
            z_gap * 1e3,
            z_after * 1e3,
            invalid_at.unwrap_or(f64::NAN),
            valid_again.unwrap_or(f64::NAN),
            s_max * 1e3,
            d.tof_rejected_range
        );
        let invalid_at = invalid_at.expect("never invalid");
        assert!((0.45..=0.56).contains(&invalid_at));
        assert!(valid_again.expect("never valid again") < 0.1);
        assert!(z_gap < 0.05);
        assert!(z_after < 0.01);
        assert_eq!(s_max, 0.0, "a range gap must not create a surface step");
    }
}

#[test]
fn garbage_never_poisons_the_state() {
    // 1 s of garbage in every input while hovering, then 0.2 s bursts during the transit.
    let traj = transit_trajectory();
    let t_end = traj.duration();
    let mut sc = Scenario::new([0.5, 1.5, 0.0], 0.0, (1.5, t_end - 1.0));
    sc.faults.push((5.0, 6.0, Fault::Garbage));
    sc.faults.push((8.0, 8.2, Fault::Garbage));
    sc.faults.push((10.0, 10.2, Fault::Garbage));
    let (est, rec) = simulate(&traj, &sc, t_end);
    assert!(rec.iter().all(all_finite), "a non-finite value escaped");
    let d = est.diagnostics();
    let z_max = max_abs(window(&rec, 6.5, t_end - 2.0).map(|r| pos_err(r)[2]));
    let att_max = window(&rec, 2.0, t_end - 2.0)
        .map(|r| attitude_error_deg(&r.est, &r.truth))
        .fold(0.0, f64::max);
    let xy_arrive = xy_err(at(&rec, 14.0));
    println!(
        "estimator garbage: IMU rejected {} + bad dt {}, flow rejected {}, ranges rejected {}, resets {}; after: \
         z error max {:.2} mm, attitude error max {att_max:.3}°, xy error after the transit {:.1} mm",
        d.imu_rejected,
        d.imu_bad_dt,
        d.flow_rejected_outlier,
        d.tof_rejected_range,
        d.divergence_resets,
        z_max * 1e3,
        xy_arrive * 1e3
    );
    assert!(d.imu_rejected > 0 && d.imu_bad_dt > 0 && d.flow_rejected_outlier > 0 && d.tof_rejected_range > 0);
    assert_eq!(d.divergence_resets, 0);
    assert!(z_max < 0.02);
    assert!(att_max < 2.0);
    assert!(xy_arrive < 0.2);
    assert!(rec.last().expect("records").est.valid);
}

#[test]
fn garbage_before_calibration_and_direct_calls() {
    let mut est = Estimator::new(EstimatorConfig::default());
    let nan3 = [f32::NAN; 3];
    est.reset([f32::NAN, f32::INFINITY, -0.0], f32::NAN);
    for dt in [0.0, -1.0, f32::NAN, f32::INFINITY, f32::MIN_POSITIVE, 1e9] {
        est.on_imu(
            &ImuSample {
                gyro_rad_s: nan3,
                accel_m_s2: nan3,
            },
            dt,
        );
        est.on_imu(
            &ImuSample {
                gyro_rad_s: [1e30; 3],
                accel_m_s2: [-1e30; 3],
            },
            dt,
        );
        est.on_flow(&FlowSample {
            dpixel_x: i16::MIN,
            dpixel_y: i16::MAX,
            squal: 255,
            motion_valid: true,
            dt_s: dt,
        });
        est.on_zrange(Some(dt));
        est.on_zrange(None);
    }
    let s = est.state();
    assert!(!s.valid);
    assert!(
        s.position_m
            .iter()
            .chain(&s.attitude_rad)
            .chain(&s.velocity_m_s)
            .all(|x| x.is_finite())
    );
    // A config of NaNs falls back to the defaults.
    let cfg = EstimatorConfig {
        flow_std_counts: f32::NAN,
        tof_min_r22: f32::INFINITY,
        step_min_m: -1.0,
        ..EstimatorConfig::default()
    };
    let est = Estimator::new(cfg);
    assert_eq!(est.config().flow_std_counts, 2.0);
    assert_eq!(est.config().step_min_m, EstimatorConfig::default().step_min_m);
    assert!(est.config().tof_min_r22 <= 1.0);
}

#[test]
fn divergence_resets_and_recovers() {
    // 0.2 s of an absurd (finite) accelerometer during the transit: the velocity leaves the stock bounds.
    let (est, rec, t_end) = fault_flight(Fault::AccelAbsurd, 8.0, 8.2);
    assert!(rec.iter().all(all_finite));
    let d = est.diagnostics();
    let invalid = window(&rec, 8.0, 8.3).any(|r| !r.est.valid);
    let vmax = window(&rec, 8.0, t_end)
        .map(|r| max_abs(f64s(r.est.velocity_m_s).into_iter()))
        .fold(0.0, f64::max);
    let valid_again = window(&rec, 8.2, t_end).find(|r| r.est.valid).map(|r| r.t - 8.2);
    println!(
        "estimator divergence: resets {}, invalid during the fault: {invalid}, |v| max {:.2} m/s, valid again \
         {:.3} s after, z error at the end {:.1} mm",
        d.divergence_resets,
        vmax,
        valid_again.unwrap_or(f64::NAN),
        pos_err(rec.last().expect("records"))[2] * 1e3
    );
    assert!(d.divergence_resets >= 1);
    assert!(invalid);
    assert!(vmax <= 10.0);
    assert!(valid_again.expect("never valid again") < 0.5);
    // Height and vertical velocity recover from the range (x and y cannot: nothing measures them absolutely).
    let z_after = max_abs(window(&rec, 9.0, t_end - 2.0).map(|r| pos_err(r)[2]));
    let vz_after = max_abs(window(&rec, 9.0, t_end - 2.0).map(|r| vel_err(r)[2]));
    println!(
        "estimator divergence recovery: from 0.8 s after the fault z error max {:.1} mm, vz error max {:.1} mm/s, \
         xy offset left by the fault {:.0} mm",
        z_after * 1e3,
        vz_after * 1e3,
        xy_err(at(&rec, 12.0)) * 1e3
    );
    assert!(z_after < 0.02 && vz_after < 0.05);
}

#[test]
fn imu_silence_invalidates() {
    let (_, rec, _) = fault_flight(Fault::ImuSilent, 8.0, 8.5);
    assert!(rec.iter().all(all_finite));
    let invalid_at = window(&rec, 8.0, 8.5).find(|r| !r.est.valid).map(|r| r.t - 8.0);
    println!(
        "estimator IMU silent: invalid after {:.3} s",
        invalid_at.unwrap_or(f64::NAN)
    );
    assert!(invalid_at.expect("never invalid") < 0.4);
    assert!(window(&rec, 8.7, 9.0).all(|r| r.est.valid));
}

#[test]
fn pad_steps_over_many_seeds() {
    // 20 noise seeds per case: the worst z deviation, surface error on the object, and surface after it.
    let cases = [
        (0.10, Footprint::Point, 0.5, 0.015),
        (0.10, Footprint::Cone, 0.5, 0.015),
        (0.20, Footprint::Cone, 0.5, 0.015),
        (0.10, Footprint::Cone, 0.3, 0.015),
        (0.20, Footprint::Point, 0.3, 0.015),
        // A documented limit: a blurred step crossed at 0.2 m/s is partly followed as height.
        (0.10, Footprint::Cone, 0.2, 0.05),
    ];
    for (height, footprint, speed, z_limit) in cases {
        let mut worst = (0.0f64, 0.0f64, 0.0f64);
        for seed in 1..=20 {
            let (z_dev, s_on, s_end, _) = pad_case_seed(0.3, height, footprint, speed, seed);
            worst = (
                worst.0.max(z_dev),
                worst.1.max((s_on - height).abs()),
                worst.2.max(s_end.abs()),
            );
        }
        println!(
            "estimator pad {:.0} cm, {footprint:?} range, {speed} m/s, 20 seeds: worst z deviation {:.2} mm, worst \
             surface error on the object {:.1} mm, worst surface after it {:.1} mm",
            height * 100.0,
            worst.0 * 1e3,
            worst.1 * 1e3,
            worst.2 * 1e3
        );
        assert!(
            worst.0 < z_limit,
            "{height} m {footprint:?} at {speed} m/s: z deviated {} m",
            worst.0
        );
        assert_eq!(worst.2, 0.0, "the surface must return to exactly 0");
    }
}
