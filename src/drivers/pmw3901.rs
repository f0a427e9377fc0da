//! PMW3901 optical-flow sensor on the Flow deck v2 (deck SPI1, chip select IO3 = PB4, SPI mode 0 at
//! ~1.3 MHz as stock; `docs/hardware.md` §2).
//!
//! Job: power the sensor up with the vendor sequence, then read one motion burst per call (stock: every
//! 10 ms, 100 Hz) and turn it into a [`FlowSample`] in the body frame with the stock Flow-deck axis mapping
//! and validity rule.
//!
//! Non-goals: no scheduling (the caller reads at 100 Hz), no outlier rejection or filtering (the estimator
//! gates |dpixel| ≥ 100 counts, SQUAL and dt itself, see `src/flight/estimator/`), no frame capture, no
//! chip-select handling (the [`SpiDevice`] owns CS), no VL53L1x (another driver).
//!
//! ## Sources
//!
//! - Register protocol and timing, power-up order, the motion-burst layout: bitcraze crazyflie-firmware
//!   `src/drivers/src/pmw3901.c` (`registerWrite`, `registerRead`, `pmw3901Init`, `pmw3901ReadMotion`) and
//!   `src/drivers/interface/pmw3901.h` (`motionBurst_t`); register names/addresses also in PixArt's
//!   PMW3901MB datasheet (Product_ID 0x00, Motion 0x02, Delta_X_L..Delta_Y_H 0x03..0x06, Motion_Burst 0x16,
//!   Power_Up_Reset 0x3A, Inverse_Product_ID 0x5F; cross-checked with libdriver/pmw3901mb
//!   `src/driver_pmw3901mb.c`).
//! - The "performance optimisation" register table ([`PERFORMANCE_OPTIMISATION`]): the vendor's
//!   undocumented-register sequence as transcribed by Bitcraze in `pmw3901.c` `InitRegisters` (same values
//!   in bitcraze/Bitcraze_PMW3901 `initRegisters`), including the 10 ms pause after `0x70 ← 0x00`.
//! - Axis mapping and validity: crazyflie-firmware `src/deck/drivers/src/flowdeck_v1v2.c` `flowdeckTask`
//!   (`accpx = -deltaY`, `accpy = -deltaX`, pushed only if `motion == 0xB0`), plus the datasheet's rule to
//!   discard motion when SQUAL < 0x19 **and** Shutter_Upper = 0x1F (as implemented in
//!   pimoroni/pmw3901-python `get_motion`), which only rejects more.
//!
//! ## SPI timing
//!
//! Every access is one [`SpiDevice`] transaction (CS low … CS high) with the stock driver's delays (they have
//! flown on this deck for years; the PMW3901 datasheet's SPI timing table could not be consulted here, so
//! its minima, tSRAD etc., are not restated — the stock values are long for this class of PixArt sensor):
//! - write: 50 µs, `reg | 0x80`, 50 µs, value, 50 µs; then 200 µs with CS high before the next access;
//! - read: 50 µs, `reg & 0x7F`, **500 µs**, one byte clocked out, 50 µs; then 200 µs with CS high;
//! - motion burst: 50 µs, 0x16, 50 µs, 12 bytes, 50 µs; then 50 µs with CS high.
//!
//! The in-transaction delays are [`Operation::DelayNs`] (CS stays low); the gaps with CS high are
//! [`DelayNs`] calls on the delay the caller passes (the board's `SpiDevice` must support
//! `Operation::DelayNs`: embassy-embedded-hal needs its `time` feature). One motion read takes ≈ 0.3 ms
//! (150 µs of in-transaction waits, 13 bytes at ~1.3 MHz, 50 µs gap); [`Pmw3901::init`] ≈ 95 ms (40 ms
//! power-up wait, 6 ms SPI-port reset, 7 register reads of ≈ 0.8 ms, 5 ms after the power-up reset, 1 ms,
//! 76 table writes of ≈ 0.37 ms, the 10 ms table pause).
//!
//! ## Output
//!
//! Motion burst (12 bytes from 0x16): motion, observation, Delta_X (i16 little-endian), Delta_Y (i16
//! little-endian), SQUAL, Raw_Data_Sum, Maximum_Raw_Data, Minimum_Raw_Data, Shutter (u16 **big-endian**:
//! upper byte first; stock swaps it). The deltas are counts accumulated since the previous burst read
//! (reading resets them), so [`FlowSample::dt_s`] is the time since the previous successful read.
//! `dpixel_x = −Delta_Y`, `dpixel_y = −Delta_X` (saturating, so −32768 maps to 32767): the sensor looks
//! down through the deck, rotated against the body frame; this is the stock mapping the stock Kalman flow
//! model (`mm_flow.c`) and this project's estimator and simulator (`tools/sim/src/sensors.rs`
//! `FlowSensor`) expect. `motion_valid` = (motion byte == 0xB0) and not (SQUAL < 0x19 and Shutter_Upper ==
//! 0x1F).
//!
//! Memory: the driver holds the SPI device plus 16 bytes (the previous read's timestamp,
//! `size_of::<Pmw3901<()>>() == 16`, tested); a read uses a 12-byte stack buffer; the register table is
//! 77 × 8 bytes of flash.

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::spi::{Operation, SpiDevice};

