//! The commander ports: RPYT setpoints (port 3) and generic setpoints (port 7) decoded into typed commands.
//!
//! Job: check and decode every setpoint packet cflib sends, keep the latest accepted command with its
//! arrival time and the RPYT thrust lock (sans-IO: the caller passes the time), and convert a command into
//! cfnav's [`Setpoint`] where that vocabulary can express it ([`SetpointFollower`]).
//!
//! Non-goals: no controller, no watchdog (the supervisor ages the setpoint it is fed: the caller hands a
//! converted setpoint to `FlightCore::commander_setpoint` only when a packet arrived, with its arrival time,
//! so the stock 500 ms / 2000 ms rules keep working), no high-level commander, no CPPM or alt-hold packets.
//!
//! # Wire formats (all little-endian, packed)
//! * Port 3 ch0 RPYT, 14 bytes: roll f32 deg, pitch f32 deg, yaw f32 deg/s, thrust u16
//!   (`docs/hardware.md` §4; cflib `commander.py` `send_setpoint` packs `<fffH` with **−pitch**).
//! * Port 7 ch0 generic, `[type u8, payload]` (`docs/hardware.md` §4; firmware `crtp_commander_generic.c` `enum packet_type`
//!   and the packed decoder structs; cflib `commander.py`):
//!
//!   | type | name | payload | bytes |
//!   |---|---|---|---|
//!   | 0 | stop | (ignored) | any |
//!   | 1 / 8 | velocity world | vx, vy, vz m/s, yaw rate deg/s (f32 ×4); 1 = legacy, yaw rate negated | 16 |
//!   | 2 / 9 | z-distance | roll, pitch deg, yaw rate deg/s, z m (f32 ×4); 2 = legacy, yaw rate negated | 16 |
//!   | 5 / 10 | hover | vx, vy m/s **body frame**, yaw rate deg/s, z m (f32 ×4); 5 = legacy, negated | 16 |
//!   | 6 | full state | 9 × i16 mm, mm/s, mm/s², compressed quaternion u32, 3 × i16 mrad/s | 28 |
//!   | 7 | position | x, y, z m, yaw deg (f32 ×4) | 16 |
//!   | 11 | manual | roll, pitch deg (or deg/s), yaw rate deg/s (f32 ×3), thrust u16, rate flag u8 | 15 |
//! * Port 7 ch1 meta, `[0, remain_valid_ms u32]` = "notify setpoint stop" (cflib packs `<BI`).
//!
//! # Conventions of the decoded [`Command`]
//! Values are converted to cfnav's frames (see [`crate::types`]): radians, right-hand rule, positive pitch
//! tilts the nose down, positive yaw rate turns counter-clockwise seen from above.
//! * The stock firmware's attitude setpoint uses the legacy pitch sign (positive = nose up), which is why
//!   cflib negates the user's pitch in `send_setpoint` and `send_setpoint_manual`: the decoded pitch is the
//!   **negated wire pitch** for RPYT, manual and z-distance packets (so for RPYT/manual it equals the pitch
//!   the cflib user passed).
//! * Yaw rate: the firmware negates the RPYT yaw rate ("legacy rate input is inverted", `docs/hardware.md` §4) and the yaw rate
//!   of generic types 1, 2 and 5 (`legacyVelocityDecoder`, `legacyZDistanceDecoder`, `legacyHoverDecoder`);
//!   types 8, 9, 10 and 11 take it as sent. The stock yaw rate is counter-clockwise positive, like cfnav's.
//! * RPYT thrust (firmware `crtp_commander_rpyt.c`): below `MIN_THRUST` 1000 → 0, above `MAX_THRUST` 60000 →
//!   60000; **thrust lock**: locked at boot, a packet with raw thrust 0 unlocks, while locked the thrust is 0.
//!   Stock re-locks when the commander's priority fell to "disabled", which the stock commander does once the
//!   setpoint is older than `COMMANDER_WDT_TIMEOUT_STABILIZE` = 500 ms (`commander.c` `commanderGetSetpoint`,
//!   `xQueueOverwrite(priorityQueue, &priorityDisable)`); here: an RPYT packet arriving more than
//!   [`THRUST_RELOCK_US`] after the previous accepted command re-locks before it is applied.
//!
//! # Refusals (the packet is dropped, the latest command and the lock are left as they were)
//! Empty payloads, a wrong length for the type (stock asserts `datalen == sizeof(struct)` and would halt;
//! here the packet is refused), unknown types, non-finite floats, unknown channels and meta commands.
//! Types 3 (CPPM emulation) and 4 (alt-hold) are refused as unsupported: cflib never sends them.
//! **Full state (6) is refused** after its length check: its orientation is a "smallest three" compressed
//! quaternion and its velocity/acceleration/body-rate fields are feed-forward terms; cfnav's [`Setpoint`] has
//! no place for any of them, and flying only its position part would silently ignore what the sender asked.
//! **Stop (0) accepts any trailing bytes**, as the stock `stopDecoder` does: refusing a stop is the unsafe way.
//!
//! # Mapping to [`Setpoint`] ([`SetpointFollower::to_setpoint`])
//! cfnav's `Setpoint` has Stop, Position, Velocity (arena-frame vx, vy at a height, absolute heading),
//! Descend and Attitude (roll, pitch, yaw rate, thrust). RPYT and manual commands map to Stop when their
//! thrust is 0 and otherwise to Attitude, as stock flies them (the held height and heading are forgotten:
//! the next rate command starts from the estimate); manual packets in rate mode (roll/pitch rates) are not
//! flyable (`None`). z-distance maps to a Velocity of zero only when roll and pitch are both 0. Rates (yaw rate, vz) are integrated per packet into the held heading/height: between two
//! packets `dt` is the time between their arrivals, capped at [`MAX_INTEGRATION_DT_US`]. Heights from
//! z-distance and hover packets ("distance to the surface" in stock) are taken as height above the arena
//! floor, the estimator's z. Velocity commands cannot land: the flight core raises Velocity heights to
//! ≥ 0.2 m while flying; land with a Stop near the floor or with a mission.
//!
//! Memory: [`CommanderService`] is 112 bytes, [`SetpointFollower`] 32 bytes (measured on the 64-bit host).

