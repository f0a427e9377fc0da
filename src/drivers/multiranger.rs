//! Multi-ranger deck: five VL53L1x rangers (front, back, left, right, up) whose XSHUT lines hang on a
//! PCA95x4 expander, all on the deck I2C bus (I2C1, 400 kHz).
//!
//! Job: hold every sensor in reset through the expander, then bring them up one at a time — release its
//! XSHUT, wait 2 ms, wait for its boot at 0x29, move it to its own address, run the VL53L1x init, start
//! continuous ranging — and read all five into a [`MultiRangerSample`]. A sensor that fails is reported
//! (which one and why, [`BringUpReport`]), put back into reset so it cannot shadow the next sensor at 0x29,
//! and the others continue. Non-goals: filtering.
//!
//! Reading both decks on one bus ([`DeckReader`]): the five beams (10 Hz) and the Flow
//! deck's z-ranger (40 Hz) range on their own oscillators, which drift against each other and against the
//! MCU (a few %). A loop that *waits* for each beam's data-ready in turn ([`MultiRanger::read_all`]) blocks
//! the bus for up to a whole beam period and starves the z-ranger (measured on the drifting-clock model in
//! `host-tests/tests/drivers/deck_schedule.rs`: the height reading falls to a fraction of its 40 Hz).
//! [`DeckReader`] never waits: each sensor's data-ready is polled once per pass, and only from shortly before
//! its next reading is expected ([`ReadSchedule`]: the expectation is re-anchored on every reading, so the
//! reader stays in step with that sensor's own clock), a ready sensor is read at once, and a sensor whose
//! reading is overdue by [`STALE_PERIODS`] periods is restarted (stop, clear, start: the stock drivers'
//! restart) so it ranges in step with its reader again. Sweeps of the five beams are assembled from the
//! beams' own readings ([`DeckEvents::sweep`]), each reading used once.
//!
//! Facts (`docs/hardware.md` §2, from the stock `multiranger.c`): expander at 0x20; XSHUT on expander
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
//! Memory: a [`MultiRanger`] is about 16 bytes (expander 2, five optional sensors 2 each, wait budget 4); a
//! [`DeckReader`] about 200 bytes (six sensors, six schedule slots of 24 bytes, the sweep being assembled).

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;

use crate::drivers::DriverError;
use crate::drivers::pca95x4::Pca95x4;
use crate::drivers::vl53l1x::{self, RangingConfig, Vl53l1x};
use crate::types::{Micros, MultiRangerSample, RangeReading};

/// Where the Flow deck's z-ranger goes when the Multi-ranger is fitted too (stock layout, `docs/hardware.md` §2).
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

    /// The running sensors in [`Direction::BRING_UP_ORDER`] (`None`: not running), for a [`DeckReader`].
    pub fn sensors_in_order(&self) -> [Option<Vl53l1x>; 5] {
        self.sensors
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
    /// `None` and its error; the others are still read. It holds the bus for up to a whole beam period
    /// (the beams' clocks drift apart): a loop that also reads another sensor uses a [`DeckReader`].
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

// ---- The deck loop: reading the z-ranger and the five beams without waiting ----

/// The Flow deck's z-ranger's slot in a [`ReadSchedule`] / [`DeckReader`]; beam `d` is at `1 + d.index()`.
pub const Z_SLOT: usize = 0;
/// Slots of a [`ReadSchedule`]: the z-ranger and the five beams.
pub const DECK_SLOTS: usize = 6;
/// A slot is first polled `period / LEAD_DIVISOR` (plus one poll interval) before its next reading is
/// expected: room for a sensor oscillator up to 12.5 % fast (the VL53L1x's is specified to a few %).
pub const LEAD_DIVISOR: u32 = 8;
/// While waiting for a reading a slot is polled every `period / POLL_DIVISOR` (z-ranger 1 ms, beams 4 ms):
/// also the longest a ready reading waits to be read when the loop runs on time.
pub const POLL_DIVISOR: u32 = 25;
/// A slot whose sensor has not shown data-ready for this many periods since its last reading is restarted.
pub const STALE_PERIODS: u32 = 2;

/// One tracked sensor's timing, µs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Slot {
    period_us: u32,
    /// Poll no earlier than this.
    due_us: Micros,
    /// The last reading (or the start, or a restart).
    last_us: Micros,
}

