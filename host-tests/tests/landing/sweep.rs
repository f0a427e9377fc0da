//! Lawnmower sweep generator tests: coverage, start corner, arena margin, axis choice, errors.

use cfnav::landing::sweep::{ArenaBounds, LawnmowerSweep, Rect, SweepAxis, SweepConfig, SweepError};
use proptest::prelude::*;

type Sweep = LawnmowerSweep;

const ARENA: ArenaBounds = ArenaBounds::new(6.0, 3.0, 0.2);

fn seg_dist(p: (f32, f32), a: (f32, f32), b: (f32, f32)) -> f32 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (qx, qy) = (a.0 + t * dx, a.1 + t * dy);
    ((p.0 - qx).powi(2) + (p.1 - qy).powi(2)).sqrt()
}

fn dist_to_path(p: (f32, f32), path: &[(f32, f32)]) -> f32 {
    path.windows(2)
        .map(|w| seg_dist(p, w[0], w[1]))
        .fold(f32::INFINITY, f32::min)
}

/// The largest distance from any point of `area` (a 1 cm grid including the border) to the path.
fn worst_gap(area: Rect, path: &[(f32, f32)]) -> f32 {
    let nx = ((area.max_x - area.min_x) / 0.01).ceil() as usize;
    let ny = ((area.max_y - area.min_y) / 0.01).ceil() as usize;
    let mut worst = 0.0f32;
    for i in 0..=nx {
        for j in 0..=ny {
            let x = (area.min_x + i as f32 * 0.01).min(area.max_x);
            let y = (area.min_y + j as f32 * 0.01).min(area.max_y);
            worst = worst.max(dist_to_path((x, y), path));
        }
    }
    worst
}

/// The four corners of a pass (its extreme waypoints).
fn pass_corners(pass: &[(f32, f32)]) -> [(f32, f32); 4] {
    let min_x = pass.iter().map(|p| p.0).fold(f32::INFINITY, f32::min);
    let max_x = pass.iter().map(|p| p.0).fold(f32::NEG_INFINITY, f32::max);
    let min_y = pass.iter().map(|p| p.1).fold(f32::INFINITY, f32::min);
    let max_y = pass.iter().map(|p| p.1).fold(f32::NEG_INFINITY, f32::max);
    [(min_x, min_y), (max_x, min_y), (min_x, max_y), (max_x, max_y)]
}

fn dist(a: (f32, f32), b: (f32, f32)) -> f32 {
    ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt()
}

#[test]
fn default_sweep_layout() {
    let s: Sweep = LawnmowerSweep::new((3.0, 1.5), (0.5, 0.5), &SweepConfig::default(), &ARENA).unwrap();
    assert_eq!(s.lines_per_pass(), [5, 5]);
    assert_eq!(s.len(), 20);
    assert_eq!(s.first_pass_len(), 10);
    assert!(s.first_pass_along_x(), "a square sweeps along x");
    for sp in s.line_spacing() {
        assert!((sp - 0.2).abs() < 1e-5, "{sp}");
    }
    // Drone at the lower left: start at the lower-left corner, first line at y = 1.0 + 0.1.
    let first = s.waypoint(0).unwrap();
    assert!(
        (first.0 - 2.5).abs() < 1e-5 && (first.1 - 1.1).abs() < 1e-5,
        "{first:?}"
    );
    // Lines along x at y = 1.1, 1.3, …, 1.9, alternating direction.
    let wps = s.waypoints();
    for k in 0..5 {
        let (a, b) = (wps[2 * k], wps[2 * k + 1]);
        assert!((a.1 - (1.1 + 0.2 * k as f32)).abs() < 1e-5 && (a.1 - b.1).abs() < 1e-6);
        assert!((a.0 - b.0).abs() > 0.99, "a full-width line");
        if k > 0 {
            assert!(
                (a.0 - wps[2 * k - 1].0).abs() < 1e-6,
                "each line starts where the last ended"
            );
        }
    }
    // Second pass along y, starting at the corner nearest the end of the first.
    let end = wps[9];
    let second = &wps[10..];
    assert!(
        second.chunks(2).all(|l| (l[0].0 - l[1].0).abs() < 1e-6),
        "second pass along y"
    );
    let nearest = pass_corners(second)
        .iter()
        .map(|c| dist(*c, end))
        .fold(f32::INFINITY, f32::min);
    assert!((dist(second[0], end) - nearest).abs() < 1e-6);
    // Accessors agree.
    assert_eq!(s.iter().collect::<Vec<_>>(), wps.to_vec());
    assert_eq!((&s).into_iter().count(), s.len());
    assert!(s.waypoint(s.len()).is_none());
    assert!(!s.is_empty());
}

