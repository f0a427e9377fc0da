//! Geometry queries on a [`World`]: ray casts (the rangers), horizontal clearance (the body disc), the
//! surface under a point, pads, and the true occupancy grid. Computed in `f64`, returned in `f32`. Also the
//! [`crate::physics::Geometry`] the physics and the sensors read.

use cfnav::nav::map::GridShape;

use super::{OCCUPANCY_MIN_HEIGHT_M, World};

/// A solid standing on the floor: a box (obstacle or pad) or a vertical cylinder, from z = 0 to `top`.
#[derive(Clone, Copy, Debug)]
enum Solid {
    Block { lo: [f64; 2], hi: [f64; 2], top: f64 },
    Column { c: [f64; 2], r: f64, top: f64 },
}

/// Intersect the parameter interval `[t0, t1]` with the slab `lo ≤ o + t·d ≤ hi`; false when it empties.
fn clip_slab(o: f64, d: f64, lo: f64, hi: f64, t0: &mut f64, t1: &mut f64) -> bool {
    if d == 0.0 {
        return o >= lo && o <= hi;
    }
    let (a, b) = ((lo - o) / d, (hi - o) / d);
    let (a, b) = if a <= b { (a, b) } else { (b, a) };
    *t0 = t0.max(a);
    *t1 = t1.min(b);
    *t0 <= *t1
}

impl Solid {
    fn top(&self) -> f64 {
        match *self {
            Solid::Block { top, .. } | Solid::Column { top, .. } => top,
        }
    }

    /// Smallest `t ≥ 0` with `o + t·d` in the solid (closed), for a unit `d`.
    fn entry(&self, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        match *self {
            Solid::Block { lo, hi, .. } => {
                for i in 0..2 {
                    if !clip_slab(o[i], d[i], lo[i], hi[i], &mut t0, &mut t1) {
                        return None;
                    }
                }
            }
            Solid::Column { c, r, .. } => {
                let (px, py) = (o[0] - c[0], o[1] - c[1]);
                let a = d[0] * d[0] + d[1] * d[1];
                let cc = px * px + py * py - r * r;
                if a < 1e-18 {
                    if cc > 0.0 {
                        return None;
                    }
                } else {
                    let b = px * d[0] + py * d[1];
                    let disc = b * b - a * cc;
                    if disc < 0.0 {
                        return None;
                    }
                    let s = disc.sqrt();
                    t0 = (-b - s) / a;
                    t1 = (-b + s) / a;
                }
            }
        }
        if !clip_slab(o[2], d[2], 0.0, self.top(), &mut t0, &mut t1) || t1 < 0.0 {
            return None;
        }
        Some(t0.max(0.0))
    }

    /// Signed horizontal distance from `(x, y)` to the footprint (negative inside).
    fn footprint_distance(&self, x: f64, y: f64) -> f64 {
        match *self {
            Solid::Block { lo, hi, .. } => {
                let dx = (lo[0] - x).max(x - hi[0]);
                let dy = (lo[1] - y).max(y - hi[1]);
                if dx <= 0.0 && dy <= 0.0 {
                    dx.max(dy)
                } else {
                    dx.max(0.0).hypot(dy.max(0.0))
                }
            }
            Solid::Column { c, r, .. } => (x - c[0]).hypot(y - c[1]) - r,
        }
    }
}

