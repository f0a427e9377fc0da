//! Pad search and landing in clutter, judged on the simulator's truth: generated worlds
//! (the widened generator, tuning seeds 7 000 000 + k of `--random 200 --seed 7`) in which the code before
//! the descent gate came down at the goal pad's edge and touched its side, or did not find a pad next to a
//! wall. The oracle is the world's geometry: the gap between the goal pad and the nearest wall or obstacle,
//! where each landing came to rest (on a pad's top, or clear of every pad by more than the body's radius),
//! and the runner's collision count.

use cfnav_sim::world::{BODY_RADIUS_M, World};
use cfnav_tools::sim::runner::{RunOptions, RunReport, run};

fn fly(world: &World) -> RunReport {
    run(world, &RunOptions::for_world(world)).expect("runs").report
}

/// Gap between the goal pad's footprint and the nearest arena wall, box or cylinder, m (the oracle of
/// "a pad next to a wall or an obstacle").
fn goal_pad_gap(world: &World) -> f32 {
    let pad = world.pads.last().expect("a goal pad");
    let (hx, hy) = (pad.size[0] / 2.0, pad.size[1] / 2.0);
    let (lo, hi) = (
        [pad.center[0] - hx, pad.center[1] - hy],
        [pad.center[0] + hx, pad.center[1] + hy],
    );
    let mut gap = lo[0]
        .min(lo[1])
        .min(world.arena.size[0] - hi[0])
        .min(world.arena.size[1] - hi[1]);
    // Distance between two axis-aligned rectangles, and from a rectangle to a point.
    let rect_gap = |a: [f32; 2], b: [f32; 2]| {
        let dx = (a[0] - hi[0]).max(lo[0] - b[0]).max(0.0);
        let dy = (a[1] - hi[1]).max(lo[1] - b[1]).max(0.0);
        dx.hypot(dy)
    };
    for b in &world.boxes {
        gap = gap.min(rect_gap(b.min, b.max));
    }
    for c in &world.cylinders {
        gap = gap.min(rect_gap(c.center, c.center) - c.radius);
    }
    gap
}

/// Every landing came to rest on a pad's top or clear of every pad: an off-pad landing's centre is farther
/// from the pad's centre than half its diagonal plus the body's radius (so no side was touched).
fn clear_or_on_pad(world: &World, report: &RunReport) {
    for l in report.landings.iter().filter(|l| !l.on_pad) {
        let pad = world.pads.get(l.pad).expect("the nearest pad");
        let half_diagonal = pad.size[0].hypot(pad.size[1]) / 2.0;
        assert!(l.error_m > half_diagonal + BODY_RADIUS_M, "{report:?}");
    }
}

/// The world flies without contact and every landing is on a pad's centre or clear of the pad.
fn lands_without_contact_on_a_pads_centre_or_clear_of_it(world: &World) {
    let r = fly(world);
    assert_eq!(r.collisions, 0, "{r:?}");
    for landing in &r.landings {
        assert!(
            crate::on_pad_centre_or_clear_of_it(world, landing.pad, landing),
            "landed {landing:?}, neither on the pad's centre nor clear of it"
        );
    }
}

