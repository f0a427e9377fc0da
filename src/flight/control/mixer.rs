//! Power distribution: the legacy quadrotor mixer in cfnav's attitude convention, the stock capping, the
//! battery-voltage compensation and the 8-bit duty.
//!
//! Pipeline per motor (stock `power_distribution_quadrotor.c` + `motors.c`, `docs/hardware.md` §3):
//!
//! 1. **mix** the collective thrust `T` and the rate loops' torque commands `(roll, pitch, yaw)` (signed
//!    16-bit, cfnav convention: positive roll torque lowers the right side, positive pitch torque lowers
//!    the nose, positive yaw torque turns counter-clockwise seen from above), with `r = roll/2`,
//!    `p = pitch/2`:
//!
//!    | Motor (position)        | T | roll | pitch | yaw |
//!    |-------------------------|---|------|-------|-----|
//!    | M1 front-right, CCW prop | + | − r  | − p   | − y |
//!    | M2 back-right, CW prop   | + | − r  | + p   | + y |
//!    | M3 back-left, CCW prop   | + | + r  | + p   | − y |
//!    | M4 front-left, CW prop   | + | + r  | − p   | + y |
//!
//!    Derivation (body x forward, y left, z up; a motor at `(x, y)` pushing `f` up gives the torque
//!    `(y·f, −x·f, 0)`): roll `τx = Σ yᵢfᵢ` → raise the left motors M3/M4 (same as the stock table);
//!    pitch `τy = −Σ xᵢfᵢ` → raise the back motors M2/M3 (the stock table has the opposite sign because
//!    stock pitch is nose-up positive); yaw: a CCW prop's drag turns the body CW, so `τz = k·(f2 + f4 −
//!    f1 − f3)` → raise the CW motors M2/M4 (stock gets the same by negating its yaw output before the
//!    table).
//! 2. **capping** (stock): if a motor exceeds 65535 the excess is subtracted from all four, so roll and
//!    pitch keep their authority at the cost of collective thrust; then each is floored at 0 (idle thrust
//!    0, as on a CF2.1 without arming).
//! 3. **yaw headroom** (cfnav addition): yaw is added after roll/pitch and clamped to what keeps every
//!    motor inside 0..=65535, so a big yaw command never eats the collective (stock lets a saturated yaw
//!    pull two motors to 0 and the drone sinks). Priority: roll/pitch > thrust > yaw.
//! 4. **battery compensation, then the stock cap** (stock `stabilizer.c` `controlMotors`: mix →
//!    `batteryCompensation` per motor → `powerDistributionCap`): command `c` ↔ thrust
//!    `c/65535 · THRUST_MAX` N; below `THRUST_MIN` the motor is off; otherwise the motor voltage is the
//!    inverse of the cubic `thrust(V) = Σ VMOTOR2THRUSTᵢ·Vⁱ` and the ratio is `V_motor / V_bat`, **not
//!    clamped** per motor; then, if a ratio exceeds 1, the excess is subtracted from all four and each is
//!    floored at 0, so a sagging battery costs collective thrust, not the difference between the motors
//!    (clamping each motor at 1 would flatten two saturated motors to the same duty and lose the roll or
//!    pitch torque between them). Below [`BATTERY_COMP_MIN_V`] (a broken battery reading) every motor is
//!    **off**, as stock `motorsCompensateBatteryVoltage` (it returns 0 below 2.0 V). Before the first
//!    battery reading, or with compensation switched off in the controller's configuration, the ratio is
//!    the command ([`uncompensated`]).
//! 5. **duty** = `round(255 · ratio)`, clamped to 0..=255. (On the hardware the PWM period is 256 counts,
//!    so the true on-fraction is `duty/256`; the 0.4 % difference is inside the thrust fit's error.)
//!
//! Units: thrust commands in stock 16-bit counts, volts, newtons. Memory: none (pure functions).
//! Cost: the mix is ~30 flops; the inverse cubic is a safeguarded Newton iteration, ≤ 8 steps, usually 3.

use crate::types::MotorDuty;

