//! Zero collisions: motions near obstacles also respect what the Multi-ranger's beams read now,
//! not only the map in the estimate frame. Judged on the simulator's truth (the runner's collision count and
//! minimum clearance of the body disc, `world.clearance − BODY_RADIUS_M`), on worlds in which the code before
//! each change touched an obstacle: generated worlds of the training seeds (`cfnav sim --random 200 --seed S`,
//! S in 20–29: worlds S 000 000 + k), some written out as world files, and hand-made variants of the default
//! world.

use cfnav_sim::world::{BODY_RADIUS_M, World};
use cfnav_tools::sim::runner::{RunOptions, RunReport, run};

fn fly(world: &World) -> RunReport {
    run(world, &RunOptions::for_world(world)).expect("runs").report
}

fn stressed(world: World) -> World {
    crate::with_stress(world, "worlds/stress.toml")
}

/// Each world flies its mission to completion with the body disc never touching anything.
fn completes_without_contact(worlds: impl IntoIterator<Item = World>) {
    for world in worlds {
        let report = fly(&world);
        assert_eq!(report.collisions, 0, "{} collided: {report:?}", world.name);
        assert!(
            report.min_clearance_m.expect("flew") > 0.0,
            "{}: {report:?}",
            world.name
        );
        assert_eq!(report.outcome, "completed", "{report:?}");
    }
}

#[test]
fn search_lines_respect_the_live_beams() {
    // Before (commit dc14fef, the same worlds and seeds), each touched an obstacle while searching the
    // goal pad (state 12), a beam reading it closer and closer while the drone flew on at the search
    // speed: 24 000 139 (back beam 0.27 → 0.05 m, 30° off the travel, 0.46 m/s, estimate error 3 cm: the
    // map did not hold the obstacle), and under worlds/stress.toml 20 000 090 (back beam 0.89 → 0.06 m,
    // 47° off, 0.5 m/s) and 27 000 218 (right beam 0.20 → 0.04 m, 58° off, 0.4 m/s). Now the speed
    // towards each beam's return is bounded by what the beam reads.
    let worlds = [
        World::random(24_000_139),
        stressed(World::random(20_000_090)),
        stressed(World::random(27_000_218)),
    ];
    for world in worlds {
        let report = fly(&world);
        assert_eq!(report.collisions, 0, "{} collided: {report:?}", world.name);
        let clearance = report.min_clearance_m.expect("flew");
        assert!(clearance > 0.0, "{}: min clearance {clearance} m", world.name);
        assert_eq!(report.outcome, "completed", "{report:?}");
    }
}

#[test]
fn paths_past_unseen_wall_ends_slow_down_and_look_first() {
    // Tuning worlds in which the flight code of 11731f5 touched a wall's end or a box's corner at cruise
    // height (state 11): 27 000 092 (a wall's east face alone mapped, the path 0.08 m from its near face),
    // and under worlds/stress.toml 28 000 100 (a box's far face alone mapped), 26 000 093 (a wall's end
    // 0.17 m beside the path, its face row marked free by beams passing a centimetre off, never looked at)
    // and 25 000 201 (a wall's end beside a 0.6 m gap). Now unknown cells within 0.22 m of the path ahead
    // (was 0.15 m) slow the drone and turn a beam at them before it passes.
    let worlds = [
        World::random(27_000_092),
        stressed(World::random(26_000_093)),
        stressed(World::random(28_000_100)),
        stressed(World::random(25_000_201)),
    ];
    completes_without_contact(worlds);
}

#[test]
fn a_look_at_unseen_space_keeps_its_beam_until_it_gets_there() {
    // Under worlds/stress.toml, the flight code of 6862444 touched a box's end at cruise height (state 11)
    // in 21 000 079 and 28 000 098: the look-ahead pointed a beam at the first unobserved cell in raster
    // order, often one on the far side of the path, and with the cell about 45° off the travel the front and
    // side beams needed nearly the same turn, so the commanded heading flipped between them every few ticks
    // (traced in 119 000 413: 69° and −17°), reached neither, and the sector where the box's end was went
    // unswept. Now the nearest unobserved cell is looked at, and a beam keeps it while its turn is within
    // 0.35 rad of the least.
    let worlds = [stressed(World::random(21_000_079)), stressed(World::random(28_000_098))];
    completes_without_contact(worlds);
}

