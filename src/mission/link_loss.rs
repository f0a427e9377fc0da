//! The link-loss policy: what an autonomous mission does when the radio goes silent.
//!
//! Job: a sans-IO watch. The radio side reports the time of every packet it received
//! ([`LinkWatch::on_packet`]); once per mission tick [`LinkWatch::check`] says whether a running mission has
//! gone [`LinkLossConfig::timeout_s`] without ANY packet, and if so returns the policy to apply, exactly once
//! per mission. The mission applies it ([`super::Mission::on_link_lost`]):
//! - [`LinkLossPolicy::Continue`] (0, the default): nothing changes; cfnav flies its whole mission on board
//!   and needs no link.
//! - [`LinkLossPolicy::Land`] (1): land where it is, motors off, ends with
//!   [`super::MissionState::LinkLost`] (207).
//! - [`LinkLossPolicy::ReturnHome`] (2): on the outbound leg, turn back at once and fly the return leg (plan,
//!   search the home pad, land on it), ending with [`super::MissionState::LinkLostHome`] (208); on the
//!   return leg, or paused on the goal pad, the mission is already going home and goes on as normal. The
//!   hover test's home is its take-off point: it lands there (state 51) and ends with 208; the
//!   exploration ends and flies home as when its coverage is reached.
//!
//! Decisions (README "Safety behaviour"):
//! - The decision is latched for the mission: a link that comes back does not undo a landing or a return
//!   once decided (a flapping link must not make the drone hesitate in the air); the user can still abort
//!   (`mission.start = 0`: land where it is).
//! - Only a running mission is watched. A user flying with setpoints has the supervisor's setpoint watchdog
//!   (level out after 0.5 s, motors off after 2 s), and a mission refuses setpoints, so the two never meet.
//!   The high-level commander (port 8) is treated as stock treats it: its trajectory is flown to the end and
//!   held there, with no link-loss rule (stock's `crtp_commander_high_level.c` has none either).
//! - The timer runs from the later of the mission start and the last packet, so a mission started without
//!   any radio (the simulator's built-in trigger) is not cut short at once.
//!
//! Non-goals: the radio transport, the supervisor's timeouts, the flight itself.
//! Units: seconds in the configuration, µs ([`Micros`]) on the clock. Memory: a few dozen bytes.

use crate::types::Micros;

/// Shortest `mission.linkTimeout`, s: below this an ordinary radio hiccup (cflib reconnects, 2.4 GHz
/// interference, a USB stall of the Crazyradio) would end missions.
pub const MIN_LINK_TIMEOUT_S: f32 = 0.5;
/// Longest `mission.linkTimeout`, s.
pub const MAX_LINK_TIMEOUT_S: f32 = 60.0;
/// Default `mission.linkTimeout`, s. Stock calls the radio link connected while a packet arrived within the
/// last 1000 ms (`radiolink.c`, `RADIO_ACTIVITY_TIMEOUT_MS`), and cflib keeps the link busy with null packets
/// whenever it has nothing to send, so a silence of 2 s is twice what stock already calls "disconnected",
/// and the same as the supervisor's setpoint shutdown time a pilot is used to.
pub const DEFAULT_LINK_TIMEOUT_S: f32 = 2.0;

/// `mission.linkLoss`: what a running mission does when the link is lost.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum LinkLossPolicy {
    /// 0: go on with the mission on board (the default).
    #[default]
    Continue = 0,
    /// 1: land where it is.
    Land = 1,
    /// 2: return home and land on the home pad.
    ReturnHome = 2,
}

impl LinkLossPolicy {
    /// The policy for a `mission.linkLoss` value; `None` outside 0..=2.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::Continue),
            1 => Some(Self::Land),
            2 => Some(Self::ReturnHome),
            _ => None,
        }
    }

    /// The `mission.linkLoss` value.
    pub const fn code(self) -> u8 {
        self as u8
    }
}

/// The two link-loss parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkLossConfig {
    /// `mission.linkLoss`.
    pub policy: LinkLossPolicy,
    /// `mission.linkTimeout`, s ([`MIN_LINK_TIMEOUT_S`]..=[`MAX_LINK_TIMEOUT_S`]).
    pub timeout_s: f32,
}

impl LinkLossConfig {
    /// Continue on board, 2 s.
    pub const DEFAULT: Self = Self {
        policy: LinkLossPolicy::Continue,
        timeout_s: DEFAULT_LINK_TIMEOUT_S,
    };

    /// The timeout in µs, clamped to the accepted range (NaN counts as the default).
    pub fn timeout_us(&self) -> Micros {
        let s = if self.timeout_s.is_finite() {
            self.timeout_s.clamp(MIN_LINK_TIMEOUT_S, MAX_LINK_TIMEOUT_S)
        } else {
            DEFAULT_LINK_TIMEOUT_S
        };
        (s * 1e6) as Micros
    }
}

impl Default for LinkLossConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The watch: see the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkWatch {
    config: LinkLossConfig,
    last_packet: Option<Micros>,
    /// When the running mission started (the timer's earliest origin); `None` while no mission runs.
    mission_since: Option<Micros>,
    /// When the timeout fired during the current (or last) mission.
    fired_at: Option<Micros>,
}

impl Default for LinkWatch {
    fn default() -> Self {
        Self::new()
    }
}

impl LinkWatch {
    /// No packet yet, the default configuration.
    pub const fn new() -> Self {
        Self {
            config: LinkLossConfig::DEFAULT,
            last_packet: None,
            mission_since: None,
            fired_at: None,
        }
    }

    /// The parameters in effect (they may change at any time, also during a mission).
    pub fn set_config(&mut self, config: LinkLossConfig) {
        self.config = config;
    }

    /// The parameters in effect.
    pub fn config(&self) -> LinkLossConfig {
        self.config
    }

    /// A radio packet (any port, null packets too) arrived at `now`. Times never go backwards here: an older
    /// time than the latest is ignored.
    pub fn on_packet(&mut self, now: Micros) {
        if self.last_packet.is_none_or(|t| now > t) {
            self.last_packet = Some(now);
        }
    }

    /// When the latest packet arrived.
    pub fn last_packet(&self) -> Option<Micros> {
        self.last_packet
    }

    /// When the timeout fired in the current (or last) mission, µs.
    pub fn fired_at(&self) -> Option<Micros> {
        self.fired_at
    }

    /// Once per mission tick: `mission_running` says whether a mission runs now. Returns the policy to apply
    /// when the link has just been found lost (once per mission; never while no mission runs). A new mission
    /// (running after not running) restarts the watch.
    pub fn check(&mut self, now: Micros, mission_running: bool) -> Option<LinkLossPolicy> {
        if !mission_running {
            self.mission_since = None;
            return None;
        }
        let since = *self.mission_since.get_or_insert_with(|| {
            self.fired_at = None;
            now
        });
        if self.fired_at.is_some() {
            return None;
        }
        let origin = self.last_packet.map_or(since, |t| t.max(since));
        if now.saturating_sub(origin) < self.config.timeout_us() {
            return None;
        }
        self.fired_at = Some(now);
        Some(self.config.policy)
    }
}
