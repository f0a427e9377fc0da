//! The link-loss policy (`cfnav::mission::link_loss`) flown in the simulator: the simulated
//! link delivers a packet every 10 ms until `--link-loss-at`, then nothing. Judged on the simulator's truth
//! (where the drone was when the timeout fired, where it came to rest, which pad it landed on).

use cfnav::mission::link_loss::{LinkLossConfig, LinkLossPolicy, LinkWatch};
use cfnav::mission::{MissionParams, MissionState};
use cfnav::types::{MotorDuty, Setpoint};
use cfnav_sim::world::World;
use cfnav_tools::sim::runner::{Faults, RunOptions, RunResult, SimDrone, mission_params, run};

use crate::{default_world_enters, on_pad_centre_or_clear_of_it};

/// Times the link goes silent: just after take-off, early, halfway and late in the outbound navigation,
/// during the goal-pad search, so that the timeout fires while the drone stands on the goal pad, and
/// during the return leg.
fn silent_at_s() -> [f64; 7] {
    let (nav, search) = (
        default_world_enters(MissionState::NavigateToGoal),
        default_world_enters(MissionState::SearchGoalPad),
    );
    [
        default_world_enters(MissionState::TakeOffOutbound) + 0.5,
        nav + 1.5,
        0.5 * (nav + search),
        search - 4.0,
        search + 2.5,
        default_world_enters(MissionState::OnGoalPad) + 0.5 - TIMEOUT_S,
        default_world_enters(MissionState::NavigateHome) + 4.0,
    ]
}
const TIMEOUT_S: f64 = 2.0;

fn fly(policy: LinkLossPolicy, silent_at_s: f64) -> RunResult {
    let world = World::default_world();
    let mut options = RunOptions::for_world(&world);
    options.record = true;
    options.faults = Faults {
        link_loss_at_s: Some(silent_at_s),
        ..Faults::default()
    };
    options.link_loss = LinkLossConfig {
        policy,
        timeout_s: TIMEOUT_S as f32,
    };
    run(&world, &options).expect("runs")
}

fn fired_at(r: &RunResult, silent_at_s: f64) -> f64 {
    let t = r.report.link_lost_at_s.expect("the timeout fired");
    // Packets every 10 ms up to the silence, mission ticks every 20 ms: the timeout fires within a tick of
    // the last packet + 2 s.
    assert!(
        (t - (silent_at_s + TIMEOUT_S)).abs() <= 0.03,
        "fired at {t} s, silent from {silent_at_s} s"
    );
    t
}

/// Policy 0 (the default): the timeout fires, nothing changes, the round trip completes on both pads.
#[test]
fn policy_0_goes_on_and_completes() {
    for at in silent_at_s() {
        let r = fly(LinkLossPolicy::Continue, at);
        fired_at(&r, at);
        assert_eq!(r.report.outcome, "completed", "silent at {at} s: {:?}", r.report);
        assert_eq!(r.report.mission_state, 100);
        assert_eq!(r.report.collisions, 0);
    }
}

/// Policy 1: it lands where it was when the timeout fired (within 15 cm horizontally: the brake from cruise
/// speed and the flow-only estimate's drift over the descent), motors off, soon (within 5 s), ending
/// `link_lost` (207); near a pad, on its centre if the mission knows it, else on the floor clear of it.
/// Silent on the goal pad (motors off, pausing), it stays there.
#[test]
fn policy_1_lands_where_the_link_was_lost() {
    for at in silent_at_s() {
        let r = fly(LinkLossPolicy::Land, at);
        let t = fired_at(&r, at);
        let rep = &r.report;
        assert_eq!(
            (rep.outcome, rep.reason),
            ("aborted", Some("link_lost")),
            "silent at {at} s: {rep:?}"
        );
        assert_eq!(rep.mission_state, MissionState::LinkLost.code());
        assert_eq!(rep.collisions, 0, "silent at {at} s");
        let fired = rep.link_lost_point.expect("the truth when it fired");
        let rest = r.trace.last().expect("a trace").truth;
        let off = (rest[0] - fired[0]).hypot(rest[1] - fired[1]);
        let last = rep.landings.last().expect("it landed");
        println!("silent at {at} s: fired at {t:.2} s at {fired:?}, at rest {off:.3} m from there, {last:?}");
        // Near a pad (within 0.3 m of its centre) it lands on that pad's centre rather than across its rim.
        let world = World::default_world();
        let near_pad = world
            .pads
            .iter()
            .position(|p| (p.center[0] - fired[0]).hypot(p.center[1] - fired[1]) < 0.35);
        // Where the goal pad may lie but was not located yet (its search), it comes down on the floor clear
        // of the pad: the body wholly beside it, never across its rim.
        match near_pad {
            Some(i) if off >= 0.15 => assert!(
                on_pad_centre_or_clear_of_it(&world, i, last),
                "silent at {at} s: near pad {i}, landed {last:?}"
            ),
            _ => assert!(
                off < 0.15,
                "silent at {at} s: came to rest {off} m from where the link was lost"
            ),
        }
        // Ended with the motors off, on the ground, within 5 s of the timeout.
        let end_s = 1.0 + rep.mission_time_s.expect("the motors stopped");
        assert!(
            end_s - t < 5.0,
            "silent at {at} s: motors stopped {:.2} s after the timeout",
            end_s - t
        );
        assert!(
            rep.sim_time_s - t < 6.0,
            "silent at {at} s: the run ended at {} s",
            rep.sim_time_s
        );
    }
}

