//! The whole flight stack in the simulator: hover and steps flown through the firmware's step functions on
//! simulated sensors, the estimator against the simulator's truth, and the mission's outcomes on the
//! shipped worlds and under faults (each judged on the true state by the runner).

use cfnav::mission::{MissionParams, MissionState};
use cfnav::types::Setpoint;
use cfnav_sim::world::World;
use cfnav_tools::sim::runner::{Faults, RunOptions, SimDrone, run};

use crate::{default_world_enters, on_pad_centre_or_clear_of_it};

/// Fly commander setpoints (a function of time) on the default world's start, through the simulator's
/// lockstep drone, and return the truth trace (t, position) sampled every 10 ms.
fn fly_commander(seconds: f64, seed: u64, setpoint: impl Fn(f64) -> Setpoint) -> Vec<(f64, [f32; 3])> {
    fly_commander_in(&World::default_world(), seconds, seed, setpoint).0
}

/// The same on any world; also returns the drone at the end (for its diagnostics).
fn fly_commander_in(
    world: &World,
    seconds: f64,
    seed: u64,
    setpoint: impl Fn(f64) -> Setpoint,
) -> (Vec<(f64, [f32; 3])>, SimDrone) {
    let mut drone = SimDrone::new(world, seed, &Faults::default()).unwrap();
    let mut trace = Vec::new();
    for tick in 0..(seconds * 1000.0) as u64 {
        let t = tick as f64 * 1e-3;
        if tick.is_multiple_of(10) {
            trace.push((t, drone.quad.position()));
        }
        if tick.is_multiple_of(20) {
            drone.core.commander_setpoint(setpoint(t), tick * 1000);
        }
        drone.step(world);
    }
    (trace, drone)
}

/// Stop for 1.5 s (calibration, thrust lock), then hold 0.5 m above the world's start.
fn hover_at_start(world: &World) -> impl Fn(f64) -> Setpoint {
    let (x0, y0) = (world.mission.start[0], world.mission.start[1]);
    move |t| {
        if t < 1.5 {
            Setpoint::Stop
        } else {
            Setpoint::Position {
                x_m: x0,
                y_m: y0,
                z_m: 0.5,
                yaw_rad: 0.0,
            }
        }
    }
}

fn window(trace: &[(f64, [f32; 3])], from: f64, to: f64) -> Vec<[f32; 3]> {
    trace
        .iter()
        .filter(|(t, _)| *t >= from && *t < to)
        .map(|(_, p)| *p)
        .collect()
}

/// The worst per-axis deviation from the mean position over 10 s of hover, and the mean.
fn hover_deviation(world: &World, seed: u64) -> ([f32; 3], [f32; 3]) {
    let (trace, _) = fly_commander_in(world, 16.0, seed, hover_at_start(world));
    let hover = window(&trace, 6.0, 16.0);
    let n = hover.len() as f32;
    let mean = [0, 1, 2].map(|i| hover.iter().map(|p| p[i]).sum::<f32>() / n);
    let worst = [0, 1, 2].map(|i| hover.iter().map(|p| (p[i] - mean[i]).abs()).fold(0.0f32, f32::max));
    (worst, mean)
}

/// Hovers at the world's start under noise seeds 1–10, checking on each that the height stays within ±1 cm,
/// that it hovers where it was told (the estimate's frame starts at the start point) and that the horizontal
/// worst deviation is at most `max_horizontal_m`. Returns those worst deviations, sorted.
fn hover_ten_seeds(world: &World, label: &str, max_horizontal_m: f32) -> Vec<f32> {
    let (x0, y0) = (world.mission.start[0], world.mission.start[1]);
    let mut horizontal = Vec::new();
    for seed in 1..=10 {
        let (worst, mean) = hover_deviation(world, seed);
        println!(
            "{label} seed {seed}: worst deviation from the mean over 10 s, x/y/z: {:.1} / {:.1} / {:.1} mm",
            worst[0] * 1e3,
            worst[1] * 1e3,
            worst[2] * 1e3
        );
        assert!(worst[2] <= 0.01, "seed {seed}: height wandered {} m", worst[2]);
        assert!(
            worst[0].max(worst[1]) <= max_horizontal_m,
            "seed {seed}: hover wandered {worst:?} m"
        );
        assert!(
            (mean[0] - x0).abs() < 0.1 && (mean[1] - y0).abs() < 0.1,
            "hover at {mean:?}"
        );
        horizontal.push(worst[0].max(worst[1]));
    }
    horizontal.sort_by(f32::total_cmp);
    horizontal
}

