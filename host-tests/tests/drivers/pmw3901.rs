//! PMW3901 driver against recorded SPI traffic (embedded-hal-mock) written from the stock Crazyflie driver
//! (crazyflie-firmware src/drivers/src/pmw3901.c: protocol, timing, power-up and the performance table;
//! src/deck/drivers/src/flowdeck_v1v2.c: axis mapping and the 0xB0 validity rule) and the PMW3901MB
//! datasheet (register addresses, motion-burst layout, the SQUAL/Shutter_Upper rejection rule).

use std::cell::RefCell;
use std::rc::Rc;

use cfnav::drivers::DriverError;
use cfnav::drivers::pmw3901::Pmw3901;
use embassy_futures::block_on;
use embedded_hal::spi::ErrorKind;
use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::spi::{ErrorType, Operation, SpiDevice};
use embedded_hal_mock::eh1::delay::{CheckedDelay, Transaction as D};
use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as S};

const US: u32 = 1_000; // ns

/// The vendor's performance-optimisation writes as listed in crazyflie-firmware pmw3901.c `InitRegisters`
/// (transcribed for the test); `None` marks the 10 ms pause after 0x70 ← 0x00.
const TABLE: &[Option<(u8, u8)>] = &[
    Some((0x7F, 0x00)),
    Some((0x61, 0xAD)),
    Some((0x7F, 0x03)),
    Some((0x40, 0x00)),
    Some((0x7F, 0x05)),
    Some((0x41, 0xB3)),
    Some((0x43, 0xF1)),
    Some((0x45, 0x14)),
    Some((0x5B, 0x32)),
    Some((0x5F, 0x34)),
    Some((0x7B, 0x08)),
    Some((0x7F, 0x06)),
    Some((0x44, 0x1B)),
    Some((0x40, 0xBF)),
    Some((0x4E, 0x3F)),
    Some((0x7F, 0x08)),
    Some((0x65, 0x20)),
    Some((0x6A, 0x18)),
    Some((0x7F, 0x09)),
    Some((0x4F, 0xAF)),
    Some((0x5F, 0x40)),
    Some((0x48, 0x80)),
    Some((0x49, 0x80)),
    Some((0x57, 0x77)),
    Some((0x60, 0x78)),
    Some((0x61, 0x78)),
    Some((0x62, 0x08)),
    Some((0x63, 0x50)),
    Some((0x7F, 0x0A)),
    Some((0x45, 0x60)),
    Some((0x7F, 0x00)),
    Some((0x4D, 0x11)),
    Some((0x55, 0x80)),
    Some((0x74, 0x1F)),
    Some((0x75, 0x1F)),
    Some((0x4A, 0x78)),
    Some((0x4B, 0x78)),
    Some((0x44, 0x08)),
    Some((0x45, 0x50)),
    Some((0x64, 0xFF)),
    Some((0x65, 0x1F)),
    Some((0x7F, 0x14)),
    Some((0x65, 0x67)),
    Some((0x66, 0x08)),
    Some((0x63, 0x70)),
    Some((0x7F, 0x15)),
    Some((0x48, 0x48)),
    Some((0x7F, 0x07)),
    Some((0x41, 0x0D)),
    Some((0x43, 0x14)),
    Some((0x4B, 0x0E)),
    Some((0x45, 0x0F)),
    Some((0x44, 0x42)),
    Some((0x4C, 0x80)),
    Some((0x7F, 0x10)),
    Some((0x5B, 0x02)),
    Some((0x7F, 0x07)),
    Some((0x40, 0x41)),
    Some((0x70, 0x00)),
    None,
    Some((0x32, 0x44)),
    Some((0x7F, 0x07)),
    Some((0x40, 0x40)),
    Some((0x7F, 0x06)),
    Some((0x62, 0xF0)),
    Some((0x63, 0x00)),
    Some((0x7F, 0x0D)),
    Some((0x48, 0xC0)),
    Some((0x6F, 0xD5)),
    Some((0x7F, 0x00)),
    Some((0x5B, 0xA0)),
    Some((0x4E, 0xA8)),
    Some((0x5A, 0x50)),
    Some((0x40, 0x80)),
    Some((0x7F, 0x00)),
    Some((0x5A, 0x10)),
    Some((0x54, 0x00)),
];

