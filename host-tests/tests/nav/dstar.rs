//! D* Lite against a plain Dijkstra oracle: random maps and reveal sequences, special cases, the largest
//! grids, and the expansion budget interrupted at every point.

use cfnav::nav::dstar::{DStarLite, PlanError, PlanStatus};
use cfnav::nav::map::{Cell, GridShape};
use cfnav::nav::path::{PathError, extract_path};
use heapless::Vec as HVec;
use host_tests::oracle::{VecMap, dijkstra, moves, parse, path_cost};
use proptest::prelude::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

type Planner = DStarLite<{ 128 * 64 }, 4096>;
type SmallPlanner = DStarLite<{ 40 * 30 }, 1200>;

fn boxed<const C: usize, const Q: usize>() -> Box<DStarLite<C, Q>> {
    Box::new(DStarLite::new())
}

/// Run until the repair completes, with an unlimited budget.
fn solve<const C: usize, const Q: usize>(p: &mut DStarLite<C, Q>, map: &VecMap) -> PlanStatus {
    p.compute(map, u32::MAX).expect("planner refused")
}

/// After a completed repair: the claimed cost equals the oracle's, the extracted path is legal, costs what
/// is claimed, and "no path" is reported exactly when the oracle finds none.
fn check_against_oracle<const C: usize, const Q: usize>(
    p: &DStarLite<C, Q>,
    map: &VecMap,
    status: PlanStatus,
    context: &str,
) -> Option<Vec<Cell>> {
    let oracle = dijkstra(map, p.start(), p.goal());
    match (status, oracle) {
        (PlanStatus::NoPath, None) => {
            assert_eq!(
                extract_path(p, map, &mut HVec::<Cell, 16>::new()),
                Err(PathError::NoPath),
                "{context}"
            );
            None
        }
        (PlanStatus::Found { cost }, Some(best)) => {
            assert_eq!(cost, best, "{context}: claimed cost differs from Dijkstra");
            let mut path = HVec::<Cell, 8192>::new();
            let summary = extract_path(p, map, &mut path).unwrap_or_else(|e| panic!("{context}: {e:?}"));
            assert!(summary.complete, "{context}");
            assert_eq!(path.first(), Some(&p.start()), "{context}");
            assert_eq!(path.last(), Some(&p.goal()), "{context}");
            let legal = path_cost(map, &path).unwrap_or_else(|| panic!("{context}: illegal path {path:?}"));
            assert_eq!(legal, cost, "{context}: path cost");
            assert_eq!(summary.cost, cost, "{context}: summary cost");
            Some(path.to_vec())
        }
        (s, o) => panic!("{context}: planner says {s:?}, oracle says {o:?}"),
    }
}

fn random_free_cell(rng: &mut SmallRng, map: &VecMap) -> Option<Cell> {
    for _ in 0..1000 {
        let c = Cell::new(rng.random_range(0..map.width), rng.random_range(0..map.height));
        if !map.get(c) {
            return Some(c);
        }
    }
    None
}

