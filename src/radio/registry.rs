//! The parameter declarations: one `const` line per parameter (group, name, type, flags, range, unit, doc)
//! in [`PARAM_TABLE`], a store that reads and writes values by id ([`MissionParamState`]), and the shared TOC
//! machinery (values, CRC, name checks) the log table uses too.
//!
//! Job: describe every parameter once. The TOC (type byte, names, CRC), the generic write checks (unknown id,
//! read-only, type, range: [`ParamEntry::check`]), the console line of a refusal and the README's parameter
//! table ([`write_param_table`]) all derive from the declaration; the store adds only what a declaration
//! cannot say (a goal inside the arena, an arena the map holds, the start rules). Ids are the table's indices, and the `ID_*`
//! constants are looked up in the table at compile time ([`param_id`]), so they cannot drift from it.
//!
//! Non-goals: no wire protocol (that is [`super::param`]), no EEPROM layout (that is
//! [`crate::system::persistent_params`]; the store here only keeps the records and prepares writes), no
//! 64-bit or FP16 types.
//!
//! Tuning parameters (issue 13 part 4): the block so marked in [`PARAM_TABLE`], each persistent, each
//! mapped to one field of [`Tuning`] by [`tune_field`]; a write is checked against its declaration, then
//! the whole tuning against itself ([`Tuning::consistent`]: the controller's validation, the avoidance's,
//! narrow inflation ≤ inflation, low landing speed ≤ high), and bumps [`MissionParamState::tuning_generation`]
//! so the endpoint hands it to the flight stack. `posCtlPid.x*`/`y*` and `velCtlPid.vx*`/`vy*` name one
//! horizontal gain each (cfnav's loops are symmetric): [`ParamStore::aliases`] finds the other name.
//! Persistent records are keyed by `group.name` ([`param_key`]), so they survive a table with other ids;
//! `persistent_store`/`persistent_clear` are refused while flying (the EEPROM write holds the deck bus).
//!
//! Sources: `crazyflie-hardware.md` §4.5 (type byte: bits 1..0 size, bit 2 float, bit 3 unsigned, 0x10
//! EXTENDED, 0x40 READ-ONLY; `strlen(group) + strlen(name) + 2 ≤ 26`; CRC-32 reflected 0xEDB88320,
//! init/xorout 0xFFFFFFFF); `crtp-over-udp.md` §2 (the CRC is only a cache key shared with the log TOC: it must
//! change with the TOC and differ from the log TOC's); `interfaces.md` §5 (the `mission.*` parameters and the
//! refusal rule). Stock names, types and semantics of the other groups from `bitcraze/crazyflie-firmware`
//! (`PARAM_ADD` lines): `deck.bc*` uint8 read-only, 1 when the deck was detected (`flowdeck_v1v2.c`,
//! `multiranger.c`, `zranger*.c`, `lighthouse.c`, `locodeck.c`, `ledring12.c`, `color_led_deck.c`);
//! `kalman.resetEstimation` uint8 (`estimator_kalman.c`); `stabilizer.controller` uint8, 0 auto-select, 1 PID,
//! 2 Mellinger, 3 INDI, 4 Brescianini, 5 Lee (`stabilizer.c`, `controller.h`); `commander.enHighLevel` uint8
//! (`commander.c`); `firmware.revision0` uint32, `revision1` uint16, `modified` uint8, all read-only
//! (`version.tmpl`, values from git as `tools/make/versionTemplate.py` cuts them). The deck names are every `deck.*` name the stock cfclient 2026.8.1 reads (Flight, LED-ring,
//! Color LED, Lighthouse and Loco tabs): a name it misses stalls its parameter callback.
//!
//! Design choices: the TOC CRC is CRC-32 over [`PARAM_CRC_SEED`] followed by, for every entry in id order, the
//! type byte, the group, a NUL, the name and a NUL (not stock's chaining; any value that changes with the TOC
//! works, §4.5). The seed keeps it distinct from the log TOC's CRC for the same names. The `mission.*` ids 0–6
//! are those of interfaces.md §5 and stay first; new parameters are appended. `stabilizer.controller` accepts
//! 0 and 1 only (cfnav flies one cascaded PID controller: both mean it); `kalman.resetEstimation = 1` asks
//! the endpoint to re-anchor the estimator's horizontal position at `mission.startX/startY` (refused while
//! flying), and the endpoint writes it back to 0 when done, as stock clears it.
//!
//! Memory: the table is `'static`; [`MissionParamState`] is about 2 KB (two [`Tuning`]s, the values in
//! effect and the power-on defaults, and the stored records' 640-byte slot image).

use crate::flight::control::ControllerConfig;
use crate::flight::estimator::EstimatorConfig;
use crate::mission::link_loss::{LinkLossConfig, LinkLossPolicy, MAX_LINK_TIMEOUT_S, MIN_LINK_TIMEOUT_S};
use crate::mission::{
    COVERAGE_RANGE, HOVER_TIME_RANGE_S, MAX_HEIGHT_M, MAX_SPEED_M_S, MIN_HEIGHT_M, MissionConfig, MissionMode,
    MissionParams, StartRefusal,
};
use crate::nav::avoidance::{AvoidanceMethod, SpeedClamp};
use crate::nav::map::GridShape;
use crate::system::persistent_params::{PendingWrite, PersistentParams, param_key};
use crate::system::version;

use super::crtp::MAX_DATA;
pub use super::wire_type::WireType;

/// Type byte flag: the entry has an extended type (cflib then asks misc command 7), §4.5.
pub const FLAG_EXTENDED: u8 = 0x10;
/// Type byte flag: read-only, §4.5.
pub const FLAG_READ_ONLY: u8 = 0x40;
/// Bytes before `group\0name\0` in a TOC item reply: command, id u16, type (§4.5).
pub const TOC_ITEM_HEADER: usize = 4;
/// Bytes the parameter CRC starts with, so that it differs from a log TOC CRC over the same entries.
pub const PARAM_CRC_SEED: &[u8] = b"cfnav/param-toc/v1";

