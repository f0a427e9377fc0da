//! The lockstep loop: the simulated Crazyflie and the firmware's [`FlightCore`] advance together, 1 ms at a
//! time, each firmware step function called at the rate it runs on the MCU (IMU 1 kHz, flow 100 Hz, battery
//! 100 Hz, z-ranger 40 Hz, Multi-ranger 10 Hz, mission 50 Hz). Deterministic for a world and seed. The
//! rangers' readings are measured half a timing budget before they are handed over (10 ms for the height,
//! 25 ms for the beams), as a VL53L1x integrates and then flags a range.
//!
//! The loop also keeps the score the report needs (docs/formats.md, report format): collisions and clearance measured on
//! the true state against the true world, the landings and their errors, distance flown, the estimator's
//! error against the truth.

use std::time::Instant;

use cfnav::drivers::vl53l1x::RangingConfig;
use cfnav::mission::link_loss::LinkLossConfig;
use cfnav::mission::{ExploreEnd, MissionMode, MissionParams, MissionState};
use cfnav::radio::crtp::{CrtpPacket, Service};
use cfnav::radio::param::{CH_WRITE, PORT_PARAM, ParamService};
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::{ID_ARENA_X, ID_ARENA_Y, ID_WALLS};
use cfnav::stack::{BEAM_MIDPOINT_US, FlightConfig, FlightCore, ZRANGE_MIDPOINT_US};
use cfnav::types::{MotorDuty, MultiRangerSample, RangeReading};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

use cfnav_sim::physics::Quadrotor;
use cfnav_sim::report::Landing;
use cfnav_sim::sensors::{BatterySensor, FlowSensor, Imu, MultiRanger, SensorFault, ZRanger};
use cfnav_sim::stress::{GUST_PERIOD_S, Gusts};
use cfnav_sim::world::{BODY_RADIUS_M, World};

/// Grid capacity the simulator flies with: the largest arena the firmware supports (`large-arena`).
pub const SIM_CELLS: usize = 128 * 64;
/// Open-list capacity, as on the MCU.
pub const SIM_QUEUE: usize = cfnav::nav::dstar::ARENA_QUEUE;
/// The flight stack the simulator flies.
pub type SimCore = FlightCore<SIM_CELLS, SIM_QUEUE>;

/// Faults and events injected into a run (tests and failure scenarios).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Faults {
    /// The flow deck stops delivering readings at this time, s.
    pub flow_fails_at_s: Option<f64>,
    /// The Multi-ranger stops delivering sweeps at this time, s (its deck lost in flight).
    pub ranger_fails_at_s: Option<f64>,
    /// The battery drains this many times faster than physics says.
    pub battery_drain_multiplier: Option<f32>,
    /// Initial battery state of charge (0..1).
    pub battery_state_of_charge: Option<f32>,
    /// Write `mission.start = 0` at this time, s.
    pub abort_at_s: Option<f64>,
    /// Report the decks as missing (the start is refused).
    pub decks_missing: bool,
    /// The radio link goes silent at this time, s: the simulated link delivers a packet every
    /// [`LINK_PACKET_PERIOD_MS`] until then, none after.
    pub link_loss_at_s: Option<f64>,
}

/// The simulated radio link (runs without `--serve`) delivers one packet this often, ms: cflib polls the
/// Crazyradio link with null packets whenever it has nothing to send, so the drone hears it every few ms.
pub const LINK_PACKET_PERIOD_MS: u64 = 10;

/// How to run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunOptions {
    /// Seed of all noise (defaults to the world's `sim.seed`).
    pub seed: u64,
    /// When `mission.start` is written, s after power-on.
    pub trigger_s: f64,
    /// Simulated time allowed, s.
    pub time_limit_s: f64,
    /// Keep a trace for plots (every 20 ms).
    pub record: bool,
    /// Injected faults.
    pub faults: Faults,
    /// Print every mission state change (time, truth, estimate) to stderr.
    pub verbose: bool,
    /// `mission.mode` (`--mode`): the round trip unless asked.
    pub mode: MissionMode,
    /// `mission.hoverTime`, s (`--hover-time`); the firmware's default when `None`.
    pub hover_time_s: Option<f32>,
    /// `mission.coverage` (`--coverage`); the firmware's default when `None`.
    pub coverage: Option<f32>,
    /// `mission.linkLoss` and `mission.linkTimeout` for the run.
    pub link_loss: LinkLossConfig,
}

impl RunOptions {
    /// The options a world file asks for: its seed and time limit, the mission triggered 1 s after power-on.
    pub fn for_world(world: &World) -> Self {
        Self {
            seed: world.sim.seed,
            trigger_s: 1.0,
            time_limit_s: f64::from(world.sim.time_limit),
            record: false,
            faults: Faults::default(),
            verbose: false,
            mode: MissionMode::RoundTrip,
            hover_time_s: None,
            coverage: None,
            link_loss: LinkLossConfig::DEFAULT,
        }
    }
}

