//! Heading from the arena's walls (`cfnav::flight::estimator::map_fix`, "Heading"): the
//! map fixes against the arena's exact walls carry their Jacobian on the heading, so two beams on one wall
//! (or one beam over consecutive sweeps as the drone moves) correct the yaw. Oracle: the simulator's true
//! yaw. The drift is made the way a real drone gets it: a gyro bias that changes after the at-rest
//! calibration (a few mrad/s, as the IMU warms up), which the filter cannot know, plus a drone set down a
//! few degrees off the heading the mission was told. Also the map fixes' jump rule (a jump beyond
//! `map_fix_jump_m` needs a second sweep's word).

use cfnav::flight::estimator::map_fix::{MapFix, MapFixes};
use cfnav::flight::estimator::{Estimator, EstimatorConfig};
use cfnav::math::wrap_angle;
use cfnav::stack::{FlightConfig, FlightCore};
use cfnav::types::ImuSample;

use crate::map_fix::airborne_estimator;
use cfnav_sim::physics::Quadrotor;
use cfnav_sim::world::World;
use cfnav_tools::sim::runner::{Faults, SimDrone, mission_params};

/// One mission's errors: (time s, |yaw error| rad, horizontal position error m), every 10 ms airborne.
struct Run {
    samples: Vec<(f64, f32, f32)>,
    heading_fused: u32,
}

/// Flies the default world's mission with the drone placed `yaw0_rad` off the heading the estimator is
/// told (0) and, from 3 s after the start, an extra z gyro bias of `bias_rad_s` the calibration never saw.
fn fly(config: &FlightConfig, seed: u64, yaw0_rad: f32, bias_rad_s: f32) -> Run {
    let world = World::default_world();
    let mut drone = SimDrone::new(&world, seed, &Faults::default()).unwrap();
    let start = world.mission.start;
    let mut quad = Quadrotor::new(*drone.quad.params(), [start[0], start[1], 0.0], yaw0_rad);
    quad.place_on_surface(&world);
    drone.quad = quad;
    *drone.core = FlightCore::new(config, (start[0], start[1]), 0.0).unwrap();
    let mut samples = Vec::new();
    let mut started = false;
    for tick in 0..150_000u64 {
        if tick == 1000 {
            drone.core.start_mission(mission_params(&world)).expect("starts");
            started = true;
        }
        if tick == 4000 {
            let mut b = drone.imu_mut().gyro_bias();
            b[2] += bias_rad_s;
            drone.imu_mut().set_gyro_bias(b);
        }
        drone.step(&world);
        if started && tick.is_multiple_of(10) {
            let truth = drone.quad.position();
            let est = drone.core.estimate();
            if truth[2] > 0.2 {
                let yaw_err = wrap_angle(est.attitude_rad[2] - drone.quad.attitude_rad()[2]).abs();
                let pos_err = (est.position_m[0] - truth[0]).hypot(est.position_m[1] - truth[1]);
                samples.push((tick as f64 * 1e-3, yaw_err, pos_err));
            }
            if !drone.core.mission().is_running() {
                break;
            }
        }
    }
    Run {
        samples,
        heading_fused: drone.core.estimator().diagnostics().map_heading_fused,
    }
}

