//! Reactive avoidance tests: directions, magnitudes, hysteresis, clamp, smoothing, both methods, garbage.

use std::f32::consts::{FRAC_PI_2, PI};

use cfnav::nav::avoidance::{
    AvoidanceCommand, AvoidanceConfig, AvoidanceConfigError, AvoidanceMethod, RangerReadings, ReactiveAvoidance,
    SpeedClamp,
};
use proptest::prelude::*;

const DT: f32 = 0.01;
const METHODS: [AvoidanceMethod; 2] = [AvoidanceMethod::PotentialField, AvoidanceMethod::VirtualForceField];

/// No smoothing, so one step shows the raw command.
fn raw_config(method: AvoidanceMethod) -> AvoidanceConfig {
    AvoidanceConfig {
        method,
        smoothing_tau_s: 0.0,
        ..AvoidanceConfig::default()
    }
}

fn avoider(cfg: AvoidanceConfig) -> ReactiveAvoidance {
    ReactiveAvoidance::new(cfg).expect("valid config")
}

fn front(d: f32) -> RangerReadings {
    RangerReadings {
        front: Some(d),
        ..RangerReadings::NONE
    }
}

fn speed(c: &AvoidanceCommand) -> f32 {
    c.vx.hypot(c.vy)
}

fn repulsion(c: &AvoidanceCommand) -> f32 {
    c.repulsion_x.hypot(c.repulsion_y)
}

/// The unit vector a ranger's repulsion should point along in the arena frame: minus its beam.
fn away_from(beam_body: (f32, f32), yaw: f32) -> (f32, f32) {
    let (s, c) = yaw.sin_cos();
    (
        -(c * beam_body.0 - s * beam_body.1),
        -(s * beam_body.0 + c * beam_body.1),
    )
}

#[test]
fn front_obstacle_at_yaw_0_pushes_minus_x() {
    for method in METHODS {
        let out = avoider(raw_config(method)).step(&front(0.2), 0.0, 0.0, 0.0, DT);
        assert!(out.active, "{method:?}");
        assert!(
            out.repulsion_x < -0.05 && out.repulsion_y.abs() < 1e-6,
            "{method:?}: {out:?}"
        );
        assert!(out.vx < 0.0 && out.vy.abs() < 1e-6, "{method:?}: {out:?}");
        assert_eq!(out.nearest_m, Some(0.2));
    }
}

#[test]
fn front_obstacle_at_yaw_90_pushes_minus_y() {
    for method in METHODS {
        let out = avoider(raw_config(method)).step(&front(0.2), FRAC_PI_2, 0.0, 0.0, DT);
        assert!(
            out.repulsion_y < -0.05 && out.repulsion_x.abs() < 1e-6,
            "{method:?}: {out:?}"
        );
        assert!(out.vy < 0.0 && out.vx.abs() < 1e-6, "{method:?}: {out:?}");
    }
}

#[test]
fn each_ranger_pushes_away_from_its_beam_at_any_yaw() {
    let beams = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)];
    for method in METHODS {
        for k in 0..36 {
            let yaw = -PI + k as f32 * PI / 18.0;
            for (i, beam) in beams.iter().enumerate() {
                let mut r = [None; 4];
                r[i] = Some(0.15);
                let readings = RangerReadings::new(r[0], r[1], r[2], r[3]);
                let out = avoider(raw_config(method)).step(&readings, yaw, 0.0, 0.0, DT);
                let want = away_from(*beam, yaw);
                let n = repulsion(&out);
                assert!(n > 0.0);
                let cos = (out.repulsion_x * want.0 + out.repulsion_y * want.1) / n;
                assert!(cos > 0.9999, "{method:?} yaw {yaw} ranger {i}: {out:?}");
            }
        }
    }
}

#[test]
fn symmetric_obstacles_cancel() {
    for method in METHODS {
        for readings in [
            RangerReadings::new(Some(0.2), Some(0.2), None, None),
            RangerReadings::new(None, None, Some(0.1), Some(0.1)),
            RangerReadings::new(Some(0.3), Some(0.3), Some(0.25), Some(0.25)),
        ] {
            let out = avoider(raw_config(method)).step(&readings, 0.7, 0.0, 0.0, DT);
            assert!(repulsion(&out) < 1e-6, "{method:?}: {out:?}");
            assert!(speed(&out) < 1e-6);
        }
    }
}

