//! Device models on the emulated Crazyflie's buses, written against rsemu's public [`I2cSlave`] trait and
//! attached to the machine's named buses ("sensors" = I2C3, "deck" = I2C1) from outside the emulator crate.
//!
//! Job: answer what the boot reads, the way the chips do. The BMI088 (I2C3, accelerometer 0x18,
//! gyroscope 0x69) with its chip ids, reset values, soft reset, data-ready status bits and a level,
//! motionless sample; the deck EEPROM (I2C1, 0x50, 24AA64: 8 KiB, two address bytes) holding a valid config
//! block. Nothing else answers on the deck bus (no Multi-ranger, no Flow deck: their probes see NACKs).
//!
//! Fault injection ([`Faults`]): the BMI088 that does not acknowledge the soft-reset command byte (a real
//! part can: it resets at once and NACKs), and a sensor bus where no device acknowledges anything (an IMU that
//! is not there, as the I2C master sees it). A bus whose SDA is held low by a slave is `crate::stuck`.
//!
//! Non-goals: no physics (`physics.rs` feeds the simulator's truth), no data-ready pulses on PC14, no
//! write-cycle timing in the EEPROM.
//!
//! Units: raw chip counts. Sources: Bosch BMI088 datasheet (BST-BMI088-DS001) §5.3 (accelerometer register
//! map: ACC_CHIP_ID 0x1E, reset values), §6 (gyroscope: GYRO_CHIP_ID 0x0F); docs/hardware.md §1 (the
//! EEPROM and the config block layout); the register constants are the firmware's own
//! (`cfnav::drivers::bmi088::reg`).

use std::sync::Mutex;

use rsemu::bus::i2c::{Ack, Address, Direction, I2cSlave};

use cfnav::drivers::bmi088::{ACCEL_ADDR, ACCEL_CHIP_ID, GYRO_ADDR, GYRO_CHIP_ID};
use cfnav::system::config_block;

/// What to break, for the first-flash hazards.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Faults {
    /// The BMI088 resets on the soft-reset command but does not acknowledge its data byte.
    pub bmi088_reset_nack: bool,
    /// Nothing on I2C3 acknowledges its address.
    pub sensor_bus_dead: bool,
    /// A slave holds I2C3's SDA low from power-on (`crate::stuck`), letting go as this says.
    pub sensor_bus_stuck: Option<crate::stuck::Release>,
    /// The same on the deck bus, I2C1.
    pub deck_bus_stuck: Option<crate::stuck::Release>,
    /// The nRF51 holds RTS (PA4) high from power-on.
    pub rts_high: bool,
    /// USART6's transmit DMA request never rises from power-on: every TX DMA transfer the image starts
    /// hangs (as a stalled stream or a TXE that never comes would).
    pub syslink_tx_dead: bool,
    /// The Flow deck stops answering from this virtual time (ms) on, as when its connector works loose in
    /// flight: the PMW3901 leaves MISO floating high and its VL53L1x is off the deck bus.
    pub flow_deck_lost_at_ms: Option<u64>,
    /// The BMI088 stops answering from this virtual time (ms) on, as when its supply or the sensor bus
    /// fails in flight: both halves NACK their addresses and INT3 stays low.
    pub imu_lost_at_ms: Option<u64>,
    /// The Multi-ranger deck stops answering from this virtual time (ms) on: its expander and rangers leave
    /// the deck bus.
    pub multiranger_lost_at_ms: Option<u64>,
}

/// Counters a report prints.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct BusStats {
    pub transactions: u32,
    pub nacked_addresses: u32,
    pub soft_resets: u32,
    pub nacked_bytes: u32,
}

/// One half of the BMI088 (accelerometer or gyroscope): a register file with an auto-incrementing pointer.
#[derive(Debug)]
struct Half {
    address: u8,
    regs: [u8; 128],
    pointer: u8,
    /// Whether the next written byte is the register pointer.
    expect_pointer: bool,
    addressed: bool,
}

const ACC_SOFTRESET: u8 = 0x7E;
const GYRO_SOFTRESET: u8 = 0x14;
const SOFTRESET_CMD: u8 = 0xB6;

impl Half {
    fn new(address: u8) -> Self {
        let mut half = Self {
            address,
            regs: [0; 128],
            pointer: 0,
            expect_pointer: true,
            addressed: false,
        };
        half.power_on();
        half
    }

