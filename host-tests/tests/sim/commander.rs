//! The radio commanders flown on the simulated drone: a stop setpoint in the air (the drone falls and the
//! estimate stays with it), judged on the simulator's truth.

use cfnav::types::Setpoint;
use cfnav_sim::physics::QuadParams;
use cfnav_sim::world::World;
use cfnav_tools::sim::runner::{Faults, SimDrone};

/// Hover 0.5 m above the floor beside the home pad, then one stop setpoint (cflib `send_stop_setpoint`) and
/// nothing more: the motors stay off, the drone falls to the floor, and once it lies there (0.3 s after the
/// truth touched down) the estimated height is within 10 cm of the truth; never a swing of metres (before
/// the fix: the motors came back at the 500 ms level-out and climbed to the ceiling, and the estimate fell
/// on at the fall's 2.8 m/s to −4 m for the supervisor's 2 s is-flying window).
#[test]
fn a_stop_setpoint_in_the_air_falls_and_the_estimate_follows() {
    let world = World::default_world();
    let bottom = QuadParams::default().bottom_offset_m;
    let (x0, y0) = (world.mission.start[0], world.mission.start[1]);
    let stop_s = 7.0;
    for seed in 1..=5 {
        let mut drone = SimDrone::new(&world, seed, &Faults::default()).unwrap();
        let mut touchdown: Option<f64> = None;
        let mut worst_on_floor = 0.0f32;
        let (mut est_min, mut est_max) = (f32::MAX, f32::MIN);
        let mut truth_max_after_stop = f32::MIN;
        for tick in 0..12_000u64 {
            let t = tick as f64 * 1e-3;
            if tick.is_multiple_of(20) && t < stop_s {
                let sp = if t < 1.5 {
                    Setpoint::Stop
                } else {
                    // Off the pad (it is 10 cm high), so the drone falls to the floor.
                    let dx = if t < 3.5 { 0.0 } else { 0.5 };
                    Setpoint::Position {
                        x_m: x0 + dx,
                        y_m: y0,
                        z_m: 0.5,
                        yaw_rad: 0.0,
                    }
                };
                drone.core.commander_setpoint(sp, tick * 1000);
            }
            if tick == (stop_s * 1000.0) as u64 {
                let truth_z = drone.quad.position()[2] - bottom;
                assert!(
                    (truth_z - 0.5).abs() < 0.05,
                    "seed {seed}: not hovering at the stop: {truth_z}"
                );
                drone.core.commander_setpoint(Setpoint::Stop, tick * 1000);
            }
            let truth_z = drone.quad.position()[2] - bottom;
            let est_z = drone.core.estimate().position_m[2];
            if t > stop_s + 0.01 {
                assert_eq!(
                    drone.core.duty().0,
                    [0; 4],
                    "seed {seed}: motors ran at {t:.3} s after the stop"
                );
                truth_max_after_stop = truth_max_after_stop.max(truth_z);
                est_min = est_min.min(est_z);
                est_max = est_max.max(est_z);
                if touchdown.is_none() && truth_z < 0.002 {
                    touchdown = Some(t);
                }
                if touchdown.is_some_and(|td| t > td + 0.3) {
                    worst_on_floor = worst_on_floor.max((est_z - truth_z).abs());
                }
            }
            drone.step(&world);
        }
        let td = touchdown.unwrap_or_else(|| panic!("seed {seed}: never reached the floor"));
        // Free fall from 0.5 m takes 0.32 s.
        assert!(td < stop_s + 0.6, "seed {seed}: touchdown at {td:.3} s");
        assert!(
            truth_max_after_stop < 0.52,
            "seed {seed}: climbed to {truth_max_after_stop}"
        );
        assert!(
            worst_on_floor <= 0.10,
            "seed {seed}: estimate {worst_on_floor} m off on the floor"
        );
        assert!(
            est_min > -0.4 && est_max < 0.6,
            "seed {seed}: the estimate swung over [{est_min}, {est_max}] m"
        );
    }
}

