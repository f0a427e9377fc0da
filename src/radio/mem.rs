//! The memory service, CRTP port 4: the memory count cflib asks for while connecting and, when the endpoint
//! serves it, one read-only memory holding the drone's map ([`crate::radio_binding::map_mem`]).
//!
//! Job: channel 0 answers `[1]` (GET_NUMBER_OF_MEMS) with `[1, n]` and `[2, id]` (GET_INFO) with
//! `[2, id, type, size u32, 8 zero bytes]`; channel 1 takes reads `[id, addr u32, len u8]`, channel 2 writes
//! `[id, addr u32, data…]`. Without the map (`n = 0`, the default) nothing else is listed, every read and write
//! is refused with status `EIO`, and cflib never asks. With the map ([`MemService::with_map`]), memory 0 is the
//! map, of type [`MAP_MEMORY_TYPE`]: a read of it is held ([`MemService::take_map_read`]) for the caller, who
//! owns the live map, to answer at once with [`MapRead::answer`]; writes are refused (`EIO`).
//!
//! Non-goals: other memories (EEPROM, 1-wire, decks), the map's layout (see [`crate::radio_binding::map_mem`]).
//!
//! Wire layouts (stock `src/modules/src/crtp_mem.c`: `createInfoResponse`, `memReadProcess`,
//! `memWriteProcess`; cflib 0.1.34 `cflib/crazyflie/mem/__init__.py` `_handle_cmd_info_details`,
//! `_ReadRequest`, `_handle_chan_read`): info reply `[2, id, type, size u32 LE, serial ≥ 8 bytes]`; read reply
//! `[id, addr u32 LE, status, data…]` (status 0 with `len` bytes, else `EIO` = 5 and no data); write reply
//! `[id, addr u32 LE, status]`. cflib lists a memory of a type it does not know as a plain `MemoryElement`
//! (`get_mems(type)` finds it, `mem.read` reads it); crazyflie-lib 0.8.2 lists it as `MemoryType::UNKNOWN` and
//! reads it through `RawMemory`.
//!
//! Sources also: `docs/hardware.md` §4, `docs/radio.md` (the memory count cflib asks for while connecting).
//!
//! Memory: a flag and the held read (8 bytes).

use super::crtp::{CrtpPacket, Service};

/// Memory port.
pub const PORT_MEM: u8 = 4;
/// Info channel.
pub const CH_INFO: u8 = 0;
/// Read channel.
pub const CH_READ: u8 = 1;
/// Write channel.
pub const CH_WRITE: u8 = 2;
/// Info command: number of memories.
pub const CMD_INFO_NBR: u8 = 1;
/// Info command: one memory's type, size and serial.
pub const CMD_INFO_DETAILS: u8 = 2;
/// Status of a refused read or write (stock `EIO`).
pub const STATUS_EIO: u8 = 5;
/// Id of the map memory.
pub const MAP_MEMORY_ID: u8 = 0;
/// Type id of the map memory: one neither the stock firmware nor cflib 0.1.34 nor crazyflie-lib 0.8.2 uses
/// (theirs are 0x00, 0x01, 0x10–0x1B, 0x20, 0x21; cflib `memory_element.py` `TYPE_*`).
pub const MAP_MEMORY_TYPE: u8 = 0xC4;

/// A held read of the map memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MapRead {
    /// First byte.
    pub addr: u32,
    /// Bytes asked for.
    pub len: u8,
}

/// The memory service: no memories, or the map.
#[derive(Debug, Clone, Copy, Default)]
pub struct MemService {
    map_size: Option<u32>,
    held: Option<MapRead>,
}

impl MemService {
    /// A service listing no memories.
    pub const fn new() -> Self {
        Self {
            map_size: None,
            held: None,
        }
    }

    /// A service listing the map memory, `size` bytes long. The caller must answer every
    /// [`take_map_read`](Self::take_map_read). cfnav's map builds it with `MemService::with_map` (in
    /// `crate::radio_binding::map_mem`), which gives the size of its layout.
    pub const fn with_map_size(size: u32) -> Self {
        Self {
            map_size: Some(size),
            held: None,
        }
    }

    /// The map read received last, if not taken yet (one at a time: the caller answers it before the next
    /// packet is handled).
    pub fn take_map_read(&mut self) -> Option<MapRead> {
        self.held.take()
    }

    fn count(&self) -> u8 {
        u8::from(self.map_size.is_some())
    }

    fn status_reply(channel: u8, data: &[u8]) -> Option<CrtpPacket> {
        let mut buf = [0u8; 6];
        buf[..5].copy_from_slice(data.get(..5)?);
        buf[5] = STATUS_EIO;
        CrtpPacket::new(PORT_MEM, channel, &buf).ok()
    }
}

impl Service for MemService {
    fn port(&self) -> u8 {
        PORT_MEM
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        if packet.port != PORT_MEM {
            return None;
        }
        let data = packet.data.as_slice();
        match packet.channel {
            CH_INFO => match *data.first()? {
                CMD_INFO_NBR => CrtpPacket::new(PORT_MEM, CH_INFO, &[CMD_INFO_NBR, self.count()]).ok(),
                CMD_INFO_DETAILS => {
                    let id = *data.get(1)?;
                    let size = self.map_size.filter(|_| id == MAP_MEMORY_ID)?;
                    let mut buf = [0u8; 15];
                    buf[0] = CMD_INFO_DETAILS;
                    buf[1] = id;
                    buf[2] = MAP_MEMORY_TYPE;
                    buf[3..7].copy_from_slice(&size.to_le_bytes());
                    CrtpPacket::new(PORT_MEM, CH_INFO, &buf).ok()
                }
                _ => None,
            },
            CH_READ => {
                if data.len() < 6 {
                    return None;
                }
                if data[0] == MAP_MEMORY_ID && self.map_size.is_some() {
                    let addr = u32::from_le_bytes([data[1], data[2], data[3], data[4]]);
                    self.held = Some(MapRead { addr, len: data[5] });
                    return None;
                }
                Self::status_reply(CH_READ, data)
            }
            CH_WRITE => Self::status_reply(CH_WRITE, data),
            _ => None,
        }
    }
}
