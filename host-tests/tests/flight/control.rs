//! Controller tests: mixer signs, battery compensation, loop rates, and closed-loop flights of a small
//! rigid-body quadrotor model (defined here) with perfect or noisy state feedback.
//!
//! Run with `-- --nocapture` to see the measured numbers (hover error, overshoot, settling times).

use std::f64::consts::PI;

use cfnav::flight::control::mixer::{
    self, CMD_MAX, PITCH_SIGN, ROLL_SIGN, THRUST_MAX_N, THRUST_MIN_N, YAW_SIGN, compensate, compensated_ratio,
    thrust_from_voltage, voltage_for_thrust,
};
use cfnav::flight::control::{ControlFlags, ControlOutput, Controller, ControllerConfig};
use cfnav::flight::supervisor::{Reason, Supervisor, SupervisorConfig, SupervisorInput, SupervisorState};
use cfnav::math::{cross3, mul_m3t_v3, quat_mul, quat_to_rot};
use cfnav::types::{GRAVITY_M_S2, MotorDuty, Setpoint, StateEstimate};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

// ---------------------------------------------------------------------------------------------------------
// The model: Förster's CF2 identification, motors at (±0.031, ±0.031) m, the §6 cubic thrust fit driven by
// duty·V_bat, first-order motor lag, drag torque 0.0069929·thrust with the §6 spin directions, linear drag.
// ---------------------------------------------------------------------------------------------------------

const MASS: f64 = 0.033;
const INERTIA: [f64; 3] = [1.66e-5, 1.66e-5, 2.93e-5];
const ARM: f64 = 0.031;
/// Motor positions (body x forward, y left), M1 front-right, M2 back-right, M3 back-left, M4 front-left.
const MOTOR_POS: [[f64; 2]; 4] = [[ARM, -ARM], [-ARM, -ARM], [-ARM, ARM], [ARM, ARM]];
/// Reaction torque sign on the body about +z: M1/M3 spin CCW (seen from above) → CW torque (−).
const SPIN: [f64; 4] = [-1.0, 1.0, -1.0, 1.0];
const MOTOR_TAU_S: f64 = 0.03;
const K_TORQUE: f64 = 0.0069929;
const LINEAR_DRAG: f64 = 0.01; // N per m/s
const ROT_DRAG: f64 = 2e-7; // N·m per rad/s
const G: f64 = GRAVITY_M_S2 as f64;
const DT: f64 = 0.001;

#[derive(Clone, Debug)]
struct Quad {
    p: [f64; 3],
    v: [f64; 3],
    /// Attitude quaternion (w, x, y, z), body → arena.
    q: [f64; 4],
    /// Body rates, rad/s.
    w: [f64; 3],
    /// Motor thrusts, N (lagged).
    f: [f64; 4],
    vbat: f64,
}

fn quat_from_euler(roll: f64, pitch: f64, yaw: f64) -> [f64; 4] {
    // R = Rz(yaw)·Ry(pitch)·Rx(roll)
    let qz = [(yaw / 2.0).cos(), 0.0, 0.0, (yaw / 2.0).sin()];
    let qy = [(pitch / 2.0).cos(), 0.0, (pitch / 2.0).sin(), 0.0];
    let qx = [(roll / 2.0).cos(), (roll / 2.0).sin(), 0.0, 0.0];
    quat_mul(quat_mul(qz, qy), qx)
}

impl Quad {
    fn new(p: [f64; 3], yaw: f64) -> Self {
        Quad {
            p,
            v: [0.0; 3],
            q: quat_from_euler(0.0, 0.0, yaw),
            w: [0.0; 3],
            f: [0.0; 4],
            vbat: 3.9,
        }
    }

    /// Start in the air with the motors already at hover thrust.
    fn hovering(p: [f64; 3], yaw: f64) -> Self {
        let mut q = Quad::new(p, yaw);
        q.f = [MASS * G / 4.0; 4];
        q
    }

    fn euler(&self) -> [f64; 3] {
        let r = quat_to_rot(self.q);
        [
            r[2][1].atan2(r[2][2]),
            (-r[2][0]).clamp(-1.0, 1.0).asin(),
            r[1][0].atan2(r[0][0]),
        ]
    }

    fn estimate(&self) -> StateEstimate {
        let e = self.euler();
        StateEstimate {
            position_m: self.p.map(|x| x as f32),
            velocity_m_s: self.v.map(|x| x as f32),
            attitude_rad: e.map(|x| x as f32),
            rates_rad_s: self.w.map(|x| x as f32),
            surface_height_m: 0.0,
            valid: true,
        }
    }

    /// Specific force in the body frame, m/s² (what the accelerometer reads).
    fn specific_force(&self, acc_arena: [f64; 3]) -> [f64; 3] {
        let r = quat_to_rot(self.q);
        mul_m3t_v3(&r, [acc_arena[0], acc_arena[1], acc_arena[2] + G])
    }

    /// Body torque from the current motor thrusts.
    fn torque(&self) -> [f64; 3] {
        let mut t = [0.0; 3];
        for i in 0..4 {
            t[0] += MOTOR_POS[i][1] * self.f[i];
            t[1] -= MOTOR_POS[i][0] * self.f[i];
            t[2] += SPIN[i] * K_TORQUE * self.f[i];
        }
        t
    }

    /// One 1 ms step with these duties; returns the arena-frame acceleration.
    fn step(&mut self, duty: MotorDuty) -> [f64; 3] {
        let a_lag = 1.0 - (-DT / MOTOR_TAU_S).exp();
        for i in 0..4 {
            let volts = f64::from(duty.0[i]) / 255.0 * self.vbat;
            let f_ss = if duty.0[i] == 0 {
                0.0
            } else {
                f64::from(thrust_from_voltage(volts as f32)).max(0.0)
            };
            self.f[i] += (f_ss - self.f[i]) * a_lag;
        }
        let total: f64 = self.f.iter().sum();
        let r = quat_to_rot(self.q);
        let mut acc = [0.0; 3];
        for k in 0..3 {
            acc[k] = r[k][2] * total / MASS - LINEAR_DRAG * self.v[k] / MASS;
        }
        acc[2] -= G;
        let tau = self.torque();
        let w = self.w;
        let iw = [INERTIA[0] * w[0], INERTIA[1] * w[1], INERTIA[2] * w[2]];
        let gyro = cross3(w, iw);
        for k in 0..3 {
            self.w[k] += (tau[k] - gyro[k] - ROT_DRAG * w[k]) / INERTIA[k] * DT;
            self.v[k] += acc[k] * DT;
            self.p[k] += self.v[k] * DT;
        }
        let half = [0.0, self.w[0] * DT / 2.0, self.w[1] * DT / 2.0, self.w[2] * DT / 2.0];
        let dq = quat_mul(self.q, half);
        for (qk, dk) in self.q.iter_mut().zip(dq) {
            *qk += dk;
        }
        let n = self.q.iter().map(|x| x * x).sum::<f64>().sqrt();
        self.q = self.q.map(|x| x / n);
        // Ground contact: resting on the floor, level, while the thrust cannot lift it.
        if self.p[2] <= 0.0 {
            self.p[2] = 0.0;
            if self.v[2] < 0.0 || acc[2] < 0.0 {
                let yaw = self.euler()[2];
                self.v = [0.0; 3];
                self.w = [0.0; 3];
                self.q = quat_from_euler(0.0, 0.0, yaw);
                acc = [0.0; 3];
            }
        }
        acc
    }
}

