//! Random worlds (see "Random worlds" in the parent module's documentation) and the solvability check that
//! keeps them fair.

use std::collections::VecDeque;

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::{
    Arena, BoxObstacle, Cylinder, DEFAULT_HEIGHT_M, DEFAULT_SPEED_MPS, DEFAULT_TIME_LIMIT_S, Expect, Mission, Pad,
    SimSettings, World, dist, rect_point_distance, rect_rect_distance,
};
use crate::stress::Stress;

/// Inflation of the true obstacles used to decide that a random world is solvable: the body radius 0.06 m
/// plus a 0.19 m margin, which leaves room for the firmware's own inflation (about 0.15 m beyond the body)
/// rounded out to its 5 cm cells. (Solvable with it implies solvable with any smaller inflation.)
pub const SOLVABILITY_INFLATION_M: f32 = 0.25;
/// Least distance from any obstacle of a random world to the pads, the take-off point and the nominal goal.
pub const KEEP_OUT_M: f32 = 0.4;

/// Candidates drawn before falling back to an obstacle-free world (never reached in practice).
const MAX_ATTEMPTS: usize = 500;
const PAD_SIZE: [f32; 2] = [0.3, 0.3];
const PAD_HEIGHT: f32 = 0.1;

/// Round to whole centimetres.
pub(super) fn cm(v: f32) -> f32 {
    (v * 100.0).round() / 100.0
}

/// Round to whole 5 cm cells.
fn cells5(v: f32) -> f32 {
    (v * 20.0).round() / 20.0
}

/// What obstacles must stay away from.
pub(super) struct KeepOut {
    pub(super) points: Vec<[f32; 2]>,
    pub(super) pads: Vec<([f32; 2], [f32; 2])>,
}

impl KeepOut {
    pub(super) fn allows_rect(&self, r: ([f32; 2], [f32; 2])) -> bool {
        self.points.iter().all(|&p| rect_point_distance(r, p) >= KEEP_OUT_M)
            && self.pads.iter().all(|&p| rect_rect_distance(r, p) >= KEEP_OUT_M)
    }

    fn allows_disc(&self, c: [f32; 2], r: f32) -> bool {
        self.points.iter().all(|&p| dist(p, c) - r >= KEEP_OUT_M)
            && self.pads.iter().all(|&p| rect_point_distance(p, c) - r >= KEEP_OUT_M)
    }
}

fn pad_near(rng: &mut SmallRng, nominal: [f32; 2], offset: (f32, f32), arena: [f32; 2]) -> Pad {
    let d = rng.random_range(offset.0..=offset.1);
    let a = rng.random_range(0.0..std::f32::consts::TAU);
    let margin = 0.3;
    let center = [
        cm((nominal[0] + d * a.cos()).clamp(margin, arena[0] - margin)),
        cm((nominal[1] + d * a.sin()).clamp(margin, arena[1] - margin)),
    ];
    Pad {
        center,
        size: PAD_SIZE,
        height: PAD_HEIGHT,
        yaw_deg: 0.0,
    }
}

/// Height of a random box or cylinder: the ceiling, or (half the time) 1 m to the ceiling.
fn obstacle_height(rng: &mut SmallRng, ceiling: f32) -> f32 {
    if rng.random_bool(0.5) {
        ceiling
    } else {
        cm(rng.random_range(1.0..=ceiling))
    }
}

fn candidate(rng: &mut SmallRng, seed: u64) -> World {
    let w = cells5(rng.random_range(4.5..=6.0));
    let h = cells5(rng.random_range(2.4..=3.0));
    let ceiling = (rng.random_range(2.0f32..=2.6) * 10.0).round() / 10.0;
    let mut start = [cm(rng.random_range(0.6..=1.0)), cm(rng.random_range(0.6..=h - 0.6))];
    let mut goal = [cm(w - rng.random_range(0.6..=1.0)), cm(rng.random_range(0.6..=h - 0.6))];
    if rng.random_bool(0.5) {
        start[0] = cm(w - start[0]);
        goal[0] = cm(w - goal[0]);
    }
    let home = pad_near(rng, start, (0.0, 0.05), [w, h]);
    let goal_pad = pad_near(rng, goal, (0.05, 0.30), [w, h]);
    let keep = KeepOut {
        points: vec![start, goal],
        pads: vec![home.footprint(), goal_pad.footprint()],
    };

    let mut boxes = Vec::new();
    // Walls across the arena, each with one gap, between the two ends.
    let (x_lo, x_hi) = (start[0].min(goal[0]) + 0.9, start[0].max(goal[0]) - 0.9);
    let walls = rng.random_range(1..=3);
    walls_with_gaps(rng, walls, (x_lo, x_hi), h, ceiling, &keep, &mut boxes);

    let count = rng.random_range(0..=4);
    scatter_boxes(rng, count, [w, h], ceiling, &keep, &mut boxes);

    let count = rng.random_range(0..=4);
    let mut cylinders = Vec::new();
    scatter_cylinders(rng, count, [w, h], ceiling, &keep, &mut cylinders);

    generated_world(seed, [w, h], ceiling, [start, goal], [home, goal_pad], boxes, cylinders)
}