/// The report of one run (docs/formats.md, report format), plus a few extra fields.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunReport {
    pub world: String,
    pub seed: u64,
    /// completed | aborted | crashed | timeout
    pub outcome: &'static str,
    /// A short word when not completed.
    #[serde(borrow)]
    pub reason: Option<&'static str>,
    pub mission_time_s: Option<f64>,
    pub collisions: u32,
    pub min_clearance_m: Option<f32>,
    /// The `mission.state` at the closest approach (`min_clearance_m`): which phase flies nearest.
    pub min_clearance_state: Option<u8>,
    pub landings: Vec<Landing>,
    pub replans: u32,
    pub distance_m: f64,
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    /// The final `mission.state` code.
    pub mission_state: u8,
    /// Largest horizontal error of the position estimate while airborne, m.
    pub max_estimate_error_m: f32,
    /// RMS horizontal error of the position estimate while airborne, m.
    pub rms_estimate_error_m: f32,
    /// Largest error of the height above the surface below (estimate vs truth) at flying height, m.
    pub max_height_error_m: f32,
    /// When the link-loss timeout fired (`--link-loss-at`), s since power-on.
    pub link_lost_at_s: Option<f64>,
    /// The true position (x, y, z) when it fired, m.
    pub link_lost_point: Option<[f32; 3]>,
    /// The `mission.state` at each collision's start (where to look).
    pub collision_states: Vec<u8>,
    /// The true position (x, y, z) at each collision's start, m.
    pub collision_points: Vec<[f32; 3]>,
    /// The arena has more cells than the default firmware build maps (120 × 60): the run flew the
    /// `large-arena` build's grid, as the simulator always does.
    pub needs_large_arena: bool,
    /// `mission.mode`: `round_trip`, `hover` or `explore`.
    pub mode: &'static str,
    /// The hover test's figures (mode `hover`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hover: Option<HoverReport>,
    /// The exploration's figures (mode `explore`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub explore: Option<ExploreReport>,
}

impl RunReport {
    /// A report of no simulator flight: no landings, no collisions, every figure zero, for a figure drawn
    /// from something else (`cfnav map`'s downloaded map, `cfnav pil --plot`'s emulated flight), which
    /// then sets what it knows.
    pub fn without_flight(world: String, outcome: &'static str, mode: &'static str) -> Self {
        Self {
            world,
            seed: 0,
            outcome,
            reason: None,
            mission_time_s: None,
            collisions: 0,
            min_clearance_m: None,
            min_clearance_state: None,
            landings: Vec::new(),
            replans: 0,
            distance_m: 0.0,
            sim_time_s: 0.0,
            wall_time_s: 0.0,
            mission_state: 0,
            max_estimate_error_m: 0.0,
            rms_estimate_error_m: 0.0,
            max_height_error_m: 0.0,
            link_lost_at_s: None,
            link_lost_point: None,
            collision_states: Vec::new(),
            collision_points: Vec::new(),
            needs_large_arena: false,
            mode,
            hover: None,
            explore: None,
        }
    }
}

/// The hover test in the report: the firmware's figures (`mission.hoverDevXY`, `.hoverDevZ`: the estimate's
/// view) beside the truth's.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct HoverReport {
    /// `mission.hoverTime`, s.
    pub hover_time_s: f32,
    /// How long the hold lasted (state 50), simulated s.
    pub held_s: f64,
    /// The firmware's worst horizontal deviation of the estimate from the take-off point, m.
    pub dev_xy_m: f32,
    /// The firmware's worst |estimated height − mission.height|, m.
    pub dev_z_m: f32,
    /// The truth's worst horizontal distance from the true take-off point during the hold, m.
    pub true_dev_xy_m: f32,
    /// The truth's worst |height above the take-off surface − mission.height| during the hold, m.
    pub true_dev_z_m: f32,
    /// Where the drone came to rest, from the true take-off point, m.
    pub landing_offset_m: Option<f32>,
}

/// The exploration in the report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct ExploreReport {
    /// `mission.coverage`, the target.
    pub coverage_target: f32,
    /// `mission.covered` at the end: the fraction of the arena's cells the drone's grid knows.
    pub coverage: f32,
    /// Fraction of the truly free cells (centre clear of every obstacle at cruise height) the grid knows.
    pub true_free_known: f32,
    /// Fraction of the cells the grid holds as occupied that are truly within 0.15 m of an obstacle or wall (the estimate drifts).
    pub occupied_correct: Option<f32>,
    /// `coverage`, `no_frontier`, `battery` (the reserve turned it home), or `None` when the exploration
    /// did not end (battery low, abort, crash...).
    #[serde(borrow)]
    pub end: Option<&'static str>,
    /// The mission's console lines (`Mission::take_note`), e.g. why the battery reserve turned it home.
    pub console: Vec<String>,
    /// From the trigger to the end of the exploration (the way home begins), s.
    pub explore_time_s: Option<f64>,
    pub frontiers_reached: u32,
    pub frontiers_dropped: u32,
    /// (time since the trigger s, coverage) at every frontier scan: coverage against time.
    pub coverage_curve: Vec<(f64, f32)>,
}

/// One traced instant.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TracePoint {
    pub t_s: f64,
    pub truth: [f32; 3],
    pub estimate: [f32; 3],
    pub state: u8,
}

/// Everything a run produced.
pub struct RunResult {
    pub report: RunReport,
    /// The trace (empty unless [`RunOptions::record`]).
    pub trace: Vec<TracePoint>,
    /// Planned paths as flown: snapshots of the shortened path (arena metres) whenever it changed.
    pub paths: Vec<Vec<(f32, f32)>>,
    /// The drone's occupancy grid at the end: (width, height, blocked, occupied).
    pub believed: Option<(u16, u16, Vec<bool>, Vec<bool>)>,
    /// Pad centres the drone locked on.
    pub pad_locks: Vec<(f32, f32)>,
}