#[test]
fn no_force_outside_the_danger_distance() {
    for method in METHODS {
        let cfg = raw_config(method);
        for d in [cfg.danger_distance_m + 0.001, 0.5, 0.79, 1.5, 3.9] {
            // (Desired speed below the clamp's minimum, so the clamp does not interfere.)
            let out = avoider(cfg).step(&front(d), 0.3, 0.05, -0.03, DT);
            assert_eq!((out.repulsion_x, out.repulsion_y), (0.0, 0.0), "{method:?} d {d}");
            assert!(!out.active);
            assert!(
                (out.vx - 0.05).abs() < 1e-6 && (out.vy + 0.03).abs() < 1e-6,
                "{method:?} d {d}: {out:?}"
            );
        }
    }
}

#[test]
fn potential_field_magnitude_follows_the_seed_law_and_grows_closer() {
    let cfg = raw_config(AvoidanceMethod::PotentialField);
    let d0 = cfg.danger_distance_m;
    let mut a = avoider(cfg);
    let mut last = 0.0f32;
    // Approach a wall from 0.6 m to 1 cm.
    for i in 0..60 {
        let d = 0.6 - 0.01 * i as f32;
        let out = a.step(&front(d), 0.0, 0.0, 0.0, DT);
        let f = if d < d0 { ((d0 - d) / d0).powi(2) } else { 0.0 };
        let m = repulsion(&out);
        if f > cfg.dead_band {
            assert!(
                (m - cfg.gain_mps * f).abs() < 1e-5,
                "d {d}: {m} vs {}",
                cfg.gain_mps * f
            );
            assert!(m > last, "d {d}: must grow");
        } else if !out.active {
            assert_eq!(m, 0.0, "d {d}: inside the dead band");
        }
        last = m;
    }
}

#[test]
fn virtual_force_field_saturates_and_grows_closer() {
    let cfg = raw_config(AvoidanceMethod::VirtualForceField);
    let d0 = cfg.danger_distance_m;
    let mut last = 0.0f32;
    for i in 1..40 {
        let d = d0 - 0.01 * i as f32;
        let out = avoider(cfg).step(&front(d), 0.0, 0.0, 0.0, DT);
        let want = cfg.gain_mps * (cfg.vff_steepness * (d0 - d) / d).tanh();
        let m = repulsion(&out);
        if want / cfg.gain_mps > cfg.dead_band {
            assert!((m - want).abs() < 1e-5, "d {d}: {m} vs {want}");
            // Strictly growing until tanh saturates in f32, never above the gain.
            assert!(m > last || m >= cfg.gain_mps * 0.9999, "d {d}");
            assert!(m <= cfg.gain_mps, "d {d}");
        }
        last = m;
    }
    // Touching: saturated, finite.
    let out = avoider(cfg).step(&front(0.0), 0.0, 0.0, 0.0, DT);
    assert!((repulsion(&out) - cfg.gain_mps).abs() < 1e-3, "{out:?}");
}

#[test]
fn vff_damps_only_the_velocity_towards_the_obstacle() {
    // No repulsion and no clamp, to see the damping alone.
    let cfg = AvoidanceConfig {
        gain_mps: 0.0,
        min_speed_mps: 2.0,
        cruise_speed_mps: 2.0,
        ..raw_config(AvoidanceMethod::VirtualForceField)
    };
    let d0 = cfg.danger_distance_m;
    // Half-way into the danger zone: proximity 0.5, so the component towards the wall halves.
    let out = avoider(cfg).step(&front(d0 / 2.0), 0.0, 0.3, 0.2, DT);
    assert!((out.vx - 0.15).abs() < 1e-6 && (out.vy - 0.2).abs() < 1e-6, "{out:?}");
    assert!(out.active);
    // Flying away from the wall, or at yaw 90° where the front ranger looks along +y.
    let out = avoider(cfg).step(&front(d0 / 2.0), 0.0, -0.3, 0.2, DT);
    assert!((out.vx + 0.3).abs() < 1e-6 && (out.vy - 0.2).abs() < 1e-6, "{out:?}");
    let out = avoider(cfg).step(&front(d0 / 4.0), FRAC_PI_2, 0.3, 0.2, DT);
    assert!(
        (out.vx - 0.3).abs() < 1e-6 && (out.vy - 0.2 * 0.25).abs() < 1e-6,
        "{out:?}"
    );
    // The potential field does not damp.
    let pf = AvoidanceConfig {
        method: AvoidanceMethod::PotentialField,
        ..cfg
    };
    let out = avoider(pf).step(&front(d0 / 2.0), 0.0, 0.3, 0.2, DT);
    assert!((out.vx - 0.3).abs() < 1e-6, "{out:?}");
}

