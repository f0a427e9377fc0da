//! The high-level commander port (CRTP port 8, channel 0) decoded into [`HlCommand`]s.
//!
//! Job: check and decode what cflib's `HighLevelCommander` sends (protocol 12), keep the latest decoded
//! command for the caller (sans-IO: the caller passes the time), and keep this drone's group mask.
//! Non-goals: flying the command (see [`crate::flight::high_level`]), uploaded trajectories and spirals
//! (refused: [`HlError::Unsupported`], so the caller prints a console line).
//!
//! # Wire format (little-endian, packed; stock `crtp_commander_high_level.c` `enum TrajectoryCommand_e`
//! and its `struct data_*`; cflib `high_level_commander.py` packs the same)
//!
//! | cmd | name | payload after the command byte | bytes |
//! |---|---|---|---|
//! | 0 | set group mask | groupMask u8 | 1 |
//! | 1 / 2 | takeoff / land (deprecated) | groupMask u8, height f32, duration f32 | 9 |
//! | 3 | stop | groupMask u8 | 1 |
//! | 4 | go to (protocol < 8) | groupMask u8, relative u8, x, y, z, yaw f32, duration f32 | 22 |
//! | 5 / 6 | start / define trajectory | — (refused) | |
//! | 7 / 8 | takeoff 2 / land 2 | groupMask u8, height f32, yaw f32 (rad), useCurrentYaw u8, duration f32 | 14 |
//! | 9 / 10 | takeoff / land with velocity | — (refused) | |
//! | 11 | spiral | — (refused) | |
//! | 12 | go to 2 | groupMask u8, relative u8, linear u8, x, y, z, yaw f32, duration f32 | 23 |
//! | 13 | start trajectory 2 | — (refused) | |
//!
//! Group masks (stock `isInGroup`): a command applies when its mask is 0 (all groups) or shares a bit with
//! this drone's mask (0 at boot); a command for other groups is [`HlError::NotInGroup`] (ignored, as in
//! stock, where it is silently dropped; the caller may say so on the console).
//! Yaw: radians, counter-clockwise positive, like cfnav's frames. Non-finite floats are refused.
//! Memory: [`HighLevelService`] is under 64 bytes.

use core::cell::Cell;

use crate::flight::high_level::HlCommand;
use crate::radio::crtp::{CrtpPacket, Service};
use crate::types::Micros;

/// The high-level commander port.
pub const PORT_HIGH_LEVEL: u8 = 8;

/// `COMMAND_SET_GROUP_MASK`.
pub const CMD_SET_GROUP_MASK: u8 = 0;
/// `COMMAND_TAKEOFF` (deprecated: height, duration; current yaw).
pub const CMD_TAKEOFF: u8 = 1;
/// `COMMAND_LAND` (deprecated).
pub const CMD_LAND: u8 = 2;
/// `COMMAND_STOP`.
pub const CMD_STOP: u8 = 3;
/// `COMMAND_GO_TO` (protocol < 8).
pub const CMD_GO_TO: u8 = 4;
/// `COMMAND_START_TRAJECTORY` (refused).
pub const CMD_START_TRAJECTORY: u8 = 5;
/// `COMMAND_DEFINE_TRAJECTORY` (refused).
pub const CMD_DEFINE_TRAJECTORY: u8 = 6;
/// `COMMAND_TAKEOFF_2`.
pub const CMD_TAKEOFF_2: u8 = 7;
/// `COMMAND_LAND_2`.
pub const CMD_LAND_2: u8 = 8;
/// `COMMAND_TAKEOFF_WITH_VELOCITY` (refused).
pub const CMD_TAKEOFF_WITH_VELOCITY: u8 = 9;
/// `COMMAND_LAND_WITH_VELOCITY` (refused).
pub const CMD_LAND_WITH_VELOCITY: u8 = 10;
/// `COMMAND_SPIRAL` (refused).
pub const CMD_SPIRAL: u8 = 11;
/// `COMMAND_GO_TO_2`.
pub const CMD_GO_TO_2: u8 = 12;
/// `COMMAND_START_TRAJECTORY_2` (refused).
pub const CMD_START_TRAJECTORY_2: u8 = 13;

/// Why a port 8 packet was not turned into a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HlError {
    /// No command byte.
    Empty,
    /// The payload length does not match the command.
    WrongLength {
        /// The command.
        command: u8,
        /// Bytes expected after the command byte.
        expected: usize,
        /// Bytes received after the command byte.
        got: usize,
    },
    /// A float is NaN or infinite.
    NonFinite,
    /// A command stock defines that cfnav does not fly.
    Unsupported(u8),
    /// A command number stock does not define.
    Unknown(u8),
    /// The command is for other groups.
    NotInGroup,
    /// A channel other than 0.
    UnknownChannel(u8),
}

/// A decoded port 8 packet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HlPacket {
    /// Set this drone's group mask.
    SetGroupMask(u8),
    /// A command with its group mask.
    Command {
        /// The packet's group mask.
        group_mask: u8,
        /// The command.
        command: HlCommand,
    },
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    let mut v = [0u8; 4];
    if let Some(s) = b.get(at..at + 4) {
        v.copy_from_slice(s);
    }
    f32::from_le_bytes(v)
}

fn len(command: u8, payload: &[u8], expected: usize) -> Result<(), HlError> {
    if payload.len() == expected {
        Ok(())
    } else {
        Err(HlError::WrongLength {
            command,
            expected,
            got: payload.len(),
        })
    }
}

fn finite(values: &[f32]) -> Result<(), HlError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(HlError::NonFinite)
    }
}

