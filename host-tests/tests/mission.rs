//! The mission state machine on its own: start refusals, the thrust-lock handshake, abort, state codes.

use cfnav::mission::{Mission, MissionConfig, MissionInputs, MissionParams, MissionState, StartRefusal};
use cfnav::types::{Setpoint, StateEstimate};

type M = Mission<{ 128 * 64 }, 1024>;

fn mission() -> Box<M> {
    Box::new(Mission::new(MissionConfig::default()).expect("default config is valid"))
}

/// Armed inputs with nothing else to report.
fn armed() -> MissionInputs {
    MissionInputs {
        armed: true,
        ..MissionInputs::default()
    }
}

/// A mission started with the seed parameters that has seen its first tick on the pad at (0.6, 1.3).
fn started_on_the_pad() -> Box<M> {
    let mut m = mission();
    m.start(MissionParams::SEED).unwrap();
    m.tick(20_000, &at(0.6, 1.3, 0.0), &armed());
    m
}

fn at(x: f32, y: f32, z: f32) -> StateEstimate {
    StateEstimate {
        position_m: [x, y, z],
        valid: true,
        ..StateEstimate::default()
    }
}

#[test]
fn nonsense_parameters_are_refused_and_nothing_starts() {
    let mut m = mission();
    let ok = MissionParams::SEED;
    let cases = [
        (
            MissionParams {
                goal_m: (7.0, 1.5),
                ..ok
            },
            StartRefusal::OutsideArena,
        ),
        (
            MissionParams {
                goal_m: (f32::NAN, 1.5),
                ..ok
            },
            StartRefusal::OutsideArena,
        ),
        (
            MissionParams {
                start_m: (0.6, -0.2),
                ..ok
            },
            StartRefusal::OutsideArena,
        ),
        (MissionParams { height_m: 0.1, ..ok }, StartRefusal::BadHeight),
        (MissionParams { speed_m_s: -0.3, ..ok }, StartRefusal::BadSpeed),
        (MissionParams { speed_m_s: 0.0, ..ok }, StartRefusal::BadSpeed),
        (
            MissionParams {
                arena_m: (60.0, 30.0),
                ..ok
            },
            StartRefusal::BadArena,
        ),
    ];
    for (params, why) in cases {
        assert_eq!(m.start(params), Err(why), "{params:?}");
        assert_eq!(m.state(), MissionState::Idle);
    }
    m.start(ok).unwrap();
    assert_eq!(m.start(ok), Err(StartRefusal::AlreadyRunning));
}

#[test]
fn preflight_waits_for_a_valid_estimate_and_the_armed_supervisor() {
    let mut m = mission();
    m.start(MissionParams::SEED).unwrap();
    let mut now = 0;
    let mut tick = |m: &mut M, state: StateEstimate, armed: bool| {
        now += 20_000;
        m.tick(
            now,
            &state,
            &MissionInputs {
                armed,
                ..MissionInputs::default()
            },
        )
    };
    // Valid estimate but the supervisor has not armed yet: keep sending Stop (its thrust lock needs it).
    for _ in 0..10 {
        assert_eq!(tick(&mut m, at(0.6, 1.3, 0.0), false), Setpoint::Stop);
        assert_eq!(m.state(), MissionState::Preflight);
    }
    // Armed but no valid estimate: still Stop.
    assert_eq!(
        tick(
            &mut m,
            StateEstimate {
                valid: false,
                ..at(0.6, 1.3, 0.0)
            },
            true
        ),
        Setpoint::Stop
    );
    // Both: take off.
    let sp = tick(&mut m, at(0.6, 1.3, 0.0), true);
    assert!(matches!(sp, Setpoint::Position { .. }), "{sp:?}");
    assert_eq!(m.state(), MissionState::TakeOffOutbound);
}

#[test]
fn abort_lands_where_it_is_or_on_the_pad_within_reach_and_ends_aborted() {
    // 0.8 m from the home pad (0.6, 1.3): it lands where it is.
    let mut far = started_on_the_pad();
    let inputs = armed();
    far.tick(40_000, &at(0.6, 1.3, 0.3), &inputs);
    far.abort(&at(1.4, 1.3, 0.3));
    let sp = far.tick(60_000, &at(1.4, 1.3, 0.3), &inputs);
    assert!(
        matches!(sp, Setpoint::Descend { x_m, y_m, vz_m_s, .. } if x_m == 1.4 && y_m == 1.3 && vz_m_s < 0.0),
        "{sp:?}"
    );
    // 0.14 m from the home pad's centre: it lands on that centre, not across the pad's rim. It flies there
    // at its height first (straight at the centre), and descends once within 5 cm of it.
    let mut m = started_on_the_pad();
    m.tick(40_000, &at(0.6, 1.3, 0.3), &inputs);
    m.abort(&at(0.7, 1.2, 0.3));
    let sp = m.tick(60_000, &at(0.7, 1.2, 0.3), &inputs);
    assert!(
        matches!(sp, Setpoint::Velocity { vx_m_s, vy_m_s, z_m, .. }
            if vx_m_s < -0.05 && (vx_m_s + vy_m_s).abs() < 1e-3 && z_m == 0.3),
        "{sp:?}"
    );
    let sp = m.tick(70_000, &at(0.62, 1.29, 0.3), &inputs);
    assert!(
        matches!(sp, Setpoint::Descend { x_m, y_m, vz_m_s, .. } if x_m == 0.6 && y_m == 1.3 && vz_m_s < 0.0),
        "{sp:?}"
    );
    assert_eq!(m.state(), MissionState::EmergencyLanding);
    let sp = m.tick(80_000, &at(0.7, 1.2, 0.0), &MissionInputs { landed: true, ..inputs });
    assert_eq!(sp, Setpoint::Stop);
    assert_eq!(m.state(), MissionState::Aborted);
    assert_eq!(m.state().code(), 200);
    // Idle again for a new start.
    m.start(MissionParams::SEED).unwrap();
}

