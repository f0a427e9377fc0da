//! The Multi-ranger watch: what a running mission does when the horizontal rangers stop reporting in flight.
//!
//! Job: a sans-IO watch. The deck side reports each sweep it handed over ([`RangerWatch::on_sweep`]); once per
//! mission tick [`RangerWatch::check`] says whether a running mission has gone [`RANGER_TIMEOUT_US`]
//! without a sweep, exactly once per mission. The mission then lands where it is and ends with
//! [`super::MissionState::RangerLost`] (209): without its beams it neither maps nor avoids, so flying on
//! would take it through whatever it has not seen yet (found in the emulator: with the deck unplugged mid-
//! flight the mission flew on, `cfnav-pil --fault multiranger-lost`).
//!
//! Decisions:
//! - A sweep counts whatever its beams say (a beam with no target, a dropout and an outlier all count: they
//!   are the deck answering); only sweeps that stop coming fire the watch. The deck task restarts a ranger
//!   that is two periods overdue (`drivers::multiranger`), so a single stuck sensor recovers long before this.
//! - The timer runs from the later of the mission start and the last sweep, so a mission never fires at its
//!   start. The decision is latched for the mission, as the link-loss one is.
//! - Only a running mission is watched: a user flying setpoints flies without the map.
//!
//! Non-goals: detecting one beam that always reads nothing (indistinguishable from open space), the deck's
//! bus recovery. Units: µs ([`Micros`]). Memory: 24 bytes.

use crate::types::Micros;

/// A running mission that hears no sweep for this long lands, µs: ten sweep periods (the beams come every
/// 100 ms, `RangingConfig::MULTI_RANGER`), and more than the mission's longest wait for a sweep it dropped
/// while busy (it drains its inputs every 20 ms; a sweep is dropped only when its queue is full).
pub const RANGER_TIMEOUT_US: Micros = 1_000_000;

/// The watch (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RangerWatch {
    /// A sweep came since the last [`Self::check`].
    swept: bool,
    /// When the timer was last restarted (a sweep, or the mission's first check), µs.
    last_us: Option<Micros>,
    /// The watch fired for this mission.
    fired: bool,
}

impl RangerWatch {
    /// A watch with no mission yet.
    pub const fn new() -> Self {
        Self {
            swept: false,
            last_us: None,
            fired: false,
        }
    }

    /// A sweep was handed over (any content).
    pub fn on_sweep(&mut self) {
        self.swept = true;
    }

    /// Once per mission tick: `true` exactly once when a running mission has had no sweep for
    /// [`RANGER_TIMEOUT_US`]. A stopped mission resets the watch for the next one.
    pub fn check(&mut self, now: Micros, running: bool) -> bool {
        if !running {
            *self = Self::new();
            return false;
        }
        if core::mem::take(&mut self.swept) || self.last_us.is_none() {
            self.last_us = Some(now);
        }
        let silent = self.last_us.is_some_and(|t| now.saturating_sub(t) >= RANGER_TIMEOUT_US);
        if silent && !self.fired {
            self.fired = true;
            return true;
        }
        false
    }
}