/// The simulated drone: the quadrotor, its sensors with their own noise streams, and the firmware's
/// [`FlightCore`], stepped together 1 ms at a time with each step function at its MCU rate. Shared by
/// [`run`], the UDP server and the tests, so they all fly exactly the same loop.
pub struct SimDrone {
    /// The true vehicle.
    pub quad: Quadrotor,
    /// The firmware's flight stack.
    pub core: Box<SimCore>,
    rng_imu: SmallRng,
    rng_flow: SmallRng,
    rng_z: SmallRng,
    rng_mr: SmallRng,
    rng_bat: SmallRng,
    imu: Imu,
    flow: FlowSensor,
    zranger: ZRanger,
    multiranger: MultiRanger,
    battery: BatterySensor,
    /// Steady wind, arena frame, m/s (`[disturbances] wind`).
    wind_m_s: [f32; 2],
    gusts: Gusts,
    /// The latest readings handed to the firmware (for logs).
    pub last_multiranger: MultiRangerSample,
    /// The latest downward range handed to the firmware.
    pub last_zrange: RangeReading,
    /// The readings being integrated: measured at the middle of the timing budget, handed over at its end.
    measured_multiranger: MultiRangerSample,
    measured_zrange: RangeReading,
    /// The latest battery voltage reading, V.
    pub last_vbat: f32,
    /// From this tick on no Multi-ranger sweep is handed over (`Faults::ranger_fails_at_s`).
    ranger_fails_at_tick: Option<u64>,
    tick: u64,
}

impl SimDrone {
    /// A drone standing on the world's start, powered on, with the world's `[sensors]` and `[disturbances]`
    /// and `faults` applied.
    pub fn new(world: &World, seed: u64, faults: &Faults) -> Result<Self, String> {
        let stream = |k: u64| SmallRng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ k);
        let mut rng_imu = stream(1);
        let stress = &world.stress;
        let start = world.mission.start;
        // The drone truly stands at `placed` (a hand's placement), but is told `start` and believes yaw 0.
        let (truly, yaw) = world.mission.true_start();
        let mut quad = Quadrotor::new(stress.quad_params(), [truly[0], truly[1], 0.0], yaw);
        quad.place_on_surface(world);
        if let Some(soc) = stress.battery_state_of_charge(&quad.params().battery) {
            quad.battery_mut().set_state_of_charge(soc);
        }
        let wind_m_s = stress.wind_m_s();
        quad.set_air_velocity([wind_m_s[0], wind_m_s[1], 0.0]);
        if let Some(soc) = faults.battery_state_of_charge {
            quad.battery_mut().set_state_of_charge(soc);
        }
        if let Some(k) = faults.battery_drain_multiplier {
            quad.battery_mut().set_drain_multiplier(k);
        }
        let imu = Imu::new(stress.imu_params(), &mut rng_imu);
        // Streams 6 and 7 are new (gusts, the per-seed flow scale error): the first five draw as before.
        let mut flow = FlowSensor::new(stress.flow_params(&mut stream(7)));
        let gusts = Gusts::new(stress.disturbances.gust_m_s.unwrap_or(0.0), stream(6).random());
        if let Some(t) = faults.flow_fails_at_s {
            flow.inject_fault(Some((t, SensorFault::Stopped)));
        }
        let mut core: Box<SimCore> = Box::new(
            FlightCore::new(&FlightConfig::default(), (start[0], start[1]), 0.0)
                .map_err(|e| format!("the flight configuration is invalid: {e:?}"))?,
        );
        core.set_decks_ok(!faults.decks_missing);
        Ok(Self {
            quad,
            core,
            rng_imu,
            rng_flow: stream(2),
            rng_z: stream(3),
            rng_mr: stream(4),
            rng_bat: stream(5),
            imu,
            flow,
            zranger: ZRanger::new(stress.zranger_params()),
            multiranger: MultiRanger::new(stress.multiranger_params()),
            battery: BatterySensor::default(),
            wind_m_s,
            gusts,
            last_multiranger: MultiRangerSample::default(),
            last_zrange: None,
            measured_multiranger: MultiRangerSample::default(),
            measured_zrange: None,
            last_vbat: 0.0,
            ranger_fails_at_tick: faults
                .ranger_fails_at_s
                .filter(|t| t.is_finite())
                .map(|t| (t.max(0.0) * 1000.0).round() as u64),
            tick: 0,
        })
    }

    /// The simulated IMU (tests: change its bias in flight).
    pub fn imu_mut(&mut self) -> &mut Imu {
        &mut self.imu
    }

    /// Milliseconds since power-on.
    pub fn tick(&self) -> u64 {
        self.tick
    }

    /// One millisecond: sensors at their rates into the flight core, the mission tick, the IMU step, the
    /// duties to the motors, physics. Returns the duties written.
    pub fn step(&mut self, world: &World) -> MotorDuty {
        let tick = self.tick;
        let now_us = tick * 1000;
        const GUST_TICKS: u64 = (GUST_PERIOD_S * 1000.0) as u64;
        if tick.is_multiple_of(GUST_TICKS) && self.gusts.is_active() {
            self.gusts.step();
            let g = self.gusts.value();
            self.quad
                .set_air_velocity([self.wind_m_s[0] + g[0], self.wind_m_s[1] + g[1], 0.0]);
        }
        if tick.is_multiple_of(10) {
            if let Some(f) = self.flow.sample(&self.quad, world, &mut self.rng_flow) {
                self.core.on_flow(&f);
            }
            self.last_vbat = self.battery.sample(&self.quad, &mut self.rng_bat);
            self.core.on_battery(self.last_vbat);
        }
        // A VL53L1x reports at its data-ready flag the range it integrated over its timing budget: the
        // scene half a budget earlier (`RangingConfig::integration_midpoint_us`). The truth is sampled then
        // and handed over at the flag, every 25 ms (height) and 100 ms (beams).
        if (tick + Z_MIDPOINT_TICKS).is_multiple_of(Z_PERIOD_TICKS) {
            self.measured_zrange = self.zranger.sample(&self.quad, world, &mut self.rng_z);
        }
        if tick.is_multiple_of(Z_PERIOD_TICKS) {
            self.last_zrange = self.measured_zrange;
            self.core.on_zrange(self.last_zrange);
        }
        if (tick + BEAM_MIDPOINT_TICKS).is_multiple_of(BEAM_PERIOD_TICKS) {
            self.measured_multiranger = self.multiranger.sample(&self.quad, world, &mut self.rng_mr);
        }
        let rangers_answer = self.ranger_fails_at_tick.is_none_or(|t| tick < t);
        if tick.is_multiple_of(BEAM_PERIOD_TICKS) && rangers_answer {
            self.last_multiranger = self.measured_multiranger;
            self.core.on_multiranger(&self.last_multiranger);
        }
        if tick.is_multiple_of(20) {
            self.core.mission_tick(now_us);
        }
        let sample = self.imu.sample(&self.quad, &mut self.rng_imu);
        let duty = self.core.on_imu(&sample, now_us);
        self.quad.set_duty(duty);
        self.quad.step(0.001, world);
        self.tick += 1;
        duty
    }
}

