//! Multi-ranger bring-up and reads against recorded I2C traffic.
//!
//! Expected order and wiring from docs/hardware.md §2 (stock `multiranger.c`): expander PCA95x4 at
//! 0x20 (output register 1, configuration register 3), XSHUT on P0 up, P1 back, P2 right, P4 front, P6 left,
//! bring-up order front, back, up, left, right, every sensor first at 0x29 and moved with register 0x0001;
//! addresses 0x6B.. after the Flow deck's z-ranger at 0x6A. VL53L1x register traffic as in
//! `driver_vl53l1x.rs` (ST ULD register map), written out again here with literal register numbers.

use super::{CountingDelay, NACK};
use cfnav::drivers::DriverError;
use cfnav::drivers::multiranger::{
    BringUpReport, Direction, FIRST_ADDRESS, FLOW_DECK_Z_ADDRESS, MultiRanger, SensorFault,
};
use cfnav::drivers::pca95x4::DEFAULT_ADDRESS as EXPANDER_ADDRESS;
use cfnav::drivers::vl53l1x::{DEFAULT_CONFIGURATION, RangingConfig, Vl53l1x};
use embassy_futures::block_on;
use embedded_hal::i2c::ErrorKind;
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as T};

const EXPANDER: u8 = 0x20;
const BOOT_ADDRESS: u8 = 0x29;

// ---- expander transfers ----

fn expander_output(value: u8) -> T {
    T::write(EXPANDER, vec![0x01, value])
}

fn expander_config(value: u8) -> T {
    T::write(EXPANDER, vec![0x03, value])
}

/// All five XSHUT low: output 0xA8 first, then P0/P1/P2/P4/P6 as outputs (config 0xA8).
fn hold_all_in_reset() -> Vec<T> {
    vec![expander_output(0xA8), expander_config(0xA8)]
}

/// Brings a deck up with the stock addresses against exactly the `expected` traffic (all of it consumed)
/// and returns its report; the deck itself is dropped.
fn bring_up_against(expected: &[T]) -> BringUpReport<ErrorKind> {
    let mut i2c = I2cMock::new(expected);
    let mut deck = MultiRanger::new(EXPANDER);
    let report =
        block_on(deck.bring_up(&mut i2c, &mut NoopDelay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER)).expect("deck");
    i2c.done();
    report
}

// ---- VL53L1x transfers (16-bit big-endian register index) ----

fn read8(address: u8, register: u16, value: u8) -> T {
    T::write_read(address, register.to_be_bytes().to_vec(), vec![value])
}

fn read16(address: u8, register: u16, value: u16) -> T {
    T::write_read(address, register.to_be_bytes().to_vec(), value.to_be_bytes().to_vec())
}

fn write_bytes(address: u8, register: u16, data: &[u8]) -> T {
    let mut bytes = register.to_be_bytes().to_vec();
    bytes.extend_from_slice(data);
    T::write(address, bytes)
}

/// A chip leaving reset at 0x29: booted at the first poll, moved to `address` (register 0x0001).
fn boot_and_move(address: u8) -> Vec<T> {
    vec![
        read8(BOOT_ADDRESS, 0x00E5, 0x01),
        write_bytes(BOOT_ADDRESS, 0x0001, &[address]),
    ]
}

/// ULD init at `a` with long mode, the given (A, B) budget timeouts and period; 2V8 pads; the VHV range
/// ready at the first poll; oscillator calibration 500.
fn init_at(a: u8, timeout_a: u16, timeout_b: u16, period_ms: u32) -> Vec<T> {
    let mut config = DEFAULT_CONFIGURATION.to_vec();
    config[0x2E - 0x2D] |= 0x01;
    vec![
        read8(a, 0x00E5, 0x01),
        read16(a, 0x010F, 0xEACC),
        write_bytes(a, 0x002D, &config),
        read8(a, 0x0030, 0x01),
        write_bytes(a, 0x0087, &[0x40]),
        read8(a, 0x0031, 0x01),
        write_bytes(a, 0x0086, &[0x01]),
        write_bytes(a, 0x0087, &[0x00]),
        write_bytes(a, 0x0008, &[0x09]),
        write_bytes(a, 0x000B, &[0x00]),
        write_bytes(a, 0x004B, &[0x0A]),
        write_bytes(a, 0x0060, &[0x0F]),
        write_bytes(a, 0x0063, &[0x0D]),
        write_bytes(a, 0x0069, &[0xB8]),
        write_bytes(a, 0x0078, &[0x0F, 0x0D]),
        write_bytes(a, 0x007A, &[0x0E, 0x0E]),
        write_bytes(a, 0x005E, &timeout_a.to_be_bytes()),
        write_bytes(a, 0x0061, &timeout_b.to_be_bytes()),
        read16(a, 0x00DE, 500),
        // ULD: 500 ticks/ms · period · 1.075
        write_bytes(
            a,
            0x006C,
            &((500.0 * f64::from(period_ms) * 1.075) as u32).to_be_bytes(),
        ),
    ]
}

