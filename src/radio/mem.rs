//! The memory service, CRTP port 4: only the memory count cflib asks for while connecting.
//!
//! Job: answer `[1]` (CMD_INFO_NBR) on channel 0 with `[1, 0]`: this firmware exposes no memories, which
//! completes cflib's memory step of the connect sequence.
//!
//! Non-goals: no memory details (`[2, id]`), reads or writes (channels 1 and 2): cflib never asks for them
//! when the count is 0; they get no reply.
//!
//! Sources: `crazyflie-hardware.md` §4.7 (`[1]` → `[1, n]`, n = 0 completes the step), `crtp-over-udp.md` §2
//! step 6 (`4/0 01` → `4/0 01 00`).
//!
//! Memory: none (a unit struct).

use super::crtp::{CrtpPacket, Service};

/// Memory port (§4.2).
pub const PORT_MEM: u8 = 4;
/// Info channel.
pub const CH_INFO: u8 = 0;
/// Info command: number of memories.
pub const CMD_INFO_NBR: u8 = 1;

/// The memory service: reports zero memories.
#[derive(Debug, Clone, Copy, Default)]
pub struct MemService;

impl Service for MemService {
    fn port(&self) -> u8 {
        PORT_MEM
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        if packet.port != PORT_MEM || packet.channel != CH_INFO {
            return None;
        }
        match packet.data.first()? {
            &CMD_INFO_NBR => CrtpPacket::new(PORT_MEM, CH_INFO, &[CMD_INFO_NBR, 0]).ok(),
            _ => None,
        }
    }
}
