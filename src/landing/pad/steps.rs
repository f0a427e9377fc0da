//! Pipeline stages 2–5 of the pad detector (see [`super`]): motion tracking, spatial bins, the smoothed
//! z-score, runs of signals confirmed and located as edges, and the edge list.
//!
//! Cost per sample O(1); per closed bin two insertion-sort medians of the `lag ≤ 32` window; O(`lag`) when
//! a step ends.

use super::{ActiveRun, Bin, Detection, Edge, EdgeKind, MAX_LAG, PadDetector, RING, Sample, median, serial_span};

/// The position is re-anchored (heading and odometer updated) every time the drone has moved this far.
/// 2 cm averages out position noise in the heading, yet is < 10 samples at 0.3 m/s and 100 Hz.
const HEADING_BASELINE_M: f32 = 0.02;
/// The heading at an edge is measured over this many bins before it (~2 cm): recent enough to notice a
/// turn just before the edge, long enough to average position noise.
const HEADING_BINS: u32 = 2;
/// Bins whose median is the level after a step (two stray bins among them cannot move it).
const AFTER_BINS: usize = 5;
/// A run ends after this many bins without its signal (one bad bin does not split a step in two).
const RUN_END_MISSES: u8 = 2;

impl<const EDGES: usize> PadDetector<EDGES> {
    /// Updates the heading and odometer; returns the sample's motion data.
    pub(super) fn track_motion(&mut self, x: f32, y: f32) -> Sample {
        let Some(anchor) = self.anchor else {
            self.anchor = Some((x, y));
            return Sample {
                x,
                y,
                odo: self.odo_at_anchor,
            };
        };
        let d = libm::hypotf(x - anchor.0, y - anchor.1);
        if d >= HEADING_BASELINE_M {
            self.heading = ((x - anchor.0) / d, (y - anchor.1) / d);
            self.odo_at_anchor += d;
            self.anchor = Some((x, y));
            return Sample {
                x,
                y,
                odo: self.odo_at_anchor,
            };
        }
        Sample {
            x,
            y,
            odo: self.odo_at_anchor + d,
        }
    }

    /// Closes the open bin: z-score, ring, run logic. Returns an edge stored as a result.
    pub(super) fn close_bin(&mut self) -> Option<Edge> {
        let n = self.bin_len.max(1) as f32;
        let range = median(self.bin.get_mut(..self.bin_len).unwrap_or(&mut []));
        let level = self.window_median();
        let signal = self.z_score(range);
        let bin = Bin {
            range,
            x: self.bin_sum.0 / n,
            y: self.bin_sum.1 / n,
            odo: self.bin_sum.2 / n,
            heading: self.heading,
            signal,
            level,
        };
        self.bin_len = 0;
        let serial = self.bins;
        if let Some(slot) = self.ring.get_mut(serial as usize % RING) {
            *slot = bin;
        }
        self.bins = self.bins.wrapping_add(1);
        let detection = self.follow_runs(serial, signal)?;
        self.on_detection(detection)
    }

    /// The smoothed z-score of one value: -1, 0 or +1. Updates the window.
    pub(super) fn z_score(&mut self, y: f32) -> i8 {
        let cfg = &self.config;
        if self.window_len < cfg.lag {
            // Training: the first `lag` values fill the window as they are.
            self.push_window(y);
            return 0;
        }
        let (centre, spread) = if cfg.robust_stats {
            self.window_robust_stats()
        } else {
            self.window_stats()
        };
        let dev = y - centre;
        let signal = if libm::fabsf(dev) > cfg.threshold_sigma * spread && libm::fabsf(dev) >= cfg.min_step_m {
            if dev > 0.0 { 1 } else { -1 }
        } else {
            0
        };
        let filtered = if signal != 0 {
            cfg.influence * y + (1.0 - cfg.influence) * self.last_filtered
        } else {
            y
        };
        self.push_window(filtered);
        signal
    }

    pub(super) fn push_window(&mut self, v: f32) {
        let lag = self.config.lag;
        if let Some(slot) = self.window.get_mut(self.window_head) {
            *slot = v;
        }
        self.window_head = (self.window_head + 1) % lag;
        self.window_len = (self.window_len + 1).min(lag);
        self.last_filtered = v;
    }

    /// Mean and population standard deviation of the window (two passes: exact, no drift).
    pub(super) fn window_stats(&self) -> (f32, f32) {
        let values = self.window.get(..self.window_len).unwrap_or(&[]);
        if values.is_empty() {
            return (0.0, 0.0);
        }
        let n = values.len() as f32;
        let mean = values.iter().sum::<f32>() / n;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / n;
        (mean, libm::sqrtf(var))
    }

