//! A log variable's declaration and the source the log service samples: the type codes ([`LogType`]), the
//! stock conversion of a stored value to the type a log block asks for ([`Value::convert`],
//! [`single_to_half`]), the compile-time id lookup ([`log_id`]), the TOC CRC ([`log_toc_crc`]), the
//! Markdown table of a log table ([`write_log_table`]) and the [`LogSource`] trait the log service
//! ([`super::log`]) reads through.
//!
//! Non-goals: which variables cfnav has (see `crate::radio_binding::log_table`), the wire protocol (see
//! [`super::log`]), raw-memory variables, an FP16 storage type.
//!
//! Sources: `docs/hardware.md` §4 (type codes 1 u8, 2 u16, 3 u32, 4 i8, 5 i16, 6 i32, 7 float, 8 FP16, the
//! TOC byte is the plain code); `docs/radio.md` (the CRC is a cache key shared with the param TOC: it must
//! change with the TOC and differ from the param TOC's).
//!
//! Type conversion (the protocol only says "converted to its fetch type"; rule taken from stock `log.c`
//! `logRunBlock` and `single2half`):
//! * the stored value is first read into an `int32` (`valuei`): integers widen (a `uint32` wraps), a float is
//!   converted toward zero (C conversion; on the Cortex-M4 VCVT saturates and NaN gives 0, which is Rust's
//!   `as i32`);
//! * fetch float: the float itself if stored as float, else `(float)valuei`;
//! * fetch FP16: `single2half` of that float (no subnormals: |x| < 2^-14 → 0; exponent > 15 → ±inf; NaN →
//!   0x7E00; mantissa rounded by adding bit 12, OR-ed in as stock does);
//! * fetch integer: the low 1, 2 or 4 bytes of `valuei`, little-endian (so float 3.7 → u16 `03 00`, float -1.5
//!   → u16 `FF FF`, u16 300 → u8 `2C`).
//!
//! Design choices: the TOC CRC is CRC-32 over [`LOG_CRC_SEED`] followed by, for every entry in id order, the
//! type code, the group, a NUL, the name and a NUL (same scheme as the param TOC with a different seed, so the
//! two CRCs differ even for identical names).
//!
//! Memory: declarations are `Copy` values in `'static` tables; nothing here is allocated.

use crate::crc::crc32_update;

use super::toc::{Value, assert_toc_name, crc32_toc_entry, str_eq};
pub use super::wire_type::WireType;

/// Bytes before `group\0name\0` in a TOC item reply: command, id u16, type.
pub const TOC_ITEM_HEADER: usize = 4;
/// Bytes the log CRC starts with, so that it differs from the param TOC CRC.
pub const LOG_CRC_SEED: &[u8] = b"cfnav/log-toc/v1";

/// A log type: the shared [`WireType`] (log code [`WireType::log_code`]), the storage type of a
/// variable or the fetch type of a block op.
pub type LogType = WireType;

/// A variable's value as the source holds it: the same values as parameters.
pub type LogValue = Value;

/// Stock `single2half`: float to IEEE half, no subnormals, round by adding bit 12 (module docs).
pub const fn single_to_half(x: f32) -> u16 {
    let num = x.to_bits();
    let s = num >> 31;
    let e = (num >> 23) & 0xFF;
    if e == 255 && num & 0x007F_FFFF != 0 {
        return 0x7E00;
    }
    if e > 127 + 15 {
        return if s != 0 { 0xFC00 } else { 0x7C00 };
    }
    if e < 127 - 15 {
        return 0;
    }
    ((s << 15) | ((e + 15 - 127) << 10) | (((num >> 13) & 0x3FF) + ((num >> 12) & 0x01))) as u16
}

impl Value {
    /// The stock `valuei`: the value as an `int32` (module docs).
    pub fn as_i32(self) -> i32 {
        match self {
            Self::U8(v) => i32::from(v),
            Self::U16(v) => i32::from(v),
            Self::U32(v) => v as i32,
            Self::I8(v) => i32::from(v),
            Self::I16(v) => i32::from(v),
            Self::I32(v) => v,
            Self::F32(v) => v as i32,
        }
    }