    /// Reset values (datasheet §5.3 / §6) plus what a motionless, level chip reads.
    fn power_on(&mut self) {
        self.regs = [0; 128];
        if self.address == ACCEL_ADDR {
            self.regs[0x00] = ACCEL_CHIP_ID;
            self.regs[0x03] = 0x80; // ACC_STATUS.drdy_acc
            // +1 g on z at the ±3 g reset range would be 10922 counts; the firmware sets ±24 g (1365 counts) before
            // it reads data, so the sample is written for that range.
            let z: i16 = 1365;
            self.regs[0x16..0x18].copy_from_slice(&z.to_le_bytes());
            self.regs[0x40] = 0xA8; // ACC_CONF
            self.regs[0x41] = 0x01; // ACC_RANGE
            self.regs[0x7C] = 0x03; // ACC_PWR_CONF: suspend
        } else {
            self.regs[0x00] = GYRO_CHIP_ID;
            self.regs[0x0A] = 0x80; // GYRO_INT_STAT_1.gyro_drdy
            self.regs[0x10] = 0x80; // GYRO_BANDWIDTH
        }
    }

    fn is_read_only(&self, reg: u8) -> bool {
        if self.address == ACCEL_ADDR {
            reg < 0x40
        } else {
            reg < 0x0F
        }
    }
}

/// The BMI088 on I2C3.
#[derive(Debug)]
pub struct Bmi088 {
    faults: Faults,
    /// `Faults::imu_lost_at_ms` has come: the chip is gone.
    lost: std::sync::atomic::AtomicBool,
    halves: Mutex<[Half; 2]>,
    stats: Mutex<BusStats>,
}

impl Bmi088 {
    pub fn new(faults: Faults) -> Self {
        Self {
            faults,
            lost: std::sync::atomic::AtomicBool::new(false),
            halves: Mutex::new([Half::new(ACCEL_ADDR), Half::new(GYRO_ADDR)]),
            stats: Mutex::new(BusStats::default()),
        }
    }

    /// Whether the gyroscope drives data-ready on INT3: GYRO_INT_CTRL bit 7 and INT3_INT4_IO_MAP bit 0
    /// (datasheet §5.5.8, §5.5.10).
    pub fn int3_drdy_enabled(&self) -> bool {
        !self.faults.sensor_bus_dead
            && !self.is_lost()
            && self.with_halves(|h| {
                let gyro = &h[1];
                gyro.regs[0x15] & 0x80 != 0 && gyro.regs[0x18] & 0x01 != 0
            })
    }

    /// The gyroscope's data-ready period from GYRO_BANDWIDTH (datasheet §5.5.6: ODR 2000 Hz for 0x00/0x01,
    /// 1000 Hz for 0x02, 400 Hz for 0x03, 200 Hz for 0x04/0x06, 100 Hz for 0x05/0x07), ns.
    pub fn gyro_period_ns(&self) -> u64 {
        let bw = self.with_halves(|h| h[1].regs[0x10] & 0x07);
        match bw {
            0 | 1 => 500_000,
            2 => 1_000_000,
            3 => 2_500_000,
            4 | 6 => 5_000_000,
            _ => 10_000_000,
        }
    }

    /// A new sample from the simulator (body = chip axes on the Crazyflie): rad/s and m/s², written as
    /// counts at the ranges the image configured (gyro GYRO_RANGE 0x0F: ±2000·2^-n °/s; accelerometer
    /// ACC_RANGE 0x41: ±3·2^n g, datasheet §5.3.4 with the ·1.5 of rev ≥ 1.4), saturating like the ADC, with
    /// the data-ready flags. The accelerometer converts only while powered and active (ACC_PWR_CTRL 0x04,
    /// ACC_PWR_CONF 0x00); otherwise its registers keep what they had (stale, as the chip).
    pub fn set_sample(&self, gyro_rad_s: [f32; 3], accel_m_s2: [f32; 3]) {
        self.with_halves(|h| {
            let gyro = &mut h[1];
            let range = gyro.regs[0x0F].min(4);
            let dps_full = 2000.0 / f32::from(1u16 << range);
            let lsb = dps_full * 2.0 / 65536.0 * core::f32::consts::PI / 180.0;
            for (i, v) in gyro_rad_s.iter().enumerate() {
                let c = (v / lsb).round().clamp(-32768.0, 32767.0) as i16;
                gyro.regs[0x02 + 2 * i..0x04 + 2 * i].copy_from_slice(&c.to_le_bytes());
            }
            gyro.regs[0x0A] |= 0x80;
            let acc = &mut h[0];
            if acc.regs[0x7D] == 0x04 && acc.regs[0x7C] == 0x00 {
                let g_full = 3.0 * f32::from(1u16 << (acc.regs[0x41] & 0x03));
                let lsb = g_full * 2.0 / 65536.0 * cfnav::types::GRAVITY_M_S2;
                for (i, v) in accel_m_s2.iter().enumerate() {
                    let c = (v / lsb).round().clamp(-32768.0, 32767.0) as i16;
                    acc.regs[0x12 + 2 * i..0x14 + 2 * i].copy_from_slice(&c.to_le_bytes());
                }
                acc.regs[0x03] |= 0x80;
            }
        });
    }