#[test]
fn pads_beside_walls_and_obstacles_are_found_and_landed_on() {
    // Goal pads 0.15 and 0.23 m from a wall or an obstacle. Before this work the first ended with the pad
    // not found, 27 cm off the goal pad, and the second 42 cm off the home pad (state 202); each now
    // completes (the widened, re-centred search after a failed lock).
    //
    // The first pad sits in a pocket (a wall 0.15 m below it, a cylinder 0.17 m beside it), where a search
    // line can hardly cross it, and whether a crossing locks depends on the noise: on its own noise seed
    // and seeds 1–60, 58 of 61 runs find it, with the level calibration (the others end safely, state 202, clear of the pad). So it flies its own seed and seeds 1–40: at
    // least 90 % must complete (38 of 41 did), and every run must stay clear of everything and land on a
    // pad or clear of it (without the level calibration the drone touches the cylinder on seed 33).
    for seed in [7_000_051u64, 7_000_112] {
        // 7 000 112 is kept in a file as an older generator drew it: its start is 2 cm clear of the home
        // pad, closer than the 3 cm the generator now keeps (`START_PAD_GAP_M`).
        let world = if seed == 7_000_112 {
            World::from_toml_str(include_str!("worlds/random-7000112.toml"), "random-7000112.toml")
                .expect("the kept world loads")
        } else {
            World::random(seed)
        };
        let gap = goal_pad_gap(&world);
        assert!(
            (0.1..=0.25).contains(&gap),
            "{seed}: the goal pad is {gap} m from the nearest wall or obstacle"
        );
        let noise_seeds: Vec<u64> = if seed == 7_000_051 {
            std::iter::once(seed).chain(1..=40).collect()
        } else {
            vec![seed]
        };
        let mut completed = 0;
        for &noise in &noise_seeds {
            let mut world = world.clone();
            world.sim.seed = noise;
            let r = fly(&world);
            println!("{seed} (noise seed {noise}): gap {gap:.2} m, {r:?}");
            assert_eq!(r.collisions, 0, "{seed} (noise seed {noise})");
            clear_or_on_pad(&world, &r);
            if r.outcome == "completed" {
                assert!(r.landings.iter().all(|l| l.on_pad), "{seed}: {:?}", r.landings);
                completed += 1;
            } else {
                assert_eq!(r.reason, Some("pad_not_found"), "{seed} (noise seed {noise}): {r:?}");
            }
        }
        let needed = (noise_seeds.len() * 9).div_ceil(10);
        assert!(
            completed >= needed,
            "{seed}: {completed} of {} noise seeds completed",
            noise_seeds.len()
        );
    }
}

#[test]
fn no_descent_at_a_pads_edge() {
    // Before the gate these three came down 15–20 cm from the goal pad's centre, at its edge, and touched
    // its side (collisions in states 14 and 20). Now the descent is refused there: the drone refines, or
    // lands clear of the pad and ends with 202, never touching it.
    for seed in [7_000_148u64, 7_000_156, 7_000_207] {
        let world = World::random(seed);
        let r = fly(&world);
        println!("{seed}: gap {:.2} m, {r:?}", goal_pad_gap(&world));
        assert_eq!(r.collisions, 0, "{seed}: {r:?}");
        assert!(
            r.outcome == "completed" || r.reason == Some("pad_not_found"),
            "{seed}: {r:?}"
        );
        assert_eq!(r.landings.len(), 2, "{seed}");
        clear_or_on_pad(&world, &r);
    }
}

/// The default world with its goal pad moved to `pad` and the nominal goal to `goal` (hand-made worlds of
/// a pad against the arena wall and in a corner).
fn default_world_with_goal_pad(name: &str, pad: [f32; 2], goal: [f32; 2]) -> World {
    let mut world = World::default_world();
    world.name = name.to_string();
    world.pads.last_mut().expect("a goal pad").center = pad;
    world.mission.goal = goal;
    world
}

#[test]
fn a_pad_against_a_wall_or_in_a_corner_is_found_and_landed_on() {
    // The goal pad 0.1 m from the east wall, and 0.11 m from both walls of the north-east corner: the
    // search lines towards a wall end 0.18 m from it, on the pad, so no line sees the far side. Without
    // the half crossings (`PadDetector::line_ended`) the corner pad is not found on any of these noise
    // seeds (state 202, the drone comes to rest 0.9-1.2 m off it) and `wallS` seed 2 neither; with them each
    // lands on the pad's top, within 8 cm of its centre, without touching anything. Oracle: the world's
    // geometry (the gap below) and the runner's truth. The bound is not met by luck on these seeds: over
    // noise seeds 1–60 the goal landing is within 3.7 cm in `corner` and 7.8 cm in `wallS`
    // (median 1.8, p95 4.8 cm; one seed above 6 cm). The worst is seed 4: the estimate is 8-9 cm off in x
    // when the search starts (it grew by 6 cm over 2 s of fast heading swings with no fix in x), and the
    // lock is made with it.
    let cases = [
        ("corner", [5.74, 2.74], [5.50, 2.60], [2u64, 3, 4]),
        ("wallS", [3.5, 0.26], [3.45, 0.5], [2, 3, 4]),
    ];
    for (name, pad, goal, seeds) in cases {
        let world = default_world_with_goal_pad(name, pad, goal);
        let gap = goal_pad_gap(&world);
        assert!((0.1..=0.12).contains(&gap), "{name}: gap {gap}");
        for seed in seeds {
            let options = RunOptions {
                seed,
                ..RunOptions::for_world(&world)
            };
            let r = run(&world, &options).expect("runs").report;
            println!("{name} seed {seed}: gap {gap:.2} m, {r:?}");
            assert_eq!(r.outcome, "completed", "{name} seed {seed}: {r:?}");
            assert_eq!(r.collisions, 0, "{name} seed {seed}");
            assert!(
                r.landings.iter().all(|l| l.on_pad && l.error_m <= 0.08),
                "{name} seed {seed}: {:?}",
                r.landings
            );
        }
    }
}

