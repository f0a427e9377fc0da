//! BMI088 IMU (gyroscope + accelerometer) on the Crazyflie 2.1's sensor I2C bus (I2C3, 400 kHz).
//!
//! Job: bring both halves of the chip up the way the stock firmware configures them, then read one gyro +
//! accelerometer sample per gyro data-ready edge and convert it to an [`ImuSample`] in SI units and the
//! body frame.
//!
//! Non-goals: no gyro bias estimation, accelerometer scale calibration or low-pass filtering (stock does
//! those in `sensors_bmi088_bmp3xx.c`; here they are the estimator's job), no FIFO, no self-test, no SPI
//! variant of the chip interface, no EXTI handling (the firmware owns PC14; this driver only configures
//! the chip to drive INT3).
//!
//! ## Chip configuration (what [`Bmi088::init`] writes)
//!
//! Register addresses and values: Bosch BMI088 datasheet BST-BMI088-DS001 §5 (register map) and the Bosch
//! BMI08x Sensor API `bmi08_defs.h` (boschsensortec/BMI08x_SensorAPI); stock values from bitcraze
//! crazyflie-firmware `src/hal/src/sensors_bmi088_bmp3xx.c` `sensorsDeviceInit` (`docs/hardware.md` §2).
//!
//! | half | I2C address | chip id (reg 0x00) | range | rate / filter | other |
//! |------|-------------|--------------------|-------|---------------|-------|
//! | gyro | 0x69 (SDO2 high, "secondary") | 0x0F | ±2000 °/s (GYRO_RANGE 0x0F = 0x00) | ODR 1000 Hz, 116 Hz filter (GYRO_BANDWIDTH 0x10 = 0x02) | data-ready → INT3, active high, push-pull |
//! | accel | 0x18 (SDO1 low, "primary") | 0x1E | ±24 g (ACC_RANGE 0x41 = 0x03) | ODR 1600 Hz, OSR4 ≈ 145 Hz (ACC_CONF 0x40 = 0x8C) | power on + active mode |
//!
//! Sequence and delays: gyro soft reset (0x14 ← 0xB6) then 30 ms (BMI08x API
//! `BMI08_GYRO_SOFTRESET_DELAY`), then the chip id again; gyro normal mode (LPM1 0x11 ← 0x00) then 30 ms
//! (`BMI08_GYRO_POWER_MODE_CONFIG_DELAY`); accelerometer soft reset (0x7E ← 0xB6) then 1 ms
//! (`BMI08_ACCEL_SOFTRESET_DELAY_MS`), then the chip id again; accelerometer on (ACC_PWR_CTRL 0x7D ← 0x04) then 5 ms (stock
//! `delay_ms(5)`, = `BMI08_POWER_CONFIG_DELAY`); active mode (ACC_PWR_CONF 0x7C ← 0x00) then 10 ms (stock).
//! The accelerometer's "dummy read" of the datasheet (§6.1) is only needed to switch it to **SPI** (a rising
//! CSB1 edge); it starts in I2C mode after power-on and soft reset, so on the Crazyflie it is not needed.
//! The caller must leave the chip its start-up time after power-on first (stock waits 1000 ms,
//! `SENSORS_STARTUP_TIME_MS`, mostly for the other sensors on the bus).
//!
//! **Soft resets are fire-and-forget.** A chip that resets while it receives the command may not
//! acknowledge the data byte or the STOP, so an error on the reset write is ignored; after the reset
//! delay the chip id is read again, up to [`RESET_ID_ATTEMPTS`] times [`RESET_RETRY_MS`] apart, and that
//! read decides whether the chip is there. (Stock never soft-resets the BMI088 on the Crazyflie:
//! `bmi088_*_soft_reset` exist in its Bosch driver but `sensorsBmi088Bmp3xxInit` does not call them.)
//!
//! After configuring, [`Bmi088::init`] reads ACC_ERR_REG (0x02: bit 0 `fatal_err`, bits 4:2 `error_code`,
//! 1 = invalid ACC_CONF), reads ACC_CONF/ACC_RANGE back, and waits (polling, 1 ms apart, at most
//! [`DATA_READY_POLLS`] times) for the first accelerometer (ACC_STATUS 0x03 bit 7) and gyro
//! (GYRO_INT_STAT_1 0x0A bit 7) data-ready flags, so a chip that answers but never measures is caught at
//! boot, not in flight.
//!
//! ## Reading (1 kHz, on the gyro data-ready edge on PC14)
//!
//! Two burst reads: gyro RATE_X_LSB..RATE_Z_MSB (0x02..0x07) and accelerometer ACC_X_LSB..ACC_Z_MSB
//! (0x12..0x17), each three little-endian `i16`. At 400 kHz each burst is ~0.25 ms of bus time
//! (address + register + repeated start + address + 6 bytes ≈ 100 clocks), ~0.5 ms of the 1 ms period.
//!
//! ## Units and frame
//!
//! Scale factors (datasheet §5.3.4 / §5.5.2, stock `SENSORS_BMI088_DEG_PER_LSB_CFG` and
//! `SENSORS_BMI088_G_PER_LSB_CFG`):
//! - gyro: ±2000 °/s over 16 bits → 4000/65536 °/s per LSB = [`GYRO_RAD_S_PER_LSB`] rad/s per LSB;
//! - accelerometer: `mg = raw / 32768 · 1000 · 2^(ACC_RANGE + 1) · 1.5` (the ·1.5 is in datasheet rev ≥ 1.4;
//!   rev 1.3 omitted it), at ACC_RANGE = 3 that is 48/65536 g per LSB (1365.33 LSB/g) →
//!   [`ACCEL_M_S2_PER_LSB`] m/s² per LSB with g = [`GRAVITY_M_S2`] (the same g the simulator and the
//!   estimator use).
//!
//! Axes: on the Crazyflie 2.x the chip's axes are the body axes (x forward, y left, z up): stock aligns
//! them with `IMU_PHI = IMU_THETA = IMU_PSI = 0` (crazyflie-firmware `src/platform/interface/
//! platform_defaults.h`, applied in `sensorsAlignToAirframe`), so the mapping is the identity and a level
//! drone at rest reads accel ≈ (0, 0, +g). This is what the simulator's `Imu` model (tools/src/sim/
//! sensors.rs) produces from the true body rates and specific force, so SITL and the real chip feed the
//! estimator the same quantities. Stock's board-level trim `calibRoll/calibPitch` from the config block is
//! applied by the caller with [`AccelTrim`], to the accelerometer only, as stock does.
//!
//! ## Errors
//!
//! NACK or any bus fault → [`DriverError::Bus`]; wrong chip id → [`DriverError::WrongChipId`];
//! ACC_ERR_REG `fatal_err` set → [`DriverError::InvalidData`] (the chip is not operational: boot or power
//! system fault); ACC_ERR_REG `error_code` ≠ 0 or a configuration register that does not read back →
//! [`DriverError::InvalidConfig`]; no data-ready within the polling budget → [`DriverError::Timeout`].
//! The raw ACC_ERR_REG value of the last check is kept ([`Bmi088::last_accel_error`]) for the console.
//!
//! Memory: the driver holds the bus handle plus 2 bytes (the last ACC_ERR_REG value and an initialised
//! flag; `size_of::<Bmi088<()>>() == 2`, tested); a read uses a 6-byte stack buffer per half.

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;

