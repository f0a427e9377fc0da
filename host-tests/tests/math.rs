//! The frame conventions every module relies on (src/math.rs, src/types.rs).

use cfnav::math::{
    QUAT_IDENTITY, add3, arena_to_body, body_to_arena, cross3, dot3, euler_from_rot, finite_or, finite3, mul_m3,
    mul_m3_v3, mul_m3t_v3, norm3, quat_from_euler, quat_from_rotvec, quat_mul, quat_normalize, quat_to_rot, rotation,
    scale3, skew, sub3, wrap_angle,
};

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

/// A reproducible stream of values in [−3, 3).
fn values(seed: u32) -> impl FnMut() -> f32 {
    let mut s = seed;
    move || {
        s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        (s >> 8) as f32 / (1u32 << 24) as f32 * 6.0 - 3.0
    }
}

fn close_m(a: [[f32; 3]; 3], b: [[f32; 3]; 3], tol: f32) -> bool {
    (0..3).all(|i| (0..3).all(|j| (a[i][j] - b[i][j]).abs() < tol))
}

#[test]
fn quaternions_agree_with_the_euler_matrix() {
    // Oracle: `rotation` multiplies out Rz·Ry·Rx from sines and cosines; the quaternion path composes
    // half-angle quaternions and converts. Both must give the same matrix, and the angles must come back.
    let mut next = values(7);
    for _ in 0..1000 {
        let att = [next(), next() * 0.5, next()];
        let q = quat_from_euler(att[0], att[1], att[2]);
        let r = quat_to_rot(q);
        assert!(close_m(r, rotation(att), 2e-6), "{att:?}");
        let back = euler_from_rot(&r);
        for i in 0..3 {
            assert!(wrap_angle(back[i] - att[i]).abs() < 1e-4, "{att:?} -> {back:?}");
        }
    }
}

#[test]
fn the_hamilton_product_composes_rotations_like_matrices() {
    let mut next = values(11);
    for _ in 0..1000 {
        let a = quat_from_euler(next(), next() * 0.5, next());
        let b = quat_from_euler(next(), next() * 0.5, next());
        let ab = quat_to_rot(quat_mul(a, b));
        assert!(close_m(ab, mul_m3(&quat_to_rot(a), &quat_to_rot(b)), 1e-5));
        // The rotation vector's quaternion turns about its axis by its length.
        let axis_angle = [next() * 0.3, next() * 0.3, next() * 0.3];
        let r = quat_to_rot(quat_from_rotvec(axis_angle));
        assert!(close(mul_m3_v3(&r, axis_angle), axis_angle), "the axis stays put");
        let n = norm3(axis_angle);
        let trace_angle = ((r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0).clamp(-1.0, 1.0).acos();
        assert!((trace_angle - n).abs() < 1e-3, "{trace_angle} vs {n}");
    }
    // Garbage never becomes NaN.
    assert_eq!(quat_normalize([f32::NAN, 0.0, 0.0, 0.0]), QUAT_IDENTITY);
    assert_eq!(quat_from_rotvec([f32::INFINITY, 0.0, 0.0]), QUAT_IDENTITY);
}

#[test]
fn vector_helpers_match_their_definitions_in_f32_and_f64() {
    let mut next = values(3);
    for _ in 0..200 {
        let a = [next(), next(), next()];
        let b = [next(), next(), next()];
        // a × b is perpendicular to both, |a × b|² = |a|²|b|² − (a·b)², and [a]× · b = a × b.
        let c = cross3(a, b);
        assert!(dot3(c, a).abs() < 1e-4 && dot3(c, b).abs() < 1e-4);
        let lhs = dot3(c, c);
        let rhs = dot3(a, a) * dot3(b, b) - dot3(a, b) * dot3(a, b);
        assert!((lhs - rhs).abs() < 1e-3 * (1.0 + rhs.abs()), "{lhs} vs {rhs}");
        assert!(close(mul_m3_v3(&skew(a), b), c));
        assert!(close(sub3(add3(a, b), b), a));
        assert!(close(scale3(a, 2.0), add3(a, a)));
        // The generic functions compute the same expressions in f64 (the tests' reference models).
        let wide = |v: [f32; 3]| v.map(f64::from);
        let c64 = cross3(wide(a), wide(b));
        assert!((0..3).all(|i| (c64[i] - f64::from(c[i])).abs() < 1e-4));
        let r = rotation(a);
        let r64 = r.map(wide);
        let t64 = mul_m3t_v3(&r64, wide(b));
        let t = mul_m3t_v3(&r, b);
        assert!((0..3).all(|i| (t64[i] - f64::from(t[i])).abs() < 1e-5));
    }
    assert!(finite3([1.0, 2.0, 3.0]) && !finite3([1.0, f32::NAN, 3.0]));
    assert_eq!(finite_or(f32::NAN, 2.0), 2.0);
    assert_eq!(finite_or(1.5, 2.0), 1.5);
}

#[test]
fn a_setpoint_is_finite_only_when_every_field_is() {
    use cfnav::types::Setpoint;
    let fields = |v: f32| {
        [
            Setpoint::Position {
                x_m: v,
                y_m: 1.0,
                z_m: 1.0,
                yaw_rad: 0.0,
            },
            Setpoint::Velocity {
                vx_m_s: 0.0,
                vy_m_s: 0.0,
                z_m: 1.0,
                yaw_rad: v,
            },
            Setpoint::Descend {
                x_m: 1.0,
                y_m: 1.0,
                vz_m_s: v,
                yaw_rad: 0.0,
            },
        ]
    };
    assert!(Setpoint::Stop.is_finite());
    assert!(fields(0.5).iter().all(Setpoint::is_finite));
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert!(fields(bad).iter().all(|s| !s.is_finite()), "{bad}");
    }
}
