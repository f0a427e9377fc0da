//! The table-of-contents machinery the parameter and log services share: the value a parameter or log
//! variable holds ([`Value`]), the rules for group and variable names ([`valid_name`], [`assert_toc_name`]),
//! the TOC item layout ([`toc_item`]) and the hash of one entry into a TOC CRC ([`crc32_toc_entry`]).
//!
//! Non-goals: the tables themselves and the wire protocols (see [`super::param`] and [`super::log`]).
//!
//! Sources: `docs/hardware.md` §4 (syslink and CRTP: the TOC item `[cmd, id u16, type, group\0, name\0]`,
//! `strlen(group) + strlen(name) + 2 ≤ 26`); stock `src/modules/src/param_logic.c` and `log.c`.
//!
//! Memory: nothing is kept; every function is `const` or works on the caller's buffer.

use crate::crc::crc32_update;

use super::crtp::MAX_DATA;
use super::wire_type::WireType;

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
    pub const fn ty(self) -> WireType {
        match self {
            Self::U8(_) => WireType::U8,
            Self::U16(_) => WireType::U16,
            Self::U32(_) => WireType::U32,
            Self::I8(_) => WireType::I8,
            Self::I16(_) => WireType::I16,
            Self::I32(_) => WireType::I32,
            Self::F32(_) => WireType::F32,
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

    /// Little-endian bytes: the first [`WireType::size`] bytes of the array are used.
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
    pub fn from_le(ty: WireType, bytes: &[u8]) -> Option<Self> {
        Some(match ty {
            WireType::U8 => Self::U8(u8::from_le_bytes(bytes.try_into().ok()?)),
            WireType::I8 => Self::I8(i8::from_le_bytes(bytes.try_into().ok()?)),
            WireType::U16 => Self::U16(u16::from_le_bytes(bytes.try_into().ok()?)),
            WireType::I16 => Self::I16(i16::from_le_bytes(bytes.try_into().ok()?)),
            WireType::U32 => Self::U32(u32::from_le_bytes(bytes.try_into().ok()?)),
            WireType::I32 => Self::I32(i32::from_le_bytes(bytes.try_into().ok()?)),
            WireType::F32 => Self::F32(f32::from_le_bytes(bytes.try_into().ok()?)),
            WireType::Fp16 => return None,
        })
    }
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

/// Feeds one TOC entry, `type, group, 0, name, 0`, into a running CRC-32 (the param and log TOC CRCs both
/// hash their entries this way, each after its own seed).
pub const fn crc32_toc_entry(crc: u32, type_byte: u8, group: &str, name: &str) -> u32 {
    let crc = crc32_update(crc, &[type_byte]);
    let crc = crc32_update(crc, group.as_bytes());
    let crc = crc32_update(crc, &[0]);
    let crc = crc32_update(crc, name.as_bytes());
    crc32_update(crc, &[0])
}
