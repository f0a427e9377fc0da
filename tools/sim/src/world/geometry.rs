//! Geometry queries on a [`World`]: ray casts (the rangers), horizontal clearance (the body disc), the
//! surface under a point, pads, and the true occupancy grid. Computed in `f64`, returned in `f32`. Also the
//! [`crate::physics::Geometry`] the physics and the sensors read.

use cfnav::nav::map::GridShape;

use super::{
    BODY_RADIUS_M, MOVER_GIVE_WAY_M, OCCUPANCY_MIN_HEIGHT_M, WALL_EAST, WALL_NORTH, WALL_SOUTH, WALL_WEST, World,
};

/// A solid standing on the floor, from z = 0 to `top`: an axis-aligned box (obstacle or pad), a turned box
/// (centre, half sides, cos and sin of the turn), a vertical cylinder, or a prism over a simple polygon.
#[derive(Clone, Copy, Debug)]
enum Solid<'a> {
    Block {
        lo: [f64; 2],
        hi: [f64; 2],
        top: f64,
    },
    Turned {
        c: [f64; 2],
        half: [f64; 2],
        cos: f64,
        sin: f64,
        top: f64,
    },
    Column {
        c: [f64; 2],
        r: f64,
        top: f64,
    },
    Prism {
        points: &'a [[f32; 2]],
        top: f64,
    },
}

/// A corner of a polygon in `f64`.
fn corner(points: &[[f32; 2]], i: usize) -> [f64; 2] {
    let p = points[i % points.len()];
    [f64::from(p[0]), f64::from(p[1])]
}

/// Whether `(x, y)` lies inside a simple polygon (crossing number; points on an edge may fall either way,
/// [`polygon_signed_distance`] is what decides contact).
fn polygon_contains(points: &[[f32; 2]], x: f64, y: f64) -> bool {
    let n = points.len();
    let mut inside = false;
    for i in 0..n {
        let (a, b) = (corner(points, i), corner(points, i + 1));
        if (a[1] > y) != (b[1] > y) {
            let xc = a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if x < xc {
                inside = !inside;
            }
        }
    }
    inside
}