    /// From now on the chip NACKs its addresses and drives no data-ready (`--fault imu-lost`).
    pub fn lose(&self) {
        self.lost.store(true, std::sync::atomic::Ordering::Release);
    }

    pub fn is_lost(&self) -> bool {
        self.lost.load(std::sync::atomic::Ordering::Acquire)
    }

    pub fn stats(&self) -> BusStats {
        *self.stats.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn with_halves<R>(&self, f: impl FnOnce(&mut [Half; 2]) -> R) -> R {
        f(&mut self.halves.lock().unwrap_or_else(|e| e.into_inner()))
    }

    fn count(&self, f: impl FnOnce(&mut BusStats)) {
        f(&mut self.stats.lock().unwrap_or_else(|e| e.into_inner()));
    }
}

impl I2cSlave for Bmi088 {
    fn address(&self, address: Address, _dir: Direction) -> Ack {
        let Address::Seven(a) = address else {
            return Ack::Nack;
        };
        let ours = a == ACCEL_ADDR || a == GYRO_ADDR;
        if ours {
            self.count(|s| s.transactions += 1);
        }
        if !ours || self.faults.sensor_bus_dead || self.is_lost() {
            if ours {
                self.count(|s| s.nacked_addresses += 1);
            }
            self.with_halves(|h| h.iter_mut().for_each(|h| h.addressed = false));
            return Ack::Nack;
        }
        self.with_halves(|h| {
            for half in h.iter_mut() {
                half.addressed = half.address == a;
                if half.addressed {
                    half.expect_pointer = true;
                }
            }
        });
        Ack::Ack
    }

    fn write(&self, byte: u8) -> Ack {
        let mut reset = false;
        let ack = self.with_halves(|h| {
            let Some(half) = h.iter_mut().find(|h| h.addressed) else {
                return Ack::Nack;
            };
            if half.expect_pointer {
                half.pointer = byte & 0x7F;
                half.expect_pointer = false;
                return Ack::Ack;
            }
            let reg = half.pointer;
            half.pointer = (half.pointer + 1) & 0x7F;
            let softreset_reg = if half.address == ACCEL_ADDR {
                ACC_SOFTRESET
            } else {
                GYRO_SOFTRESET
            };
            if reg == softreset_reg && byte == SOFTRESET_CMD {
                half.power_on();
                reset = true;
                return if self.faults.bmi088_reset_nack {
                    Ack::Nack
                } else {
                    Ack::Ack
                };
            }
            if !half.is_read_only(reg) {
                half.regs[usize::from(reg)] = byte;
            }
            Ack::Ack
        });
        if reset {
            self.count(|s| s.soft_resets += 1);
        }
        if ack == Ack::Nack {
            self.count(|s| s.nacked_bytes += 1);
        }
        ack
    }

    fn read(&self) -> u8 {
        self.with_halves(|h| {
            h.iter()
                .find(|h| h.addressed)
                .map_or(0xFF, |half| half.regs[usize::from(half.pointer)])
        })
    }

    fn read_ack(&self, _ack: Ack) {
        self.with_halves(|h| {
            if let Some(half) = h.iter_mut().find(|h| h.addressed) {
                half.pointer = (half.pointer + 1) & 0x7F;
            }
        });
    }

    fn stop(&self) {
        self.with_halves(|h| h.iter_mut().for_each(|h| h.addressed = false));
    }

    fn peek(&self) -> u8 {
        self.read()
    }
}

/// The deck EEPROM: 8 KiB, two address bytes (big-endian), sequential read and write with wrap-around.
#[derive(Debug)]
pub struct Eeprom {
    state: Mutex<EepromState>,
}

#[derive(Debug)]
struct EepromState {
    bytes: Vec<u8>,
    pointer: u16,
    address_bytes_seen: u8,
    addressed: bool,
}

/// 24AA64: 8 KiB.
pub const EEPROM_SIZE: usize = 8192;

/// A valid config block (docs/hardware.md §1): version 1, channel 80, 2 Mbit/s, no trim,
/// address 0xE7E7E7E7E7, and the byte-sum checksum.
pub fn default_config_block() -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(&config_block::MAGIC.to_le_bytes());
    b.push(1); // version
    b.push(config_block::DEFAULT_CHANNEL);
    b.push(2); // 2 Mbit/s
    b.extend_from_slice(&0.0f32.to_le_bytes()); // calibPitch
    b.extend_from_slice(&0.0f32.to_le_bytes()); // calibRoll
    let address = config_block::DEFAULT_ADDRESS;
    b.push((address >> 32) as u8);
    b.extend_from_slice(&(address as u32).to_le_bytes());
    let sum = b.iter().fold(0u8, |acc, &x| acc.wrapping_add(x));
    b.push(sum);
    b
}