/// Over three noise seeds of the default world, with a 3° placement error and a 6 mrad/s gyro bias
/// appearing after take-off (≈ 17° over a minute if nothing corrected it): with the heading term the
/// yaw error over the second half of each flight stays within a bound, and so does the position; without
/// it (everything else equal) the yaw and position errors grow past those bounds (worst with vs best
/// without, so every seed separates).
#[test]
fn wall_fixes_hold_the_heading_against_a_gyro_drift() {
    let on = FlightConfig::default();
    let mut off = FlightConfig::default();
    off.estimator.map_fix_heading = false;
    let late_max = |run: &Run| {
        let end = run.samples.last().map_or(0.0, |s| s.0);
        let start = run.samples.first().map_or(0.0, |s| s.0);
        let half = 0.5 * (start + end);
        let late = run.samples.iter().filter(|s| s.0 > half);
        late.fold((0.0f32, 0.0f32), |(y, p), s| (y.max(s.1), p.max(s.2)))
    };
    let mut worst_on = (0.0f32, 0.0f32);
    let mut worst_off = (f32::INFINITY, f32::INFINITY);
    for seed in [3, 7, 11] {
        let with = fly(&on, seed, 0.05, 0.006);
        let without = fly(&off, seed, 0.05, 0.006);
        assert!(
            with.samples.len() > 1000 && without.samples.len() > 1000,
            "seed {seed}: a short flight"
        );
        let (yaw_on, pos_on) = late_max(&with);
        let (yaw_off, pos_off) = late_max(&without);
        println!(
            "seed {seed}: with heading fixes ({} fused) late max yaw {:.2}° pos {:.1} cm; without: yaw {:.2}° pos {:.1} cm",
            with.heading_fused,
            yaw_on.to_degrees(),
            pos_on * 100.0,
            yaw_off.to_degrees(),
            pos_off * 100.0
        );
        assert!(with.heading_fused > 0, "seed {seed}: no heading fix fused");
        worst_on = (worst_on.0.max(yaw_on), worst_on.1.max(pos_on));
        worst_off = (worst_off.0.min(yaw_off), worst_off.1.min(pos_off));
    }
    // Measured (seeds 3, 7, 11): with 2.0–3.3° and 3.1–3.9 cm, without 6.2–10.8° and 12–66 cm. The heading
    // error with the fixes is a lag (the filter has no gyro-bias state: each fix removes part of what the
    // unknown bias turned since the last one), bounded; without them it is the bias integrated.
    // The flights' paths depend on the whole mission (the pad search turning a beam onto unobserved
    // regions, the two-crossing lock, the look at unseen space beside the path, corridor faces as
    // landmarks), so the bounds are set to separate every run with the fixes from every run without them,
    // not to one path. The late position error with the fixes peaks in the obstacle corridor on seed 3
    // (yaw error ≈ 1° there: flow drift between wall fixes, not heading), so its bound is 8 cm, the
    // default mission's maximum. One yaw threshold (4.3°) separates every run with from every run without.
    assert!(
        worst_on.0 <= 0.075,
        "with the heading fixes the late yaw error reaches {}",
        worst_on.0
    );
    assert!(
        worst_on.1 <= 0.08,
        "with the heading fixes the late position error reaches {}",
        worst_on.1
    );
    assert!(
        worst_on.0 < worst_off.0,
        "with {} vs without {}",
        worst_on.0,
        worst_off.0
    );
    assert!(
        worst_off.0 > 0.075,
        "without them the yaw error stays at {}",
        worst_off.0
    );
    assert!(
        worst_on.1 < worst_off.1,
        "position with {} vs without {}",
        worst_on.1,
        worst_off.1
    );
    // The flights slow beside the corridor's thin posts (counted as unobserved), which leaves the bias
    // less distance to act on: measured with 1.7–3.8° and 2.3–4.5 cm, without 4.9–6.7° and 6.7–17.4 cm.
    // So the position bound without is 6 cm; the bound with is the default mission's 8 cm.
    assert!(
        worst_off.1 > 0.06,
        "without them the position error stays at {}",
        worst_off.1
    );
}

/// The fixes of two beams 90° apart on the wall x = 2 (the front at −45° and the left at +45° off its
/// normal), cast as the firmware does from the estimate `est` (position and yaw) while the true heading is
/// `true_yaw` and the true position (1, 1): exact ranges, numbers computed with the estimated heading.
fn two_beam_fixes(est: &Estimator, true_yaw: f32) -> MapFixes {
    let s = est.state();
    let (px, yaw) = (s.position_m[0], s.attitude_rad[2]);
    let mut out = MapFixes::default();
    for (slot, beam) in [
        (0usize, -core::f32::consts::FRAC_PI_4),
        (1, core::f32::consts::FRAC_PI_4),
    ] {
        let r = 1.0 / (true_yaw + beam).cos();
        let measured = |heading: f32| r * heading.cos();
        out.fixes[slot] = Some(MapFix {
            normal: [1.0, 0.0],
            measured_m: measured(yaw + beam),
            expected_m: 2.0 - px,
            std_m: 0.005 + 0.02 * r,
            // d(measured)/d(heading), by a central difference (the definition, not the formula).
            yaw_lever_m: (measured(yaw + beam + 1e-3) - measured(yaw + beam - 1e-3)) / 2e-3,
        });
    }
    out
}

