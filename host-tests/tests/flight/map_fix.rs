//! Map-relative localization (`cfnav::flight::estimator::map_fix`): the ray cast against an independent
//! geometric oracle (ray against axis-aligned rectangles and the arena's walls), the fixes a sweep gives
//! (exact distances along the normal, incidence and outlier rules), the landmark rules against the real
//! occupancy grid (a face's plane placed from where beams ended, fixes only from a settled landmark long
//! enough to be a face, no ratchet between the fixes and the map writes), and the whole
//! mission against the simulator's ground truth with the fixes on and off.

use cfnav::flight::estimator::map_fix::{
    CONFIRMED_LOG_ODDS, FACE_END_MAX_DIFFERENCE_M, LANDMARK_MIN_EXTENT_CELLS, LANDMARK_SETTLE, Landmarks,
    MAX_WALL_INCIDENCE_RAD, PRE_GATE_M, RayGrid, cast_fixes, ray_cast,
};
use cfnav::flight::estimator::{Estimator, EstimatorConfig};
use cfnav::nav::grid::{ChangedCells, OccupancyGrid};
use cfnav::nav::map::{CELL_SIZE_M, Cell, GridShape};
use cfnav::stack::{FlightConfig, FlightCore};
use cfnav::types::MultiRangerSample;
use cfnav_sim::world::World;
use cfnav_tools::sim::runner::{Faults, SimDrone, mission_params};
use proptest::prelude::*;

/// A rectangle of whole cells `[x0, x1) × [y0, y1)` (cell indices).
#[derive(Clone, Copy, Debug)]
struct Rect {
    x0: i32,
    y0: i32,
    x1: i32,
    y1: i32,
}

impl Rect {
    fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x0 && x < self.x1 && y >= self.y0 && y < self.y1
    }
}

/// Oracle: where the ray `o + t·u` first enters the rectangle (slab method, f64), with the axis of the
/// face it enters by; `None` if it misses or starts inside.
fn ray_rect(o: (f64, f64), u: (f64, f64), r: &Rect, s: f64) -> Option<(f64, usize)> {
    let lo = [f64::from(r.x0) * s, f64::from(r.y0) * s];
    let hi = [f64::from(r.x1) * s, f64::from(r.y1) * s];
    let (o, u) = ([o.0, o.1], [u.0, u.1]);
    let (mut t_in, mut t_out, mut axis) = (f64::NEG_INFINITY, f64::INFINITY, 0);
    for a in 0..2 {
        if u[a].abs() < 1e-12 {
            if o[a] < lo[a] || o[a] >= hi[a] {
                return None;
            }
            continue;
        }
        let (t0, t1) = ((lo[a] - o[a]) / u[a], (hi[a] - o[a]) / u[a]);
        let (near, far) = (t0.min(t1), t0.max(t1));
        if near > t_in {
            t_in = near;
            axis = a;
        }
        t_out = t_out.min(far);
    }
    (t_in <= t_out && t_in > 0.0).then_some((t_in, axis))
}

/// Oracle: the distance to the arena's walls `[0, a.0] × [0, a.1]` from inside, and the wall's axis.
fn ray_walls(o: (f64, f64), u: (f64, f64), a: (f64, f64)) -> (f64, usize) {
    let mut best = (f64::INFINITY, 0);
    for (axis, (p, d, size)) in [(o.0, u.0, a.0), (o.1, u.1, a.1)].into_iter().enumerate() {
        if d.abs() < 1e-12 {
            continue;
        }
        let t = if d > 0.0 { (size - p) / d } else { -p / d };
        if t < best.0 {
            best = (t, axis);
        }
    }
    best
}

fn rect_strategy(w: i32, h: i32) -> impl Strategy<Value = Rect> {
    // Kept two cells away from the walls: the ray cast treats a cell next to a wall as that wall's trace.
    (2..w - 4, 2..h - 4, 1i32..8, 1i32..8).prop_map(move |(x0, y0, dx, dy)| Rect {
        x0,
        y0,
        x1: (x0 + dx).min(w - 2),
        y1: (y0 + dy).min(h - 2),
    })
}

const W: i32 = 60;
const H: i32 = 40;

