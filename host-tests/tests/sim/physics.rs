//! The simulator's quadrotor physics and sensor models (`cfnav_tools::sim::{physics, sensors}`): timing of a
//! free fall, hover duty, motor lag, the signs of the motor torques against `cfnav::types`, the battery, and
//! each sensor against its model. Run with `--nocapture` to see the measured numbers (for BENCHMARKS.md).

use std::time::Instant;

use cfnav::math::arena_to_body;
use cfnav::types::{GRAVITY_M_S2, MotorDuty};
use cfnav_sim::physics::{Geometry, QuadParams, Quadrotor};
use cfnav_sim::sensors::{
    BatterySensor, Beam, FlowParams, FlowSensor, Imu, ImuParams, MultiRanger, MultiRangerParams, SensorFault,
    VL53L1X_HALF_FOV_RAD, ZRanger, ZRangerParams, zranger_noise_std_m,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const DT: f32 = 0.001;

/// A walled room (floor at 0, ceiling at `size[2]`) with solid boxes standing on the floor (pads, obstacles).
struct Room {
    size: [f32; 3],
    boxes: Vec<([f32; 3], [f32; 3])>,
    bounded: bool,
}

impl Room {
    fn new(size: [f32; 3]) -> Self {
        Self {
            size,
            boxes: Vec::new(),
            bounded: false,
        }
    }

    /// A square pad (box) centred at (x, y) with side `side` and top at `height`.
    fn with_pad(mut self, x: f32, y: f32, side: f32, height: f32) -> Self {
        let h = side / 2.0;
        self.boxes.push(([x - h, y - h, 0.0], [x + h, y + h, height]));
        self
    }
}

fn slab(o: [f32; 3], d: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> Option<f32> {
    let (mut t0, mut t1) = (f32::NEG_INFINITY, f32::INFINITY);
    for i in 0..3 {
        if d[i].abs() < 1e-9 {
            if o[i] < lo[i] || o[i] > hi[i] {
                return None;
            }
        } else {
            let a = (lo[i] - o[i]) / d[i];
            let b = (hi[i] - o[i]) / d[i];
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
    }
    (t1 >= t0.max(0.0)).then_some(t0.max(0.0))
}

impl Geometry for Room {
    fn ray_cast(&self, o: [f32; 3], d: [f32; 3], max_range_m: f32) -> Option<f32> {
        let mut best = f32::INFINITY;
        for i in 0..3 {
            if d[i] > 1e-9 {
                best = best.min((self.size[i] - o[i]) / d[i]);
            } else if d[i] < -1e-9 {
                best = best.min(-o[i] / d[i]);
            }
        }
        for (lo, hi) in &self.boxes {
            if let Some(t) = slab(o, d, *lo, *hi) {
                best = best.min(t);
            }
        }
        (best >= 0.0 && best <= max_range_m).then_some(best)
    }

    fn surface_height(&self, x: f32, y: f32) -> f32 {
        self.boxes
            .iter()
            .filter(|(lo, hi)| x >= lo[0] && x <= hi[0] && y >= lo[1] && y <= hi[1])
            .map(|(_, hi)| hi[2])
            .fold(0.0, f32::max)
    }

    fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        self.bounded.then_some((
            [0.05, 0.05, 0.0],
            [self.size[0] - 0.05, self.size[1] - 0.05, self.size[2] - 0.03],
        ))
    }
}

/// A geometry that answers garbage.
struct NanWorld;

impl Geometry for NanWorld {
    fn ray_cast(&self, _: [f32; 3], _: [f32; 3], _: f32) -> Option<f32> {
        Some(f32::NAN)
    }
    fn surface_height(&self, _: f32, _: f32) -> f32 {
        f32::NAN
    }
}

fn big_room() -> Room {
    Room::new([10.0, 10.0, 8.0])
}

fn run(q: &mut Quadrotor, g: &impl Geometry, seconds: f32) {
    let n = (seconds / DT).round() as usize;
    for _ in 0..n {
        q.step(DT, g);
    }
}

/// Vertical acceleration after the motors have settled at `duty` (all four), in the air, level.
fn vertical_accel_at(params: QuadParams, supply_v: Option<f32>, soc: f32, duty: u8) -> (f32, f32, f32) {
    let room = big_room();
    let mut q = Quadrotor::new(params, [5.0, 5.0, 4.0], 0.0);
    q.battery_mut().set_state_of_charge(soc);
    q.battery_mut().set_supply(supply_v);
    q.set_duty(MotorDuty([duty; 4]));
    run(&mut q, &room, 0.3);
    (
        q.specific_force()[2] - GRAVITY_M_S2,
        q.battery().current(),
        q.battery_voltage(),
    )
}

/// The integer duty whose settled vertical acceleration is closest to zero (bisection on the duty), with
/// that acceleration, the battery current and the loaded voltage.
fn hover_duty(params: QuadParams, supply_v: Option<f32>, soc: f32) -> (u8, f32, f32, f32) {
    let (mut lo, mut hi) = (0u8, 255u8); // az(lo) < 0 <= az(hi)
    assert!(
        vertical_accel_at(params, supply_v, soc, hi).0 > 0.0,
        "cannot lift off at all"
    );
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if vertical_accel_at(params, supply_v, soc, mid).0 < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a_lo = vertical_accel_at(params, supply_v, soc, lo);
    let a_hi = vertical_accel_at(params, supply_v, soc, hi);
    if a_lo.0.abs() < a_hi.0.abs() {
        (lo, a_lo.0, a_lo.1, a_lo.2)
    } else {
        (hi, a_hi.0, a_hi.1, a_hi.2)
    }
}

fn bench_params() -> QuadParams {
    QuadParams::default()
}

// -------------------------------------------------------------------------------------------------------------
// Physics
// -------------------------------------------------------------------------------------------------------------

#[test]
fn free_fall_from_one_metre_lands_on_time_then_rests() {
    let room = big_room();
    let expected = (2.0f32 * 1.0 / GRAVITY_M_S2).sqrt();
    let mut vacuum = bench_params();
    vacuum.body_drag_n_s2_m2 = [0.0; 3];
    for (name, params, tol_early, tol_late) in [
        ("no drag", vacuum, 0.001, 0.001),
        ("default drag", QuadParams::default(), 0.0, 0.010),
    ] {
        // The body's bottom starts exactly 1 m above the floor.
        let mut q = Quadrotor::new(params, [5.0, 5.0, 1.0 + params.bottom_offset_m], 0.0);
        let mut steps = 0;
        while !q.on_ground() && steps < 2000 {
            q.step(DT, &room);
            steps += 1;
        }
        let td = q.last_touchdown().expect("touched down");
        println!(
            "free fall 1 m ({name}): touchdown after {:.4} s (vacuum {:.4} s), impact {:.2} m/s",
            td.time_s, expected, td.vertical_speed_m_s
        );
        let err = td.time_s as f32 - expected;
        assert!(
            err >= -tol_early - 1e-4 && err <= tol_late,
            "{name}: touchdown {} vs {expected}",
            td.time_s
        );
        assert_eq!(td.surface_height_m, 0.0);
        // Then it rests: no bounce, no slide, level, motors off.
        let p0 = q.position();
        run(&mut q, &room, 2.0);
        assert!(q.on_ground());
        let p1 = q.position();
        for i in 0..3 {
            assert!((p1[i] - p0[i]).abs() < 1e-5, "{p0:?} -> {p1:?}");
        }
        assert!((p1[2] - params.bottom_offset_m).abs() < 1e-6);
        assert_eq!(q.velocity(), [0.0; 3]);
        let sf = q.specific_force();
        assert!(
            sf[0].abs() < 1e-4 && sf[1].abs() < 1e-4 && (sf[2] - GRAVITY_M_S2).abs() < 1e-4,
            "{sf:?}"
        );
    }
}

#[test]
fn hover_duty_balances_weight_and_rises_as_the_voltage_sags() {
    let params = QuadParams::default();
    let mut last = 0u8;
    println!(
        "mass {:.4} kg, hover thrust {:.4} N/motor, motor voltage at hover {:.3} V",
        params.mass_kg,
        params.hover_thrust_per_motor_n(),
        params.motor_voltage_for_thrust(params.hover_thrust_per_motor_n())
    );
    for v in [4.2, 4.0, 3.7, 3.4, 3.1] {
        let (duty, az, current, _) = hover_duty(params, Some(v), 1.0);
        println!(
            "bench supply {v:.1} V: hover duty {duty}/255 ({:.1} %), residual az {az:+.3} m/s², \
             current {current:.2} A",
            duty as f32 / 2.55
        );
        // One duty step is ~0.12 m/s² of vertical acceleration at hover: the best integer duty is within half.
        assert!(az.abs() < 0.08, "{v} V: az {az}");
        if v == 4.0 {
            // At 4.0 V the hover motor voltage (≈2.5 V) needs ≈ 62–66 % duty.
            assert!((150..=175).contains(&duty), "hover duty at 4.0 V: {duty}");
        }
        assert!(
            duty > last,
            "hover duty must rise as the voltage drops: {duty} after {last}"
        );
        last = duty;
    }
    // On the real battery: full, half, nearly empty.
    let mut last = 0u8;
    for soc in [1.0, 0.5, 0.12] {
        let (duty, az, current, v) = hover_duty(params, None, soc);
        println!(
            "battery SoC {:.0} %: hover duty {duty}/255, loaded {v:.2} V, hover current {current:.2} A, az {az:+.3}",
            soc * 100.0
        );
        assert!(az.abs() < 0.08);
        assert!(duty > last);
        assert!((1.9..3.0).contains(&current), "hover current {current} A");
        last = duty;
    }
}

#[test]
fn motor_lag_reaches_63_percent_at_tau() {
    let room = big_room();
    let params = QuadParams::default();
    let tau = params.motor_time_constant_s;
    let mut q = Quadrotor::new(params, [5.0, 5.0, 4.0], 0.0);
    q.battery_mut().set_supply(Some(4.0));
    let duty = 180u8;
    let t_ss = params.thrust_from_motor_voltage(duty as f32 / 255.0 * 4.0);
    q.set_duty(MotorDuty([duty; 4]));
    run(&mut q, &room, tau);
    let f = q.motor_thrusts()[0] / t_ss;
    println!(
        "motor step 0 → {duty}: {:.1} % of {t_ss:.4} N after τ = {tau} s",
        f * 100.0
    );
    assert!((f - (1.0 - (-1.0f32).exp())).abs() < 0.005, "{f}");
    run(&mut q, &room, 10.0 * tau);
    assert!((q.motor_thrusts()[0] / t_ss - 1.0).abs() < 1e-3);
    // And down.
    q.set_duty(MotorDuty([0; 4]));
    run(&mut q, &room, tau);
    let f = q.motor_thrusts()[0] / t_ss;
    assert!((f - (-1.0f32).exp()).abs() < 0.005, "{f}");
}

/// In the air at hover on a 4.0 V supply, with some motors `delta` duty stronger and the others weaker.
fn differential(up: [bool; 4], delta: u8, seconds: f32) -> Quadrotor {
    let room = big_room();
    let params = QuadParams::default();
    let (d, _, _, _) = hover_duty(params, Some(4.0), 1.0);
    let mut q = Quadrotor::new(params, [5.0, 5.0, 4.0], 0.0);
    q.battery_mut().set_supply(Some(4.0));
    q.set_duty(MotorDuty([d; 4]));
    let t = params.thrust_from_motor_voltage(d as f32 / 255.0 * 4.0);
    q.set_motor_thrusts([t; 4]);
    let duties = up.map(|u| if u { d + delta } else { d - delta });
    q.set_duty(MotorDuty(duties));
    run(&mut q, &room, seconds);
    q
}

#[test]
fn left_motors_stronger_roll_positive_right_side_down_and_move_right() {
    // M3 (back-left) and M4 (front-left) up, M1/M2 (right) down.
    let q = differential([false, false, true, true], 2, 0.05);
    let [roll, pitch, yaw] = q.attitude_rad();
    println!("left motors +2/right −2 duty, 50 ms: roll {roll:+.4} rad, pitch {pitch:+.5}, yaw {yaw:+.5}");
    assert!(roll > 0.005, "roll {roll}");
    assert!(q.rates()[0] > 0.0);
    assert!(pitch.abs() < 1e-4 && yaw.abs() < 1e-4);
    // Positive roll lowers the right side: the body's right (−y) axis points down.
    let r = q.rotation();
    assert!(-r[2][1] < 0.0, "right axis z component {}", -r[2][1]);
    let q = differential([false, false, true, true], 2, 0.2);
    let vb = q.body_velocity();
    assert!(vb[1] < -0.01, "should accelerate to the right (−y): {vb:?}");
}

#[test]
fn back_motors_stronger_pitch_positive_nose_down_and_move_forward() {
    // M2 (back-right) and M3 (back-left) up.
    let q = differential([false, true, true, false], 2, 0.05);
    let [roll, pitch, yaw] = q.attitude_rad();
    println!("back motors +2/front −2 duty, 50 ms: roll {roll:+.5}, pitch {pitch:+.4} rad, yaw {yaw:+.5}");
    assert!(pitch > 0.005, "pitch {pitch}");
    assert!(q.rates()[1] > 0.0);
    assert!(roll.abs() < 1e-4 && yaw.abs() < 1e-4);
    assert!(q.rotation()[2][0] < 0.0, "nose must point down");
    let q = differential([false, true, true, false], 2, 0.2);
    assert!(
        q.body_velocity()[0] > 0.01,
        "should accelerate forward: {:?}",
        q.body_velocity()
    );
}

#[test]
fn cw_props_stronger_yaw_counter_clockwise() {
    // M2 and M4 spin CW (seen from above): their reaction torque on the body is CCW = positive yaw.
    let q = differential([false, true, false, true], 10, 0.2);
    let [roll, pitch, yaw] = q.attitude_rad();
    println!(
        "M2/M4 +10, M1/M3 −10 duty, 200 ms: yaw {yaw:+.4} rad, yaw rate {:+.3} rad/s",
        q.rates()[2]
    );
    assert!(yaw > 0.01 && q.rates()[2] > 0.0, "yaw {yaw}");
    assert!(roll.abs() < 1e-4 && pitch.abs() < 1e-4);
    // And M1/M3 (CCW props) stronger turns it clockwise.
    let q = differential([true, false, true, false], 10, 0.2);
    assert!(q.attitude_rad()[2] < -0.01);
}

#[test]
fn landing_on_a_pad_and_side_contact() {
    let room = big_room().with_pad(5.0, 5.0, 0.3, 0.1);
    let params = QuadParams::default();
    // Drop onto the pad.
    let mut q = Quadrotor::new(params, [5.05, 4.95, 0.6], 0.4);
    run(&mut q, &room, 1.0);
    assert!(q.on_ground());
    assert!((q.position()[2] - (0.1 + params.bottom_offset_m)).abs() < 1e-6);
    assert_eq!(q.support_height(), 0.1);
    assert_eq!(q.last_touchdown().unwrap().surface_height_m, 0.1);
    assert!((q.attitude_rad()[2] - 0.4).abs() < 1e-4, "yaw kept");
    // Motors off: it stays put for a long time.
    let p0 = q.position();
    run(&mut q, &room, 10.0);
    assert_eq!(q.position(), p0);
    // Landing tilted and sliding: it levels within ~0.3 s and stops.
    let mut q = Quadrotor::new(params, [3.0, 3.0, 0.3], 0.0);
    q.set_attitude_rad([0.2, -0.15, 1.0]);
    q.set_velocity([0.3, 0.0, -0.5]);
    run(&mut q, &room, 0.5);
    assert!(q.on_ground());
    let [r, p, _] = q.attitude_rad();
    assert!(r.abs() < 0.01 && p.abs() < 0.01, "levelled: {r} {p}");
    assert_eq!(q.velocity(), [0.0; 3]);
    // Flying low (6 cm, hover thrust) into the side of the 10 cm pad does not lift the drone onto it.
    let mut q = Quadrotor::new(params, [4.5, 5.0, 0.06], 0.0);
    q.battery_mut().set_supply(Some(4.0));
    let (d, _, _, _) = hover_duty(params, Some(4.0), 1.0);
    q.set_duty(MotorDuty([d; 4]));
    q.set_motor_thrusts([params.thrust_from_motor_voltage(d as f32 / 255.0 * 4.0); 4]);
    q.set_velocity([1.0, 0.0, 0.0]);
    run(&mut q, &room, 0.6);
    assert!(
        q.position()[0] > 4.9,
        "passed into the pad's footprint: {:?}",
        q.position()
    );
    assert!(
        q.position()[2] < 0.08 && !q.on_ground(),
        "not put on top: {:?}",
        q.position()
    );
    assert_eq!(q.support_height(), 0.0);
    // Walls: with bounds, the body origin stays inside.
    let mut walled = big_room();
    walled.bounded = true;
    let mut q = Quadrotor::new(params, [9.8, 5.0, 1.0], 0.0);
    q.set_velocity([3.0, 0.0, 0.0]);
    run(&mut q, &walled, 0.3);
    assert!(q.position()[0] <= 9.95 + 1e-6);
}

// -------------------------------------------------------------------------------------------------------------
// Battery
// -------------------------------------------------------------------------------------------------------------

#[test]
fn battery_sags_under_load_and_recovers() {
    let room = big_room();
    let mut q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.0], 0.0);
    q.place_on_surface(&room);
    q.battery_mut().set_state_of_charge(0.8);
    run(&mut q, &room, 0.1);
    let v_rest = q.battery_voltage();
    let ocv = q.battery().open_circuit_voltage();
    // Duty 150 stays below the weight: the motors load the battery while it sits on the floor.
    q.set_duty(MotorDuty([150; 4]));
    run(&mut q, &room, 2.0);
    assert!(q.on_ground());
    let v_load = q.battery_voltage();
    let i_load = q.battery().current();
    q.set_duty(MotorDuty([0; 4]));
    run(&mut q, &room, 0.2);
    let v_after = q.battery_voltage();
    run(&mut q, &room, 60.0);
    let v_recovered = q.battery_voltage();
    println!(
        "battery at 80 %: OCV {ocv:.3} V, rest {v_rest:.3} V, {i_load:.2} A load {v_load:.3} V, \
         0.2 s after {v_after:.3} V, 60 s after {v_recovered:.3} V"
    );
    assert!(v_rest - v_load > 0.25, "sag {}", v_rest - v_load);
    assert!(
        v_after > v_load + 0.2 && v_after < v_rest,
        "ohmic part recovers at once, polarisation slowly"
    );
    // Back to the open-circuit voltage of the (slightly lower) charge minus the electronics' draw.
    let b = q.battery().params();
    let at_rest = q.battery().open_circuit_voltage() - (b.r0_ohm + b.r1_ohm) * b.electronics_current_a;
    assert!(
        (v_recovered - at_rest).abs() < 0.002,
        "recovered {v_recovered} vs {at_rest}"
    );
    assert!(v_rest - v_recovered < 0.015, "the charge used costs a few mV only");
}