// ---------------------------------------------------------------------------------------------------------
// The loop: controller at 1 kHz on the model, perfect or noisy feedback.
// ---------------------------------------------------------------------------------------------------------

struct Noise {
    rng: SmallRng,
    pos: f32,
    vel: f32,
    att: f32,
    gyro: f32,
}

impl Noise {
    fn gauss(&mut self) -> f32 {
        let u1: f32 = self.rng.random::<f32>().max(1e-9);
        let u2: f32 = self.rng.random::<f32>();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f32::consts::PI * u2).cos()
    }
}

struct Flight {
    quad: Quad,
    ctrl: Controller,
    t_us: u64,
    noise: Option<Noise>,
    last: ControlOutput,
}

impl Flight {
    fn new(quad: Quad) -> Self {
        Flight::with_config(quad, ControllerConfig::default())
    }

    fn with_config(quad: Quad, cfg: ControllerConfig) -> Self {
        Flight {
            quad,
            ctrl: Controller::new(cfg).expect("valid config"),
            t_us: 0,
            noise: None,
            last: ControlOutput::default(),
        }
    }

    fn t(&self) -> f64 {
        self.t_us as f64 * 1e-6
    }

    fn step(&mut self, sp: &Setpoint) -> ControlOutput {
        let mut est = self.quad.estimate();
        let mut gyro = est.rates_rad_s;
        if let Some(n) = self.noise.as_mut() {
            for (k, g) in gyro.iter_mut().enumerate() {
                est.position_m[k] += n.pos * n.gauss();
                est.velocity_m_s[k] += n.vel * n.gauss();
                est.attitude_rad[k] += n.att * n.gauss();
                *g += n.gyro * n.gauss();
            }
            est.rates_rad_s = gyro;
        }
        let out = self.ctrl.update(sp, &est, gyro, self.quad.vbat as f32, self.t_us);
        self.quad.step(out.duty);
        self.t_us += 1000;
        self.last = out;
        out
    }

    /// Fly `sp` for `seconds`, calling `watch(t, quad)` after every step.
    fn fly(&mut self, sp: Setpoint, seconds: f64, mut watch: impl FnMut(f64, &Quad, &ControlOutput)) {
        let steps = (seconds / DT).round() as usize;
        for _ in 0..steps {
            let out = self.step(&sp);
            let t = self.t();
            watch(t, &self.quad, &out);
        }
    }

    /// Take off from the floor at (x, y) and settle at z for `seconds`.
    fn take_off(x: f64, y: f64, z: f64, yaw: f64, seconds: f64) -> Flight {
        let mut f = Flight::new(Quad::new([x, y, 0.0], yaw));
        f.fly(pos(x, y, z, yaw), seconds, |_, _, _| {});
        f
    }
}

fn pos(x: f64, y: f64, z: f64, yaw: f64) -> Setpoint {
    Setpoint::Position {
        x_m: x as f32,
        y_m: y as f32,
        z_m: z as f32,
        yaw_rad: yaw as f32,
    }
}

/// Step response along one coordinate: overshoot (fraction of the step) and the settling time (last time
/// outside ±`band` of the target, from the step).
struct StepResponse {
    overshoot: f64,
    settle_s: f64,
    rise_s: f64,
}

fn step_response(samples: &[(f64, f64)], start: f64, target: f64, band: f64) -> StepResponse {
    let dir = (target - start).signum();
    let size = (target - start).abs();
    let peak = samples
        .iter()
        .map(|&(_, v)| (v - target) * dir)
        .fold(f64::MIN, f64::max);
    let settle = samples
        .iter()
        .filter(|&&(_, v)| (v - target).abs() > band)
        .map(|&(t, _)| t)
        .fold(0.0, f64::max);
    let rise = samples
        .iter()
        .find(|&&(_, v)| (v - start) * dir >= 0.9 * size)
        .map_or(f64::INFINITY, |&(t, _)| t);
    StepResponse {
        overshoot: peak.max(0.0) / size,
        settle_s: settle,
        rise_s: rise,
    }
}

fn max_tilt_deg(q: &Quad) -> f64 {
    let r = quat_to_rot(q.q);
    r[2][2].clamp(-1.0, 1.0).acos().to_degrees()
}

// ---------------------------------------------------------------------------------------------------------
// Mixer and power distribution.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn mixer_table_matches_the_geometry() {
    // Sign tables against the motor positions and spins of §6.
    for i in 0..4 {
        assert_eq!(
            f64::from(ROLL_SIGN[i]),
            MOTOR_POS[i][1].signum(),
            "roll sign of M{}",
            i + 1
        );
        assert_eq!(
            f64::from(PITCH_SIGN[i]),
            -MOTOR_POS[i][0].signum(),
            "pitch sign of M{}",
            i + 1
        );
        assert_eq!(f64::from(YAW_SIGN[i]), SPIN[i], "yaw sign of M{}", i + 1);
    }
    let m = mixer::mix(30000.0, 2000, 0, 0);
    assert_eq!(
        m.cmd,
        [29000, 29000, 31000, 31000],
        "positive roll raises the left motors M3/M4"
    );
    let m = mixer::mix(30000.0, 0, 2000, 0);
    assert_eq!(
        m.cmd,
        [29000, 31000, 31000, 29000],
        "positive pitch raises the back motors M2/M3"
    );
    let m = mixer::mix(30000.0, 0, 0, 1000);
    assert_eq!(
        m.cmd,
        [29000, 31000, 29000, 31000],
        "positive yaw raises the CW motors M2/M4"
    );
}

