//! BMI088 driver against recorded I2C traffic (embedded-hal-mock) written from the Bosch BMI088 datasheet
//! (BST-BMI088-DS001 §5 register map) and the stock Crazyflie configuration (crazyflie-firmware
//! sensors_bmi088_bmp3xx.c, docs/hardware.md §2): full init, a data read converted with the
//! datasheet's scale formulas, and every failure path (NACK, wrong id, ACC_ERR_REG, config read-back,
//! data-ready timeout).

use super::NACK;
use cfnav::drivers::DriverError;
use cfnav::drivers::bmi088::{Bmi088, DATA_READY_POLLS};
use embassy_futures::block_on;
use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource};
use embedded_hal_mock::eh1::delay::{CheckedDelay, Transaction as D};
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as T};

// Datasheet facts, written here independently of the driver.
const ACC: u8 = 0x18; // SDO1 to GND on the CF2.1
const GYR: u8 = 0x69; // SDO2 to VDDIO on the CF2.1
const G: f32 = 9.81; // the g of cfnav::types::GRAVITY_M_S2 and the simulator

fn reg_read(addr: u8, reg: u8, value: u8) -> T {
    T::write_read(addr, vec![reg], vec![value])
}

fn reg_write(addr: u8, reg: u8, value: u8) -> T {
    T::write(addr, vec![reg, value])
}

/// Gyro part of init: id, soft reset, normal mode, ±2000 °/s, 1 kHz / 116 Hz, DRDY on INT3 active-high
/// push-pull, DRDY interrupt on.
fn gyro_init() -> (Vec<T>, Vec<D>) {
    (
        vec![
            reg_read(GYR, 0x00, 0x0F),  // GYRO_CHIP_ID
            reg_write(GYR, 0x14, 0xB6), // GYRO_SOFTRESET
            reg_read(GYR, 0x00, 0x0F),  // back after the reset
            reg_write(GYR, 0x11, 0x00), // GYRO_LPM1: normal
            reg_write(GYR, 0x0F, 0x00), // GYRO_RANGE: ±2000 °/s
            reg_write(GYR, 0x10, 0x02), // GYRO_BANDWIDTH: ODR 1000 Hz, 116 Hz
            reg_write(GYR, 0x16, 0x0D), // INT3_INT4_IO_CONF: int3_lvl = 1, int3_od = 0 (INT4 at reset)
            reg_write(GYR, 0x18, 0x01), // INT3_INT4_IO_MAP: DRDY → INT3
            reg_write(GYR, 0x15, 0x80), // GYRO_INT_CTRL: DRDY enable
        ],
        vec![D::delay_ms(30), D::delay_ms(30)],
    )
}

/// Accelerometer part of init up to (not including) the error check.
fn accel_config() -> (Vec<T>, Vec<D>) {
    (
        vec![
            reg_read(ACC, 0x00, 0x1E),  // ACC_CHIP_ID
            reg_write(ACC, 0x7E, 0xB6), // ACC_SOFTRESET
            reg_read(ACC, 0x00, 0x1E),  // back after the reset
            reg_write(ACC, 0x7D, 0x04), // ACC_PWR_CTRL: on
            reg_write(ACC, 0x7C, 0x00), // ACC_PWR_CONF: active
            reg_write(ACC, 0x40, 0x8C), // ACC_CONF: bwp OSR4 (0x8 << 4) | odr 1600 Hz (0xC)
            reg_write(ACC, 0x41, 0x03), // ACC_RANGE: ±24 g
        ],
        vec![D::delay_ms(1), D::delay_ms(5), D::delay_ms(10)],
    )
}

/// Error register clean and ACC_CONF/ACC_RANGE read back (ACC_RANGE's reserved bits may read non-zero).
fn accel_checks() -> Vec<T> {
    vec![
        reg_read(ACC, 0x02, 0x00),
        T::write_read(ACC, vec![0x40], vec![0x8C, 0xF3]),
    ]
}

/// Data ready at the first poll: ACC_STATUS bit 7, then GYRO_INT_STAT_1 bit 7.
fn ready_at_once() -> Vec<T> {
    vec![reg_read(ACC, 0x03, 0x80), reg_read(GYR, 0x0A, 0x80)]
}

fn full_init() -> (Vec<T>, Vec<D>) {
    let (mut bus, mut delays) = gyro_init();
    let (b, d) = accel_config();
    bus.extend(b);
    delays.extend(d);
    bus.extend(accel_checks());
    bus.extend(ready_at_once());
    (bus, delays)
}

