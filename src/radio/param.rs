//! The parameter service, CRTP port 2 (param protocol v2), over a [`ParamStore`].
//!
//! Job: answer TOC info and items (channel 0), reads (1), writes (2) and misc commands (3: set-by-name,
//! extended type v2) with the stock firmware's byte layouts, and build the unsolicited VALUE_UPDATED packets
//! the firmware queues when it changes a parameter itself.
//!
//! Non-goals: no V1 (8-bit id) commands, no EEPROM access (the persistent commands hand the caller the
//! bytes to write, [`ParamService::eeprom_write`], and answer when it reports back).
//!
//! Sources (`docs/hardware.md` §4, `docs/radio.md`, the connection steps that fetch the parameter TOC and values and their trace):
//! * ch0 `[3]` → `[3, count u16, crc u32]` (7 bytes); `[2, id u16]` → `[2, id u16, type, group\0, name\0]`,
//!   id out of range → `[2]` only.
//! * ch1 `[id u16]` → `[id u16, 0, value]` (exactly 3 + size), unknown id → `[id u16, 2]` (ENOENT).
//! * ch2 `[id u16, value]` → echo `[id u16, value]`; unknown id → `[id u16, 2]`; read-only id → no reply.
//! * ch3 `[0, group\0, name\0, type, value]` → `[0, group\0, name\0, err]`; `[7, id u16]` →
//!   `[7, id u16, 0, ext_type]`; firmware-side changes → unsolicited `[1, id u16, value]`.
//!
//! Design choices not fixed by the references:
//! * A write whose value is not exactly the parameter's size, and any truncated request (TOC item or read
//!   without a full id, write without one, set-by-name without two NULs and a type byte) gets **no reply** and
//!   changes nothing. Stock does not check these sizes (it reads past the payload); cflib never sends them.
//! * A write refused by its declaration (range) or by the store (`docs/radio.md`) is echoed with the value **in effect**; the refusal is
//!   kept for a console line ([`ParamService::take_refusal`]). Every write echo carries the value read back.
//! * Set-by-name errors: ENOENT (2) unknown name, EINVAL (22) type mismatch, wrong value size or a refused
//!   value, EACCES (13) read-only; a successful set-by-name queues no VALUE_UPDATED (as stock).
//! * Misc 7 for an unknown id → `[7, id u16, 2]`; ext_type is 1 (persistent) for [`FLAG_EXTENDED`] entries.
//! * Default value (stock `paramGetDefaultValue[V2]`, `param_logic.c`): v2 `[8, id u16]` → `[8, id u16, 0,
//!   value]`, v1 `[6, id u16]` → `[6, id u16, value]`; unknown, read-only or no default
//!   ([`ParamStore::default_value`]) → `[cmd, id u16, ENOENT]`. cfclient asks for it whenever a parameter is
//!   selected, and cflib's parameter queue waits for the answer: without one, every later write stalls.
//! * Unknown TOC/misc commands: no reply.
//! * Persistent parameters (stock `param_logic.c` `paramPersistentStore/GetState/Clear`, cflib
//!   `param.py` `persistent_store/get_state/clear`): misc 3 STORE `[3, id u16]` → `[3, id u16, status]`,
//!   misc 5 CLEAR `[5, id u16]` → `[5, id u16, status]`, status 0 on success; misc 4 GET_STATE `[4, id u16]`
//!   → `[4, id u16, 0 (not stored), default]` or `[4, id u16, 1 (stored), default, stored]`, unknown id →
//!   `[4, id u16, ENOENT]`. A store or a clear that changes the EEPROM is answered only once the caller
//!   reports the write done ([`ParamService::eeprom_write_done`]: status 0, or EIO if it failed), as stock
//!   answers after `storageStore`; while one waits, another gets EBUSY. Refusals: unknown id ENOENT, a
//!   parameter that is not persistent ENOENT (as stock), a full store ENOSPC, a store or clear while flying
//!   EBUSY (each of the last two with a console line: the EEPROM shares the deck bus with the height
//!   ranger). Clearing a value that is not stored succeeds without a write.
//! * Aliases ([`ParamStore::aliases`], one gain behind two stock names): a write queues a VALUE_UPDATED
//!   for each other name, so clients' caches follow.
//!
//! Memory: the store, a queue of 8 pending VALUE_UPDATED ids, 4 pending refusals and one EEPROM write
//! (a slot image, 640 bytes).