use super::DriverError;
use crate::types::{FlowSample, Micros};

/// Product_ID (register 0x00) of the PMW3901.
pub const PRODUCT_ID: u8 = 0x49;
/// Inverse_Product_ID (register 0x5F): the bitwise inverse of [`PRODUCT_ID`].
pub const INVERSE_PRODUCT_ID: u8 = 0xB6;
/// Stock read period of the Flow deck, s (100 Hz); also the `dt_s` reported for the first reading.
pub const READ_PERIOD_S: f32 = 0.01;
/// Motion byte of a valid reading as the stock Flow-deck driver requires it (MOT set, bits 5:4 set).
pub const MOTION_VALID: u8 = 0xB0;
/// Datasheet rejection rule: SQUAL below this …
pub const SQUAL_MIN_WHEN_SHUTTER_MAX: u8 = 0x19;
/// … while Shutter_Upper is at this (maximum exposure: too dark to track) means the deltas are unusable.
pub const SHUTTER_UPPER_MAX: u8 = 0x1F;

/// Register addresses (PMW3901MB datasheet; stock `pmw3901.c`).
mod reg {
    pub const PRODUCT_ID: u8 = 0x00;
    pub const MOTION: u8 = 0x02;
    pub const DELTA_Y_H: u8 = 0x06;
    pub const MOTION_BURST: u8 = 0x16;
    pub const POWER_UP_RESET: u8 = 0x3A;
    pub const INVERSE_PRODUCT_ID: u8 = 0x5F;
}

/// Power_Up_Reset command value.
const POWER_UP_RESET_CMD: u8 = 0x5A;
/// Bit 7 of the address byte: 1 = write, 0 = read.
const WRITE_BIT: u8 = 0x80;

const NS_PER_US: u32 = 1_000;
/// CS low to first clock, between bytes of a write, last clock to CS high (stock `sleepus(50)`).
const SETUP_NS: u32 = 50 * NS_PER_US;
/// Address to data of a single-register read (stock `sleepus(500)`).
const READ_ADDRESS_TO_DATA_NS: u32 = 500 * NS_PER_US;
/// CS high after a register access before the next one (stock `sleepus(200)`).
const REGISTER_GAP_US: u32 = 200;
/// CS high after a motion burst (stock `sleepus(50)`).
const BURST_GAP_US: u32 = 50;
/// Wait after power-up before the first access (stock `vTaskDelay(M2T(40))`).
const POWER_UP_WAIT_MS: u32 = 40;
/// CS high / low / high phases that reset the SPI port (stock, 2 ms each; datasheet power-up step 2).
const SPI_RESET_PHASE_MS: u32 = 2;
/// After Power_Up_Reset (stock and datasheet: 5 ms).
const POWER_UP_RESET_WAIT_MS: u32 = 5;
/// After the first reads of 0x02..0x06 (stock 1 ms).
const AFTER_MOTION_READS_MS: u32 = 1;