#[test]
fn hysteresis_keeps_avoidance_engaged_until_d0_plus_margin() {
    let cfg = raw_config(AvoidanceMethod::PotentialField);
    let (d0, h) = (cfg.danger_distance_m, cfg.hysteresis_m);
    let mut a = avoider(cfg);
    // A ranger just inside d0 makes a force inside the dead band: not engaged.
    assert!(!a.step(&front(d0 - 0.01), 0.0, 0.0, 0.0, DT).active);
    // Close in: engaged.
    assert!(a.step(&front(0.2), 0.0, 0.0, 0.0, DT).active);
    // Back out past d0 but within the hysteresis: still engaged (no force left, but no chatter).
    let out = a.step(&front(d0 + 0.5 * h), 0.0, 0.0, 0.0, DT);
    assert!(out.active && repulsion(&out) == 0.0, "{out:?}");
    // Just inside d0 again: engaged, so even a force below the dead band acts (continuously).
    let out = a.step(&front(d0 - 0.01), 0.0, 0.0, 0.0, DT);
    assert!(out.active && repulsion(&out) > 0.0, "{out:?}");
    // Beyond d0 + hysteresis: released.
    assert!(!a.step(&front(d0 + h + 0.01), 0.0, 0.0, 0.0, DT).active);
    assert!(!a.step(&front(d0 - 0.01), 0.0, 0.0, 0.0, DT).active);
}

#[test]
fn speed_limit_ramps_from_min_at_d0_to_cruise_at_slow_down() {
    let cfg = AvoidanceConfig::default();
    assert_eq!(cfg.speed_limit(None), cfg.cruise_speed_mps);
    assert_eq!(cfg.speed_limit(Some(0.0)), cfg.min_speed_mps);
    assert_eq!(cfg.speed_limit(Some(cfg.danger_distance_m)), cfg.min_speed_mps);
    assert_eq!(cfg.speed_limit(Some(cfg.slow_down_distance_m)), cfg.cruise_speed_mps);
    assert_eq!(cfg.speed_limit(Some(10.0)), cfg.cruise_speed_mps);
    let mid = 0.5 * (cfg.danger_distance_m + cfg.slow_down_distance_m);
    let want = 0.5 * (cfg.min_speed_mps + cfg.cruise_speed_mps);
    assert!((cfg.speed_limit(Some(mid)) - want).abs() < 1e-6);
    // A zero-length ramp is a step at d0.
    let step = AvoidanceConfig {
        slow_down_distance_m: cfg.danger_distance_m,
        ..cfg
    };
    assert_eq!(step.speed_limit(Some(cfg.danger_distance_m - 0.01)), cfg.min_speed_mps);
    assert_eq!(step.speed_limit(Some(cfg.danger_distance_m)), cfg.cruise_speed_mps);
}

#[test]
fn clamp_applies_to_the_nearest_valid_range() {
    for method in METHODS {
        let cfg = raw_config(method);
        let mut a = avoider(cfg);
        // Nearest is the left ranger at 0.6 m; the front one is garbage.
        let r = RangerReadings::new(Some(f32::NAN), Some(1.5), Some(0.6), None);
        let out = a.step(&r, 0.0, 2.0, 0.0, DT);
        assert_eq!(out.nearest_m, Some(0.6));
        assert!((out.speed_limit_mps - cfg.speed_limit(Some(0.6))).abs() < 1e-6);
        assert!(
            (speed(&out) - out.speed_limit_mps).abs() < 1e-5 && out.vx > 0.0,
            "{out:?}"
        );
        // Nothing seen: cruise speed.
        let out = a.step(&RangerReadings::NONE, 0.0, 2.0, 2.0, DT);
        assert!((speed(&out) - cfg.cruise_speed_mps).abs() < 1e-5);
    }
}