// ---------------------------------------------------------------------------------------------------------
// The widened generator

/// Smallest and largest arena of the widened generator, metres (the largest is the `large-arena` build's).
pub const WIDE_ARENA_MIN_M: [f32; 2] = [4.0, 2.0];
/// See [`WIDE_ARENA_MIN_M`].
pub const WIDE_ARENA_MAX_M: [f32; 2] = [6.4, 3.2];
/// Edge-to-edge gap between the goal pad and the wall or obstacle it is placed next to, metres.
pub const NEAR_PAD_GAP_M: (f32, f32) = (0.1, 0.25);
/// Radii of a forest's thin cylinders, metres.
pub const FOREST_RADIUS_M: (f32, f32) = (0.08, 0.15);
/// Least edge gap between a forest cylinder and the goal pad, metres.
pub const FOREST_PAD_GAP_M: f32 = 0.1;
/// Least gap between the body disc and the home pad's sides when the drone starts on the floor beside it,
/// m. The world files allow 0 (touching); a generated start that close was always a pad's corner diagonal
/// to the drone, which the four single-ray beams pass beside (a real VL53L1x's 27° cone would see it), so
/// the lift-off's millimetres of drift would count as a collision before the flight begins (BENCHMARKS.md
/// §5). A person setting the drone down beside a pad
/// leaves a few centimetres.
pub const START_PAD_GAP_M: f32 = 0.03;

/// Up to `count` cylinders of radius 5–25 cm where `keep` allows them (20 tries each), appended to `out`.
fn scatter_cylinders(
    rng: &mut SmallRng,
    count: u32,
    [w, h]: [f32; 2],
    ceiling: f32,
    keep: &KeepOut,
    out: &mut Vec<Cylinder>,
) {
    for _ in 0..count {
        for _ in 0..20 {
            let r = cm(rng.random_range(0.05..=0.25));
            let center = [cm(rng.random_range(r..=w - r)), cm(rng.random_range(r..=h - r))];
            if keep.allows_disc(center, r) {
                out.push(Cylinder {
                    center,
                    radius: r,
                    height: obstacle_height(rng, ceiling),
                });
                break;
            }
        }
    }
}

/// Up to `count` walls across the arena between `x_lo` and `x_hi` (20 tries each), 5–25 cm thick, 0.7 m
/// apart, each with one 0.6–1 m gap anywhere along its height `h` (a segment shorter than 5 cm is left out),
/// where `keep` allows both segments; appended to `out`. The classic and the widened generator both use it.
fn walls_with_gaps(
    rng: &mut SmallRng,
    count: u32,
    (x_lo, x_hi): (f32, f32),
    h: f32,
    ceiling: f32,
    keep: &KeepOut,
    out: &mut Vec<BoxObstacle>,
) {
    let mut wall_xs: Vec<(f32, f32)> = Vec::new();
    for _ in 0..count {
        for _ in 0..20 {
            let t = cm(rng.random_range(0.05..=0.25));
            if x_hi - t <= x_lo {
                break;
            }
            let x = cm(rng.random_range(x_lo..=x_hi - t));
            if wall_xs.iter().any(|&(a, b)| x < b + 0.7 && a < x + t + 0.7) {
                continue;
            }
            let gap = cm(rng.random_range(0.6..=1.0));
            let gy = cm(rng.random_range(0.0..=(h - gap).max(0.0)));
            let mut segments = Vec::new();
            if gy > 0.05 {
                segments.push(BoxObstacle {
                    min: [x, 0.0],
                    max: [cm(x + t), gy],
                    height: ceiling,
                    yaw_deg: 0.0,
                });
            }
            if gy + gap < h - 0.05 {
                segments.push(BoxObstacle {
                    min: [x, gy + gap],
                    max: [cm(x + t), h],
                    height: ceiling,
                    yaw_deg: 0.0,
                });
            }
            if segments.iter().all(|b| keep.allows_rect(b.footprint())) {
                out.extend(segments);
                wall_xs.push((x, x + t));
                break;
            }
        }
    }
}

