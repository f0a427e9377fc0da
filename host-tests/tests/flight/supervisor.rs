//! Supervisor tests: arming, the setpoint watchdog, tumble detection, touchdown, battery, the minimum-height
//! check; each rule at its timing boundary (1 ms ticks), latching, garbage inputs.

use cfnav::flight::supervisor::{
    Reason, Supervisor, SupervisorConfig, SupervisorFlags, SupervisorInput, SupervisorOutput, SupervisorState,
    clamp_min_height,
};
use cfnav::types::{GRAVITY_M_S2, Setpoint, StateEstimate};

const G: f32 = GRAVITY_M_S2;
const LEVEL: [f32; 3] = [0.0, 0.0, G];
const HOVER_CMD: u16 = 44200;

fn on_ground() -> StateEstimate {
    StateEstimate {
        position_m: [1.0, 1.0, 0.0],
        valid: true,
        ..StateEstimate::default()
    }
}

fn at_height(z: f32) -> StateEstimate {
    StateEstimate {
        position_m: [1.0, 1.0, z],
        valid: true,
        ..StateEstimate::default()
    }
}

fn hold(z: f32) -> Setpoint {
    Setpoint::Position {
        x_m: 1.0,
        y_m: 1.0,
        z_m: z,
        yaw_rad: 0.3,
    }
}

const LAND: Setpoint = Setpoint::Descend {
    x_m: 1.0,
    y_m: 1.0,
    vz_m_s: -0.2,
    yaw_rad: 0.0,
};

/// A supervisor ticked every millisecond with an input the test edits between ticks.
struct Bench {
    sup: Supervisor,
    input: SupervisorInput,
    last: SupervisorOutput,
}

impl Bench {
    fn new() -> Self {
        Bench::with_config(SupervisorConfig::default())
    }

    fn with_config(cfg: SupervisorConfig) -> Self {
        Bench {
            sup: Supervisor::new(cfg),
            input: SupervisorInput {
                now: 0,
                accel_m_s2: LEVEL,
                estimate: on_ground(),
                thrust_cmd: [0; 4],
                setpoint: Setpoint::Stop,
                setpoint_age_us: Some(0),
                battery_v: 3.9,
                arm_request: false,
            },
            last: SupervisorOutput::default(),
        }
    }

    /// One tick at the current time, then advance 1 ms.
    fn tick(&mut self) -> SupervisorOutput {
        self.last = self.sup.update(&self.input);
        self.input.now += 1000;
        self.last
    }

    /// `ms` ticks; returns the last output.
    fn run(&mut self, ms: u64) -> SupervisorOutput {
        for _ in 0..ms {
            self.tick();
        }
        self.last
    }

    /// Armed, then take off: the controller's motors run, the drone is at 0.5 m.
    fn flying() -> Bench {
        let mut b = Bench::new();
        assert_eq!(b.tick().state, SupervisorState::Armed);
        b.input.setpoint = hold(0.5);
        b.input.thrust_cmd = [HOVER_CMD; 4];
        assert_eq!(b.tick().state, SupervisorState::Flying);
        b.input.estimate = at_height(0.5);
        b.run(100);
        assert_eq!(b.last.state, SupervisorState::Flying);
        b
    }

    /// Run with the setpoint age growing by 1 ms per tick from `age0`.
    fn run_aging(&mut self, age0: u64, ms: u64) -> SupervisorOutput {
        for k in 0..ms {
            self.input.setpoint_age_us = Some(age0 + k * 1000);
            self.tick();
        }
        self.last
    }
}

// ---------------------------------------------------------------------------------------------------------
// Arming.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn auto_arms_when_upright_valid_and_stopped() {
    let mut b = Bench::new();
    let out = b.tick();
    assert_eq!(out.state, SupervisorState::Armed);
    assert!(out.motors_allowed && !out.flying);
    assert_eq!(out.reason, Reason::None);
    // No setpoint ever received counts as Stop.
    let mut b = Bench::new();
    b.input.setpoint = hold(0.5);
    b.input.setpoint_age_us = None;
    assert_eq!(b.tick().state, SupervisorState::Armed);
}

