//! VL53L1x time-of-flight ranger (the Flow deck v2's z-ranger and the Multi-ranger's five beams), on an
//! `embedded-hal-async` I2C bus, following the register sequence of ST's "ultra lite driver" (ULD).
//!
//! Job: boot poll, identity check, ST's default configuration block, the first-range VHV calibration step,
//! distance mode, timing budget, inter-measurement period, start/stop of continuous ranging, data-ready
//! polling, reading one range as metres, clearing the interrupt and moving the chip to another I2C address.
//!
//! Non-goals: no ROI, threshold, offset or crosstalk calibration (the ULD defaults are used), no
//! interrupt pin (the GPIO1 line is not wired to the STM32 on either deck; readiness is polled), no
//! scheduling (the caller owns the bus and decides when to read).
//!
//! Register sources: ST VL53L1X ULD API (STSW-IMG009, `VL53L1X_api.h` / `VL53L1X_api.c`, v3.5), read from
//! the public ports `rneurink/VL53L1X_ULD` (`src/core/VL53L1X_api.cpp`, `.h`) and `stm32duino/VL53L1X`
//! (`src/vl53l1x_class.cpp`, ST's own Arduino port); both carry the same bytes. The model id 0xEACC is the
//! value ST's datasheet gives for IDENTIFICATION__MODEL_ID (also checked by Pololu's `vl53l1x-arduino`).
//! Crazyflie facts (addresses, rates, 2V8 pads): `docs/hardware.md` §2.
//!
//! Bus format: every register index is 16 bits, sent big-endian before the data; multi-byte registers are
//! big-endian too. A write is one I2C write `[index_hi, index_lo, data...]`; a read is a write-read of the
//! index followed by the data bytes. The chip auto-increments the index, so ST's 91-byte default
//! configuration goes out as one write starting at 0x002D (the ULD writes it byte by byte; same result).
//!
//! Units: distances come out of the chip in millimetres (`RESULT__FINAL_CROSSTALK_CORRECTED_RANGE_MM_SD0`,
//! u16) and leave this driver in metres (`mm / 1000`, [`RangeReading`]). Times are milliseconds.
//!
//! Rates: the Flow deck z-ranger preset ([`RangingConfig::FLOW_DECK_Z`]) ranges at 40 Hz (20 ms budget, 25 ms
//! period; stock runs 40 Hz too, with ST's full driver in its medium mode, which the ULD does not have);
//! the Multi-ranger preset ([`RangingConfig::MULTI_RANGER`]) at 10 Hz per beam (50 ms budget, 100 ms period,
//! stock: 41 ms budget, read every 100 ms). One range read costs three bus transfers (status, distance,
//! interrupt clear), about 143 bit times = 0.36 ms at 400 kHz, plus 0.12 ms per data-ready poll; the
//! initialisation is about 20 transfers (the 93-byte configuration write alone ≈ 2.1 ms) plus the first
//! range (≈ 100 ms with ST's default budget).
//!
//! Validity: only ST range status 0 (VALID) gives a distance; every other status (sigma/signal fail,
//! wrap-around, ...) gives `None` — the stock Multi-ranger reports 32767 mm for those, which is the same
//! "no reading" in this firmware's types. The raw status is available through [`Vl53l1x::read_measurement`].
//!
//! Bus ownership: the deck bus carries up to seven chips (expander, five Multi-ranger sensors, the Flow deck
//! sensor), so a [`Vl53l1x`] holds no bus; every call borrows the bus (`&mut I`), which works with a plain
//! embassy I2C peripheral and with a shared-bus device alike.
//!
//! Memory: a [`Vl53l1x`] is 2 bytes (its address and the data-ready level); the default-configuration table
//! is 91 bytes of flash; the largest stack buffer is the 93-byte configuration write.

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;

use crate::drivers::DriverError;
use crate::types::RangeReading;

/// The 7-bit I2C address every VL53L1x answers at after power-up or XSHUT release (ST ULD
/// `VL51L1X_NVM_CONFIGURATION` byte 0x01; `docs/hardware.md` §2).
pub const DEFAULT_ADDRESS: u8 = 0x29;

/// IDENTIFICATION__MODEL_ID of a VL53L1x (ST datasheet; ULD `VL53L1X_GetSensorId`).
pub const MODEL_ID: u16 = 0xEACC;

