//! A parameter's declaration and the store the parameter service works on: the type byte and its flags,
//! the values a write may carry ([`Range`]), the reasons a write is refused ([`Refusal`]), the compile-time
//! id lookup ([`param_id`]), the TOC CRC ([`toc_crc`]), the Markdown table of a parameter table
//! ([`write_param_table`]) and the [`ParamStore`] trait the parameter service ([`super::param`]) reads and
//! writes through.
//!
//! Non-goals: which parameters cfnav has (see `crate::radio_binding::param_table`), the wire protocol (see
//! [`super::param`]), the EEPROM layout (see [`crate::system::persistent_params`]), 64-bit or FP16 types.
//!
//! Sources: `docs/hardware.md` §4 (type byte: bits 1..0 size, bit 2 float, bit 3 unsigned, 0x10 EXTENDED,
//! 0x40 READ-ONLY; CRC-32 reflected 0xEDB88320, init/xorout 0xFFFFFFFF); `docs/radio.md` (the TOC CRC is
//! only a cache key shared with the log TOC: it must change with the TOC and differ from the log TOC's).
//!
//! Design choices: the TOC CRC is CRC-32 over [`PARAM_CRC_SEED`] followed by, for every entry in id order, the
//! type byte, the group, a NUL, the name and a NUL (not stock's chaining; any value that changes with the TOC
//! works). The seed keeps it distinct from the log TOC's CRC for the same names.
//!
//! Memory: declarations are `Copy` values in `'static` tables; nothing here is allocated.

use crate::crc::crc32_update;
use crate::system::persistent_params::{PendingWrite, PersistentParams};

use super::toc::{Value, assert_toc_name, crc32_toc_entry, str_eq};
pub use super::wire_type::WireType;

/// Type byte flag: the entry has an extended type (cflib then asks misc command 7), `docs/hardware.md` §4.
pub const FLAG_EXTENDED: u8 = 0x10;
/// Type byte flag: read-only, `docs/hardware.md` §4.
pub const FLAG_READ_ONLY: u8 = 0x40;
/// Bytes before `group\0name\0` in a TOC item reply: command, id u16, type.
pub const TOC_ITEM_HEADER: usize = 4;
/// Bytes the parameter CRC starts with, so that it differs from a log TOC CRC over the same entries.
pub const PARAM_CRC_SEED: &[u8] = b"cfnav/param-toc/v1";

/// A parameter's value type: the shared [`WireType`] (param code [`WireType::param_code`]); never
/// [`WireType::Fp16`] ([`ParamEntry::new`] refuses it).
pub type ParamType = WireType;

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