use super::DriverError;
use crate::types::{GRAVITY_M_S2, ImuSample};

/// I2C address of the accelerometer half (SDO1 low; stock `BMI088_ACCEL_I2C_ADDR_PRIMARY`).
pub const ACCEL_ADDR: u8 = 0x18;
/// I2C address of the gyroscope half (SDO2 high; stock `BMI088_GYRO_I2C_ADDR_SECONDARY`).
pub const GYRO_ADDR: u8 = 0x69;
/// ACC_CHIP_ID value (datasheet §5.3.1).
pub const ACCEL_CHIP_ID: u8 = 0x1E;
/// GYRO_CHIP_ID value (datasheet §5.5.1).
pub const GYRO_CHIP_ID: u8 = 0x0F;

/// Gyro scale at ±2000 °/s: 4000/65536 °/s per LSB, in rad/s per LSB.
pub const GYRO_RAD_S_PER_LSB: f32 = 4000.0 / 65536.0 * core::f32::consts::PI / 180.0;
/// Accelerometer scale at ±24 g: 48/65536 g per LSB, in m/s² per LSB.
pub const ACCEL_M_S2_PER_LSB: f32 = 48.0 / 65536.0 * GRAVITY_M_S2;

/// How many times [`Bmi088::init`] polls each data-ready flag (1 ms apart) before giving up. The slowest
/// configured rate is the gyro's 1 kHz, so a working chip sets its flag within ~1 ms of being configured.
pub const DATA_READY_POLLS: u32 = 20;