/// The default world with the home pad moved beside the take-off point, its side `gap_m` beyond the body's
/// radius (the start on the floor, as the widened generator places one world in six).
fn home_pad_beside_start(gap_m: f32) -> World {
    let mut world = World::default_world();
    let start = world.mission.start;
    let home = world.pads.first_mut().expect("a home pad");
    home.center = [start[0] - home.size[0] / 2.0 - BODY_RADIUS_M - gap_m, start[1]];
    world.name = format!("home-pad-{gap_m}-m-beside");
    world
}

#[test]
fn take_off_steps_away_from_a_pad_beside_the_start() {
    // A start 0.5 mm beyond one body radius from the home pad's side (valid: the body does not touch it;
    // the generator made one exactly one radius away, world 23 000 223). Before, the lift-off's first
    // millimetres of drift touched the pad's side on noise seeds 2, 3 and 4 (state 10). Now the climb
    // first steps away from the back beam's return (0.06 m), and the body never touches the pad.
    for seed in 1..=4u64 {
        let mut world = home_pad_beside_start(0.0005);
        world.validate().expect("a valid world: the body clears the pad");
        let pad = &world.pads[0];
        let side = pad.center[0] + pad.size[0] / 2.0;
        assert!((world.mission.start[0] - side - BODY_RADIUS_M - 0.0005).abs() < 1e-4);
        world.sim.seed = seed;
        let report = fly(&world);
        assert_eq!(report.collisions, 0, "seed {seed}: {report:?}");
        assert!(report.min_clearance_m.expect("flew") >= 0.0, "seed {seed}: {report:?}");
        assert_eq!(report.outcome, "completed", "seed {seed}: {report:?}");
    }
}

/// The default world with the home pad's corner diagonally beside the take-off point, `gap_m` beyond the
/// body's radius: no horizontal beam sees the pad, so the climb cannot step away from it.
fn home_pad_corner_beside_start(gap_m: f32) -> World {
    let mut world = World::default_world();
    let start = world.mission.start;
    let home = world.pads.first_mut().expect("a home pad");
    let d = (BODY_RADIUS_M + gap_m) / std::f32::consts::SQRT_2;
    home.center = [start[0] - d - home.size[0] / 2.0, start[1] - d - home.size[1] / 2.0];
    world.name = format!("home-pad-corner-{gap_m}-m-beside");
    world
}

#[test]
fn the_lift_off_does_not_slide_into_a_pad_corner_beside_the_start() {
    // Generated worlds 101 000 487 and 104 000 419 start with a pad's corner 0.8 mm beyond the body's
    // radius, diagonally. Before, the lift-off slid 1–3 mm sideways while climbing past the pad's top and
    // touched the corner (state 10): the attitude was levelled on the accelerometer at rest, so its offset
    // (up to 0.05 m/s² in the simulator, ≈ 0.3°) became a real tilt once the controller held "level", and
    // the climb took 0.45 s to pass the pad's top. Now the estimate starts level (the offset calibrated
    // out at rest) and the first 0.13 m are climbed at 0.8 m/s.
    for seed in 1..=6u64 {
        let mut world = home_pad_corner_beside_start(0.001);
        world.validate().expect("a valid world: the body clears the pad");
        world.sim.seed = seed;
        let report = fly(&world);
        assert_eq!(report.collisions, 0, "seed {seed}: {report:?}");
        assert!(report.min_clearance_m.expect("flew") >= 0.0, "seed {seed}: {report:?}");
        assert_eq!(report.outcome, "completed", "seed {seed}: {report:?}");
    }
}

/// Generated worlds 20 000 186 and 24 000 101 (`--random 200 --seed 20`, `--seed 24`), written out as files.
const CYLINDER_BESIDE_THE_GOAL_PAD: &str = r#"
name = "random-20000186"

[arena]
size = [4.4, 2.8]
ceiling = 2.1

[mission]
start = [0.89, 1.3]
goal = [3.62, 0.41]
height = 0.5
speed = 0.5

[[pads]]
center = [0.9, 1.27]
size = [0.3, 0.3]
height = 0.1

[[pads]]
center = [3.8, 0.69]
size = [0.3, 0.3]
height = 0.1

[[boxes]]
min = [1.79, 0.0]
max = [1.85, 2.03]
height = 2.1

[[cylinders]]
center = [3.8, 1.09]
radius = 0.09
height = 1.01

[sim]
seed = 20000186
time_limit = 300.0
"#;
const CYLINDER_ON_A_SEARCH_LINE: &str = r#"
name = "random-24000101"

[arena]
size = [5.85, 2.9]
ceiling = 2.1

[mission]
start = [0.52, 0.87]
goal = [5.07, 1.92]
height = 0.5
speed = 0.5

