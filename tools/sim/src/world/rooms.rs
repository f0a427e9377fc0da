//! The `rooms` generator (`cfnav sim --random N --generator rooms`): rooms as people have them, over the
//! whole range of arenas the firmware maps.
//!
//! Drawn, in this order from one random stream: the arena (width and depth in whole 5 cm cells, from
//! [`ROOM_MIN_M`] up to what `cfnav::nav::map` holds: at most `MAX_WIDTH_CELLS` × `MAX_HEIGHT_CELLS` and at
//! most `ARENA_CELLS` cells, so larger rooms appear by themselves when the firmware's grid grows); the
//! ceiling (2.2–2.8 m); each side open one time in five (never all four); the take-off point 0.5–0.9 m
//! from one end of the long axis and the nominal goal as far from the other; the pads (each side
//! [`PAD_SIDE_M`], square half the time, [`PAD_HEIGHT_M`] high, turned up to ±45° half the time), the home
//! pad within 3 cm of the take-off point, the goal pad 5–30 cm from the nominal goal; the drone put down by
//! hand within 4 cm of the take-off point and up to ±10° turned (`mission.placed`, always on the home
//! pad's top). Then the furniture, each piece kept [`super::KEEP_OUT_M`] from the pads, the take-off point and the
//! nominal goal: 0–2 tables (four legs 2–3 cm in radius, 0.72 m tall, at the corners of a 0.6–1.4 × 0.5–0.9
//! m top), 0–2 shelves against walls that exist (0.25–0.4 m deep, 0.6–1.6 m long, 1–2 m tall), 0–1 sofa
//! (0.8–0.9 × 1.6–2.2 m, 0.8 m tall, turned up to ±30°), 0–3 boxes turned by any angle, 0–2 polygons
//! (3–6 corners around a centre, counter-clockwise); 0–2 walkers (radius 0.2–0.25 m, 1.7–1.9 m tall,
//! 0.2–0.5 m/s) on a straight path across the room that keeps 0.3 m beyond their radius from the pads,
//! the take-off point and the nominal goal; 0–2 poor floor patches (0.5–1.5 m sides, SQUAL 10–60 and/or
//! a dropout probability 0.2–0.7).
//!
//! A candidate is kept only if it validates and is solvable with [`super::SOLVABILITY_INFLATION_M`] with every
//! side counted as walled (the drone must stay inside the arena) and the walkers left out (they give way);
//! otherwise the generator draws again from the same stream, so a seed always gives the same room.

use cfnav::nav::map::{ARENA_CELLS, CELL_SIZE_M, MAX_HEIGHT_CELLS, MAX_WIDTH_CELLS};
use rand::Rng;
use rand::rngs::SmallRng;

use super::random::{KeepOut, cm};
use super::{
    ALL_WALLS, Arena, BoxObstacle, Cylinder, DEFAULT_HEIGHT_M, DEFAULT_SPEED_MPS, DEFAULT_TIME_LIMIT_S, Expect,
    FloorPatch, MOVER_GIVE_WAY_M, Mission, Mover, PAD_HEIGHT_M, PAD_SIDE_M, Pad, Polygon, SimSettings, WALL_NAMES,
    WALL_NORTH, WALL_SOUTH, WALL_WEST, World, dist,
};
use crate::stress::Stress;

/// Smallest room side the generator draws, metres.
pub const ROOM_MIN_M: f32 = 2.0;

/// The largest room side the firmware maps along x and along y (5 cm cells), and its cell capacity.
pub fn room_capacity() -> ([u16; 2], usize) {
    ([MAX_WIDTH_CELLS, MAX_HEIGHT_CELLS], ARENA_CELLS)
}

/// Width and depth of a room, metres: whole cells within [`room_capacity`].
fn room_size(rng: &mut SmallRng) -> [f32; 2] {
    let ([max_w, max_h], capacity) = room_capacity();
    let min_cells = (ROOM_MIN_M / CELL_SIZE_M).round() as usize;
    let max_w = usize::from(max_w).min(capacity / min_cells).max(min_cells);
    let wc = rng.random_range(min_cells..=max_w);
    let max_h = usize::from(max_h).min(capacity / wc).max(min_cells);
    let hc = rng.random_range(min_cells..=max_h);
    [wc as f32 * CELL_SIZE_M, hc as f32 * CELL_SIZE_M]
}