/// Full-scale motor command.
pub const CMD_MAX: f32 = 65535.0;
/// Thrust of one motor at full command with battery compensation, N (CF2.1+ propellers).
pub const THRUST_MAX_N: f32 = 0.12;
/// Below this thrust a motor is switched off, N.
pub const THRUST_MIN_N: f32 = 0.012818;
/// Cubic fit `thrust(V) = c0 + c1·V + c2·V² + c3·V³` (N, V) of one motor with CF2.1+ propellers.
pub const VMOTOR2THRUST: [f32; 4] = [-0.024765, 0.065238, -0.026793, 0.0067768];
/// Yaw drag torque per newton of thrust, m.
pub const THRUST2TORQUE_M: f32 = 0.0069929;
/// Battery compensation is disabled below this (filtered) battery voltage, V.
pub const BATTERY_COMP_MIN_V: f32 = 2.0;

/// Yaw direction of each motor's drag torque on the body: +1 for the CW props (M2, M4) whose reaction
/// turns the body CCW (positive yaw), −1 for the CCW props (M1, M3).
pub const YAW_SIGN: [f32; 4] = [-1.0, 1.0, -1.0, 1.0];
/// Roll sign per motor (+1 = left side, raised by a positive roll torque).
pub const ROLL_SIGN: [f32; 4] = [-1.0, -1.0, 1.0, 1.0];
/// Pitch sign per motor (+1 = back, raised by a positive (nose-down) pitch torque).
pub const PITCH_SIGN: [f32; 4] = [-1.0, 1.0, 1.0, -1.0];

/// What the mixer did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Mix {
    /// Per-motor 16-bit commands, stock numbering M1..M4.
    pub cmd: [u16; 4],
    /// The capping removed collective thrust (a motor wanted more than 65535).
    pub capped: bool,
    /// A motor was floored at 0: part of the roll/pitch torque was not delivered.
    pub clipped_low: bool,
    /// The yaw command was reduced to fit (sign of the lost part: +1 wanted more, −1 wanted less).
    pub yaw_limited: i8,
}

/// Mix the collective `thrust` (counts, clamped to 0..=65535) with the torque commands (see the module
/// doc for the table). Non-finite thrust counts as 0.
pub fn mix(thrust: f32, roll: i16, pitch: i16, yaw: i16) -> Mix {
    let t = if thrust.is_finite() {
        thrust.clamp(0.0, CMD_MAX)
    } else {
        0.0
    };
    let r = f32::from(roll) / 2.0;
    let p = f32::from(pitch) / 2.0;
    let mut m = [0.0f32; 4];
    for ((mi, rs), ps) in m.iter_mut().zip(ROLL_SIGN).zip(PITCH_SIGN) {
        *mi = t + rs * r + ps * p;
    }
    // Stock capping.
    let max = m.iter().fold(f32::MIN, |a, &b| a.max(b));
    let capped = max > CMD_MAX;
    if capped {
        let excess = max - CMD_MAX;
        for mi in m.iter_mut() {
            *mi -= excess;
        }
    }
    let clipped_low = m.iter().any(|&v| v < 0.0);
    for mi in m.iter_mut() {
        *mi = mi.clamp(0.0, CMD_MAX);
    }
    // Yaw within the headroom of every motor: 0 ≤ mᵢ + sᵢ·y ≤ 65535.
    let (mut lo, mut hi) = (f32::MIN, f32::MAX);
    for (&mi, ys) in m.iter().zip(YAW_SIGN) {
        if ys > 0.0 {
            lo = lo.max(-mi);
            hi = hi.min(CMD_MAX - mi);
        } else {
            lo = lo.max(mi - CMD_MAX);
            hi = hi.min(mi);
        }
    }
    let want = f32::from(yaw);
    let y = if lo <= hi { want.clamp(lo, hi) } else { 0.0 };
    let yaw_limited = if want > y {
        1
    } else if want < y {
        -1
    } else {
        0
    };
    let mut cmd = [0u16; 4];
    for ((c, mi), ys) in cmd.iter_mut().zip(m).zip(YAW_SIGN) {
        *c = to_u16(libm::roundf(mi + ys * y));
    }
    Mix {
        cmd,
        capped,
        clipped_low,
        yaw_limited,
    }
}

/// One motor's thrust (N) at a motor voltage (V), from the cubic fit (may be negative near 0 V).
pub fn thrust_from_voltage(v: f32) -> f32 {
    let [c0, c1, c2, c3] = VMOTOR2THRUST;
    c0 + v * (c1 + v * (c2 + v * c3))
}

