//! Host benchmark: D* Lite against repeated A* (the `pathfinding` crate) on three replay maps.
//!
//! Maps: the seed scenario (`maps/seed.map`, 120 × 60, start (0.6, 1.3) m, goal (5.0, 1.5) m, walls hidden
//! until sensed), and two on the large arena (128 × 64): `maps/large-clutter.map` (known and hidden boxes)
//! and `maps/large-maze.map` (a maze of known walls with hidden blocked passages). Each is replayed once with
//! D* Lite (sense radius 8 cells) to record the drone's trajectory and what it learns at every step. Both
//! planners are then timed on exactly that sequence: D* Lite repairs incrementally, A* searches from scratch
//! from the drone's cell each time the map changed.
//!
//! Equal work: both planners produce the path, not only its cost. The first plan is, for D* Lite,
//! `reset` (O(cells)) + `compute` + [`extract_path`] into a buffer; for A*, `astar`, which returns the path
//! as a `Vec`. Replans: D* Lite `set_start` + `cells_changed` + `compute` + [`extract_path`]; A* `astar`
//! from the drone's cell. A*'s successor function yields the same moves as the planner (8 neighbours, 10/14,
//! no corner cutting) from an iterator, without allocating. The bench first checks that both find the same
//! costs at every step.
//!
//! Run: `cargo bench -p cfnav-tools --bench planner` (prints `RESULT` lines with the ratios at the end).

use std::hint::black_box;
use std::time::{Duration, Instant};

use cfnav::nav::dstar::{ARENA_QUEUE, DStarLite, PlanStatus};
use cfnav::nav::map::{Cell, GridShape, Traversability};
use cfnav::nav::path::extract_path;
use cfnav_tools::nav::replay::{ReplayMap, replay};
use criterion::{BatchSize, Criterion};
use pathfinding::prelude::astar;

/// The firmware's planner with the `large-arena` capacity (128 × 64 cells) and its open-list size.
type Planner = DStarLite<{ 128 * 64 }, ARENA_QUEUE>;
/// The D* Lite side's path buffer (the longest path on these maps is far shorter).
type PathBuf = heapless::Vec<Cell, 4096>;
/// The maps, by name.
const MAPS: [(&str, &str); 3] = [
    ("seed", include_str!("../../maps/seed.map")),
    ("large_clutter", include_str!("../../maps/large-clutter.map")),
    ("large_maze", include_str!("../../maps/large-maze.map")),
];
const SENSE_RADIUS: u16 = 8;

#[derive(Clone)]
struct Belief {
    width: u16,
    height: u16,
    blocked: Vec<bool>,
}

impl Traversability for Belief {
    fn shape(&self) -> GridShape {
        GridShape {
            width: self.width,
            height: self.height,
        }
    }
    fn is_blocked(&self, x: i32, y: i32) -> bool {
        x < 0
            || y < 0
            || x >= i32::from(self.width)
            || y >= i32::from(self.height)
            || self.blocked[y as usize * usize::from(self.width) + x as usize]
    }
}

impl Belief {
    fn set(&mut self, c: Cell, blocked: bool) {
        self.blocked[usize::from(c.y) * usize::from(self.width) + usize::from(c.x)] = blocked;
    }
}

/// One replan of the recorded flight: where the drone was and what it had just learnt.
struct Event {
    at: Cell,
    changed: Vec<Cell>,
}

struct Scenario {
    initial: Belief,
    truth: Belief,
    start: Cell,
    goal: Cell,
    /// Replans after map changes (the first plan excluded).
    events: Vec<Event>,
}

fn scenario(text: &str) -> Scenario {
    let map = ReplayMap::parse(text).expect("map");
    let cells = usize::from(map.width) * usize::from(map.height);
    let mut initial = Belief {
        width: map.width,
        height: map.height,
        blocked: vec![false; cells],
    };
    let mut truth = initial.clone();
    for y in 0..map.height {
        for x in 0..map.width {
            let c = Cell::new(x, y);
            initial.set(c, map.is_believed_blocked(c));
            truth.set(c, map.is_obstacle(c));
        }
    }
    let (start, goal) = (map.start, map.goal);
    let report = replay(map, SENSE_RADIUS).expect("replay");
    assert_eq!(report.status, "reached");
    // The first plan is made after the first sense (docs/formats.md, map format): it starts from that belief.
    for &c in &report.steps[0].changed_cells {
        initial.set(c, truth.is_blocked(i32::from(c.x), i32::from(c.y)));
    }
    let events = report
        .steps
        .iter()
        .skip(1)
        .filter(|s| !s.changed_cells.is_empty())
        .map(|s| Event {
            at: Cell::new(s.x, s.y),
            changed: s.changed_cells.clone(),
        })
        .collect();
    Scenario {
        initial,
        truth,
        start,
        goal,
        events,
    }
}

