//! A declarative, fixed-size parameter registry: a `const` table of entries and a store that reads and writes
//! values by id, plus the `mission.*` parameters of interfaces.md §5 over [`MissionParamState`].
//!
//! Job: describe every parameter once (group, name, wire type, flags), check at compile time that each TOC item
//! fits one CRTP packet, give the TOC its CRC, and validate radio writes (refusals keep the old value and give a
//! short reason for the console).
//!
//! Non-goals: no wire protocol (that is [`super::param`]), no persistence, no 64-bit or FP16 types.
//!
//! Sources: `crazyflie-hardware.md` §4.5 (type byte: bits 1..0 size, bit 2 float, bit 3 unsigned, 0x10
//! EXTENDED, 0x40 READ-ONLY; `strlen(group) + strlen(name) + 2 ≤ 26`; CRC-32 reflected 0xEDB88320,
//! init/xorout 0xFFFFFFFF); `crtp-over-udp.md` §2 (the CRC is only a cache key shared with the log TOC: it must
//! change with the TOC and differ from the log TOC's); `interfaces.md` §5 (the parameters and the refusal rule).
//!
//! Design choices: the TOC CRC is CRC-32 over [`PARAM_CRC_SEED`] followed by, for every entry in id order, the
//! type byte, the group, a NUL, the name and a NUL (not stock's chaining; any value that changes with the TOC
//! works, §4.5). The seed keeps it distinct from the log TOC's CRC for the same names. `mission.start` accepts 0
//! and 1 only; goal and start positions use the same 0.1 m wall margin as [`MissionParams::validate`]; speed
//! must be in (0, 1] m/s and height in [0.2, 2] m, as there.
//!
//! Memory: the table is `'static`; [`MissionParamState`] is a few dozen bytes.

use crate::mission::{MAX_HEIGHT_M, MAX_SPEED_M_S, MIN_HEIGHT_M, MissionParams, StartRefusal};

use super::crtp::MAX_DATA;

/// Type byte flag: the entry has an extended type (cflib then asks misc command 7), §4.5.
pub const FLAG_EXTENDED: u8 = 0x10;
/// Type byte flag: read-only, §4.5.
pub const FLAG_READ_ONLY: u8 = 0x40;
/// Bytes before `group\0name\0` in a TOC item reply: command, id u16, type (§4.5).
pub const TOC_ITEM_HEADER: usize = 4;
/// Bytes the parameter CRC starts with, so that it differs from a log TOC CRC over the same entries.
pub const PARAM_CRC_SEED: &[u8] = b"cfnav/param-toc/v1";

/// A parameter's value type with its wire type code (§4.5, low nibble).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamType {
    /// `uint8_t`, code 0x08.
    U8,
    /// `uint16_t`, code 0x09.
    U16,
    /// `uint32_t`, code 0x0A.
    U32,
    /// `int8_t`, code 0x00.
    I8,
    /// `int16_t`, code 0x01.
    I16,
    /// `int32_t`, code 0x02.
    I32,
    /// `float`, code 0x06.
    F32,
}

impl ParamType {
    /// The wire type code (low nibble of the type byte).
    pub const fn code(self) -> u8 {
        match self {
            Self::U8 => 0x08,
            Self::U16 => 0x09,
            Self::U32 => 0x0A,
            Self::I8 => 0x00,
            Self::I16 => 0x01,
            Self::I32 => 0x02,
            Self::F32 => 0x06,
        }
    }

    /// The type for a wire code (flags in the high nibble ignored); `None` for types this registry lacks.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code & 0x0F {
            0x08 => Some(Self::U8),
            0x09 => Some(Self::U16),
            0x0A => Some(Self::U32),
            0x00 => Some(Self::I8),
            0x01 => Some(Self::I16),
            0x02 => Some(Self::I32),
            0x06 => Some(Self::F32),
            _ => None,
        }
    }

    /// Size of a value on the wire, bytes.
    pub const fn size(self) -> usize {
        match self {
            Self::U8 | Self::I8 => 1,
            Self::U16 | Self::I16 => 2,
            Self::U32 | Self::I32 | Self::F32 => 4,
        }
    }
}

/// A parameter value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    /// uint8.
    U8(u8),
    /// uint16.
    U16(u16),
    /// uint32.
    U32(u32),
    /// int8.
    I8(i8),
    /// int16.
    I16(i16),
    /// int32.
    I32(i32),
    /// float.
    F32(f32),
}