fn run_init(bus: &[T], delays: &[D]) -> (Result<(), DriverError<ErrorKind>>, Bmi088<I2cMock>, CheckedDelay) {
    let mut imu = Bmi088::new(I2cMock::new(bus));
    let mut delay = CheckedDelay::new(delays);
    let result = block_on(imu.init(&mut delay));
    (result, imu, delay)
}

fn finish(imu: Bmi088<I2cMock>, mut delay: CheckedDelay) {
    imu.release().done();
    delay.done();
}

#[test]
fn init_writes_the_stock_configuration_with_the_datasheet_delays() {
    let (bus, delays) = full_init();
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(result, Ok(()));
    assert!(imu.is_initialised());
    assert_eq!(imu.last_accel_error(), 0);
    finish(imu, delay);
}

#[test]
fn init_polls_data_ready_one_millisecond_apart() {
    let (mut bus, mut delays) = gyro_init();
    let (b, d) = accel_config();
    bus.extend(b);
    delays.extend(d);
    bus.extend(accel_checks());
    // Accelerometer ready at the third poll (other ACC_STATUS bits are reserved and ignored), gyro at the
    // second.
    bus.extend([
        reg_read(ACC, 0x03, 0x00),
        reg_read(ACC, 0x03, 0x7F),
        reg_read(ACC, 0x03, 0x80),
        reg_read(GYR, 0x0A, 0x00),
        reg_read(GYR, 0x0A, 0x80),
    ]);
    delays.extend([D::delay_ms(1), D::delay_ms(1), D::delay_ms(1)]);
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(result, Ok(()));
    finish(imu, delay);
}

/// Expected gyro rate from the datasheet: ±2000 °/s full scale over ±32768 LSB.
fn gyro_rad_s(raw: i16) -> f32 {
    (raw as f32 / 32768.0 * 2000.0).to_radians()
}

/// Expected acceleration from the datasheet formula `mg = raw / 32768 · 1000 · 2^(range + 1) · 1.5`
/// with ACC_RANGE = 3, in m/s².
fn accel_m_s2(raw: i16) -> f32 {
    let range = 3;
    raw as f32 / 32768.0 * 1000.0 * 2f32.powi(range + 1) * 1.5 / 1000.0 * G
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-6 * b.abs().max(1.0)
}

#[test]
fn read_converts_little_endian_counts_to_si_in_the_body_frame() {
    // Gyro: x = 0x4000 = +16384 (+1000 °/s), y = 0x8000 = −32768 (−2000 °/s), z = 0x0001 (+1 LSB).
    // Accel: level at rest: x = −2 LSB, y = +3 LSB, z = 0x0555 = 1365 LSB ≈ +1 g (1365.33 LSB/g).
    let bus = [
        T::write_read(GYR, vec![0x02], vec![0x00, 0x40, 0x00, 0x80, 0x01, 0x00]),
        T::write_read(ACC, vec![0x12], vec![0xFE, 0xFF, 0x03, 0x00, 0x55, 0x05]),
    ];
    let mut imu = Bmi088::new(I2cMock::new(&bus));
    let sample = block_on(imu.read()).expect("read");
    let expected_gyro = [gyro_rad_s(16384), gyro_rad_s(-32768), gyro_rad_s(1)];
    let expected_accel = [accel_m_s2(-2), accel_m_s2(3), accel_m_s2(1365)];
    for i in 0..3 {
        assert!(close(sample.gyro_rad_s[i], expected_gyro[i]), "gyro {i}: {sample:?}");
        assert!(close(sample.accel_m_s2[i], expected_accel[i]), "accel {i}: {sample:?}");
    }
    // Sanity in physical terms: +1000 °/s is 17.45 rad/s; 1365 LSB is one g up (level, at rest).
    assert!((sample.gyro_rad_s[0] - 17.453_29).abs() < 1e-4);
    assert!((sample.accel_m_s2[2] - G).abs() < 0.01);
    imu.release().done();
}

#[test]
fn read_raw_keeps_the_counts() {
    let bus = [
        T::write_read(GYR, vec![0x02], vec![0xFF, 0x7F, 0x00, 0x00, 0x34, 0x12]),
        T::write_read(ACC, vec![0x12], vec![0x01, 0x80, 0x10, 0x00, 0x00, 0x01]),
    ];
    let mut imu = Bmi088::new(I2cMock::new(&bus));
    let raw = block_on(imu.read_raw()).expect("read");
    assert_eq!(raw.gyro, [32767, 0, 0x1234]);
    assert_eq!(raw.accel, [-32767, 16, 256]);
    imu.release().done();
}

