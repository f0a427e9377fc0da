//! The control step and the longest thread-mode slice, in exact Cortex-M4 instructions (this file is the
//! board layer's section of the benchmark; the planner scenario is `lib.rs` + `mcu.rs`).
//!
//! Control step: what the firmware's control task does per gyro edge after the IMU read (`src/board/
//! control.rs`): drain the queued inputs into the [`Stabilizer`] (flow 100 Hz, height 40 Hz, Multi-ranger
//! 10 Hz, battery 100 Hz, commander setpoints) and run [`Stabilizer::on_imu`] (estimator predict, supervisor,
//! controller, mixer). The drone hovers 0.5 m above the floor 1 m from four walls under a commander position
//! hold (so the Multi-ranger sweep fuses its wall anchors, the costliest update), after a 1.5 s calibration
//! at rest. Inputs land on their real schedules, aligned so that every 100th step gets a flow reading, a
//! height reading, a Multi-ranger sweep and a battery report at once, and pass through the firmware's
//! [`HeavyInputGate`] (at most one flow or Multi-ranger update per step; the second waits one step), as
//! `src/board/control.rs` drains them. `control_step_instructions_max` is the worst step;
//! `control_step_ungated_instructions_max` the same schedule with every input applied at once (the firmware
//! before the gate).
//!
//! Thread-mode slice: one planner call with the mission's full budget (`MissionConfig::planner_budget`
//! expansions) that cannot finish early: the seed map with the start walled in, so the backward search from
//! the goal runs out of budget before it can prove the start unreachable.
//!
//! Output: `control_step_instructions_{median,p90,max}` over every step, `control_step_imu_only_*` over the
//! steps with no input, `control_step_worst_inputs=` (inputs applied in the max step),
//! `planner_slice_{instructions,expansions}`.

use cfnav::mission::MissionConfig;
use cfnav::nav::dstar::{ArenaPlanner, PlanError, PlanStatus};
use cfnav::nav::map::Cell;
use cfnav::stack::{FlightConfig, Stabilizer};
use cfnav::system::step_pacing::HeavyInputGate;
use cfnav::types::{GRAVITY_M_S2, ImuSample, Setpoint};
use cortex_m_semihosting::hprintln;
use qemu_bench::{Meter, SEED_MAP, STILL_FLOW, WALLS_AT_1M, World, summarize};

/// Measured steps (two simulated seconds).
const STEPS: usize = 2000;
/// Input kinds that can arrive in one step.
const ARRIVALS: usize = 5;

fn print(name: &str, values: &mut [u32]) {
    let s = summarize(values);
    hprintln!("{}_median={}", name, s.median);
    hprintln!("{}_p90={}", name, s.p90);
    hprintln!("{}_max={}", name, s.max);
}

/// A queued input of the control step (the firmware's `FastInput`, minus the ones this scenario has no use for).
#[derive(Clone, Copy)]
enum Input {
    Commander,
    Flow,
    Height,
    Sweep,
    Battery,
}

/// The 1 kHz control step, hovering under a commander hold; see the module documentation.
pub fn control_step_bench(meter: &mut impl Meter) -> Result<(), ()> {
    control_step_run(meter, true)?;
    control_step_run(meter, false)
}