/// Up to `count` boxes of 10–60 cm sides anywhere in the arena where `keep` allows them (20 tries each),
/// appended to `out`.
fn scatter_boxes(
    rng: &mut SmallRng,
    count: u32,
    [w, h]: [f32; 2],
    ceiling: f32,
    keep: &KeepOut,
    out: &mut Vec<BoxObstacle>,
) {
    for _ in 0..count {
        for _ in 0..20 {
            let size = [cm(rng.random_range(0.1..=0.6)), cm(rng.random_range(0.1..=0.6))];
            let min = [
                cm(rng.random_range(0.0..=w - size[0])),
                cm(rng.random_range(0.0..=h - size[1])),
            ];
            let b = BoxObstacle {
                min,
                max: [cm(min[0] + size[0]).min(w), cm(min[1] + size[1]).min(h)],
                height: obstacle_height(rng, ceiling),
                yaw_deg: 0.0,
            };
            if keep.allows_rect(b.footprint()) {
                out.push(b);
                break;
            }
        }
    }
}

/// A generated world with the default mission settings: `[start, goal]`, `[home pad, goal pad]`.
fn generated_world(
    seed: u64,
    size: [f32; 2],
    ceiling: f32,
    [start, goal]: [[f32; 2]; 2],
    [home, goal_pad]: [Pad; 2],
    boxes: Vec<BoxObstacle>,
    cylinders: Vec<Cylinder>,
) -> World {
    World {
        name: format!("random-{seed}"),
        arena: Arena {
            size,
            ceiling,
            walls: super::ALL_WALLS,
        },
        mission: Mission {
            start,
            goal,
            height: DEFAULT_HEIGHT_M,
            speed: DEFAULT_SPEED_MPS,
            placed: None,
        },
        pads: vec![home, goal_pad],
        boxes,
        cylinders,
        polygons: Vec::new(),
        movers: Vec::new(),
        floor: Vec::new(),
        sim: SimSettings {
            seed,
            time_limit: DEFAULT_TIME_LIMIT_S,
            expect: Expect::Completed,
        },
        stress: Stress::default(),
    }
}

/// A random obstacle placed `gap` (edge to edge) from the pad's footprint on a random side.
fn obstacle_next_to(rng: &mut SmallRng, pad: &Pad, gap: f32, ceiling: f32) -> (Option<BoxObstacle>, Option<Cylinder>) {
    let (lo, hi) = pad.footprint();
    let side = rng.random_range(0..4u8);
    let along = |rng: &mut SmallRng, a: f32, b: f32| cm(rng.random_range(a - 0.1..=b + 0.1));
    if rng.random_bool(0.5) {
        let r = cm(rng.random_range(0.08..=0.25));
        let c = match side {
            0 => [cm(lo[0] - gap - r), along(rng, lo[1], hi[1])],
            1 => [cm(hi[0] + gap + r), along(rng, lo[1], hi[1])],
            2 => [along(rng, lo[0], hi[0]), cm(lo[1] - gap - r)],
            _ => [along(rng, lo[0], hi[0]), cm(hi[1] + gap + r)],
        };
        let cyl = Cylinder {
            center: c,
            radius: r,
            height: obstacle_height(rng, ceiling),
        };
        (None, Some(cyl))
    } else {
        let size = [cm(rng.random_range(0.1..=0.5)), cm(rng.random_range(0.1..=0.5))];
        let (min, max) = match side {
            0 => {
                let y = along(rng, lo[1], hi[1]) - size[1] / 2.0;
                ([cm(lo[0] - gap - size[0]), cm(y)], [cm(lo[0] - gap), cm(y + size[1])])
            }
            1 => {
                let y = along(rng, lo[1], hi[1]) - size[1] / 2.0;
                ([cm(hi[0] + gap), cm(y)], [cm(hi[0] + gap + size[0]), cm(y + size[1])])
            }
            2 => {
                let x = along(rng, lo[0], hi[0]) - size[0] / 2.0;
                ([cm(x), cm(lo[1] - gap - size[1])], [cm(x + size[0]), cm(lo[1] - gap)])
            }
            _ => {
                let x = along(rng, lo[0], hi[0]) - size[0] / 2.0;
                ([cm(x), cm(hi[1] + gap)], [cm(x + size[0]), cm(hi[1] + gap + size[1])])
            }
        };
        let b = BoxObstacle {
            min,
            max,
            height: obstacle_height(rng, ceiling),
            yaw_deg: 0.0,
        };
        (Some(b), None)
    }
}