/// Closed-loop vertical hold at 1 m (PD on height, battery-compensated duty like the stock firmware);
/// returns the quad after `seconds` or when the loaded voltage falls below `stop_below_v`.
fn hover_for(q: &mut Quadrotor, room: &Room, seconds: f32, stop_below_v: f32) -> f32 {
    let params = *q.params();
    let steps = (seconds / DT) as usize;
    for k in 0..steps {
        if k.is_multiple_of(2) {
            let p = q.position();
            let v = q.velocity();
            let t_need = params.mass_kg / 4.0 * (GRAVITY_M_S2 + 4.0 * (1.0 - p[2]) - 3.0 * v[2]);
            let v_need = params.motor_voltage_for_thrust(t_need);
            let duty = (255.0 * v_need / q.battery_voltage()).round().clamp(0.0, 255.0) as u8;
            q.set_duty(MotorDuty([duty; 4]));
        }
        q.step(DT, room);
        if q.battery_voltage() < stop_below_v {
            return k as f32 * DT;
        }
    }
    seconds
}

#[test]
fn battery_drains_plausibly_over_a_minute_of_hover() {
    let room = big_room();
    let params = QuadParams::default();
    let mut q = Quadrotor::new(params, [5.0, 5.0, 1.0], 0.0);
    let t = params.hover_thrust_per_motor_n();
    q.set_motor_thrusts([t; 4]);
    hover_for(&mut q, &room, 60.0, 0.0);
    let used = q.battery().consumed_mah();
    let soc = q.battery().state_of_charge();
    println!(
        "60 s hover from full: {used:.1} mAh used ({:.1} % of 250 mAh, mean {:.2} A), SoC {:.1} %, \
         loaded {:.3} V, height {:.3} m",
        used / 2.5,
        used * 3.6 / 60.0,
        soc * 100.0,
        q.battery_voltage(),
        q.position()[2]
    );
    assert!((q.position()[2] - 1.0).abs() < 0.05);
    // 2.2–2.5 A for a minute: 37–42 mAh, i.e. 15–17 % of the battery.
    assert!((30.0..=50.0).contains(&used), "{used} mAh");
    assert!((1.0 - soc - used / 250.0).abs() < 1e-3);
}