/// One Multi-ranger sensor from reset to ranging (long mode, 50 ms budget: A 0x00AD, B 0x00C6; 100 ms).
fn sensor_to_ranging(address: u8) -> Vec<T> {
    let mut sequence = boot_and_move(address);
    sequence.extend(init_at(address, 0x00AD, 0x00C6, 100));
    sequence.push(write_bytes(address, 0x0087, &[0x40]));
    sequence
}

/// The whole deck coming up: expander reset, then front (P4) 0x6B, back (P1) 0x6C, up (P0) 0x6D,
/// left (P6) 0x6E, right (P2) 0x6F, each XSHUT raised on top of the previous ones.
fn full_bring_up() -> Vec<T> {
    let mut sequence = hold_all_in_reset();
    sequence.push(expander_output(0xA8 | 0x10));
    sequence.extend(sensor_to_ranging(0x6B));
    sequence.push(expander_output(0xA8 | 0x10 | 0x02));
    sequence.extend(sensor_to_ranging(0x6C));
    sequence.push(expander_output(0xA8 | 0x10 | 0x02 | 0x01));
    sequence.extend(sensor_to_ranging(0x6D));
    sequence.push(expander_output(0xA8 | 0x10 | 0x02 | 0x01 | 0x40));
    sequence.extend(sensor_to_ranging(0x6E));
    sequence.push(expander_output(0xA8 | 0x10 | 0x02 | 0x01 | 0x40 | 0x04));
    sequence.extend(sensor_to_ranging(0x6F));
    sequence
}

#[test]
fn constants_match_the_stock_layout() {
    assert_eq!(EXPANDER_ADDRESS, 0x20);
    assert_eq!(FIRST_ADDRESS, 0x6B);
    assert_eq!(FLOW_DECK_Z_ADDRESS, 0x6A);
    assert_eq!(Direction::Up.xshut_mask(), 1 << 0);
    assert_eq!(Direction::Back.xshut_mask(), 1 << 1);
    assert_eq!(Direction::Right.xshut_mask(), 1 << 2);
    assert_eq!(Direction::Front.xshut_mask(), 1 << 4);
    assert_eq!(Direction::Left.xshut_mask(), 1 << 6);
    assert_eq!(
        Direction::BRING_UP_ORDER,
        [
            Direction::Front,
            Direction::Back,
            Direction::Up,
            Direction::Left,
            Direction::Right
        ]
    );
}

#[test]
fn all_five_come_up_in_stock_order_at_their_own_addresses() {
    let mut i2c = I2cMock::new(&full_bring_up());
    let mut delay = CountingDelay::default();
    let mut deck = MultiRanger::new(EXPANDER);
    let report = block_on(deck.bring_up(&mut i2c, &mut delay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER))
        .expect("expander answers");
    assert!(report.all_up(), "{report:?}");
    for (direction, address) in [
        (Direction::Front, 0x6B),
        (Direction::Back, 0x6C),
        (Direction::Up, 0x6D),
        (Direction::Left, 0x6E),
        (Direction::Right, 0x6F),
    ] {
        assert_eq!(
            deck.sensor(direction).map(Vl53l1x::address),
            Some(address),
            "{direction:?}"
        );
    }
    assert_eq!(deck.expander().output(), 0xFF);
    // Only the 2 ms XSHUT waits (every chip booted and ranged at the first poll).
    assert_eq!(delay.total_ns, 5 * 2_000_000);
    i2c.done();
}

