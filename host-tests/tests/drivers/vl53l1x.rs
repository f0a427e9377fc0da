//! VL53L1x driver against recorded I2C traffic (embedded-hal-mock).
//!
//! Expected transactions are written from ST's ULD register map (STSW-IMG009 `VL53L1X_api.h` / `.c`, read
//! in the public ports `rneurink/VL53L1X_ULD` and `stm32duino/VL53L1X`): register numbers, values and the
//! order of `VL53L1X_SensorInit`, `SetDistanceMode`, `SetTimingBudgetInMs`, `SetInterMeasurementInMs`,
//! `CheckForDataReady`, `GetRangeStatus`, `GetDistance`, `ClearInterrupt`, `SetI2CAddress`. Register numbers
//! are literals here on purpose (not the driver's constants), so a wrong constant in the driver fails.

use super::{CountingDelay, NACK};
use cfnav::drivers::DriverError;
use cfnav::drivers::vl53l1x::{DEFAULT_CONFIGURATION, DistanceMode, RangeStatus, RangingConfig, TimingBudget, Vl53l1x};
use embassy_futures::block_on;
use embedded_hal::i2c::ErrorKind;
use embedded_hal_mock::eh1::delay::NoopDelay;
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as T};

// ---- expected transactions: 16-bit big-endian register index, big-endian data ----

fn read8(address: u8, register: u16, value: u8) -> T {
    T::write_read(address, register.to_be_bytes().to_vec(), vec![value])
}

fn read16(address: u8, register: u16, value: u16) -> T {
    T::write_read(address, register.to_be_bytes().to_vec(), value.to_be_bytes().to_vec())
}

fn write8(address: u8, register: u16, value: u8) -> T {
    let mut bytes = register.to_be_bytes().to_vec();
    bytes.push(value);
    T::write(address, bytes)
}

fn write16(address: u8, register: u16, value: u16) -> T {
    let mut bytes = register.to_be_bytes().to_vec();
    bytes.extend_from_slice(&value.to_be_bytes());
    T::write(address, bytes)
}

fn write32(address: u8, register: u16, value: u32) -> T {
    let mut bytes = register.to_be_bytes().to_vec();
    bytes.extend_from_slice(&value.to_be_bytes());
    T::write(address, bytes)
}

/// The 91-byte default configuration write from 0x002D, with 0x002E bit 0 set in 2V8 mode.
fn default_config_write(address: u8, io_2v8: bool) -> T {
    let mut bytes = vec![0x00, 0x2D];
    bytes.extend_from_slice(&DEFAULT_CONFIGURATION);
    if io_2v8 {
        bytes[2 + (0x2E - 0x2D)] |= 0x01;
    }
    T::write(address, bytes)
}

/// ULD `VL53L1X_SetInterMeasurementInMs`: `(uint32_t)((osc & 0x3FF) * ms * 1.075)`, in floating point.
fn uld_inter_measurement(osc: u16, ms: u32) -> u32 {
    (f64::from(osc & 0x3FF) * f64::from(ms) * 1.075) as u32
}

const OSC_CALIBRATE: u16 = 0xFDF4; // high bits set on purpose: only the low 10 bits (500) count

