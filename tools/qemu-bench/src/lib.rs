//! The seed-scenario benchmark of the firmware's planner ([`ArenaPlanner`]), independent of how work is counted.
//!
//! Job: parse `maps/seed.map` without allocation, replay it as `cfnav plan` does (docs/formats.md
//! §2) with a sense radius of [`SENSE_RADIUS`] cells, and time every planner call through a [`Meter`]. The
//! Cortex-M4 binary (`src/main.rs`) plugs in an exact instruction counter under QEMU; host tests use
//! [`NoMeter`] to check the scenario itself.
//!
//! Three things are measured, always as the planner calls only (sensing and bookkeeping are outside):
//! 1. the first plan: `reset` + `set_start` + `cells_changed` (the cells sensed at the start) + `compute`;
//! 2. every replan of the flight: `set_start` + `cells_changed` + `compute`, after moving one cell and sensing;
//! 3. "20 cm obstacle" replans: for k = 1..=9, the planner is re-planned from scratch on the first plan's
//!    map (not measured) and replanned once with no change (measured as the *first replan*: it completes
//!    the first plan's set of optimal paths, see `cfnav::nav::dstar`, as the mission's first replan after a
//!    first plan does), then a [`BOX_CELLS`] × [`BOX_CELLS`] box is dropped on the first plan's path at k/10 of
//!    its length, the drone still at the start, and `set_start` + `cells_changed` + `compute` is measured.
//!    The box covers `x - 2 ..= x + 1`, `y - 2 ..= y + 1` around the path cell `(x, y)`; cells outside the grid,
//!    already blocked, or the start or goal are left out.
//!
//! The believed map is one `bool` per cell, like the firmware's byte-per-cell grid, so the planner's map reads
//! cost about what they cost in flight.

#![no_std]

use cfnav::flight::estimator::{Estimator, EstimatorConfig};
use cfnav::nav::dstar::{ArenaPlanner, PlanError, PlanStatus, move_cost};
use cfnav::nav::map::{ARENA_CELLS, Cell, GridShape, Traversability};
use cfnav::types::{FlowSample, GRAVITY_M_S2, ImuSample, MultiRangerSample};

/// The seed scenario (6 × 3 m at 5 cm).
pub const SEED_MAP: &str = include_str!("../../../maps/seed.map");
/// Sensing radius, cells (Chebyshev): 8 cells = 0.4 m.
pub const SENSE_RADIUS: u16 = 8;
/// Edge of the dropped box, cells (4 × 5 cm = 20 cm).
pub const BOX_CELLS: u16 = 4;
/// Number of box positions (k = 1..=9 tenths of the path).
pub const BOX_POSITIONS: usize = 9;
/// Most sense + replan steps a replay may take (including the first plan).
pub const MAX_STEPS: usize = 1024;
/// Longest first-plan path, in cells (including start and goal).
pub const MAX_PATH: usize = 1024;
/// Most cells one sense (a `(2R + 1)²` square) or one box can change.
pub const MAX_CHANGES: usize = (2 * SENSE_RADIUS as usize + 1) * (2 * SENSE_RADIUS as usize + 1);

const _: () = assert!(MAX_CHANGES >= (BOX_CELLS as usize) * (BOX_CELLS as usize));

/// A problem in the map text. Lines count from 1, as in an editor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapError {
    /// No rows.
    Empty,
    /// A row of a different width than the first one.
    Ragged {
        /// The offending line.
        line: usize,
    },
    /// More cells than the planner holds, or a side beyond `u16`.
    TooLarge,
    /// A character other than `. # o S G`.
    BadChar {
        /// The offending line.
        line: usize,
        /// Its column, from 1.
        column: usize,
    },
    /// A second `S` or `G`.
    Duplicate {
        /// The offending line.
        line: usize,
    },
    /// No `S`.
    NoStart,
    /// No `G`.
    NoGoal,
}

/// What the world holds at a cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Truth {
    Free,
    /// `#`: occupied and known from the start.
    Known,
    /// `o`: occupied, believed free until sensed.
    Hidden,
}

/// The replay world: the truth and the drone's belief. The belief is what the planner reads.
pub struct World {
    shape: GridShape,
    truth: [Truth; ARENA_CELLS],
    belief: [bool; ARENA_CELLS],
    start: Cell,
    goal: Cell,
}