/// A parameter's value type: the shared [`WireType`] (param code [`WireType::param_code`], §4.5); never
/// [`WireType::Fp16`] ([`ParamEntry::new`] refuses it).
pub type ParamType = WireType;

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

    /// The value as an `f64` (exact for every type here).
    pub fn as_f64(self) -> f64 {
        match self {
            Self::U8(v) => f64::from(v),
            Self::U16(v) => f64::from(v),
            Self::U32(v) => f64::from(v),
            Self::I8(v) => f64::from(v),
            Self::I16(v) => f64::from(v),
            Self::I32(v) => f64::from(v),
            Self::F32(v) => f64::from(v),
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

    /// Decodes exactly `ty.size()` little-endian bytes; `None` for any other length and for FP16 (no value is
    /// stored as one).
    pub fn from_le(ty: ParamType, bytes: &[u8]) -> Option<Self> {
        Some(match ty {
            ParamType::U8 => Self::U8(u8::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::I8 => Self::I8(i8::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::U16 => Self::U16(u16::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::I16 => Self::I16(i16::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::U32 => Self::U32(u32::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::I32 => Self::I32(i32::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::F32 => Self::F32(f32::from_le_bytes(bytes.try_into().ok()?)),
            ParamType::Fp16 => return None,
        })
    }
}

/// The values a parameter accepts, as declared (checked on every radio write; shown in the README table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Range {
    /// Any value of the type (a store may still refuse it for a reason the declaration cannot state).
    Any,
    /// `min ≤ v ≤ max` (NaN is outside).
    Closed(f32, f32),
    /// `min < v ≤ max` (NaN is outside).
    LeftOpen(f32, f32),
}

impl Range {
    /// Whether `value` lies in the range (integers compared exactly as `f64`).
    pub fn contains(self, value: Value) -> bool {
        let v = value.as_f64();
        match self {
            Self::Any => true,
            Self::Closed(lo, hi) => v >= f64::from(lo) && v <= f64::from(hi),
            Self::LeftOpen(lo, hi) => v > f64::from(lo) && v <= f64::from(hi),
        }
    }
}

impl core::fmt::Display for Range {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Any => f.write_str("any"),
            Self::Closed(lo, hi) => write!(f, "[{lo}, {hi}]"),
            Self::LeftOpen(lo, hi) => write!(f, "({lo}, {hi}]"),
        }
    }
}

/// One parameter's declaration. Build it with [`ParamEntry::new`] (bare TOC entry) or
/// [`ParamEntry::declare`] in a `const` so the checks run at compile time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamEntry {
    /// Group name (ASCII, no NUL).
    pub group: &'static str,
    /// Parameter name (ASCII, no NUL).
    pub name: &'static str,
    /// Value type.
    pub ty: ParamType,
    /// [`FLAG_READ_ONLY`] and/or [`FLAG_EXTENDED`].
    pub flags: u8,
    /// The values a write may carry.
    pub range: Range,
    /// What a write outside [`Self::range`] is refused as.
    pub out_of_range: Refusal,
    /// Unit of the value (`""` for none).
    pub unit: &'static str,
    /// One sentence for the README table.
    pub doc: &'static str,
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

/// Panics (a compile error in a `const`) unless `group.name` fits a TOC item of `header` bytes in one CRTP
/// packet and both are valid names (shared by the param and log tables).
pub const fn assert_toc_name(group: &str, name: &str, header: usize) {
    assert!(
        group.len() + name.len() + 2 + header <= MAX_DATA,
        "group + name too long for a TOC item"
    );
    assert!(
        valid_name(group) && valid_name(name),
        "group and name must be non-empty ASCII without NUL"
    );
}

/// Appends the TOC item `[cmd, id u16, type, group\0, name\0]` (param and log TOCs share this layout).
pub fn toc_item(
    out: &mut heapless::Vec<u8, MAX_DATA>,
    cmd: u8,
    id: u16,
    type_byte: u8,
    group: &str,
    name: &str,
) -> Option<()> {
    out.push(cmd).ok()?;
    out.extend_from_slice(&id.to_le_bytes()).ok()?;
    out.push(type_byte).ok()?;
    out.extend_from_slice(group.as_bytes()).ok()?;
    out.push(0).ok()?;
    out.extend_from_slice(name.as_bytes()).ok()?;
    out.push(0).ok()
}

/// Id of `group.name` in `table`, at compile time; panics (a compile error in a `const`) if it is missing.
pub const fn param_id(table: &[ParamEntry], group: &str, name: &str) -> u16 {
    let mut i = 0;
    while i < table.len() {
        if str_eq(table[i].group, group) && str_eq(table[i].name, name) {
            return i as u16;
        }
        i += 1;
    }
    panic!("no such parameter")
}

/// `a == b` in a `const`.
pub const fn str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

impl ParamEntry {
    /// A bare entry (any value, no unit or doc); panics (a compile error in a `const`) if the TOC item
    /// `[2, id u16, type, group\0, name\0]` would not fit 30 bytes, a name is empty, holds a NUL or non-ASCII
    /// byte, or `flags` has other bits.
    pub const fn new(group: &'static str, name: &'static str, ty: ParamType, flags: u8) -> Self {
        assert_toc_name(group, name, TOC_ITEM_HEADER);
        assert!(flags & !(FLAG_READ_ONLY | FLAG_EXTENDED) == 0, "unknown param flag");
        assert!(!matches!(ty, ParamType::Fp16), "FP16 is not a parameter type");
        Self {
            group,
            name,
            ty,
            flags,
            range: Range::Any,
            out_of_range: Refusal::OutOfRange,
            unit: "",
            doc: "",
        }
    }

    /// The one-line declaration: [`Self::new`]'s checks, plus the accepted range, the unit and the doc.
    pub const fn declare(
        group: &'static str,
        name: &'static str,
        ty: ParamType,
        flags: u8,
        range: Range,
        unit: &'static str,
        doc: &'static str,
    ) -> Self {
        let mut e = Self::new(group, name, ty, flags);
        e.range = range;
        e.unit = unit;
        e.doc = doc;
        e
    }

    /// The same declaration, with a write outside the range refused as `refusal` (for a clearer console line).
    pub const fn refused_as(mut self, refusal: Refusal) -> Self {
        self.out_of_range = refusal;
        self
    }

    /// The same declaration, marked persistent (extended type 1: cflib's `persistent_store` and friends
    /// accept it).
    pub const fn persistent(mut self) -> Self {
        self.flags |= FLAG_EXTENDED;
        self
    }

    /// True if the value can be stored in the EEPROM (`persistent_store`).
    pub const fn is_persistent(&self) -> bool {
        self.flags & FLAG_EXTENDED != 0
    }

    /// The wire type byte: type code | flags.
    pub const fn type_byte(&self) -> u8 {
        self.ty.param_code() | self.flags
    }

    /// True if radio writes are not allowed.
    pub const fn read_only(&self) -> bool {
        self.flags & FLAG_READ_ONLY != 0
    }

    /// The checks every write goes through, from the declaration alone: writable, the declared type, in range.
    pub fn check(&self, value: Value) -> Result<(), Refusal> {
        if self.read_only() {
            return Err(Refusal::ReadOnly);
        }
        if value.ty() != self.ty {
            return Err(Refusal::WrongType);
        }
        if !self.range.contains(value) {
            return Err(self.out_of_range);
        }
        Ok(())
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
    /// A start with an arena the map cannot hold, or an `arenaX`/`arenaY` write that would make one (not
    /// finite and positive, or more cells than the map has with the other side in effect).
    BadArena,
    /// Outside the range its declaration gives (the console line names the range).
    OutOfRange,
    /// `stabilizer.controller` other than 0 (auto) or 1 (PID): cfnav has one controller.
    UnsupportedController,
    /// `kalman.resetEstimation = 1` while flying or while a mission runs.
    ResetWhileFlying,
    /// A tuning value in range that conflicts with a related one (e.g. `avoid.slowDist < avoid.dangerDist`).
    Inconsistent,
    /// `persistent_store` of a new parameter with every EEPROM record taken.
    StoreFull,
    /// A persistent command for a parameter that is not persistent.
    NotPersistent,
    /// `persistent_store`/`persistent_clear` while flying: the EEPROM shares the deck bus with the height
    /// ranger, and a write holds the bus for ~100 ms.
    StoreWhileFlying,
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
            Self::OutOfRange => "out of range",
            Self::UnsupportedController => "only 0 (auto) or 1 (PID)",
            Self::ResetWhileFlying => "reset while flying",
            Self::Inconsistent => "inconsistent with others",
            Self::StoreFull => "persistent store full",
            Self::NotPersistent => "not persistent",
            Self::StoreWhileFlying => "not while flying",
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
    /// The value parameter `id` had at power-on (what cfclient shows as the default); `None` if unknown.
    fn default_value(&self, id: u16) -> Option<Value> {
        let _ = id;
        None
    }
    /// The value stored in the EEPROM for persistent parameter `id` (`persistent_get_state`).
    fn stored_value(&self, id: u16) -> Option<Value> {
        let _ = id;
        None
    }
    /// The EEPROM write that stores the value in effect of persistent parameter `id`
    /// (`persistent_store`); the caller writes it and hands it to [`Self::commit_persistent`].
    fn prepare_persistent_store(&self, id: u16) -> Result<PendingWrite, Refusal> {
        let _ = id;
        Err(Refusal::NotPersistent)
    }
    /// The EEPROM write that forgets the stored value of `id` (`persistent_clear`); `Ok(None)` when none is
    /// stored (nothing to write).
    fn prepare_persistent_clear(&self, id: u16) -> Result<Option<PendingWrite>, Refusal> {
        let _ = id;
        Err(Refusal::NotPersistent)
    }
    /// A prepared write is in the EEPROM: its records are the stored ones now. False if it was stale.
    fn commit_persistent(&mut self, write: PendingWrite) -> bool {
        let _ = write;
        false
    }
    /// The records read from the EEPROM at boot become the stored ones (not yet applied: see
    /// [`super::param::ParamService::load_persistent`]).
    fn set_persistent(&mut self, stored: PersistentParams) {
        let _ = stored;
    }
    /// Ids that show the same value as `id` (one gain behind two stock names): notified after a write.
    fn aliases(&self, id: u16) -> impl Iterator<Item = u16> {
        let _ = id;
        core::iter::empty()
    }
}

/// Read-only flag, shortened for the declarations below.
const RO: u8 = FLAG_READ_ONLY;
/// A 0/1 switch.
const SWITCH: Range = Range::Closed(0.0, 1.0);

/// Every parameter cfnav serves, in id order: one declaration each (see the module docs). The `mission.*`
/// ids 0–6 are interfaces.md §5's.
pub const PARAM_TABLE: &[ParamEntry] = &[
    ParamEntry::declare(
        "mission",
        "start",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "write 1 to start the mission from idle; 0 during a mission aborts it (land where it is)",
    )
    .refused_as(Refusal::BadStartValue),
    ParamEntry::declare(
        "mission",
        "goalX",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "nominal goal x, arena frame; must lie inside the arena, 0.1 m from the walls",
    ),
    ParamEntry::declare(
        "mission",
        "goalY",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "nominal goal y, arena frame; must lie inside the arena, 0.1 m from the walls",
    ),
    ParamEntry::declare(
        "mission",
        "startX",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "where the drone stands at power-on, x, arena frame; inside the arena",
    ),
    ParamEntry::declare(
        "mission",
        "startY",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "where the drone stands at power-on, y, arena frame; inside the arena",
    ),
    ParamEntry::declare(
        "mission",
        "height",
        ParamType::F32,
        0,
        Range::Closed(MIN_HEIGHT_M, MAX_HEIGHT_M),
        "m",
        "cruise height",
    )
    .refused_as(Refusal::BadHeight),
    ParamEntry::declare(
        "mission",
        "speed",
        ParamType::F32,
        0,
        Range::LeftOpen(0.0, MAX_SPEED_M_S),
        "m/s",
        "cruise speed",
    )
    .refused_as(Refusal::BadSpeed),
    ParamEntry::declare(
        "deck",
        "bcFlow",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Flow deck v1 detected: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcFlow2",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Flow deck v2 detected (its PMW3901 answered at boot)",
    ),
    ParamEntry::declare(
        "deck",
        "bcZRanger",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Z-ranger deck v1: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcZRanger2",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Z-ranger deck v2 (a separate deck; the Flow v2's own ranger counts as bcFlow2): always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcMultiranger",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Multi-ranger deck detected (all five beams answered at boot)",
    ),
    ParamEntry::declare(
        "deck",
        "bcLighthouse4",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Lighthouse deck: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcLoco",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Loco positioning deck: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcDWM1000",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Loco deck, old name: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcLedRing",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "LED-ring deck: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcColorLedBot",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Color LED deck, bottom: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcColorLedTop",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Color LED deck, top: always 0",
    ),
    ParamEntry::declare(
        "kalman",
        "resetEstimation",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "write 1 on the ground: the estimate's x, y go back to mission.startX/startY (heading kept); reads 0 again when done",
    ),
    ParamEntry::declare(
        "stabilizer",
        "controller",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "0 auto-select or 1 PID: both are cfnav's cascaded PID (2..5, stock's other controllers, are refused)",
    )
    .refused_as(Refusal::UnsupportedController),
    ParamEntry::declare(
        "commander",
        "enHighLevel",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "stock's high-level-commander switch, kept for clients that write it",
    ),
    // Mission modes (issue 13 part 3)
    ParamEntry::declare(
        "mission",
        "mode",
        ParamType::U8,
        0,
        Range::Closed(0.0, 2.0),
        "",
        "0 round trip, 1 hover test, 2 explore (README mode table); refused while a mission runs",
    ),
    ParamEntry::declare(
        "mission",
        "hoverTime",
        ParamType::F32,
        0,
        Range::Closed(HOVER_TIME_RANGE_S.0, HOVER_TIME_RANGE_S.1),
        "s",
        "hover test: how long to hold over the take-off point; refused while a mission runs",
    ),
    ParamEntry::declare(
        "mission",
        "coverage",
        ParamType::F32,
        0,
        Range::Closed(COVERAGE_RANGE.0, COVERAGE_RANGE.1),
        "",
        "explore: fly home once this fraction of the arena's cells is known; refused while a mission runs",
    ),
    // Tuning parameters (issue 13 part 4): stock names and types where stock has the parameter
    // (`attitude_pid_controller.c`, `position_controller_pid.c`, `flowdeck_v1v2.c`), cfnav's own groups
    // `avoid`, `plan` and `mission` otherwise. Each is persistent and maps to one field of [`Tuning`]
    // ([`tune_field`]). Bounds are sanity limits (no negative gain, no NaN), not a stability guarantee.
    ParamEntry::declare("pid_rate", "roll_kp", ParamType::F32, 0, Range::Closed(0.0, 1000.0), "", "roll-rate loop, torque counts per deg/s; P gain (stock 250)").persistent(),
    ParamEntry::declare("pid_rate", "roll_ki", ParamType::F32, 0, Range::Closed(0.0, 2000.0), "", "roll-rate loop, torque counts per deg/s; I gain (stock 500)").persistent(),
    ParamEntry::declare("pid_rate", "roll_kd", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "roll-rate loop, torque counts per deg/s; D gain (stock 2.5)").persistent(),
    ParamEntry::declare("pid_rate", "pitch_kp", ParamType::F32, 0, Range::Closed(0.0, 1000.0), "", "pitch-rate loop, torque counts per deg/s; P gain (stock 250)").persistent(),
    ParamEntry::declare("pid_rate", "pitch_ki", ParamType::F32, 0, Range::Closed(0.0, 2000.0), "", "pitch-rate loop, torque counts per deg/s; I gain (stock 500)").persistent(),
    ParamEntry::declare("pid_rate", "pitch_kd", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "pitch-rate loop, torque counts per deg/s; D gain (stock 2.5)").persistent(),
    ParamEntry::declare("pid_rate", "yaw_kp", ParamType::F32, 0, Range::Closed(0.0, 1000.0), "", "yaw-rate loop, torque counts per deg/s; P gain (stock 120)").persistent(),
    ParamEntry::declare("pid_rate", "yaw_ki", ParamType::F32, 0, Range::Closed(0.0, 2000.0), "", "yaw-rate loop, torque counts per deg/s; I gain (stock 16.7)").persistent(),
    ParamEntry::declare("pid_rate", "yaw_kd", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "yaw-rate loop, torque counts per deg/s; D gain (stock 0)").persistent(),
    ParamEntry::declare("pid_attitude", "roll_kp", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "roll-angle loop, deg/s per deg; P gain (stock 6)").persistent(),
    ParamEntry::declare("pid_attitude", "roll_ki", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "roll-angle loop, deg/s per deg; I gain (stock 3)").persistent(),
    ParamEntry::declare("pid_attitude", "roll_kd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "roll-angle loop, deg/s per deg; D gain (stock 0)").persistent(),
    ParamEntry::declare("pid_attitude", "pitch_kp", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "pitch-angle loop, deg/s per deg; P gain (stock 6)").persistent(),
    ParamEntry::declare("pid_attitude", "pitch_ki", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "pitch-angle loop, deg/s per deg; I gain (stock 3)").persistent(),
    ParamEntry::declare("pid_attitude", "pitch_kd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "pitch-angle loop, deg/s per deg; D gain (stock 0)").persistent(),
    ParamEntry::declare("pid_attitude", "yaw_kp", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "yaw-angle loop, deg/s per deg; P gain (stock 6)").persistent(),
    ParamEntry::declare("pid_attitude", "yaw_ki", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "yaw-angle loop, deg/s per deg; I gain (stock 1)").persistent(),
    ParamEntry::declare("pid_attitude", "yaw_kd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "yaw-angle loop, deg/s per deg; D gain (stock 0.35)").persistent(),
    ParamEntry::declare("velCtlPid", "vxKp", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; P gain (stock 25) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vxKi", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; I gain (stock 1) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vxKd", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "velocity loop, deg of tilt per m/s; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vyKp", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; P gain (stock 25) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vyKi", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; I gain (stock 1) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vyKd", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "velocity loop, deg of tilt per m/s; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vzKp", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "vertical-speed loop, thrust/1000 per m/s; P gain (stock 25)").persistent(),
    ParamEntry::declare("velCtlPid", "vzKi", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "vertical-speed loop, thrust/1000 per m/s; I gain (stock 15)").persistent(),
    ParamEntry::declare("velCtlPid", "vzKd", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "vertical-speed loop, thrust/1000 per m/s; D gain (stock 0)").persistent(),
    ParamEntry::declare("posCtlPid", "xKp", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; P gain (stock 2) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "xKi", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; I gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "xKd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "position loop, m/s per m; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "yKp", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; P gain (stock 2) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "yKi", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; I gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "yKd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "position loop, m/s per m; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "zKp", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "height loop, m/s per m (cfnav default 2/0/0.5, D on the measured vertical speed); P gain (stock 2)").persistent(),
    ParamEntry::declare("posCtlPid", "zKi", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "height loop, m/s per m (cfnav default 2/0/0.5, D on the measured vertical speed); I gain (stock 0.5)").persistent(),
    ParamEntry::declare("posCtlPid", "zKd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "height loop, m/s per m (cfnav default 2/0/0.5, D on the measured vertical speed); D gain (stock 0)").persistent(),
    ParamEntry::declare("posCtlPid", "xVelMax", ParamType::F32, 0, Range::LeftOpen(0.0, 2.0), "m/s", "largest horizontal speed target (stock 1; cfnav: one limit for x and y)").persistent(),
    ParamEntry::declare("posCtlPid", "yVelMax", ParamType::F32, 0, Range::LeftOpen(0.0, 2.0), "m/s", "same value as xVelMax (one horizontal limit in cfnav)").persistent(),
    ParamEntry::declare("posCtlPid", "zVelMax", ParamType::F32, 0, Range::LeftOpen(0.0, 2.0), "m/s", "largest vertical speed target (stock 1)").persistent(),
    ParamEntry::declare("posCtlPid", "thrustBase", ParamType::U16, 0, Range::Closed(10000.0, 65000.0), "", "hover thrust feed-forward, counts (cfnav: the hover of 33 g, ~44200; stock 36000)").persistent(),
    ParamEntry::declare("posCtlPid", "thrustMin", ParamType::U16, 0, Range::Closed(0.0, 40000.0), "", "smallest collective thrust while flying, counts (stock 20000)").persistent(),
    ParamEntry::declare("motion", "flowStdFixed", ParamType::F32, 0, Range::Closed(0.1, 20.0), "", "flow measurement std, sensor counts (stock name and default 2.0)").persistent(),
    ParamEntry::declare("avoid", "mode", ParamType::U8, 0, SWITCH, "", "reactive avoidance law: 0 potential field, 1 virtual force field").persistent(),
    ParamEntry::declare("avoid", "clamp", ParamType::U8, 0, SWITCH, "", "speed clamp: 0 by the nearest range, 1 the speed towards each range").persistent(),
    ParamEntry::declare("avoid", "gain", ParamType::F32, 0, Range::Closed(0.0, 2.0), "m/s", "push-back speed per unit repulsion").persistent(),
    ParamEntry::declare("avoid", "dangerDist", ParamType::F32, 0, Range::Closed(0.05, 1.0), "m", "ranges closer than this repel (below slowDist)").persistent(),
    ParamEntry::declare("avoid", "slowDist", ParamType::F32, 0, Range::Closed(0.05, 2.0), "m", "ranges closer than this slow the drone (at least dangerDist)").persistent(),
    ParamEntry::declare("avoid", "minSpeed", ParamType::F32, 0, Range::Closed(0.0, 1.0), "m/s", "speed allowed at the danger distance (at most the avoidance cruise cap, 0.4)").persistent(),
    ParamEntry::declare("plan", "inflation", ParamType::F32, 0, Range::Closed(0.06, 0.5), "m", "obstacles grow by this for planning (drone radius 0.06 + margin)").persistent(),
    ParamEntry::declare("plan", "narrowInfl", ParamType::F32, 0, Range::Closed(0.06, 0.5), "m", "fallback inflation when no path exists (at most plan.inflation)").persistent(),
    ParamEntry::declare("plan", "narrowSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "speed cap while the narrow inflation is in use").persistent(),
    ParamEntry::declare("mission", "searchSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "speed along the pad search's sweep lines").persistent(),
    ParamEntry::declare("mission", "climbSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "take-off climb rate").persistent(),
    ParamEntry::declare("mission", "landSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 0.5), "m/s", "descent rate in the last 0.2 m of a landing (at most landSpeedHigh)").persistent(),
    ParamEntry::declare("mission", "landSpeedHigh", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "descent rate above 0.2 m").persistent(),
    ParamEntry::declare("mission", "goalTol", ParamType::F32, 0, Range::Closed(0.05, 1.0), "m", "distance to the goal at which the pad search begins").persistent(),
    ParamEntry::declare("mission", "padTol", ParamType::F32, 0, Range::Closed(0.01, 0.3), "m", "horizontal error to the pad centre accepted before descending").persistent(),
    ParamEntry::declare("mission", "padPause", ParamType::F32, 0, Range::Closed(0.0, 30.0), "s", "pause on the goal pad, motors off").persistent(),
    ParamEntry::declare("mission", "sweepSpacing", ParamType::F32, 0, Range::Closed(0.05, 0.5), "m", "spacing of the pad search's sweep lines").persistent(),
    ParamEntry::declare("mission", "batReserve", ParamType::F32, 0, Range::Closed(1.0, 5.0), "", "explore turns home once the battery, at the discharge rate measured in flight, no longer lasts this many times the flight home (planned path at cruise speed + 15 s for the pad search and landing)").persistent(),
    // Link loss (issue 13 part 5)
    ParamEntry::declare(
        "mission",
        "linkLoss",
        ParamType::U8,
        0,
        Range::Closed(0.0, 2.0),
        "",
        "after mission.linkTimeout s without any radio packet in a mission: 0 go on (default), 1 land where it is, 2 return home and land on the home pad",
    ),
    ParamEntry::declare(
        "mission",
        "linkTimeout",
        ParamType::F32,
        0,
        Range::Closed(MIN_LINK_TIMEOUT_S, MAX_LINK_TIMEOUT_S),
        "s",
        "radio silence that counts as a lost link during a mission (default 2)",
    ),
    // The build's revision (stock `version.tmpl`; values from git via build.rs, `crate::system::version`)
    ParamEntry::declare(
        "firmware",
        "revision0",
        ParamType::U32,
        RO,
        Range::Any,
        "",
        "the build's git commit, first 8 hex digits as a number (stock; cfclient shows it in hex)",
    ),
    ParamEntry::declare(
        "firmware",
        "revision1",
        ParamType::U16,
        RO,
        Range::Any,
        "",
        "the build's git commit, hex digits 9 to 12 as a number (stock)",
    ),
    ParamEntry::declare(
        "firmware",
        "modified",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "1 when the firmware's tracked sources differed from that commit at build time (stock)",
    ),
    // The room (appended: the ids above stay). Checked against the map's capacity with the other side in
    // effect; refused while a mission runs (the grid is shaped at the start).
    ParamEntry::declare("mission", "arenaX", ParamType::F32, 0, Range::Any, "m", "arena size along x, from the west wall (x = 0) to the east; the map must hold arenaX × arenaY").persistent(),
    ParamEntry::declare("mission", "arenaY", ParamType::F32, 0, Range::Any, "m", "arena size along y, from the south wall (y = 0) to the north; the map must hold arenaX × arenaY").persistent(),
    ParamEntry::declare("mission", "walls", ParamType::U8, 0, Range::Closed(0.0, 15.0), "", "which sides are walls: south (y = 0) 1, east 2, north 4, west (x = 0) 8; an open side is a geofence 0.3 m inside it").persistent(),
];

/// Id of `mission.start` (uint8).
pub const ID_START: u16 = param_id(PARAM_TABLE, "mission", "start");
/// Id of `mission.goalX` (float).
pub const ID_GOAL_X: u16 = param_id(PARAM_TABLE, "mission", "goalX");
/// Id of `mission.goalY` (float).
pub const ID_GOAL_Y: u16 = param_id(PARAM_TABLE, "mission", "goalY");
/// Id of `mission.startX` (float).
pub const ID_START_X: u16 = param_id(PARAM_TABLE, "mission", "startX");
/// Id of `mission.startY` (float).
pub const ID_START_Y: u16 = param_id(PARAM_TABLE, "mission", "startY");
/// Id of `mission.height` (float).
pub const ID_HEIGHT: u16 = param_id(PARAM_TABLE, "mission", "height");
/// Id of `mission.speed` (float).
pub const ID_SPEED: u16 = param_id(PARAM_TABLE, "mission", "speed");
/// Id of `deck.bcFlow2` (uint8, read-only).
pub const ID_DECK_FLOW2: u16 = param_id(PARAM_TABLE, "deck", "bcFlow2");
/// Id of `deck.bcMultiranger` (uint8, read-only).
pub const ID_DECK_MULTIRANGER: u16 = param_id(PARAM_TABLE, "deck", "bcMultiranger");
/// Id of `kalman.resetEstimation` (uint8).
pub const ID_RESET_ESTIMATION: u16 = param_id(PARAM_TABLE, "kalman", "resetEstimation");
/// Id of `stabilizer.controller` (uint8).
pub const ID_CONTROLLER: u16 = param_id(PARAM_TABLE, "stabilizer", "controller");
/// Id of `commander.enHighLevel` (uint8).
pub const ID_EN_HIGH_LEVEL: u16 = param_id(PARAM_TABLE, "commander", "enHighLevel");
/// Id of `mission.mode` (uint8: 0 round trip, 1 hover test, 2 explore).
pub const ID_MODE: u16 = param_id(PARAM_TABLE, "mission", "mode");
/// Id of `mission.hoverTime` (float, s).
pub const ID_HOVER_TIME: u16 = param_id(PARAM_TABLE, "mission", "hoverTime");
/// Id of `mission.coverage` (float, fraction).
pub const ID_COVERAGE: u16 = param_id(PARAM_TABLE, "mission", "coverage");
/// Id of `mission.linkLoss` (uint8).
pub const ID_LINK_LOSS: u16 = param_id(PARAM_TABLE, "mission", "linkLoss");
/// Id of `mission.linkTimeout` (float).
pub const ID_LINK_TIMEOUT: u16 = param_id(PARAM_TABLE, "mission", "linkTimeout");
/// Id of `firmware.revision0` (uint32, read-only).
pub const ID_FW_REVISION0: u16 = param_id(PARAM_TABLE, "firmware", "revision0");
/// Id of `firmware.revision1` (uint16, read-only).
pub const ID_FW_REVISION1: u16 = param_id(PARAM_TABLE, "firmware", "revision1");
/// Id of `firmware.modified` (uint8, read-only).
pub const ID_FW_MODIFIED: u16 = param_id(PARAM_TABLE, "firmware", "modified");
/// Id of `mission.arenaX` (float, m, persistent).
pub const ID_ARENA_X: u16 = param_id(PARAM_TABLE, "mission", "arenaX");
/// Id of `mission.arenaY` (float, m, persistent).
pub const ID_ARENA_Y: u16 = param_id(PARAM_TABLE, "mission", "arenaY");
/// Id of `mission.walls` (uint8 bitmask, persistent).
pub const ID_WALLS: u16 = param_id(PARAM_TABLE, "mission", "walls");

/// Writes the README's parameter table for `table`: one Markdown row per declaration.
pub fn write_param_table(out: &mut impl core::fmt::Write, table: &[ParamEntry]) -> core::fmt::Result {
    writeln!(out, "| name | type | values | unit | access | meaning |")?;
    writeln!(out, "|---|---|---|---|---|---|")?;
    for e in table {
        let unit = if e.unit.is_empty() { "" } else { e.unit };
        let access = match (e.read_only(), e.is_persistent()) {
            (true, _) => "read-only",
            (false, true) => "read/write, persistent",
            (false, false) => "read/write",
        };
        writeln!(
            out,
            "| `{}.{}` | {} | {} | {} | {} | {} |",
            e.group,
            e.name,
            e.ty.name(),
            e.range,
            unit,
            access,
            e.doc
        )?;
    }
    Ok(())
}

/// The tuning parameters' values: the parts of the flight configuration users tune without reflashing
/// (issue 13 part 4). The endpoint hands them to the flight stack (`FlightCore::set_tuning`) whenever
/// [`MissionParamState::tuning_generation`] changes: controller gains and the flow std from the next step
/// (in flight too, as stock), the mission's tuning from the next mission start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tuning {
    /// Controller gains and limits.
    pub controller: ControllerConfig,
    /// The estimator's flow measurement std, counts.
    pub flow_std_counts: f32,
    /// Mission, planner and avoidance tuning.
    pub mission: MissionConfig,
}

impl Default for Tuning {
    fn default() -> Self {
        Self::new(
            ControllerConfig::default(),
            &EstimatorConfig::default(),
            MissionConfig::default(),
        )
    }
}

impl Tuning {
    /// The tuning of a flight stack built with these configurations.
    pub fn new(controller: ControllerConfig, estimator: &EstimatorConfig, mission: MissionConfig) -> Self {
        Self {
            controller,
            flow_std_counts: estimator.flow_std_counts,
            mission,
        }
    }

    /// Whether the values work together: the controller's own validation, the avoidance's, the narrow
    /// inflation at most the full one, the low landing speed at most the high one.
    pub fn consistent(&self) -> bool {
        let m = &self.mission;
        self.controller.validate().is_ok()
            && m.avoidance.validate().is_ok()
            && m.narrow_inflation_radius_m <= m.inflation_radius_m
            && m.descent_speed_m_s <= m.high_descent_speed_m_s
    }
}

/// Where a tuning parameter's value lives in [`Tuning`].
pub enum TuneField<'a> {
    /// A float, as is.
    F32(&'a mut f32),
    /// A thrust in counts, a uint16 on the wire (rounded when read).
    Thrust(&'a mut f32),
    /// The avoidance law: 0 potential field, 1 virtual force field.
    Method(&'a mut AvoidanceMethod),
    /// The avoidance speed clamp: 0 nearest, 1 towards each range.
    Clamp(&'a mut SpeedClamp),
}

/// The field of `t` that tuning parameter `group.name` sets; `None` for the other parameters. The
/// `PARAM_TABLE` block "Tuning parameters" declares each; this says only where its value goes.
pub fn tune_field<'a>(t: &'a mut Tuning, group: &str, name: &str) -> Option<TuneField<'a>> {
    Some(match (group, name) {
        ("pid_rate", "roll_kp") => TuneField::F32(&mut t.controller.roll_rate.kp),
        ("pid_rate", "roll_ki") => TuneField::F32(&mut t.controller.roll_rate.ki),
        ("pid_rate", "roll_kd") => TuneField::F32(&mut t.controller.roll_rate.kd),
        ("pid_rate", "pitch_kp") => TuneField::F32(&mut t.controller.pitch_rate.kp),
        ("pid_rate", "pitch_ki") => TuneField::F32(&mut t.controller.pitch_rate.ki),
        ("pid_rate", "pitch_kd") => TuneField::F32(&mut t.controller.pitch_rate.kd),
        ("pid_rate", "yaw_kp") => TuneField::F32(&mut t.controller.yaw_rate.kp),
        ("pid_rate", "yaw_ki") => TuneField::F32(&mut t.controller.yaw_rate.ki),
        ("pid_rate", "yaw_kd") => TuneField::F32(&mut t.controller.yaw_rate.kd),
        ("pid_attitude", "roll_kp") => TuneField::F32(&mut t.controller.roll.kp),
        ("pid_attitude", "roll_ki") => TuneField::F32(&mut t.controller.roll.ki),
        ("pid_attitude", "roll_kd") => TuneField::F32(&mut t.controller.roll.kd),
        ("pid_attitude", "pitch_kp") => TuneField::F32(&mut t.controller.pitch.kp),
        ("pid_attitude", "pitch_ki") => TuneField::F32(&mut t.controller.pitch.ki),
        ("pid_attitude", "pitch_kd") => TuneField::F32(&mut t.controller.pitch.kd),
        ("pid_attitude", "yaw_kp") => TuneField::F32(&mut t.controller.yaw.kp),
        ("pid_attitude", "yaw_ki") => TuneField::F32(&mut t.controller.yaw.ki),
        ("pid_attitude", "yaw_kd") => TuneField::F32(&mut t.controller.yaw.kd),
        ("velCtlPid", "vxKp") => TuneField::F32(&mut t.controller.vel_xy.kp),
        ("velCtlPid", "vxKi") => TuneField::F32(&mut t.controller.vel_xy.ki),
        ("velCtlPid", "vxKd") => TuneField::F32(&mut t.controller.vel_xy.kd),
        ("velCtlPid", "vyKp") => TuneField::F32(&mut t.controller.vel_xy.kp),
        ("velCtlPid", "vyKi") => TuneField::F32(&mut t.controller.vel_xy.ki),
        ("velCtlPid", "vyKd") => TuneField::F32(&mut t.controller.vel_xy.kd),
        ("velCtlPid", "vzKp") => TuneField::F32(&mut t.controller.vel_z.kp),
        ("velCtlPid", "vzKi") => TuneField::F32(&mut t.controller.vel_z.ki),
        ("velCtlPid", "vzKd") => TuneField::F32(&mut t.controller.vel_z.kd),
        ("posCtlPid", "xKp") => TuneField::F32(&mut t.controller.pos_xy.kp),
        ("posCtlPid", "xKi") => TuneField::F32(&mut t.controller.pos_xy.ki),
        ("posCtlPid", "xKd") => TuneField::F32(&mut t.controller.pos_xy.kd),
        ("posCtlPid", "yKp") => TuneField::F32(&mut t.controller.pos_xy.kp),
        ("posCtlPid", "yKi") => TuneField::F32(&mut t.controller.pos_xy.ki),
        ("posCtlPid", "yKd") => TuneField::F32(&mut t.controller.pos_xy.kd),
        ("posCtlPid", "zKp") => TuneField::F32(&mut t.controller.pos_z.kp),
        ("posCtlPid", "zKi") => TuneField::F32(&mut t.controller.pos_z.ki),
        ("posCtlPid", "zKd") => TuneField::F32(&mut t.controller.pos_z.kd),
        ("posCtlPid", "xVelMax") => TuneField::F32(&mut t.controller.max_xy_speed_m_s),
        ("posCtlPid", "yVelMax") => TuneField::F32(&mut t.controller.max_xy_speed_m_s),
        ("posCtlPid", "zVelMax") => TuneField::F32(&mut t.controller.max_vz_m_s),
        ("posCtlPid", "thrustBase") => TuneField::Thrust(&mut t.controller.thrust_base),
        ("posCtlPid", "thrustMin") => TuneField::Thrust(&mut t.controller.thrust_min),
        ("motion", "flowStdFixed") => TuneField::F32(&mut t.flow_std_counts),
        ("avoid", "mode") => TuneField::Method(&mut t.mission.avoidance.method),
        ("avoid", "clamp") => TuneField::Clamp(&mut t.mission.avoidance.clamp),
        ("avoid", "gain") => TuneField::F32(&mut t.mission.avoidance.gain_mps),
        ("avoid", "dangerDist") => TuneField::F32(&mut t.mission.avoidance.danger_distance_m),
        ("avoid", "slowDist") => TuneField::F32(&mut t.mission.avoidance.slow_down_distance_m),
        ("avoid", "minSpeed") => TuneField::F32(&mut t.mission.avoidance.min_speed_mps),
        ("plan", "inflation") => TuneField::F32(&mut t.mission.inflation_radius_m),
        ("plan", "narrowInfl") => TuneField::F32(&mut t.mission.narrow_inflation_radius_m),
        ("plan", "narrowSpeed") => TuneField::F32(&mut t.mission.narrow_speed_m_s),
        ("mission", "searchSpeed") => TuneField::F32(&mut t.mission.search_speed_m_s),
        ("mission", "climbSpeed") => TuneField::F32(&mut t.mission.climb_speed_m_s),
        ("mission", "landSpeed") => TuneField::F32(&mut t.mission.descent_speed_m_s),
        ("mission", "landSpeedHigh") => TuneField::F32(&mut t.mission.high_descent_speed_m_s),
        ("mission", "goalTol") => TuneField::F32(&mut t.mission.goal_tolerance_m),
        ("mission", "padTol") => TuneField::F32(&mut t.mission.settle_tolerance_m),
        ("mission", "padPause") => TuneField::F32(&mut t.mission.pause_s),
        ("mission", "sweepSpacing") => TuneField::F32(&mut t.mission.sweep.spacing_m),
        ("mission", "batReserve") => TuneField::F32(&mut t.mission.battery_reserve),
        _ => return None,
    })
}

/// The value of tuning parameter `e` in `t`.
fn tune_read(t: &Tuning, e: &ParamEntry) -> Option<Value> {
    let mut t = *t;
    Some(match tune_field(&mut t, e.group, e.name)? {
        TuneField::F32(v) => Value::F32(*v),
        TuneField::Thrust(v) => Value::U16(libm::roundf(v.clamp(0.0, 65535.0)) as u16),
        TuneField::Method(m) => Value::U8(u8::from(*m == AvoidanceMethod::VirtualForceField)),
        TuneField::Clamp(c) => Value::U8(u8::from(*c == SpeedClamp::TowardsEachRange)),
    })
}

/// `t` with tuning parameter `e` set to `value` (already checked against the declaration).
fn tune_write(t: &Tuning, e: &ParamEntry, value: Value) -> Result<Tuning, Refusal> {
    let mut t = *t;
    match (tune_field(&mut t, e.group, e.name).ok_or(Refusal::UnknownId)?, value) {
        (TuneField::F32(f), Value::F32(v)) => *f = v,
        (TuneField::Thrust(f), Value::U16(v)) => *f = f32::from(v),
        (TuneField::Method(m), Value::U8(v)) => {
            *m = if v == 0 {
                AvoidanceMethod::PotentialField
            } else {
                AvoidanceMethod::VirtualForceField
            }
        }
        (TuneField::Clamp(c), Value::U8(v)) => {
            *c = if v == 0 {
                SpeedClamp::Nearest
            } else {
                SpeedClamp::TowardsEachRange
            }
        }
        _ => return Err(Refusal::WrongType),
    }
    if t.consistent() {
        Ok(t)
    } else {
        Err(Refusal::Inconsistent)
    }
}

/// The parameters' values in effect plus what validation needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MissionParamState {
    /// `mission.start`: 1 while a mission runs (set by the radio), back to 0 when it ends (set by the firmware,
    /// which then queues a VALUE_UPDATED).
    pub start: u8,
    /// Positions, height, speed, the arena's size and walls.
    pub params: MissionParams,
    /// The drone is flying: a start is refused.
    pub flying: bool,
    /// Every deck the mission needs is present: a start is refused otherwise.
    pub decks_ok: bool,
    /// `deck.bcFlow2`: the Flow deck v2 was detected.
    pub flow2_deck: bool,
    /// `deck.bcMultiranger`: the Multi-ranger deck was detected.
    pub multiranger_deck: bool,
    /// `kalman.resetEstimation`: 1 from the write until the endpoint has reset the estimate.
    pub reset_estimation: u8,
    /// `stabilizer.controller` (0 or 1).
    pub controller: u8,
    /// `commander.enHighLevel` (0 or 1).
    pub en_high_level: u8,
    /// `mission.linkLoss` and `mission.linkTimeout` (the endpoint hands them to the navigator).
    pub link_loss: LinkLossConfig,
    /// Map capacity, cells, for [`MissionParams::validate`] at start.
    pub capacity_cells: usize,
    /// The mission parameters at power-on (the defaults cfclient shows).
    pub default_params: MissionParams,
    /// The tuning parameters in effect.
    pub tuning: Tuning,
    /// The tuning the flight stack was built with (the defaults cfclient shows).
    pub default_tuning: Tuning,
    /// Counts accepted tuning writes: the endpoint pushes [`Self::tuning`] to the stack when it changes.
    pub tuning_generation: u32,
    /// The values stored in the EEPROM (`persistent_store`).
    pub persistent: PersistentParams,
}

impl MissionParamState {
    /// Idle state with `params`, on the ground, decks present, the default tuning, nothing stored.
    pub fn new(params: MissionParams, capacity_cells: usize) -> Self {
        Self {
            start: 0,
            params,
            flying: false,
            decks_ok: true,
            flow2_deck: true,
            multiranger_deck: true,
            reset_estimation: 0,
            controller: 0,
            en_high_level: 0,
            link_loss: LinkLossConfig::DEFAULT,
            capacity_cells,
            default_params: params,
            tuning: Tuning::default(),
            default_tuning: Tuning::default(),
            tuning_generation: 0,
            persistent: PersistentParams::empty(),
        }
    }

    /// The same state with the tuning the flight stack was built with (its defaults and values in effect).
    pub fn with_tuning(mut self, tuning: Tuning) -> Self {
        self.tuning = tuning;
        self.default_tuning = tuning;
        self
    }

    /// Records which decks answered at boot (`decks_ok` is both).
    pub fn set_decks(&mut self, flow2: bool, multiranger: bool) {
        self.flow2_deck = flow2;
        self.multiranger_deck = multiranger;
        self.decks_ok = flow2 && multiranger;
    }

    /// A pending `kalman.resetEstimation` request: the caller resets the estimate, then sets the
    /// parameter back to 0 and announces it (VALUE_UPDATED). Returns the point to reset x, y to.
    pub fn pending_reset(&self) -> Option<(f32, f32)> {
        (self.reset_estimation != 0).then_some(self.params.start_m)
    }

    fn inside(&self, p: (f32, f32)) -> bool {
        let a = self.params.arena_m;
        p.0.is_finite() && p.1.is_finite() && p.0 > 0.1 && p.1 > 0.1 && p.0 < a.0 - 0.1 && p.1 < a.1 - 0.1
    }

    fn write_start(&mut self, v: u8) -> Result<(), Refusal> {
        if v == 0 {
            self.start = 0;
            return Ok(());
        }
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
            StartRefusal::BadModeSetting => Refusal::OutOfRange,
        })?;
        self.start = 1;
        Ok(())
    }

    /// A float write that passed the declaration's checks.
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
            ID_HEIGHT => self.params.height_m = v,
            ID_SPEED => self.params.speed_m_s = v,
            // The mission modes' settings: what a running mission does cannot change under it.
            ID_HOVER_TIME | ID_COVERAGE if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_HOVER_TIME => self.params.hover_time_s = v,
            ID_COVERAGE => self.params.coverage_target = v,
            ID_LINK_TIMEOUT => self.link_loss.timeout_s = v,
            ID_ARENA_X | ID_ARENA_Y if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_ARENA_X | ID_ARENA_Y => {
                let arena = if id == ID_ARENA_X {
                    (v, p.arena_m.1)
                } else {
                    (p.arena_m.0, v)
                };
                if GridShape::for_arena(arena.0, arena.1, self.capacity_cells).is_none() {
                    return Err(Refusal::BadArena);
                }
                self.params.arena_m = arena;
            }
            _ => return Err(Refusal::UnknownId),
        }
        Ok(())
    }

    /// A uint8 write that passed the declaration's checks (0 or 1 for every writable uint8 here but
    /// `mission.mode` and `mission.linkLoss`, 0..2).
    fn write_u8(&mut self, id: u16, v: u8) -> Result<(), Refusal> {
        match id {
            ID_START => return self.write_start(v),
            ID_RESET_ESTIMATION if v != 0 && (self.flying || self.start != 0) => {
                return Err(Refusal::ResetWhileFlying);
            }
            ID_RESET_ESTIMATION => self.reset_estimation = v,
            ID_CONTROLLER => self.controller = v,
            ID_EN_HIGH_LEVEL => self.en_high_level = v,
            ID_MODE if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_MODE => self.params.mode = MissionMode::from_code(v).ok_or(Refusal::OutOfRange)?,
            ID_LINK_LOSS => self.link_loss.policy = LinkLossPolicy::from_code(v).ok_or(Refusal::OutOfRange)?,
            ID_WALLS if self.start != 0 => return Err(Refusal::AlreadyRunning),
            ID_WALLS => self.params.walls = v,
            _ => return Err(Refusal::UnknownId),
        }
        Ok(())
    }
}

impl ParamStore for MissionParamState {
    const TABLE: &'static [ParamEntry] = PARAM_TABLE;

    fn read(&self, id: u16) -> Option<Value> {
        if let Some(v) = tune_read(&self.tuning, PARAM_TABLE.get(usize::from(id))?) {
            return Some(v);
        }
        let p = &self.params;
        let flag = |b: bool| Value::U8(u8::from(b));
        Some(match id {
            ID_START => Value::U8(self.start),
            ID_GOAL_X => Value::F32(p.goal_m.0),
            ID_GOAL_Y => Value::F32(p.goal_m.1),
            ID_START_X => Value::F32(p.start_m.0),
            ID_START_Y => Value::F32(p.start_m.1),
            ID_HEIGHT => Value::F32(p.height_m),
            ID_SPEED => Value::F32(p.speed_m_s),
            ID_DECK_FLOW2 => flag(self.flow2_deck),
            ID_DECK_MULTIRANGER => flag(self.multiranger_deck),
            ID_RESET_ESTIMATION => Value::U8(self.reset_estimation),
            ID_CONTROLLER => Value::U8(self.controller),
            ID_EN_HIGH_LEVEL => Value::U8(self.en_high_level),
            ID_MODE => Value::U8(p.mode.code()),
            ID_HOVER_TIME => Value::F32(p.hover_time_s),
            ID_COVERAGE => Value::F32(p.coverage_target),
            ID_LINK_LOSS => Value::U8(self.link_loss.policy.code()),
            ID_LINK_TIMEOUT => Value::F32(self.link_loss.timeout_s),
            ID_FW_REVISION0 => Value::U32(version::REVISION0),
            ID_FW_REVISION1 => Value::U16(version::REVISION1),
            ID_FW_MODIFIED => Value::U8(version::MODIFIED),
            ID_ARENA_X => Value::F32(p.arena_m.0),
            ID_ARENA_Y => Value::F32(p.arena_m.1),
            ID_WALLS => Value::U8(p.walls),
            // The other deck.* entries: decks cfnav never drives.
            _ if PARAM_TABLE.get(usize::from(id))?.group == "deck" => flag(false),
            _ => return None,
        })
    }

    fn default_value(&self, id: u16) -> Option<Value> {
        let e = PARAM_TABLE.get(usize::from(id))?;
        if let Some(v) = tune_read(&self.default_tuning, e) {
            return Some(v);
        }
        let mut power_on = Self::new(self.default_params, self.capacity_cells);
        power_on.set_decks(self.flow2_deck, self.multiranger_deck);
        power_on.read(id)
    }

    fn write(&mut self, id: u16, value: Value) -> Result<(), Refusal> {
        let e = PARAM_TABLE.get(usize::from(id)).ok_or(Refusal::UnknownId)?;
        e.check(value)?;
        if tune_read(&self.tuning, e).is_some() {
            self.tuning = tune_write(&self.tuning, e, value)?;
            self.tuning_generation = self.tuning_generation.wrapping_add(1);
            return Ok(());
        }
        match value {
            Value::U8(v) => self.write_u8(id, v),
            Value::F32(v) => self.write_f32(id, v),
            _ => Err(Refusal::WrongType),
        }
    }

    fn stored_value(&self, id: u16) -> Option<Value> {
        let e = PARAM_TABLE.get(usize::from(id)).filter(|e| e.is_persistent())?;
        let r = self.persistent.get(param_key(e.group, e.name))?;
        if r.type_code != e.ty.param_code() {
            return None;
        }
        Value::from_le(e.ty, &r.value[..e.ty.size()])
    }

    fn prepare_persistent_store(&self, id: u16) -> Result<PendingWrite, Refusal> {
        let e = PARAM_TABLE.get(usize::from(id)).ok_or(Refusal::UnknownId)?;
        if !e.is_persistent() {
            return Err(Refusal::NotPersistent);
        }
        if self.flying {
            return Err(Refusal::StoreWhileFlying);
        }
        let (bytes, _) = self.read(id).ok_or(Refusal::UnknownId)?.to_le();
        self.persistent
            .prepare_store(param_key(e.group, e.name), e.ty.param_code(), bytes)
            .map_err(|_| Refusal::StoreFull)
    }

    fn prepare_persistent_clear(&self, id: u16) -> Result<Option<PendingWrite>, Refusal> {
        let e = PARAM_TABLE.get(usize::from(id)).ok_or(Refusal::UnknownId)?;
        if !e.is_persistent() {
            return Err(Refusal::NotPersistent);
        }
        if self.flying {
            return Err(Refusal::StoreWhileFlying);
        }
        Ok(self.persistent.prepare_clear(param_key(e.group, e.name)))
    }

    fn commit_persistent(&mut self, write: PendingWrite) -> bool {
        self.persistent.commit(write)
    }

    fn set_persistent(&mut self, stored: PersistentParams) {
        self.persistent = stored;
    }

    fn aliases(&self, id: u16) -> impl Iterator<Item = u16> {
        // Two names of one field: the same address in a scratch copy of the tuning.
        let mut probe = self.tuning;
        let target = PARAM_TABLE.get(usize::from(id)).and_then(|e| field_addr(&mut probe, e));
        (0..PARAM_TABLE.len() as u16).filter(move |&other| {
            let mut probe = probe;
            other != id && target.is_some() && field_addr(&mut probe, &PARAM_TABLE[usize::from(other)]) == target
        })
    }
}

/// The address of tuning parameter `e`'s field inside `t` (as an offset), to find two names of one field.
fn field_addr(t: &mut Tuning, e: &ParamEntry) -> Option<usize> {
    let base = t as *const Tuning as usize;
    let addr = match tune_field(t, e.group, e.name)? {
        TuneField::F32(f) | TuneField::Thrust(f) => f as *const f32 as usize,
        TuneField::Method(m) => m as *const AvoidanceMethod as usize,
        TuneField::Clamp(c) => c as *const SpeedClamp as usize,
    };
    Some(addr - base)
}
