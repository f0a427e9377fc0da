//! The estimator's own small algebra: the 10 × 10 error covariance and its vectors, and the second-order
//! low-pass of the rate output. Everything else (3-vectors, rotations, quaternions) is [`crate::math`].
//! Plain arrays, no allocation; every index is a constant or a loop counter bounded by the array's own
//! length, so none can panic.

/// Error-state dimension: position (3), velocity (3), attitude error (3), the flow's scale error (1).
pub(crate) const N: usize = 10;
/// An N × N matrix (the covariance), row-major.
pub(crate) type MatN = [[f32; N]; N];
/// An N-vector (a measurement Jacobian row, a gain, a state correction).
pub(crate) type VecN = [f32; N];

/// `m · v` for an N × N matrix.
pub(crate) fn mul_mat_vec(m: &MatN, v: &VecN) -> VecN {
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