/// The motor voltage (V) that gives `thrust_n` according to the cubic fit. The fit is strictly increasing
/// (its derivative's discriminant is negative), so the inverse is unique; a safeguarded Newton iteration
/// inside [0, 8] V finds it to ~1e-5 V. Non-finite or non-positive thrust gives 0.
pub fn voltage_for_thrust(thrust_n: f32) -> f32 {
    if !(thrust_n.is_finite() && thrust_n > 0.0) {
        return 0.0;
    }
    let [_, c1, c2, c3] = VMOTOR2THRUST;
    let (mut lo, mut hi) = (0.0f32, 8.0f32);
    // A good start: the fit is nearly linear around hover.
    let mut v = (1.0 + (thrust_n - 0.02) / 0.03).clamp(0.1, 7.9);
    for _ in 0..8 {
        let f = thrust_from_voltage(v) - thrust_n;
        if f.abs() < 1e-7 {
            break;
        }
        if f > 0.0 {
            hi = v;
        } else {
            lo = v;
        }
        let df = c1 + v * (2.0 * c2 + 3.0 * c3 * v);
        let next = v - f / df;
        v = if next > lo && next < hi { next } else { 0.5 * (lo + hi) };
    }
    v
}

/// Stock `motorsCompensateBatteryVoltage` of one 16-bit command: the ratio of the battery voltage the
/// motor needs, **uncapped** (above 1 when the battery cannot give it). `vbat` is the filtered battery
/// voltage; below [`BATTERY_COMP_MIN_V`] (or non-finite) the motor is off (0), as stock.
pub fn compensated_ratio_uncapped(cmd: u16, vbat: f32) -> f32 {
    if cmd == 0 || !(vbat.is_finite() && vbat >= BATTERY_COMP_MIN_V) {
        return 0.0;
    }
    let thrust = f32::from(cmd) / CMD_MAX * THRUST_MAX_N;
    if thrust < THRUST_MIN_N {
        return 0.0;
    }
    voltage_for_thrust(thrust) / vbat
}

/// One motor alone: [`compensated_ratio_uncapped`] clamped to 0..=1 (what the motor gets when it is the
/// only one saturating; [`compensate`] caps the four together).
pub fn compensated_ratio(cmd: u16, vbat: f32) -> f32 {
    compensated_ratio_uncapped(cmd, vbat).clamp(0.0, 1.0)
}

/// A ratio (0..=1) as the stock 16-bit motor ratio.
pub fn ratio_to_u16(ratio: f32) -> u16 {
    to_u16(libm::roundf(ratio * CMD_MAX))
}

/// A ratio (0..=1) as the 8-bit duty: `round(255·ratio)`, clamped.
pub fn ratio_to_duty(ratio: f32) -> u8 {
    let d = libm::roundf(ratio * 255.0);
    if d.is_finite() { d.clamp(0.0, 255.0) as u8 } else { 0 }
}

/// Battery compensation and the stock cap for the four motors (module doc, step 4): `(ratios as u16,
/// duties)`. Below [`BATTERY_COMP_MIN_V`] every motor is off.
pub fn compensate(cmd: [u16; 4], vbat: f32) -> ([u16; 4], MotorDuty) {
    let mut ratio = cmd.map(|c| compensated_ratio_uncapped(c, vbat));
    let max = ratio.iter().fold(0.0f32, |a, &b| a.max(b));
    if max > 1.0 {
        let excess = max - 1.0;
        for r in ratio.iter_mut() {
            *r = (*r - excess).max(0.0);
        }
    }
    finish(ratio)
}

/// No battery compensation (switched off, or no battery reading yet): the ratio is the command.
pub fn uncompensated(cmd: [u16; 4]) -> ([u16; 4], MotorDuty) {
    finish(cmd.map(|c| f32::from(c) / CMD_MAX))
}

fn finish(ratio: [f32; 4]) -> ([u16; 4], MotorDuty) {
    let r = ratio.map(|r| r.clamp(0.0, 1.0));
    (r.map(ratio_to_u16), MotorDuty(r.map(ratio_to_duty)))
}

fn to_u16(x: f32) -> u16 {
    if x.is_finite() { x.clamp(0.0, CMD_MAX) as u16 } else { 0 }
}