#[test]
fn pads_boxed_in_by_a_wall_and_an_obstacle_are_found() {
    // Training worlds (`cfnav sim --random 200 --seed S`, S in 20–22, and under worlds/stress.toml) whose
    // goal pad lies 0.11–0.14 m from a wall, a cylinder or both. Before (main at e27037e) each ended with
    // the pad not found (state 202, landed 0.66–1.18 m off the goal pad). Two causes: the search's
    // clearance counted the wall's own mapped cells on top of the exact wall, so a line along a pad against
    // the wall was clipped to nothing (21 000 228, 22 000 227, stressed 20 000 113); and a pad boxed in by a
    // wall and a cylinder (20 000 074) gave two crossings, one each way, agreeing within 2 cm on every
    // refinement round, but never the third the detector's lock waits for. Oracle: the world's geometry
    // (the gap) and the runner's truth (outcome, landings on the pads' tops, collisions).
    let worlds = [
        World::random(20_000_074),
        World::random(21_000_228),
        World::random(22_000_227),
        stressed(World::random(20_000_113)),
    ];
    // Each world on its own noise seed and five others: a boxed-in pad's search is chaotic (a few mm of
    // estimate change the lines the map allows), so one seed says little. Every run collision-free, and at
    // least four of the six with both landings on the pads' tops (before the fixes: none). Measured with the
    // rangers' latency modelled: 22 000 227 misses two (its own seed and seed 4: the
    // search gives up; SITL without the latency completed all six), the stressed 20 000 113 one (its own
    // seed), the other two none.
    for world in worlds {
        let gap = goal_pad_gap(&world);
        assert!((0.1..=0.15).contains(&gap), "{}: gap {gap}", world.name);
        let mut missed = Vec::new();
        for seed in [world.sim.seed, 1, 2, 3, 4, 5] {
            let r = run(
                &world,
                &RunOptions {
                    seed,
                    ..RunOptions::for_world(&world)
                },
            )
            .expect("runs")
            .report;
            println!("{} seed {seed}: gap {gap:.2} m, {r:?}", world.name);
            assert_eq!(r.collisions, 0, "{} seed {seed}", world.name);
            let landed_on_pads = r.outcome == "completed" && r.landings.iter().all(|l| l.on_pad && l.error_m <= 0.06);
            if !landed_on_pads {
                missed.push((seed, r.reason, r.landings));
            }
        }
        assert!(missed.len() <= 2, "{}: {missed:?}", world.name);
    }
}

/// `world` under the `[sensors]` and `[disturbances]` of worlds/stress.toml.
fn stressed(world: World) -> World {
    crate::with_stress(world, "worlds/stress.toml")
}

