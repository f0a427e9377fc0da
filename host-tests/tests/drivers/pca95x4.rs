//! PCA95x4 expander driver against recorded I2C traffic.
//!
//! Expected bytes from the NXP PCA9534/PCA9554 register map (command byte 0 input, 1 output, 2 polarity,
//! 3 configuration with 1 = input; power-on output 0xFF) and the Multi-ranger wiring of
//! docs/hardware.md §2 (expander at 0x20, XSHUT on P0, P1, P2, P4, P6).

use super::NACK;
use cfnav::drivers::DriverError;
use cfnav::drivers::pca95x4::Pca95x4;
use embassy_futures::block_on;
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as T};

const EXPANDER: u8 = 0x20;
const OUTPUT_REGISTER: u8 = 0x01;
const CONFIG_REGISTER: u8 = 0x03;
/// P0 | P1 | P2 | P4 | P6.
const XSHUT_PINS: u8 = 0b0101_0111;

#[test]
fn a_new_expander_assumes_the_power_on_output_register() {
    let expander = Pca95x4::new(EXPANDER);
    assert_eq!(expander.output(), 0xFF);
    assert_eq!(expander.address(), 0x20);
}

#[test]
fn configuring_the_xshut_pins_low_writes_output_before_configuration() {
    // The five XSHUT bits cleared, the other bits left at their power-on 1: 0xA8 in both registers
    // (the same values the stock mrInit ends with, but the levels go out before the pins become outputs).
    let mut i2c = I2cMock::new(&[
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xA8]),
        T::write(EXPANDER, vec![CONFIG_REGISTER, 0xA8]),
    ]);
    let mut expander = Pca95x4::new(EXPANDER);
    block_on(expander.configure_outputs(&mut i2c, XSHUT_PINS, 0x00)).expect("configure");
    assert_eq!(expander.output(), 0xA8);
    i2c.done();
}

#[test]
fn levels_outside_the_output_mask_are_ignored() {
    let mut i2c = I2cMock::new(&[
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xF5]), // low nibble 0101 driven, high nibble stays 1
        T::write(EXPANDER, vec![CONFIG_REGISTER, 0xF0]), // low nibble outputs
    ]);
    let mut expander = Pca95x4::new(EXPANDER);
    block_on(expander.configure_outputs(&mut i2c, 0x0F, 0x05 | 0xA0)).expect("configure");
    i2c.done();
}

#[test]
fn set_and_clear_change_only_the_named_pins() {
    let mut i2c = I2cMock::new(&[
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xA8]),
        T::write(EXPANDER, vec![CONFIG_REGISTER, 0xA8]),
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xB8]), // P4 (front) high
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xBA]), // P1 (back) high too
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xAA]), // P4 low again, P1 stays high
    ]);
    let mut expander = Pca95x4::new(EXPANDER);
    block_on(expander.configure_outputs(&mut i2c, XSHUT_PINS, 0x00)).expect("configure");
    block_on(expander.set_pins(&mut i2c, 1 << 4)).expect("set P4");
    block_on(expander.set_pins(&mut i2c, 1 << 1)).expect("set P1");
    block_on(expander.clear_pins(&mut i2c, 1 << 4)).expect("clear P4");
    assert_eq!(expander.output(), 0xAA);
    i2c.done();
}

#[test]
fn read_inputs_reads_command_zero() {
    let mut i2c = I2cMock::new(&[T::write_read(EXPANDER, vec![0x00], vec![0x5A])]);
    let mut expander = Pca95x4::new(EXPANDER);
    assert_eq!(block_on(expander.read_inputs(&mut i2c)).expect("read"), 0x5A);
    i2c.done();
}

#[test]
fn nack_on_the_output_write_stops_before_the_configuration_and_keeps_the_copy() {
    let mut i2c = I2cMock::new(&[T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xA8]).with_error(NACK)]);
    let mut expander = Pca95x4::new(EXPANDER);
    assert_eq!(
        block_on(expander.configure_outputs(&mut i2c, XSHUT_PINS, 0x00)),
        Err(DriverError::Bus(NACK))
    );
    assert_eq!(expander.output(), 0xFF);
    i2c.done();
}

#[test]
fn nack_on_the_configuration_write_is_reported() {
    let mut i2c = I2cMock::new(&[
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xA8]),
        T::write(EXPANDER, vec![CONFIG_REGISTER, 0xA8]).with_error(NACK),
    ]);
    let mut expander = Pca95x4::new(EXPANDER);
    assert_eq!(
        block_on(expander.configure_outputs(&mut i2c, XSHUT_PINS, 0x00)),
        Err(DriverError::Bus(NACK))
    );
    i2c.done();
}

#[test]
fn nack_on_a_pin_change_keeps_the_previous_output_copy() {
    let mut i2c = I2cMock::new(&[
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xA8]),
        T::write(EXPANDER, vec![CONFIG_REGISTER, 0xA8]),
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xA9]).with_error(NACK),
        T::write(EXPANDER, vec![OUTPUT_REGISTER, 0xAC]), // the next change starts from 0xA8, not 0xA9
    ]);
    let mut expander = Pca95x4::new(EXPANDER);
    block_on(expander.configure_outputs(&mut i2c, XSHUT_PINS, 0x00)).expect("configure");
    assert_eq!(
        block_on(expander.set_pins(&mut i2c, 1 << 0)),
        Err(DriverError::Bus(NACK))
    );
    assert_eq!(expander.output(), 0xA8);
    block_on(expander.set_pins(&mut i2c, 1 << 2)).expect("set P2");
    i2c.done();
}
