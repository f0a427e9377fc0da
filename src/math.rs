//! The one implementation of the small geometry every part of cfnav shares: 3-vectors, 3 × 3 rotation
//! matrices, Hamilton quaternions, roll/pitch/yaw and angle wrapping. The estimator, the controller, the
//! mission, the simulator (`tools/src/sim`) and the tests' rigid-body model all use these functions; none
//! keeps its own copy.
//!
//! Job: pure functions on plain arrays. Non-goals: the estimator's 9 × 9 covariance algebra (it stays with
//! the estimator, its only user), general linear algebra, allocation. No state, no memory beyond the
//! arguments; every index is a constant, so nothing here can panic.
//!
//! Conventions (those of [`crate::types`]): rotation matrices and quaternions rotate **body → arena**
//! (`v_arena = R · v_body = q ⊗ v_body ⊗ q*`), matrices are row-major (`m[row][col]`), quaternions are
//! `[w, x, y, z]`, attitudes are `[roll, pitch, yaw]` in radians composed as `R = Rz(ψ)·Ry(θ)·Rx(φ)`.
//!
//! Precision: the arithmetic-only functions are generic over [`Scalar`] (`f32` on the drone, `f64` in the
//! tests' reference model) and evaluate exactly the same expressions for both, so an `f32` caller gets the
//! same bits as a hand-written `f32` version. Functions that need a square root or trigonometry are `f32`
//! only and use `libm` (the Cortex-M4 has no hardware for them; see each one for its cost-saving paths).

use core::ops::{Add, Mul, Neg, Sub};

/// A 3-vector.
pub type V3 = [f32; 3];
/// A 3 × 3 matrix, row-major: `m[row][col]`.
pub type M3 = [[f32; 3]; 3];
/// A unit quaternion `[w, x, y, z]`.
pub type Quat = [f32; 4];

/// The number types the arithmetic functions accept: `f32` and `f64` (anything with these operations and a
/// conversion from `f32` for the constants 0, 1 and 2).
pub trait Scalar:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self> + From<f32>
{
}

impl<T> Scalar for T where T: Copy + Add<Output = T> + Sub<Output = T> + Mul<Output = T> + Neg<Output = T> + From<f32> {}

/// `x` if it is finite, else `fallback`.
pub fn finite_or(x: f32, fallback: f32) -> f32 {
    if x.is_finite() { x } else { fallback }
}

/// `a + b`.
pub fn add3<T: Scalar>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
pub fn sub3<T: Scalar>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `k · a`.
pub fn scale3<T: Scalar>(a: [T; 3], k: T) -> [T; 3] {
    [a[0] * k, a[1] * k, a[2] * k]
}

/// `a · b`.
pub fn dot3<T: Scalar>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
pub fn cross3<T: Scalar>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `|a|`.
pub fn norm3(a: V3) -> f32 {
    libm::sqrtf(dot3(a, a))
}

/// Every component is finite.
pub fn finite3(a: V3) -> bool {
    a.iter().all(|x| x.is_finite())
}

/// `m · v`.
pub fn mul_m3_v3<T: Scalar>(m: &[[T; 3]; 3], v: [T; 3]) -> [T; 3] {
    [dot3(m[0], v), dot3(m[1], v), dot3(m[2], v)]
}