#[test]
fn a_sensor_with_the_wrong_id_is_reported_put_back_in_reset_and_the_others_continue() {
    let mut expected = hold_all_in_reset();
    expected.push(expander_output(0xB8));
    expected.extend(sensor_to_ranging(0x6B));
    // Back: moved to 0x6C, then the id read returns a VL53L0X-like value.
    expected.push(expander_output(0xBA));
    expected.extend(boot_and_move(0x6C));
    expected.push(read8(0x6C, 0x00E5, 0x01));
    expected.push(read16(0x6C, 0x010F, 0xEEAA));
    expected.push(expander_output(0xB8)); // back's XSHUT low again
    expected.push(expander_output(0xB9)); // up
    expected.extend(sensor_to_ranging(0x6D));
    expected.push(expander_output(0xF9)); // left
    expected.extend(sensor_to_ranging(0x6E));
    expected.push(expander_output(0xFD)); // right
    expected.extend(sensor_to_ranging(0x6F));
    let mut i2c = I2cMock::new(&expected);
    let mut deck = MultiRanger::new(EXPANDER);
    let report =
        block_on(deck.bring_up(&mut i2c, &mut NoopDelay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER)).expect("deck");
    assert_eq!(report.working_count(), 4);
    assert_eq!(
        report.fault(Direction::Back),
        Some(&SensorFault::Sensor(DriverError::WrongChipId {
            expected: 0xEACC,
            found: 0xEEAA
        }))
    );
    assert!(deck.sensor(Direction::Back).is_none());
    assert_eq!(
        deck.sensor(Direction::Right).map(Vl53l1x::address),
        Some(0x6F),
        "addresses do not shift"
    );
    i2c.done();
}

#[test]
fn an_absent_sensor_is_a_bus_fault_after_its_boot_budget() {
    let mut expected = hold_all_in_reset();
    expected.push(expander_output(0xB8)); // front released, but nothing answers at 0x29
    expected.extend((0..50).map(|_| read8(BOOT_ADDRESS, 0x00E5, 0).with_error(NACK)));
    expected.push(expander_output(0xA8));
    expected.push(expander_output(0xAA)); // back
    expected.extend(sensor_to_ranging(0x6C));
    expected.push(expander_output(0xAB)); // up
    expected.extend(sensor_to_ranging(0x6D));
    expected.push(expander_output(0xEB)); // left
    expected.extend(sensor_to_ranging(0x6E));
    expected.push(expander_output(0xEF)); // right
    expected.extend(sensor_to_ranging(0x6F));
    let report = bring_up_against(&expected);
    assert_eq!(
        report.fault(Direction::Front),
        Some(&SensorFault::Sensor(DriverError::Bus(NACK)))
    );
    assert_eq!(report.working_count(), 4);
}

#[test]
fn a_sensor_that_never_boots_times_out() {
    let mut expected = hold_all_in_reset();
    expected.push(expander_output(0xB8));
    expected.extend(sensor_to_ranging(0x6B));
    expected.push(expander_output(0xBA));
    expected.extend(sensor_to_ranging(0x6C));
    expected.push(expander_output(0xBB)); // up: answers, never boots
    expected.extend((0..50).map(|_| read8(BOOT_ADDRESS, 0x00E5, 0x00)));
    expected.push(expander_output(0xBA));
    expected.push(expander_output(0xFA));
    expected.extend(sensor_to_ranging(0x6E));
    expected.push(expander_output(0xFE));
    expected.extend(sensor_to_ranging(0x6F));
    let report = bring_up_against(&expected);
    assert_eq!(
        report.fault(Direction::Up),
        Some(&SensorFault::Sensor(DriverError::Timeout))
    );
    assert_eq!(report.working_count(), 4);
}

#[test]
fn a_failed_release_is_an_expander_fault_and_the_next_sensor_still_comes_up() {
    let mut expected = hold_all_in_reset();
    expected.push(expander_output(0xB8).with_error(NACK)); // front release fails
    expected.push(expander_output(0xA8)); // held low again (the copy is still 0xA8)
    expected.push(expander_output(0xAA)); // back
    expected.extend(sensor_to_ranging(0x6C));
    expected.push(expander_output(0xAB));
    expected.extend(sensor_to_ranging(0x6D));
    expected.push(expander_output(0xEB));
    expected.extend(sensor_to_ranging(0x6E));
    expected.push(expander_output(0xEF));
    expected.extend(sensor_to_ranging(0x6F));
    let report = bring_up_against(&expected);
    assert_eq!(
        report.fault(Direction::Front),
        Some(&SensorFault::Expander(DriverError::Bus(NACK)))
    );
    assert_eq!(report.working_count(), 4);
}