/// Register indices used by this driver (ST ULD `VL53L1X_api.h`).
pub mod reg {
    /// I2C_SLAVE__DEVICE_ADDRESS: the 7-bit address the chip answers at (u8).
    pub const I2C_SLAVE_DEVICE_ADDRESS: u16 = 0x0001;
    /// VHV_CONFIG__TIMEOUT_MACROP_LOOP_BOUND (u8), set to 0x09 after the first range ("two bounds VHV").
    pub const VHV_CONFIG_TIMEOUT_MACROP_LOOP_BOUND: u16 = 0x0008;
    /// VHV_CONFIG__INIT (u8; the ULD writes it by number, 0x0B), set to 0 to start VHV from the last
    /// temperature.
    pub const VHV_CONFIG_INIT: u16 = 0x000B;
    /// PAD_I2C_HV__EXTSUP_CONFIG (u8): bit 0 = I2C pads referenced to AVDD (2V8) instead of 1V8.
    pub const PAD_I2C_HV_EXTSUP_CONFIG: u16 = 0x002E;
    /// GPIO_HV_MUX__CTRL (u8): bit 4 = interrupt active low.
    pub const GPIO_HV_MUX_CTRL: u16 = 0x0030;
    /// GPIO__TIO_HV_STATUS (u8): bit 0 = the interrupt line level (data ready at the active level).
    pub const GPIO_TIO_HV_STATUS: u16 = 0x0031;
    /// PHASECAL_CONFIG__TIMEOUT_MACROP (u8): 0x14 in short mode, 0x0A in long mode.
    pub const PHASECAL_CONFIG_TIMEOUT_MACROP: u16 = 0x004B;
    /// RANGE_CONFIG__TIMEOUT_MACROP_A_HI (u16).
    pub const RANGE_CONFIG_TIMEOUT_MACROP_A: u16 = 0x005E;
    /// RANGE_CONFIG__VCSEL_PERIOD_A (u8).
    pub const RANGE_CONFIG_VCSEL_PERIOD_A: u16 = 0x0060;
    /// RANGE_CONFIG__TIMEOUT_MACROP_B_HI (u16).
    pub const RANGE_CONFIG_TIMEOUT_MACROP_B: u16 = 0x0061;
    /// RANGE_CONFIG__VCSEL_PERIOD_B (u8).
    pub const RANGE_CONFIG_VCSEL_PERIOD_B: u16 = 0x0063;
    /// RANGE_CONFIG__VALID_PHASE_HIGH (u8).
    pub const RANGE_CONFIG_VALID_PHASE_HIGH: u16 = 0x0069;
    /// SYSTEM__INTERMEASUREMENT_PERIOD (u32, oscillator ticks).
    pub const SYSTEM_INTERMEASUREMENT_PERIOD: u16 = 0x006C;
    /// SD_CONFIG__WOI_SD0 (u16: WOI_SD0, WOI_SD1).
    pub const SD_CONFIG_WOI_SD0: u16 = 0x0078;
    /// SD_CONFIG__INITIAL_PHASE_SD0 (u16: INITIAL_PHASE_SD0, INITIAL_PHASE_SD1).
    pub const SD_CONFIG_INITIAL_PHASE_SD0: u16 = 0x007A;
    /// SYSTEM__INTERRUPT_CLEAR (u8): write 0x01 to clear the data-ready interrupt.
    pub const SYSTEM_INTERRUPT_CLEAR: u16 = 0x0086;
    /// SYSTEM__MODE_START (u8): 0x40 = continuous ranging, 0x00 = stop.
    pub const SYSTEM_MODE_START: u16 = 0x0087;
    /// RESULT__RANGE_STATUS (u8, low 5 bits = device status code).
    pub const RESULT_RANGE_STATUS: u16 = 0x0089;
    /// RESULT__FINAL_CROSSTALK_CORRECTED_RANGE_MM_SD0 (u16, millimetres).
    pub const RESULT_FINAL_RANGE_MM_SD0: u16 = 0x0096;
    /// RESULT__OSC_CALIBRATE_VAL (u16, low 10 bits = oscillator ticks per millisecond, roughly).
    pub const RESULT_OSC_CALIBRATE_VAL: u16 = 0x00DE;
    /// FIRMWARE__SYSTEM_STATUS (u8): bit 0 = boot complete.
    pub const FIRMWARE_SYSTEM_STATUS: u16 = 0x00E5;
    /// IDENTIFICATION__MODEL_ID (u16).
    pub const IDENTIFICATION_MODEL_ID: u16 = 0x010F;
}

/// First register of ST's default configuration block.
pub const DEFAULT_CONFIGURATION_FIRST_REGISTER: u16 = 0x002D;