/// Hold the model in the air at hover, apply a torque command through mixer + compensation for 60 ms
/// and look at what the body does.
fn response_to(roll: i16, pitch: i16, yaw: i16) -> ([f64; 3], [f64; 3]) {
    let mut q = Quad::hovering([0.0, 0.0, 1.0], 0.0);
    let hover_cmd = (MASS * G / 4.0 / f64::from(THRUST_MAX_N) * f64::from(CMD_MAX)) as f32;
    let m = mixer::mix(hover_cmd, roll, pitch, yaw);
    let (_, duty) = compensate(m.cmd, q.vbat as f32);
    let mut torque = [0.0; 3];
    for k in 0..60 {
        q.step(duty);
        if k == 59 {
            torque = q.torque();
        }
    }
    (torque, q.euler())
}

#[test]
fn mixer_signs_move_the_body_the_commanded_way() {
    for (axis, name, meaning, min_angle_rad) in [
        (
            0,
            "roll",
            "positive roll command lowers the right side (roll > 0)",
            0.01,
        ),
        (1, "pitch", "positive pitch command lowers the nose (pitch > 0)", 0.01),
        (
            2,
            "yaw",
            "positive yaw command turns counter-clockwise (yaw > 0)",
            0.001,
        ),
    ] {
        let mut cmd = [0i16; 3];
        cmd[axis] = 3000;
        let (t, e) = response_to(cmd[0], cmd[1], cmd[2]);
        println!(
            "{name} +3000: torque {t:?} N·m, attitude {:?} deg",
            e.map(f64::to_degrees)
        );
        assert!(t[axis] > 0.0 && e[axis] > min_angle_rad, "{meaning}");
        for other in (0..3).filter(|&k| k != axis) {
            assert!(e[other].abs() < 0.1 * e[axis], "{name} moves {other} too: {e:?}");
        }
    }
    let (t, e) = response_to(-3000, 0, 0);
    assert!(t[0] < 0.0 && e[0] < -0.01);
}

#[test]
fn capping_keeps_torque_and_yaw_never_eats_the_collective() {
    // Stock capping: 60000 + 8000 on the left → excess 2535 subtracted from all four.
    let m = mixer::mix(60000.0, 16000, 0, 0);
    assert!(m.capped);
    assert_eq!(m.cmd[2], 65535);
    assert_eq!(
        i32::from(m.cmd[2]) - i32::from(m.cmd[0]),
        16000,
        "the roll difference survives the capping"
    );
    // Floor at 0.
    let m = mixer::mix(5000.0, 32767, 0, 0);
    assert!(m.clipped_low);
    assert_eq!(m.cmd[0], 0);
    // Saturated yaw at hover thrust: clamped to the headroom, the collective stays.
    let hover = 44000.0;
    let m = mixer::mix(hover, 0, 0, 32767);
    assert_eq!(m.yaw_limited, 1);
    let sum: u32 = m.cmd.iter().map(|&c| u32::from(c)).sum();
    assert!(
        (f64::from(sum) - 4.0 * f64::from(hover)).abs() <= 4.0,
        "collective kept: {:?}",
        m.cmd
    );
    assert_eq!(m.cmd[1], 65535);
    // Garbage thrust.
    assert_eq!(mixer::mix(f32::NAN, 0, 0, 0).cmd, [0; 4]);
    assert_eq!(mixer::mix(f32::INFINITY, 0, 0, 0).cmd, [0; 4]);
}

#[test]
fn inverse_thrust_curve_is_exact() {
    for i in 1..=200 {
        let t = 0.15 * i as f32 / 200.0;
        let v = voltage_for_thrust(t);
        assert!((thrust_from_voltage(v) - t).abs() < 2e-6, "thrust {t}: V {v}");
    }
    assert_eq!(voltage_for_thrust(0.0), 0.0);
    assert_eq!(voltage_for_thrust(f32::NAN), 0.0);
}

#[test]
fn battery_compensation_raises_duty_as_the_voltage_drops() {
    let cmd = 44200u16; // hover of a 33 g drone
    let thrust = f32::from(cmd) / CMD_MAX * THRUST_MAX_N;
    let v_motor = voltage_for_thrust(thrust);
    let mut last = 0u8;
    println!("battery compensation at cmd {cmd} ({thrust:.4} N/motor, V_motor {v_motor:.3} V):");
    for vbat in [4.2f32, 4.0, 3.8, 3.6, 3.4, 3.2, 3.0] {
        let (ratio, duty) = compensate([cmd; 4], vbat);
        let expect = (255.0 * v_motor / vbat).round() as u8;
        println!("  V_bat {vbat:.1} V → duty {} (ratio {})", duty.0[0], ratio[0]);
        assert_eq!(duty.0, [expect; 4]);
        assert!(duty.0[0] > last, "duty rises as the battery drops");
        last = duty.0[0];
        // The motor then sees V_motor and makes the commanded thrust.
        let made = thrust_from_voltage(f32::from(duty.0[0]) / 255.0 * vbat);
        assert!((made - thrust).abs() < 0.003, "thrust {made} vs {thrust}");
    }
    // The controller's filter reaches the same duty.
    let (mut c, sp, est) = holding_one_metre();
    let duty_at = |vbat: f32, c: &mut Controller| {
        let mut out = ControlOutput::default();
        for k in 0..2000 {
            out = c.update(&sp, &est, [0.0; 3], vbat, k * 1000);
        }
        let ratio = f64::from(out.motor_ratio[0]) / f64::from(CMD_MAX);
        let v_m = f64::from(voltage_for_thrust(
            f32::from(out.thrust_cmd[0]) / CMD_MAX * THRUST_MAX_N,
        ));
        assert!(
            (ratio - v_m / f64::from(vbat)).abs() < 1e-3,
            "ratio {ratio} vs V_motor/V_bat"
        );
        out.duty.0[0]
    };
    let d42 = duty_at(4.2, &mut c);
    let d33 = duty_at(3.3, &mut c);
    assert!(d33 > d42, "{d33} > {d42}");

    // Below THRUST_MIN the motor is off.
    let tiny = (THRUST_MIN_N * 0.9 / THRUST_MAX_N * CMD_MAX) as u16;
    assert_eq!(compensated_ratio(tiny, 3.7), 0.0);
    assert_eq!(
        compensated_ratio(65535, 2.5),
        1.0,
        "a flat battery saturates at full duty"
    );
}

