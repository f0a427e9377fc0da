//! The flight stack split as the MCU runs it: [`Stabilizer`] (interrupt priority) and [`Navigator`] (thread
//! mode) exchange only small `Copy` messages. Checks the message contract: start refusals leave everything
//! unchanged, a start re-anchors the estimate and silences the commander hold, the idle mission does not
//! overwrite a fresh commander setpoint (2 s hold, docs/hardware.md §4), the commander gating, and
//! that [`FlightCore`] behaves exactly like the two parts wired by hand with messages delivered at once.

use cfnav::mission::{HOME_TOLERANCE_M, MissionMode, MissionParams, MissionState, PositionRefusal};
use cfnav::nav::dstar::ARENA_QUEUE;
use cfnav::nav::map::ARENA_CELLS;
use cfnav::stack::{
    COMMANDER_HOLD_US, FastStatus, FlightConfig, FlightCore, MissionCommand, Navigator, Stabilizer, StartError,
};
use cfnav::types::{ImuSample, Setpoint};

type Nav = Navigator<ARENA_CELLS, ARENA_QUEUE>;
type Core = FlightCore<ARENA_CELLS, ARENA_QUEUE>;

const LEVEL: ImuSample = ImuSample {
    gyro_rad_s: [0.0; 3],
    accel_m_s2: [0.0, 0.0, 9.81],
};

fn params() -> MissionParams {
    MissionParams {
        start_m: (1.0, 1.5),
        ..MissionParams::SEED
    }
}

/// The parameters with the home pad where [`parts`] and the cores below stand at power-on.
fn on_pad() -> MissionParams {
    MissionParams {
        start_m: (0.5, 0.5),
        ..params()
    }
}

fn parts() -> (Stabilizer, Box<Nav>) {
    let config = FlightConfig::default();
    (
        Stabilizer::new(&config, (0.5, 0.5), 0.0).unwrap(),
        Box::new(Nav::new(&config).unwrap()),
    )
}

#[test]
fn messages_are_small_enough_to_copy_under_a_short_lock() {
    // 168 MHz copies ~1 word per cycle or two: 256 bytes is well under a microsecond.
    assert!(size_of::<FastStatus>() <= 256, "{}", size_of::<FastStatus>());
    // A command carries at most one sweep's map fixes (four beams, 24 B each with the heading lever:
    // `estimator::map_fix`); the control task's 8-slot queue of them stays under 1 KiB of SRAM.
    assert!(size_of::<MissionCommand>() <= 112, "{}", size_of::<MissionCommand>());
}

#[test]
fn a_start_refused_for_flying_or_missing_decks_changes_nothing() {
    let (stab, mut nav) = parts();
    let mut status = stab.status();
    status.supervisor.flying = true;
    assert_eq!(nav.start(params(), &status), Err(StartError::Flying));
    assert_eq!(nav.state(), MissionState::Idle);
    nav.set_decks_ok(false);
    assert_eq!(nav.start(params(), &stab.status()), Err(StartError::DeckMissing));
    assert_eq!(nav.state(), MissionState::Idle);
    assert!(!nav.is_running());
}

#[test]
fn a_round_trip_start_puts_the_estimate_on_the_home_pad_and_forgets_the_commander() {
    let (mut stab, mut nav) = parts();
    stab.commander_setpoint(Setpoint::Stop, 1_000);
    assert_eq!(stab.status().commander_time, Some(1_000));
    // The home pad 0.1 m from where the estimate stands: within the tolerance, the round trip starts on it.
    let home = MissionParams {
        start_m: (0.6, 0.5),
        ..params()
    };
    let command = nav.start(home, &stab.status()).unwrap();
    assert_eq!(command, MissionCommand::Started { start_m: (0.6, 0.5) });
    assert!(nav.is_running());
    // Until the stabilizer gets the message, nothing changed on its side.
    assert_eq!(stab.estimate().position_m[0], 0.5);
    stab.apply(command);
    let p = stab.estimate().position_m;
    assert_eq!((p[0], p[1], p[2]), (0.6, 0.5, 0.0));
    assert_eq!(stab.status().commander_time, None);
    // A second start while running is refused.
    assert_eq!(nav.start(home, &stab.status()), Err(StartError::Flying));
}