use core::cell::Cell;

use super::crtp::{CrtpPacket, Service};
use crate::math::wrap_angle;
use crate::types::{Micros, Setpoint, StateEstimate};

/// RPYT commander port.
pub const PORT_RPYT: u8 = 3;
/// Generic commander port.
pub const PORT_GENERIC: u8 = 7;
/// Generic port channel carrying setpoints.
pub const CH_SETPOINT: u8 = 0;
/// Generic port channel carrying meta commands.
pub const CH_META: u8 = 1;

/// Generic setpoint types (`crtp_commander_generic.c` `enum packet_type`).
pub const TYPE_STOP: u8 = 0;
/// Legacy velocity-world setpoint (yaw rate negated by the firmware).
pub const TYPE_VELOCITY_WORLD_LEGACY: u8 = 1;
/// Legacy z-distance setpoint (yaw rate negated by the firmware).
pub const TYPE_ZDISTANCE_LEGACY: u8 = 2;
/// CPPM emulation (refused).
pub const TYPE_CPPM_EMU: u8 = 3;
/// Alt-hold (refused).
pub const TYPE_ALT_HOLD: u8 = 4;
/// Legacy hover setpoint (yaw rate negated by the firmware).
pub const TYPE_HOVER_LEGACY: u8 = 5;
/// Full-state setpoint (refused, see the module documentation).
pub const TYPE_FULL_STATE: u8 = 6;
/// Position setpoint.
pub const TYPE_POSITION: u8 = 7;
/// Velocity-world setpoint.
pub const TYPE_VELOCITY_WORLD: u8 = 8;
/// Z-distance setpoint.
pub const TYPE_ZDISTANCE: u8 = 9;
/// Hover setpoint.
pub const TYPE_HOVER: u8 = 10;
/// Manual (attitude + thrust) setpoint.
pub const TYPE_MANUAL: u8 = 11;
/// Meta command "notify setpoint stop" (port 7 channel 1).
pub const META_NOTIFY_SETPOINT_STOP: u8 = 0;