/// The height ranger's period and the Multi-ranger's, ms ticks (the firmware's `RangingConfig` presets).
const Z_PERIOD_TICKS: u64 = RangingConfig::FLOW_DECK_Z.inter_measurement_ms as u64;
const BEAM_PERIOD_TICKS: u64 = RangingConfig::MULTI_RANGER.inter_measurement_ms as u64;
/// How long before its hand-over a reading is measured, ms ticks (half the timing budget).
const Z_MIDPOINT_TICKS: u64 = ZRANGE_MIDPOINT_US / 1000;
const BEAM_MIDPOINT_TICKS: u64 = BEAM_MIDPOINT_US / 1000;
const _: () = assert!(Z_MIDPOINT_TICKS < Z_PERIOD_TICKS && BEAM_MIDPOINT_TICKS < BEAM_PERIOD_TICKS);

/// The parameters the world gives the drone: its start, goal, height and speed as the power-on values,
/// and its room (`mission.arenaX`, `arenaY`, `walls`) written over the radio before the start, as a user
/// does ([`room_params`]). A room the map cannot hold keeps the world's size, which the start then refuses
/// (`BadArena`), as the drone refuses it.
pub fn mission_params(world: &World) -> MissionParams {
    room_params(world).unwrap_or_else(|_| MissionParams {
        arena_m: (world.arena.size[0], world.arena.size[1]),
        walls: world_walls(world),
        ..power_on_params(world)
    })
}

/// The world's start, goal, height and speed on the seed's arena: what the drone holds before the room is
/// written.
pub fn power_on_params(world: &World) -> MissionParams {
    MissionParams {
        start_m: (world.mission.start[0], world.mission.start[1]),
        goal_m: (world.mission.goal[0], world.mission.goal[1]),
        height_m: world.mission.height,
        speed_m_s: world.mission.speed,
        ..MissionParams::SEED
    }
}

/// The world's `mission.walls` bitmask (`[arena] walls`, south 1, east 2, north 4, west 8).
pub fn world_walls(world: &World) -> u8 {
    world.arena.walls
}

/// The parameter writes (port 2, channel 2) that give the drone a room: `mission.arenaX`, `arenaY`, `arenaX`
/// again (a write is checked with the other side in effect, so growing x may need y first), `walls`.
pub fn room_writes(size_m: (f32, f32), walls: u8) -> [CrtpPacket; 4] {
    let f = |id: u16, v: f32| {
        let mut data = id.to_le_bytes().to_vec();
        data.extend_from_slice(&v.to_le_bytes());
        CrtpPacket::new(PORT_PARAM, CH_WRITE, &data).expect("7 bytes fit a packet")
    };
    let w = ID_WALLS.to_le_bytes();
    [
        f(ID_ARENA_X, size_m.0),
        f(ID_ARENA_Y, size_m.1),
        f(ID_ARENA_X, size_m.0),
        CrtpPacket::new(PORT_PARAM, CH_WRITE, &[w[0], w[1], walls]).expect("3 bytes fit a packet"),
    ]
}

