//! The Multi-ranger lost in flight (`cfnav::mission::ranger_watch`, `sim --ranger-fails-at`): from the
//! given time no sweep reaches the flight stack. Judged on the simulator's truth: where the drone was when
//! the watch must have fired (1 s after the last sweep), where it came to rest, that it touched nothing.

use cfnav::mission::MissionState;
use cfnav::mission::ranger_watch::{RANGER_TIMEOUT_US, RangerWatch};
use cfnav_sim::world::World;
use cfnav_tools::sim::runner::{Faults, RunOptions, RunResult, run};

use crate::{default_world_enters, on_pad_centre_or_clear_of_it};

fn fly(fails_at_s: f64) -> RunResult {
    let world = World::default_world();
    let mut options = RunOptions::for_world(&world);
    options.record = true;
    options.faults = Faults {
        ranger_fails_at_s: Some(fails_at_s),
        ..Faults::default()
    };
    run(&world, &options).expect("runs")
}

/// Lost just after take-off, while navigating out, during the goal-pad search and on the way home: the
/// mission lands where it was 1 s later (within 0.2 m: the brake from cruise speed and the descent; on a
/// known pad's centre when within 0.3 m of it; clear of a goal pad not located yet), motors off within 6 s of the loss, state 209
/// (`ranger_lost`), no collision. Without the watch the mission flies on blind.
#[test]
fn a_mission_that_loses_its_rangers_lands_where_it_is() {
    let world = World::default_world();
    let times = [
        default_world_enters(MissionState::TakeOffOutbound) + 1.0,
        default_world_enters(MissionState::NavigateToGoal) + 3.0,
        default_world_enters(MissionState::SearchGoalPad) + 2.0,
        default_world_enters(MissionState::NavigateHome) + 3.0,
    ];
    for at in times {
        let r = fly(at);
        let rep = &r.report;
        assert_eq!(
            (rep.outcome, rep.reason, rep.mission_state),
            ("aborted", Some("ranger_lost"), MissionState::RangerLost.code()),
            "lost at {at:.1} s: {rep:?}"
        );
        assert_eq!(rep.collisions, 0, "lost at {at:.1} s");
        let fired_s = at + RANGER_TIMEOUT_US as f64 * 1e-6;
        let fired = r
            .trace
            .iter()
            .find(|p| p.t_s >= fired_s)
            .expect("a trace point after the watch fired")
            .truth;
        let rest = r.trace.last().expect("a trace").truth;
        let off = (rest[0] - fired[0]).hypot(rest[1] - fired[1]);
        // Within 0.35 m of a pad's centre, or (the goal pad, not located yet, may lie anywhere within
        // 0.35 m of the goal) within 0.67 m of the nominal goal.
        let goal = world.mission.goal;
        let near_pad = world
            .pads
            .iter()
            .position(|p| (p.center[0] - fired[0]).hypot(p.center[1] - fired[1]) < 0.35)
            .or_else(|| ((goal[0] - fired[0]).hypot(goal[1] - fired[1]) < 0.67).then_some(world.pads.len() - 1));
        let last = rep.landings.last().expect("it landed");
        println!("lost at {at:.1} s: at rest {off:.3} m from where the watch fired, {last:?}");
        // Near a pad it lands on its centre if the mission knows it, else (the goal pad not located yet)
        // on the floor clear of it: the body wholly beside the pad, never across its rim.
        match near_pad {
            Some(i) if off >= 0.2 => assert!(
                on_pad_centre_or_clear_of_it(&world, i, last),
                "lost at {at:.1} s: near pad {i}, landed {last:?}"
            ),
            _ => assert!(
                off < 0.2,
                "lost at {at:.1} s: came to rest {off} m from where the watch fired"
            ),
        }
        let motors_off_s = 1.0 + rep.mission_time_s.expect("the motors stopped");
        assert!(
            motors_off_s - at < 6.0,
            "lost at {at:.1} s: motors stopped {:.2} s after the loss",
            motors_off_s - at
        );
    }
}

/// The watch alone: silent for the timeout fires once; any sweep restarts the timer; never while no
/// mission runs; a new mission starts its own timer (a mission started long after the last sweep does
/// not fire at once).
#[test]
fn the_ranger_watch_fires_once_after_a_second_without_a_sweep() {
    let s = 1_000_000u64;
    let t = RANGER_TIMEOUT_US;
    let mut w = RangerWatch::new();
    assert!(!w.check(0, false));
    w.on_sweep();
    // The mission starts at 10 s; the sweep before it does not count against it.
    assert!(!w.check(10 * s, true));
    assert!(!w.check(10 * s + t - 1, true));
    assert!(w.check(10 * s + t, true), "fires after the timeout");
    assert!(!w.check(10 * s + 2 * t, true), "once");
    w.on_sweep();
    assert!(!w.check(20 * s, true), "latched");
    // Stopped, then a new mission: sweeps every 100 ms keep it quiet.
    assert!(!w.check(30 * s, false));
    for k in 0..50u64 {
        w.on_sweep();
        assert!(!w.check(31 * s + k * 100_000, true), "sweep {k}");
    }
    // Sweeps stop after the last one at 35.9 s: fires at 36.9 s, not before.
    assert!(!w.check(36 * s + 880_000, true));
    assert!(w.check(36 * s + 900_000, true));
}