/// One step of the vendor's performance-optimisation sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InitStep {
    /// Write `value` to `register` (register 0x7F selects the bank of the following writes).
    Write {
        /// Register address (bit 7 clear).
        register: u8,
        /// Value.
        value: u8,
    },
    /// Wait this many milliseconds.
    PauseMs(u32),
}

const fn w(register: u8, value: u8) -> InitStep {
    InitStep::Write { register, value }
}

/// The performance-optimisation register sequence written after the power-up reset. Source:
/// bitcraze crazyflie-firmware `src/drivers/src/pmw3901.c` `InitRegisters` (PixArt's values for
/// undocumented registers; 0x7F is the bank select).
pub const PERFORMANCE_OPTIMISATION: &[InitStep] = &[
    w(0x7F, 0x00),
    w(0x61, 0xAD),
    w(0x7F, 0x03),
    w(0x40, 0x00),
    w(0x7F, 0x05),
    w(0x41, 0xB3),
    w(0x43, 0xF1),
    w(0x45, 0x14),
    w(0x5B, 0x32),
    w(0x5F, 0x34),
    w(0x7B, 0x08),
    w(0x7F, 0x06),
    w(0x44, 0x1B),
    w(0x40, 0xBF),
    w(0x4E, 0x3F),
    w(0x7F, 0x08),
    w(0x65, 0x20),
    w(0x6A, 0x18),
    w(0x7F, 0x09),
    w(0x4F, 0xAF),
    w(0x5F, 0x40),
    w(0x48, 0x80),
    w(0x49, 0x80),
    w(0x57, 0x77),
    w(0x60, 0x78),
    w(0x61, 0x78),
    w(0x62, 0x08),
    w(0x63, 0x50),
    w(0x7F, 0x0A),
    w(0x45, 0x60),
    w(0x7F, 0x00),
    w(0x4D, 0x11),
    w(0x55, 0x80),
    w(0x74, 0x1F),
    w(0x75, 0x1F),
    w(0x4A, 0x78),
    w(0x4B, 0x78),
    w(0x44, 0x08),
    w(0x45, 0x50),
    w(0x64, 0xFF),
    w(0x65, 0x1F),
    w(0x7F, 0x14),
    w(0x65, 0x67),
    w(0x66, 0x08),
    w(0x63, 0x70),
    w(0x7F, 0x15),
    w(0x48, 0x48),
    w(0x7F, 0x07),
    w(0x41, 0x0D),
    w(0x43, 0x14),
    w(0x4B, 0x0E),
    w(0x45, 0x0F),
    w(0x44, 0x42),
    w(0x4C, 0x80),
    w(0x7F, 0x10),
    w(0x5B, 0x02),
    w(0x7F, 0x07),
    w(0x40, 0x41),
    w(0x70, 0x00),
    InitStep::PauseMs(10),
    w(0x32, 0x44),
    w(0x7F, 0x07),
    w(0x40, 0x40),
    w(0x7F, 0x06),
    w(0x62, 0xF0),
    w(0x63, 0x00),
    w(0x7F, 0x0D),
    w(0x48, 0xC0),
    w(0x6F, 0xD5),
    w(0x7F, 0x00),
    w(0x5B, 0xA0),
    w(0x4E, 0xA8),
    w(0x5A, 0x50),
    w(0x40, 0x80),
    w(0x7F, 0x00),
    w(0x5A, 0x10),
    w(0x54, 0x00),
];

