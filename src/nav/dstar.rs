//! D* Lite (Koenig & Likhachev, "Fast Replanning for Navigation in Unknown Terrain", IEEE T-RO 2005, the
//! optimized version with the key modifier `km`) on an 8-connected grid.
//!
//! Job: keep the cost-to-goal `g` of every cell consistent with the map the drone believes, repairing it
//! incrementally when cells become blocked or free and while the start (the drone) moves, so that a
//! shortest path from the drone's cell to the goal can be read off greedily (see [`DStarLite::next_cell`]).
//!
//! Non-goals: building the map (see [`crate::nav::grid`]), path shortening and smoothing (see [`crate::nav::path`]).
//!
//! Rules (those of the planner map format, `docs/formats.md`): moves go to the 8 neighbours; a straight move costs 10,
//! a diagonal one 14; a diagonal move is allowed only when both cells it passes between are free (no corner
//! cutting); blocked cells and cells outside the grid cannot be entered. Leaving a blocked cell is allowed,
//! so a drone whose own cell was inflated into an obstacle can still plan its way out. The heuristic is the
//! octile distance `10·max(dx,dy) + 4·min(dx,dy)`, which is exact on an empty grid, hence admissible and
//! consistent.
//!
//! Implementation notes:
//! - The search runs backwards from the goal. `rhs` is kept only for queued cells, as the queue entry's
//!   payload: D* Lite's invariant is that the open list holds exactly the locally inconsistent cells
//!   (`g ≠ rhs`), so every other cell has `rhs = g`. That saves `2·CELLS` bytes.
//! - Costs are `u16` with `u16::MAX` as infinity. A shortest path visits each cell at most once and no
//!   two non-consecutive cells of it are 4-adjacent, so its cost stays far below 65 535 for any grid of at
//!   most 8192 cells; a sum that would still reach it saturates to infinity rather than wrapping.
//! - `km` grows by `h(last, start)` whenever the start has moved since the last repair; keys stay lower
//!   bounds, and a popped cell whose key is stale is re-queued with its fresh key. When `km` gets large the
//!   queue is re-keyed from scratch and `km` restarts at 0.
//! - Changed cells: when a cell's blocked state flips, the edges that change are those entering it and the
//!   diagonals that pass beside it; all of them leave one of its 8 neighbours, so those neighbours get their
//!   `rhs` recomputed from their successors and are re-queued as needed.
//! - Ties on `f = min(g, rhs) + h + km`: the octile heuristic is exact on open ground, so every cell on
//!   some optimal path ties on `f`. The paper's order (smaller `min(g, rhs)` first) expands all of them
//!   before stopping: 424 cells for the seed map's 89-cell first path. The *first search* after
//!   [`DStarLite::reset`] breaks ties in two classes instead (see `key_of`): under-consistent cells first
//!   (a cell whose `g` is too small can tie with the start or with a cell whose `rhs` came through it and
//!   must be raised first), then the settling cell nearest the start (larger `rhs`) first, as an A* prefers
//!   deep nodes; it walks one optimal path and stops at the start (88 expansions), so the first path is
//!   ready in a quarter of the work. Every later repair uses the paper's order (the queue is re-keyed once,
//!   at the first call after the first search): the first replan then expands the remaining optimal cells
//!   (336 on the seed map), after which every optimal path is known, so [`DStarLite::next_cell`]'s
//!   straight-first choice among them is a geometric rule, not an accident of expansion order (the mission
//!   flies the same paths as with the paper's order throughout), and an obstacle dropped on the path finds a
//!   computed alternative (a 20 cm box on the seed path: 9 expansions; 169 if the first search's order were
//!   kept). The Dijkstra-oracle tests in `host-tests/tests/nav/dstar.rs` cover both orders and the switch,
//!   and catch a plain deepest-first order (wrong costs after blocks).
//! - The search stops as soon as the start is consistent and its key is not above the queue's top
//!   (the start's key is recomputed only when the start was expanded or its `rhs` changed).
//! - Move checks read the 4 straight neighbours of a cell once: a diagonal between a cell and its neighbour
//!   at `(dx, dy)` passes between the straight neighbours `(dx, 0)` and `(0, dy)` of either end.
//! - [`DStarLite::compute`] takes an expansion budget. When it is spent the call returns
//!   [`PlanStatus::Incomplete`] with all state intact; the next call resumes. The loop always terminates:
//!   each cell is expanded at most twice per repair (once over-, once under-consistent), so "no path" is an
//!   answer ([`PlanStatus::NoPath`]), never a hang.
//!
//! Memory: `g` `2·CELLS` bytes + the queue `2·CELLS + 10·QUEUE` bytes + a few scalars. The firmware's
//! [`ArenaPlanner`] (7200 cells, 1024 queue entries) takes 39 080 B.
//!
//! Complexity: a repair expands `O(k)` cells for `k` affected cells, each expansion `O(8 · log QUEUE)`.
//! If the queue overflows the planner refuses further work ([`PlanError::QueueFull`]) until
//! [`DStarLite::reset`], which the caller follows with a fresh plan.