impl World {
    /// Every solid but the arena's shell: pads, boxes, cylinders.
    fn solids(&self) -> impl Iterator<Item = Solid> + '_ {
        let pads = self.pads.iter().map(|p| {
            let (lo, hi) = p.footprint();
            Solid::Block {
                lo: lo.map(f64::from),
                hi: hi.map(f64::from),
                top: f64::from(p.height),
            }
        });
        let boxes = self.boxes.iter().map(|b| Solid::Block {
            lo: b.min.map(f64::from),
            hi: b.max.map(f64::from),
            top: f64::from(b.height),
        });
        let cylinders = self.cylinders.iter().map(|c| Solid::Column {
            c: c.center.map(f64::from),
            r: f64::from(c.radius),
            top: f64::from(c.height),
        });
        pads.chain(boxes).chain(cylinders)
    }

    /// The interior box's far corner `(W, H, ceiling)`.
    fn interior(&self) -> [f64; 3] {
        [
            f64::from(self.arena.size[0]),
            f64::from(self.arena.size[1]),
            f64::from(self.arena.ceiling),
        ]
    }

    /// Distance along the unit `d` from `o` to the arena's shell (walls, floor, ceiling); 0 when `o` is not
    /// strictly inside the arena.
    fn shell_distance(&self, o: [f64; 3], d: [f64; 3]) -> f64 {
        let hi = self.interior();
        if (0..3).any(|i| o[i] <= 0.0 || o[i] >= hi[i]) {
            return 0.0;
        }
        let mut t = f64::INFINITY;
        for i in 0..3 {
            if d[i] > 0.0 {
                t = t.min((hi[i] - o[i]) / d[i]);
            } else if d[i] < 0.0 {
                t = t.min(-o[i] / d[i]);
            }
        }
        t
    }

    /// Distance from `origin` along `dir` (any non-zero length) to the first surface: the arena's walls,
    /// floor and ceiling, boxes, cylinders (sides and top cap), pads. `Some(0.0)` when the origin is inside a
    /// solid or on its surface; `None` when nothing lies within `max_range_m`, or for a zero or non-finite
    /// direction or origin. Exact: slabs for boxes, a quadratic for cylinders.
    pub fn ray_cast(&self, origin: [f32; 3], dir: [f32; 3], max_range_m: f32) -> Option<f32> {
        let o = origin.map(f64::from);
        let d = dir.map(f64::from);
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !(n.is_finite() && n > 0.0 && o.iter().all(|v| v.is_finite())) || max_range_m.is_nan() {
            return None;
        }
        let d = d.map(|v| v / n);
        let mut best = self.shell_distance(o, d);
        for s in self.solids() {
            if let Some(t) = s.entry(o, d) {
                best = best.min(t);
            }
        }
        (best <= f64::from(max_range_m)).then_some(best as f32)
    }

    /// Horizontal distance from `(x, y)` to the nearest obstacle present at height `z`: the arena walls and
    /// every box, cylinder and pad taller than `z`. Negative inside one (or outside the arena). A body disc
    /// centred there collides when this is below [`super::BODY_RADIUS_M`].
    pub fn clearance(&self, x: f32, y: f32, z: f32) -> f32 {
        let (x, y, z) = (f64::from(x), f64::from(y), f64::from(z));
        let hi = self.interior();
        // The walls: the distance to the interior's edge inside it, minus the distance to the interior outside.
        let (ox, oy) = ((-x).max(x - hi[0]).max(0.0), (-y).max(y - hi[1]).max(0.0));
        let mut c = if ox > 0.0 || oy > 0.0 {
            -ox.hypot(oy)
        } else {
            x.min(hi[0] - x).min(y).min(hi[1] - y)
        };
        for s in self.solids() {
            if s.top() > z {
                c = c.min(s.footprint_distance(x, y));
            }
        }
        c as f32
    }

    /// Whether a body disc at `(x, y, z)` touches an obstacle or a wall (clearance below the body radius).
    pub fn collides(&self, x: f32, y: f32, z: f32) -> bool {
        let c = self.clearance(x, y, z);
        c.is_nan() || c < super::BODY_RADIUS_M
    }

    /// Height of what a drone would stand on at `(x, y)`: the top of the tallest pad, box or cylinder whose
    /// footprint contains the point (edges included), else the floor, 0.
    pub fn surface_height(&self, x: f32, y: f32) -> f32 {
        let (x, y) = (f64::from(x), f64::from(y));
        self.solids()
            .filter(|s| s.footprint_distance(x, y) <= 0.0)
            .map(|s| s.top())
            .fold(0.0, f64::max) as f32
    }

    /// The pad whose top contains `(x, y)` (edges included), if any.
    pub fn pad_index_at(&self, x: f32, y: f32) -> Option<usize> {
        self.pads
            .iter()
            .position(|p| (x - p.center[0]).abs() <= p.size[0] / 2.0 && (y - p.center[1]).abs() <= p.size[1] / 2.0)
    }

    /// The pad a landing at (x, y) is scored against: the pad under it (`true`), else the nearest pad
    /// (`false`); index 0 when the world has none.
    pub fn landing_pad_at(&self, x: f32, y: f32) -> (usize, bool) {
        match self.pad_index_at(x, y) {
            Some(i) => (i, true),
            None => {
                let nearest = self
                    .pads
                    .iter()
                    .enumerate()
                    .map(|(i, pad)| (i, (pad.center[0] - x).hypot(pad.center[1] - y)))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map_or(0, |(i, _)| i);
                (nearest, false)
            }
        }
    }

    /// Row-major cells of `shape` whose centre lies outside the arena or inside an obstacle (box, cylinder or
    /// pad) taller than [`OCCUPANCY_MIN_HEIGHT_M`]: what a perfect map would hold.
    pub fn true_occupancy(&self, shape: GridShape) -> Vec<bool> {
        let hi = self.interior();
        (0..shape.cells())
            .map(|i| {
                let (x, y) = shape.center_of(shape.cell(i));
                let (x, y) = (f64::from(x), f64::from(y));
                x <= 0.0
                    || y <= 0.0
                    || x >= hi[0]
                    || y >= hi[1]
                    || self
                        .solids()
                        .any(|s| s.top() > f64::from(OCCUPANCY_MIN_HEIGHT_M) && s.footprint_distance(x, y) <= 0.0)
            })
            .collect()
    }

    /// Row-major cells of `shape` whose centre has less than `inflation_m` of [`World::clearance`] at the
    /// cruise height: the true obstacles and walls inflated by `inflation_m`.
    pub fn blocked_cells(&self, shape: GridShape, inflation_m: f32) -> Vec<bool> {
        (0..shape.cells())
            .map(|i| {
                let (x, y) = shape.center_of(shape.cell(i));
                let c = self.clearance(x, y, self.mission.height);
                c.is_nan() || c < inflation_m
            })
            .collect()
    }
}

/// The world as the physics and the sensors see it.
impl crate::physics::Geometry for World {
    fn ray_cast(&self, origin: [f32; 3], dir: [f32; 3], max_range_m: f32) -> Option<f32> {
        World::ray_cast(self, origin, dir, max_range_m)
    }

    fn surface_height(&self, x: f32, y: f32) -> f32 {
        World::surface_height(self, x, y)
    }

    /// The arena's walls, floor and ceiling.
    fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        Some(([0.0; 3], [self.arena.size[0], self.arena.size[1], self.arena.ceiling]))
    }
}