#[test]
fn nack_at_the_gyro_probe_is_a_bus_error_and_nothing_else_is_sent() {
    let bus = [reg_read(GYR, 0x00, 0x00).with_error(NACK)];
    let (result, imu, delay) = run_init(&bus, &[]);
    assert_eq!(result, Err(DriverError::Bus(NACK)));
    assert!(!imu.is_initialised());
    finish(imu, delay);
}

#[test]
fn nack_at_the_accelerometer_probe_is_a_bus_error() {
    let (mut bus, delays) = gyro_init();
    bus.push(reg_read(ACC, 0x00, 0x00).with_error(NACK));
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(result, Err(DriverError::Bus(NACK)));
    finish(imu, delay);
}

#[test]
fn nack_during_configuration_is_a_bus_error() {
    let (mut bus, _) = gyro_init();
    // GYRO_LPM1 (normal mode) lost.
    bus.truncate(4);
    bus[3] = reg_write(GYR, 0x11, 0x00).with_error(ErrorKind::ArbitrationLoss);
    let (result, imu, delay) = run_init(&bus, &[D::delay_ms(30)]);
    assert_eq!(result, Err(DriverError::Bus(ErrorKind::ArbitrationLoss)));
    finish(imu, delay);
}

/// The soft-reset write of both halves NACKed (the chip resets while it receives the command): init goes
/// on, the chip id read after the reset decides.
#[test]
fn soft_reset_that_is_not_acknowledged_does_not_abort_init() {
    let (mut bus, mut delays) = full_init();
    for t in bus.iter_mut() {
        if *t == reg_write(GYR, 0x14, 0xB6) || *t == reg_write(ACC, 0x7E, 0xB6) {
            *t = t
                .clone()
                .with_error(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data));
        }
    }
    // The gyro is still booting at the first id read after its reset: one NACK, then it answers 5 ms later.
    let at = bus
        .iter()
        .position(|t| *t == reg_write(GYR, 0x14, 0xB6).with_error(ErrorKind::NoAcknowledge(NoAcknowledgeSource::Data)));
    let at = at.expect("gyro reset in the script") + 1;
    bus.insert(at, reg_read(GYR, 0x00, 0x00).with_error(NACK));
    delays.insert(1, D::delay_ms(5));
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(result, Ok(()));
    assert!(imu.is_initialised());
    finish(imu, delay);
}

/// A chip that never comes back after the reset: three id reads (5 ms apart), then the last error.
#[test]
fn chip_that_does_not_return_after_its_soft_reset_fails_init() {
    let bus = [
        reg_read(GYR, 0x00, 0x0F),
        reg_write(GYR, 0x14, 0xB6).with_error(NACK),
        reg_read(GYR, 0x00, 0x00).with_error(NACK),
        reg_read(GYR, 0x00, 0x00).with_error(NACK),
        reg_read(GYR, 0x00, 0xFF),
    ];
    let delays = [D::delay_ms(30), D::delay_ms(5), D::delay_ms(5)];
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(
        result,
        Err(DriverError::WrongChipId {
            expected: 0x0F,
            found: 0xFF
        })
    );
    assert!(!imu.is_initialised());
    finish(imu, delay);
}

#[test]
fn wrong_gyro_id_is_reported_and_nothing_is_written() {
    // An all-ones read (floating bus that still ACKs) is not a BMI088 gyro.
    let bus = [reg_read(GYR, 0x00, 0xFF)];
    let (result, imu, delay) = run_init(&bus, &[]);
    assert_eq!(
        result,
        Err(DriverError::WrongChipId {
            expected: 0x0F,
            found: 0xFF
        })
    );
    finish(imu, delay);
}

#[test]
fn wrong_accelerometer_id_is_reported() {
    // 0x1F is the BMI085's accelerometer id: a different part, different ranges.
    let (mut bus, delays) = gyro_init();
    bus.push(reg_read(ACC, 0x00, 0x1F));
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(
        result,
        Err(DriverError::WrongChipId {
            expected: 0x1E,
            found: 0x1F
        })
    );
    finish(imu, delay);
}

