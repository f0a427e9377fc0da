//! The simulated Crazyflie 2.1 (+ Flow deck v2 + Multi-ranger deck): rigid body, brushed motors, battery and
//! ground contact, stepped at 1 kHz by the runner.
//!
//! Conventions are exactly those of `cfnav::types`: arena frame x right / y up the page / z up, body frame
//! x forward / y left / z up, attitude `R = Rz(ψ)·Ry(θ)·Rx(φ)` (body → arena) with the right-hand rule, so
//! positive pitch lowers the nose and positive roll lowers the right side. The state keeps the attitude as a
//! unit quaternion (`[w, x, y, z]`, body → arena) and derives roll/pitch/yaw only when asked.
//!
//! # Motors and the signs of their torques
//!
//! Motor `i` sits at body `(x_i, y_i, 0)` and pushes `T_i` along body +z. Its torque on the body is
//! `r_i × F_i = (y_i·T_i, −x_i·T_i, 0)` plus the propeller's reaction (drag) torque about z,
//! `∓ THRUST2TORQUE·T_i`: a propeller spinning counter-clockwise seen from above drags the body clockwise
//! (negative yaw torque), and vice versa (docs/hardware.md §3; the stock mixers agree: the legacy
//! mixer adds `+yaw` to M1/M3 after the PID negated it, the force/torque mixer subtracts `τz/(4k)` from
//! M1/M3). With the stock layout (positions ±0.031 m, [SIM] model.sdf):
//!
//! | motor | position (x, y) | prop spin (from above) | roll torque τx | pitch torque τy | yaw torque τz |
//! |-------|-----------------|------------------------|----------------|-----------------|---------------|
//! | M1 front-right | (+0.031, −0.031) | CCW | − | − (nose up) | − (CW) |
//! | M2 back-right  | (−0.031, −0.031) | CW  | − | + (nose down) | + (CCW) |
//! | M3 back-left   | (−0.031, +0.031) | CCW | + | + (nose down) | − (CW) |
//! | M4 front-left  | (+0.031, +0.031) | CW  | + | − (nose up) | + (CCW) |
//!
//! So: left motors (M3+M4) stronger → positive roll → right side down → the drone accelerates right (−y);
//! back motors (M2+M3) stronger → positive pitch → nose down → it accelerates forward (+x);
//! CW-spinning props (M2+M4) stronger → positive yaw (counter-clockwise seen from above).
//!
//! # Model (per step, `dt` ≤ 1 ms; larger steps are split)
//!
//! 1. Motor voltage `V_m = duty/255 · V_bat` (loaded battery voltage of the previous step); steady thrust
//!    `T_ss = max(0, c0 + c1·V_m + c2·V_m² + c3·V_m³)` (the stock CF2.1+ fit); first-order lag
//!    `T += (T_ss − T)·(1 − e^(−dt/τ))`, same τ up and down.
//! 2. Battery: electrical power `Σ (k_P·T_i + P_idle)` plus the electronics' constant current, drawn from an
//!    OCV(SoC) source with an ohmic resistance R0 and one polarisation RC branch; the loaded voltage solves
//!    `V = E − R0·(P/V + I_e)` in closed form.
//! 3. Forces: thrust `Σ T_i` along body z (times a Cheeseman–Bennett ground-effect factor near the surface),
//!    rotor drag `−K·s·v_b` with `s` the mean of `√(T_i/T_hover)` (Förster's drag model: proportional to the
//!    sum of rotor speeds, so it vanishes with the motors off), quadratic body drag `−c·|v_b|·v_b`, gravity;
//!    `v_b` is the body-frame velocity relative to the air (wind and gusts: [`Quadrotor::set_air_velocity`]).
//! 4. Translation: `p += v·dt + ½·a·dt²; v += a·dt` (exact under constant acceleration, so free fall lands on
//!    time); rotation: `ω += I⁻¹(τ − ω×Iω)·dt`, `q += ½·q⊗(0,ω)·dt`, renormalised.
//! 5. Contact with the surface under the drone ([`Geometry::surface_height`]): when the body's bottom
//!    (`bottom_offset_m` below the body origin) reaches it, the vertical velocity is zeroed (no bounce) and the
//!    drone *rests*: while the thrust cannot lift it, the normal force cancels the vertical acceleration,
//!    Coulomb friction (μ = 0.6) stops horizontal sliding, and the attitude is levelled with a 50 ms time
//!    constant (the legs force it flat; the body rates are set to the levelling rates, so the gyro stays
//!    consistent). Surfaces more than 2 cm above the bottom are side obstacles, not support: flying into a
//!    pad's or a box's side does not lift the drone onto it (the runner detects that collision with the
//!    world's clearance); it keeps resting on / falling to the last surface it was over.
//! 6. Walls: if the geometry reports [`Geometry::bounds`], the body origin is clamped inside them and the
//!    velocity into the wall is zeroed (no bounce). Obstacles are not modelled physically.
//!
//! Everything is allocation-free; a step costs a few hundred flops plus one `surface_height` query.

use cfnav::math::{cross3, euler_from_rot, finite_or, mul_m3_v3, mul_m3t_v3, quat_from_euler, quat_mul, quat_to_rot};
use cfnav::types::{GRAVITY_M_S2, MotorDuty};