fn pad(rng: &mut SmallRng, center: [f32; 2]) -> Pad {
    let [lo, hi] = PAD_SIDE_M;
    let a = cm(rng.random_range(lo..=hi));
    let b = if rng.random_bool(0.5) {
        a
    } else {
        cm(rng.random_range(lo..=hi))
    };
    let height = cm(rng.random_range(PAD_HEIGHT_M[0]..=PAD_HEIGHT_M[1]));
    let yaw_deg = if rng.random_bool(0.5) {
        rng.random_range(-45.0f32..=45.0).round()
    } else {
        0.0
    };
    Pad {
        center,
        size: [a, b],
        height,
        yaw_deg,
    }
}

/// A point `d` (drawn from `range`) from `c` in a random direction.
fn around(rng: &mut SmallRng, c: [f32; 2], range: (f32, f32)) -> [f32; 2] {
    let d = rng.random_range(range.0..=range.1);
    let a = rng.random_range(0.0..std::f32::consts::TAU);
    [c[0] + d * a.cos(), c[1] + d * a.sin()]
}

/// Swap x and y when the room's long axis is y (the generator lays rooms out along x).
fn along(long_x: bool, p: [f32; 2]) -> [f32; 2] {
    if long_x { p } else { [p[1], p[0]] }
}

/// Whether a point lies at least `margin` inside the arena.
fn inside(p: [f32; 2], [w, h]: [f32; 2], margin: f32) -> bool {
    p[0] >= margin && p[1] >= margin && p[0] <= w - margin && p[1] <= h - margin
}