#[test]
fn start_is_the_corner_nearest_the_drone_in_every_quadrant() {
    let centre = (3.0, 1.5);
    for (sx, sy) in [(-1.0f32, -1.0f32), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        for crosshatch in [false, true] {
            let cfg = SweepConfig {
                crosshatch,
                ..SweepConfig::default()
            };
            let drone = (centre.0 + sx * 2.0, centre.1 + sy * 1.0);
            let s: Sweep = LawnmowerSweep::new(centre, drone, &cfg, &ARENA).unwrap();
            let first = s.waypoint(0).unwrap();
            assert_eq!((first.0 - centre.0).signum(), sx, "quadrant {sx},{sy}: {first:?}");
            assert_eq!((first.1 - centre.1).signum(), sy, "quadrant {sx},{sy}: {first:?}");
            let pass = &s.waypoints()[..s.first_pass_len()];
            let nearest = pass_corners(pass)
                .iter()
                .map(|c| dist(*c, drone))
                .fold(f32::INFINITY, f32::min);
            assert!((dist(first, drone) - nearest).abs() < 1e-6);
        }
    }
}

#[test]
fn auto_axis_runs_lines_along_the_longer_side() {
    let wide = SweepConfig {
        size_x_m: 1.0,
        size_y_m: 0.5,
        crosshatch: false,
        ..SweepConfig::default()
    };
    let s: Sweep = LawnmowerSweep::new((3.0, 1.5), (3.0, 1.5), &wide, &ARENA).unwrap();
    assert!(s.first_pass_along_x());
    assert_eq!(s.lines_per_pass(), [3, 0]);
    let tall = SweepConfig {
        size_x_m: 0.5,
        size_y_m: 1.0,
        ..wide
    };
    let s: Sweep = LawnmowerSweep::new((3.0, 1.5), (3.0, 1.5), &tall, &ARENA).unwrap();
    assert!(!s.first_pass_along_x());
    assert_eq!(s.lines_per_pass(), [3, 0]);
    let forced = SweepConfig {
        axis: SweepAxis::AlongY,
        ..wide
    };
    let s: Sweep = LawnmowerSweep::new((3.0, 1.5), (3.0, 1.5), &forced, &ARENA).unwrap();
    assert!(!s.first_pass_along_x());
    assert_eq!(s.lines_per_pass(), [5, 0]);
    let forced = SweepConfig {
        axis: SweepAxis::AlongX,
        ..tall
    };
    let s: Sweep = LawnmowerSweep::new((3.0, 1.5), (3.0, 1.5), &forced, &ARENA).unwrap();
    assert!(s.first_pass_along_x());
    assert_eq!(s.lines_per_pass(), [5, 0]);
}