/// The map rows of a map text: comment (`;`) and blank lines skipped, `\r` stripped, with 1-based line numbers.
fn rows(text: &str) -> impl Iterator<Item = (usize, &[u8])> {
    text.lines().enumerate().filter_map(|(n, raw)| {
        let line = raw.strip_suffix('\r').unwrap_or(raw);
        (!line.starts_with(';') && !line.trim().is_empty()).then_some((n + 1, line.as_bytes()))
    })
}

impl World {
    /// Parse a map text (docs/formats.md, map format); the belief starts with the `#` cells only.
    pub fn parse(text: &str) -> Result<Self, MapError> {
        let (_, first) = rows(text).next().ok_or(MapError::Empty)?;
        let width = first.len();
        let mut height = 0usize;
        for (line, row) in rows(text) {
            if row.len() != width {
                return Err(MapError::Ragged { line });
            }
            height += 1;
        }
        let (w, h) = (u16::try_from(width), u16::try_from(height));
        let (Ok(w), Ok(h)) = (w, h) else {
            return Err(MapError::TooLarge);
        };
        let shape = GridShape::new(w, h, ARENA_CELLS).ok_or(MapError::TooLarge)?;
        let mut world = World {
            shape,
            truth: [Truth::Free; ARENA_CELLS],
            belief: [false; ARENA_CELLS],
            start: Cell::default(),
            goal: Cell::default(),
        };
        let (mut start, mut goal) = (None, None);
        for (r, (line, row)) in rows(text).enumerate() {
            let y = h - 1 - r as u16;
            for (x, &ch) in row.iter().enumerate() {
                let cell = Cell::new(x as u16, y);
                let i = shape.index(cell);
                match ch {
                    b'.' => {}
                    b'#' => world.truth[i] = Truth::Known,
                    b'o' => world.truth[i] = Truth::Hidden,
                    b'S' | b'G' => {
                        let slot = if ch == b'S' { &mut start } else { &mut goal };
                        if slot.replace(cell).is_some() {
                            return Err(MapError::Duplicate { line });
                        }
                    }
                    _ => return Err(MapError::BadChar { line, column: x + 1 }),
                }
            }
        }
        world.start = start.ok_or(MapError::NoStart)?;
        world.goal = goal.ok_or(MapError::NoGoal)?;
        world.reset_belief();
        Ok(world)
    }

    /// The grid's size.
    pub fn grid(&self) -> GridShape {
        self.shape
    }

    /// The `S` cell.
    pub fn start(&self) -> Cell {
        self.start
    }

    /// The `G` cell.
    pub fn goal(&self) -> Cell {
        self.goal
    }

    /// Forget everything sensed: believe exactly the `#` cells.
    pub fn reset_belief(&mut self) {
        for (b, t) in self.belief.iter_mut().zip(self.truth.iter()) {
            *b = *t == Truth::Known;
        }
    }

    /// Reveal every hidden obstacle within Chebyshev distance `radius` of `at`; `changes` gets exactly the
    /// cells whose belief changed (it is cleared first).
    pub fn sense(&mut self, at: Cell, radius: u16, changes: &mut Changes) {
        changes.clear();
        let (w, h) = (self.shape.width, self.shape.height);
        let (x0, x1) = (at.x.saturating_sub(radius), at.x.saturating_add(radius).min(w - 1));
        let (y0, y1) = (at.y.saturating_sub(radius), at.y.saturating_add(radius).min(h - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let cell = Cell::new(x, y);
                let i = self.shape.index(cell);
                let truth = self.truth[i] != Truth::Free;
                if self.belief[i] != truth {
                    self.belief[i] = truth;
                    changes.push(cell);
                }
            }
        }
    }

    /// Believe `cell` blocked; whether that changed anything (false outside the grid or when already blocked).
    pub fn block(&mut self, cell: Cell) -> bool {
        if cell.x >= self.shape.width || cell.y >= self.shape.height {
            return false;
        }
        let i = self.shape.index(cell);
        !core::mem::replace(&mut self.belief[i], true)
    }
}

impl Traversability for World {
    fn shape(&self) -> GridShape {
        self.shape
    }