/// Expected traffic, built up in order: SPI transactions and the CS-high delays between them.
#[derive(Default)]
struct Script {
    spi: Vec<S<u8>>,
    delays: Vec<D>,
}

impl Script {
    /// Single-register read: CS low, 50 µs, address with bit 7 clear, 500 µs, one byte, 50 µs, CS high,
    /// then 200 µs.
    fn read(&mut self, reg: u8, value: u8) -> &mut Self {
        assert_eq!(reg & 0x80, 0);
        self.spi.extend([
            S::transaction_start(),
            S::delay(50 * US),
            S::write(reg),
            S::delay(500 * US),
            S::read(value),
            S::delay(50 * US),
            S::transaction_end(),
        ]);
        self.delays.push(D::delay_us(200));
        self
    }

    /// Register write: CS low, 50 µs, address | 0x80, 50 µs, value, 50 µs, CS high, then 200 µs.
    fn write(&mut self, reg: u8, value: u8) -> &mut Self {
        self.spi.extend([
            S::transaction_start(),
            S::delay(50 * US),
            S::write(reg | 0x80),
            S::delay(50 * US),
            S::write(value),
            S::delay(50 * US),
            S::transaction_end(),
        ]);
        self.delays.push(D::delay_us(200));
        self
    }

    fn wait_ms(&mut self, ms: u32) -> &mut Self {
        self.delays.push(D::delay_ms(ms));
        self
    }

    /// Power-up wait and the SPI-port reset: 40 ms, then CS high 2 ms / low 2 ms / high 2 ms.
    fn power_up(&mut self) -> &mut Self {
        self.wait_ms(40).wait_ms(2);
        self.spi
            .extend([S::transaction_start(), S::delay(2_000 * US), S::transaction_end()]);
        self.wait_ms(2)
    }

    /// Everything after a good identity check.
    fn reset_and_table(&mut self) -> &mut Self {
        self.write(0x3A, 0x5A).wait_ms(5);
        for reg in 0x02..=0x06 {
            self.read(reg, 0x00);
        }
        self.wait_ms(1);
        for step in TABLE {
            match step {
                Some((reg, value)) => self.write(*reg, *value),
                None => self.wait_ms(10),
            };
        }
        self
    }

    fn full_init() -> Self {
        let mut s = Script::default();
        s.power_up().read(0x00, 0x49).read(0x5F, 0xB6).reset_and_table();
        s
    }

    /// Motion burst: CS low, 50 µs, 0x16, 50 µs, 12 bytes, 50 µs, CS high, then 50 µs.
    fn burst(&mut self, bytes: [u8; 12]) -> &mut Self {
        self.spi.extend([
            S::transaction_start(),
            S::delay(50 * US),
            S::write(0x16),
            S::delay(50 * US),
            S::read_vec(bytes.to_vec()),
            S::delay(50 * US),
            S::transaction_end(),
        ]);
        self.delays.push(D::delay_us(50));
        self
    }

    fn run(&self) -> (Pmw3901<SpiMock<u8>>, CheckedDelay) {
        (Pmw3901::new(SpiMock::new(&self.spi)), CheckedDelay::new(&self.delays))
    }
}

fn finish(flow: Pmw3901<SpiMock<u8>>, mut delay: CheckedDelay) {
    flow.release().done();
    delay.done();
}

#[test]
fn table_transcription_has_the_stock_length() {
    // 59 writes, the 10 ms pause, 17 writes (pmw3901.c InitRegisters).
    assert_eq!(TABLE.len(), 77);
    assert_eq!(TABLE.iter().position(Option::is_none), Some(59));
}

#[test]
fn init_runs_the_stock_power_up_sequence() {
    let script = Script::full_init();
    let (mut flow, mut delay) = script.run();
    assert_eq!(block_on(flow.init(&mut delay)), Ok(()));
    finish(flow, delay);
}

#[test]
fn absent_deck_reads_a_wrong_id_and_nothing_is_written() {
    // MISO pulled low (0x00) or floating high (0xFF): no chip.
    for found in [0x00u8, 0xFF] {
        let mut script = Script::default();
        script.power_up().read(0x00, found);
        let (mut flow, mut delay) = script.run();
        assert_eq!(
            block_on(flow.init(&mut delay)),
            Err(DriverError::WrongChipId {
                expected: 0x49,
                found: u16::from(found)
            })
        );
        finish(flow, delay);
    }
}