impl Slot {
    fn poll_interval_us(&self) -> u64 {
        u64::from((self.period_us / POLL_DIVISOR).max(1))
    }

    /// When to poll first for the reading after one seen ready at `at_us`.
    fn first_poll_after(&self, at_us: Micros) -> Micros {
        let lead = u64::from(self.period_us / LEAD_DIVISOR) + self.poll_interval_us();
        at_us + u64::from(self.period_us).saturating_sub(lead)
    }
}

/// What the caller does after polling a slot's data-ready ([`ReadSchedule::on_poll`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PollAction {
    /// Not ready: poll again later.
    Wait,
    /// Ready: read it now, then [`ReadSchedule::on_read`].
    Read,
    /// Overdue by [`STALE_PERIODS`] periods: restart its ranging, then [`ReadSchedule::on_restart`].
    Restart,
}

/// The sans-IO read schedule of the deck loop: for each tracked sensor, when to poll its data-ready next.
/// It never asks the caller to wait on a sensor; the caller sleeps until [`ReadSchedule::next_due_us`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReadSchedule {
    slots: [Option<Slot>; DECK_SLOTS],
}

impl Default for ReadSchedule {
    fn default() -> Self {
        Self::new()
    }
}

impl ReadSchedule {
    /// Tracks nothing.
    pub const fn new() -> Self {
        Self {
            slots: [None; DECK_SLOTS],
        }
    }

    /// Tracks `slot` (ranging every `period_us`, at least 1 µs), first poll at `now_us`. Out-of-range slots
    /// are ignored.
    pub fn track(&mut self, slot: usize, period_us: u32, now_us: Micros) {
        if let Some(s) = self.slots.get_mut(slot) {
            *s = Some(Slot {
                period_us: period_us.max(1),
                due_us: now_us,
                last_us: now_us,
            });
        }
    }

    /// Whether `slot` is tracked.
    pub fn is_tracked(&self, slot: usize) -> bool {
        self.slots.get(slot).is_some_and(Option::is_some)
    }

    /// Whether `slot` should be polled at `now_us`.
    pub fn is_due(&self, slot: usize, now_us: Micros) -> bool {
        self.slot(slot).is_some_and(|s| now_us >= s.due_us)
    }

    /// The earliest time any tracked slot is due; `None` when nothing is tracked.
    pub fn next_due_us(&self) -> Option<Micros> {
        self.slots.iter().flatten().map(|s| s.due_us).min()
    }

    /// `slot`'s data-ready read `ready` at `now_us`.
    pub fn on_poll(&mut self, slot: usize, now_us: Micros, ready: bool) -> PollAction {
        let Some(s) = self.slot_mut(slot) else {
            return PollAction::Wait;
        };
        if ready {
            return PollAction::Read;
        }
        let overdue = u64::from(s.period_us) * u64::from(STALE_PERIODS);
        if now_us.saturating_sub(s.last_us) >= overdue {
            return PollAction::Restart;
        }
        s.due_us = now_us + s.poll_interval_us();
        PollAction::Wait
    }

    /// `slot` was read after its poll at `polled_at_us` found it ready (its reading came at or before then).
    pub fn on_read(&mut self, slot: usize, polled_at_us: Micros) {
        if let Some(s) = self.slot_mut(slot) {
            s.last_us = polled_at_us;
            s.due_us = s.first_poll_after(polled_at_us);
        }
    }

    /// `slot`'s ranging was restarted at `now_us`: its first reading comes about one period later.
    pub fn on_restart(&mut self, slot: usize, now_us: Micros) {
        self.on_read(slot, now_us);
    }

    /// A bus error on `slot` at `now_us` (the bus guard has already recovered the bus): try it again one
    /// period later, so a sensor that went away cannot take the bus from the others.
    pub fn on_error(&mut self, slot: usize, now_us: Micros) {
        if let Some(s) = self.slot_mut(slot) {
            s.due_us = now_us + u64::from(s.period_us);
        }
    }

    fn slot(&self, slot: usize) -> Option<&Slot> {
        self.slots.get(slot).and_then(Option::as_ref)
    }

    fn slot_mut(&mut self, slot: usize) -> Option<&mut Slot> {
        self.slots.get_mut(slot).and_then(Option::as_mut)
    }
}