/// What the physics and the sensors need to know about the world. `sim::world` implements it for worlds; tests
/// use small hand-made geometries.
pub trait Geometry {
    /// Distance along the unit vector `dir` from `origin` to the first surface hit, if it is within
    /// `max_range_m` (arena frame, metres).
    fn ray_cast(&self, origin: [f32; 3], dir: [f32; 3], max_range_m: f32) -> Option<f32>;
    /// Height of the highest surface at `(x, y)` that something could rest on: 0 over the floor, the top of a
    /// pad or box over it (metres above the arena floor).
    fn surface_height(&self, x: f32, y: f32) -> f32;
    /// Where the body origin may be at all (arena walls and ceiling), as (min corner, max corner); `None` (the
    /// default) for unbounded.
    fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        None
    }
    /// The floor under `(x, y)` as the flow sensor reads it, if it is a poor patch: its SQUAL (in place of
    /// the height model's) and the probability that a reading is invalid there. `None` (the default): the
    /// sensor's own model.
    fn flow_floor(&self, _x: f32, _y: f32) -> Option<(Option<u8>, Option<f32>)> {
        None
    }
}

/// The battery: a 1S LiPo behind the Crazyflie's power path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatteryParams {
    /// Capacity, mAh. Stock CF2.1 battery: 250 mAh 1S LiPo.
    pub capacity_mah: f32,
    /// Open-circuit voltage at state of charge 0 %, 10 %, …, 100 %, V. 0–90 %: the stock firmware's LiPo
    /// table (pm_stm32f4.c, docs/hardware.md §3); 100 %: 4.20 V, a full LiPo's charge voltage.
    pub ocv_table_v: [f32; 11],
    /// Ohmic resistance of the cell, connector, traces and MOSFETs, Ω.
    pub r0_ohm: f32,
    /// Polarisation resistance (the slow part of the sag and of the recovery), Ω.
    pub r1_ohm: f32,
    /// Polarisation time constant, s.
    pub tau1_s: f32,
    /// Current of everything but the motors (MCUs, radio, LEDs, decks), A.
    pub electronics_current_a: f32,
    /// Electrical power per newton of thrust of one motor, W/N.
    pub motor_power_w_per_n: f32,
    /// Extra electrical power of a motor whenever its duty is non-zero, W.
    pub motor_idle_power_w: f32,
    /// State of charge at power-on, 0..=1.
    pub initial_state_of_charge: f32,
}

impl Default for BatteryParams {
    /// A healthy stock 250 mAh battery.
    ///
    /// - Resistances: R0 0.17 Ω + R1 0.08 Ω (τ 15 s) = 0.25 Ω in steady state. Bitcraze's CF2.0 thrust-stand
    ///   table (bitcraze.io "PWM to Thrust", 2015) shows 0.36 V drop for 2.15 A on a bench supply
    ///   (≈ 0.17 Ω of supply leads, connector and board); a small 1S cell adds ~0.1 Ω. The split into an
    ///   instant and a slow part is a modelling choice (a LiPo recovers over tens of seconds).
    /// - Power: the same table gives electrical power ≈ 0.2356 W per gram of thrust + 0.133 W for four
    ///   running motors (fit over 4.8–37.3 g; current minus the 0.24 A idle draw, times the logged
    ///   voltage): 24.0 W/N per motor and 0.033 W idle per motor. At hover (31 g) that is ≈ 7.5 W, i.e.
    ///   ≈ 2.0 A of motor current at the loaded ~3.7 V, ≈ 2.3 A in total — not the 3.5–4 A sometimes quoted,
    ///   which would empty 250 mAh in ~4 min; Bitcraze specifies ~7 min for a bare CF2.1 (≈ 2.1 A average).
    /// - Electronics: 0.24 A measured at zero thrust on the stand (CF2.0, incl. LEDs and radio), + ~0.06 A for
    ///   the Flow deck (PMW3901 + VL53L1x) and the Multi-ranger (5 × VL53L1x, stop/start ranging).
    fn default() -> Self {
        Self {
            capacity_mah: 250.0,
            ocv_table_v: [3.00, 3.78, 3.83, 3.87, 3.89, 3.92, 3.96, 4.00, 4.04, 4.10, 4.20],
            r0_ohm: 0.17,
            r1_ohm: 0.08,
            tau1_s: 15.0,
            electronics_current_a: 0.30,
            motor_power_w_per_n: 24.0,
            motor_idle_power_w: 0.033,
            initial_state_of_charge: 1.0,
        }
    }
}

/// The battery's state: charge, polarisation, loaded voltage and current.
#[derive(Clone, Debug, PartialEq)]
pub struct Battery {
    params: BatteryParams,
    soc: f32,
    v_rc: f32,
    voltage_v: f32,
    current_a: f32,
    drain_multiplier: f32,
    supply_v: Option<f32>,
    consumed_mah: f32,
}

