//! The scalar types a parameter or a log variable travels as: one enum, [`WireType`], with its size, its
//! name and its two wire codes (the parameter type byte's low nibble and the log type code).
//!
//! Job: say once what a `uint16` or a `float` is on the wire, for both TOCs. The parameter registry
//! ([`super::param_decl::ParamType`]) and the log registry ([`crate::radio::log_decl::LogType`]) are this type under
//! their protocol's name; the values themselves are [`super::toc::Value`] (encode `to_le`, decode
//! `from_le`, log conversion `convert`).
//!
//! Non-goals: no 64-bit types, no FP16 parameters (FP16 is a log *fetch* type only: no value is stored as
//! one, and [`WireType::from_param_code`] never yields it).
//!
//! Sources: `docs/hardware.md` §4 (parameter type byte: bits 1..0 size 0 = 1 B, 1 = 2 B, 2 = 4 B; bit 2
//! float; bit 3 unsigned) and `docs/hardware.md` §4 (log type codes 1 u8, 2 u16, 3 u32, 4 i8, 5 i16, 6 i32, 7 float, 8 FP16).
//!
//! Memory: one byte, `Copy`.

/// A scalar type on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireType {
    /// `uint8_t`: param code 0x08, log code 1.
    U8,
    /// `uint16_t`: param code 0x09, log code 2.
    U16,
    /// `uint32_t`: param code 0x0A, log code 3.
    U32,
    /// `int8_t`: param code 0x00, log code 4.
    I8,
    /// `int16_t`: param code 0x01, log code 5.
    I16,
    /// `int32_t`: param code 0x02, log code 6.
    I32,
    /// `float`: param code 0x06, log code 7.
    F32,
    /// IEEE half float, log code 8: a log fetch type only (module docs).
    Fp16,
}

impl WireType {
    /// Every type, in log-code order.
    pub const ALL: [Self; 8] = [
        Self::U8,
        Self::U16,
        Self::U32,
        Self::I8,
        Self::I16,
        Self::I32,
        Self::F32,
        Self::Fp16,
    ];

    /// Size of a value on the wire, bytes.
    pub const fn size(self) -> usize {
        match self {
            Self::U8 | Self::I8 => 1,
            Self::U16 | Self::I16 | Self::Fp16 => 2,
            Self::U32 | Self::I32 | Self::F32 => 4,
        }
    }

    /// The name `docs/radio.md` and the README use (`uint8`, `float`, ...).
    pub const fn name(self) -> &'static str {
        match self {
            Self::U8 => "uint8",
            Self::U16 => "uint16",
            Self::U32 => "uint32",
            Self::I8 => "int8",
            Self::I16 => "int16",
            Self::I32 => "int32",
            Self::F32 => "float",
            Self::Fp16 => "fp16",
        }
    }

    /// The parameter type code (low nibble of the type byte), built from `docs/hardware.md` §4's bits: size, float, unsigned.
    pub const fn param_code(self) -> u8 {
        let size_bits = match self.size() {
            1 => 0,
            2 => 1,
            _ => 2,
        };
        let float = matches!(self, Self::F32 | Self::Fp16);
        let unsigned = matches!(self, Self::U8 | Self::U16 | Self::U32);
        size_bits | (float as u8) << 2 | (unsigned as u8) << 3
    }

    /// The parameter type for a type byte (flags in the high nibble ignored); `None` for codes no parameter
    /// here has (64-bit, FP16, double).
    pub const fn from_param_code(code: u8) -> Option<Self> {
        let mut i = 0;
        while i < Self::ALL.len() {
            let t = Self::ALL[i];
            if !matches!(t, Self::Fp16) && t.param_code() == code & 0x0F {
                return Some(t);
            }
            i += 1;
        }
        None
    }

    /// The log type code.
    pub const fn log_code(self) -> u8 {
        match self {
            Self::U8 => 1,
            Self::U16 => 2,
            Self::U32 => 3,
            Self::I8 => 4,
            Self::I16 => 5,
            Self::I32 => 6,
            Self::F32 => 7,
            Self::Fp16 => 8,
        }
    }

    /// The log type for a code (exact, no flag bits); `None` for 0 and 9..=255.
    pub const fn from_log_code(code: u8) -> Option<Self> {
        let mut i = 0;
        while i < Self::ALL.len() {
            if Self::ALL[i].log_code() == code {
                return Some(Self::ALL[i]);
            }
            i += 1;
        }
        None
    }
}