/// One motion burst as the chip sends it (12 bytes from register 0x16).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MotionBurst {
    /// Motion register: bit 7 MOT (motion since last read), other bits operating state.
    pub motion: u8,
    /// Observation register.
    pub observation: u8,
    /// Accumulated motion along the sensor's x, counts.
    pub delta_x: i16,
    /// Accumulated motion along the sensor's y, counts.
    pub delta_y: i16,
    /// Surface quality (number of features / 4 in PixArt's description), 0..=255.
    pub squal: u8,
    /// Raw_Data_Sum.
    pub raw_data_sum: u8,
    /// Maximum_Raw_Data.
    pub max_raw_data: u8,
    /// Minimum_Raw_Data.
    pub min_raw_data: u8,
    /// Shutter (exposure) time, clock cycles; upper byte first on the wire.
    pub shutter: u16,
}

/// Length of a motion burst, bytes.
pub const MOTION_BURST_LEN: usize = 12;

impl MotionBurst {
    /// Decodes the 12 bytes of a burst (layout in the module doc).
    pub fn parse(b: &[u8; MOTION_BURST_LEN]) -> Self {
        Self {
            motion: b[0],
            observation: b[1],
            delta_x: i16::from_le_bytes([b[2], b[3]]),
            delta_y: i16::from_le_bytes([b[4], b[5]]),
            squal: b[6],
            raw_data_sum: b[7],
            max_raw_data: b[8],
            min_raw_data: b[9],
            shutter: u16::from_be_bytes([b[10], b[11]]),
        }
    }

    /// The upper byte of the shutter register.
    pub fn shutter_upper(&self) -> u8 {
        self.shutter.to_be_bytes()[0]
    }

    /// Stock's rule (motion byte == 0xB0) and the datasheet's low-light rule (not SQUAL < 0x19 with the
    /// shutter at its maximum).
    pub fn is_valid(&self) -> bool {
        let too_dark = self.squal < SQUAL_MIN_WHEN_SHUTTER_MAX && self.shutter_upper() == SHUTTER_UPPER_MAX;
        self.motion == MOTION_VALID && !too_dark
    }

    /// The body-frame sample (stock Flow-deck mapping `dpixel_x = −Δy`, `dpixel_y = −Δx`).
    pub fn to_sample(&self, dt_s: f32) -> FlowSample {
        FlowSample {
            dpixel_x: self.delta_y.saturating_neg(),
            dpixel_y: self.delta_x.saturating_neg(),
            squal: self.squal,
            motion_valid: self.is_valid(),
            dt_s,
        }
    }
}

/// The PMW3901 behind one SPI device.
#[derive(Debug)]
pub struct Pmw3901<S> {
    spi: S,
    last_read_us: Option<Micros>,
}

impl<S: SpiDevice> Pmw3901<S> {
    /// A driver for the sensor on `spi`; nothing is sent until [`Pmw3901::init`].
    pub fn new(spi: S) -> Self {
        Self {
            spi,
            last_read_us: None,
        }
    }

    /// Gives the SPI device back.
    pub fn release(self) -> S {
        self.spi
    }

    /// Power-up sequence (stock order): wait 40 ms, pulse CS to reset the SPI port, check Product_ID and
    /// Inverse_Product_ID, Power_Up_Reset, read 0x02..=0x06 once, then the performance-optimisation table.
    /// The identity is checked before anything is written, so nothing is sent to a chip that is not a
    /// PMW3901 (an absent deck reads 0x00 or 0xFF).
    pub async fn init<D: DelayNs>(&mut self, delay: &mut D) -> Result<(), DriverError<S::Error>> {
        self.last_read_us = None;
        delay.delay_ms(POWER_UP_WAIT_MS).await;
        // CS high (idle) 2 ms, low 2 ms with no clock, high 2 ms: resets the chip's SPI port.
        delay.delay_ms(SPI_RESET_PHASE_MS).await;
        self.spi
            .transaction(&mut [Operation::DelayNs(SPI_RESET_PHASE_MS * 1_000_000)])
            .await?;
        delay.delay_ms(SPI_RESET_PHASE_MS).await;

        let id = self.read_register(reg::PRODUCT_ID, delay).await?;
        if id != PRODUCT_ID {
            return Err(DriverError::WrongChipId {
                expected: u16::from(PRODUCT_ID),
                found: u16::from(id),
            });
        }
        let inverse = self.read_register(reg::INVERSE_PRODUCT_ID, delay).await?;
        if inverse != INVERSE_PRODUCT_ID {
            return Err(DriverError::WrongChipId {
                expected: u16::from(INVERSE_PRODUCT_ID),
                found: u16::from(inverse),
            });
        }

        self.write_register(reg::POWER_UP_RESET, POWER_UP_RESET_CMD, delay)
            .await?;
        delay.delay_ms(POWER_UP_RESET_WAIT_MS).await;
        // The datasheet asks for one read of Motion and the delta registers after the reset, whatever
        // the motion pin says; the values are discarded.
        for register in reg::MOTION..=reg::DELTA_Y_H {
            self.read_register(register, delay).await?;
        }
        delay.delay_ms(AFTER_MOTION_READS_MS).await;

        for step in PERFORMANCE_OPTIMISATION {
            match *step {
                InitStep::Write { register, value } => self.write_register(register, value, delay).await?,
                InitStep::PauseMs(ms) => delay.delay_ms(ms).await,
            }
        }
        Ok(())
    }