#[test]
fn hover_endurance_estimate() {
    let room = big_room();
    let params = QuadParams::default();
    let mut q = Quadrotor::new(params, [5.0, 5.0, 1.0], 0.0);
    let t = params.hover_thrust_per_motor_n();
    q.set_motor_thrusts([t; 4]);
    let t_low = hover_for(&mut q, &room, 900.0, 3.2);
    let soc_low = q.battery().state_of_charge();
    let t_crit = t_low + hover_for(&mut q, &room, 900.0, 3.0);
    let soc_crit = q.battery().state_of_charge();
    println!(
        "hover endurance from full: loaded voltage < 3.2 V (stock low-battery level) after {:.0} s ({:.1} min, \
         SoC {:.0} %), < 3.0 V after {:.0} s ({:.1} min, SoC {:.0} %, height {:.2} m)",
        t_low,
        t_low / 60.0,
        soc_low * 100.0,
        t_crit,
        t_crit / 60.0,
        soc_crit * 100.0,
        q.position()[2]
    );
    // Bitcraze: ~7 min for a bare CF2.1; with 4 g of decks, 4.5–7 min is plausible.
    assert!((240.0..420.0).contains(&t_low), "{t_low}");
}

#[test]
fn fast_drain_knob_and_state_of_charge() {
    let room = big_room();
    let params = QuadParams::default();
    let mut q = Quadrotor::new(params, [5.0, 5.0, 1.0], 0.0);
    q.set_motor_thrusts([params.hover_thrust_per_motor_n(); 4]);
    q.battery_mut().set_drain_multiplier(20.0);
    hover_for(&mut q, &room, 10.0, 0.0);
    let soc = q.battery().state_of_charge();
    println!(
        "10 s hover with drain ×20: SoC {:.1} %, loaded {:.2} V",
        soc * 100.0,
        q.battery_voltage()
    );
    // ≈ 20 × 10 s × 2.3 A = 128 mAh ≈ 51 % of the battery.
    assert!((0.35..0.65).contains(&soc), "{soc}");
    // Starting low: below the stock low-battery threshold within seconds of hovering.
    let mut q = Quadrotor::new(params, [5.0, 5.0, 1.0], 0.0);
    q.battery_mut().set_state_of_charge(0.05);
    q.set_motor_thrusts([params.hover_thrust_per_motor_n(); 4]);
    let t = hover_for(&mut q, &room, 30.0, 3.2);
    assert!(t < 5.0, "{t}");
}

