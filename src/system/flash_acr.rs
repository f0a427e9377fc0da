//! The STM32F405's flash access control register (`FLASH_ACR`): the value the firmware must leave in it after
//! the clock setup, and the check of what it reads back.
//!
//! Job: wait states for an HCLK, the `FLASH_ACR` word with the ART accelerator on (prefetch, instruction and
//! data caches), the cache-reset word written before it, and the decoding of a read-back value into what is
//! missing. Why: embassy-stm32 0.6's F4 clock setup writes the register whole with only the latency
//! (`rcc/f247.rs`: `FLASH.acr().write(|w| w.set_latency(latency))`), which clears PRFTEN, ICEN and DCEN; the
//! stock `SystemInit` writes `PRFTEN | ICEN | DCEN | LATENCY_5WS` (bitcraze crazyflie-firmware
//! `src/lib/CMSIS/STM32F4xx/Source/system_stm32f4xx.c`). The board layer writes [`cache_reset_word`] then
//! [`expected_acr`] right after `embassy_stm32::init` and records a fault if [`check_acr`] finds a difference.
//!
//! Non-goals: no register access (the board layer reads and writes), no voltage ranges other than 2.7–3.6 V
//! (the Crazyflie's 3.0 V rail).
//!
//! Units: Hz. Memory: constants only.
//!
//! Source: RM0090 rev 19 §3.9.1 "Flash access control register (FLASH_ACR)": LATENCY bits 2:0, PRFTEN
//! bit 8, ICEN bit 9, DCEN bit 10, ICRST bit 11, DCRST bit 12 (the caches may only be reset while disabled);
//! §3.5.1 table 10: at 2.7–3.6 V one wait state per 30 MHz of HCLK (5 WS for 150 < HCLK ≤ 168 MHz).

/// `LATENCY` field (bits 2:0): wait states.
pub const LATENCY_MASK: u32 = 0b111;
/// Prefetch enable (bit 8).
pub const PRFTEN: u32 = 1 << 8;
/// Instruction cache enable (bit 9).
pub const ICEN: u32 = 1 << 9;
/// Data cache enable (bit 10).
pub const DCEN: u32 = 1 << 10;
/// Instruction cache reset (bit 11; only while ICEN = 0).
pub const ICRST: u32 = 1 << 11;
/// Data cache reset (bit 12; only while DCEN = 0).
pub const DCRST: u32 = 1 << 12;
/// HCLK per wait state at 2.7–3.6 V (RM0090 table 10).
pub const HZ_PER_WAIT_STATE: u32 = 30_000_000;
/// The STM32F405's highest HCLK.
pub const MAX_HCLK_HZ: u32 = 168_000_000;

/// Wait states the flash needs at `hclk_hz` (2.7–3.6 V), or `None` above 168 MHz or at 0 Hz.
pub const fn wait_states(hclk_hz: u32) -> Option<u32> {
    if hclk_hz == 0 || hclk_hz > MAX_HCLK_HZ {
        return None;
    }
    Some((hclk_hz - 1) / HZ_PER_WAIT_STATE)
}

/// The `FLASH_ACR` value to run with at `hclk_hz`: the latency and the ART accelerator (PRFTEN, ICEN, DCEN).
pub const fn expected_acr(hclk_hz: u32) -> Option<u32> {
    match wait_states(hclk_hz) {
        Some(ws) => Some(ws | PRFTEN | ICEN | DCEN),
        None => None,
    }
}

/// The word written before [`expected_acr`]: caches disabled (ICEN = DCEN = 0, which the reset bits
/// require) with both reset bits set, latency kept.
pub const fn cache_reset_word(hclk_hz: u32) -> Option<u32> {
    match wait_states(hclk_hz) {
        Some(ws) => Some(ws | ICRST | DCRST),
        None => None,
    }
}

/// What a read-back `FLASH_ACR` lacks against [`expected_acr`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AcrFindings {
    /// The latency field differs (value read).
    pub wrong_latency: Option<u32>,
    /// Prefetch is off.
    pub prefetch_off: bool,
    /// The instruction cache is off.
    pub icache_off: bool,
    /// The data cache is off.
    pub dcache_off: bool,
    /// A cache reset bit is still set (the caches would be held in reset).
    pub reset_held: bool,
}

impl AcrFindings {
    /// Nothing is missing.
    pub fn is_ok(&self) -> bool {
        *self == Self::default()
    }
}

/// Compares a read-back `FLASH_ACR` with what `hclk_hz` needs; `None` if `hclk_hz` is out of range.
pub fn check_acr(read: u32, hclk_hz: u32) -> Option<AcrFindings> {
    let ws = wait_states(hclk_hz)?;
    let latency = read & LATENCY_MASK;
    Some(AcrFindings {
        wrong_latency: (latency != ws).then_some(latency),
        prefetch_off: read & PRFTEN == 0,
        icache_off: read & ICEN == 0,
        dcache_off: read & DCEN == 0,
        reset_held: read & (ICRST | DCRST) != 0,
    })
}