impl Battery {
    /// A battery at `params.initial_state_of_charge`, at rest with only the electronics drawing current.
    pub fn new(params: BatteryParams) -> Self {
        let mut params = params;
        params.capacity_mah = finite_or(params.capacity_mah, 250.0).max(1.0);
        params.r0_ohm = finite_or(params.r0_ohm, 0.17).max(0.0);
        params.r1_ohm = finite_or(params.r1_ohm, 0.08).max(0.0);
        params.tau1_s = finite_or(params.tau1_s, 15.0).max(1e-3);
        params.electronics_current_a = finite_or(params.electronics_current_a, 0.3).max(0.0);
        params.motor_power_w_per_n = finite_or(params.motor_power_w_per_n, 24.0).max(0.0);
        params.motor_idle_power_w = finite_or(params.motor_idle_power_w, 0.0).max(0.0);
        for v in &mut params.ocv_table_v {
            *v = finite_or(*v, 3.7).clamp(0.5, 5.0);
        }
        let mut b = Self {
            params,
            soc: 1.0,
            v_rc: 0.0,
            voltage_v: 0.0,
            current_a: 0.0,
            drain_multiplier: 1.0,
            supply_v: None,
            consumed_mah: 0.0,
        };
        b.set_state_of_charge(params.initial_state_of_charge);
        b
    }

    /// The parameters.
    pub fn params(&self) -> &BatteryParams {
        &self.params
    }

    /// Sets the state of charge (0..=1) and puts the cell at rest (electronics load only).
    pub fn set_state_of_charge(&mut self, soc: f32) {
        self.soc = finite_or(soc, 1.0).clamp(0.0, 1.0);
        let ie = self.params.electronics_current_a;
        self.v_rc = ie * self.params.r1_ohm;
        self.current_a = ie;
        self.voltage_v = self.solve_voltage(0.0).0;
    }

    /// State of charge, 0..=1.
    pub fn state_of_charge(&self) -> f32 {
        self.soc
    }

    /// Charge drawn since power-on (or the last [`Battery::set_state_of_charge`]), mAh (without the drain
    /// multiplier).
    pub fn consumed_mah(&self) -> f32 {
        self.consumed_mah
    }

    /// Drains the charge `k` times faster than the current drawn (≥ 0; 1 = physical): the "battery low
    /// mid-flight" scenario without simulating minutes of flight.
    pub fn set_drain_multiplier(&mut self, k: f32) {
        self.drain_multiplier = finite_or(k, 1.0).max(0.0);
    }

    /// Replaces the battery by an ideal supply of `v` volts (a bench supply: no sag, no drain), or back to
    /// the battery with `None`.
    pub fn set_supply(&mut self, v: Option<f32>) {
        self.supply_v = v.filter(|v| v.is_finite()).map(|v| v.clamp(0.0, 10.0));
        if let Some(v) = self.supply_v {
            self.voltage_v = v;
        } else {
            self.voltage_v = self.solve_voltage(0.0).0;
        }
    }

    /// Loaded terminal voltage (what the nRF measures), V.
    pub fn voltage(&self) -> f32 {
        self.voltage_v
    }

    /// Total current drawn, A.
    pub fn current(&self) -> f32 {
        self.current_a
    }

    /// Open-circuit voltage at the present state of charge, V.
    pub fn open_circuit_voltage(&self) -> f32 {
        let t = &self.params.ocv_table_v;
        let x = self.soc.clamp(0.0, 1.0) * 10.0;
        let i = (x as usize).min(9);
        let f = x - i as f32;
        t[i] + (t[i + 1] - t[i]) * f
    }

    /// Loaded voltage and current for `motor_power_w` at the present state (no state change).
    fn solve_voltage(&self, motor_power_w: f32) -> (f32, f32) {
        let ie = self.params.electronics_current_a;
        if let Some(v) = self.supply_v {
            let i = if v > 0.1 { motor_power_w / v + ie } else { ie };
            return (v, i);
        }
        let r0 = self.params.r0_ohm;
        let e = self.open_circuit_voltage() - self.v_rc - r0 * ie;
        let p = motor_power_w.max(0.0);
        // V = E' − R0·P/V  →  V² − E'·V + R0·P = 0, the upper root; past the maximum-power point the
        // voltage collapses to E'/2.
        let disc = e * e - 4.0 * r0 * p;
        let v = if disc > 0.0 { 0.5 * (e + disc.sqrt()) } else { 0.5 * e }.max(0.0);
        let i = if v > 0.05 { p / v + ie } else { ie };
        (v, i)
    }

    /// Advances the battery by `dt_s` with the motors drawing `motor_power_w`.
    pub fn step(&mut self, dt_s: f32, motor_power_w: f32) {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return;
        }
        let p = finite_or(motor_power_w, 0.0).max(0.0);
        let (v, i) = self.solve_voltage(p);
        self.voltage_v = v;
        self.current_a = i;
        if self.supply_v.is_some() {
            return;
        }
        let mah = i * dt_s / 3.6;
        self.consumed_mah += mah;
        self.soc = (self.soc - mah * self.drain_multiplier / self.params.capacity_mah).max(0.0);
        let a = (dt_s / self.params.tau1_s).min(1.0);
        self.v_rc += (i * self.params.r1_ohm - self.v_rc) * a;
    }
}