/// Everything `init` sends for the Flow deck preset (long, 20 ms, 25 ms, 2V8), the chip booted at once and
/// the VHV range ready on the second poll.
fn flow_deck_init_sequence(a: u8) -> Vec<T> {
    vec![
        read8(a, 0x00E5, 0x01),                                       // FIRMWARE__SYSTEM_STATUS: booted
        read16(a, 0x010F, 0xEACC),                                    // IDENTIFICATION__MODEL_ID
        default_config_write(a, true),                                // VL51L1X_DEFAULT_CONFIGURATION, 2V8 pads
        read8(a, 0x0030, 0x01),                                       // GPIO_HV_MUX__CTRL: bit 4 clear = active high
        write8(a, 0x0087, 0x40),                                      // SYSTEM__MODE_START: range (VHV)
        read8(a, 0x0031, 0x00),                                       // GPIO__TIO_HV_STATUS: not yet
        read8(a, 0x0031, 0x03),                                       // bit 0 = 1: ready
        write8(a, 0x0086, 0x01),                                      // SYSTEM__INTERRUPT_CLEAR
        write8(a, 0x0087, 0x00),                                      // SYSTEM__MODE_START: stop
        write8(a, 0x0008, 0x09),          // VHV_CONFIG__TIMEOUT_MACROP_LOOP_BOUND: two bounds
        write8(a, 0x000B, 0x00),          // VHV from the previous temperature
        write8(a, 0x004B, 0x0A),          // long: PHASECAL_CONFIG__TIMEOUT_MACROP
        write8(a, 0x0060, 0x0F),          // RANGE_CONFIG__VCSEL_PERIOD_A
        write8(a, 0x0063, 0x0D),          // RANGE_CONFIG__VCSEL_PERIOD_B
        write8(a, 0x0069, 0xB8),          // RANGE_CONFIG__VALID_PHASE_HIGH
        write16(a, 0x0078, 0x0F0D),       // SD_CONFIG__WOI_SD0
        write16(a, 0x007A, 0x0E0E),       // SD_CONFIG__INITIAL_PHASE_SD0
        write16(a, 0x005E, 0x001E),       // long 20 ms: TIMEOUT_MACROP_A
        write16(a, 0x0061, 0x0022),       // long 20 ms: TIMEOUT_MACROP_B
        read16(a, 0x00DE, OSC_CALIBRATE), // RESULT__OSC_CALIBRATE_VAL
        write32(a, 0x006C, uld_inter_measurement(OSC_CALIBRATE, 25)), // SYSTEM__INTERMEASUREMENT_PERIOD
    ]
}

#[test]
fn default_configuration_table_matches_the_uld_source() {
    let table = DEFAULT_CONFIGURATION;
    // 0x2D..=0x87 inclusive.
    assert_eq!(table.len(), 0x87 - 0x2D + 1);
    let at = |register: usize| table[register - 0x2D];
    // Entries with a meaning in ST's comments / other ULD functions:
    assert_eq!(at(0x30), 0x01, "GPIO_HV_MUX__CTRL: active-high interrupt, bits 3:0 = 1");
    assert_eq!(at(0x31), 0x02, "GPIO__TIO_HV_STATUS");
    assert_eq!(at(0x46), 0x20, "SYSTEM__INTERRUPT_CONFIG_GPIO: new sample ready");
    assert_eq!(
        at(0x4B),
        0x0A,
        "PHASECAL timeout 0x0A = long mode (VL53L1X_GetDistanceMode)"
    );
    assert_eq!(
        [at(0x5E), at(0x5F)],
        [0x01, 0xCC],
        "TIMEOUT_MACROP_A 0x01CC = 100 ms long"
    );
    assert_eq!(
        [at(0x60), at(0x63), at(0x69)],
        [0x0F, 0x0D, 0xB8],
        "long-mode VCSEL periods, phase"
    );
    assert_eq!([at(0x64), at(0x65)], [0x01, 0x68], "sigma threshold 14.2 = 90 mm");
    assert_eq!([at(0x66), at(0x67)], [0x00, 0x80], "min count rate 9.7 format");
    assert_eq!(
        [at(0x6C), at(0x6D), at(0x6E), at(0x6F)],
        [0x00, 0x00, 0x0F, 0x89],
        "period"
    );
    assert_eq!(
        [at(0x78), at(0x79), at(0x7A), at(0x7B)],
        [0x0F, 0x0D, 0x0E, 0x0E],
        "long WOI/phase"
    );
    assert_eq!(at(0x7F), 0xC7, "ROI centre SPAD 199 (VL53L1X_SetROI's optical centre)");
    assert_eq!(at(0x80), 0xFF, "ROI 16x16: (16-1)<<4 | (16-1)");
    assert_eq!([at(0x86), at(0x87)], [0x00, 0x00], "no interrupt clear, not ranging");
    assert_eq!(at(0x2E), 0x00, "ST's table leaves the 2V8 pad bit clear");
    // Byte sum of the 91 entries as transcribed from stm32duino/VL53L1X src/vl53l1x_class.cpp.
    let sum: u32 = table.iter().map(|&b| u32::from(b)).sum();
    assert_eq!(sum, 2643);
}