/// ST's default configuration, registers 0x002D..=0x0087 (91 bytes), exactly as
/// `VL51L1X_DEFAULT_CONFIGURATION[]` in the ULD (STSW-IMG009 `VL53L1X_api.c`; verified identical in
/// `rneurink/VL53L1X_ULD` `src/core/VL53L1X_api.cpp` and `stm32duino/VL53L1X` `src/vl53l1x_class.cpp`).
/// Notable entries (ST's comments): 0x2E bit 0 = I2C pads at AVDD (left 0 here, set by
/// [`RangingConfig::io_2v8`]); 0x30 = 0x01 interrupt active high; 0x46 = 0x20 interrupt on new sample;
/// 0x4B = 0x0A and 0x5E..0x62 = 100 ms budget in long mode; 0x6C..0x6F = inter-measurement 0x00000F89;
/// 0x87 = 0x00 (not ranging).
pub const DEFAULT_CONFIGURATION: [u8; 91] = [
    0x00, 0x00, 0x00, 0x01, 0x02, 0x00, 0x02, 0x08, // 0x2D..0x34
    0x00, 0x08, 0x10, 0x01, 0x01, 0x00, 0x00, 0x00, // 0x35..0x3C
    0x00, 0xFF, 0x00, 0x0F, 0x00, 0x00, 0x00, 0x00, // 0x3D..0x44
    0x00, 0x20, 0x0B, 0x00, 0x00, 0x02, 0x0A, 0x21, // 0x45..0x4C
    0x00, 0x00, 0x05, 0x00, 0x00, 0x00, 0x00, 0xC8, // 0x4D..0x54
    0x00, 0x00, 0x38, 0xFF, 0x01, 0x00, 0x08, 0x00, // 0x55..0x5C
    0x00, 0x01, 0xCC, 0x0F, 0x01, 0xF1, 0x0D, 0x01, // 0x5D..0x64
    0x68, 0x00, 0x80, 0x08, 0xB8, 0x00, 0x00, 0x00, // 0x65..0x6C
    0x00, 0x0F, 0x89, 0x00, 0x00, 0x00, 0x00, 0x00, // 0x6D..0x74
    0x00, 0x00, 0x01, 0x0F, 0x0D, 0x0E, 0x0E, 0x00, // 0x75..0x7C
    0x00, 0x02, 0xC7, 0xFF, 0x9B, 0x00, 0x00, 0x00, // 0x7D..0x84
    0x01, 0x00, 0x00, // 0x85..0x87
];

/// How often the boot and data-ready polls ask the chip, milliseconds.
pub const POLL_INTERVAL_MS: u32 = 1;

/// Boot-state polls before [`DriverError::Timeout`] (or the last bus error, if the chip never answered).
/// ST's datasheet gives a boot time of 1.2 ms after XSHUT release; 50 polls at 1 ms leave a wide margin.
pub const BOOT_POLL_LIMIT: u32 = 50;

/// Data-ready polls allowed for the first (VHV calibration) range during [`Vl53l1x::init`]. That range
/// runs with the default configuration's 100 ms budget; 250 polls at 1 ms leave a wide margin.
pub const VHV_POLL_LIMIT: u32 = 250;

/// Longest inter-measurement period accepted, milliseconds (keeps the period register far from overflow).
pub const MAX_INTER_MEASUREMENT_MS: u32 = 10_000;

/// ST's two ULD distance modes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DistanceMode {
    /// Up to about 1.3 m, better ambient-light immunity.
    Short,
    /// Up to about 4 m in the dark (less in daylight or with a short budget).
    Long,
}

/// The register values one distance mode writes (ULD `VL53L1X_SetDistanceMode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DistanceModeRegisters {
    /// PHASECAL_CONFIG__TIMEOUT_MACROP.
    pub phasecal_timeout_macrop: u8,
    /// RANGE_CONFIG__VCSEL_PERIOD_A.
    pub vcsel_period_a: u8,
    /// RANGE_CONFIG__VCSEL_PERIOD_B.
    pub vcsel_period_b: u8,
    /// RANGE_CONFIG__VALID_PHASE_HIGH.
    pub valid_phase_high: u8,
    /// SD_CONFIG__WOI_SD0/SD1 as one u16.
    pub woi_sd0: u16,
    /// SD_CONFIG__INITIAL_PHASE_SD0/SD1 as one u16.
    pub initial_phase_sd0: u16,
}

impl DistanceMode {
    /// The mode's register set (ULD `VL53L1X_SetDistanceMode`, cases 1 = short and 2 = long).
    pub const fn registers(self) -> DistanceModeRegisters {
        match self {
            DistanceMode::Short => DistanceModeRegisters {
                phasecal_timeout_macrop: 0x14,
                vcsel_period_a: 0x07,
                vcsel_period_b: 0x05,
                valid_phase_high: 0x38,
                woi_sd0: 0x0705,
                initial_phase_sd0: 0x0606,
            },
            DistanceMode::Long => DistanceModeRegisters {
                phasecal_timeout_macrop: 0x0A,
                vcsel_period_a: 0x0F,
                vcsel_period_b: 0x0D,
                valid_phase_high: 0xB8,
                woi_sd0: 0x0F0D,
                initial_phase_sd0: 0x0E0E,
            },
        }
    }
}

/// The ULD's predefined timing budgets (the time the chip integrates one range).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimingBudget {
    /// 15 ms (short mode only).
    Ms15,
    /// 20 ms.
    Ms20,
    /// 33 ms.
    Ms33,
    /// 50 ms.
    Ms50,
    /// 100 ms.
    Ms100,
    /// 200 ms.
    Ms200,
    /// 500 ms.
    Ms500,
}

impl TimingBudget {
    /// The budget in milliseconds.
    pub const fn ms(self) -> u32 {
        match self {
            TimingBudget::Ms15 => 15,
            TimingBudget::Ms20 => 20,
            TimingBudget::Ms33 => 33,
            TimingBudget::Ms50 => 50,
            TimingBudget::Ms100 => 100,
            TimingBudget::Ms200 => 200,
            TimingBudget::Ms500 => 500,
        }
    }