/// The goal: ±3 cm on each axis for 10 s, with every sensor's noise. Hovering at the default world's start
/// the Multi-ranger sees the arena's walls 0.6–1.7 m away, and the estimator's wall anchors hold the
/// position against them (flow alone wanders ≈ 1 cm/√s: see the open-floor test below). Every one of ten
/// seeds must stay within ±3 cm, and the height within ±1 cm.
#[test]
fn hover_holds_within_3_cm_for_10_s_with_sensor_noise() {
    let horizontal = hover_ten_seeds(&World::default_world(), "hover", 0.03);
    println!(
        "hover by walls: median worst {:.1} mm, worst {:.1} mm",
        horizontal[5] * 1e3,
        horizontal[9] * 1e3
    );
}

/// The wall anchors are the commander's: a hover fuses wall ranges, a running mission (whose holds over a
/// pad are short, and whose landings measured no better with them) never does.
#[test]
fn wall_anchors_serve_the_commanders_hover_not_the_mission() {
    let world = World::default_world();
    let (_, hover) = fly_commander_in(&world, 8.0, 3, hover_at_start(&world));
    let d = hover.core.estimator().diagnostics();
    println!(
        "hover: {} wall ranges fused, {} rejected",
        d.wall_fused, d.wall_rejected
    );
    // Four beams at 10 Hz for the ~5 s of still hover after the climb.
    assert!(d.wall_fused > 100, "{d:?}");

    let mut mission = SimDrone::new(&world, 3, &Faults::default()).unwrap();
    let params = cfnav_tools::sim::runner::mission_params(&world);
    for tick in 0..40_000u64 {
        if tick == 1000 {
            mission.core.start_mission(params).expect("starts");
        }
        mission.step(&world);
    }
    let d = mission.core.estimator().diagnostics();
    assert_eq!((d.wall_fused, d.wall_rejected), (0, 0), "{d:?}");
}

/// The same hover in the middle of a 12 × 12 m hall, every wall beyond the Multi-ranger's 4 m: only the
/// flow observes the position, and the simulated flow noise (1 count per reading) makes it a random walk of
/// ≈ 1 cm/√s, which the controller follows (it holds the *estimate* within ~1 cm). This is the open-floor
/// limit, asserted as the distribution measured (median seed within ±4.5 cm, none beyond ±6 cm) so that it
/// cannot get worse unnoticed; with half the flow noise it halves (BENCHMARKS.md §5).
#[test]
fn hover_on_open_floor_drifts_with_the_flow_noise() {
    let mut world = World::default_world();
    world.arena.size = [12.0, 12.0];
    world.mission.start = [6.0, 6.0];
    world.mission.goal = [7.0, 6.0];
    world.boxes.clear();
    world.cylinders.clear();
    world.pads.truncate(1);
    world.pads[0].center = [6.0, 6.0];
    let horizontal = hover_ten_seeds(&world, "open-floor hover", 0.06);
    let within = horizontal.iter().filter(|w| **w <= 0.03).count();
    println!(
        "open-floor hover: {within} of 10 seeds within ±3 cm; median worst {:.1} mm",
        horizontal[5] * 1e3
    );
    assert!(horizontal[5] <= 0.045, "median seed {} m", horizontal[5]);
}

#[test]
fn position_step_settles_with_less_than_20_percent_overshoot() {
    let world = World::default_world();
    let (x0, y0) = (world.mission.start[0], world.mission.start[1]);
    let trace = fly_commander(16.0, 5, |t| {
        if t < 1.5 {
            Setpoint::Stop
        } else if t < 8.0 {
            Setpoint::Position {
                x_m: x0,
                y_m: y0,
                z_m: 0.5,
                yaw_rad: 0.0,
            }
        } else {
            Setpoint::Position {
                x_m: x0 + 1.0,
                y_m: y0,
                z_m: 0.5,
                yaw_rad: 0.0,
            }
        }
    });
    let before = window(&trace, 7.0, 8.0);
    let x_before = before.iter().map(|p| p[0]).sum::<f32>() / before.len() as f32;
    let after = window(&trace, 8.0, 16.0);
    let x_final = window(&trace, 14.0, 16.0).iter().map(|p| p[0]).sum::<f32>() / 200.0;
    let peak = after.iter().map(|p| p[0]).fold(f32::MIN, f32::max);
    let step = x_final - x_before;
    let overshoot = (peak - x_final) / step;
    let settle = trace
        .iter()
        .filter(|(t, _)| *t >= 8.0)
        .rev()
        .find(|(_, p)| (p[0] - x_final).abs() > 0.05 * step)
        .map_or(0.0, |(t, _)| t - 8.0);
    println!(
        "1 m step: moved {step:.3} m, overshoot {:.1} %, settled (±5 %) after {settle:.2} s",
        overshoot * 100.0
    );
    assert!((step - 1.0).abs() < 0.1, "moved {step}");
    assert!(overshoot < 0.2, "overshoot {overshoot}");
    assert!(settle < 5.0, "settle {settle}");
}

