//! Pacing of the control step's queued inputs: at most one costly estimator update per 1 kHz step.
//!
//! Job: the control task drains its input queue before each step. A flow update (≈ 14 k instructions) and
//! a Multi-ranger sweep with wall anchors (≈ 20 k) landing in the same step made that step 37 k
//! instructions (QEMU counts, BENCHMARKS.md), a third of the core at CPI 1.5; the budget is a quarter. [`HeavyInputGate`]
//! lets the first costly input of a step through and holds the next one for the following step (1 ms
//! later; the sensors deliver at 100 Hz and 10 Hz, so it never holds more than one), and the caller stops
//! draining while it holds one, so the inputs keep their order.
//!
//! Non-goals: deciding which inputs are costly (the caller says so), any queue of its own beyond the one
//! held input.
//!
//! Units: control steps. Memory: one input plus a flag.

/// Holds back the second costly input of a control step (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeavyInputGate<T> {
    held: Option<T>,
    heavy_taken: bool,
}

impl<T> Default for HeavyInputGate<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T> HeavyInputGate<T> {
    /// A gate holding nothing.
    pub const fn new() -> Self {
        Self {
            held: None,
            heavy_taken: false,
        }
    }

    /// Starts a step: returns the input held from the previous step, to apply first (it is this step's
    /// costly input).
    pub fn begin_step(&mut self) -> Option<T> {
        let held = self.held.take();
        self.heavy_taken = held.is_some();
        held
    }

    /// An input taken from the queue: `Some` to apply it now, `None` if it is held for the next step (then
    /// stop draining until the next step, see [`holding`](Self::holding)).
    pub fn admit(&mut self, input: T, heavy: bool) -> Option<T> {
        if heavy {
            if self.heavy_taken {
                self.held = Some(input);
                return None;
            }
            self.heavy_taken = true;
        }
        Some(input)
    }

    /// An input is held for the next step.
    pub fn holding(&self) -> bool {
        self.held.is_some()
    }
}