    #[inline]
    fn is_blocked(&self, x: i32, y: i32) -> bool {
        if !self.shape.contains(x, y) {
            return true;
        }
        self.belief[y as usize * usize::from(self.shape.width) + x as usize]
    }
}

/// A fixed-capacity list of changed cells.
pub struct Changes {
    cells: [Cell; MAX_CHANGES],
    len: usize,
}

impl Default for Changes {
    fn default() -> Self {
        Self::new()
    }
}

impl Changes {
    /// An empty list.
    pub const fn new() -> Self {
        Self {
            cells: [Cell::new(0, 0); MAX_CHANGES],
            len: 0,
        }
    }

    /// Empty the list.
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// Append a cell (silently dropped when full, which [`MAX_CHANGES`] rules out for senses and boxes).
    pub fn push(&mut self, cell: Cell) {
        if let Some(slot) = self.cells.get_mut(self.len) {
            *slot = cell;
            self.len += 1;
        }
    }

    /// The cells.
    pub fn as_slice(&self) -> &[Cell] {
        &self.cells[..self.len]
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// Counts the work of a closure.
pub trait Meter {
    /// Run `f`, returning its result and the work it took (instructions, net of the meter's own overhead).
    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32);
}

/// A meter that counts nothing (host tests).
pub struct NoMeter;

impl Meter for NoMeter {
    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        (f(), 0)
    }
}

/// Why the benchmark failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchError {
    /// The planner refused.
    Planner(PlanError),
    /// The planner found no path from this cell (the seed map has one).
    NoPath(Cell),
    /// `compute` with an unlimited budget returned `Incomplete`.
    Incomplete,
    /// The planner had a cost but no next cell, or proposed an illegal move, at this cell.
    BadMove(Cell),
    /// More than [`MAX_STEPS`] steps, or a path longer than [`MAX_PATH`].
    TooLong,
}

impl From<PlanError> for BenchError {
    fn from(e: PlanError) -> Self {
        BenchError::Planner(e)
    }
}

/// One measured planner call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Step {
    /// The drone's cell.
    pub at: Cell,
    /// Cells whose belief changed before the call.
    pub changed: u16,
    /// Vertex expansions of the repair.
    pub expansions: u32,
    /// Instructions of the planner calls (0 with [`NoMeter`]).
    pub instructions: u32,
    /// Planned cost from `at` to the goal.
    pub cost: u32,
}

/// One "20 cm obstacle" replan.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoxReplan {
    /// Position along the first plan's path, tenths.
    pub k: u16,
    /// Index of the box's path cell in the first plan's path.
    pub path_index: u16,
    /// The path cell the box is centred on.
    pub centre: Cell,
    /// The re-plan from scratch that preceded the drop (not measured): its expansions.
    pub baseline_expansions: u32,
    /// The replan without changes between that plan and the drop (the first replan after a first plan).
    pub first_replan: Step,
    /// The measured replan.
    pub replan: Step,
}

/// Everything the benchmark measured.
pub struct Report {
    /// Steps of the flight; `steps[0]` is the first plan.
    pub steps: [Step; MAX_STEPS],
    /// Number of valid `steps`.
    pub step_count: usize,
    /// The first plan's path, start to goal.
    pub path: [Cell; MAX_PATH],
    /// Number of valid `path` cells.
    pub path_len: usize,
    /// Cost of the first plan's path, summed move by move (must equal the first plan's cost).
    pub path_cost: u32,
    /// Cells the drone moved during the flight.
    pub moves: u32,
    /// Sum of the costs of those moves.
    pub flight_cost: u32,
    /// Largest open list of the flight.
    pub queue_high_water: usize,
    /// The box replans, k = 1..=9.
    pub boxes: [BoxReplan; BOX_POSITIONS],
}

impl Default for Report {
    fn default() -> Self {
        Self::new()
    }
}