/// The quadrotor's physical parameters. [`Default`] is a Crazyflie 2.1 with the stock CF2.1+ propellers, a
/// Flow deck v2 and a Multi-ranger deck.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadParams {
    /// Total mass, kg. Default 0.031: CF2.1 27 g (Bitcraze datasheet, with battery) + Flow deck v2 1.6 g +
    /// Multi-ranger 2.3 g (Bitcraze deck datasheets) = 30.9 g.
    pub mass_kg: f32,
    /// Principal moments of inertia about body x, y, z, kg·m². Default: Förster 2015, "System Identification
    /// of the Crazyflie 2.0 Nano Quadrocopter" (ETH BSc thesis), diagonal 16.57, 16.66, 29.26 × 10⁻⁶
    /// (off-diagonals < 2 × 10⁻⁶ neglected; the decks, near the centre, add a few % that are neglected too).
    pub inertia_kg_m2: [f32; 3],
    /// Motor positions (body x, y), m, in the order M1..M4. Default (±0.031, ±0.031) ([SIM] model.sdf,
    /// docs/hardware.md §3).
    pub motor_positions_m: [[f32; 2]; 4],
    /// Sign of each motor's reaction yaw torque per unit thrust: −1 for a prop spinning CCW seen from above
    /// (M1, M3), +1 for CW (M2, M4).
    pub motor_yaw_sign: [f32; 4],
    /// Steady thrust per motor (N) from motor voltage (V): `c0 + c1·V + c2·V² + c3·V³`, clamped ≥ 0. Default:
    /// the stock CF2.1+ `VMOTOR2THRUST0..3` (platform_defaults_cf2.h).
    pub thrust_fit: [f32; 4],
    /// Per-motor thrust multiplier (1 = nominal; < 1 models a weak motor or a chipped prop).
    pub motor_thrust_scale: [f32; 4],
    /// Reaction torque per newton of thrust, m. Default: stock `THRUST2TORQUE` 0.0069929.
    pub thrust_to_torque_m: f32,
    /// First-order motor (thrust) time constant, s. Default 0.03: Bitcraze's CF2.0 RPM step (0 → 25 krpm in
    /// ≈ 180 ms, a full-voltage large-signal step, ≈ 3–5 τ of the speed) puts the speed time constant at
    /// 40–60 ms; thrust ∝ speed², so small steps around hover settle about twice as fast: ≈ 30 ms.
    pub motor_time_constant_s: f32,
    /// Rotor drag at hover thrust, N per (m/s) of body-frame velocity, (x, y, z); scaled by the mean of
    /// `√(T_i/T_hover)` (∝ rotor speed). Default: Förster 2015's `K = diag(10.2, 10.2, 7.1) × 10⁻⁷ kg/rad`
    /// times the sum of the four rotor speeds at hover (≈ 4 × 1870 rad/s for 31 g, from Bitcraze's
    /// 17 krpm at 28.6 g, speed ∝ √thrust): (0.0076, 0.0076, 0.0053).
    pub rotor_drag_n_s_m: [f32; 3],
    /// Quadratic (parasitic) body drag `½·ρ·Cd·A`, N per (m/s)², body (x, y, z). Default: Cd ≈ 1.2, side area
    /// ≈ 1.2 × 10⁻³ m², top area ≈ 3 × 10⁻³ m² (PCB, battery, decks): (0.0009, 0.0009, 0.0022).
    pub body_drag_n_s2_m2: [f32; 3],
    /// Propeller radius for the ground effect, m (0 disables it). Default 0.0225 (45 mm props).
    pub rotor_radius_m: f32,
    /// Height of the body origin above the body's lowest point (the motor-mount legs / Flow deck) when level,
    /// m. The sensors sit at the body origin, so a landed drone's z-ranger reads about this.
    pub bottom_offset_m: f32,
    /// Coulomb friction coefficient between the legs and the surface.
    pub friction_coefficient: f32,
    /// The battery.
    pub battery: BatteryParams,
}

impl Default for QuadParams {
    fn default() -> Self {
        let a = 0.031;
        Self {
            mass_kg: 0.031,
            inertia_kg_m2: [16.571_71e-6, 16.655_602e-6, 29.261_652e-6],
            motor_positions_m: [[a, -a], [-a, -a], [-a, a], [a, a]],
            motor_yaw_sign: [-1.0, 1.0, -1.0, 1.0],
            thrust_fit: [-0.024_765, 0.065_238, -0.026_793, 0.006_776_8],
            motor_thrust_scale: [1.0; 4],
            thrust_to_torque_m: 0.006_992_9,
            motor_time_constant_s: 0.03,
            rotor_drag_n_s_m: [0.0076, 0.0076, 0.0053],
            body_drag_n_s2_m2: [0.0009, 0.0009, 0.0022],
            rotor_radius_m: 0.0225,
            bottom_offset_m: 0.015,
            friction_coefficient: 0.6,
            battery: BatteryParams::default(),
        }
    }
}

impl QuadParams {
    /// Steady thrust of one (nominal) motor at motor voltage `v`, N (≥ 0).
    pub fn thrust_from_motor_voltage(&self, v: f32) -> f32 {
        let [c0, c1, c2, c3] = self.thrust_fit;
        let v = finite_or(v, 0.0).max(0.0);
        (c0 + v * (c1 + v * (c2 + v * c3))).max(0.0)
    }