/// cflib's `HighLevelCommander` script on the simulated drone: take off to 0.5 m in 2 s, go 0.6 m along x
/// in 2.5 s (smooth), come back with a linear relative go-to, land in 2 s. The truth reaches each target
/// within 6 cm by the end of its duration plus 1 s, the drone ends on the floor with the motors off, and a
/// high-level command during a mission is refused.
#[test]
fn the_high_level_commander_takes_off_goes_to_and_lands() {
    use cfnav::flight::high_level::HlCommand;
    use cfnav::stack::HighLevelError;
    let world = World::default_world();
    let bottom = QuadParams::default().bottom_offset_m;
    let (x0, y0) = (world.mission.start[0], world.mission.start[1]);
    for seed in 1..=3 {
        let mut drone = SimDrone::new(&world, seed, &Faults::default()).unwrap();
        let run_to = |drone: &mut SimDrone, t_s: f64| {
            while (drone.tick() as f64) < t_s * 1000.0 {
                drone.step(&world);
            }
        };
        let near = |drone: &SimDrone, x: f32, y: f32, z: f32| {
            let p = drone.quad.position();
            let d = ((p[0] - x).powi(2) + (p[1] - y).powi(2) + (p[2] - bottom - z).powi(2)).sqrt();
            assert!(d < 0.06, "seed {seed}: at {p:?}, wanted ({x}, {y}, {z}): {d} m off");
        };
        run_to(&mut drone, 1.5);
        let cmd = |drone: &mut SimDrone, c: HlCommand| {
            let now = drone.tick() * 1000;
            drone.core.high_level_command(c, now).unwrap();
        };
        cmd(
            &mut drone,
            HlCommand::Takeoff {
                height_m: 0.5,
                yaw_rad: None,
                duration_s: 2.0,
            },
        );
        run_to(&mut drone, 4.5);
        // The take-off starts from the estimate, whose z is 0 on the home pad (the arena frame's anchor).
        let start_est = drone.core.estimate().position_m;
        near(&drone, x0, y0, 0.5 + 0.1);
        cmd(
            &mut drone,
            HlCommand::GoTo {
                position_m: [x0 + 0.6, y0, 0.5],
                yaw_rad: 0.0,
                duration_s: 2.5,
                relative: false,
                linear: false,
            },
        );
        run_to(&mut drone, 8.0);
        assert!(drone.core.supervisor().flying);
        let p = drone.quad.position();
        assert!(
            (p[0] - (x0 + 0.6)).abs() < 0.06,
            "seed {seed}: go-to reached x {}",
            p[0]
        );
        cmd(
            &mut drone,
            HlCommand::GoTo {
                position_m: [-0.6, 0.0, 0.0],
                yaw_rad: 0.0,
                duration_s: 2.5,
                relative: true,
                linear: true,
            },
        );
        run_to(&mut drone, 11.5);
        let p = drone.quad.position();
        assert!(
            (p[0] - x0).abs() < 0.06,
            "seed {seed}: relative go-to reached x {} ({start_est:?})",
            p[0]
        );
        cmd(
            &mut drone,
            HlCommand::Land {
                height_m: 0.0,
                yaw_rad: None,
                duration_s: 2.0,
            },
        );
        run_to(&mut drone, 16.0);
        assert_eq!(
            drone.core.duty().0,
            [0; 4],
            "seed {seed}: motors still on after landing"
        );
        assert!(!drone.core.supervisor().flying);
        assert!(!drone.core.stabilizer().high_level().is_active());
        // Back on the home pad (0.1 m high) it took off from.
        let p = drone.quad.position();
        assert!(p[2] - bottom < 0.12, "seed {seed}: not down: {p:?}");
    }
    // During a mission: refused, nothing changes.
    let mut drone = SimDrone::new(&world, 1, &Faults::default()).unwrap();
    run_to_ms(&mut drone, &world, 1500);
    drone
        .core
        .start_mission(cfnav_tools::sim::runner::mission_params(&world))
        .unwrap();
    run_to_ms(&mut drone, &world, 2000);
    let take = HlCommand::Takeoff {
        height_m: 1.0,
        yaw_rad: None,
        duration_s: 1.0,
    };
    assert_eq!(
        drone.core.high_level_command(take, 2_000_000),
        Err(HighLevelError::MissionRunning)
    );
    assert!(!drone.core.stabilizer().high_level().is_active());
}

fn run_to_ms(drone: &mut SimDrone, world: &World, ms: u64) {
    while drone.tick() < ms {
        drone.step(world);
    }
}

