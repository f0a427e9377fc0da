//! Paths on the grid: reading a path off the planner, shortening it to waypoints joined by straight lines
//! that the inflated map says are clear, and optionally rounding its corners.
//!
//! Non-goals: planning (see [`crate::nav::dstar`]), following a path (the mission does that).
//!
//! Units: cells for [`extract_path`] and [`simplify`]; arena-frame metres for [`smooth`].
//!
//! Memory: the caller's fixed-capacity buffers only. Complexity: extraction O(path · 8); simplification
//! O(path · segment length); smoothing O(waypoints · segment length).

use heapless::Vec;

use crate::nav::dstar::{DStarLite, move_cost};
use crate::nav::map::{CELL_SIZE_M, Cell, GridShape, Traversability};

/// Why no path could be read off.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathError {
    /// The planner has no path from its start.
    NoPath,
    /// The planner's costs do not decrease along the greedy path (the repair was not completed); a loop
    /// guard, never expected after a completed [`DStarLite::compute`].
    Inconsistent,
}

/// A path read off the planner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathSummary {
    /// Sum of the move costs of the cells written to the buffer.
    pub cost: u32,
    /// Whether the buffer reaches the goal (false: it filled up first; what it holds is a valid prefix).
    pub complete: bool,
}

/// Write the planner's current shortest path, start and goal included, into `out` (cleared first).
///
/// Loop guard: the cost-to-goal must strictly decrease at every step, so a path with inconsistent costs is
/// reported as [`PathError::Inconsistent`] instead of looping.
pub fn extract_path<const CELLS: usize, const QUEUE: usize, const N: usize>(
    planner: &DStarLite<CELLS, QUEUE>,
    map: &impl Traversability,
    out: &mut Vec<Cell, N>,
) -> Result<PathSummary, PathError> {
    out.clear();
    let start = planner.start();
    let goal = planner.goal();
    let mut remaining = if start == goal {
        0
    } else {
        planner.rhs_of(start).ok_or(PathError::NoPath)?
    };
    let mut cost = 0u32;
    let mut current = start;
    if out.push(current).is_err() {
        return Ok(PathSummary { cost, complete: false });
    }
    while current != goal {
        let next = planner.next_cell(map, current).ok_or(PathError::NoPath)?;
        let dx = i32::from(next.x) - i32::from(current.x);
        let dy = i32::from(next.y) - i32::from(current.y);
        let step = move_cost(map, i32::from(current.x), i32::from(current.y), dx, dy).ok_or(PathError::NoPath)?;
        let next_remaining = if next == goal {
            0
        } else {
            planner.g(next).ok_or(PathError::NoPath)?
        };
        if next_remaining >= remaining {
            return Err(PathError::Inconsistent);
        }
        if out.push(next).is_err() {
            return Ok(PathSummary { cost, complete: false });
        }
        remaining = next_remaining;
        cost += u32::from(step);
        current = next;
    }
    Ok(PathSummary { cost, complete: true })
}

/// Whether the straight segment between the centres of `a` and `b` crosses only unblocked cells.
///
/// Conservative: every cell the segment touches counts, and where it passes exactly through a cell corner
/// both cells beside the corner count, matching the planner's no-corner-cutting rule.
pub fn line_of_sight(map: &impl Traversability, a: Cell, b: Cell) -> bool {
    let (mut x, mut y) = (i32::from(a.x), i32::from(a.y));
    let (x1, y1) = (i32::from(b.x), i32::from(b.y));
    let (dx, dy) = ((x1 - x).abs(), (y1 - y).abs());
    let (sx, sy) = ((x1 - x).signum(), (y1 - y).signum());
    // Supercover walk between cell centres: `error` tracks which cell boundary the segment crosses next.
    let mut error = dx - dy;
    let mut steps = 1 + dx + dy;
    while steps > 0 {
        if map.is_blocked(x, y) {
            return false;
        }
        steps -= 1;
        if error > 0 {
            x += sx;
            error -= 2 * dy;
        } else if error < 0 {
            y += sy;
            error += 2 * dx;
        } else if steps > 0 {
            // Exactly through a corner: both side cells must be free.
            if map.is_blocked(x + sx, y) || map.is_blocked(x, y + sy) {
                return false;
            }
            x += sx;
            y += sy;
            error += 2 * (dx - dy);
            steps -= 1;
        }
    }
    true
}

/// Shorten a cell path to the waypoints where it must turn: from each kept waypoint, jump to the farthest
/// later cell still in [`line_of_sight`]. The first and last cells are always kept. Writes into `out`
/// (cleared first); returns `false` if `out` filled up (what it holds is then a valid prefix).
pub fn simplify<const M: usize>(map: &impl Traversability, path: &[Cell], out: &mut Vec<Cell, M>) -> bool {
    out.clear();
    let Some(&first) = path.first() else { return true };
    if out.push(first).is_err() {
        return false;
    }
    let mut anchor = 0;
    while anchor + 1 < path.len() {
        let mut reach = anchor + 1;
        while reach + 1 < path.len() && line_of_sight(map, path[anchor], path[reach + 1]) {
            reach += 1;
        }
        if out.push(path[reach]).is_err() {
            return false;
        }
        anchor = reach;
    }
    true
}

