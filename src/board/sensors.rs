//! The deck sensors and the on-board EEPROM: the seams between the drivers in `cfnav::drivers` and the
//! flight stack.
//!
//! * Flow deck v2: PMW3901 on SPI1 (SCK PA5, MISO PA6, MOSI PA7; mode 0, ~1.3 MHz as stock) with its chip
//!   select on deck IO3 = PB4 (`docs/hardware.md` §2), read at 100 Hz → [`FastInput::Flow`]. Its
//!   VL53L1x height ranger (deck I2C1, moved to 0x6A) → [`FastInput::ZRange`] at 40 Hz.
//! * Multi-ranger: PCA95x4 expander at 0x20 on I2C1 and five VL53L1x (0x6B..0x6F) →
//!   [`super::NavInput::MultiRanger`] at 10 Hz, with the latest estimate, and [`FastInput::MultiRanger`]
//!   (the estimator's wall anchors).
//!
//! Bring-up order on the deck bus (`cfnav::drivers::multiranger`): the expander holds the five Multi-ranger
//! sensors in reset first, so only the Flow deck's ranger answers at 0x29; it moves to 0x6A; then the
//! Multi-ranger sensors come up one by one. One task owns I2C1 afterwards and reads both decks without
//! waiting on any sensor ([`deck_task`]).
//! * EEPROM at 0x50 on I2C1: the config block (radio settings), read once at boot; persistent-parameter
//!   writes (`super::eeprom`) between readings.
//!
//! Deck presence is decided by probing at boot (the PMW3901's identity, the expander answering); the
//! mission may only start when every sensor it needs is present *and* has a reader running
//! ([`super::DECKS_OK`]).

use cfnav::drivers::DriverError;
use cfnav::drivers::multiranger::{DeckReader, FIRST_ADDRESS, FLOW_DECK_Z_ADDRESS, MultiRanger};
use cfnav::drivers::pca95x4;
use cfnav::drivers::pmw3901::{Pmw3901, ReadHealth, ReadOutcome, RecoveryAction};
use cfnav::drivers::vl53l1x::{RangingConfig, Vl53l1x};
use cfnav::stack::BEAM_MIDPOINT_US;
use cfnav::system::config_block::{EEPROM_I2C_ADDRESS, READ_LEN, RadioSettings};
use cfnav::types::RangeReading;
use defmt::{info, warn};
use embassy_stm32::gpio::Output;
use embassy_stm32::mode::Async;
use embassy_stm32::spi::Spi;
use embassy_stm32::spi::mode::Master as SpiMaster;
use embassy_time::{Delay, Duration, Instant, Ticker, Timer, with_timeout};
use embedded_hal_async::i2c::I2c as _;
use embedded_hal_async::spi::{ErrorType, Operation, SpiDevice};

use super::i2c_bus::DeckI2c;
use super::{FAST_INPUTS, FastInput, NAV_INPUTS, NO_RANGE_MM, NavInput, fast_status, now_us, update_log};

/// Deadline of one boot-time I2C transfer on the deck bus (a stuck bus must not hang the boot).
const I2C_PROBE_TIMEOUT: Duration = Duration::from_millis(20);

/// Flow read period (stock `flowdeck_v1v2.c`: 10 ms).
pub const FLOW_PERIOD: Duration = Duration::from_millis(10);

/// Deadline of one SPI bus operation of the flow deck (a write, read or transfer; the driver's own delays
/// are not counted). A motion burst is 13 bytes, ≈ 80 µs at 1.3 MHz: 1 ms is 12× that. Stock
/// (`spi_drv.c` `spiExchange`) waits on its DMA semaphores with no bound.
pub const SPI_OP_TIMEOUT: Duration = Duration::from_millis(1);

/// Why a flow-deck SPI transaction failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlowSpiError {
    /// The peripheral reported an error.
    Bus(embassy_stm32::spi::Error),
    /// An operation did not finish within [`SPI_OP_TIMEOUT`]: its future was dropped (embassy stops both
    /// DMA streams and waits for them on drop; the next transfer flushes DR, clearing an overrun) and chip
    /// select raised, which also resets the PMW3901's SPI port.
    Timeout,
}

