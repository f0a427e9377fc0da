//! Multi-ranger deck: five VL53L1x rangers (front, back, left, right, up) whose XSHUT lines hang on a
//! PCA95x4 expander, all on the deck I2C bus (I2C1, 400 kHz).
//!
//! Job: hold every sensor in reset through the expander, then bring them up one at a time — release its
//! XSHUT, wait 2 ms, wait for its boot at 0x29, move it to its own address, run the VL53L1x init, start
//! continuous ranging — and read all five into a [`MultiRangerSample`]. A sensor that fails is reported
//! (which one and why, [`BringUpReport`]), put back into reset so it cannot shadow the next sensor at 0x29,
//! and the others continue. Non-goals: scheduling (call [`MultiRanger::read_all`] every 100 ms), filtering.
//!
//! Facts (crazyflie-hardware.md §5.5, from the stock `multiranger.c`): expander at 0x20; XSHUT on expander
//! pins P0 = up, P1 = back, P2 = right, P4 = front, P6 = left; stock bring-up order front, back, up, left,
//! right with a 2 ms boot wait after each release; stock addresses from the pool 0x6A..=0x6F, which with a
//! Flow deck present gives z-ranger 0x6A, then front 0x6B, back 0x6C, up 0x6D, left 0x6E, right 0x6F. This
//! driver assigns `first_address + position in the bring-up order`, so [`FIRST_ADDRESS`] (0x6B) reproduces
//! that layout whether or not the Flow deck is fitted (addresses do not shift when a sensor fails).
//!
//! Both decks on one bus: the Flow deck's VL53L1x also powers up at 0x29 and has no XSHUT. Order:
//! [`MultiRanger::hold_all_in_reset`] first (so no Multi-ranger sensor answers at 0x29), then
//! `Vl53l1x::bring_up(.., FLOW_DECK_Z_ADDRESS, &RangingConfig::FLOW_DECK_Z)` to move the z-ranger to 0x6A,
//! then [`MultiRanger::bring_up`]. With the Flow deck alone, the z-ranger may stay at 0x29.
//!
//! Rates: 10 Hz per beam ([`RangingConfig::MULTI_RANGER`]: 50 ms budget, 100 ms period). Units: metres in
//! the body frame axes of [`MultiRangerSample`]; `None` for no valid return or a failed sensor.
//!
//! Memory: a [`MultiRanger`] is about 16 bytes (expander 2, five optional sensors 2 each, wait budget 4).

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;

use crate::drivers::DriverError;
use crate::drivers::pca95x4::Pca95x4;
use crate::drivers::vl53l1x::{self, RangingConfig, Vl53l1x};
use crate::types::{MultiRangerSample, RangeReading};

/// Where the Flow deck's z-ranger goes when the Multi-ranger is fitted too (stock layout, §5.5).
pub const FLOW_DECK_Z_ADDRESS: u8 = 0x6A;

/// Address of the first sensor brought up (front); the others follow in [`Direction::BRING_UP_ORDER`].
pub const FIRST_ADDRESS: u8 = 0x6B;

/// Wait after releasing an XSHUT before talking to the sensor, ms (stock `mrInitSensor`).
pub const XSHUT_RELEASE_WAIT_MS: u32 = 2;

/// The five beams.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Body +x.
    Front,
    /// Body −x.
    Back,
    /// Body +z.
    Up,
    /// Body +y.
    Left,
    /// Body −y.
    Right,
}

impl Direction {
    /// The stock bring-up (and read) order: front, back, up, left, right.
    pub const BRING_UP_ORDER: [Direction; 5] = [
        Direction::Front,
        Direction::Back,
        Direction::Up,
        Direction::Left,
        Direction::Right,
    ];

    /// The expander pin driving this sensor's XSHUT (stock `MR_PIN_*`: P0 up, P1 back, P2 right,
    /// P4 front, P6 left).
    pub const fn xshut_mask(self) -> u8 {
        match self {
            Direction::Up => 1 << 0,
            Direction::Back => 1 << 1,
            Direction::Right => 1 << 2,
            Direction::Front => 1 << 4,
            Direction::Left => 1 << 6,
        }
    }

