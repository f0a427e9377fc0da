//! The `mission.start` parameter's bookkeeping when the mission runs in another task than the radio (the
//! firmware: radio at interrupt priority, mission in thread mode), so a start is only *requested* when the
//! client writes 1 and its outcome comes back later.
//!
//! Job: turn a write of `mission.start` into a request for the mission task or a refusal, and tell the radio
//! when the parameter must go back to 0: a refused start (the outcome came back as an error, or the request
//! could not be queued, or a fault is recorded) and the end of a mission (`docs/radio.md`: "back to 0 when
//! it ends, set by the firmware, which then queues a VALUE_UPDATED").
//!
//! Rule that avoids the race: while a start request is pending (sent, no outcome yet) the parameter is never
//! reset for "no mission running", because the mission task may not have started it yet.
//!
//! Non-goals: no queue or signal (the caller moves the requests and outcomes), no parameter store (the caller
//! applies [`StartDecision`]s to it), no console (the caller prints the reason).
//! Memory: one flag.

/// What to do after a write changed `mission.start`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartDecision {
    /// Nothing (the value did not change, or changed in a way that needs no action).
    None,
    /// Send a start request to the mission task; call [`StartTracker::request_queued`] with whether it went.
    RequestStart,
    /// Send an abort request to the mission task.
    RequestAbort,
    /// Refuse: put the parameter back to 0, notify the client, print the reason.
    Refuse(&'static str),
}

/// See the module documentation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StartTracker {
    pending: bool,
}

impl StartTracker {
    /// No request pending.
    pub const fn new() -> Self {
        Self { pending: false }
    }

    /// A start request is with the mission task, without an outcome yet.
    pub fn pending(&self) -> bool {
        self.pending
    }

    /// The client's write changed `mission.start` from `before` to `after` (values the parameter store
    /// accepted); `fault` says whether the firmware has recorded a fault (motors off until reset).
    pub fn on_write(&mut self, before: u8, after: u8, fault: bool) -> StartDecision {
        match (before, after) {
            (0, 1) if fault => StartDecision::Refuse("mission.start refused: a fault is recorded; power-cycle\n"),
            (0, 1) => StartDecision::RequestStart,
            (1, 0) => StartDecision::RequestAbort,
            _ => StartDecision::None,
        }
    }

    /// Whether the start request of [`StartDecision::RequestStart`] could be queued; `Some(reason)` to refuse
    /// (parameter back to 0) if not.
    pub fn request_queued(&mut self, queued: bool) -> Option<&'static str> {
        self.pending = queued;
        (!queued).then_some("mission.start refused: the mission task is busy\n")
    }

    /// The mission task's answer to the pending request: `true` = started. Returns whether the parameter
    /// must go back to 0 (a refusal). An outcome with no request pending changes nothing.
    pub fn on_outcome(&mut self, started: bool) -> bool {
        let was_pending = core::mem::replace(&mut self.pending, false);
        was_pending && !started
    }

    /// Whether `mission.start` (now `start`) must go back to 0 because no mission runs: the mission ended,
    /// or was aborted. Never while a start request is pending.
    pub fn must_clear(&self, start: u8, mission_running: bool) -> bool {
        !self.pending && start == 1 && !mission_running
    }
}