/// How many times the chip id is read after a soft reset before init gives up (the first read comes after
/// the datasheet reset delay; the others [`RESET_RETRY_MS`] apart).
pub const RESET_ID_ATTEMPTS: u32 = 3;
/// Wait between two identity reads after a soft reset, ms.
pub const RESET_RETRY_MS: u32 = 5;

/// Register map (datasheet §5.2 accelerometer, §5.4 gyroscope; BMI08x API `bmi08_defs.h`).
mod reg {
    pub const ACC_CHIP_ID: u8 = 0x00;
    pub const ACC_ERR_REG: u8 = 0x02;
    pub const ACC_STATUS: u8 = 0x03;
    pub const ACC_X_LSB: u8 = 0x12;
    pub const ACC_CONF: u8 = 0x40;
    pub const ACC_RANGE: u8 = 0x41;
    pub const ACC_PWR_CONF: u8 = 0x7C;
    pub const ACC_PWR_CTRL: u8 = 0x7D;
    pub const ACC_SOFTRESET: u8 = 0x7E;

    pub const GYRO_CHIP_ID: u8 = 0x00;
    pub const GYRO_RATE_X_LSB: u8 = 0x02;
    pub const GYRO_INT_STAT_1: u8 = 0x0A;
    pub const GYRO_RANGE: u8 = 0x0F;
    pub const GYRO_BANDWIDTH: u8 = 0x10;
    pub const GYRO_LPM1: u8 = 0x11;
    pub const GYRO_SOFTRESET: u8 = 0x14;
    pub const GYRO_INT_CTRL: u8 = 0x15;
    pub const INT3_INT4_IO_CONF: u8 = 0x16;
    pub const INT3_INT4_IO_MAP: u8 = 0x18;
}

/// Register values written by [`Bmi088::init`] (datasheet §5.3, §5.5; stock in the table above).
mod val {
    /// Soft-reset command, both halves.
    pub const SOFTRESET: u8 = 0xB6;
    /// ACC_PWR_CTRL: accelerometer on.
    pub const ACC_ENABLE: u8 = 0x04;
    /// ACC_PWR_CONF: active mode (0x03 = suspend, the reset value).
    pub const ACC_ACTIVE: u8 = 0x00;
    /// ACC_CONF: acc_bwp = 0x8 (OSR4) in bits 7:4, acc_odr = 0xC (1600 Hz) in bits 3:0. Stock reaches the
    /// same byte by a read-modify-write of the reset value 0xA8.
    pub const ACC_CONF_OSR4_1600HZ: u8 = 0x8C;
    /// ACC_RANGE: ±24 g (bits 1:0).
    pub const ACC_RANGE_24G: u8 = 0x03;
    /// GYRO_LPM1: normal mode.
    pub const GYRO_NORMAL: u8 = 0x00;
    /// GYRO_RANGE: ±2000 °/s.
    pub const GYRO_RANGE_2000DPS: u8 = 0x00;
    /// GYRO_BANDWIDTH: ODR 1000 Hz, filter bandwidth 116 Hz (bit 7 reads back as 1).
    pub const GYRO_BW_116HZ_ODR_1000HZ: u8 = 0x02;
    /// GYRO_INT_CTRL: data-ready interrupt enabled.
    pub const GYRO_DRDY_ENABLE: u8 = 0x80;
    /// INT3_INT4_IO_CONF: INT3 active high (bit 0) and push-pull (bit 1 = 0); INT4 bits 3:2 left at their
    /// reset value 0b11 (active high, open drain), which is what stock's read-modify-write produces.
    pub const INT3_ACTIVE_HIGH_PUSH_PULL: u8 = 0x0D;
    /// INT3_INT4_IO_MAP: data-ready to INT3 only.
    pub const DRDY_TO_INT3: u8 = 0x01;
}

/// Bit 7 of ACC_STATUS and of GYRO_INT_STAT_1: new data.
const DATA_READY_BIT: u8 = 0x80;
/// ACC_ERR_REG bit 0.
const ACC_ERR_FATAL: u8 = 0x01;
/// ACC_ERR_REG bits 4:2.
const ACC_ERR_CODE_MASK: u8 = 0x1C;
/// ACC_RANGE bits that hold the range (7:2 are reserved).
const ACC_RANGE_MASK: u8 = 0x03;