/// cflib's `send_setpoint` (RPYT) on the simulated drone, as stock flies it (attitude and thrust, no
/// position or height loop), judged on the truth: a thrust above the hover command climbs; a nose-down pitch
/// accelerates along +x and a right-side-down roll along −y (cfnav's convention, the decoded RPYT signs); a
/// yaw rate turns counter-clockwise at about that rate; setpoints that stop arriving level out and hold the
/// height it had when they went stale (the supervisor's 500 ms rule) instead of flying on at the last thrust
/// or sinking to the minimum height; thrust 0 stops the motors. Before: the follower had no attitude setpoint
/// and nothing flew.
#[test]
fn rpyt_setpoints_fly_attitude_and_thrust() {
    let world = World::default_world();
    let bottom = QuadParams::default().bottom_offset_m;
    let deg = |d: f32| d.to_radians();
    for seed in 1..=3 {
        let mut drone = SimDrone::new(&world, seed, &Faults::default()).unwrap();
        // Setpoints every 20 ms (cflib scripts send at 10–100 Hz) from `from_s` to `to_s`.
        let fly = |drone: &mut SimDrone, sp: Setpoint, from_s: f64, to_s: f64| {
            for tick in (from_s * 1000.0) as u64..(to_s * 1000.0) as u64 {
                if tick.is_multiple_of(20) {
                    drone.core.commander_setpoint(sp, tick * 1000);
                }
                drone.step(&world);
            }
        };
        let att = |roll: f32, pitch: f32, yaw_rate: f32, thrust: u16| Setpoint::Attitude {
            roll_rad: deg(roll),
            pitch_rad: deg(pitch),
            yaw_rate_rad_s: deg(yaw_rate),
            thrust,
        };
        fly(&mut drone, Setpoint::Stop, 0.0, 1.5);
        let z0 = drone.quad.position()[2] - bottom;
        fly(&mut drone, att(0.0, 0.0, 0.0, 52000), 1.5, 2.5);
        let z1 = drone.quad.position()[2] - bottom;
        assert!(drone.core.supervisor().flying, "seed {seed}");
        assert!(z1 - z0 > 0.1, "seed {seed}: climbed {} m at thrust 52000", z1 - z0);
        // Hover-ish thrust with a tilt: the acceleration's sign follows the attitude.
        let v0 = drone.quad.velocity();
        fly(&mut drone, att(0.0, 8.0, 0.0, 46000), 2.5, 3.1);
        let v1 = drone.quad.velocity();
        assert!(v1[0] - v0[0] > 0.2, "seed {seed}: nose down: vx {} → {}", v0[0], v1[0]);
        fly(&mut drone, att(8.0, 0.0, 0.0, 46000), 3.1, 3.7);
        let v2 = drone.quad.velocity();
        assert!(
            v2[1] - v1[1] < -0.2,
            "seed {seed}: right side down: vy {} → {}",
            v1[1],
            v2[1]
        );
        let yaw0 = drone.quad.attitude_rad()[2];
        fly(&mut drone, att(0.0, 0.0, 45.0, 46000), 3.7, 4.7);
        let turned = cfnav::math::wrap_angle(drone.quad.attitude_rad()[2] - yaw0).to_degrees();
        assert!(
            (30.0..60.0).contains(&turned),
            "seed {seed}: 45°/s for 1 s turned {turned}°"
        );
        // Higher up (well above the 0.2 m minimum height, which a hold without a height would fly to), the
        // setpoints stop: after 0.5 s the supervisor levels out and holds the height it had.
        fly(&mut drone, att(0.0, 0.0, 0.0, 50000), 4.7, 5.4);
        let z_stale = drone.quad.position()[2] - bottom;
        assert!(z_stale > 0.7, "seed {seed}: climbed to {z_stale} m");
        fly(&mut drone, att(0.0, 0.0, 0.0, 46000), 5.4, 5.42);
        let mut z_min = f32::MAX;
        let mut z_max = f32::MIN;
        for _ in 0..1400 {
            drone.step(&world);
            let z = drone.quad.position()[2] - bottom;
            z_min = z_min.min(z);
            z_max = z_max.max(z);
        }
        assert!(
            z_min > z_stale - 0.2 && z_max < z_stale + 0.2,
            "seed {seed}: silent from {z_stale} m: height in [{z_min}, {z_max}]"
        );
        assert!(drone.core.supervisor().level_out, "seed {seed}");
        // Thrust 0 (cflib's stop; the follower maps RPYT thrust 0 to Stop): motors off at once.
        let now = drone.tick() * 1000;
        drone.core.commander_setpoint(Setpoint::Stop, now);
        drone.step(&world);
        assert_eq!(drone.core.duty().0, [0; 4], "seed {seed}");
    }
}
