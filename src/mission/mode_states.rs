//! Which `mission.state` codes each mission mode may reach: the hover test never searches a pad, the
//! exploration never flies to the goal, the round trip never hovers in place or explores.
//!
//! Job: one table, [`MODE_STATES`], that [`super::Mission::tick`] checks its state against in debug builds
//! (and so every host test, the simulator's tests included) and that the documentation of the modes is
//! written from. A state missing from a mode's row is a transition that must not exist.
//!
//! Every mode shares idle, preflight, the emergency landing (40) and the final codes its failures can end
//! with; the rows list them explicitly, so a new state has to be placed in each mode by hand.
//!
//! Memory: the table is `'static` (about 60 bytes). Cost: a linear scan of one row (≤ 24 entries).

use super::{MissionMode, MissionState};

use MissionState as S;

/// The states of the round trip (`mission.mode = 0`).
const ROUND_TRIP: &[MissionState] = &[
    S::Idle,
    S::Preflight,
    S::TakeOffOutbound,
    S::NavigateToGoal,
    S::SearchGoalPad,
    S::ApproachGoalPad,
    S::LandOnGoalPad,
    S::OnGoalPad,
    S::TakeOffReturn,
    S::NavigateHome,
    S::SearchHomePad,
    S::ApproachHomePad,
    S::LandOnHomePad,
    S::NoPathHover,
    S::EmergencyLanding,
    S::Completed,
    S::Aborted,
    S::NoPath,
    S::PadNotFound,
    S::BatteryLow,
    S::EstimatorFault,
    S::Crashed,
    S::PlannerFault,
    S::LinkLost,
    S::LinkLostHome,
    S::RangerLost,
    S::LeftArena,
];

/// The states of the hover test (`mission.mode = 1`): climb (10), hold (50), land at the take-off point
/// (51). No planning (no 30, 201, 206) and no pad (no search, no 202); link loss with `mission.linkLoss = 2`
/// lands at the take-off point, its home, and ends with 208.
const HOVER_TEST: &[MissionState] = &[
    S::Idle,
    S::Preflight,
    S::TakeOffOutbound,
    S::HoverHold,
    S::HoverLand,
    S::EmergencyLanding,
    S::Completed,
    S::Aborted,
    S::BatteryLow,
    S::EstimatorFault,
    S::Crashed,
    S::LinkLost,
    S::LinkLostHome,
    S::RangerLost,
    S::LeftArena,
];

/// The states of the exploration (`mission.mode = 2`): climb (10), explore (60, 61), then the round trip's
/// way home (20–24, 30). Never the goal leg (11–15).
const EXPLORE: &[MissionState] = &[
    S::Idle,
    S::Preflight,
    S::TakeOffOutbound,
    S::Explore,
    S::ExploreLook,
    S::TakeOffReturn,
    S::NavigateHome,
    S::SearchHomePad,
    S::ApproachHomePad,
    S::LandOnHomePad,
    S::NoPathHover,
    S::EmergencyLanding,
    S::Completed,
    S::Aborted,
    S::NoPath,
    S::PadNotFound,
    S::BatteryLow,
    S::EstimatorFault,
    S::Crashed,
    S::PlannerFault,
    S::LinkLost,
    S::LinkLostHome,
    S::RangerLost,
    S::LeftArena,
];

/// Each mode with the states it may reach, in `mission.mode` order.
pub const MODE_STATES: [(MissionMode, &[MissionState]); 3] = [
    (MissionMode::RoundTrip, ROUND_TRIP),
    (MissionMode::HoverTest, HOVER_TEST),
    (MissionMode::Explore, EXPLORE),
];

/// The states `mode` may reach.
pub fn states_of(mode: MissionMode) -> &'static [MissionState] {
    MODE_STATES
        .iter()
        .find(|(m, _)| *m == mode)
        .map_or(&[], |(_, states)| *states)
}

/// Whether a mission flown in `mode` may be in `state`.
pub fn may_reach(mode: MissionMode, state: MissionState) -> bool {
    states_of(mode).contains(&state)
}