const MS: u32 = 1;
const GYRO_SOFTRESET_DELAY_MS: u32 = 30 * MS;
const GYRO_POWER_MODE_DELAY_MS: u32 = 30 * MS;
const ACC_SOFTRESET_DELAY_MS: u32 = MS;
const ACC_POWER_ON_DELAY_MS: u32 = 5 * MS;
const ACC_ACTIVE_DELAY_MS: u32 = 10 * MS;
const DATA_READY_POLL_MS: u32 = MS;

/// One raw reading in chip counts, chip axes (= body axes on the Crazyflie).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RawImu {
    /// Gyro x, y, z, LSB (±2000 °/s full scale).
    pub gyro: [i16; 3],
    /// Accelerometer x, y, z, LSB (±24 g full scale).
    pub accel: [i16; 3],
}

impl RawImu {
    /// Converts to SI units in the body frame (see the module doc for the constants and the axis mapping).
    pub fn to_sample(&self) -> ImuSample {
        ImuSample {
            gyro_rad_s: self.gyro.map(|v| f32::from(v) * GYRO_RAD_S_PER_LSB),
            accel_m_s2: self.accel.map(|v| f32::from(v) * ACCEL_M_S2_PER_LSB),
        }
    }
}

/// The config block's board trim `calibRoll/calibPitch` (degrees), applied to the accelerometer as stock
/// `sensorsAccAlignToGravity` (crazyflie-firmware `sensors_bmi088_bmp3xx.c`): rotate about x by the roll
/// trim, then about y by the pitch trim; the gyro is left alone (stock too). Non-finite trims, or trims
/// beyond ±[`AccelTrim::MAX_DEG`] (a corrupt block), give the identity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AccelTrim {
    cos_roll: f32,
    sin_roll: f32,
    cos_pitch: f32,
    sin_pitch: f32,
}

impl AccelTrim {
    /// The largest trim accepted, degrees (cfclient's trim is a few degrees).
    pub const MAX_DEG: f32 = 20.0;
    /// No trim.
    pub const IDENTITY: Self = Self {
        cos_roll: 1.0,
        sin_roll: 0.0,
        cos_pitch: 1.0,
        sin_pitch: 0.0,
    };

    /// From the config block's `calib_roll_deg` and `calib_pitch_deg`.
    pub fn from_degrees(roll_deg: f32, pitch_deg: f32) -> Self {
        let ok = |d: f32| d.is_finite() && d.abs() <= Self::MAX_DEG;
        if !(ok(roll_deg) && ok(pitch_deg)) {
            return Self::IDENTITY;
        }
        let (r, p) = (roll_deg.to_radians(), pitch_deg.to_radians());
        Self {
            cos_roll: libm::cosf(r),
            sin_roll: libm::sinf(r),
            cos_pitch: libm::cosf(p),
            sin_pitch: libm::sinf(p),
        }
    }

    /// The trimmed accelerometer vector (stock's two rotations, in its order).
    pub fn apply(&self, a: [f32; 3]) -> [f32; 3] {
        let rx = [
            a[0],
            a[1] * self.cos_roll - a[2] * self.sin_roll,
            a[1] * self.sin_roll + a[2] * self.cos_roll,
        ];
        [
            rx[0] * self.cos_pitch - rx[2] * self.sin_pitch,
            rx[1],
            rx[0] * self.sin_pitch + rx[2] * self.cos_pitch,
        ]
    }

    /// `sample` with its accelerometer trimmed.
    pub fn apply_to(&self, sample: ImuSample) -> ImuSample {
        ImuSample {
            accel_m_s2: self.apply(sample.accel_m_s2),
            ..sample
        }
    }
}

/// The BMI088 on one I2C bus (both halves).
#[derive(Debug)]
pub struct Bmi088<I> {
    i2c: I,
    last_accel_error: u8,
    initialised: bool,
}

impl<I: I2c> Bmi088<I> {
    /// A driver for the chip on `i2c`; nothing is sent until [`Bmi088::init`].
    pub fn new(i2c: I) -> Self {
        Self {
            i2c,
            last_accel_error: 0,
            initialised: false,
        }
    }

    /// Gives the bus back.
    pub fn release(self) -> I {
        self.i2c
    }

    /// The ACC_ERR_REG value read by the last [`Bmi088::init`] or [`Bmi088::check_accel_errors`]
    /// (0 = no error; bit 0 fatal, bits 4:2 error code).
    pub fn last_accel_error(&self) -> u8 {
        self.last_accel_error
    }