    /// Motor voltage that gives `thrust_n` steady thrust on a nominal motor (inverse of
    /// [`QuadParams::thrust_from_motor_voltage`], by bisection over 0..=10 V).
    pub fn motor_voltage_for_thrust(&self, thrust_n: f32) -> f32 {
        let t = finite_or(thrust_n, 0.0);
        if t <= 0.0 {
            return 0.0;
        }
        let (mut lo, mut hi) = (0.0f32, 10.0f32);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if self.thrust_from_motor_voltage(mid) < t {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Thrust per motor that balances the weight, N.
    pub fn hover_thrust_per_motor_n(&self) -> f32 {
        self.mass_kg * GRAVITY_M_S2 / 4.0
    }

    fn sanitised(mut self) -> Self {
        let d = Self::default();
        self.mass_kg = finite_or(self.mass_kg, d.mass_kg).max(1e-3);
        for i in 0..3 {
            self.inertia_kg_m2[i] = finite_or(self.inertia_kg_m2[i], d.inertia_kg_m2[i]).max(1e-9);
            self.rotor_drag_n_s_m[i] = finite_or(self.rotor_drag_n_s_m[i], 0.0).max(0.0);
            self.body_drag_n_s2_m2[i] = finite_or(self.body_drag_n_s2_m2[i], 0.0).max(0.0);
        }
        for i in 0..4 {
            for j in 0..2 {
                self.motor_positions_m[i][j] = finite_or(self.motor_positions_m[i][j], d.motor_positions_m[i][j]);
            }
            self.motor_yaw_sign[i] = finite_or(self.motor_yaw_sign[i], d.motor_yaw_sign[i]);
            self.thrust_fit[i] = finite_or(self.thrust_fit[i], d.thrust_fit[i]);
            self.motor_thrust_scale[i] = finite_or(self.motor_thrust_scale[i], 1.0).max(0.0);
        }
        self.thrust_to_torque_m = finite_or(self.thrust_to_torque_m, d.thrust_to_torque_m);
        self.motor_time_constant_s = finite_or(self.motor_time_constant_s, d.motor_time_constant_s).max(1e-4);
        self.rotor_radius_m = finite_or(self.rotor_radius_m, 0.0).max(0.0);
        self.bottom_offset_m = finite_or(self.bottom_offset_m, d.bottom_offset_m).max(0.0);
        self.friction_coefficient = finite_or(self.friction_coefficient, d.friction_coefficient).max(0.0);
        self
    }
}

/// The last touchdown: when and how hard the drone met a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Touchdown {
    /// Simulated time of the contact (interpolated inside the step), s.
    pub time_s: f64,
    /// Vertical speed at contact (positive = downwards), m/s.
    pub vertical_speed_m_s: f32,
    /// Horizontal speed at contact, m/s.
    pub horizontal_speed_m_s: f32,
    /// Height of the surface touched above the arena floor, m (0 = floor, else a pad's or box's top).
    pub surface_height_m: f32,
}

/// Larger steps are split into substeps of at most this (s).
pub const MAX_SUBSTEP_S: f32 = 0.001;
/// Longest step accepted (s); longer ones are clamped.
pub const MAX_STEP_S: f32 = 1.0;
/// A surface up to this far above the body's bottom still counts as support (m); higher ones are sides.
const SUPPORT_STEP_M: f32 = 0.02;
/// Levelling time constant of a resting drone, s.
const LEVEL_TAU_S: f32 = 0.05;

/// The simulated quadrotor (truth).
#[derive(Clone, Debug)]
pub struct Quadrotor {
    params: QuadParams,
    inv_inertia: [f32; 3],
    inv_hover_thrust: f32,
    time_s: f64,
    position: [f32; 3],
    velocity: [f32; 3],
    /// Body → arena, `[w, x, y, z]`.
    q: [f32; 4],
    /// Cached rotation matrix of `q`.
    rot: [[f32; 3]; 3],
    rates: [f32; 3],
    thrusts: [f32; 4],
    duty: MotorDuty,
    specific_force: [f32; 3],
    battery: Battery,
    resting: bool,
    support_height: f32,
    touchdown: Option<Touchdown>,
    alpha_dt: f32,
    motor_alpha: f32,
    /// Velocity of the air, arena frame, m/s: drag acts on the velocity relative to it.
    air_velocity: [f32; 3],
}

impl Quadrotor {
    /// A drone at `position_m` (body origin, arena frame) with heading `yaw_rad`, level, at rest in the air
    /// (call [`Quadrotor::place_on_surface`] to start landed), motors off.
    pub fn new(params: QuadParams, position_m: [f32; 3], yaw_rad: f32) -> Self {
        let params = params.sanitised();
        let yaw = finite_or(yaw_rad, 0.0);
        let q = [(0.5 * yaw).cos(), 0.0, 0.0, (0.5 * yaw).sin()];
        let position = position_m.map(|v| finite_or(v, 0.0));
        Self {
            inv_inertia: params.inertia_kg_m2.map(|i| 1.0 / i),
            inv_hover_thrust: 1.0 / params.hover_thrust_per_motor_n(),
            time_s: 0.0,
            position,
            velocity: [0.0; 3],
            q,
            rot: quat_to_rot(q),
            rates: [0.0; 3],
            thrusts: [0.0; 4],
            duty: MotorDuty([0; 4]),
            specific_force: [0.0, 0.0, GRAVITY_M_S2],
            battery: Battery::new(params.battery),
            resting: false,
            support_height: 0.0,
            touchdown: None,
            alpha_dt: -1.0,
            motor_alpha: 0.0,
            air_velocity: [0.0; 3],
            params,
        }
    }