/// One candidate of the widened generator (see "Random worlds" in the module documentation).
fn candidate_wide(rng: &mut SmallRng, seed: u64) -> World {
    let w = cells5(rng.random_range(WIDE_ARENA_MIN_M[0]..=WIDE_ARENA_MAX_M[0]));
    let h = cells5(rng.random_range(WIDE_ARENA_MIN_M[1]..=WIDE_ARENA_MAX_M[1]));
    let ceiling = (rng.random_range(2.0f32..=2.6) * 10.0).round() / 10.0;
    let mut start = [cm(rng.random_range(0.5..=0.9)), cm(rng.random_range(0.5..=h - 0.5))];
    let mut goal = [cm(w - rng.random_range(0.5..=0.9)), cm(rng.random_range(0.4..=h - 0.4))];
    let mirrored = rng.random_bool(0.5);
    if mirrored {
        start[0] = cm(w - start[0]);
        goal[0] = cm(w - goal[0]);
    }
    // Home: under the take-off point (within 5 cm), or (one world in six) beside it, the drone starting on
    // the floor 0.25–0.35 m from the pad's centre.
    let home = if rng.random_bool(1.0 / 6.0) {
        pad_near(rng, start, (0.25, 0.35), [w, h])
    } else {
        pad_near(rng, start, (0.0, 0.05), [w, h])
    };
    // The goal pad: 0.05–0.35 m from the nominal goal, and in one world in three 0.1–0.25 m from a wall
    // (the two side walls or the far end).
    let pad_by_wall = rng.random_bool(1.0 / 3.0);
    let goal_pad = if pad_by_wall {
        let gap = cm(rng.random_range(NEAR_PAD_GAP_M.0..=NEAR_PAD_GAP_M.1));
        let half = PAD_SIZE[0] / 2.0;
        let c = match rng.random_range(0..3u8) {
            0 => [goal[0] + rng.random_range(-0.2..=0.2), half + gap],
            1 => [goal[0] + rng.random_range(-0.2..=0.2), h - half - gap],
            _ if mirrored => [half + gap, goal[1] + rng.random_range(-0.2..=0.2)],
            _ => [w - half - gap, goal[1] + rng.random_range(-0.2..=0.2)],
        };
        let c = [cm(c[0].clamp(half, w - half)), cm(c[1].clamp(half, h - half))];
        // The nominal goal within 0.35 m of the pad, inside the arena with room for the body.
        let d = rng.random_range(0.05..=0.33f32);
        let a = rng.random_range(0.0..std::f32::consts::TAU);
        goal = [
            cm((c[0] + d * a.cos()).clamp(0.3, w - 0.3)),
            cm((c[1] + d * a.sin()).clamp(0.3, h - 0.3)),
        ];
        Pad {
            center: c,
            size: PAD_SIZE,
            height: PAD_HEIGHT,
            yaw_deg: 0.0,
        }
    } else {
        pad_near(rng, goal, (0.05, 0.35), [w, h])
    };
    // Start and home keep the classic keep-out; the goal end keeps it from walls and the filler obstacles,
    // but the obstacle next to the pad and the forest come closer by design.
    let keep = KeepOut {
        points: vec![start, goal],
        pads: vec![home.footprint(), goal_pad.footprint()],
    };
    let near_keep = KeepOut {
        points: vec![start],
        pads: vec![home.footprint()],
    };
    let clear_of_goal_pad_rect =
        |r: ([f32; 2], [f32; 2]), gap: f32| rect_rect_distance(r, goal_pad.footprint()) >= gap - 1e-4;
    let clear_of_goal_pad_disc =
        |c: [f32; 2], r: f32, gap: f32| rect_point_distance(goal_pad.footprint(), c) - r >= gap - 1e-4;

    let mut boxes = Vec::new();
    let mut cylinders = Vec::new();
    let (x_lo, x_hi) = (start[0].min(goal[0]) + 0.9, start[0].max(goal[0]) - 0.9);
    if rng.random_bool(0.35) {
        // A zig-zag corridor: walls across the arena whose gaps alternate between the two side walls, so each
        // turn lies next to an arena wall.
        let n = rng.random_range(2..=4);
        let mut bottom = rng.random_bool(0.5);
        let mut x = x_lo;
        for _ in 0..n {
            let t = cm(rng.random_range(0.05..=0.2));
            let gap = cm(rng.random_range(0.6..=0.9));
            if x + t > x_hi {
                break;
            }
            let xa = cm(x);
            let b = if bottom {
                BoxObstacle {
                    min: [xa, gap],
                    max: [cm(xa + t), h],
                    height: ceiling,
                    yaw_deg: 0.0,
                }
            } else {
                BoxObstacle {
                    min: [xa, 0.0],
                    max: [cm(xa + t), cm(h - gap)],
                    height: ceiling,
                    yaw_deg: 0.0,
                }
            };
            if keep.allows_rect(b.footprint()) {
                boxes.push(b);
                bottom = !bottom;
            }
            x = xa + t + rng.random_range(0.7..=1.2);
        }
    } else {
        // Walls across the arena, each with one gap anywhere.
        let walls = rng.random_range(0..=3);
        walls_with_gaps(rng, walls, (x_lo, x_hi), h, ceiling, &keep, &mut boxes);
    }

    // An obstacle 0.1–0.25 m from the goal pad (one world in three).
    if rng.random_bool(1.0 / 3.0) {
        for _ in 0..20 {
            let gap = cm(rng.random_range(NEAR_PAD_GAP_M.0..=NEAR_PAD_GAP_M.1));
            match obstacle_next_to(rng, &goal_pad, gap, ceiling) {
                (Some(b), _) if near_keep.allows_rect(b.footprint()) && clear_of_goal_pad_rect(b.footprint(), 0.1) => {
                    boxes.push(b);
                    break;
                }
                (_, Some(c))
                    if near_keep.allows_disc(c.center, c.radius) && clear_of_goal_pad_disc(c.center, c.radius, 0.1) =>
                {
                    cylinders.push(c);
                    break;
                }
                _ => {}
            }
        }
    }

    // A forest of thin cylinders around the goal (one world in three): up to 4–9 of them, centres 0.3–1.1 m
    // from the goal pad's centre, at least 0.1 m from the pad and 0.5–0.7 m apart edge to edge (room for the
    // drone's inflated path between them, so that the forest is a maze rather than a fence).
    if rng.random_bool(1.0 / 3.0) {
        let n = rng.random_range(4..=9);
        let spacing = rng.random_range(0.5..=0.7f32);
        let first = cylinders.len();
        for _ in 0..n {
            for _ in 0..30 {
                let r = cm(rng.random_range(FOREST_RADIUS_M.0..=FOREST_RADIUS_M.1));
                let d = rng.random_range(0.3..=1.1f32);
                let a = rng.random_range(0.0..std::f32::consts::TAU);
                let c = [
                    cm(goal_pad.center[0] + d * a.cos()),
                    cm(goal_pad.center[1] + d * a.sin()),
                ];
                let inside = c[0] - r > 0.05 && c[1] - r > 0.05 && c[0] + r < w - 0.05 && c[1] + r < h - 0.05;
                let apart = cylinders[first..]
                    .iter()
                    .all(|o: &Cylinder| dist(o.center, c) - o.radius - r >= spacing);
                if inside && apart && near_keep.allows_disc(c, r) && clear_of_goal_pad_disc(c, r, FOREST_PAD_GAP_M) {
                    cylinders.push(Cylinder {
                        center: c,
                        radius: r,
                        height: obstacle_height(rng, ceiling),
                    });
                    break;
                }
            }
        }
    }

    // Filler: up to three boxes and three cylinders anywhere, with the classic keep-out.
    let count = rng.random_range(0..=3);
    scatter_boxes(rng, count, [w, h], ceiling, &keep, &mut boxes);
    let count = rng.random_range(0..=3);
    scatter_cylinders(rng, count, [w, h], ceiling, &keep, &mut cylinders);

    generated_world(seed, [w, h], ceiling, [start, goal], [home, goal_pad], boxes, cylinders)
}