#[test]
fn battery_low_and_crash_end_flying_phases() {
    let mut m = started_on_the_pad();
    let inputs = armed();
    m.tick(
        40_000,
        &at(0.6, 1.3, 0.3),
        &MissionInputs {
            battery_low: true,
            ..inputs
        },
    );
    assert_eq!(m.state(), MissionState::EmergencyLanding);
    m.tick(60_000, &at(0.6, 1.3, 0.0), &MissionInputs { landed: true, ..inputs });
    assert_eq!(m.state(), MissionState::BatteryLow);

    let mut m = started_on_the_pad();
    assert_eq!(
        m.tick(
            40_000,
            &at(0.6, 1.3, 0.3),
            &MissionInputs {
                crashed: true,
                ..inputs
            }
        ),
        Setpoint::Stop
    );
    assert_eq!(m.state(), MissionState::Crashed);
}

#[test]
fn state_codes_follow_the_documented_ranges() {
    use MissionState::*;
    for s in [
        Idle,
        Preflight,
        TakeOffOutbound,
        NavigateToGoal,
        SearchGoalPad,
        ApproachGoalPad,
        LandOnGoalPad,
        OnGoalPad,
        TakeOffReturn,
        NavigateHome,
        SearchHomePad,
        ApproachHomePad,
        LandOnHomePad,
        NoPathHover,
        EmergencyLanding,
    ] {
        assert!(s.code() < 100 && !s.is_final(), "{s:?}");
    }
    assert_eq!(Completed.code(), 100);
    for s in [
        Aborted,
        NoPath,
        PadNotFound,
        BatteryLow,
        EstimatorFault,
        Crashed,
        PlannerFault,
    ] {
        assert!(s.code() >= 200 && s.is_final(), "{s:?}");
    }
}

/// Explore's discharge watch (`cfnav::mission::reserve`): on a synthetic linear discharge with noise it
/// measures the slope (least squares against the known one), only after settling and a minimum span, and
/// the remaining time is the straight-line extrapolation to the threshold.
#[test]
fn the_discharge_watch_measures_a_linear_discharge() {
    use cfnav::mission::reserve::{DischargeWatch, MIN_SPAN_S, SETTLE_US, needed_s, remaining_s};
    let mut w = DischargeWatch::new();
    let rate = 4e-3f32; // V/s
    let mut seen_at = None;
    for ms in (0..60_000u64).step_by(20) {
        let t = ms as f32 * 1e-3;
        // ±5 mV of deterministic "noise".
        let noise = 5e-3 * ((ms / 20) % 7) as f32 / 6.0 - 2.5e-3;
        w.on_sample(ms * 1000, 3.9 - rate * t + noise);
        w.on_sample(ms * 1000, f32::NAN);
        if seen_at.is_none() && w.rate_v_per_s().is_some() {
            seen_at = Some(t);
        }
    }
    let first = seen_at.expect("a rate");
    assert!(
        first >= SETTLE_US as f32 * 1e-6 + MIN_SPAN_S - 0.1,
        "trusted at {first} s"
    );
    let measured = w.rate_v_per_s().unwrap();
    assert!((measured - rate).abs() < 0.1e-3, "{measured} V/s");
    assert!((remaining_s(3.4, 3.2, rate) - 50.0).abs() < 1e-3);
    // 3 m home at 0.5 m/s + 15 s of search and landing, times 1.5.
    assert!((needed_s(3.0, 0.5, 1.5) - 31.5).abs() < 1e-3);
}

