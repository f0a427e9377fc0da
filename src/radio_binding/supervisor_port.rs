//! The supervisor port, CRTP port 9: state bits for the client, arm/disarm, crash recovery, emergency stop
//! and the emergency-stop watchdog.
//!
//! Job: answer the info and command channels with the stock byte layouts from a snapshot of cfnav's
//! supervisor ([`SupervisorStatus`], refreshed by the caller), and turn commands into [`SupervisorRequests`]
//! the caller acts on. Sans-IO: the caller passes the time ([`SupervisorPortService::set_now`]).
//!
//! Non-goals: it changes no flight state itself (the caller owns the supervisor and the flight core); no
//! deprecated platform-port arming (port 13 ch0) or localization-port emergency stop (port 6).
//!
//! # Wire format (`docs/hardware.md` §4; firmware `crtp_supervisor.h` / `crtp_supervisor.c`;
//! cflib 0.1.34 `cflib/crazyflie/supervisor.py`, read from the installed package)
//! * ch0 info: `[0x0C]` → `[0x8C, bitfield u16 LE]`; `[n]` for n = 0x01..=0x0B → `[0x80 | n, bit n−1]`
//!   (stock `handleSupervisorInfo`); anything else, or an empty packet → no reply. cflib 0.1.34 only sends
//!   `[0x0C]` and reads `data[1:]` as a little-endian integer.
//! * ch1 commands (cflib 0.1.34 packs each as bytes of a tuple):
//!   - `[0x01, doArm]` arm/disarm → `[0x81, success, isArmed]`;
//!   - `[0x02]` recover → `[0x82, success, recovered]` (stock: `recovered = !isCrashed`);
//!   - `[0x03]` emergency stop → no reply; `[0x04]` emergency-stop watchdog keepalive → no reply;
//!   - an arm command without its `doArm` byte is refused (stock reads past the payload);
//!   - unknown commands, empty packets and other channels → no reply.
//! * Replies echo the command with bit 7 set (`CMD_RESPONSE` 0x80).
//!
//! # Bitfield mapping (stock meaning → cfnav source)
//! | bit | stock | cfnav |
//! |---|---|---|
//! | 0 | can be armed (PreFlChecksPassed) | supervisor Idle and only the arming is missing (`Reason::NotArmed`) |
//! | 1 | is armed | auto-arming, or the latest granted arm request was "arm" |
//! | 2 | is auto armed | [`SupervisorPortConfig::auto_arm`] (CF2.1 stock default) |
//! | 3 | can fly | `motors_allowed` (Armed or Flying) and no emergency stop |
//! | 4 | is flying | `flying` |
//! | 5 | is tumbled | the supervisor reports a tumble (flag `TUMBLED` or reason `Tumbled`) |
//! | 6 | is locked | state `Locked` (setpoint timeout) or an emergency stop latched here |
//! | 7 | is crashed | state `Crashed` |
//! | 8 | HL control active | a mission runs (the mission is cfnav's high-level commander) |
//! | 9 | HL trajectory finished | the mission reached a final state |
//! | 10 | HL control disabled | no mission runs |
//! | 11 | deck fault | the Flow or Multi-ranger deck is missing or failed |
//!
//! # Emergency stop
//! `[0x03]`, or no keepalive for [`ESTOP_WATCHDOG_US`] (1000 ms, stock) once a first `[0x04]` arrived, latch
//! the emergency stop: [`SupervisorRequests::emergency_stop`] is raised once for the caller, bit 6 stays set
//! and arming is refused until [`SupervisorPortService::clear_emergency_stop`] (stock: Locked, reboot
//! required). The watchdog is checked by [`SupervisorPortService::poll`]; it cannot be switched off again
//! (stock has no command for it either).
//!
//! # Arming and recovery answers
//! With auto-arming (the flight core's default) arm requests cannot change anything: "arm" succeeds (already
//! armed), "disarm" fails with isArmed = 1. Without auto-arming the service keeps the arm level: "arm" is
//! granted when already armed or when bit 0 (can be armed) is set, "disarm" always; the caller reads the level
//! with [`SupervisorPortService::arm_level`]. Recovery: not crashed → success; crashed and tumbled → refused;
//! crashed, upright and [`SupervisorPortConfig::can_recover`] → success and [`SupervisorRequests::recover`]
//! raised (the caller must reset the supervisor); otherwise refused.
//!
//! Memory: 56 bytes (measured on the 64-bit host).