    /// The value converted to `fetch` as stock does, little-endian: the first `fetch.size()` bytes are used.
    pub fn convert(self, fetch: LogType) -> ([u8; 4], usize) {
        let mut out = [0u8; 4];
        let n = fetch.size();
        let as_float = || match self {
            Self::F32(v) => v,
            other => other.as_i32() as f32,
        };
        match fetch {
            LogType::F32 => out = as_float().to_le_bytes(),
            LogType::Fp16 => out[..2].copy_from_slice(&single_to_half(as_float()).to_le_bytes()),
            _ => {
                let b = self.as_i32().to_le_bytes();
                out[..n].copy_from_slice(&b[..n]);
            }
        }
        (out, n)
    }
}

/// One variable's declaration. Build it with [`LogEntry::new`] or [`LogEntry::declare`] in a `const` so the
/// checks run at compile time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogEntry {
    /// Group name (ASCII, no NUL).
    pub group: &'static str,
    /// Variable name (ASCII, no NUL).
    pub name: &'static str,
    /// Storage type (never [`LogType::Fp16`]).
    pub ty: LogType,
    /// Unit (`""` for none).
    pub unit: &'static str,
    /// One sentence for the README table.
    pub doc: &'static str,
}

impl LogEntry {
    /// A bare entry; panics (a compile error in a `const`) if the TOC item `[2, id u16, type, group\0, name\0]`
    /// would not fit 30 bytes, a name is empty, holds a NUL or non-ASCII byte, or the type is FP16.
    pub const fn new(group: &'static str, name: &'static str, ty: LogType) -> Self {
        Self::declare(group, name, ty, "", "")
    }

    /// The one-line declaration: [`Self::new`]'s checks, plus the unit and the doc.
    pub const fn declare(
        group: &'static str,
        name: &'static str,
        ty: LogType,
        unit: &'static str,
        doc: &'static str,
    ) -> Self {
        assert_toc_name(group, name, TOC_ITEM_HEADER);
        assert!(!matches!(ty, LogType::Fp16), "FP16 is not a storage type");
        Self {
            group,
            name,
            ty,
            unit,
            doc,
        }
    }
}

/// The log TOC CRC: CRC-32 over [`LOG_CRC_SEED`], then per entry `type, group, 0, name, 0`.
pub const fn log_toc_crc(table: &[LogEntry]) -> u32 {
    let mut crc = crc32_update(0xFFFF_FFFF, LOG_CRC_SEED);
    let mut i = 0;
    while i < table.len() {
        let e = &table[i];
        crc = crc32_toc_entry(crc, e.ty.log_code(), e.group, e.name);
        i += 1;
    }
    crc ^ 0xFFFF_FFFF
}

/// Id of `group.name` in `table`, at compile time; panics (a compile error in a `const`) if it is missing.
pub const fn log_id(table: &[LogEntry], group: &str, name: &str) -> u16 {
    let mut i = 0;
    while i < table.len() {
        if str_eq(table[i].group, group) && str_eq(table[i].name, name) {
            return i as u16;
        }
        i += 1;
    }
    panic!("no such log variable")
}

/// Writes the README's log table for `table`: one Markdown row per declaration.
pub fn write_log_table(out: &mut impl core::fmt::Write, table: &[LogEntry]) -> core::fmt::Result {
    writeln!(out, "| name | type | unit | meaning |")?;
    writeln!(out, "|---|---|---|---|")?;
    for e in table {
        writeln!(
            out,
            "| `{}.{}` | {} | {} | {} |",
            e.group,
            e.name,
            e.ty.name(),
            e.unit,
            e.doc
        )?;
    }
    Ok(())
}

/// State the log service samples by id (ids are indices into [`Self::TABLE`]).
pub trait LogSource {
    /// The table, in id order.
    const TABLE: &'static [LogEntry];
    /// The current value of variable `id`; `None` if there is no such id.
    fn value(&self, id: u16) -> Option<LogValue>;
}