#[test]
fn clipped_to_the_arena_margin() {
    // Goal in the lower-left corner: the 1 × 1 m area is cut to [0.2, 0.5] × [0.2, 0.5].
    let s: Sweep = LawnmowerSweep::new((0.0, 0.0), (1.0, 1.0), &SweepConfig::default(), &ARENA).unwrap();
    let a = s.area();
    assert_eq!((a.min_x, a.min_y), (0.2, 0.2));
    assert!((a.max_x - 0.5).abs() < 1e-6 && (a.max_y - 0.5).abs() < 1e-6);
    assert_eq!(s.lines_per_pass(), [2, 2]);
    assert!(
        s.iter()
            .all(|(x, y)| (0.2..=0.5).contains(&x) && (0.2..=0.5).contains(&y))
    );
    assert!(worst_gap(a, s.waypoints()) <= 0.1 + 1e-4);
}

#[test]
fn invalid_parameters_are_errors() {
    let ok = SweepConfig::default();
    let c = (3.0, 1.5);
    let new = |cfg: &SweepConfig, centre: (f32, f32), drone: (f32, f32), arena: &ArenaBounds| {
        LawnmowerSweep::<64>::new(centre, drone, cfg, arena).map(|s| s.len())
    };
    assert_eq!(
        new(&SweepConfig { spacing_m: 0.0, ..ok }, c, c, &ARENA),
        Err(SweepError::NonPositiveSpacing)
    );
    assert_eq!(
        new(&SweepConfig { spacing_m: -0.2, ..ok }, c, c, &ARENA),
        Err(SweepError::NonPositiveSpacing)
    );
    assert_eq!(
        new(
            &SweepConfig {
                spacing_m: f32::NAN,
                ..ok
            },
            c,
            c,
            &ARENA
        ),
        Err(SweepError::NonFinite)
    );
    assert_eq!(
        new(
            &SweepConfig {
                size_x_m: f32::INFINITY,
                ..ok
            },
            c,
            c,
            &ARENA
        ),
        Err(SweepError::NonFinite)
    );
    assert_eq!(new(&ok, (f32::NAN, 1.0), c, &ARENA), Err(SweepError::NonFinite));
    assert_eq!(
        new(&ok, c, (1.0, f32::NEG_INFINITY), &ARENA),
        Err(SweepError::NonFinite)
    );
    assert_eq!(
        new(&SweepConfig { size_y_m: 0.0, ..ok }, c, c, &ARENA),
        Err(SweepError::InvalidSize)
    );
    assert_eq!(
        new(&ok, c, c, &ArenaBounds::new(6.0, 3.0, -0.1)),
        Err(SweepError::InvalidSize)
    );
    assert_eq!(
        new(&ok, c, c, &ArenaBounds::new(6.0, 0.3, 0.2)),
        Err(SweepError::InvalidSize)
    );
    assert_eq!(new(&ok, (9.0, 1.5), c, &ARENA), Err(SweepError::OutsideArena));
    // Too many lines: 1 m at 1 cm is 100 lines per pass.
    assert!(matches!(
        new(&SweepConfig { spacing_m: 0.01, ..ok }, c, c, &ARENA),
        Err(SweepError::TooManyWaypoints { capacity: 64, .. })
    ));
    // Absurdly small spacing: still an error, no overflow.
    assert!(matches!(
        new(&SweepConfig { spacing_m: 1e-30, ..ok }, c, c, &ARENA),
        Err(SweepError::TooManyWaypoints { .. })
    ));
    // Exactly at capacity: 16 lines × 2 waypoints × 2 passes = 64.
    let tight = SweepConfig {
        spacing_m: 1.0 / 16.0,
        ..ok
    };
    assert_eq!(new(&tight, c, c, &ARENA), Ok(64));
    assert!(matches!(
        LawnmowerSweep::<63>::new(c, c, &tight, &ARENA),
        Err(SweepError::TooManyWaypoints { .. })
    ));
}

