//! `--track FILE`: the emulated flight as a list of points for `cfnav pil --plot` (tools/src/pil.rs draws it
//! with the simulator's figure, tools/src/sim/plot.rs).
//!
//! Each point pairs what the image believed with the truth at the same instant: the estimate, yaw and mission
//! state come from the image's trace log block (`hover::TraceSample`, every 50 ms through the emulated radio,
//! as a cfclient user would see them), stamped with the image's own clock; the truth is the rigid body's
//! position at that stamp, interpolated from a short history sampled every 10 ms. The image's clock starts at
//! its reset, as the emulator's virtual time does, so the two agree to the millisecond. Memory: the history
//! holds 1 s; a 60 s flight writes about 1 200 points (≈ 100 kB of JSON).

use std::collections::VecDeque;

use cfnav_sim::report::TrackPoint;

use crate::hover::TraceSample;

/// How often the truth history is sampled, ns.
const HISTORY_PERIOD_NS: u64 = 10_000_000;
/// How much truth history is kept, ns (the radio's delay is far shorter).
const HISTORY_SPAN_NS: u64 = 1_000_000_000;

/// Collects the track during a run.
#[derive(Debug, Default)]
pub struct TrackRecorder {
    /// (virtual ns, position, airborne), oldest first.
    history: VecDeque<(u64, [f32; 3], bool)>,
    pub points: Vec<TrackPoint>,
}

impl TrackRecorder {
    /// The truth at virtual time `t_ns` (called every emulator slice; keeps one sample per 10 ms).
    pub fn truth(&mut self, t_ns: u64, position: [f32; 3], airborne: bool) {
        if self
            .history
            .back()
            .is_some_and(|&(t, _, _)| t_ns < t + HISTORY_PERIOD_NS)
        {
            return;
        }
        self.history.push_back((t_ns, position, airborne));
        while self
            .history
            .front()
            .is_some_and(|&(t, _, _)| t + HISTORY_SPAN_NS < t_ns)
        {
            self.history.pop_front();
        }
    }

    /// One trace sample from the image.
    pub fn sample(&mut self, s: &TraceSample) {
        let t_ns = u64::from(s.at_ms) * 1_000_000;
        let Some((truth, airborne)) = self.truth_at(t_ns) else {
            return;
        };
        if !s.position_m.iter().all(|v| v.is_finite()) {
            return;
        }
        self.points.push(TrackPoint {
            t_s: t_ns as f64 * 1e-9,
            truth,
            estimate: s.position_m,
            airborne,
            state: s.mission_state,
        });
    }

    /// The truth at `t_ns`, linearly between the two history samples around it; the nearest end outside
    /// the history; `None` before any truth.
    fn truth_at(&self, t_ns: u64) -> Option<([f32; 3], bool)> {
        let first = *self.history.front()?;
        let last = *self.history.back()?;
        if t_ns <= first.0 {
            return Some((first.1, first.2));
        }
        if t_ns >= last.0 {
            return Some((last.1, last.2));
        }
        let after = self.history.iter().position(|&(t, _, _)| t >= t_ns)?;
        let (t1, p1, a1) = self.history[after];
        let (t0, p0, _) = self.history[after.saturating_sub(1)];
        let f = if t1 > t0 {
            (t_ns - t0) as f32 / (t1 - t0) as f32
        } else {
            1.0
        };
        Some(([0, 1, 2].map(|k| p0[k] + (p1[k] - p0[k]) * f), a1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(at_ms: u32, x: f32) -> TraceSample {
        TraceSample {
            at_ms,
            position_m: [x, 1.0, 0.5],
            yaw_deg: 0.0,
            zrange_mm: 500,
            mission_state: 11,
        }
    }

    #[test]
    fn a_sample_is_paired_with_the_truth_at_its_own_time_stamp() {
        let mut r = TrackRecorder::default();
        // The truth moves 1 m/s along x; slices of 1 ms, history every 10 ms.
        for ms in 0..=300u64 {
            r.truth(ms * 1_000_000, [ms as f32 * 1e-3, 1.0, 0.5], ms > 100);
        }
        // The sample arrives late (now 300 ms) but is stamped 155 ms: its truth is x = 0.155.
        r.sample(&sample(155, 0.16));
        let p = r.points[0];
        assert!((p.truth[0] - 0.155).abs() < 1e-4, "{p:?}");
        assert!((p.t_s - 0.155).abs() < 1e-9 && p.airborne && p.state == 11);
        assert_eq!(p.estimate, [0.16, 1.0, 0.5]);
        // Stamped after the newest truth: the newest; before any: nothing is invented.
        r.sample(&sample(900, 0.0));
        assert!((r.points[1].truth[0] - 0.300).abs() < 1e-6);
        let mut empty = TrackRecorder::default();
        empty.sample(&sample(10, 0.0));
        assert!(empty.points.is_empty());
        // A non-finite estimate (a garbled packet) is left out.
        let mut bad = sample(200, f32::NAN);
        bad.position_m[0] = f32::NAN;
        r.sample(&bad);
        assert_eq!(r.points.len(), 2);
    }

    #[test]
    fn the_history_keeps_one_second() {
        let mut r = TrackRecorder::default();
        for ms in 0..5_000u64 {
            r.truth(ms * 1_000_000, [0.0; 3], false);
        }
        assert!(r.history.len() <= 101, "{}", r.history.len());
        assert!(r.history.front().unwrap().0 >= 3_990_000_000);
    }
}