#[test]
fn thrust_lock_needs_a_stop_before_arming() {
    let mut b = Bench::new();
    b.input.setpoint = hold(0.5);
    let out = b.run(50);
    assert_eq!(out.state, SupervisorState::Idle);
    assert_eq!(out.reason, Reason::WaitingForStop);
    assert!(!out.motors_allowed);
    b.input.setpoint = Setpoint::Stop;
    assert_eq!(b.tick().state, SupervisorState::Armed);
    b.input.setpoint = hold(0.5);
    assert_eq!(b.tick().state, SupervisorState::Armed, "no motor running yet");
    b.input.thrust_cmd = [1, 0, 0, 0];
    let out = b.tick();
    assert_eq!(out.state, SupervisorState::Flying);
    assert!(out.flying && out.motors_allowed);
}

#[test]
fn preflight_checks_block_arming() {
    // Tilted on the bench.
    let mut b = Bench::new();
    b.input.accel_m_s2 = [0.0, 0.8 * G, 0.4 * G];
    assert_eq!(b.tick().reason, Reason::NotUpright);
    assert!(!b.last.motors_allowed);
    // Estimate not valid.
    let mut b = Bench::new();
    b.input.estimate.valid = false;
    assert_eq!(b.tick().reason, Reason::EstimateInvalid);
    b.input.estimate.valid = true;
    assert_eq!(b.tick().state, SupervisorState::Armed);
    // Armed, then the estimate goes bad: back to Idle.
    b.input.estimate.valid = false;
    assert_eq!(b.tick().state, SupervisorState::Idle);
    // No accelerometer sample yet.
    let mut b = Bench::new();
    b.input.accel_m_s2 = [f32::NAN; 3];
    assert_eq!(b.tick().reason, Reason::NotUpright);
}

#[test]
fn manual_arming_and_disarm_in_flight() {
    let cfg = SupervisorConfig {
        auto_arm: false,
        ..SupervisorConfig::default()
    };
    let mut b = Bench::with_config(cfg);
    assert_eq!(b.run(10).reason, Reason::NotArmed);
    b.input.arm_request = true;
    assert_eq!(b.tick().state, SupervisorState::Armed);
    b.input.setpoint = hold(0.5);
    b.input.thrust_cmd = [HOVER_CMD; 4];
    assert_eq!(b.tick().state, SupervisorState::Flying);
    b.input.arm_request = false;
    let out = b.tick();
    assert_eq!(out.state, SupervisorState::Idle);
    assert_eq!(out.reason, Reason::NotArmed);
    assert!(!out.motors_allowed);
    // Auto-arm ignores the request.
    let mut b = Bench::new();
    b.input.arm_request = false;
    assert_eq!(b.tick().state, SupervisorState::Armed);
}

// ---------------------------------------------------------------------------------------------------------
// Setpoint watchdog.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn stale_setpoint_levels_out_at_500_ms() {
    let mut b = Bench::flying();
    b.input.setpoint_age_us = Some(500_000);
    let out = b.tick();
    assert!(!out.level_out && !out.flags.contains(SupervisorFlags::SETPOINT_STALE));
    assert_eq!(b.sup.guard_setpoint(hold(0.5)), hold(0.5));
    b.input.setpoint_age_us = Some(500_001);
    let out = b.tick();
    assert!(out.level_out && out.flags.contains(SupervisorFlags::SETPOINT_STALE));
    assert_eq!(out.state, SupervisorState::Flying);
    assert!(out.motors_allowed);
    // Level out: zero velocity at the last fresh setpoint's height and heading.
    assert_eq!(
        b.sup.guard_setpoint(hold(0.9)),
        Setpoint::Velocity {
            vx_m_s: 0.0,
            vy_m_s: 0.0,
            z_m: 0.5,
            yaw_rad: 0.3
        }
    );
    // Fresh again: back to normal.
    b.input.setpoint_age_us = Some(10_000);
    let out = b.tick();
    assert!(!out.level_out);
    assert_eq!(b.sup.guard_setpoint(hold(0.9)), hold(0.9));
}

/// A Stop that goes stale stays a Stop: stock's level-out keeps the setpoint's z mode and a stop setpoint
/// has none, so a drone stopped in the air falls; it must not climb back to the height it held before.
#[test]
fn a_stale_stop_stays_a_stop() {
    let mut b = Bench::flying();
    b.input.setpoint_age_us = Some(10_000);
    b.tick();
    b.input.setpoint = Setpoint::Stop;
    b.input.setpoint_age_us = Some(600_000);
    let out = b.tick();
    assert!(out.level_out && out.motors_allowed);
    assert_eq!(b.sup.guard_setpoint(Setpoint::Stop), Setpoint::Stop);
}

