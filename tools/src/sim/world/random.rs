//! Random worlds (see "Random worlds" in the parent module's documentation) and the solvability check that
//! keeps them fair.

use std::collections::VecDeque;

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::{
    Arena, BoxObstacle, Cylinder, DEFAULT_HEIGHT_M, DEFAULT_SPEED_MPS, DEFAULT_TIME_LIMIT_S, Expect, Mission, Pad,
    SimSettings, World, dist, rect_point_distance, rect_rect_distance,
};

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
fn cm(v: f32) -> f32 {
    (v * 100.0).round() / 100.0
}

/// Round to whole 5 cm cells.
fn cells5(v: f32) -> f32 {
    (v * 20.0).round() / 20.0
}

/// What obstacles must stay away from.
struct KeepOut {
    points: Vec<[f32; 2]>,
    pads: Vec<([f32; 2], [f32; 2])>,
}

impl KeepOut {
    fn allows_rect(&self, r: ([f32; 2], [f32; 2])) -> bool {
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
    let mut wall_xs: Vec<(f32, f32)> = Vec::new();
    for _ in 0..walls {
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
            let gy = cm(rng.random_range(0.0..=h - gap));
            let mut segments = Vec::new();
            if gy > 0.05 {
                segments.push(BoxObstacle {
                    min: [x, 0.0],
                    max: [cm(x + t), gy],
                    height: ceiling,
                });
            }
            if gy + gap < h - 0.05 {
                segments.push(BoxObstacle {
                    min: [x, gy + gap],
                    max: [cm(x + t), h],
                    height: ceiling,
                });
            }
            if segments.iter().all(|b| keep.allows_rect(b.footprint())) {
                boxes.extend(segments);
                wall_xs.push((x, x + t));
                break;
            }
        }
    }

    for _ in 0..rng.random_range(0..=4) {
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
            };
            if keep.allows_rect(b.footprint()) {
                boxes.push(b);
                break;
            }
        }
    }

    let mut cylinders = Vec::new();
    for _ in 0..rng.random_range(0..=4) {
        for _ in 0..20 {
            let r = cm(rng.random_range(0.05..=0.25));
            let center = [cm(rng.random_range(r..=w - r)), cm(rng.random_range(r..=h - r))];
            if keep.allows_disc(center, r) {
                cylinders.push(Cylinder {
                    center,
                    radius: r,
                    height: obstacle_height(rng, ceiling),
                });
                break;
            }
        }
    }

    World {
        name: format!("random-{seed}"),
        arena: Arena { size: [w, h], ceiling },
        mission: Mission {
            start,
            goal,
            height: DEFAULT_HEIGHT_M,
            speed: DEFAULT_SPEED_MPS,
        },
        pads: vec![home, goal_pad],
        boxes,
        cylinders,
        sim: SimSettings {
            seed,
            time_limit: DEFAULT_TIME_LIMIT_S,
            expect: Expect::Completed,
        },
    }
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

impl World {
    /// A random world for `seed` (see "Random worlds" in the module documentation): walls with gaps, boxes,
    /// cylinders, pads near the take-off point and the nominal goal; always valid and solvable with
    /// [`SOLVABILITY_INFLATION_M`]; the same for the same seed. Its `name` is `random-SEED` and its
    /// `sim.seed` is `seed`.
    pub fn random(seed: u64) -> World {
        let mut rng = SmallRng::seed_from_u64(seed);
        for _ in 0..MAX_ATTEMPTS {
            let w = candidate(&mut rng, seed);
            if w.check().is_ok() && w.is_solvable(SOLVABILITY_INFLATION_M) {
                return w;
            }
        }
        open_world(seed)
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