impl Eeprom {
    pub fn new(contents: &[u8]) -> Self {
        let mut bytes = vec![0xFF; EEPROM_SIZE];
        let n = contents.len().min(EEPROM_SIZE);
        bytes[..n].copy_from_slice(&contents[..n]);
        Self {
            state: Mutex::new(EepromState {
                bytes,
                pointer: 0,
                address_bytes_seen: 0,
                addressed: false,
            }),
        }
    }

    fn with<R>(&self, f: impl FnOnce(&mut EepromState) -> R) -> R {
        f(&mut self.state.lock().unwrap_or_else(|e| e.into_inner()))
    }
}

impl I2cSlave for Eeprom {
    fn address(&self, address: Address, dir: Direction) -> Ack {
        let ours = address == Address::Seven(config_block::EEPROM_I2C_ADDRESS);
        self.with(|s| {
            s.addressed = ours;
            if ours && dir == Direction::Write {
                s.address_bytes_seen = 0;
            }
        });
        if ours { Ack::Ack } else { Ack::Nack }
    }

    fn write(&self, byte: u8) -> Ack {
        self.with(|s| {
            if !s.addressed {
                return Ack::Nack;
            }
            match s.address_bytes_seen {
                0 => {
                    s.pointer = (u16::from(byte) << 8) & (EEPROM_SIZE as u16 - 1);
                    s.address_bytes_seen = 1;
                }
                1 => {
                    s.pointer = (s.pointer | u16::from(byte)) & (EEPROM_SIZE as u16 - 1);
                    s.address_bytes_seen = 2;
                }
                _ => {
                    let at = usize::from(s.pointer);
                    s.bytes[at] = byte;
                    s.pointer = (s.pointer + 1) & (EEPROM_SIZE as u16 - 1);
                }
            }
            Ack::Ack
        })
    }

    fn read(&self) -> u8 {
        self.with(|s| {
            if s.addressed {
                s.bytes[usize::from(s.pointer)]
            } else {
                0xFF
            }
        })
    }

    fn read_ack(&self, _ack: Ack) {
        self.with(|s| s.pointer = (s.pointer + 1) & (EEPROM_SIZE as u16 - 1));
    }

    fn stop(&self) {
        self.with(|s| s.addressed = false);
    }

