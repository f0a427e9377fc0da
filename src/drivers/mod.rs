//! Sensor drivers, written against the `embedded-hal-async` bus traits so the firmware runs them on
//! embassy-stm32's I2C/SPI and the host tests run them on `embedded-hal-mock` with recorded register traffic.
//!
//! Job: bring a chip up (identity check, reset, configuration), read it, and convert its raw registers into
//! the SI sample types of [`crate::types`] in the Crazyflie body frame (x forward, y left, z up).
//!
//! Non-goals: no scheduling (the caller decides when to read, usually on a data-ready edge), no filtering or
//! calibration beyond what the chip does (that is the estimator's), no pins other than what the driver needs.
//!
//! Errors: every driver returns [`DriverError`], which keeps the bus error and names the failure a user can
//! act on (absent chip, wrong identity, timeout, invalid data) so the firmware can log it, print it on the
//! console and make the supervisor refuse take-off.

pub mod bmi088;
pub mod i2c_guard;
pub mod multiranger;
pub mod pca95x4;
pub mod pmw3901;
pub mod vl53l1x;

/// Why a driver call failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriverError<E> {
    /// The bus transfer failed (NACK, arbitration loss, bus timeout): the chip is absent or the bus is stuck.
    Bus(E),
    /// The chip answered but its identity register is not the expected one.
    WrongChipId {
        /// What the datasheet says the register holds.
        expected: u16,
        /// What the chip returned.
        found: u16,
    },
    /// The chip did not become ready (boot, reset, data) within the driver's polling budget.
    Timeout,
    /// The chip returned data the driver refuses to use (a range status other than valid, a saturated or
    /// low-quality frame); the reading is dropped, not the driver.
    InvalidData,
    /// An argument outside what the chip supports (an I2C address, a timing budget).
    InvalidConfig,
}

impl<E> From<E> for DriverError<E> {
    fn from(error: E) -> Self {
        DriverError::Bus(error)
    }
}