fn finite_setup() -> impl Strategy<Value = ((f32, f32), (f32, f32), SweepConfig)> {
    (
        (-0.5f32..6.5, -0.5f32..3.5),
        (-1.0f32..7.0, -1.0f32..4.0),
        (0.2f32..2.0, 0.2f32..2.0, 0.1f32..0.4),
        prop_oneof![Just(SweepAxis::Auto), Just(SweepAxis::AlongX), Just(SweepAxis::AlongY)],
        any::<bool>(),
    )
        .prop_map(|(centre, drone, (sx, sy, spacing), axis, crosshatch)| {
            (
                centre,
                drone,
                SweepConfig {
                    size_x_m: sx,
                    size_y_m: sy,
                    spacing_m: spacing,
                    axis,
                    crosshatch,
                },
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, failure_persistence: None, ..ProptestConfig::default() })]

    /// Every point of the (clipped) area is within spacing/2 of the first pass (and so of the whole path);
    /// every waypoint keeps the margin; the first waypoint is the pattern corner nearest the drone.
    #[test]
    fn covers_the_area_inside_the_margin((centre, drone, cfg) in finite_setup()) {
        let sweep = LawnmowerSweep::<64>::new(centre, drone, &cfg, &ARENA);
        let s = match sweep {
            Ok(s) => s,
            // A centre too far outside the arena, or more lines than the capacity (2 m at 0.1 m crosshatched
            // needs 80 waypoints), may fail here; nothing else.
            Err(SweepError::TooManyWaypoints { needed, capacity }) => {
                prop_assert!(needed > capacity);
                return Ok(());
            }
            Err(e) => {
                prop_assert_eq!(e, SweepError::OutsideArena);
                return Ok(());
            }
        };
        let m = ARENA.margin_m;
        for (x, y) in s.iter() {
            prop_assert!(x >= m - 1e-5 && x <= ARENA.width_m - m + 1e-5, "x {}", x);
            prop_assert!(y >= m - 1e-5 && y <= ARENA.height_m - m + 1e-5, "y {}", y);
            prop_assert!(s.area().contains(x, y, 1e-5));
        }
        let first_pass = &s.waypoints()[..s.first_pass_len()];
        let gap = worst_gap(s.area(), first_pass);
        prop_assert!(gap <= 0.5 * cfg.spacing_m + 1e-3, "gap {} spacing {}", gap, cfg.spacing_m);
        if cfg.crosshatch {
            let second = &s.waypoints()[s.first_pass_len()..];
            prop_assert!(worst_gap(s.area(), second) <= 0.5 * cfg.spacing_m + 1e-3);
            prop_assert_eq!(s.first_pass_along_x(), second.chunks(2).all(|l| (l[0].0 - l[1].0).abs() < 1e-6));
        }
        let nearest = pass_corners(first_pass).iter().map(|c| dist(*c, drone)).fold(f32::INFINITY, f32::min);
        prop_assert!((dist(s.waypoints()[0], drone) - nearest).abs() < 1e-5);
        for sp in s.line_spacing().iter().take(if cfg.crosshatch { 2 } else { 1 }) {
            prop_assert!(*sp <= cfg.spacing_m * (1.0 + 1e-3) && *sp > 0.0);
        }
    }

    /// Any input, finite or not: an answer, never a panic.
    #[test]
    fn never_panics(
        c in (any::<f32>(), any::<f32>()),
        d in (any::<f32>(), any::<f32>()),
        size in (any::<f32>(), any::<f32>(), any::<f32>()),
        arena in (any::<f32>(), any::<f32>(), any::<f32>()),
    ) {
        let cfg = SweepConfig { size_x_m: size.0, size_y_m: size.1, spacing_m: size.2, ..SweepConfig::default() };
        let arena = ArenaBounds::new(arena.0, arena.1, arena.2);
        if let Ok(s) = LawnmowerSweep::<16>::new(c, d, &cfg, &arena) {
            prop_assert!(s.len() <= 16 && !s.is_empty());
            prop_assert!(s.iter().all(|(x, y)| x.is_finite() && y.is_finite()));
        }
    }
}

#[test]
fn memory_size() {
    let size = std::mem::size_of::<Sweep>();
    eprintln!("LawnmowerSweep (N = 64): {size} bytes");
    assert!(size <= 600, "{size} bytes");
}
