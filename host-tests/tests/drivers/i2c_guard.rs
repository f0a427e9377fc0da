//! The I2C guard against a simulated bus: a transfer that never completes, a NACK, a slave that holds SDA
//! low until it is clocked. The oracle is the I2C bus itself (a slave in the middle of a byte releases
//! SDA after at most 9 clocks; a STOP is SDA rising while SCL is high) and the stock recovery sequence
//! (crazyflie-firmware i2c_drv.c `i2cdrvdevUnlockBus`).

use std::cell::RefCell;
use std::future::Future;
use std::pin::pin;
use std::rc::Rc;
use std::task::{Context, Waker};

use cfnav::drivers::DriverError;
use cfnav::drivers::bmi088::Bmi088;
use cfnav::drivers::i2c_guard::{BusRecovery, GuardConfig, GuardError, GuardStats, GuardedI2c, MAX_RECOVERY_CLOCKS};
use embassy_futures::block_on;
use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource};
use embedded_hal_async::i2c::{ErrorType, I2c, Operation};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Line {
    SclLow,
    SclHigh,
    SdaLow,
    SdaHigh,
}

/// The simulated bus: the peripheral's transfers, a slave that may hold SDA, the pins during recovery.
#[derive(Default)]
struct World {
    /// Transactions that will hang (a future that never completes) before one succeeds.
    stalls_left: u32,
    /// Every transaction hangs.
    stall_forever: bool,
    /// Every transaction is NACKed.
    nack: bool,
    /// Clocks the slave still needs before it releases SDA (u32::MAX: never). While it holds SDA, the
    /// peripheral cannot make a START: the transfer hangs.
    sda_held_for_clocks: u32,
    /// Pins are GPIO (between begin and end).
    gpio: bool,
    scl_high: bool,
    sda_released_by_master: bool,
    /// Line changes while the pins are GPIO.
    lines: Vec<Line>,
    /// SCL rising edges while GPIO.
    clocks: u32,
    /// Peripheral re-initialisations.
    reinits: u32,
    /// Transactions started.
    started: u32,
    /// Simulated time, µs (advanced by the delay).
    now_us: u64,
    /// Transactions attempted while the pins were GPIO (must stay 0).
    during_recovery: u32,
}

#[derive(Clone, Default)]
struct Sim(Rc<RefCell<World>>);

impl Sim {
    fn sda_high(&self) -> bool {
        let w = self.0.borrow();
        w.sda_released_by_master && w.sda_held_for_clocks == 0
    }
}

impl ErrorType for Sim {
    type Error = ErrorKind;
}

impl I2c for Sim {
    async fn transaction(&mut self, _address: u8, operations: &mut [Operation<'_>]) -> Result<(), ErrorKind> {
        let hang = {
            let mut w = self.0.borrow_mut();
            w.started += 1;
            if w.gpio {
                w.during_recovery += 1;
            }
            if w.stalls_left > 0 {
                w.stalls_left -= 1;
                true
            } else {
                w.stall_forever || w.sda_held_for_clocks > 0
            }
        };
        if hang {
            std::future::pending::<()>().await;
        }
        if self.0.borrow().nack {
            return Err(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address));
        }
        for op in operations {
            if let Operation::Read(buf) = op {
                buf.fill(0x5A);
            }
        }
        Ok(())
    }
}

impl BusRecovery<Sim> for Sim {
    fn begin(&mut self, _bus: &mut Sim) {
        let mut w = self.0.borrow_mut();
        w.gpio = true;
        w.scl_high = true;
        w.sda_released_by_master = true;
    }
    fn set_scl(&mut self, high: bool) {
        let mut w = self.0.borrow_mut();
        assert!(w.gpio, "SCL driven outside the recovery");
        if high && !w.scl_high {
            w.clocks += 1;
            if w.sda_held_for_clocks != u32::MAX {
                w.sda_held_for_clocks = w.sda_held_for_clocks.saturating_sub(1);
            }
        }
        w.scl_high = high;
        w.lines.push(if high { Line::SclHigh } else { Line::SclLow });
    }
    fn set_sda(&mut self, high: bool) {
        let mut w = self.0.borrow_mut();
        assert!(w.gpio, "SDA driven outside the recovery");
        w.sda_released_by_master = high;
        w.lines.push(if high { Line::SdaHigh } else { Line::SdaLow });
    }
    fn sda_is_high(&mut self) -> bool {
        self.sda_high()
    }
    fn end(&mut self, _bus: &mut Sim) {
        let mut w = self.0.borrow_mut();
        assert!(
            w.scl_high && w.sda_released_by_master,
            "lines released before the peripheral takes them"
        );
        w.gpio = false;
        w.reinits += 1;
    }
}

/// A delay that advances the simulated time at once.
impl embedded_hal_async::delay::DelayNs for Sim {
    async fn delay_ns(&mut self, ns: u32) {
        self.0.borrow_mut().now_us += u64::from(ns.div_ceil(1000));
    }
}

const CONFIG: GuardConfig = GuardConfig {
    timeout_us: 2_000,
    retries: 1,
};

