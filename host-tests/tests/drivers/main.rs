//! Drivers (src/drivers): each chip's bring-up and reads against recorded register traffic on embedded-hal-mock
//! buses.

mod bmi088;
mod i2c_guard;
mod multiranger;
mod pca95x4;
mod pmw3901;
mod vl53l1x;
