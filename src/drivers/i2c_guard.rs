//! An I2C bus with a deadline on every transaction and the stock bus recovery.
//!
//! Job: wrap any `embedded-hal-async` I2C bus so that no transaction waits longer than
//! [`GuardConfig::timeout_us`], and so that a bus that hangs (the transaction times out) or reports a
//! bus fault (a misplaced START/STOP, an arbitration loss: typically a slave holding SDA low after a
//! transfer was cut) is recovered and the transaction retried, as the stock driver does
//! (crazyflie-firmware `src/drivers/src/i2c_drv.c`: `i2cdrvMessageTransfer` → on timeout
//! `i2cdrvTryToRestartBus` → `i2cdrvdevUnlockBus`):
//!
//! 1. the pins become open-drain GPIO, both released ([`BusRecovery::begin`]);
//! 2. while SDA reads low, one SCL clock (low, then high), at most [`MAX_RECOVERY_CLOCKS`] = 9 times (a
//!    slave in the middle of a byte needs at most 8 clocks to finish it and one for the ACK; stock clocks
//!    until SDA rises, without a bound);
//! 3. a START then a STOP (SDA falls while SCL is high, SCL low, then SDA rises while SCL is high), which
//!    resets every slave's bus state machine;
//! 4. the pins go back to the peripheral, which is reset and re-initialised ([`BusRecovery::end`]).
//!
//! Half-periods are [`RECOVERY_HALF_PERIOD_US`] = 5 µs (100 kHz, stock `I2CDEV_CLK_TS` is 10 µs).
//!
//! A NACK is an answer (the chip is absent or busy), not a stuck bus: it is returned at once, without
//! recovery or retry, so drivers keep their own retry policies (a ranger's data-ready poll). A
//! transaction that is abandoned by the timeout is cancelled by dropping its future (for embassy-stm32
//! this stops the DMA), then the bus is recovered before anything else is sent.
//!
//! Non-goals: no clock stretching timeout of its own (the deadline covers it), no multi-master, no
//! blocking API. Timing comes from the [`DelayNs`] the guard is given, racing the transaction.
//!
//! Units: µs. Memory: the bus, the recovery pins, the delay, the configuration (8 bytes) and the
//! counters ([`GuardStats`], 12 bytes).

use core::future::Future;
use core::pin::pin;
use core::task::Poll;

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::{Error as _, ErrorKind, ErrorType, I2c, Operation, SevenBitAddress};

/// The most SCL clocks the recovery gives a slave that holds SDA low.
pub const MAX_RECOVERY_CLOCKS: u32 = 9;
/// Half a clock period of the recovery's bit-banged SCL, µs (100 kHz).
pub const RECOVERY_HALF_PERIOD_US: u32 = 5;

/// The pin work of the recovery, done by the board (embassy `Flex` pins or GPIO registers).
///
/// Between [`BusRecovery::begin`] and [`BusRecovery::end`] SCL and SDA are open-drain outputs: "high"
/// releases the line (the pull-up raises it), "low" drives it low. `B` is the bus the guard wraps, so
/// `end` can re-initialise its peripheral.
pub trait BusRecovery<B> {
    /// Takes SCL and SDA from the peripheral as open-drain GPIO outputs, both released.
    fn begin(&mut self, bus: &mut B);
    /// Drives SCL low (`false`) or releases it (`true`).
    fn set_scl(&mut self, high: bool);
    /// Drives SDA low (`false`) or releases it (`true`).
    fn set_sda(&mut self, high: bool);
    /// Whether the SDA line reads high.
    fn sda_is_high(&mut self) -> bool;
    /// Gives the pins back to the peripheral, then resets and re-initialises it.
    fn end(&mut self, bus: &mut B);
}

/// Timing of the guard.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GuardConfig {
    /// Deadline of one transaction, µs.
    pub timeout_us: u32,
    /// Retries after a recovery (0 = recover, then report the failure).
    pub retries: u8,
}

/// What the guard has done since it was made (for logs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GuardStats {
    /// Transactions that hit the deadline.
    pub timeouts: u32,
    /// Bus recoveries run.
    pub recoveries: u32,
    /// Recoveries after which SDA was still low (the bus may be dead: a shorted line or a dead slave).
    pub failed_recoveries: u32,
}

/// Why a guarded transaction failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GuardError<E> {
    /// The bus reported an error on the last attempt.
    Bus(E),
    /// The last attempt did not finish within the deadline.
    Timeout,
}