impl Report {
    /// An empty report.
    pub const fn new() -> Self {
        const STEP: Step = Step {
            at: Cell::new(0, 0),
            changed: 0,
            expansions: 0,
            instructions: 0,
            cost: 0,
        };
        const BOX: BoxReplan = BoxReplan {
            k: 0,
            path_index: 0,
            centre: Cell::new(0, 0),
            baseline_expansions: 0,
            first_replan: STEP,
            replan: STEP,
        };
        Self {
            steps: [STEP; MAX_STEPS],
            step_count: 0,
            path: [Cell::new(0, 0); MAX_PATH],
            path_len: 0,
            path_cost: 0,
            moves: 0,
            flight_cost: 0,
            queue_high_water: 0,
            boxes: [BOX; BOX_POSITIONS],
        }
    }

    /// The first plan.
    pub fn first_plan(&self) -> Step {
        self.steps[0]
    }

    /// The flight's replans (every step after the first plan).
    pub fn replans(&self) -> &[Step] {
        &self.steps[1..self.step_count.max(1)]
    }

    /// The first plan's path.
    pub fn path(&self) -> &[Cell] {
        &self.path[..self.path_len]
    }
}

/// Median, 90th percentile and maximum of some values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Summary {
    /// Number of values.
    pub count: usize,
    /// The middle value (the mean of the two middle ones, rounded down, for an even count).
    pub median: u32,
    /// Nearest-rank 90th percentile: the smallest value at least 90 % of the values do not exceed.
    pub p90: u32,
    /// The largest value.
    pub max: u32,
}

/// Summarise `values` (sorted in place). All zero for no values.
pub fn summarize(values: &mut [u32]) -> Summary {
    values.sort_unstable();
    let n = values.len();
    if n == 0 {
        return Summary::default();
    }
    let median = if n % 2 == 1 {
        values[n / 2]
    } else {
        ((u64::from(values[n / 2 - 1]) + u64::from(values[n / 2])) / 2) as u32
    };
    let rank = (9 * n).div_ceil(10); // ceil(0.9 n), at least 1
    Summary {
        count: n,
        median,
        p90: values[rank - 1],
        max: values[n - 1],
    }
}

fn found(status: PlanStatus, at: Cell) -> Result<u32, BenchError> {
    match status {
        PlanStatus::Found { cost } => Ok(cost),
        PlanStatus::NoPath => Err(BenchError::NoPath(at)),
        PlanStatus::Incomplete => Err(BenchError::Incomplete),
    }
}

/// The measured incremental replan from `at` after `changes`.
fn replan(
    planner: &mut ArenaPlanner,
    world: &World,
    at: Cell,
    changes: &Changes,
    meter: &mut impl Meter,
) -> Result<Step, BenchError> {
    let (status, instructions) = meter.measure(|| -> Result<PlanStatus, PlanError> {
        planner.set_start(at)?;
        planner.cells_changed(world, changes.as_slice())?;
        planner.compute(world, u32::MAX)
    });
    let cost = found(status?, at)?;
    Ok(Step {
        at,
        changed: changes.len() as u16,
        expansions: planner.expansions(),
        instructions,
        cost,
    })
}

/// Plan from scratch from the start on the current belief, after the start's sense (`changes`).
fn first_plan(
    planner: &mut ArenaPlanner,
    world: &World,
    changes: &Changes,
    meter: &mut impl Meter,
) -> Result<Step, BenchError> {
    let (start, goal) = (world.start(), world.goal());
    let (status, instructions) = meter.measure(|| -> Result<PlanStatus, PlanError> {
        planner.reset(world.grid(), start, goal)?;
        planner.set_start(start)?;
        planner.cells_changed(world, changes.as_slice())?;
        planner.compute(world, u32::MAX)
    });
    let cost = found(status?, start)?;
    Ok(Step {
        at: start,
        changed: changes.len() as u16,
        expansions: planner.expansions(),
        instructions,
        cost,
    })
}

/// The planner's next cell from `at` and the move's cost.
fn next_move(planner: &ArenaPlanner, world: &World, at: Cell) -> Result<(Cell, u32), BenchError> {
    let next = planner.next_cell(world, at).ok_or(BenchError::BadMove(at))?;
    let (x, y) = (i32::from(at.x), i32::from(at.y));
    let cost = move_cost(world, x, y, i32::from(next.x) - x, i32::from(next.y) - y).ok_or(BenchError::BadMove(at))?;
    Ok((next, u32::from(cost)))
}