use crate::flight::supervisor::{Reason, SupervisorFlags, SupervisorOutput, SupervisorState};
use crate::radio::crtp::{CrtpPacket, Service};
use crate::types::Micros;

/// Supervisor port.
pub const PORT_SUPERVISOR: u8 = 9;
/// Info channel.
pub const CH_INFO: u8 = 0;
/// Command channel.
pub const CH_COMMAND: u8 = 1;
/// Reply flag ORed into the command byte (`CMD_RESPONSE`).
pub const CMD_RESPONSE: u8 = 0x80;
/// Info: the whole bitfield.
pub const CMD_GET_STATE_BITFIELD: u8 = 0x0C;
/// Command: arm / disarm.
pub const CMD_ARM_SYSTEM: u8 = 0x01;
/// Command: crash recovery.
pub const CMD_RECOVER_SYSTEM: u8 = 0x02;
/// Command: emergency stop.
pub const CMD_EMERGENCY_STOP: u8 = 0x03;
/// Command: emergency-stop watchdog keepalive.
pub const CMD_EMERGENCY_STOP_WATCHDOG: u8 = 0x04;
/// Emergency-stop watchdog timeout once started, µs (stock `supervisor.c` `DEFAULT_EMERGENCY_STOP_WATCHDOG_TIMEOUT`, 1000 ms).
pub const ESTOP_WATCHDOG_US: u64 = 1_000_000;

/// Bit numbers of the bitfield (stock order, cflib `BIT_*`).
pub mod bits {
    /// Can be armed.
    pub const CAN_BE_ARMED: u16 = 1 << 0;
    /// Is armed.
    pub const IS_ARMED: u16 = 1 << 1;
    /// Is auto armed.
    pub const IS_AUTO_ARMED: u16 = 1 << 2;
    /// Can fly.
    pub const CAN_FLY: u16 = 1 << 3;
    /// Is flying.
    pub const IS_FLYING: u16 = 1 << 4;
    /// Is tumbled.
    pub const IS_TUMBLED: u16 = 1 << 5;
    /// Is locked.
    pub const IS_LOCKED: u16 = 1 << 6;
    /// Is crashed.
    pub const IS_CRASHED: u16 = 1 << 7;
    /// High-level control active.
    pub const HL_CONTROL_ACTIVE: u16 = 1 << 8;
    /// High-level trajectory finished.
    pub const HL_TRAJ_FINISHED: u16 = 1 << 9;
    /// High-level control disabled.
    pub const HL_CONTROL_DISABLED: u16 = 1 << 10;
    /// Deck fault.
    pub const DECK_FAULT: u16 = 1 << 11;
}

/// Fixed configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SupervisorPortConfig {
    /// The flight core arms automatically (stock CF2.1 default; cfnav `SupervisorConfig::auto_arm`).
    pub auto_arm: bool,
    /// The caller can reset a crashed supervisor on [`SupervisorRequests::recover`].
    pub can_recover: bool,
}

impl Default for SupervisorPortConfig {
    fn default() -> Self {
        Self {
            auto_arm: true,
            can_recover: false,
        }
    }
}

/// What the caller knows about the flight stack, refreshed before packets are handled.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SupervisorStatus {
    /// The supervisor's latest verdict.
    pub output: SupervisorOutput,
    /// A mission runs.
    pub mission_running: bool,
    /// The mission reached a final state.
    pub mission_finished: bool,
    /// Both decks are present and working.
    pub decks_ok: bool,
}

/// Requests for the caller, collected since the previous [`SupervisorPortService::take_requests`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SupervisorRequests {
    /// A granted arm (`Some(true)`) or disarm (`Some(false)`) request (only without auto-arming).
    pub arm: Option<bool>,
    /// A granted crash recovery: reset the supervisor.
    pub recover: bool,
    /// Emergency stop: stop the motors now and keep them stopped.
    pub emergency_stop: bool,
}

/// Counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SupervisorPortStats {
    /// Packets answered or acted on.
    pub handled: u32,
    /// Packets refused (empty, truncated, unknown command or channel).
    pub refused: u32,
}

/// The supervisor port service (see the module documentation).
#[derive(Debug, Clone, Copy)]
pub struct SupervisorPortService {
    config: SupervisorPortConfig,
    status: SupervisorStatus,
    now_us: Micros,
    arm_level: bool,
    estop_latched: bool,
    watchdog_last_us: Option<Micros>,
    requests: SupervisorRequests,
    stats: SupervisorPortStats,
}

impl SupervisorPortService {
    /// A service at boot: no status yet (a default verdict, Idle; decks assumed present), not armed, no
    /// emergency stop, watchdog off.
    pub fn new(config: SupervisorPortConfig) -> Self {
        Self {
            config,
            status: SupervisorStatus {
                decks_ok: true,
                ..SupervisorStatus::default()
            },
            now_us: 0,
            arm_level: false,
            estop_latched: false,
            watchdog_last_us: None,
            requests: SupervisorRequests::default(),
            stats: SupervisorPortStats::default(),
        }
    }

    /// Refreshes the snapshot the answers are built from.
    pub fn set_status(&mut self, status: SupervisorStatus) {
        self.status = status;
    }

    /// Sets the time of the packets handled next, µs since boot.
    pub fn set_now(&mut self, now_us: Micros) {
        self.now_us = now_us;
    }

    /// Checks the emergency-stop watchdog at `now_us`; returns true if it fired now (the emergency stop is
    /// then latched and requested).
    pub fn poll(&mut self, now_us: Micros) -> bool {
        self.now_us = self.now_us.max(now_us);
        match self.watchdog_last_us {
            Some(t) if !self.estop_latched && now_us.saturating_sub(t) > ESTOP_WATCHDOG_US => {
                self.emergency_stop();
                true
            }
            _ => false,
        }
    }

    /// The state bitfield (see the mapping table in the module documentation).
    pub fn bitfield(&self) -> u16 {
        let out = &self.status.output;
        let mut b = 0u16;
        let mut set = |bit: u16, on: bool| {
            if on {
                b |= bit;
            }
        };
        let armed = self.is_armed();
        set(
            bits::CAN_BE_ARMED,
            !self.estop_latched && out.state == SupervisorState::Idle && out.reason == Reason::NotArmed,
        );
        set(bits::IS_ARMED, armed);
        set(bits::IS_AUTO_ARMED, self.config.auto_arm);
        set(bits::CAN_FLY, out.motors_allowed && !self.estop_latched);
        set(bits::IS_FLYING, out.flying);
        set(
            bits::IS_TUMBLED,
            out.flags.contains(SupervisorFlags::TUMBLED) || out.reason == Reason::Tumbled,
        );
        set(
            bits::IS_LOCKED,
            out.state == SupervisorState::Locked || self.estop_latched,
        );
        set(bits::IS_CRASHED, out.state == SupervisorState::Crashed);
        set(bits::HL_CONTROL_ACTIVE, self.status.mission_running);
        set(bits::HL_TRAJ_FINISHED, self.status.mission_finished);
        set(bits::HL_CONTROL_DISABLED, !self.status.mission_running);
        set(bits::DECK_FAULT, !self.status.decks_ok);
        b
    }

    /// Armed as the client sees it: auto-arming, or the arm level.
    pub fn is_armed(&self) -> bool {
        !self.estop_latched && (self.config.auto_arm || self.arm_level)
    }

    /// The arm level requested by the client (meaningful without auto-arming).
    pub fn arm_level(&self) -> bool {
        self.arm_level
    }

    /// An emergency stop is latched.
    pub fn emergency_stopped(&self) -> bool {
        self.estop_latched
    }