fn arena() -> RayGrid {
    RayGrid {
        width: W,
        height: H,
        cell_m: CELL_SIZE_M,
        arena_m: (W as f32 * CELL_SIZE_M, H as f32 * CELL_SIZE_M),
        walls: cfnav::mission::ALL_WALLS,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// The ray cast finds the nearest of the rectangles or the wall, at the oracle's distance (within
    /// float rounding), entering by the oracle's face, with the plane through the entered cell's centre.
    #[test]
    fn ray_cast_matches_rectangles_and_walls(
        rects in prop::collection::vec(rect_strategy(W, H), 0..5),
        ox in 0.05f64..2.95,
        oy in 0.05f64..1.95,
        angle in -3.2f64..3.2,
        max_m in 0.3f32..3.5,
    ) {
        let s = f64::from(CELL_SIZE_M);
        prop_assume!(!rects.iter().any(|r| r.contains((ox / s).floor() as i32, (oy / s).floor() as i32)));
        let u = (angle.cos(), angle.sin());
        let grid = arena();
        let hit = ray_cast(&grid, (ox as f32, oy as f32), (u.0 as f32, u.1 as f32), max_m, |x, y| {
            assert!((0..W).contains(&x) && (0..H).contains(&y), "asked outside the grid: {x}, {y}");
            rects.iter().any(|r| r.contains(x, y))
        });
        let nearest_rect = rects
            .iter()
            .filter_map(|r| ray_rect((ox, oy), u, r, s))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let (t_wall, wall_axis) = ray_walls((ox, oy), u, (f64::from(W) * s, f64::from(H) * s));
        let expected = match nearest_rect {
            Some((t, axis)) if t < t_wall => Some((t, axis, false)),
            _ => Some((t_wall, wall_axis, true)),
        }
        .filter(|(t, _, _)| *t < f64::from(max_m));
        match (hit, expected) {
            (None, None) => {}
            (Some(h), Some((t, axis, wall))) => {
                prop_assert!((f64::from(h.distance_m) - t).abs() < 1e-3, "{h:?} vs {t}");
                prop_assert_eq!(h.wall, wall, "{:?} vs {}", h, t);
                // At a corner (both faces within rounding) either axis is right.
                let corner = {
                    let p = (ox + t * u.0, oy + t * u.1);
                    let near = |v: f64| (v / s - (v / s).round()).abs() < 1e-3;
                    near(p.0) && near(p.1)
                };
                if !corner {
                    prop_assert_eq!(h.axis, axis, "{:?}", h);
                }
                let v = [u.0, u.1][h.axis];
                prop_assert_eq!(h.sign, if v > 0.0 { 1.0 } else { -1.0 });
                if wall {
                    let far = if h.axis == 0 { f64::from(W) * s } else { f64::from(H) * s };
                    prop_assert!((f64::from(h.plane_m) - if v > 0.0 { far } else { 0.0 }).abs() < 1e-5, "{:?}", h);
                } else {
                    let (cx, cy) = h.cell;
                    prop_assert!(rects.iter().any(|r| r.contains(cx, cy)));
                    let c = if h.axis == 0 { cx } else { cy };
                    prop_assert!((f64::from(h.plane_m) - (f64::from(c) + 0.5) * s).abs() < 1e-5);
                }
            }
            (h, e) => prop_assert!(false, "cast {h:?}, oracle {e:?} (t_wall {t_wall}, max {max_m})"),
        }
    }

    /// In an empty arena, every beam square enough to a wall gives a fix whose measured distance equals
    /// the expected one (exact ranges) and whose expected distance is the oracle's distance to that wall
    /// along its normal; a beam more oblique than the limit gives none.
    #[test]
    fn fixes_in_an_empty_room_are_exact(
        x in 0.4f32..2.6,
        y in 0.4f32..1.6,
        yaw in -3.2f32..3.2,
    ) {
        let grid = arena();
        let sample = exact_sweep(&grid, &[], (x, y), yaw);
        let fixes = cast_fixes(&grid, &sample, [x, y], yaw, &mut Landmarks::new(), |_, _| false, |_, _| false);
        let offsets = [0.0, std::f32::consts::PI, std::f32::consts::FRAC_PI_2, -std::f32::consts::FRAC_PI_2];
        for (beam, fix) in fixes.fixes.iter().enumerate() {
            let a = f64::from(yaw + offsets[beam]);
            let u = (a.cos(), a.sin());
            let (t, axis) = ray_walls((f64::from(x), f64::from(y)), u, (3.0, 2.0));
            let cos_inc = [u.0, u.1][axis].abs();
            // The arena's exact walls allow more incidence than an obstacle's face (the heading fixes).
            let usable = t <= 2.5 && cos_inc >= f64::from(MAX_WALL_INCIDENCE_RAD).cos() + 1e-4;
            let too_oblique = cos_inc < f64::from(MAX_WALL_INCIDENCE_RAD).cos() - 1e-4;
            match fix {
                Some(f) => {
                    prop_assert!(!too_oblique, "beam {beam}: {f:?}");
                    prop_assert!((f.measured_m - f.expected_m).abs() < 1e-4, "{f:?}");
                    prop_assert!((f64::from(f.expected_m) - t * cos_inc).abs() < 1e-4, "{f:?} vs {}", t * cos_inc);
                    prop_assert!(f.std_m > 0.0 && f.std_m < 0.06);
                    // The heading's lever: d/d(yaw) of the range times |n·u| at the fixed range.
                    let along = |a: f64| [a.cos(), a.sin()][axis].abs();
                    let lever = t * (along(a + 1e-4) - along(a - 1e-4)) / 2e-4;
                    prop_assert!((f64::from(f.yaw_lever_m) - lever).abs() < 2e-3, "{f:?} vs lever {lever}");
                }
                None => prop_assert!(!usable, "beam {beam} gave no fix at {t} m, cos {cos_inc}"),
            }
        }
    }
}

/// Exact ranges of a sweep at `p`, heading `yaw`, in `grid`'s arena holding `rects` (`None` beyond 4 m).
fn exact_sweep(grid: &RayGrid, rects: &[Rect], p: (f32, f32), yaw: f32) -> MultiRangerSample {
    let s = f64::from(grid.cell_m);
    let a = (f64::from(grid.arena_m.0), f64::from(grid.arena_m.1));
    let range = |offset: f32| {
        let ang = f64::from(yaw + offset);
        let u = (ang.cos(), ang.sin());
        let o = (f64::from(p.0), f64::from(p.1));
        let t = rects
            .iter()
            .filter_map(|r| ray_rect(o, u, r, s))
            .map(|(t, _)| t)
            .fold(ray_walls(o, u, a).0, f64::min);
        (t <= 4.0).then_some(t as f32)
    };
    use std::f32::consts::{FRAC_PI_2, PI};
    MultiRangerSample {
        front_m: range(0.0),
        back_m: range(PI),
        left_m: range(FRAC_PI_2),
        right_m: range(-FRAC_PI_2),
        up_m: None,
    }
}

#[test]
fn an_unmapped_object_in_front_of_a_wall_gives_no_fix() {
    let grid = arena();
    // The front beam reads 0.5 m short of the wall (something the map does not hold): beyond the pre-gate.
    let (x, y) = (1.5, 1.0);
    let mut sample = exact_sweep(&grid, &[], (x, y), 0.0);
    sample.front_m = sample.front_m.map(|r| r - (PRE_GATE_M + 0.2));
    let fixes = cast_fixes(
        &grid,
        &sample,
        [x, y],
        0.0,
        &mut Landmarks::new(),
        |_, _| false,
        |_, _| false,
    );
    assert!(fixes.fixes[0].is_none(), "{:?}", fixes.fixes[0]);
    assert!(fixes.fixes[1].is_some() && fixes.fixes[2].is_some() && fixes.fixes[3].is_some());
}

/// A beam that ends well short of the wall the cast reaches, beside a cell an earlier sweep hit, met that
/// object, not the wall (world 368 001 203: a cylinder in front of the west wall, whose every sweep read
/// the same shortfall and so "confirmed" a 19 cm jump). The drone at (1.5, 1.025) m faces the east wall
/// (x = 3 m); its front beam reads 0.22 m short. Without an earlier hit near its end the beam gives a fix
/// (a drift it could be); with one sweep's hit a row beside its end it gives none; hits of the wall itself
/// (its trace, within a cell of the plane) do not count, so a real drift towards a mapped wall still gives
/// its fix.
#[test]
fn a_short_beam_that_ends_beside_an_earlier_hit_gives_no_fix() {
    let (x, y) = (1.5, 1.025);
    let mut sample = exact_sweep(&arena(), &[], (x, y), 0.0);
    let true_range = sample.front_m.unwrap();
    sample.front_m = Some(true_range - 0.22);
    // Nothing mapped: the beam's shortfall is a fix (within the pre-gate).
    let (mut map, shape) = empty_map();
    let fix = cast_on(&map, shape, &sample, [x, y], &mut Landmarks::new()).fixes[0].expect("a fix");
    assert!((fix.expected_m - fix.measured_m - 0.22).abs() < 1e-3, "{fix:?}");
    // The wall's own trace (an earlier sweep's hit in the last cell before x = 3 m, a row beside): still a fix.
    let mut changed: ChangedCells<64> = ChangedCells::new();
    map.integrate_beam((x, 1.075), (2.99, 1.075), true, &mut changed);
    assert!(map.is_occupied(Cell::new(59, 21)));
    assert!(cast_on(&map, shape, &sample, [x, y], &mut Landmarks::new()).fixes[0].is_some());
    // One earlier sweep met the object a row beside this beam's end (x = 2.78 m): no fix.
    map.integrate_beam((x, 0.975), (x + true_range - 0.22, 0.975), true, &mut changed);
    assert!(map.is_occupied(Cell::new(55, 19)));
    let fixes = cast_on(&map, shape, &sample, [x, y], &mut Landmarks::new());
    assert!(fixes.fixes[0].is_none(), "{:?}", fixes.fixes[0]);
    // The other beams (to the side walls and the west wall, read exactly) keep their fixes.
    assert!(fixes.fixes[1].is_some() && fixes.fixes[2].is_some() && fixes.fixes[3].is_some());
}

#[test]
fn bad_input_gives_no_fix() {
    let grid = arena();
    let sample = exact_sweep(&grid, &[], (1.5, 1.0), 0.0);
    for (p, yaw) in [
        ([f32::NAN, 1.0], 0.0),
        ([1.5, 1.0], f32::INFINITY),
        ([-1.0, 1.0], 0.0),
        ([9.0, 1.0], 0.0),
    ] {
        let fixes = cast_fixes(&grid, &sample, p, yaw, &mut Landmarks::new(), |_, _| true, |_, _| true);
        assert!(fixes.is_empty(), "{p:?} {yaw}: {fixes:?}");
    }
    let mut weird = sample;
    weird.front_m = Some(f32::NAN);
    weird.back_m = Some(-1.0);
    weird.left_m = Some(f32::INFINITY);
    weird.right_m = Some(1e30);
    assert!(
        cast_fixes(
            &grid,
            &weird,
            [1.5, 1.0],
            0.0,
            &mut Landmarks::new(),
            |_, _| false,
            |_, _| false
        )
        .is_empty()
    );
    assert!(ray_cast(&grid, (1.0, 1.0), (0.0, 0.0), 2.0, |_, _| true).is_none());
    assert!(ray_cast(&grid, (1.0, 1.0), (f32::NAN, 1.0), 2.0, |_, _| true).is_none());
}

type Map = OccupancyGrid<{ (W * H) as usize }>;

fn empty_map() -> (Map, GridShape) {
    let shape = GridShape::new(W as u16, H as u16, (W * H) as usize).unwrap();
    let mut map: Map = OccupancyGrid::new();
    assert!(map.reset(shape, 2));
    (map, shape)
}

/// `cast_fixes` against the real grid, as the navigator calls it.
fn cast_on(
    map: &Map,
    shape: GridShape,
    sample: &MultiRangerSample,
    p: [f32; 2],
    landmarks: &mut Landmarks,
) -> cfnav::flight::estimator::map_fix::MapFixes {
    let cell = |x: i32, y: i32| Cell::new(x as u16, y as u16);
    cast_fixes(
        &arena(),
        sample,
        p,
        0.0,
        landmarks,
        |x, y| map.log_odds(cell(x, y)) >= CONFIRMED_LOG_ODDS,
        |x, y| shape.contains(x, y) && map.is_occupied(cell(x, y)),
    )
}

/// Writes the front beam `range` from `x` into the map along the `2·half_rows + 1` rows around `y` (one
/// sweep's hits on a straight face, log-odds 8 at each row's end cell).
fn write_face(map: &mut Map, x: f32, y: f32, range: f32, half_rows: i32) {
    for j in -half_rows..=half_rows {
        let mut changed: ChangedCells<64> = ChangedCells::new();
        let dy = j as f32 * CELL_SIZE_M;
        map.integrate_beam((x, y + dy), (x + range, y + dy), true, &mut changed);
    }
}

/// The centre of the `k`-th row from 1.025 m (whole cells: no beam runs along a cell boundary).
fn row_centre(k: i32) -> f32 {
    1.025 + k as f32 * CELL_SIZE_M
}

/// The box of the landmark tests: its face at x = 2.0 m (cells 40..44 × 10..30).
const BOX: Rect = Rect {
    x0: 40,
    y0: 10,
    x1: 44,
    y1: 30,
};

/// The landmark rules on the real occupancy grid. Nothing mapped: no fix and no landmark. One earlier
/// sweep's hits (log-odds 8; the caller casts before it writes, so never the same sweep's) locate the
/// face; then `LANDMARK_SETTLE` beams place its plane (no fix yet). Beams that all meet one row give no
/// fix however many there are (a cylinder's flank looks like that); the first beam that stretches the rows
/// met to `LANDMARK_MIN_EXTENT_CELLS` gives one, against the plane where the beams ended (2.0 m), not the
/// cell's centre (2.025 m).
#[test]
fn a_face_gives_fixes_once_its_landmark_is_settled_and_long_enough() {
    let (mut map, shape) = empty_map();
    let x = 1.2;
    let sample_at = |k: i32| exact_sweep(&arena(), &[BOX], (x, row_centre(k)), 0.0);
    let range = sample_at(0).front_m.unwrap();
    assert!((range - 0.8).abs() < 1e-4);
    let mut landmarks = Landmarks::new();
    let cast = |k: i32, landmarks: &mut Landmarks, map: &Map| {
        cast_on(map, shape, &sample_at(k), [x, row_centre(k)], landmarks).fixes[0]
    };
    assert!(cast(0, &mut landmarks, &map).is_none());
    assert_eq!(landmarks.iter().count(), 0, "nothing mapped, no landmark");
    // One pass of the drone along the face; the hits land just inside the face's cells (a hair long).
    let extent = LANDMARK_MIN_EXTENT_CELLS as i32;
    write_face(&mut map, x, row_centre(0), range + 0.01, extent);
    let face = Cell::new(40, 20);
    assert!(map.log_odds(face) >= CONFIRMED_LOG_ODDS && map.log_odds(face) < 16);
    for k in 0..2 * LANDMARK_SETTLE {
        let f = cast(0, &mut landmarks, &map);
        assert!(f.is_none(), "beam {k}, all at one row: no fix: {f:?}");
    }
    assert_eq!(landmarks.iter().count(), 1);
    assert!(landmarks.iter().all(|l| l.seen >= LANDMARK_SETTLE));
    for k in 1..extent - 1 {
        let f = cast(k, &mut landmarks, &map);
        assert!(f.is_none(), "rows 0..={k} met, fewer than {extent}: no fix: {f:?}");
    }
    let fix = cast(extent - 1, &mut landmarks, &map).expect("a settled face met over enough rows gives a fix");
    assert!((fix.expected_m - 0.8).abs() < 1e-4, "{fix:?}");
    assert!((fix.measured_m - 0.8).abs() < 1e-4, "{fix:?}");
    assert!(fix.std_m > 0.005 && fix.std_m < 0.03, "{fix:?}");
    let l = landmarks.iter().next().unwrap();
    assert_eq!((l.axis, l.sign), (0, 1));
    assert!((l.plane_m - 2.0).abs() < 1e-4, "{l:?}");
    assert_eq!(landmarks.iter().count(), 1, "one face, one landmark");
}

/// When all `MAX_LANDMARKS` slots are taken, a new landmark replaces an unsettled one, never a settled one
/// while an unsettled one is left: the faces found on the way out must still hold on the way back. A 50 m
/// tall arena with one long face at x = 2.0 m; the front beam from x = 1.2 m meets it at rows 8 cells apart
/// (beyond the join distance), so each row is a landmark of its own. Row 10 settles first; then
/// `MAX_LANDMARKS` + 10 other rows are met once each (unsettled): row 10's landmark survives them all, and
/// the slots hold the newest of the others.
#[test]
fn a_new_landmark_replaces_an_unsettled_one_first() {
    use cfnav::flight::estimator::map_fix::{LANDMARK_GAP_CELLS, MAX_LANDMARKS};
    let grid = RayGrid {
        width: 120,
        height: 1000,
        cell_m: CELL_SIZE_M,
        arena_m: (6.0, 50.0),
        walls: cfnav::mission::ALL_WALLS,
    };
    let face = |x: i32, _y: i32| x == 40;
    let spacing = 8;
    assert!(spacing > LANDMARK_GAP_CELLS as i32 + 1);
    // Rows from 10 on: a cell within half a cell of the wall y = 0 is the wall's own trace.
    let beam_at = |k: i32, landmarks: &mut Landmarks| {
        let y = ((10 + k * spacing) as f32 + 0.5) * CELL_SIZE_M;
        let sample = MultiRangerSample {
            front_m: Some(0.8),
            ..MultiRangerSample::default()
        };
        cast_fixes(&grid, &sample, [1.2, y], 0.0, landmarks, face, face)
    };
    let mut landmarks = Landmarks::new();
    for _ in 0..LANDMARK_SETTLE {
        assert!(beam_at(0, &mut landmarks).is_empty());
    }
    let others = MAX_LANDMARKS as i32 + 10;
    for k in 1..=others {
        assert!(beam_at(k, &mut landmarks).is_empty());
    }
    assert_eq!(landmarks.iter().count(), MAX_LANDMARKS);
    let first = landmarks
        .iter()
        .find(|l| l.along == (10, 10))
        .expect("the settled landmark is kept");
    assert!(
        first.seen >= LANDMARK_SETTLE && (first.plane_m - 2.0).abs() < 1e-4,
        "{first:?}"
    );
    let mut rows: Vec<i16> = landmarks.iter().filter(|l| l.along.0 > 10).map(|l| l.along.0).collect();
    rows.sort_unstable();
    let newest: Vec<i16> = ((others - MAX_LANDMARKS as i32 + 2)..=others)
        .map(|k| (10 + k * spacing) as i16)
        .collect();
    assert_eq!(rows, newest, "the unsettled slots hold the newest rows");
}

/// A face's last cell (one neighbour along it mapped, not both) gives a fix only for a small difference:
/// the map smears a surface's end and a cylinder's flank looks straight for a few cells, so a beam there
/// reading far from the plane may have passed the end or met the curve behind it. Inside the face the same
/// difference is an estimate error and gives a fix. The face: eleven rows (15–25) of cells at x = 2.0 m.
#[test]
fn a_face_end_gives_a_fix_only_near_the_plane() {
    let (mut map, shape) = empty_map();
    let x = 1.2;
    // A pass maps the face (rows 1.025 ± 0.25 m), then beams across it place the landmark and stretch it.
    let centre = row_centre(0);
    let range = exact_sweep(&arena(), &[BOX], (x, centre), 0.0).front_m.unwrap();
    write_face(&mut map, x, centre, range + 0.01, 5);
    let mut landmarks = Landmarks::new();
    for k in -5..=5 {
        let exact = exact_sweep(&arena(), &[BOX], (x, row_centre(k)), 0.0);
        cast_on(&map, shape, &exact, [x, row_centre(k)], &mut landmarks);
    }
    assert!(
        landmarks
            .iter()
            .all(|l| l.seen >= LANDMARK_SETTLE && l.along == (15, 25))
    );
    let row = |y: f32| (y / CELL_SIZE_M) as u16;
    assert!(map.is_occupied(Cell::new(40, row(1.275))) && !map.is_occupied(Cell::new(40, row(1.325))));
    // From 1.2 m the beams read `long` further than the plane: the drone is that much nearer x = 0 than
    // the estimate says, or the beam met something else behind the face's plane.
    let fix_at = |y: f32, long: f32, landmarks: &mut Landmarks| {
        let mut sample = exact_sweep(&arena(), &[BOX], (x, y), 0.0);
        sample.front_m = Some(range + long);
        cast_on(&map, shape, &sample, [x, y], landmarks).fixes[0]
    };
    let small = 0.5 * FACE_END_MAX_DIFFERENCE_M;
    let large = FACE_END_MAX_DIFFERENCE_M + 0.02;
    for (y, what) in [(1.025, "the face's middle"), (1.075, "inside the face")] {
        for long in [small, large] {
            let fix = fix_at(y, long, &mut landmarks).unwrap_or_else(|| panic!("{what}, {long} m long: a fix"));
            assert!((fix.measured_m - fix.expected_m - long).abs() < 1e-4, "{fix:?}");
        }
    }
    // The last row: the small difference is a fix, the large one none.
    let end = row_centre(5);
    let fix = fix_at(end, small, &mut landmarks).expect("the end, a small difference: a fix");
    assert!((fix.measured_m - fix.expected_m - small).abs() < 1e-4, "{fix:?}");
    assert!(
        fix_at(end, large, &mut landmarks).is_none(),
        "the end, {large} m long: no fix"
    );
    assert!(
        fix_at(end, -large, &mut landmarks).is_none(),
        "the end, {large} m short: no fix"
    );
}

/// No self-reinforcing loop: a drone flies to and fro along a box's face, 0.8 m from it, with noisy
/// ranges and, every sweep, first corrects its estimate with the fixes and then writes the beam into the
/// map from the corrected estimate (what the navigator and the stabilizer do together). Over 400 sweeps,
/// most of them fixes, the estimate stays at the truth. With the plane through the first confirmed cell's
/// centre instead of a frozen landmark this loop ratchets: the nearest of the cells the noisy hits
/// straddle gets confirmed, its centre lies nearer than the surface, the fix moves the estimate back, the
/// next hits confirm a nearer cell, and the estimate walks away from the wall (the default world's noise
/// seed 14 crept 21 cm that way).
#[test]
fn fixes_and_map_writes_do_not_ratchet() {
    use rand::{Rng, SeedableRng, rngs::SmallRng};
    for seed in 0..5u64 {
        let mut rng = SmallRng::seed_from_u64(seed);
        let (mut map, shape) = empty_map();
        let mut landmarks = Landmarks::new();
        let x_true = 1.2f32;
        let mut late: Vec<f32> = Vec::new();
        let mut x_est = x_true;
        let mut worst = 0.0f32;
        let mut fixed = 0;
        for k in 0..400 {
            // Rows −6..=5 and back: 0.6 m of the face, one row per sweep.
            let step = k % 24;
            let y = row_centre(if step < 12 { step - 6 } else { 17 - step });
            let mut sample = exact_sweep(&arena(), &[BOX], (x_true, y), 0.0);
            let noise = |rng: &mut SmallRng, r: f32| {
                let g: f32 = (0..12).map(|_| rng.random::<f32>()).sum::<f32>() - 6.0;
                r + (0.003 + 0.01 * r) * g
            };
            sample.front_m = sample.front_m.map(|r| noise(&mut rng, r));
            sample.back_m = None;
            let fixes = cast_on(&map, shape, &sample, [x_est, y], &mut landmarks);
            if let Some(f) = fixes.fixes[0] {
                // A scalar filter with a fixed gain along the normal (+x): p += −n·k·innovation.
                x_est -= 0.3 * (f.measured_m - f.expected_m);
                fixed += 1;
            }
            write_face(&mut map, x_est, y, sample.front_m.unwrap(), 0);
            worst = worst.max((x_est - x_true).abs());
            if k >= 300 {
                late.push(x_est - x_true);
            }
        }
        // The fixes' own noise (gain 0.3, ≈ 1.1 cm per range) and the landmark's placement error move the
        // estimate by a centimetre or two; a ratchet walks on by a cell per few sweeps.
        let mean_late = late.iter().sum::<f32>() / late.len() as f32;
        assert!(fixed > 300, "seed {seed}: only {fixed} of 400 sweeps gave a fix");
        assert!(
            worst < 0.04,
            "seed {seed}: the estimate walked {worst} m from the truth"
        );
        assert!(
            mean_late.abs() < 0.015,
            "seed {seed}: mean error over the last 100 sweeps {mean_late} m"
        );
    }
}

/// The estimator's side: a fix within the gate moves the estimate along the normal by part of the
/// innovation; one far outside is rejected and changes nothing.
#[test]
fn the_estimator_gates_fixes() {
    use cfnav::flight::estimator::map_fix::{MapFix, MapFixes};
    let mut est = airborne_estimator(EstimatorConfig::default());
    let before = est.state().position_m;
    let fix = |measured: f32| MapFixes {
        fixes: [
            Some(MapFix {
                normal: [1.0, 0.0],
                measured_m: measured,
                expected_m: 1.0,
                std_m: 0.01,
                yaw_lever_m: 0.0,
            }),
            None,
            None,
            None,
        ],
    };
    // Measured 2 m to the +x wall, expected 1 m: the estimate would be 1 m off, far beyond 3σ.
    est.on_map_fixes(&fix(2.0));
    assert_eq!(est.diagnostics().map_rejected, 1);
    assert_eq!(est.state().position_m, before);
    // Measured 1 cm farther than expected: the drone is 1 cm further from the wall (towards −x).
    est.on_map_fixes(&fix(1.01));
    assert_eq!(est.diagnostics().map_fused, 1);
    let moved = est.state().position_m[0] - before[0];
    assert!(moved < -0.001 && moved > -0.0101, "moved {moved}");
    assert!((est.state().position_m[1] - before[1]).abs() < 1e-3);
    // Switched off: nothing.
    let mut off = airborne_estimator(EstimatorConfig {
        map_fix: false,
        ..EstimatorConfig::default()
    });
    off.on_map_fixes(&fix(1.01));
    assert_eq!(off.diagnostics().map_fused + off.diagnostics().map_rejected, 0);
}

/// An estimator calibrated at rest at (1, 1), yaw 0, then told it flies (also the heading tests').
pub(crate) fn airborne_estimator(cfg: EstimatorConfig) -> Estimator {
    use cfnav::types::ImuSample;
    let mut est = Estimator::new(cfg);
    est.reset([1.0, 1.0, 0.0], 0.0);
    let still = ImuSample {
        gyro_rad_s: [0.0; 3],
        accel_m_s2: [0.0, 0.0, cfnav::types::GRAVITY_M_S2],
    };
    for _ in 0..1200 {
        est.on_imu(&still, 0.001);
    }
    assert!(est.is_calibrated());
    est.set_flying(true);
    est.on_imu(&still, 0.001);
    est
}

/// Flies the default world's mission with `config` and returns the horizontal estimate error (estimate
/// minus truth) sampled every 10 ms while the drone is above 0.2 m, with the time, and the outcome.
fn mission_errors(config: &FlightConfig, seed: u64) -> (Vec<(f64, f32)>, cfnav::mission::MissionState) {
    let world = World::default_world();
    let mut drone = SimDrone::new(&world, seed, &Faults::default()).unwrap();
    let start = world.mission.start;
    *drone.core = FlightCore::new(config, (start[0], start[1]), 0.0).unwrap();
    let mut errors = Vec::new();
    let mut started = false;
    for tick in 0..120_000u64 {
        if tick == 1000 {
            drone.core.start_mission(mission_params(&world)).expect("starts");
            started = true;
        }
        drone.step(&world);
        if started && tick.is_multiple_of(10) {
            let truth = drone.quad.position();
            let est = drone.core.estimate().position_m;
            if truth[2] > 0.2 {
                errors.push((tick as f64 * 1e-3, (est[0] - truth[0]).hypot(est[1] - truth[1])));
            }
            if !drone.core.mission().is_running() {
                break;
            }
        }
    }
    (errors, drone.core.mission_state())
}

/// The headline: over the default world's whole mission the horizontal drift stops growing once the
/// walls are mapped. With the map fixes the RMS of the estimate error over the mission and its error over
/// the last 20 airborne seconds stay small; with them switched off (everything else equal) the same seeds
/// drift as the flow's random walk does. The bound sits between the two (measured: see BENCHMARKS.md §5,
/// "map-relative localization").
#[test]
fn map_fixes_stop_the_drift_over_a_mission() {
    let on = FlightConfig::default();
    let mut off = FlightConfig::default();
    off.estimator.map_fix = false;
    let summary = |config: &FlightConfig| {
        let mut rms_all = Vec::new();
        let mut late_max = Vec::new();
        for seed in [3, 7, 11] {
            let (errors, state) = mission_errors(config, seed);
            assert!(!errors.is_empty(), "seed {seed}: never airborne ({state:?})");
            let rms = (errors.iter().map(|(_, e)| e * e).sum::<f32>() / errors.len() as f32).sqrt();
            let end = errors.last().unwrap().0;
            let late = errors
                .iter()
                .filter(|(t, _)| *t > end - 20.0)
                .map(|(_, e)| *e)
                .fold(0.0f32, f32::max);
            println!(
                "seed {seed}: {state:?}, RMS {:.1} cm, max over the last 20 s {:.1} cm",
                rms * 100.0,
                late * 100.0
            );
            rms_all.push(rms);
            late_max.push(late);
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        (mean(&rms_all), mean(&late_max))
    };
    let (rms_on, late_on) = summary(&on);
    let (rms_off, late_off) = summary(&off);
    println!(
        "with fixes: RMS {:.1} cm, late max {:.1} cm; without: {:.1} / {:.1} cm",
        rms_on * 100.0,
        late_on * 100.0,
        rms_off * 100.0,
        late_off * 100.0
    );
    assert!(rms_on <= 0.035, "with the map fixes the mean RMS is {rms_on}");
    assert!(late_on <= 0.06, "with the map fixes the late error is {late_on}");
    assert!(rms_off > 0.035 || late_off > 0.06, "without: {rms_off} / {late_off}");
}

/// Open sides (`mission.walls`): for every bitmask, a ray that leaves the empty arena through a side with
/// its bit is a wall hit at the oracle's distance, and one through an open side reaches nothing; a
/// confirmed cell along an open side is an obstacle like any other (no wall's trace to skip), while along
/// a wall it is skipped for the exact wall.
#[test]
fn open_sides_give_no_wall_and_keep_their_border_cells() {
    use cfnav::mission::wall_bit;
    let s = f64::from(CELL_SIZE_M);
    let size = (f64::from(W) * s, f64::from(H) * s);
    let mut hits = [0u32; 2];
    for walls in 0..16u8 {
        let grid = RayGrid { walls, ..arena() };
        for k in 0..72 {
            let angle = f64::from(k) * std::f64::consts::TAU / 72.0 + 0.01;
            let u = (angle.cos(), angle.sin());
            for &(ox, oy) in &[(0.4, 0.3), (1.5, 1.0), (2.7, 1.7)] {
                let hit = ray_cast(&grid, (ox as f32, oy as f32), (u.0 as f32, u.1 as f32), 3.5, |_, _| {
                    false
                });
                let (t, axis) = ray_walls((ox, oy), u, size);
                let positive = [u.0, u.1][axis] > 0.0;
                let wall = walls & wall_bit(axis, positive) != 0;
                match hit {
                    Some(h) => {
                        assert!(wall && t < 3.5, "mask {walls}: hit {h:?} through an open side");
                        assert!(h.wall && (f64::from(h.distance_m) - t).abs() < 1e-3, "{h:?} vs {t}");
                        hits[0] += 1;
                    }
                    None => {
                        assert!(!wall || t >= 3.5, "mask {walls}: no hit at {t} m on a wall");
                        hits[1] += 1;
                    }
                }
            }
        }
    }
    assert!(hits[0] > 1000 && hits[1] > 1000, "both cases exercised: {hits:?}");
    // The last column (x = 2.95–3.0 m) holds a confirmed cell in row 20: square to the east side.
    let border = |x: i32, y: i32| x == W - 1 && y == 20;
    let o = (2.0, 20.5 * CELL_SIZE_M);
    let walled = ray_cast(&arena(), o, (1.0, 0.0), 2.0, border).unwrap();
    assert!(
        walled.wall && (walled.distance_m - 1.0).abs() < 1e-4,
        "wall trace skipped: {walled:?}"
    );
    let open_east = RayGrid {
        walls: 15 & !wall_bit(0, true),
        ..arena()
    };
    let cell = ray_cast(&open_east, o, (1.0, 0.0), 2.0, border).unwrap();
    assert!(
        !cell.wall && cell.cell == (W - 1, 20) && (cell.distance_m - 0.95).abs() < 1e-4,
        "{cell:?}"
    );
}

/// Localization uses only the walls that exist: behind an open east side, 5 cm beyond the arena's edge,
/// stands something the beam reads (a skirting board, the next room's furniture). Told the east side is a
/// wall, the front beam gives a fix 5 cm off that the estimator fuses (a pull on the estimate towards −x);
/// told it is open, that beam gives no fix, the other three walls' fixes are unchanged, and the estimate
/// does not move.
#[test]
fn a_missing_wall_gives_no_fix_and_does_not_pull_the_estimate() {
    let (x, y) = (1.0f32, 1.0f32);
    let walled = arena();
    let open_east = RayGrid {
        walls: 15 & !cfnav::mission::WALL_EAST,
        ..arena()
    };
    let mut sample = exact_sweep(&walled, &[], (x, y), 0.0);
    // The arena ends at x = 3 m; the surface the front beam meets is at 3.05 m.
    sample.front_m = Some(3.05 - x);
    let cast = |grid: &RayGrid| {
        cast_fixes(
            grid,
            &sample,
            [x, y],
            0.0,
            &mut Landmarks::new(),
            |_, _| false,
            |_, _| false,
        )
    };
    let (all, open) = (cast(&walled), cast(&open_east));
    let wrong = all.fixes[0].expect("against the supposed east wall");
    assert!((wrong.measured_m - wrong.expected_m - 0.05).abs() < 1e-4, "{wrong:?}");
    assert!(open.fixes[0].is_none(), "{:?}", open.fixes[0]);
    assert_eq!(&all.fixes[1..], &open.fixes[1..], "the other walls' fixes");
    assert!(open.fixes[1..].iter().all(Option::is_some));
    // Through the estimator (at (1, 1), yaw 0, airborne): only the supposed wall moves x.
    let shift = |fixes| {
        let mut est = airborne_estimator(EstimatorConfig::default());
        let before = est.state().position_m;
        est.on_map_fixes(&fixes);
        let d = est.diagnostics();
        (est.state().position_m[0] - before[0], d.map_fused, d.map_rejected)
    };
    let (pulled, fused_all, _) = shift(all);
    let (kept, fused_open, rejected_open) = shift(open);
    assert!(pulled < -0.005, "the supposed wall pulls x by {pulled}");
    assert_eq!((fused_all, fused_open, rejected_open), (4, 3, 0));
    assert!(kept.abs() < 1e-5, "no east wall, no pull along x: {kept}");
}