/// RPYT payload length: `<fffH`.
pub const RPYT_LEN: usize = 14;
/// Payload length (after the type byte) of the four-float generic setpoints (packed `struct { float ×4 }`).
pub const FOUR_FLOAT_LEN: usize = 16;
/// Manual setpoint payload length: `<fffHB` (`struct manualPacket_s`, packed).
pub const MANUAL_LEN: usize = 15;
/// Full-state payload length: 9 × i16 + u32 + 3 × i16 (`struct fullStatePacket_s`, packed).
pub const FULL_STATE_LEN: usize = 28;
/// Meta "notify setpoint stop" payload length after the meta type byte: u32.
pub const META_NOTIFY_LEN: usize = 4;

/// RPYT thrust below this is 0 (`MIN_THRUST`, `crtp_commander_rpyt.c`).
pub const RPYT_MIN_THRUST: u16 = 1000;
/// RPYT thrust cap (`MAX_THRUST`, same file).
pub const RPYT_MAX_THRUST: u16 = 60000;
/// An RPYT packet arriving this long after the previous accepted command re-locks the thrust (stock: the
/// commander priority falls to "disabled" after `COMMANDER_WDT_TIMEOUT_STABILIZE`, 500 ms).
pub const THRUST_RELOCK_US: u64 = 500_000;
/// Longest gap between two packets over which rates are integrated into the held height/heading, µs: stock's
/// `COMMANDER_WDT_TIMEOUT_STABILIZE` (a setpoint older than that is stale anyway). cflib's `MotionCommander`
/// sends its hover setpoints every 200 ms (`_SetPointThread.UPDATE_PERIOD = 0.2`): a 100 ms cap integrated
/// half of each interval, and `turn_left(90)` turned the simulated drone by 37°.
pub const MAX_INTEGRATION_DT_US: u64 = 500_000;

/// Why a commander packet was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommanderError {
    /// No payload (a generic packet without a type byte, or an empty RPYT packet).
    Empty,
    /// The payload length does not match the type (stock would assert).
    WrongLength {
        /// The packet type (generic type, meta type, or 0xFF for RPYT).
        kind: u8,
        /// Payload bytes expected after the type byte.
        expected: usize,
        /// Payload bytes received after the type byte.
        got: usize,
    },
    /// A generic type the firmware does not define.
    UnknownType(u8),
    /// A defined type cfnav does not fly (3 CPPM, 4 alt-hold, 6 full state).
    Unsupported(u8),
    /// A float field is NaN or infinite.
    NonFinite,
    /// Port 7 channel 2 or 3, or port 3 channel ≠ 0.
    UnknownChannel(u8),
    /// A meta command other than "notify setpoint stop".
    UnknownMeta(u8),
    /// A port that is not a commander port.
    WrongPort(u8),
}

/// The `kind` used in [`CommanderError::WrongLength`] for RPYT packets.
pub const KIND_RPYT: u8 = 0xFF;