#[test]
fn stale_descend_holds_the_current_height() {
    let mut b = Bench::flying();
    b.input.setpoint = LAND;
    b.input.estimate = at_height(0.12);
    b.tick();
    b.input.setpoint_age_us = Some(600_000);
    assert!(b.tick().level_out);
    match b.sup.guard_setpoint(LAND) {
        Setpoint::Velocity {
            z_m, vx_m_s, vy_m_s, ..
        } => {
            assert_eq!((vx_m_s, vy_m_s), (0.0, 0.0));
            assert!(
                (z_m - 0.12).abs() < 1e-6,
                "holds where it is, does not climb to the minimum: {z_m}"
            );
        }
        other => panic!("expected a hold, got {other:?}"),
    }
}

#[test]
fn setpoint_timeout_locks_at_2_s_and_latches() {
    let mut b = Bench::flying();
    let out = b.run_aging(1_000_000, 1001); // ages 1.000 .. 2.000 s
    assert_eq!(out.state, SupervisorState::Flying, "2.000 s is not yet a timeout");
    b.input.setpoint_age_us = Some(2_000_001);
    let out = b.tick();
    assert_eq!(out.state, SupervisorState::Locked);
    assert_eq!(out.reason, Reason::SetpointTimeout);
    assert!(!out.motors_allowed && !out.flying);
    assert_eq!(b.sup.guard_setpoint(hold(0.5)), Setpoint::Stop);
    // Latched: fresh setpoints, Stop, upright — still locked.
    b.input.setpoint_age_us = Some(0);
    b.input.setpoint = Setpoint::Stop;
    b.input.thrust_cmd = [0; 4];
    assert_eq!(b.run(3000).state, SupervisorState::Locked);
    b.sup.reset();
    assert_eq!(b.tick().state, SupervisorState::Armed);
}

#[test]
fn watchdog_only_applies_in_flight() {
    let mut b = Bench::new();
    b.input.setpoint_age_us = Some(10_000_000);
    let out = b.run(10);
    assert_eq!(out.state, SupervisorState::Armed);
    assert!(!out.level_out);
}

// ---------------------------------------------------------------------------------------------------------
// Tumble detection.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn tilt_for_more_than_1_s_crashes() {
    let mut b = Bench::flying();
    b.input.accel_m_s2 = [0.0, 0.85 * G, 0.45 * G];
    let out = b.run(1001); // tilt samples at 0 .. 1000 ms after the first
    assert_eq!(out.state, SupervisorState::Flying, "exactly 1 s tilted is allowed");
    assert!(out.flags.contains(SupervisorFlags::TILTED));
    let out = b.tick();
    assert_eq!(out.state, SupervisorState::Crashed);
    assert_eq!(out.reason, Reason::Tumbled);
    assert!(!out.motors_allowed);
    // Latched.
    b.input.accel_m_s2 = LEVEL;
    b.input.thrust_cmd = [0; 4];
    b.input.setpoint = Setpoint::Stop;
    assert_eq!(b.run(5000).state, SupervisorState::Crashed);
    assert_eq!(b.sup.guard_setpoint(hold(0.5)), Setpoint::Stop);
    b.sup.reset();
    assert_eq!(b.tick().state, SupervisorState::Armed);
}

#[test]
fn upside_down_for_more_than_100_ms_crashes() {
    let mut b = Bench::flying();
    b.input.accel_m_s2 = [0.0, 0.0, -0.5 * G];
    let out = b.run(101);
    assert_eq!(
        out.state,
        SupervisorState::Flying,
        "exactly 100 ms upside down is allowed"
    );
    assert!(out.flags.contains(SupervisorFlags::UPSIDE_DOWN));
    assert_eq!(b.tick().state, SupervisorState::Crashed);
}