    /// RANGE_CONFIG__TIMEOUT_MACROP_A and _B for this budget in `mode` (ULD `VL53L1X_SetTimingBudgetInMs`),
    /// or `None` for the one combination the ULD refuses (15 ms in long mode).
    pub const fn timeout_macrop_a_b(self, mode: DistanceMode) -> Option<(u16, u16)> {
        match mode {
            DistanceMode::Short => Some(match self {
                TimingBudget::Ms15 => (0x001D, 0x0027),
                TimingBudget::Ms20 => (0x0051, 0x006E),
                TimingBudget::Ms33 => (0x00D6, 0x006E),
                TimingBudget::Ms50 => (0x01AE, 0x01E8),
                TimingBudget::Ms100 => (0x02E1, 0x0388),
                TimingBudget::Ms200 => (0x03E1, 0x0496),
                TimingBudget::Ms500 => (0x0591, 0x05C1),
            }),
            DistanceMode::Long => match self {
                TimingBudget::Ms15 => None,
                TimingBudget::Ms20 => Some((0x001E, 0x0022)),
                TimingBudget::Ms33 => Some((0x0060, 0x006E)),
                TimingBudget::Ms50 => Some((0x00AD, 0x00C6)),
                TimingBudget::Ms100 => Some((0x01CC, 0x01EA)),
                TimingBudget::Ms200 => Some((0x02D9, 0x02F8)),
                TimingBudget::Ms500 => Some((0x048F, 0x04A4)),
            },
        }
    }
}

/// How [`Vl53l1x::init`] configures ranging.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RangingConfig {
    /// Short or long.
    pub distance_mode: DistanceMode,
    /// Integration time of one range.
    pub timing_budget: TimingBudget,
    /// Period between the starts of two ranges in continuous mode, ms; must be ≥ the timing budget.
    pub inter_measurement_ms: u32,
    /// Reference the I2C pads to AVDD (2V8) instead of 1V8: sets bit 0 of register 0x002E in the default
    /// configuration write, as the stock Crazyflie firmware does (`USE_I2C_2V8`, `docs/hardware.md` §2).
    pub io_2v8: bool,
}

impl RangingConfig {
    /// The Flow deck v2 z-ranger: long mode, 20 ms budget, 25 ms period → 40 Hz like stock `zranger2.c`.
    pub const FLOW_DECK_Z: RangingConfig = RangingConfig {
        distance_mode: DistanceMode::Long,
        timing_budget: TimingBudget::Ms20,
        inter_measurement_ms: 25,
        io_2v8: true,
    };

    /// A Multi-ranger beam: long mode, 50 ms budget, 100 ms period → 10 Hz like stock `multiranger.c`.
    pub const MULTI_RANGER: RangingConfig = RangingConfig {
        distance_mode: DistanceMode::Long,
        timing_budget: TimingBudget::Ms50,
        inter_measurement_ms: 100,
        io_2v8: true,
    };

    /// How long before its data-ready flag a range was measured, on average, µs. The timing budget is the
    /// time the chip takes to perform one range (ST DS12385, ULD `VL53L1X_SetTimingBudgetInMs`): it
    /// integrates the returns over it and flags the result at its end, so the reading describes the scene
    /// half a budget before the flag. A moving drone's reading belongs to the pose that long ago, plus
    /// however long the result waited to be read.
    pub const fn integration_midpoint_us(&self) -> u64 {
        self.timing_budget.ms() as u64 * 500
    }

    /// Whether the chip can run this configuration: the budget exists in the mode and the period is at
    /// least the budget and at most [`MAX_INTER_MEASUREMENT_MS`].
    pub const fn is_valid(&self) -> bool {
        self.timing_budget.timeout_macrop_a_b(self.distance_mode).is_some()
            && self.inter_measurement_ms >= self.timing_budget.ms()
            && self.inter_measurement_ms <= MAX_INTER_MEASUREMENT_MS
    }
}

/// The range status as ST's API reports it (ULD `status_rtn[]` maps the device's 5-bit code to these;
/// names and numbers from ST's `VL53L1_RANGESTATUS_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RangeStatus {
    /// 0: the range is valid.
    Valid,
    /// 1: sigma (standard deviation) above the threshold.
    SigmaFail,
    /// 2: return signal below the threshold.
    SignalFail,
    /// 3: target below the minimum range, distance clipped.
    MinRangeClipped,
    /// 4: phase out of valid limits (usually: nothing within reach).
    OutOfBounds,
    /// 5: hardware (VCSEL/VHV) failure.
    HardwareFail,
    /// 6: valid range but the wrap-around check was not done.
    NoWrapCheckFail,
    /// 7: wrapped target (no matching phase in the other VCSEL period).
    WrapTargetFail,
    /// 9: crosstalk signal failure.
    XtalkSignalFail,
    /// 10: first interrupt after start in back-to-back mode; ignore the data.
    SynchronisationInt,
    /// 11: valid range, but the target is several merged pulses.
    MergedPulse,
    /// 12: target present but signal too weak.
    LackOfSignal,
    /// 13: minimum range failure (ROI outside the SPAD array).
    MinRangeFail,
    /// A device code the ULD does not map (its status 255), carrying the raw 5-bit code.
    Unknown(u8),
}