fn control_step_run(meter: &mut impl Meter, gated: bool) -> Result<(), ()> {
    let config = FlightConfig::default();
    let Ok(mut stab) = Stabilizer::new(&config, (1.0, 1.0), 0.0) else {
        hprintln!("error=stabilizer_config");
        return Err(());
    };
    let level = ImuSample {
        gyro_rad_s: [0.0; 3],
        accel_m_s2: [0.0, 0.0, GRAVITY_M_S2],
    };
    let mut now_us = 0u64;
    // At rest on the floor until the estimator has calibrated (as the firmware after boot).
    for k in 0..1500u32 {
        now_us += 1000;
        stab.on_battery(4.0);
        if k % 25 == 0 {
            let _ = stab.on_zrange(Some(0.0));
        }
        let _ = stab.on_imu(&level, now_us);
    }
    if !stab.estimator().is_calibrated() {
        hprintln!("error=estimator_not_calibrated");
        return Err(());
    }
    let hold = Setpoint::Position {
        x_m: 1.0,
        y_m: 1.0,
        z_m: 0.5,
        yaw_rad: 0.0,
    };
    let flow = STILL_FLOW;
    let walls = WALLS_AT_1M;
    let mut all = [0u32; STEPS];
    let mut imu_only = [0u32; STEPS];
    let mut n_imu_only = 0;
    let (mut worst, mut worst_inputs) = (0u32, 0u32);
    let mut gate = HeavyInputGate::new();
    let mut carry: [Option<Input>; 2 * ARRIVALS] = [None; 2 * ARRIVALS];
    // Warm-up (take-off into the hold), then the measured steps.
    for k in 0..(1000 + STEPS) {
        now_us += 1000;
        let flow_due = k % 10 == 0;
        let height_due = k % 25 == 0;
        let sweep_due = k % 100 == 0;
        let battery_due = k % 10 == 0;
        let commander_due = k % 20 == 0;
        // The queue: what waited from the last step, then this step's arrivals, in order.
        let mut queue = [None; 2 * ARRIVALS];
        let mut len = 0;
        for input in carry.iter_mut().filter_map(Option::take).chain(
            [
                (commander_due, Input::Commander),
                (flow_due, Input::Flow),
                (height_due, Input::Height),
                (sweep_due, Input::Sweep),
                (battery_due, Input::Battery),
            ]
            .into_iter()
            .filter_map(|(due, input)| due.then_some(input)),
        ) {
            queue[len] = Some(input);
            len += 1;
        }
        let (applied, n) = meter.measure(|| {
            let mut applied = 0u32;
            let mut apply = |input: Input| {
                applied += 1;
                match input {
                    Input::Commander => stab.commander_setpoint(hold, now_us),
                    Input::Flow => stab.on_flow(&flow),
                    Input::Height => {
                        let _ = stab.on_zrange(Some(0.5));
                    }
                    Input::Sweep => stab.on_multiranger(&walls),
                    Input::Battery => stab.on_battery(3.9),
                }
            };
            let mut taken = 0;
            if gated {
                if let Some(input) = gate.begin_step() {
                    apply(input);
                }
                // As `drain_inputs`: stop draining while the gate holds an input; the rest stays queued.
                while !gate.holding() && taken < len {
                    let Some(input) = queue[taken] else { break };
                    taken += 1;
                    if let Some(input) = gate.admit(input, matches!(input, Input::Flow | Input::Sweep)) {
                        apply(input);
                    }
                }
            } else {
                for input in queue[..len].iter().flatten().copied() {
                    apply(input);
                }
                taken = len;
            }
            let _ = stab.on_imu(&level, now_us);
            (applied, taken)
        });
        let (applied, taken) = applied;
        for (slot, input) in carry.iter_mut().zip(queue[taken..len].iter().copied()) {
            *slot = input;
        }
        let Some(i) = k.checked_sub(1000) else {
            continue;
        };
        all[i] = n;
        let inputs = applied;
        if inputs == 0 {
            imu_only[n_imu_only] = n;
            n_imu_only += 1;
        }
        if n > worst {
            (worst, worst_inputs) = (n, inputs);
        }
    }
    if !stab.supervisor().flying {
        hprintln!("error=control_step_not_flying");
        return Err(());
    }
    let fused = stab.estimator().diagnostics().wall_fused;
    if fused == 0 {
        hprintln!("error=control_step_no_wall_anchor_fused");
        return Err(());
    }
    if !gated {
        print("control_step_ungated_instructions", &mut all);
        return Ok(());
    }
    hprintln!("control_step_steps={}", STEPS);
    hprintln!("control_step_wall_ranges_fused={}", fused);
    hprintln!("control_step_worst_inputs={}", worst_inputs);
    print("control_step_instructions", &mut all);
    print("control_step_imu_only_instructions", &mut imu_only[..n_imu_only]);
    Ok(())
}

/// One full planner slice that cannot finish early; see the module documentation.
pub fn planner_slice_bench(meter: &mut impl Meter) -> Result<(), ()> {
    let Ok(mut world) = World::parse(SEED_MAP) else {
        hprintln!("error=map");
        return Err(());
    };
    let start = world.start();
    for (dx, dy) in [
        (1i32, 0i32),
        (1, 1),
        (0, 1),
        (-1, 1),
        (-1, 0),
        (-1, -1),
        (0, -1),
        (1, -1),
    ] {
        let (x, y) = (i32::from(start.x) + dx, i32::from(start.y) + dy);
        if let (Ok(x), Ok(y)) = (u16::try_from(x), u16::try_from(y)) {
            world.block(Cell::new(x, y));
        }
    }
    let budget = MissionConfig::default().planner_budget;
    let mut planner = ArenaPlanner::new();
    let (status, n) = meter.measure(|| -> Result<PlanStatus, PlanError> {
        planner.reset(world.grid(), start, world.goal())?;
        planner.compute(&world, budget)
    });
    let expansions = planner.expansions();
    match status {
        Ok(PlanStatus::Found { .. }) => {
            hprintln!("error=planner_slice_found_a_path");
            return Err(());
        }
        Ok(_) => {}
        Err(e) => {
            hprintln!("error=planner_slice {:?}", e);
            return Err(());
        }
    }
    hprintln!("planner_slice_budget={}", budget);
    hprintln!("planner_slice_expansions={}", expansions);
    hprintln!("planner_slice_instructions={}", n);
    Ok(())
}
