//! The two guarded I2C buses of the board: the deck bus I2C1 (Flow deck and Multi-ranger sensors, the
//! EEPROM) and the sensor bus I2C3 (the IMU), each an embassy I2C driver behind the deadline-and-recovery
//! guard of `cfnav::drivers::i2c_guard`, with the register-level bus recovery the guard calls.
//!
//! Its own module because the deck task (`super::sensors`) and the EEPROM I/O (`super::eeprom`) both use
//! the deck bus type, and the control task (`super::control`) the sensor bus type.
//!
//! Memory: the recovery state is a few words per bus; nothing is allocated.

use cfnav::drivers::i2c_guard::{BusRecovery, GuardConfig, GuardedI2c};
use defmt::warn;
use embassy_stm32::i2c::I2c;
use embassy_stm32::i2c::mode::Master as I2cMaster;
use embassy_stm32::mode::Async;
use embassy_stm32::pac;
use embassy_stm32::pac::gpio::vals as gpio_vals;
use embassy_time::Delay;

/// The bus recovery of one I2C peripheral (`cfnav::drivers::i2c_guard`), by register: the embassy I2C
/// driver owns the pins, so the recovery switches their mode (MODER: alternate function ↔ output; they
/// are already open-drain, OTYPER, as the I2C driver set them) and drives them through BSRR while the
/// peripheral is disabled, then resets the peripheral (CR1.SWRST, the F4 errata workaround embassy also
/// applies at init) and restores its timing registers (RM0090 §27.6.1, §8.4). Each recovery whose count
/// is a power of two is logged ("I2C3 (IMU): bus recovery 1: 9 SCL clocks, SDA released"), so a stuck
/// slave shows in the log whether or not it let go.
pub struct I2cRecoveryPins {
    i2c: pac::i2c::I2c,
    scl_port: pac::gpio::Gpio,
    scl: usize,
    sda_port: pac::gpio::Gpio,
    sda: usize,
    /// For the log line: the bus's name, the recoveries so far, and of the one running the SCL clocks
    /// given while SDA was read low and whether SDA read high at the end of them.
    name: &'static str,
    recoveries: u32,
    clocks: u32,
    clocking: bool,
    sda_high: bool,
}

impl I2cRecoveryPins {
    /// Deck bus I2C1: SCL PB6, SDA PB7 (`docs/hardware.md` §2).
    pub fn deck() -> Self {
        Self::new(pac::I2C1, (pac::GPIOB, 6), (pac::GPIOB, 7), "I2C1 (deck)")
    }

    /// Sensor bus I2C3: SCL PA8, SDA PC9 (stock `i2c_drv.c` `sensorBusDef`).
    pub fn sensors() -> Self {
        Self::new(pac::I2C3, (pac::GPIOA, 8), (pac::GPIOC, 9), "I2C3 (IMU)")
    }

    fn new(
        i2c: pac::i2c::I2c,
        (scl_port, scl): (pac::gpio::Gpio, usize),
        (sda_port, sda): (pac::gpio::Gpio, usize),
        name: &'static str,
    ) -> Self {
        Self {
            i2c,
            scl_port,
            scl,
            sda_port,
            sda,
            name,
            recoveries: 0,
            clocks: 0,
            clocking: false,
            sda_high: true,
        }
    }

    fn set_mode(&self, mode: gpio_vals::Moder) {
        self.scl_port.moder().modify(|w| w.set_moder(self.scl, mode));
        self.sda_port.moder().modify(|w| w.set_moder(self.sda, mode));
    }
}

impl<'d> BusRecovery<I2c<'d, Async, I2cMaster>> for I2cRecoveryPins {
    fn begin(&mut self, _bus: &mut I2c<'d, Async, I2cMaster>) {
        self.i2c.cr1().modify(|w| w.set_pe(false));
        // Released (high) before they become outputs, so switching the mode makes no edge.
        self.set_scl(true);
        self.set_sda(true);
        self.set_mode(gpio_vals::Moder::OUTPUT);
        self.clocks = 0;
        self.clocking = true;
    }

    fn set_scl(&mut self, high: bool) {
        if !high && self.clocking {
            self.clocks = self.clocks.saturating_add(1);
        }
        let n = self.scl;
        self.scl_port
            .bsrr()
            .write(|w| if high { w.set_bs(n, true) } else { w.set_br(n, true) });
    }

    fn set_sda(&mut self, high: bool) {
        // SDA driven low is the START that follows the clocks (`i2c_guard::GuardedI2c::recover`).
        if !high {
            self.clocking = false;
        }
        let n = self.sda;
        self.sda_port
            .bsrr()
            .write(|w| if high { w.set_bs(n, true) } else { w.set_br(n, true) });
    }

    fn sda_is_high(&mut self) -> bool {
        self.sda_high = self.sda_port.idr().read().idr(self.sda) == gpio_vals::Idr::HIGH;
        self.sda_high
    }

    fn end(&mut self, _bus: &mut I2c<'d, Async, I2cMaster>) {
        self.set_mode(gpio_vals::Moder::ALTERNATE);
        // The timing the driver configured (CR2.FREQ, CCR, TRISE) survives the reset by copy; the reset
        // clears everything else (a stuck BUSY flag, a half-done transfer's state).
        let cr2 = self.i2c.cr2().read();
        let ccr = self.i2c.ccr().read();
        let trise = self.i2c.trise().read();
        self.i2c.cr1().modify(|w| w.set_swrst(true));
        self.i2c.cr1().modify(|w| w.set_swrst(false));
        self.i2c.cr2().write_value(cr2);
        self.i2c.ccr().write_value(ccr);
        self.i2c.trise().write_value(trise);
        self.i2c.cr1().modify(|w| w.set_pe(true));
        self.recoveries = self.recoveries.saturating_add(1);
        if self.recoveries.is_power_of_two() {
            warn!(
                "{=str}: bus recovery {}: {} SCL clocks, SDA {=str}",
                self.name,
                self.recoveries,
                self.clocks,
                if self.sda_high { "released" } else { "still held low" }
            );
        }
    }
}

/// An embassy I2C bus behind the deadline-and-recovery guard.
pub type GuardedBus = GuardedI2c<I2c<'static, Async, I2cMaster>, I2cRecoveryPins, Delay>;

/// Deck bus transactions: the longest is a VL53L1x configuration burst (≈ 140 bytes, 3.5 ms at 400 kHz).
pub const DECK_GUARD: GuardConfig = GuardConfig {
    timeout_us: 10_000,
    retries: 1,
};

/// IMU transactions: a 6-byte burst takes ≈ 0.25 ms at 400 kHz; two tries with their recoveries stay
/// near 2 ms, two control periods.
pub const IMU_GUARD: GuardConfig = GuardConfig {
    timeout_us: 1_000,
    retries: 1,
};

/// Wraps an I2C bus in the guard.
pub fn guard(bus: I2c<'static, Async, I2cMaster>, pins: I2cRecoveryPins, config: GuardConfig) -> GuardedBus {
    GuardedI2c::new(bus, pins, Delay, config)
}

/// The deck bus (guarded), owned by the deck task (`super::sensors::deck_task`) after boot.
pub type DeckI2c = GuardedBus;