#[test]
fn upside_down_timer_is_separate_from_the_tilt_timer() {
    let mut b = Bench::flying();
    b.input.accel_m_s2 = [0.0, 0.9 * G, 0.2 * G]; // tilted, not upside down
    b.run(500);
    b.input.accel_m_s2 = [0.0, 0.0, -0.3 * G];
    assert_eq!(b.run(101).state, SupervisorState::Flying);
    assert_eq!(b.tick().state, SupervisorState::Crashed);
}

#[test]
fn upright_sample_or_free_fall_resets_the_timers() {
    let mut b = Bench::flying();
    let tilted = [0.0, 0.85 * G, 0.45 * G];
    for reset in [LEVEL, [0.05 * G, 0.0, 0.02 * G]] {
        b.input.accel_m_s2 = tilted;
        b.run(900);
        b.input.accel_m_s2 = reset;
        b.tick();
    }
    b.input.accel_m_s2 = tilted;
    assert_eq!(b.run(1000).state, SupervisorState::Flying);
    // Long free fall is not a tumble.
    b.input.accel_m_s2 = [0.01, -0.02, 0.03];
    let out = b.run(3000);
    assert_eq!(out.state, SupervisorState::Flying);
    assert!(out.flags.contains(SupervisorFlags::FREE_FALL));
    // Free fall at the upside-down boundary also resets.
    b.input.accel_m_s2 = [0.0, 0.0, -0.5 * G];
    b.run(90);
    b.input.accel_m_s2 = [0.0, 0.0, 0.0];
    b.tick();
    b.input.accel_m_s2 = [0.0, 0.0, -0.5 * G];
    assert_eq!(b.run(100).state, SupervisorState::Flying);
}

#[test]
fn garbage_accel_neither_masks_nor_causes_a_tumble() {
    let garbage = [
        [f32::NAN, 0.0, G],
        [0.0, 0.0, f32::INFINITY],
        [0.0, 0.0, -1e6],
        [f32::NEG_INFINITY; 3],
    ];
    for bad in garbage {
        // Does not mask: tilted 500 ms, then garbage; the timer keeps running and fires on time.
        let mut b = Bench::flying();
        b.input.accel_m_s2 = [0.0, 0.85 * G, 0.45 * G];
        b.run(500);
        b.input.accel_m_s2 = bad;
        let out = b.run(501);
        assert_eq!(out.state, SupervisorState::Flying);
        assert!(out.flags.contains(SupervisorFlags::ACCEL_INVALID));
        assert_eq!(
            b.tick().state,
            SupervisorState::Crashed,
            "garbage {bad:?} masked a tumble"
        );
        // Does not cause: upright, then garbage for 1 s (the fault limit) is not a crash.
        let mut b = Bench::flying();
        b.input.accel_m_s2 = bad;
        let out = b.run(1000);
        assert_eq!(out.state, SupervisorState::Flying, "garbage {bad:?} caused a crash");
        assert!(!out.flags.contains(SupervisorFlags::ACCEL_FAULT));
        // A valid sample in between keeps it alive.
        b.input.accel_m_s2 = LEVEL;
        b.tick();
        b.input.accel_m_s2 = bad;
        assert_eq!(b.run(900).state, SupervisorState::Flying);
    }
}

#[test]
fn dead_accelerometer_for_more_than_1_s_is_a_crash() {
    let mut b = Bench::flying();
    b.input.accel_m_s2 = LEVEL;
    b.tick(); // last good sample at t
    b.input.accel_m_s2 = [f32::NAN; 3];
    let out = b.run(1000); // t+1 .. t+1000 ms
    assert_eq!(out.state, SupervisorState::Flying);
    let out = b.tick(); // t + 1001 ms
    assert_eq!(out.state, SupervisorState::Crashed);
    assert_eq!(out.reason, Reason::AccelFault);
    assert!(out.flags.contains(SupervisorFlags::ACCEL_FAULT));
    // Before flight the same fault blocks arming.
    let mut b = Bench::new();
    b.tick();
    b.input.accel_m_s2 = [f32::NAN; 3];
    let out = b.run(1002);
    assert_eq!(out.state, SupervisorState::Idle);
    assert_eq!(out.reason, Reason::AccelFault);
}

