//! The frame conventions every module relies on (src/types.rs).

use cfnav::types::{arena_to_body, body_to_arena, wrap_angle};

fn close(a: [f32; 3], b: [f32; 3]) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-5)
}

#[test]
fn positive_pitch_is_nose_down_and_positive_roll_is_right_side_down() {
    let pitch = 0.3f32;
    let nose = body_to_arena([1.0, 0.0, 0.0], [0.0, pitch, 0.0]);
    assert!(nose[2] < 0.0, "nose {nose:?}");
    let thrust = body_to_arena([0.0, 0.0, 1.0], [0.0, pitch, 0.0]);
    assert!(thrust[0] > 0.0, "thrust tilts forward: {thrust:?}");
    let left = body_to_arena([0.0, 1.0, 0.0], [0.3, 0.0, 0.0]);
    assert!(left[2] > 0.0, "left side up: {left:?}");
    let thrust = body_to_arena([0.0, 0.0, 1.0], [0.3, 0.0, 0.0]);
    assert!(thrust[1] < 0.0, "thrust tilts to the right (−y): {thrust:?}");
    // Yaw 90° turns the nose to +y.
    assert!(close(
        body_to_arena([1.0, 0.0, 0.0], [0.0, 0.0, core::f32::consts::FRAC_PI_2]),
        [0.0, 1.0, 0.0]
    ));
}

#[test]
fn arena_to_body_inverts_body_to_arena() {
    let mut s = 1u32;
    let mut next = || {
        s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (s >> 8) as f32 / (1u32 << 24) as f32 * 6.0 - 3.0
    };
    for _ in 0..1000 {
        let att = [next(), next() * 0.5, next()];
        let v = [next(), next(), next()];
        let back = arena_to_body(body_to_arena(v, att), att);
        assert!(close(back, v), "{v:?} -> {back:?}");
        // Rotations keep lengths.
        let w = body_to_arena(v, att);
        let n = |a: [f32; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        assert!((n(w) - n(v)).abs() < 1e-4);
    }
}

#[test]
fn wrap_angle_stays_in_range() {
    for i in -1000..1000 {
        let a = i as f32 * 0.037;
        let w = wrap_angle(a);
        assert!(w > -core::f32::consts::PI - 1e-5 && w <= core::f32::consts::PI + 1e-5);
        // a and w differ by a whole number of turns.
        let turns = (a - w) / (2.0 * core::f32::consts::PI);
        assert!((turns - turns.round()).abs() < 1e-3, "{a} -> {w}");
    }
    assert_eq!(wrap_angle(f32::NAN), 0.0);
    assert_eq!(wrap_angle(f32::INFINITY), 0.0);
}