/// The whole Flow deck lost in flight (found in the emulator, `cfnav-pil --fault flow-deck-lost`): no flow and
/// no height reading, so the estimate stays invalid down to the floor and the supervisor, which never counts
/// a touchdown on an invalid estimate, never reports one. The blind descent must still end with the motors
/// stopped, within the time a descent from the last valid height can take; and not before that time, so a
/// descent that is still in the air keeps its thrust.
#[test]
fn a_blind_descent_stops_the_motors_after_its_time_bound() {
    let mut m = started_on_the_pad();
    let inputs = armed();
    let mut now = 20_000u64;
    // Fly: take off and climb to 0.6 m with a valid estimate.
    for k in 0..200 {
        now += 20_000;
        let z = (k as f32 * 0.005).min(0.6);
        m.tick(now, &at(0.6, 1.3, z), &inputs);
    }
    assert!(!m.state().is_final(), "{:?}", m.state());
    // The estimate is lost at 0.6 m and never comes back.
    let lost_at = now;
    let blind = StateEstimate {
        valid: false,
        ..at(0.6, 1.3, 0.6)
    };
    let mut stopped_at = None;
    while now < lost_at + 20_000_000 {
        now += 20_000;
        let sp = m.tick(now, &blind, &inputs);
        if sp == Setpoint::Stop {
            stopped_at = Some(now);
            break;
        }
        assert!(
            matches!(sp, Setpoint::Descend { vz_m_s, .. } if vz_m_s < 0.0),
            "a blind descent: {sp:?}"
        );
        assert_eq!(m.state(), MissionState::EmergencyLanding);
    }
    let stopped_after_s = (stopped_at.expect("the motors stop") - lost_at) as f32 * 1e-6;
    // From 0.6 m at the slowest commanded rate (0.2 m/s) with 0.2 m of margin it is down after 4 s; the
    // bound is 5 s: the motors must keep turning until then and stop right after.
    assert!(
        (4.0..=5.1).contains(&stopped_after_s),
        "the motors stopped {stopped_after_s} s after the estimate was lost"
    );
    assert_eq!(m.state(), MissionState::EstimatorFault);
    assert_eq!(m.tick(now + 20_000, &blind, &inputs), Setpoint::Stop);
}

/// Open sides (`mission.walls`): the grid blocks the cells within the geofence (0.3 m, 6 cells) of an
/// open side, one cell more than the inflation (0.25 m, 5 cells) that a wall gets; an estimate past an
/// open side's edge lands where it is and ends `LeftArena`, while past a walled side (an estimate error
/// the walls' fixes will pull back) it does not.
#[test]
fn an_open_side_is_a_geofence_and_crossing_it_ends_the_mission() {
    use cfnav::mission::{ALL_WALLS, GEOFENCE_M, WALL_WEST};
    use cfnav::nav::map::{CELL_SIZE_M, Cell};
    let open_west = MissionParams {
        walls: ALL_WALLS & !WALL_WEST,
        ..MissionParams::SEED
    };
    let fence_cells = (GEOFENCE_M / CELL_SIZE_M).round() as u16;
    assert_eq!(fence_cells, 6);
    let mut walled = mission();
    walled.start(MissionParams::SEED).unwrap();
    let mut open = mission();
    open.start(open_west).unwrap();
    let row = 30;
    for x in 0..8u16 {
        // Distance from the cell's centre to the west side.
        let centre = (f32::from(x) + 0.5) * CELL_SIZE_M;
        let c = Cell::new(x, row);
        assert_eq!(open.grid().is_blocked(c), centre < GEOFENCE_M, "open, column {x}");
        assert_eq!(walled.grid().is_blocked(c), x < 5, "walled, column {x}");
        // The east side is a wall in both.
        let e = Cell::new(119 - x, row);
        assert_eq!(
            open.grid().is_blocked(e),
            walled.grid().is_blocked(e),
            "east, column {}",
            119 - x
        );
    }

    let inputs = armed();
    let fly = |params: MissionParams, x: f32, y: f32| {
        let mut m = mission();
        m.start(params).unwrap();
        m.tick(20_000, &at(0.6, 1.3, 0.0), &inputs);
        m.tick(40_000, &at(0.6, 1.3, 0.3), &inputs);
        m.tick(60_000, &at(x, y, 0.3), &inputs);
        m
    };
    let mut m = fly(open_west, -0.02, 1.3);
    assert_eq!(m.state(), MissionState::EmergencyLanding);
    m.tick(80_000, &at(-0.02, 1.3, 0.0), &MissionInputs { landed: true, ..inputs });
    assert_eq!(m.state(), MissionState::LeftArena);
    assert_eq!(m.state().code(), 210);
    assert!(m.state().is_final());
    // Inside the open edge (within the fence, but not past the edge), or past a walled side: flying on.
    for (params, x, y) in [
        (open_west, 0.05, 1.3),
        (MissionParams::SEED, -0.02, 1.3),
        (open_west, 0.6, -0.02),
    ] {
        let m = fly(params, x, y);
        assert_ne!(
            m.state(),
            MissionState::EmergencyLanding,
            "walls {} at ({x}, {y})",
            params.walls
        );
        assert!(!m.state().is_final());
    }
}