#[test]
fn init_sends_the_uld_sequence_for_the_flow_deck_preset() {
    let mut i2c = I2cMock::new(&flow_deck_init_sequence(0x29));
    let mut delay = CountingDelay::default();
    let mut sensor = Vl53l1x::new(0x29);
    block_on(sensor.init(&mut i2c, &mut delay, &RangingConfig::FLOW_DECK_Z)).expect("init");
    // One 1 ms wait between the two data-ready polls of the VHV range.
    assert_eq!(delay.total_ns, 1_000_000);
    assert_eq!(sensor.address(), 0x29);
    i2c.done();
}

#[test]
fn init_without_2v8_writes_sts_table_unchanged_and_short_mode_registers() {
    let a = 0x29;
    let config = RangingConfig {
        distance_mode: DistanceMode::Short,
        timing_budget: TimingBudget::Ms15,
        inter_measurement_ms: 15,
        io_2v8: false,
    };
    let mut expected = vec![
        read8(a, 0x00E5, 0x03),
        read16(a, 0x010F, 0xEACC),
        default_config_write(a, false),
        read8(a, 0x0030, 0x01),
        write8(a, 0x0087, 0x40),
        read8(a, 0x0031, 0x01),
        write8(a, 0x0086, 0x01),
        write8(a, 0x0087, 0x00),
        write8(a, 0x0008, 0x09),
        write8(a, 0x000B, 0x00),
    ];
    expected.extend([
        write8(a, 0x004B, 0x14), // short (ULD DistanceMode 1)
        write8(a, 0x0060, 0x07),
        write8(a, 0x0063, 0x05),
        write8(a, 0x0069, 0x38),
        write16(a, 0x0078, 0x0705),
        write16(a, 0x007A, 0x0606),
        write16(a, 0x005E, 0x001D), // short 15 ms
        write16(a, 0x0061, 0x0027),
        read16(a, 0x00DE, 0x0100),
        write32(a, 0x006C, uld_inter_measurement(0x0100, 15)),
    ]);
    let mut i2c = I2cMock::new(&expected);
    let mut sensor = Vl53l1x::new(a);
    block_on(sensor.init(&mut i2c, &mut NoopDelay, &config)).expect("init");
    i2c.done();
}

#[test]
fn timing_budget_registers_follow_the_uld_tables() {
    // (mode, budget, A, B) from VL53L1X_SetTimingBudgetInMs.
    let cases = [
        (DistanceMode::Short, TimingBudget::Ms33, 0x00D6, 0x006E),
        (DistanceMode::Short, TimingBudget::Ms200, 0x03E1, 0x0496),
        (DistanceMode::Long, TimingBudget::Ms50, 0x00AD, 0x00C6),
        (DistanceMode::Long, TimingBudget::Ms500, 0x048F, 0x04A4),
    ];
    for (mode, budget, timeout_a, timeout_b) in cases {
        let mut i2c = I2cMock::new(&[]);
        let mut sensor = Vl53l1x::new(0x6C);
        let mode_writes: Vec<T> = match mode {
            DistanceMode::Short => vec![
                write8(0x6C, 0x004B, 0x14),
                write8(0x6C, 0x0060, 0x07),
                write8(0x6C, 0x0063, 0x05),
                write8(0x6C, 0x0069, 0x38),
                write16(0x6C, 0x0078, 0x0705),
                write16(0x6C, 0x007A, 0x0606),
            ],
            DistanceMode::Long => vec![
                write8(0x6C, 0x004B, 0x0A),
                write8(0x6C, 0x0060, 0x0F),
                write8(0x6C, 0x0063, 0x0D),
                write8(0x6C, 0x0069, 0xB8),
                write16(0x6C, 0x0078, 0x0F0D),
                write16(0x6C, 0x007A, 0x0E0E),
            ],
        };
        let mut expected = mode_writes;
        expected.push(write16(0x6C, 0x005E, timeout_a));
        expected.push(write16(0x6C, 0x0061, timeout_b));
        i2c.update_expectations(&expected);
        block_on(sensor.set_distance_mode_and_budget(&mut i2c, mode, budget)).expect("budget");
        i2c.done();
    }
}