impl RangeStatus {
    /// Maps RESULT__RANGE_STATUS (low 5 bits) the way the ULD's `status_rtn[24]` table does:
    /// device code 9 → 0 (valid), 6 → 1, 4 → 2, 8 → 3, 5 → 4, 3 → 5, 19 → 6, 7 → 7, 12 → 9, 18 → 10,
    /// 22 → 11, 23 → 12, 13 → 13, every other code → 255.
    pub const fn from_register(raw: u8) -> RangeStatus {
        match raw & 0x1F {
            9 => RangeStatus::Valid,
            6 => RangeStatus::SigmaFail,
            4 => RangeStatus::SignalFail,
            8 => RangeStatus::MinRangeClipped,
            5 => RangeStatus::OutOfBounds,
            3 => RangeStatus::HardwareFail,
            19 => RangeStatus::NoWrapCheckFail,
            7 => RangeStatus::WrapTargetFail,
            12 => RangeStatus::XtalkSignalFail,
            18 => RangeStatus::SynchronisationInt,
            22 => RangeStatus::MergedPulse,
            23 => RangeStatus::LackOfSignal,
            13 => RangeStatus::MinRangeFail,
            code => RangeStatus::Unknown(code),
        }
    }

    /// ST's status number (`VL53L1_RANGESTATUS_*`; 255 for [`RangeStatus::Unknown`]), for logs.
    pub const fn st_code(self) -> u8 {
        match self {
            RangeStatus::Valid => 0,
            RangeStatus::SigmaFail => 1,
            RangeStatus::SignalFail => 2,
            RangeStatus::MinRangeClipped => 3,
            RangeStatus::OutOfBounds => 4,
            RangeStatus::HardwareFail => 5,
            RangeStatus::NoWrapCheckFail => 6,
            RangeStatus::WrapTargetFail => 7,
            RangeStatus::XtalkSignalFail => 9,
            RangeStatus::SynchronisationInt => 10,
            RangeStatus::MergedPulse => 11,
            RangeStatus::LackOfSignal => 12,
            RangeStatus::MinRangeFail => 13,
            RangeStatus::Unknown(_) => 255,
        }
    }
}

/// One raw result: the range status and the distance register.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Measurement {
    /// The mapped range status.
    pub status: RangeStatus,
    /// RESULT__FINAL_CROSSTALK_CORRECTED_RANGE_MM_SD0, millimetres.
    pub distance_mm: u16,
}

impl Measurement {
    /// The distance in metres when the status is [`RangeStatus::Valid`], otherwise `None`.
    pub fn range_m(&self) -> RangeReading {
        match self.status {
            RangeStatus::Valid => Some(f32::from(self.distance_mm) / 1000.0),
            _ => None,
        }
    }
}

/// One VL53L1x: its current I2C address and the GPIO__TIO_HV_STATUS level that means "data ready".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Vl53l1x {
    address: u8,
    data_ready_level: bool,
}

/// Whether `address` is a usable 7-bit I2C address (not in the reserved 0x00..=0x07 and 0x78..=0x7F).
pub const fn is_valid_address(address: u8) -> bool {
    address >= 0x08 && address <= 0x77
}

/// The inter-measurement register value for `period_ms` given RESULT__OSC_CALIBRATE_VAL: ULD
/// `VL53L1X_SetInterMeasurementInMs` computes `(osc & 0x3FF) · ms · 1.075` truncated; done here in integers
/// (`· 1075 / 1000`, same result).
pub const fn inter_measurement_register(osc_calibrate_val: u16, period_ms: u32) -> u32 {
    let ticks = (osc_calibrate_val & 0x03FF) as u64 * period_ms as u64 * 1075 / 1000;
    if ticks > u32::MAX as u64 {
        u32::MAX
    } else {
        ticks as u32
    }
}

impl Vl53l1x {
    /// A sensor expected at `address` (use [`DEFAULT_ADDRESS`] for a chip fresh out of reset). Nothing
    /// is sent; the data-ready level starts at the default configuration's (active high).
    pub const fn new(address: u8) -> Self {
        Self {
            address,
            data_ready_level: true,
        }
    }

    /// The address the driver talks to.
    pub const fn address(&self) -> u8 {
        self.address
    }

