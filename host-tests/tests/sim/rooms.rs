//! Rooms that are not the seed's arena: the world keys `walls`, `placed`, `yaw`, `[[polygons]]`,
//! `[[movers]]` and `[[floor]]`, their geometry, and the `rooms` generator.

use cfnav_sim::physics::{Geometry, QuadParams, Quadrotor};
use cfnav_sim::sensors::{FlowParams, FlowSensor};
use cfnav_sim::world::{
    ALL_WALLS, BODY_RADIUS_M, FloorPatch, Generator, MAX_MOVER_SPEED_MPS, MOVER_GIVE_WAY_M, Mover, PAD_HEIGHT_M,
    PAD_SIDE_M, Polygon, SOLVABILITY_INFLATION_M, WALL_EAST, WALL_NORTH, WALL_SOUTH, WALL_WEST, World, room_capacity,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// A world file using every rooms key (docs/formats.md (world files)'s example, in a 6 × 3 m arena).
const ROOM: &str = r#"
[arena]
size = [6.0, 3.0]
walls = ["south", "west"]

[mission]
start = [0.6, 1.3]
goal = [5.0, 1.5]
placed = [0.63, 1.27, 9.0]

[[pads]]
center = [0.6, 1.3]
size = [0.3, 0.3]
height = 0.1

[[pads]]
center = [5.1, 1.4]
size = [0.2, 0.4]
height = 0.1
yaw = 15.0

[[boxes]]
min = [3.6, 1.9]
max = [4.6, 2.2]
yaw = 30.0

[[polygons]]
points = [[4.0, 0.3], [4.5, 0.4], [4.4, 0.9], [3.9, 0.8]]
height = 0.9

[[movers]]
radius = 0.2
height = 1.8
speed = 0.4
path = [[3.3, 0.4], [3.3, 2.6]]

[[floor]]
min = [2.6, 0.0]
max = [3.6, 3.0]
squal = 20
flow_dropout = 0.6
"#;

fn room() -> World {
    World::from_toml_str(ROOM, "room.toml").unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn every_rooms_key_is_read() {
    let w = room();
    assert_eq!(w.arena.walls, WALL_SOUTH | WALL_WEST);
    assert_eq!(w.mission.placed, Some([0.63, 1.27, 9.0]));
    assert_eq!(w.mission.start, [0.6, 1.3]);
    assert_eq!(w.pads[1].yaw_deg, 15.0);
    assert_eq!(w.pads[0].yaw_deg, 0.0);
    assert_eq!(w.boxes[0].yaw_deg, 30.0);
    assert_eq!(
        w.boxes[0].height, w.arena.ceiling,
        "a box's height defaults to the ceiling"
    );
    assert_eq!(
        w.polygons,
        vec![Polygon {
            points: vec![[4.0, 0.3], [4.5, 0.4], [4.4, 0.9], [3.9, 0.8]],
            height: 0.9
        }]
    );
    assert_eq!(
        w.movers,
        vec![Mover {
            radius: 0.2,
            height: 1.8,
            speed: 0.4,
            path: vec![[3.3, 0.4], [3.3, 2.6]],
            walked_m: 0.0
        }]
    );
    assert_eq!(
        w.floor,
        vec![FloorPatch {
            min: [2.6, 0.0],
            max: [3.6, 3.0],
            squal: Some(20),
            flow_dropout: Some(0.6)
        }]
    );
    // Written out and read back, the same world.
    let back = World::from_toml_str(&w.to_toml_string(), "back.toml").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(back, w);
    // Without the keys: today's defaults.
    let d = World::default_world();
    assert_eq!(d.arena.walls, ALL_WALLS);
    assert_eq!(d.mission.placed, None);
    assert!(d.polygons.is_empty() && d.movers.is_empty() && d.floor.is_empty());
}

/// The error for `ROOM` with `from` replaced by `to`: one line that names `key`.
fn refused(from: &str, to: &str, key: &str) {
    assert!(ROOM.contains(from), "{from:?} is not in the room");
    let text = ROOM.replacen(from, to, 1);
    let e = World::from_toml_str(&text, "bad.toml").expect_err(&format!("{to:?} was accepted"));
    let line = e.to_string();
    assert!(!line.contains('\n'), "{line}");
    assert!(line.contains(key), "{to:?}: the error does not name {key}: {line}");
}

#[test]
fn rooms_keys_out_of_range_are_refused_naming_the_key() {
    refused(
        r#"walls = ["south", "west"]"#,
        r#"walls = ["south", "up"]"#,
        "arena.walls",
    );
    refused(
        r#"walls = ["south", "west"]"#,
        r#"walls = ["south", "south"]"#,
        "arena.walls",
    );
    refused("placed = [0.63, 1.27, 9.0]", "placed = [0.63, 1.27]", "mission.placed");
    refused(
        "placed = [0.63, 1.27, 9.0]",
        "placed = [-0.5, 1.27, 9.0]",
        "mission.placed",
    );
    refused(
        "placed = [0.63, 1.27, 9.0]",
        "placed = [3.3, 0.4, 0.0]",
        "mission.placed",
    );
    refused("size = [0.2, 0.4]", "size = [0.15, 0.4]", "pads[1].size");
    refused("size = [0.2, 0.4]", "size = [0.2, 0.45]", "pads[1].size");
    refused(
        "height = 0.1\nyaw = 15.0",
        "height = 0.04\nyaw = 15.0",
        "pads[1].height",
    );
    refused(
        "height = 0.1\nyaw = 15.0",
        "height = 0.25\nyaw = 15.0",
        "pads[1].height",
    );
    refused("yaw = 30.0", "yaw = nan", "boxes[0].yaw");
    // A self-crossing polygon (a bow tie) and a clockwise one.
    refused(
        "points = [[4.0, 0.3], [4.5, 0.4], [4.4, 0.9], [3.9, 0.8]]",
        "points = [[4.0, 0.3], [4.5, 0.4], [3.9, 0.8], [4.4, 0.9]]",
        "polygons[0].points",
    );
    refused(
        "points = [[4.0, 0.3], [4.5, 0.4], [4.4, 0.9], [3.9, 0.8]]",
        "points = [[3.9, 0.8], [4.4, 0.9], [4.5, 0.4], [4.0, 0.3]]",
        "polygons[0].points",
    );
    refused(
        "points = [[4.0, 0.3], [4.5, 0.4], [4.4, 0.9], [3.9, 0.8]]",
        "points = [[4.0, 0.3], [4.5, 0.4]]",
        "polygons[0].points",
    );
    refused(
        "points = [[4.0, 0.3], [4.5, 0.4], [4.4, 0.9], [3.9, 0.8]]",
        "points = [[4.0, 0.3], [6.5, 0.4], [4.4, 0.9]]",
        "polygons[0].points",
    );
    refused("height = 0.9", "height = 0.0", "polygons[0].height");
    refused(
        "speed = 0.4",
        &format!("speed = {}", MAX_MOVER_SPEED_MPS + 0.05),
        "movers[0].speed",
    );
    refused("speed = 0.4", "speed = -0.1", "movers[0].speed");
    refused("radius = 0.2", "radius = 0.0", "movers[0].radius");
    refused("path = [[3.3, 0.4], [3.3, 2.6]]", "path = []", "movers[0].path");
    refused(
        "path = [[3.3, 0.4], [3.3, 2.6]]",
        "path = [[3.3, 0.4], [7.0, 2.6]]",
        "movers[0].path",
    );
    refused(
        "path = [[3.3, 0.4], [3.3, 2.6]]",
        "path = [[0.6, 1.4], [3.3, 2.6]]",
        "movers[0].path",
    );
    refused("squal = 20", "squal = 256", "floor[0].squal");
    refused("squal = 20", "squal = -1", "floor[0].squal");
    refused("flow_dropout = 0.6", "flow_dropout = 1.5", "floor[0].flow_dropout");
    refused("max = [3.6, 3.0]", "max = [2.0, 3.0]", "floor[0]");
    refused("max = [3.6, 3.0]\nsqual", "max = [3.6, 3.5]\nsqual", "floor[0]");
    refused("[[floor]]", "[[floor]]\ncolour = 1", "colour");
    // A room larger than the firmware maps (its widest grid, from cfnav::nav::map).
    let ([cells_x, _], _) = room_capacity();
    let too_wide = f32::from(cells_x) * cfnav::nav::map::CELL_SIZE_M + 0.05;
    refused(
        "size = [6.0, 3.0]",
        &format!("size = [{too_wide:.2}, 3.0]"),
        "arena.size",
    );
}

/// A box of `size` centred on `c` and turned by `yaw_deg`, the only obstacle of an otherwise empty room.
fn room_with_box(c: [f32; 2], size: [f32; 2], yaw_deg: f32) -> World {
    let mut w = room();
    w.movers.clear();
    w.polygons.clear();
    w.boxes.clear();
    w.boxes.push(cfnav_sim::world::BoxObstacle {
        min: [c[0] - size[0] / 2.0, c[1] - size[1] / 2.0],
        max: [c[0] + size[0] / 2.0, c[1] + size[1] / 2.0],
        height: 1.0,
        yaw_deg,
    });
    w
}

/// Where a 2-D ray first meets a closed polygon's edges (an independent oracle: each edge's line solved
/// for the crossing by Cramer's rule, kept when it lies on the edge).
fn first_edge_hit(points: &[[f64; 2]], o: [f64; 2], d: [f64; 2]) -> Option<f64> {
    let n = points.len();
    let mut best: Option<f64> = None;
    for i in 0..n {
        let (a, b) = (points[i], points[(i + 1) % n]);
        // o + t d = a + u (b - a)  ⇒  t d - u (b - a) = a - o
        let (m11, m12, m21, m22) = (d[0], a[0] - b[0], d[1], a[1] - b[1]);
        let det = m11 * m22 - m12 * m21;
        if det.abs() < 1e-12 {
            continue;
        }
        let (r1, r2) = (a[0] - o[0], a[1] - o[1]);
        let t = (r1 * m22 - m12 * r2) / det;
        let u = (m11 * r2 - r1 * m21) / det;
        if t >= 0.0 && (-1e-9..=1.0 + 1e-9).contains(&u) {
            best = Some(best.map_or(t, |b: f64| b.min(t)));
        }
    }
    best
}

#[test]
fn ray_casts_against_a_turned_box_match_an_independent_computation() {
    // A 0.4 m square turned 45° about (3, 1.5): a ray along +x at the centre's height meets its corner at
    // x = 3 − 0.2·√2.
    let w = room_with_box([3.0, 1.5], [0.4, 0.4], 45.0);
    let t = w.ray_cast([1.0, 1.5, 0.5], [1.0, 0.0, 0.0], 10.0).expect("a hit");
    assert!((f64::from(t) - (2.0 - 0.2 * 2f64.sqrt())).abs() < 1e-5, "{t}");
    // Over its top (1 m) the ray passes on and out through the open east side.
    assert_eq!(w.ray_cast([1.0, 1.5, 1.2], [1.0, 0.0, 0.0], 10.0), None);
    // Random rays in the plane at 0.5 m against a 0.8 × 0.3 box turned 30°.
    let (c, size, yaw) = ([3.0f64, 1.5], [0.8f64, 0.3], 30f64);
    let w = room_with_box([3.0, 1.5], [0.8, 0.3], 30.0);
    let (s, co) = yaw.to_radians().sin_cos();
    let corners: Vec<[f64; 2]> = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
        .iter()
        .map(|k| {
            let (x, y) = (k[0] * size[0] / 2.0, k[1] * size[1] / 2.0);
            [c[0] + co * x - s * y, c[1] + s * x + co * y]
        })
        .collect();
    let mut rng = SmallRng::seed_from_u64(44);
    let mut hits = 0;
    for _ in 0..400 {
        // Within 0.5 m of these origins nothing but the box stands (the walls are farther).
        let o = [rng.random_range(2.0..4.0), rng.random_range(0.6..2.4)];
        let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let d = [a.cos(), a.sin()];
        let cast = w.ray_cast([o[0] as f32, o[1] as f32, 0.5], [d[0] as f32, d[1] as f32, 0.0], 0.5);
        let inside = {
            let (px, py) = (o[0] - c[0], o[1] - c[1]);
            (co * px + s * py).abs() <= size[0] / 2.0 && (-s * px + co * py).abs() <= size[1] / 2.0
        };
        let oracle = if inside {
            Some(0.0)
        } else {
            first_edge_hit(&corners, o, d)
        }
        .filter(|t| *t <= 0.5);
        match (oracle, cast) {
            (Some(t), Some(got)) => {
                hits += 1;
                assert!((f64::from(got) - t).abs() < 1e-4, "o {o:?} d {d:?}: {got} vs {t}");
            }
            (None, None) => {}
            other => panic!("o {o:?} d {d:?}: {other:?}"),
        }
    }
    assert!(hits > 50, "only {hits} rays met the box");
}

#[test]
fn ray_casts_against_a_polygon_match_an_independent_computation() {
    let mut w = room();
    w.movers.clear();
    w.boxes.clear();
    // A non-convex L: the notch at the upper right is free.
    let l = [[2.0, 1.0], [3.0, 1.0], [3.0, 1.4], [2.4, 1.4], [2.4, 2.0], [2.0, 2.0]];
    w.polygons = vec![Polygon {
        points: l.to_vec(),
        height: 0.9,
    }];
    w.validate().unwrap_or_else(|e| panic!("{e}"));
    // Known answers: along −x through the notch at y = 1.7 the first face is x = 2.4; along −y at x = 2.7
    // from y = 2.5 the notch lets the ray down to y = 1.4; over the top (0.9 m) nothing but the floor.
    let t = w.ray_cast([3.5, 1.7, 0.5], [-1.0, 0.0, 0.0], 5.0).expect("a hit");
    assert!((t - 1.1).abs() < 1e-5, "{t}");
    let t = w.ray_cast([2.7, 2.5, 0.5], [0.0, -1.0, 0.0], 5.0).expect("a hit");
    assert!((t - 1.1).abs() < 1e-5, "{t}");
    let t = w.ray_cast([2.2, 1.5, 1.5], [0.0, 0.0, -1.0], 5.0).expect("the top");
    assert!((t - 0.6).abs() < 1e-5, "{t}");
    let t = w
        .ray_cast([2.7, 1.7, 1.5], [0.0, 0.0, -1.0], 5.0)
        .expect("the floor in the notch");
    assert!((t - 1.5).abs() < 1e-5, "{t}");
    // Random rays at 0.5 m from points outside it against the edge oracle.
    let pts: Vec<[f64; 2]> = l.iter().map(|p| [f64::from(p[0]), f64::from(p[1])]).collect();
    let mut rng = SmallRng::seed_from_u64(45);
    let mut hits = 0;
    for _ in 0..400 {
        let o = [rng.random_range(1.6..3.4), rng.random_range(0.6..2.4)];
        let inside_l = (o[0] >= 2.0 && o[0] <= 3.0 && o[1] >= 1.0 && o[1] <= 1.4)
            || (o[0] >= 2.0 && o[0] <= 2.4 && o[1] >= 1.0 && o[1] <= 2.0);
        if inside_l {
            let got = w.ray_cast([o[0] as f32, o[1] as f32, 0.5], [1.0, 0.0, 0.0], 5.0);
            assert_eq!(got, Some(0.0), "inside at {o:?}");
            continue;
        }
        let a: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let d = [a.cos(), a.sin()];
        let oracle = first_edge_hit(&pts, o, d).filter(|t| *t <= 0.5);
        let got = w.ray_cast([o[0] as f32, o[1] as f32, 0.5], [d[0] as f32, d[1] as f32, 0.0], 0.5);
        match (oracle, got) {
            (Some(t), Some(g)) => {
                hits += 1;
                assert!((f64::from(g) - t).abs() < 1e-4, "o {o:?} d {d:?}: {g} vs {t}");
            }
            (None, None) => {}
            other => panic!("o {o:?} d {d:?}: {other:?}"),
        }
    }
    assert!(hits > 50, "only {hits} rays met the polygon");
    // Clearance in the notch: the nearer of its two faces (x = 2.4 and y = 1.4), 0.2 m; beyond the inner
    // corner, the distance to that corner.
    let c = w.clearance(2.6, 1.6, 0.5);
    assert!((c - 0.2).abs() < 1e-5, "{c}");
    let c = w.clearance(2.6, 1.5, 0.5);
    assert!((c - 0.1).abs() < 1e-5, "{c}");
    let c = w.clearance(3.3, 1.8, 0.5);
    assert!((f64::from(c) - 0.3f64.hypot(0.4)).abs() < 1e-5, "{c}");
    assert!(w.collides(3.0 + BODY_RADIUS_M - 0.01, 1.2, 0.5));
    assert!(!w.collides(3.0 + BODY_RADIUS_M + 0.01, 1.2, 0.5));
}

#[test]
fn an_open_side_lets_a_ray_pass_and_a_walled_one_stops_it() {
    let mut w = room();
    w.movers.clear();
    w.polygons.clear();
    w.boxes.clear();
    w.floor.clear();
    // East and north open: rays go on to their range; south and west stop them.
    assert_eq!(w.ray_cast([5.5, 1.5, 0.5], [1.0, 0.0, 0.0], 4.0), None);
    assert_eq!(w.ray_cast([3.0, 2.5, 0.5], [0.0, 1.0, 0.0], 4.0), None);
    assert_eq!(w.ray_cast([3.0, 2.5, 0.5], [1.0, 1.0, 0.0], 4.0), None);
    let t = w
        .ray_cast([3.0, 1.0, 0.5], [0.0, -1.0, 0.0], 4.0)
        .expect("the south wall");
    assert!((t - 1.0).abs() < 1e-6, "{t}");
    let t = w
        .ray_cast([1.0, 1.0, 0.5], [-1.0, 0.0, 0.0], 4.0)
        .expect("the west wall");
    assert!((t - 1.0).abs() < 1e-6, "{t}");
    // Out through the open east side and south of the arena's corner: the south wall ends at x = 6.
    assert_eq!(w.ray_cast([5.9, 0.1, 0.5], [1.0, -1.0, 0.0], 4.0), None);
    // The floor goes on beyond an open side.
    let t = w.ray_cast([5.9, 1.0, 0.5], [1.0, 0.0, -0.5], 4.0).expect("the floor");
    assert!((t - 0.5 * 5f32.sqrt()).abs() < 1e-5, "{t}");
    // The same room walled all round stops the first ray at the east wall.
    w.arena.walls = ALL_WALLS;
    let t = w
        .ray_cast([5.5, 1.5, 0.5], [1.0, 0.0, 0.0], 4.0)
        .expect("the east wall");
    assert!((t - 0.5).abs() < 1e-6, "{t}");
    // Clearance: an open side is no wall; the body can cross it without contact.
    w.arena.walls = WALL_SOUTH | WALL_WEST;
    assert!(!w.collides(5.99, 1.5, 0.5));
    assert!(!w.collides(6.3, 1.5, 0.5));
    assert!(w.collides(3.0, 0.03, 0.5));
    assert!(w.collides(0.03, 1.5, 0.5));
    // Physics bounds: open sides unbounded.
    let (lo, hi) = w.bounds().expect("bounds");
    assert_eq!((lo[0], lo[1]), (0.0, 0.0));
    assert!(hi[0].is_infinite() && hi[1].is_infinite());
}

#[test]
fn leaving_through_an_open_side_is_detected_and_only_there() {
    let mut w = room();
    w.arena.walls = WALL_SOUTH | WALL_EAST | WALL_WEST; // north open
    let a = w.arena;
    assert!(a.left_through_open_side(3.0, 3.01));
    assert!(!a.left_through_open_side(3.0, 2.99));
    assert!(!a.left_through_open_side(3.0, -0.01), "south is walled");
    assert!(!a.left_through_open_side(6.01, 1.0), "east is walled");
    w.arena.walls = WALL_NORTH;
    let a = w.arena;
    for (x, y) in [(-0.01, 1.0), (6.01, 1.0), (3.0, -0.01)] {
        assert!(a.left_through_open_side(x, y), "({x}, {y})");
    }
    assert!(!a.left_through_open_side(0.0, 0.0), "on the edge is inside");
}

#[test]
fn a_mover_walks_its_path_and_pauses_near_the_drone() {
    let mut w = room();
    w.movers = vec![Mover {
        radius: 0.2,
        height: 1.8,
        speed: 0.5,
        path: vec![[1.5, 0.4], [1.5, 2.6]],
        walked_m: 0.0,
    }];
    w.validate().unwrap_or_else(|e| panic!("{e}"));
    // Far from the drone it walks there and back: 2.2 m at 0.5 m/s is 4.4 s each way.
    let far = [5.0, 1.5, 0.5];
    let mut top = 0.0f32;
    for _ in 0..4400 {
        w.step_movers(0.001, far);
        top = top.max(w.movers[0].position()[1]);
    }
    assert!((top - 2.6).abs() < 2e-3, "{top}");
    for _ in 0..4400 {
        w.step_movers(0.001, far);
    }
    let p = w.movers[0].position();
    assert!((p[1] - 0.4).abs() < 2e-3, "back at the start: {p:?}");
    // The drone hovers on its path: it stops short of the give-way distance and waits there.
    let drone = [1.5f32, 1.5, 0.5];
    let gap = |w: &World| {
        let p = w.movers[0].position();
        (p[0] - drone[0]).hypot(p[1] - drone[1]) - 0.2 - BODY_RADIUS_M
    };
    let mut least = f32::INFINITY;
    for _ in 0..10_000 {
        w.step_movers(0.001, drone);
        least = least.min(gap(&w));
    }
    assert!(least >= MOVER_GIVE_WAY_M - 1e-4, "came within {least} m");
    assert!(
        least < MOVER_GIVE_WAY_M + 0.001,
        "stopped {least} m away, not at the give-way distance"
    );
    let before = w.movers[0].position();
    w.step_movers(0.5, drone);
    assert_eq!(w.movers[0].position(), before, "it waits while the drone is there");
    // The drone moves off: it walks on.
    w.step_movers(0.1, far);
    assert_ne!(w.movers[0].position(), before);
    // It is a solid where it stands: a ray along its path meets it.
    let p = w.movers[0].position();
    let t = w
        .ray_cast([p[0] - 1.0, p[1], 0.5], [1.0, 0.0, 0.0], 4.0)
        .expect("the mover");
    assert!((t - 0.8).abs() < 1e-4, "{t}");
}

#[test]
fn a_poor_floor_patch_changes_the_flow_reading() {
    let mut w = room();
    w.movers.clear();
    w.floor = vec![FloorPatch {
        min: [2.0, 0.0],
        max: [3.0, 3.0],
        squal: Some(15),
        flow_dropout: None,
    }];
    let params = QuadParams::default();
    let read = |w: &World, x: f32| {
        let mut q = Quadrotor::new(params, [x, 1.5, 0.5], 0.0);
        q.set_velocity([0.3, 0.0, 0.0]);
        let mut f = FlowSensor::new(FlowParams::default());
        let mut rng = SmallRng::seed_from_u64(3);
        (0..50)
            .map(|_| f.sample(&q, w, &mut rng).expect("a reading"))
            .collect::<Vec<_>>()
    };
    let over = read(&w, 2.5);
    let off = read(&w, 1.5);
    let mean = |v: &[cfnav::types::FlowSample]| v.iter().map(|s| f32::from(s.squal)).sum::<f32>() / v.len() as f32;
    assert!((mean(&over) - 15.0).abs() < 3.0, "{}", mean(&over));
    assert!(mean(&off) > 100.0, "{}", mean(&off));
    assert!(over.iter().all(|s| s.motion_valid));
    w.floor[0].flow_dropout = Some(1.0);
    assert!(read(&w, 2.5).iter().all(|s| !s.motion_valid));
    assert!(
        read(&w, 1.5).iter().all(|s| s.motion_valid),
        "off the patch nothing changes"
    );
}

#[test]
fn the_rooms_generator_is_deterministic_valid_and_solvable() {
    let ([cells_x, cells_y], capacity) = room_capacity();
    let cell = cfnav::nav::map::CELL_SIZE_M;
    let mut seen = [0usize; 8];
    for seed in 0..60u64 {
        let w = World::random_with(Generator::Rooms, seed);
        assert_eq!(w, World::random_with(Generator::Rooms, seed), "seed {seed}");
        w.validate().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        assert_eq!(
            w.name,
            format!("room-{seed}"),
            "seed {seed}: fell back to the open world"
        );
        let back = World::from_toml_str(&w.to_toml_string(), "room.toml").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back, w, "seed {seed}");
        // Within what the firmware maps.
        let shape = w.grid_shape().expect("a grid");
        assert!(
            shape.width <= cells_x && shape.height <= cells_y && shape.cells() <= capacity,
            "seed {seed}"
        );
        assert!(w.arena.size[0] >= 2.0 - cell && w.arena.size[1] >= 2.0 - cell);
        // Solvable for the body with margin, every side counted as walled and the walkers aside.
        let mut closed = w.clone();
        closed.arena.walls = ALL_WALLS;
        closed.movers.clear();
        assert!(closed.is_solvable(SOLVABILITY_INFLATION_M), "seed {seed}");
        // Pads over the whole range; the hand's placement a few cm and up to ±10°, on the home pad.
        for p in &w.pads {
            for s in p.size {
                assert!((PAD_SIDE_M[0]..=PAD_SIDE_M[1]).contains(&s), "seed {seed}: {p:?}");
            }
            assert!(
                (PAD_HEIGHT_M[0]..=PAD_HEIGHT_M[1]).contains(&p.height),
                "seed {seed}: {p:?}"
            );
        }
        let [x, y, yaw] = w.mission.placed.expect("placed by hand");
        let s = w.mission.start;
        assert!((x - s[0]).hypot(y - s[1]) <= 0.045 && yaw.abs() <= 10.0, "seed {seed}");
        assert_eq!(w.pad_index_at(x, y), Some(0), "seed {seed}: not on the home pad");
        seen[0] += usize::from(w.arena.walls != ALL_WALLS);
        seen[1] += usize::from(!w.movers.is_empty());
        seen[2] += usize::from(!w.polygons.is_empty());
        seen[3] += usize::from(w.boxes.iter().any(|b| b.yaw_deg != 0.0));
        seen[4] += usize::from(!w.floor.is_empty());
        seen[5] += usize::from(w.pads.iter().any(|p| p.yaw_deg != 0.0));
        seen[6] += usize::from(w.cylinders.len() >= 4);
        seen[7] += usize::from(w.pads.iter().any(|p| p.size[0] != p.size[1]));
    }
    assert!(
        seen.iter().all(|&n| n >= 3),
        "some feature is (nearly) never drawn: {seen:?}"
    );
}