/// Writes the room into a parameter service as a client does ([`room_writes`]); the console lines of the
/// writes that stay refused as the error.
pub fn write_room(service: &mut ParamService<MissionParamState>, size_m: (f32, f32), walls: u8) -> Result<(), String> {
    for p in room_writes(size_m, walls) {
        let _echo = service.handle(&p);
    }
    let mut lines = String::new();
    while let Some(note) = service.take_refusal() {
        lines.push_str(ParamService::<MissionParamState>::console_line(&note).as_str());
    }
    // The first arenaX write may be refused and the second taken: what counts is the room held now.
    let p = service.store().params;
    if p.arena_m == size_m && p.walls == walls {
        Ok(())
    } else {
        Err(lines)
    }
}

/// [`power_on_params`] with the world's room written over the radio; the refusals' console lines if the
/// drone would not take it.
pub fn room_params(world: &World) -> Result<MissionParams, String> {
    let mut service = ParamService::new(MissionParamState::new(power_on_params(world), SIM_CELLS));
    write_room(
        &mut service,
        (world.arena.size[0], world.arena.size[1]),
        world_walls(world),
    )?;
    Ok(service.store().params)
}

/// Fly one world. Fails only if the flight stack's configuration is invalid.
pub fn run(world: &World, options: &RunOptions) -> Result<RunResult, String> {
    // The movers walk: the run flies its own copy of the world, stepped every millisecond.
    let mut world = world.clone();
    let has_movers = !world.movers.is_empty();
    let mut left_arena = false;
    let wall = Instant::now();
    let seed = options.seed;
    let mut drone = SimDrone::new(&world, seed, &options.faults)?;
    let room = room_params(&world);
    if let (Err(lines), true) = (&room, options.verbose) {
        eprint!("{lines}");
    }
    let mut params = match &room {
        Ok(p) => *p,
        Err(_) => mission_params(&world),
    };
    params.mode = options.mode;
    if let Some(t) = options.hover_time_s {
        params.hover_time_s = t;
    }
    if let Some(c) = options.coverage {
        params.coverage_target = c;
    }
    let take_off_truth = drone.quad.position();
    let mut hover_truth = (0.0f32, 0.0f32, 0u64);
    let mut coverage_curve: Vec<(f64, f32)> = Vec::new();
    let mut mission_notes: Vec<String> = Vec::new();
    let mut explore_ended_at: Option<u64> = None;
    let take_off_surface = drone.quad.position()[2];

    let total_ticks = (options.time_limit_s * 1000.0).max(0.0) as u64;
    let trigger_tick = (options.trigger_s * 1000.0) as u64;
    let abort_tick = options.faults.abort_at_s.map(|t| (t * 1000.0) as u64);
    let link_silent_tick = options.faults.link_loss_at_s.map(|t| (t.max(0.0) * 1000.0) as u64);
    drone.core.set_link_loss(options.link_loss);
    let mut link_lost: Option<(f64, [f32; 3])> = None;

    let mut score = Score::new();
    let mut trace = Vec::new();
    let mut paths: Vec<Vec<(f32, f32)>> = Vec::new();
    let mut duty = MotorDuty::default();
    let mut started = false;
    let mut start_refused = false;
    let mut ended_at: Option<u64> = None;
    let mut last_motor_stop: Option<u64> = None;
    let mut was_on_ground = true;
    let mut tick = 0u64;
    let mut last_state = drone.core.mission_state();

    while tick < total_ticks {
        if tick == trigger_tick {
            match room.as_ref().map(|_| drone.core.start_mission(params)) {
                Ok(Ok(())) => started = true,
                Ok(Err(_)) | Err(_) => start_refused = true,
            }
        }
        if Some(tick) == abort_tick {
            drone.core.abort_mission();
        }
        if tick.is_multiple_of(LINK_PACKET_PERIOD_MS) && link_silent_tick.is_none_or(|t| tick < t) {
            drone.core.on_radio_packet(tick * 1000);
        }
        if has_movers {
            world.step_movers(0.001, drone.quad.position());
        }
        let new_duty = drone.step(&world);
        if let Some(note) = drone.core.take_mission_note() {
            if options.verbose {
                eprintln!("{:8.3} s  console: {note}", tick as f64 * 1e-3);
            }
            mission_notes.push(note.to_string());
        }
        if link_lost.is_none()
            && let Some(t) = drone.core.navigator().link_watch().fired_at()
        {
            link_lost = Some((t as f64 * 1e-6, drone.quad.position()));
        }
        if tick.is_multiple_of(20)
            && let Some(snapshot) = path_snapshot(&drone.core)
            && paths.last() != Some(&snapshot)
        {
            paths.push(snapshot);
        }
        if duty != MotorDuty::default() && new_duty == MotorDuty::default() {
            last_motor_stop = Some(tick);
        }
        duty = new_duty;
        let (quad, core) = (&drone.quad, &drone.core);

        // Score on the truth.
        let p = quad.position();
        let on_ground = quad.on_ground();
        if !on_ground {
            let clearance = world.clearance(p[0], p[1], p[2]) - BODY_RADIUS_M;
            score.airborne(clearance, core, p, take_off_surface, world.surface_height(p[0], p[1]));
        } else {
            score.grounded();
        }
        if world.arena.left_through_open_side(p[0], p[1]) {
            left_arena = true;
            ended_at = Some(tick);
            break;
        }
        if on_ground && !was_on_ground && started {
            score.pending_landing = Some(tick);
        }
        // A landing counts once the drone has come to rest with its motors stopped.
        if let Some(t0) = score.pending_landing
            && on_ground
            && duty == MotorDuty::default()
            && tick >= t0 + 200
        {
            score.land(&world, p);
        }
        if !on_ground {
            score.pending_landing = None;
        }
        was_on_ground = on_ground;
        if options.record && tick.is_multiple_of(20) {
            trace.push(TracePoint {
                t_s: tick as f64 * 1e-3,
                truth: p,
                estimate: core.estimate().position_m,
                state: core.mission_state().code(),
            });
        }
        let state = core.mission_state();
        if state == MissionState::HoverHold {
            hover_truth.0 = hover_truth
                .0
                .max((p[0] - take_off_truth[0]).hypot(p[1] - take_off_truth[1]));
            // The estimate's heights count from the surface it took off from (the home pad's top).
            hover_truth.1 = hover_truth.1.max((p[2] - take_off_truth[2] - params.height_m).abs());
            hover_truth.2 += 1;
        }
        if options.mode == MissionMode::Explore && tick.is_multiple_of(20) {
            let c = core.mission().stats().coverage;
            if c > 0.0 && coverage_curve.last().is_none_or(|l| l.1 != c) {
                coverage_curve.push((tick.saturating_sub(trigger_tick) as f64 * 1e-3, c));
            }
            if explore_ended_at.is_none() && core.mission().stats().explore_end.is_some() {
                explore_ended_at = Some(tick);
            }
        }
        if options.verbose && state != last_state {
            let e = core.estimate();
            eprintln!(
                "{:8.3} s  state {:3} {:?}  truth ({:.2}, {:.2}, {:.2})  estimate ({:.2}, {:.2}, {:.2})  surface {:.2}  supervisor {:?}",
                tick as f64 * 1e-3,
                state.code(),
                state,
                p[0],
                p[1],
                p[2],
                e.position_m[0],
                e.position_m[1],
                e.position_m[2],
                e.surface_height_m,
                core.supervisor().state,
            );
        }
        if options.verbose
            && state != last_state
            && matches!(state, MissionState::ApproachGoalPad | MissionState::ApproachHomePad)
        {
            for e in core.mission().pad_detector().edges() {
                eprintln!(
                    "             edge {:?} at ({:.3}, {:.3}) step {:.3}",
                    e.kind, e.x, e.y, e.step_m
                );
            }
            for c in core.mission().pad_detector().crossings() {
                eprintln!(
                    "             crossing mid ({:.3}, {:.3}) len {:.3}",
                    c.midpoint().0,
                    c.midpoint().1,
                    c.length()
                );
            }
        }
        last_state = state;
        if options.verbose && tick.is_multiple_of(1000) && started && !state.is_final() {
            let e = core.estimate();
            let c = core.control();
            let sup = core.supervisor();
            eprintln!(
                "{:8.3} s    flow scale {:+.4} ± {:.4}  err ({:+.3}, {:+.3}) yaw err {:+.2}° roll/pitch err ({:+.2}, {:+.2})° xy ({:.2}, {:.2}) v ({:.2}, {:.2}) pad edges {} crossings {} est {:?} sp {:?}\n             z {:.3} (truth {:.3}) surface {:.3} vz {:.3} cmd {:?} duty {:?} sup {:?} flags {:?} valid {}",
                tick as f64 * 1e-3,
                core.estimator().diagnostics().flow_scale_error,
                core.estimator().diagnostics().flow_scale_std,
                e.position_m[0] - p[0],
                e.position_m[1] - p[1],
                (e.attitude_rad[2] - quad.attitude_rad()[2]).to_degrees(),
                (e.attitude_rad[0] - quad.attitude_rad()[0]).to_degrees(),
                (e.attitude_rad[1] - quad.attitude_rad()[1]).to_degrees(),
                e.position_m[0],
                e.position_m[1],
                e.velocity_m_s[0],
                e.velocity_m_s[1],
                core.mission().pad_detector().edges().len(),
                core.mission().pad_detector().crossings().len(),
                core.mission()
                    .pad_detector()
                    .estimate()
                    .map(|e| (e.x, e.y, e.confidence, e.inliers)),
                core.setpoint(),
                e.position_m[2],
                p[2],
                e.surface_height_m,
                e.velocity_m_s[2],
                c.thrust_cmd,
                duty.0,
                sup.state,
                sup.flags,
                e.valid,
            );
        }
        if (started && state.is_final() && on_ground && duty == MotorDuty::default()) || start_refused {
            if let Some(t0) = score.pending_landing
                && tick >= t0 + 200
            {
                score.land(&world, p);
            }
            if score.pending_landing.is_none() || start_refused {
                ended_at = Some(tick);
                break;
            }
        }
        tick += 1;
    }

    let sim_time_s = tick as f64 * 1e-3;
    let core = &drone.core;
    let state = core.mission_state();
    let home_landing = score.landings.last().is_some_and(|l| l.on_pad && l.pad == 0);
    let completed_on_pads = match options.mode {
        MissionMode::RoundTrip => {
            score.landings.len() >= 2
                && score.landings[0].on_pad
                && score.landings[0].pad == world.goal_pad_index()
                && home_landing
        }
        // Both modes take off from the home pad and end on it (one landing).
        MissionMode::HoverTest | MissionMode::Explore => score.landings.len() == 1 && home_landing,
    };
    let (outcome, reason) = if score.collisions > 0 {
        ("crashed", Some("collision"))
    } else if left_arena {
        ("aborted", Some("left_arena"))
    } else if start_refused {
        ("aborted", Some("start_refused"))
    } else if ended_at.is_none() {
        ("timeout", Some("time_limit"))
    } else {
        match state {
            MissionState::Completed if completed_on_pads => ("completed", None),
            MissionState::Completed => ("aborted", Some("missed_pad")),
            MissionState::Crashed => ("crashed", Some("tumble")),
            MissionState::Aborted => ("aborted", Some("aborted")),
            MissionState::NoPath => ("aborted", Some("no_path")),
            MissionState::PadNotFound => ("aborted", Some("pad_not_found")),
            MissionState::BatteryLow => ("aborted", Some("battery")),
            MissionState::EstimatorFault => ("aborted", Some("estimator_fault")),
            MissionState::PlannerFault => ("aborted", Some("planner_fault")),
            MissionState::LinkLost => ("aborted", Some("link_lost")),
            MissionState::LinkLostHome => ("aborted", Some("link_lost_home")),
            MissionState::RangerLost => ("aborted", Some("ranger_lost")),
            MissionState::LeftArena => ("aborted", Some("left_arena")),
            _ => ("aborted", Some("unknown")),
        }
    };
    let mission_time_s = last_motor_stop
        .filter(|_| started)
        .map(|t| (t.saturating_sub(trigger_tick)) as f64 * 1e-3);
    let mission = core.mission();
    let grid = mission.grid();
    let shape = grid.shape();
    let believed = (shape.cells() > 0).then(|| {
        let cells: Vec<cfnav::nav::map::Cell> = (0..shape.cells()).map(|i| shape.cell(i)).collect();
        (
            shape.width,
            shape.height,
            cells.iter().map(|c| grid.is_blocked(*c)).collect(),
            cells.iter().map(|c| grid.is_occupied(*c)).collect(),
        )
    });
    let pad_locks = mission.stats().pad_centres.iter().flatten().copied().collect();
    let report = RunReport {
        world: world.name.clone(),
        seed,
        outcome,
        reason,
        mission_time_s,
        collisions: score.collisions,
        min_clearance_m: score.min_clearance.is_finite().then_some(score.min_clearance),
        min_clearance_state: score.min_clearance.is_finite().then_some(score.min_clearance_state),
        landings: score.landings.clone(),
        replans: mission.stats().replans,
        distance_m: score.distance,
        sim_time_s,
        wall_time_s: wall.elapsed().as_secs_f64(),
        mission_state: state.code(),
        max_estimate_error_m: score.max_err,
        rms_estimate_error_m: if score.err_n > 0 {
            (score.err_sq / score.err_n as f64).sqrt() as f32
        } else {
            0.0
        },
        max_height_error_m: score.max_height_err,
        link_lost_at_s: link_lost.map(|(t, _)| t),
        link_lost_point: link_lost.map(|(_, p)| p),
        collision_states: score.collision_states.clone(),
        collision_points: score.collision_points.clone(),
        needs_large_arena: world.needs_large_arena(),
        mode: match options.mode {
            MissionMode::RoundTrip => "round_trip",
            MissionMode::HoverTest => "hover",
            MissionMode::Explore => "explore",
        },
        hover: (options.mode == MissionMode::HoverTest).then(|| {
            let stats = mission.stats();
            let rest = drone.quad.position();
            HoverReport {
                hover_time_s: params.hover_time_s,
                held_s: hover_truth.2 as f64 * 1e-3,
                dev_xy_m: stats.hover_dev_xy_m,
                dev_z_m: stats.hover_dev_z_m,
                true_dev_xy_m: hover_truth.0,
                true_dev_z_m: hover_truth.1,
                landing_offset_m: (!score.landings.is_empty())
                    .then(|| (rest[0] - take_off_truth[0]).hypot(rest[1] - take_off_truth[1])),
            }
        }),
        explore: (options.mode == MissionMode::Explore).then(|| {
            let stats = mission.stats();
            let (free_known, occupied_correct) = map_truth(&world, grid, params.height_m);
            ExploreReport {
                coverage_target: params.coverage_target,
                coverage: stats.coverage,
                true_free_known: free_known,
                occupied_correct,
                end: stats.explore_end.map(|e| match e {
                    ExploreEnd::Coverage => "coverage",
                    ExploreEnd::NoFrontier => "no_frontier",
                    ExploreEnd::Battery => "battery",
                }),
                console: mission_notes.clone(),
                explore_time_s: explore_ended_at.map(|t| t.saturating_sub(trigger_tick) as f64 * 1e-3),
                frontiers_reached: stats.frontiers_reached,
                frontiers_dropped: stats.frontiers_dropped,
                coverage_curve,
            }
        }),
    };
    Ok(RunResult {
        report,
        trace,
        paths,
        believed,
        pad_locks,
    })
}

