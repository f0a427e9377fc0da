//! Drivers (src/drivers): each chip's bring-up and reads against recorded register traffic on embedded-hal-mock
//! buses.

mod bmi088;
mod deck_schedule;
mod i2c_guard;
mod multiranger;
mod pca95x4;
mod pmw3901;
mod vl53l1x;

use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource};

/// The bus error the mocks inject: the chip did not acknowledge its address.
const NACK: ErrorKind = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);

/// A delay that only adds up how long the driver asked to wait.
#[derive(Default)]
struct CountingDelay {
    total_ns: u64,
}

impl embedded_hal_async::delay::DelayNs for CountingDelay {
    async fn delay_ns(&mut self, ns: u32) {
        self.total_ns += u64::from(ns);
    }
}
