//! A declarative, fixed-size log-variable table: a `const` table of entries, the values read through
//! [`LogSource`], the stock type conversion, plus the interfaces.md §5 variables over [`FlightLogState`].
//!
//! Job: describe every log variable once (group, name, storage type), check at compile time that each TOC item
//! fits one CRTP packet, give the TOC its CRC, and convert a value to the type a log block asks for.
//!
//! Non-goals: no wire protocol (that is [`super::log`]), no raw-memory variables, no FP16 storage type.
//!
//! Sources: `crazyflie-hardware.md` §4.6 (type codes 1 u8, 2 u16, 3 u32, 4 i8, 5 i16, 6 i32, 7 float, 8 FP16,
//! the TOC byte is the plain code); `crtp-over-udp.md` §2 (the CRC is a cache key shared with the param TOC: it
//! must change with the TOC and differ from the param TOC's); `interfaces.md` §5 (the variables).
//!
//! Type conversion (the references only say "converted to its fetch type"; rule taken from stock `log.c`
//! `logRunBlock` and `single2half`, read in a public copy of the Bitcraze firmware):
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
//! type code, the group, a NUL, the name and a NUL (same scheme as the param TOC with a different seed, so the two
//! CRCs differ even for identical names).
//!
//! Memory: the table is `'static`; [`FlightLogState`] is 32 bytes.

use super::crtp::MAX_DATA;
use super::registry::{crc32_toc_entry, crc32_update, valid_name};

/// Bytes before `group\0name\0` in a TOC item reply: command, id u16, type (§4.6).
pub const TOC_ITEM_HEADER: usize = 4;
/// Bytes the log CRC starts with, so that it differs from the param TOC CRC.
pub const LOG_CRC_SEED: &[u8] = b"cfnav/log-toc/v1";

/// A log type with its wire code (§4.6): the storage type of a variable or the fetch type of a block op.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogType {
    /// `uint8_t`, code 1.
    U8,
    /// `uint16_t`, code 2.
    U16,
    /// `uint32_t`, code 3.
    U32,
    /// `int8_t`, code 4.
    I8,
    /// `int16_t`, code 5.
    I16,
    /// `int32_t`, code 6.
    I32,
    /// `float`, code 7.
    F32,
    /// IEEE half float, code 8 (fetch type only).
    Fp16,
}

impl LogType {
    /// The wire code.
    pub const fn code(self) -> u8 {
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

    /// The type for a code (exact, no flag bits); `None` for 0 and 9..=255.
    pub const fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            1 => Self::U8,
            2 => Self::U16,
            3 => Self::U32,
            4 => Self::I8,
            5 => Self::I16,
            6 => Self::I32,
            7 => Self::F32,
            8 => Self::Fp16,
            _ => return None,
        })
    }

    /// Size on the wire, bytes.
    pub const fn size(self) -> usize {
        match self {
            Self::U8 | Self::I8 => 1,
            Self::U16 | Self::I16 | Self::Fp16 => 2,
            Self::U32 | Self::I32 | Self::F32 => 4,
        }
    }
}

/// A variable's value as the source holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LogValue {
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

impl LogValue {
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

/// One table entry. Build it with [`LogEntry::new`] in a `const` so the checks run at compile time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LogEntry {
    /// Group name (ASCII, no NUL).
    pub group: &'static str,
    /// Variable name (ASCII, no NUL).
    pub name: &'static str,
    /// Storage type (never [`LogType::Fp16`]).
    pub ty: LogType,
}

impl LogEntry {
    /// An entry; panics (a compile error in a `const`) if the TOC item `[2, id u16, type, group\0, name\0]`
    /// would not fit 30 bytes, a name is empty, holds a NUL or non-ASCII byte, or the type is FP16.
    pub const fn new(group: &'static str, name: &'static str, ty: LogType) -> Self {
        assert!(
            group.len() + name.len() + 2 + TOC_ITEM_HEADER <= MAX_DATA,
            "log group + name too long for a TOC item"
        );
        assert!(
            valid_name(group) && valid_name(name),
            "log group and name must be non-empty ASCII without NUL"
        );
        assert!(!matches!(ty, LogType::Fp16), "FP16 is not a storage type");
        Self { group, name, ty }
    }
}