    /// Median and σ estimated from the median absolute deviation (`1.4826·MAD`, the Gaussian σ). Neither
    /// moves for a few stray values in the window, or for the first bins of a blurred step.
    pub(super) fn window_robust_stats(&self) -> (f32, f32) {
        let mut copy = [0.0f32; MAX_LAG];
        let (Some(dst), Some(src)) = (copy.get_mut(..self.window_len), self.window.get(..self.window_len)) else {
            return (self.last_filtered, 0.0);
        };
        if src.is_empty() {
            return (self.last_filtered, 0.0);
        }
        dst.copy_from_slice(src);
        let med = median(dst);
        for v in dst.iter_mut() {
            *v = libm::fabsf(*v - med);
        }
        (med, 1.4826 * median(dst))
    }

    /// Median of the window: the level before a step, robust to the first part of a blurred step and
    /// to stray values. The last value pushed stands in while the window is empty.
    pub(super) fn window_median(&self) -> f32 {
        let mut copy = [0.0f32; MAX_LAG];
        let Some(dst) = copy.get_mut(..self.window_len) else {
            return self.last_filtered;
        };
        let Some(src) = self.window.get(..self.window_len) else {
            return self.last_filtered;
        };
        if src.is_empty() {
            return self.last_filtered;
        }
        dst.copy_from_slice(src);
        median(dst)
    }

    /// Direction of travel into bin `serial` (at `hit`), from the bin [`HEADING_BINS`] before it; the
    /// slower-moving anchor heading when that is missing or too close (hovering).
    pub(super) fn heading_before(&self, serial: u32, hit: Bin) -> (f32, f32) {
        let from = serial.checked_sub(HEADING_BINS).and_then(|s| self.ring_bin(s));
        if let Some(b) = from {
            let (dx, dy) = (hit.x - b.x, hit.y - b.y);
            let d = libm::hypotf(dx, dy);
            if d >= 0.005 {
                return (dx / d, dy / d);
            }
        }
        hit.heading
    }

    pub(super) fn ring_bin(&self, serial: u32) -> Option<&Bin> {
        // Only the last RING serials are still in the ring.
        if self.bins.wrapping_sub(serial) as usize > RING || serial >= self.bins {
            return None;
        }
        self.ring.get(serial as usize % RING)
    }

    /// Run bookkeeping after bin `serial` with `signal`: ends runs, confirms new ones (module docs,
    /// step 4). Returns the detection of a run that ended.
    pub(super) fn follow_runs(&mut self, serial: u32, signal: i8) -> Option<Detection> {
        let mut ended = None;
        if let Some(mut run) = self.run {
            run.misses = if signal == run.sign {
                0
            } else {
                run.misses.saturating_add(1)
            };
            // A run older than the ring can hold is located now, before its start is overwritten.
            let too_long = serial.wrapping_sub(run.first) as usize + self.config.lag + 2 >= RING;
            if run.misses >= RUN_END_MISSES || too_long {
                ended = self.locate(&run, serial);
                self.run = None;
            } else {
                self.run = Some(run);
            }
        }
        if signal != 0 && self.run.is_none_or(|r| r.sign != signal) {
            // m of n: `min_run` of the last `min_run + 1` bins carry this sign.
            let n = self.config.min_run as u32 + 1;
            let mut count = 0usize;
            let mut first = serial;
            for back in 0..n {
                let Some(s) = serial.checked_sub(back) else { break };
                if self.ring_bin(s).is_some_and(|b| b.signal == signal) {
                    count += 1;
                    first = s;
                }
            }
            if count >= self.config.min_run {
                // An opposite run still open ends here (a narrow crossing); report it first.
                if let Some(run) = self.run.take() {
                    ended = ended.or(first.checked_sub(1).and_then(|end| self.locate(&run, end)));
                }
                self.run = Some(ActiveRun {
                    sign: signal,
                    first,
                    misses: 0,
                });
            }
        }
        ended
    }

