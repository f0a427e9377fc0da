//! The vocabulary the flight modules share: sensor samples as the drivers deliver them, the state estimate,
//! setpoints and motor outputs. Plain data, no behaviour beyond small conversions.
//!
//! Frames and conventions (every module follows them):
//! - **Arena frame**: origin at the arena's lower-left corner on the floor, x right, y up the page, z up
//!   (metres). Yaw 0 looks along +x, positive yaw turns counter-clockwise seen from above (towards +y).
//! - **Body frame**: x forward, y left, z up (the Crazyflie's frame). The IMU axes are the body axes.
//! - **Attitude**: roll φ about body x, pitch θ about body y, yaw ψ about z, right-hand rule, radians,
//!   composed as `R = Rz(ψ)·Ry(θ)·Rx(φ)` (body → arena). Positive pitch therefore tilts the nose **down**
//!   (so accelerating forward needs positive pitch) and positive roll lowers the right side (accelerating
//!   to the right, −y, needs positive roll). (The stock firmware exports pitch with the opposite sign;
//!   cfnav uses the right-hand rule everywhere and converts only at the radio boundary.)
//! - **Accelerometer**: specific force in the body frame, m/s²: at rest and level it reads (0, 0, +g).
//! - **Time**: microseconds since boot as `u64` ([`Micros`]); durations as `f32` seconds named `dt_s`.

/// Standard gravity, m/s².
pub const GRAVITY_M_S2: f32 = 9.81;

/// Microseconds since boot.
pub type Micros = u64;

/// One gyro + accelerometer reading (BMI088), body frame, at 1 kHz (the gyro's data-ready).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuSample {
    /// Angular rate, rad/s.
    pub gyro_rad_s: [f32; 3],
    /// Specific force, m/s² (level at rest: `[0, 0, 9.81]`).
    pub accel_m_s2: [f32; 3],
}

/// One optical-flow reading (PMW3901 motion burst, 100 Hz), already mapped to the body axes the way the
/// stock Flow-deck driver does (`dpixel_x = −deltaY`, `dpixel_y = −deltaX`; `docs/hardware.md` §2).
///
/// Measurement model (stock `mm_flow.c`): with `N = 0.1 · dpixel`,
/// `N_x ≈ dt·(35/0.71674)·(v_bx·R22/z − ω_y)` and `N_y ≈ dt·(35/0.71674)·(v_by·R22/z + ω_x)`, where
/// `v_b` is the body-frame velocity, `ω` the body rates, `R22` the cosine of the tilt and `z` the height of
/// the camera above the surface below it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FlowSample {
    /// Accumulated motion along body x since the previous reading, sensor counts.
    pub dpixel_x: i16,
    /// Accumulated motion along body y since the previous reading, sensor counts.
    pub dpixel_y: i16,
    /// Surface quality (SQUAL register), 0 = no features.
    pub squal: u8,
    /// The sensor reports valid motion (stock: motion byte == 0xB0). False in darkness or when too low.
    pub motion_valid: bool,
    /// Time since the previous reading, seconds.
    pub dt_s: f32,
}

/// One reading of a VL53L1x ranger, metres along its beam; `None` when there was no valid return
/// (range status not VALID, beyond the sensor's reach, or a bus fault).
pub type RangeReading = Option<f32>;

/// The Multi-ranger deck's five beams (10 Hz): body +x, −x, +y, −y and +z.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MultiRangerSample {
    /// Along body +x.
    pub front_m: RangeReading,
    /// Along body −x.
    pub back_m: RangeReading,
    /// Along body +y.
    pub left_m: RangeReading,
    /// Along body −y.
    pub right_m: RangeReading,
    /// Along body +z.
    pub up_m: RangeReading,
}

impl MultiRangerSample {
    /// Body-frame unit vectors (x, y) of the four horizontal beams, in the order of
    /// [`MultiRangerSample::horizontal`]: front, back, left, right.
    pub const HORIZONTAL_BEAMS_BODY: [(f32, f32); 4] = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)];

    /// The four horizontal readings: front, back, left, right.
    pub fn horizontal(&self) -> [RangeReading; 4] {
        [self.front_m, self.back_m, self.left_m, self.right_m]
    }
}

/// The vehicle state as the estimator believes it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StateEstimate {
    /// Position in the arena frame, m (z = height above the arena floor, not above a pad).
    pub position_m: [f32; 3],
    /// Velocity in the arena frame, m/s.
    pub velocity_m_s: [f32; 3],
    /// Roll, pitch, yaw, rad (see the module conventions).
    pub attitude_rad: [f32; 3],
    /// Body rates, rad/s (the filtered gyro).
    pub rates_rad_s: [f32; 3],
    /// Height of the surface under the drone above the arena floor, m (0 over the floor, ≈ pad height
    /// over a pad): what the downward ranger's steps were attributed to instead of the drone's height.
    pub surface_height_m: f32,
    /// The estimate can be flown on (attitude converged, position fixes recent and plausible).
    pub valid: bool,
}

