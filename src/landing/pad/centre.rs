//! Pipeline stages 7–8 of the pad detector (see [`super`]): the centre fitted to the crossings with
//! outlier removal (7), half crossings beside a side set aside (7b), and the confidence (8).
//!
//! Cost per new crossing O(`EDGES`²) in the worst case (refit with outlier removal).

use super::{Crossing, PadDetector, PadEstimate};

/// A half crossing whose entry lies within this of a pad side parallel to its travel (by the fit of the
/// others) is set aside, m: about the downward ranger's footprint over the pad's top (7.5° half-angle at
/// 0.4 m, 5 cm) less the position noise between the crossings: an entry 1 cm beyond such a side, on a line
/// 17° off the axis, would otherwise put the centre 15 cm off along the travel.
const HALF_CROSSING_SIDE_MARGIN_M: f32 = 0.04;
/// ... when the full crossings' directions weigh at least this much across the half crossing's travel
/// (about one crossing along it): otherwise nothing says where the sides are.
const HALF_CROSSING_LATERAL_WEIGHT: f32 = 0.8;
/// Weight of the pull towards the midpoints' centroid in the centre fit (see the module docs, step 7).
const CENTROID_PULL: f32 = 1e-3;

impl<const EDGES: usize> PadDetector<EDGES> {
    /// Refits the centre over the crossings, dropping outliers one at a time (worst first), then half
    /// crossings whose entry the fit puts beside a side parallel to their travel (module docs, step 7b).
    pub(super) fn refit(&mut self) {
        // Half crossings set aside so far, by index (only the first 64 can be; more is never reached with
        // the detector's capacity of at most a few dozen crossings).
        let mut set_aside = 0u64;
        for _ in 0..self.crossings.len() {
            self.refit_without(set_aside);
            let Some(estimate) = self.estimate else {
                return;
            };
            match self.half_crossing_beside_a_side(estimate.x, estimate.y) {
                Some(i) if i < 64 => set_aside |= 1 << i,
                _ => return,
            }
        }
    }

    /// The inlier half crossing (turn-back or line end) whose entry lies furthest across its travel from
    /// the centre `(cx, cy)`, if that is within [`HALF_CROSSING_SIDE_MARGIN_M`] of the pad's side parallel
    /// to the travel and the full crossings measure that coordinate (their directions' weight along it at
    /// least [`HALF_CROSSING_LATERAL_WEIGHT`]). Such an entry may have been over that side, not the one
    /// facing the travel, and then the pad's half size inwards along the travel is not the centre.
    pub(super) fn half_crossing_beside_a_side(&self, cx: f32, cy: f32) -> Option<usize> {
        let limit = 0.5 * self.config.pad_size_m - HALF_CROSSING_SIDE_MARGIN_M;
        let mut worst: Option<(usize, f32)> = None;
        for (i, half) in self.crossings.iter().enumerate() {
            if !(half.inlier && half.turn_back) {
                continue;
            }
            // The pad's sides run along the arena's axes: the side crossed faces the axis nearest the
            // travel, the other axis is across it.
            let d = half.direction();
            let across = usize::from(libm::fabsf(d.0) >= libm::fabsf(d.1));
            let weight: f32 = self
                .crossings
                .iter()
                .filter(|c| c.inlier && !c.turn_back)
                .map(|c| {
                    let dc = c.direction();
                    let along = if across == 0 { dc.0 } else { dc.1 };
                    along * along
                })
                .sum();
            if weight < HALF_CROSSING_LATERAL_WEIGHT {
                continue;
            }
            let offset = if across == 0 {
                half.enter.0 - cx
            } else {
                half.enter.1 - cy
            };
            let offset = libm::fabsf(offset);
            if offset > limit && worst.is_none_or(|(_, w)| offset > w) {
                worst = Some((i, offset));
            }
        }
        worst.map(|(i, _)| i)
    }

    /// [`Self::refit`]'s outlier loop over the crossings not in the bit set `set_aside`.
    pub(super) fn refit_without(&mut self, set_aside: u64) {
        for (i, c) in self.crossings.iter_mut().enumerate() {
            c.inlier = i >= 64 || set_aside & (1 << i) == 0;
        }
        self.estimate = None;
        let total = self.crossings.len();
        // At most half the crossings may be rejected: beyond that "outlier" has no meaning.
        for _ in 0..=total / 2 {
            let Some((cx, cy)) = fit_centre(&self.crossings) else {
                return;
            };
            let worst = self
                .crossings
                .iter()
                .enumerate()
                .filter(|(_, c)| c.inlier)
                .map(|(i, c)| (i, libm::fabsf(residual(c, cx, cy))))
                .fold(None, |acc: Option<(usize, f32)>, (i, r)| match acc {
                    Some((_, best)) if best >= r => acc,
                    _ => Some((i, r)),
                });
            let inliers = self.crossings.iter().filter(|c| c.inlier).count();
            match worst {
                Some((i, r)) if r > self.config.outlier_m && inliers > 1 && total - inliers < total / 2 => {
                    if let Some(c) = self.crossings.get_mut(i) {
                        c.inlier = false;
                    }
                }
                _ => {
                    self.estimate = Some(self.score(cx, cy));
                    return;
                }
            }
        }
        // Out of iterations: score the last fit anyway.
        if let Some((cx, cy)) = fit_centre(&self.crossings) {
            self.estimate = Some(self.score(cx, cy));
        }
    }

