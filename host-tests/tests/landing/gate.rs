//! Descent gate tests (src/landing/gate.rs) against a ground-truth oracle: a 0.3 × 0.3 × 0.1 m pad on a
//! flat floor, a drone hovering at 0.5 m whose *true* position is given, and the downward range it would
//! read there (ray straight down, 3 mm noise, some tilt). The oracle of a safe descent is the geometry:
//! the body's centre over the pad's top lands on it; a centre outside the pad but within the body radius
//! (0.06 m) of its side touches that side (docs/formats.md, world files).

use cfnav::landing::gate::{self, Clearance, DECIDING_READINGS, SurfaceVotes, Target, Verdict};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const PAD_SIDE_M: f32 = 0.3;
const PAD_HEIGHT_M: f32 = 0.1;
const HEIGHT_M: f32 = 0.5;
const BODY_RADIUS_M: f32 = 0.06;

fn gauss(rng: &mut SmallRng) -> f32 {
    // Box–Muller.
    let u1: f32 = rng.random_range(1e-6..1.0);
    let u2: f32 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f32::consts::PI * u2).cos()
}

/// The surface under a true position `(dx, dy)` from the pad's centre.
fn surface(dx: f32, dy: f32) -> f32 {
    if dx.abs() <= 0.5 * PAD_SIDE_M && dy.abs() <= 0.5 * PAD_SIDE_M {
        PAD_HEIGHT_M
    } else {
        0.0
    }
}

/// Within 1 cm of the pad's outline: the hover's own wander (3 mm) puts readings on both levels there.
fn near_outline(dx: f32, dy: f32) -> bool {
    let (ax, ay) = (dx.abs() - 0.5 * PAD_SIDE_M, dy.abs() - 0.5 * PAD_SIDE_M);
    (ax.abs() < 0.01 && ay < 0.01) || (ay.abs() < 0.01 && ax < 0.01)
}

/// The oracle: where would a vertical descent at the true offset end? `Some(true)` on the pad's top,
/// `Some(false)` on the floor clear of it, `None` touching its side.
fn descent_outcome(dx: f32, dy: f32) -> Option<bool> {
    if surface(dx, dy) > 0.0 {
        return Some(true);
    }
    let ox = (dx.abs() - 0.5 * PAD_SIDE_M).max(0.0);
    let oy = (dy.abs() - 0.5 * PAD_SIDE_M).max(0.0);
    if ox.hypot(oy) < BODY_RADIUS_M {
        None
    } else {
        Some(false)
    }
}

/// Hover `readings` downward readings at the true offset (small random wander and tilt) and ask the gate.
fn hover_verdict(target: Target, dx: f32, dy: f32, readings: usize, rng: &mut SmallRng) -> Verdict {
    let mut votes = SurfaceVotes::new();
    let mut verdict = Verdict::Wait;
    for _ in 0..readings {
        let tilt: f32 = rng.random_range(0.0..0.05);
        let (x, y) = (dx + 0.003 * gauss(rng), dy + 0.003 * gauss(rng));
        let range = (HEIGHT_M - surface(x, y)) / tilt.cos() + 0.003 * gauss(rng);
        votes.update(range, tilt.cos(), HEIGHT_M + 0.005 * gauss(rng), PAD_HEIGHT_M);
        verdict = gate::verdict(target, true, true, &votes);
        if verdict != Verdict::Wait {
            break;
        }
    }
    verdict
}

#[test]
fn a_pad_descent_happens_only_where_the_centre_is_over_the_pads_top() {
    let mut rng = SmallRng::seed_from_u64(14);
    let (mut descents, mut refusals) = (0, 0);
    for _ in 0..2000 {
        let dx = rng.random_range(-0.35..0.35);
        let dy = rng.random_range(-0.35..0.35);
        if near_outline(dx, dy) {
            continue;
        }
        let verdict = hover_verdict(Target::PadTop, dx, dy, 40, &mut rng);
        let outcome = descent_outcome(dx, dy);
        match verdict {
            // Every descent the gate allows lands on the pad, none touches its side.
            Verdict::Descend => {
                assert_eq!(outcome, Some(true), "descended at ({dx:.3}, {dy:.3})");
                descents += 1;
            }
            Verdict::Refuse => {
                assert_ne!(outcome, Some(true), "refused over the pad's top at ({dx:.3}, {dy:.3})");
                refusals += 1;
            }
            Verdict::Wait => panic!("40 readings at one level and still undecided at ({dx:.3}, {dy:.3})"),
        }
    }
    assert!(
        descents > 200 && refusals > 1000,
        "{descents} descents, {refusals} refusals"
    );
}