/// Brute-force oracle of [`SpeedClamp::TowardsEachRange`]: the largest scale `k` in [0, 1] (searched on a
/// 10⁻⁴ grid) for which `k·v` is no faster than cruise and approaches no ranger's obstacle faster than that
/// ranger's limit. Beam directions come from the yaw written out per ranger (front = yaw, left = yaw + π/2,
/// back = yaw + π, right = yaw − π/2).
fn oracle_towards_each_range(cfg: &AvoidanceConfig, ranges: [Option<f32>; 4], yaw: f32, v: (f64, f64)) -> f64 {
    let offsets = [0.0, PI, FRAC_PI_2, -FRAC_PI_2];
    let ok = |k: f64| {
        let (x, y) = (k * v.0, k * v.1);
        if x.hypot(y) > f64::from(cfg.cruise_speed_mps) + 1e-6 {
            return false;
        }
        ranges.iter().zip(offsets).all(|(r, off)| match r {
            Some(d) if d.is_finite() && *d >= 0.0 && *d <= cfg.max_range_m => {
                let a = f64::from(yaw + off);
                x * a.cos() + y * a.sin() <= f64::from(cfg.speed_limit(Some(*d))) + 1e-6
            }
            _ => true,
        })
    };
    (0..=10_000)
        .rev()
        .map(|i| f64::from(i) * 1e-4)
        .find(|k| ok(*k))
        .unwrap_or(0.0)
}

/// [`SpeedClamp::TowardsEachRange`] keeps the direction and scales exactly as far down as the brute force
/// finds necessary: a wall beside the drone no longer slows flight along it, one ahead still does.
#[test]
fn towards_each_range_clamp_matches_brute_force() {
    let cfg = AvoidanceConfig {
        smoothing_tau_s: 0.0,
        danger_distance_m: 0.2,
        slow_down_distance_m: 0.4,
        min_speed_mps: 0.2,
        cruise_speed_mps: 0.5,
        clamp: SpeedClamp::TowardsEachRange,
        ..AvoidanceConfig::default()
    };
    // Along a wall 0.25 m to the left: full cruise (the nearest-range clamp would allow 0.275 m/s).
    let mut a = avoider(cfg);
    let out = a.step(&RangerReadings::new(None, None, Some(0.25), None), 0.0, 0.5, 0.0, DT);
    assert!((out.vx - 0.5).abs() < 1e-6 && out.vy.abs() < 1e-6, "{out:?}");
    // Into a wall 0.3 m ahead: the limit there (0.35 m/s).
    let out = a.step(&RangerReadings::new(Some(0.3), None, None, None), 0.0, 0.5, 0.0, DT);
    assert!((out.vx - 0.35).abs() < 1e-5, "{out:?}");

    let mut rng = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut clamped = 0;
    for _ in 0..3000 {
        let range = |u: f64, w: f64| (u < 0.7).then_some((0.02 + w * 0.8) as f32);
        let ranges = [
            range(next(), next()),
            range(next(), next()),
            range(next(), next()),
            range(next(), next()),
        ];
        let yaw = ((next() * 2.0 - 1.0) * std::f64::consts::PI) as f32;
        let v = ((next() * 2.0 - 1.0) as f32 * 0.8, (next() * 2.0 - 1.0) as f32 * 0.8);
        // No repulsion: danger distance tiny, so the clamp alone shapes the command.
        let cfg = AvoidanceConfig {
            danger_distance_m: 0.01,
            hysteresis_m: 0.0,
            ..cfg
        };
        let mut a = avoider(cfg);
        let out = a.step(
            &RangerReadings::new(ranges[0], ranges[1], ranges[2], ranges[3]),
            yaw,
            v.0,
            v.1,
            DT,
        );
        assert_eq!((out.repulsion_x, out.repulsion_y), (0.0, 0.0), "{ranges:?}");
        let k = oracle_towards_each_range(&cfg, ranges, yaw, (f64::from(v.0), f64::from(v.1)));
        let want = (k * f64::from(v.0), k * f64::from(v.1));
        let context = format!("ranges {ranges:?} yaw {yaw} v {v:?} -> {out:?}, oracle k {k}");
        // Within the oracle's grid step (10⁻⁴ of |v| ≤ 1.2 m/s) plus f32 rounding.
        assert!(
            (f64::from(out.vx) - want.0).abs() < 2e-4 && (f64::from(out.vy) - want.1).abs() < 2e-4,
            "{context}"
        );
        clamped += usize::from(k < 0.999);
    }
    // The cases exercise the clamp, not only free flight.
    assert!(clamped > 1000, "{clamped}");
}