    /// Puts the drone down, level, on the surface under it (the start of a mission).
    pub fn place_on_surface<G: Geometry + ?Sized>(&mut self, geometry: &G) {
        let s = finite_or(geometry.surface_height(self.position[0], self.position[1]), 0.0);
        self.support_height = s;
        self.position[2] = s + self.params.bottom_offset_m;
        self.velocity = [0.0; 3];
        self.rates = [0.0; 3];
        let yaw = self.yaw();
        self.q = [(0.5 * yaw).cos(), 0.0, 0.0, (0.5 * yaw).sin()];
        self.rot = quat_to_rot(self.q);
        self.specific_force = [0.0, 0.0, GRAVITY_M_S2];
        self.resting = true;
    }

    /// The parameters in use (sanitised).
    pub fn params(&self) -> &QuadParams {
        &self.params
    }

    /// Sets the motor duties (held until changed), as the firmware writes TIM2/TIM4.
    pub fn set_duty(&mut self, duty: MotorDuty) {
        self.duty = duty;
    }

    /// The duties last set.
    pub fn duty(&self) -> MotorDuty {
        self.duty
    }

    /// Advances the simulation by `dt_s` (split into ≤ 1 ms substeps; non-finite or non-positive steps are
    /// ignored, steps longer than 1 s are clamped to 1 s).
    pub fn step<G: Geometry + ?Sized>(&mut self, dt_s: f32, geometry: &G) {
        if !(dt_s > 0.0 && dt_s.is_finite()) {
            return;
        }
        let dt = dt_s.min(MAX_STEP_S);
        let n = (dt / MAX_SUBSTEP_S - 1e-3).ceil().max(1.0) as u32;
        let h = dt / n as f32;
        for _ in 0..n {
            self.substep(h, geometry);
        }
    }