/// Stock `motorsCompensateBatteryVoltage` returns 0 below 2.0 V: a broken battery reading stops the
/// motors instead of running them uncompensated.
#[test]
fn battery_reading_below_two_volts_turns_the_motors_off_as_stock() {
    for vbat in [1.99f32, 1.5, 0.0, f32::NAN] {
        let (ratio, duty) = compensate([30000, 40000, 50000, 65535], vbat);
        assert_eq!(duty.0, [0; 4], "{vbat} V");
        assert_eq!(ratio, [0; 4], "{vbat} V");
    }
    // At 2.0 V compensation is on again (a motor that needs more than the battery has is at full duty).
    let (_, duty) = compensate([30000; 4], 2.0);
    assert!(duty.0.iter().all(|&d| d > 0), "{duty:?}");
    // The controller does the same with a filtered reading below 2 V; before any reading it flies
    // uncompensated (ratio = command).
    let sp = pos(0.0, 0.0, 1.0, 0.0);
    let est = StateEstimate {
        position_m: [0.0, 0.0, 1.0],
        valid: true,
        ..StateEstimate::default()
    };
    let mut c = Controller::new(ControllerConfig::default()).expect("valid");
    let out = c.update(&sp, &est, [0.0; 3], 1.2, 0);
    assert!(out.thrust_cmd.iter().all(|&t| t > 0), "{:?}", out.thrust_cmd);
    assert_eq!(out.duty.0, [0; 4]);
    let mut c = Controller::new(ControllerConfig::default()).expect("valid");
    let out = c.update(&sp, &est, [0.0; 3], f32::NAN, 0);
    let expect = out.thrust_cmd.map(|t| (f32::from(t) / CMD_MAX * 255.0).round() as u8);
    assert_eq!(out.duty.0, expect);
}

/// Stock order: compensate each motor, then cap the four together. On a sagging battery two motors that
/// both need more than the battery gives keep their difference (the roll/pitch torque), at the cost of
/// collective thrust; clamping each motor at full duty would flatten them.
#[test]
fn saturated_compensation_keeps_the_differential_thrust() {
    let vbat = 2.9f32;
    // Roll: the left motors (M3, M4) at full command, the right ones a bit lower; all beyond 2.9 V.
    let cmd = [60000u16, 60000, 65535, 65535];
    // The motor voltages from the cubic fit, found by bisection here (independent of the driver's Newton).
    let volts = cmd.map(|c| {
        let thrust = f64::from(c) / 65535.0 * 0.12;
        let f = |v: f64| -0.024765 + 0.065238 * v - 0.026793 * v * v + 0.0067768 * v * v * v;
        let (mut lo, mut hi) = (0.0f64, 8.0f64);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if f(mid) < thrust { lo = mid } else { hi = mid }
        }
        lo
    });
    assert!(
        volts.iter().all(|&v| v > f64::from(vbat)),
        "the battery cannot give any of them: {volts:?}"
    );
    let (ratio, duty) = compensate(cmd, vbat);
    let r = ratio.map(|x| f64::from(x) / 65535.0);
    // The fullest motors at full duty, the difference as uncapped.
    assert_eq!(duty.0[2], 255);
    assert_eq!(duty.0[3], 255);
    let want = (volts[2] - volts[0]) / f64::from(vbat);
    assert!(want > 0.02);
    for (lo, hi) in [(0, 2), (1, 3)] {
        assert!(
            (r[hi] - r[lo] - want).abs() < 1e-3,
            "difference {} vs {want}",
            r[hi] - r[lo]
        );
    }
    assert!(duty.0[0] < duty.0[2] && duty.0[1] < duty.0[3], "{duty:?}");
    // Unsaturated: the ratio is V_motor / V_bat per motor, untouched by the cap.
    let (ratio, _) = compensate(cmd, 4.2);
    for i in 0..4 {
        let r = f64::from(ratio[i]) / 65535.0;
        assert!((r - volts[i] / 4.2).abs() < 1e-3, "motor {i}: {r}");
    }
}

/// A default controller already at its setpoint, 1 m above the origin: only the battery changes its output.
fn holding_one_metre() -> (Controller, Setpoint, StateEstimate) {
    let est = StateEstimate {
        position_m: [0.0, 0.0, 1.0],
        valid: true,
        ..StateEstimate::default()
    };
    let c = Controller::new(ControllerConfig::default()).expect("valid");
    (c, pos(0.0, 0.0, 1.0, 0.0), est)
}

#[test]
fn battery_filter_is_stock_and_ignores_garbage() {
    let (mut c, sp, est) = holding_one_metre();
    let out = c.update(&sp, &est, [0.0; 3], 4.0, 0);
    assert_eq!(out.battery_v_filtered, 4.0, "first reading initialises the filter");
    let out = c.update(&sp, &est, [0.0; 3], 3.0, 1000);
    assert!((out.battery_v_filtered - 3.99).abs() < 1e-5, "factor 0.01 per tick");
    let out = c.update(&sp, &est, [0.0; 3], f32::NAN, 2000);
    assert!((out.battery_v_filtered - 3.99).abs() < 1e-5);
    let out = c.update(&sp, &est, [0.0; 3], 1e6, 3000);
    assert!((out.battery_v_filtered - 3.99).abs() < 1e-5);
}

// ---------------------------------------------------------------------------------------------------------
// Loop structure.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn loops_run_at_100_and_500_hz() {
    let mut c = Controller::new(ControllerConfig::default()).expect("valid");
    let sp = pos(1.0, 0.0, 1.0, 0.0);
    let mut collective_changes = Vec::new();
    let mut torque_changes = Vec::new();
    let mut prev = ControlOutput::default();
    for k in 0..40u64 {
        // A changing state so every loop run changes its output.
        let est = StateEstimate {
            position_m: [0.0, 0.0, 0.5 + 0.001 * k as f32],
            velocity_m_s: [0.0, 0.0, 0.01 * k as f32],
            attitude_rad: [0.001 * k as f32, 0.0, 0.0],
            valid: true,
            ..StateEstimate::default()
        };
        let out = c.update(&sp, &est, [0.01 * k as f32, 0.0, 0.0], 3.9, k * 1000);
        if out.collective != prev.collective {
            collective_changes.push(k);
        }
        if out.torque_cmd != prev.torque_cmd {
            torque_changes.push(k);
        }
        prev = out;
    }
    assert_eq!(collective_changes, vec![0, 10, 20, 30]);
    assert_eq!(torque_changes, (0..40).step_by(2).collect::<Vec<_>>());
}