use core::fmt::Write as _;

use heapless::{Deque, String, Vec};

use super::crtp::{CrtpPacket, MAX_DATA, Service};
use super::param_decl::{FLAG_EXTENDED, ParamEntry, ParamStore, ParamType, Refusal, toc_crc};
use super::toc::{Value, toc_item};
use crate::system::persistent_params::{PendingWrite, PersistentParams};

/// Parameter port.
pub const PORT_PARAM: u8 = 2;
/// TOC channel.
pub const CH_TOC: u8 = 0;
/// Read channel.
pub const CH_READ: u8 = 1;
/// Write channel.
pub const CH_WRITE: u8 = 2;
/// Misc channel.
pub const CH_MISC: u8 = 3;
/// TOC command: one item (v2).
pub const TOC_GET_ITEM_V2: u8 = 0x02;
/// TOC command: count and CRC (v2).
pub const TOC_GET_INFO_V2: u8 = 0x03;
/// Misc command: set by name.
pub const MISC_SET_BY_NAME: u8 = 0;
/// Misc command: value updated (downlink only).
pub const MISC_VALUE_UPDATED: u8 = 1;
/// Misc command: store the value in effect in the EEPROM.
pub const MISC_PERSISTENT_STORE: u8 = 3;
/// Misc command: whether a value is stored, with the default and the stored value.
pub const MISC_PERSISTENT_GET_STATE: u8 = 4;
/// Misc command: forget the stored value.
pub const MISC_PERSISTENT_CLEAR: u8 = 5;
/// Misc command: default value (v1: no status byte).
pub const MISC_GET_DEFAULT_VALUE: u8 = 6;
/// Misc command: extended type (v2).
pub const MISC_GET_EXTENDED_TYPE_V2: u8 = 7;
/// Misc command: default value (v2: with a status byte).
pub const MISC_GET_DEFAULT_VALUE_V2: u8 = 8;
/// `ENOENT`: no such parameter.
pub const ENOENT: u8 = 2;
/// `EACCES`: read-only.
pub const EACCES: u8 = 13;
/// `EINVAL`: wrong type or size, or a refused value.
pub const EINVAL: u8 = 22;
/// `EIO`: the EEPROM write failed.
pub const EIO: u8 = 5;
/// `EBUSY`: another EEPROM write is still under way.
pub const EBUSY: u8 = 16;
/// `ENOSPC`: every EEPROM record is taken.
pub const ENOSPC: u8 = 28;
/// GET_STATE status: no value stored.
pub const PERSISTENT_NOT_STORED: u8 = 0;
/// GET_STATE status: a value is stored.
pub const PERSISTENT_STORED: u8 = 1;

/// Pending VALUE_UPDATED ids.
const NOTIFY_DEPTH: usize = 8;
/// Pending refusals.
const REFUSAL_DEPTH: usize = 4;

/// A refused write, for the console.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RefusalNote {
    /// The parameter.
    pub id: u16,
    /// Why.
    pub refusal: Refusal,
}

/// The parameter service, owning its store.
#[derive(Debug, Clone)]
pub struct ParamService<S: ParamStore> {
    store: S,
    notify: Deque<u16, NOTIFY_DEPTH>,
    refusals: Deque<RefusalNote, REFUSAL_DEPTH>,
    dropped_refusals: u32,
    eeprom: Option<EepromJob>,
}

/// A persistent store or clear waiting for its EEPROM write.
#[derive(Debug, Clone)]
struct EepromJob {
    cmd: u8,
    id: u16,
    write: PendingWrite,
}

/// What [`ParamService::load_persistent`] did with the stored records.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LoadSummary {
    /// Values applied.
    pub applied: u16,
    /// Records of no parameter of this firmware, of another type, or not persistent: ignored.
    pub unknown: u16,
    /// Values the parameter's checks refused (out of today's bounds): ignored, each with a refusal note.
    pub refused: u16,
}

