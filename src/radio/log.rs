//! The log service, CRTP port 5 (log protocol v2), over a [`LogSource`] table.
//!
//! Job: answer TOC info and items (channel 0) and block control (channel 1) with the stock firmware's byte
//! layouts, and produce the due data packets (channel 2) from a sans-IO [`LogService::tick`].
//!
//! Non-goals: no V1 (8-bit id) TOC or block commands, no raw-memory ops (var id 0xFFFF), no clock (the caller
//! passes `now_ms`), no connection-loss detection (call [`LogService::reset`] on inactivity).
//!
//! Sources (`docs/hardware.md` §4 step 3–4; `docs/radio.md`, the connection steps that fetch the log TOC and their trace):
//! * ch0 `[3]` → `[3, count u16, crc u32, 16, 128]` (9 bytes); `[2, id u16]` → `[2, id u16, type, group\0,
//!   name\0]`, id out of range → `[2]`.
//! * ch1 every reply is `[cmd, block id, result]`: create v2 `[6, id, (fmt, var u16)…]`, append v2 `[7, …]`,
//!   start `[3, id, period×10 ms]`, start v2 `[8, id, period ms u16]`, stop `[4, id]`, delete `[2, id]`,
//!   reset `[5]` → `[5, 0, 0]`. Errors: ENOENT 2, E2BIG 7, ENOMEM 12, EEXIST 17.
//! * ch2 `[block id, timestamp ms 24-bit LE, values…]`, values ≤ 26 bytes, each converted to the fetch type
//!   (the op's low nibble; the high nibble, cflib's stored type, is ignored: the TOC's type is used).
//! * Limits: 16 blocks, 128 ops in total.
//!
//! Design choices not fixed by the references:
//! * Per op, checks run in stock's order: E2BIG (block data would pass 26 bytes), ENOMEM (128 ops used), ENOENT
//!   (no such variable); an unknown fetch type (0 or 9..15) gives EINVAL (22). Unlike stock, a create or append
//!   that fails changes **nothing** (stock keeps the ops added before the failing one, and a created block).
//! * Start with period 0 (either form) is refused with EINVAL (22) and leaves the block as it was (stock runs
//!   the block once). Start on a running block restarts it with the new period. Stop and delete of an unknown
//!   block give ENOENT; stop of a stopped block is fine.
//! * A started block sends its first packet at the first [`LogService::tick`] after the start, then every
//!   period; a tick late by more than one period does not burst (the schedule restarts from `now_ms`).
//! * Truncated requests (no block id, TOC item without a full id) and unknown commands get **no reply**;
//!   trailing bytes that do not make a whole 3-byte op are ignored (stock's `(len - 2) / 3`).
//! * Reset replies `[5, data[1] or 0, 0]` (stock echoes whatever byte 1 holds; the trace shows 0).
//! * A variable the source has no value for is sent as zeros.
//!
//! Memory: 16 block slots of 26 ops × 4 bytes plus a few words each, about 2 kB.

use core::marker::PhantomData;

use heapless::Vec;

use super::crtp::{CrtpPacket, MAX_DATA, Service};
use super::toc::toc_item;
use crate::radio::log_decl::{LogEntry, LogSource, LogType, log_toc_crc};