/// A decoded commander packet, in cfnav's units and frames (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Motors off (generic type 0).
    Stop,
    /// Attitude and thrust: RPYT (port 3, thrust after min/cap/lock) and manual (type 11).
    Attitude {
        /// Roll angle, rad (or roll rate, rad/s, when `rate_mode`).
        roll_rad: f32,
        /// Pitch angle, rad, positive nose down (or pitch rate, rad/s, when `rate_mode`).
        pitch_rad: f32,
        /// Yaw rate, rad/s, counter-clockwise positive.
        yaw_rate_rad_s: f32,
        /// Collective thrust command, 0..=65535 (stock units).
        thrust: u16,
        /// Roll and pitch are rates (manual packets with the rate flag set).
        rate_mode: bool,
    },
    /// World-frame velocity (types 1 and 8).
    VelocityWorld {
        /// Arena-frame velocity, m/s.
        velocity_m_s: [f32; 3],
        /// Yaw rate, rad/s.
        yaw_rate_rad_s: f32,
    },
    /// Height with roll/pitch angles (types 2 and 9).
    ZDistance {
        /// Roll, rad.
        roll_rad: f32,
        /// Pitch, rad, positive nose down.
        pitch_rad: f32,
        /// Yaw rate, rad/s.
        yaw_rate_rad_s: f32,
        /// Height, m.
        z_m: f32,
    },
    /// Body-frame horizontal velocity at a height (types 5 and 10).
    Hover {
        /// Velocity along body x, m/s.
        vx_body_m_s: f32,
        /// Velocity along body y (left), m/s.
        vy_body_m_s: f32,
        /// Yaw rate, rad/s.
        yaw_rate_rad_s: f32,
        /// Height, m.
        z_m: f32,
    },
    /// Absolute position and heading (type 7).
    Position {
        /// Arena-frame position, m.
        position_m: [f32; 3],
        /// Heading, rad.
        yaw_rad: f32,
    },
}

/// A meta command (port 7 channel 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MetaCommand {
    /// Hand control back to the high-level commander, optionally after the current setpoint stayed valid
    /// for `remain_valid_ms`.
    NotifySetpointStop {
        /// How long the current setpoint stays valid, ms.
        remain_valid_ms: u32,
    },
}

fn f32_at(bytes: &[u8], offset: usize) -> f32 {
    let mut b = [0u8; 4];
    if let Some(s) = bytes.get(offset..offset + 4) {
        b.copy_from_slice(s);
    }
    f32::from_le_bytes(b)
}

fn u16_at(bytes: &[u8], offset: usize) -> u16 {
    let mut b = [0u8; 2];
    if let Some(s) = bytes.get(offset..offset + 2) {
        b.copy_from_slice(s);
    }
    u16::from_le_bytes(b)
}

fn u32_at(bytes: &[u8], offset: usize) -> u32 {
    let mut b = [0u8; 4];
    if let Some(s) = bytes.get(offset..offset + 4) {
        b.copy_from_slice(s);
    }
    u32::from_le_bytes(b)
}

fn finite<const N: usize>(values: [f32; N]) -> Result<[f32; N], CommanderError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(values)
    } else {
        Err(CommanderError::NonFinite)
    }
}

fn expect_len(kind: u8, payload: &[u8], expected: usize) -> Result<(), CommanderError> {
    if payload.len() == expected {
        Ok(())
    } else {
        Err(CommanderError::WrongLength {
            kind,
            expected,
            got: payload.len(),
        })
    }
}

/// Raw RPYT fields as they are on the wire (before thrust handling).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawRpyt {
    /// Wire roll, deg.
    pub roll_deg: f32,
    /// Wire pitch, deg (the stock firmware's legacy sign; cflib sends −pitch).
    pub pitch_deg: f32,
    /// Wire yaw rate, deg/s (negated by the firmware).
    pub yaw_deg_s: f32,
    /// Raw thrust.
    pub thrust: u16,
}

/// Decodes the 14-byte RPYT payload (no thrust handling; see [`CommanderService`] for the lock).
pub fn decode_rpyt(payload: &[u8]) -> Result<RawRpyt, CommanderError> {
    if payload.is_empty() {
        return Err(CommanderError::Empty);
    }
    expect_len(KIND_RPYT, payload, RPYT_LEN)?;
    let [roll_deg, pitch_deg, yaw_deg_s] = finite([f32_at(payload, 0), f32_at(payload, 4), f32_at(payload, 8)])?;
    Ok(RawRpyt {
        roll_deg,
        pitch_deg,
        yaw_deg_s,
        thrust: u16_at(payload, 12),
    })
}

/// The RPYT thrust rule without the lock: < 1000 → 0, capped at 60000.
pub fn rpyt_thrust(raw: u16) -> u16 {
    if raw < RPYT_MIN_THRUST {
        0
    } else {
        raw.min(RPYT_MAX_THRUST)
    }
}