#[test]
fn tumble_before_flight_blocks_arming_without_latching() {
    let mut b = Bench::new();
    assert_eq!(b.tick().state, SupervisorState::Armed);
    b.input.accel_m_s2 = [0.0, 0.0, -G];
    let out = b.run(5);
    assert_eq!(out.state, SupervisorState::Idle, "not upright: disarmed at once");
    let out = b.run(200);
    assert_eq!(out.reason, Reason::Tumbled);
    b.input.accel_m_s2 = LEVEL;
    assert_eq!(b.tick().state, SupervisorState::Armed, "upright again: armed again");
}

// ---------------------------------------------------------------------------------------------------------
// Touchdown.
// ---------------------------------------------------------------------------------------------------------

/// Flying, then sitting on a surface of height `surface` with a Descend setpoint and low thrust.
fn touched_down(surface: f32) -> Bench {
    let mut b = Bench::flying();
    b.input.setpoint = LAND;
    b.input.estimate = at_height(surface + 0.01);
    b.input.estimate.surface_height_m = surface;
    b.input.thrust_cmd = [(0.8 * f32::from(HOVER_CMD)) as u16; 4];
    b
}

#[test]
fn touchdown_after_300_ms_lands() {
    let mut b = touched_down(0.0);
    let out = b.run(301);
    assert_eq!(
        out.state,
        SupervisorState::Flying,
        "exactly 300 ms is not yet a landing"
    );
    assert!(out.flags.contains(SupervisorFlags::TOUCHDOWN));
    let out = b.tick();
    assert_eq!(out.state, SupervisorState::Landed);
    assert_eq!(out.reason, Reason::Touchdown);
    assert!(!out.motors_allowed);
    assert_eq!(b.sup.guard_setpoint(LAND), Setpoint::Stop);
    // Stays landed until the mission sends Stop, then re-arms and can take off again.
    b.input.thrust_cmd = [0; 4];
    assert_eq!(b.run(1000).state, SupervisorState::Landed);
    b.input.setpoint = Setpoint::Stop;
    assert_eq!(b.tick().state, SupervisorState::Armed);
    b.input.setpoint = hold(0.5);
    b.input.thrust_cmd = [HOVER_CMD; 4];
    assert_eq!(b.tick().state, SupervisorState::Flying);
}

#[test]
fn touchdown_on_a_pad_uses_the_surface_height() {
    let mut b = touched_down(0.1);
    assert_eq!(b.run(302).state, SupervisorState::Landed);
    // 11 cm above the floor over the floor is not a touchdown.
    let mut b = touched_down(0.1);
    b.input.estimate.surface_height_m = 0.0;
    assert_eq!(b.run(1000).state, SupervisorState::Flying);
}

#[test]
fn touchdown_needs_every_condition() {
    type Spoil = fn(&mut Bench);
    let spoilers: [(&str, Spoil); 7] = [
        ("too high", |b| b.input.estimate.position_m[2] = 0.031),
        ("moving", |b| b.input.estimate.velocity_m_s[2] = -0.15),
        ("hover thrust", |b| b.input.thrust_cmd = [HOVER_CMD; 4]),
        ("holding height", |b| b.input.setpoint = hold(0.5)),
        ("climbing", |b| {
            b.input.setpoint = Setpoint::Descend {
                x_m: 1.0,
                y_m: 1.0,
                vz_m_s: 0.1,
                yaw_rad: 0.0,
            }
        }),
        ("garbage height", |b| b.input.estimate.position_m[2] = f32::NAN),
        ("garbage speed", |b| b.input.estimate.velocity_m_s[2] = f32::INFINITY),
    ];
    for (what, spoil) in spoilers {
        let mut b = touched_down(0.0);
        spoil(&mut b);
        assert_eq!(b.run(2000).state, SupervisorState::Flying, "{what}");
    }
    // An interruption restarts the 300 ms.
    let mut b = touched_down(0.0);
    b.run(250);
    b.input.thrust_cmd = [HOVER_CMD; 4];
    b.tick();
    b.input.thrust_cmd = [(0.8 * f32::from(HOVER_CMD)) as u16; 4];
    assert_eq!(b.run(301).state, SupervisorState::Flying);
    assert_eq!(b.tick().state, SupervisorState::Landed);
    // A Position setpoint at the surface is a landing intent too.
    let mut b = touched_down(0.0);
    b.input.setpoint = hold(0.0);
    assert_eq!(b.run(302).state, SupervisorState::Landed);
}