#[test]
fn a_round_trip_off_the_home_pad_is_refused_and_the_other_modes_start_where_the_drone_stands() {
    let (stab, mut nav) = parts();
    // The estimate at (0.5, 0.5), the home pad at (1.0, 1.5): 1.12 m away.
    let refused = nav.start(params(), &stab.status());
    assert_eq!(
        refused,
        Err(StartError::Position(PositionRefusal::OffHomePad {
            at: (0.5, 0.5),
            home: (1.0, 1.5)
        }))
    );
    let line = refused.unwrap_err().to_string();
    assert!(
        line.contains("(0.50, 0.50), 1.12 m from the home pad (1.00, 1.50)"),
        "{line}"
    );
    assert!(!nav.is_running());
    assert_eq!(nav.state(), MissionState::Idle);
    // Just inside and just outside the tolerance.
    let at = |dx: f32| MissionParams {
        start_m: (0.5 + dx, 0.5),
        ..params()
    };
    assert!(nav.start(at(HOME_TOLERANCE_M + 0.01), &stab.status()).is_err());
    assert!(!nav.is_running());
    for mode in [MissionMode::HoverTest, MissionMode::Explore] {
        let (stab, mut nav) = parts();
        let command = nav.start(MissionParams { mode, ..params() }, &stab.status()).unwrap();
        assert_eq!(command, MissionCommand::Started { start_m: (0.5, 0.5) }, "{mode:?}");
    }
    let (stab, mut nav) = parts();
    assert!(nav.start(at(HOME_TOLERANCE_M - 0.01), &stab.status()).is_ok());
    // Outside the arena (or within 0.1 m of a wall) no mode starts.
    let config = FlightConfig::default();
    let stab = Stabilizer::new(&config, (0.05, 1.0), 0.0).unwrap();
    let mut nav = Box::new(Nav::new(&config).unwrap());
    let hover = MissionParams {
        mode: MissionMode::HoverTest,
        ..params()
    };
    assert_eq!(
        nav.start(hover, &stab.status()),
        Err(StartError::Position(PositionRefusal::OutsideArena { at: (0.05, 1.0) }))
    );
}

#[test]
fn the_idle_mission_holds_off_while_the_commander_speaks() {
    let (mut stab, mut nav) = parts();
    let hover = Setpoint::Position {
        x_m: 0.5,
        y_m: 0.5,
        z_m: 0.4,
        yaw_rad: 0.0,
    };
    stab.commander_setpoint(hover, 10_000);
    assert_eq!(nav.tick(10_000 + COMMANDER_HOLD_US - 1, &stab.status()), None);
    assert_eq!(stab.setpoint(), hover);
    // After the hold, the idle mission asks for Stop again.
    let cmd = nav.tick(10_000 + COMMANDER_HOLD_US, &stab.status()).unwrap();
    assert_eq!(
        cmd,
        MissionCommand::Setpoint {
            setpoint: Setpoint::Stop,
            time: 10_000 + COMMANDER_HOLD_US
        }
    );
    stab.apply(cmd);
    assert_eq!(stab.setpoint(), Setpoint::Stop);
}

#[test]
fn the_core_refuses_commander_setpoints_during_a_mission() {
    let mut core = Box::new(Core::new(&FlightConfig::default(), (0.5, 0.5), 0.0).unwrap());
    core.start_mission(on_pad()).unwrap();
    core.mission_tick(0);
    let before = core.setpoint();
    core.commander_setpoint(
        Setpoint::Velocity {
            vx_m_s: 1.0,
            vy_m_s: 0.0,
            z_m: 0.5,
            yaw_rad: 0.0,
        },
        1_000,
    );
    assert_eq!(core.setpoint(), before);
    assert_eq!(core.stabilizer().status().commander_time, None);
}