/// One random scenario: a true map, a believed map (known obstacles, plus false obstacles that vanish when
/// sensed), the drone revealing cells within `radius` and moving one cell per step.
fn random_scenario(seed: u64, max_w: u16, max_h: u16, budget: Option<u32>) -> (usize, usize) {
    let mut rng = SmallRng::seed_from_u64(seed);
    let w = rng.random_range(2..=max_w);
    let h = rng.random_range(2..=max_h);
    let density = rng.random_range(0.0..0.45);
    let mut truth = VecMap::new(w, h);
    for c in truth.cells().collect::<Vec<_>>() {
        truth.set(c, rng.random_bool(density));
    }
    let Some(start) = random_free_cell(&mut rng, &truth) else {
        return (0, 0);
    };
    let goal = if rng.random_bool(0.05) {
        start
    } else {
        random_free_cell(&mut rng, &truth).unwrap_or(start)
    };
    // Believed map: each true obstacle known with some probability; some phantom obstacles.
    let known = rng.random_range(0.0..1.0);
    let phantom = rng.random_range(0.0..0.1);
    let mut belief = VecMap::new(w, h);
    for c in truth.cells().collect::<Vec<_>>() {
        let b = if truth.get(c) {
            rng.random_bool(known)
        } else {
            c != start && rng.random_bool(phantom)
        };
        belief.set(c, b);
    }
    let radius = rng.random_range(1..=3u16);
    let mut p: Box<SmallPlanner> = boxed();
    p.reset(belief_shape(&belief), start, goal).expect("reset");
    let mut here = start;
    let mut replans = 0;
    for step in 0..(4 * usize::from(w) * usize::from(h)) {
        // Sense.
        let mut changed = Vec::new();
        for c in belief.cells().collect::<Vec<_>>() {
            if c.chebyshev(here) <= radius && belief.get(c) != truth.get(c) {
                belief.set(c, truth.get(c));
                changed.push(c);
            }
        }
        p.set_start(here).expect("start");
        p.cells_changed(&belief, &changed).expect("changed");
        let status = match budget {
            None => solve(&mut p, &belief),
            Some(b) => loop {
                match p.compute(&belief, b).expect("compute") {
                    PlanStatus::Incomplete => continue,
                    s => break s,
                }
            },
        };
        replans += 1;
        let ctx = format!("seed {seed} step {step} at {here:?} goal {goal:?} {w}x{h}");
        let Some(path) = check_against_oracle(&p, &belief, status, &ctx) else {
            return (replans, step);
        };
        if here == goal {
            return (replans, step);
        }
        here = path[1];
        // Occasionally a cell turns out blocked right where the drone is heading (the "next cell" case).
        if rng.random_bool(0.05) && path.len() > 2 && path[2] != goal {
            truth.set(path[2], true);
        }
    }
    panic!("seed {seed}: did not terminate");
}

fn belief_shape(m: &VecMap) -> GridShape {
    GridShape {
        width: m.width,
        height: m.height,
    }
}

#[test]
fn random_maps_and_reveals_match_dijkstra() {
    let mut replans = 0;
    for seed in 0..2500 {
        replans += random_scenario(seed, 40, 30, None).0;
    }
    assert!(replans > 20_000, "too few replans checked: {replans}");
}

#[test]
fn random_maps_with_small_budgets_match_dijkstra() {
    for seed in 10_000..10_400 {
        let budget = 1 + (seed % 7) as u32;
        random_scenario(seed, 25, 20, Some(budget));
    }
}

#[test]
fn start_next_to_goal_and_start_on_goal() {
    let map = parse(&["....", "....", "...."]);
    let mut p: Box<SmallPlanner> = boxed();
    p.reset(belief_shape(&map), Cell::new(1, 1), Cell::new(2, 1)).unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::Found { cost: 10 });
    p.reset(belief_shape(&map), Cell::new(1, 1), Cell::new(2, 2)).unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::Found { cost: 14 });
    p.reset(belief_shape(&map), Cell::new(1, 1), Cell::new(1, 1)).unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::Found { cost: 0 });
    let mut path = HVec::<Cell, 4>::new();
    assert_eq!(extract_path(&*p, &map, &mut path).unwrap().cost, 0);
    assert_eq!(path.as_slice(), &[Cell::new(1, 1)]);
}

#[test]
fn no_corner_cutting() {
    // Diagonal from (0,0) to (1,1) passes between (1,0) and (0,1); one of them is blocked.
    let map = parse(&["..", ".#", ".."]);
    let mut p: Box<SmallPlanner> = boxed();
    p.reset(belief_shape(&map), Cell::new(0, 0), Cell::new(1, 2)).unwrap();
    let s = solve(&mut p, &map);
    let path = check_against_oracle(&*p, &map, s, "corner").unwrap();
    // Without the rule the diagonal (0,1)→(1,2) past the blocked (1,1) would give 10 + 14.
    assert_eq!(s, PlanStatus::Found { cost: 30 });
    assert_eq!(
        path,
        vec![Cell::new(0, 0), Cell::new(0, 1), Cell::new(0, 2), Cell::new(1, 2)]
    );
}