    /// Reads one register (single-byte read with the stock timing).
    pub async fn read_register<D: DelayNs>(
        &mut self,
        register: u8,
        delay: &mut D,
    ) -> Result<u8, DriverError<S::Error>> {
        let mut value = [0u8; 1];
        self.spi
            .transaction(&mut [
                Operation::DelayNs(SETUP_NS),
                Operation::Write(&[register & !WRITE_BIT]),
                Operation::DelayNs(READ_ADDRESS_TO_DATA_NS),
                Operation::Read(&mut value),
                Operation::DelayNs(SETUP_NS),
            ])
            .await?;
        delay.delay_us(REGISTER_GAP_US).await;
        Ok(value[0])
    }

    /// Writes one register (address with bit 7 set, then the value, with the stock timing).
    pub async fn write_register<D: DelayNs>(
        &mut self,
        register: u8,
        value: u8,
        delay: &mut D,
    ) -> Result<(), DriverError<S::Error>> {
        self.spi
            .transaction(&mut [
                Operation::DelayNs(SETUP_NS),
                Operation::Write(&[register | WRITE_BIT]),
                Operation::DelayNs(SETUP_NS),
                Operation::Write(&[value]),
                Operation::DelayNs(SETUP_NS),
            ])
            .await?;
        delay.delay_us(REGISTER_GAP_US).await;
        Ok(())
    }

    /// Reads one motion burst (resets the chip's delta accumulators).
    pub async fn read_motion_burst<D: DelayNs>(&mut self, delay: &mut D) -> Result<MotionBurst, DriverError<S::Error>> {
        let mut b = [0u8; MOTION_BURST_LEN];
        self.spi
            .transaction(&mut [
                Operation::DelayNs(SETUP_NS),
                Operation::Write(&[reg::MOTION_BURST]),
                Operation::DelayNs(SETUP_NS),
                Operation::Read(&mut b),
                Operation::DelayNs(SETUP_NS),
            ])
            .await?;
        delay.delay_us(BURST_GAP_US).await;
        Ok(MotionBurst::parse(&b))
    }

    /// Reads the motion since the previous read and returns it as a body-frame [`FlowSample`]; `now_us` is
    /// the time of this read (its `dt_s` is the time since the previous successful read, or
    /// [`READ_PERIOD_S`] for the first read or when the clock did not advance). A bus error leaves the
    /// previous timestamp in place, so the next sample's `dt_s` spans the motion it accumulates.
    pub async fn read<D: DelayNs>(
        &mut self,
        now_us: Micros,
        delay: &mut D,
    ) -> Result<FlowSample, DriverError<S::Error>> {
        let burst = self.read_motion_burst(delay).await?;
        let dt_s = match self.last_read_us {
            Some(previous) if now_us > previous => (now_us - previous) as f32 * 1e-6,
            _ => READ_PERIOD_S,
        };
        self.last_read_us = Some(now_us);
        Ok(burst.to_sample(dt_s))
    }
}