/// The drone's map against the world: the fraction of truly free cells (centre clear of everything at
/// `height_m`) it knows, and the fraction of its occupied cells that truly lie within 0.15 m of an obstacle
/// or a wall (`None` when it marked none).
fn map_truth<const N: usize>(
    world: &World,
    grid: &cfnav::nav::grid::OccupancyGrid<N>,
    height_m: f32,
) -> (f32, Option<f32>) {
    let shape = grid.shape();
    let (mut free, mut free_known, mut occupied, mut occupied_ok) = (0u32, 0u32, 0u32, 0u32);
    for i in 0..shape.cells() {
        let c = shape.cell(i);
        let (x, y) = shape.center_of(c);
        let clearance = world.clearance(x, y, height_m);
        if clearance > 0.0 {
            free += 1;
            free_known += u32::from(!grid.is_unknown(c));
        }
        if grid.is_occupied(c) {
            occupied += 1;
            occupied_ok += u32::from(clearance < 0.15);
        }
    }
    (
        if free > 0 { free_known as f32 / free as f32 } else { 0.0 },
        (occupied > 0).then(|| occupied_ok as f32 / occupied as f32),
    )
}

fn path_snapshot(core: &SimCore) -> Option<Vec<(f32, f32)>> {
    let mission = core.mission();
    let shape = mission.grid().shape();
    let w = mission.waypoints();
    (w.len() >= 2).then(|| w.iter().map(|c| shape.center_of(*c)).collect())
}