impl RawRpyt {
    /// The command for these fields with `thrust` (already limited/locked by the caller).
    pub fn command(&self, thrust: u16) -> Command {
        Command::Attitude {
            roll_rad: self.roll_deg.to_radians(),
            pitch_rad: -self.pitch_deg.to_radians(),
            yaw_rate_rad_s: -self.yaw_deg_s.to_radians(),
            thrust,
            rate_mode: false,
        }
    }
}

/// Decodes a port 7 channel 0 payload (`[type, …]`).
pub fn decode_generic(data: &[u8]) -> Result<Command, CommanderError> {
    let Some((&kind, payload)) = data.split_first() else {
        return Err(CommanderError::Empty);
    };
    let four = |payload: &[u8]| -> Result<[f32; 4], CommanderError> {
        expect_len(kind, payload, FOUR_FLOAT_LEN)?;
        finite([
            f32_at(payload, 0),
            f32_at(payload, 4),
            f32_at(payload, 8),
            f32_at(payload, 12),
        ])
    };
    // The legacy types' yaw rate is negated by the firmware.
    let yaw_sign = |legacy: u8| if kind == legacy { -1.0 } else { 1.0 };
    match kind {
        TYPE_STOP => Ok(Command::Stop),
        TYPE_VELOCITY_WORLD_LEGACY | TYPE_VELOCITY_WORLD => {
            let [vx, vy, vz, yaw_rate] = four(payload)?;
            Ok(Command::VelocityWorld {
                velocity_m_s: [vx, vy, vz],
                yaw_rate_rad_s: yaw_sign(TYPE_VELOCITY_WORLD_LEGACY) * yaw_rate.to_radians(),
            })
        }
        TYPE_ZDISTANCE_LEGACY | TYPE_ZDISTANCE => {
            let [roll, pitch, yaw_rate, z] = four(payload)?;
            Ok(Command::ZDistance {
                roll_rad: roll.to_radians(),
                pitch_rad: -pitch.to_radians(),
                yaw_rate_rad_s: yaw_sign(TYPE_ZDISTANCE_LEGACY) * yaw_rate.to_radians(),
                z_m: z,
            })
        }
        TYPE_HOVER_LEGACY | TYPE_HOVER => {
            let [vx, vy, yaw_rate, z] = four(payload)?;
            Ok(Command::Hover {
                vx_body_m_s: vx,
                vy_body_m_s: vy,
                yaw_rate_rad_s: yaw_sign(TYPE_HOVER_LEGACY) * yaw_rate.to_radians(),
                z_m: z,
            })
        }
        TYPE_POSITION => {
            let [x, y, z, yaw] = four(payload)?;
            Ok(Command::Position {
                position_m: [x, y, z],
                yaw_rad: yaw.to_radians(),
            })
        }
        TYPE_MANUAL => {
            expect_len(kind, payload, MANUAL_LEN)?;
            let [roll, pitch, yaw_rate] = finite([f32_at(payload, 0), f32_at(payload, 4), f32_at(payload, 8)])?;
            Ok(Command::Attitude {
                roll_rad: roll.to_radians(),
                pitch_rad: -pitch.to_radians(),
                yaw_rate_rad_s: yaw_rate.to_radians(),
                thrust: u16_at(payload, 12),
                // Stock compares `rate == true`, i.e. exactly 1.
                rate_mode: payload.get(14) == Some(&1),
            })
        }
        TYPE_FULL_STATE => {
            expect_len(kind, payload, FULL_STATE_LEN)?;
            Err(CommanderError::Unsupported(kind))
        }
        TYPE_CPPM_EMU | TYPE_ALT_HOLD => Err(CommanderError::Unsupported(kind)),
        other => Err(CommanderError::UnknownType(other)),
    }
}