impl Value {
    /// The value's type.
    pub const fn ty(self) -> ParamType {
        match self {
            Self::U8(_) => ParamType::U8,
            Self::U16(_) => ParamType::U16,
            Self::U32(_) => ParamType::U32,
            Self::I8(_) => ParamType::I8,
            Self::I16(_) => ParamType::I16,
            Self::I32(_) => ParamType::I32,
            Self::F32(_) => ParamType::F32,
        }
    }

    /// Little-endian bytes: the first [`ParamType::size`] bytes of the array are used.
    pub fn to_le(self) -> ([u8; 4], usize) {
        let mut out = [0u8; 4];
        let n = self.ty().size();
        match self {
            Self::U8(v) => out[0] = v,
            Self::I8(v) => out[0] = v.to_le_bytes()[0],
            Self::U16(v) => out[..2].copy_from_slice(&v.to_le_bytes()),
            Self::I16(v) => out[..2].copy_from_slice(&v.to_le_bytes()),
            Self::U32(v) => out = v.to_le_bytes(),
            Self::I32(v) => out = v.to_le_bytes(),
            Self::F32(v) => out = v.to_le_bytes(),
        }
        (out, n)
    }

    /// Decodes exactly `ty.size()` little-endian bytes; `None` for any other length.
    pub fn from_le(ty: ParamType, bytes: &[u8]) -> Option<Self> {
        Some(match ty {
            ParamType::U8 => Self::U8(u8::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::I8 => Self::I8(i8::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::U16 => Self::U16(u16::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::I16 => Self::I16(i16::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::U32 => Self::U32(u32::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::I32 => Self::I32(i32::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::F32 => Self::F32(f32::from_le_bytes(bytes.try_into().ok()?)),
        })
    }
}

/// One table entry. Build it with [`ParamEntry::new`] in a `const` so the checks run at compile time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamEntry {
    /// Group name (ASCII, no NUL).
    pub group: &'static str,
    /// Parameter name (ASCII, no NUL).
    pub name: &'static str,
    /// Value type.
    pub ty: ParamType,
    /// [`FLAG_READ_ONLY`] and/or [`FLAG_EXTENDED`].
    pub flags: u8,
}

/// Whether a TOC group or name is usable: non-empty ASCII without NUL (shared with the log table).
pub const fn valid_name(s: &str) -> bool {
    let b = s.as_bytes();
    if b.is_empty() {
        return false;
    }
    let mut i = 0;
    while i < b.len() {
        if b[i] == 0 || b[i] >= 0x80 {
            return false;
        }
        i += 1;
    }
    true
}

impl ParamEntry {
    /// An entry; panics (a compile error in a `const`) if the TOC item `[2, id u16, type, group\0, name\0]`
    /// would not fit 30 bytes, a name is empty, holds a NUL or non-ASCII byte, or `flags` has other bits.
    pub const fn new(group: &'static str, name: &'static str, ty: ParamType, flags: u8) -> Self {
        assert!(
            group.len() + name.len() + 2 + TOC_ITEM_HEADER <= MAX_DATA,
            "param group + name too long for a TOC item"
        );
        assert!(
            valid_name(group) && valid_name(name),
            "param group and name must be non-empty ASCII without NUL"
        );
        assert!(flags & !(FLAG_READ_ONLY | FLAG_EXTENDED) == 0, "unknown param flag");
        Self { group, name, ty, flags }
    }

    /// The wire type byte: type code | flags.
    pub const fn type_byte(&self) -> u8 {
        self.ty.code() | self.flags
    }

    /// True if radio writes are not allowed.
    pub const fn read_only(&self) -> bool {
        self.flags & FLAG_READ_ONLY != 0
    }
}

/// Feeds `bytes` into a running CRC-32 register (reflected poly 0xEDB88320). Start with `0xFFFF_FFFF` and
/// XOR the result with `0xFFFF_FFFF` at the end (§4.5, check value of "123456789" is 0xCBF43926).
pub const fn crc32_update(mut crc: u32, bytes: &[u8]) -> u32 {
    let mut i = 0;
    while i < bytes.len() {
        crc ^= bytes[i] as u32;
        let mut k = 0;
        while k < 8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
            k += 1;
        }
        i += 1;
    }
    crc
}

/// CRC-32 of `bytes` (init and xorout 0xFFFFFFFF).
pub const fn crc32(bytes: &[u8]) -> u32 {
    crc32_update(0xFFFF_FFFF, bytes) ^ 0xFFFF_FFFF
}

/// Feeds one TOC entry, `type, group, 0, name, 0`, into a running CRC-32 (the param and log TOC CRCs both
/// hash their entries this way, each after its own seed).
pub const fn crc32_toc_entry(crc: u32, type_byte: u8, group: &str, name: &str) -> u32 {
    let crc = crc32_update(crc, &[type_byte]);
    let crc = crc32_update(crc, group.as_bytes());
    let crc = crc32_update(crc, &[0]);
    let crc = crc32_update(crc, name.as_bytes());
    crc32_update(crc, &[0])
}

/// The parameter TOC CRC: CRC-32 over [`PARAM_CRC_SEED`], then per entry `type, group, 0, name, 0`.
pub const fn toc_crc(table: &[ParamEntry]) -> u32 {
    let mut crc = crc32_update(0xFFFF_FFFF, PARAM_CRC_SEED);
    let mut i = 0;
    while i < table.len() {
        let e = &table[i];
        crc = crc32_toc_entry(crc, e.type_byte(), e.group, e.name);
        i += 1;
    }
    crc ^ 0xFFFF_FFFF
}

/// Why a parameter write was refused. The value in effect is unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// No parameter has this id.
    UnknownId,
    /// The value's type is not the parameter's.
    WrongType,
    /// The parameter is read-only.
    ReadOnly,
    /// The goal lies outside the arena (or within 0.1 m of a wall), or is not finite.
    GoalOutsideArena,
    /// The start position lies outside the arena (or within 0.1 m of a wall), or is not finite.
    StartOutsideArena,
    /// Height below 0.2 m, above 2 m or not finite.
    BadHeight,
    /// Speed not in (0, 1] m/s.
    BadSpeed,
    /// `mission.start` only takes 0 or 1.
    BadStartValue,
    /// A start while flying.
    StartWhileFlying,
    /// A start with a deck missing.
    DeckMissing,
    /// A start while a mission runs.
    AlreadyRunning,
    /// A start with an arena the map cannot hold.
    BadArena,
}

impl Refusal {
    /// A short reason for the console.
    pub const fn reason(self) -> &'static str {
        match self {
            Self::UnknownId => "no such parameter",
            Self::WrongType => "wrong type",
            Self::ReadOnly => "read-only",
            Self::GoalOutsideArena => "goal outside the arena",
            Self::StartOutsideArena => "start outside the arena",
            Self::BadHeight => "height not in 0.2..2 m",
            Self::BadSpeed => "speed not in (0, 1] m/s",
            Self::BadStartValue => "start takes 0 or 1",
            Self::StartWhileFlying => "start while flying",
            Self::DeckMissing => "a deck is missing",
            Self::AlreadyRunning => "mission already running",
            Self::BadArena => "arena too large for the map",
        }
    }
}

/// A state struct the parameter service reads and writes by id (ids are indices into [`Self::TABLE`]).
pub trait ParamStore {
    /// The table, in id order.
    const TABLE: &'static [ParamEntry];
    /// The value in effect of parameter `id`; `None` if there is no such id.
    fn read(&self, id: u16) -> Option<Value>;
    /// A radio write: validates and applies `value`, or refuses and leaves the state unchanged.
    fn write(&mut self, id: u16, value: Value) -> Result<(), Refusal>;
}

/// Id of `mission.start` (uint8).
pub const ID_START: u16 = 0;
/// Id of `mission.goalX` (float).
pub const ID_GOAL_X: u16 = 1;
/// Id of `mission.goalY` (float).
pub const ID_GOAL_Y: u16 = 2;
/// Id of `mission.startX` (float).
pub const ID_START_X: u16 = 3;
/// Id of `mission.startY` (float).
pub const ID_START_Y: u16 = 4;
/// Id of `mission.height` (float).
pub const ID_HEIGHT: u16 = 5;
/// Id of `mission.speed` (float).
pub const ID_SPEED: u16 = 6;

/// The `mission.*` parameters (interfaces.md §5), in id order.
pub const MISSION_TABLE: &[ParamEntry] = &[
    ParamEntry::new("mission", "start", ParamType::U8, 0),
    ParamEntry::new("mission", "goalX", ParamType::F32, 0),
    ParamEntry::new("mission", "goalY", ParamType::F32, 0),
    ParamEntry::new("mission", "startX", ParamType::F32, 0),
    ParamEntry::new("mission", "startY", ParamType::F32, 0),
    ParamEntry::new("mission", "height", ParamType::F32, 0),
    ParamEntry::new("mission", "speed", ParamType::F32, 0),
];

/// The mission parameters' values in effect plus what validation needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionParamState {
    /// `mission.start`: 1 while a mission runs (set by the radio), back to 0 when it ends (set by the firmware,
    /// which then queues a VALUE_UPDATED).
    pub start: u8,
    /// Positions, height, speed and the arena size (not a parameter).
    pub params: MissionParams,
    /// The drone is flying: a start is refused.
    pub flying: bool,
    /// Every deck the mission needs is present: a start is refused otherwise.
    pub decks_ok: bool,
    /// Map capacity, cells, for [`MissionParams::validate`] at start.
    pub capacity_cells: usize,
}

impl MissionParamState {
    /// Idle state with `params`, on the ground, decks present.
    pub const fn new(params: MissionParams, capacity_cells: usize) -> Self {
        Self {
            start: 0,
            params,
            flying: false,
            decks_ok: true,
            capacity_cells,
        }
    }