#[test]
fn hover_command_is_learned() {
    let mut b = Bench::flying();
    b.input.thrust_cmd = [40000; 4];
    b.run(15_000);
    let learned = b.sup.hover_cmd();
    println!("learned hover command after 15 s at 40000: {learned:.0}");
    assert!((learned - 40000.0).abs() < 100.0);
    // The touchdown threshold follows: 0.9 × 40000 = 36000, so 37000 is not low, 35000 is.
    let mut b2 = b;
    b2.input.setpoint = LAND;
    b2.input.estimate = at_height(0.01);
    b2.input.thrust_cmd = [37000; 4];
    assert_eq!(b2.run(1000).state, SupervisorState::Flying);
    b2.input.thrust_cmd = [35000; 4];
    assert_eq!(b2.run(400).state, SupervisorState::Landed);
}

/// cflib's `MotionCommander.land`: one stop setpoint in the air (0.2 m, the velocity floor) and nothing
/// more. The stop ages past 2 s while no touchdown is seen: that is a landing (motors stopped), not a
/// setpoint-timeout lock (which refused the next take-off until a reboot).
#[test]
fn an_aging_stop_setpoint_lands_instead_of_locking() {
    let mut b = Bench::flying();
    b.input.setpoint = Setpoint::Stop;
    b.input.thrust_cmd = [0; 4];
    b.input.estimate = at_height(0.2);
    let mut states = Vec::new();
    for k in 0..2100u64 {
        b.input.setpoint_age_us = Some(k * 1000);
        let state = b.tick().state;
        if states.last() != Some(&state) {
            states.push(state);
        }
    }
    // Landed (motors stopped for 2 s), and with the setpoint Stop the pre-flight rules re-arm at once: ready
    // for the next take-off, never Locked.
    assert_eq!(
        states,
        vec![SupervisorState::Flying, SupervisorState::Landed, SupervisorState::Armed],
        "{:?}",
        b.last
    );
    assert!(b.last.motors_allowed);
}

#[test]
fn motors_stopped_in_flight_for_2_s_is_a_landing() {
    let mut b = Bench::flying();
    b.input.thrust_cmd = [0; 4];
    let out = b.run(2001);
    assert_eq!(out.state, SupervisorState::Flying);
    let out = b.tick();
    assert_eq!(out.state, SupervisorState::Landed);
    assert_eq!(out.reason, Reason::MotorsStopped);
}

// ---------------------------------------------------------------------------------------------------------
// Battery.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn battery_low_after_5_s_below_3_2_v_and_latches() {
    let mut b = Bench::new();
    b.input.battery_v = 3.1; // the first reading initialises the filter
    let out = b.run(5001); // 0 .. 5000 ms
    assert!(!out.battery_low, "exactly 5 s is not yet low");
    let out = b.tick();
    assert!(out.battery_low && out.flags.contains(SupervisorFlags::BATTERY_LOW));
    // Latched: the voltage recovers when the motors stop.
    b.input.battery_v = 4.0;
    assert!(b.run(10_000).battery_low);
    b.sup.reset();
    assert!(!b.tick().battery_low);
}

#[test]
fn battery_filter_rides_through_sag() {
    let mut b = Bench::new();
    b.input.battery_v = 3.8;
    b.tick();
    // Load spikes: 3.0 V for 1 ms out of 3 (mean 3.53 V) for 30 s.
    for k in 0..30_000 {
        b.input.battery_v = if k % 3 == 0 { 3.0 } else { 3.8 };
        b.tick();
    }
    assert!(!b.last.battery_low);
    assert!(
        (b.last.battery_v_filtered - 3.53).abs() < 0.05,
        "{}",
        b.last.battery_v_filtered
    );
    // A 3 s dip is not enough either.
    b.input.battery_v = 3.0;
    b.run(3000);
    b.input.battery_v = 3.8;
    assert!(!b.run(10_000).battery_low);
    // A real drop: 3.8 → 3.1 V. The filter crosses 3.2 V after ≈ τ·ln(7) ≈ 1.95 s, then 5 s more.
    b.input.battery_v = 3.1;
    assert!(!b.run(6_500).battery_low);
    assert!(b.run(1_000).battery_low);
}