#[test]
fn fifteen_ms_in_long_mode_and_too_short_periods_are_refused_without_bus_traffic() {
    let mut i2c = I2cMock::new(&[]);
    let mut sensor = Vl53l1x::new(0x29);
    let result = block_on(sensor.set_distance_mode_and_budget(&mut i2c, DistanceMode::Long, TimingBudget::Ms15));
    assert_eq!(result, Err(DriverError::InvalidConfig));

    let too_fast = RangingConfig {
        inter_measurement_ms: 19, // below the 20 ms budget
        ..RangingConfig::FLOW_DECK_Z
    };
    assert_eq!(
        block_on(sensor.init(&mut i2c, &mut NoopDelay, &too_fast)),
        Err(DriverError::InvalidConfig)
    );
    assert_eq!(
        block_on(sensor.set_inter_measurement_ms(&mut i2c, 0)),
        Err(DriverError::InvalidConfig)
    );
    i2c.done();
}

#[test]
fn inter_measurement_matches_the_uld_float_formula() {
    for (osc, ms) in [
        (0x01F4u16, 25u32),
        (0x03FF, 100),
        (0xFFFF, 1000),
        (0x0187, 33),
        (0x0000, 50),
    ] {
        let mut i2c = I2cMock::new(&[
            read16(0x29, 0x00DE, osc),
            write32(0x29, 0x006C, uld_inter_measurement(osc, ms)),
        ]);
        let mut sensor = Vl53l1x::new(0x29);
        block_on(sensor.set_inter_measurement_ms(&mut i2c, ms)).expect("period");
        i2c.done();
    }
}

#[test]
fn valid_range_reads_status_and_distance_then_clears_the_interrupt() {
    let a = 0x6A;
    let mut i2c = I2cMock::new(&[
        read8(a, 0x0031, 0x01),  // data ready (active high)
        read8(a, 0x0089, 0x09),  // RESULT__RANGE_STATUS device code 9 = ST status 0 (valid)
        read16(a, 0x0096, 1234), // RESULT__FINAL_CROSSTALK_CORRECTED_RANGE_MM_SD0
        write8(a, 0x0086, 0x01), // SYSTEM__INTERRUPT_CLEAR
    ]);
    let mut sensor = Vl53l1x::new(a);
    assert!(block_on(sensor.data_ready(&mut i2c)).expect("ready"));
    let range = block_on(sensor.read_range(&mut i2c)).expect("read");
    let metres = range.expect("valid status gives a distance");
    assert!((metres - 1.234).abs() < 1e-6, "1234 mm → 1.234 m, got {metres}");
    i2c.done();
}

#[test]
fn status_bits_above_the_low_five_are_ignored_and_large_distances_convert() {
    let a = 0x29;
    let mut i2c = I2cMock::new(&[
        read8(a, 0x0089, 0xE9), // upper bits set, low 5 bits = 9 (valid)
        read16(a, 0x0096, 0xFFFF),
        write8(a, 0x0086, 0x01),
    ]);
    let mut sensor = Vl53l1x::new(a);
    let metres = block_on(sensor.read_range(&mut i2c)).expect("read").expect("valid");
    assert!((metres - 65.535).abs() < 1e-4);
    i2c.done();
}

#[test]
fn invalid_range_status_gives_no_reading_but_still_clears_the_interrupt() {
    // Device codes that the ULD maps to non-zero statuses: 4 → 2 signal fail, 6 → 1 sigma fail,
    // 7 → 7 wrap-around, 5 → 4 out of bounds, 0 → 255.
    for raw in [4u8, 6, 7, 5, 0] {
        let a = 0x29;
        let mut i2c = I2cMock::new(&[read8(a, 0x0089, raw), read16(a, 0x0096, 812), write8(a, 0x0086, 0x01)]);
        let mut sensor = Vl53l1x::new(a);
        assert_eq!(block_on(sensor.read_range(&mut i2c)).expect("read"), None, "raw {raw}");
        i2c.done();
    }
}