/// The last resort: the default world's arena, mission and pads without obstacles.
fn open_world(seed: u64) -> World {
    let mut w = World::default_world();
    w.name = format!("random-{seed}");
    w.boxes.clear();
    w.cylinders.clear();
    w.sim.seed = seed;
    w
}

/// Which random generator `--random` uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Generator {
    /// The widened generator: 4 × 2 to 6.4 × 3.2 m arenas, pads next to walls and obstacles,
    /// forests of thin cylinders around the goal, zig-zag corridors, goal pads up to 0.35 m off.
    #[default]
    Wide,
    /// The older generator (its seeds give the same worlds as before, for the older figures).
    Classic,
    /// Rooms as people have them, over the firmware's whole range of arenas: open sides, tables, shelves,
    /// sofas, turned boxes, polygons, walkers, poor floor patches, pads of every size, hand placement.
    Rooms,
}

impl World {
    /// A random world for `seed` from the widened generator (see "Random worlds" in the module
    /// documentation); always valid and solvable with [`SOLVABILITY_INFLATION_M`]; the same for the same
    /// seed. Its `name` is `random-SEED` and its `sim.seed` is `seed`.
    pub fn random(seed: u64) -> World {
        Self::random_with(Generator::Wide, seed)
    }

    /// A random world of the older generator (walls with gaps, boxes, cylinders, every
    /// obstacle 0.4 m from the pads, 4.5–6 × 2.4–3 m arenas): the same world for a seed as before.
    pub fn random_classic(seed: u64) -> World {
        Self::random_with(Generator::Classic, seed)
    }