#[test]
fn stop_gives_zero_duties_and_resets() {
    let mut f = Flight::take_off(1.0, 1.0, 0.5, 0.0, 4.0);
    assert!(f.last.duty.0.iter().all(|&d| d > 0));
    assert!(f.ctrl.integrals().iter().any(|&i| i != 0.0));
    let out = f.step(&Setpoint::Stop);
    assert_eq!(out.duty, MotorDuty([0; 4]));
    assert_eq!(out.thrust_cmd, [0; 4]);
    assert_eq!(out.motor_ratio, [0; 4]);
    assert!(out.flags.contains(ControlFlags::STOPPED));
    assert_eq!(f.ctrl.integrals(), [0.0; 12]);
    // Stays off.
    for _ in 0..100 {
        assert_eq!(f.step(&Setpoint::Stop).duty, MotorDuty([0; 4]));
    }
}

// ---------------------------------------------------------------------------------------------------------
// Closed-loop flights.
// ---------------------------------------------------------------------------------------------------------

fn hover_error(noise: Option<Noise>) -> (f64, f64, f64) {
    let mut f = Flight::take_off(1.0, 1.0, 0.5, 0.0, 0.0);
    f.noise = noise;
    // Take off and settle.
    f.fly(pos(1.0, 1.0, 0.5, 0.0), 6.0, |_, _, _| {});
    let (mut max_z, mut max_xy, mut sum_sq, mut n) = (0.0f64, 0.0f64, 0.0f64, 0.0);
    f.fly(pos(1.0, 1.0, 0.5, 0.0), 10.0, |_, q, _| {
        let ez = q.p[2] - 0.5;
        let exy = (q.p[0] - 1.0).hypot(q.p[1] - 1.0);
        max_z = max_z.max(ez.abs());
        max_xy = max_xy.max(exy);
        sum_sq += ez * ez + exy * exy;
        n += 1.0;
    });
    (max_z, max_xy, (sum_sq / n).sqrt())
}

/// Hovers 10 s at 0.5 m with this state feedback (`label` says which) and checks it stays within 3 cm.
fn assert_hovers(label: &str, noise: Option<Noise>) {
    let (z, xy, rms) = hover_error(noise);
    println!(
        "hover 0.5 m, {label}, 10 s: max |dz| {:.1} mm, max horizontal {:.1} mm, rms {:.1} mm",
        z * 1e3,
        xy * 1e3,
        rms * 1e3
    );
    assert!(z < 0.03 && xy < 0.03);
}

#[test]
fn hover_holds_half_a_metre() {
    assert_hovers("perfect state", None);
}

#[test]
fn hover_holds_with_noisy_state() {
    let noise = Noise {
        rng: SmallRng::seed_from_u64(7),
        pos: 0.005,
        vel: 0.02,
        att: 0.5f32.to_radians(),
        gyro: 0.02,
    };
    assert_hovers("noisy state (σ 5 mm, 2 cm/s, 0.5°, 0.02 rad/s)", Some(noise));
}

#[test]
fn rate_d_filter_option_still_hovers() {
    let cfg = ControllerConfig {
        rate_d_filter_hz: 30.0,
        ..ControllerConfig::default()
    };
    let mut f = Flight::with_config(Quad::new([1.0, 1.0, 0.0], 0.0), cfg);
    f.fly(pos(1.0, 1.0, 0.5, 0.0), 5.0, |_, _, _| {});
    let mut worst = 0.0f64;
    f.fly(pos(2.0, 1.0, 0.5, 0.0), 5.0, |_, q, _| {
        worst = worst.max((q.p[0] - 2.0).max(0.0))
    });
    println!(
        "rate D filtered at 30 Hz: 1 m step overshoot {:.1} mm, final x {:.3} m",
        worst * 1e3,
        f.quad.p[0]
    );
    assert!(worst < 0.2 && (f.quad.p[0] - 2.0).abs() < 0.03 && (f.quad.p[2] - 0.5).abs() < 0.03);
}

#[test]
fn take_off_climbs_without_overshooting() {
    for (cfg, label) in [
        (ControllerConfig::default(), "thrust base = 33 g hover"),
        (
            ControllerConfig {
                thrust_base: 36000.0,
                ..ControllerConfig::default()
            },
            "stock thrust base 36000",
        ),
    ] {
        let mut f = Flight::with_config(Quad::new([1.0, 1.0, 0.0], 0.0), cfg);
        let mut samples = Vec::new();
        f.fly(pos(1.0, 1.0, 0.5, 0.0), 8.0, |t, q, _| samples.push((t, q.p[2])));
        let r = step_response(&samples, 0.0, 0.5, 0.025);
        println!(
            "take-off to 0.5 m ({label}): overshoot {:.1} %, 90 % rise {:.2} s, settled (±2.5 cm) at {:.2} s",
            r.overshoot * 100.0,
            r.rise_s,
            r.settle_s
        );
        assert!(r.overshoot < 0.2 && r.settle_s < 5.0);
    }
    assert!((ControllerConfig::default().with_mass(0.027).thrust_base - 36100.0).abs() < 100.0);
}

#[test]
fn position_step_in_x() {
    for (yaw_deg, label) in [(0.0f64, "yaw 0°"), (90.0, "yaw 90°"), (-135.0, "yaw −135°")] {
        let yaw = yaw_deg.to_radians();
        let mut f = Flight::take_off(1.0, 1.0, 0.5, yaw, 6.0);
        let t0 = f.t();
        let (mut xs, mut max_dz, mut max_dy, mut max_tilt) = (Vec::new(), 0.0f64, 0.0f64, 0.0f64);
        f.fly(pos(2.0, 1.0, 0.5, yaw), 6.0, |t, q, _| {
            xs.push((t - t0, q.p[0]));
            max_dz = max_dz.max((q.p[2] - 0.5).abs());
            max_dy = max_dy.max((q.p[1] - 1.0).abs());
            max_tilt = max_tilt.max(max_tilt_deg(q));
        });
        let r = step_response(&xs, 1.0, 2.0, 0.05);
        println!(
            "1 m step in x ({label}): overshoot {:.1} %, 90 % rise {:.2} s, settled (±5 cm) {:.2} s, max |dz| {:.1} \
             mm, max |dy| {:.1} mm, max tilt {:.1}°",
            r.overshoot * 100.0,
            r.rise_s,
            r.settle_s,
            max_dz * 1e3,
            max_dy * 1e3,
            max_tilt
        );
        assert!(r.overshoot < 0.2, "overshoot {}", r.overshoot);
        assert!(r.settle_s < 3.5, "settle {}", r.settle_s);
        assert!(max_dz < 0.1 && max_dy < 0.1);
        assert!(max_tilt < 25.0);
    }
}