// -------------------------------------------------------------------------------------------------------------
// Sensors
// -------------------------------------------------------------------------------------------------------------

#[test]
fn imu_at_rest_reads_gravity_plus_bias_and_noise() {
    let room = big_room();
    let mut rng = SmallRng::seed_from_u64(7);
    let params = ImuParams::default();
    let mut imu = Imu::new(params, &mut rng);
    let mut q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.0], 0.3);
    q.place_on_surface(&room);
    let n = 4000;
    let (mut ma, mut mg, mut sa) = ([0.0f64; 3], [0.0f64; 3], [0.0f64; 3]);
    for _ in 0..n {
        q.step(DT, &room);
        let s = imu.sample(&q, &mut rng);
        for i in 0..3 {
            ma[i] += s.accel_m_s2[i] as f64 / n as f64;
            mg[i] += s.gyro_rad_s[i] as f64 / n as f64;
            sa[i] += (s.accel_m_s2[i] as f64).powi(2) / n as f64;
        }
    }
    let std_z = (sa[2] - ma[2] * ma[2]).sqrt();
    println!(
        "IMU at rest: accel mean {ma:.4?} (std z {std_z:.4}), gyro mean {mg:.4?}, bias {:?}",
        imu.accel_bias()
    );
    let expect = [0.0, 0.0, GRAVITY_M_S2 as f64];
    for i in 0..3 {
        assert!(
            (ma[i] - expect[i]).abs() < params.accel_bias_max_m_s2 as f64 * 2.0 + 0.01,
            "{ma:?}"
        );
        assert!((ma[i] - expect[i] - imu.accel_bias()[i] as f64).abs() < 0.02, "{ma:?}");
        assert!(mg[i].abs() < params.gyro_bias_max_rad_s as f64 * 2.0 + 0.002, "{mg:?}");
    }
    assert!((std_z - 0.04).abs() < 0.01, "{std_z}");
    // Ideal IMU: exactly the truth.
    let mut ideal = Imu::new(ImuParams::ideal(), &mut rng);
    let s = ideal.sample(&q, &mut rng);
    assert_eq!(s.accel_m_s2, q.specific_force());
    assert!((s.accel_m_s2[2] - GRAVITY_M_S2).abs() < 1e-4);
}