fn init_with_error_register(value: u8) -> (Result<(), DriverError<ErrorKind>>, Bmi088<I2cMock>, CheckedDelay) {
    let (mut bus, mut delays) = gyro_init();
    let (b, d) = accel_config();
    bus.extend(b);
    delays.extend(d);
    bus.push(reg_read(ACC, 0x02, value));
    run_init(&bus, &delays)
}

#[test]
fn accelerometer_fatal_error_is_reported() {
    // ACC_ERR_REG bit 0 fatal_err: chip not operational.
    let (result, imu, delay) = init_with_error_register(0x01);
    assert_eq!(result, Err(DriverError::InvalidData));
    assert_eq!(imu.last_accel_error(), 0x01);
    assert!(!imu.is_initialised());
    finish(imu, delay);
}

#[test]
fn accelerometer_configuration_error_is_reported() {
    // ACC_ERR_REG bits 4:2 error_code = 1: invalid ACC_CONF.
    let (result, imu, delay) = init_with_error_register(0x01 << 2);
    assert_eq!(result, Err(DriverError::InvalidConfig));
    assert_eq!(imu.last_accel_error(), 0x04);
    finish(imu, delay);
}

#[test]
fn reserved_error_bits_alone_are_not_an_error() {
    // Bits 7:5 and 1 are reserved in ACC_ERR_REG.
    let (mut bus, mut delays) = gyro_init();
    let (b, d) = accel_config();
    bus.extend(b);
    delays.extend(d);
    bus.push(reg_read(ACC, 0x02, 0xE2));
    bus.push(T::write_read(ACC, vec![0x40], vec![0x8C, 0x03]));
    bus.extend(ready_at_once());
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(result, Ok(()));
    assert_eq!(imu.last_accel_error(), 0xE2);
    finish(imu, delay);
}

#[test]
fn configuration_that_does_not_read_back_is_refused() {
    for readback in [[0xA8, 0x03], [0x8C, 0x01]] {
        // 0xA8 = ACC_CONF reset value (write lost); 0x01 = ACC_RANGE reset value (±6 g).
        let (mut bus, mut delays) = gyro_init();
        let (b, d) = accel_config();
        bus.extend(b);
        delays.extend(d);
        bus.push(reg_read(ACC, 0x02, 0x00));
        bus.push(T::write_read(ACC, vec![0x40], readback.to_vec()));
        let (result, imu, delay) = run_init(&bus, &delays);
        assert_eq!(result, Err(DriverError::InvalidConfig), "read back {readback:02X?}");
        finish(imu, delay);
    }
}

#[test]
fn accelerometer_that_never_has_data_times_out() {
    let (mut bus, mut delays) = gyro_init();
    let (b, d) = accel_config();
    bus.extend(b);
    delays.extend(d);
    bus.extend(accel_checks());
    for i in 0..DATA_READY_POLLS {
        bus.push(reg_read(ACC, 0x03, 0x00));
        if i > 0 {
            delays.push(D::delay_ms(1));
        }
    }
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(result, Err(DriverError::Timeout));
    assert!(!imu.is_initialised());
    // The budget covers many periods of the slowest configured rate (1 kHz gyro).
    const { assert!(DATA_READY_POLLS >= 5) };
    finish(imu, delay);
}

#[test]
fn gyro_that_never_has_data_times_out() {
    let (mut bus, mut delays) = gyro_init();
    let (b, d) = accel_config();
    bus.extend(b);
    delays.extend(d);
    bus.extend(accel_checks());
    bus.push(reg_read(ACC, 0x03, 0x80));
    for i in 0..DATA_READY_POLLS {
        bus.push(reg_read(GYR, 0x0A, 0x7F));
        if i > 0 {
            delays.push(D::delay_ms(1));
        }
    }
    let (result, imu, delay) = run_init(&bus, &delays);
    assert_eq!(result, Err(DriverError::Timeout));
    finish(imu, delay);
}

#[test]
fn init_after_a_failure_starts_over() {
    let (good_bus, good_delays) = full_init();
    let mut bus = vec![reg_read(GYR, 0x00, 0x00).with_error(NACK)];
    bus.extend(good_bus);
    let mut imu = Bmi088::new(I2cMock::new(&bus));
    let mut delay = CheckedDelay::new(&good_delays);
    assert_eq!(block_on(imu.init(&mut delay)), Err(DriverError::Bus(NACK)));
    assert_eq!(block_on(imu.init(&mut delay)), Ok(()));
    assert!(imu.is_initialised());
    finish(imu, delay);
}