impl StateEstimate {
    /// The longest age [`StateEstimate::backdated`] extrapolates over, s: beyond it a constant-velocity
    /// guess is worse than none (a VL53L1x reading is at most a timing budget plus a poll old, ≤ 0.1 s).
    pub const MAX_BACKDATE_S: f32 = 0.2;

    /// The estimate `age_s` seconds ago, extrapolated back at the current velocity and yaw rate: where a
    /// sensor reading that old was measured from. A VL53L1x integrates its range over its timing budget and
    /// flags it at the end, so a moving drone's reading belongs to a pose half a budget (plus the time it
    /// waited to be read) behind the current one (module `drivers::vl53l1x`). Position, height and yaw
    /// move; the rest is kept. A non-finite or non-positive age changes nothing; ages beyond
    /// [`StateEstimate::MAX_BACKDATE_S`] are clamped to it.
    pub fn backdated(&self, age_s: f32) -> Self {
        if !(age_s.is_finite() && age_s > 0.0) {
            return *self;
        }
        let age_s = age_s.min(Self::MAX_BACKDATE_S);
        let mut past = *self;
        for (p, v) in past.position_m.iter_mut().zip(self.velocity_m_s) {
            if v.is_finite() {
                *p -= v * age_s;
            }
        }
        // The body z rate is the yaw rate to first order in the tilt (a few degrees in flight).
        let yaw_rate = self.rates_rad_s[2];
        if yaw_rate.is_finite() {
            past.attitude_rad[2] = crate::math::wrap_angle(self.attitude_rad[2] - yaw_rate * age_s);
        }
        past
    }
}

/// What the mission (or the radio commander) asks of the controller.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Setpoint {
    /// Motors off.
    #[default]
    Stop,
    /// Hold a position and heading: arena frame, m and rad.
    Position {
        /// Target x, m.
        x_m: f32,
        /// Target y, m.
        y_m: f32,
        /// Target height above the arena floor, m.
        z_m: f32,
        /// Target heading, rad.
        yaw_rad: f32,
    },
    /// Fly a horizontal velocity (arena frame) at a height, with a heading.
    Velocity {
        /// Target velocity along arena x, m/s.
        vx_m_s: f32,
        /// Target velocity along arena y, m/s.
        vy_m_s: f32,
        /// Target height above the arena floor, m.
        z_m: f32,
        /// Target heading, rad.
        yaw_rad: f32,
    },
    /// Descend (or climb) at a vertical speed while holding a horizontal position: landing.
    Descend {
        /// Target x, m.
        x_m: f32,
        /// Target y, m.
        y_m: f32,
        /// Vertical speed, m/s (negative = down).
        vz_m_s: f32,
        /// Target heading, rad.
        yaw_rad: f32,
    },
    /// Fly an attitude with a collective thrust, no position or height loop: cflib's `send_setpoint`
    /// (commander port 3, RPYT) as stock flies it. Angles in cfnav's convention (types.rs: positive pitch =
    /// nose down), yaw as a rate.
    Attitude {
        /// Target roll, rad.
        roll_rad: f32,
        /// Target pitch, rad (positive: nose down).
        pitch_rad: f32,
        /// Yaw rate, rad/s (counter-clockwise positive).
        yaw_rate_rad_s: f32,
        /// Collective thrust command per motor, counts (0..=65535, stock units).
        thrust: u16,
    },
}

impl Setpoint {
    /// Every number in it is finite (Stop has none).
    pub fn is_finite(&self) -> bool {
        match *self {
            Setpoint::Stop => true,
            Setpoint::Position { x_m, y_m, z_m, yaw_rad } => [x_m, y_m, z_m, yaw_rad].iter().all(|v| v.is_finite()),
            Setpoint::Velocity {
                vx_m_s,
                vy_m_s,
                z_m,
                yaw_rad,
            } => [vx_m_s, vy_m_s, z_m, yaw_rad].iter().all(|v| v.is_finite()),
            Setpoint::Descend {
                x_m,
                y_m,
                vz_m_s,
                yaw_rad,
            } => [x_m, y_m, vz_m_s, yaw_rad].iter().all(|v| v.is_finite()),
            Setpoint::Attitude {
                roll_rad,
                pitch_rad,
                yaw_rate_rad_s,
                ..
            } => [roll_rad, pitch_rad, yaw_rate_rad_s].iter().all(|v| v.is_finite()),
        }
    }
}

/// The four motor duties as the firmware writes them to TIM2/TIM4 (8-bit, 0..=255), in the stock motor
/// numbering: M1 front-right, M2 back-right, M3 back-left, M4 front-left (`docs/hardware.md` §3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MotorDuty(pub [u8; 4]);
