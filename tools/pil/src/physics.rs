//! The simulator's physics behind the emulated sensors: the same rigid body, motors,
//! battery, world geometry and sensor noise models as `cfnav sim` (the `cfnav_sim` crate,
//! `tools/sim/src/{physics,sensors,world,stress}.rs`), stepped in the emulator's virtual time.
//!
//! Job, per host slice: before it, the truth goes out through the device models (BMI088 sample registers
//! at the gyro's ODR, VL53L1x ranges ray-cast in the world at 40 Hz / 10 Hz, PMW3901 counts at 100 Hz, the
//! battery voltage to the nRF51's PM packets); after it, the motor duties the image left in TIM2/TIM4's
//! compare registers drive the body for the slice's length.
//!
//! Motors (docs/hardware.md §3, `src/board/motors.rs`): M1 = TIM2 CCR2, M2 = TIM2 CCR4, M3 = TIM2 CCR1,
//! M4 = TIM4 CCR4; a channel counts only while its timer runs (CR1.CEN) and its output is enabled
//! (CCER.CCxE); duty = CCR / (ARR + 1) on the 8-bit scale the simulator takes (RM0090 §18.3.9, PWM mode 1).
//!
//! Units: SI in the simulator, chip counts on the buses; time in ns.

use rand::SeedableRng;
use rand::rngs::SmallRng;

use cfnav::types::MotorDuty;

use crate::board::Board;
use cfnav_sim::physics::Quadrotor;
use cfnav_sim::sensors::{FlowSensor, Imu, MultiRanger, ZRanger};
use cfnav_sim::world::World;

/// TIM2 and TIM4 (RM0090 Table 1).
const TIM2: u64 = 0x4000_0000;
const TIM4: u64 = 0x4000_0800;

/// How often the simulator's range models (`sensors.rs`) are sampled for the deck's rangers, in ns: every
/// slice, so the VL53L1x model can take each result's range at the middle of its own ranging period (the
/// image sets the periods: 25 ms down, 100 ms for the beams), not at an instant of the host's choosing.
const ZRANGE_PERIOD_NS: u64 = 1_000_000;
const BEAM_PERIOD_NS: u64 = 1_000_000;
/// The flow model's rate, ns.
const FLOW_PERIOD_NS: u64 = 10_000_000;

/// The world, the body and the sensor models.
pub struct Physics {
    pub world: World,
    pub quad: Quadrotor,
    imu: Imu,
    flow: FlowSensor,
    zranger: ZRanger,
    multiranger: MultiRanger,
    rng_imu: SmallRng,
    rng_flow: SmallRng,
    rng_z: SmallRng,
    rng_mr: SmallRng,
    next_z_ns: u64,
    next_beams_ns: u64,
    next_flow_ns: u64,
    ranges_m: [Option<f32>; 6],
    /// The truth's time, ns (the physics' clock; it follows the emulator's).
    now_ns: u64,
    pub duty: MotorDuty,
}