    fn substep<G: Geometry + ?Sized>(&mut self, h: f32, geometry: &G) {
        let p = &self.params;
        if h != self.alpha_dt {
            self.alpha_dt = h;
            self.motor_alpha = 1.0 - (-h / p.motor_time_constant_s).exp();
        }
        let saved = (self.position, self.velocity, self.q, self.rates, self.thrusts);

        // 1. Motors.
        let v_bat = self.battery.voltage();
        let mut motor_power = 0.0;
        for i in 0..4 {
            let d = self.duty.0[i];
            let v_m = d as f32 * (1.0 / 255.0) * v_bat;
            let t_ss = p.thrust_from_motor_voltage(v_m) * p.motor_thrust_scale[i];
            self.thrusts[i] += (t_ss - self.thrusts[i]) * self.motor_alpha;
            if d > 0 {
                motor_power += p.battery.motor_power_w_per_n * self.thrusts[i] + p.battery.motor_idle_power_w;
            }
        }
        // 2. Battery.
        self.battery.step(h, motor_power);

        // 3. The surface under the drone.
        let bottom_prev = self.position[2] - p.bottom_offset_m;
        let s = geometry.surface_height(self.position[0], self.position[1]);
        if s.is_finite() && s <= bottom_prev + SUPPORT_STEP_M {
            self.support_height = s;
        }
        let support = self.support_height;
        if self.resting && bottom_prev > support + 1e-4 {
            self.resting = false;
        }

        // 4. Forces.
        let r = self.rot;
        let ge = if p.rotor_radius_m > 0.0 {
            let hr = (self.position[2] - support + p.bottom_offset_m).max(0.5 * p.rotor_radius_m);
            let k = p.rotor_radius_m / (4.0 * hr);
            1.0 / (1.0 - k * k)
        } else {
            1.0
        };
        let t = [
            self.thrusts[0] * ge,
            self.thrusts[1] * ge,
            self.thrusts[2] * ge,
            self.thrusts[3] * ge,
        ];
        let t_total = t[0] + t[1] + t[2] + t[3];
        // Drag acts on the velocity relative to the air (wind and gusts, `set_air_velocity`).
        let v_air = [
            self.velocity[0] - self.air_velocity[0],
            self.velocity[1] - self.air_velocity[1],
            self.velocity[2] - self.air_velocity[2],
        ];
        let vb = mul_m3t_v3(&r, v_air);
        let s_rot = 0.25
            * ((self.thrusts[0] * self.inv_hover_thrust).sqrt()
                + (self.thrusts[1] * self.inv_hover_thrust).sqrt()
                + (self.thrusts[2] * self.inv_hover_thrust).sqrt()
                + (self.thrusts[3] * self.inv_hover_thrust).sqrt());
        let mut fb = [0.0; 3];
        for i in 0..3 {
            fb[i] = -(p.rotor_drag_n_s_m[i] * s_rot + p.body_drag_n_s2_m2[i] * vb[i].abs()) * vb[i];
        }
        fb[2] += t_total;
        let fa = mul_m3_v3(&r, fb);
        let inv_m = 1.0 / p.mass_kg;
        let mut acc = [fa[0] * inv_m, fa[1] * inv_m, fa[2] * inv_m - GRAVITY_M_S2];

        // 5. Contact forces while resting.
        if self.resting {
            if acc[2] > 0.0 {
                self.resting = false;
            } else {
                let normal_acc = -acc[2];
                acc[2] = 0.0;
                self.velocity[2] = 0.0;
                let fric = p.friction_coefficient * normal_acc;
                let speed = (self.velocity[0] * self.velocity[0] + self.velocity[1] * self.velocity[1]).sqrt();
                if speed <= fric * h + 1e-6 {
                    self.velocity[0] = 0.0;
                    self.velocity[1] = 0.0;
                    let ah = (acc[0] * acc[0] + acc[1] * acc[1]).sqrt();
                    let k = if ah > fric { (ah - fric) / ah } else { 0.0 };
                    acc[0] *= k;
                    acc[1] *= k;
                } else {
                    acc[0] -= fric * self.velocity[0] / speed;
                    acc[1] -= fric * self.velocity[1] / speed;
                }
            }
        }

        // 6. Translation.
        let v0 = self.velocity;
        for i in 0..3 {
            self.position[i] += v0[i] * h + 0.5 * acc[i] * h * h;
            self.velocity[i] += acc[i] * h;
        }
        if self.resting && self.velocity[0] * v0[0] + self.velocity[1] * v0[1] < 0.0 {
            // Friction stops, it does not reverse.
            self.velocity[0] = 0.0;
            self.velocity[1] = 0.0;
        }
        let bottom = self.position[2] - p.bottom_offset_m;
        if bottom < support {
            if !self.resting {
                let frac = if bottom_prev > bottom {
                    ((bottom_prev - support) / (bottom_prev - bottom)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let vz = v0[2] + acc[2] * h * frac;
                self.touchdown = Some(Touchdown {
                    time_s: self.time_s + (h * frac) as f64,
                    vertical_speed_m_s: (-vz).max(0.0),
                    horizontal_speed_m_s: (self.velocity[0] * self.velocity[0] + self.velocity[1] * self.velocity[1])
                        .sqrt(),
                    surface_height_m: support,
                });
            }
            self.position[2] = support + p.bottom_offset_m;
            self.velocity[2] = self.velocity[2].max(0.0);
            self.resting = true;
        }
        if let Some((lo, hi)) = geometry.bounds() {
            for i in 0..3 {
                if lo[i].is_finite() && self.position[i] < lo[i] {
                    self.position[i] = lo[i];
                    self.velocity[i] = self.velocity[i].max(0.0);
                }
                if hi[i].is_finite() && self.position[i] > hi[i] {
                    self.position[i] = hi[i];
                    self.velocity[i] = self.velocity[i].min(0.0);
                }
            }
        }
        // Specific force: what an accelerometer at the body origin feels, from the realised acceleration
        // (so contact and wall impulses show up as they would).
        let inv_h = 1.0 / h;
        let sf_arena = [
            (self.velocity[0] - v0[0]) * inv_h,
            (self.velocity[1] - v0[1]) * inv_h,
            (self.velocity[2] - v0[2]) * inv_h + GRAVITY_M_S2,
        ];
        self.specific_force = mul_m3t_v3(&r, sf_arena);

        // 7. Rotation.
        if self.resting {
            // The legs hold it: rates are whatever levels the body (keeping its yaw).
            let yaw = r[1][0].atan2(r[0][0]);
            let mut ql = [(0.5 * yaw).cos(), 0.0, 0.0, (0.5 * yaw).sin()];
            let q = self.q;
            if q[0] * ql[0] + q[3] * ql[3] < 0.0 {
                ql = ql.map(|v| -v);
            }
            // Error rotation in the body frame: conj(q) ⊗ ql.
            let e = quat_mul([q[0], -q[1], -q[2], -q[3]], ql);
            let k = 2.0 / LEVEL_TAU_S * if e[0] < 0.0 { -1.0 } else { 1.0 };
            self.rates = [e[1] * k, e[2] * k, e[3] * k];
        } else {
            let pos = &p.motor_positions_m;
            let mut tau = [0.0f32; 3];
            for i in 0..4 {
                tau[0] += pos[i][1] * t[i];
                tau[1] -= pos[i][0] * t[i];
                tau[2] += p.motor_yaw_sign[i] * p.thrust_to_torque_m * t[i];
            }
            let w = self.rates;
            let iw = [
                p.inertia_kg_m2[0] * w[0],
                p.inertia_kg_m2[1] * w[1],
                p.inertia_kg_m2[2] * w[2],
            ];
            let gyro = cross3(w, iw);
            for i in 0..3 {
                self.rates[i] += (tau[i] - gyro[i]) * self.inv_inertia[i] * h;
            }
        }
        let w = self.rates;
        let dq = quat_mul(self.q, [0.0, w[0], w[1], w[2]]);
        for (qi, dqi) in self.q.iter_mut().zip(dq) {
            *qi += 0.5 * dqi * h;
        }
        let n2 = self.q.iter().map(|v| v * v).sum::<f32>();
        if n2 > 0.0 && n2.is_finite() {
            let inv = 1.0 / n2.sqrt();
            self.q = self.q.map(|v| v * inv);
        }
        self.rot = quat_to_rot(self.q);
        self.time_s += h as f64;

        // Belt and braces: never let a non-finite value into the state.
        let finite = self
            .position
            .iter()
            .chain(&self.velocity)
            .chain(&self.q)
            .chain(&self.rates)
            .chain(&self.thrusts)
            .chain(&self.specific_force)
            .all(|v| v.is_finite());
        if !finite {
            (self.position, self.velocity, self.q, self.rates, self.thrusts) = saved;
            self.velocity = [0.0; 3];
            self.rates = [0.0; 3];
            if !self.q.iter().all(|v| v.is_finite()) {
                self.q = [1.0, 0.0, 0.0, 0.0];
            }
            self.rot = quat_to_rot(self.q);
            self.specific_force = [0.0, 0.0, GRAVITY_M_S2];
        }
    }

    /// Sets the velocity of the air around the drone (steady wind plus gusts), arena frame, m/s; the rotor
    /// and body drag act on the velocity relative to it. Non-finite components count as still air.
    pub fn set_air_velocity(&mut self, air_m_s: [f32; 3]) {
        self.air_velocity = air_m_s.map(|v| finite_or(v, 0.0));
    }

    /// The velocity of the air, arena frame, m/s.
    pub fn air_velocity(&self) -> [f32; 3] {
        self.air_velocity
    }

    /// Simulated time since [`Quadrotor::new`], s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Body-origin position, arena frame, m.
    pub fn position(&self) -> [f32; 3] {
        self.position
    }

    /// Velocity, arena frame, m/s.
    pub fn velocity(&self) -> [f32; 3] {
        self.velocity
    }

    /// Velocity in the body frame, m/s.
    pub fn body_velocity(&self) -> [f32; 3] {
        mul_m3t_v3(&self.rot, self.velocity)
    }

    /// Attitude quaternion `[w, x, y, z]`, body → arena.
    pub fn quaternion(&self) -> [f32; 4] {
        self.q
    }

    /// Rotation matrix body → arena (`v_arena = R · v_body`; columns are the body axes in the arena frame).
    pub fn rotation(&self) -> [[f32; 3]; 3] {
        self.rot
    }

    /// Roll, pitch, yaw (rad) per `cfnav::types`: `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
    pub fn attitude_rad(&self) -> [f32; 3] {
        euler_from_rot(&self.rot)
    }

    fn yaw(&self) -> f32 {
        self.rot[1][0].atan2(self.rot[0][0])
    }

    /// Body rates (what a perfect gyro reads), rad/s.
    pub fn rates(&self) -> [f32; 3] {
        self.rates
    }

    /// Specific force in the body frame over the last step (what a perfect accelerometer reads), m/s²:
    /// `(0, 0, +g)` at rest and level.
    pub fn specific_force(&self) -> [f32; 3] {
        self.specific_force
    }

    /// Present thrust of each motor (after the lag, without the ground effect), N.
    pub fn motor_thrusts(&self) -> [f32; 4] {
        self.thrusts
    }

    /// Forces the motors' present thrusts (e.g. to start a test in hover without the spin-up).
    pub fn set_motor_thrusts(&mut self, thrusts_n: [f32; 4]) {
        self.thrusts = thrusts_n.map(|t| finite_or(t, 0.0).max(0.0));
    }

    /// Sets the velocity (arena frame, m/s); the drone stops resting if it moves.
    pub fn set_velocity(&mut self, velocity_m_s: [f32; 3]) {
        self.velocity = velocity_m_s.map(|v| finite_or(v, 0.0));
        if self.velocity.iter().any(|v| *v != 0.0) {
            self.resting = false;
        }
    }

    /// Sets the position (arena frame, m) and lifts the drone off any surface.
    pub fn set_position(&mut self, position_m: [f32; 3]) {
        self.position = position_m.map(|v| finite_or(v, 0.0));
        self.resting = false;
    }

    /// Sets the attitude from roll, pitch, yaw (rad, `cfnav::types` conventions).
    pub fn set_attitude_rad(&mut self, rpy: [f32; 3]) {
        let [r, p, y] = rpy.map(|v| finite_or(v, 0.0));
        self.q = quat_from_euler(r, p, y);
        self.rot = quat_to_rot(self.q);
    }

    /// Sets the body rates, rad/s.
    pub fn set_rates(&mut self, rates_rad_s: [f32; 3]) {
        self.rates = rates_rad_s.map(|v| finite_or(v, 0.0));
    }

    /// The drone rests on a surface (landed).
    pub fn on_ground(&self) -> bool {
        self.resting
    }

    /// Height above the arena floor of the surface the drone is over / resting on (0 = floor), m.
    pub fn support_height(&self) -> f32 {
        self.support_height
    }

    /// The last touchdown, if any.
    pub fn last_touchdown(&self) -> Option<Touchdown> {
        self.touchdown
    }

    /// The battery.
    pub fn battery(&self) -> &Battery {
        &self.battery
    }

    /// The battery, to set its charge, a drain multiplier or a bench supply.
    pub fn battery_mut(&mut self) -> &mut Battery {
        &mut self.battery
    }

    /// Loaded battery voltage, V.
    pub fn battery_voltage(&self) -> f32 {
        self.battery.voltage()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_round_trip_matches_types_convention() {
        let mut q = Quadrotor::new(QuadParams::default(), [0.0; 3], 0.0);
        let rpy = [0.3, -0.2, 1.1];
        q.set_attitude_rad(rpy);
        let got = q.attitude_rad();
        for i in 0..3 {
            assert!((got[i] - rpy[i]).abs() < 1e-5, "{got:?}");
        }
        // Same matrix as cfnav::math::body_to_arena.
        let v = [0.3, -0.7, 0.2];
        let a = mul_m3_v3(&q.rotation(), v);
        let b = cfnav::math::body_to_arena(v, rpy);
        for i in 0..3 {
            assert!((a[i] - b[i]).abs() < 1e-5);
        }
    }
}