use crate::nav::map::{ARENA_CELLS, Cell, GridShape, Traversability};
use crate::nav::queue::{IndexedQueue, Key};

/// "Unreachable".
pub const INFINITE: u16 = u16::MAX;
/// Cost of a straight move.
pub const STRAIGHT_COST: u16 = 10;
/// Cost of a diagonal move.
pub const DIAGONAL_COST: u16 = 14;
/// Open-list capacity of the firmware's planner.
pub const ARENA_QUEUE: usize = 1024;
/// The planner the firmware is built with.
pub type ArenaPlanner = DStarLite<ARENA_CELLS, ARENA_QUEUE>;

/// `km` beyond which the queue is re-keyed (keeps `k1` far from overflowing `u32`).
const KM_REKEY_LIMIT: u32 = 1 << 30;

/// The 8 neighbour offsets, straight moves first (they win ties when a path is read off).
const NEIGHBOURS: [(i32, i32); 8] = [(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1)];

/// For each of [`NEIGHBOURS`]: its move cost and, for a diagonal `(dx, dy)`, the indices (into the first
/// four of [`NEIGHBOURS`]) of the straight neighbours `(dx, 0)` and `(0, dy)` it passes between.
const MOVES: [(u16, usize, usize); 8] = [
    (STRAIGHT_COST, 0, 0),
    (STRAIGHT_COST, 1, 1),
    (STRAIGHT_COST, 2, 2),
    (STRAIGHT_COST, 3, 3),
    (DIAGONAL_COST, 0, 1),
    (DIAGONAL_COST, 2, 1),
    (DIAGONAL_COST, 2, 3),
    (DIAGONAL_COST, 0, 3),
];

/// For each straight neighbour index of [`NEIGHBOURS`], the index of the opposite direction.
const OPPOSITE: [usize; 4] = [2, 3, 0, 1];

/// Bit 0 of a key's `k1` (see [`DStarLite::key`]): set for consistent and over-consistent cells, clear for
/// under-consistent ones, so that among equal `min(g, rhs) + h + km` the under-consistent cells come first.
const SETTLING: u32 = 1;

/// Why the planner refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanError {
    /// The grid is empty or larger than the planner's capacity.
    BadShape,
    /// A start or goal outside the grid.
    OutOfBounds,
    /// The open list overflowed; the planner needs [`DStarLite::reset`].
    QueueFull,
    /// No plan was set up yet ([`DStarLite::reset`] was never called).
    NotReady,
}

/// The outcome of a [`DStarLite::compute`] call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanStatus {
    /// A shortest path exists; its cost from the start, in move-cost units (10 per straight cell).
    Found {
        /// Cost from the start to the goal.
        cost: u32,
    },
    /// The goal cannot be reached from the start on the current map.
    NoPath,
    /// The expansion budget ran out; call again to continue.
    Incomplete,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Readiness {
    Empty,
    Ready,
    Broken,
}

/// See the module documentation.
#[derive(Clone)]
pub struct DStarLite<const CELLS: usize, const QUEUE: usize> {
    shape: GridShape,
    g: [u16; CELLS],
    open: IndexedQueue<CELLS, QUEUE>,
    start: Cell,
    last_start: Cell,
    goal: Cell,
    km: u32,
    readiness: Readiness,
    /// Expansions of the current repair (summed over [`PlanStatus::Incomplete`] slices).
    expansions: u32,
    /// The last [`DStarLite::compute`] ran out of budget: the next one continues the same repair.
    resuming: bool,
    /// The start's `g` or `rhs` may have changed since [`DStarLite::compute`] last computed its key.
    start_touched: bool,
    /// Ties on `f` are broken deepest-first (the first search after [`DStarLite::reset`]) rather than
    /// smaller-`g`-first (the paper's order, every later repair); see `key_of`.
    deepest_first: bool,
    /// The first search has ended: the queue must be re-keyed in the paper's order before the next change.
    rekey_pending: bool,
}