#[test]
fn wrong_inverse_id_is_reported() {
    let mut script = Script::default();
    script.power_up().read(0x00, 0x49).read(0x5F, 0x49);
    let (mut flow, mut delay) = script.run();
    assert_eq!(
        block_on(flow.init(&mut delay)),
        Err(DriverError::WrongChipId {
            expected: 0xB6,
            found: 0x49
        })
    );
    finish(flow, delay);
}

/// Burst bytes in datasheet order: motion, observation, Delta_X L/H, Delta_Y L/H, SQUAL, Raw_Data_Sum,
/// Maximum_Raw_Data, Minimum_Raw_Data, Shutter_Upper, Shutter_Lower.
fn burst(motion: u8, dx: i16, dy: i16, squal: u8, shutter: u16) -> [u8; 12] {
    let [dxl, dxh] = dx.to_le_bytes();
    let [dyl, dyh] = dy.to_le_bytes();
    let [su, sl] = shutter.to_be_bytes();
    [motion, 0x3F, dxl, dxh, dyl, dyh, squal, 0x20, 0x90, 0x10, su, sl]
}

#[test]
fn motion_burst_decodes_the_datasheet_layout() {
    let mut script = Script::default();
    script.burst([0xB0, 0x3F, 0x05, 0x00, 0xD4, 0xFE, 0x80, 0x21, 0x92, 0x13, 0x01, 0x2C]);
    let (mut flow, mut delay) = script.run();
    let b = block_on(flow.read_motion_burst(&mut delay)).expect("burst");
    assert_eq!(b.motion, 0xB0);
    assert_eq!(b.observation, 0x3F);
    assert_eq!(b.delta_x, 5);
    assert_eq!(b.delta_y, -300); // 0xFED4
    assert_eq!(b.squal, 0x80);
    assert_eq!(b.raw_data_sum, 0x21);
    assert_eq!(b.max_raw_data, 0x92);
    assert_eq!(b.min_raw_data, 0x13);
    assert_eq!(b.shutter, 300); // upper byte first
    assert_eq!(b.shutter_upper(), 0x01);
    finish(flow, delay);
}

#[test]
fn read_maps_axes_like_the_stock_flow_deck_and_measures_dt() {
    let mut script = Script::default();
    script
        .burst(burst(0xB0, 5, -300, 0x80, 300))
        .burst(burst(0xB0, -7, 12, 0x60, 300))
        .burst(burst(0xB0, 0, 0, 0x60, 300))
        .burst(burst(0xB0, 1, 1, 0x60, 300));
    let (mut flow, mut delay) = script.run();
    // First read: no previous read, dt is the stock period 10 ms.
    let a = block_on(flow.read(1_000_000, &mut delay)).expect("read");
    assert_eq!((a.dpixel_x, a.dpixel_y), (300, -5)); // dpixel_x = −Δy, dpixel_y = −Δx
    assert_eq!(a.squal, 0x80);
    assert!(a.motion_valid);
    assert!((a.dt_s - 0.01).abs() < 1e-7);
    let b = block_on(flow.read(1_012_000, &mut delay)).expect("read");
    assert_eq!((b.dpixel_x, b.dpixel_y), (-12, 7));
    assert!((b.dt_s - 0.012).abs() < 1e-7, "{b:?}");
    let c = block_on(flow.read(1_032_000, &mut delay)).expect("read");
    assert!((c.dt_s - 0.020).abs() < 1e-7, "{c:?}");
    // A clock that did not advance gives the nominal period, never 0 or negative.
    let d = block_on(flow.read(1_032_000, &mut delay)).expect("read");
    assert!((d.dt_s - 0.01).abs() < 1e-7, "{d:?}");
    finish(flow, delay);
}