fn flow_expected(q: &Quadrotor, h: f32, dt: f32) -> [f32; 2] {
    // Independent of the model's code: body velocity with cfnav::types, R22 = cos φ cos θ.
    let att = q.attitude_rad();
    let vb = arena_to_body(q.velocity(), att);
    let r22 = att[0].cos() * att[1].cos();
    let w = q.rates();
    let k = dt * (35.0 / 0.71674) * 10.0;
    [k * (vb[0] * r22 / h - w[1]), k * (vb[1] * r22 / h + w[0])]
}

#[test]
fn flow_matches_the_stock_model_when_noise_free() {
    let room = big_room();
    let mut rng = SmallRng::seed_from_u64(1);
    let noise_free = FlowParams {
        noise_counts: 0.0,
        ..FlowParams::default()
    };
    // Pure forward velocity at height h.
    for (v, h) in [(0.5f32, 0.8f32), (1.5, 0.4), (-0.7, 1.2), (0.2, 3.5)] {
        let mut q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, h], 0.0);
        q.set_velocity([v, 0.0, 0.0]);
        let mut flow = FlowSensor::new(noise_free);
        let s = flow.sample(&q, &room, &mut rng).expect("reading");
        let model = 0.01 * (35.0 / 0.71674) * (v / h) * 10.0;
        println!(
            "flow: v {v} m/s at {h} m: dpixel_x {} (model {model:.3}), squal {}",
            s.dpixel_x, s.squal
        );
        assert!(s.motion_valid);
        assert_eq!(s.dt_s, 0.01);
        assert_eq!(s.dpixel_x, model.round() as i16);
        assert_eq!(s.dpixel_y, 0);
        assert!(s.squal >= 80);
    }
    // Tilted, turning, flying sideways, at a heading, over a pad.
    let room = big_room().with_pad(5.0, 5.0, 1.0, 0.2);
    let mut q = Quadrotor::new(QuadParams::default(), [5.1, 4.9, 0.9], 0.0);
    q.set_attitude_rad([0.1, -0.05, 0.7]);
    q.set_rates([0.3, -0.2, 0.1]);
    q.set_velocity([0.8, -1.1, 0.05]);
    let mut flow = FlowSensor::new(noise_free);
    let s = flow.sample(&q, &room, &mut rng).unwrap();
    let e = flow_expected(&q, 0.9 - 0.2, 0.01);
    println!("flow tilted: {:?} vs model {e:?}", (s.dpixel_x, s.dpixel_y));
    assert_eq!((s.dpixel_x, s.dpixel_y), (e[0].round() as i16, e[1].round() as i16));
    // dt comes from the truth's clock.
    run(&mut q, &room, 0.02);
    let s = flow.sample(&q, &room, &mut rng).unwrap();
    assert!((s.dt_s - 0.02).abs() < 1e-4, "{}", s.dt_s);
    // Fractions are carried, not lost: 100 readings sum to the model's sum within one count.
    let mut q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 1.0], 0.0);
    q.set_velocity([0.13, 0.0, 0.0]);
    let mut flow = FlowSensor::new(noise_free);
    let total: i32 = (0..100)
        .map(|_| flow.sample(&q, &big_room(), &mut rng).unwrap().dpixel_x as i32)
        .sum();
    let model = 100.0 * 0.01 * (35.0 / 0.71674) * 0.13 * 10.0;
    assert!((total as f32 - model).abs() <= 1.0, "{total} vs {model}");
}