/// The log TOC CRC: CRC-32 over [`LOG_CRC_SEED`], then per entry `type, group, 0, name, 0`.
pub const fn log_toc_crc(table: &[LogEntry]) -> u32 {
    let mut crc = crc32_update(0xFFFF_FFFF, LOG_CRC_SEED);
    let mut i = 0;
    while i < table.len() {
        let e = &table[i];
        crc = crc32_toc_entry(crc, e.ty.code(), e.group, e.name);
        i += 1;
    }
    crc ^ 0xFFFF_FFFF
}

/// State the log service samples by id (ids are indices into [`Self::TABLE`]).
pub trait LogSource {
    /// The table, in id order.
    const TABLE: &'static [LogEntry];
    /// The current value of variable `id`; `None` if there is no such id.
    fn value(&self, id: u16) -> Option<LogValue>;
}

/// Id of `mission.state` (uint8).
pub const ID_MISSION_STATE: u16 = 0;
/// Id of `stateEstimate.x` (float).
pub const ID_X: u16 = 1;
/// Id of `stateEstimate.y` (float).
pub const ID_Y: u16 = 2;
/// Id of `stateEstimate.z` (float).
pub const ID_Z: u16 = 3;
/// Id of `range.front` (uint16, mm); `range.back`, `.left`, `.right`, `.up`, `.zrange` follow.
pub const ID_RANGE_FRONT: u16 = 4;
/// Id of `range.zrange` (uint16, mm).
pub const ID_RANGE_ZRANGE: u16 = 9;
/// Id of `pm.vbat` (float).
pub const ID_VBAT: u16 = 10;

/// The interfaces.md §5 log variables, in id order.
pub const FLIGHT_LOG_TABLE: &[LogEntry] = &[
    LogEntry::new("mission", "state", LogType::U8),
    LogEntry::new("stateEstimate", "x", LogType::F32),
    LogEntry::new("stateEstimate", "y", LogType::F32),
    LogEntry::new("stateEstimate", "z", LogType::F32),
    LogEntry::new("range", "front", LogType::U16),
    LogEntry::new("range", "back", LogType::U16),
    LogEntry::new("range", "left", LogType::U16),
    LogEntry::new("range", "right", LogType::U16),
    LogEntry::new("range", "up", LogType::U16),
    LogEntry::new("range", "zrange", LogType::U16),
    LogEntry::new("pm", "vbat", LogType::F32),
];

/// What the firmware or the simulator publishes for logging; fill it every control cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FlightLogState {
    /// `mission.state` (interfaces.md §5 codes).
    pub mission_state: u8,
    /// `stateEstimate.x/.y/.z`, arena frame, m.
    pub position_m: [f32; 3],
    /// `range.front, .back, .left, .right, .up, .zrange`, mm, in that order.
    pub ranges_mm: [u16; 6],
    /// `pm.vbat`, V.
    pub vbat_v: f32,
}

impl LogSource for FlightLogState {
    const TABLE: &'static [LogEntry] = FLIGHT_LOG_TABLE;

    fn value(&self, id: u16) -> Option<LogValue> {
        Some(match id {
            ID_MISSION_STATE => LogValue::U8(self.mission_state),
            ID_X..=ID_Z => LogValue::F32(*self.position_m.get(usize::from(id - ID_X))?),
            ID_RANGE_FRONT..=ID_RANGE_ZRANGE => LogValue::U16(*self.ranges_mm.get(usize::from(id - ID_RANGE_FRONT))?),
            ID_VBAT => LogValue::F32(self.vbat_v),
            _ => return None,
        })
    }
}

// ---------------------------------------------------------------------------------------------------------
// Firmware-only variables: the table above (what the simulator serves) followed by the board's timing.
// ---------------------------------------------------------------------------------------------------------

