//! The independent watchdog (IWDG): its real timeout over the LSI's tolerance, and the rule that decides,
//! at each feed opportunity, whether the firmware is healthy enough to feed it.
//!
//! Job: (1) the IWDG's prescaler and reload as embassy-stm32 0.6 computes them from a requested timeout
//! with a nominal 32 kHz LSI ([`IwdgSetting::embassy`], a copy of `wdg/mod.rs`'s arithmetic), and the timeout
//! that setting really gives at any LSI frequency ([`IwdgSetting::timeout_us`]); the STM32F405's LSI is
//! 17–47 kHz (DS8626 rev 9, table 41 "LSI oscillator characteristics"), so the shortest real timeout comes
//! with the fastest LSI (47 kHz: 68 % of nominal) and the longest with the slowest (17 kHz: 188 %).
//! (2) [`FeedGate`]: the feeder runs at interrupt priority (the firmware's I/O executor), where no
//! thread-mode planner slice can delay it, and feeds only while thread mode and the control loop both
//! show progress within their own limits ([`THREAD_STALL_US`], [`CONTROL_STALL_US`]). A stuck thread mode
//! or control loop therefore resets the MCU [`THREAD_STALL_US`] (or [`CONTROL_STALL_US`]) plus at most one
//! real IWDG timeout after it last made progress; a long but finite planner slice never does.
//!
//! Non-goals: no register access (the board layer owns the IWDG), no clock (times are passed in, µs).
//!
//! Units: µs, Hz. Memory: [`FeedGate`] is 24 bytes.

use crate::types::Micros;

/// The STM32F405's LSI, slowest (DS8626 table 41).
pub const LSI_MIN_HZ: u32 = 17_000;
/// The LSI's typical frequency, which embassy-stm32 assumes (`rcc::LSI_FREQ` = 32 kHz on F4).
pub const LSI_TYP_HZ: u32 = 32_000;
/// The STM32F405's LSI, fastest (DS8626 table 41): the shortest real timeout.
pub const LSI_MAX_HZ: u32 = 47_000;
/// The IWDG reload field's largest value (12 bits).
pub const MAX_RELOAD: u16 = 0xFFF;

/// The nominal timeout the board asks embassy for, µs. With embassy's rounding it gives prescaler 4,
/// reload 1199: 150 ms at 32 kHz, 102.1 ms at 47 kHz, 282.4 ms at 17 kHz (stock: 100–353 ms,
/// crazyflie-firmware `src/drivers/src/watchdog.c`).
pub const NOMINAL_TIMEOUT_US: u32 = 150_000;
/// The shortest real timeout the feeder's period and latency need, µs (stock's goal: "> 100 ms").
pub const MIN_TIMEOUT_US: u32 = 100_000;
/// How often the feeder runs, µs: a fifth of [`MIN_TIMEOUT_US`], so four periods of lateness are tolerated.
pub const FEED_PERIOD_US: u32 = 20_000;
/// Thread mode (the mission task) must report progress within this, µs. The longest thread-mode slice is one
/// planner slice (QEMU counts in BENCHMARKS.md: 4000 expansions ≈ 6.5 M instructions, ≤ 155 ms even at a CPI of 3
/// with the control and I/O executors taking a quarter of the core), so this leaves a 3× margin.
pub const THREAD_STALL_US: u32 = 500_000;
/// The control loop (1 kHz) must advance within this once running, µs (its own missed-edge handling stops the
/// motors after 5 ms; this catches a control executor that stopped altogether).
pub const CONTROL_STALL_US: u32 = 50_000;

/// An IWDG prescaler and reload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IwdgSetting {
    /// Divider of the LSI: 4, 8, …, 256.
    pub prescaler: u16,
    /// Reload value, 0..=[`MAX_RELOAD`].
    pub reload: u16,
}

impl IwdgSetting {
    /// What `embassy_stm32::wdg::IndependentWatchdog::new(timeout_us)` programs (embassy-stm32 0.6.0
    /// `src/wdg/mod.rs`: the smallest prescaler 2^2..2^8 whose 4096-count timeout at 32 kHz reaches
    /// `timeout_us`, then `reload = timeout_us / prescaler * 32000 / 1e6 - 1` in u32 arithmetic); `None` where
    /// embassy would panic (no prescaler fits, or a reload below 0).
    pub fn embassy(timeout_us: u32) -> Option<Self> {
        let mut power = 2u32;
        while power <= 8 {
            let prescaler = 1u32 << power;
            let max_timeout = 1_000_000u64 * (u64::from(MAX_RELOAD) + 1) / u64::from(LSI_TYP_HZ / prescaler);
            if u64::from(timeout_us) <= max_timeout {
                let counts = u64::from(timeout_us / prescaler) * u64::from(LSI_TYP_HZ) / 1_000_000;
                let reload = counts.checked_sub(1)?;
                return Some(Self {
                    prescaler: prescaler as u16,
                    reload: u16::try_from(reload).ok()?,
                });
            }
            power += 1;
        }
        None
    }