/// Decodes a port 7 channel 1 payload (`[meta type, …]`).
pub fn decode_meta(data: &[u8]) -> Result<MetaCommand, CommanderError> {
    let Some((&kind, payload)) = data.split_first() else {
        return Err(CommanderError::Empty);
    };
    match kind {
        META_NOTIFY_SETPOINT_STOP => {
            expect_len(kind, payload, META_NOTIFY_LEN)?;
            Ok(MetaCommand::NotifySetpointStop {
                remain_valid_ms: u32_at(payload, 0),
            })
        }
        other => Err(CommanderError::UnknownMeta(other)),
    }
}

/// Counters kept by [`CommanderService`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CommanderStats {
    /// Setpoint commands accepted.
    pub accepted: u32,
    /// Meta commands accepted.
    pub meta: u32,
    /// Packets refused.
    pub refused: u32,
    /// RPYT packets whose thrust the lock forced to 0.
    pub thrust_locked: u32,
}

/// The service's state (copyable, so that the two port adapters can share it through a `Cell`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct State {
    now_us: Micros,
    latest: Option<(Command, Micros)>,
    fresh: bool,
    meta: Option<(MetaCommand, Micros)>,
    thrust_locked: bool,
    last_error: Option<CommanderError>,
    stats: CommanderStats,
}

impl State {
    fn handle(&mut self, packet: &CrtpPacket) -> Result<(), CommanderError> {
        match (packet.port, packet.channel) {
            (PORT_RPYT, 0) => {
                let raw = decode_rpyt(&packet.data)?;
                // Stock: priority "disabled" (no command for 500 ms, or none since boot) locks the thrust.
                let stale = self
                    .latest
                    .is_none_or(|(_, t)| self.now_us.saturating_sub(t) > THRUST_RELOCK_US);
                if stale {
                    self.thrust_locked = true;
                }
                if raw.thrust == 0 {
                    self.thrust_locked = false;
                }
                let thrust = if self.thrust_locked {
                    if raw.thrust != 0 {
                        self.stats.thrust_locked = self.stats.thrust_locked.saturating_add(1);
                    }
                    0
                } else {
                    rpyt_thrust(raw.thrust)
                };
                self.accept(raw.command(thrust));
                Ok(())
            }
            (PORT_RPYT, ch) => Err(CommanderError::UnknownChannel(ch)),
            (PORT_GENERIC, CH_SETPOINT) => {
                let command = decode_generic(&packet.data)?;
                self.accept(command);
                Ok(())
            }
            (PORT_GENERIC, CH_META) => {
                let meta = decode_meta(&packet.data)?;
                self.meta = Some((meta, self.now_us));
                self.stats.meta = self.stats.meta.saturating_add(1);
                Ok(())
            }
            (PORT_GENERIC, ch) => Err(CommanderError::UnknownChannel(ch)),
            (port, _) => Err(CommanderError::WrongPort(port)),
        }
    }

    fn accept(&mut self, command: Command) {
        self.latest = Some((command, self.now_us));
        self.fresh = true;
        self.stats.accepted = self.stats.accepted.saturating_add(1);
    }
}

/// The commander service for ports 3 and 7: the latest accepted command, its arrival time, the RPYT thrust
/// lock, the latest meta command, counters.
///
/// The router dispatches each port to one [`Service`], so the service is plugged in through the two
/// adapters of [`CommanderService::ports`] (they share the state through a [`Cell`]; no reply is ever sent,
/// as in stock). [`CommanderService::handle_packet`] handles either port directly.
#[derive(Debug, Clone)]
pub struct CommanderService {
    state: Cell<State>,
}

impl Default for CommanderService {
    fn default() -> Self {
        Self::new()
    }
}

impl CommanderService {
    /// A service at boot: no command, thrust locked, time 0.
    pub const fn new() -> Self {
        Self {
            state: Cell::new(State {
                now_us: 0,
                latest: None,
                fresh: false,
                meta: None,
                thrust_locked: true,
                last_error: None,
                stats: CommanderStats {
                    accepted: 0,
                    meta: 0,
                    refused: 0,
                    thrust_locked: 0,
                },
            }),
        }
    }

    /// Sets the time stamped on the packets handled next, µs since boot.
    pub fn set_now(&self, now_us: Micros) {
        self.update(|s| s.now_us = now_us);
    }