/// One candidate room (see the module documentation).
pub(super) fn candidate(rng: &mut SmallRng, seed: u64) -> World {
    let size = room_size(rng);
    let [w, h] = size;
    let ceiling = (rng.random_range(2.2f32..=2.8) * 10.0).round() / 10.0;
    let mut walls = ALL_WALLS;
    for &(_, bit) in &WALL_NAMES {
        if rng.random_bool(0.2) {
            walls &= !bit;
        }
    }
    if walls == 0 {
        walls = WALL_NAMES[rng.random_range(0..4)].1;
    }

    // Start and goal along the long axis, a random end first.
    let long_x = w >= h;
    let (l, s) = if long_x { (w, h) } else { (h, w) };
    let flip = rng.random_bool(0.5);
    let mut ends = [
        [cm(rng.random_range(0.5..=0.9)), cm(rng.random_range(0.5..=s - 0.5))],
        [cm(l - rng.random_range(0.5..=0.9)), cm(rng.random_range(0.5..=s - 0.5))],
    ];
    if flip {
        ends.swap(0, 1);
    }
    let start = along(long_x, ends[0]);
    let goal = along(long_x, ends[1]);
    let home_c = around(rng, start, (0.0, 0.03)).map(cm);
    let home = pad(rng, home_c);
    let goal_c = around(rng, goal, (0.05, 0.3)).map(cm);
    let goal_c = [goal_c[0].clamp(0.3, w - 0.3), goal_c[1].clamp(0.3, h - 0.3)];
    let goal_pad = pad(rng, goal_c);
    let placed_at = around(rng, start, (0.0, 0.04));
    let placed = [
        cm(placed_at[0]),
        cm(placed_at[1]),
        rng.random_range(-10.0f32..=10.0).round(),
    ];

    let keep = KeepOut {
        points: vec![start, goal, [placed[0], placed[1]]],
        pads: vec![home.footprint(), goal_pad.footprint()],
    };
    let mut boxes: Vec<BoxObstacle> = Vec::new();
    let mut cylinders: Vec<Cylinder> = Vec::new();
    let mut polygons: Vec<Polygon> = Vec::new();

    // Tables: four thin legs at the corners of the top.
    for _ in 0..rng.random_range(0..=2) {
        for _ in 0..20 {
            let top = [cm(rng.random_range(0.6..=1.4)), cm(rng.random_range(0.5..=0.9))];
            if top[0] > w - 0.2 || top[1] > h - 0.2 {
                break;
            }
            let lo = [
                cm(rng.random_range(0.1..=w - top[0] - 0.1)),
                cm(rng.random_range(0.1..=h - top[1] - 0.1)),
            ];
            let r = cm(rng.random_range(0.02..=0.03));
            let legs: Vec<Cylinder> = [
                [0.05, 0.05],
                [top[0] - 0.05, 0.05],
                [0.05, top[1] - 0.05],
                [top[0] - 0.05, top[1] - 0.05],
            ]
            .iter()
            .map(|o| Cylinder {
                center: [cm(lo[0] + o[0]), cm(lo[1] + o[1])],
                radius: r,
                height: 0.72,
            })
            .collect();
            if keep.allows_rect((lo, [lo[0] + top[0], lo[1] + top[1]])) {
                cylinders.extend(legs);
                break;
            }
        }
    }
    // Shelves against walls that exist.
    for _ in 0..rng.random_range(0..=2) {
        for _ in 0..20 {
            let side = WALL_NAMES[rng.random_range(0..4)].1;
            if walls & side == 0 {
                continue;
            }
            let depth = cm(rng.random_range(0.25..=0.4));
            let length = cm(rng.random_range(0.6..=1.6));
            let height = cm(rng.random_range(1.0..=2.0f32).min(ceiling));
            let (min, max) = match side {
                WALL_SOUTH | WALL_NORTH => {
                    if length > w - 0.1 {
                        continue;
                    }
                    let x = cm(rng.random_range(0.0..=w - length));
                    let y0 = if side == WALL_SOUTH { 0.0 } else { cm(h - depth) };
                    ([x, y0], [cm(x + length).min(w), cm(y0 + depth).min(h)])
                }
                _ => {
                    if length > h - 0.1 {
                        continue;
                    }
                    let y = cm(rng.random_range(0.0..=h - length));
                    let x0 = if side == WALL_WEST { 0.0 } else { cm(w - depth) };
                    ([x0, y], [cm(x0 + depth).min(w), cm(y + length).min(h)])
                }
            };
            let b = BoxObstacle {
                min,
                max,
                height,
                yaw_deg: 0.0,
            };
            if keep.allows_rect(b.footprint()) {
                boxes.push(b);
                break;
            }
        }
    }
    // A sofa, perhaps turned.
    if rng.random_bool(0.5) {
        for _ in 0..20 {
            let sz = [cm(rng.random_range(1.6..=2.2)), cm(rng.random_range(0.8..=0.9))];
            if sz[0] > w - 0.4 || sz[1] > h - 0.4 {
                break;
            }
            let c = [
                rng.random_range(0.2 + sz[0] / 2.0..=w - 0.2 - sz[0] / 2.0),
                rng.random_range(0.2 + sz[1] / 2.0..=h - 0.2 - sz[1] / 2.0),
            ];
            let min = [cm(c[0] - sz[0] / 2.0), cm(c[1] - sz[1] / 2.0)];
            let b = BoxObstacle {
                min,
                max: [cm(min[0] + sz[0]), cm(min[1] + sz[1])],
                height: 0.8,
                yaw_deg: rng.random_range(-30.0f32..=30.0).round(),
            };
            let (lo, hi) = b.footprint();
            if inside(lo, size, 0.0) && inside(hi, size, 0.0) && keep.allows_rect((lo, hi)) {
                boxes.push(b);
                break;
            }
        }
    }
    // Boxes turned by any angle.
    for _ in 0..rng.random_range(0..=3) {
        for _ in 0..20 {
            let sz = [cm(rng.random_range(0.2..=0.8)), cm(rng.random_range(0.2..=0.8))];
            let c = [rng.random_range(0.5..=w - 0.5), rng.random_range(0.5..=h - 0.5)];
            let min = [cm(c[0] - sz[0] / 2.0), cm(c[1] - sz[1] / 2.0)];
            let b = BoxObstacle {
                min,
                max: [cm(min[0] + sz[0]), cm(min[1] + sz[1])],
                height: if rng.random_bool(0.5) {
                    ceiling
                } else {
                    cm(rng.random_range(0.7..=ceiling))
                },
                yaw_deg: rng.random_range(0.0f32..90.0).round(),
            };
            let (lo, hi) = b.footprint();
            if inside(lo, size, 0.0) && inside(hi, size, 0.0) && keep.allows_rect((lo, hi)) {
                boxes.push(b);
                break;
            }
        }
    }
    // Polygons: corners at increasing angles around a centre (simple, counter-clockwise).
    for _ in 0..rng.random_range(0..=2) {
        for _ in 0..20 {
            let n = rng.random_range(3..=6);
            let c = [rng.random_range(0.6..=w - 0.6), rng.random_range(0.6..=h - 0.6)];
            let mut angles: Vec<f32> = (0..n).map(|_| rng.random_range(0.0..std::f32::consts::TAU)).collect();
            angles.sort_by(f32::total_cmp);
            let points: Vec<[f32; 2]> = angles
                .iter()
                .map(|a| {
                    let r = rng.random_range(0.15..=0.5f32);
                    [cm(c[0] + r * a.cos()), cm(c[1] + r * a.sin())]
                })
                .collect();
            let q = Polygon {
                points,
                height: if rng.random_bool(0.5) {
                    ceiling
                } else {
                    cm(rng.random_range(0.7..=ceiling))
                },
            };
            let bounds = super::polygon_bounds(&q.points);
            let ok = inside(bounds.0, size, 0.0)
                && inside(bounds.1, size, 0.0)
                && super::self_crossing(&q.points).is_none()
                && super::twice_area(&q.points) > 1e-3
                && keep.allows_rect(bounds);
            if ok {
                polygons.push(q);
                break;
            }
        }
    }
    // Walkers on a straight path across the room.
    let mut movers = Vec::new();
    for _ in 0..rng.random_range(0..=2) {
        for _ in 0..20 {
            let radius = cm(rng.random_range(0.2..=0.25));
            let a = rng.random_range(0.0..=1.0f32);
            let b = rng.random_range(0.0..=1.0f32);
            let m = radius + 0.05;
            let (p, q) = if rng.random_bool(0.7) {
                // Across the long axis.
                let x = m + a * (l - 2.0 * m);
                (
                    along(long_x, [cm(x), cm(m)]),
                    along(long_x, [cm(m + b * (l - 2.0 * m)), cm(s - m)]),
                )
            } else {
                let y = m + a * (s - 2.0 * m);
                (
                    along(long_x, [cm(m), cm(y)]),
                    along(long_x, [cm(l - m), cm(m + b * (s - 2.0 * m))]),
                )
            };
            let clear = radius + BODY_GAP_M;
            let far = |c: [f32; 2]| segment_point_distance(p, q, c) >= clear;
            let pads_clear = [&home, &goal_pad].iter().all(|pd| {
                let (lo, hi) = pd.footprint();
                segment_point_distance(p, q, pd.center) >= clear + dist(lo, hi) / 2.0
            });
            if far(start) && far(goal) && far([placed[0], placed[1]]) && pads_clear {
                movers.push(Mover {
                    radius,
                    height: cm(rng.random_range(1.7..=1.9f32).min(ceiling)),
                    speed: cm(rng.random_range(0.2..=0.5)),
                    path: vec![p, q],
                    walked_m: 0.0,
                });
                break;
            }
        }
    }
    // Poor floor patches.
    let mut floor = Vec::new();
    for _ in 0..rng.random_range(0..=2) {
        let sz = [
            cm(rng.random_range(0.5..=1.5f32).min(w)),
            cm(rng.random_range(0.5..=1.5f32).min(h)),
        ];
        let min = [
            cm(rng.random_range(0.0..=w - sz[0])),
            cm(rng.random_range(0.0..=h - sz[1])),
        ];
        let kind = rng.random_range(0..3);
        floor.push(FloorPatch {
            min,
            max: [cm(min[0] + sz[0]).min(w), cm(min[1] + sz[1]).min(h)],
            squal: (kind != 1).then(|| rng.random_range(10..=60)),
            flow_dropout: (kind != 0).then(|| cm(rng.random_range(0.2..=0.7))),
        });
    }

    World {
        name: format!("room-{seed}"),
        arena: Arena { size, ceiling, walls },
        mission: Mission {
            start,
            goal,
            height: DEFAULT_HEIGHT_M,
            speed: DEFAULT_SPEED_MPS,
            placed: Some(placed),
        },
        pads: vec![home, goal_pad],
        boxes,
        cylinders,
        polygons,
        movers,
        floor,
        sim: SimSettings {
            seed,
            time_limit: DEFAULT_TIME_LIMIT_S,
            expect: Expect::Completed,
        },
        stress: Stress::default(),
    }
}

/// A walker's path keeps this beyond its radius from the pads, the take-off point and the nominal goal
/// (more than [`MOVER_GIVE_WAY_M`], so that a drone waiting there never stops it for good), metres.
const BODY_GAP_M: f32 = MOVER_GIVE_WAY_M + 0.05;

fn segment_point_distance(a: [f32; 2], b: [f32; 2], p: [f32; 2]) -> f32 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// Whether a room is fair: valid, and solvable with every side walled and without its walkers.
pub(super) fn fair(w: &World) -> bool {
    if w.check().is_err() {
        return false;
    }
    let mut closed = w.clone();
    closed.arena.walls = ALL_WALLS;
    closed.movers.clear();
    closed.is_solvable(super::SOLVABILITY_INFLATION_M)
}