    /// The emergency-stop watchdog has been started by a keepalive.
    pub fn watchdog_started(&self) -> bool {
        self.watchdog_last_us.is_some()
    }

    /// Clears a latched emergency stop and stops the watchdog (a reboot, in stock terms).
    pub fn clear_emergency_stop(&mut self) {
        self.estop_latched = false;
        self.watchdog_last_us = None;
    }

    /// Requests collected since the previous call.
    pub fn take_requests(&mut self) -> SupervisorRequests {
        core::mem::take(&mut self.requests)
    }

    /// The counters.
    pub fn stats(&self) -> SupervisorPortStats {
        self.stats
    }

    fn emergency_stop(&mut self) {
        self.estop_latched = true;
        self.arm_level = false;
        self.requests.emergency_stop = true;
    }

    fn reply(channel: u8, cmd: u8, data: &[u8]) -> Option<CrtpPacket> {
        let mut buf = [0u8; 3];
        let n = data.len().min(2);
        buf[0] = CMD_RESPONSE | cmd;
        buf[1..1 + n].copy_from_slice(&data[..n]);
        CrtpPacket::new(PORT_SUPERVISOR, channel, &buf[..1 + n]).ok()
    }

    fn info(&self, cmd: u8) -> Option<CrtpPacket> {
        let field = self.bitfield();
        match cmd {
            CMD_GET_STATE_BITFIELD => Self::reply(CH_INFO, cmd, &field.to_le_bytes()),
            // Single bits: command n answers bit n − 1 (stock `handleSupervisorInfo`).
            1..=0x0B => Self::reply(CH_INFO, cmd, &[((field >> (cmd - 1)) & 1) as u8]),
            _ => None,
        }
    }

    fn command(&mut self, cmd: u8, args: &[u8]) -> Result<Option<CrtpPacket>, ()> {
        match cmd {
            CMD_ARM_SYSTEM => {
                let do_arm = *args.first().ok_or(())? != 0;
                let success = if self.config.auto_arm {
                    do_arm && !self.estop_latched
                } else if do_arm == self.arm_level {
                    true
                } else if do_arm {
                    let can = self.bitfield() & bits::CAN_BE_ARMED != 0;
                    if can {
                        self.arm_level = true;
                        self.requests.arm = Some(true);
                    }
                    can
                } else {
                    self.arm_level = false;
                    self.requests.arm = Some(false);
                    true
                };
                Ok(Self::reply(CH_COMMAND, cmd, &[success as u8, self.is_armed() as u8]))
            }
            CMD_RECOVER_SYSTEM => {
                let out = &self.status.output;
                let crashed = out.state == SupervisorState::Crashed;
                let tumbled = self.bitfield() & bits::IS_TUMBLED != 0;
                let success = if !crashed {
                    true
                } else if !tumbled && self.config.can_recover {
                    self.requests.recover = true;
                    true
                } else {
                    false
                };
                let recovered = !crashed || success;
                Ok(Self::reply(CH_COMMAND, cmd, &[success as u8, recovered as u8]))
            }
            CMD_EMERGENCY_STOP => {
                self.emergency_stop();
                Ok(None)
            }
            CMD_EMERGENCY_STOP_WATCHDOG => {
                if !self.estop_latched {
                    self.watchdog_last_us = Some(self.now_us);
                }
                Ok(None)
            }
            _ => Err(()),
        }
    }
}

impl Service for SupervisorPortService {
    fn port(&self) -> u8 {
        PORT_SUPERVISOR
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        let result = match (packet.port, packet.channel, packet.data.split_first()) {
            (PORT_SUPERVISOR, CH_INFO, Some((&cmd, _))) => self.info(cmd).ok_or(()).map(Some),
            (PORT_SUPERVISOR, CH_COMMAND, Some((&cmd, args))) => self.command(cmd, args),
            _ => Err(()),
        };
        match result {
            Ok(reply) => {
                self.stats.handled = self.stats.handled.saturating_add(1);
                reply
            }
            Err(()) => {
                self.stats.refused = self.stats.refused.saturating_add(1);
                None
            }
        }
    }
}