#[test]
fn enclosed_goal_reports_no_path_quickly_and_repeatedly() {
    let mut map = parse(&["..........", "...###....", "...#.#....", "...###....", ".........."]);
    let mut p: Box<SmallPlanner> = boxed();
    p.reset(belief_shape(&map), Cell::new(0, 0), Cell::new(4, 2)).unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::NoPath);
    // Asking again costs nothing and gives the same answer.
    assert_eq!(solve(&mut p, &map), PlanStatus::NoPath);
    assert_eq!(p.expansions(), 0);
    // Opening the enclosure finds the path.
    map.set(Cell::new(4, 1), false);
    p.cells_changed(&map, &[Cell::new(4, 1)]).unwrap();
    let s = solve(&mut p, &map);
    check_against_oracle(&*p, &map, s, "opened");
    assert!(matches!(s, PlanStatus::Found { .. }));
}

#[test]
fn goal_becoming_blocked() {
    let mut map = VecMap::new(20, 10);
    let mut p: Box<SmallPlanner> = boxed();
    let goal = Cell::new(15, 5);
    p.reset(belief_shape(&map), Cell::new(2, 2), goal).unwrap();
    assert!(matches!(solve(&mut p, &map), PlanStatus::Found { .. }));
    map.set(goal, true);
    p.cells_changed(&map, &[goal]).unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::NoPath);
    map.set(goal, false);
    p.cells_changed(&map, &[goal]).unwrap();
    let s = solve(&mut p, &map);
    check_against_oracle(&*p, &map, s, "goal freed");
}

#[test]
fn obstacle_on_next_cell() {
    let mut map = VecMap::new(40, 30);
    let mut p: Box<SmallPlanner> = boxed();
    p.reset(belief_shape(&map), Cell::new(8, 15), Cell::new(38, 15))
        .unwrap();
    let mut here = Cell::new(8, 15);
    for _ in 0..10 {
        let s = solve(&mut p, &map);
        let path = check_against_oracle(&*p, &map, s, "next").unwrap();
        let next = path[1];
        assert_eq!(path[0], here);
        map.set(next, true);
        p.cells_changed(&map, &[next]).unwrap();
        let s = solve(&mut p, &map);
        let Some(path) = check_against_oracle(&*p, &map, s, "after block") else {
            panic!(
                "enclosed at {here:?}: {:?}",
                map.cells().filter(|c| map.get(*c)).collect::<Vec<_>>()
            );
        };
        assert!(!path.contains(&next), "the new path avoids the blocked cell");
        here = path[1];
        p.set_start(here).unwrap();
    }
    assert_ne!(here, Cell::new(8, 15));
}

#[test]
fn empty_map_costs_octile_distance() {
    let map = VecMap::new(120, 60);
    let mut p: Box<Planner> = boxed();
    p.reset(belief_shape(&map), Cell::new(12, 26), Cell::new(100, 30))
        .unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::Found { cost: 88 * 10 + 4 * 4 });
    // The octile heuristic is exact on open ground, so every cell on some optimal path ties on f. Ties
    // between settling cells go to the one nearest the start, so the search walks one optimal path and
    // stops at the start: one expansion per path cell (89), where the paper's smaller-g-first order
    // expands the whole band of optimal paths (424 cells here).
    assert!(p.expansions() <= 89, "expansions {}", p.expansions());
}

/// The first plan on the seed map's open start (nothing known yet) expands one cell per path cell.
#[test]
fn first_plan_on_open_ground_expands_only_the_path() {
    let map = VecMap::new(120, 60);
    for (start, goal) in [
        (Cell::new(12, 26), Cell::new(100, 30)),
        (Cell::new(0, 0), Cell::new(119, 59)),
        (Cell::new(60, 59), Cell::new(60, 0)),
        (Cell::new(5, 40), Cell::new(90, 2)),
    ] {
        let mut p: Box<Planner> = boxed();
        p.reset(belief_shape(&map), start, goal).unwrap();
        let s = solve(&mut p, &map);
        let path = check_against_oracle(&*p, &map, s, "open ground").unwrap();
        assert!(
            p.expansions() as usize <= path.len(),
            "{start:?} -> {goal:?}: {} expansions for a {}-cell path",
            p.expansions(),
            path.len()
        );
    }
}