    /// Whether [`Bmi088::init`] has completed successfully.
    pub fn is_initialised(&self) -> bool {
        self.initialised
    }

    /// Probes, resets and configures both halves, then waits for their first samples (≈ 80 ms, mostly the
    /// datasheet delays). Safe to call again after a failure: it starts over with the soft resets.
    pub async fn init<D: DelayNs>(&mut self, delay: &mut D) -> Result<(), DriverError<I::Error>> {
        self.initialised = false;
        self.init_gyro(delay).await?;
        self.init_accel(delay).await?;
        self.wait_data_ready(ACCEL_ADDR, reg::ACC_STATUS, delay).await?;
        self.wait_data_ready(GYRO_ADDR, reg::GYRO_INT_STAT_1, delay).await?;
        self.initialised = true;
        Ok(())
    }

    async fn init_gyro<D: DelayNs>(&mut self, delay: &mut D) -> Result<(), DriverError<I::Error>> {
        self.check_chip_id(GYRO_ADDR, reg::GYRO_CHIP_ID, GYRO_CHIP_ID).await?;
        self.soft_reset(GYRO_ADDR, reg::GYRO_SOFTRESET, GYRO_SOFTRESET_DELAY_MS, delay)
            .await;
        self.check_chip_id_after_reset(GYRO_ADDR, reg::GYRO_CHIP_ID, GYRO_CHIP_ID, delay)
            .await?;
        self.write(GYRO_ADDR, reg::GYRO_LPM1, val::GYRO_NORMAL).await?;
        delay.delay_ms(GYRO_POWER_MODE_DELAY_MS).await;
        self.write(GYRO_ADDR, reg::GYRO_RANGE, val::GYRO_RANGE_2000DPS).await?;
        self.write(GYRO_ADDR, reg::GYRO_BANDWIDTH, val::GYRO_BW_116HZ_ODR_1000HZ)
            .await?;
        self.write(GYRO_ADDR, reg::INT3_INT4_IO_CONF, val::INT3_ACTIVE_HIGH_PUSH_PULL)
            .await?;
        self.write(GYRO_ADDR, reg::INT3_INT4_IO_MAP, val::DRDY_TO_INT3).await?;
        self.write(GYRO_ADDR, reg::GYRO_INT_CTRL, val::GYRO_DRDY_ENABLE).await?;
        Ok(())
    }

    async fn init_accel<D: DelayNs>(&mut self, delay: &mut D) -> Result<(), DriverError<I::Error>> {
        self.check_chip_id(ACCEL_ADDR, reg::ACC_CHIP_ID, ACCEL_CHIP_ID).await?;
        self.soft_reset(ACCEL_ADDR, reg::ACC_SOFTRESET, ACC_SOFTRESET_DELAY_MS, delay)
            .await;
        self.check_chip_id_after_reset(ACCEL_ADDR, reg::ACC_CHIP_ID, ACCEL_CHIP_ID, delay)
            .await?;
        self.write(ACCEL_ADDR, reg::ACC_PWR_CTRL, val::ACC_ENABLE).await?;
        delay.delay_ms(ACC_POWER_ON_DELAY_MS).await;
        self.write(ACCEL_ADDR, reg::ACC_PWR_CONF, val::ACC_ACTIVE).await?;
        delay.delay_ms(ACC_ACTIVE_DELAY_MS).await;
        self.write(ACCEL_ADDR, reg::ACC_CONF, val::ACC_CONF_OSR4_1600HZ).await?;
        self.write(ACCEL_ADDR, reg::ACC_RANGE, val::ACC_RANGE_24G).await?;
        self.check_accel_errors().await?;
        // ACC_CONF and ACC_RANGE are adjacent: one burst reads both back.
        let mut conf = [0u8; 2];
        self.i2c.write_read(ACCEL_ADDR, &[reg::ACC_CONF], &mut conf).await?;
        if conf[0] != val::ACC_CONF_OSR4_1600HZ || conf[1] & ACC_RANGE_MASK != val::ACC_RANGE_24G {
            return Err(DriverError::InvalidConfig);
        }
        Ok(())
    }