#[test]
fn nack_during_a_read_is_a_bus_error() {
    let bus = [
        T::write_read(GYR, vec![0x02], vec![0; 6]),
        T::write_read(ACC, vec![0x12], vec![0; 6]).with_error(NACK),
    ];
    let mut imu = Bmi088::new(I2cMock::new(&bus));
    assert_eq!(block_on(imu.read()), Err(DriverError::Bus(NACK)));
    imu.release().done();
}

#[test]
fn runtime_error_check_reads_acc_err_reg() {
    let bus = [reg_read(ACC, 0x02, 0x00), reg_read(ACC, 0x02, 0x01)];
    let mut imu = Bmi088::new(I2cMock::new(&bus));
    assert_eq!(block_on(imu.check_accel_errors()), Ok(()));
    assert_eq!(block_on(imu.check_accel_errors()), Err(DriverError::InvalidData));
    assert_eq!(imu.last_accel_error(), 0x01);
    imu.release().done();
}

/// Everything the driver does on the bus and with the delay, in one ordered log.
#[derive(Debug, Clone, PartialEq)]
enum Event {
    /// Register write: address, register, value.
    Write(u8, u8, u8),
    /// Register read: address, first register, length.
    Read(u8, u8, usize),
    DelayNs(u64),
}

/// A BMI088 model that answers like a healthy chip and logs every access and delay in order.
#[derive(Clone, Default)]
struct Recorder {
    log: std::rc::Rc<std::cell::RefCell<Vec<Event>>>,
}

impl embedded_hal_async::i2c::ErrorType for Recorder {
    type Error = ErrorKind;
}

