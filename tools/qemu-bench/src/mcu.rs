//! The bare-metal benchmark: exact instruction counts from QEMU's `-icount shift=10` virtual clock.
//!
//! Method (shared/reference/toolchain.md §5.3): with `-icount shift=10` every guest instruction advances
//! QEMU's virtual clock by exactly 2¹⁰ ns, and the CMSDK APB timer 0 of mps2-an386 counts down at 25 MHz of
//! that clock, i.e. 25.6 ticks per instruction. A region's instruction count is its tick difference / 25.6,
//! rounded: a read quantises time to one tick (1/25.6 of an instruction), so the rounding is exact. The reads
//! themselves cost a constant number of instructions, measured on an empty region and subtracted. Before
//! measuring anything the program proves the method exact: `N` inline `nop`s must read as `N` + that same
//! constant for every `N`, and so must a counted loop of three million instructions; otherwise it fails (as it
//! does without `-icount`, where the clock is the host's).
//!
//! Output: one `key=value` line per value (summaries) or per event (`replan …`, `box …`, `calib …`), through
//! semihosting; exit status 0, or 1 on any error (planner error, no path, inexact calibration, panic, fault).

use core::arch::asm;
use core::mem::size_of;
use core::panic::PanicInfo;
use core::sync::atomic::{Ordering, compiler_fence};

use cfnav::nav::dstar::ArenaPlanner;
use cfnav::nav::grid::OccupancyGrid;
use cfnav::nav::map::ARENA_CELLS;
use cortex_m_semihosting::{debug, hprintln};
use qemu_bench::{
    BOX_CELLS, IMU_AT_REST, MAX_STEPS, Meter, Report, SEED_MAP, SENSE_RADIUS, STILL_FLOW, Step, Summary, WALLS_AT_1M,
    World, estimator_calibrated_at_rest, run, summarize,
};

/// The CMSDK APB timer 0 of mps2-an386, clocked at 25 MHz.
mod timer0 {
    const BASE: usize = 0x4000_0000;
    const CTRL: *mut u32 = BASE as *mut u32;
    const VALUE: *mut u32 = (BASE + 0x4) as *mut u32;
    const RELOAD: *mut u32 = (BASE + 0x8) as *mut u32;

    /// Start the timer free-running down from `u32::MAX` (wraps after 2³² ticks = 167 M instructions; a
    /// measured region must be shorter, which the wrapping difference then handles).
    pub fn start() {
        // SAFETY: CTRL, RELOAD and VALUE are the documented 32-bit registers of CMSDK APB timer 0, mapped at
        // 0x4000_0000 on mps2-an386; nothing else in this program uses the timer, its interrupt stays disabled
        // (CTRL bit 3 = 0), and aligned volatile word writes are how the device is programmed.
        unsafe {
            CTRL.write_volatile(0);
            RELOAD.write_volatile(u32::MAX);
            VALUE.write_volatile(u32::MAX);
            CTRL.write_volatile(1);
        }
    }

    /// The current count (counts down).
    #[inline(always)]
    pub fn value() -> u32 {
        // SAFETY: VALUE is a readable 32-bit register of the timer (see `start`); reading it has no side effect.
        unsafe { VALUE.read_volatile() }
    }
}

/// Virtual timer ticks per instruction × 10: 25 MHz × 1024 ns = 25.6.
const TICKS_PER_INSTRUCTION_X10: u64 = 256;

/// Instructions of a tick count: ticks / 25.6, rounded to nearest.
fn instructions(ticks: u32) -> u32 {
    ((u64::from(ticks) * 10 + TICKS_PER_INSTRUCTION_X10 / 2) / TICKS_PER_INSTRUCTION_X10) as u32
}

/// Run `f` between two timer reads; its result and the elapsed ticks.
///
/// Never inlined, so that the compiler cannot schedule instructions of the caller's surrounding code between the
/// reads (it did, one `movs`, when this was inlined); `f` itself is inlined into each instance.
#[inline(never)]
fn ticks_of<R>(f: impl FnOnce() -> R) -> (R, u32) {
    compiler_fence(Ordering::SeqCst);
    let t0 = timer0::value();
    compiler_fence(Ordering::SeqCst);
    let r = f();
    compiler_fence(Ordering::SeqCst);
    let t1 = timer0::value();
    compiler_fence(Ordering::SeqCst);
    (r, t0.wrapping_sub(t1))
}

/// Exact instruction counts, net of the calibrated cost of the two timer reads.
struct Icount {
    overhead: u32,
}

impl Meter for Icount {
    #[inline(always)]
    fn measure<R>(&mut self, f: impl FnOnce() -> R) -> (R, u32) {
        let (r, ticks) = ticks_of(f);
        (r, instructions(ticks).saturating_sub(self.overhead))
    }
}

/// `N` `nop` instructions.
#[inline(always)]
fn nops<const N: usize>() {
    // SAFETY: `nop`s touch no register, flag or memory.
    unsafe { asm!(".rept {n}", "nop", ".endr", n = const N, options(nostack, preserves_flags)) }
}

