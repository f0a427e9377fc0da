//! The EEPROM config block (docs/hardware.md §1; stock `configblockeeprom.c` layouts v0/v1) and the
//! radio boot packets (§3.3, §3.4 and the worked frame examples of §3.2). Blocks are built here byte by byte
//! from the documented layout, with the checksum computed here.

use cfnav::radio::syslink::{Datarate, encode, kind};
use cfnav::system::config_block::{ConfigBlockError, RadioSettings};

/// A v1 block per the documented layout: magic, version, channel, speed, pitch, roll, address upper u8,
/// address lower u32, checksum (byte sum of the 20 bytes before it).
fn v1_block(channel: u8, speed: u8, pitch: f32, roll: f32, address: u64) -> Vec<u8> {
    let mut b = vec![0x30, 0x78, 0x42, 0x43, 1, channel, speed];
    b.extend_from_slice(&pitch.to_le_bytes());
    b.extend_from_slice(&roll.to_le_bytes());
    b.push((address >> 32) as u8);
    b.extend_from_slice(&(address as u32).to_le_bytes());
    let sum = b.iter().map(|&x| u32::from(x)).sum::<u32>() % 256;
    b.push(sum as u8);
    assert_eq!(b.len(), 21);
    b
}

fn v0_block(channel: u8, speed: u8) -> Vec<u8> {
    let mut b = vec![0x30, 0x78, 0x42, 0x43, 0, channel, speed];
    b.extend_from_slice(&1.5f32.to_le_bytes());
    b.extend_from_slice(&(-0.5f32).to_le_bytes());
    let sum = b.iter().map(|&x| u32::from(x)).sum::<u32>() % 256;
    b.push(sum as u8);
    assert_eq!(b.len(), 16);
    b
}

fn frame(p: &cfnav::radio::syslink::SyslinkPacket) -> Vec<u8> {
    let mut out = [0u8; 80];
    let n = encode(p, &mut out).unwrap();
    out[..n].to_vec()
}

/// §3.2 checksum, computed independently: 8-bit Fletcher over TYPE, LEN, DATA.
fn fletcher(body: &[u8]) -> [u8; 2] {
    let (mut a, mut b) = (0u8, 0u8);
    for &x in body {
        a = a.wrapping_add(x);
        b = b.wrapping_add(a);
    }
    [a, b]
}

#[test]
fn a_valid_v1_block_gives_its_settings() {
    let bytes = v1_block(42, 1, 0.25, -1.75, 0xE7_E7E7_E701);
    let s = RadioSettings::parse(&bytes).unwrap();
    assert_eq!(s.channel, 42);
    assert_eq!(s.datarate, Datarate::Rate1M);
    assert_eq!(s.address, 0xE7_E7E7_E701);
    assert_eq!(s.calib_pitch_deg, 0.25);
    assert_eq!(s.calib_roll_deg, -1.75);
    // Extra bytes read past the block are ignored.
    let mut longer = bytes.clone();
    longer.extend_from_slice(&[0xAA; 11]);
    assert_eq!(RadioSettings::parse(&longer).unwrap(), s);
}

#[test]
fn speed_codes_map_to_the_documented_rates() {
    for (code, rate) in [(0, Datarate::Rate250K), (1, Datarate::Rate1M), (2, Datarate::Rate2M)] {
        let s = RadioSettings::parse(&v1_block(80, code, 0.0, 0.0, 0xE7_E7E7_E7E7)).unwrap();
        assert_eq!(s.datarate, rate);
    }
    assert_eq!(
        RadioSettings::parse(&v1_block(80, 3, 0.0, 0.0, 0xE7_E7E7_E7E7)),
        Err(ConfigBlockError::BadDatarate(3))
    );
}

#[test]
fn a_v0_block_keeps_channel_and_rate_with_the_default_address() {
    let s = RadioSettings::parse(&v0_block(10, 0)).unwrap();
    assert_eq!(s.channel, 10);
    assert_eq!(s.datarate, Datarate::Rate250K);
    assert_eq!(s.address, 0xE7_E7E7_E7E7);
    assert_eq!(s.calib_pitch_deg, 1.5);
}

