//! What `cfnav mission start` makes of the `mission.state` samples: names for the codes, when the mission
//! has ended, and the exit status.
//!
//! Job: pure logic, no I/O, so it can be tested without a drone. The codes are `cfnav::mission::MissionState`'s
//! (docs/radio.md: 0 idle, 1..=99 phases, 100 completed, ≥ 200 ended without completing).
//!
//! The one subtle rule: a drone that already flew a mission keeps reporting its final code until the next
//! start takes effect, and log samples taken just before the start may arrive after it. So after the start,
//! a final code counts only once the mission has been seen running (a code in 1..=99), or when it differs
//! from the code seen before the start, or after [`STALE_FINAL_GRACE_MS`] of drone time.
//!
//! Non-goals: drawing (see `mod.rs`). Memory: a few bytes.

use cfnav::mission::MissionState;

/// Drone milliseconds after which a final code that was already there before the start is believed.
pub const STALE_FINAL_GRACE_MS: u32 = 3000;

/// Every `mission.state` code with a short description (README.md "The mission" table).
pub const STATES: &[(MissionState, &str)] = &[
    (MissionState::Idle, "idle, ready"),
    (MissionState::Preflight, "started, waiting for a valid estimate"),
    (MissionState::TakeOffOutbound, "taking off from the home pad"),
    (MissionState::NavigateToGoal, "navigating to the goal"),
    (MissionState::SearchGoalPad, "searching the goal pad"),
    (MissionState::ApproachGoalPad, "moving over the goal pad"),
    (MissionState::LandOnGoalPad, "landing on the goal pad"),
    (MissionState::OnGoalPad, "on the goal pad, motors off"),
    (MissionState::TakeOffReturn, "taking off from the goal pad"),
    (MissionState::NavigateHome, "navigating home"),
    (MissionState::SearchHomePad, "searching the home pad"),
    (MissionState::ApproachHomePad, "moving over the home pad"),
    (MissionState::LandOnHomePad, "landing on the home pad"),
    (MissionState::NoPathHover, "no path: hovering"),
    (MissionState::EmergencyLanding, "landing where it is"),
    (MissionState::Completed, "completed"),
    (MissionState::Aborted, "aborted by the user, landed"),
    (MissionState::NoPath, "no path, landed"),
    (MissionState::PadNotFound, "a pad was not found"),
    (MissionState::BatteryLow, "battery low, landed"),
    (MissionState::EstimatorFault, "estimate lost, landed"),
    (MissionState::Crashed, "crashed: motors cut"),
    (MissionState::PlannerFault, "planner fault"),
];

/// The description of `code`, or a generic one for a code this build does not know.
pub fn state_name(code: u8) -> &'static str {
    match STATES.iter().find(|(s, _)| s.code() == code) {
        Some((_, name)) => name,
        None if code == 0 => "idle",
        None if code < 100 => "a phase this tool does not know",
        None if code == 100 => "completed",
        None => "ended without completing",
    }
}

/// How the mission ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// `mission.state` 100.
    Completed,
    /// Any other final code (≥ 101; 200 and above name why).
    NotCompleted(u8),
}

impl Outcome {
    /// The final code.
    pub fn code(self) -> u8 {
        match self {
            Self::Completed => MissionState::Completed.code(),
            Self::NotCompleted(code) => code,
        }
    }

    /// The command's exit status: 0 completed, 1 not.
    pub fn exit_code(self) -> u8 {
        match self {
            Self::Completed => 0,
            Self::NotCompleted(_) => 1,
        }
    }
}

/// Follows the samples of one mission.
#[derive(Clone, Debug, Default)]
pub struct MissionTracker {
    /// The last code sampled before the start was accepted.
    before_start: Option<u8>,
    /// Drone time (ms, 24-bit log clock) of the first sample after the start.
    first_after_start_ms: Option<u32>,
    started: bool,
    seen_running: bool,
    last_code: Option<u8>,
    outcome: Option<Outcome>,
}

/// Milliseconds from `from` to `to` on the 24-bit log clock (it wraps after about 4.6 hours).
pub fn log_clock_elapsed_ms(from: u32, to: u32) -> u32 {
    to.wrapping_sub(from) & 0x00FF_FFFF
}

impl MissionTracker {
    /// A tracker that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// The start write was accepted: samples from now on belong to this mission.
    pub fn start_accepted(&mut self) {
        self.before_start = self.last_code;
        self.started = true;
    }

    /// Whether the mission has been seen in a phase (1..=99) since the start.
    pub fn seen_running(&self) -> bool {
        self.seen_running
    }

    /// The last code sampled.
    pub fn last_code(&self) -> Option<u8> {
        self.last_code
    }