#[test]
fn validity_follows_the_stock_motion_byte_and_the_datasheet_low_light_rule() {
    let cases = [
        // (motion, squal, shutter, valid)
        (0xB0, 0x80, 0x0100, true),
        (0x80, 0x80, 0x0100, false), // MOT alone: stock pushes only 0xB0
        (0x00, 0x80, 0x0100, false), // no motion bit
        (0xB1, 0x80, 0x0100, false),
        (0xB0, 0x18, 0x1F00, false), // SQUAL < 0x19 with Shutter_Upper = 0x1F: discard
        (0xB0, 0x18, 0x1EFF, true),  // shutter not at maximum
        (0xB0, 0x19, 0x1F00, true),  // SQUAL at the limit
        (0xB0, 0x00, 0x0000, true),  // the datasheet rule needs both conditions
    ];
    let mut script = Script::default();
    for (motion, squal, shutter, _) in cases {
        script.burst(burst(motion, 3, 4, squal, shutter));
    }
    let (mut flow, mut delay) = script.run();
    for (i, (motion, squal, shutter, valid)) in cases.into_iter().enumerate() {
        let s = block_on(flow.read(10_000 * i as u64, &mut delay)).expect("read");
        assert_eq!(
            s.motion_valid, valid,
            "motion {motion:#04X} squal {squal:#04X} shutter {shutter:#06X}"
        );
        assert_eq!(s.squal, squal);
        // Counts are reported whatever the validity (the estimator decides).
        assert_eq!((s.dpixel_x, s.dpixel_y), (-4, -3));
    }
    finish(flow, delay);
}

#[test]
fn extreme_counts_saturate_instead_of_overflowing() {
    let mut script = Script::default();
    script.burst(burst(0xB0, i16::MIN, i16::MIN, 0x80, 0x0100));
    script.burst(burst(0xB0, i16::MAX, i16::MAX, 0x80, 0x0100));
    let (mut flow, mut delay) = script.run();
    let a = block_on(flow.read(0, &mut delay)).expect("read");
    assert_eq!((a.dpixel_x, a.dpixel_y), (i16::MAX, i16::MAX));
    let b = block_on(flow.read(10_000, &mut delay)).expect("read");
    assert_eq!((b.dpixel_x, b.dpixel_y), (-i16::MAX, -i16::MAX));
    finish(flow, delay);
}

/// An SPI device that fails its `fail_call`-th transaction (0-based), otherwise behaves like the mock.
struct Flaky {
    calls: usize,
    fail_call: usize,
    inner: SpiMock<u8>,
}

impl ErrorType for Flaky {
    type Error = ErrorKind;
}

impl SpiDevice for Flaky {
    async fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), ErrorKind> {
        let call = self.calls;
        self.calls += 1;
        if call == self.fail_call {
            return Err(ErrorKind::Overrun);
        }
        self.inner.transaction(operations).await
    }
}

#[test]
fn spi_fault_during_init_is_a_bus_error() {
    // The first transaction (the CS pulse) fails: nothing after it is attempted.
    let mut script = Script::default();
    script.wait_ms(40).wait_ms(2);
    let mut flow = Pmw3901::new(Flaky {
        calls: 0,
        fail_call: 0,
        inner: SpiMock::new(&[]),
    });
    let mut delay = CheckedDelay::new(&script.delays);
    assert_eq!(
        block_on(flow.init(&mut delay)),
        Err(DriverError::Bus(ErrorKind::Overrun))
    );
    flow.release().inner.done();
    delay.done();
}

#[test]
fn spi_fault_during_a_read_is_a_bus_error_and_keeps_the_previous_timestamp() {
    let mut script = Script::default();
    script
        .burst(burst(0xB0, 1, 2, 0x80, 0x0100))
        .burst(burst(0xB0, 3, 4, 0x80, 0x0100));
    let mut flow = Pmw3901::new(Flaky {
        calls: 0,
        fail_call: 1,
        inner: SpiMock::new(&script.spi),
    });
    let mut delay = CheckedDelay::new(&script.delays);
    let a = block_on(flow.read(1_000_000, &mut delay)).expect("first read");
    assert_eq!((a.dpixel_x, a.dpixel_y), (-2, -1));
    assert_eq!(
        block_on(flow.read(1_010_000, &mut delay)),
        Err(DriverError::Bus(ErrorKind::Overrun))
    );
    // The chip kept accumulating since the last successful read: dt spans both periods.
    let c = block_on(flow.read(1_020_000, &mut delay)).expect("read after the fault");
    assert_eq!((c.dpixel_x, c.dpixel_y), (-4, -3));
    assert!((c.dt_s - 0.02).abs() < 1e-7, "{c:?}");
    flow.release().inner.done();
    delay.done();
}