    /// Position in [`Direction::BRING_UP_ORDER`] (also the index into report arrays).
    pub const fn index(self) -> usize {
        match self {
            Direction::Front => 0,
            Direction::Back => 1,
            Direction::Up => 2,
            Direction::Left => 3,
            Direction::Right => 4,
        }
    }
}

/// All five XSHUT pins (P0, P1, P2, P4, P6).
pub const XSHUT_ALL_MASK: u8 = 0x57;

/// Why one sensor is not running.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SensorFault<E> {
    /// The expander write releasing its XSHUT failed.
    Expander(DriverError<E>),
    /// The sensor itself failed (absent: bus error at boot; wrong model id; boot or first-range timeout).
    Sensor(DriverError<E>),
    /// Not tried: an earlier sensor could not be put back into reset, so releasing this one could have put
    /// two chips at 0x29.
    NotAttempted,
}

/// The outcome of [`MultiRanger::bring_up`], per direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BringUpReport<E> {
    /// `None` = the sensor is ranging; indexed by [`Direction::index`].
    pub faults: [Option<SensorFault<E>>; 5],
}

impl<E> BringUpReport<E> {
    /// Why `direction` is not running, if it is not.
    pub fn fault(&self, direction: Direction) -> Option<&SensorFault<E>> {
        self.faults[direction.index()].as_ref()
    }

    /// How many sensors are ranging.
    pub fn working_count(&self) -> usize {
        self.faults.iter().filter(|fault| fault.is_none()).count()
    }

    /// Whether all five are ranging.
    pub fn all_up(&self) -> bool {
        self.working_count() == 5
    }
}

/// The outcome of [`MultiRanger::read_all`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadOutcome<E> {
    /// The five readings (`None`: no valid return, sensor not running, or a fault below).
    pub sample: MultiRangerSample,
    /// The read errors of running sensors, indexed by [`Direction::index`].
    pub faults: [Option<DriverError<E>>; 5],
}

/// The Multi-ranger deck: its expander and the sensors that came up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MultiRanger {
    expander: Pca95x4,
    sensors: [Option<Vl53l1x>; 5],
    data_ready_poll_limit: u32,
}

impl MultiRanger {
    /// A deck whose expander is at `expander_address` ([`crate::drivers::pca95x4::DEFAULT_ADDRESS`] on the
    /// Bitcraze deck); nothing is sent.
    pub const fn new(expander_address: u8) -> Self {
        Self {
            expander: Pca95x4::new(expander_address),
            sensors: [None; 5],
            data_ready_poll_limit: 2 * RangingConfig::MULTI_RANGER.inter_measurement_ms,
        }
    }

    /// The running sensor of `direction`, if any.
    pub fn sensor(&self, direction: Direction) -> Option<&Vl53l1x> {
        self.sensors[direction.index()].as_ref()
    }

    /// The expander (for its output-register copy).
    pub fn expander(&self) -> &Pca95x4 {
        &self.expander
    }

    /// Puts every sensor into reset: expander output register with the five XSHUT bits low, then those
    /// pins as outputs (see the expander's glitch-free order). Forgets the running sensors first, also when
    /// the expander then fails (their state is unknown, so they are not read).
    pub async fn hold_all_in_reset<I: I2c>(&mut self, i2c: &mut I) -> Result<(), DriverError<I::Error>> {
        self.sensors = [None; 5];
        self.expander.configure_outputs(i2c, XSHUT_ALL_MASK, 0x00).await
    }