/// How one flow read ended, as the board saw it (the input of [`ReadHealth::record`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadOutcome {
    /// A burst was read (valid or not: the chip answered).
    Read,
    /// The bus reported an error.
    BusError,
    /// The transfer did not finish within the board's deadline and was abandoned (its DMA stopped, chip
    /// select raised): a byte lost on the bus, a deck unplugged mid-burst.
    Timeout,
}

/// What the board should do after a read ([`ReadHealth::record`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecoveryAction {
    /// Nothing: read again at the next period (a failed read's burst is dropped; the next burst carries the
    /// motion it accumulated, and [`Pmw3901::read`] keeps the previous timestamp so its `dt_s` spans it).
    None,
    /// Re-synchronise the chip with its own power-up sequence ([`Pmw3901::init`]: the CS pulse that resets
    /// its SPI port, the identity check, Power_Up_Reset and the vendor table), then read again.
    Resync,
}

/// Counters of [`ReadHealth`] (for the board's log lines).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadStats {
    /// Reads abandoned at the deadline.
    pub timeouts: u32,
    /// Reads that ended in a bus error.
    pub bus_errors: u32,
    /// Re-synchronisations started.
    pub resyncs: u32,
    /// Re-synchronisations that failed (the chip did not answer its identity or the bus failed again).
    pub failed_resyncs: u32,
}

/// The flow read's recovery policy, sans-IO: counts the failures and asks for a re-synchronisation of the
/// chip when [`RESYNC_AFTER_FAILURES`] reads in a row failed. One failed read is only dropped (a glitch);
/// a repeated one means the chip's SPI port may be out of step (the datasheet's power-up step 2 resets
/// it: CS high, low, high). After a re-synchronisation the count starts again, so a deck that stays
/// absent is retried every [`RESYNC_AFTER_FAILURES`] periods (20 ms at 100 Hz, ≈ 60 ms of bus time each,
/// on the flow task only). Memory: 17 bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadHealth {
    failures_in_a_row: u8,
    stats: ReadStats,
}

/// Failed reads in a row that trigger [`RecoveryAction::Resync`].
pub const RESYNC_AFTER_FAILURES: u8 = 2;

impl ReadHealth {
    /// No failures yet.
    pub const fn new() -> Self {
        Self {
            failures_in_a_row: 0,
            stats: ReadStats {
                timeouts: 0,
                bus_errors: 0,
                resyncs: 0,
                failed_resyncs: 0,
            },
        }
    }

    /// Records how a read ended; returns what to do next.
    pub fn record(&mut self, outcome: ReadOutcome) -> RecoveryAction {
        match outcome {
            ReadOutcome::Read => {
                self.failures_in_a_row = 0;
                return RecoveryAction::None;
            }
            ReadOutcome::BusError => self.stats.bus_errors = self.stats.bus_errors.saturating_add(1),
            ReadOutcome::Timeout => self.stats.timeouts = self.stats.timeouts.saturating_add(1),
        }
        self.failures_in_a_row = self.failures_in_a_row.saturating_add(1);
        if self.failures_in_a_row >= RESYNC_AFTER_FAILURES {
            self.failures_in_a_row = 0;
            self.stats.resyncs = self.stats.resyncs.saturating_add(1);
            RecoveryAction::Resync
        } else {
            RecoveryAction::None
        }
    }

    /// Records the end of a re-synchronisation the last [`ReadHealth::record`] asked for.
    pub fn record_resync(&mut self, ok: bool) {
        if !ok {
            self.stats.failed_resyncs = self.stats.failed_resyncs.saturating_add(1);
        }
    }

    /// The counters.
    pub fn stats(&self) -> ReadStats {
        self.stats
    }

    /// Failures since the last successful read or re-synchronisation.
    pub fn failures_in_a_row(&self) -> u8 {
        self.failures_in_a_row
    }
}