#[test]
fn a_sensor_that_cannot_be_put_back_in_reset_stops_the_remaining_releases() {
    let mut expected = hold_all_in_reset();
    expected.push(expander_output(0xB8));
    expected.extend(sensor_to_ranging(0x6B));
    expected.push(expander_output(0xBA)); // back released
    expected.push(read8(BOOT_ADDRESS, 0x00E5, 0x01));
    expected.push(write_bytes(BOOT_ADDRESS, 0x0001, &[0x6C]).with_error(NACK)); // address write fails
    expected.push(expander_output(0xB8).with_error(NACK)); // and its XSHUT cannot be lowered
    // Nothing more: back may still sit at 0x29, so up/left/right are not released.
    let report = bring_up_against(&expected);
    assert_eq!(report.fault(Direction::Front), None);
    assert_eq!(
        report.fault(Direction::Back),
        Some(&SensorFault::Sensor(DriverError::Bus(NACK)))
    );
    for direction in [Direction::Up, Direction::Left, Direction::Right] {
        assert_eq!(
            report.fault(direction),
            Some(&SensorFault::NotAttempted),
            "{direction:?}"
        );
    }
    assert_eq!(report.working_count(), 1);
}

#[test]
fn an_expander_that_does_not_answer_fails_the_bring_up_before_any_sensor_traffic() {
    let mut i2c = I2cMock::new(&[expander_output(0xA8).with_error(NACK)]);
    let mut deck = MultiRanger::new(EXPANDER);
    assert_eq!(
        block_on(deck.bring_up(&mut i2c, &mut NoopDelay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER)),
        Err(DriverError::Bus(NACK))
    );
    i2c.done();
}

#[test]
fn unusable_address_ranges_and_configs_are_refused_without_bus_traffic() {
    let mut i2c = I2cMock::new(&[]);
    let mut deck = MultiRanger::new(EXPANDER);
    // 0x25..=0x29 includes the boot address, 0x1E..=0x22 the expander, 0x74..=0x78 a reserved address,
    // 0xFD overflows.
    for first in [0x25u8, 0x1E, 0x74, 0xFD, 0x00] {
        assert_eq!(
            block_on(deck.bring_up(&mut i2c, &mut NoopDelay, first, &RangingConfig::MULTI_RANGER)),
            Err(DriverError::InvalidConfig),
            "first address {first:#04x}"
        );
    }
    let bad_config = RangingConfig {
        inter_measurement_ms: 40, // below the 50 ms budget
        ..RangingConfig::MULTI_RANGER
    };
    assert_eq!(
        block_on(deck.bring_up(&mut i2c, &mut NoopDelay, FIRST_ADDRESS, &bad_config)),
        Err(DriverError::InvalidConfig)
    );
    i2c.done();
}

fn range_read(address: u8, raw_status: u8, distance_mm: u16) -> Vec<T> {
    vec![
        read8(address, 0x0031, 0x01),
        read8(address, 0x0089, raw_status),
        read16(address, 0x0096, distance_mm),
        write_bytes(address, 0x0086, &[0x01]),
    ]
}

#[test]
fn read_all_fills_each_direction_and_reports_the_sensor_that_failed() {
    let mut expected = full_bring_up();
    expected.extend(range_read(0x6B, 0x09, 500)); // front: valid 0.5 m
    expected.extend(range_read(0x6C, 0x04, 4000)); // back: signal fail → none
    expected.extend(range_read(0x6D, 0x09, 2000)); // up: valid 2.0 m
    expected.push(read8(0x6E, 0x0031, 0x01)); // left: ready, then the status read NACKs
    expected.push(read8(0x6E, 0x0089, 0x09).with_error(NACK));
    expected.push(read8(0x6F, 0x0031, 0x00)); // right: not ready at first
    expected.extend(range_read(0x6F, 0x09, 1500)); // then 1.5 m
    let mut i2c = I2cMock::new(&expected);
    let mut deck = MultiRanger::new(EXPANDER);
    let report =
        block_on(deck.bring_up(&mut i2c, &mut NoopDelay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER)).expect("deck");
    assert!(report.all_up());

    let outcome = block_on(deck.read_all(&mut i2c, &mut NoopDelay));
    let close = |reading: Option<f32>, metres: f32| reading.is_some_and(|r| (r - metres).abs() < 1e-6);
    assert!(close(outcome.sample.front_m, 0.5), "{:?}", outcome.sample);
    assert_eq!(outcome.sample.back_m, None);
    assert!(close(outcome.sample.up_m, 2.0));
    assert_eq!(outcome.sample.left_m, None);
    assert!(close(outcome.sample.right_m, 1.5));
    assert_eq!(outcome.faults[Direction::Left.index()], Some(DriverError::Bus(NACK)));
    assert_eq!(outcome.faults.iter().filter(|fault| fault.is_some()).count(), 1);
    i2c.done();
}