#[test]
fn height_step() {
    let mut f = Flight::take_off(1.0, 1.0, 0.5, 0.0, 6.0);
    let t0 = f.t();
    let mut zs = Vec::new();
    f.fly(pos(1.0, 1.0, 1.0, 0.0), 6.0, |t, q, _| zs.push((t - t0, q.p[2])));
    let up = step_response(&zs, 0.5, 1.0, 0.025);
    let t1 = f.t();
    zs.clear();
    f.fly(pos(1.0, 1.0, 0.5, 0.0), 6.0, |t, q, _| zs.push((t - t1, q.p[2])));
    let down = step_response(&zs, 1.0, 0.5, 0.025);
    println!(
        "height step 0.5 → 1.0 m: overshoot {:.1} %, rise {:.2} s, settled (±2.5 cm) {:.2} s; 1.0 → 0.5 m: \
         overshoot {:.1} %, rise {:.2} s, settled {:.2} s",
        up.overshoot * 100.0,
        up.rise_s,
        up.settle_s,
        down.overshoot * 100.0,
        down.rise_s,
        down.settle_s
    );
    assert!(up.overshoot < 0.2 && up.settle_s < 3.0);
    assert!(down.overshoot < 0.2 && down.settle_s < 3.0);
}

fn unwrap_towards(prev: f64, a: f64) -> f64 {
    let mut d = a - prev.rem_euclid(2.0 * PI);
    d = (d + PI).rem_euclid(2.0 * PI) - PI;
    prev + d
}

#[test]
fn yaw_step_wraps_the_short_way() {
    let start = 170f64.to_radians();
    let mut f = Flight::take_off(1.0, 1.0, 0.5, start, 6.0);
    let t0 = f.t();
    let mut yaw = f.quad.euler()[2];
    let (mut samples, mut min_yaw, mut max_dz) = (Vec::new(), f64::MAX, 0.0f64);
    f.fly(pos(1.0, 1.0, 0.5, (-170f64).to_radians()), 5.0, |t, q, _| {
        yaw = unwrap_towards(yaw, q.euler()[2]);
        samples.push((t - t0, yaw.to_degrees()));
        min_yaw = min_yaw.min(yaw.to_degrees());
        max_dz = max_dz.max((q.p[2] - 0.5).abs());
    });
    let r = step_response(&samples, 170.0, 190.0, 1.0);
    let end = samples.last().map_or(0.0, |s| s.1);
    println!(
        "yaw step 170° → −170°: went +{:.1}° (short way), overshoot {:.1} %, settled (±1°) {:.2} s, lowest {:.1}°, \
         max |dz| {:.1} mm",
        end - 170.0,
        r.overshoot * 100.0,
        r.settle_s,
        min_yaw,
        max_dz * 1e3
    );
    assert!((end - 190.0).abs() < 1.0, "ends at 190° unwrapped, i.e. −170°");
    assert!(min_yaw > 168.0, "never turned the long way");
    assert!(r.settle_s < 3.0);

    // A half turn does not cost height (yaw has the lowest priority in the mixer).
    let mut max_dz = 0.0f64;
    f.fly(pos(1.0, 1.0, 0.5, 10f64.to_radians()), 6.0, |_, q, _| {
        max_dz = max_dz.max((q.p[2] - 0.5).abs())
    });
    let e = f.quad.euler()[2].to_degrees();
    println!(
        "yaw step −170° → 10° (half turn): final {e:.1}°, max |dz| {:.1} mm",
        max_dz * 1e3
    );
    assert!((e - 10.0).abs() < 1.0 && max_dz < 0.05);
}

#[test]
fn velocity_setpoint_in_the_arena_frame() {
    // Heading 90°: arena +x is the drone's right. A Velocity setpoint is arena-frame regardless.
    let yaw = 90f64.to_radians();
    let mut f = Flight::take_off(1.0, 1.0, 0.5, yaw, 6.0);
    let sp = Setpoint::Velocity {
        vx_m_s: 0.5,
        vy_m_s: -0.2,
        z_m: 0.5,
        yaw_rad: yaw as f32,
    };
    f.fly(sp, 3.0, |_, _, _| {});
    let mut n = 0.0;
    let mut mean = [0.0f64; 3];
    f.fly(sp, 2.0, |_, q, _| {
        for (m, v) in mean.iter_mut().zip(q.v) {
            *m += v;
        }
        n += 1.0;
    });
    let mean = mean.map(|m| m / n);
    println!(
        "velocity setpoint (0.5, −0.2) at yaw 90°: mean velocity {mean:.3?} m/s, height {:.3} m",
        f.quad.p[2]
    );
    assert!((mean[0] - 0.5).abs() < 0.05 && (mean[1] + 0.2).abs() < 0.05 && mean[2].abs() < 0.02);
    assert!((f.quad.p[2] - 0.5).abs() < 0.03);
}