/// Everything the driver does, in one ordered log: SPI transactions (with CS) and delays.
#[derive(Debug, Clone, PartialEq)]
enum Event {
    /// One transaction: bytes written (reads recorded as `None`) and in-transaction delays, ns.
    Spi(Vec<Op>),
    DelayNs(u64),
}

#[derive(Debug, Clone, PartialEq)]
enum Op {
    Write(Vec<u8>),
    Read(usize),
    Delay(u32),
}

/// A chip model that answers register reads from a fixed table and logs everything in order.
#[derive(Clone)]
struct Recorder {
    log: Rc<RefCell<Vec<Event>>>,
}

impl ErrorType for Recorder {
    type Error = ErrorKind;
}

impl SpiDevice for Recorder {
    async fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), ErrorKind> {
        let mut ops = Vec::new();
        let mut last_address = None;
        for op in operations {
            match op {
                Operation::Write(bytes) => {
                    last_address = bytes.first().copied();
                    ops.push(Op::Write(bytes.to_vec()));
                }
                Operation::Read(buf) => {
                    let answer = match last_address {
                        Some(0x00) => 0x49,
                        Some(0x5F) => 0xB6,
                        _ => 0x00,
                    };
                    buf.fill(answer);
                    ops.push(Op::Read(buf.len()));
                }
                Operation::DelayNs(ns) => ops.push(Op::Delay(*ns)),
                Operation::Transfer(..) | Operation::TransferInPlace(..) => panic!("unexpected transfer"),
            }
        }
        self.log.borrow_mut().push(Event::Spi(ops));
        Ok(())
    }
}

impl DelayNs for Recorder {
    async fn delay_ns(&mut self, ns: u32) {
        self.log.borrow_mut().push(Event::DelayNs(u64::from(ns)));
    }
    async fn delay_us(&mut self, us: u32) {
        self.log.borrow_mut().push(Event::DelayNs(u64::from(us) * 1_000));
    }
    async fn delay_ms(&mut self, ms: u32) {
        self.log.borrow_mut().push(Event::DelayNs(u64::from(ms) * 1_000_000));
    }
}

fn is_write(e: &Event, reg: u8, value: u8) -> bool {
    matches!(e, Event::Spi(ops) if ops.iter().filter_map(|o| match o {
        Op::Write(b) => Some(b[0]),
        _ => None,
    }).eq([reg | 0x80, value]))
}

#[test]
fn init_orders_delays_and_accesses_as_the_datasheet_requires() {
    let rec = Recorder {
        log: Rc::new(RefCell::new(Vec::new())),
    };
    let mut flow = Pmw3901::new(rec.clone());
    let mut delay = rec.clone();
    assert_eq!(block_on(flow.init(&mut delay)), Ok(()));
    let log = rec.log.borrow();
    // The first SPI traffic is the CS pulse, after at least 40 ms.
    let first_spi = log.iter().position(|e| matches!(e, Event::Spi(_))).unwrap();
    let waited: u64 = log[..first_spi]
        .iter()
        .map(|e| if let Event::DelayNs(ns) = e { *ns } else { 0 })
        .sum();
    assert!(waited >= 42_000_000, "{waited} ns before the CS pulse");
    assert_eq!(log[first_spi], Event::Spi(vec![Op::Delay(2_000_000)]));
    assert_eq!(log[first_spi + 1], Event::DelayNs(2_000_000));
    // Power-up reset, then ≥ 5 ms (after its 200 µs CS-high gap) before the next access.
    let reset = log
        .iter()
        .position(|e| is_write(e, 0x3A, 0x5A))
        .expect("power-up reset");
    assert_eq!(log[reset + 1], Event::DelayNs(200_000));
    assert_eq!(log[reset + 2], Event::DelayNs(5_000_000));
    // Then reads of 0x02..=0x06, in order, before any table write.
    let reads: Vec<u8> = log[reset + 3..]
        .iter()
        .filter_map(|e| match e {
            Event::Spi(ops) => match ops.as_slice() {
                [
                    Op::Delay(50_000),
                    Op::Write(a),
                    Op::Delay(500_000),
                    Op::Read(1),
                    Op::Delay(50_000),
                ] => Some(a[0]),
                _ => None,
            },
            _ => None,
        })
        .collect();
    assert_eq!(reads, vec![0x02, 0x03, 0x04, 0x05, 0x06]);
    // The 10 ms pause sits between 0x70 ← 0x00 and 0x32 ← 0x44.
    let before = log.iter().position(|e| is_write(e, 0x70, 0x00)).unwrap();
    assert_eq!(log[before + 1], Event::DelayNs(200_000));
    assert_eq!(log[before + 2], Event::DelayNs(10_000_000));
    assert!(is_write(&log[before + 3], 0x32, 0x44));
    // Every register access is followed by its CS-high gap.
    for (i, e) in log.iter().enumerate() {
        if let Event::Spi(ops) = e
            && ops.len() == 5
        {
            assert_eq!(log.get(i + 1), Some(&Event::DelayNs(200_000)), "access {i} without gap");
        }
    }
}