/// Two beams on one wall: a heading error shortens one beam's distance along the normal and lengthens the
/// other's, which no position explains. Repeated sweeps (a 3 s hover) turn the estimate to the true
/// heading (oracle: the geometry above) and keep the position; switched off, nothing turns; a fix whose
/// turn would exceed the bound is rejected.
#[test]
fn two_beams_on_one_wall_turn_the_heading() {
    let still = ImuSample {
        gyro_rad_s: [0.0; 3],
        accel_m_s2: [0.0, 0.0, cfnav::types::GRAVITY_M_S2],
    };
    let hover = |cfg: EstimatorConfig, delta: f32| {
        let mut est = airborne_estimator(cfg);
        for _ in 0..30 {
            let fixes = two_beam_fixes(&est, delta);
            est.on_map_fixes(&fixes);
            for _ in 0..100 {
                est.on_imu(&still, 0.001);
            }
        }
        est
    };
    let delta = 0.03f32;
    let est = hover(EstimatorConfig::default(), delta);
    let yaw = est.state().attitude_rad[2];
    assert!(est.diagnostics().map_heading_fused >= 50);
    assert!((yaw - delta).abs() < 0.3 * delta, "turned to {yaw}, truth {delta}");
    assert!(
        (est.state().position_m[0] - 1.0).abs() < 0.01,
        "x {}",
        est.state().position_m[0]
    );

    let off = hover(
        EstimatorConfig {
            map_fix_heading: false,
            ..EstimatorConfig::default()
        },
        delta,
    );
    assert_eq!(off.diagnostics().map_heading_fused, 0);
    assert!(
        off.state().attitude_rad[2].abs() < 1e-4,
        "off: turned {}",
        off.state().attitude_rad[2]
    );
    let exact = hover(EstimatorConfig::default(), 0.0);
    assert!(
        exact.state().attitude_rad[2].abs() < 2e-3,
        "no error: turned {}",
        exact.state().attitude_rad[2]
    );

    // A bound of 0.1 mrad per fix rejects them all.
    let tight = hover(
        EstimatorConfig {
            map_fix_max_yaw_step_rad: 1e-4,
            ..EstimatorConfig::default()
        },
        delta,
    );
    assert_eq!(tight.diagnostics().map_heading_fused, 0);
    assert!(tight.state().attitude_rad[2].abs() < 1e-4);
}

/// One wall fix along +x with `innovation_m` (measured − expected), no heading lever.
fn x_fix(innovation_m: f32) -> MapFixes {
    let mut out = MapFixes::default();
    out.fixes[0] = Some(MapFix {
        normal: [1.0, 0.0],
        measured_m: 1.0 + innovation_m,
        expected_m: 1.0,
        std_m: 0.01,
        yaw_lever_m: 0.0,
    });
    out
}

/// A fix implying a jump beyond `map_fix_jump_m` (here 10 cm, inside the 3σ gate of a 5 cm position std)
/// moves nothing alone: a beam that met another surface in one sweep (training world 21000241: a 14 cm
/// step) is held back. The same jump in the next sweep is a real drift and is fused; a different one is
/// not; with the rule switched off (a 10 m threshold) the single sweep moves the estimate.
#[test]
fn a_jump_needs_a_second_sweep() {
    let x0 = |e: &Estimator| e.state().position_m[0];
    let mut est = airborne_estimator(EstimatorConfig::default());
    let start = x0(&est);
    est.on_map_fixes(&x_fix(0.10));
    assert_eq!(est.diagnostics().map_jumps_held, 1);
    assert_eq!(x0(&est), start, "a single sweep's jump moved the estimate");
    // A disagreeing jump (−10 cm) does not confirm it.
    est.on_map_fixes(&x_fix(-0.10));
    assert_eq!(est.diagnostics().map_jumps_held, 2);
    assert_eq!(x0(&est), start);
    // Two sweeps agreeing: fused; the wall is nearer than believed, so the drone is further towards +x.
    est.on_map_fixes(&x_fix(-0.09));
    assert_eq!(est.diagnostics().map_fused, 1);
    assert!(x0(&est) > start + 0.03, "moved to {} from {start}", x0(&est));
    // Small innovations need no confirmation.
    let mut small = airborne_estimator(EstimatorConfig::default());
    small.on_map_fixes(&x_fix(0.03));
    assert_eq!(small.diagnostics().map_fused, 1);
    // Without the rule the single jump is fused at once.
    let mut off = airborne_estimator(EstimatorConfig {
        map_fix_jump_m: 10.0,
        ..EstimatorConfig::default()
    });
    off.on_map_fixes(&x_fix(0.10));
    assert_eq!(off.diagnostics().map_fused, 1);
    assert!(x0(&off) < start - 0.05);
}