impl Physics {
    /// The drone standing at the world's start; `seed` seeds the noise streams as `cfnav sim` does.
    pub fn new(world: World, seed: u64) -> Self {
        let stream = |k: u64| SmallRng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ k);
        let mut rng_imu = stream(1);
        let stress = &world.stress;
        // The drone truly stands at `mission.placed` (put down by hand) when the world says so.
        let (start, yaw) = world.mission.true_start();
        let mut quad = Quadrotor::new(stress.quad_params(), [start[0], start[1], 0.0], yaw);
        quad.place_on_surface(&world);
        let imu = Imu::new(stress.imu_params(), &mut rng_imu);
        let flow = FlowSensor::new(stress.flow_params(&mut stream(7)));
        let zranger = ZRanger::new(stress.zranger_params());
        let multiranger = MultiRanger::new(stress.multiranger_params());
        Self {
            world,
            quad,
            imu,
            flow,
            zranger,
            multiranger,
            rng_imu,
            rng_flow: stream(2),
            rng_z: stream(3),
            rng_mr: stream(4),
            next_z_ns: 0,
            next_beams_ns: 0,
            next_flow_ns: 0,
            ranges_m: [None; 6],
            now_ns: 0,
            duty: MotorDuty::default(),
        }
    }

    /// Feeds the device models from the truth at the start of a slice.
    pub fn sensors_out(&mut self, board: &Board) {
        let now = self.now_ns;
        let imu = self.imu.sample(&self.quad, &mut self.rng_imu);
        board.imu.set_sample(imu.gyro_rad_s, imu.accel_m_s2);
        if now >= self.next_z_ns {
            self.ranges_m[crate::deck::DOWN] = self.zranger.sample(&self.quad, &self.world, &mut self.rng_z);
            self.next_z_ns = now + ZRANGE_PERIOD_NS;
        }
        if now >= self.next_beams_ns {
            let s = self.multiranger.sample(&self.quad, &self.world, &mut self.rng_mr);
            use crate::deck::{BACK, FRONT, LEFT, RIGHT, UP};
            self.ranges_m[FRONT] = s.front_m;
            self.ranges_m[BACK] = s.back_m;
            self.ranges_m[UP] = s.up_m;
            self.ranges_m[LEFT] = s.left_m;
            self.ranges_m[RIGHT] = s.right_m;
            self.next_beams_ns = now + BEAM_PERIOD_NS;
        }
        board.deck.set_ranges(self.ranges_m);
        if now >= self.next_flow_ns {
            match self.flow.sample(&self.quad, &self.world, &mut self.rng_flow) {
                Some(f) if f.motion_valid => {
                    board.flow.set_tracking(true);
                    board.flow.add_motion([f32::from(f.dpixel_x), f32::from(f.dpixel_y)]);
                }
                _ => board.flow.set_tracking(false),
            }
            self.next_flow_ns = now + FLOW_PERIOD_NS;
        }
    }

    /// Reads the motor duties from the timers and steps the body to `now_ns`.
    pub fn step_to(&mut self, board: &Board, now_ns: u64) {
        self.duty = motor_duty(board);
        self.quad.set_duty(self.duty);
        if now_ns > self.now_ns {
            let dt_s = (now_ns - self.now_ns) as f32 * 1e-9;
            // The walkers walk first, giving way to the drone where it is.
            self.world.step_movers(dt_s, self.quad.position());
            self.quad.step(dt_s, &self.world);
            self.now_ns = now_ns;
        }
    }

    /// The z-ranger's latest reading from the simulator's model (noise included), m; `None` = no return.
    pub fn down_range_m(&self) -> Option<f32> {
        self.ranges_m[crate::deck::DOWN]
    }

    /// The battery's loaded voltage, V.
    pub fn battery_v(&self) -> f32 {
        self.quad.battery_voltage()
    }
}

/// The duty of one channel: 0 unless the timer counts and the channel's output is enabled.
fn channel_duty(board: &Board, tim: u64, ch: u32) -> u8 {
    let cr1 = board.peek32(tim).unwrap_or(0);
    let ccer = board.peek32(tim + 0x20).unwrap_or(0);
    let arr = board.peek32(tim + 0x2C).unwrap_or(0);
    let ccr = board.peek32(tim + 0x34 + 4 * u64::from(ch - 1)).unwrap_or(0);
    if cr1 & 1 == 0 || ccer & (1 << (4 * (ch - 1))) == 0 || arr == 0 {
        return 0;
    }
    // Scaled to the 8-bit duty the simulator's motor model takes (the image runs ARR = 255).
    let steps = u64::from(arr) + 1;
    (u64::from(ccr).min(steps) * 255 / 255.max(steps - 1)).min(255) as u8
}

/// M1..M4 from TIM2/TIM4.
pub fn motor_duty(board: &Board) -> MotorDuty {
    MotorDuty([
        channel_duty(board, TIM2, 2),
        channel_duty(board, TIM2, 4),
        channel_duty(board, TIM2, 1),
        channel_duty(board, TIM4, 4),
    ])
}
