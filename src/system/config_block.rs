//! The Crazyflie's config block (radio channel, data rate and address, board tilt calibration) as stored at
//! offset 0 of the on-board I2C EEPROM, and the syslink packets that hand the radio settings to the nRF51.
//!
//! Job: parse the block's bytes, check magic, version and checksum, and fall back to the stock defaults
//! (channel 80, 2 Mbit/s, address 0xE7E7E7E7E7) with a reason when anything is wrong; build the boot
//! packets RADIO_CHANNEL, RADIO_DATARATE and RADIO_ADDRESS in the stock order.
//!
//! Non-goals: no I2C (the board layer reads [`READ_LEN`] bytes from EEPROM address 0x0000 at I2C address
//! [`EEPROM_I2C_ADDRESS`]), no writing or upgrading the block, no KVE (persistent parameters at offset 1024).
//!
//! Layout (`docs/hardware.md` §1; bitcraze crazyflie-firmware `src/utils/src/configblockeeprom.c`,
//! `configblock_v0_s` / `configblock_v1_s`, packed, little-endian):
//!
//! | offset | v0 | v1 |
//! |---|---|---|
//! | 0 | magic u32 = 0x43427830 | same |
//! | 4 | version u8 = 0 | version u8 = 1 |
//! | 5 | radio channel u8 | same |
//! | 6 | radio speed u8 (0 = 250K, 1 = 1M, 2 = 2M) | same |
//! | 7 | calib pitch f32 (°) | same |
//! | 11 | calib roll f32 (°) | same |
//! | 15 | checksum u8 | radio address upper u8 |
//! | 16 | — | radio address lower u32 |
//! | 20 | — | checksum u8 |
//!
//! The checksum is the byte sum (mod 256) of every byte before it (`calculate_cksum`). A v0 block has no
//! address: the default address is used with its channel and rate. Other versions (v2 is a development
//! layout) are not trusted: defaults. Channel > 125 (`docs/hardware.md` §4) or an unknown rate code also give the defaults.
//!
//! Memory: [`RadioSettings`] is 16 bytes; nothing is kept.

use crate::radio::syslink::{Datarate, EncodeError, SyslinkPacket};

/// The EEPROM's 7-bit I2C address on the deck bus I2C1 (`docs/hardware.md` §1, §2).
pub const EEPROM_I2C_ADDRESS: u8 = 0x50;
/// Magic number at offset 0 ("0xCB" in ASCII order, stock `MAGIC`).
pub const MAGIC: u32 = 0x4342_7830;
/// Bytes of a v1 block (the longest layout parsed); read this many from EEPROM address 0.
pub const READ_LEN: usize = 21;
/// Bytes of a v0 block.
pub const V0_LEN: usize = 16;
/// Stock default radio channel (`config.h` `RADIO_CHANNEL`).
pub const DEFAULT_CHANNEL: u8 = 80;
/// Stock default data rate (`config.h` `RADIO_DATARATE`).
pub const DEFAULT_DATARATE: Datarate = Datarate::Rate2M;
/// Stock default radio address (`config.h` `RADIO_ADDRESS`).
pub const DEFAULT_ADDRESS: u64 = 0xE7_E7E7_E7E7;
/// Highest radio channel (2400 + 125 MHz, `docs/hardware.md` §4).
pub const MAX_CHANNEL: u8 = 125;

/// Radio settings and board calibration, from the block or the defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadioSettings {
    /// Channel, 0..=125 (2400 + channel MHz).
    pub channel: u8,
    /// Over-the-air data rate.
    pub datarate: Datarate,
    /// 40-bit radio address.
    pub address: u64,
    /// Board tilt calibration, pitch, degrees (0 with the defaults).
    pub calib_pitch_deg: f32,
    /// Board tilt calibration, roll, degrees (0 with the defaults).
    pub calib_roll_deg: f32,
}

impl Default for RadioSettings {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why the block was not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigBlockError {
    /// Fewer bytes than the block's version needs.
    TooShort,
    /// The magic number is wrong (blank or foreign EEPROM).
    BadMagic,
    /// A version this firmware does not parse.
    UnknownVersion(u8),
    /// The checksum byte does not match.
    BadChecksum,
    /// The channel is above 125.
    BadChannel(u8),
    /// The data-rate code is not 0, 1 or 2.
    BadDatarate(u8),
}

fn u32_le(bytes: &[u8], at: usize) -> u32 {
    let mut b = [0u8; 4];
    b.copy_from_slice(&bytes[at..at + 4]);
    u32::from_le_bytes(b)
}

fn byte_sum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |acc, &b| acc.wrapping_add(b))
}

impl RadioSettings {
    /// The stock defaults: channel 80, 2 Mbit/s, address 0xE7E7E7E7E7, no tilt calibration.
    pub const DEFAULT: Self = Self {
        channel: DEFAULT_CHANNEL,
        datarate: DEFAULT_DATARATE,
        address: DEFAULT_ADDRESS,
        calib_pitch_deg: 0.0,
        calib_roll_deg: 0.0,
    };

    /// Parses the block read from EEPROM offset 0 (extra bytes after the block are ignored).
    pub fn parse(bytes: &[u8]) -> Result<Self, ConfigBlockError> {
        if bytes.len() < 5 {
            return Err(ConfigBlockError::TooShort);
        }
        if u32_le(bytes, 0) != MAGIC {
            return Err(ConfigBlockError::BadMagic);
        }
        let len = match bytes[4] {
            0 => V0_LEN,
            1 => READ_LEN,
            v => return Err(ConfigBlockError::UnknownVersion(v)),
        };
        let block = bytes.get(..len).ok_or(ConfigBlockError::TooShort)?;
        if byte_sum(&block[..len - 1]) != block[len - 1] {
            return Err(ConfigBlockError::BadChecksum);
        }
        let channel = block[5];
        if channel > MAX_CHANNEL {
            return Err(ConfigBlockError::BadChannel(channel));
        }
        let datarate = match block[6] {
            0 => Datarate::Rate250K,
            1 => Datarate::Rate1M,
            2 => Datarate::Rate2M,
            code => return Err(ConfigBlockError::BadDatarate(code)),
        };
        let address = if len == READ_LEN {
            (u64::from(block[15]) << 32) | u64::from(u32_le(block, 16))
        } else {
            DEFAULT_ADDRESS
        };
        Ok(Self {
            channel,
            datarate,
            address,
            calib_pitch_deg: f32::from_bits(u32_le(block, 7)),
            calib_roll_deg: f32::from_bits(u32_le(block, 11)),
        })
    }

    /// [`parse`](Self::parse), or the defaults and the reason they were used.
    pub fn parse_or_default(bytes: &[u8]) -> (Self, Option<ConfigBlockError>) {
        match Self::parse(bytes) {
            Ok(s) => (s, None),
            Err(e) => (Self::DEFAULT, Some(e)),
        }
    }

    /// The boot packets in the stock order (`radiolink.c` `radiolinkInit`: channel, data rate, address),
    /// sent before RADIO_READY (`docs/hardware.md` §4 step 1). Fails only for a hand-built value with
    /// a channel above 125 or an address wider than 40 bits ([`parse`](Self::parse) never makes one).
    pub fn boot_packets(&self) -> Result<[SyslinkPacket; 3], EncodeError> {
        Ok([
            SyslinkPacket::radio_channel(self.channel)?,
            SyslinkPacket::radio_datarate(self.datarate),
            SyslinkPacket::radio_address(self.address)?,
        ])
    }
}