    /// Full bring-up of a chip that has just left reset at [`DEFAULT_ADDRESS`]: wait for its boot, move it
    /// to `new_address` (skipped when that is the default address), then [`Vl53l1x::init`] there. Ranging is
    /// not started. A chip that has not answered yet at 0x29 (it NACKs while booting) is retried for
    /// [`BOOT_POLL_LIMIT`] polls.
    pub async fn bring_up<I: I2c, D: DelayNs>(
        i2c: &mut I,
        delay: &mut D,
        new_address: u8,
        config: &RangingConfig,
    ) -> Result<Self, DriverError<I::Error>> {
        if !is_valid_address(new_address) || !config.is_valid() {
            return Err(DriverError::InvalidConfig);
        }
        let mut sensor = Self::new(DEFAULT_ADDRESS);
        if new_address != DEFAULT_ADDRESS {
            sensor.wait_boot(i2c, delay).await?;
            sensor.set_address(i2c, new_address).await?;
        }
        sensor.init(i2c, delay, config).await?;
        Ok(sensor)
    }

    /// [`Vl53l1x::bring_up`] for a chip without a shutdown line (the Flow deck's z-ranger): after an
    /// STM32-only reset (watchdog, debugger) the ranger kept its power and so the address it was moved
    /// to, and no longer answers at [`DEFAULT_ADDRESS`]. One probe of FIRMWARE__SYSTEM_STATUS at
    /// `new_address` first: if the chip answers there it is initialised there (no move); otherwise the
    /// normal bring-up from the default address.
    pub async fn bring_up_or_find<I: I2c, D: DelayNs>(
        i2c: &mut I,
        delay: &mut D,
        new_address: u8,
        config: &RangingConfig,
    ) -> Result<Self, DriverError<I::Error>> {
        if !is_valid_address(new_address) || !config.is_valid() {
            return Err(DriverError::InvalidConfig);
        }
        if new_address != DEFAULT_ADDRESS {
            let mut moved = Self::new(new_address);
            if moved.read_u8(i2c, reg::FIRMWARE_SYSTEM_STATUS).await.is_ok() {
                moved.init(i2c, delay, config).await?;
                return Ok(moved);
            }
        }
        Self::bring_up(i2c, delay, new_address, config).await
    }

    /// Polls FIRMWARE__SYSTEM_STATUS until bit 0 (boot complete) is set, every [`POLL_INTERVAL_MS`], at most
    /// [`BOOT_POLL_LIMIT`] times. A bus error counts as "still booting" (the chip NACKs during boot); if the
    /// last poll was a bus error the result is that error (chip absent), otherwise [`DriverError::Timeout`].
    pub async fn wait_boot<I: I2c, D: DelayNs>(
        &mut self,
        i2c: &mut I,
        delay: &mut D,
    ) -> Result<(), DriverError<I::Error>> {
        let mut last_bus_error = None;
        for poll in 0..BOOT_POLL_LIMIT {
            match self.read_u8(i2c, reg::FIRMWARE_SYSTEM_STATUS).await {
                Ok(status) if status & 0x01 == 0x01 => return Ok(()),
                Ok(_) => last_bus_error = None,
                Err(error) => last_bus_error = Some(error),
            }
            if poll + 1 < BOOT_POLL_LIMIT {
                delay.delay_ms(POLL_INTERVAL_MS).await;
            }
        }
        Err(match last_bus_error {
            Some(error) => DriverError::Bus(error),
            None => DriverError::Timeout,
        })
    }

    /// Reads IDENTIFICATION__MODEL_ID.
    pub async fn read_model_id<I: I2c>(&mut self, i2c: &mut I) -> Result<u16, DriverError<I::Error>> {
        self.read_u16(i2c, reg::IDENTIFICATION_MODEL_ID).await
    }

    /// ULD initialisation at the current address: boot poll, model id check (0xEACC), ST's default
    /// configuration (with the 2V8 pad bit from `config`), the interrupt polarity read, the VHV step (start
    /// ranging, wait for the first data-ready, clear the interrupt, stop, VHV loop bound 0x09, VHV init 0),
    /// then `config`'s distance mode, timing budget and inter-measurement period. Ranging is left stopped.
    pub async fn init<I: I2c, D: DelayNs>(
        &mut self,
        i2c: &mut I,
        delay: &mut D,
        config: &RangingConfig,
    ) -> Result<(), DriverError<I::Error>> {
        if !config.is_valid() {
            return Err(DriverError::InvalidConfig);
        }
        self.wait_boot(i2c, delay).await?;
        let model_id = self.read_model_id(i2c).await?;
        if model_id != MODEL_ID {
            return Err(DriverError::WrongChipId {
                expected: MODEL_ID,
                found: model_id,
            });
        }
        self.write_default_configuration(i2c, config.io_2v8).await?;
        self.read_interrupt_polarity(i2c).await?;

        // VHV (temperature) calibration on a first range, as ULD `VL53L1X_SensorInit`.
        self.start_ranging(i2c).await?;
        self.wait_data_ready(i2c, delay, VHV_POLL_LIMIT).await?;
        self.clear_interrupt(i2c).await?;
        self.stop_ranging(i2c).await?;
        self.write_u8(i2c, reg::VHV_CONFIG_TIMEOUT_MACROP_LOOP_BOUND, 0x09)
            .await?;
        self.write_u8(i2c, reg::VHV_CONFIG_INIT, 0x00).await?;

        self.set_distance_mode_and_budget(i2c, config.distance_mode, config.timing_budget)
            .await?;
        self.set_inter_measurement_ms(i2c, config.inter_measurement_ms).await
    }