#[test]
fn smoothing_converges_with_the_documented_time_constant() {
    for method in METHODS {
        let cfg = AvoidanceConfig {
            method,
            smoothing_tau_s: 0.2,
            ..AvoidanceConfig::default()
        };
        let target = (0.2f32, -0.1f32);
        for dt in [0.005f32, 0.01, 0.05] {
            let mut a = avoider(cfg);
            let steps = (1.0 / dt).round() as usize; // one second
            for n in 1..=steps {
                let out = a.step(&RangerReadings::NONE, 0.0, target.0, target.1, dt);
                let k = 1.0 - (-(n as f32) * dt / cfg.smoothing_tau_s).exp();
                assert!((out.vx - k * target.0).abs() < 1e-5 && (out.vy - k * target.1).abs() < 1e-5);
                if ((n as f32) * dt - cfg.smoothing_tau_s).abs() < 1e-4 {
                    // After one time constant: 63.2 % of the way.
                    assert!((out.vx / target.0 - 0.632).abs() < 1e-3, "dt {dt}: {out:?}");
                }
            }
            // After 1 s = 5 τ it is within e⁻⁵ (0.7 %) of the target.
            let out = a.step(&RangerReadings::NONE, 0.0, target.0, target.1, dt);
            assert!((out.vx - target.0).abs() <= 0.007 * target.0.abs() && (out.vy - target.1).abs() <= 0.007 * 0.1);
        }
    }
}

#[test]
fn bad_dt_holds_the_previous_command() {
    let mut a = avoider(AvoidanceConfig::default());
    for _ in 0..200 {
        a.step(&RangerReadings::NONE, 0.0, 0.2, 0.0, DT);
    }
    let held = a.step(&RangerReadings::NONE, 0.0, 0.2, 0.0, DT);
    for dt in [0.0, -0.01, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let out = a.step(&RangerReadings::NONE, 0.0, -0.3, 0.3, dt);
        assert_eq!((out.vx, out.vy), (held.vx, held.vy), "dt {dt}");
    }
    // The held command is still re-clamped when an obstacle appears.
    let out = a.step(&front(0.1), 0.0, 0.2, 0.0, 0.0);
    assert!(speed(&out) <= a.config().min_speed_mps + 1e-6, "{out:?}");
    a.reset();
    let out = a.step(&RangerReadings::NONE, 0.0, 0.2, 0.0, f32::NAN);
    assert_eq!((out.vx, out.vy), (0.0, 0.0));
}

#[test]
fn invalid_ranges_are_no_return() {
    for method in METHODS {
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -0.1, 4.5, f32::MAX] {
            let out = avoider(raw_config(method)).step(&front(bad), 0.0, 0.1, 0.0, DT);
            assert_eq!(out.nearest_m, None, "{bad}");
            assert_eq!(repulsion(&out), 0.0, "{bad}");
            assert!(!out.active);
            assert!((out.vx - 0.1).abs() < 1e-6);
        }
    }
}

#[test]
fn nan_yaw_uses_the_last_yaw_or_no_repulsion() {
    let cfg = raw_config(AvoidanceMethod::PotentialField);
    // Never a finite yaw: the direction is unknown, so no repulsion, but the clamp still holds.
    let out = avoider(cfg).step(&front(0.1), f32::NAN, 0.3, 0.0, DT);
    assert_eq!(repulsion(&out), 0.0);
    assert!(speed(&out) <= cfg.min_speed_mps + 1e-6);
    // After a finite yaw of 90°, a NaN yaw reuses it.
    let mut a = avoider(cfg);
    a.step(&RangerReadings::NONE, FRAC_PI_2, 0.0, 0.0, DT);
    let out = a.step(&front(0.1), f32::NAN, 0.0, 0.0, DT);
    assert!(out.repulsion_y < -0.05 && out.repulsion_x.abs() < 1e-6, "{out:?}");
    // Yaw wrapped many turns still points the same way.
    let out = avoider(cfg).step(&front(0.1), FRAC_PI_2 + 2.0 * PI * 1000.0, 0.0, 0.0, DT);
    assert!(out.repulsion_y < -0.05 && out.repulsion_x.abs() < 1e-3, "{out:?}");
}