/// A random `w × h` map (about `density_pct` % blocked) from `seed`, with `keep` cells left free.
fn seeded_map(seed: u64, w: u16, h: u16, density_pct: u8, keep: &[Cell]) -> VecMap {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut map = VecMap::new(w, h);
    for c in map.cells().collect::<Vec<_>>() {
        map.set(c, !keep.contains(&c) && rng.random_range(0..100u8) < density_pct);
    }
    map
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]
    /// The tie-break (under-consistent cells first, then settling cells nearest the start first) against
    /// Dijkstra: small maps where many cells tie on f, cells blocked and freed on and beside the current
    /// path, the drone moving along it; after every repair the cost, the path and "no path" must match.
    #[test]
    fn tie_break_keeps_every_repair_optimal(
        seed in any::<u64>(),
        w in 2u16..16,
        h in 2u16..12,
        density_pct in 0u8..35,
        ends in (any::<u16>(), any::<u16>(), any::<u16>(), any::<u16>()),
        events in proptest::collection::vec((0u8..4, any::<u16>(), any::<u16>()), 0..40),
    ) {
        let start = Cell::new(ends.0 % w, ends.1 % h);
        let goal = Cell::new(ends.2 % w, ends.3 % h);
        let mut map = seeded_map(seed, w, h, density_pct, &[start, goal]);
        let mut p: Box<SmallPlanner> = boxed();
        p.reset(belief_shape(&map), start, goal).unwrap();
        let s = solve(&mut p, &map);
        let mut path = check_against_oracle(&*p, &map, s, "first plan");
        for (i, &(kind, a, b)) in events.iter().enumerate() {
            let ctx = format!("event {i} ({kind}, {a}, {b})");
            match (kind, &path) {
                // Block or free a cell of the current path (the drone's own cell included).
                (0, Some(cells)) => {
                    let c = cells[usize::from(a) % cells.len()];
                    map.set(c, !map.get(c));
                    p.cells_changed(&map, &[c]).unwrap();
                }
                // Move the drone one cell along its path.
                (1, Some(cells)) if cells.len() > 1 => p.set_start(cells[1]).unwrap(),
                // Toggle any cell, or a 2 × 2 block of cells.
                (2, _) | (0, None) | (1, _) => {
                    let c = Cell::new(a % w, b % h);
                    map.set(c, !map.get(c));
                    p.cells_changed(&map, &[c]).unwrap();
                }
                _ => {
                    let mut changed = Vec::new();
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let c = Cell::new((a % w + dx).min(w - 1), (b % h + dy).min(h - 1));
                        if !changed.contains(&c) {
                            map.set(c, !map.get(c));
                            changed.push(c);
                        }
                    }
                    p.cells_changed(&map, &changed).unwrap();
                }
            }
            let s = solve(&mut p, &map);
            path = check_against_oracle(&*p, &map, s, &ctx);
        }
    }
}

/// The path the mission flies, by its geometric rule alone (independent of any search order): from the
/// start, step to the first of +x, +y, −x, −y, then the diagonals (+1,+1), (−1,+1), (−1,−1), (+1,−1) that
/// lies on some shortest path (move cost + Dijkstra's cost-to-goal = the cell's own cost-to-goal).
fn straight_first_path(map: &VecMap, start: Cell, goal: Cell) -> Option<Vec<Cell>> {
    const ORDER: [(i32, i32); 8] = [(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1)];
    let mut remaining = dijkstra(map, start, goal)?;
    let mut path = vec![start];
    let mut here = start;
    while here != goal {
        let legal = moves(map, here);
        let (next, rest) = ORDER
            .iter()
            .filter_map(|&(dx, dy)| {
                let (x, y) = (i32::from(here.x) + dx, i32::from(here.y) + dy);
                let &(n, c) = legal.iter().find(|(n, _)| i32::from(n.x) == x && i32::from(n.y) == y)?;
                let rest = dijkstra(map, n, goal)?;
                (c + rest == remaining).then_some((n, rest))
            })
            .next()
            .expect("a cell on a shortest path has a successor on one");
        path.push(next);
        (here, remaining) = (next, rest);
    }
    Some(path)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    /// Which of several shortest paths is flown does not depend on the first search's tie-break: after
    /// the first replan (here one without any change, as the mission's next tick) the path read off is the
    /// straight-first one of [`straight_first_path`], the choice the mission flew before the first search
    /// went deepest-first (that order alone reads off whichever optimal path it happened to expand).
    #[test]
    fn after_the_first_replan_the_path_is_the_straight_first_one(
        seed in any::<u64>(),
        w in 2u16..16,
        h in 2u16..12,
        density_pct in 0u8..35,
        ends in (any::<u16>(), any::<u16>(), any::<u16>(), any::<u16>()),
    ) {
        let start = Cell::new(ends.0 % w, ends.1 % h);
        let goal = Cell::new(ends.2 % w, ends.3 % h);
        let map = seeded_map(seed, w, h, density_pct, &[start, goal]);
        let mut p: Box<SmallPlanner> = boxed();
        p.reset(belief_shape(&map), start, goal).unwrap();
        let s = solve(&mut p, &map);
        check_against_oracle(&*p, &map, s, "first plan");
        let s = solve(&mut p, &map);
        let path = check_against_oracle(&*p, &map, s, "first replan");
        prop_assert_eq!(path, straight_first_path(&map, start, goal));
    }
}