#[test]
fn descend_holds_xy_and_lands() {
    let mut f = Flight::take_off(1.0, 1.0, 0.8, 0.0, 6.0);
    let sp = Setpoint::Descend {
        x_m: 1.0,
        y_m: 1.0,
        vz_m_s: -0.3,
        yaw_rad: 0.0,
    };
    let mut vz_samples = Vec::new();
    let mut max_xy = 0.0f64;
    let mut touchdown = None;
    f.fly(sp, 5.0, |t, q, out| {
        if q.p[2] > 0.2 && q.p[2] < 0.6 {
            vz_samples.push(q.v[2]);
        }
        max_xy = max_xy.max((q.p[0] - 1.0).hypot(q.p[1] - 1.0));
        if touchdown.is_none() && q.p[2] <= 0.0 {
            touchdown = Some((t, out.thrust_cmd));
        }
    });
    let mean_vz = vz_samples.iter().sum::<f64>() / vz_samples.len() as f64;
    println!(
        "descend at −0.3 m/s: mean vz {mean_vz:.3} m/s, max horizontal error {:.1} mm",
        max_xy * 1e3
    );
    assert!((mean_vz + 0.3).abs() < 0.03);
    assert!(max_xy < 0.03);
    assert!(touchdown.is_some());
    // On the ground the integrators only decay and the thrust drops below hover.
    let out = f.last;
    assert!(out.flags.contains(ControlFlags::ON_GROUND));
    let mean_cmd = out.thrust_cmd.iter().map(|&c| f64::from(c)).sum::<f64>() / 4.0;
    let hover = MASS * G / 4.0 / f64::from(THRUST_MAX_N) * f64::from(CMD_MAX);
    println!("on the ground after descending: mean command {mean_cmd:.0} (hover {hover:.0})");
    assert!(mean_cmd < 0.9 * hover);
    let before = f.ctrl.integrals();
    f.fly(sp, 1.0, |_, _, _| {});
    let after = f.ctrl.integrals();
    for k in 0..12 {
        assert!(
            after[k].abs() <= before[k].abs() + 1e-6,
            "integrator {k} grew on the ground"
        );
    }
}

#[test]
fn huge_setpoints_stay_bounded() {
    let cfg = ControllerConfig::default();
    let max_tilt = f64::from(cfg.max_tilt_rad).to_degrees();
    let mut f = Flight::take_off(1.0, 1.0, 1.0, 0.0, 6.0);
    let (mut tilt, mut speed, mut vz, mut min_z) = (0.0f64, 0.0f64, 0.0f64, f64::MAX);
    let mut check = |_: f64, q: &Quad, out: &ControlOutput| {
        tilt = tilt.max(max_tilt_deg(q));
        speed = speed.max(q.v[0].hypot(q.v[1]));
        vz = vz.max(q.v[2].abs());
        min_z = min_z.min(q.p[2]);
        let [r, p, _] = out.attitude_target_rad;
        assert!(f64::from(r.hypot(p)).to_degrees() <= max_tilt + 1e-3);
        let v = out.velocity_target_m_s;
        assert!(v[0].hypot(v[1]) <= cfg.max_xy_speed_m_s + 1e-4 && v[2].abs() <= cfg.max_vz_m_s + 1e-4);
    };
    f.fly(pos(1e6, -1e6, 1.0, 1e3), 3.0, &mut check);
    f.fly(
        Setpoint::Velocity {
            vx_m_s: -100.0,
            vy_m_s: 1e9,
            z_m: 1.0,
            yaw_rad: 0.0,
        },
        3.0,
        &mut check,
    );
    f.fly(
        Setpoint::Descend {
            x_m: f.quad.p[0] as f32,
            y_m: 0.0,
            vz_m_s: 50.0,
            yaw_rad: 0.0,
        },
        1.0,
        &mut check,
    );
    f.fly(pos(f.quad.p[0], f.quad.p[1], 1e4, 0.0), 1.0, &mut check);
    println!(
        "huge setpoints: max tilt {tilt:.1}° (limit {max_tilt:.1}°), max horizontal speed {speed:.2} m/s, max |vz| \
         {vz:.2} m/s"
    );
    assert!(tilt < max_tilt + 5.0, "tilt {tilt}");
    assert!(speed < 1.3 && vz < 1.3);
    assert!(min_z > 0.7);
    let ints = f.ctrl.integrals();
    assert!(ints.iter().all(|i| i.is_finite()));
    // No windup while saturated: the velocity integrators (degrees of tilt per unit Ki) stayed small.
    println!(
        "integrators after the saturated phases: vx {:.3}, vy {:.3}, vz {:.3}",
        ints[6], ints[7], ints[8]
    );
    assert!(ints[6].abs() < 1.0 && ints[7].abs() < 1.0 && ints[8].abs() < 0.5);
    // And an ordinary step afterwards is clean.
    let (x0, y0) = (f.quad.p[0], f.quad.p[1]);
    f.fly(pos(x0, y0, 1.0, 0.0), 4.0, |_, _, _| {});
    let t0 = f.t();
    let mut xs = Vec::new();
    f.fly(pos(x0 + 0.5, y0, 1.0, 0.0), 4.0, |t, q, _| xs.push((t - t0, q.p[0])));
    let r = step_response(&xs, x0, x0 + 0.5, 0.025);
    println!(
        "0.5 m step after saturation: overshoot {:.1} %, settled (±2.5 cm) {:.2} s",
        r.overshoot * 100.0,
        r.settle_s
    );
    assert!(r.overshoot < 0.2 && r.settle_s < 3.0);
}

#[test]
fn garbage_inputs_give_finite_outputs() {
    let mut f = Flight::take_off(1.0, 1.0, 0.5, 0.0, 4.0);
    let nan = f32::NAN;
    let sp_garbage = [
        Setpoint::Position {
            x_m: nan,
            y_m: 1.0,
            z_m: 0.5,
            yaw_rad: 0.0,
        },
        Setpoint::Position {
            x_m: 1.0,
            y_m: f32::INFINITY,
            z_m: nan,
            yaw_rad: nan,
        },
        Setpoint::Velocity {
            vx_m_s: nan,
            vy_m_s: 0.0,
            z_m: 0.5,
            yaw_rad: 0.0,
        },
        Setpoint::Descend {
            x_m: 1.0,
            y_m: 1.0,
            vz_m_s: nan,
            yaw_rad: f32::NEG_INFINITY,
        },
    ];
    for sp in sp_garbage {
        let mut z_err = 0.0f64;
        f.fly(sp, 0.5, |_, q, out| {
            z_err = z_err.max((q.p[2] - 0.5).abs());
            assert!(out.collective.is_finite());
            assert!(out.attitude_target_rad.iter().all(|a| a.is_finite()));
        });
        assert!(f.last.flags.contains(ControlFlags::SETPOINT_GARBAGE));
        assert!(z_err < 0.05, "garbage setpoint {sp:?} moved the drone by {z_err}");
        f.fly(pos(1.0, 1.0, 0.5, 0.0), 1.0, |_, _, _| {});
    }
    // Garbage state and gyro: outputs stay finite and bounded.
    let mut c = Controller::new(ControllerConfig::default()).expect("valid");
    let bad = StateEstimate {
        position_m: [nan, f32::INFINITY, nan],
        velocity_m_s: [nan; 3],
        attitude_rad: [nan, f32::NEG_INFINITY, nan],
        rates_rad_s: [nan; 3],
        surface_height_m: nan,
        valid: false,
    };
    for k in 0..100u64 {
        let out = c.update(&pos(1.0, 1.0, 0.5, 0.0), &bad, [nan; 3], nan, k * 1000);
        assert!(out.flags.contains(ControlFlags::STATE_GARBAGE));
        assert!(out.collective.is_finite() && out.rate_target_rad_s.iter().all(|r| r.is_finite()));
        assert!(c.integrals().iter().all(|i| i.is_finite()));
    }
    // Time running backwards or jumping: still finite.
    let est = StateEstimate {
        position_m: [1.0, 1.0, 0.5],
        valid: true,
        ..StateEstimate::default()
    };
    for now in [5_000_000u64, 1_000, u64::MAX, 0] {
        let out = c.update(&pos(1.0, 1.0, 0.5, 0.0), &est, [0.0; 3], 3.9, now);
        assert!(out.collective.is_finite());
    }
}

