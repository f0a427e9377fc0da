//! The map-relative localization per Multi-ranger sweep, in exact Cortex-M4 instructions (this file is the
//! localization's section of the benchmark): the navigator's half (`cast_fixes`: four grid walks against
//! the occupancy grid, thread mode) and the stabilizer's half (`Estimator::on_map_fixes`: up to four gated
//! scalar updates, the control executor), as `src/stack.rs` runs them.
//!
//! Scenario: the firmware's grid (120 × 60 cells, 6 × 3 m), a box face mapped and confirmed across the
//! drone's path 2.3 m ahead (x = 4.3 m); the drone hovers at (2.0, 1.5) m with a heading of 0.2 rad, so the
//! front beam walks 2.35 m (≈ 50 cells across both axes) to the box, the back one 2.04 m to the x = 0
//! wall, the side ones 1.53 m to the y walls: four fixes per sweep, each walk near the 2.5 m bound. The
//! estimator is calibrated at rest and airborne, as in the estimator benchmark; the box's face is settled
//! as a landmark before the measured sweeps, by sweeps from seven points 5 cm apart along y, so that its
//! beams meet more than `LANDMARK_MIN_EXTENT_CELLS` rows of it (every measured sweep matches it among the
//! landmarks).
//!
//! Output: `map_fix_cast_instructions_{median,p90,max}`, `map_fix_update_instructions_{median,p90,max}`
//! over 20 sweeps, `map_fix_fused=`.

use cfnav::flight::estimator::map_fix::{
    CONFIRMED_LOG_ODDS, LANDMARK_MIN_EXTENT_CELLS, LANDMARK_SETTLE, Landmarks, RayGrid, cast_fixes,
};
use cfnav::nav::grid::{ChangedCells, OccupancyGrid};
use cfnav::nav::map::{ARENA_CELLS, CELL_SIZE_M, Cell, GridShape};
use cfnav::types::MultiRangerSample;
use cortex_m_semihosting::hprintln;
use qemu_bench::{IMU_AT_REST, Meter, STILL_FLOW, estimator_calibrated_at_rest, summarize};

const SWEEPS: usize = 20;

fn print(name: &str, values: &mut [u32]) {
    let s = summarize(values);
    hprintln!("{}_median={}", name, s.median);
    hprintln!("{}_p90={}", name, s.p90);
    hprintln!("{}_max={}", name, s.max);
}

/// Runs the scenario (see the module documentation).
pub fn map_fix_bench(meter: &mut impl Meter) -> Result<(), ()> {
    let Some(shape) = GridShape::new(120, 60, ARENA_CELLS) else {
        hprintln!("error=map_fix_grid_shape");
        return Err(());
    };
    let mut map: OccupancyGrid<ARENA_CELLS> = OccupancyGrid::new();
    if !map.reset(shape, 4) {
        hprintln!("error=map_fix_grid_reset");
        return Err(());
    }
    let mut changed: ChangedCells<512> = ChangedCells::new();
    // The box's face: column 86 (4.30–4.35 m), rows 20–43 (1.0–2.2 m).
    for y in 20..44 {
        map.set_occupied(Cell::new(86, y), &mut changed);
    }
    let grid = RayGrid {
        width: 120,
        height: 60,
        cell_m: CELL_SIZE_M,
        arena_m: (6.0, 3.0),
        walls: cfnav::mission::ALL_WALLS,
    };
    let (x, y, yaw) = (2.0f32, 1.5f32, 0.2f32);
    // cos(0.2 rad).
    let c = 0.980_066_6f32;
    let sweep = MultiRangerSample {
        front_m: Some((4.3 - x) / c),
        back_m: Some(x / c),
        left_m: Some((3.0 - y) / c),
        right_m: Some(y / c),
        up_m: None,
    };

    let Some(mut est) = estimator_calibrated_at_rest([x, y, 0.0], yaw) else {
        hprintln!("error=map_fix_estimator_not_calibrated");
        return Err(());
    };

    let confirmed = |cx: i32, cy: i32| map.log_odds(Cell::new(cx as u16, cy as u16)) >= CONFIRMED_LOG_ODDS;
    let occupied = |cx: i32, cy: i32| shape.contains(cx, cy) && map.is_occupied(Cell::new(cx as u16, cy as u16));
    // The box's face becomes a landmark over its first sweeps (no fix from the front beam meanwhile),
    // from points along y so that the front beam meets seven of its rows.
    let mut landmarks = Landmarks::new();
    let points = (LANDMARK_SETTLE as i16).max(LANDMARK_MIN_EXTENT_CELLS) + 1;
    for k in 0..points {
        let y_k = y + f32::from(k - points / 2) * CELL_SIZE_M;
        let _ = cast_fixes(&grid, &sweep, [x, y_k], yaw, &mut landmarks, confirmed, occupied);
    }
    let mut cast_counts = [0u32; SWEEPS];
    let mut update_counts = [0u32; SWEEPS];
    for run in 0..SWEEPS {
        // One simulated tenth of a second between sweeps (flow and height keep the filter as in flight).
        for k in 0..100u32 {
            est.on_imu(&IMU_AT_REST, 0.001);
            if k % 10 == 0 {
                est.on_flow(&STILL_FLOW);
            }
            if k % 25 == 0 {
                est.on_zrange(Some(0.5));
            }
        }
        let p = est.state().position_m;
        let (fixes, n) =
            meter.measure(|| cast_fixes(&grid, &sweep, [p[0], p[1]], yaw, &mut landmarks, confirmed, occupied));
        cast_counts[run] = n;
        if fixes.fixes.iter().any(Option::is_none) {
            hprintln!("error=map_fix_missing_fix");
            return Err(());
        }
        let ((), n) = meter.measure(|| est.on_map_fixes(&fixes));
        update_counts[run] = n;
    }
    let fused = est.diagnostics().map_fused;
    if fused != 4 * SWEEPS as u32 {
        hprintln!("error=map_fix_fused {} of {}", fused, 4 * SWEEPS);
        return Err(());
    }
    hprintln!("map_fix_fused={}", fused);
    print("map_fix_cast_instructions", &mut cast_counts);
    print("map_fix_update_instructions", &mut update_counts);
    Ok(())
}