    /// A random world of `generator` for `seed`.
    pub fn random_with(generator: Generator, seed: u64) -> World {
        let mut rng = SmallRng::seed_from_u64(seed);
        for _ in 0..MAX_ATTEMPTS {
            let w = match generator {
                Generator::Classic => candidate(&mut rng, seed),
                Generator::Wide => candidate_wide(&mut rng, seed),
                Generator::Rooms => {
                    let w = super::rooms::candidate(&mut rng, seed);
                    if super::rooms::fair(&w) {
                        return w;
                    }
                    continue;
                }
            };
            let start_room = generator == Generator::Classic || w.start_leaves_room_beside_home_pad();
            if start_room && w.check().is_ok() && w.is_solvable(SOLVABILITY_INFLATION_M) {
                return w;
            }
        }
        open_world(seed)
    }

    /// Whether the drone starts on the home pad's top or at least [`START_PAD_GAP_M`] clear of its sides.
    fn start_leaves_room_beside_home_pad(&self) -> bool {
        let Some(home) = self.pads.first() else {
            return true;
        };
        let start = self.mission.start;
        let footprint = home.footprint();
        let on_top = (0..2).all(|k| start[k] >= footprint.0[k] && start[k] <= footprint.1[k]);
        on_top || rect_point_distance(footprint, start) - super::BODY_RADIUS_M >= START_PAD_GAP_M - 1e-4
    }

    /// Whether a drone can fly from `mission.start` to the nominal goal, the goal pad's centre and the home
    /// pad's centre, on the 5 cm grid of the arena, avoiding every cell whose centre has less than
    /// `inflation_m` of [`World::clearance`] at the cruise height (walls included). Moves as the planner's
    /// (8 neighbours, no corner cutting), which connect the same cells as 4-neighbour moves.
    pub fn is_solvable(&self, inflation_m: f32) -> bool {
        let Some(shape) = self.grid_shape() else {
            return false;
        };
        let blocked = self.blocked_cells(shape, inflation_m);
        let index = |p: [f32; 2]| shape.cell_at(p[0], p[1]).map(|c| shape.index(c));
        let Some(start) = index(self.mission.start) else {
            return false;
        };
        let mut targets = vec![index(self.mission.goal)];
        targets.extend(self.goal_pad().map(|p| index(p.center)));
        targets.extend(self.home_pad().map(|p| index(p.center)));
        if blocked.get(start).copied().unwrap_or(true) {
            return false;
        }
        let mut seen = vec![false; blocked.len()];
        let mut queue = VecDeque::from([start]);
        seen[start] = true;
        let (w, h) = (i32::from(shape.width), i32::from(shape.height));
        while let Some(i) = queue.pop_front() {
            let c = shape.cell(i);
            let (x, y) = (i32::from(c.x), i32::from(c.y));
            for (dx, dy) in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= w || ny >= h {
                    continue;
                }
                let n = (ny * w + nx) as usize;
                if !seen[n] && !blocked[n] {
                    seen[n] = true;
                    queue.push_back(n);
                }
            }
        }
        targets
            .into_iter()
            .all(|t| t.is_some_and(|t| seen.get(t).copied().unwrap_or(false)))
    }
}