impl embedded_hal_async::spi::Error for FlowSpiError {
    fn kind(&self) -> embedded_hal_async::spi::ErrorKind {
        match self {
            FlowSpiError::Bus(e) => embedded_hal_async::spi::Error::kind(e),
            FlowSpiError::Timeout => embedded_hal_async::spi::ErrorKind::Other,
        }
    }
}

/// SPI1 with one chip-select pin: the `SpiDevice` the PMW3901 driver needs (the flow deck is the only SPI
/// device this firmware uses, so the bus is not shared). Every bus operation has a deadline
/// ([`SPI_OP_TIMEOUT`]): a lost byte (SPI overrun, the RX DMA stream waiting for one more byte) or a deck
/// unplugged mid-burst must not park the flow task forever.
pub struct SpiWithCs {
    bus: Spi<'static, Async, SpiMaster>,
    cs: Output<'static>,
}

impl SpiWithCs {
    /// `cs` must already be high (deselected).
    pub fn new(bus: Spi<'static, Async, SpiMaster>, cs: Output<'static>) -> Self {
        Self { bus, cs }
    }
}

impl ErrorType for SpiWithCs {
    type Error = FlowSpiError;
}

impl SpiDevice for SpiWithCs {
    async fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        self.cs.set_low();
        let mut result = Ok(());
        for op in operations.iter_mut() {
            let outcome = match op {
                Operation::Read(buf) => with_timeout(SPI_OP_TIMEOUT, self.bus.read(buf)).await,
                Operation::Write(buf) => with_timeout(SPI_OP_TIMEOUT, self.bus.write(buf)).await,
                Operation::Transfer(read, write) => with_timeout(SPI_OP_TIMEOUT, self.bus.transfer(read, write)).await,
                Operation::TransferInPlace(buf) => with_timeout(SPI_OP_TIMEOUT, self.bus.transfer_in_place(buf)).await,
                Operation::DelayNs(ns) => {
                    Timer::after_nanos(u64::from(*ns)).await;
                    Ok(Ok(()))
                }
            };
            result = match outcome {
                Ok(Ok(())) => Ok(()),
                Ok(Err(e)) => Err(FlowSpiError::Bus(e)),
                Err(_) => Err(FlowSpiError::Timeout),
            };
            if result.is_err() {
                break;
            }
        }
        self.cs.set_high();
        result
    }
}

/// The flow sensor on its SPI device.
pub type FlowSensor = Pmw3901<SpiWithCs>;

/// Reads the config block from EEPROM address 0; the defaults (with a warning) if it cannot be read or is
/// not valid.
pub async fn read_radio_settings(i2c: &mut DeckI2c) -> RadioSettings {
    let mut block = [0u8; READ_LEN];
    // 16-bit memory address 0x0000 (the 8 KB EEPROM uses two address bytes, stock `eeprom.c`).
    match with_timeout(
        I2C_PROBE_TIMEOUT,
        i2c.write_read(EEPROM_I2C_ADDRESS, &[0, 0], &mut block),
    )
    .await
    {
        Ok(Ok(())) => {
            let (settings, error) = RadioSettings::parse_or_default(&block);
            match error {
                None => info!(
                    "config block: channel {}, rate code {}, address {=u64:#x}",
                    settings.channel, settings.datarate as u8, settings.address
                ),
                Some(e) => warn!("config block not valid ({}): radio defaults", defmt::Debug2Format(&e)),
            }
            settings
        }
        Ok(Err(e)) => {
            warn!("EEPROM read failed ({}): radio defaults", defmt::Debug2Format(&e));
            RadioSettings::DEFAULT
        }
        Err(_) => {
            warn!("EEPROM read timed out: radio defaults");
            RadioSettings::DEFAULT
        }
    }
}

/// The rangers that came up at boot.
pub struct DeckRangers {
    /// The Flow deck's downward VL53L1x, ranging.
    pub z: Option<Vl53l1x>,
    /// The Multi-ranger, if its expander answered and all five sensors range.
    pub multi: Option<MultiRanger>,
}