/// `mᵀ · v` (for a rotation: arena → body).
pub fn mul_m3t_v3<T: Scalar>(m: &[[T; 3]; 3], v: [T; 3]) -> [T; 3] {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// `a · b`.
pub fn mul_m3<T: Scalar>(a: &[[T; 3]; 3], b: &[[T; 3]; 3]) -> [[T; 3]; 3] {
    let mut out = [[T::from(0.0); 3]; 3];
    for (row, a_row) in out.iter_mut().zip(a.iter()) {
        for (c, cell) in row.iter_mut().enumerate() {
            *cell = a_row[0] * b[0][c] + a_row[1] * b[1][c] + a_row[2] * b[2][c];
        }
    }
    out
}

/// The cross-product matrix `[v]×`, so that `[v]× · w = v × w`.
pub fn skew<T: Scalar>(v: [T; 3]) -> [[T; 3]; 3] {
    let z = T::from(0.0);
    [[z, -v[2], v[1]], [v[2], z, -v[0]], [-v[1], v[0], z]]
}

/// The identity rotation.
pub const QUAT_IDENTITY: Quat = [1.0, 0.0, 0.0, 0.0];

/// Hamilton product `a ⊗ b`.
pub fn quat_mul<T: Scalar>(a: [T; 4], b: [T; 4]) -> [T; 4] {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// The rotation matrix (body → arena) of a unit quaternion.
pub fn quat_to_rot<T: Scalar>(q: [T; 4]) -> [[T; 3]; 3] {
    let [w, x, y, z] = q;
    let (one, two) = (T::from(1.0), T::from(2.0));
    [
        [
            one - two * (y * y + z * z),
            two * (x * y - w * z),
            two * (x * z + w * y),
        ],
        [
            two * (x * y + w * z),
            one - two * (x * x + z * z),
            two * (y * z - w * x),
        ],
        [
            two * (x * z - w * y),
            two * (y * z + w * x),
            one - two * (x * x + y * y),
        ],
    ]
}

/// Normalise; a degenerate or non-finite quaternion becomes the identity (the caller's supervisor notices
/// the jump; a NaN must never propagate).
///
/// Near unit norm (the only case at 1 kHz: one small rotation away from a unit quaternion) the first-order
/// correction `(3 − |q|²)/2` is exact to ~1e-7 and needs no square root, which on the Cortex-M4 is a
/// software routine in `libm` (its hardware paths are for x86, aarch64 and wasm).
pub fn quat_normalize(q: Quat) -> Quat {
    let n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if !(n2.is_finite() && n2 > 1e-12) {
        return QUAT_IDENTITY;
    }
    let inv = if (n2 - 1.0).abs() < 1e-3 {
        0.5 * (3.0 - n2)
    } else {
        1.0 / libm::sqrtf(n2)
    };
    // Keep w ≥ 0 (the same rotation) so that consecutive quaternions stay in one hemisphere.
    let s = if q[0] < 0.0 { -inv } else { inv };
    [q[0] * s, q[1] * s, q[2] * s, q[3] * s]
}

/// The rotation by the rotation vector `r` (axis · angle, rad) as a quaternion: `exp`, by its series up to
/// 0.1 rad (every IMU step: 2000 °/s for 1 ms is 0.035 rad; the first omitted terms are a⁶/46080 and
/// a⁶/645120 ≈ 2e-11, far below f32 resolution), exactly (sin, cos) beyond.
pub fn quat_from_rotvec(r: V3) -> Quat {
    let a2 = dot3(r, r);
    if !(a2.is_finite()) {
        return QUAT_IDENTITY;
    }
    if a2 < 0.01 {
        // cos(a/2) = 1 − a²/8 + a⁴/384 − …, sin(a/2)/a = 1/2 − a²/48 + a⁴/3840 − …
        let c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0;
        let k = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0;
        return [c, r[0] * k, r[1] * k, r[2] * k];
    }
    let a = libm::sqrtf(a2);
    let (s, c) = (libm::sinf(0.5 * a), libm::cosf(0.5 * a));
    let k = s / a;
    [c, r[0] * k, r[1] * k, r[2] * k]
}

/// `q = qz(ψ) ⊗ qy(θ) ⊗ qx(φ)`: the quaternion of `R = Rz(ψ)·Ry(θ)·Rx(φ)`, normalised.
pub fn quat_from_euler(roll: f32, pitch: f32, yaw: f32) -> Quat {
    let (sr, cr) = (libm::sinf(0.5 * roll), libm::cosf(0.5 * roll));
    let (sp, cp) = (libm::sinf(0.5 * pitch), libm::cosf(0.5 * pitch));
    let (sy, cy) = (libm::sinf(0.5 * yaw), libm::cosf(0.5 * yaw));
    quat_normalize([
        cy * cp * cr + sy * sp * sr,
        cy * cp * sr - sy * sp * cr,
        cy * sp * cr + sy * cp * sr,
        sy * cp * cr - cy * sp * sr,
    ])
}

/// `[roll, pitch, yaw]` of `R = Rz(ψ)·Ry(θ)·Rx(φ)` (pitch clamped to ±90° at the singularity).
pub fn euler_from_rot(r: &M3) -> V3 {
    let roll = libm::atan2f(r[2][1], r[2][2]);
    let pitch = libm::asinf((-r[2][0]).clamp(-1.0, 1.0));
    let yaw = libm::atan2f(r[1][0], r[0][0]);
    [roll, pitch, yaw]
}

/// Wrap an angle to (−π, π]; a non-finite angle becomes 0.
pub fn wrap_angle(a: f32) -> f32 {
    if !a.is_finite() {
        return 0.0;
    }
    let two_pi = 2.0 * core::f32::consts::PI;
    let mut w = libm::fmodf(a + core::f32::consts::PI, two_pi);
    if w < 0.0 {
        w += two_pi;
    }
    w - core::f32::consts::PI
}

/// The rotation matrix `R = Rz(yaw)·Ry(pitch)·Rx(roll)` (body → arena) of the attitude `[roll, pitch, yaw]`.
pub fn rotation(attitude_rad: V3) -> M3 {
    let (sr, cr) = (libm::sinf(attitude_rad[0]), libm::cosf(attitude_rad[0]));
    let (sp, cp) = (libm::sinf(attitude_rad[1]), libm::cosf(attitude_rad[1]));
    let (sy, cy) = (libm::sinf(attitude_rad[2]), libm::cosf(attitude_rad[2]));
    [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
}

/// Rotate a body-frame vector into the arena frame with the attitude `[roll, pitch, yaw]`.
pub fn body_to_arena(v: V3, attitude_rad: V3) -> V3 {
    mul_m3_v3(&rotation(attitude_rad), v)
}

/// Rotate an arena-frame vector into the body frame (the transpose of [`body_to_arena`]).
pub fn arena_to_body(v: V3, attitude_rad: V3) -> V3 {
    mul_m3t_v3(&rotation(attitude_rad), v)
}