fn fly(world: &World, faults: Faults) -> cfnav_tools::sim::runner::RunReport {
    let mut options = RunOptions::for_world(world);
    options.faults = faults;
    run(world, &options).expect("runs").report
}

/// The default world under 120 noise seeds: every flight completes without a collision on both pads, the
/// landings meet the accuracy goal as a distribution (median ≤ 3 cm, 95 % ≤ 6 cm; one landing is one
/// draw of the flow-only drift, so a single landing against the p95 bound would fail one run in ten, and
/// 80 landings put the measured p95 anywhere from 5 to 7 cm), the median mission takes at most 60 s, and the
/// estimator stays within its stated bounds.
#[test]
fn default_world_completes_and_the_estimator_stays_close_to_the_truth() {
    const SEEDS: u64 = 120;
    let world = World::default_world();
    let mut errors = Vec::new();
    let mut rms = Vec::new();
    let mut times = Vec::new();
    for seed in 1..=SEEDS {
        let mut options = RunOptions::for_world(&world);
        options.seed = seed;
        let r = run(&world, &options).expect("runs").report;
        println!("seed {seed}: {:?} s, landings {:?}", r.mission_time_s, r.landings);
        assert_eq!(r.outcome, "completed", "seed {seed}: {r:?}");
        assert_eq!(r.collisions, 0, "seed {seed}");
        assert_eq!(r.landings.len(), 2, "seed {seed}");
        assert!(r.landings.iter().all(|l| l.on_pad), "seed {seed}: {:?}", r.landings);
        errors.extend(r.landings.iter().map(|l| l.error_m));
        times.push(r.mission_time_s.expect("a completed mission has a time"));
        // Stated bounds for flow-only navigation (no absolute position fix, the drift a random walk of the
        // flow noise, so the worst of ten seeds is about twice the median): see BENCHMARKS.md.
        assert!(
            r.rms_estimate_error_m < 0.2,
            "seed {seed}: rms {}",
            r.rms_estimate_error_m
        );
        rms.push(r.rms_estimate_error_m);
        assert!(
            r.max_estimate_error_m < 0.35,
            "seed {seed}: max {}",
            r.max_estimate_error_m
        );
        // Height above the surface below; the worst instants are the pad edges (a step is judged over three
        // ranges, 75 ms) and the re-anchoring on leaving the home pad.
        assert!(
            r.max_height_error_m < 0.15,
            "seed {seed}: height {}",
            r.max_height_error_m
        );
    }
    rms.sort_by(f32::total_cmp);
    let median_rms = rms[rms.len() / 2];
    println!(
        "default world, {SEEDS} seeds: median RMS estimate error {:.1} cm",
        median_rms * 100.0
    );
    assert!(median_rms < 0.1, "median RMS estimate error {median_rms} m");
    errors.sort_by(f32::total_cmp);
    let median = errors[errors.len() / 2];
    let within_6_cm = errors.iter().filter(|e| **e <= 0.06).count();
    println!(
        "default world, {} landings: median {:.1} cm, {within_6_cm} within 6 cm",
        errors.len(),
        median * 100.0
    );
    assert!(median <= 0.03, "median landing error {median} m");
    assert!(20 * within_6_cm >= 19 * errors.len(), "landing errors {errors:?}");
    times.sort_by(f64::total_cmp);
    let median_time = times[times.len() / 2];
    println!("default world: median mission time {median_time:.1} s");
    assert!(median_time <= 60.0, "median mission time {median_time} s");
}