/// A serpentine maze with one-cell corridors: the longest shortest path the largest grid allows.
#[test]
fn largest_grid_serpentine() {
    let (w, h) = (128u16, 64u16);
    let mut map = VecMap::new(w, h);
    for y in (1..h).step_by(2) {
        for x in 0..w {
            map.set(Cell::new(x, y), true);
        }
        let gap = if (y / 2) % 2 == 0 { w - 1 } else { 0 };
        map.set(Cell::new(gap, y), false);
    }
    let mut p: Box<Planner> = boxed();
    p.reset(belief_shape(&map), Cell::new(0, 0), Cell::new(0, h - 2))
        .unwrap();
    let s = solve(&mut p, &map);
    let path = check_against_oracle(&*p, &map, s, "serpentine").unwrap();
    assert!(path.len() > 3500);
    // Cut the maze in the middle: no path; reopen: path again.
    let cut = Cell::new(64, 30);
    map.set(cut, true);
    p.cells_changed(&map, &[cut]).unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::NoPath);
    map.set(cut, false);
    p.cells_changed(&map, &[cut]).unwrap();
    let s = solve(&mut p, &map);
    check_against_oracle(&*p, &map, s, "reopened");
}

#[test]
fn largest_grid_random_reveals() {
    for seed in 0..6 {
        let mut rng = SmallRng::seed_from_u64(seed);
        let (w, h) = (128u16, 64u16);
        let mut truth = VecMap::new(w, h);
        for _ in 0..40 {
            let (x0, y0) = (rng.random_range(0..w), rng.random_range(0..h));
            let (bw, bh) = (rng.random_range(1..20u16), rng.random_range(1..20u16));
            for y in y0..(y0 + bh).min(h) {
                for x in x0..(x0 + bw).min(w) {
                    truth.set(Cell::new(x, y), true);
                }
            }
        }
        let start = random_free_cell(&mut rng, &truth).unwrap();
        let goal = random_free_cell(&mut rng, &truth).unwrap();
        let mut belief = VecMap::new(w, h);
        let mut p: Box<Planner> = boxed();
        p.reset(belief_shape(&belief), start, goal).unwrap();
        let mut here = start;
        for step in 0..2000 {
            let mut changed = Vec::new();
            for c in belief.cells().collect::<Vec<_>>() {
                if c.chebyshev(here) <= 4 && belief.get(c) != truth.get(c) {
                    belief.set(c, truth.get(c));
                    changed.push(c);
                }
            }
            p.set_start(here).unwrap();
            p.cells_changed(&belief, &changed).unwrap();
            let s = solve(&mut p, &belief);
            let ctx = format!("large seed {seed} step {step}");
            let Some(path) = check_against_oracle(&*p, &belief, s, &ctx) else {
                break;
            };
            if here == goal {
                break;
            }
            here = path[1];
        }
    }
}

