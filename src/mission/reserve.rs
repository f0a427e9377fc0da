//! The exploration's battery reserve: how long the battery still lasts, from the discharge the
//! drone measures in flight, against how long the flight home takes.
//!
//! Job: a sans-IO watch of the supervisor's filtered battery voltage (the only battery figure the firmware
//! has: the nRF51 reports the loaded voltage, no current). [`DischargeWatch::on_sample`] keeps, from
//! [`SETTLE_US`] after its first call, one sample every [`SAMPLE_PERIOD_US`] over the last [`WINDOW`]; [`DischargeWatch::rate_v_per_s`] is the
//! least-squares slope over them (a straight line through a window of up to 30 s: the noise of one
//! sample does not decide), once they span [`MIN_SPAN_S`]. [`remaining_s`] extrapolates it down to the supervisor's
//! battery-low threshold (below which it lands where it is). The mission compares that with the flight home
//! ([`needed_s`]: the planned home path at the cruise speed plus the home pad's search and landing, times
//! `mission.batReserve`) and turns home when the battery no longer covers it.
//!
//! Why a measured slope and not a charge model: the drone knows neither the capacity nor the current, and
//! a battery that is old, cold or drained faster (the simulator's drain multiplier) shows it in the slope.
//! The LiPo curve steepens towards empty (the simulator's OCV table: 3.92 V at 50 %, 3.78 V at 10 %,
//! 3.00 V at 0 %; loaded, 0.25 Ω × ≈ 2.3 A lower), so a linear extrapolation is optimistic near the end:
//! the reserve factor covers that, and the supervisor's battery-low landing stays the last resort.
//!
//! Non-goals: no state-of-charge estimate, no current model, no rule for the round trip (it has no choice
//! of when to turn). Units: V, s, µs ([`Micros`]), m. Memory: 16 samples, ≈ 200 B.

use crate::types::Micros;

/// Samples begin this long after the watch's first call (the exploration's first look), µs: the
/// take-off's sag is still settling (a LiPo's polarisation; the simulator's R1 = 0.08 Ω, τ = 15 s,
/// ≈ 0.18 V at hover current). Counted as discharge from the first look it read 15 mV/s where the charge
/// drained at ≈ 4 (half charge, drain ×3, the default world); what is left of it after this settling
/// errs on the safe side (an earlier turn home), and waiting longer leaves a weak battery no time to act.
pub const SETTLE_US: Micros = 8_000_000;
/// One sample this often, µs.
pub const SAMPLE_PERIOD_US: Micros = 2_000_000;
/// Samples kept (the slope's window: 15 periods, 30 s).
pub const WINDOW: usize = 16;
/// The slope is trusted once the samples span this long, s.
pub const MIN_SPAN_S: f32 = 8.0;
/// Slowest discharge assumed, V/s: a flat stretch of the curve (or noise) must not promise hours.
pub const MIN_RATE_V_PER_S: f32 = 0.2e-3;
/// The home pad's search and landing after the flight home, s (the default world's goal pad: search
/// ≈ 8 s, approach and descent ≈ 3 s, `host-tests/tests/sim/link_loss.rs`'s timeline; rounded up).
pub const SEARCH_AND_LAND_S: f32 = 15.0;

/// See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DischargeWatch {
    samples: [(Micros, f32); WINDOW],
    len: usize,
    /// Index of the oldest sample once the ring is full.
    head: usize,
    next_at: Micros,
    /// The first call, µs (samples begin [`SETTLE_US`] later).
    since: Option<Micros>,
}

impl Default for DischargeWatch {
    fn default() -> Self {
        Self::new()
    }
}

impl DischargeWatch {
    /// No samples.
    pub const fn new() -> Self {
        Self {
            samples: [(0, 0.0); WINDOW],
            len: 0,
            head: 0,
            next_at: 0,
            since: None,
        }
    }

    /// Forget every sample (a new flight).
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The filtered battery voltage at `now`; kept when a sample is due. Not finite or not positive (no
    /// reading yet) is ignored.
    pub fn on_sample(&mut self, now: Micros, volts: f32) {
        let since = *self.since.get_or_insert(now);
        if now.saturating_sub(since) < SETTLE_US
            || !(volts.is_finite() && volts > 0.0)
            || (self.len > 0 && now < self.next_at)
        {
            return;
        }
        self.next_at = now.saturating_add(SAMPLE_PERIOD_US);
        if self.len < WINDOW {
            self.samples[self.len] = (now, volts);
            self.len += 1;
        } else {
            self.samples[self.head] = (now, volts);
            self.head = (self.head + 1) % WINDOW;
        }
    }

    /// The discharge rate, V/s (positive while discharging, at least [`MIN_RATE_V_PER_S`]): the
    /// least-squares slope of the samples; `None` until they span [`MIN_SPAN_S`].
    pub fn rate_v_per_s(&self) -> Option<f32> {
        let s = &self.samples[..self.len];
        let t0 = s.iter().map(|p| p.0).min()?;
        let t1 = s.iter().map(|p| p.0).max()?;
        if ((t1 - t0) as f32 * 1e-6) < MIN_SPAN_S {
            return None;
        }
        let n = s.len() as f32;
        let t = |p: &(Micros, f32)| (p.0 - t0) as f32 * 1e-6;
        let mean_t = s.iter().map(t).sum::<f32>() / n;
        let mean_v = s.iter().map(|p| p.1).sum::<f32>() / n;
        let (mut stt, mut stv) = (0.0f32, 0.0f32);
        for p in s {
            let dt = t(p) - mean_t;
            stt += dt * dt;
            stv += dt * (p.1 - mean_v);
        }
        if stt <= 0.0 {
            return None;
        }
        Some((-stv / stt).max(MIN_RATE_V_PER_S))
    }
}

/// How long until the voltage `volts` falls to `low_v` at `rate_v_per_s`, s (0 when already below).
pub fn remaining_s(volts: f32, low_v: f32, rate_v_per_s: f32) -> f32 {
    ((volts - low_v) / rate_v_per_s.max(MIN_RATE_V_PER_S)).max(0.0)
}

/// What the flight home needs, s: `home_path_m` at `speed_m_s`, plus [`SEARCH_AND_LAND_S`], times
/// `reserve` (`mission.batReserve`).
pub fn needed_s(home_path_m: f32, speed_m_s: f32, reserve: f32) -> f32 {
    (home_path_m.max(0.0) / speed_m_s.max(0.05) + SEARCH_AND_LAND_S) * reserve.max(1.0)
}