#[test]
fn config_validation() {
    let ok = AvoidanceConfig::default();
    assert!(ok.validate().is_ok());
    let bad = |cfg: AvoidanceConfig| ReactiveAvoidance::new(cfg).err();
    assert_eq!(
        bad(AvoidanceConfig {
            gain_mps: f32::NAN,
            ..ok
        }),
        Some(AvoidanceConfigError::NonFinite)
    );
    assert_eq!(
        bad(AvoidanceConfig {
            danger_distance_m: 0.0,
            ..ok
        }),
        Some(AvoidanceConfigError::NonPositive)
    );
    assert_eq!(
        bad(AvoidanceConfig { max_range_m: 0.3, ..ok }),
        Some(AvoidanceConfigError::NonPositive)
    );
    assert_eq!(
        bad(AvoidanceConfig {
            smoothing_tau_s: -1.0,
            ..ok
        }),
        Some(AvoidanceConfigError::OutOfRange)
    );
    assert_eq!(
        bad(AvoidanceConfig { vff_damping: 1.5, ..ok }),
        Some(AvoidanceConfigError::OutOfRange)
    );
    assert_eq!(
        bad(AvoidanceConfig {
            min_speed_mps: 1.0,
            ..ok
        }),
        Some(AvoidanceConfigError::Inconsistent)
    );
    assert_eq!(
        bad(AvoidanceConfig {
            slow_down_distance_m: 0.3,
            ..ok
        }),
        Some(AvoidanceConfigError::Inconsistent)
    );
}

fn any_range() -> impl Strategy<Value = Option<f32>> {
    prop_oneof![
        2 => Just(None),
        4 => (0.0f32..1.0).prop_map(Some),
        1 => (1.0f32..5.0).prop_map(Some),
        1 => any::<f32>().prop_map(Some),
        1 => prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY), Just(-0.0)].prop_map(Some),
    ]
}

fn any_value(range: std::ops::Range<f32>) -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => range,
        1 => any::<f32>(),
        1 => prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY), Just(0.0)],
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

    /// Any sequence of inputs, garbage included, with either method: a finite command within the clamp
    /// for the nearest valid range.
    #[test]
    fn garbage_never_makes_nan_or_exceeds_the_clamp(
        vff in any::<bool>(),
        tau in prop_oneof![Just(0.0f32), 0.01f32..1.0],
        steps in proptest::collection::vec(
            ((any_range(), any_range(), any_range(), any_range()),
             any_value(-10.0..10.0), any_value(-2.0..2.0), any_value(-2.0..2.0), any_value(-0.1..0.2)),
            1..60,
        ),
    ) {
        let method = if vff { AvoidanceMethod::VirtualForceField } else { AvoidanceMethod::PotentialField };
        let cfg = AvoidanceConfig { method, smoothing_tau_s: tau, ..AvoidanceConfig::default() };
        let mut a = avoider(cfg);
        for ((f, b, l, r), yaw, vx, vy, dt) in steps {
            let out = a.step(&RangerReadings::new(f, b, l, r), yaw, vx, vy, dt);
            prop_assert!(out.vx.is_finite() && out.vy.is_finite(), "{:?}", out);
            prop_assert!(out.repulsion_x.is_finite() && out.repulsion_y.is_finite());
            prop_assert!(speed(&out) <= out.speed_limit_mps * (1.0 + 1e-6) + 1e-7, "{:?}", out);
            let valid: Vec<f32> = [f, b, l, r]
                .into_iter()
                .flatten()
                .filter(|d| d.is_finite() && *d >= 0.0 && *d <= cfg.max_range_m)
                .collect();
            let nearest = valid.iter().copied().reduce(f32::min);
            prop_assert_eq!(out.nearest_m, nearest);
            prop_assert!((out.speed_limit_mps - cfg.speed_limit(nearest)).abs() < 1e-6);
        }
    }
}

#[test]
fn memory_size() {
    let size = std::mem::size_of::<ReactiveAvoidance>();
    eprintln!("ReactiveAvoidance: {size} bytes");
    assert!(size <= 96, "{size} bytes");
}