#[test]
fn read_all_skips_sensors_that_did_not_come_up() {
    let mut expected = hold_all_in_reset();
    expected.push(expander_output(0xB8)); // front absent
    expected.extend((0..50).map(|_| read8(BOOT_ADDRESS, 0x00E5, 0).with_error(NACK)));
    expected.push(expander_output(0xA8));
    expected.push(expander_output(0xAA));
    expected.extend(sensor_to_ranging(0x6C));
    expected.push(expander_output(0xAB));
    expected.extend(sensor_to_ranging(0x6D));
    expected.push(expander_output(0xEB));
    expected.extend(sensor_to_ranging(0x6E));
    expected.push(expander_output(0xEF));
    expected.extend(sensor_to_ranging(0x6F));
    for address in 0x6C..=0x6F {
        expected.extend(range_read(address, 0x09, 1000));
    }
    let mut i2c = I2cMock::new(&expected);
    let mut deck = MultiRanger::new(EXPANDER);
    block_on(deck.bring_up(&mut i2c, &mut NoopDelay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER)).expect("deck");
    let outcome = block_on(deck.read_all(&mut i2c, &mut NoopDelay));
    assert_eq!(outcome.sample.front_m, None);
    assert_eq!(outcome.sample.back_m, Some(1.0));
    assert_eq!(outcome.sample.right_m, Some(1.0));
    assert!(outcome.faults.iter().all(Option::is_none));
    i2c.done();
}

#[test]
fn flow_deck_z_ranger_moves_off_0x29_before_the_multi_ranger_sensors_are_released() {
    let mut expected = hold_all_in_reset();
    expected.extend(boot_and_move(0x6A)); // Flow deck z-ranger: the only chip at 0x29 now
    // Long mode, 20 ms budget (A 0x001E, B 0x0022), 25 ms period: 40 Hz.
    expected.extend(init_at(0x6A, 0x001E, 0x0022, 25));
    expected.extend(full_bring_up());
    let mut i2c = I2cMock::new(&expected);
    let mut deck = MultiRanger::new(EXPANDER);
    block_on(deck.hold_all_in_reset(&mut i2c)).expect("reset");
    let z_ranger = block_on(Vl53l1x::bring_up(
        &mut i2c,
        &mut NoopDelay,
        FLOW_DECK_Z_ADDRESS,
        &RangingConfig::FLOW_DECK_Z,
    ))
    .expect("z-ranger");
    assert_eq!(z_ranger.address(), 0x6A);
    let report =
        block_on(deck.bring_up(&mut i2c, &mut NoopDelay, FIRST_ADDRESS, &RangingConfig::MULTI_RANGER)).expect("deck");
    assert!(report.all_up());
    i2c.done();
}

#[test]
fn driver_state_is_as_small_as_documented() {
    use cfnav::drivers::pca95x4::Pca95x4;
    // Module docs: a VL53L1x is 2 bytes (address, data-ready level), the expander 2 (address, output
    // copy), the whole deck about 16.
    assert_eq!(core::mem::size_of::<Vl53l1x>(), 2);
    assert_eq!(core::mem::size_of::<Option<Vl53l1x>>(), 2);
    assert_eq!(core::mem::size_of::<Pca95x4>(), 2);
    assert!(
        core::mem::size_of::<MultiRanger>() <= 16,
        "{}",
        core::mem::size_of::<MultiRanger>()
    );
}