    fn peek(&self) -> u8 {
        self.read()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_config_block_parses_with_the_firmwares_own_parser() {
        let block = default_config_block();
        assert_eq!(block.len(), config_block::READ_LEN);
        let settings = config_block::RadioSettings::parse(&block).expect("valid block");
        assert_eq!(settings, config_block::RadioSettings::DEFAULT);
    }

    fn write_reg(dev: &Bmi088, addr: u8, reg: u8, value: u8) -> Ack {
        assert_eq!(dev.address(Address::Seven(addr), Direction::Write), Ack::Ack);
        assert_eq!(dev.write(reg), Ack::Ack);
        let ack = dev.write(value);
        dev.stop();
        ack
    }

    fn read_reg(dev: &Bmi088, addr: u8, reg: u8) -> u8 {
        assert_eq!(dev.address(Address::Seven(addr), Direction::Write), Ack::Ack);
        assert_eq!(dev.write(reg), Ack::Ack);
        assert_eq!(dev.address(Address::Seven(addr), Direction::Read), Ack::Ack);
        let v = dev.read();
        dev.read_ack(Ack::Nack);
        dev.stop();
        v
    }

    #[test]
    fn the_bmi088_answers_its_chip_ids_and_resets_its_registers() {
        let dev = Bmi088::new(Faults::default());
        assert_eq!(read_reg(&dev, ACCEL_ADDR, 0x00), 0x1E);
        assert_eq!(read_reg(&dev, GYRO_ADDR, 0x00), 0x0F);
        assert_eq!(write_reg(&dev, ACCEL_ADDR, 0x40, 0x8C), Ack::Ack);
        assert_eq!(read_reg(&dev, ACCEL_ADDR, 0x40), 0x8C);
        assert_eq!(write_reg(&dev, ACCEL_ADDR, ACC_SOFTRESET, SOFTRESET_CMD), Ack::Ack);
        assert_eq!(read_reg(&dev, ACCEL_ADDR, 0x40), 0xA8, "reset value after a soft reset");
        assert_eq!(dev.address(Address::Seven(0x42), Direction::Write), Ack::Nack);
    }

    fn read_burst(dev: &Bmi088, addr: u8, reg: u8) -> [i16; 3] {
        assert_eq!(dev.address(Address::Seven(addr), Direction::Write), Ack::Ack);
        dev.write(reg);
        assert_eq!(dev.address(Address::Seven(addr), Direction::Read), Ack::Ack);
        let mut b = [0u8; 6];
        for x in b.iter_mut() {
            *x = dev.read();
            dev.read_ack(Ack::Ack);
        }
        dev.stop();
        [0, 1, 2].map(|i| i16::from_le_bytes([b[2 * i], b[2 * i + 1]]))
    }

    #[test]
    fn a_simulator_sample_reads_back_through_the_firmwares_own_conversion() {
        use cfnav::drivers::bmi088::RawImu;
        let dev = Bmi088::new(Faults::default());
        // The firmware's configuration: gyro ±2000 °/s (0x00), accelerometer ±24 g (0x03), powered, active.
        write_reg(&dev, GYRO_ADDR, 0x0F, 0x00);
        write_reg(&dev, ACCEL_ADDR, 0x41, 0x03);
        let gyro = [0.5, -1.25, 3.0];
        let accel = [0.3, -0.2, 9.81];
        dev.set_sample(gyro, accel);
        // Accelerometer still suspended: its registers keep the power-on sample.
        assert_eq!(read_burst(&dev, ACCEL_ADDR, 0x12), [0, 0, 1365]);
        write_reg(&dev, ACCEL_ADDR, 0x7D, 0x04);
        write_reg(&dev, ACCEL_ADDR, 0x7C, 0x00);
        dev.set_sample(gyro, accel);
        let raw = RawImu {
            gyro: read_burst(&dev, GYRO_ADDR, 0x02),
            accel: read_burst(&dev, ACCEL_ADDR, 0x12),
        };
        let back = raw.to_sample();
        for i in 0..3 {
            assert!((back.gyro_rad_s[i] - gyro[i]).abs() <= cfnav::drivers::bmi088::GYRO_RAD_S_PER_LSB);
            assert!((back.accel_m_s2[i] - accel[i]).abs() <= cfnav::drivers::bmi088::ACCEL_M_S2_PER_LSB);
        }
        // A driver that left the gyro at ±250 °/s (GYRO_RANGE 0x03) reads 8× the counts, saturating past
        // 250 °/s (4.36 rad/s).
        write_reg(&dev, GYRO_ADDR, 0x0F, 0x03);
        dev.set_sample(gyro, accel);
        let at_250 = read_burst(&dev, GYRO_ADDR, 0x02);
        assert!((i32::from(at_250[2]) - 8 * i32::from(raw.gyro[2])).abs() <= 8);
        dev.set_sample([0.0, 0.0, 5.0], accel);
        assert_eq!(read_burst(&dev, GYRO_ADDR, 0x02)[2], i16::MAX);
    }

    #[test]
    fn the_nack_fault_resets_but_does_not_acknowledge() {
        let dev = Bmi088::new(Faults {
            bmi088_reset_nack: true,
            ..Faults::default()
        });
        assert_eq!(write_reg(&dev, GYRO_ADDR, 0x10, 0x02), Ack::Ack);
        assert_eq!(write_reg(&dev, GYRO_ADDR, GYRO_SOFTRESET, SOFTRESET_CMD), Ack::Nack);
        assert_eq!(read_reg(&dev, GYRO_ADDR, 0x10), 0x80);
        assert_eq!(dev.stats().nacked_bytes, 1);
    }

    #[test]
    fn the_eeprom_reads_back_sequentially_from_a_two_byte_address() {
        let dev = Eeprom::new(&[1, 2, 3, 4]);
        assert_eq!(dev.address(Address::Seven(0x50), Direction::Write), Ack::Ack);
        assert_eq!(dev.write(0x00), Ack::Ack);
        assert_eq!(dev.write(0x01), Ack::Ack);
        assert_eq!(dev.address(Address::Seven(0x50), Direction::Read), Ack::Ack);
        let mut got = Vec::new();
        for _ in 0..4 {
            got.push(dev.read());
            dev.read_ack(Ack::Ack);
        }
        dev.stop();
        assert_eq!(got, vec![2, 3, 4, 0xFF]);
    }
}