/// Decodes a port 8 channel 0 payload (`[command, …]`).
pub fn decode(data: &[u8]) -> Result<HlPacket, HlError> {
    let Some((&cmd, p)) = data.split_first() else {
        return Err(HlError::Empty);
    };
    let mask = p.first().copied().unwrap_or(0);
    let command = |command| {
        Ok(HlPacket::Command {
            group_mask: mask,
            command,
        })
    };
    match cmd {
        CMD_SET_GROUP_MASK => {
            len(cmd, p, 1)?;
            Ok(HlPacket::SetGroupMask(mask))
        }
        CMD_STOP => {
            len(cmd, p, 1)?;
            command(HlCommand::Stop)
        }
        CMD_TAKEOFF | CMD_LAND => {
            len(cmd, p, 9)?;
            let (height_m, duration_s) = (f32_at(p, 1), f32_at(p, 5));
            finite(&[height_m, duration_s])?;
            command(if cmd == CMD_TAKEOFF {
                HlCommand::Takeoff {
                    height_m,
                    yaw_rad: None,
                    duration_s,
                }
            } else {
                HlCommand::Land {
                    height_m,
                    yaw_rad: None,
                    duration_s,
                }
            })
        }
        CMD_TAKEOFF_2 | CMD_LAND_2 => {
            len(cmd, p, 14)?;
            let (height_m, yaw, duration_s) = (f32_at(p, 1), f32_at(p, 5), f32_at(p, 10));
            finite(&[height_m, yaw, duration_s])?;
            // `useCurrentYaw` is a C bool; cflib packs `?` (0 or 1).
            let yaw_rad = if p[9] != 0 { None } else { Some(yaw) };
            command(if cmd == CMD_TAKEOFF_2 {
                HlCommand::Takeoff {
                    height_m,
                    yaw_rad,
                    duration_s,
                }
            } else {
                HlCommand::Land {
                    height_m,
                    yaw_rad,
                    duration_s,
                }
            })
        }
        CMD_GO_TO | CMD_GO_TO_2 => {
            let (linear, floats) = if cmd == CMD_GO_TO_2 {
                len(cmd, p, 23)?;
                (p[2] != 0, 3)
            } else {
                len(cmd, p, 22)?;
                (false, 2)
            };
            let v: [f32; 5] = core::array::from_fn(|i| f32_at(p, floats + 4 * i));
            finite(&v)?;
            command(HlCommand::GoTo {
                position_m: [v[0], v[1], v[2]],
                yaw_rad: v[3],
                duration_s: v[4],
                relative: p[1] != 0,
                linear,
            })
        }
        CMD_START_TRAJECTORY
        | CMD_DEFINE_TRAJECTORY
        | CMD_TAKEOFF_WITH_VELOCITY
        | CMD_LAND_WITH_VELOCITY
        | CMD_SPIRAL
        | CMD_START_TRAJECTORY_2 => Err(HlError::Unsupported(cmd)),
        other => Err(HlError::Unknown(other)),
    }
}

/// Whether a command with `packet_mask` applies to a drone in `own_mask` (stock `isInGroup`).
pub fn in_group(packet_mask: u8, own_mask: u8) -> bool {
    packet_mask == 0 || packet_mask & own_mask != 0
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct State {
    now_us: Micros,
    group_mask: u8,
    pending: Option<(HlCommand, Micros)>,
    last_error: Option<HlError>,
    refused: u32,
}

/// The port 8 service: decodes, applies the group mask, keeps the latest command for the caller. Never
/// replies (as stock).
#[derive(Debug, Default)]
pub struct HighLevelService {
    state: Cell<State>,
}

impl HighLevelService {
    /// At boot: group mask 0, nothing pending.
    pub const fn new() -> Self {
        Self {
            state: Cell::new(State {
                now_us: 0,
                group_mask: 0,
                pending: None,
                last_error: None,
                refused: 0,
            }),
        }
    }

    /// Sets the time stamped on the packets handled next, µs.
    pub fn set_now(&self, now_us: Micros) {
        let mut s = self.state.get();
        s.now_us = now_us;
        self.state.set(s);
    }

    /// Handles one packet (port 8). A refused packet changes nothing but the error and the counter.
    pub fn handle_packet(&self, packet: &CrtpPacket) -> Result<(), HlError> {
        let mut s = self.state.get();
        let result = if packet.channel != 0 {
            Err(HlError::UnknownChannel(packet.channel))
        } else {
            decode(&packet.data).and_then(|p| match p {
                HlPacket::SetGroupMask(m) => {
                    s.group_mask = m;
                    Ok(())
                }
                HlPacket::Command { group_mask, command } if in_group(group_mask, s.group_mask) => {
                    s.pending = Some((command, s.now_us));
                    Ok(())
                }
                HlPacket::Command { .. } => Err(HlError::NotInGroup),
            })
        };
        if let Err(e) = result {
            s.last_error = Some(e);
            s.refused = s.refused.saturating_add(1);
        }
        self.state.set(s);
        result
    }

    /// The command received since the previous call, with its arrival time.
    pub fn take(&self) -> Option<(HlCommand, Micros)> {
        let mut s = self.state.get();
        let out = s.pending.take();
        self.state.set(s);
        out
    }

    /// Takes the latest refusal (so each is reported once).
    pub fn take_error(&self) -> Option<HlError> {
        let mut s = self.state.get();
        let out = s.last_error.take();
        self.state.set(s);
        out
    }

    /// Packets refused so far.
    pub fn refused(&self) -> u32 {
        self.state.get().refused
    }

    /// This drone's group mask.
    pub fn group_mask(&self) -> u8 {
        self.state.get().group_mask
    }
}

impl Service for HighLevelService {
    fn port(&self) -> u8 {
        PORT_HIGH_LEVEL
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        if packet.port == PORT_HIGH_LEVEL {
            let _ = self.handle_packet(packet);
        }
        None
    }
}