    /// Writes ST's 91-byte default configuration from 0x002D in one transfer, with bit 0 of 0x002E set
    /// when `io_2v8`.
    pub async fn write_default_configuration<I: I2c>(
        &mut self,
        i2c: &mut I,
        io_2v8: bool,
    ) -> Result<(), DriverError<I::Error>> {
        let mut frame = [0u8; 2 + DEFAULT_CONFIGURATION.len()];
        frame[..2].copy_from_slice(&DEFAULT_CONFIGURATION_FIRST_REGISTER.to_be_bytes());
        frame[2..].copy_from_slice(&DEFAULT_CONFIGURATION);
        if io_2v8 {
            let pad = 2 + usize::from(reg::PAD_I2C_HV_EXTSUP_CONFIG - DEFAULT_CONFIGURATION_FIRST_REGISTER);
            frame[pad] |= 0x01;
        }
        i2c.write(self.address, &frame).await?;
        Ok(())
    }

    /// Reads GPIO_HV_MUX__CTRL and remembers which GPIO__TIO_HV_STATUS level means data ready (ULD
    /// `VL53L1X_GetInterruptPolarity`: bit 4 clear = active high = ready when status bit 0 is 1).
    pub async fn read_interrupt_polarity<I: I2c>(&mut self, i2c: &mut I) -> Result<(), DriverError<I::Error>> {
        let mux = self.read_u8(i2c, reg::GPIO_HV_MUX_CTRL).await?;
        self.data_ready_level = mux & 0x10 == 0;
        Ok(())
    }

    /// Writes the distance mode's register set, then the timing budget's two timeouts for that mode
    /// (ULD `VL53L1X_SetDistanceMode` + `VL53L1X_SetTimingBudgetInMs`). Refuses (before any write) a budget
    /// the mode does not have.
    pub async fn set_distance_mode_and_budget<I: I2c>(
        &mut self,
        i2c: &mut I,
        mode: DistanceMode,
        budget: TimingBudget,
    ) -> Result<(), DriverError<I::Error>> {
        let Some((timeout_a, timeout_b)) = budget.timeout_macrop_a_b(mode) else {
            return Err(DriverError::InvalidConfig);
        };
        let regs = mode.registers();
        self.write_u8(i2c, reg::PHASECAL_CONFIG_TIMEOUT_MACROP, regs.phasecal_timeout_macrop)
            .await?;
        self.write_u8(i2c, reg::RANGE_CONFIG_VCSEL_PERIOD_A, regs.vcsel_period_a)
            .await?;
        self.write_u8(i2c, reg::RANGE_CONFIG_VCSEL_PERIOD_B, regs.vcsel_period_b)
            .await?;
        self.write_u8(i2c, reg::RANGE_CONFIG_VALID_PHASE_HIGH, regs.valid_phase_high)
            .await?;
        self.write_u16(i2c, reg::SD_CONFIG_WOI_SD0, regs.woi_sd0).await?;
        self.write_u16(i2c, reg::SD_CONFIG_INITIAL_PHASE_SD0, regs.initial_phase_sd0)
            .await?;
        self.write_u16(i2c, reg::RANGE_CONFIG_TIMEOUT_MACROP_A, timeout_a)
            .await?;
        self.write_u16(i2c, reg::RANGE_CONFIG_TIMEOUT_MACROP_B, timeout_b).await
    }

    /// Reads the oscillator calibration and writes the inter-measurement period for `period_ms`
    /// (see [`inter_measurement_register`]). Refuses 0 and periods above [`MAX_INTER_MEASUREMENT_MS`].
    pub async fn set_inter_measurement_ms<I: I2c>(
        &mut self,
        i2c: &mut I,
        period_ms: u32,
    ) -> Result<(), DriverError<I::Error>> {
        if period_ms == 0 || period_ms > MAX_INTER_MEASUREMENT_MS {
            return Err(DriverError::InvalidConfig);
        }
        let osc = self.read_u16(i2c, reg::RESULT_OSC_CALIBRATE_VAL).await?;
        let value = inter_measurement_register(osc, period_ms);
        self.write_u32(i2c, reg::SYSTEM_INTERMEASUREMENT_PERIOD, value).await
    }

    /// Moves the chip to `new_address` (7-bit) by writing I2C_SLAVE__DEVICE_ADDRESS at the current address;
    /// from then on the driver uses the new one. The chip forgets it on reset or XSHUT. Refuses reserved
    /// addresses without sending anything.
    pub async fn set_address<I: I2c>(&mut self, i2c: &mut I, new_address: u8) -> Result<(), DriverError<I::Error>> {
        if !is_valid_address(new_address) {
            return Err(DriverError::InvalidConfig);
        }
        self.write_u8(i2c, reg::I2C_SLAVE_DEVICE_ADDRESS, new_address).await?;
        self.address = new_address;
        Ok(())
    }