/// Log port.
pub const PORT_LOG: u8 = 5;
/// TOC channel.
pub const CH_TOC: u8 = 0;
/// Settings (block control) channel.
pub const CH_SETTINGS: u8 = 1;
/// Data channel (firmware → host).
pub const CH_DATA: u8 = 2;
/// TOC command: one item (v2).
pub const TOC_GET_ITEM_V2: u8 = 0x02;
/// TOC command: count, CRC and limits (v2).
pub const TOC_GET_INFO_V2: u8 = 0x03;
/// Control: delete a block.
pub const CMD_DELETE_BLOCK: u8 = 0x02;
/// Control: start a block, period in 10 ms units (u8).
pub const CMD_START_BLOCK: u8 = 0x03;
/// Control: stop a block.
pub const CMD_STOP_BLOCK: u8 = 0x04;
/// Control: delete every block.
pub const CMD_RESET: u8 = 0x05;
/// Control: create a block (v2 ops: fmt, var id u16).
pub const CMD_CREATE_BLOCK_V2: u8 = 0x06;
/// Control: append ops to a block (v2).
pub const CMD_APPEND_BLOCK_V2: u8 = 0x07;
/// Control: start a block, period in ms (u16 LE).
pub const CMD_START_BLOCK_V2: u8 = 0x08;
/// `ENOENT`: no such variable or block.
pub const ENOENT: u8 = 2;
/// `E2BIG`: the block's data would pass [`MAX_BLOCK_DATA`] bytes.
pub const E2BIG: u8 = 7;
/// `ENOMEM`: 16 blocks or 128 ops in use.
pub const ENOMEM: u8 = 12;
/// `EEXIST`: a block with this id exists.
pub const EEXIST: u8 = 17;
/// `EINVAL`: period 0 or an unknown fetch type (this firmware's choice, module docs).
pub const EINVAL: u8 = 22;
/// Most blocks at once (`LOG_MAX_BLOCKS`).
pub const MAX_BLOCKS: usize = 16;
/// Most ops over all blocks (`LOG_MAX_OPS`).
pub const MAX_OPS: usize = 128;
/// Most value bytes in one block's data packet (`LOG_MAX_LEN`).
pub const MAX_BLOCK_DATA: usize = 26;
/// Bytes before the values in a data packet: block id and 24-bit timestamp.
pub const DATA_HEADER: usize = 4;

/// One op: a variable and the type it is sent as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Op {
    var: u16,
    fetch: LogType,
}

#[derive(Debug, Clone, PartialEq, Eq)]
struct Block {
    id: u8,
    ops: Vec<Op, MAX_BLOCK_DATA>,
    /// 0 while stopped.
    period_ms: u32,
    /// `None` right after a start: send at the next tick.
    next_due_ms: Option<u32>,
}

impl Block {
    fn data_len(&self) -> usize {
        self.ops.iter().map(|o| o.fetch.size()).sum()
    }
}

/// The log service. `S` gives the table; the values are read from the `&S` passed to [`Self::tick`].
#[derive(Debug, Clone)]
pub struct LogService<S: LogSource> {
    blocks: [Option<Block>; MAX_BLOCKS],
    /// Slot to look at first in the next tick (round robin, so one block cannot starve the others).
    cursor: usize,
    _source: PhantomData<fn(&S)>,
}

fn packet(channel: u8, data: &[u8]) -> Option<CrtpPacket> {
    CrtpPacket::new(PORT_LOG, channel, data).ok()
}

fn control_reply(cmd: u8, id: u8, result: u8) -> Option<CrtpPacket> {
    packet(CH_SETTINGS, &[cmd, id, result])
}

impl<S: LogSource> Default for LogService<S> {
    fn default() -> Self {
        Self::new()
    }
}

impl<S: LogSource> LogService<S> {
    /// Number of variables; the table must have at most 65 535 entries (checked at compile time on use).
    pub const COUNT: u16 = {
        assert!(S::TABLE.len() <= u16::MAX as usize, "too many log variables");
        S::TABLE.len() as u16
    };
    /// The TOC CRC ([`log_toc_crc`]), computed at compile time.
    pub const CRC: u32 = log_toc_crc(S::TABLE);

    /// A service with no blocks.
    pub const fn new() -> Self {
        Self {
            blocks: [const { None }; MAX_BLOCKS],
            cursor: 0,
            _source: PhantomData,
        }
    }