    fn inside(&self, p: (f32, f32)) -> bool {
        let a = self.params.arena_m;
        p.0.is_finite() && p.1.is_finite() && p.0 > 0.1 && p.1 > 0.1 && p.0 < a.0 - 0.1 && p.1 < a.1 - 0.1
    }

    fn write_start(&mut self, v: u8) -> Result<(), Refusal> {
        match v {
            0 => {
                self.start = 0;
                Ok(())
            }
            1 => {
                if self.flying {
                    return Err(Refusal::StartWhileFlying);
                }
                if !self.decks_ok {
                    return Err(Refusal::DeckMissing);
                }
                if self.start != 0 {
                    return Err(Refusal::AlreadyRunning);
                }
                self.params.validate(self.capacity_cells).map_err(|e| match e {
                    StartRefusal::AlreadyRunning => Refusal::AlreadyRunning,
                    StartRefusal::BadArena => Refusal::BadArena,
                    StartRefusal::OutsideArena if !self.inside(self.params.goal_m) => Refusal::GoalOutsideArena,
                    StartRefusal::OutsideArena => Refusal::StartOutsideArena,
                    StartRefusal::BadHeight => Refusal::BadHeight,
                    StartRefusal::BadSpeed => Refusal::BadSpeed,
                })?;
                self.start = 1;
                Ok(())
            }
            _ => Err(Refusal::BadStartValue),
        }
    }