fn packet(channel: u8, data: &[u8]) -> Option<CrtpPacket> {
    CrtpPacket::new(PORT_PARAM, channel, data).ok()
}

fn split_cstr(bytes: &[u8]) -> Option<(&[u8], &[u8])> {
    let nul = bytes.iter().position(|&b| b == 0)?;
    Some((&bytes[..nul], &bytes[nul + 1..]))
}

impl<S: ParamStore> ParamService<S> {
    /// Number of parameters; the table must have at most 65 535 entries (checked at compile time on use).
    pub const COUNT: u16 = {
        assert!(S::TABLE.len() <= u16::MAX as usize, "too many parameters");
        S::TABLE.len() as u16
    };
    /// The TOC CRC ([`toc_crc`]), computed at compile time.
    pub const CRC: u32 = toc_crc(S::TABLE);

    /// A service over `store`.
    pub fn new(store: S) -> Self {
        Self {
            store,
            notify: Deque::new(),
            refusals: Deque::new(),
            dropped_refusals: 0,
            eeprom: None,
        }
    }

    /// The EEPROM write a `persistent_store` or `persistent_clear` waits for: write [`PendingWrite::pages`]
    /// in order, then call [`Self::eeprom_write_done`].
    pub fn eeprom_write(&self) -> Option<&PendingWrite> {
        self.eeprom.as_ref().map(|j| &j.write)
    }

    /// The caller finished (`ok`) or failed the write of [`Self::eeprom_write`]: the records are committed
    /// (if ok) and the reply to the waiting command is returned (hand it to the router); `None` if no write
    /// was waiting.
    pub fn eeprom_write_done(&mut self, ok: bool) -> Option<CrtpPacket> {
        let job = self.eeprom.take()?;
        let committed = ok && self.store.commit_persistent(job.write);
        let b = job.id.to_le_bytes();
        packet(CH_MISC, &[job.cmd, b[0], b[1], if committed { 0 } else { EIO }])
    }

    /// Boot: the records read from the EEPROM become the stored ones, and each value is applied through
    /// the same checks as a radio write; one of no parameter here, of another type, not persistent, or
    /// refused by the checks (a refusal note, for the console) is ignored. A value refused in the first
    /// pass is tried once more after the others, without a note the first time: one may be checked against
    /// another that comes later (`mission.arenaX` against the `arenaY` in effect). Call before any client
    /// connects.
    pub fn load_persistent(&mut self, stored: PersistentParams) -> LoadSummary {
        let mut summary = LoadSummary::default();
        let mut retry = [false; crate::system::persistent_params::MAX_RECORDS];
        for pass in 0..2 {
            for (k, record) in stored.records().enumerate() {
                if pass == 1 && !retry.get(k).copied().unwrap_or(false) {
                    continue;
                }
                let found = S::TABLE
                    .iter()
                    .enumerate()
                    .find(|(_, e)| crate::system::persistent_params::param_key(e.group, e.name) == record.key);
                let Some((i, e)) = found.filter(|(_, e)| e.is_persistent() && e.ty.param_code() == record.type_code)
                else {
                    summary.unknown += u16::from(pass == 0);
                    continue;
                };
                let Ok(id) = u16::try_from(i) else {
                    summary.unknown += u16::from(pass == 0);
                    continue;
                };
                let bytes = &record.value[..e.ty.size()];
                let first_try = pass == 0 && k < retry.len();
                let result = if first_try {
                    Value::from_le(e.ty, bytes).map(|v| e.check(v).and_then(|()| self.store.write(id, v)))
                } else {
                    self.apply(id, e.ty, bytes)
                };
                match result {
                    Some(Ok(())) => summary.applied += 1,
                    _ if first_try => retry[k] = true,
                    _ => summary.refused += 1,
                }
            }
        }
        self.store.set_persistent(stored);
        summary
    }

    /// The state.
    pub fn store(&self) -> &S {
        &self.store
    }