impl<const CELLS: usize, const QUEUE: usize> Default for DStarLite<CELLS, QUEUE> {
    fn default() -> Self {
        Self::new()
    }
}

/// Octile distance between two cells, in move-cost units.
#[inline]
pub fn octile(a: Cell, b: Cell) -> u32 {
    let dx = u32::from(a.x.abs_diff(b.x));
    let dy = u32::from(a.y.abs_diff(b.y));
    let (lo, hi) = if dx < dy { (dx, dy) } else { (dy, dx) };
    u32::from(STRAIGHT_COST) * hi + u32::from(DIAGONAL_COST - STRAIGHT_COST) * lo
}

/// Cost of moving from `(x, y)` by `(dx, dy)` (one of the 8 neighbour offsets) on `map`, or `None` when the
/// move is not allowed: the target is blocked or outside, or a diagonal would cut a blocked corner.
#[inline]
pub fn move_cost(map: &impl Traversability, x: i32, y: i32, dx: i32, dy: i32) -> Option<u16> {
    if map.is_blocked(x + dx, y + dy) {
        return None;
    }
    if dx != 0 && dy != 0 {
        if map.is_blocked(x + dx, y) || map.is_blocked(x, y + dy) {
            return None;
        }
        Some(DIAGONAL_COST)
    } else {
        Some(STRAIGHT_COST)
    }
}

#[inline(always)]
fn add_cost(c: u16, g: u16) -> u16 {
    if g == INFINITE {
        return INFINITE;
    }
    let sum = u32::from(c) + u32::from(g);
    if sum >= u32::from(INFINITE) {
        INFINITE
    } else {
        sum as u16
    }
}

/// The queue key of a cell with `g` and `rhs` whose heuristic is `h`, under the key modifier `km`.
///
/// D* Lite orders by `f = min(g, rhs) + h + km` first (the paper's `k1`); this key's `k1` is `2·f + tag`.
/// Without `deepest_first` the tag is 0 and ties on `f` go to the smaller `min(g, rhs)` (the paper's
/// `k2`). With it (the first search) ties on `f` are broken in two classes:
/// - under-consistent cells (`g < rhs`) first, smaller `g` first, as in the paper. They must come first:
///   a cell whose `g` is too small (its path was cut) can tie on `f` with the start or with an
///   over-consistent cell whose `rhs` was computed through it, and must be raised before either is settled
///   or the search stops;
/// - then over-consistent and consistent cells, *larger* `rhs` first (A*'s "deepest first"): they only
///   lower values, so among them any order settles correct costs (each popped over-consistent cell has an
///   `f` no larger than that of any cell on its true shortest path still queued, strictly so when its `rhs`
///   is wrong), and preferring the cell nearest the start ends the search once the start is reached instead
///   of first expanding every cell that lies on some optimal path (the octile heuristic is exact on open
///   ground, so those all tie).
#[inline(always)]
fn key_of(h: u32, km: u32, g: u16, rhs: u16, deepest_first: bool) -> Key {
    let f = u32::from(g.min(rhs)) + h + km;
    if !deepest_first {
        return Key {
            k1: f << 1,
            k2: g.min(rhs),
        };
    }
    if g < rhs {
        Key { k1: f << 1, k2: g }
    } else {
        Key {
            k1: (f << 1) | SETTLING,
            k2: INFINITE - rhs,
        }
    }
}

/// Whether each of the four straight neighbours of `(x, y)` (in [`NEIGHBOURS`] order) may be entered; cells
/// outside the grid count as blocked ([`Traversability`]'s contract).
#[inline(always)]
fn straight_free(map: &impl Traversability, x: i32, y: i32) -> [bool; 4] {
    [
        !map.is_blocked(x + 1, y),
        !map.is_blocked(x, y + 1),
        !map.is_blocked(x - 1, y),
        !map.is_blocked(x, y - 1),
    ]
}

