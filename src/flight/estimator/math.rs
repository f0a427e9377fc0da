//! Small fixed-size linear algebra for the estimator: 3-vectors, 3 × 3 rotations, Hamilton quaternions and
//! the 9 × 9 error covariance. Plain arrays, no allocation; every index is a constant or a loop counter
//! bounded by the array's own length, so none can panic.
//!
//! Quaternions are `[w, x, y, z]` and rotate body → arena (`v_arena = q ⊗ v_body ⊗ q*`), matching the
//! rotation matrix `R = Rz(ψ)·Ry(θ)·Rx(φ)` of [`crate::types`].

/// A 3-vector.
pub(crate) type V3 = [f32; 3];
/// A 3 × 3 matrix, row-major: `m[row][col]`.
pub(crate) type M3 = [[f32; 3]; 3];
/// A unit quaternion `[w, x, y, z]`.
pub(crate) type Quat = [f32; 4];

/// Error-state dimension: position (3), velocity (3), attitude error (3).
pub(crate) const N: usize = 9;
/// A 9 × 9 matrix (the covariance), row-major.
pub(crate) type Mat9 = [[f32; N]; N];
/// A 9-vector (a measurement Jacobian row, a gain, a state correction).
pub(crate) type Vec9 = [f32; N];

pub(crate) fn add3(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub(crate) fn sub3(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn scale3(a: V3, k: f32) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

pub(crate) fn dot3(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn norm3(a: V3) -> f32 {
    libm::sqrtf(dot3(a, a))
}

pub(crate) fn finite3(a: V3) -> bool {
    a.iter().all(|x| x.is_finite())
}

/// `m · v`.
pub(crate) fn mul_m3_v3(m: &M3, v: V3) -> V3 {
    [dot3(m[0], v), dot3(m[1], v), dot3(m[2], v)]
}

/// `mᵀ · v`.
pub(crate) fn mul_m3t_v3(m: &M3, v: V3) -> V3 {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// `a · b`.
pub(crate) fn mul_m3(a: &M3, b: &M3) -> M3 {
    let mut out = [[0.0; 3]; 3];
    for (row, a_row) in out.iter_mut().zip(a.iter()) {
        for (c, cell) in row.iter_mut().enumerate() {
            *cell = a_row[0] * b[0][c] + a_row[1] * b[1][c] + a_row[2] * b[2][c];
        }
    }
    out
}

/// The cross-product matrix `[v]×`, so that `[v]× · w = v × w`.
pub(crate) fn skew(v: V3) -> M3 {
    [[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]]
}

pub(crate) const QUAT_IDENTITY: Quat = [1.0, 0.0, 0.0, 0.0];

/// Hamilton product `a ⊗ b`.
pub(crate) fn quat_mul(a: Quat, b: Quat) -> Quat {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// Normalise; a degenerate or non-finite quaternion becomes the identity (the caller's supervisor notices
/// the jump; a NaN must never propagate).
///
/// Near unit norm (the only case at 1 kHz: one small rotation away from a unit quaternion) the first-order
/// correction `(3 − |q|²)/2` is exact to ~1e-7 and needs no square root, which on the Cortex-M4 is a
/// software routine in `libm` (its hardware paths are for x86, aarch64 and wasm).
pub(crate) fn quat_normalize(q: Quat) -> Quat {
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
pub(crate) fn quat_from_rotvec(r: V3) -> Quat {
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

/// `q = qz(ψ) ⊗ qy(θ) ⊗ qx(φ)`: the quaternion of `R = Rz(ψ)·Ry(θ)·Rx(φ)`.
pub(crate) fn quat_from_euler(roll: f32, pitch: f32, yaw: f32) -> Quat {
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

/// The rotation matrix (body → arena) of a unit quaternion.
pub(crate) fn quat_to_rot(q: Quat) -> M3 {
    let [w, x, y, z] = q;
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// `[roll, pitch, yaw]` of `R = Rz(ψ)·Ry(θ)·Rx(φ)` (pitch clamped to ±90° at the singularity).
pub(crate) fn euler_from_rot(r: &M3) -> V3 {
    let roll = libm::atan2f(r[2][1], r[2][2]);
    let pitch = libm::asinf((-r[2][0]).clamp(-1.0, 1.0));
    let yaw = libm::atan2f(r[1][0], r[0][0]);
    [roll, pitch, yaw]
}

/// `m · v` for a 9 × 9 matrix.
pub(crate) fn mul9_v(m: &Mat9, v: &Vec9) -> Vec9 {
    let mut out = [0.0; N];
    for (o, row) in out.iter_mut().zip(m.iter()) {
        *o = row.iter().zip(v.iter()).map(|(x, y)| x * y).sum();
    }
    out
}

/// A second-order Butterworth low-pass (the stock `lpf2p`, \[FW\] src/utils/src/filter.c), one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Lpf2 {
    b0: f32,
    a1: f32,
    a2: f32,
    d1: f32,
    d2: f32,
}

impl Lpf2 {
    /// Cut-off `cutoff_hz` at `sample_hz` (cut-off ≥ Nyquist or nonsense → pass-through).
    pub(crate) fn new(sample_hz: f32, cutoff_hz: f32) -> Self {
        if !(cutoff_hz > 0.0 && sample_hz > 2.0 * cutoff_hz) {
            return Self {
                b0: 1.0,
                a1: 0.0,
                a2: 0.0,
                d1: 0.0,
                d2: 0.0,
            };
        }
        let ohm = libm::tanf(core::f32::consts::PI * cutoff_hz / sample_hz);
        let cos_pi_4 = core::f32::consts::FRAC_1_SQRT_2;
        let c = 1.0 + 2.0 * cos_pi_4 * ohm + ohm * ohm;
        Self {
            b0: ohm * ohm / c,
            a1: 2.0 * (ohm * ohm - 1.0) / c,
            a2: (1.0 - 2.0 * cos_pi_4 * ohm + ohm * ohm) / c,
            d1: 0.0,
            d2: 0.0,
        }
    }

    /// Feed one sample, get the filtered value (b1 = 2·b0, b2 = b0).
    pub(crate) fn apply(&mut self, x: f32) -> f32 {
        let mut d0 = x - self.d1 * self.a1 - self.d2 * self.a2;
        if !d0.is_finite() {
            // Stock does the same: restart from the input rather than carry a NaN forever.
            d0 = if x.is_finite() { x } else { 0.0 };
        }
        let y = self.b0 * (d0 + 2.0 * self.d1 + self.d2);
        self.d2 = self.d1;
        self.d1 = d0;
        y
    }
}