/// Policy 2: silent on the outbound leg, it turns back, lands on the home pad within the usual landing
/// error (on the pad, ≤ 6 cm from its centre: BENCHMARKS' p95 for flow-only landings), never on the goal
/// pad, ending `link_lost_home` (208). Silent after the goal-pad landing began (on the pad, or on the
/// return), it is going home anyway: the round trip completes.
#[test]
fn policy_2_returns_home_and_lands_on_the_home_pad() {
    for at in silent_at_s() {
        let r = fly(LinkLossPolicy::ReturnHome, at);
        fired_at(&r, at);
        let rep = &r.report;
        assert_eq!(rep.collisions, 0, "silent at {at} s");
        let home = rep.landings.last().expect("it landed");
        println!(
            "silent at {at} s: {} {:?}, landings {:?}",
            rep.outcome, rep.reason, rep.landings
        );
        assert_eq!(home.pad, 0, "silent at {at} s: {:?}", rep.landings);
        assert!(home.on_pad && home.error_m <= 0.06, "silent at {at} s: {home:?}");
        // Fired before the drone stood on the goal pad: it turns back and lands at home only.
        if at + TIMEOUT_S < default_world_enters(MissionState::OnGoalPad) {
            assert_eq!(
                (rep.outcome, rep.reason),
                ("aborted", Some("link_lost_home")),
                "silent at {at} s: {rep:?}"
            );
            assert_eq!(rep.mission_state, MissionState::LinkLostHome.code());
            assert_eq!(
                rep.landings.len(),
                1,
                "silent at {at} s: straight home: {:?}",
                rep.landings
            );
        } else {
            assert_eq!(rep.outcome, "completed", "silent at {at} s: {rep:?}");
        }
    }
}

/// Steps a drone with the mission started at 1 s; `packet(t)` says whether the link delivers a packet in the
/// 10 ms slot at `t` s. Returns the `mission.state` codes seen after the timeout fired, and the final state.
fn fly_with_link(policy: LinkLossPolicy, packet: impl Fn(f64) -> bool, until_s: f64) -> (Vec<u8>, MissionState) {
    let world = World::default_world();
    let mut drone = SimDrone::new(&world, 7, &Faults::default()).expect("a drone");
    drone.core.set_link_loss(LinkLossConfig {
        policy,
        timeout_s: TIMEOUT_S as f32,
    });
    let params: MissionParams = mission_params(&world);
    let mut after = Vec::new();
    for tick in 0..(until_s * 1000.0) as u64 {
        let t = tick as f64 * 1e-3;
        if tick == 1000 {
            drone.core.start_mission(params).expect("the start");
        }
        if tick.is_multiple_of(10) && packet(t) {
            drone.core.on_radio_packet(tick * 1000);
        }
        drone.step(&world);
        if drone.core.navigator().link_watch().fired_at().is_some() {
            let code = drone.core.mission_state().code();
            if after.last() != Some(&code) {
                after.push(code);
            }
        }
    }
    (after, drone.core.mission_state())
}