/// Distance from `p` to the segment `ab`.
fn segment_distance(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// Signed distance from `p` to a simple polygon's area: distance to its boundary, negative inside.
pub(super) fn polygon_signed_distance(points: &[[f32; 2]], p: [f64; 2]) -> f64 {
    let n = points.len();
    let d = (0..n)
        .map(|i| segment_distance(corner(points, i), corner(points, i + 1), p))
        .fold(f64::INFINITY, f64::min);
    if polygon_contains(points, p[0], p[1]) { -d } else { d }
}

/// Smallest `t ≥ 0` with `o + t·d` in a prism over a simple polygon from z = 0 to `top` (closed): the origin
/// itself, a side face, or the top cap.
fn prism_entry(points: &[[f32; 2]], top: f64, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
    let z_ok = |t: f64| {
        let z = o[2] + t * d[2];
        (-1e-12..=top + 1e-12).contains(&z)
    };
    if (0.0..=top).contains(&o[2]) && polygon_signed_distance(points, [o[0], o[1]]) <= 0.0 {
        return Some(0.0);
    }
    let mut best = f64::INFINITY;
    // Side faces: where the ray's footprint crosses an edge at a height within the prism.
    for i in 0..points.len() {
        let (a, b) = (corner(points, i), corner(points, i + 1));
        let e = [b[0] - a[0], b[1] - a[1]];
        let den = d[0] * e[1] - d[1] * e[0];
        if den.abs() < 1e-15 {
            continue;
        }
        let w = [a[0] - o[0], a[1] - o[1]];
        let t = (w[0] * e[1] - w[1] * e[0]) / den;
        let u = (w[0] * d[1] - w[1] * d[0]) / den;
        if t >= 0.0 && (0.0..=1.0).contains(&u) && z_ok(t) {
            best = best.min(t);
        }
    }
    // The top cap (from above) and the bottom (from below the floor, never in practice).
    for plane in [top, 0.0] {
        if d[2] != 0.0 {
            let t = (plane - o[2]) / d[2];
            if t >= 0.0 && polygon_contains(points, o[0] + t * d[0], o[1] + t * d[1]) {
                best = best.min(t);
            }
        }
    }
    best.is_finite().then_some(best)
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

impl Solid<'_> {
    fn top(&self) -> f64 {
        match *self {
            Solid::Block { top, .. }
            | Solid::Turned { top, .. }
            | Solid::Column { top, .. }
            | Solid::Prism { top, .. } => top,
        }
    }

    /// Smallest `t ≥ 0` with `o + t·d` in the solid (closed), for a unit `d`.
    fn entry(&self, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        match *self {
            Solid::Prism { points, top } => return prism_entry(points, top, o, d),
            Solid::Turned {
                c, half, cos, sin, top, ..
            } => {
                // The box's own frame: turned back by its yaw about its centre, where it is a block.
                let (px, py) = (o[0] - c[0], o[1] - c[1]);
                let lo_ = [cos * px + sin * py, -sin * px + cos * py, o[2]];
                let ld = [cos * d[0] + sin * d[1], -sin * d[0] + cos * d[1], d[2]];
                let block = Solid::Block {
                    lo: [-half[0], -half[1]],
                    hi: half,
                    top,
                };
                return block.entry(lo_, ld);
            }
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
            Solid::Turned { c, half, cos, sin, top } => {
                let (px, py) = (x - c[0], y - c[1]);
                let block = Solid::Block {
                    lo: [-half[0], -half[1]],
                    hi: half,
                    top,
                };
                block.footprint_distance(cos * px + sin * py, -sin * px + cos * py)
            }
            Solid::Prism { points, .. } => polygon_signed_distance(points, [x, y]),
        }
    }
}

/// An axis-aligned block, or a turned one when `yaw_deg` is not 0, of footprint `lo`..`hi`.
fn block<'a>(lo: [f32; 2], hi: [f32; 2], yaw_deg: f32, top: f32) -> Solid<'a> {
    let (lo, hi, top) = (lo.map(f64::from), hi.map(f64::from), f64::from(top));
    if yaw_deg == 0.0 {
        return Solid::Block { lo, hi, top };
    }
    let (sin, cos) = f64::from(yaw_deg).to_radians().sin_cos();
    Solid::Turned {
        c: [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0],
        half: [(hi[0] - lo[0]) / 2.0, (hi[1] - lo[1]) / 2.0],
        cos,
        sin,
        top,
    }
}

impl World {
    /// Every solid but the arena's shell: pads, boxes, cylinders, polygons, and the movers where they stand.
    fn solids(&self) -> impl Iterator<Item = Solid<'_>> + '_ {
        self.static_solids().chain(self.movers.iter().map(|m| Solid::Column {
            c: m.position().map(f64::from),
            r: f64::from(m.radius),
            top: f64::from(m.height),
        }))
    }

    /// The solids that never move: pads, boxes, cylinders, polygons.
    fn static_solids(&self) -> impl Iterator<Item = Solid<'_>> + '_ {
        let pads = self.pads.iter().map(|p| {
            let h = [p.size[0] / 2.0, p.size[1] / 2.0];
            let (lo, hi) = if p.yaw_deg == 0.0 {
                p.footprint()
            } else {
                (
                    [p.center[0] - h[0], p.center[1] - h[1]],
                    [p.center[0] + h[0], p.center[1] + h[1]],
                )
            };
            block(lo, hi, p.yaw_deg, p.height)
        });
        let boxes = self.boxes.iter().map(|b| block(b.min, b.max, b.yaw_deg, b.height));
        let cylinders = self.cylinders.iter().map(|c| Solid::Column {
            c: c.center.map(f64::from),
            r: f64::from(c.radius),
            top: f64::from(c.height),
        });
        let polygons = self.polygons.iter().map(|q| Solid::Prism {
            points: &q.points,
            top: f64::from(q.height),
        });
        pads.chain(boxes).chain(cylinders).chain(polygons)
    }

    /// Walk the movers on by `dt_s`. A mover whose next step would bring its side within
    /// [`MOVER_GIVE_WAY_M`] of the drone's body (the disc of [`BODY_RADIUS_M`] about `drone`'s x, y) and no
    /// farther from it than it is now pauses instead (people give way; one walking away from the drone
    /// goes on). Deterministic; no effect on a world without movers.
    pub fn step_movers(&mut self, dt_s: f32, drone: [f32; 3]) {
        for m in &mut self.movers {
            if !(m.speed > 0.0 && dt_s > 0.0) {
                continue;
            }
            let now = m.position();
            let next_walked = m.walked_m + m.speed * dt_s;
            let next = m.position_after(next_walked);
            let gap = |p: [f32; 2]| (p[0] - drone[0]).hypot(p[1] - drone[1]) - m.radius - BODY_RADIUS_M;
            let (g_now, g_next) = (gap(now), gap(next));
            if g_next < MOVER_GIVE_WAY_M && g_next <= g_now {
                continue;
            }
            m.walked_m = next_walked;
        }
    }

    /// The floor patch under `(x, y)`, if any (the first listed when they overlap).
    pub fn floor_patch_at(&self, x: f32, y: f32) -> Option<&super::FloorPatch> {
        self.floor.iter().find(|p| p.contains(x, y))
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
        if self.arena.walls != super::ALL_WALLS {
            return self.open_shell_distance(o, d);
        }
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

    /// [`World::shell_distance`] when a side is open: the floor and the ceiling go on without end, and each
    /// wall that exists is its side of the arena, `[0, W]` or `[0, H]` long, from the floor to the ceiling.
    /// 0 when `o` is below the floor, above the ceiling or beyond a wall that exists (within its length).
    fn open_shell_distance(&self, o: [f64; 3], d: [f64; 3]) -> f64 {
        let hi = self.interior();
        let a = &self.arena;
        if o[2] <= 0.0 || o[2] >= hi[2] {
            return 0.0;
        }
        // (axis, plane, wall side is beyond when below the plane, present)
        let walls = [
            (1, 0.0, true, a.has_wall(WALL_SOUTH)),
            (0, hi[0], false, a.has_wall(WALL_EAST)),
            (1, hi[1], false, a.has_wall(WALL_NORTH)),
            (0, 0.0, true, a.has_wall(WALL_WEST)),
        ];
        for &(axis, plane, below, present) in &walls {
            let other = 1 - axis;
            let beyond = if below { o[axis] <= plane } else { o[axis] >= plane };
            if present && beyond && (0.0..=hi[other]).contains(&o[other]) {
                return 0.0;
            }
        }
        let mut t = f64::INFINITY;
        if d[2] > 0.0 {
            t = t.min((hi[2] - o[2]) / d[2]);
        } else if d[2] < 0.0 {
            t = t.min(-o[2] / d[2]);
        }
        for &(axis, plane, _, present) in &walls {
            if !present || d[axis] == 0.0 {
                continue;
            }
            let s = (plane - o[axis]) / d[axis];
            let other = 1 - axis;
            if s >= 0.0 && s < t && (0.0..=hi[other]).contains(&(o[other] + s * d[other])) {
                t = s;
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
        let mut c = if self.arena.walls == super::ALL_WALLS {
            // The walls: the distance to the interior's edge inside it, minus the distance to the interior outside.
            let (ox, oy) = ((-x).max(x - hi[0]).max(0.0), (-y).max(y - hi[1]).max(0.0));
            if ox > 0.0 || oy > 0.0 {
                -ox.hypot(oy)
            } else {
                x.min(hi[0] - x).min(y).min(hi[1] - y)
            }
        } else {
            self.open_wall_clearance(x, y)
        };
        for s in self.solids() {
            if s.top() > z {
                c = c.min(s.footprint_distance(x, y));
            }
        }
        c as f32
    }

    /// [`World::clearance`]'s walls when a side is open: the distance to the nearest wall that exists (a
    /// segment along its side), negative beyond it; open sides count for nothing.
    fn open_wall_clearance(&self, x: f64, y: f64) -> f64 {
        let hi = self.interior();
        let a = &self.arena;
        let mut c = f64::INFINITY;
        // (present, signed distance inside the wall's line, position along it, its length)
        for (present, inside, along, length) in [
            (a.has_wall(WALL_SOUTH), y, x, hi[0]),
            (a.has_wall(WALL_EAST), hi[0] - x, y, hi[1]),
            (a.has_wall(WALL_NORTH), hi[1] - y, x, hi[0]),
            (a.has_wall(WALL_WEST), x, y, hi[1]),
        ] {
            if !present {
                continue;
            }
            let past_end = (-along).max(along - length).max(0.0);
            let d = if past_end > 0.0 {
                inside.abs().hypot(past_end)
            } else {
                inside
            };
            c = c.min(d);
        }
        c
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
        self.pads.iter().position(|p| {
            let (dx, dy) = (x - p.center[0], y - p.center[1]);
            let (dx, dy) = if p.yaw_deg == 0.0 {
                (dx, dy)
            } else {
                // In the pad's own frame (turned back by its yaw).
                let (s, c) = p.yaw_deg.to_radians().sin_cos();
                (c * dx + s * dy, -s * dx + c * dy)
            };
            dx.abs() <= p.size[0] / 2.0 && dy.abs() <= p.size[1] / 2.0
        })
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
                        .static_solids()
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
        let a = &self.arena;
        let side = |bit, at: f32, open: f32| if a.has_wall(bit) { at } else { open };
        Some((
            [
                side(WALL_WEST, 0.0, f32::NEG_INFINITY),
                side(WALL_SOUTH, 0.0, f32::NEG_INFINITY),
                0.0,
            ],
            [
                side(WALL_EAST, a.size[0], f32::INFINITY),
                side(WALL_NORTH, a.size[1], f32::INFINITY),
                a.ceiling,
            ],
        ))
    }

    fn flow_floor(&self, x: f32, y: f32) -> Option<(Option<u8>, Option<f32>)> {
        self.floor_patch_at(x, y).map(|p| (p.squal, p.flow_dropout))
    }
}