/// Run the whole benchmark on `world` (as parsed; its belief is changed), filling `report`.
pub fn run(
    world: &mut World,
    planner: &mut ArenaPlanner,
    meter: &mut impl Meter,
    report: &mut Report,
) -> Result<(), BenchError> {
    let mut changes = Changes::new();
    let (start, goal) = (world.start(), world.goal());

    // 1. The first plan, then its path (walked on the plan, before anything is sensed on the way).
    world.reset_belief();
    world.sense(start, SENSE_RADIUS, &mut changes);
    report.steps[0] = first_plan(planner, world, &changes, meter)?;
    report.step_count = 1;
    report.path[0] = start;
    report.path_len = 1;
    report.path_cost = 0;
    let mut here = start;
    while here != goal {
        let (next, cost) = next_move(planner, world, here)?;
        *report.path.get_mut(report.path_len).ok_or(BenchError::TooLong)? = next;
        report.path_len += 1;
        report.path_cost += cost;
        here = next;
    }

    // 2. The flight: move one cell, sense, replan, until the goal (docs/formats.md, map format).
    here = start;
    report.moves = 0;
    report.flight_cost = 0;
    while here != goal {
        let (next, cost) = next_move(planner, world, here)?;
        report.moves += 1;
        report.flight_cost += cost;
        here = next;
        world.sense(here, SENSE_RADIUS, &mut changes);
        let step = replan(planner, world, here, &changes, meter)?;
        *report.steps.get_mut(report.step_count).ok_or(BenchError::TooLong)? = step;
        report.step_count += 1;
    }
    report.queue_high_water = planner.queue_high_water();

    // 3. A 20 cm box dropped on the first plan's path at k/10 of its length, the drone at the start.
    let moves = report.path_len - 1;
    for (slot, k) in report.boxes.iter_mut().zip(1u16..) {
        let index = usize::from(k) * moves / 10;
        let centre = report.path[index];
        world.reset_belief();
        world.sense(start, SENSE_RADIUS, &mut changes);
        let baseline = first_plan(planner, world, &changes, &mut NoMeter)?;
        changes.clear();
        let first_replan = replan(planner, world, start, &changes, meter)?;
        let half = BOX_CELLS / 2;
        for y in centre.y.saturating_sub(half)..centre.y.saturating_sub(half) + BOX_CELLS {
            for x in centre.x.saturating_sub(half)..centre.x.saturating_sub(half) + BOX_CELLS {
                let cell = Cell::new(x, y);
                if cell != start && cell != goal && world.block(cell) {
                    changes.push(cell);
                }
            }
        }
        let step = replan(planner, world, start, &changes, meter)?;
        *slot = BoxReplan {
            k,
            path_index: index as u16,
            centre,
            baseline_expansions: baseline.expansions,
            first_replan,
            replan: step,
        };
    }
    Ok(())
}

/// An IMU sample of a drone at rest and level (gravity only).
pub const IMU_AT_REST: ImuSample = ImuSample {
    gyro_rad_s: [0.0; 3],
    accel_m_s2: [0.0, 0.0, GRAVITY_M_S2],
};

/// An estimator at `position` (arena frame, m) and `yaw` (rad), calibrated as on the ground before a take-off
/// (1.5 s of IMU samples at rest with height readings every 25 ms) and set flying; `None` if it did not
/// calibrate. The benchmarks that time the estimator's updates start from it.
pub fn estimator_calibrated_at_rest(position: [f32; 3], yaw: f32) -> Option<Estimator> {
    let mut est = Estimator::new(EstimatorConfig::default());
    est.reset(position, yaw);
    for k in 0..1500u32 {
        est.on_imu(&IMU_AT_REST, 0.001);
        if k % 25 == 0 {
            est.on_zrange(Some(0.0));
        }
    }
    if !est.is_calibrated() {
        return None;
    }
    est.set_flying(true);
    Some(est)
}

/// A flow reading of a drone at rest over good texture (the estimator benchmarks' flow input, 100 Hz).
pub const STILL_FLOW: FlowSample = FlowSample {
    dpixel_x: 0,
    dpixel_y: 0,
    squal: 140,
    motion_valid: true,
    dt_s: 0.01,
};

