//! Path tools: line of sight against an exact geometric oracle, simplification and smoothing invariants.

use cfnav::nav::dstar::{DStarLite, PlanStatus};
use cfnav::nav::map::{CELL_SIZE_M, Cell, GridShape, Traversability};
use cfnav::nav::path::{extract_path, length_m, line_of_sight, simplify, smooth};
use heapless::Vec as HVec;
use host_tests::oracle::{VecMap, path_cost};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Whether the closed unit square of cell `c` meets the segment between the centres of `a` and `b`
/// (Liang–Barsky clipping; all coordinates are half-integers, so f64 is exact here).
fn touches(a: Cell, b: Cell, c: Cell) -> bool {
    let (x0, y0) = (f64::from(a.x) + 0.5, f64::from(a.y) + 0.5);
    let (dx, dy) = (f64::from(b.x) - f64::from(a.x), f64::from(b.y) - f64::from(a.y));
    let (lo_x, hi_x, lo_y, hi_y) = (
        f64::from(c.x),
        f64::from(c.x) + 1.0,
        f64::from(c.y),
        f64::from(c.y) + 1.0,
    );
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [(-dx, x0 - lo_x), (dx, hi_x - x0), (-dy, y0 - lo_y), (dy, hi_y - y0)] {
        if p == 0.0 {
            if q < 0.0 {
                return false;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    t0 <= t1
}

fn random_map(rng: &mut SmallRng, w: u16, h: u16, density: f64) -> VecMap {
    let mut m = VecMap::new(w, h);
    for c in m.cells().collect::<Vec<_>>() {
        m.set(c, rng.random_bool(density));
    }
    m
}

#[test]
fn line_of_sight_matches_geometry() {
    let mut rng = SmallRng::seed_from_u64(3);
    let mut checked = 0;
    for _ in 0..300 {
        let density = rng.random_range(0.0..0.15);
        let map = random_map(&mut rng, 20, 16, density);
        for _ in 0..50 {
            let a = Cell::new(rng.random_range(0..20), rng.random_range(0..16));
            let b = Cell::new(rng.random_range(0..20), rng.random_range(0..16));
            let oracle = map.cells().filter(|c| map.get(*c)).all(|c| !touches(a, b, c));
            assert_eq!(line_of_sight(&map, a, b), oracle, "{a:?} -> {b:?}");
            checked += 1;
        }
    }
    assert!(checked == 15_000);
}

#[test]
fn simplified_paths_keep_sight_and_shorten() {
    let mut rng = SmallRng::seed_from_u64(9);
    let mut tested = 0;
    for _ in 0..400 {
        let density = rng.random_range(0.0..0.3);
        let map = random_map(&mut rng, 40, 30, density);
        let free: Vec<Cell> = map.cells().filter(|c| !map.get(*c)).collect();
        if free.len() < 2 {
            continue;
        }
        let (s, g) = (
            free[rng.random_range(0..free.len())],
            free[rng.random_range(0..free.len())],
        );
        let mut p: Box<DStarLite<1200, 1200>> = Box::new(DStarLite::new());
        p.reset(map.shape(), s, g).unwrap();
        if !matches!(p.compute(&map, u32::MAX).unwrap(), PlanStatus::Found { .. }) {
            continue;
        }
        let mut path = HVec::<Cell, 1200>::new();
        extract_path(&*p, &map, &mut path).unwrap();
        assert!(path_cost(&map, &path).is_some());
        let mut way = HVec::<Cell, 1200>::new();
        assert!(simplify(&map, &path, &mut way));
        assert_eq!(way.first(), path.first());
        assert_eq!(way.last(), path.last());
        // A subsequence of the path, each leg in sight.
        let mut i = 0;
        for w in &way {
            while path[i] != *w {
                i += 1;
            }
        }
        for leg in way.windows(2) {
            assert!(line_of_sight(&map, leg[0], leg[1]));
        }
        let poly: f32 = way
            .windows(2)
            .map(|l| {
                let (dx, dy) = (
                    f32::from(l[0].x) - f32::from(l[1].x),
                    f32::from(l[0].y) - f32::from(l[1].y),
                );
                (dx * dx + dy * dy).sqrt() * CELL_SIZE_M
            })
            .sum();
        assert!(poly <= length_m(&path) + 1e-4);
        // Smoothing keeps every point of the polyline in free cells.
        let pts: Vec<(f32, f32)> = way.iter().map(|c| map.shape().center_of(*c)).collect();
        let mut smoothed = HVec::<(f32, f32), 2400>::new();
        assert!(smooth(&map, &pts, &mut smoothed));
        assert_eq!(smoothed.first(), pts.first());
        assert_eq!(smoothed.last(), pts.last());
        for seg in smoothed.windows(2) {
            for k in 0..=40 {
                let t = k as f32 / 40.0;
                let (x, y) = (
                    seg[0].0 + (seg[1].0 - seg[0].0) * t,
                    seg[0].1 + (seg[1].1 - seg[0].1) * t,
                );
                let c = map.shape().cell_at(x, y).expect("inside");
                assert!(
                    !map.is_blocked(i32::from(c.x), i32::from(c.y)),
                    "smoothed point in a blocked cell"
                );
            }
        }
        tested += 1;
    }
    assert!(tested > 200, "{tested}");
}

#[test]
fn open_space_path_collapses_to_one_leg() {
    let map = VecMap::new(30, 20);
    let mut p: Box<DStarLite<600, 600>> = Box::new(DStarLite::new());
    p.reset(GridShape { width: 30, height: 20 }, Cell::new(1, 1), Cell::new(25, 12))
        .unwrap();
    p.compute(&map, u32::MAX).unwrap();
    let mut path = HVec::<Cell, 600>::new();
    extract_path(&*p, &map, &mut path).unwrap();
    let mut way = HVec::<Cell, 600>::new();
    simplify(&map, &path, &mut way);
    assert_eq!(way.as_slice(), &[Cell::new(1, 1), Cell::new(25, 12)]);
}

#[test]
fn tiny_buffers_report_truncation() {
    let map = VecMap::new(30, 20);
    let mut p: Box<DStarLite<600, 600>> = Box::new(DStarLite::new());
    p.reset(GridShape { width: 30, height: 20 }, Cell::new(1, 1), Cell::new(25, 1))
        .unwrap();
    p.compute(&map, u32::MAX).unwrap();
    let mut path = HVec::<Cell, 4>::new();
    let s = extract_path(&*p, &map, &mut path).unwrap();
    assert!(!s.complete);
    assert_eq!(s.cost, 30);
    assert_eq!(path.len(), 4);
}