/// Iterations of [`counted_loop`]: 2²⁰ is a Thumb-2 modified immediate, so it loads in one `mov.w`.
const LOOP_ITERATIONS: u32 = 1 << 20;
/// Instructions of [`counted_loop`]: the `mov.w`, then `nop`, `subs`, `bne` per iteration.
const LOOP_INSTRUCTIONS: u32 = 1 + 3 * LOOP_ITERATIONS;

/// A loop of exactly [`LOOP_INSTRUCTIONS`] instructions, about the size of a first plan.
#[inline(always)]
fn counted_loop() {
    // SAFETY: register-only code: it clobbers one scratch register (declared) and the flags (not preserved).
    unsafe {
        asm!(
            "mov.w {r}, #{n}",
            "2:",
            "nop",
            "subs {r}, {r}, #1",
            "bne 2b",
            r = out(reg) _,
            n = const LOOP_ITERATIONS,
            options(nostack),
        )
    }
}

/// Check that instruction counts are exact; the meter's overhead, or `None` when they are not.
fn calibrate() -> Option<u32> {
    let mut empty = [0u32; 3];
    for e in &mut empty {
        *e = instructions(ticks_of(|| ()).1);
    }
    let overhead = empty[0];
    let mut exact = empty.iter().all(|&e| e == overhead);
    hprintln!(
        "calib region=empty runs=3 instructions={},{},{} overhead={}",
        empty[0],
        empty[1],
        empty[2],
        overhead
    );
    let mut check = |name: &str, expected: u32, ticks: u32| {
        let measured = instructions(ticks);
        let delta = i64::from(measured) - i64::from(expected);
        let ok = delta == i64::from(overhead);
        exact &= ok;
        hprintln!(
            "calib region={} expected={} ticks={} instructions={} delta={} exact={}",
            name,
            expected,
            ticks,
            measured,
            delta,
            u8::from(ok)
        );
    };
    for _ in 0..2 {
        check("nops", 1, ticks_of(nops::<1>).1);
        check("nops", 2, ticks_of(nops::<2>).1);
        check("nops", 3, ticks_of(nops::<3>).1);
        check("nops", 10, ticks_of(nops::<10>).1);
        check("nops", 100, ticks_of(nops::<100>).1);
        check("nops", 1000, ticks_of(nops::<1000>).1);
        check("nops", 4096, ticks_of(nops::<4096>).1);
    }
    check("loop", LOOP_INSTRUCTIONS, ticks_of(counted_loop).1);
    hprintln!("calib_overhead={}", overhead);
    hprintln!("calib_exact={}", u8::from(exact));
    exact.then_some(overhead)
}

fn print_summary(name: &str, s: Summary) {
    hprintln!("{}_median={}", name, s.median);
    hprintln!("{}_p90={}", name, s.p90);
    hprintln!("{}_max={}", name, s.max);
}

/// Summaries of one field over some steps.
fn summary_of<'a>(steps: impl Iterator<Item = &'a Step>, field: fn(&Step) -> u32) -> Summary {
    let mut values = [0u32; MAX_STEPS];
    let mut n = 0;
    for (slot, step) in values.iter_mut().zip(steps) {
        *slot = field(step);
        n += 1;
    }
    summarize(&mut values[..n])
}