    /// Reads ACC_ERR_REG: `fatal_err` → [`DriverError::InvalidData`], a non-zero `error_code` (invalid
    /// ACC_CONF) → [`DriverError::InvalidConfig`]. Cheap (one 1-byte read); the firmware may call it at a
    /// low rate in flight as a health check.
    pub async fn check_accel_errors(&mut self) -> Result<(), DriverError<I::Error>> {
        let err = self.read_u8(ACCEL_ADDR, reg::ACC_ERR_REG).await?;
        self.last_accel_error = err;
        if err & ACC_ERR_FATAL != 0 {
            Err(DriverError::InvalidData)
        } else if err & ACC_ERR_CODE_MASK != 0 {
            Err(DriverError::InvalidConfig)
        } else {
            Ok(())
        }
    }

    /// Reads one gyro and one accelerometer sample in chip counts (two 6-byte bursts).
    pub async fn read_raw(&mut self) -> Result<RawImu, DriverError<I::Error>> {
        let gyro = self.read_vector(GYRO_ADDR, reg::GYRO_RATE_X_LSB).await?;
        let accel = self.read_vector(ACCEL_ADDR, reg::ACC_X_LSB).await?;
        Ok(RawImu { gyro, accel })
    }

    /// Reads one sample in SI units, body frame (call on each gyro data-ready edge, 1 kHz).
    pub async fn read(&mut self) -> Result<ImuSample, DriverError<I::Error>> {
        Ok(self.read_raw().await?.to_sample())
    }

    async fn read_vector(&mut self, addr: u8, first: u8) -> Result<[i16; 3], DriverError<I::Error>> {
        let mut b = [0u8; 6];
        self.i2c.write_read(addr, &[first], &mut b).await?;
        Ok([
            i16::from_le_bytes([b[0], b[1]]),
            i16::from_le_bytes([b[2], b[3]]),
            i16::from_le_bytes([b[4], b[5]]),
        ])
    }

    /// Writes the soft-reset command and waits `delay_ms`. Fire-and-forget: the chip resets while it
    /// receives the command and may not acknowledge it (or the STOP after it), so a bus error here says
    /// nothing about the chip; the identity read that follows ([`Self::check_chip_id_after_reset`]) does.
    async fn soft_reset<D: DelayNs>(&mut self, addr: u8, reset_reg: u8, delay_ms: u32, delay: &mut D) {
        let _ = self.i2c.write(addr, &[reset_reg, val::SOFTRESET]).await;
        delay.delay_ms(delay_ms).await;
    }

    /// The identity read after a soft reset: up to [`RESET_ID_ATTEMPTS`] tries, [`RESET_RETRY_MS`] apart,
    /// for a chip that is still booting; the last failure is returned.
    async fn check_chip_id_after_reset<D: DelayNs>(
        &mut self,
        addr: u8,
        id_reg: u8,
        expected: u8,
        delay: &mut D,
    ) -> Result<(), DriverError<I::Error>> {
        let mut result = Ok(());
        for attempt in 0..RESET_ID_ATTEMPTS {
            if attempt > 0 {
                delay.delay_ms(RESET_RETRY_MS).await;
            }
            result = self.check_chip_id(addr, id_reg, expected).await;
            if result.is_ok() {
                break;
            }
        }
        result
    }

    async fn check_chip_id(&mut self, addr: u8, id_reg: u8, expected: u8) -> Result<(), DriverError<I::Error>> {
        let found = self.read_u8(addr, id_reg).await?;
        if found != expected {
            return Err(DriverError::WrongChipId {
                expected: u16::from(expected),
                found: u16::from(found),
            });
        }
        Ok(())
    }

    async fn wait_data_ready<D: DelayNs>(
        &mut self,
        addr: u8,
        status_reg: u8,
        delay: &mut D,
    ) -> Result<(), DriverError<I::Error>> {
        for attempt in 0..DATA_READY_POLLS {
            if attempt > 0 {
                delay.delay_ms(DATA_READY_POLL_MS).await;
            }
            if self.read_u8(addr, status_reg).await? & DATA_READY_BIT != 0 {
                return Ok(());
            }
        }
        Err(DriverError::Timeout)
    }

    async fn read_u8(&mut self, addr: u8, register: u8) -> Result<u8, DriverError<I::Error>> {
        let mut b = [0u8; 1];
        self.i2c.write_read(addr, &[register], &mut b).await?;
        Ok(b[0])
    }

    async fn write(&mut self, addr: u8, register: u8, value: u8) -> Result<(), DriverError<I::Error>> {
        self.i2c.write(addr, &[register, value]).await?;
        Ok(())
    }
}