    /// The timeout this setting gives when the LSI runs at `lsi_hz`, µs (RM0090 §19.3.3: the counter counts
    /// `reload + 1` periods of LSI / prescaler); `u32::MAX` at 0 Hz.
    pub fn timeout_us(&self, lsi_hz: u32) -> u32 {
        if lsi_hz == 0 {
            return u32::MAX;
        }
        let us = (u64::from(self.reload) + 1) * u64::from(self.prescaler) * 1_000_000 / u64::from(lsi_hz);
        u32::try_from(us).unwrap_or(u32::MAX)
    }

    /// The shortest real timeout over the datasheet's LSI range.
    pub fn worst_case_timeout_us(&self) -> u32 {
        self.timeout_us(LSI_MAX_HZ)
    }

    /// The longest real timeout over the datasheet's LSI range.
    pub fn longest_timeout_us(&self) -> u32 {
        self.timeout_us(LSI_MIN_HZ)
    }
}

/// What the feeder sees at one feed opportunity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FeedInputs {
    /// Now, µs.
    pub now_us: Micros,
    /// Initialisation has finished (before that only the boot task runs in thread mode; a boot fault keeps
    /// the feeder feeding so the red LEDs stay on instead of a reset loop).
    pub booted: bool,
    /// The control loop was started.
    pub control_running: bool,
    /// Control loop passes so far (wrapping): each pass counts, a sample flown or a missed one, so a lost IMU
    /// (which the loop handles: motors off, fault latched) does not starve the feed; a loop that stopped does.
    pub control_passes: u32,
    /// Thread-mode heartbeats so far (wrapping; the mission task counts one per tick).
    pub thread_beats: u32,
}

/// Why the feeder withholds the feed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Starved {
    /// Thread mode made no progress for longer than [`THREAD_STALL_US`].
    ThreadMode,
    /// The control loop made no progress for longer than [`CONTROL_STALL_US`].
    Control,
}

/// Decides at each feed opportunity whether to feed the IWDG (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FeedGate {
    control_passes: u32,
    control_seen_us: Option<Micros>,
    thread_beats: u32,
    thread_seen_us: Option<Micros>,
}

impl FeedGate {
    /// A gate that has seen nothing yet.
    pub const fn new() -> Self {
        Self {
            control_passes: 0,
            control_seen_us: None,
            thread_beats: 0,
            thread_seen_us: None,
        }
    }

    /// Ok to feed now, or why not. The first observation of each counter (and the moment the firmware
    /// boots or the control loop starts) counts as progress.
    pub fn decide(&mut self, inputs: FeedInputs) -> Result<(), Starved> {
        let now = inputs.now_us;
        if !inputs.booted {
            self.thread_seen_us = None;
            self.control_seen_us = None;
            return Ok(());
        }
        let thread_last = Self::progress(
            &mut self.thread_beats,
            &mut self.thread_seen_us,
            inputs.thread_beats,
            now,
        );
        let control_last = if inputs.control_running {
            Some(Self::progress(
                &mut self.control_passes,
                &mut self.control_seen_us,
                inputs.control_passes,
                now,
            ))
        } else {
            self.control_seen_us = None;
            None
        };
        if now.saturating_sub(thread_last) > u64::from(THREAD_STALL_US) {
            return Err(Starved::ThreadMode);
        }
        if control_last.is_some_and(|t| now.saturating_sub(t) > u64::from(CONTROL_STALL_US)) {
            return Err(Starved::Control);
        }
        Ok(())
    }

    /// Updates one counter's last-progress time and returns it.
    fn progress(seen: &mut u32, seen_at: &mut Option<Micros>, count: u32, now: Micros) -> Micros {
        match *seen_at {
            Some(t) if *seen == count => t,
            _ => {
                *seen = count;
                *seen_at = Some(now);
                now
            }
        }
    }
}
