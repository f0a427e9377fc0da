//! The occupancy grid against independent oracles: an exact segment–square intersection test for beams, a
//! brute-force inflation from the occupied set plus the walls, a model of the log-odds hysteresis, the
//! frame transform round trip, and garbage input.

use std::collections::BTreeSet;

use cfnav::nav::grid::{
    ChangedCells, GRAZE_CELLS, GridConfig, LOG_ODDS_MAX, LOG_ODDS_MIN, MAX_INFLATION_RADIUS_CELLS, OccupancyGrid,
};
use cfnav::nav::map::{ARENA_CELLS, CELL_SIZE_M, Cell, GridShape, Traversability};
use proptest::prelude::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const CAP: usize = 128 * 64;
type Grid = OccupancyGrid<CAP>;
type Changes = ChangedCells<CAP>;

/// Beam classification tolerance, metres (2·10⁻⁵ cell). A cell the segment enters by less than this, or
/// misses by less than this, is "touched at a corner or edge": a measure-zero ambiguity where either answer
/// is right, so the oracle accepts both. It also absorbs the firmware's `f32` arithmetic: endpoints are
/// divided by the cell size in `f32` (error ≈ 4·10⁻⁷ m at 6 m) and crossings are compared in `f32`. When
/// this was written, 420 000 random beams (these generators, 50× the iterations) still passed at 2·10⁻⁷ m,
/// so 10⁻⁶ m leaves a 5× margin.
const TOL_M: f64 = 1e-6;

fn grid(width: u16, height: u16, radius: u8) -> Box<Grid> {
    let mut g = Box::new(Grid::new());
    let shape = GridShape::new(width, height, CAP).expect("test shape fits");
    assert!(g.reset(shape, radius));
    g
}

fn all_cells(shape: GridShape) -> impl Iterator<Item = Cell> {
    (0..shape.height).flat_map(move |y| (0..shape.width).map(move |x| Cell::new(x, y)))
}

fn s() -> f64 {
    f64::from(CELL_SIZE_M)
}

// ---------------------------------------------------------------------------------------------------------
// Oracles
// ---------------------------------------------------------------------------------------------------------

