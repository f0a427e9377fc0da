//! CPU load and control-loop timing from a free-running cycle counter (the Cortex-M4's DWT `CYCCNT` on the
//! drone), for the log variables the firmware publishes.
//!
//! Job: account the cycles spent in measured work sections per priority level, *excluding* the time a
//! section was preempted by higher-priority sections, and keep the control loop's period spread and its
//! longest step over a window.
//!
//! How preemption is excluded: every finished section adds its exclusive cycles to one running total. A
//! section remembers that total when it begins; when it ends, whatever the total grew by meanwhile was done
//! by sections that preempted it (on a single core a section can only be interrupted by sections that
//! start *and* end inside it), so it subtracts that. Rule for callers: a section must not span an `.await`
//! (two sections of one level then never overlap).
//!
//! Non-goals: no clock access (the caller passes counter readings), no idle detection: work outside the
//! sections (executor overhead, DMA and EXTI interrupt handlers, the time driver) is not counted, so the
//! load reported is the load of the instrumented work.
//! Units: cycles (u32, wrapping: sections and windows must be shorter than 2^32 cycles, 25.5 s at 168 MHz).
//! Memory: [`LoadMeter`] is 16 bytes of atomics (usable from several interrupt priorities through `&`);
//! [`LoopTiming`] 32 bytes, owned by the control task.

use core::sync::atomic::{AtomicU32, Ordering};

/// The priority levels measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// Estimation and control (the highest-priority executor).
    Control = 0,
    /// Sensors and radio (the medium-priority executor).
    Io = 1,
    /// Mission and planning (thread mode).
    Mission = 2,
}

/// Number of [`Level`]s.
pub const LEVELS: usize = 3;

/// An open work section; hand it back to [`LoadMeter::end`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[must_use = "a section counts nothing until it is ended"]
pub struct Section {
    level: Level,
    start: u32,
    total_at_start: u32,
}

/// Busy cycles per level, preemption excluded. See the module documentation.
#[derive(Debug, Default)]
pub struct LoadMeter {
    busy: [AtomicU32; LEVELS],
    total: AtomicU32,
}

impl LoadMeter {
    /// A meter with nothing counted.
    pub const fn new() -> Self {
        Self {
            busy: [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)],
            total: AtomicU32::new(0),
        }
    }

    /// Opens a section of `level` at counter reading `now`.
    pub fn begin(&self, level: Level, now: u32) -> Section {
        Section {
            level,
            start: now,
            total_at_start: self.total.load(Ordering::Acquire),
        }
    }

    /// Closes `section` at counter reading `now`; returns its exclusive cycles (0 if the readings make no
    /// sense, e.g. more preemption than elapsed time).
    pub fn end(&self, section: Section, now: u32) -> u32 {
        let elapsed = now.wrapping_sub(section.start);
        let preempted = self.total.load(Ordering::Acquire).wrapping_sub(section.total_at_start);
        let exclusive = elapsed.saturating_sub(preempted);
        self.busy[section.level as usize].fetch_add(exclusive, Ordering::AcqRel);
        self.total.fetch_add(exclusive, Ordering::AcqRel);
        exclusive
    }

    /// The busy cycles per level since the previous call (or since creation), and restarts the count.
    pub fn take(&self) -> [u32; LEVELS] {
        [
            self.busy[0].swap(0, Ordering::AcqRel),
            self.busy[1].swap(0, Ordering::AcqRel),
            self.busy[2].swap(0, Ordering::AcqRel),
        ]
    }
}

/// `busy` cycles out of a `window` of cycles, in percent, rounded down and capped at 100 (0 for an empty
/// window).
pub fn percent(busy: u64, window: u64) -> u8 {
    if window == 0 {
        return 0;
    }
    (busy.saturating_mul(100) / window).min(100) as u8
}

/// Cycles → microseconds at `cpu_hz`, saturating at `u16::MAX` (the log variables are 16-bit).
pub fn cycles_to_us_u16(cycles: u32, cpu_hz: u32) -> u16 {
    if cpu_hz == 0 {
        return u16::MAX;
    }
    let us = u64::from(cycles) * 1_000_000 / u64::from(cpu_hz);
    u16::try_from(us).unwrap_or(u16::MAX)
}

/// What [`LoopTiming::take`] reports for one window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LoopWindow {
    /// Control steps in the window.
    pub steps: u32,
    /// Shortest interval between two step starts, cycles (0 with fewer than two steps).
    pub min_interval: u32,
    /// Longest interval between two step starts, cycles.
    pub max_interval: u32,
    /// Longest step (start to end), cycles.
    pub max_step: u32,
}

impl LoopWindow {
    /// Peak-to-peak spread of the step period, cycles: the loop jitter.
    pub fn jitter(&self) -> u32 {
        self.max_interval.saturating_sub(self.min_interval)
    }
}

/// The control loop's timing: period spread and longest step over a window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LoopTiming {
    last_start: Option<u32>,
    /// Intervals recorded in the current window.
    intervals: u32,
    window: LoopWindow,
}

impl LoopTiming {
    /// Nothing recorded.
    pub const fn new() -> Self {
        Self {
            last_start: None,
            intervals: 0,
            window: LoopWindow {
                steps: 0,
                min_interval: 0,
                max_interval: 0,
                max_step: 0,
            },
        }
    }

    /// One control step that began at counter reading `start` and ended at `end`.
    pub fn record(&mut self, start: u32, end: u32) {
        let w = &mut self.window;
        if let Some(prev) = self.last_start {
            let interval = start.wrapping_sub(prev);
            if self.intervals == 0 {
                w.min_interval = interval;
                w.max_interval = interval;
            } else {
                w.min_interval = w.min_interval.min(interval);
                w.max_interval = w.max_interval.max(interval);
            }
            self.intervals = self.intervals.saturating_add(1);
        }
        self.last_start = Some(start);
        w.steps = w.steps.saturating_add(1);
        w.max_step = w.max_step.max(end.wrapping_sub(start));
    }

    /// The window so far, and starts a new one (the next step's interval still counts from the last start).
    pub fn take(&mut self) -> LoopWindow {
        self.intervals = 0;
        core::mem::take(&mut self.window)
    }
}