#[test]
fn driver_state_beyond_the_spi_device_is_the_previous_timestamp() {
    // Module doc: 16 bytes (Option<u64> microseconds).
    assert_eq!(size_of::<Pmw3901<()>>(), 16);
}

// The flow read's recovery policy (`ReadHealth`): the board drops a failed read (a timed-out transfer
// after a lost SPI byte, a bus error), and re-synchronises the chip only when failures repeat. Oracle:
// the rule as specified (drop one, resync after RESYNC_AFTER_FAILURES in a row, count everything).

use cfnav::drivers::pmw3901::{RESYNC_AFTER_FAILURES, ReadHealth, ReadOutcome, RecoveryAction};

#[test]
fn a_single_timeout_is_dropped_without_resync() {
    let mut health = ReadHealth::new();
    assert_eq!(health.record(ReadOutcome::Read), RecoveryAction::None);
    assert_eq!(health.record(ReadOutcome::Timeout), RecoveryAction::None);
    assert_eq!(health.record(ReadOutcome::Read), RecoveryAction::None);
    assert_eq!(health.record(ReadOutcome::Timeout), RecoveryAction::None);
    let stats = health.stats();
    assert_eq!((stats.timeouts, stats.bus_errors, stats.resyncs), (2, 0, 0));
}

#[test]
fn repeated_timeouts_resync_the_chip_and_the_count_restarts() {
    assert_eq!(RESYNC_AFTER_FAILURES, 2);
    let mut health = ReadHealth::new();
    assert_eq!(health.record(ReadOutcome::Timeout), RecoveryAction::None);
    assert_eq!(health.record(ReadOutcome::Timeout), RecoveryAction::Resync);
    assert_eq!(health.failures_in_a_row(), 0);
    health.record_resync(true);
    // The next failure after a resync is a new glitch, not a repeat.
    assert_eq!(health.record(ReadOutcome::Timeout), RecoveryAction::None);
    let stats = health.stats();
    assert_eq!((stats.timeouts, stats.resyncs, stats.failed_resyncs), (3, 1, 0));
}

#[test]
fn bus_errors_and_timeouts_count_together_towards_a_resync() {
    let mut health = ReadHealth::new();
    assert_eq!(health.record(ReadOutcome::BusError), RecoveryAction::None);
    assert_eq!(health.record(ReadOutcome::Timeout), RecoveryAction::Resync);
    let stats = health.stats();
    assert_eq!((stats.timeouts, stats.bus_errors, stats.resyncs), (1, 1, 1));
}

#[test]
fn an_unplugged_deck_is_retried_every_few_periods_and_never_saturates_into_a_panic() {
    let mut health = ReadHealth::new();
    let mut resyncs = 0u32;
    for _ in 0..1_000 {
        if health.record(ReadOutcome::Timeout) == RecoveryAction::Resync {
            resyncs += 1;
            health.record_resync(false);
        }
    }
    assert_eq!(resyncs, 1_000 / u32::from(RESYNC_AFTER_FAILURES));
    let stats = health.stats();
    assert_eq!(stats.resyncs, resyncs);
    assert_eq!(stats.failed_resyncs, resyncs);
    assert_eq!(stats.timeouts, 1_000);
    // Plugged back in: the first good read clears the streak.
    assert_eq!(health.record(ReadOutcome::Read), RecoveryAction::None);
    assert_eq!(health.failures_in_a_row(), 0);
}