    /// Brings the deck up: [`MultiRanger::hold_all_in_reset`], then for each direction in
    /// [`Direction::BRING_UP_ORDER`]: release its XSHUT, wait [`XSHUT_RELEASE_WAIT_MS`], bring the chip up at
    /// `first_address + index` with `config` and start ranging. A sensor that fails goes back into reset and
    /// is reported; the others continue. Errors (nothing started): `InvalidConfig` when an address is
    /// reserved, is 0x29 or the expander's, or `config` is invalid; the expander's bus error when the reset
    /// itself fails.
    pub async fn bring_up<I: I2c, D: DelayNs>(
        &mut self,
        i2c: &mut I,
        delay: &mut D,
        first_address: u8,
        config: &RangingConfig,
    ) -> Result<BringUpReport<I::Error>, DriverError<I::Error>> {
        if !self.addresses_usable(first_address) || !config.is_valid() {
            return Err(DriverError::InvalidConfig);
        }
        self.hold_all_in_reset(i2c).await?;
        self.data_ready_poll_limit = 2 * config.inter_measurement_ms;

        let mut faults = [None, None, None, None, None];
        let mut blocked = false;
        for (index, direction) in Direction::BRING_UP_ORDER.iter().enumerate() {
            if blocked {
                faults[index] = Some(SensorFault::NotAttempted);
                continue;
            }
            let pin = direction.xshut_mask();
            let fault = match self.expander.set_pins(i2c, pin).await {
                Err(error) => Some(SensorFault::Expander(error)),
                Ok(()) => {
                    delay.delay_ms(XSHUT_RELEASE_WAIT_MS).await;
                    let address = first_address + index as u8;
                    match Self::bring_up_one(i2c, delay, address, config).await {
                        Ok(sensor) => {
                            self.sensors[index] = Some(sensor);
                            None
                        }
                        Err(error) => Some(SensorFault::Sensor(error)),
                    }
                }
            };
            if fault.is_some() && self.expander.clear_pins(i2c, pin).await.is_err() {
                blocked = true;
            }
            faults[index] = fault;
        }
        Ok(BringUpReport { faults })
    }

    /// Reads every running sensor in [`Direction::BRING_UP_ORDER`]: waits for its data-ready (up to twice
    /// the inter-measurement period), reads the range and clears the interrupt. A failing sensor gives
    /// `None` and its error; the others are still read.
    pub async fn read_all<I: I2c, D: DelayNs>(&mut self, i2c: &mut I, delay: &mut D) -> ReadOutcome<I::Error> {
        let mut sample = MultiRangerSample::default();
        let mut faults = [None, None, None, None, None];
        let poll_limit = self.data_ready_poll_limit;
        for direction in Direction::BRING_UP_ORDER {
            let Some(sensor) = self.sensors[direction.index()].as_mut() else {
                continue;
            };
            let reading = match Self::read_one(sensor, i2c, delay, poll_limit).await {
                Ok(reading) => reading,
                Err(error) => {
                    faults[direction.index()] = Some(error);
                    None
                }
            };
            match direction {
                Direction::Front => sample.front_m = reading,
                Direction::Back => sample.back_m = reading,
                Direction::Up => sample.up_m = reading,
                Direction::Left => sample.left_m = reading,
                Direction::Right => sample.right_m = reading,
            }
        }
        ReadOutcome { sample, faults }
    }

    fn addresses_usable(&self, first_address: u8) -> bool {
        (0..5u8).all(|offset| {
            let Some(address) = first_address.checked_add(offset) else {
                return false;
            };
            vl53l1x::is_valid_address(address)
                && address != vl53l1x::DEFAULT_ADDRESS
                && address != self.expander.address()
        })
    }

    async fn bring_up_one<I: I2c, D: DelayNs>(
        i2c: &mut I,
        delay: &mut D,
        address: u8,
        config: &RangingConfig,
    ) -> Result<Vl53l1x, DriverError<I::Error>> {
        let mut sensor = Vl53l1x::bring_up(i2c, delay, address, config).await?;
        sensor.start_ranging(i2c).await?;
        Ok(sensor)
    }

    async fn read_one<I: I2c, D: DelayNs>(
        sensor: &mut Vl53l1x,
        i2c: &mut I,
        delay: &mut D,
        poll_limit: u32,
    ) -> Result<RangeReading, DriverError<I::Error>> {
        sensor.wait_data_ready(i2c, delay, poll_limit).await?;
        sensor.read_range(i2c).await
    }
}