    /// Handles one packet for port 3 or 7; a refused packet changes nothing but the counters.
    pub fn handle_packet(&self, packet: &CrtpPacket) -> Result<(), CommanderError> {
        let mut state = self.state.get();
        let mut trial = state;
        let result = trial.handle(packet);
        match result {
            Ok(()) => state = trial,
            Err(e) => {
                state.last_error = Some(e);
                state.stats.refused = state.stats.refused.saturating_add(1);
            }
        }
        self.state.set(state);
        result
    }

    /// The two router adapters: port 3 (RPYT) and port 7 (generic + meta).
    pub fn ports(&self) -> [CommanderPort<'_>; 2] {
        [
            CommanderPort {
                service: self,
                port: PORT_RPYT,
            },
            CommanderPort {
                service: self,
                port: PORT_GENERIC,
            },
        ]
    }

    /// The latest accepted command and its arrival time.
    pub fn latest(&self) -> Option<(Command, Micros)> {
        self.state.get().latest
    }

    /// The latest accepted command if it arrived since the previous call (then marks it taken).
    pub fn take_fresh(&self) -> Option<(Command, Micros)> {
        let mut state = self.state.get();
        let out = if state.fresh { state.latest } else { None };
        state.fresh = false;
        self.state.set(state);
        out
    }

    /// The latest meta command since the previous call, with its arrival time.
    pub fn take_meta(&self) -> Option<(MetaCommand, Micros)> {
        let mut state = self.state.get();
        let out = state.meta.take();
        self.state.set(state);
        out
    }

    /// Age of the latest command at `now_us`, µs (`None` before the first command).
    pub fn age_us(&self, now_us: Micros) -> Option<u64> {
        self.latest().map(|(_, t)| now_us.saturating_sub(t))
    }

    /// The RPYT thrust lock is engaged.
    pub fn thrust_locked(&self) -> bool {
        self.state.get().thrust_locked
    }

    /// Why the latest refused packet was refused.
    pub fn last_error(&self) -> Option<CommanderError> {
        self.state.get().last_error
    }

    /// The counters.
    pub fn stats(&self) -> CommanderStats {
        self.state.get().stats
    }

    fn update(&self, f: impl FnOnce(&mut State)) {
        let mut s = self.state.get();
        f(&mut s);
        self.state.set(s);
    }
}

/// One port of a [`CommanderService`], for the router.
#[derive(Debug, Clone, Copy)]
pub struct CommanderPort<'a> {
    service: &'a CommanderService,
    port: u8,
}

impl Service for CommanderPort<'_> {
    fn port(&self) -> u8 {
        self.port
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        if packet.port == self.port {
            let _ = self.service.handle_packet(packet);
        }
        None
    }
}

/// Turns commands into cfnav [`Setpoint`]s, integrating rates into a held height and heading.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SetpointFollower {
    held_z_m: Option<f32>,
    held_yaw_rad: Option<f32>,
    last_us: Option<Micros>,
}

impl SetpointFollower {
    /// A follower holding nothing (the first rate command starts from the estimate).
    pub const fn new() -> Self {
        Self {
            held_z_m: None,
            held_yaw_rad: None,
            last_us: None,
        }
    }

    /// Forgets the held height and heading.
    pub fn reset(&mut self) {
        *self = Self::new();
    }