    /// Drone milliseconds since the first sample after the start (0 before it).
    pub fn mission_time_ms(&self, timestamp_ms: u32) -> u32 {
        self.first_after_start_ms
            .map_or(0, |t0| log_clock_elapsed_ms(t0, timestamp_ms))
    }

    /// One `mission.state` sample taken at `timestamp_ms` (drone clock). Returns the outcome once the mission
    /// has ended (and on every later sample).
    pub fn on_sample(&mut self, code: u8, timestamp_ms: u32) -> Option<Outcome> {
        self.last_code = Some(code);
        if !self.started || self.outcome.is_some() {
            return self.outcome;
        }
        let t0 = *self.first_after_start_ms.get_or_insert(timestamp_ms);
        if (1..100).contains(&code) {
            self.seen_running = true;
            return None;
        }
        if code < 100 {
            return None;
        }
        let fresh = self.seen_running
            || self.before_start.is_some_and(|before| before != code)
            || log_clock_elapsed_ms(t0, timestamp_ms) >= STALE_FINAL_GRACE_MS;
        if fresh {
            self.outcome = Some(if code == MissionState::Completed.code() {
                Outcome::Completed
            } else {
                Outcome::NotCompleted(code)
            });
        }
        self.outcome
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_match_the_interface() {
        // docs/radio.md: 0 idle, 1..99 phases, 100 completed, >= 200 ended without completing.
        let mut codes: Vec<u8> = STATES.iter().map(|(s, _)| s.code()).collect();
        codes.sort_unstable();
        codes.dedup();
        assert_eq!(codes.len(), STATES.len(), "duplicate codes");
        assert_eq!(state_name(0), "idle, ready");
        assert_eq!(state_name(100), "completed");
        assert_eq!(state_name(200), "aborted by the user, landed");
        for (s, _) in STATES {
            let c = s.code();
            assert!(c <= 100 || c >= 200, "{s:?} = {c}");
        }
        assert_eq!(state_name(99), "a phase this tool does not know");
        assert_eq!(state_name(250), "ended without completing");
    }

    #[test]
    fn a_fresh_drone_completes() {
        let mut t = MissionTracker::new();
        assert_eq!(t.on_sample(0, 1000), None);
        t.start_accepted();
        assert_eq!(t.on_sample(0, 1100), None);
        assert_eq!(t.on_sample(1, 1200), None);
        assert_eq!(t.on_sample(11, 5000), None);
        assert_eq!(t.on_sample(100, 60_000), Some(Outcome::Completed));
        assert_eq!(Outcome::Completed.exit_code(), 0);
        assert_eq!(t.mission_time_ms(60_000), 60_000 - 1100);
    }

    #[test]
    fn a_stale_final_code_is_not_the_new_mission_s() {
        let mut t = MissionTracker::new();
        t.on_sample(100, 10_000);
        t.start_accepted();
        // A sample taken before the start took effect still says 100.
        assert_eq!(t.on_sample(100, 10_100), None);
        assert_eq!(t.on_sample(1, 10_200), None);
        assert_eq!(t.on_sample(40, 20_000), None);
        assert_eq!(t.on_sample(200, 21_000), Some(Outcome::NotCompleted(200)));
        assert_eq!(Outcome::NotCompleted(200).exit_code(), 1);
    }

    #[test]
    fn a_different_final_code_counts_at_once() {
        let mut t = MissionTracker::new();
        t.on_sample(100, 10_000);
        t.start_accepted();
        assert_eq!(t.on_sample(205, 10_100), Some(Outcome::NotCompleted(205)));
    }

    #[test]
    fn the_stale_code_is_believed_after_the_grace() {
        let mut t = MissionTracker::new();
        t.on_sample(100, 10_000);
        t.start_accepted();
        assert_eq!(t.on_sample(100, 10_100), None);
        assert_eq!(t.on_sample(100, 10_100 + STALE_FINAL_GRACE_MS - 1), None);
        assert_eq!(
            t.on_sample(100, 10_100 + STALE_FINAL_GRACE_MS),
            Some(Outcome::Completed)
        );
    }

    #[test]
    fn nothing_ends_before_the_start() {
        let mut t = MissionTracker::new();
        assert_eq!(t.on_sample(100, 0), None);
        assert_eq!(t.on_sample(201, 100), None);
    }

    #[test]
    fn the_log_clock_wraps_at_24_bits() {
        assert_eq!(log_clock_elapsed_ms(0x00FF_FF00, 0x0000_0100), 0x200);
        assert_eq!(log_clock_elapsed_ms(5, 5), 0);
        let mut t = MissionTracker::new();
        t.start_accepted();
        t.on_sample(1, 0x00FF_FFF0);
        assert_eq!(t.mission_time_ms(0x10), 0x20);
    }
}