/// Round the corners of a waypoint polyline (arena frame, metres) by one pass of corner cutting
/// (points at ¼ and ¾ of every inner segment), keeping a corner wherever the cut chord would cross a
/// blocked cell. End points are kept. Returns `false` if `out` filled up.
pub fn smooth<const M: usize>(
    map: &impl Traversability,
    waypoints: &[(f32, f32)],
    out: &mut Vec<(f32, f32), M>,
) -> bool {
    out.clear();
    let n = waypoints.len();
    if n < 3 {
        return waypoints.iter().all(|&p| out.push(p).is_ok());
    }
    let shape = map.shape();
    let lerp = |a: (f32, f32), b: (f32, f32), t: f32| (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
    if out.push(waypoints[0]).is_err() {
        return false;
    }
    for i in 1..n - 1 {
        let (prev, corner, next) = (waypoints[i - 1], waypoints[i], waypoints[i + 1]);
        let entry = lerp(prev, corner, if i == 1 { 0.5 } else { 0.75 });
        let exit = lerp(corner, next, if i == n - 2 { 0.5 } else { 0.25 });
        let clear = segment_clear(map, shape, entry, exit);
        let pushed = if clear {
            out.push(entry).and_then(|_| out.push(exit))
        } else {
            out.push(corner)
        };
        if pushed.is_err() {
            return false;
        }
    }
    out.push(waypoints[n - 1]).is_ok()
}

/// Length of a cell path in metres (straight and diagonal steps).
pub fn length_m(path: &[Cell]) -> f32 {
    path.windows(2)
        .map(|w| {
            let dx = f32::from(w[0].x.abs_diff(w[1].x));
            let dy = f32::from(w[0].y.abs_diff(w[1].y));
            libm::sqrtf(dx * dx + dy * dy) * CELL_SIZE_M
        })
        .sum()
}

/// Whether every cell the segment `a`–`b` (arena frame, metres) passes through is unblocked: an exact grid
/// walk (Amanatides–Woo), conservative where the segment passes exactly through a cell corner.
fn segment_clear(map: &impl Traversability, shape: GridShape, a: (f32, f32), b: (f32, f32)) -> bool {
    let (ax, ay, bx, by) = (
        a.0 / CELL_SIZE_M,
        a.1 / CELL_SIZE_M,
        b.0 / CELL_SIZE_M,
        b.1 / CELL_SIZE_M,
    );
    if !(ax.is_finite() && ay.is_finite() && bx.is_finite() && by.is_finite()) {
        return false;
    }
    let limit = 2.0 * f32::from(shape.width.max(shape.height));
    if ax.abs() > limit || ay.abs() > limit || bx.abs() > limit || by.abs() > limit {
        return false;
    }
    let (mut x, mut y) = (libm::floorf(ax) as i32, libm::floorf(ay) as i32);
    let (end_x, end_y) = (libm::floorf(bx) as i32, libm::floorf(by) as i32);
    let (dx, dy) = (bx - ax, by - ay);
    let (step_x, step_y) = (if dx > 0.0 { 1 } else { -1 }, if dy > 0.0 { 1 } else { -1 });
    // Parameter t in [0, 1] along the segment at which the walk crosses the next vertical/horizontal line.
    let first_crossing = |p: f32, cell: i32, d: f32| {
        if d > 0.0 {
            (cell as f32 + 1.0 - p) / d
        } else if d < 0.0 {
            (cell as f32 - p) / d
        } else {
            f32::INFINITY
        }
    };
    let (mut t_x, mut t_y) = (first_crossing(ax, x, dx), first_crossing(ay, y, dy));
    let (dt_x, dt_y) = (
        if dx != 0.0 { 1.0 / dx.abs() } else { f32::INFINITY },
        if dy != 0.0 { 1.0 / dy.abs() } else { f32::INFINITY },
    );
    let mut steps = (end_x - x).abs() + (end_y - y).abs() + 2;
    loop {
        if map.is_blocked(x, y) {
            return false;
        }
        if (x == end_x && y == end_y) || steps == 0 {
            return true;
        }
        steps -= 1;
        if t_x < t_y {
            x += step_x;
            t_x += dt_x;
        } else if t_y < t_x {
            y += step_y;
            t_y += dt_y;
        } else {
            if map.is_blocked(x + step_x, y) || map.is_blocked(x, y + step_y) {
                return false;
            }
            x += step_x;
            y += step_y;
            t_x += dt_x;
            t_y += dt_y;
        }
    }
}