/// The default world's round trip takes at most 55 s on its own noise seed (7) and as the median
/// of noise seeds 1–12, with both landings on their pads. Before the goal leg's first search line was steered
/// onto (`src/mission/search.rs`, `line_carrot`) it took 58.0 s and 55.75 s: joined 5 cm off that line and
/// flown straight at its far end, the first line passed the goal pad's edge, found nothing, and the next
/// line cost ~3 s (BENCHMARKS.md §5, mission time).
#[test]
fn default_world_mission_time_is_at_most_55_s() {
    let world = World::default_world();
    let mut times = Vec::new();
    for seed in 1..=12 {
        let mut options = RunOptions::for_world(&world);
        options.seed = seed;
        let r = run(&world, &options).expect("runs").report;
        assert_eq!(r.outcome, "completed", "seed {seed}: {r:?}");
        assert_eq!(r.collisions, 0, "seed {seed}");
        assert!(r.landings.iter().all(|l| l.on_pad), "seed {seed}: {:?}", r.landings);
        let t = r.mission_time_s.expect("a completed mission has a time");
        println!("seed {seed}: {t:.1} s");
        if seed == 7 {
            assert!(t <= 55.0, "seed 7 (the world's own): {t} s");
        }
        times.push(t);
    }
    times.sort_by(f64::total_cmp);
    let median = 0.5 * (times[5] + times[6]);
    assert!(median <= 55.0, "median of noise seeds 1–12: {median} s ({times:?})");
}