/// Brings both decks' rangers up in the safe order (module documentation).
pub async fn bring_up_rangers(i2c: &mut DeckI2c) -> DeckRangers {
    let mut multi = MultiRanger::new(pca95x4::DEFAULT_ADDRESS);
    let expander = matches!(
        with_timeout(I2C_PROBE_TIMEOUT, multi.hold_all_in_reset(i2c)).await,
        Ok(Ok(()))
    );
    if !expander {
        warn!("Multi-ranger deck not found (no PCA95x4 at 0x20)");
    }
    // Probes 0x6A first: after a watchdog reset the ranger (no XSHUT) is still there.
    let z = match Vl53l1x::bring_up_or_find(i2c, &mut Delay, FLOW_DECK_Z_ADDRESS, &RangingConfig::FLOW_DECK_Z).await {
        Ok(mut z) => match z.start_ranging(i2c).await {
            Ok(()) => {
                info!("flow deck: height ranger up at {=u8:#x}", FLOW_DECK_Z_ADDRESS);
                Some(z)
            }
            Err(e) => {
                warn!("flow deck: height ranger does not start ({})", defmt::Debug2Format(&e));
                None
            }
        },
        Err(e) => {
            warn!("flow deck: no height ranger ({})", defmt::Debug2Format(&e));
            None
        }
    };
    let multi = if expander {
        match multi
            .bring_up(i2c, &mut Delay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER)
            .await
        {
            Ok(report) if report.all_up() => {
                info!("Multi-ranger: five rangers up");
                Some(multi)
            }
            Ok(report) => {
                warn!(
                    "Multi-ranger: only {} of 5 rangers up ({})",
                    report.working_count(),
                    defmt::Debug2Format(&report)
                );
                None
            }
            Err(e) => {
                warn!("Multi-ranger bring-up failed ({})", defmt::Debug2Format(&e));
                None
            }
        }
    } else {
        None
    };
    DeckRangers { z, multi }
}

/// A range as the log variables carry it: mm, [`NO_RANGE_MM`] for no valid reading.
fn range_mm(range: RangeReading) -> u16 {
    match range {
        Some(m) if m.is_finite() && m >= 0.0 => {
            let mm = m * 1000.0 + 0.5;
            if mm >= f32::from(NO_RANGE_MM) {
                NO_RANGE_MM
            } else {
                mm as u16
            }
        }
        _ => NO_RANGE_MM,
    }
}

/// Height ranger period (stock `zranger2.c`: 25 ms), ms.
pub const ZRANGE_PERIOD_MS: u32 = RangingConfig::FLOW_DECK_Z.inter_measurement_ms;
/// Multi-ranger beam period (stock `multiranger.c`: 100 ms), ms.
pub const BEAM_PERIOD_MS: u32 = RangingConfig::MULTI_RANGER.inter_measurement_ms;