fn bench() -> Result<(), ()> {
    hprintln!(
        "bench=qemu-bench target=cortex-m4 machine=mps2-an386 planner=ArenaPlanner cells={}",
        ARENA_CELLS
    );
    hprintln!("method=icount_shift10_cmsdk_timer0 ticks_per_instruction=25.6");
    timer0::start();
    let Some(overhead) = calibrate() else {
        hprintln!("error=calibration_not_exact (run under qemu-system-arm -M mps2-an386 -icount shift=10)");
        return Err(());
    };

    let mut world = match World::parse(SEED_MAP) {
        Ok(w) => w,
        Err(e) => {
            hprintln!("error=map {:?}", e);
            return Err(());
        }
    };
    let mut planner = ArenaPlanner::new();
    let mut report = Report::new();
    let grid = world.grid();
    hprintln!(
        "map=seed width={} height={} start={},{} goal={},{} sense_radius={} box_cells={}",
        grid.width,
        grid.height,
        world.start().x,
        world.start().y,
        world.goal().x,
        world.goal().y,
        SENSE_RADIUS,
        BOX_CELLS
    );
    let mut meter = Icount { overhead };
    if let Err(e) = run(&mut world, &mut planner, &mut meter, &mut report) {
        hprintln!("error=planner {:?}", e);
        return Err(());
    }

    let first = report.first_plan();
    hprintln!("first_plan_instructions={}", first.instructions);
    hprintln!("first_plan_expansions={}", first.expansions);
    hprintln!("first_plan_cost={}", first.cost);
    hprintln!("first_plan_path_cells={}", report.path().len());

    for (i, s) in report.replans().iter().enumerate() {
        hprintln!(
            "replan step={} x={} y={} changed={} expansions={} instructions={} cost={}",
            i + 1,
            s.at.x,
            s.at.y,
            s.changed,
            s.expansions,
            s.instructions,
            s.cost
        );
    }
    let changed = || report.replans().iter().filter(|s| s.changed > 0);
    let idle = || report.replans().iter().filter(|s| s.changed == 0);
    hprintln!("flight_status=reached");
    hprintln!("flight_moves={}", report.moves);
    hprintln!("flight_cost={}", report.flight_cost);
    hprintln!("flight_queue_high_water={}", report.queue_high_water);
    hprintln!("replans_with_changes={}", changed().count());
    print_summary("replan_instructions", summary_of(changed(), |s| s.instructions));
    print_summary("replan_expansions", summary_of(changed(), |s| s.expansions));
    print_summary("replan_changed_cells", summary_of(changed(), |s| u32::from(s.changed)));
    hprintln!("replans_without_changes={}", idle().count());
    print_summary("idle_replan_instructions", summary_of(idle(), |s| s.instructions));

    for b in &report.boxes {
        hprintln!(
            "box k={} path_index={} x={} y={} changed={} expansions={} instructions={} cost_before={} cost_after={}",
            b.k,
            b.path_index,
            b.centre.x,
            b.centre.y,
            b.replan.changed,
            b.replan.expansions,
            b.replan.instructions,
            first.cost,
            b.replan.cost
        );
    }
    // The first replan after a first plan is the same call for every k; the first plan's remaining work.
    let first_replan = report.boxes[0].first_replan;
    hprintln!("first_replan_instructions={}", first_replan.instructions);
    hprintln!("first_replan_expansions={}", first_replan.expansions);
    hprintln!(
        "first_plan_and_first_replan_instructions={}",
        first.instructions + first_replan.instructions
    );
    let boxes = || report.boxes.iter().map(|b| &b.replan);
    hprintln!("box_replans={}", report.boxes.len());
    print_summary("box_instructions", summary_of(boxes(), |s| s.instructions));
    print_summary("box_expansions", summary_of(boxes(), |s| s.expansions));

    let planner_bytes = size_of::<ArenaPlanner>();
    let grid_bytes = size_of::<OccupancyGrid<ARENA_CELLS>>();
    hprintln!("planner_bytes={}", planner_bytes);
    hprintln!("grid_bytes={}", grid_bytes);
    hprintln!("ram_total_bytes={}", planner_bytes + grid_bytes);
    estimator_bench(&mut meter)?;
    crate::map_fix::map_fix_bench(&mut meter)?;
    crate::control::control_step_bench(&mut meter)?;
    crate::control::planner_slice_bench(&mut meter)?;
    hprintln!("result=ok");
    Ok(())
}

/// The estimator's 10 Hz wall-anchor update against its 100 Hz flow update, hovering 0.5 m above the floor
/// 1 m from four walls: calibrate at rest, take off (height readings), then one simulated second per reading
/// kind in the proportions the MCU sees (10 IMU samples per flow reading, 100 per Multi-ranger sweep).
fn estimator_bench(meter: &mut Icount) -> Result<(), ()> {
    const RUNS: usize = 20;
    let Some(mut est) = estimator_calibrated_at_rest([1.0, 1.0, 0.0], 0.0) else {
        hprintln!("error=estimator_not_calibrated");
        return Err(());
    };
    let flow = STILL_FLOW;
    let walls = WALLS_AT_1M;
    let mut flow_counts = [0u32; RUNS];
    let mut wall_counts = [0u32; RUNS];
    for run in 0..RUNS {
        for k in 0..100u32 {
            est.on_imu(&IMU_AT_REST, 0.001);
            if k % 10 == 0 {
                let ((), n) = meter.measure(|| est.on_flow(&flow));
                if k == 0 {
                    flow_counts[run] = n;
                }
            }
            if k % 25 == 0 {
                est.on_zrange(Some(0.5));
            }
        }
        let ((), n) = meter.measure(|| est.on_multiranger(&walls, true));
        wall_counts[run] = n;
    }
    let fused = est.diagnostics().wall_fused;
    // The first sweep only anchors; every later one fuses four beams.
    if fused != 4 * (RUNS as u32 - 1) {
        hprintln!("error=wall_ranges_fused {} of {}", fused, 4 * (RUNS - 1));
        return Err(());
    }
    hprintln!("estimator_wall_ranges_fused={}", fused);
    print_summary("estimator_on_flow_instructions", summarize(&mut flow_counts[..]));
    print_summary(
        "estimator_on_multiranger_instructions",
        summarize(&mut wall_counts[1..]),
    );
    Ok(())
}

/// The program, called by the reset handler (`src/rt.rs`) once the FPU is on and RAM is initialised: run the
/// benchmark and exit QEMU with its status.
pub extern "C" fn main() -> ! {
    let status = if bench().is_ok() {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    };
    debug::exit(status);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("error=panic {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