    /// Confidence and diagnostics of the centre `(cx, cy)` over the inlier crossings.
    pub(super) fn score(&self, cx: f32, cy: f32) -> PadEstimate {
        let cfg = &self.config;
        let total = self.crossings.len();
        let inl = || self.crossings.iter().filter(|c| c.inlier);
        let inliers = inl().count();

        let (mut a, mut b, mut c) = (0.0f32, 0.0f32, 0.0f32);
        let mut sq = 0.0f32;
        for cr in inl() {
            let d = cr.direction();
            a += d.0 * d.0;
            b += d.0 * d.1;
            c += d.1 * d.1;
            let r = residual(cr, cx, cy);
            sq += r * r;
        }
        let lambda_min = 0.5 * (a + c) - libm::sqrtf(0.25 * (a - c) * (a - c) + b * b);
        let rms = if inliers > 0 {
            libm::sqrtf(sq / inliers as f32)
        } else {
            0.0
        };

        // The seed's spread: distances from the centre to every supporting edge.
        let mut sum = 0.0f32;
        let mut sum_sq = 0.0f32;
        let mut n = 0.0f32;
        for cr in inl() {
            for p in [cr.enter, cr.exit] {
                let r = libm::hypotf(p.0 - cx, p.1 - cy);
                sum += r;
                sum_sq += r * r;
                n += 1.0;
            }
        }
        let shape = if n > 0.0 && sum > 0.0 {
            let mean = sum / n;
            let std = libm::sqrtf((sum_sq / n - mean * mean).max(0.0));
            (1.0 - std / mean).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let wanted = f32::from(cfg.min_crossings_per_direction.max(1));
        let coverage = (lambda_min / wanted).clamp(0.0, 1.0);
        let fit = (1.0 - rms / cfg.fit_tolerance_m).clamp(0.0, 1.0);
        let consensus = if total > 0 { inliers as f32 / total as f32 } else { 0.0 };
        let confidence = coverage * fit * shape * consensus;
        PadEstimate {
            x: cx,
            y: cy,
            confidence: if confidence.is_finite() { confidence } else { 0.0 },
            inliers,
            outliers: total - inliers,
            min_direction_crossings: lambda_min.max(0.0),
            rms_residual_m: rms,
        }
    }
}

/// Signed distance along the chord from the crossing's midpoint to the centre.
fn residual(c: &Crossing, cx: f32, cy: f32) -> f32 {
    let d = c.direction();
    let m = c.midpoint();
    d.0 * (cx - m.0) + d.1 * (cy - m.1)
}

/// Least-squares centre over the inlier crossings (module docs, step 7); `None` without inliers.
fn fit_centre(crossings: &[Crossing]) -> Option<(f32, f32)> {
    // Work relative to the first inlier midpoint: keeps the sums small (f32 precision).
    let origin = crossings.iter().find(|c| c.inlier)?.midpoint();
    let (mut m00, mut m01, mut m11) = (0.0f32, 0.0f32, 0.0f32);
    let (mut r0, mut r1) = (0.0f32, 0.0f32);
    let (mut sx, mut sy, mut n) = (0.0f32, 0.0f32, 0.0f32);
    for c in crossings.iter().filter(|c| c.inlier) {
        let d = c.direction();
        let m = c.midpoint();
        let m = (m.0 - origin.0, m.1 - origin.1);
        let dm = d.0 * m.0 + d.1 * m.1;
        m00 += d.0 * d.0;
        m01 += d.0 * d.1;
        m11 += d.1 * d.1;
        r0 += d.0 * dm;
        r1 += d.1 * dm;
        sx += m.0;
        sy += m.1;
        n += 1.0;
    }
    let k = CENTROID_PULL * n;
    let (m00, m11) = (m00 + k, m11 + k);
    let (r0, r1) = (r0 + CENTROID_PULL * sx, r1 + CENTROID_PULL * sy);
    let det = m00 * m11 - m01 * m01;
    if !(det.is_finite() && det > 0.0) {
        return None;
    }
    let cx = (m11 * r0 - m01 * r1) / det;
    let cy = (m00 * r1 - m01 * r0) / det;
    Some((cx + origin.0, cy + origin.1))
}