    /// Starts continuous ranging (SYSTEM__MODE_START = 0x40).
    pub async fn start_ranging<I: I2c>(&mut self, i2c: &mut I) -> Result<(), DriverError<I::Error>> {
        self.write_u8(i2c, reg::SYSTEM_MODE_START, 0x40).await
    }

    /// Stops ranging (SYSTEM__MODE_START = 0x00).
    pub async fn stop_ranging<I: I2c>(&mut self, i2c: &mut I) -> Result<(), DriverError<I::Error>> {
        self.write_u8(i2c, reg::SYSTEM_MODE_START, 0x00).await
    }

    /// Clears the data-ready interrupt so the next range can raise it (SYSTEM__INTERRUPT_CLEAR = 0x01).
    pub async fn clear_interrupt<I: I2c>(&mut self, i2c: &mut I) -> Result<(), DriverError<I::Error>> {
        self.write_u8(i2c, reg::SYSTEM_INTERRUPT_CLEAR, 0x01).await
    }

    /// Whether a new range is waiting: GPIO__TIO_HV_STATUS bit 0 equals the active interrupt level.
    pub async fn data_ready<I: I2c>(&mut self, i2c: &mut I) -> Result<bool, DriverError<I::Error>> {
        let status = self.read_u8(i2c, reg::GPIO_TIO_HV_STATUS).await?;
        Ok((status & 0x01 == 0x01) == self.data_ready_level)
    }

    /// Polls [`Vl53l1x::data_ready`] every [`POLL_INTERVAL_MS`] up to `poll_limit` times; a bus error ends
    /// the wait at once, no data within the limit is [`DriverError::Timeout`].
    pub async fn wait_data_ready<I: I2c, D: DelayNs>(
        &mut self,
        i2c: &mut I,
        delay: &mut D,
        poll_limit: u32,
    ) -> Result<(), DriverError<I::Error>> {
        for poll in 0..poll_limit {
            if self.data_ready(i2c).await? {
                return Ok(());
            }
            if poll + 1 < poll_limit {
                delay.delay_ms(POLL_INTERVAL_MS).await;
            }
        }
        Err(DriverError::Timeout)
    }

    /// Reads RESULT__RANGE_STATUS and the distance register (does not clear the interrupt).
    pub async fn read_measurement<I: I2c>(&mut self, i2c: &mut I) -> Result<Measurement, DriverError<I::Error>> {
        let raw_status = self.read_u8(i2c, reg::RESULT_RANGE_STATUS).await?;
        let distance_mm = self.read_u16(i2c, reg::RESULT_FINAL_RANGE_MM_SD0).await?;
        Ok(Measurement {
            status: RangeStatus::from_register(raw_status),
            distance_mm,
        })
    }

    /// Reads the waiting range and clears the interrupt: `Some(metres)` for a valid status, `None` for any
    /// other (the interrupt is cleared either way). Call it once [`Vl53l1x::data_ready`] says so.
    pub async fn read_range<I: I2c>(&mut self, i2c: &mut I) -> Result<RangeReading, DriverError<I::Error>> {
        let measurement = self.read_measurement(i2c).await?;
        self.clear_interrupt(i2c).await?;
        Ok(measurement.range_m())
    }

    async fn read_u8<I: I2c>(&mut self, i2c: &mut I, register: u16) -> Result<u8, I::Error> {
        let mut value = [0u8; 1];
        i2c.write_read(self.address, &register.to_be_bytes(), &mut value)
            .await?;
        Ok(value[0])
    }

    async fn read_u16<I: I2c>(&mut self, i2c: &mut I, register: u16) -> Result<u16, DriverError<I::Error>> {
        let mut value = [0u8; 2];
        i2c.write_read(self.address, &register.to_be_bytes(), &mut value)
            .await?;
        Ok(u16::from_be_bytes(value))
    }

    async fn write_u8<I: I2c>(&mut self, i2c: &mut I, register: u16, value: u8) -> Result<(), DriverError<I::Error>> {
        let [hi, lo] = register.to_be_bytes();
        i2c.write(self.address, &[hi, lo, value]).await?;
        Ok(())
    }

    async fn write_u16<I: I2c>(&mut self, i2c: &mut I, register: u16, value: u16) -> Result<(), DriverError<I::Error>> {
        let [hi, lo] = register.to_be_bytes();
        let [v1, v0] = value.to_be_bytes();
        i2c.write(self.address, &[hi, lo, v1, v0]).await?;
        Ok(())
    }

    async fn write_u32<I: I2c>(&mut self, i2c: &mut I, register: u16, value: u32) -> Result<(), DriverError<I::Error>> {
        let [hi, lo] = register.to_be_bytes();
        let [v3, v2, v1, v0] = value.to_be_bytes();
        i2c.write(self.address, &[hi, lo, v3, v2, v1, v0]).await?;
        Ok(())
    }
}