fn octile(a: Cell, b: Cell) -> u32 {
    let (dx, dy) = (u32::from(a.x.abs_diff(b.x)), u32::from(a.y.abs_diff(b.y)));
    10 * dx.max(dy) + 4 * dx.min(dy)
}

/// The moves of the planner's rules from `c` (8 neighbours, 10 / 14, no corner cutting), without allocating.
fn successors(map: &Belief, c: Cell) -> impl Iterator<Item = (Cell, u32)> + '_ {
    let (x, y) = (i32::from(c.x), i32::from(c.y));
    [(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1)]
        .into_iter()
        .filter_map(move |(dx, dy)| {
            if map.is_blocked(x + dx, y + dy) {
                return None;
            }
            let diagonal = dx != 0 && dy != 0;
            if diagonal && (map.is_blocked(x + dx, y) || map.is_blocked(x, y + dy)) {
                return None;
            }
            Some((
                Cell::new((x + dx) as u16, (y + dy) as u16),
                if diagonal { 14 } else { 10 },
            ))
        })
}

/// A* from `from` to `goal`: the path and its cost.
fn astar_plan(map: &Belief, from: Cell, goal: Cell) -> Option<(Vec<Cell>, u32)> {
    astar(&from, |c| successors(map, *c), |c| octile(*c, goal), |c| *c == goal)
}

fn astar_cost(map: &Belief, from: Cell, goal: Cell) -> Option<u32> {
    astar_plan(map, from, goal).map(|(path, cost)| {
        assert_eq!(path.first(), Some(&from));
        cost
    })
}

/// D* Lite's path (into `path`) and cost after a completed repair.
fn dstar_path(p: &Planner, map: &Belief, path: &mut PathBuf) -> u32 {
    let summary = extract_path(p, map, path).expect("path");
    assert!(summary.complete);
    summary.cost
}

fn first_plan_dstar(s: &Scenario, p: &mut Planner, path: &mut PathBuf) -> u32 {
    p.reset(s.initial.shape(), s.start, s.goal).expect("reset");
    match p.compute(&s.initial, u32::MAX).expect("compute") {
        PlanStatus::Found { .. } => dstar_path(p, &s.initial, path),
        other => panic!("{other:?}"),
    }
}

/// All replans of the flight on a planner that has made the first plan. Returns the summed costs.
fn replans_dstar(s: &Scenario, p: &mut Planner, belief: &mut Belief, path: &mut PathBuf) -> u64 {
    let mut sum = 0u64;
    for e in &s.events {
        for &c in &e.changed {
            belief.set(c, s.truth.is_blocked(i32::from(c.x), i32::from(c.y)));
        }
        p.set_start(e.at).expect("start");
        p.cells_changed(belief, &e.changed).expect("changed");
        if let PlanStatus::Found { .. } = p.compute(belief, u32::MAX).expect("compute") {
            sum += u64::from(dstar_path(p, belief, path));
        }
    }
    sum
}

fn replans_astar(s: &Scenario, belief: &mut Belief) -> u64 {
    let mut sum = 0u64;
    for e in &s.events {
        for &c in &e.changed {
            belief.set(c, s.truth.is_blocked(i32::from(c.x), i32::from(c.y)));
        }
        sum += u64::from(astar_cost(belief, e.at, s.goal).unwrap_or(0));
    }
    sum
}

/// Median times of `a` and `b` over `runs` runs each, run alternately (a, b, a, b, …) so that a change in
/// the machine's load during the measurement hits both alike.
fn paired_medians(mut a: impl FnMut(usize), mut b: impl FnMut(usize), runs: usize) -> (Duration, Duration) {
    let mut ta = Vec::with_capacity(runs);
    let mut tb = Vec::with_capacity(runs);
    for i in 0..runs {
        let t0 = Instant::now();
        a(i);
        ta.push(t0.elapsed());
        let t0 = Instant::now();
        b(i);
        tb.push(t0.elapsed());
    }
    ta.sort();
    tb.sort();
    (ta[runs / 2], tb[runs / 2])
}