    /// Locates a finished run's step (module docs, step 4): where the binned range crosses halfway
    /// between the levels before and after, interpolated between bin centres.
    /// `end` is the run's last bin (the newest, or the one before a new run took over).
    pub(super) fn locate(&mut self, run: &ActiveRun, end: u32) -> Option<Detection> {
        let first = *self.ring_bin(run.first)?;
        let before = first.level;
        // The level after: median of the run's last bins, signalling or not. (Not "the last signalling
        // bins": once the window has caught up with the step only stray bins still signal.)
        let mut tail = [0.0f32; AFTER_BINS];
        let mut k = 0usize;
        let mut s = end;
        while k < tail.len() && s >= run.first {
            if let (Some(b), Some(slot)) = (self.ring_bin(s), tail.get_mut(k)) {
                *slot = b.range;
                k += 1;
            }
            let Some(prev) = s.checked_sub(1) else { break };
            s = prev;
        }
        let after = median(tail.get_mut(..k).unwrap_or(&mut []));
        let height = after - before;
        if libm::fabsf(height) < self.config.min_step_m {
            return None;
        }
        // Position of a bin between the two levels: 0 = before, 1 = after. Bins beyond either level by
        // more than half the step are stray (outliers that survived the bin) and are skipped.
        let level_of = |b: &Bin| (b.range - before) / height;
        let stray = |b: &Bin| !(-0.5..=1.5).contains(&level_of(b));
        let new_side = |b: &Bin| level_of(b) > 0.5;

        // Walk back from the settled end of the run to the first two consecutive (non-stray) bins on the
        // old side of the half level: the step lies between the later of them and the next non-stray bin.
        // Starting from the settled end (not the first signal) keeps a stray bin just before a blurred
        // step from being taken for the step; needing two old-side bins skips a stray one on the new level.
        let start = end.wrapping_add(1);
        let limit = serial_span(run.first, start) + self.config.lag;
        let mut later: Option<(u32, Bin)> = None;
        let mut old_pair: Option<Bin> = None;
        let mut crossing = None;
        let mut s = start;
        for _ in 0..limit {
            let Some(prev) = s.checked_sub(1) else { break };
            s = prev;
            let Some(b) = self.ring_bin(s).copied() else { break };
            if stray(&b) {
                continue;
            }
            if new_side(&b) {
                later = Some((s, b));
                old_pair = None;
            } else if let Some(first_old) = old_pair {
                crossing = later.map(|(at, hit)| (first_old, hit, at));
                break;
            } else {
                old_pair = Some(b);
            }
        }
        let (old, hit, at_serial) = match crossing {
            Some(found) => found,
            // No clean old level found in the ring: fall back to the first signalling bin.
            None => (*self.ring_bin(run.first)?, *self.ring_bin(run.first)?, run.first),
        };
        let (mut x, mut y, mut odo) = (hit.x, hit.y, hit.odo);
        let t = (0.5 - level_of(&old)) / (level_of(&hit) - level_of(&old));
        if t.is_finite() {
            let t = t.clamp(0.0, 1.0);
            x = old.x + t * (hit.x - old.x);
            y = old.y + t * (hit.y - old.y);
            odo = old.odo + t * (hit.odo - old.odo);
        }
        let kind = if height < 0.0 { EdgeKind::Enter } else { EdgeKind::Exit };
        let detection = Detection {
            edge: Edge {
                x,
                y,
                kind,
                step_m: height,
            },
            odo,
            heading: self.heading_before(at_serial, hit),
            level_before: before,
            level_after: after,
        };
        // The same step flickering back on: merge it with the edge it belongs to.
        if let Some(last) = self.last_detection
            && last.edge.kind == kind
            && libm::fabsf(detection.odo - last.odo) < self.config.min_edge_spacing_m
        {
            return None;
        }
        self.last_detection = Some(detection);
        Some(detection)
    }

    /// Stores the edge (unless a duplicate) and pairs it into a crossing.
    pub(super) fn on_detection(&mut self, det: Detection) -> Option<Edge> {
        let stored = self.store_edge(det.edge);
        match det.edge.kind {
            EdgeKind::Enter => self.pending_enter = Some(det),
            EdgeKind::Exit => {
                if let Some(enter) = self.pending_enter.take()
                    && let Some(crossing) = self.pair(&enter, &det).or_else(|| self.turn_back(&enter, &det))
                {
                    if self.crossings.push(crossing).is_err() {
                        self.dropped = self.dropped.saturating_add(1);
                    } else {
                        self.refit();
                    }
                }
            }
        }
        stored
    }

    pub(super) fn store_edge(&mut self, edge: Edge) -> Option<Edge> {
        let spacing = self.config.min_edge_spacing_m;
        if self
            .edges
            .iter()
            .any(|e| libm::hypotf(e.x - edge.x, e.y - edge.y) < spacing)
        {
            return None;
        }
        if self.edges.push(edge).is_err() {
            self.dropped = self.dropped.saturating_add(1);
            return None;
        }
        Some(edge)
    }
}