/// What one [`DeckReader::service`] pass produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeckEvents<E> {
    /// A new z-ranger reading (`Some(None)`: the chip had no valid return).
    pub z: Option<RangeReading>,
    /// When the z-ranger reading was found ready (its data-ready poll), µs: the reading was measured
    /// about half a timing budget before (`RangingConfig::integration_midpoint_us`).
    pub z_at_us: Micros,
    /// A sweep of the five beams, each a reading not used in an earlier sweep (`None` in a beam: no valid
    /// return, or no reading from that beam within [`SWEEP_DEADLINE_PERIODS_NUM`]/2 periods).
    pub sweep: Option<MultiRangerSample>,
    /// The mean time the sweep's readings were found ready, µs (the beams' clocks drift apart, so a sweep's
    /// readings are up to a period apart).
    pub sweep_at_us: Micros,
    /// Beam readings this pass, by [`Direction::index`] (for logs and tests).
    pub beams: [Option<RangeReading>; 5],
    /// Bus errors this pass.
    pub errors: u32,
    /// The first bus error this pass.
    pub first_error: Option<DriverError<E>>,
    /// Sensors restarted this pass (overdue readings).
    pub restarts: u32,
}

impl<E> Default for DeckEvents<E> {
    fn default() -> Self {
        Self {
            z: None,
            z_at_us: 0,
            sweep: None,
            sweep_at_us: 0,
            beams: [None; 5],
            errors: 0,
            first_error: None,
            restarts: 0,
        }
    }
}

impl<E> DeckEvents<E> {
    fn error(&mut self, error: DriverError<E>) {
        self.errors = self.errors.saturating_add(1);
        if self.first_error.is_none() {
            self.first_error = Some(error);
        }
    }
}

/// A sweep is sent incomplete once its oldest reading is this many half beam periods old (3: 1.5 periods),
/// so a beam that stopped answering cannot hold the others back.
pub const SWEEP_DEADLINE_PERIODS_NUM: u32 = 3;

/// The sweep being assembled: the latest unused reading of each beam.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Sweep {
    readings: [RangeReading; 5],
    /// When each reading was found ready, µs.
    ready_us: [Micros; 5],
    fresh: u8,
    oldest_us: Micros,
}

/// Both decks' rangers on the deck bus, read without waiting ([`ReadSchedule`]; module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeckReader {
    sensors: [Option<Vl53l1x>; DECK_SLOTS],
    schedule: ReadSchedule,
    /// The beams that are running (bit = [`Direction::index`]).
    beams_running: u8,
    beam_period_us: u32,
    sweep: Sweep,
}

impl DeckReader {
    /// Reads the ranging z-ranger (`z`, every `z_period_ms`) and the running beams (`beams` in
    /// [`Direction::BRING_UP_ORDER`], every `beam_period_ms`), the first poll of each at `now_us`.
    pub fn new(
        z: Option<Vl53l1x>,
        z_period_ms: u32,
        beams: [Option<Vl53l1x>; 5],
        beam_period_ms: u32,
        now_us: Micros,
    ) -> Self {
        let mut sensors = [None; DECK_SLOTS];
        let mut schedule = ReadSchedule::new();
        let mut beams_running = 0u8;
        sensors[Z_SLOT] = z;
        if z.is_some() {
            schedule.track(Z_SLOT, z_period_ms.saturating_mul(1000), now_us);
        }
        for (index, beam) in beams.iter().enumerate() {
            if beam.is_some() {
                sensors[1 + index] = *beam;
                schedule.track(1 + index, beam_period_ms.saturating_mul(1000), now_us);
                beams_running |= 1 << index;
            }
        }
        Self {
            sensors,
            schedule,
            beams_running,
            beam_period_us: beam_period_ms.saturating_mul(1000).max(1),
            sweep: Sweep::default(),
        }
    }

    /// The schedule (for inspection).
    pub fn schedule(&self) -> &ReadSchedule {
        &self.schedule
    }