#[test]
fn flow_invalid_when_too_low_too_high_dark_or_failed() {
    let room = Room::new([10.0, 10.0, 8.0]).with_pad(2.0, 2.0, 0.4, 0.1);
    let mut rng = SmallRng::seed_from_u64(2);
    let check_invalid = |s: Option<cfnav::types::FlowSample>| {
        let s = s.expect("a reading");
        assert!(
            !s.motion_valid && s.squal == 0 && s.dpixel_x == 0 && s.dpixel_y == 0,
            "{s:?}"
        );
    };
    let mut flow = FlowSensor::new(FlowParams::default());
    // 5 cm over the floor.
    let mut q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.05], 0.0);
    q.set_velocity([0.3, 0.0, 0.0]);
    check_invalid(flow.sample(&q, &room, &mut rng));
    // 9 cm over the floor is valid ...
    q.set_position([5.0, 5.0, 0.09]);
    assert!(flow.sample(&q, &room, &mut rng).unwrap().motion_valid);
    // ... but 15 cm above the floor is 5 cm above a 10 cm pad.
    q.set_position([2.0, 2.0, 0.15]);
    check_invalid(flow.sample(&q, &room, &mut rng));
    // Landed.
    let mut landed = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.0], 0.0);
    landed.place_on_surface(&room);
    check_invalid(flow.sample(&landed, &room, &mut rng));
    // Above 4 m.
    q.set_position([5.0, 5.0, 4.5]);
    check_invalid(flow.sample(&q, &room, &mut rng));
    // Dark world.
    q.set_position([5.0, 5.0, 1.0]);
    assert!(flow.sample(&q, &room, &mut rng).unwrap().motion_valid);
    flow.params_mut().dark = true;
    check_invalid(flow.sample(&q, &room, &mut rng));
    flow.params_mut().dark = false;
    // Deck failure at t = 0.5 s: readings stop, or become invalid.
    flow.inject_fault(Some((0.5, SensorFault::Stopped)));
    run(&mut q, &room, 0.4);
    assert!(flow.sample(&q, &room, &mut rng).is_some());
    run(&mut q, &room, 0.2);
    assert!(flow.sample(&q, &room, &mut rng).is_none());
    flow.inject_fault(Some((0.5, SensorFault::Invalid)));
    check_invalid(flow.sample(&q, &room, &mut rng));
    flow.inject_fault(None);
    assert!(
        flow.sample(&q, &room, &mut rng)
            .is_some_and(|s| s.motion_valid || q.position()[2] < 0.08)
    );
}

#[test]
fn zranger_over_a_pad_reads_height_minus_pad() {
    let room = Room::new([10.0, 10.0, 8.0]).with_pad(2.0, 2.0, 0.4, 0.1);
    let mut rng = SmallRng::seed_from_u64(3);
    let mut z = ZRanger::new(ZRangerParams::default());
    let mean = |z: &mut ZRanger, q: &Quadrotor, rng: &mut SmallRng| {
        let r: Vec<f32> = (0..400).filter_map(|_| z.sample(q, &room, rng)).collect();
        (r.iter().sum::<f32>() / r.len() as f32, 400 - r.len())
    };
    let mut q = Quadrotor::new(QuadParams::default(), [2.0, 2.0, 0.8], 0.0);
    let (m, invalid) = mean(&mut z, &q, &mut rng);
    println!("z-ranger over a 10 cm pad at 0.8 m: mean {m:.4} m, {invalid}/400 invalid");
    assert!((m - 0.7).abs() < 0.001, "{m}");
    assert!(invalid <= 10);
    q.set_position([5.0, 5.0, 0.8]);
    let (m, _) = mean(&mut z, &q, &mut rng);
    assert!((m - 0.8).abs() < 0.001, "{m}");
    // Tilted: the beam is longer.
    q.set_attitude_rad([0.2, 0.0, 0.0]);
    let (m, _) = mean(&mut z, &q, &mut rng);
    assert!((m - 0.8 / 0.2f32.cos()).abs() < 0.001, "{m}");
    // Beyond 4 m: nothing.
    q.set_attitude_rad([0.0; 3]);
    q.set_position([5.0, 5.0, 4.2]);
    assert!((0..100).all(|_| z.sample(&q, &room, &mut rng).is_none()));
    // Noise model: 2.5 mm at 2.5 m, 0.2 m at 4 m.
    assert!((zranger_noise_std_m(2.5) - 0.005).abs() < 1e-6);
    assert!((zranger_noise_std_m(4.0) - 0.2).abs() < 0.01);
    // Stuck fault repeats the last value.
    q.set_position([5.0, 5.0, 1.0]);
    let last = (0..10).filter_map(|_| z.sample(&q, &room, &mut rng)).last().unwrap();
    z.inject_fault(Some((0.0, SensorFault::Stuck)));
    q.set_position([5.0, 5.0, 2.0]);
    assert_eq!(z.sample(&q, &room, &mut rng), Some(last));
}

#[test]
fn multiranger_sees_walls_within_4_m_only() {
    let room = Room::new([10.0, 3.0, 2.5]);
    let mut rng = SmallRng::seed_from_u64(4);
    let mut mr = MultiRanger::new(MultiRangerParams {
        invalid_probability: 0.0,
        ..MultiRangerParams::default()
    });
    let q = Quadrotor::new(QuadParams::default(), [2.0, 1.2, 1.0], 0.0);
    let s = mr.sample(&q, &room, &mut rng);
    println!("multi-ranger at (2, 1.2, 1): {s:?}");
    assert_eq!(s.front_m, None, "the front wall is 8 m away");
    let close = |r: Option<f32>, d: f32| r.is_some_and(|r| (r - d).abs() < 0.01 * d * 4.0 + 0.012);
    assert!(close(s.back_m, 2.0));
    assert!(close(s.left_m, 1.8));
    assert!(close(s.right_m, 1.2));
    assert!(close(s.up_m, 1.5));
    // Turned left by 90°: front looks at +y (1.8 m), right at +x (8 m: none).
    let q = Quadrotor::new(QuadParams::default(), [2.0, 1.2, 1.0], std::f32::consts::FRAC_PI_2);
    let s = mr.sample(&q, &room, &mut rng);
    assert!(close(s.front_m, 1.8));
    assert!(close(s.back_m, 1.2));
    assert!(close(s.left_m, 2.0));
    assert_eq!(s.right_m, None);
    // Occasional invalid readings with the default parameters.
    let mut mr = MultiRanger::new(MultiRangerParams::default());
    let n_none = (0..2000)
        .filter(|_| mr.sample(&q, &room, &mut rng).front_m.is_none())
        .count();
    assert!((1..40).contains(&n_none), "{n_none}");
    // Faults: invalid and stuck.
    mr.inject_fault(Beam::Front, Some((0.0, SensorFault::Invalid)));
    assert_eq!(mr.sample(&q, &room, &mut rng).front_m, None);
    mr.inject_fault(Beam::Front, None);
    let last_back = (0..5)
        .filter_map(|_| mr.sample(&q, &room, &mut rng).back_m)
        .last()
        .unwrap();
    mr.inject_fault(Beam::Back, Some((0.0, SensorFault::Stuck)));
    let moved = Quadrotor::new(QuadParams::default(), [1.0, 1.0, 1.0], 0.0);
    assert_eq!(mr.sample(&moved, &room, &mut rng).back_m, Some(last_back));
}