/// A link that comes back does not undo a decided landing: silent from 6 s to 8.5 s (the timeout fires at
/// 8 s), then packets again; with policy 1 the drone goes on landing (40) and ends 207, never back to the
/// mission's phases; with policy 2 it goes on home (20..24) and never resumes the outbound leg (10..15).
#[test]
fn a_link_that_comes_back_does_not_undo_the_decision() {
    let link = |t: f64| !(6.0..8.5).contains(&t);
    let (seen, end) = fly_with_link(LinkLossPolicy::Land, link, 16.0);
    assert_eq!(seen, vec![40, 207], "policy 1: states after the timeout");
    assert_eq!(end, MissionState::LinkLost);

    let (seen, end) = fly_with_link(LinkLossPolicy::ReturnHome, link, 40.0);
    assert!(
        seen.iter().all(|c| (20..=24).contains(c) || *c == 208),
        "policy 2: states after the timeout {seen:?}"
    );
    assert_eq!(end, MissionState::LinkLostHome, "{seen:?}");

    // And the oracle for the watch: with the link never silent for 2 s (gaps of 1.9 s), nothing fires and
    // the round trip completes.
    let (seen, end) = fly_with_link(LinkLossPolicy::Land, |t| (t % 4.0) > 1.9, 65.0);
    assert!(seen.is_empty(), "{seen:?}");
    assert_eq!(end, MissionState::Completed);
}

/// Flying with commander setpoints (no mission), the link-loss rule never fires even with policy 1: the
/// setpoint watchdog rules (level out and hold after 0.5 s, motors off after 2 s), the mission stays idle.
#[test]
fn setpoint_flight_is_left_to_the_setpoint_watchdog() {
    let world = World::default_world();
    let (x0, y0) = (world.mission.start[0], world.mission.start[1]);
    let mut drone = SimDrone::new(&world, 3, &Faults::default()).expect("a drone");
    drone.core.set_link_loss(LinkLossConfig {
        policy: LinkLossPolicy::Land,
        timeout_s: 0.5,
    });
    let last_setpoint_s = 6.0;
    for tick in 0..10_000u64 {
        let t = tick as f64 * 1e-3;
        if tick.is_multiple_of(20) && (1.5..last_setpoint_s).contains(&t) {
            let sp = Setpoint::Position {
                x_m: x0,
                y_m: y0,
                z_m: 0.6,
                yaw_rad: 0.0,
            };
            drone.core.on_radio_packet(tick * 1000);
            drone.core.commander_setpoint(sp, tick * 1000);
        }
        drone.step(&world);
        assert_eq!(drone.core.mission_state(), MissionState::Idle, "at {t} s");
        assert!(drone.core.navigator().link_watch().fired_at().is_none(), "at {t} s");
        // Motors run through the level-out (0.5..2 s after the last setpoint) and stop at 2 s.
        if (5.0..last_setpoint_s + 1.95).contains(&t) {
            assert_ne!(drone.core.duty(), MotorDuty::default(), "motors off at {t} s");
        }
        if t > last_setpoint_s + 2.05 {
            assert_eq!(drone.core.duty(), MotorDuty::default(), "motors on at {t} s");
        }
    }
}

/// The watch alone, against hand-computed times: it fires once per mission, `timeout` after the later of
/// the mission start and the last packet; never while no mission runs; a new mission re-arms it.
#[test]
fn the_watch_fires_once_per_mission_after_the_timeout() {
    let s = 1_000_000u64;
    let mut w = LinkWatch::new();
    w.set_config(LinkLossConfig {
        policy: LinkLossPolicy::Land,
        timeout_s: 2.0,
    });
    w.on_packet(0);
    assert_eq!(w.check(10 * s, false), None, "no mission");
    // Mission from 10 s: the timer starts there, not at the old packet.
    assert_eq!(w.check(10 * s, true), None);
    assert_eq!(w.check(12 * s - 1, true), None);
    assert_eq!(w.check(12 * s, true), Some(LinkLossPolicy::Land));
    assert_eq!(w.check(13 * s, true), None, "once");
    w.on_packet(13 * s);
    assert_eq!(
        w.check(20 * s, true),
        None,
        "latched: the returning link changes nothing"
    );
    assert_eq!(w.fired_at(), Some(12 * s));
    // Mission ends; a new one starts at 30 s with a packet at 31 s: fires at 33 s.
    assert_eq!(w.check(25 * s, false), None);
    assert_eq!(w.check(30 * s, true), None);
    assert_eq!(w.fired_at(), None, "re-armed");
    w.on_packet(31 * s);
    w.on_packet(5 * s); // an older time is ignored
    assert_eq!(w.check(33 * s - 1, true), None);
    assert_eq!(w.check(33 * s, true), Some(LinkLossPolicy::Land));
    // A timeout outside the bounds is clamped (0.5..60 s), NaN is the default 2 s.
    let c = |timeout_s| LinkLossConfig {
        policy: LinkLossPolicy::Continue,
        timeout_s,
    };
    assert_eq!(c(0.01).timeout_us(), 500_000);
    assert_eq!(c(1e9).timeout_us(), 60 * s);
    assert_eq!(c(f32::NAN).timeout_us(), 2 * s);
    assert_eq!(LinkLossPolicy::from_code(3), None);
}