#[test]
fn range_status_mapping_is_the_uld_status_table() {
    // ULD `status_rtn[24]`, index = RESULT__RANGE_STATUS & 0x1F; 255 beyond the table.
    let status_rtn: [u8; 24] = [
        255, 255, 255, 5, 2, 4, 1, 7, 3, 0, 255, 255, 9, 13, 255, 255, 255, 255, 10, 6, 255, 255, 11, 12,
    ];
    for raw in 0u8..=255 {
        let code = usize::from(raw & 0x1F);
        let expected = status_rtn.get(code).copied().unwrap_or(255);
        assert_eq!(RangeStatus::from_register(raw).st_code(), expected, "raw {raw:#04x}");
    }
    assert_eq!(RangeStatus::from_register(9), RangeStatus::Valid);
    assert_eq!(RangeStatus::from_register(4), RangeStatus::SignalFail);
}

#[test]
fn read_measurement_keeps_the_raw_status_for_logs() {
    let mut i2c = I2cMock::new(&[read8(0x29, 0x0089, 0x06), read16(0x29, 0x0096, 40)]);
    let mut sensor = Vl53l1x::new(0x29);
    let measurement = block_on(sensor.read_measurement(&mut i2c)).expect("read");
    assert_eq!(measurement.status, RangeStatus::SigmaFail);
    assert_eq!(measurement.distance_mm, 40);
    assert_eq!(measurement.range_m(), None);
    i2c.done();
}

#[test]
fn data_ready_follows_the_interrupt_polarity() {
    let a = 0x29;
    let mut i2c = I2cMock::new(&[
        read8(a, 0x0030, 0x11), // bit 4 set: active low
        read8(a, 0x0031, 0x00), // line low → ready
        read8(a, 0x0031, 0x01), // line high → not ready
    ]);
    let mut sensor = Vl53l1x::new(a);
    block_on(sensor.read_interrupt_polarity(&mut i2c)).expect("polarity");
    assert!(block_on(sensor.data_ready(&mut i2c)).expect("poll"));
    assert!(!block_on(sensor.data_ready(&mut i2c)).expect("poll"));
    i2c.done();
}

#[test]
fn address_change_writes_register_0x0001_then_uses_the_new_address() {
    let mut i2c = I2cMock::new(&[
        T::write(0x29, vec![0x00, 0x01, 0x6B]), // I2C_SLAVE__DEVICE_ADDRESS = 0x6B (7-bit)
        read16(0x6B, 0x010F, 0xEACC),           // the chip now answers at 0x6B
    ]);
    let mut sensor = Vl53l1x::new(0x29);
    block_on(sensor.set_address(&mut i2c, 0x6B)).expect("address");
    assert_eq!(sensor.address(), 0x6B);
    assert_eq!(block_on(sensor.read_model_id(&mut i2c)).expect("id"), 0xEACC);
    i2c.done();
}

#[test]
fn reserved_addresses_are_refused_without_bus_traffic() {
    let mut i2c = I2cMock::new(&[]);
    let mut sensor = Vl53l1x::new(0x29);
    for bad in [0x00u8, 0x07, 0x78, 0x7F, 0x80, 0xFF] {
        assert_eq!(
            block_on(sensor.set_address(&mut i2c, bad)),
            Err(DriverError::InvalidConfig)
        );
        assert_eq!(sensor.address(), 0x29);
    }
    i2c.done();
}

#[test]
fn bring_up_moves_the_chip_then_initialises_it_at_its_new_address() {
    let mut expected = vec![
        read8(0x29, 0x00E5, 0x00).with_error(NACK), // booting: NACK
        read8(0x29, 0x00E5, 0x00),                  // answers, not booted
        read8(0x29, 0x00E5, 0x01),                  // booted
        T::write(0x29, vec![0x00, 0x01, 0x6A]),     // move to 0x6A
    ];
    expected.extend(flow_deck_init_sequence(0x6A));
    let mut i2c = I2cMock::new(&expected);
    let mut delay = CountingDelay::default();
    let sensor = block_on(Vl53l1x::bring_up(
        &mut i2c,
        &mut delay,
        0x6A,
        &RangingConfig::FLOW_DECK_Z,
    ))
    .expect("bring-up");
    assert_eq!(sensor.address(), 0x6A);
    // Two 1 ms boot-poll waits, one 1 ms data-ready wait.
    assert_eq!(delay.total_ns, 3_000_000);
    i2c.done();
}