/// A short flight with every sensor at its stock rate; returns everything it read.
fn scenario(seed: u64) -> Vec<f32> {
    let room = big_room().with_pad(5.0, 5.0, 0.3, 0.1);
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut imu = Imu::new(ImuParams::default(), &mut rng);
    let mut flow = FlowSensor::new(FlowParams::default());
    let mut z = ZRanger::new(ZRangerParams::default());
    let mut mr = MultiRanger::new(MultiRangerParams::default());
    let bat = BatterySensor::default();
    let mut q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.0], 0.2);
    q.place_on_surface(&room);
    let mut out = Vec::new();
    for k in 0..3000u32 {
        let d = if k < 1500 { 170 + (k % 7) as u8 } else { 150 };
        q.set_duty(MotorDuty([d, d + 1, d, d - 1]));
        q.step(DT, &room);
        let s = imu.sample(&q, &mut rng);
        out.extend(s.gyro_rad_s.iter().chain(&s.accel_m_s2));
        if k.is_multiple_of(10) {
            if let Some(f) = flow.sample(&q, &room, &mut rng) {
                out.extend([f.dpixel_x as f32, f.dpixel_y as f32, f.squal as f32]);
            }
            out.push(bat.sample(&q, &mut rng));
        }
        if k.is_multiple_of(25) {
            out.push(z.sample(&q, &room, &mut rng).unwrap_or(-1.0));
        }
        if k.is_multiple_of(100) {
            let m = mr.sample(&q, &room, &mut rng);
            out.extend([m.front_m, m.back_m, m.left_m, m.right_m, m.up_m].map(|r| r.unwrap_or(-1.0)));
        }
    }
    out.extend(q.position());
    out
}

#[test]
fn deterministic_for_a_seed() {
    let a = scenario(42);
    let b = scenario(42);
    let c = scenario(43);
    assert_eq!(a.len(), b.len());
    assert!(
        a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
        "same seed, same run"
    );
    assert_ne!(a, c, "another seed, another run");
}

#[test]
fn no_nan_for_garbage_inputs() {
    let room = big_room().with_pad(5.0, 5.0, 0.3, 0.1);
    let mut rng = SmallRng::seed_from_u64(9);
    let garbage_dt = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        -1.0,
        0.0,
        1e-12,
        f32::MIN_POSITIVE,
        0.001,
        0.0137,
        0.5,
        7.0,
        1e30,
    ];
    let weird = QuadParams {
        mass_kg: f32::NAN,
        motor_time_constant_s: 0.0,
        ..QuadParams::default()
    };
    for (params, geometry) in [
        (QuadParams::default(), &room as &dyn Geometry),
        (weird, &NanWorld as &dyn Geometry),
    ] {
        let mut q = Quadrotor::new(params, [5.0, 5.0, 1.0], f32::NAN);
        let mut imu = Imu::new(ImuParams::default(), &mut rng);
        let mut flow = FlowSensor::new(FlowParams::default());
        let mut z = ZRanger::new(ZRangerParams::default());
        let mut mr = MultiRanger::new(MultiRangerParams::default());
        for i in 0..3000usize {
            q.set_duty(MotorDuty(rng.random()));
            if i.is_multiple_of(97) {
                q.set_velocity([1e30, -1e25, f32::NAN]);
                q.set_rates([1e20, f32::INFINITY, -3.0]);
                q.set_attitude_rad([1e9, f32::NAN, 3.0]);
            }
            let dt = if i.is_multiple_of(3) {
                garbage_dt[i % garbage_dt.len()]
            } else {
                DT
            };
            q.step(dt, geometry);
            let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
            assert!(
                finite(&q.position()) && finite(&q.velocity()) && finite(&q.rates()),
                "step {i}"
            );
            assert!(finite(&q.attitude_rad()) && finite(&q.specific_force()) && finite(&q.motor_thrusts()));
            assert!(q.battery_voltage().is_finite() && q.battery().current().is_finite());
            let s = imu.sample(&q, &mut rng);
            assert!(finite(&s.gyro_rad_s) && finite(&s.accel_m_s2));
            if let Some(f) = flow.sample(&q, geometry, &mut rng) {
                assert!(f.dt_s.is_finite());
            }
            assert!(z.sample(&q, geometry, &mut rng).is_none_or(f32::is_finite));
            let m = mr.sample(&q, geometry, &mut rng);
            assert!(
                [m.front_m, m.back_m, m.left_m, m.right_m, m.up_m]
                    .iter()
                    .all(|r| r.is_none_or(f32::is_finite))
            );
        }
    }
}