/// Flights whose pad searches once left the estimator's surface a pad's height too high (each crossing's
/// blurred edges added up, or a pad left within the settling time counted as the rest of the step onto it):
/// the height estimate went as wrong, so the drone cruised 10–15 cm lower than commanded and, in the gap
/// world, lost its way through the opening. Now flying off a pad returns the surface to the floor it came
/// from: while navigating, the height estimate stays within 3 cm of the truth.
#[test]
fn pad_searches_leave_the_height_estimate_alone() {
    let gap = World::load(format!("{}/../worlds/gap.toml", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let cases = [
        (gap, 8),
        (World::random_classic(1_000_082), 1_000_082),
        (World::random_classic(2_000_084), 2_000_084),
    ];
    for (world, seed) in cases {
        let mut options = RunOptions::for_world(&world);
        options.seed = seed;
        options.record = true;
        let result = run(&world, &options).expect("runs");
        // Navigating, from 2 s after the leg's start (leaving the take-off pad re-anchors the height once).
        let mut entered = (0u8, 0.0f64);
        let mut worst = 0.0f32;
        for p in &result.trace {
            if p.state != entered.0 {
                entered = (p.state, p.t_s);
            }
            if (p.state == 11 || p.state == 21) && p.t_s - entered.1 >= 2.0 {
                worst = worst.max((p.truth[2] - p.estimate[2]).abs());
            }
        }
        println!(
            "{} seed {seed}: worst height estimate error while navigating {:.1} cm, {}",
            world.name,
            worst * 100.0,
            result.report.outcome
        );
        assert!(
            worst < 0.03,
            "{} seed {seed}: height estimate {worst} m off while navigating",
            world.name
        );
    }
}

#[test]
fn enclosed_goal_ends_with_no_path_landed_motors_off_no_collision() {
    for name in ["fail-enclosed-goal", "fail-narrow-gap"] {
        let world = World::load(format!("{}/../worlds/{name}.toml", env!("CARGO_MANIFEST_DIR"))).unwrap();
        let r = fly(&world, Faults::default());
        assert_eq!((r.outcome, r.reason), ("aborted", Some("no_path")), "{name}: {r:?}");
        assert_eq!(r.collisions, 0, "{name}");
        assert_eq!(r.mission_state, 201, "{name}");
        // The runner only ends a run once the drone rests with its motors stopped.
        assert_eq!(r.landings.len(), 1, "{name}: landed once, where it gave up");
    }
}

#[test]
fn battery_low_mid_flight_lands() {
    let world = World::default_world();
    let r = fly(
        &world,
        Faults {
            battery_state_of_charge: Some(0.35),
            battery_drain_multiplier: Some(6.0),
            ..Faults::default()
        },
    );
    assert_eq!((r.outcome, r.reason), ("aborted", Some("battery")), "{r:?}");
    assert_eq!(r.collisions, 0);
    assert_eq!(r.mission_state, 203);
    assert!(!r.landings.is_empty(), "it landed");
}

#[test]
fn abort_through_mission_start_0_lands() {
    let world = World::default_world();
    let r = fly(
        &world,
        Faults {
            abort_at_s: Some(8.0),
            ..Faults::default()
        },
    );
    assert_eq!((r.outcome, r.reason), ("aborted", Some("aborted")), "{r:?}");
    assert_eq!(r.collisions, 0);
    assert_eq!(r.mission_state, 200);
    assert_eq!(r.landings.len(), 1);
    assert!(
        r.mission_time_s.unwrap() < 15.0,
        "landed soon after the abort: {:?}",
        r.mission_time_s
    );
}

/// The flow deck dies before take-off (the drone lifts off, loses validity a second later and lands) or at
/// any time in flight — a sweep of failure times every 2 s over the whole default mission: the drone lands,
/// motors off, the mission ends `estimator_fault` (or had already completed), and nothing is ever hit in
/// flight. The known gap, measured here rather than hidden: without flow the horizontal position is
/// unobserved, so a failure while the drone searches over a pad can bring it down across the pad's rim
/// (the score counts the body touching the pad's top edge at touchdown as a collision): 2 of these 40
/// failure times today (8 of 77 in a 1 s sweep, BENCHMARKS.md). The test fails on any other collision, or
/// if rim touchdowns grow beyond a quarter of the sweep.
#[test]
fn flow_deck_failure_lands_safely() {
    let world = World::default_world();
    let mut rim_touchdowns = 0;
    let times: Vec<f64> = (0..40).map(|k| 0.5 + 2.0 * f64::from(k)).collect();
    for &t in &times {
        let r = fly(
            &world,
            Faults {
                flow_fails_at_s: Some(t),
                ..Faults::default()
            },
        );
        if r.outcome == "completed" {
            // The mission was over before the failure (its time runs from the trigger, 1 s into the run).
            let ended = r.mission_time_s.expect("a completed mission has a time");
            // Or the flow died during the very last descent onto the home pad (the estimator's 0.5 s sensor
            // timeout and the touchdown race there): the mission may then complete, but only on both pads.
            assert!(
                t >= ended || (t + 1.5 >= ended && r.landings.len() == 2 && r.landings.iter().all(|l| l.on_pad)),
                "at {t} s: {r:?}"
            );
            continue;
        }
        // The mission's own verdict; the score's outcome says `collision` when a rim touchdown happened.
        let expected = if r.collisions > 0 {
            "collision"
        } else {
            "estimator_fault"
        };
        assert_eq!(r.reason, Some(expected), "at {t} s: {r:?}");
        // Failing on the goal pad, the drone lands there, lifts off for the return (the flow is needed only
        // above 0.15 m), sees the fault and lands again: one or two landings.
        assert!(matches!(r.landings.len(), 1 | 2), "at {t} s: {:?}", r.landings);
        assert_eq!(r.mission_state, 204, "at {t} s");
        for (state, point) in r.collision_states.iter().zip(&r.collision_points) {
            // Only the blind touchdown (emergency landing, state 40) across a pad's rim: the body no
            // higher than the pad's top, its centre within a body radius (6 cm) of the pad's footprint.
            let on_rim = world.pads.iter().any(|pad| {
                let dx = ((point[0] - pad.center[0]).abs() - 0.5 * pad.size[0]).max(0.0);
                let dy = ((point[1] - pad.center[1]).abs() - 0.5 * pad.size[1]).max(0.0);
                dx.hypot(dy) <= 0.07 && point[2] <= pad.height + 0.01
            });
            assert!(
                *state == 40 && on_rim,
                "at {t} s: a collision in state {state} at {point:?}"
            );
        }
        if r.collisions > 0 {
            rim_touchdowns += 1;
        }
    }
    println!(
        "flow failure at {} times: {rim_touchdowns} touchdowns across a pad's rim, no other collision",
        times.len()
    );
    assert!(rim_touchdowns * 4 <= times.len(), "{rim_touchdowns} rim touchdowns");
}

#[test]
fn missing_deck_refuses_the_start() {
    let world = World::default_world();
    let r = fly(
        &world,
        Faults {
            decks_missing: true,
            ..Faults::default()
        },
    );
    assert_eq!((r.outcome, r.reason), ("aborted", Some("start_refused")), "{r:?}");
    assert!(r.landings.is_empty());
    assert_eq!(r.distance_m, 0.0);
}

#[test]
fn runs_are_deterministic_for_a_seed() {
    let world = World::default_world();
    let a = fly(&world, Faults::default());
    let b = fly(&world, Faults::default());
    assert_eq!(
        format!("{:?}", (a.outcome, a.landings, a.mission_time_s, a.replans)),
        format!("{:?}", (b.outcome, b.landings, b.mission_time_s, b.replans))
    );
}

/// An abort near a pad: the landing where the drone is follows the link-loss policy's rule (one
/// function, `Mission::land_where_it_is`): within 0.3 m of a pad whose centre the mission knows (the home
/// pad, a pad once locked), or approaching / descending onto a pad, it lands on that pad's centre instead of
/// across its rim. Aborts through the default mission (trigger at 1 s): just after take-off beside the home
/// pad, during the goal pad's approach and descent, and far from any pad (lands where it is). Judged on the
/// truth: where the drone was at the abort, where it came to rest, which pad it landed on.
#[test]
fn an_abort_near_a_pad_lands_on_its_centre() {
    let world = World::default_world();
    let mut near_pad_cases = 0;
    // The goal pad's approach and descent, from a run without an abort.
    let approach_s = default_world_enters(MissionState::ApproachGoalPad);
    let descent_s = default_world_enters(MissionState::LandOnGoalPad);
    for abort_s in [3.0, 3.5, 8.0, approach_s + 0.8, descent_s + 0.4] {
        let mut options = RunOptions::for_world(&world);
        options.record = true;
        options.faults = Faults {
            abort_at_s: Some(abort_s),
            ..Faults::default()
        };
        let r = run(&world, &options).expect("runs");
        let rep = &r.report;
        assert_eq!(
            (rep.outcome, rep.reason),
            ("aborted", Some("aborted")),
            "abort at {abort_s} s: {rep:?}"
        );
        assert_eq!(rep.collisions, 0, "abort at {abort_s} s");
        let at_abort = r
            .trace
            .iter()
            .find(|p| p.t_s >= abort_s)
            .expect("a trace point at the abort")
            .truth;
        let rest = r.trace.last().expect("a trace").truth;
        let last = rep.landings.last().expect("it landed");
        let near = world
            .pads
            .iter()
            .position(|p| (p.center[0] - at_abort[0]).hypot(p.center[1] - at_abort[1]) < 0.25);
        println!("abort at {abort_s} s at {at_abort:?}: rest {rest:?}, {last:?}");
        match near {
            Some(i) => {
                near_pad_cases += 1;
                assert!(
                    last.pad == i && last.on_pad && last.error_m < 0.06,
                    "abort at {abort_s} s near pad {i}: landed {last:?}"
                );
            }
            None => {
                let off = (rest[0] - at_abort[0]).hypot(rest[1] - at_abort[1]);
                assert!(off < 0.15, "abort at {abort_s} s: came to rest {off} m away");
            }
        }
    }
    assert!(near_pad_cases >= 2, "the sweep must include aborts near a pad");
}

/// An abort at any moment of a pad search, before the pad is located: landing exactly where the drone is
/// can put the body across the pad's rim. Measured before the rules below, aborts every 0.1 s through the
/// default world's searches touched a pad's side in 13 of 82 runs during the goal search (81 of 808 over
/// noise seeds 1–8: an edge just crossed and not yet reported, or no edge seen at all) and 4 of 66 during
/// the home search (moved off the detector's estimate of the home pad after being put on its centre). Now
/// (`Mission::land_where_it_is`): where the goal pad may lie and is not located, the nearest floor spot clear
/// of anywhere it can be; near the home pad, its centre as the mission knows it; a moved point is flown to
/// at cruise height before the descent. Every abort lands with no collision, on the pad's centre or clear of
/// it, and soon (within 6 s).
#[test]
fn an_abort_anywhere_in_a_pad_search_lands_on_the_pad_or_clear_of_it() {
    let world = World::default_world();
    for (search, approach, pad_index) in [
        (
            MissionState::SearchGoalPad,
            MissionState::ApproachGoalPad,
            world.pads.len() - 1,
        ),
        (MissionState::SearchHomePad, MissionState::ApproachHomePad, 0),
    ] {
        let (search_s, approach_s) = (default_world_enters(search), default_world_enters(approach));
        let mut abort_s = search_s + 0.05;
        let mut aborts = 0;
        while abort_s < approach_s {
            let mut options = RunOptions::for_world(&world);
            options.faults = Faults {
                abort_at_s: Some(abort_s),
                ..Faults::default()
            };
            let rep = run(&world, &options).expect("runs").report;
            println!(
                "{search:?}, abort at {abort_s:.2} s: {} {:?}, landings {:?}",
                rep.outcome, rep.reason, rep.landings
            );
            assert_eq!(rep.collisions, 0, "abort at {abort_s:.2} s: {rep:?}");
            assert_eq!(
                (rep.outcome, rep.reason),
                ("aborted", Some("aborted")),
                "abort at {abort_s:.2} s"
            );
            let last = rep.landings.last().expect("it landed");
            assert!(
                on_pad_centre_or_clear_of_it(&world, pad_index, last),
                "abort at {abort_s:.2} s: landed {last:?}, neither on the pad's centre nor clear of it"
            );
            let end_s = 1.0 + rep.mission_time_s.expect("the motors stopped");
            assert!(end_s - abort_s < 6.0, "abort at {abort_s:.2} s: down at {end_s:.2} s");
            aborts += 1;
            abort_s += 0.1;
        }
        assert!(aborts >= 40, "{search:?}: {aborts} aborts through the search");
    }
}

/// A battery that runs low during a long home search lands clear of the home pad it has not located yet.
/// Generated world 100000475 (the take-off point on the floor, the home pad 0.3 m beside it) with the battery
/// started low: the home search has gone on for 16 s when the battery runs low with the drone over the home
/// pad (its body disc across the rim). The landing where it was (before: moved only off the pad edges the
/// detector had reported) touched the pad's side; now, within reach of the take-off point and with the home
/// pad not located, it lands on the nearest floor spot clear of wherever that pad can be, as on the outbound
/// leg near the goal.
/// The start voltage is what puts the low battery in that phase, and it moves with any change of the
/// flight; it is found by a scan of 3.8800–3.9000 V in 0.2 mV steps. With the current flight it is
/// 3.8938 V (3.8894, 3.8914, 3.8942, 3.8956, 3.8964, 3.8970 and 3.8982 V give the scene too, and none
/// gives it with a landing against the pad). The test
/// checks the scene itself, so a flight change that moves it fails here rather than passing on a different
/// scene.
#[test]
fn a_battery_low_in_the_home_search_lands_clear_of_the_home_pad() {
    let mut world = World::random(100_000_475);
    let low_start = "[disturbances]\nbattery_start_v = 3.8938\n";
    let stress = cfnav_sim::stress::Stress::from_toml_str(low_start, "battery 3.8938 V").expect("parses");
    world.stress = world.stress.overlaid(&stress);
    let mut options = RunOptions::for_world(&world);
    options.seed = 100_000_475;
    options.record = true;
    let result = run(&world, &options).expect("runs");
    let rep = &result.report;
    // The scene: the battery ran low during the home search, with the drone over the home pad's footprint
    // (else re-pick the start voltage).
    assert_eq!((rep.outcome, rep.reason), ("aborted", Some("battery")), "{rep:?}");
    let search = MissionState::SearchHomePad as u8;
    let low = result
        .trace
        .windows(2)
        .find(|w| w[0].state == search && w[1].state != search)
        .map(|w| w[1])
        .expect("the home search ended");
    let search_start = result
        .trace
        .iter()
        .find(|p| p.state == search)
        .expect("home search")
        .t_s;
    let pad = &world.pads[0];
    let over_pad = (0..2).all(|k| (low.truth[k] - pad.center[k]).abs() < pad.size[k] / 2.0);
    assert!(
        over_pad && low.t_s - search_start > 10.0,
        "the home search ended at {:.2} s ({:.1} s in) at {:?}, not a long search ending over the pad",
        low.t_s,
        low.t_s - search_start,
        low.truth
    );
    assert_eq!(rep.collisions, 0, "{rep:?}");
    let last = rep.landings.last().expect("it landed");
    assert!(
        on_pad_centre_or_clear_of_it(&world, 0, last),
        "landed {last:?}, neither on the home pad's centre nor clear of it"
    );
}

/// One millisecond of a round trip flown tick by tick: the mission starts 1 s after power-on (as
/// `cfnav sim` starts it) and a radio packet arrives every 10 ms, so the link-loss watch stays quiet.
fn mission_tick(drone: &mut SimDrone, world: &World, params: MissionParams, tick: u64) {
    if tick == 1000 {
        drone.core.start_mission(params).expect("starts");
    }
    if tick.is_multiple_of(10) {
        drone.core.on_radio_packet(tick * 1000);
    }
    drone.step(world);
}

/// Flying off the home pad, the downward range drops by the pad's height below the surface the estimate
/// counts heights from; the estimator re-anchors the height on the floor. That jump says nothing about the
/// vertical velocity: measured against the simulator's truth over the 3 s after the drone's centre leaves
/// the pad (while the controller takes it down onto the floor-referred cruise height), the estimated
/// vertical velocity stays within 3 cm/s of the truth. (Inflating its variance there let the re-anchoring
/// range bend it: 0.034–0.069 m/s off on noise seeds 3, 4 and 6 of the default world, and 0.15 m/s in
/// a stressed world, where the next ranges then read the unseen descent as a surface rising and the drone
/// sank onto the floor believing it held 0.5 m.)
#[test]
fn flying_off_the_home_pad_keeps_the_vertical_velocity() {
    let world = World::default_world();
    let params = cfnav_tools::sim::runner::mission_params(&world);
    let mut report = Vec::new();
    for seed in 1..=8u64 {
        let mut drone = SimDrone::new(&world, seed, &Faults::default()).unwrap();
        let mut off_pad_at: Option<u64> = None;
        let mut worst = 0.0f32;
        for tick in 0..8000u64 {
            mission_tick(&mut drone, &world, params, tick);
            let p = drone.quad.position();
            if off_pad_at.is_none() && tick > 1500 && world.surface_height(p[0], p[1]) == 0.0 {
                off_pad_at = Some(tick);
            }
            if off_pad_at.is_some_and(|t0| tick < t0 + 3000) {
                worst = worst.max((drone.core.estimate().velocity_m_s[2] - drone.quad.velocity()[2]).abs());
            }
        }
        assert!(off_pad_at.is_some(), "seed {seed}: never left the home pad");
        report.push((seed, worst));
    }
    println!("vertical velocity error after leaving the home pad, m/s: {report:?}");
    for (seed, worst) in report {
        assert!(
            worst < 0.03,
            "seed {seed}: vertical velocity {worst} m/s off after leaving the pad"
        );
    }
}

/// The estimator learns the flow's scale error from the arena's walls (its module docs, "Flow scale"),
/// judged against the simulator's own: the default world flown with `flow_scale_error` −0.05, 0 and +0.05
/// (the magnitude of the world-file example in docs/formats.md), noise seeds 1–3. When the drone lands home (≈ 12 m flown
/// past walls) the held scale error lies within 2.5 percentage points of the truth and within 2.5 of its
/// own std, that std has come down from the prior's 0.05 to under 0.02, and per seed the +5 % flight holds
/// at least 6 points more than the −5 % one: it was learnt, not left at 0. (Measured: held −4.3 to −3.4,
/// +0.4 to +2.0, +5.6 to +6.5 %, std 1.1 %; seed 1 sits about 1.5 points high in all three.)
#[test]
fn the_flow_scale_is_learnt_from_the_walls() {
    let mut report = Vec::new();
    for truth in [-0.05f32, 0.0, 0.05] {
        for seed in 1..=3u64 {
            let mut world = World::default_world();
            let text = format!("[sensors]\nflow_scale_error = {truth}\n");
            let stress = cfnav_sim::stress::Stress::from_toml_str(&text, "scale").expect("parses");
            world.stress = world.stress.overlaid(&stress);
            let params = cfnav_tools::sim::runner::mission_params(&world);
            let mut drone = SimDrone::new(&world, seed, &Faults::default()).unwrap();
            let mut at_home: Option<(f32, f32)> = None;
            for tick in 0..120_000u64 {
                mission_tick(&mut drone, &world, params, tick);
                if drone.core.mission_state() == MissionState::LandOnHomePad {
                    let d = drone.core.estimator().diagnostics();
                    at_home = Some((d.flow_scale_error, d.flow_scale_std));
                    break;
                }
            }
            let (held, std) = at_home.unwrap_or_else(|| panic!("scale {truth}, seed {seed}: never came home"));
            report.push((truth, seed, held, std));
        }
    }
    println!("flow scale error (truth, seed, held, std): {report:?}");
    for &(truth, seed, held, std) in &report {
        assert!(
            (held - truth).abs() <= 0.025 && (held - truth).abs() <= 2.5 * std && std < 0.02,
            "scale {truth}, seed {seed}: held {held} ± {std}"
        );
    }
    for seed in 1..=3u64 {
        let held = |truth: f32| {
            report
                .iter()
                .find(|r| r.0 == truth && r.1 == seed)
                .map(|r| r.2)
                .expect("flown")
        };
        assert!(
            held(0.05) - held(-0.05) >= 0.06,
            "seed {seed}: +5 % held {}, -5 % held {}",
            held(0.05),
            held(-0.05)
        );
    }
}
