//! `mission.start` bookkeeping between the radio and an asynchronous mission task (docs/radio.md: a
//! refused start leaves the value in effect at 0; the firmware sets it back to 0 when the mission ends),
//! including the race where the outcome has not come back yet.

use cfnav::system::mission_start::{StartDecision, StartTracker};

#[test]
fn writes_map_to_requests() {
    let mut t = StartTracker::new();
    assert_eq!(t.on_write(0, 1, false), StartDecision::RequestStart);
    assert_eq!(t.on_write(1, 0, false), StartDecision::RequestAbort);
    assert_eq!(t.on_write(0, 0, false), StartDecision::None);
    assert_eq!(t.on_write(1, 1, false), StartDecision::None);
    assert!(
        matches!(t.on_write(0, 1, true), StartDecision::Refuse(_)),
        "no start after a fault"
    );
    // An abort is always passed on, fault or not: landing is the safe direction.
    assert_eq!(t.on_write(1, 0, true), StartDecision::RequestAbort);
    assert!(!t.pending(), "deciding alone does not make a request pending");
}

#[test]
fn a_request_that_cannot_be_queued_is_refused() {
    let mut t = StartTracker::new();
    assert!(t.request_queued(false).is_some());
    assert!(!t.pending());
    assert!(t.must_clear(1, false), "the refused value goes back to 0");
}

#[test]
fn no_reset_while_the_outcome_is_pending() {
    let mut t = StartTracker::new();
    assert_eq!(t.on_write(0, 1, false), StartDecision::RequestStart);
    assert_eq!(t.request_queued(true), None);
    assert!(t.pending());
    // The mission task has not run yet: no mission is running, but the start must not be undone.
    assert!(!t.must_clear(1, false));
    // Started.
    assert!(!t.on_outcome(true));
    assert!(!t.pending());
    assert!(!t.must_clear(1, true), "running: keep 1");
    // The mission ends: back to 0.
    assert!(t.must_clear(1, false));
    assert!(!t.must_clear(0, false), "already 0: nothing to do");
}

#[test]
fn a_refused_outcome_reverts() {
    let mut t = StartTracker::new();
    t.on_write(0, 1, false);
    t.request_queued(true);
    assert!(t.on_outcome(false), "refused by the flight core: revert");
    assert!(!t.pending());
    // A stray outcome without a pending request changes nothing.
    assert!(!t.on_outcome(false));
}