#[test]
fn invalid_configs_are_refused() {
    let mut cfg = ControllerConfig::default();
    cfg.roll_rate.kp = f32::NAN;
    assert!(Controller::new(cfg).is_err());
    let cfg = ControllerConfig {
        max_tilt_rad: 0.0,
        ..ControllerConfig::default()
    };
    assert!(Controller::new(cfg).is_err());
    let mut cfg = ControllerConfig::default();
    cfg.vel_z.i_limit = -1.0;
    assert!(Controller::new(cfg).is_err());
    assert!(Controller::new(ControllerConfig::default()).is_ok());
}

#[test]
fn memory_footprint() {
    let size = std::mem::size_of::<Controller>();
    println!("Controller: {size} bytes");
    assert!(size <= 1024);
}

// ---------------------------------------------------------------------------------------------------------
// With the supervisor in the loop.
// ---------------------------------------------------------------------------------------------------------

/// Controller + supervisor + model: the firmware's 1 kHz loop in miniature.
struct Guarded {
    f: Flight,
    sup: Supervisor,
    acc: [f64; 3],
}

impl Guarded {
    fn new(quad: Quad) -> Self {
        Guarded {
            f: Flight::new(quad),
            sup: Supervisor::new(SupervisorConfig::default()),
            acc: [0.0; 3],
        }
    }

    fn step(&mut self, mission: Setpoint) -> cfnav::flight::supervisor::SupervisorOutput {
        let q = &self.f.quad;
        let sf = q.specific_force(self.acc);
        let input = SupervisorInput {
            now: self.f.t_us,
            accel_m_s2: sf.map(|x| x as f32),
            estimate: q.estimate(),
            thrust_cmd: self.f.last.thrust_cmd,
            setpoint: mission,
            setpoint_age_us: Some(0),
            battery_v: q.vbat as f32,
            arm_request: false,
        };
        let out = self.sup.update(&input);
        let sp = self.sup.guard_setpoint(mission);
        let est = self.f.quad.estimate();
        let c = self
            .f
            .ctrl
            .update(&sp, &est, est.rates_rad_s, self.f.quad.vbat as f32, self.f.t_us);
        self.acc = self.f.quad.step(c.duty);
        self.f.t_us += 1000;
        self.f.last = c;
        out
    }
}

#[test]
fn take_off_hover_land_with_the_supervisor() {
    let mut g = Guarded::new(Quad::new([1.0, 1.0, 0.0], 0.0));
    assert_eq!(g.step(Setpoint::Stop).state, SupervisorState::Armed);
    for _ in 0..6000 {
        g.step(pos(1.0, 1.0, 0.5, 0.0));
    }
    assert_eq!(g.sup.state(), SupervisorState::Flying);
    assert!((g.f.quad.p[2] - 0.5).abs() < 0.03);
    let land = Setpoint::Descend {
        x_m: 1.0,
        y_m: 1.0,
        vz_m_s: -0.3,
        yaw_rad: 0.0,
    };
    let (mut contact, mut landed) = (None, None);
    for k in 0..5000 {
        let out = g.step(land);
        let t = f64::from(k) * 1e-3;
        if contact.is_none() && g.f.quad.p[2] <= 0.0 {
            contact = Some(t);
        }
        if out.state == SupervisorState::Landed {
            assert_eq!(out.reason, Reason::Touchdown);
            landed = Some(t);
            break;
        }
    }
    let (contact, landed) = (contact.expect("touched the floor"), landed.expect("touchdown detected"));
    println!(
        "landing at −0.3 m/s: floor contact at {contact:.2} s, touchdown detected {:.0} ms later",
        (landed - contact) * 1e3
    );
    assert!(landed - contact < 0.6);
    // Motors off on the next tick.
    g.step(land);
    assert_eq!(g.f.last.duty, MotorDuty([0; 4]));
}

#[test]
fn a_knock_in_flight_is_recovered_and_not_a_false_crash() {
    // In the air the accelerometer reads the thrust along body z (positive even upside down), so the
    // tumble rules cannot fire; they catch a drone lying on its side or back. The controller must right
    // itself from a large upset, and the supervisor must not cut the motors meanwhile.
    let mut g = Guarded::new(Quad::new([1.0, 1.0, 0.0], 0.0));
    g.step(Setpoint::Stop);
    for _ in 0..5000 {
        g.step(pos(1.0, 1.0, 1.0, 0.0));
    }
    g.f.quad.q = quat_from_euler(PI / 3.0, -PI / 8.0, 0.0);
    g.f.quad.w = [5.0, -2.0, 3.0];
    let (mut min_z, mut upright_at) = (f64::MAX, None);
    for k in 0..3000 {
        let out = g.step(pos(1.0, 1.0, 1.0, 0.0));
        assert_eq!(out.state, SupervisorState::Flying, "false crash at {k} ms");
        min_z = min_z.min(g.f.quad.p[2]);
        if upright_at.is_none() && quat_to_rot(g.f.quad.q)[2][2] > (10f64).to_radians().cos() {
            upright_at = Some(k);
        }
    }
    println!(
        "knocked to 60° roll, −22.5° pitch, spinning, at 1 m: within 10° of level after {upright_at:?} ms, \
         lowest height {min_z:.2} m"
    );
    assert!(upright_at.is_some_and(|k| k < 1000) && min_z > 0.5);
    assert!((g.f.quad.p[2] - 1.0).abs() < 0.05);
}