/// After an STM32-only reset the Flow deck's ranger (no XSHUT line) is still at 0x6A and NACKs at 0x29.
#[test]
fn a_ranger_that_kept_its_moved_address_is_found_there() {
    // The chip as the bus sees it: answers only at 0x6A.
    let mut expected = vec![read8(0x6A, 0x00E5, 0x01)]; // the probe: answers, booted
    expected.extend(flow_deck_init_sequence(0x6A));
    let mut i2c = I2cMock::new(&expected);
    let sensor = block_on(Vl53l1x::bring_up_or_find(
        &mut i2c,
        &mut NoopDelay,
        0x6A,
        &RangingConfig::FLOW_DECK_Z,
    ))
    .expect("found at the moved address");
    assert_eq!(sensor.address(), 0x6A);
    i2c.done();

    // The hazard: the plain bring-up only looks at 0x29 and gives up after its boot budget.
    let polls: Vec<T> = (0..50).map(|_| read8(0x29, 0x00E5, 0x00).with_error(NACK)).collect();
    let mut i2c = I2cMock::new(&polls);
    let plain = block_on(Vl53l1x::bring_up(
        &mut i2c,
        &mut NoopDelay,
        0x6A,
        &RangingConfig::FLOW_DECK_Z,
    ));
    assert_eq!(plain.map(|s| s.address()), Err(DriverError::Bus(NACK)));
    i2c.done();
}

/// After a power-on the moved address is silent: one NACKed probe, then the normal bring-up from 0x29.
#[test]
fn a_fresh_ranger_is_moved_as_usual_after_one_probe() {
    let mut expected = vec![
        read8(0x6A, 0x00E5, 0x00).with_error(NACK), // nobody at 0x6A
        read8(0x29, 0x00E5, 0x01),                  // booted at the default address
        T::write(0x29, vec![0x00, 0x01, 0x6A]),     // move to 0x6A
    ];
    expected.extend(flow_deck_init_sequence(0x6A));
    let mut i2c = I2cMock::new(&expected);
    let sensor = block_on(Vl53l1x::bring_up_or_find(
        &mut i2c,
        &mut NoopDelay,
        0x6A,
        &RangingConfig::FLOW_DECK_Z,
    ))
    .expect("bring-up");
    assert_eq!(sensor.address(), 0x6A);
    i2c.done();
}

#[test]
fn bring_up_at_the_default_address_sends_no_address_write() {
    let mut i2c = I2cMock::new(&flow_deck_init_sequence(0x29));
    let sensor = block_on(Vl53l1x::bring_up(
        &mut i2c,
        &mut NoopDelay,
        0x29,
        &RangingConfig::FLOW_DECK_Z,
    ))
    .expect("bring-up");
    assert_eq!(sensor.address(), 0x29);
    i2c.done();
}

#[test]
fn start_and_stop_ranging_write_mode_start() {
    let mut i2c = I2cMock::new(&[write8(0x6B, 0x0087, 0x40), write8(0x6B, 0x0087, 0x00)]);
    let mut sensor = Vl53l1x::new(0x6B);
    block_on(sensor.start_ranging(&mut i2c)).expect("start");
    block_on(sensor.stop_ranging(&mut i2c)).expect("stop");
    i2c.done();
}

// ---- error paths ----

#[test]
fn boot_timeout_when_the_chip_answers_but_never_boots() {
    let polls: Vec<T> = (0..50).map(|_| read8(0x29, 0x00E5, 0x00)).collect();
    let mut i2c = I2cMock::new(&polls);
    let mut delay = CountingDelay::default();
    let mut sensor = Vl53l1x::new(0x29);
    assert_eq!(
        block_on(sensor.init(&mut i2c, &mut delay, &RangingConfig::FLOW_DECK_Z)),
        Err(DriverError::Timeout)
    );
    // 50 polls, a 1 ms wait between consecutive polls: 49 ms of waiting (datasheet boot time: 1.2 ms).
    assert_eq!(delay.total_ns, 49_000_000);
    i2c.done();
}