#[test]
fn a_landing_clear_of_a_pad_never_found_keeps_off_its_corner() {
    // Generated world 157 000 588 (seeds 150–159 were held out: this one was looked at only after the
    // batch that found it): the goal pad lies 0.3 m from the nominal goal, between a cylinder and the north
    // wall, and the search never crosses it (no edge). No floor spot 0.67 m from the nominal goal is
    // reachable, so the landing clear of the pad takes a spot clear of what the detector saw, which is
    // nothing: the one nearest the drone was 0.253 m from the pad's centre and the body touched its corner
    // (state 14). Now the spot farthest from the nominal goal is taken. Oracle: the runner's truth (the
    // landing's distance from the pad against its half diagonal plus the body's radius, the collisions).
    // The goal pad is lowered under the detector's 3 cm least step: never found whatever the search lines
    // do (at its full 10 cm the search finds it), and still a solid the body touches if it comes down on
    // its corner. At 2.5 cm the step plus the ranger's noise can reach the threshold (the pad is then found
    // and landed on); at 1.5 cm it stays unseen.
    let mut world = World::random(157_000_588);
    world.pads.last_mut().expect("a goal pad").height = 0.015;
    let r = fly(&world);
    assert_eq!((r.outcome, r.reason), ("aborted", Some("pad_not_found")), "{r:?}");
    assert_eq!(r.collisions, 0, "{r:?}");
    let goal = r.landings.first().expect("a landing on the outbound leg");
    assert!(
        crate::on_pad_centre_or_clear_of_it(&world, goal.pad, goal),
        "landed {goal:?}, neither on the goal pad's centre nor clear of it"
    );
}

#[test]
fn a_landing_clear_of_a_pad_whose_edges_were_seen_keeps_off_the_side_they_imply() {
    // Generated world 347 001 180 (default settings; seeds 344–353 held out, looked at after the batch
    // that found it): the goal pad sits among cylinders, 0.22 m east of the nominal goal; the search
    // saw two of its edges near its south-east corner and no lock. No floor spot 0.67 m from the nominal
    // goal was reachable, and the spot farthest from the nominal goal, (4.20, 1.22), was 5 cm from the
    // pad's north-east corner: the body touched it (2 collisions, state 14). Now the spot farthest from
    // every pad centre that explains both edges is taken. Oracle: the runner's truth (collisions, and the
    // landing against the pad's half diagonal plus the body's radius).
    lands_without_contact_on_a_pads_centre_or_clear_of_it(&World::random(347_001_180));
}

#[test]
fn a_landing_clear_of_a_pad_keeps_off_an_estimate_the_detector_refit_elsewhere() {
    // Generated world 411 001 354 (default settings; seeds 404–423 held out, looked at after the batch
    // that found it): the goal pad lies about 0.28 m north-east of the nominal goal, among cylinders. One
    // crossing put the detector's estimate at (3.85, 1.94), over the pad; the next refit it to (3.60, 2.08),
    // off it; the restarts kept only that one. No lock; the floor spot farthest from the possible pad
    // centres, (3.93, 1.95), was 0.35 m from the kept estimate and on the pad's north rim: the landing touched
    // it (2 collisions, state 14). Now an estimate refit more than 10 cm away is kept too. Oracle: the
    // runner's truth (collisions, and the landing against the pad's half diagonal plus the body's radius).
    lands_without_contact_on_a_pads_centre_or_clear_of_it(&World::random(411_001_354));
}

#[test]
fn a_half_crossing_over_a_pads_side_along_the_line_is_not_landed_on() {
    // Generated world 163 000 537 (seeds 160–169 had not been flown before it): a search line 17° off the
    // x axis came onto the goal pad over its side along the line, ended there, and its half crossing put
    // the centre 15 cm off in x; two crossings along y agreed with it (they measure only y), the detector
    // locked at (5.02, 1.44) on the pad at (5.16, 1.43), and the drone came down on the pad's edge (states
    // 14 and 20 collisions, 16 cm off). Now that half crossing is set aside once the crossings along y put
    // its entry on the side, and the search goes on until a crossing measures x. Oracle: the runner's truth.
    let world = World::random(163_000_537);
    let r = fly(&world);
    assert_eq!(r.collisions, 0, "{r:?}");
    assert_eq!(r.outcome, "completed", "{r:?}");
    for landing in &r.landings {
        assert!(landing.error_m <= 0.05, "{landing:?}");
    }
}