#[test]
fn the_core_is_the_two_parts_with_messages_delivered_at_once() {
    let config = FlightConfig::default();
    let mut core = Box::new(Core::new(&config, (0.5, 0.5), 0.0).unwrap());
    let (mut stab, mut nav) = parts();
    core.start_mission(on_pad()).unwrap();
    let cmd = nav.start(on_pad(), &stab.status()).unwrap();
    stab.apply(cmd);
    // Two seconds on the ground at 1 kHz with a 50 Hz mission tick and a few height readings.
    for tick in 0u64..2000 {
        let now = tick * 1000;
        if tick.is_multiple_of(25) {
            core.on_zrange(Some(0.0));
            let est = stab.on_zrange(Some(0.0));
            nav.on_zrange(Some(0.0), &est);
        }
        if tick.is_multiple_of(10) {
            core.on_battery(4.0);
            stab.on_battery(4.0);
        }
        if tick.is_multiple_of(20) {
            core.mission_tick(now);
            if let Some(cmd) = nav.tick(now, &stab.status()) {
                stab.apply(cmd);
            }
        }
        let a = core.on_imu(&LEVEL, now);
        let b = stab.on_imu(&LEVEL, now);
        assert_eq!(a, b, "tick {tick}");
        assert_eq!(core.estimate(), stab.estimate(), "tick {tick}");
        assert_eq!(core.mission_state(), nav.state(), "tick {tick}");
    }
    // The comparison ran on a started mission, not on an idle core.
    assert_ne!(core.mission_state(), MissionState::Idle);
}

/// A stabilizer flying at 0.5 m on commander setpoints (level IMU samples, 4 V battery), and the time of
/// its last step, µs.
fn flying_stabilizer() -> (Stabilizer, u64) {
    let (mut stab, _) = parts();
    let mut now = 0;
    for tick in 0u64..3000 {
        now = tick * 1000;
        if tick.is_multiple_of(10) {
            stab.on_battery(4.0);
            // Still over a textured floor: no motion, good surface quality.
            stab.on_flow(&cfnav::types::FlowSample {
                dpixel_x: 0,
                dpixel_y: 0,
                squal: 100,
                motion_valid: true,
                dt_s: 0.01,
            });
        }
        if tick.is_multiple_of(25) {
            // The ranger agrees with the estimate (a steady climb in still air).
            let z = stab.estimate().position_m[2].max(0.0);
            stab.on_zrange(Some(z));
        }
        let setpoint = if tick < 1500 {
            Setpoint::Stop
        } else {
            Setpoint::Position {
                x_m: 0.5,
                y_m: 0.5,
                z_m: 0.5,
                yaw_rad: 0.0,
            }
        };
        stab.commander_setpoint(setpoint, now);
        stab.on_imu(&LEVEL, now);
    }
    assert!(stab.supervisor().flying, "{:?}", stab.supervisor());
    assert_ne!(stab.duty(), cfnav::types::MotorDuty::default());
    (stab, now)
}

/// A hung IMU read in flight: the control loop reports missed samples. The supervisor's own accelerometer
/// timeout (1 s) only runs when a sample arrives, so without `on_imu_missed` nothing would stop the
/// motors. Oracle: level (four equal duties, their mean) for at most 5 ms, then off and latched.
#[test]
fn missed_imu_samples_in_flight_level_then_stop_the_motors_and_latch() {
    use cfnav::flight::supervisor::{Reason, SupervisorState};
    use cfnav::stack::IMU_LEVEL_US;
    let (mut stab, last) = flying_stabilizer();
    let before = stab.duty().0;
    let mean = (before.iter().map(|&d| u32::from(d)).sum::<u32>()).div_ceil(4) as u8;
    // Misses reported every 2 ms (the board's data-ready / read deadline).
    let mut t = last;
    let mut off_at = None;
    while t < last + 20_000 {
        t += 2_000;
        let duty = stab.on_imu_missed(t);
        if t - last <= IMU_LEVEL_US {
            assert_eq!(duty.0, [mean; 4], "level at +{} µs", t - last);
        } else {
            assert_eq!(duty.0, [0; 4], "off at +{} µs", t - last);
            off_at.get_or_insert(t - last);
        }
    }
    assert!(off_at.is_some_and(|d| d <= IMU_LEVEL_US + 2_000), "{off_at:?}");
    assert_eq!(stab.supervisor().state, SupervisorState::Crashed);
    assert_eq!(stab.supervisor().reason, Reason::AccelFault);
    assert!(stab.status().motors_stopped);
    // The IMU comes back: the crash stays latched, the motors stay off.
    for k in 1..100 {
        assert_eq!(stab.on_imu(&LEVEL, t + k * 1000).0, [0; 4]);
    }
    assert_eq!(stab.supervisor().state, SupervisorState::Crashed);
}