[[pads]]
center = [0.49, 0.85]
size = [0.3, 0.3]
height = 0.1

[[pads]]
center = [5.05, 1.66]
size = [0.3, 0.3]
height = 0.1

[[boxes]]
min = [1.42, 0.71]
max = [1.58, 2.9]
height = 2.1

[[boxes]]
min = [2.71, 0.0]
max = [2.9, 2.07]
height = 2.1

[[cylinders]]
center = [4.68, 1.89]
radius = 0.09
height = 1.66

[[cylinders]]
center = [3.6, 0.26]
radius = 0.12
height = 2.1

[[cylinders]]
center = [2.52, 1.62]
radius = 0.12
height = 2.02

[sim]
seed = 24000101
time_limit = 300.0
"#;

#[test]
fn search_lines_look_at_unobserved_regions_before_flying_into_them() {
    // Under worlds/stress.toml with their own noise seeds, the code before this change flew a search line
    // (state 12) into a thin cylinder (r 0.09 m) no beam had seen: the line ran 45–50° off all four beams
    // (heading −63°, travel 68°), the back beam first returned from it at 0.11 m; in the second the right
    // beam, 23° off the travel, passed beside it. The map held none of its cells (the estimate was within
    // 1–2 cm). Now a search line slows before an unobserved region within 0.15 m of it and turns the
    // nearest beam onto it (as navigation does): no contact, the cylinder kept at ≥ 7 cm.
    for (text, name) in [
        (CYLINDER_BESIDE_THE_GOAL_PAD, "cylinder-beside-the-goal-pad"),
        (CYLINDER_ON_A_SEARCH_LINE, "cylinder-on-a-search-line"),
    ] {
        let world = stressed(World::from_toml_str(text, name).unwrap_or_else(|e| panic!("{e}")));
        let report = fly(&world);
        assert_eq!(report.collisions, 0, "{name}: {report:?}");
        assert!(report.min_clearance_m.expect("flew") > 0.03, "{name}: {report:?}");
        assert_eq!(report.outcome, "completed", "{name}: {report:?}");
    }
}

#[test]
fn a_cylinders_flank_taken_for_a_face_does_not_pull_the_estimate_into_a_wall() {
    // Stressed generated world 156 000 500 (a held-out seed when it was found): while searching the goal
    // pad, the left beam met a 14 cm cylinder's flank beside the cell that ended the face the map held
    // for it (its last cell), 6–9 cm behind that face's plane, three sweeps running. The fixes it gave
    // pulled the estimate 4.4 and then 4.0 cm off in x (error 1.9 → 14.7 cm) and the body touched the
    // wall (−27 mm). A face's last cell now gives a fix only for a reading within 4 cm of its plane.
    completes_without_contact([stressed(World::random(156_000_500))]);
}

#[test]
fn a_wall_end_or_a_post_hit_once_below_the_threshold_is_still_looked_at() {
    // Stressed generated worlds 158 000 608 and 167 000 577 (held-out seeds when they were found). In the
    // first the path rounded the end of a wall whose cells the map held as unknown, single misses and a
    // sub-threshold hit (a hit then a miss: 5); in the second it turned at a 12 cm cylinder mapped as two
    // sub-threshold cells. To the unobserved-region test such a cell was "seen", so the drone neither
    // slowed nor turned a beam there: 5 mm from contact, and −20 mm. A cell now counts as seen free only
    // when its misses outweigh its hits in log-odds (negative).
    completes_without_contact([
        stressed(World::random(158_000_608)),
        stressed(World::random(167_000_577)),
    ]);
}

#[test]
fn a_post_the_map_missed_ahead_bounds_the_navigation_by_the_live_beams() {
    // Generated world 188 000 679 (a held-out seed): a post of 5 cm radius on the first leg's
    // straight path. A grazing sweep left it as one sub-threshold hit among cells beams had crossed (no
    // unobserved region), and when the front beam read it at 17, 13 and 10 cm the reactive avoidance, which
    // smooths over 0.2 s and keeps 0.1 m/s at its danger distance, still would close on it and touch
    // it (−3 mm). So the live beams also bound the navigation's command too (stop distance 0.13 m).
    completes_without_contact([World::random(188_000_679)]);
}