#[test]
fn an_estimate_at_the_pads_edge_is_refused() {
    // The baseline's collisions: the drone believed it hovered over the pad's centre but was 15–21 cm off,
    // at the pad's edge, where the body touches the side on the way down (the oracle says so).
    let mut rng = SmallRng::seed_from_u64(3);
    for (dx, dy) in [(0.16, 0.0), (0.0, -0.18), (0.2, 0.05), (-0.19, 0.19), (0.155, -0.02)] {
        assert_eq!(
            descent_outcome(dx, dy),
            None,
            "the oracle: ({dx}, {dy}) touches the side"
        );
        assert_eq!(
            hover_verdict(Target::PadTop, dx, dy, 40, &mut rng),
            Verdict::Refuse,
            "({dx}, {dy})"
        );
    }
    // In the estimate frame: a drone 0.12 m from the pad estimate, or any estimate with one coordinate
    // unmeasured (crossings in one direction only), breaks the clearance rule; a centred one keeps it.
    let rule = Clearance {
        pad_size_m: PAD_SIDE_M,
        margin_m: 0.04,
    };
    assert!(!rule.allows(0.12, rule.uncertainty_m(0.01, 1.0, true)));
    assert!(!rule.allows(0.0, rule.uncertainty_m(0.0, 0.0, false)));
    assert!(rule.allows(0.03, rule.uncertainty_m(0.01, 2.0, true)));
    // Twenty seconds after the crossings the drift term alone (4.5 cm) and a 5 cm offset are too much.
    assert!(!rule.allows(0.05, rule.uncertainty_m(0.02, 20.0, true)));
    // The rule's refusal wins over the readings (it is checked once settled).
    let mut votes = SurfaceVotes::new();
    for _ in 0..DECIDING_READINGS {
        votes.update(HEIGHT_M - PAD_HEIGHT_M, 1.0, HEIGHT_M, PAD_HEIGHT_M);
    }
    assert_eq!(gate::verdict(Target::PadTop, false, true, &votes), Verdict::Refuse);
    assert_eq!(gate::verdict(Target::PadTop, true, true, &votes), Verdict::Descend);
    // Not settled: nothing is decided yet.
    assert_eq!(gate::verdict(Target::PadTop, false, false, &votes), Verdict::Wait);
}

#[test]
fn a_landing_clear_of_the_pad_wants_the_floor_under_it() {
    let mut rng = SmallRng::seed_from_u64(5);
    for _ in 0..1000 {
        let dx = rng.random_range(-0.6..0.6);
        let dy = rng.random_range(-0.6..0.6);
        if near_outline(dx, dy) {
            continue;
        }
        match hover_verdict(Target::Floor, dx, dy, 40, &mut rng) {
            Verdict::Descend => assert_ne!(surface(dx, dy), PAD_HEIGHT_M, "({dx}, {dy}) is over the pad"),
            Verdict::Refuse => assert_eq!(surface(dx, dy), PAD_HEIGHT_M, "({dx}, {dy}) is floor"),
            Verdict::Wait => panic!("undecided at ({dx}, {dy})"),
        }
    }
}

#[test]
fn bad_readings_are_ignored_and_never_panic() {
    let mut votes = SurfaceVotes::new();
    for (r, c, h, p) in [
        (f32::NAN, 1.0, HEIGHT_M, PAD_HEIGHT_M),
        (0.4, f32::NAN, HEIGHT_M, PAD_HEIGHT_M),
        (0.4, 1.0, f32::INFINITY, PAD_HEIGHT_M),
        (0.4, 1.0, HEIGHT_M, f32::NAN),
        (-0.4, 1.0, HEIGHT_M, PAD_HEIGHT_M),
        (0.4, 0.1, HEIGHT_M, PAD_HEIGHT_M),
        (0.4, 1.0, HEIGHT_M, 0.0),
        // A stray range far below the floor or far above the pad.
        (3.5, 1.0, HEIGHT_M, PAD_HEIGHT_M),
        (0.05, 1.0, HEIGHT_M, PAD_HEIGHT_M),
    ] {
        votes.update(r, c, h, p);
    }
    assert_eq!((votes.pad_run(), votes.floor_run()), (0, 0));
    // One stray reading in a run restarts the other level's count but decides nothing by itself.
    for _ in 0..3 {
        votes.update(HEIGHT_M, 1.0, HEIGHT_M + 0.001, PAD_HEIGHT_M);
    }
    votes.update(HEIGHT_M - PAD_HEIGHT_M, 1.0, HEIGHT_M, PAD_HEIGHT_M);
    assert_eq!(gate::verdict(Target::PadTop, true, true, &votes), Verdict::Wait);
    assert_eq!(gate::verdict(Target::Floor, true, true, &votes), Verdict::Wait);
    let rule = Clearance {
        pad_size_m: PAD_SIDE_M,
        margin_m: 0.04,
    };
    assert!(!rule.allows(f32::NAN, 0.0));
    assert!(!rule.allows(0.0, rule.uncertainty_m(f32::NAN, 1.0, true)));
}