#[test]
fn cost_of_90_s_of_physics_and_sensors() {
    let room = big_room().with_pad(5.0, 5.0, 0.3, 0.1);
    let mut rng = SmallRng::seed_from_u64(5);
    let mut imu = Imu::new(ImuParams::default(), &mut rng);
    let mut flow = FlowSensor::new(FlowParams::default());
    let mut z = ZRanger::new(ZRangerParams::default());
    let mut mr = MultiRanger::new(MultiRangerParams::default());
    let bat = BatterySensor::default();
    let params = QuadParams::default();
    let mut q = Quadrotor::new(params, [3.0, 3.0, 1.0], 0.0);
    q.set_motor_thrusts([params.hover_thrust_per_motor_n(); 4]);
    q.set_velocity([0.3, 0.1, 0.0]);
    let steps = 90_000u32;
    // Physics alone (a vertical hold updated at 100 Hz).
    let start = Instant::now();
    for k in 0..steps {
        if k.is_multiple_of(10) {
            let t_need = params.mass_kg / 4.0 * (GRAVITY_M_S2 + 4.0 * (1.0 - q.position()[2]) - 3.0 * q.velocity()[2]);
            let duty = (255.0 * params.motor_voltage_for_thrust(t_need) / q.battery_voltage()).clamp(0.0, 255.0);
            q.set_duty(MotorDuty([duty.round() as u8; 4]));
        }
        q.step(DT, &room);
    }
    let physics = start.elapsed().as_secs_f64();
    // All sensors at their stock rates, as many calls as in 90 s.
    let start = Instant::now();
    let mut acc = 0.0f32;
    for k in 0..steps {
        acc += imu.sample(&q, &mut rng).accel_m_s2[2];
        if k.is_multiple_of(10) {
            acc += flow.sample(&q, &room, &mut rng).map_or(0.0, |f| f.dpixel_x as f32);
            acc += bat.sample(&q, &mut rng);
        }
        if k.is_multiple_of(25) {
            acc += z.sample(&q, &room, &mut rng).unwrap_or(0.0);
        }
        if k.is_multiple_of(100) {
            acc += mr.sample(&q, &room, &mut rng).up_m.unwrap_or(0.0);
        }
    }
    let sensors = start.elapsed().as_secs_f64();
    println!(
        "90 s simulated, {} build: physics {:.1} ms ({:.0} ns/step), sensors at stock rates {:.1} ms; \
         together {:.0}× real time [{acc:.0}]",
        if cfg!(debug_assertions) { "dev" } else { "release" },
        physics * 1e3,
        physics * 1e9 / steps as f64,
        sensors * 1e3,
        90.0 / (physics + sensors),
    );
    assert!((q.position()[2] - 1.0).abs() < 0.05);
}

/// The cone model of the horizontal beams (`MultiRangerParams::cone_half_angle_rad`, off by default)
/// against plane geometry worked out by hand: a thin post beside the axis that the ray misses is seen
/// once two of the cone's rays reach it, a post only the cone's edge ray grazes is not (the partial-fill
/// rule), and a wall at 45° reads `D / cos(45° − 13.5°)` instead of the ray's `D / cos 45°`.
#[test]
fn multiranger_cone_sees_what_the_ray_misses_and_no_more() {
    let ray = MultiRangerParams {
        invalid_probability: 0.0,
        noise_relative: 0.0,
        noise_floor_m: 0.0,
        ..MultiRangerParams::default()
    };
    let cone = MultiRangerParams {
        cone_half_angle_rad: VL53L1X_HALF_FOV_RAD,
        ..ray
    };
    let mut rng = SmallRng::seed_from_u64(10);
    let at = [2.0, 1.5, 0.5];
    // A 0.16 m square post (a thin cylinder's size) whose centre lies 0.42 m ahead and `side` m to the
    // left; nothing else within 4 m ahead (the front wall is 8 m away).
    let post = |side: f32| {
        let (cx, cy) = (at[0] + 0.42, at[1] + side);
        let mut room = Room::new([10.0, 3.0, 2.5]);
        room.boxes
            .push(([cx - 0.08, cy - 0.08, 0.0], [cx + 0.08, cy + 0.08, 2.5]));
        room
    };
    let q = Quadrotor::new(QuadParams::default(), at, 0.0);
    // 0.15 m to the side: the post spans 8.0°–34.1° of bearing; the axis passes 7 cm beside it. The
    // cone's rays at 10.1° and 13.5° reach it: the near face (x = 0.34 m ahead) along 13.5°, 0.350 m.
    let room = post(0.15);
    assert_eq!(
        MultiRanger::new(ray).sample(&q, &room, &mut rng).front_m,
        None,
        "the ray passes beside the post"
    );
    let seen = MultiRanger::new(cone).sample(&q, &room, &mut rng).front_m;
    println!("post 0.15 m beside the axis: cone reads {seen:?}");
    assert!(
        seen.is_some_and(|d| (d - 0.34 / 13.5f32.to_radians().cos()).abs() < 0.005),
        "{seen:?}"
    );
    // 0.18 m to the side: it spans 11.3°–37.3°, only the edge ray (13.5°) touches it: too little of the
    // cone to be reported.
    let grazed = MultiRanger::new(cone).sample(&q, &post(0.18), &mut rng).front_m;
    assert_eq!(grazed, None, "a post only the cone's edge grazes");
    // 0.20 m to the side: 14.0°–41.2°, outside the cone altogether.
    assert_eq!(MultiRanger::new(cone).sample(&q, &post(0.20), &mut rng).front_m, None);

    // A wall at 45°: 1 m from the wall x = 10, turned 45° towards +y (the wall y = 3 lies 2.1 m along it).
    let room = Room::new([10.0, 3.0, 2.5]);
    let q = Quadrotor::new(QuadParams::default(), [9.0, 1.5, 0.5], std::f32::consts::FRAC_PI_4);
    let r = MultiRanger::new(ray).sample(&q, &room, &mut rng).front_m;
    let c = MultiRanger::new(cone).sample(&q, &room, &mut rng).front_m;
    println!("wall at 45°, 1 m: ray {r:?}, cone {c:?}");
    assert!(r.is_some_and(|d| (d - std::f32::consts::SQRT_2).abs() < 1e-3), "{r:?}");
    let nearest = 1.0 / (45f32 - 13.5).to_radians().cos();
    assert!(c.is_some_and(|d| (d - nearest).abs() < 1e-3), "{c:?} against {nearest}");
}