/// Whether the move from a cell with [`straight_free`] `side_free` to its neighbour `(nx, ny)`, the [`MOVES`]
/// entry `(cost, a, b)`, is open: a straight move needs its target (side `a`) free, a diagonal one both sides
/// and the target.
#[inline(always)]
fn move_open(
    map: &impl Traversability,
    side_free: &[bool; 4],
    (cost, a, b): (u16, usize, usize),
    nx: i32,
    ny: i32,
) -> bool {
    if cost == STRAIGHT_COST {
        side_free[a]
    } else {
        side_free[a] && side_free[b] && !map.is_blocked(nx, ny)
    }
}

/// Whether the diagonal move from `u - (dx, dy)` into a free `u` is open, given `u`'s [`straight_free`]
/// and the [`MOVES`] side indices `a`, `b` of `(dx, dy)`: it passes `u`'s straight neighbours at `(-dx, 0)`
/// and `(0, -dy)`, the opposites of `a` and `b`.
#[inline(always)]
fn diagonal_open_into(side_free: &[bool; 4], a: usize, b: usize) -> bool {
    side_free[OPPOSITE[a]] && side_free[OPPOSITE[b]]
}

/// A predecessor `s = u - (dx, dy)` of an expanded cell `u`: its index and coordinates, and the cost and
/// [`MOVES`] side indices of the move `s → u`.
struct Predecessor {
    s: usize,
    x: i32,
    y: i32,
    cost: u16,
    a: usize,
    b: usize,
}

impl Predecessor {
    /// Whether the move into `u` is open, given `u`'s [`straight_free`] (a straight move always is: `u` is free).
    #[inline(always)]
    fn open_into(&self, side_free: &[bool; 4]) -> bool {
        self.cost != DIAGONAL_COST || diagonal_open_into(side_free, self.a, self.b)
    }
}

/// The `k`-th predecessor (in [`NEIGHBOURS`] order) of `u` at `(ux, uy)`, if it is inside the grid and not the
/// goal (whose rhs is fixed at 0): the one neighbour step both of [`DStarLite::compute`]'s expansion cases walk
/// with `for k in 0..8`. `back` holds the index offset of each predecessor; `interior` (every neighbour inside
/// the grid) skips the bounds test. (A plain indexed step: an iterator adapter chain here cost the first plan
/// 17 % more Cortex-M4 instructions at `opt-level = "s"`.)
#[inline(always)]
fn predecessor(
    shape: GridShape,
    back: &[isize; 8],
    goal: usize,
    u: usize,
    (ux, uy): (i32, i32),
    interior: bool,
    k: usize,
) -> Option<Predecessor> {
    let (dx, dy) = NEIGHBOURS[k];
    let (x, y) = (ux - dx, uy - dy);
    if !interior && !shape.contains(x, y) {
        return None;
    }
    let s = u.wrapping_add_signed(back[k]);
    if s == goal {
        return None;
    }
    let (cost, a, b) = MOVES[k];
    Some(Predecessor { s, x, y, cost, a, b })
}

impl<const CELLS: usize, const QUEUE: usize> DStarLite<CELLS, QUEUE> {
    /// A planner with no plan; call [`DStarLite::reset`] before anything else.
    pub const fn new() -> Self {
        Self {
            shape: GridShape { width: 0, height: 0 },
            g: [0; CELLS],
            open: IndexedQueue::new(),
            start: Cell::new(0, 0),
            last_start: Cell::new(0, 0),
            goal: Cell::new(0, 0),
            km: 0,
            readiness: Readiness::Empty,
            expansions: 0,
            resuming: false,
            start_touched: true,
            deepest_first: true,
            rekey_pending: false,
        }
    }

    /// Start a new plan from scratch on a `shape` grid (every cell unknown: `g = rhs = ∞` except the goal).
    /// O(cells). The planner learns the map only through [`DStarLite::cells_changed`] and the edge costs
    /// it reads while searching, so a map that already has obstacles needs no special treatment.
    pub fn reset(&mut self, shape: GridShape, start: Cell, goal: Cell) -> Result<(), PlanError> {
        self.readiness = Readiness::Empty;
        if shape.width == 0 || shape.height == 0 || shape.cells() > CELLS {
            return Err(PlanError::BadShape);
        }
        let inside = |c: Cell| c.x < shape.width && c.y < shape.height;
        if !inside(start) || !inside(goal) {
            return Err(PlanError::OutOfBounds);
        }
        self.shape = shape;
        self.g[..shape.cells()].fill(INFINITE);
        // The queue's position index may hold garbage from a previous, larger shape or uninitialised memory.
        self.open.wipe();
        self.start = start;
        self.last_start = start;
        self.goal = goal;
        self.km = 0;
        self.expansions = 0;
        self.resuming = false;
        self.deepest_first = true;
        self.rekey_pending = false;
        let goal_index = shape.index(goal);
        let key = key_of(octile(start, goal), 0, INFINITE, 0, true);
        self.open.push(goal_index, key, 0).map_err(|_| PlanError::QueueFull)?;
        self.readiness = Readiness::Ready;
        Ok(())
    }