struct Score {
    collisions: u32,
    collision_states: Vec<u8>,
    collision_points: Vec<[f32; 3]>,
    in_collision: bool,
    min_clearance: f32,
    min_clearance_state: u8,
    landings: Vec<Landing>,
    pending_landing: Option<u64>,
    distance: f64,
    last_airborne: Option<[f32; 3]>,
    max_err: f32,
    err_sq: f64,
    err_n: u64,
    max_height_err: f32,
}

impl Score {
    fn new() -> Self {
        Self {
            collisions: 0,
            collision_states: Vec::new(),
            collision_points: Vec::new(),
            in_collision: false,
            min_clearance: f32::INFINITY,
            min_clearance_state: 0,
            landings: Vec::new(),
            pending_landing: None,
            distance: 0.0,
            last_airborne: None,
            max_err: 0.0,
            err_sq: 0.0,
            err_n: 0,
            max_height_err: 0.0,
        }
    }

    fn airborne(&mut self, clearance: f32, core: &SimCore, p: [f32; 3], take_off_surface: f32, surface: f32) {
        if clearance < self.min_clearance {
            self.min_clearance = clearance;
            self.min_clearance_state = core.mission_state().code();
        }
        if clearance < 0.0 {
            if !self.in_collision {
                self.collisions += 1;
                self.collision_states.push(core.mission_state().code());
                self.collision_points.push(p);
            }
            self.in_collision = true;
        } else {
            self.in_collision = false;
        }
        if let Some(q) = self.last_airborne {
            self.distance += f64::from(((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt());
        }
        self.last_airborne = Some(p);
        let e = core.estimate();
        // Only judge the estimate at flying height (on the pads the drone is still sorting out its surface).
        if p[2] > take_off_surface + 0.15 {
            let err = ((e.position_m[0] - p[0]).powi(2) + (e.position_m[1] - p[1]).powi(2)).sqrt();
            self.max_err = self.max_err.max(err);
            self.err_sq += f64::from(err * err);
            self.err_n += 1;
            // Height above whatever is below: the estimate's own reference (take-off surface or floor) cancels.
            let h_err = ((e.position_m[2] - e.surface_height_m) - (p[2] - surface)).abs();
            self.max_height_err = self.max_height_err.max(h_err);
        }
    }

    fn grounded(&mut self) {
        self.last_airborne = None;
        self.in_collision = false;
    }

    fn land(&mut self, world: &World, p: [f32; 3]) {
        self.pending_landing = None;
        let (pad, on_pad) = world.landing_pad_at(p[0], p[1]);
        let c = world.pads.get(pad).map_or([p[0], p[1]], |pd| pd.center);
        self.landings.push(Landing {
            pad,
            error_m: (c[0] - p[0]).hypot(c[1] - p[1]),
            on_pad,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The room reaches the drone through the parameter service: the default world's 6 × 3 m walled box
    /// is what the drone holds after the writes; an arena the simulator's map cannot hold is refused with
    /// the drone's console line, and the start is then refused (`BadArena`) as on the drone.
    #[test]
    fn the_world_s_room_is_written_as_parameters() {
        let world = World::default_world();
        let p = room_params(&world).unwrap();
        assert_eq!((p.arena_m, p.walls), ((6.0, 3.0), cfnav::mission::ALL_WALLS));
        assert_eq!(p, mission_params(&world));
        let mut big = world.clone();
        // 10 × 5 m = 200 × 100 cells, more than the simulator's 128 × 64.
        big.arena.size = [10.0, 5.0];
        let lines = room_params(&big).unwrap_err();
        assert!(
            lines.contains("param mission.arenaX refused: arena too large for the map"),
            "{lines}"
        );
        assert_eq!(mission_params(&big).arena_m, (10.0, 5.0));
        // A narrower room that needs y first: 8 × 1 m (160 × 20 cells) fits, 8 × 3 m does not.
        let mut long = world.clone();
        long.arena.size = [8.0, 1.0];
        assert_eq!(room_params(&long).unwrap().arena_m, (8.0, 1.0));
    }
}