    fn write_f32(&mut self, id: u16, v: f32) -> Result<(), Refusal> {
        let p = &self.params;
        match id {
            ID_GOAL_X | ID_GOAL_Y => {
                let goal = if id == ID_GOAL_X {
                    (v, p.goal_m.1)
                } else {
                    (p.goal_m.0, v)
                };
                if !self.inside(goal) {
                    return Err(Refusal::GoalOutsideArena);
                }
                self.params.goal_m = goal;
            }
            ID_START_X | ID_START_Y => {
                let start = if id == ID_START_X {
                    (v, p.start_m.1)
                } else {
                    (p.start_m.0, v)
                };
                if !self.inside(start) {
                    return Err(Refusal::StartOutsideArena);
                }
                self.params.start_m = start;
            }
            ID_HEIGHT => {
                if !(MIN_HEIGHT_M..=MAX_HEIGHT_M).contains(&v) {
                    return Err(Refusal::BadHeight);
                }
                self.params.height_m = v;
            }
            ID_SPEED => {
                if !(v > 0.0 && v <= MAX_SPEED_M_S) {
                    return Err(Refusal::BadSpeed);
                }
                self.params.speed_m_s = v;
            }
            ID_START => return Err(Refusal::WrongType),
            _ => return Err(Refusal::UnknownId),
        }
        Ok(())
    }
}

impl ParamStore for MissionParamState {
    const TABLE: &'static [ParamEntry] = MISSION_TABLE;

    fn read(&self, id: u16) -> Option<Value> {
        let p = &self.params;
        Some(match id {
            ID_START => Value::U8(self.start),
            ID_GOAL_X => Value::F32(p.goal_m.0),
            ID_GOAL_Y => Value::F32(p.goal_m.1),
            ID_START_X => Value::F32(p.start_m.0),
            ID_START_Y => Value::F32(p.start_m.1),
            ID_HEIGHT => Value::F32(p.height_m),
            ID_SPEED => Value::F32(p.speed_m_s),
            _ => return None,
        })
    }

    fn write(&mut self, id: u16, value: Value) -> Result<(), Refusal> {
        match (id, value) {
            (ID_START, Value::U8(v)) => self.write_start(v),
            (ID_START, _) => Err(Refusal::WrongType),
            (_, Value::F32(v)) => self.write_f32(id, v),
            (ID_GOAL_X..=ID_SPEED, _) => Err(Refusal::WrongType),
            _ => Err(Refusal::UnknownId),
        }
    }
}