    /// The state, for the firmware (flags, and changes it then announces with [`notify`](Self::notify)).
    pub fn store_mut(&mut self) -> &mut S {
        &mut self.store
    }

    /// The entry of `id`.
    pub fn entry(id: u16) -> Option<&'static ParamEntry> {
        S::TABLE.get(usize::from(id))
    }

    /// The id of `group.name`.
    pub fn find(group: &str, name: &str) -> Option<u16> {
        let i = S::TABLE.iter().position(|e| e.group == group && e.name == name)?;
        u16::try_from(i).ok()
    }

    /// Queues a VALUE_UPDATED for `id` (the firmware changed it). An id already queued is not queued twice;
    /// false if `id` is unknown or the queue is full.
    pub fn notify(&mut self, id: u16) -> bool {
        if Self::entry(id).is_none() {
            return false;
        }
        self.notify.iter().any(|&q| q == id) || self.notify.push_back(id).is_ok()
    }

    /// The next VALUE_UPDATED packet `[1, id u16, value]` (port 2, ch 3), carrying the value at call time;
    /// hand it to [`super::crtp::Router::enqueue`].
    pub fn next_notification(&mut self) -> Option<CrtpPacket> {
        while let Some(id) = self.notify.pop_front() {
            if let Some(value) = self.store.read(id) {
                let mut data: Vec<u8, MAX_DATA> = Vec::new();
                data.push(MISC_VALUE_UPDATED).ok()?;
                data.extend_from_slice(&id.to_le_bytes()).ok()?;
                let (bytes, n) = value.to_le();
                data.extend_from_slice(&bytes[..n]).ok()?;
                return packet(CH_MISC, &data);
            }
        }
        None
    }

    /// The oldest refused write not yet taken.
    pub fn take_refusal(&mut self) -> Option<RefusalNote> {
        self.refusals.pop_front()
    }

    /// Refusals lost because 4 were already waiting.
    pub fn dropped_refusals(&self) -> u32 {
        self.dropped_refusals
    }

    /// The console line for a refusal: `param group.name refused: reason\n`; a value outside the declared
    /// range names the range, `param group.name refused: not in [0, 1]` (truncated to 64 bytes; every line
    /// of [`crate::radio_binding::param_table::PARAM_TABLE`] fits).
    pub fn console_line(note: &RefusalNote) -> String<64> {
        let mut out = String::new();
        let _ = match (Self::entry(note.id), note.refusal) {
            (Some(e), Refusal::OutOfRange) => {
                writeln!(
                    out,
                    "param {}.{} refused: not in {} {}",
                    e.group, e.name, e.range, e.unit
                )
            }
            (Some(e), r) => writeln!(out, "param {}.{} refused: {}", e.group, e.name, r.reason()),
            (None, r) => writeln!(out, "param {} refused: {}", note.id, r.reason()),
        };
        if note.refusal == Refusal::OutOfRange && out.ends_with(" \n") {
            // No unit: drop the space before the newline.
            out.truncate(out.len() - 2);
            let _ = out.push('\n');
        }
        out
    }

    fn refuse(&mut self, id: u16, refusal: Refusal) {
        if self.refusals.push_back(RefusalNote { id, refusal }).is_err() {
            self.dropped_refusals = self.dropped_refusals.saturating_add(1);
        }
    }

    fn toc(&self, data: &[u8]) -> Option<CrtpPacket> {
        match *data.first()? {
            TOC_GET_INFO_V2 => {
                let c = Self::COUNT.to_le_bytes();
                let k = Self::CRC.to_le_bytes();
                packet(CH_TOC, &[TOC_GET_INFO_V2, c[0], c[1], k[0], k[1], k[2], k[3]])
            }
            TOC_GET_ITEM_V2 => {
                let id = u16::from_le_bytes([*data.get(1)?, *data.get(2)?]);
                let Some(e) = Self::entry(id) else {
                    return packet(CH_TOC, &[TOC_GET_ITEM_V2]);
                };
                let mut out: Vec<u8, MAX_DATA> = Vec::new();
                toc_item(&mut out, TOC_GET_ITEM_V2, id, e.type_byte(), e.group, e.name)?;
                packet(CH_TOC, &out)
            }
            _ => None,
        }
    }

    /// `[id u16, status 0, value]` (or `[id u16, value]` without status, the write echo), or `[id u16, ENOENT]`.
    fn value_reply(&self, channel: u8, id: u16, with_status: bool) -> Option<CrtpPacket> {
        let mut out: Vec<u8, MAX_DATA> = Vec::new();
        out.extend_from_slice(&id.to_le_bytes()).ok()?;
        match self.store.read(id) {
            Some(value) if Self::entry(id).is_some() => {
                if with_status {
                    out.push(0).ok()?;
                }
                let (bytes, n) = value.to_le();
                out.extend_from_slice(&bytes[..n]).ok()?;
            }
            _ => out.push(ENOENT).ok()?,
        }
        packet(channel, &out)
    }

    fn read(&self, data: &[u8]) -> Option<CrtpPacket> {
        let id = u16::from_le_bytes([*data.first()?, *data.get(1)?]);
        self.value_reply(CH_READ, id, true)
    }

    /// Decodes a value of exactly the entry's size and type and applies it: the declaration's checks
    /// ([`ParamEntry::check`]) first, then the store's.
    fn apply(&mut self, id: u16, ty: ParamType, bytes: &[u8]) -> Option<Result<(), Refusal>> {
        let value = Value::from_le(ty, bytes)?;
        let entry = Self::entry(id)?;
        let result = entry.check(value).and_then(|()| self.store.write(id, value));
        match result {
            Err(refusal) => self.refuse(id, refusal),
            Ok(()) => {
                let aliases: Vec<u16, NOTIFY_DEPTH> = self.store.aliases(id).take(NOTIFY_DEPTH).collect();
                for alias in aliases {
                    self.notify(alias);
                }
            }
        }
        Some(result)
    }

    fn write(&mut self, data: &[u8]) -> Option<CrtpPacket> {
        let id = u16::from_le_bytes([*data.first()?, *data.get(1)?]);
        let Some(e) = Self::entry(id) else {
            let b = id.to_le_bytes();
            return packet(CH_WRITE, &[b[0], b[1], ENOENT]);
        };
        if e.read_only() {
            return None;
        }
        // Accepted or refused, the echo carries the value in effect (`docs/radio.md`).
        let _accepted_or_refused = self.apply(id, e.ty, &data[2..])?;
        self.value_reply(CH_WRITE, id, false)
    }

    fn set_by_name(&mut self, data: &[u8]) -> Option<CrtpPacket> {
        let (group, rest) = split_cstr(data.get(1..)?)?;
        let (name, rest) = split_cstr(rest)?;
        let (&ty, value) = rest.split_first()?;
        let err = match S::TABLE
            .iter()
            .position(|e| e.group.as_bytes() == group && e.name.as_bytes() == name)
        {
            None => ENOENT,
            Some(i) => {
                let e = &S::TABLE[i];
                let id = u16::try_from(i).ok()?;
                if ParamType::from_param_code(ty) != Some(e.ty) {
                    EINVAL
                } else if e.read_only() {
                    EACCES
                } else {
                    match self.apply(id, e.ty, value) {
                        Some(Ok(())) => 0,
                        _ => EINVAL,
                    }
                }
            }
        };
        let mut out: Vec<u8, MAX_DATA> = Vec::new();
        out.push(MISC_SET_BY_NAME).ok()?;
        out.extend_from_slice(group).ok()?;
        out.push(0).ok()?;
        out.extend_from_slice(name).ok()?;
        out.push(0).ok()?;
        out.push(err).ok()?;
        packet(CH_MISC, &out)
    }

    fn misc(&mut self, data: &[u8]) -> Option<CrtpPacket> {
        match *data.first()? {
            MISC_SET_BY_NAME => self.set_by_name(data),
            cmd @ (MISC_GET_DEFAULT_VALUE | MISC_GET_DEFAULT_VALUE_V2) => {
                let id = u16::from_le_bytes([*data.get(1)?, *data.get(2)?]);
                let b = id.to_le_bytes();
                let mut out: Vec<u8, MAX_DATA> = Vec::new();
                out.extend_from_slice(&[cmd, b[0], b[1]]).ok()?;
                let default = Self::entry(id)
                    .filter(|e| !e.read_only())
                    .and_then(|_| self.store.default_value(id));
                match default {
                    Some(value) => {
                        if cmd == MISC_GET_DEFAULT_VALUE_V2 {
                            out.push(0).ok()?;
                        }
                        let (bytes, n) = value.to_le();
                        out.extend_from_slice(&bytes[..n]).ok()?;
                    }
                    None => out.push(ENOENT).ok()?,
                }
                packet(CH_MISC, &out)
            }
            cmd @ (MISC_PERSISTENT_STORE | MISC_PERSISTENT_CLEAR) => {
                let id = u16::from_le_bytes([*data.get(1)?, *data.get(2)?]);
                let b = id.to_le_bytes();
                let status = if self.eeprom.is_some() {
                    EBUSY
                } else {
                    let prepared = if cmd == MISC_PERSISTENT_STORE {
                        self.store.prepare_persistent_store(id).map(Some)
                    } else {
                        self.store.prepare_persistent_clear(id)
                    };
                    match prepared {
                        Ok(Some(write)) => {
                            self.eeprom = Some(EepromJob { cmd, id, write });
                            return None;
                        }
                        Ok(None) => 0,
                        Err(Refusal::StoreFull) => {
                            self.refuse(id, Refusal::StoreFull);
                            ENOSPC
                        }
                        Err(Refusal::StoreWhileFlying) => {
                            self.refuse(id, Refusal::StoreWhileFlying);
                            EBUSY
                        }
                        Err(_) => ENOENT,
                    }
                };
                packet(CH_MISC, &[cmd, b[0], b[1], status])
            }
            MISC_PERSISTENT_GET_STATE => {
                let id = u16::from_le_bytes([*data.get(1)?, *data.get(2)?]);
                let b = id.to_le_bytes();
                let mut out: Vec<u8, MAX_DATA> = Vec::new();
                out.extend_from_slice(&[MISC_PERSISTENT_GET_STATE, b[0], b[1]]).ok()?;
                let default = Self::entry(id)
                    .filter(|e| !e.read_only())
                    .and_then(|_| self.store.default_value(id));
                match default {
                    None => out.push(ENOENT).ok()?,
                    Some(default) => {
                        let stored = self.store.stored_value(id);
                        out.push(if stored.is_some() {
                            PERSISTENT_STORED
                        } else {
                            PERSISTENT_NOT_STORED
                        })
                        .ok()?;
                        for v in core::iter::once(default).chain(stored) {
                            let (bytes, n) = v.to_le();
                            out.extend_from_slice(&bytes[..n]).ok()?;
                        }
                    }
                }
                packet(CH_MISC, &out)
            }
            MISC_GET_EXTENDED_TYPE_V2 => {
                let id = u16::from_le_bytes([*data.get(1)?, *data.get(2)?]);
                let b = id.to_le_bytes();
                match Self::entry(id) {
                    Some(e) => packet(
                        CH_MISC,
                        &[
                            MISC_GET_EXTENDED_TYPE_V2,
                            b[0],
                            b[1],
                            0,
                            u8::from(e.flags & FLAG_EXTENDED != 0),
                        ],
                    ),
                    None => packet(CH_MISC, &[MISC_GET_EXTENDED_TYPE_V2, b[0], b[1], ENOENT]),
                }
            }
            _ => None,
        }
    }
}

impl<S: ParamStore> Service for ParamService<S> {
    fn port(&self) -> u8 {
        PORT_PARAM
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        if packet.port != PORT_PARAM {
            return None;
        }
        match packet.channel {
            CH_TOC => self.toc(&packet.data),
            CH_READ => self.read(&packet.data),
            CH_WRITE => self.write(&packet.data),
            CH_MISC => self.misc(&packet.data),
            _ => None,
        }
    }
}