    /// The entry of `id`.
    pub fn entry(id: u16) -> Option<&'static LogEntry> {
        S::TABLE.get(usize::from(id))
    }

    /// The id of `group.name`.
    pub fn find(group: &str, name: &str) -> Option<u16> {
        let i = S::TABLE.iter().position(|e| e.group == group && e.name == name)?;
        u16::try_from(i).ok()
    }

    /// Deletes every block (the RESET command; also for the firmware on link loss).
    pub fn reset(&mut self) {
        self.blocks = [const { None }; MAX_BLOCKS];
        self.cursor = 0;
    }

    /// Blocks in use.
    pub fn block_count(&self) -> usize {
        self.blocks.iter().flatten().count()
    }

    /// Ops in use over all blocks.
    pub fn ops_used(&self) -> usize {
        self.blocks.iter().flatten().map(|b| b.ops.len()).sum()
    }

    /// The period of block `id` if it is running.
    pub fn running_period_ms(&self, id: u8) -> Option<u32> {
        self.block(id).map(|b| b.period_ms).filter(|&p| p > 0)
    }

    /// Bytes of values block `id` sends, if it exists.
    pub fn block_data_len(&self, id: u8) -> Option<usize> {
        self.block(id).map(Block::data_len)
    }

    fn slot(&self, id: u8) -> Option<usize> {
        self.blocks.iter().position(|b| b.as_ref().is_some_and(|b| b.id == id))
    }

    fn block(&self, id: u8) -> Option<&Block> {
        self.blocks.get(self.slot(id)?)?.as_ref()
    }

    /// The next due data packet `[block id, ts 24-bit LE, values]` (port 5, ch 2), or `None` when no running
    /// block is due at `now_ms`. Call it until `None` and hand each packet to
    /// [`super::crtp::Router::enqueue`]. `now_ms` is a wrapping millisecond clock.
    pub fn tick(&mut self, now_ms: u32, source: &S) -> Option<CrtpPacket> {
        for k in 0..MAX_BLOCKS {
            let slot = (self.cursor + k) % MAX_BLOCKS;
            let Some(block) = self.blocks.get_mut(slot).and_then(Option::as_mut) else {
                continue;
            };
            if block.period_ms == 0 {
                continue;
            }
            let due = match block.next_due_ms {
                None => true,
                Some(t) => now_ms.wrapping_sub(t) as i32 >= 0,
            };
            if !due {
                continue;
            }
            let mut next = match block.next_due_ms {
                None => now_ms.wrapping_add(block.period_ms),
                Some(t) => t.wrapping_add(block.period_ms),
            };
            if now_ms.wrapping_sub(next) as i32 >= 0 {
                next = now_ms.wrapping_add(block.period_ms);
            }
            block.next_due_ms = Some(next);
            self.cursor = (slot + 1) % MAX_BLOCKS;
            return Self::data_packet(block, now_ms, source);
        }
        None
    }

    fn data_packet(block: &Block, now_ms: u32, source: &S) -> Option<CrtpPacket> {
        let mut out: Vec<u8, MAX_DATA> = Vec::new();
        let ts = now_ms.to_le_bytes();
        out.extend_from_slice(&[block.id, ts[0], ts[1], ts[2]]).ok()?;
        for op in &block.ops {
            let (bytes, n) = match source.value(op.var) {
                Some(v) => v.convert(op.fetch),
                None => ([0; 4], op.fetch.size()),
            };
            out.extend_from_slice(&bytes[..n]).ok()?;
        }
        packet(CH_DATA, &out)
    }

    fn toc(&self, data: &[u8]) -> Option<CrtpPacket> {
        match *data.first()? {
            TOC_GET_INFO_V2 => {
                let c = Self::COUNT.to_le_bytes();
                let k = Self::CRC.to_le_bytes();
                packet(
                    CH_TOC,
                    &[
                        TOC_GET_INFO_V2,
                        c[0],
                        c[1],
                        k[0],
                        k[1],
                        k[2],
                        k[3],
                        MAX_BLOCKS as u8,
                        MAX_OPS as u8,
                    ],
                )
            }
            TOC_GET_ITEM_V2 => {
                let id = u16::from_le_bytes([*data.get(1)?, *data.get(2)?]);
                let Some(e) = Self::entry(id) else {
                    return packet(CH_TOC, &[TOC_GET_ITEM_V2]);
                };
                let mut out: Vec<u8, MAX_DATA> = Vec::new();
                toc_item(&mut out, TOC_GET_ITEM_V2, id, e.ty.log_code(), e.group, e.name)?;
                packet(CH_TOC, &out)
            }
            _ => None,
        }
    }

    /// Validates `ops_bytes` (whole 3-byte ops) for block `slot` and appends them all, or none.
    fn append(&mut self, slot: usize, ops_bytes: &[u8]) -> Result<(), u8> {
        let used = self.ops_used();
        let Some(block) = self.blocks.get(slot).and_then(Option::as_ref) else {
            return Err(ENOENT);
        };
        // Ops of the other blocks; `new_ops` holds this block's.
        let others = used - block.ops.len();
        let mut len = block.data_len();
        let mut new_ops: Vec<Op, MAX_BLOCK_DATA> = block.ops.clone();
        for raw in ops_bytes.chunks_exact(3) {
            let fetch = LogType::from_log_code(raw[0] & 0x0F).ok_or(EINVAL)?;
            if len + fetch.size() > MAX_BLOCK_DATA {
                return Err(E2BIG);
            }
            if others + new_ops.len() >= MAX_OPS {
                return Err(ENOMEM);
            }
            let var = u16::from_le_bytes([raw[1], raw[2]]);
            if Self::entry(var).is_none() {
                return Err(ENOENT);
            }
            new_ops.push(Op { var, fetch }).map_err(|_| E2BIG)?;
            len += fetch.size();
        }
        if let Some(block) = self.blocks.get_mut(slot).and_then(Option::as_mut) {
            block.ops = new_ops;
        }
        Ok(())
    }

    fn create(&mut self, id: u8, ops_bytes: &[u8]) -> Result<(), u8> {
        if self.slot(id).is_some() {
            return Err(EEXIST);
        }
        let free = self.blocks.iter().position(Option::is_none).ok_or(ENOMEM)?;
        self.blocks[free] = Some(Block {
            id,
            ops: Vec::new(),
            period_ms: 0,
            next_due_ms: None,
        });
        let result = self.append(free, ops_bytes);
        if result.is_err() {
            self.blocks[free] = None;
        }
        result
    }

    fn start(&mut self, id: u8, period_ms: u32) -> Result<(), u8> {
        let slot = self.slot(id).ok_or(ENOENT)?;
        if period_ms == 0 {
            return Err(EINVAL);
        }
        let block = self.blocks.get_mut(slot).and_then(Option::as_mut).ok_or(ENOENT)?;
        block.period_ms = period_ms;
        block.next_due_ms = None;
        Ok(())
    }

    fn control(&mut self, data: &[u8]) -> Option<CrtpPacket> {
        let cmd = *data.first()?;
        if cmd == CMD_RESET {
            self.reset();
            return control_reply(cmd, data.get(1).copied().unwrap_or(0), 0);
        }
        let id = *data.get(1)?;
        let result = match cmd {
            CMD_CREATE_BLOCK_V2 => self.create(id, &data[2..]),
            CMD_APPEND_BLOCK_V2 => match self.slot(id) {
                Some(slot) => self.append(slot, &data[2..]),
                None => Err(ENOENT),
            },
            CMD_START_BLOCK => self.start(id, u32::from(*data.get(2)?) * 10),
            CMD_START_BLOCK_V2 => self.start(id, u32::from(u16::from_le_bytes([*data.get(2)?, *data.get(3)?]))),
            CMD_STOP_BLOCK => match self.slot(id).and_then(|s| self.blocks.get_mut(s)?.as_mut()) {
                Some(block) => {
                    block.period_ms = 0;
                    block.next_due_ms = None;
                    Ok(())
                }
                None => Err(ENOENT),
            },
            CMD_DELETE_BLOCK => match self.slot(id) {
                Some(slot) => {
                    self.blocks[slot] = None;
                    Ok(())
                }
                None => Err(ENOENT),
            },
            _ => return None,
        };
        control_reply(cmd, id, result.err().unwrap_or(0))
    }
}

impl<S: LogSource> Service for LogService<S> {
    fn port(&self) -> u8 {
        PORT_LOG
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        if packet.port != PORT_LOG {
            return None;
        }
        match packet.channel {
            CH_TOC => self.toc(&packet.data),
            CH_SETTINGS => self.control(&packet.data),
            _ => None,
        }
    }
}