impl embedded_hal_async::i2c::I2c for Recorder {
    async fn transaction(
        &mut self,
        address: u8,
        operations: &mut [embedded_hal_async::i2c::Operation<'_>],
    ) -> Result<(), ErrorKind> {
        use embedded_hal_async::i2c::Operation;
        let mut register = None;
        for op in operations {
            match op {
                Operation::Write(bytes) if bytes.len() == 2 => {
                    self.log.borrow_mut().push(Event::Write(address, bytes[0], bytes[1]));
                }
                Operation::Write(bytes) if bytes.len() == 1 => register = Some(bytes[0]),
                Operation::Write(bytes) => panic!("unexpected write {bytes:02X?}"),
                Operation::Read(buf) => {
                    let reg = register.expect("read without a register");
                    let answer: &[u8] = match (address, reg) {
                        (GYR, 0x00) => &[0x0F],
                        (ACC, 0x00) => &[0x1E],
                        (ACC, 0x40) => &[0x8C, 0x03],
                        (ACC, 0x03) | (GYR, 0x0A) => &[0x80],
                        _ => &[0x00; 6],
                    };
                    buf.copy_from_slice(&answer[..buf.len()]);
                    self.log.borrow_mut().push(Event::Read(address, reg, buf.len()));
                }
            }
        }
        Ok(())
    }
}

impl embedded_hal_async::delay::DelayNs for Recorder {
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

#[test]
fn init_waits_after_each_reset_and_power_change_before_the_next_access() {
    let rec = Recorder::default();
    let mut imu = Bmi088::new(rec.clone());
    let mut delay = rec.clone();
    assert_eq!(block_on(imu.init(&mut delay)), Ok(()));
    let log = rec.log.borrow();
    let at = |e: Event| {
        log.iter()
            .position(|x| *x == e)
            .unwrap_or_else(|| panic!("{e:?} missing"))
    };
    let ms = |n: u64| Event::DelayNs(n * 1_000_000);
    // Each reset / power-mode write is immediately followed by its datasheet / Bosch-API wait.
    for (write, wait_ms) in [
        (Event::Write(GYR, 0x14, 0xB6), 30), // gyro soft reset
        (Event::Write(GYR, 0x11, 0x00), 30), // gyro normal mode
        (Event::Write(ACC, 0x7E, 0xB6), 1),  // accelerometer soft reset
        (Event::Write(ACC, 0x7D, 0x04), 5),  // accelerometer on
        (Event::Write(ACC, 0x7C, 0x00), 10), // accelerometer active
    ] {
        let i = at(write.clone());
        assert_eq!(log.get(i + 1), Some(&ms(wait_ms)), "after {write:?}");
    }
    // Identity is checked before anything is written to each half.
    assert!(at(Event::Read(GYR, 0x00, 1)) < at(Event::Write(GYR, 0x14, 0xB6)));
    assert!(at(Event::Read(ACC, 0x00, 1)) < at(Event::Write(ACC, 0x7E, 0xB6)));
    // The measurement configuration is written once the accelerometer is active; the error register and
    // the read-back come after it, and the data-ready polls last.
    let active = at(Event::Write(ACC, 0x7C, 0x00));
    let conf = at(Event::Write(ACC, 0x40, 0x8C));
    let range = at(Event::Write(ACC, 0x41, 0x03));
    let err = at(Event::Read(ACC, 0x02, 1));
    let readback = at(Event::Read(ACC, 0x40, 2));
    let acc_ready = at(Event::Read(ACC, 0x03, 1));
    let gyro_ready = at(Event::Read(GYR, 0x0A, 1));
    assert!(active < conf && conf < range && range < err && err < readback);
    assert!(readback < acc_ready && acc_ready < gyro_ready);
    assert_eq!(gyro_ready, log.len() - 1);
    // The gyro interrupt is configured (mapped, then enabled) before init returns.
    assert!(at(Event::Write(GYR, 0x18, 0x01)) < at(Event::Write(GYR, 0x15, 0x80)));
    // Total waiting: 76 ms (30 + 30 + 1 + 5 + 10) for a chip whose data is ready at once.
    let waited: u64 = log
        .iter()
        .map(|e| if let Event::DelayNs(ns) = e { *ns } else { 0 })
        .sum();
    assert_eq!(waited, 76_000_000);
}

#[test]
fn driver_state_beyond_the_bus_handle_is_two_bytes() {
    // Module doc: the last ACC_ERR_REG value and the initialised flag.
    assert_eq!(size_of::<Bmi088<()>>(), 2);
}

/// Stock `sensorsAccAlignToGravity`, written out in f64 from its C source (rotate about x by the roll trim,
/// then about y by the pitch trim).
fn stock_align(a: [f64; 3], roll_deg: f64, pitch_deg: f64) -> [f64; 3] {
    let (cr, sr) = (roll_deg.to_radians().cos(), roll_deg.to_radians().sin());
    let (cp, sp) = (pitch_deg.to_radians().cos(), pitch_deg.to_radians().sin());
    let rx = [a[0], a[1] * cr - a[2] * sr, a[1] * sr + a[2] * cr];
    [rx[0] * cp - rx[2] * sp, rx[1], rx[0] * sp + rx[2] * cp]
}

#[test]
fn config_block_trim_rotates_the_accelerometer_as_stock() {
    use cfnav::drivers::bmi088::AccelTrim;
    let a = [0.3f32, -0.2, 9.7];
    for (roll, pitch) in [(0.0f32, 0.0f32), (2.0, 0.0), (0.0, -3.0), (1.5, 2.5), (-20.0, 20.0)] {
        let got = AccelTrim::from_degrees(roll, pitch).apply(a);
        let want = stock_align(a.map(f64::from), f64::from(roll), f64::from(pitch));
        for i in 0..3 {
            assert!(
                (f64::from(got[i]) - want[i]).abs() < 1e-5,
                "{roll}/{pitch}: {got:?} vs {want:?}"
            );
        }
    }
    // A 2° roll trim on a board whose accelerometer reads 2° of roll when the frame is level: level again.
    let tilted = [0.0, 9.81 * 2f32.to_radians().sin(), 9.81 * 2f32.to_radians().cos()];
    let level = AccelTrim::from_degrees(2.0, 0.0).apply(tilted);
    assert!(level[1].abs() < 1e-4 && (level[2] - 9.81).abs() < 1e-4, "{level:?}");
    // The gyro is not trimmed (stock).
    let s = cfnav::types::ImuSample {
        gyro_rad_s: [0.1, 0.2, 0.3],
        accel_m_s2: a,
    };
    assert_eq!(
        AccelTrim::from_degrees(3.0, 1.0).apply_to(s).gyro_rad_s,
        [0.1, 0.2, 0.3]
    );
    // A corrupt block does nothing.
    for (roll, pitch) in [(f32::NAN, 0.0), (0.0, f32::INFINITY), (45.0, 0.0)] {
        assert_eq!(AccelTrim::from_degrees(roll, pitch), AccelTrim::IDENTITY);
        assert_eq!(AccelTrim::from_degrees(roll, pitch).apply(a), a);
    }
}