#[test]
fn a_wall_end_grazed_into_single_misses_around_a_hit_is_still_looked_at() {
    // Stressed generated worlds 217 000 740 and 224 000 694 (from seeds 210-229). In
    // both the path rounds a wall's end at cruise height. Beams grazing the end leave its cells as one
    // miss each (-3) around a hit and a miss (5): taken as seen free by the unobserved-region test, the
    // drone would pass at 0.3-0.45 m/s, meet the end with the front beam 13-25 cm away and touch it (-5 and
    // -14 mm). So next to such a contested cell a cell needs two net misses to count as seen.
    // With the flow scale as an estimator state, 217 000 740 at its own noise seed ends with no path
    // at 15.5 s, before the wall's end, 18 cm from anything (an estimate 5 cm off closed a gap): that run
    // must still touch nothing, and the world's noise seeds 1-3, which all round the end, must complete.
    let report = fly(&stressed(World::random(217_000_740)));
    assert!(
        report.collisions == 0 && report.min_clearance_m.expect("flew") > 0.0,
        "{report:?}"
    );
    let reseeded = (1..=3u64).map(|seed| {
        let mut world = stressed(World::random(217_000_740));
        world.sim.seed = seed;
        world
    });
    completes_without_contact(reseeded.chain([stressed(World::random(224_000_694))]));
}

#[test]
fn a_look_along_a_beam_that_returns_nothing_gives_way_to_the_sweep() {
    // Generated world 306 000 918 (a held-out seed, default settings): the first leg runs west
    // along y = 1.22 m from (5.09, 1.22), with nothing for the front beam to return from within its 4 m, and
    // a box's corner 4 cm beside the path, 1 m ahead. Every cell ahead is unobserved, so the drone slows
    // and points its front beam at the nearest one, on the path itself: a beam with no return maps nothing,
    // the cells stay unobserved, and the side beams would meet the box only when abeam of it, touching the
    // corner (-13 mm). So a look whose beam returns nothing two sweeps in a row gives way to
    // the heading sweep for one period, which turns the front beam onto the box's face.
    // Generated world 252 000 829 (a held-out seed, default settings): during
    // the take-off turn the look points the front beam north-west into more than 4 m of open space (no
    // return, twice); flying the straight first leg at 0.45 m/s the drone would meet a 5 cm post 10 cm
    // beside it (-10 mm). With the sweep instead it flies that leg at 0.2-0.3 m/s and passes 9 cm clear.
    completes_without_contact([World::random(306_000_918), World::random(252_000_829)]);
}

#[test]
fn a_thin_post_in_the_swept_corridor_is_looked_at_before_the_drone_passes() {
    // Generated world 314 001 008 (default settings): a search line ends 0.3 m from the
    // west wall and the next one turns south at 0.5 m/s; a post about 10 cm across stands 6 cm beside it, with every beam
    // pointing elsewhere. The beams sweep the cells around the post free, so its unseen 2 x 2 cells have
    // three unseen neighbours each, not the five of an unobserved region: taken for a gap between beam
    // traces, they would slow nothing (-45 mm). Stressed world 334 001 007: the return leg flies at a similar
    // post at 0.47 m/s the same way (-0.8 mm). So within 0.12 m of the path (the width the body sweeps) three
    // such neighbours make a cell unobserved.
    completes_without_contact([World::random(314_001_008), stressed(World::random(334_001_007))]);
}

#[test]
fn a_slab_seen_end_on_is_not_taken_for_a_gap_between_beam_traces() {
    // Generated world 438 001 497 (default settings; seeds 424–453 were held out, looked at after the batch
    // that found it): an 11 cm slab (x 3.20–3.73 m, y 1.75–1.86 m) lies along the first leg, end-on. Two
    // beams nearly parallel to its south face, a few millimetres off it, ended on that face 0.3 m in and
    // marked the cells of its bottom row free; beams along its north face did the same for its top row.
    // Its middle row alone stayed unseen, a one-cell strip like the gaps between beam traces, so nothing
    // slowed; the path ran 6.5 cm past its end and the body touched its corner (−1.1 mm, state 11). Now a
    // returning beam's last cells in its own row are not seen free by it, unless the map already shows a
    // face across the beam at its end. Three more worlds touched something before the rule and complete
    // after it, not traced further: stressed 446 001 508 (a wall's end, −0.5 mm, state 11), 493 001 497
    // (a post about 12 cm across, −3.9 cm, state 11; seeds 454–493 held out) and stressed 497 001 673
    // (seeds 494–513 held out, found by main's batch there).
    completes_without_contact([
        World::random(438_001_497),
        stressed(World::random(446_001_508)),
        World::random(493_001_497),
        stressed(World::random(497_001_673)),
    ]);
}