    /// The grid shape of the current plan.
    pub fn shape(&self) -> GridShape {
        self.shape
    }

    /// The goal of the current plan.
    pub fn goal(&self) -> Cell {
        self.goal
    }

    /// The start (the drone's cell) of the current plan.
    pub fn start(&self) -> Cell {
        self.start
    }

    /// Move the start to the drone's current cell. Takes effect at the next repair.
    pub fn set_start(&mut self, start: Cell) -> Result<(), PlanError> {
        self.check_ready()?;
        if start.x >= self.shape.width || start.y >= self.shape.height {
            return Err(PlanError::OutOfBounds);
        }
        self.start = start;
        Ok(())
    }

    /// Tell the planner that the blocked state of `cells` changed on `map` (which already shows the new
    /// state). Cells outside the grid are ignored. Call [`DStarLite::compute`] afterwards.
    pub fn cells_changed(&mut self, map: &impl Traversability, cells: &[Cell]) -> Result<(), PlanError> {
        self.check_ready()?;
        self.sync_start();
        let goal = self.shape.index(self.goal);
        for &changed in cells {
            let (cx, cy) = (i32::from(changed.x), i32::from(changed.y));
            if !self.shape.contains(cx, cy) {
                continue;
            }
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (x, y) = (cx + dx, cy + dy);
                    if (dx == 0 && dy == 0) || !self.shape.contains(x, y) {
                        continue;
                    }
                    let u = self.index_of(x, y);
                    if u == goal {
                        continue;
                    }
                    let best = self.best_successor_cost(map, x, y);
                    if best != self.rhs(u) {
                        self.update_vertex(u, x, y, best)?;
                    }
                }
            }
        }
        Ok(())
    }

    /// Run (or continue) the repair: expand at most `max_expansions` cells. Returns the plan's status.
    pub fn compute(&mut self, map: &impl Traversability, max_expansions: u32) -> Result<PlanStatus, PlanError> {
        self.check_ready()?;
        self.sync_start();
        if !self.resuming {
            self.expansions = 0;
        }
        self.resuming = true;
        let start = self.shape.index(self.start);
        let goal = self.shape.index(self.goal);
        let (width, height) = (i32::from(self.shape.width), i32::from(self.shape.height));
        // Index offset of the predecessor `u - (dx, dy)` for each of NEIGHBOURS.
        let back = NEIGHBOURS.map(|(dx, dy)| -(dy as isize * width as isize + dx as isize));
        let mut budget = max_expansions;
        // The start's key changes only when the start is expanded or its rhs is updated (`start_touched`).
        self.start_touched = true;
        let (mut g_start, mut rhs_start, mut start_key) = (INFINITE, INFINITE, Key::MAX);
        loop {
            if self.start_touched {
                self.start_touched = false;
                g_start = self.g[start];
                rhs_start = self.rhs(start);
                start_key = self.key(i32::from(self.start.x), i32::from(self.start.y), g_start, rhs_start);
            }
            let Some((u, old_key)) = self.open.top() else { break };
            if old_key >= start_key && rhs_start <= g_start {
                break;
            }
            if budget == 0 {
                return Ok(PlanStatus::Incomplete);
            }
            budget -= 1;
            self.expansions = self.expansions.saturating_add(1);

            let g_u = self.g[u];
            let rhs_u = self.rhs(u);
            let (ux, uy) = self.coords(u);
            if u == start {
                self.start_touched = true;
            }
            // Away from the edges every neighbour is inside the grid: no bounds test per neighbour.
            let interior = ux > 0 && uy > 0 && ux + 1 < width && uy + 1 < height;
            let new_key = self.key(ux, uy, g_u, rhs_u);
            if old_key < new_key {
                self.open.update(u, new_key, rhs_u);
            } else if g_u > rhs_u {
                // Over-consistent: settle u, then offer it as a successor to its predecessors.
                self.g[u] = rhs_u;
                self.open.remove(u);
                // Entering a blocked cell is never allowed: then u has no predecessors.
                if map.is_blocked(ux, uy) {
                    continue;
                }
                let side_free = straight_free(map, ux, uy);
                for k in 0..NEIGHBOURS.len() {
                    let Some(p) = predecessor(self.shape, &back, goal, u, (ux, uy), interior, k) else {
                        continue;
                    };
                    // The cheap test first: only a cell whose rhs would drop needs its move checked.
                    let through_u = add_cost(p.cost, rhs_u);
                    if through_u >= self.rhs(p.s) || !p.open_into(&side_free) {
                        continue;
                    }
                    self.update_vertex(p.s, p.x, p.y, through_u)?;
                }
            } else {
                // Under-consistent: raise u to infinity; every cell whose rhs came through u recomputes it.
                let g_old = g_u;
                self.g[u] = INFINITE;
                if !map.is_blocked(ux, uy) {
                    let side_free = straight_free(map, ux, uy);
                    for k in 0..NEIGHBOURS.len() {
                        let Some(p) = predecessor(self.shape, &back, goal, u, (ux, uy), interior, k) else {
                            continue;
                        };
                        let rhs_s = self.rhs(p.s);
                        if rhs_s == INFINITE || rhs_s != add_cost(p.cost, g_old) || !p.open_into(&side_free) {
                            continue;
                        }
                        let best = self.best_successor_cost(map, p.x, p.y);
                        self.update_vertex(p.s, p.x, p.y, best)?;
                    }
                }
                // u's own rhs does not depend on g(u); it only changes consistency.
                self.update_vertex(u, ux, uy, rhs_u)?;
            }
        }
        self.resuming = false;
        if self.deepest_first {
            self.deepest_first = false;
            self.rekey_pending = true;
        }
        let cost = self.rhs(start);
        Ok(if cost == INFINITE {
            PlanStatus::NoPath
        } else {
            PlanStatus::Found { cost: u32::from(cost) }
        })
    }

    /// Expansions of the latest repair (all of its slices).
    pub fn expansions(&self) -> u32 {
        self.expansions
    }

    /// Cells in the open list right now.
    pub fn queue_len(&self) -> usize {
        self.open.len()
    }

    /// The most cells the open list held since [`DStarLite::reset`].
    pub fn queue_high_water(&self) -> usize {
        self.open.high_water()
    }

    /// Cost-to-goal of a cell as the planner knows it (`g`), `None` for unknown/unreachable or outside.
    pub fn g(&self, cell: Cell) -> Option<u32> {
        let i = self.checked_index(cell)?;
        let g = self.g[i];
        (g != INFINITE).then_some(u32::from(g))
    }

    /// One-step look-ahead cost-to-goal of a cell (`rhs`); for the start after a completed repair this is
    /// the cost of the shortest path.
    pub fn rhs_of(&self, cell: Cell) -> Option<u32> {
        let i = self.checked_index(cell)?;
        let r = self.rhs(i);
        (r != INFINITE).then_some(u32::from(r))
    }

    /// The next cell on a shortest path from `from`: the successor minimising move cost + `g`, straight
    /// moves winning ties. `None` at the goal, when nothing is reachable, or outside the grid.
    pub fn next_cell(&self, map: &impl Traversability, from: Cell) -> Option<Cell> {
        self.checked_index(from)?;
        if from == self.goal {
            return None;
        }
        let (x, y) = (i32::from(from.x), i32::from(from.y));
        let side_free = straight_free(map, x, y);
        let mut best: Option<(u16, Cell)> = None;
        for (k, (dx, dy)) in NEIGHBOURS.into_iter().enumerate() {
            let (c, _, _) = MOVES[k];
            let (nx, ny) = (x + dx, y + dy);
            if !move_open(map, &side_free, MOVES[k], nx, ny) || !self.shape.contains(nx, ny) {
                continue;
            }
            let total = add_cost(c, self.g[self.index_of(nx, ny)]);
            if total != INFINITE && best.is_none_or(|(b, _)| total < b) {
                best = Some((total, Cell::new(nx as u16, ny as u16)));
            }
        }
        best.map(|(_, cell)| cell)
    }

    fn check_ready(&self) -> Result<(), PlanError> {
        match self.readiness {
            Readiness::Ready => Ok(()),
            Readiness::Empty => Err(PlanError::NotReady),
            Readiness::Broken => Err(PlanError::QueueFull),
        }
    }

    /// Account for start moves in `km` (always valid: by the triangle inequality the stored keys remain
    /// lower bounds of the fresh ones).
    ///
    /// Also re-keys the whole queue, with fresh keys (`km` back at 0), when `km` grows large or when the
    /// first search has just switched the tie-break to the paper's order.
    fn sync_start(&mut self) {
        if self.start != self.last_start {
            self.km = self.km.saturating_add(octile(self.last_start, self.start));
            self.last_start = self.start;
        }
        if self.km > KM_REKEY_LIMIT || self.rekey_pending {
            self.km = 0;
            self.rekey_pending = false;
            let (shape, start, g, deepest_first) = (self.shape, self.start, &self.g, self.deepest_first);
            self.open
                .rekey(|cell, rhs| key_of(octile(start, shape.cell(cell)), 0, g[cell], rhs, deepest_first));
        }
    }

    #[inline]
    fn rhs(&self, cell: usize) -> u16 {
        self.open.payload(cell).unwrap_or(self.g[cell])
    }

    /// The key of the cell at `(x, y)` (coordinates passed in because the callers have them; deriving them
    /// from the index would cost a division per key).
    #[inline]
    fn key(&self, x: i32, y: i32, g: u16, rhs: u16) -> Key {
        let dx = x.abs_diff(i32::from(self.start.x));
        let dy = y.abs_diff(i32::from(self.start.y));
        let (lo, hi) = if dx < dy { (dx, dy) } else { (dy, dx) };
        let h = u32::from(STRAIGHT_COST) * hi + u32::from(DIAGONAL_COST - STRAIGHT_COST) * lo;
        key_of(h, self.km, g, rhs, self.deepest_first)
    }

    /// D* Lite's UpdateVertex with the new `rhs`: queue the cell iff it is inconsistent.
    fn update_vertex(&mut self, cell: usize, x: i32, y: i32, rhs: u16) -> Result<(), PlanError> {
        if x == i32::from(self.start.x) && y == i32::from(self.start.y) {
            self.start_touched = true;
        }
        let g = self.g[cell];
        if g != rhs {
            let key = self.key(x, y, g, rhs);
            if self.open.push(cell, key, rhs).is_err() {
                self.readiness = Readiness::Broken;
                return Err(PlanError::QueueFull);
            }
        } else {
            self.open.remove(cell);
        }
        Ok(())
    }

    fn best_successor_cost(&self, map: &impl Traversability, x: i32, y: i32) -> u16 {
        let side_free = straight_free(map, x, y);
        let (width, height) = (i32::from(self.shape.width), i32::from(self.shape.height));
        // Away from the edges every neighbour is inside the grid: no bounds test, no multiplication.
        let interior = x > 0 && y > 0 && x + 1 < width && y + 1 < height;
        let here = self.index_of(x, y);
        let mut best = INFINITE;
        for (k, (dx, dy)) in NEIGHBOURS.into_iter().enumerate() {
            let (c, _, _) = MOVES[k];
            let (nx, ny) = (x + dx, y + dy);
            // `is_blocked` is true outside the map, but the map's shape is the caller's: check ours too.
            if move_open(map, &side_free, MOVES[k], nx, ny) && (interior || self.shape.contains(nx, ny)) {
                let n = here.wrapping_add_signed(dy as isize * width as isize + dx as isize);
                best = best.min(add_cost(c, self.g[n]));
            }
        }
        best
    }

    #[inline]
    fn index_of(&self, x: i32, y: i32) -> usize {
        (y as usize) * usize::from(self.shape.width) + x as usize
    }

    #[inline]
    fn coords(&self, index: usize) -> (i32, i32) {
        let w = usize::from(self.shape.width);
        ((index % w) as i32, (index / w) as i32)
    }

    fn checked_index(&self, cell: Cell) -> Option<usize> {
        (self.readiness != Readiness::Empty && cell.x < self.shape.width && cell.y < self.shape.height)
            .then(|| self.shape.index(cell))
    }
}
