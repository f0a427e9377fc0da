//! The high-level commander's trajectory follower: the 7th-order rest-to-rest polynomial against its
//! closed form's boundary conditions (numerical derivatives), durations honoured, relative and linear
//! go-tos, refusals leaving everything unchanged, landing handing over to a descent.

use cfnav::flight::high_level::{HighLevel, HlCommand, HlPhase, HlRefusal, LAND_HANDOVER_M, smooth_step};
use cfnav::types::{Setpoint, StateEstimate};

fn at(x: f32, y: f32, z: f32, yaw: f32) -> StateEstimate {
    StateEstimate {
        position_m: [x, y, z],
        attitude_rad: [0.0, 0.0, yaw],
        valid: true,
        ..StateEstimate::default()
    }
}

fn assert_near(a: [f32; 4], b: [f32; 4]) {
    assert!(a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5), "{a:?} != {b:?}");
}

fn pos(sp: Option<Setpoint>) -> [f32; 4] {
    match sp {
        Some(Setpoint::Position { x_m, y_m, z_m, yaw_rad }) => [x_m, y_m, z_m, yaw_rad],
        other => panic!("expected a position setpoint, got {other:?}"),
    }
}

#[test]
fn the_smooth_step_starts_and_ends_at_rest() {
    let h = 1e-3f32;
    assert_eq!(smooth_step(0.0), 0.0);
    assert!((smooth_step(1.0) - 1.0).abs() < 1e-6);
    assert!((smooth_step(0.5) - 0.5).abs() < 1e-6, "symmetric");
    for t in [0.0f32, 1.0] {
        // Velocity, acceleration (central differences on the clamped polynomial) vanish at both ends.
        let v = (smooth_step(t + h) - smooth_step(t - h)) / (2.0 * h);
        // f32 rounding of the polynomial near τ = 1 is ~1e-6 over a 2e-3 step.
        assert!(v.abs() < 5e-3, "velocity {v} at {t}");
    }
    // Monotonic and peak speed 35/16 = 2.1875 (at τ = 0.5) of the mean speed.
    let mut prev = 0.0;
    for i in 1..=1000 {
        let s = smooth_step(i as f32 / 1000.0);
        assert!(s >= prev);
        prev = s;
    }
    let v_mid = (smooth_step(0.5 + h) - smooth_step(0.5 - h)) / (2.0 * h);
    assert!((v_mid - 2.1875).abs() < 1e-2, "{v_mid}");
}

#[test]
fn takeoff_go_to_and_land_honour_their_durations() {
    let mut hl = HighLevel::new();
    let ground = at(1.0, 2.0, 0.0, 0.3);
    assert_eq!(hl.setpoint(0), None);
    // Go-to and land need a flight first; nothing changes.
    let go = HlCommand::GoTo {
        position_m: [0.5, 0.0, 0.0],
        yaw_rad: 0.0,
        duration_s: 1.0,
        relative: true,
        linear: false,
    };
    assert_eq!(hl.command(go, 0, &ground), Err(HlRefusal::NotFlying));
    assert_eq!(hl.phase(), HlPhase::Idle);
    hl.command(
        HlCommand::Takeoff {
            height_m: 0.5,
            yaw_rad: None,
            duration_s: 2.0,
        },
        1_000_000,
        &ground,
    )
    .unwrap();
    assert_near(pos(hl.setpoint(1_000_000)), [1.0, 2.0, 0.0, 0.3]);
    let mid = pos(hl.setpoint(2_000_000));
    assert!((mid[2] - 0.25).abs() < 1e-5, "{mid:?}");
    assert!(!hl.finished(2_999_999));
    assert!(hl.finished(3_000_000));
    assert_near(pos(hl.setpoint(3_000_000)), [1.0, 2.0, 0.5, 0.3]);
    assert_near(pos(hl.setpoint(9_000_000)), [1.0, 2.0, 0.5, 0.3]);
    // Relative go-to from the held point, 1 s: +0.5 m in x.
    hl.command(go, 10_000_000, &ground).unwrap();
    assert_near(pos(hl.setpoint(11_000_000)), [1.5, 2.0, 0.5, 0.3]);
    // Linear absolute go-to: constant speed, a quarter of the way after a quarter of the time.
    let lin = HlCommand::GoTo {
        position_m: [2.5, 2.0, 0.5],
        yaw_rad: 0.3,
        duration_s: 4.0,
        relative: false,
        linear: true,
    };
    hl.command(lin, 12_000_000, &ground).unwrap();
    let q = pos(hl.setpoint(13_000_000));
    assert!((q[0] - 1.75).abs() < 1e-5, "{q:?}");
    // Bad durations and targets change nothing.
    let before = hl;
    for d in [-1.0, f32::NAN, f32::INFINITY, 601.0] {
        let bad = HlCommand::Land {
            height_m: 0.0,
            yaw_rad: None,
            duration_s: d,
        };
        assert_eq!(hl.command(bad, 14_000_000, &ground), Err(HlRefusal::BadDuration));
    }
    assert_eq!(hl, before);
    // Land from 0.5 m in 2 s: a position setpoint above the hand-over height, a descent below it.
    hl.command(
        HlCommand::Land {
            height_m: 0.0,
            yaw_rad: None,
            duration_s: 2.0,
        },
        16_000_000,
        &ground,
    )
    .unwrap();
    assert_eq!(hl.phase(), HlPhase::Landing);
    assert!(pos(hl.setpoint(16_500_000))[2] > LAND_HANDOVER_M);
    assert!(matches!(
        hl.setpoint(17_900_000),
        Some(Setpoint::Descend { vz_m_s, .. }) if vz_m_s < 0.0
    ));
    hl.command(HlCommand::Stop, 18_000_000, &ground).unwrap();
    assert_eq!(hl.setpoint(18_000_000), None);
    assert!(!hl.is_active());
}
