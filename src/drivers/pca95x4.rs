//! PCA95x4 8-bit I2C I/O expander (PCA9534/PCA9554; the Multi-ranger deck's, at 0x20 on the deck bus),
//! used to drive the five VL53L1x XSHUT lines.
//!
//! Job: make chosen pins push-pull outputs at chosen levels, then raise or lower output pins. Non-goals:
//! interrupts, polarity inversion, reading inputs beyond a plain input-port read.
//!
//! Register map (NXP PCA9534/PCA9554 datasheets §"Register descriptions"; the same in the Crazyflie's
//! `src/hal/interface/pca95x4.h`, `docs/hardware.md` §2): command byte 0 = input port, 1 = output
//! port, 2 = polarity inversion, 3 = configuration (bit = 1: input, 0: output). Power-on: output 0xFF,
//! polarity 0x00, configuration 0xFF (all inputs). A register write is `[command, value]`, a read is a
//! write of the command byte followed by one data byte. Address 0x20 = `0100 A2 A1 A0` with A2..A0 = 0
//! (PCA9534/PCA9554; the "A" variants would be at 0x38 — not the Multi-ranger's, `docs/hardware.md` §2).
//!
//! Glitch-free start: because the output register powers up at 0xFF, this driver writes the output levels
//! *before* switching the pins to outputs (the stock `mrInit` does it the other way round, which can pulse
//! the lines high for one transfer). It keeps a copy of the output register instead of reading it back
//! before each change (stock does read-modify-write); the copy is exact because the driver writes the whole
//! register each time.
//!
//! Units: none (bit masks, bit n = pin Pn). Memory: 2 bytes (address, output copy). Bus: borrowed per call.

use embedded_hal_async::i2c::I2c;

use crate::drivers::DriverError;

/// The Multi-ranger's expander address (A2..A0 tied low; `docs/hardware.md` §2).
pub const DEFAULT_ADDRESS: u8 = 0x20;

/// Command bytes (register indices) of the PCA95x4.
pub mod reg {
    /// Input port (read-only): the pin levels.
    pub const INPUT: u8 = 0x00;
    /// Output port: the levels driven on pins configured as outputs.
    pub const OUTPUT: u8 = 0x01;
    /// Polarity inversion of the input port.
    pub const POLARITY: u8 = 0x02;
    /// Configuration: bit = 1 input (power-on), 0 output.
    pub const CONFIG: u8 = 0x03;
}

/// Output register value at power-on (datasheet): all ones.
pub const POWER_ON_OUTPUT: u8 = 0xFF;

/// One PCA95x4.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pca95x4 {
    address: u8,
    output: u8,
}

impl Pca95x4 {
    /// An expander at `address`, assumed in its power-on state (nothing is sent).
    pub const fn new(address: u8) -> Self {
        Self {
            address,
            output: POWER_ON_OUTPUT,
        }
    }

    /// The expander's address.
    pub const fn address(&self) -> u8 {
        self.address
    }

    /// The output register as last written.
    pub const fn output(&self) -> u8 {
        self.output
    }

    /// Makes the pins in `output_mask` outputs driving `levels` (bits outside the mask are ignored and
    /// written as 1, the power-on value), the others inputs: writes the output register first, then the
    /// configuration register (`!output_mask`).
    pub async fn configure_outputs<I: I2c>(
        &mut self,
        i2c: &mut I,
        output_mask: u8,
        levels: u8,
    ) -> Result<(), DriverError<I::Error>> {
        let output = (levels & output_mask) | !output_mask;
        self.write_output(i2c, output).await?;
        i2c.write(self.address, &[reg::CONFIG, !output_mask]).await?;
        Ok(())
    }

    /// Drives the pins in `mask` high (others unchanged).
    pub async fn set_pins<I: I2c>(&mut self, i2c: &mut I, mask: u8) -> Result<(), DriverError<I::Error>> {
        self.write_output(i2c, self.output | mask).await
    }

    /// Drives the pins in `mask` low (others unchanged).
    pub async fn clear_pins<I: I2c>(&mut self, i2c: &mut I, mask: u8) -> Result<(), DriverError<I::Error>> {
        self.write_output(i2c, self.output & !mask).await
    }

    /// Reads the input port (the level of every pin, outputs included).
    pub async fn read_inputs<I: I2c>(&mut self, i2c: &mut I) -> Result<u8, DriverError<I::Error>> {
        let mut value = [0u8; 1];
        i2c.write_read(self.address, &[reg::INPUT], &mut value).await?;
        Ok(value[0])
    }

    /// Writes the output register; the copy changes only when the chip acknowledged the write.
    async fn write_output<I: I2c>(&mut self, i2c: &mut I, output: u8) -> Result<(), DriverError<I::Error>> {
        i2c.write(self.address, &[reg::OUTPUT, output]).await?;
        self.output = output;
        Ok(())
    }
}