fn guarded(sim: &Sim) -> GuardedI2c<Sim, Sim, Sim> {
    GuardedI2c::new(sim.clone(), sim.clone(), sim.clone(), CONFIG)
}

fn read(bus: &mut GuardedI2c<Sim, Sim, Sim>) -> Result<[u8; 2], GuardError<ErrorKind>> {
    let mut buf = [0u8; 2];
    block_on(bus.write_read(0x18, &[0x12], &mut buf)).map(|()| buf)
}

/// The lines after the clocking end with a START then a STOP: SDA falls while SCL is high, SCL falls,
/// SCL rises, SDA rises while SCL is high.
fn ends_with_start_stop(lines: &[Line]) -> bool {
    lines.ends_with(&[Line::SdaLow, Line::SclLow, Line::SclHigh, Line::SdaHigh])
}

#[test]
fn a_transfer_that_never_completes_ends_at_the_deadline_and_is_retried_after_a_recovery() {
    let sim = Sim::default();
    sim.0.borrow_mut().stalls_left = 1;
    let mut bus = guarded(&sim);
    assert_eq!(read(&mut bus), Ok([0x5A, 0x5A]));
    assert_eq!(
        bus.stats(),
        GuardStats {
            timeouts: 1,
            recoveries: 1,
            failed_recoveries: 0
        }
    );
    let w = sim.0.borrow();
    assert_eq!(w.started, 2);
    assert_eq!(w.reinits, 1);
    assert_eq!(w.clocks, 1, "only the STOP's clock: SDA was already high");
    assert!(ends_with_start_stop(&w.lines), "{:?}", w.lines);
    assert_eq!(w.during_recovery, 0);
}

#[test]
fn a_bus_that_hangs_for_good_fails_in_bounded_time() {
    let sim = Sim::default();
    sim.0.borrow_mut().stall_forever = true;
    let mut bus = guarded(&sim);
    assert_eq!(read(&mut bus), Err(GuardError::Timeout));
    let w = sim.0.borrow();
    // One try and one retry, each followed by a recovery.
    assert_eq!(w.started, 2);
    assert_eq!(w.reinits, 2);
    // Two deadlines plus two recoveries of (1 + 4) half-periods of 5 µs: well inside 5 control periods.
    assert_eq!(w.now_us, 2 * 2_000 + 2 * 5 * 5);
    assert!(w.now_us < 5_000);
}

#[test]
fn a_nack_is_returned_at_once_without_recovery() {
    let sim = Sim::default();
    sim.0.borrow_mut().nack = true;
    let mut bus = guarded(&sim);
    assert_eq!(
        read(&mut bus),
        Err(GuardError::Bus(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address)))
    );
    let w = sim.0.borrow();
    assert_eq!((w.started, w.reinits, w.clocks, w.now_us), (1, 0, 0, 0));
    assert_eq!(bus.stats(), GuardStats::default());
}

#[test]
fn a_slave_holding_sda_is_clocked_until_it_lets_go_then_start_stop_and_reinit() {
    let sim = Sim::default();
    sim.0.borrow_mut().sda_held_for_clocks = 5;
    let mut bus = guarded(&sim);
    assert_eq!(read(&mut bus), Ok([0x5A, 0x5A]));
    let w = sim.0.borrow();
    // Five clocks for the slave, then the one of the START/STOP.
    assert_eq!(w.clocks, 5 + 1);
    assert!(ends_with_start_stop(&w.lines), "{:?}", w.lines);
    assert_eq!(w.reinits, 1);
    assert_eq!(bus.stats().failed_recoveries, 0);
}

#[test]
fn a_line_held_low_for_good_gets_nine_clocks_per_recovery_and_is_reported() {
    let sim = Sim::default();
    sim.0.borrow_mut().sda_held_for_clocks = u32::MAX;
    let mut bus = guarded(&sim);
    assert_eq!(read(&mut bus), Err(GuardError::Timeout));
    let w = sim.0.borrow();
    assert_eq!(MAX_RECOVERY_CLOCKS, 9);
    assert_eq!(w.clocks, 2 * (9 + 1));
    assert_eq!(bus.stats().failed_recoveries, 2);
}

#[test]
fn an_imu_read_on_a_hung_bus_returns_an_error_instead_of_waiting_forever() {
    // The hazard: the bare bus never completes (one poll, still pending, and it would stay so).
    let sim = Sim::default();
    sim.0.borrow_mut().stall_forever = true;
    let mut bare = Bmi088::new(sim.clone());
    {
        let mut read = pin!(bare.read());
        let mut cx = Context::from_waker(Waker::noop());
        assert!(read.as_mut().poll(&mut cx).is_pending());
        assert!(read.as_mut().poll(&mut cx).is_pending());
    }
    // Guarded: an error within the deadline, retry and recoveries.
    let mut imu = Bmi088::new(guarded(&sim));
    let before = sim.0.borrow().now_us;
    assert_eq!(block_on(imu.read()), Err(DriverError::Bus(GuardError::Timeout)));
    assert!(sim.0.borrow().now_us - before < 5_000);
}