#[test]
fn absent_chip_is_a_bus_error_after_the_boot_budget() {
    let polls: Vec<T> = (0..50).map(|_| read8(0x29, 0x00E5, 0x00).with_error(NACK)).collect();
    let mut i2c = I2cMock::new(&polls);
    let mut sensor = Vl53l1x::new(0x29);
    assert_eq!(
        block_on(sensor.wait_boot(&mut i2c, &mut NoopDelay)),
        Err(DriverError::Bus(NACK))
    );
    i2c.done();
}

#[test]
fn wrong_model_id_is_reported_with_both_values() {
    let mut i2c = I2cMock::new(&[read8(0x29, 0x00E5, 0x01), read16(0x29, 0x010F, 0xEEAA)]);
    let mut sensor = Vl53l1x::new(0x29);
    assert_eq!(
        block_on(sensor.init(&mut i2c, &mut NoopDelay, &RangingConfig::MULTI_RANGER)),
        Err(DriverError::WrongChipId {
            expected: 0xEACC,
            found: 0xEEAA
        })
    );
    i2c.done();
}

#[test]
fn nack_on_each_init_transfer_stops_init_with_that_bus_error() {
    let full = flow_deck_init_sequence(0x29);
    // Fail the transfer at every position after the boot poll (a NACK during the boot poll is retried).
    for failing in 1..full.len() {
        let mut expected: Vec<T> = full[..failing].to_vec();
        expected.push(full[failing].clone().with_error(ErrorKind::Bus));
        let mut i2c = I2cMock::new(&expected);
        let mut sensor = Vl53l1x::new(0x29);
        assert_eq!(
            block_on(sensor.init(&mut i2c, &mut NoopDelay, &RangingConfig::FLOW_DECK_Z)),
            Err(DriverError::Bus(ErrorKind::Bus)),
            "transfer {failing}"
        );
        i2c.done();
    }
}

#[test]
fn vhv_range_that_never_arrives_is_a_timeout() {
    let a = 0x29;
    let mut expected = vec![
        read8(a, 0x00E5, 0x01),
        read16(a, 0x010F, 0xEACC),
        default_config_write(a, true),
        read8(a, 0x0030, 0x01),
        write8(a, 0x0087, 0x40),
    ];
    expected.extend((0..250).map(|_| read8(a, 0x0031, 0x00)));
    let mut i2c = I2cMock::new(&expected);
    let mut delay = CountingDelay::default();
    let mut sensor = Vl53l1x::new(a);
    assert_eq!(
        block_on(sensor.init(&mut i2c, &mut delay, &RangingConfig::FLOW_DECK_Z)),
        Err(DriverError::Timeout)
    );
    // More than the default configuration's 100 ms budget was allowed.
    assert!(delay.total_ns > 100_000_000);
    i2c.done();
}

#[test]
fn nack_on_a_range_read_is_a_bus_error() {
    let mut i2c = I2cMock::new(&[read8(0x6D, 0x0089, 0x09), read16(0x6D, 0x0096, 0).with_error(NACK)]);
    let mut sensor = Vl53l1x::new(0x6D);
    assert_eq!(block_on(sensor.read_range(&mut i2c)), Err(DriverError::Bus(NACK)));
    i2c.done();
}

#[test]
fn nack_while_waiting_for_data_ends_the_wait_at_once() {
    let mut i2c = I2cMock::new(&[read8(0x29, 0x0031, 0x00), read8(0x29, 0x0031, 0x00).with_error(NACK)]);
    let mut sensor = Vl53l1x::new(0x29);
    assert_eq!(
        block_on(sensor.wait_data_ready(&mut i2c, &mut NoopDelay, 100)),
        Err(DriverError::Bus(NACK))
    );
    i2c.done();
}

#[test]
fn nack_on_the_address_write_keeps_the_old_address() {
    let mut i2c = I2cMock::new(&[T::write(0x29, vec![0x00, 0x01, 0x6E]).with_error(NACK)]);
    let mut sensor = Vl53l1x::new(0x29);
    assert_eq!(
        block_on(sensor.set_address(&mut i2c, 0x6E)),
        Err(DriverError::Bus(NACK))
    );
    assert_eq!(sensor.address(), 0x29);
    i2c.done();
}