    /// The setpoint for `command` received at `received_us`, given the current `estimate`; `None` when
    /// cfnav's [`Setpoint`] cannot express it (manual roll/pitch rates, z-distance with a tilt) or the
    /// result would not be finite (huge values overflowing).
    /// The follower's held height/heading change only when a setpoint is returned.
    pub fn to_setpoint(
        &mut self,
        command: &Command,
        received_us: Micros,
        estimate: &StateEstimate,
    ) -> Option<Setpoint> {
        let dt_s = match self.last_us {
            Some(t) => received_us.saturating_sub(t).min(MAX_INTEGRATION_DT_US) as f32 * 1e-6,
            None => 0.0,
        };
        let est_z = if estimate.position_m[2].is_finite() {
            estimate.position_m[2]
        } else {
            0.0
        };
        let est_yaw = wrap_angle(estimate.attitude_rad[2]);
        let held_yaw = self.held_yaw_rad.unwrap_or(est_yaw);
        let yaw_after = |rate: f32| wrap_angle(held_yaw + rate * dt_s);
        let (setpoint, z, yaw) = match *command {
            Command::Stop => {
                self.reset();
                self.last_us = Some(received_us);
                return Some(Setpoint::Stop);
            }
            Command::Attitude { thrust: 0, .. } => {
                self.reset();
                self.last_us = Some(received_us);
                return Some(Setpoint::Stop);
            }
            Command::Attitude { rate_mode: true, .. } => return None,
            Command::Attitude {
                roll_rad,
                pitch_rad,
                yaw_rate_rad_s,
                thrust,
                rate_mode: false,
            } => {
                if !(roll_rad.is_finite() && pitch_rad.is_finite() && yaw_rate_rad_s.is_finite()) {
                    return None;
                }
                self.reset();
                self.last_us = Some(received_us);
                return Some(Setpoint::Attitude {
                    roll_rad,
                    pitch_rad,
                    yaw_rate_rad_s,
                    thrust,
                });
            }
            Command::Position { position_m, yaw_rad } => {
                let yaw = wrap_angle(yaw_rad);
                let sp = Setpoint::Position {
                    x_m: position_m[0],
                    y_m: position_m[1],
                    z_m: position_m[2],
                    yaw_rad: yaw,
                };
                (sp, position_m[2], yaw)
            }
            Command::VelocityWorld {
                velocity_m_s,
                yaw_rate_rad_s,
            } => {
                let z = self.held_z_m.unwrap_or(est_z) + velocity_m_s[2] * dt_s;
                let yaw = yaw_after(yaw_rate_rad_s);
                let sp = Setpoint::Velocity {
                    vx_m_s: velocity_m_s[0],
                    vy_m_s: velocity_m_s[1],
                    z_m: z,
                    yaw_rad: yaw,
                };
                (sp, z, yaw)
            }
            Command::ZDistance {
                roll_rad,
                pitch_rad,
                yaw_rate_rad_s,
                z_m,
            } => {
                if roll_rad != 0.0 || pitch_rad != 0.0 {
                    return None;
                }
                let yaw = yaw_after(yaw_rate_rad_s);
                let sp = Setpoint::Velocity {
                    vx_m_s: 0.0,
                    vy_m_s: 0.0,
                    z_m,
                    yaw_rad: yaw,
                };
                (sp, z_m, yaw)
            }
            Command::Hover {
                vx_body_m_s,
                vy_body_m_s,
                yaw_rate_rad_s,
                z_m,
            } => {
                // Body → arena with the current heading (the hover velocity is horizontal).
                let (s, c) = (libm::sinf(est_yaw), libm::cosf(est_yaw));
                let yaw = yaw_after(yaw_rate_rad_s);
                let sp = Setpoint::Velocity {
                    vx_m_s: c * vx_body_m_s - s * vy_body_m_s,
                    vy_m_s: s * vx_body_m_s + c * vy_body_m_s,
                    z_m,
                    yaw_rad: yaw,
                };
                (sp, z_m, yaw)
            }
        };
        // Finite inputs can still overflow (a huge velocity times dt, rotated or accumulated).
        let fields = match setpoint {
            Setpoint::Position { x_m, y_m, z_m, yaw_rad } => [x_m, y_m, z_m, yaw_rad],
            Setpoint::Velocity {
                vx_m_s,
                vy_m_s,
                z_m,
                yaw_rad,
            } => [vx_m_s, vy_m_s, z_m, yaw_rad],
            _ => [0.0; 4],
        };
        if !fields.iter().all(|v| v.is_finite()) {
            return None;
        }
        self.held_z_m = Some(z);
        self.held_yaw_rad = Some(yaw);
        self.last_us = Some(received_us);
        Some(setpoint)
    }
}