impl<E: embedded_hal_async::i2c::Error> embedded_hal_async::i2c::Error for GuardError<E> {
    fn kind(&self) -> ErrorKind {
        match self {
            GuardError::Bus(e) => e.kind(),
            // The closest kind: the bus did not complete the transfer.
            GuardError::Timeout => ErrorKind::Bus,
        }
    }
}

/// An I2C bus with a deadline and recovery. See the module documentation.
pub struct GuardedI2c<B, R, D> {
    bus: B,
    recovery: R,
    delay: D,
    config: GuardConfig,
    stats: GuardStats,
}

/// Runs `work` unless `deadline` finishes first; `None` on the deadline. `work` is polled first, so a
/// transaction that completes at once always wins.
pub async fn with_deadline<T>(work: impl Future<Output = T>, deadline: impl Future<Output = ()>) -> Option<T> {
    let mut work = pin!(work);
    let mut deadline = pin!(deadline);
    core::future::poll_fn(|cx| {
        if let Poll::Ready(v) = work.as_mut().poll(cx) {
            return Poll::Ready(Some(v));
        }
        if deadline.as_mut().poll(cx).is_ready() {
            return Poll::Ready(None);
        }
        Poll::Pending
    })
    .await
}

impl<B, R, D> GuardedI2c<B, R, D>
where
    B: I2c,
    R: BusRecovery<B>,
    D: DelayNs,
{
    /// Wraps `bus`; nothing is sent.
    pub fn new(bus: B, recovery: R, delay: D, config: GuardConfig) -> Self {
        Self {
            bus,
            recovery,
            delay,
            config,
            stats: GuardStats::default(),
        }
    }

    /// The counters.
    pub fn stats(&self) -> GuardStats {
        self.stats
    }

    /// The wrapped bus, recovery and delay.
    pub fn release(self) -> (B, R, D) {
        (self.bus, self.recovery, self.delay)
    }

    /// Runs the recovery now (module documentation, steps 1–4). Returns whether SDA was released.
    pub async fn recover(&mut self) -> bool {
        self.stats.recoveries = self.stats.recoveries.saturating_add(1);
        let half = RECOVERY_HALF_PERIOD_US;
        self.recovery.begin(&mut self.bus);
        self.recovery.set_sda(true);
        self.recovery.set_scl(true);
        self.delay.delay_us(half).await;
        let mut clocks = 0;
        while !self.recovery.sda_is_high() && clocks < MAX_RECOVERY_CLOCKS {
            self.recovery.set_scl(false);
            self.delay.delay_us(half).await;
            self.recovery.set_scl(true);
            self.delay.delay_us(half).await;
            clocks += 1;
        }
        let released = self.recovery.sda_is_high();
        // START (SDA falls while SCL is high), SCL low, then STOP (SDA rises while SCL is high).
        self.recovery.set_sda(false);
        self.delay.delay_us(half).await;
        self.recovery.set_scl(false);
        self.delay.delay_us(half).await;
        self.recovery.set_scl(true);
        self.delay.delay_us(half).await;
        self.recovery.set_sda(true);
        self.delay.delay_us(half).await;
        self.recovery.end(&mut self.bus);
        if !released {
            self.stats.failed_recoveries = self.stats.failed_recoveries.saturating_add(1);
        }
        released
    }
}

impl<B: I2c, R, D> ErrorType for GuardedI2c<B, R, D> {
    type Error = GuardError<B::Error>;
}

impl<B, R, D> I2c<SevenBitAddress> for GuardedI2c<B, R, D>
where
    B: I2c,
    R: BusRecovery<B>,
    D: DelayNs,
{
    async fn transaction(&mut self, address: u8, operations: &mut [Operation<'_>]) -> Result<(), Self::Error> {
        let mut attempt = 0u8;
        loop {
            let timeout_us = self.config.timeout_us;
            let outcome = with_deadline(
                self.bus.transaction(address, operations),
                self.delay.delay_us(timeout_us),
            )
            .await;
            let error = match outcome {
                Some(Ok(())) => return Ok(()),
                // An answer from the chip, not a stuck bus.
                Some(Err(e)) if matches!(e.kind(), ErrorKind::NoAcknowledge(_)) => return Err(GuardError::Bus(e)),
                Some(Err(e)) => GuardError::Bus(e),
                None => {
                    self.stats.timeouts = self.stats.timeouts.saturating_add(1);
                    GuardError::Timeout
                }
            };
            self.recover().await;
            if attempt >= self.config.retries {
                return Err(error);
            }
            attempt += 1;
        }
    }
}