/// A collapsing cell latches within a second: 3.6 → 2.8 V, the filter (τ = 1 s) crosses 3.0 V after
/// τ·ln(4) ≈ 1.39 s and the latch follows 0.5 s later, not 5 s after it crossed 3.2 V (0.69 s in).
/// A dip that stays at 3.0 V, or a filtered voltage at 3.05 V for a minute, is only low after the 5 s.
#[test]
fn a_collapsing_battery_latches_low_half_a_second_below_3_0_v() {
    let mut b = Bench::new();
    b.input.battery_v = 3.6;
    b.tick();
    b.input.battery_v = 2.8;
    assert!(!b.run(1_800).battery_low, "the filter is not below 3.0 V for 0.5 s yet");
    assert!(b.run(200).battery_low, "1.39 s + 0.5 s after the drop");
    assert!(b.last.flags.contains(SupervisorFlags::BATTERY_LOW));
    // Just above the critical level: the 3.2 V rule's 5 s, measured from the filter's crossing of 3.2 V.
    let mut b = Bench::new();
    b.input.battery_v = 3.6;
    b.tick();
    b.input.battery_v = 3.05;
    assert!(!b.run(5_500).battery_low, "above 3.0 V the 5 s rule holds");
    assert!(b.run(1_000).battery_low);
}

#[test]
fn garbage_battery_readings_are_ignored() {
    let mut b = Bench::new();
    b.input.battery_v = 3.9;
    b.tick();
    for bad in [f32::NAN, f32::INFINITY, -1.0, 100.0] {
        b.input.battery_v = bad;
        let out = b.run(2000);
        assert!(out.flags.contains(SupervisorFlags::BATTERY_INVALID));
        assert!((out.battery_v_filtered - 3.9).abs() < 1e-5);
        assert!(!out.battery_low);
    }
}

// ---------------------------------------------------------------------------------------------------------
// Builders, time, misc.
// ---------------------------------------------------------------------------------------------------------

#[test]
fn minimum_height_clamp() {
    assert_eq!(clamp_min_height(hold(0.1), 0.2), hold(0.2));
    assert_eq!(clamp_min_height(hold(0.5), 0.2), hold(0.5));
    assert_eq!(clamp_min_height(hold(f32::NAN), 0.2), hold(0.2));
    let v = Setpoint::Velocity {
        vx_m_s: 0.3,
        vy_m_s: 0.0,
        z_m: -1.0,
        yaw_rad: 0.0,
    };
    assert_eq!(
        clamp_min_height(v, 0.2),
        Setpoint::Velocity {
            vx_m_s: 0.3,
            vy_m_s: 0.0,
            z_m: 0.2,
            yaw_rad: 0.0
        }
    );
    assert_eq!(clamp_min_height(LAND, 0.2), LAND);
    assert_eq!(clamp_min_height(Setpoint::Stop, 0.2), Setpoint::Stop);
    // The guard applies it while the motors are allowed, and Stop otherwise.
    let mut b = Bench::new();
    b.input.accel_m_s2 = [0.0, 0.0, -G];
    b.tick();
    assert_eq!(b.sup.guard_setpoint(hold(0.5)), Setpoint::Stop);
    let b = Bench::flying();
    assert_eq!(b.sup.guard_setpoint(hold(0.05)), hold(0.2));
}

#[test]
fn time_running_backwards_does_not_fire_timers() {
    let mut b = Bench::flying();
    b.input.accel_m_s2 = [0.0, 0.0, -0.5 * G];
    b.run(50);
    b.input.now = 1_000; // clock jumps back
    let out = b.run(60);
    assert_eq!(out.state, SupervisorState::Flying);
    b.input.now = u64::MAX - 10;
    let out = b.sup.update(&b.input);
    assert_eq!(
        out.state,
        SupervisorState::Crashed,
        "a huge jump forward counts as elapsed time"
    );
}

#[test]
fn invalid_estimate_in_flight_is_reported_not_acted_on() {
    let mut b = Bench::flying();
    b.input.estimate.valid = false;
    let out = b.run(1000);
    assert_eq!(out.state, SupervisorState::Flying);
    assert!(out.flags.contains(SupervisorFlags::ESTIMATE_INVALID));
}

#[test]
fn memory_footprint() {
    println!("Supervisor: {} bytes", std::mem::size_of::<Supervisor>());
    assert!(std::mem::size_of::<Supervisor>() <= 320);
}