/// Id of `cfnav.cpuLoadPct` (uint8, %): instrumented work of all levels over the last second.
pub const ID_CPU_LOAD_PCT: u16 = 11;
/// Id of `cfnav.ctrlLoadPct` (uint8, %): estimation + control.
pub const ID_CTRL_LOAD_PCT: u16 = 12;
/// Id of `cfnav.ioLoadPct` (uint8, %): sensors and radio.
pub const ID_IO_LOAD_PCT: u16 = 13;
/// Id of `cfnav.missionLoadPct` (uint8, %): mission and planner (thread mode).
pub const ID_MISSION_LOAD_PCT: u16 = 14;
/// Id of `cfnav.loopJitterUs` (uint16, µs): peak-to-peak spread of the control period over the last second.
pub const ID_LOOP_JITTER_US: u16 = 15;
/// Id of `cfnav.loopStepMaxUs` (uint16, µs): the longest control step over the last second.
pub const ID_LOOP_STEP_MAX_US: u16 = 16;
/// Id of `cfnav.loopRateHz` (uint16): control steps in the last second.
pub const ID_LOOP_RATE_HZ: u16 = 17;

/// The firmware's log table: [`FLIGHT_LOG_TABLE`] (same ids) followed by the CPU-load and loop-timing
/// variables.
pub const FIRMWARE_LOG_TABLE: &[LogEntry] = &[
    FLIGHT_LOG_TABLE[0],
    FLIGHT_LOG_TABLE[1],
    FLIGHT_LOG_TABLE[2],
    FLIGHT_LOG_TABLE[3],
    FLIGHT_LOG_TABLE[4],
    FLIGHT_LOG_TABLE[5],
    FLIGHT_LOG_TABLE[6],
    FLIGHT_LOG_TABLE[7],
    FLIGHT_LOG_TABLE[8],
    FLIGHT_LOG_TABLE[9],
    FLIGHT_LOG_TABLE[10],
    LogEntry::new("cfnav", "cpuLoadPct", LogType::U8),
    LogEntry::new("cfnav", "ctrlLoadPct", LogType::U8),
    LogEntry::new("cfnav", "ioLoadPct", LogType::U8),
    LogEntry::new("cfnav", "missionLoadPct", LogType::U8),
    LogEntry::new("cfnav", "loopJitterUs", LogType::U16),
    LogEntry::new("cfnav", "loopStepMaxUs", LogType::U16),
    LogEntry::new("cfnav", "loopRateHz", LogType::U16),
];

const _: () = assert!(
    FLIGHT_LOG_TABLE.len() == ID_CPU_LOAD_PCT as usize && FIRMWARE_LOG_TABLE.len() == ID_LOOP_RATE_HZ as usize + 1,
    "the firmware table repeats the whole flight table, then its own variables"
);

/// What the firmware publishes: the flight variables plus CPU load and control-loop timing.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FirmwareLogState {
    /// The interfaces.md §5 variables.
    pub flight: FlightLogState,
    /// `cfnav.cpuLoadPct`, `.ctrlLoadPct`, `.ioLoadPct`, `.missionLoadPct`, %.
    pub load_pct: [u8; 4],
    /// `cfnav.loopJitterUs`, µs.
    pub loop_jitter_us: u16,
    /// `cfnav.loopStepMaxUs`, µs.
    pub loop_step_max_us: u16,
    /// `cfnav.loopRateHz`.
    pub loop_rate_hz: u16,
}

impl LogSource for FirmwareLogState {
    const TABLE: &'static [LogEntry] = FIRMWARE_LOG_TABLE;

    fn value(&self, id: u16) -> Option<LogValue> {
        Some(match id {
            ID_MISSION_STATE..=ID_VBAT => return self.flight.value(id),
            ID_CPU_LOAD_PCT..=ID_MISSION_LOAD_PCT => {
                LogValue::U8(*self.load_pct.get(usize::from(id - ID_CPU_LOAD_PCT))?)
            }
            ID_LOOP_JITTER_US => LogValue::U16(self.loop_jitter_us),
            ID_LOOP_STEP_MAX_US => LogValue::U16(self.loop_step_max_us),
            ID_LOOP_RATE_HZ => LogValue::U16(self.loop_rate_hz),
            _ => return None,
        })
    }
}