/// The budget interrupted at every possible point gives the same answer as one uninterrupted call.
#[test]
fn budget_interrupted_at_every_point() {
    let map = parse(&[
        "....................",
        "..######....#####...",
        ".......#........#...",
        "..###..#..####..#...",
        "....#..#.....#..#...",
        "....#........#......",
    ]);
    let (start, goal) = (Cell::new(0, 0), Cell::new(19, 5));
    let mut reference: Box<SmallPlanner> = boxed();
    reference.reset(belief_shape(&map), start, goal).unwrap();
    let want = solve(&mut reference, &map);
    let total = reference.expansions();
    assert!(total > 20);
    for first in 0..=total {
        let mut p: Box<SmallPlanner> = boxed();
        p.reset(belief_shape(&map), start, goal).unwrap();
        // First slice of `first` expansions, then single steps.
        let mut status = p.compute(&map, first).unwrap();
        let mut calls = 1;
        while status == PlanStatus::Incomplete {
            status = p.compute(&map, 1).unwrap();
            calls += 1;
            assert!(calls <= total + 2, "did not converge");
        }
        assert_eq!(status, want, "interrupted after {first}");
        assert_eq!(p.expansions(), total, "interrupted after {first}: total expansions");
        check_against_oracle(&*p, &map, status, "budget");
    }
}

#[test]
fn refuses_bad_setup_without_panicking() {
    let mut p: Box<SmallPlanner> = boxed();
    let map = VecMap::new(10, 10);
    assert_eq!(p.compute(&map, 10), Err(PlanError::NotReady));
    assert_eq!(p.set_start(Cell::new(1, 1)), Err(PlanError::NotReady));
    assert_eq!(
        p.reset(
            GridShape {
                width: 100,
                height: 100
            },
            Cell::new(0, 0),
            Cell::new(1, 1)
        ),
        Err(PlanError::BadShape)
    );
    assert_eq!(
        p.reset(GridShape { width: 0, height: 10 }, Cell::new(0, 0), Cell::new(1, 1)),
        Err(PlanError::BadShape)
    );
    assert_eq!(
        p.reset(belief_shape(&map), Cell::new(10, 0), Cell::new(1, 1)),
        Err(PlanError::OutOfBounds)
    );
    p.reset(belief_shape(&map), Cell::new(0, 0), Cell::new(9, 9)).unwrap();
    assert_eq!(p.set_start(Cell::new(0, 10)), Err(PlanError::OutOfBounds));
    // Changed cells outside the grid are ignored.
    p.cells_changed(&map, &[Cell::new(500, 500)]).unwrap();
    assert_eq!(solve(&mut p, &map), PlanStatus::Found { cost: 9 * 14 });
    assert_eq!(p.next_cell(&map, Cell::new(90, 90)), None);
}

#[test]
fn queue_overflow_is_an_error_and_reset_recovers() {
    type Tiny = DStarLite<{ 40 * 30 }, 8>;
    let map = VecMap::new(40, 30);
    let mut p: Box<Tiny> = boxed();
    p.reset(belief_shape(&map), Cell::new(0, 0), Cell::new(39, 29)).unwrap();
    assert_eq!(p.compute(&map, u32::MAX), Err(PlanError::QueueFull));
    assert_eq!(
        p.compute(&map, u32::MAX),
        Err(PlanError::QueueFull),
        "stays refused until reset"
    );
    // A small problem fits after a reset.
    p.reset(belief_shape(&map), Cell::new(0, 0), Cell::new(2, 0)).unwrap();
    assert_eq!(p.compute(&map, u32::MAX), Ok(PlanStatus::Found { cost: 20 }));
}

/// The firmware's queue capacity holds the seed arena's worst cases seen in random scenarios.
#[test]
fn arena_queue_capacity_suffices_on_seed_sized_maps() {
    let mut worst = 0;
    for seed in 0..40 {
        let mut rng = SmallRng::seed_from_u64(1000 + seed);
        let (w, h) = (120u16, 60u16);
        let mut map = VecMap::new(w, h);
        let density = rng.random_range(0.0..0.35);
        for c in map.cells().collect::<Vec<_>>() {
            map.set(c, rng.random_bool(density));
        }
        let start = random_free_cell(&mut rng, &map).unwrap();
        let goal = random_free_cell(&mut rng, &map).unwrap();
        let mut p: Box<cfnav::nav::dstar::ArenaPlanner> = boxed();
        p.reset(belief_shape(&map), start, goal).unwrap();
        let s = solve(&mut p, &map);
        check_against_oracle(&*p, &map, s, "arena");
        worst = worst.max(p.queue_high_water());
    }
    assert!(worst <= cfnav::nav::dstar::ARENA_QUEUE, "worst queue {worst}");
    println!("worst open-list size on 120x60 random maps: {worst}");
}