fn bench_map(c: &mut Criterion, name: &str, s: &Scenario) {
    let mut planner: Box<Planner> = Box::new(DStarLite::new());
    let mut path: Box<PathBuf> = Box::new(PathBuf::new());
    let first_cost = first_plan_dstar(s, &mut planner, &mut path);
    assert_eq!(
        astar_cost(&s.initial, s.start, s.goal),
        Some(first_cost),
        "{name}: both planners agree"
    );
    let first_expansions = planner.expansions();
    let after_first = planner.clone();
    // Both planners must agree on every replan too.
    let (mut b1, mut b2) = (s.initial.clone(), s.initial.clone());
    let mut check = after_first.clone();
    assert_eq!(
        replans_dstar(s, &mut check, &mut b1, &mut path),
        replans_astar(s, &mut b2),
        "{name}: replans agree"
    );
    println!(
        "{name}: {} replans after map changes, first plan cost {first_cost} ({first_expansions} D* Lite expansions)",
        s.events.len()
    );

    let mut g = c.benchmark_group(name);
    g.bench_function("first_plan/dstar_lite", |b| {
        b.iter(|| first_plan_dstar(s, black_box(&mut planner), &mut path))
    });
    g.bench_function("first_plan/astar", |b| {
        b.iter(|| astar_plan(black_box(&s.initial), s.start, s.goal))
    });
    g.bench_function("all_replans/dstar_lite", |b| {
        b.iter_batched_ref(
            || (after_first.clone(), s.initial.clone()),
            |(p, belief)| replans_dstar(s, p, belief, &mut path),
            BatchSize::SmallInput,
        )
    });
    g.bench_function("all_replans/astar", |b| {
        b.iter_batched_ref(
            || s.initial.clone(),
            |belief| replans_astar(s, belief),
            BatchSize::SmallInput,
        )
    });
    g.finish();
}

/// The ratios, measured in this same run (median of repeated runs, setup excluded where possible).
fn ratios(name: &str, s: &Scenario) {
    let mut planner: Box<Planner> = Box::new(DStarLite::new());
    let mut path: Box<PathBuf> = Box::new(PathBuf::new());
    first_plan_dstar(s, &mut planner, &mut path);
    let after_first = planner.clone();
    let runs = 201;
    let (first_d, first_a) = paired_medians(
        |_| {
            black_box(first_plan_dstar(s, &mut planner, &mut path));
        },
        |_| {
            black_box(astar_plan(&s.initial, s.start, s.goal));
        },
        runs,
    );
    // Each replan run starts from a fresh copy of the state after the first plan (copies made beforehand).
    let mut pairs: Vec<_> = (0..runs).map(|_| (after_first.clone(), s.initial.clone())).collect();
    let mut beliefs: Vec<_> = (0..runs).map(|_| s.initial.clone()).collect();
    let (replan_d, replan_a) = paired_medians(
        |i| {
            let (p, b) = &mut pairs[i];
            black_box(replans_dstar(s, p, b, &mut path));
        },
        |i| {
            black_box(replans_astar(s, &mut beliefs[i]));
        },
        runs,
    );
    let n = s.events.len().max(1) as u32;
    println!(
        "RESULT {name} first_plan dstar_lite={first_d:?} astar={first_a:?} ratio_astar_over_dstar={:.2}",
        first_a.as_secs_f64() / first_d.as_secs_f64()
    );
    println!(
        "RESULT {name} replans n={n} dstar_lite_total={replan_d:?} ({:?}/replan) astar_total={replan_a:?} ({:?}/replan) ratio_astar_over_dstar={:.2}",
        replan_d / n,
        replan_a / n,
        replan_a.as_secs_f64() / replan_d.as_secs_f64()
    );
}

fn main() {
    let scenarios: Vec<(&str, Scenario)> = MAPS.iter().map(|(name, text)| (*name, scenario(text))).collect();
    let mut c = Criterion::default()
        .configure_from_args()
        .warm_up_time(Duration::from_millis(500));
    for (name, s) in &scenarios {
        bench_map(&mut c, name, s);
    }
    c.final_summary();
    for (name, s) in &scenarios {
        ratios(name, s);
    }
}