/// One missed sample is not a crash: the next good sample resumes the attitude loop.
#[test]
fn a_single_missed_imu_sample_is_bridged_level() {
    use cfnav::flight::supervisor::SupervisorState;
    let (mut stab, last) = flying_stabilizer();
    let duty = stab.on_imu_missed(last + 2_000);
    assert!(duty.0.iter().all(|&d| d == duty.0[0] && d > 0), "{duty:?}");
    stab.on_imu(&LEVEL, last + 3_000);
    assert_eq!(stab.supervisor().state, SupervisorState::Flying);
    assert!(stab.duty().0.iter().all(|&d| d > 0));
}

/// On the ground (motors off) a missed sample keeps them off and does not latch anything.
#[test]
fn missed_imu_samples_on_the_ground_keep_the_motors_off() {
    use cfnav::flight::supervisor::SupervisorState;
    let (mut stab, _) = parts();
    for tick in 0u64..200 {
        stab.on_imu(&LEVEL, tick * 1000);
    }
    assert_eq!(stab.on_imu_missed(201_000).0, [0; 4]);
    assert_ne!(stab.supervisor().state, SupervisorState::Crashed);
    assert_eq!(stab.on_imu_missed(400_000).0, [0; 4]);
    assert_ne!(stab.supervisor().state, SupervisorState::Crashed);
}

/// A reading `age` old belongs to the pose the drone had then: back along the velocity and the yaw rate.
/// Bad or absurd ages change nothing or are bounded (a VL53L1x reading is never older than ~0.1 s).
#[test]
fn a_backdated_estimate_is_the_pose_a_reading_was_measured_from() {
    use cfnav::types::StateEstimate;
    let now = StateEstimate {
        position_m: [2.0, 1.0, 0.5],
        velocity_m_s: [0.5, -0.2, 0.1],
        attitude_rad: [0.01, -0.02, 3.1],
        rates_rad_s: [0.0, 0.0, 2.0],
        surface_height_m: 0.1,
        valid: true,
    };
    let past = now.backdated(0.025);
    let close = |a: f32, b: f32| (a - b).abs() < 1e-5;
    assert!(close(past.position_m[0], 2.0 - 0.0125), "{past:?}");
    assert!(close(past.position_m[1], 1.0 + 0.005), "{past:?}");
    assert!(close(past.position_m[2], 0.5 - 0.0025), "{past:?}");
    assert!(close(past.attitude_rad[2], 3.05), "{past:?}");
    // Everything else is the current estimate's.
    assert_eq!(
        (
            past.velocity_m_s,
            &past.attitude_rad[..2],
            past.rates_rad_s,
            past.surface_height_m,
            past.valid
        ),
        (
            now.velocity_m_s,
            &now.attitude_rad[..2],
            now.rates_rad_s,
            now.surface_height_m,
            now.valid
        )
    );
    // Turning backwards through ±π stays wrapped.
    let turning = StateEstimate {
        attitude_rad: [0.0, 0.0, -3.1],
        rates_rad_s: [0.0, 0.0, 4.0],
        ..now
    };
    let back = turning.backdated(0.025).attitude_rad[2];
    assert!(close(back, -3.2 + 2.0 * core::f32::consts::PI), "{back}");
    // No age, a negative or non-finite one: unchanged; a huge one: bounded.
    for age in [0.0, -0.1, f32::NAN, f32::INFINITY] {
        assert_eq!(now.backdated(age), now, "age {age}");
    }
    let bounded = now.backdated(10.0);
    assert!(close(bounded.position_m[0], 2.0 - 0.5 * StateEstimate::MAX_BACKDATE_S));
}