    /// When the next pass has work: sleep until then (`None`: no sensor, nothing to do ever). A sweep
    /// waiting for a beam that stopped answering also needs a pass at its deadline.
    pub fn next_due_us(&self) -> Option<Micros> {
        let due = self.schedule.next_due_us();
        match (due, self.sweep_deadline_us()) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn sweep_deadline_us(&self) -> Option<Micros> {
        (self.sweep.fresh != 0)
            .then(|| self.sweep.oldest_us + u64::from(self.beam_period_us) * u64::from(SWEEP_DEADLINE_PERIODS_NUM) / 2)
    }

    /// One pass: every due sensor's data-ready is read once; each ready sensor is read (the interrupt
    /// cleared), each overdue one restarted. Never waits for a sensor; the bus time is one data-ready poll
    /// (≈ 0.12 ms at 400 kHz) per due sensor plus one range read (≈ 0.36 ms) per ready one. `now_us` is the
    /// clock (read before each sensor).
    pub async fn service<I: I2c>(&mut self, i2c: &mut I, now_us: &mut impl FnMut() -> Micros) -> DeckEvents<I::Error> {
        let mut events = DeckEvents::default();
        for slot in 0..DECK_SLOTS {
            let Some(sensor) = self.sensors[slot].as_mut() else {
                continue;
            };
            let polled_at = now_us();
            if !self.schedule.is_due(slot, polled_at) {
                continue;
            }
            let ready = match sensor.data_ready(i2c).await {
                Ok(ready) => ready,
                Err(error) => {
                    events.error(error);
                    self.schedule.on_error(slot, now_us());
                    continue;
                }
            };
            match self.schedule.on_poll(slot, polled_at, ready) {
                PollAction::Wait => {}
                PollAction::Read => match sensor.read_range(i2c).await {
                    Ok(range) => {
                        self.schedule.on_read(slot, polled_at);
                        if slot == Z_SLOT {
                            events.z = Some(range);
                            events.z_at_us = polled_at;
                        } else {
                            events.beams[slot - 1] = Some(range);
                            self.add_to_sweep(slot - 1, range, polled_at, &mut events);
                        }
                    }
                    Err(error) => {
                        events.error(error);
                        self.schedule.on_error(slot, now_us());
                    }
                },
                PollAction::Restart => {
                    events.restarts = events.restarts.saturating_add(1);
                    let restarted = async {
                        sensor.stop_ranging(i2c).await?;
                        sensor.clear_interrupt(i2c).await?;
                        sensor.start_ranging(i2c).await
                    };
                    match restarted.await {
                        Ok(()) => self.schedule.on_restart(slot, now_us()),
                        Err(error) => {
                            events.error(error);
                            self.schedule.on_error(slot, now_us());
                        }
                    }
                }
            }
        }
        if events.sweep.is_none()
            && let Some(deadline) = self.sweep_deadline_us()
            && now_us() >= deadline
        {
            events.sweep_at_us = self.sweep_ready_us();
            events.sweep = Some(self.take_sweep());
        }
        events
    }

    /// The mean ready time of the sweep's fresh readings, µs (0 when none is fresh).
    fn sweep_ready_us(&self) -> Micros {
        let (sum, n) = (0..5)
            .filter(|beam| self.sweep.fresh & (1 << beam) != 0)
            .fold((0u64, 0u64), |(sum, n), beam| (sum + self.sweep.ready_us[beam], n + 1));
        sum.checked_div(n).unwrap_or(0)
    }

    /// Adds a beam's reading; a complete sweep goes out at once. A second reading of a beam before the
    /// sweep is complete (that beam's clock runs faster than the slowest one's) replaces the first.
    fn add_to_sweep<E>(&mut self, beam: usize, range: RangeReading, at_us: Micros, events: &mut DeckEvents<E>) {
        if self.sweep.fresh == 0 {
            self.sweep.oldest_us = at_us;
        }
        let (Some(reading), Some(ready)) = (self.sweep.readings.get_mut(beam), self.sweep.ready_us.get_mut(beam))
        else {
            return;
        };
        *reading = range;
        *ready = at_us;
        self.sweep.fresh |= 1 << beam;
        if self.sweep.fresh & self.beams_running == self.beams_running {
            events.sweep_at_us = self.sweep_ready_us();
            events.sweep = Some(self.take_sweep());
        }
    }

    fn take_sweep(&mut self) -> MultiRangerSample {
        let mut r = [None; 5];
        for (beam, out) in r.iter_mut().enumerate() {
            if self.sweep.fresh & (1 << beam) != 0 {
                *out = self.sweep.readings[beam];
            }
        }
        self.sweep = Sweep::default();
        MultiRangerSample {
            front_m: r[Direction::Front.index()],
            back_m: r[Direction::Back.index()],
            up_m: r[Direction::Up.index()],
            left_m: r[Direction::Left.index()],
            right_m: r[Direction::Right.index()],
        }
    }
}