#[test]
fn bad_blocks_give_the_stock_defaults_and_a_reason() {
    let good = v1_block(42, 1, 0.0, 0.0, 0x12_3456_789A);
    let mut bad_sum = good.clone();
    bad_sum[20] = bad_sum[20].wrapping_add(1);
    let mut flipped = good.clone();
    flipped[6] ^= 0x01; // rate 1 → 0 without fixing the checksum
    let blank = vec![0xFF; 21];
    let cases: Vec<(Vec<u8>, ConfigBlockError)> = vec![
        (bad_sum, ConfigBlockError::BadChecksum),
        (flipped, ConfigBlockError::BadChecksum),
        (blank, ConfigBlockError::BadMagic),
        (vec![0; 21], ConfigBlockError::BadMagic),
        (good[..20].to_vec(), ConfigBlockError::TooShort),
        (good[..4].to_vec(), ConfigBlockError::TooShort),
        (Vec::new(), ConfigBlockError::TooShort),
        (v1_block(126, 2, 0.0, 0.0, 1), ConfigBlockError::BadChannel(126)),
    ];
    for (bytes, why) in cases {
        let (s, err) = RadioSettings::parse_or_default(&bytes);
        assert_eq!(err, Some(why), "{bytes:02X?}");
        assert_eq!(s.channel, 80);
        assert_eq!(s.datarate, Datarate::Rate2M);
        assert_eq!(s.address, 0xE7_E7E7_E7E7);
    }
    // Version 2 (a development layout) is not trusted.
    let mut v2 = good.clone();
    v2[4] = 2;
    assert_eq!(RadioSettings::parse(&v2), Err(ConfigBlockError::UnknownVersion(2)));
    // Channel 125 is the highest valid one.
    assert_eq!(
        RadioSettings::parse(&v1_block(125, 2, 0.0, 0.0, 1)).unwrap().channel,
        125
    );
}

#[test]
fn default_boot_packets_match_the_worked_frames() {
    let [channel, rate, address] = RadioSettings::DEFAULT.boot_packets().unwrap();
    // §3.2 worked example: RADIO_CHANNEL 80 = BC CF 01 01 50 52 55.
    assert_eq!(frame(&channel), vec![0xBC, 0xCF, 0x01, 0x01, 0x50, 0x52, 0x55]);
    // RADIO_DATARATE 2 Mbit/s: type 0x02, one byte 2.
    let body = [kind::RADIO_DATARATE, 1, 2];
    let ck = fletcher(&body);
    assert_eq!(frame(&rate), vec![0xBC, 0xCF, body[0], body[1], body[2], ck[0], ck[1]]);
    // RADIO_ADDRESS: five bytes little-endian.
    let body = [kind::RADIO_ADDRESS, 5, 0xE7, 0xE7, 0xE7, 0xE7, 0xE7];
    let ck = fletcher(&body);
    let mut expected = vec![0xBC, 0xCF];
    expected.extend_from_slice(&body);
    expected.extend_from_slice(&ck);
    assert_eq!(frame(&address), expected);
}

#[test]
fn parsed_settings_reach_the_boot_packets() {
    let s = RadioSettings::parse(&v1_block(7, 0, 0.0, 0.0, 0x01_0203_0405)).unwrap();
    let [channel, rate, address] = s.boot_packets().unwrap();
    assert_eq!(channel.payload.as_slice(), &[7]);
    assert_eq!(rate.payload.as_slice(), &[0]);
    assert_eq!(address.payload.as_slice(), &[0x05, 0x04, 0x03, 0x02, 0x01]);
}

#[test]
fn hand_built_out_of_range_settings_are_refused_not_sent() {
    let s = RadioSettings {
        channel: 200,
        ..RadioSettings::DEFAULT
    };
    assert!(s.boot_packets().is_err());
    let s = RadioSettings {
        address: 1 << 40,
        ..RadioSettings::DEFAULT
    };
    assert!(s.boot_packets().is_err());
}

#[test]
fn random_bytes_never_panic() {
    let mut x: u32 = 0x1234_5678;
    for _ in 0..20_000 {
        let mut b = [0u8; 21];
        for byte in &mut b {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *byte = x as u8;
        }
        // Half the cases get a valid magic so the later checks run.
        if x & 1 == 0 {
            b[..4].copy_from_slice(&[0x30, 0x78, 0x42, 0x43]);
            b[4] = (x >> 8) as u8 % 3;
        }
        let len = (x >> 16) as usize % 22;
        let (s, _) = RadioSettings::parse_or_default(&b[..len]);
        assert!(s.channel <= 125);
        assert!(s.address >> 40 == 0);
    }
}