/// The deck bus: the height ranger (40 Hz) → control task, the Multi-ranger's sweeps (10 Hz) → control
/// and mission tasks; both into the log variables. Never waits on a sensor: `cfnav`'s [`DeckReader`]
/// polls each sensor's data-ready only from shortly before its next reading is due and reads it at once,
/// so the beams' drifting clocks cannot starve the height reading; the task sleeps until
/// the next sensor is due.
#[embassy_executor::task]
pub async fn deck_task(mut i2c: DeckI2c, rangers: DeckRangers) {
    let beams = rangers.multi.map(|m| m.sensors_in_order()).unwrap_or([None; 5]);
    let mut reader = DeckReader::new(rangers.z, ZRANGE_PERIOD_MS, beams, BEAM_PERIOD_MS, now_us());
    let mut errors = 0u32;
    let mut restarts = 0u32;
    loop {
        let Some(due_us) = reader.next_due_us() else {
            // No ranger came up: only the EEPROM's persistent-parameter writes are left to serve.
            Timer::after_millis(100).await;
            super::eeprom::service(&mut i2c).await;
            continue;
        };
        Timer::at(Instant::from_micros(due_us)).await;
        // A persistent-parameter write, if the radio queued one (never in flight: the store refuses it).
        super::eeprom::service(&mut i2c).await;
        let events = reader.service(&mut i2c, &mut now_us).await;
        if let Some(range) = events.z {
            let _ = FAST_INPUTS.try_send(FastInput::ZRange(range, events.z_at_us));
            update_log(|s| s.flight.ranges_mm[5] = range_mm(range));
        }
        if let Some(sample) = events.sweep {
            let _ = FAST_INPUTS.try_send(FastInput::MultiRanger(sample));
            // Dropped if the mission is behind (it drains every 20 ms): the next sweep is 100 ms later.
            // Mapped from the pose the beams measured from (module `cfnav::stack`, BEAM_MIDPOINT_US).
            let age_us = now_us().saturating_sub(events.sweep_at_us) + BEAM_MIDPOINT_US;
            let estimate = fast_status().estimate.backdated(age_us as f32 * 1e-6);
            let _ = NAV_INPUTS.try_send(NavInput::MultiRanger(sample, estimate));
            update_log(|s| {
                s.flight.ranges_mm[..5].copy_from_slice(&[
                    range_mm(sample.front_m),
                    range_mm(sample.back_m),
                    range_mm(sample.left_m),
                    range_mm(sample.right_m),
                    range_mm(sample.up_m),
                ]);
            });
        }
        if events.errors > 0 {
            let before = errors;
            errors = errors.saturating_add(events.errors);
            if (before + 1..=errors).any(u32::is_power_of_two) {
                warn!(
                    "deck ranger read errors: {} so far ({})",
                    errors,
                    defmt::Debug2Format(&events.first_error)
                );
            }
        }
        if events.restarts > 0 {
            restarts = restarts.saturating_add(events.restarts);
            if restarts.is_power_of_two() {
                warn!("deck rangers restarted (reading overdue): {} so far", restarts);
            }
        }
    }
}

/// Brings the PMW3901 up; `None` (flow deck absent or failed) with a log line otherwise.
pub async fn init_flow(spi: SpiWithCs) -> Option<FlowSensor> {
    let mut flow = Pmw3901::new(spi);
    match flow.init(&mut Delay).await {
        Ok(()) => {
            info!("flow deck: PMW3901 up");
            Some(flow)
        }
        Err(e) => {
            warn!("flow deck: PMW3901 not found ({})", defmt::Debug2Format(&e));
            None
        }
    }
}

/// 100 Hz optical flow → the control task. A failed read (bus error or [`SPI_OP_TIMEOUT`]) is dropped and
/// counted; repeated failures re-synchronise the chip ([`ReadHealth`], `drivers::pmw3901`). Logged on
/// power-of-two counts: "flow read failed", "flow read timed out", "flow sensor re-synced".
#[embassy_executor::task]
pub async fn flow_task(mut flow: FlowSensor) {
    let mut ticker = Ticker::every(FLOW_PERIOD);
    let mut health = ReadHealth::new();
    loop {
        ticker.next().await;
        let outcome = match flow.read(now_us(), &mut Delay).await {
            // Dropped if the control task is behind: the next reading carries the accumulated motion.
            Ok(sample) => {
                let _ = FAST_INPUTS.try_send(FastInput::Flow(sample));
                ReadOutcome::Read
            }
            Err(DriverError::Bus(FlowSpiError::Timeout)) => {
                let n = health.stats().timeouts.saturating_add(1);
                if n.is_power_of_two() {
                    warn!("flow read timed out ({} so far): burst dropped", n);
                }
                ReadOutcome::Timeout
            }
            Err(e) => {
                let n = health.stats().bus_errors.saturating_add(1);
                if n.is_power_of_two() {
                    warn!("flow read failed ({} so far): {}", n, defmt::Debug2Format(&e));
                }
                ReadOutcome::BusError
            }
        };
        if health.record(outcome) == RecoveryAction::Resync {
            let ok = flow.init(&mut Delay).await.is_ok();
            health.record_resync(ok);
            let stats = health.stats();
            if !ok || stats.resyncs.is_power_of_two() {
                warn!(
                    "flow sensor re-synced ({} so far, {} failed; {} timeouts, {} bus errors)",
                    stats.resyncs, stats.failed_resyncs, stats.timeouts, stats.bus_errors
                );
            }
        }
    }
}