/// Liang–Barsky in f64: the parameter interval of the segment `a → b` inside the closed box `lo … hi`.
fn clip_segment(a: (f64, f64), b: (f64, f64), lo: (f64, f64), hi: (f64, f64)) -> Option<(f64, f64)> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [(-dx, a.0 - lo.0), (dx, hi.0 - a.0), (-dy, a.1 - lo.1), (dy, hi.1 - a.1)] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else if p < 0.0 {
            t0 = t0.max(q / p);
        } else {
            t1 = t1.min(q / p);
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Crossing {
    /// The segment runs through the cell's interior by more than the tolerance.
    Must,
    /// The segment stays farther than the tolerance from the cell.
    MustNot,
    /// Touches the cell at a corner or edge, within the tolerance: either answer is accepted.
    Either,
}

/// Whether the segment crosses the (closed) square of `cell`, decided in f64 from the metres given.
fn crossing(a: (f32, f32), b: (f32, f32), cell: Cell) -> Crossing {
    let a = (f64::from(a.0), f64::from(a.1));
    let b = (f64::from(b.0), f64::from(b.1));
    let (x0, y0) = (f64::from(cell.x) * s(), f64::from(cell.y) * s());
    let (x1, y1) = (x0 + s(), y0 + s());
    if clip_segment(a, b, (x0 + TOL_M, y0 + TOL_M), (x1 - TOL_M, y1 - TOL_M)).is_some() {
        Crossing::Must
    } else if clip_segment(a, b, (x0 - TOL_M, y0 - TOL_M), (x1 + TOL_M, y1 + TOL_M)).is_none() {
        Crossing::MustNot
    } else {
        Crossing::Either
    }
}

/// Brute-force blocked layer: for every cell, look for an occupied cell or a wall cell (row −1, row h,
/// column −1, column w) within the Euclidean radius. Reads only `is_occupied`.
fn oracle_blocked(g: &Grid, r: i32) -> Vec<bool> {
    let shape = g.shape();
    let (w, h) = (i32::from(shape.width), i32::from(shape.height));
    let obstacle = |x: i32, y: i32| {
        let wall = (x == -1 || x == w || y == -1 || y == h) && (-1..=w).contains(&x) && (-1..=h).contains(&y);
        wall || (shape.contains(x, y) && g.is_occupied(Cell::new(x as u16, y as u16)))
    };
    all_cells(shape)
        .map(|c| {
            let (x, y) = (i32::from(c.x), i32::from(c.y));
            (-r..=r).any(|dy| (-r..=r).any(|dx| dx * dx + dy * dy <= r * r && obstacle(x + dx, y + dy)))
        })
        .collect()
}

fn blocked_snapshot(g: &Grid) -> Vec<bool> {
    all_cells(g.shape()).map(|c| g.is_blocked(c)).collect()
}

fn state_snapshot(g: &Grid) -> Vec<(i8, bool)> {
    all_cells(g.shape())
        .map(|c| (g.log_odds(c), g.is_occupied(c)))
        .collect()
}

/// The blocked layer matches the brute force, and `changed` holds exactly the cells that flipped, once each.
fn check_layer(g: &Grid, before: &[bool], changed: &Changes, context: &str) {
    let after = blocked_snapshot(g);
    let r = i32::from(g.inflation_radius_cells());
    assert_eq!(
        after,
        oracle_blocked(g, r),
        "{context}: blocked layer differs from the brute force"
    );
    if r == 0 {
        let occupied: Vec<bool> = all_cells(g.shape()).map(|c| g.is_occupied(c)).collect();
        assert_eq!(after, occupied, "{context}: radius 0 must make blocked == occupied");
    }
    assert!(!changed.overflowed(), "{context}");
    let reported: BTreeSet<Cell> = changed.as_slice().iter().copied().collect();
    assert_eq!(reported.len(), changed.len(), "{context}: a cell was reported twice");
    let flipped: BTreeSet<Cell> = all_cells(g.shape())
        .zip(before.iter().zip(&after))
        .filter(|(_, (b, a))| b != a)
        .map(|(c, _)| c)
        .collect();
    assert_eq!(
        reported, flipped,
        "{context}: reported changes differ from the flipped cells"
    );
}

/// Hysteresis model: after an update that touched each cell at most once, every cell's occupancy follows
/// from its previous occupancy and its new log-odds.
fn check_hysteresis(g: &Grid, before: &[(i8, bool)], forced: Option<Cell>, context: &str) {
    let cfg = g.config();
    for (c, &(_, was)) in all_cells(g.shape()).zip(before) {
        let lo = g.log_odds(c);
        assert!(
            (cfg.min_log_odds..=cfg.max_log_odds).contains(&lo),
            "{context}: {c:?} log-odds {lo} out of clamp"
        );
        let expected = if forced == Some(c) {
            true
        } else if was {
            lo > cfg.free_threshold
        } else {
            lo >= cfg.occupied_threshold
        };
        assert_eq!(
            g.is_occupied(c),
            expected,
            "{context}: {c:?} log-odds {lo}, was occupied {was}"
        );
    }
}

// ---------------------------------------------------------------------------------------------------------
// Random input
// ---------------------------------------------------------------------------------------------------------

/// A point for a beam: mostly uniform inside or around the grid, sometimes exactly on cell edges or
/// centres, sometimes far away.
fn random_point(rng: &mut SmallRng, shape: GridShape) -> (f32, f32) {
    let (w, h) = (
        f32::from(shape.width) * CELL_SIZE_M,
        f32::from(shape.height) * CELL_SIZE_M,
    );
    let mut coord = |size: f32, cells: u16| -> f32 {
        match rng.random_range(0..10) {
            0..=4 => rng.random_range(0.0..size),
            5..=7 => rng.random_range(-1.0..size + 1.0),
            8 => f32::from(rng.random_range(0..=cells)) * CELL_SIZE_M,
            _ => (f32::from(rng.random_range(0..cells)) + 0.5) * CELL_SIZE_M,
        }
    };
    let x = coord(w, shape.width);
    let y = coord(h, shape.height);
    if rng.random_range(0..40) == 0 {
        return (rng.random_range(-60.0..60.0), rng.random_range(-60.0..60.0));
    }
    (x, y)
}

fn random_beam(rng: &mut SmallRng, shape: GridShape) -> ((f32, f32), (f32, f32)) {
    let a = random_point(rng, shape);
    let b = match rng.random_range(0..12) {
        0 => a,
        1 => (a.0, random_point(rng, shape).1),
        2 => (random_point(rng, shape).0, a.1),
        _ => random_point(rng, shape),
    };
    (a, b)
}

// ---------------------------------------------------------------------------------------------------------
// Beams
// ---------------------------------------------------------------------------------------------------------

/// Whether `c` lies in the stretch of a returning beam `a → b` (end cell `end`) whose misses stop at
/// log-odds 0 unless the map already shows a face across the beam there ([`across_end`]): one of the
/// [`GRAZE_CELLS`] cells before the end cell in its row (a beam nearer the x axis) or column, the end cell
/// itself excluded.
fn in_graze_zone(a: (f32, f32), b: (f32, f32), hit: bool, end: Option<Cell>, c: Cell) -> bool {
    let Some(e) = end.filter(|e| hit && *e != c) else {
        return false;
    };
    let (dx, dy) = (i32::from(c.x) - i32::from(e.x), i32::from(c.y) - i32::from(e.y));
    if (b.0 - a.0).abs() >= (b.1 - a.1).abs() {
        dy == 0 && dx.abs() <= GRAZE_CELLS
    } else {
        dx == 0 && dy.abs() <= GRAZE_CELLS
    }
}

/// The two neighbours of a returning beam's end cell across the beam (above and below it for a beam nearer
/// the x axis, else left and right), as `all_cells` indices; `None` without a return or when either lies
/// outside the grid. When both hold evidence (log-odds > 0) before the beam, the return came from a face
/// across it and its graze zone is missed like any crossed cell.
fn across_end(shape: GridShape, a: (f32, f32), b: (f32, f32), hit: bool, end: Option<Cell>) -> Option<[usize; 2]> {
    let e = end.filter(|_| hit)?;
    let (x, y) = (i32::from(e.x), i32::from(e.y));
    let pair = if (b.0 - a.0).abs() >= (b.1 - a.1).abs() {
        [(x, y - 1), (x, y + 1)]
    } else {
        [(x - 1, y), (x + 1, y)]
    };
    let index = |(x, y): (i32, i32)| shape.contains(x, y).then(|| shape.index(Cell::new(x as u16, y as u16)));
    Some([index(pair[0])?, index(pair[1])?])
}

/// Shoots one beam into a fresh grid and checks the updated cells against the exact crossing oracle.
/// Returns (cells that must be crossed, ambiguous cells) for the statistics.
fn check_beam(g: &mut Grid, a: (f32, f32), b: (f32, f32), hit: bool) -> (usize, usize) {
    let shape = g.shape();
    assert!(g.reset(shape, 0));
    let cfg = g.config();
    let mut changed = Changes::new();
    g.integrate_beam(a, b, hit, &mut changed);
    let context = format!("beam {a:?} -> {b:?} hit {hit} in {}x{}", shape.width, shape.height);
    let end = shape.cell_at(b.0, b.1);
    let (mut must, mut either) = (0, 0);
    for c in all_cells(shape) {
        let lo = g.log_odds(c);
        let visited = lo != 0;
        // Exactly one update per visited cell: a double visit would show as two misses.
        if hit && Some(c) == end {
            assert_eq!(
                lo, cfg.hit_increment as i8,
                "{context}: end cell {c:?} must get exactly one hit"
            );
            assert!(
                g.is_occupied(c),
                "{context}: a single hit on an unknown cell makes it occupied"
            );
        } else {
            assert!(
                lo == 0 || lo == -(cfg.miss_decrement as i8),
                "{context}: {c:?} has log-odds {lo}"
            );
            assert!(!g.is_occupied(c), "{context}: {c:?} occupied without a hit");
        }
        match crossing(a, b, c) {
            // On a fresh grid a grazed cell holds no evidence, which its miss does not go beyond.
            Crossing::Must if in_graze_zone(a, b, hit, end, c) => {
                assert!(!visited, "{context}: grazed cell {c:?} updated");
            }
            Crossing::Must => {
                must += 1;
                assert!(visited, "{context}: crossed cell {c:?} not updated");
            }
            Crossing::MustNot => assert!(!visited, "{context}: cell {c:?} updated but not crossed"),
            Crossing::Either => either += 1,
        }
    }
    // Radius 0: blocked == occupied, and the only possible flip is the hit cell.
    let expected: Vec<Cell> = end.filter(|_| hit).into_iter().collect();
    assert_eq!(changed.as_slice(), expected.as_slice(), "{context}: changes");
    (must, either)
}

/// The graze zone, in the world that motivated it and the one it must leave alone. A return whose end
/// cell's neighbours across the beam hold no evidence may be a beam grazing a face along it (an 11 cm slab
/// seen end-on, world 438 001 497): the cells before the end in its row stay unknown. Once the map shows a
/// face across the beam there (a wall, the neighbours above and below the end already hit), the same return
/// is a wall seen head-on and the row before it is seen free, as without the rule. Oracle: the log-odds
/// arithmetic of the default config (hit +8, miss −3).
#[test]
fn a_return_from_a_face_across_the_beam_clears_its_row_and_a_graze_does_not() {
    let cell = f64::from(CELL_SIZE_M) as f32;
    let at = |x: f32, y: f32| (x * cell, y * cell);
    let row = |g: &Grid, y: u16| (2..=9).map(|x| g.log_odds(Cell::new(x, y))).collect::<Vec<_>>();
    let mut changed = Changes::new();
    // No face across yet: the eight cells before the end (x 2..=9 in row 5) keep log-odds 0.
    let mut g = grid(20, 12, 0);
    g.integrate_beam(at(1.5, 5.5), at(10.5, 5.5), true, &mut changed);
    assert_eq!(row(&g, 5), vec![0; 8]);
    assert_eq!(
        g.log_odds(Cell::new(1, 5)),
        -3,
        "the cell beyond the graze zone is missed"
    );
    assert!(g.is_occupied(Cell::new(10, 5)));
    // A wall: returns along the column end in (10, 4) and (10, 6) first, then the same beam as above.
    let mut g = grid(20, 12, 0);
    g.integrate_beam(at(10.5, 0.5), at(10.5, 4.5), true, &mut changed);
    g.integrate_beam(at(10.5, 11.5), at(10.5, 6.5), true, &mut changed);
    g.integrate_beam(at(1.5, 5.5), at(10.5, 5.5), true, &mut changed);
    assert_eq!(row(&g, 5), vec![-3; 8]);
    // Evidence on one side only is not a face across: still a possible graze.
    let mut g = grid(20, 12, 0);
    g.integrate_beam(at(10.5, 0.5), at(10.5, 4.5), true, &mut changed);
    g.integrate_beam(at(1.5, 5.5), at(10.5, 5.5), true, &mut changed);
    assert_eq!(row(&g, 5), vec![0; 8]);
    // A beam nearer the y axis looks at the neighbours left and right of its end.
    let mut g = grid(12, 20, 0);
    g.integrate_beam(at(0.5, 10.5), at(4.5, 10.5), true, &mut changed);
    g.integrate_beam(at(11.5, 10.5), at(6.5, 10.5), true, &mut changed);
    g.integrate_beam(at(5.5, 1.5), at(5.5, 10.5), true, &mut changed);
    let column: Vec<i8> = (2..=9).map(|y| g.log_odds(Cell::new(5, y))).collect();
    assert_eq!(column, vec![-3; 8]);
}

#[test]
fn beams_update_exactly_the_crossed_cells() {
    let mut rng = SmallRng::seed_from_u64(0x6e1d_0001);
    let mut g = Box::new(Grid::new());
    let (mut must, mut either, mut beams) = (0usize, 0usize, 0usize);
    for _ in 0..300 {
        let shape = GridShape::new(rng.random_range(1..=40), rng.random_range(1..=30), CAP).unwrap();
        assert!(g.reset(shape, 0));
        for _ in 0..20 {
            let (a, b) = random_beam(&mut rng, shape);
            let (m, e) = check_beam(&mut g, a, b, rng.random_bool(0.5));
            must += m;
            either += e;
            beams += 1;
        }
    }
    // The oracle must not be vacuous: most decisions are definite.
    assert_eq!(beams, 6000);
    println!("{beams} beams: {must} definite crossings, {either} ambiguous cells");
    assert!(must > 5 * beams, "only {must} definite crossings");
    assert!(
        either * 10 < must,
        "{either} ambiguous cells vs {must} definite crossings"
    );
}

#[test]
fn long_beams_across_the_largest_arena() {
    // Long diagonal beams accumulate the most f32 rounding; they must still match the f64 oracle.
    let mut rng = SmallRng::seed_from_u64(0x6e1d_0002);
    let mut g = grid(128, 64, 0);
    let shape = g.shape();
    for _ in 0..400 {
        let (w, h) = (
            f32::from(shape.width) * CELL_SIZE_M,
            f32::from(shape.height) * CELL_SIZE_M,
        );
        let a = (rng.random_range(-0.5..0.5), rng.random_range(-0.5..h + 0.5));
        let b = (rng.random_range(w - 0.5..w + 0.5), rng.random_range(-0.5..h + 0.5));
        let (a, b) = if rng.random_bool(0.5) { (a, b) } else { (b, a) };
        check_beam(&mut g, a, b, rng.random_bool(0.5));
    }
}

#[test]
fn beam_special_cases() {
    let mut g = grid(20, 10, 0);
    let shape = g.shape();
    let c = |x, y| shape.center_of(Cell::new(x, y));
    // Zero length: only the cell itself, which gets the hit.
    check_beam(&mut g, c(3, 4), c(3, 4), true);
    check_beam(&mut g, c(3, 4), c(3, 4), false);
    // Along a row, a column, exactly along a cell edge, and through exact cell corners.
    check_beam(&mut g, c(0, 4), c(19, 4), true);
    check_beam(&mut g, c(5, 0), c(5, 9), false);
    check_beam(&mut g, (0.2, 0.1), (0.9, 0.1), true);
    check_beam(&mut g, (0.0, 0.0), (0.5, 0.5), true);
    check_beam(&mut g, (0.5, 0.5), (0.0, 0.0), true);
    // Starting outside, ending inside; crossing the whole grid; outside only; grazing the border.
    check_beam(&mut g, (-3.0, -1.0), c(10, 5), true);
    check_beam(&mut g, (-3.0, 0.25), (4.0, 0.26), true);
    check_beam(&mut g, (-3.0, -0.1), (4.0, -0.2), true);
    check_beam(&mut g, (-1.0, 0.0), (2.0, 0.0), true);
    check_beam(&mut g, (1.0, -1.0), (1.0, 0.5), true);
    check_beam(&mut g, (1.0, 0.5), (1.0, 1000.0), true);
    // Ending a hair inside the border, from outside: the clip is nearly empty but the end cell gets its hit.
    check_beam(&mut g, (-1.0, 0.3), (1e-9, 0.3001), true);
    check_beam(&mut g, (-50.0, 0.31), (1e-6, 0.32), true);
    check_beam(&mut g, (2.0, 0.3), (0.999_999_9, 0.3), true);
    check_beam(&mut g, (0.5, -7.0), (0.52, 1e-7), true);

    // A return from outside the grid (the wall behind the last cell) marks nothing occupied.
    assert!(g.reset(g.shape(), 0));
    let mut changed = Changes::new();
    g.integrate_beam(c(2, 2), (5.0, 0.1), true, &mut changed);
    assert!(all_cells(g.shape()).all(|c| !g.is_occupied(c) && g.log_odds(c) <= 0));
    assert!(changed.is_empty());
    // A max-range reading never marks anything occupied, even its end cell.
    g.integrate_beam(c(2, 2), c(15, 7), false, &mut changed);
    assert!(all_cells(g.shape()).all(|c| !g.is_occupied(c)));
    assert!(g.log_odds(Cell::new(15, 7)) < 0);
}

// ---------------------------------------------------------------------------------------------------------
// Inflation and change reporting
// ---------------------------------------------------------------------------------------------------------

#[test]
fn reset_inflates_the_walls() {
    for (w, h) in [(1, 1), (2, 7), (10, 10), (33, 17), (128, 64)] {
        for r in [0, 1, 2, 3, 5, 8, 16] {
            let g = grid(w, h, r);
            assert_eq!(blocked_snapshot(&g), oracle_blocked(&g, i32::from(r)), "{w}x{h} r {r}");
            assert!(all_cells(g.shape()).all(|c| g.log_odds(c) == 0 && !g.is_occupied(c)));
        }
    }
    // Radii above the cap are clamped to it.
    let g = grid(40, 40, 200);
    assert_eq!(g.inflation_radius_cells(), MAX_INFLATION_RADIUS_CELLS);
    assert_eq!(
        blocked_snapshot(&g),
        oracle_blocked(&g, i32::from(MAX_INFLATION_RADIUS_CELLS))
    );
}

/// One random update of any kind; returns the forced cell for `set_occupied`.
fn random_update(rng: &mut SmallRng, g: &mut Grid, changed: &mut Changes) -> (String, Option<Cell>) {
    let shape = g.shape();
    match rng.random_range(0..10) {
        0..=1 => {
            // Sometimes out of range: must be ignored.
            let c = Cell::new(
                rng.random_range(0..shape.width + 2),
                rng.random_range(0..shape.height + 2),
            );
            g.set_occupied(c, changed);
            (
                format!("set_occupied {c:?}"),
                shape.contains(i32::from(c.x), i32::from(c.y)).then_some(c),
            )
        }
        2..=6 => {
            let (a, b) = random_beam(rng, shape);
            let hit = rng.random_bool(0.7);
            g.integrate_beam(a, b, hit, changed);
            (format!("beam {a:?} -> {b:?} hit {hit}"), None)
        }
        7..=8 => {
            // Short beams from a common origin, like a sweeping ranger: builds and erodes walls.
            let a = (rng.random_range(0.0..0.3), rng.random_range(0.0..0.3));
            let b = random_point(rng, shape);
            g.integrate_beam(a, b, true, changed);
            (format!("beam {a:?} -> {b:?} hit true"), None)
        }
        _ => {
            let center = random_point(rng, shape);
            let radius = rng.random_range(-0.05..0.4);
            g.mark_free_disc(center, radius, changed);
            (format!("free disc {center:?} r {radius}"), None)
        }
    }
}

#[test]
fn inflation_and_changes_match_brute_force() {
    let mut rng = SmallRng::seed_from_u64(0x6e1d_0003);
    let mut g = Box::new(Grid::new());
    let mut changed = Changes::new();
    let (mut flips_on, mut flips_off) = (0usize, 0usize);
    for trial in 0..40 {
        let shape = GridShape::new(rng.random_range(1..=30), rng.random_range(1..=20), CAP).unwrap();
        let r = rng.random_range(0..=5);
        assert!(g.reset(shape, r));
        for step in 0..120 {
            let before = blocked_snapshot(&g);
            let state = state_snapshot(&g);
            changed.clear();
            let (what, forced) = random_update(&mut rng, &mut g, &mut changed);
            let context = format!(
                "trial {trial} step {step} {}x{} r {r}: {what}",
                shape.width, shape.height
            );
            check_layer(&g, &before, &changed, &context);
            check_hysteresis(&g, &state, forced, &context);
            for c in changed.as_slice() {
                if g.is_blocked(*c) {
                    flips_on += 1;
                } else {
                    flips_off += 1;
                }
            }
        }
    }
    // Both directions of the incremental path were exercised.
    assert!(flips_on > 1000 && flips_off > 1000, "on {flips_on} off {flips_off}");
}

#[test]
fn dense_obstacles_then_freed_one_by_one() {
    // The un-inflation path with many overlapping discs: every freed cell leaves neighbours that other
    // obstacles still block.
    let mut rng = SmallRng::seed_from_u64(0x6e1d_0004);
    for r in [1u8, 2, 4] {
        let mut g = grid(24, 16, r);
        let mut changed = Changes::new();
        let mut obstacles: Vec<Cell> = all_cells(g.shape()).filter(|_| rng.random_bool(0.25)).collect();
        for &c in &obstacles {
            let before = blocked_snapshot(&g);
            changed.clear();
            g.set_occupied(c, &mut changed);
            check_layer(&g, &before, &changed, &format!("r {r} set {c:?}"));
        }
        while let Some(c) = obstacles.pop() {
            let before = blocked_snapshot(&g);
            changed.clear();
            // A footprint-sized free disc around the cell's centre frees exactly that cell.
            g.mark_free_disc(g.shape().center_of(c), 0.01, &mut changed);
            assert!(!g.is_occupied(c));
            check_layer(&g, &before, &changed, &format!("r {r} free {c:?}"));
        }
        assert_eq!(
            blocked_snapshot(&g),
            oracle_blocked(&grid(24, 16, r), i32::from(r)),
            "only walls remain"
        );
    }
}

#[test]
fn beam_that_moves_an_obstacle_reports_each_flip_once() {
    // One beam both frees an occupied cell (its third miss) and hits the cell next to it: the discs of the
    // two overlap, and every cell of the overlap must be reported at most once (here: not at all).
    for r in [1u8, 2, 3] {
        let mut g = grid(30, 9, r);
        let shape = g.shape();
        let mut changed = Changes::new();
        shoot(&mut g, 4, 10, true);
        // Two misses down column 10, which leave (11, 4) unknown.
        for _ in 0..2 {
            g.integrate_beam(
                shape.center_of(Cell::new(10, 0)),
                shape.center_of(Cell::new(10, 8)),
                false,
                &mut changed,
            );
        }
        assert!(g.is_occupied(Cell::new(10, 4)));
        assert_eq!(g.log_odds(Cell::new(11, 4)), 0);
        let before = blocked_snapshot(&g);
        changed.clear();
        g.integrate_beam(
            g.shape().center_of(Cell::new(0, 4)),
            g.shape().center_of(Cell::new(11, 4)),
            true,
            &mut changed,
        );
        assert!(!g.is_occupied(Cell::new(10, 4)) && g.is_occupied(Cell::new(11, 4)));
        check_layer(&g, &before, &changed, &format!("r {r}"));
    }
}

#[test]
fn changed_cells_overflow_is_flagged() {
    let mut g = grid(20, 20, 3);
    let mut small = ChangedCells::<4>::new();
    g.set_occupied(Cell::new(10, 10), &mut small);
    // A radius-3 disc has 29 cells; only 4 fit.
    assert!(small.overflowed());
    assert_eq!(small.len(), 4);
    small.clear();
    assert!(!small.overflowed() && small.is_empty());
    // Setting an already occupied cell changes nothing.
    g.set_occupied(Cell::new(10, 10), &mut small);
    assert!(small.is_empty() && !small.overflowed());
    // Updates append: two calls accumulate.
    let mut changed = Changes::new();
    g.set_occupied(Cell::new(5, 10), &mut changed);
    let first = changed.len();
    g.set_occupied(Cell::new(15, 10), &mut changed);
    assert!(changed.len() > first);
}

// ---------------------------------------------------------------------------------------------------------
// Hysteresis
// ---------------------------------------------------------------------------------------------------------

/// A beam along row `y` from the centre of column 0 to the centre of column `x`.
fn shoot(g: &mut Grid, y: u16, x: u16, hit: bool) {
    let shape = g.shape();
    let mut changed = Changes::new();
    g.integrate_beam(
        shape.center_of(Cell::new(0, y)),
        shape.center_of(Cell::new(x, y)),
        hit,
        &mut changed,
    );
}

#[test]
fn documented_defaults_and_false_hit_clearing() {
    let cfg = GridConfig::default();
    assert_eq!(cfg, GridConfig::DEFAULT);
    assert_eq!(
        (
            cfg.hit_increment,
            cfg.miss_decrement,
            cfg.min_log_odds,
            cfg.max_log_odds
        ),
        (8, 3, -8, 24),
        "documented defaults"
    );
    assert_eq!((cfg.occupied_threshold, cfg.free_threshold), (6, 0));

    let target = Cell::new(10, 3);
    let mut g = grid(30, 8, 0);
    // One hit on an unknown cell makes it occupied.
    shoot(&mut g, 3, 10, true);
    assert!(g.is_occupied(target) && g.is_blocked(target));
    // Two misses are not enough, the third clears it (8 → 5 → 2 → −1).
    for expected in [5, 2] {
        shoot(&mut g, 3, 20, false);
        assert_eq!(g.log_odds(target), expected);
        assert!(g.is_occupied(target), "still occupied at {expected}");
    }
    shoot(&mut g, 3, 20, false);
    assert_eq!(g.log_odds(target), -1);
    assert!(!g.is_occupied(target) && !g.is_blocked(target));

    // Hysteresis band: a cell seen free once needs two hits, and then stays occupied below the occupied
    // threshold until it reaches the free threshold.
    let mut g = grid(30, 8, 0);
    shoot(&mut g, 3, 20, false);
    assert_eq!(g.log_odds(target), -3);
    shoot(&mut g, 3, 10, true);
    assert_eq!(g.log_odds(target), 5);
    assert!(!g.is_occupied(target), "5 < 6: not yet occupied");
    shoot(&mut g, 3, 10, true);
    assert!(g.is_occupied(target));
    for expected in [10, 7, 4, 1] {
        shoot(&mut g, 3, 20, false);
        assert_eq!(g.log_odds(target), expected);
        assert!(g.is_occupied(target), "hysteresis keeps it occupied at {expected}");
    }
    shoot(&mut g, 3, 20, false);
    assert!(!g.is_occupied(target));

    // A confirmed obstacle saturates at the upper clamp and needs eight misses.
    let mut g = grid(30, 8, 0);
    for _ in 0..5 {
        shoot(&mut g, 3, 10, true);
    }
    assert_eq!(g.log_odds(target), cfg.max_log_odds);
    for _ in 0..7 {
        shoot(&mut g, 3, 20, false);
    }
    assert!(g.is_occupied(target));
    shoot(&mut g, 3, 20, false);
    assert!(!g.is_occupied(target));
    // Long free: saturates at the lower clamp.
    for _ in 0..10 {
        shoot(&mut g, 3, 20, false);
    }
    assert_eq!(g.log_odds(target), cfg.min_log_odds);
}

#[test]
fn custom_configs_are_sanitized() {
    let mut g = Box::new(Grid::new());
    let shape = GridShape::new(10, 10, CAP).unwrap();
    let weird = [
        GridConfig {
            hit_increment: 255,
            miss_decrement: 255,
            min_log_odds: 100,
            max_log_odds: -100,
            occupied_threshold: 127,
            free_threshold: 127,
        },
        GridConfig {
            hit_increment: 0,
            miss_decrement: 0,
            min_log_odds: i8::MIN,
            max_log_odds: i8::MAX,
            occupied_threshold: i8::MIN,
            free_threshold: i8::MAX,
        },
        GridConfig {
            min_log_odds: 5,
            max_log_odds: 5,
            ..GridConfig::DEFAULT
        },
    ];
    let mut rng = SmallRng::seed_from_u64(0x6e1d_0005);
    for cfg in weird {
        assert!(g.reset_with(shape, 1, cfg));
        let c = g.config();
        assert!(LOG_ODDS_MIN <= c.min_log_odds && c.min_log_odds <= 0, "{c:?}");
        assert!(0 < c.occupied_threshold && c.occupied_threshold <= c.max_log_odds && c.max_log_odds <= LOG_ODDS_MAX);
        assert!(c.min_log_odds <= c.free_threshold && c.free_threshold < c.occupied_threshold);
        // `reset` keeps the config.
        assert!(g.reset(shape, 1));
        assert_eq!(g.config(), c);
        let mut changed = Changes::new();
        for step in 0..200 {
            let before = blocked_snapshot(&g);
            let state = state_snapshot(&g);
            changed.clear();
            let (what, forced) = random_update(&mut rng, &mut g, &mut changed);
            let context = format!("{cfg:?} step {step}: {what}");
            check_layer(&g, &before, &changed, &context);
            check_hysteresis(&g, &state, forced, &context);
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Free disc
// ---------------------------------------------------------------------------------------------------------

#[test]
fn free_disc_clears_exactly_the_cells_whose_centres_lie_inside() {
    let mut rng = SmallRng::seed_from_u64(0x6e1d_0006);
    for _ in 0..300 {
        let mut g = grid(
            rng.random_range(1..=25),
            rng.random_range(1..=25),
            rng.random_range(0..=3),
        );
        let shape = g.shape();
        let mut changed = Changes::new();
        for c in all_cells(shape).filter(|_| rng.random_bool(0.5)) {
            g.set_occupied(c, &mut changed);
        }
        let center = random_point(&mut rng, shape);
        let radius: f32 = rng.random_range(-0.1..0.5);
        let state = state_snapshot(&g);
        let before = blocked_snapshot(&g);
        changed.clear();
        g.mark_free_disc(center, radius, &mut changed);
        let context = format!("disc {center:?} r {radius}");
        check_layer(&g, &before, &changed, &context);
        let min = g.config().min_log_odds;
        let own = shape.cell_at(center.0, center.1);
        for (c, &(lo, _)) in all_cells(shape).zip(&state) {
            let (px, py) = ((f64::from(c.x) + 0.5) * s(), (f64::from(c.y) + 0.5) * s());
            let d = ((px - f64::from(center.0)).powi(2) + (py - f64::from(center.1)).powi(2)).sqrt();
            let r = f64::from(radius);
            if Some(c) == own || (r >= 0.0 && d < r - 1e-6) {
                assert_eq!(g.log_odds(c), min, "{context}: {c:?} at {d} must be cleared");
                assert!(!g.is_occupied(c));
            } else if r < 0.0 || d > r + 1e-6 {
                assert_eq!(g.log_odds(c), lo, "{context}: {c:?} at {d} must be untouched");
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Frames
// ---------------------------------------------------------------------------------------------------------

#[test]
fn frames_round_trip() {
    for (w, h) in [(1, 1), (7, 3), (120, 60), (128, 64), (255, 32)] {
        let shape = GridShape::new(w, h, usize::MAX).unwrap();
        for c in all_cells(shape) {
            let (x, y) = shape.center_of(c);
            assert_eq!(shape.cell_at(x, y), Some(c), "centre of {c:?}");
            // Just inside the cell's lower-left corner.
            let corner = (f32::from(c.x) * CELL_SIZE_M + 1e-4, f32::from(c.y) * CELL_SIZE_M + 1e-4);
            assert_eq!(shape.cell_at(corner.0, corner.1), Some(c), "corner of {c:?}");
        }
        let (wm, hm) = (f32::from(w) * CELL_SIZE_M, f32::from(h) * CELL_SIZE_M);
        assert_eq!(shape.cell_at(0.0, 0.0), Some(Cell::new(0, 0)));
        assert_eq!(shape.cell_at(-0.0, -0.0), Some(Cell::new(0, 0)));
        assert_eq!(shape.cell_at(wm - 1e-4, hm - 1e-4), Some(Cell::new(w - 1, h - 1)));
        for (x, y) in [
            (-1e-4, 0.0),
            (0.0, -1e-4),
            (wm + 1e-4, 0.0),
            (0.0, hm + 1e-4),
            (f32::NAN, 0.0),
            (0.0, f32::NAN),
            (f32::INFINITY, 0.0),
            (f32::NEG_INFINITY, 0.0),
            (f32::MAX, f32::MAX),
            (f32::MIN, 0.0),
        ] {
            assert_eq!(shape.cell_at(x, y), None, "({x}, {y}) in {w}x{h}");
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Garbage and edge cases
// ---------------------------------------------------------------------------------------------------------

const SPECIAL: [f32; 12] = [
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    f32::MIN,
    f32::MIN_POSITIVE,
    -f32::MIN_POSITIVE,
    1e30,
    -1e30,
    3.3e3,
    -0.0,
    0.0,
];

#[test]
fn garbage_never_panics() {
    let mut g = grid(20, 15, 2);
    let mut changed = ChangedCells::<8>::new();
    for &a in &SPECIAL {
        for &b in &SPECIAL {
            for hit in [false, true] {
                g.integrate_beam((a, 0.3), (b, 0.4), hit, &mut changed);
                g.integrate_beam((0.3, a), (0.4, b), hit, &mut changed);
                g.integrate_beam((a, b), (0.5, 0.5), hit, &mut changed);
                g.integrate_beam((0.5, 0.5), (a, b), hit, &mut changed);
                g.integrate_beam((a, a), (b, b), hit, &mut changed);
            }
            g.mark_free_disc((a, b), 0.2, &mut changed);
            g.mark_free_disc((0.5, 0.5), a, &mut changed);
        }
    }
    for c in [Cell::new(20, 0), Cell::new(0, 15), Cell::new(u16::MAX, u16::MAX)] {
        g.set_occupied(c, &mut changed);
        assert!(g.is_blocked(c) && !g.is_occupied(c) && g.log_odds(c) == 0);
    }
    for (x, y) in [(-1, 0), (0, -1), (20, 0), (0, 15), (i32::MIN, i32::MIN), (i32::MAX, 0)] {
        assert!(Traversability::is_blocked(&*g, x, y), "({x}, {y}) is outside");
    }
    // Whatever happened, the layer is still consistent.
    assert_eq!(blocked_snapshot(&g), oracle_blocked(&g, 2));

    // Beams far outside, never touching the grid, change nothing.
    let mut g = grid(20, 15, 0);
    let mut changed = Changes::new();
    g.integrate_beam((-5.0, -5.0), (-5.0, 50.0), true, &mut changed);
    g.integrate_beam((100.0, 100.0), (200.0, -300.0), false, &mut changed);
    g.integrate_beam((-3.0, 3.0), (3.0, 9.0), true, &mut changed);
    assert!(all_cells(g.shape()).all(|c| g.log_odds(c) == 0));
    // An infinite or huge free disc clears the whole grid.
    g.set_occupied(Cell::new(3, 3), &mut changed);
    g.mark_free_disc((0.5, 0.5), f32::INFINITY, &mut changed);
    assert!(all_cells(g.shape()).all(|c| g.log_odds(c) == g.config().min_log_odds));
}

#[test]
fn empty_and_oversized_grids() {
    static EMPTY: OccupancyGrid<64> = OccupancyGrid::new();
    assert_eq!(EMPTY.shape(), GridShape { width: 0, height: 0 });
    assert!(EMPTY.is_blocked(Cell::new(0, 0)));
    assert!(Traversability::is_blocked(&EMPTY, 0, 0));
    assert_eq!(Traversability::shape(&EMPTY), EMPTY.shape());

    let mut g = OccupancyGrid::<64>::default();
    let mut changed = ChangedCells::<64>::default();
    g.integrate_beam((0.0, 0.0), (1.0, 1.0), true, &mut changed);
    g.mark_free_disc((0.0, 0.0), 1.0, &mut changed);
    g.set_occupied(Cell::new(0, 0), &mut changed);
    assert!(changed.is_empty());

    // A shape larger than the capacity (built by hand, bypassing `GridShape::new`) is refused.
    assert!(!g.reset(GridShape { width: 9, height: 8 }, 1));
    assert_eq!(g.shape(), GridShape { width: 0, height: 0 });
    assert!(g.reset(GridShape { width: 8, height: 8 }, 1));
    assert!(g.reset(GridShape { width: 64, height: 1 }, 1));
    assert!(g.reset(GridShape { width: 0, height: 5 }, 1));
    g.integrate_beam((0.0, 0.0), (1.0, 1.0), true, &mut changed);
    assert!(changed.is_empty());
}

#[test]
fn memory_is_one_byte_per_cell() {
    assert_eq!(size_of::<OccupancyGrid<{ 120 * 60 }>>(), 120 * 60 + 12);
    assert_eq!(size_of::<OccupancyGrid<{ 128 * 64 }>>(), 128 * 64 + 12);
    assert!(size_of::<OccupancyGrid<ARENA_CELLS>>() <= ARENA_CELLS + 12);
}

fn any_coord() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -2.0f32..4.0,
        1 => any::<f32>(),
        1 => prop::sample::select(SPECIAL.to_vec()),
        1 => -1e7f32..1e7,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Arbitrary floats (NaN, infinities, subnormals, huge values) never panic, and the blocked layer and
    /// change reports stay exact.
    #[test]
    fn arbitrary_floats_keep_the_layer_exact(
        ops in prop::collection::vec((any_coord(), any_coord(), any_coord(), any_coord(), any::<bool>(), 0u8..3), 1..12),
        r in 0u8..4,
    ) {
        let mut g = grid(30, 20, r);
        let mut changed = Changes::new();
        for (a, b, c, d, hit, kind) in ops {
            let before = blocked_snapshot(&g);
            changed.clear();
            match kind {
                0 => g.integrate_beam((a, b), (c, d), hit, &mut changed),
                1 => g.mark_free_disc((a, b), c, &mut changed),
                _ => g.set_occupied(Cell::new(a.abs().min(100.0) as u16, b.abs().min(100.0) as u16), &mut changed),
            }
            check_layer(&g, &before, &changed, &format!("{a} {b} {c} {d} {hit} {kind}"));
        }
    }
}

#[test]
fn changing_the_inflation_radius_rebuilds_the_layer_and_keeps_the_evidence() {
    let mut rng = SmallRng::seed_from_u64(77);
    let mut g = grid(40, 24, 4);
    let mut changed = Changes::new();
    for _ in 0..60 {
        random_update(&mut rng, &mut g, &mut changed);
    }
    for radius in [2u8, 0, 3, 4, 4, MAX_INFLATION_RADIUS_CELLS + 3] {
        let evidence = state_snapshot(&g);
        let before = blocked_snapshot(&g);
        changed.clear();
        g.set_inflation_radius(radius, &mut changed);
        assert_eq!(g.inflation_radius_cells(), radius.min(MAX_INFLATION_RADIUS_CELLS));
        assert_eq!(
            state_snapshot(&g),
            evidence,
            "radius {radius}: log-odds or occupancy changed"
        );
        check_layer(&g, &before, &changed, &format!("radius {radius}"));
        // Later updates keep the layer exact at the new radius.
        for _ in 0..10 {
            let before = blocked_snapshot(&g);
            changed.clear();
            let (what, _) = random_update(&mut rng, &mut g, &mut changed);
            check_layer(&g, &before, &changed, &format!("radius {radius}, then {what}"));
        }
    }
}

// ---------------------------------------------------------------------------------------------------------
// Unknown cells and unobserved regions
// ---------------------------------------------------------------------------------------------------------

/// Oracle of the region tests: how many of cell (x, y)'s eight neighbours lie outside the grid, are
/// occupied, or are `unseen` (asked only inside the grid).
fn neighbours_not_free(g: &Grid, x: i32, y: i32, unseen: impl Fn(i32, i32) -> bool) -> u8 {
    let shape = g.shape();
    (-1..=1)
        .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| (dx, dy) != (0, 0))
        .filter(|&(dx, dy)| {
            let (nx, ny) = (x + dx, y + dy);
            !shape.contains(nx, ny) || unseen(nx, ny) || g.is_occupied(Cell::new(nx as u16, ny as u16))
        })
        .count() as u8
}

/// One beam of the brute-force region tests: whether it returned, the cell its end lies in, and how it
/// crosses each cell of the grid (in `all_cells` order).
struct ShotBeam {
    hit: bool,
    end: Option<Cell>,
    crossings: Vec<Crossing>,
    /// Per cell: [`in_graze_zone`].
    grazed: Vec<bool>,
    /// [`across_end`].
    across: Option<[usize; 2]>,
}

impl ShotBeam {
    /// The beam's update of cell `i` (`c`) in the log-odds model of the brute-force tests (the grid's
    /// default increments and bounds, −8 … 24): 8 for the return's cell, 3 less for a crossed cell, but
    /// not below 0 for a grazed cell that held more, unless `face_across` ([`Self::face_across`]).
    fn update(&self, lo: &mut i32, i: usize, c: Cell, face_across: bool) {
        if self.hit && Some(c) == self.end {
            *lo = (*lo + 8).min(24);
        } else if self.crossings[i] == Crossing::Must {
            if !self.grazed[i] || face_across {
                *lo = (*lo - 3).max(-8);
            } else if *lo > 0 {
                *lo = (*lo - 3).max(0);
            }
        }
    }

    /// Whether, in the modelled log-odds before this beam, both of its end's neighbours across it
    /// ([`across_end`]) hold evidence.
    fn face_across(&self, log_odds: &[i32]) -> bool {
        self.across.is_some_and(|pair| pair.iter().all(|&i| log_odds[i] > 0))
    }

    /// Applies the beam to the modelled log-odds of every cell.
    fn apply(&self, log_odds: &mut [i32], shape: GridShape) {
        let face_across = self.face_across(log_odds);
        for (i, c) in all_cells(shape).enumerate() {
            self.update(&mut log_odds[i], i, c, face_across);
        }
    }
}

/// Shoots `beams` random beams into `g` (the first `returning` return with probability ½, the others only miss;
/// with `wall`, four returns in five end in that cell or the one above or below it, a short wall that later
/// returns meet across)
/// and returns them in order. A beam touching a cell only at a corner or along an edge, where either answer
/// would be right, is drawn again.
fn shoot_random_beams(
    g: &mut Grid,
    rng: &mut SmallRng,
    beams: usize,
    returning: usize,
    wall: Option<Cell>,
) -> Vec<ShotBeam> {
    let shape = g.shape();
    let mut changed = Changes::new();
    let mut shot = Vec::with_capacity(beams);
    while shot.len() < beams {
        let (a, mut b) = random_beam(rng, shape);
        let hit = shot.len() < returning && rng.random_range(0..2) == 0;
        if let Some(w) = wall.filter(|_| hit && rng.random_bool(0.8)) {
            b.0 = (f32::from(w.x) + rng.random_range(0.1..0.9)) * CELL_SIZE_M;
            b.1 = (f32::from(w.y) + rng.random_range(-0.9..1.9)) * CELL_SIZE_M;
        }
        let crossings: Vec<Crossing> = all_cells(shape).map(|c| crossing(a, b, c)).collect();
        if crossings.contains(&Crossing::Either) {
            continue;
        }
        g.integrate_beam(a, b, hit, &mut changed);
        let end = shape.cell_at(b.0, b.1);
        shot.push(ShotBeam {
            hit,
            end,
            crossings,
            grazed: all_cells(shape).map(|c| in_graze_zone(a, b, hit, end, c)).collect(),
            across: across_end(shape, a, b, hit, end),
        });
    }
    shot
}

/// `is_unknown` and `is_unobserved_region` against a brute force that knows only the beams' geometry: a
/// cell is unknown exactly when its modelled log-odds ([`ShotBeam::update`], from the exact segment–square
/// test) is 0, i.e. no beam crossed it, or only returning beams' grazed stretches ([`in_graze_zone`]) did,
/// or those took back a hit exactly (a cell with log-odds 0 is never occupied: it leaves the occupied state
/// at 0). Beams touching a cell only at a corner or edge are redrawn (either answer would be right there).
#[test]
fn unknown_cells_and_unobserved_regions_match_brute_force() {
    let mut rng = SmallRng::seed_from_u64(0x0b5e_12ed);
    let mut g = grid(14, 9, 2);
    let shape = g.shape();
    let w = i32::from(shape.width);
    let (mut regions, mut lone_unknown) = (0usize, 0usize);
    for case in 0..400 {
        assert!(g.reset(shape, 2));
        let mut log_odds = vec![0i32; shape.cells()];
        let beams = rng.random_range(0..14);
        for beam in shoot_random_beams(&mut g, &mut rng, beams, 2, None) {
            beam.apply(&mut log_odds, shape);
        }
        let unknown = |x: i32, y: i32| shape.contains(x, y) && log_odds[(y * w + x) as usize] == 0;
        for c in all_cells(shape) {
            let (x, y) = (i32::from(c.x), i32::from(c.y));
            assert_eq!(g.is_unknown(c), unknown(x, y), "case {case}: {c:?}");
            let not_free = neighbours_not_free(&g, x, y, unknown);
            for min in [0u8, 3, 5, 8, 9] {
                let want = unknown(x, y) && not_free >= min;
                assert_eq!(
                    g.is_unobserved_region(c, min),
                    want,
                    "case {case}: {c:?} with {not_free} unknown/occupied/outside neighbours, min {min}"
                );
            }
            regions += usize::from(unknown(x, y) && not_free >= 5);
            lone_unknown += usize::from(unknown(x, y) && not_free < 5);
        }
    }
    // Both outcomes occur often.
    assert!(regions > 1000 && lone_unknown > 100, "{regions} {lone_unknown}");
    // Outside the grid nothing is unknown.
    assert!(!g.is_unknown(Cell::new(14, 0)) && !g.is_unobserved_region(Cell::new(0, 9), 0));
}

/// `is_weakly_observed_region` against a brute force that knows only the beams' geometry: each cell's
/// log-odds is 8 per return that ended in it less 3 per beam that crossed it otherwise (exact segment–square
/// test; a returning beam's grazed stretch only down to 0: [`ShotBeam::update`]), beam by beam within the
/// default bounds −8 … 24. A cell is unseen when it is not occupied and that sum
/// lies above `free_max`; a region when it is unseen and at least `min` of its neighbours are unseen,
/// occupied or outside the grid. With `free_max` −6 a cell one beam crossed (−3) is still unseen, while
/// `is_unobserved_region` calls it free.
#[test]
fn weakly_observed_regions_match_brute_force() {
    let mut rng = SmallRng::seed_from_u64(0x5ee_f12e);
    let mut g = grid(14, 9, 2);
    let shape = g.shape();
    let (mut regions, mut single_miss_regions, mut faces_across) = (0usize, 0usize, 0usize);
    for case in 0..400 {
        assert!(g.reset(shape, 2));
        let mut log_odds = vec![0i32; shape.cells()];
        let beams = rng.random_range(0..9);
        let wall = Cell::new(rng.random_range(0..shape.width), rng.random_range(1..shape.height - 1));
        for beam in shoot_random_beams(&mut g, &mut rng, beams, beams, Some(wall)) {
            faces_across += usize::from(beam.face_across(&log_odds));
            beam.apply(&mut log_odds, shape);
        }
        for c in all_cells(shape) {
            assert_eq!(i32::from(g.log_odds(c)), log_odds[shape.index(c)], "case {case}: {c:?}");
        }
        for free_max in [-6i8, -3, -1] {
            let unseen = |x: i32, y: i32| {
                let c = Cell::new(x as u16, y as u16);
                !g.is_occupied(c) && log_odds[shape.index(c)] > i32::from(free_max)
            };
            for c in all_cells(shape) {
                let (x, y) = (i32::from(c.x), i32::from(c.y));
                let around = neighbours_not_free(&g, x, y, unseen);
                for min in [0u8, 3, 5, 8] {
                    let want = unseen(x, y) && around >= min;
                    assert_eq!(
                        g.is_weakly_observed_region(c, min, free_max),
                        want,
                        "case {case}: {c:?}, log-odds {}, {around} neighbours, min {min}, free at {free_max}",
                        log_odds[shape.index(c)]
                    );
                }
                if free_max == -6 && unseen(x, y) && around >= 5 {
                    regions += 1;
                    if log_odds[shape.index(c)] == -3 && !g.is_unobserved_region(c, 5) {
                        single_miss_regions += 1;
                    }
                }
            }
        }
    }
    // Both the common case and the one the stricter test exists for occur.
    assert!(
        regions > 1000 && single_miss_regions > 100,
        "{regions} {single_miss_regions}"
    );
    println!("{faces_across} returns from a face across the beam");
    assert!(
        faces_across >= 5,
        "only {faces_across} returns met a face across their beam"
    );
    assert!(!g.is_weakly_observed_region(Cell::new(14, 0), 0, -6));
}

/// `is_doubtful_region` against a brute force of its rule over the cells' log-odds after random beams (the
/// log-odds themselves are checked against the beams' geometry by `weakly_observed_regions_match_brute_force`):
/// a cell is unseen when it is not occupied and its log-odds lie above `free_max`, or above
/// `contested_free_max` with a neighbour (inside the grid) whose log-odds lie in 1 ..= 7; a region when it is
/// unseen and at least `min` of its neighbours are unseen, occupied or outside the grid. A cell one beam
/// crossed next to a hit and a miss is the case it exists for.
#[test]
fn doubtful_regions_match_brute_force() {
    let mut rng = SmallRng::seed_from_u64(0xd0b7_f001);
    let mut g = grid(14, 9, 2);
    let shape = g.shape();
    let (mut regions, mut contested_regions) = (0usize, 0usize);
    for case in 0..400 {
        assert!(g.reset(shape, 2));
        let beams = rng.random_range(0..12);
        shoot_random_beams(&mut g, &mut rng, beams, 2, None);
        let log_odds = |x: i32, y: i32| g.log_odds(Cell::new(x as u16, y as u16));
        let contested_next_to = |x: i32, y: i32| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    (dx, dy) != (0, 0) && shape.contains(x + dx, y + dy) && (1..=7).contains(&log_odds(x + dx, y + dy))
                })
            })
        };
        for (free_max, contested_free_max) in [(-1i8, -6i8), (-1, -3), (-3, -8)] {
            let unseen = |x: i32, y: i32| {
                let lo = log_odds(x, y);
                !g.is_occupied(Cell::new(x as u16, y as u16))
                    && (lo > free_max || (lo > contested_free_max && contested_next_to(x, y)))
            };
            for c in all_cells(shape) {
                let (x, y) = (i32::from(c.x), i32::from(c.y));
                let around = neighbours_not_free(&g, x, y, unseen);
                for min in [0u8, 3, 5, 8] {
                    let want = unseen(x, y) && around >= min;
                    assert_eq!(
                        g.is_doubtful_region(c, min, free_max, contested_free_max),
                        want,
                        "case {case}: {c:?}, log-odds {}, {around} neighbours, min {min}, free at {free_max} / {contested_free_max}",
                        log_odds(x, y)
                    );
                }
                if (free_max, contested_free_max) == (-1, -6) && unseen(x, y) && around >= 5 {
                    regions += 1;
                    if !g.is_weakly_observed_region(c, 5, -1) {
                        contested_regions += 1;
                    }
                }
            }
        }
    }
    // Both the common case and the one the contested rule adds occur.
    assert!(
        regions > 1000 && contested_regions > 20,
        "{regions} {contested_regions}"
    );
    assert!(!g.is_doubtful_region(Cell::new(14, 0), 0, -1, -6));
}

/// A wall's end as grazing beams leave it: the end cell holds a hit and a miss (5), the cells around it one
/// miss each (−3). To `is_weakly_observed_region` they were seen free; to `is_doubtful_region` the end is a
/// region, while the same single misses in open space, with no contested cell near, are not.
#[test]
fn a_grazed_wall_end_is_a_doubtful_region() {
    let mut g = grid(20, 12, 2);
    let shape = g.shape();
    // A short beam inside one cell: a hit there, or with no return one miss, and nothing elsewhere.
    let shoot = |g: &mut Grid, x: u16, y: u16, hit: bool| {
        let (cx, cy) = shape.center_of(Cell::new(x, y));
        g.integrate_beam((cx - 0.01, cy), (cx + 0.01, cy), hit, &mut Changes::new());
    };
    let miss = |g: &mut Grid, x: u16, y: u16| shoot(g, x, y, false);
    // The end cell (5, 5): a miss, then a hit.
    miss(&mut g, 5, 5);
    shoot(&mut g, 5, 5, true);
    assert_eq!(g.log_odds(Cell::new(5, 5)), 5);
    assert!(!g.is_occupied(Cell::new(5, 5)));
    for (x, y) in [(4, 4), (5, 4), (6, 4), (4, 5), (6, 5), (4, 6), (5, 6), (6, 6)] {
        miss(&mut g, x, y);
    }
    // The same ring of single misses in open space.
    for (x, y) in [
        (14, 4),
        (15, 4),
        (16, 4),
        (14, 5),
        (15, 5),
        (16, 5),
        (14, 6),
        (15, 6),
        (16, 6),
    ] {
        miss(&mut g, x, y);
    }
    assert!(!g.is_weakly_observed_region(Cell::new(5, 4), 5, -1));
    assert!(g.is_doubtful_region(Cell::new(5, 4), 5, -1, -6));
    assert!(g.is_doubtful_region(Cell::new(5, 5), 5, -1, -6));
    assert!(!g.is_doubtful_region(Cell::new(15, 5), 5, -1, -6));
    // A second miss settles a cell even next to the contested end.
    miss(&mut g, 5, 4);
    assert_eq!(g.log_odds(Cell::new(5, 4)), -6);
    assert!(!g.is_doubtful_region(Cell::new(5, 4), 5, -1, -6));
}

/// A fan of beams from one point leaves one-cell strips between its traces: those are not unobserved
/// regions, while the untouched block beyond the fan's end is.
#[test]
fn gaps_between_beam_traces_are_not_regions() {
    let mut g = grid(20, 20, 0);
    let mut changed = Changes::new();
    // Horizontal beams along every other row (rows 2, 4, …, 16) from x = 0.05 m to 0.5 m (cells 1 … 9):
    // rows 3, 5, … between them stay unknown, each such cell with two unknown neighbours in its row and
    // free cells above and below.
    for row in (2..=16).step_by(2) {
        let y = (f32::from(row as u16) + 0.5) * CELL_SIZE_M;
        g.integrate_beam((0.05 + 0.001, y), (0.5 - 0.001, y), false, &mut changed);
    }
    for row in (3..=15).step_by(2) {
        for x in 2..=8 {
            let c = Cell::new(x, row);
            assert!(g.is_unknown(c), "{c:?}");
            assert!(!g.is_unobserved_region(c, 5), "{c:?} is a gap between traces");
        }
    }
    // Beyond the traces (x ≥ 11) every cell is unknown with unknown neighbours: a region.
    for y in 1..19 {
        for x in 11..19 {
            assert!(g.is_unobserved_region(Cell::new(x, y), 8), "{x} {y}");
        }
    }
}