/// A Multi-ranger sweep 1 m from a wall on each side, nothing above (the wall-anchor benchmarks' input).
pub const WALLS_AT_1M: MultiRangerSample = MultiRangerSample {
    front_m: Some(1.0),
    back_m: Some(1.0),
    left_m: Some(1.0),
    right_m: Some(1.0),
    up_m: None,
};

#[cfg(test)]
mod tests {
    extern crate std;
    use std::boxed::Box;

    use super::*;

    #[test]
    fn parses_the_seed_map() {
        let world = World::parse(SEED_MAP).expect("seed map parses");
        assert_eq!(world.grid(), GridShape { width: 120, height: 60 });
        assert_eq!(world.start(), Cell::new(12, 26));
        assert_eq!(world.goal(), Cell::new(100, 30));
        // Everything hidden: the belief starts empty.
        assert!((0..60).all(|y| (0..120).all(|x| !world.is_blocked(x, y))));
        assert!(world.is_blocked(-1, 0) && world.is_blocked(120, 0) && world.is_blocked(0, 60));
    }

    #[test]
    fn rejects_bad_maps() {
        assert_eq!(World::parse("; only a comment\n").err(), Some(MapError::Empty));
        assert_eq!(World::parse("S.\n.G.\n").err(), Some(MapError::Ragged { line: 2 }));
        assert_eq!(
            World::parse("S.\nGx\n").err(),
            Some(MapError::BadChar { line: 2, column: 2 })
        );
        assert_eq!(World::parse("SS\nG.\n").err(), Some(MapError::Duplicate { line: 1 }));
        assert_eq!(World::parse("S.\n..\n").err(), Some(MapError::NoGoal));
        assert_eq!(World::parse("#G\r\n..\r\n").err(), Some(MapError::NoStart));
    }

    #[test]
    fn senses_within_the_radius_only() {
        let mut world = World::parse("o...o\n.S..G\n").expect("parses");
        let mut changes = Changes::new();
        world.sense(Cell::new(1, 0), 1, &mut changes);
        assert_eq!(changes.as_slice(), &[Cell::new(0, 1)]);
        world.sense(Cell::new(1, 0), 1, &mut changes);
        assert!(changes.is_empty());
        assert!(world.is_blocked(0, 1) && !world.is_blocked(4, 1));
    }

    #[test]
    fn summaries() {
        assert_eq!(summarize(&mut []), Summary::default());
        assert_eq!(
            summarize(&mut [5]),
            Summary {
                count: 1,
                median: 5,
                p90: 5,
                max: 5
            }
        );
        assert_eq!(
            summarize(&mut [4, 1, 3, 2]),
            Summary {
                count: 4,
                median: 2,
                p90: 4,
                max: 4
            }
        );
        let mut v: std::vec::Vec<u32> = (1..=20).rev().collect();
        assert_eq!(
            summarize(&mut v),
            Summary {
                count: 20,
                median: 10,
                p90: 18,
                max: 20
            }
        );
    }

    #[test]
    fn replays_the_seed_scenario() {
        let mut world = Box::new(World::parse(SEED_MAP).expect("seed map parses"));
        let mut planner: Box<ArenaPlanner> = Box::new(ArenaPlanner::new());
        let mut report = Box::new(Report::new());
        run(&mut world, &mut planner, &mut NoMeter, &mut report).expect("the seed map has a path");
        let first = report.first_plan();
        assert!(first.expansions > 0);
        assert_eq!(report.path_cost, first.cost);
        assert_eq!(report.path().first(), Some(&world.start()));
        assert_eq!(report.path().last(), Some(&world.goal()));
        assert_eq!(report.replans().len(), report.moves as usize);
        assert!(
            report.replans().iter().any(|s| s.changed > 0),
            "the flight senses the hidden walls"
        );
        assert!(report.flight_cost >= first.cost);
        for b in &report.boxes {
            // Every re-plan from scratch repeats the first plan exactly, and every box changes cells.
            assert_eq!(b.baseline_expansions, first.expansions);
            assert_eq!(
                b.first_replan.cost, first.cost,
                "a replan without changes keeps the cost"
            );
            assert!(b.replan.changed > 0 && b.replan.changed <= 16);
            assert!(b.replan.cost >= first.cost);
        }
    }
}
