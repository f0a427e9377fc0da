//! Syslink: the framed UART protocol between the STM32 and the nRF51 radio chip.
//!
//! Job: encode [`SyslinkPacket`]s into frames, decode a byte stream into packets with [`SyslinkDecoder`]
//! (resynchronising after garbage without losing a following good frame), build the packets the STM32 sends
//! at boot, and parse the nRF's `PM_BATTERY_STATE` report.
//!
//! Non-goals: no UART, DMA or TXEN flow-control handling (the caller moves bytes); no policy on when to send
//! what (the "one RADIO_RAW down per RADIO_RAW up" rule is kept by [`super::crtp::Router`]).
//!
//! Sources (`docs/hardware.md` §4, syslink):
//! * frame format: `BC CF TYPE LEN DATA… CK_A CK_B`, `LEN ≤ 64`, 8-bit Fletcher checksum over
//!   TYPE, LEN and DATA (`A += byte; B += A`, both mod 256); worked examples RADIO_READY = `BC CF 0B 00 0B 16`,
//!   PM_BATTERY_AUTOUPDATE = `BC CF 14 00 14 28`, RADIO_CHANNEL 80 = `BC CF 01 01 50 52 55`.
//! * packet type numbers and payloads; the stock boot order; the PM_BATTERY_STATE payload.
//!
//! Memory: a packet is 66 bytes; the decoder holds one 70-byte frame buffer plus counters.

use heapless::Vec;

/// First start byte of every frame.
pub const START1: u8 = 0xBC;
/// Second start byte of every frame.
pub const START2: u8 = 0xCF;
/// Largest payload (`SYSLINK_MTU`).
pub const MTU: usize = 64;
/// Largest whole frame: 2 start bytes, type, length, payload, 2 checksum bytes.
pub const MAX_FRAME: usize = 4 + MTU + 2;

/// Packet type numbers (`docs/hardware.md` §4, identical in the STM32 and nRF firmwares).
pub mod kind {
    /// Raw ESB payload: CRTP header byte + ≤ 30 data bytes.
    pub const RADIO_RAW: u8 = 0x00;
    /// Radio channel, u8 0–125 (2400 + ch MHz); echoed by the nRF.
    pub const RADIO_CHANNEL: u8 = 0x01;
    /// Radio data rate, u8 0 = 250K, 1 = 1M, 2 = 2M; echoed.
    pub const RADIO_DATARATE: u8 = 0x02;
    /// Continuous-wave test mode, u8 enable; echoed.
    pub const RADIO_CONTWAVE: u8 = 0x03;
    /// Received signal strength, u8 (40–100 ⇒ −40…−100 dBm).
    pub const RADIO_RSSI: u8 = 0x04;
    /// Radio address, 5 bytes little-endian; echoed.
    pub const RADIO_ADDRESS: u8 = 0x05;
    /// Broadcast ESB payload; no reply allowed.
    pub const RADIO_RAW_BROADCAST: u8 = 0x06;
    /// Radio power, i8 dBm; echoed.
    pub const RADIO_POWER: u8 = 0x07;
    /// Peer-to-peer packet: port, rssi, data.
    pub const RADIO_P2P: u8 = 0x08;
    /// Reserved.
    pub const RADIO_P2P_ACK: u8 = 0x09;
    /// Peer-to-peer broadcast.
    pub const RADIO_P2P_BROADCAST: u8 = 0x0A;
    /// The STM32 is ready: the nRF switches its ESB receiver on and acks with the same type.
    pub const RADIO_READY: u8 = 0x0B;
    /// Unused.
    pub const PM_SOURCE: u8 = 0x10;
    /// The nRF powers everything off.
    pub const PM_ONOFF_SWITCHOFF: u8 = 0x11;
    /// Unused (the voltage is in [`PM_BATTERY_STATE`]).
    pub const PM_BATTERY_VOLTAGE: u8 = 0x12;
    /// Battery report, see [`super::BatteryState`].
    pub const PM_BATTERY_STATE: u8 = 0x13;
    /// Enables the 100 Hz PM_BATTERY_STATE and RADIO_RSSI streams.
    pub const PM_BATTERY_AUTOUPDATE: u8 = 0x14;
    /// Button short-press; the STM32 must answer [`PM_SHUTDOWN_ACK`] within 100 ms.
    pub const PM_SHUTDOWN_REQUEST: u8 = 0x15;
    /// Answer to [`PM_SHUTDOWN_REQUEST`].
    pub const PM_SHUTDOWN_ACK: u8 = 0x16;
    /// Blue LED on.
    pub const PM_LED_ON: u8 = 0x17;
    /// Blue LED off.
    pub const PM_LED_OFF: u8 = 0x18;
    /// Deck controller DFU.
    pub const PM_DECKCTRL_DFU: u8 = 0x19;
    /// The nRF enters its "sys off" state.
    pub const PM_ONOFF_STM_OFF: u8 = 0x1A;
    /// One-wire scan.
    pub const OW_SCAN: u8 = 0x20;
    /// One-wire memory info.
    pub const OW_GETINFO: u8 = 0x21;
    /// One-wire read.
    pub const OW_READ: u8 = 0x22;
    /// One-wire write.
    pub const OW_WRITE: u8 = 0x23;
    /// nRF firmware version string.
    pub const SYS_NRF_VERSION: u8 = 0x30;
    /// nRF debug counters.
    pub const DEBUG_PROBE: u8 = 0xF0;
}

/// Why a packet could not be built or encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncodeError {
    /// The output buffer is shorter than the frame (`needed` bytes).
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
    },
    /// The payload is longer than [`MTU`].
    PayloadTooLong,
    /// An argument is outside the range `docs/hardware.md` §4 allows (channel > 125, address wider than 40 bits).
    OutOfRange,
}

/// Why a candidate frame was rejected; the decoder has already resynchronised when it reports one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeError {
    /// The length byte exceeded [`MTU`] (the stock receiver resyncs too).
    Oversized(u8),
    /// The two checksum bytes did not match the frame.
    BadChecksum,
}

/// One syslink packet: a type number (see [`kind`]) and up to [`MTU`] payload bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SyslinkPacket {
    /// Packet type.
    pub kind: u8,
    /// Payload, little-endian multi-byte values.
    pub payload: Vec<u8, MTU>,
}

/// Radio data rates for [`SyslinkPacket::radio_datarate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Datarate {
    /// 250 kbit/s.
    Rate250K = 0,
    /// 1 Mbit/s.
    Rate1M = 1,
    /// 2 Mbit/s (nRF default).
    Rate2M = 2,
}

impl SyslinkPacket {
    /// A packet of type `kind` carrying `payload`.
    pub fn new(kind: u8, payload: &[u8]) -> Result<Self, EncodeError> {
        let payload = Vec::from_slice(payload).map_err(|_| EncodeError::PayloadTooLong)?;
        Ok(Self { kind, payload })
    }

    fn empty(kind: u8) -> Self {
        Self {
            kind,
            payload: Vec::new(),
        }
    }

    /// RADIO_RAW carrying one CRTP packet on air (header + ≤ 30 bytes).
    pub fn radio_raw(crtp: &[u8]) -> Result<Self, EncodeError> {
        Self::new(kind::RADIO_RAW, crtp)
    }

    /// RADIO_CHANNEL (boot step 1); `channel` must be 0–125.
    pub fn radio_channel(channel: u8) -> Result<Self, EncodeError> {
        if channel > 125 {
            return Err(EncodeError::OutOfRange);
        }
        Self::new(kind::RADIO_CHANNEL, &[channel])
    }

    /// RADIO_DATARATE (boot step 1).
    pub fn radio_datarate(rate: Datarate) -> Self {
        let mut p = Self::empty(kind::RADIO_DATARATE);
        // One byte always fits in an empty 64-byte vector.
        let _ = p.payload.push(rate as u8);
        p
    }

    /// RADIO_ADDRESS (boot step 1): 5 bytes little-endian; `address` must fit in 40 bits
    /// (default 0xE7E7E7E7E7).
    pub fn radio_address(address: u64) -> Result<Self, EncodeError> {
        if address >> 40 != 0 {
            return Err(EncodeError::OutOfRange);
        }
        let bytes = address.to_le_bytes();
        Self::new(kind::RADIO_ADDRESS, &bytes[..5])
    }

    /// RADIO_READY (boot step 5): no payload.
    pub fn radio_ready() -> Self {
        Self::empty(kind::RADIO_READY)
    }

    /// PM_BATTERY_AUTOUPDATE (boot step 4): no payload.
    pub fn pm_battery_autoupdate() -> Self {
        Self::empty(kind::PM_BATTERY_AUTOUPDATE)
    }

    /// PM_SHUTDOWN_ACK, the answer to PM_SHUTDOWN_REQUEST: no payload.
    pub fn pm_shutdown_ack() -> Self {
        Self::empty(kind::PM_SHUTDOWN_ACK)
    }

    /// Length of this packet's frame on the wire.
    pub fn frame_len(&self) -> usize {
        self.payload.len() + 6
    }
}

/// The syslink checksum of a frame body (`TYPE, LEN, DATA…`): 8-bit Fletcher, `A += byte; B += A`, mod 256.
pub fn checksum(body: &[u8]) -> [u8; 2] {
    let (mut a, mut b) = (0u8, 0u8);
    for &byte in body {
        a = a.wrapping_add(byte);
        b = b.wrapping_add(a);
    }
    [a, b]
}

/// Writes `packet` as one frame into `out` and returns the frame length.
pub fn encode(packet: &SyslinkPacket, out: &mut [u8]) -> Result<usize, EncodeError> {
    let n = packet.payload.len();
    let needed = n + 6;
    let Some(frame) = out.get_mut(..needed) else {
        return Err(EncodeError::BufferTooSmall { needed });
    };
    frame[0] = START1;
    frame[1] = START2;
    frame[2] = packet.kind;
    // The payload vector holds at most 64 bytes, so its length fits in a u8.
    frame[3] = n as u8;
    frame[4..4 + n].copy_from_slice(&packet.payload);
    let ck = checksum(&frame[2..4 + n]);
    frame[4 + n..needed].copy_from_slice(&ck);
    Ok(needed)
}

/// Counters kept by [`SyslinkDecoder`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DecodeStats {
    /// Good packets delivered.
    pub packets: u32,
    /// Bytes dropped while hunting for `BC CF`.
    pub skipped_bytes: u32,
    /// Frames rejected for a length byte above [`MTU`].
    pub oversized: u32,
    /// Frames rejected for a checksum mismatch.
    pub bad_checksum: u32,
}

/// Byte-by-byte syslink receiver.
///
/// The frame being assembled always starts at `buf[0]`. When a candidate frame fails (length above the MTU
/// or a checksum mismatch), only its first byte is discarded and the rest is re-examined, so a good frame
/// hidden inside a bad candidate (for example after a truncated frame) is still found. Because one input
/// byte can therefore complete several events, [`push`](Self::push) returns the first and
/// [`poll`](Self::poll) returns the rest; call `poll` until it returns `None` after each `push`.
#[derive(Debug, Clone)]
pub struct SyslinkDecoder {
    buf: [u8; MAX_FRAME],
    /// Bytes held in `buf`.
    len: usize,
    /// Bytes of `buf` the parser has examined (always ≤ `len`).
    pos: usize,
    stats: DecodeStats,
}

impl Default for SyslinkDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl SyslinkDecoder {
    /// An empty decoder hunting for a start byte.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_FRAME],
            len: 0,
            pos: 0,
            stats: DecodeStats {
                packets: 0,
                skipped_bytes: 0,
                oversized: 0,
                bad_checksum: 0,
            },
        }
    }

    /// The error and packet counters.
    pub fn stats(&self) -> DecodeStats {
        self.stats
    }

    /// Feeds one received byte; returns a packet or a rejected frame if one completes.
    pub fn push(&mut self, byte: u8) -> Option<Result<SyslinkPacket, DecodeError>> {
        let mut early = None;
        if self.len == MAX_FRAME {
            // Only reachable if the caller skipped `poll`: work through the backlog first.
            early = self.step();
        }
        if self.len == MAX_FRAME {
            // Cannot happen (a full buffer always completes a frame), but stay total.
            self.drop_front(1);
            self.stats.skipped_bytes = self.stats.skipped_bytes.saturating_add(1);
        }
        self.buf[self.len] = byte;
        self.len += 1;
        match early {
            Some(event) => Some(event),
            None => self.step(),
        }
    }

    /// Returns the next event already held in the buffer, if any (see the type's documentation).
    pub fn poll(&mut self) -> Option<Result<SyslinkPacket, DecodeError>> {
        self.step()
    }

    fn drop_front(&mut self, n: usize) {
        let n = n.min(self.len);
        self.buf.copy_within(n..self.len, 0);
        self.len -= n;
        self.pos = 0;
    }

    fn step(&mut self) -> Option<Result<SyslinkPacket, DecodeError>> {
        while self.pos < self.len {
            let byte = self.buf[self.pos];
            match self.pos {
                0 => {
                    if byte == START1 {
                        self.pos = 1;
                    } else {
                        self.drop_front(1);
                        self.stats.skipped_bytes = self.stats.skipped_bytes.saturating_add(1);
                    }
                }
                1 => {
                    if byte == START2 {
                        self.pos = 2;
                    } else {
                        self.drop_front(1);
                        self.stats.skipped_bytes = self.stats.skipped_bytes.saturating_add(1);
                    }
                }
                2 => self.pos = 3,
                3 => {
                    if usize::from(byte) > MTU {
                        self.drop_front(1);
                        self.stats.oversized = self.stats.oversized.saturating_add(1);
                        return Some(Err(DecodeError::Oversized(byte)));
                    }
                    self.pos = 4;
                }
                p => {
                    let n = usize::from(self.buf[3]);
                    if p < n + 5 {
                        self.pos += 1;
                        continue;
                    }
                    let ck = checksum(&self.buf[2..4 + n]);
                    if ck != [self.buf[4 + n], self.buf[5 + n]] {
                        self.drop_front(1);
                        self.stats.bad_checksum = self.stats.bad_checksum.saturating_add(1);
                        return Some(Err(DecodeError::BadChecksum));
                    }
                    let mut payload = Vec::new();
                    // n ≤ MTU was checked at the length byte, so this cannot fail.
                    let _ = payload.extend_from_slice(&self.buf[4..4 + n]);
                    let packet = SyslinkPacket {
                        kind: self.buf[2],
                        payload,
                    };
                    self.drop_front(n + 6);
                    self.stats.packets = self.stats.packets.saturating_add(1);
                    return Some(Ok(packet));
                }
            }
        }
        None
    }
}

/// The nRF's battery report (PM_BATTERY_STATE).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatteryState {
    /// Raw flag byte.
    pub flags: u8,
    /// Flag bit 0: charging.
    pub charging: bool,
    /// Flag bit 1: USB powered.
    pub usb_powered: bool,
    /// Flag bit 2: can charge.
    pub can_charge: bool,
    /// Battery voltage, V.
    pub vbat: f32,
    /// Charge current setting, mA.
    pub iset_ma: f32,
    /// Temperature, only sent by nRF builds with `PM_SYSLINK_INCLUDE_TEMP` (payload length 13).
    pub temperature: Option<f32>,
}

/// Why a PM_BATTERY_STATE payload was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BatteryError {
    /// The packet is not of type PM_BATTERY_STATE.
    WrongKind,
    /// The payload is shorter than the 9 bytes `docs/hardware.md` §4 requires.
    TooShort,
}

fn f32_at(bytes: &[u8], at: usize) -> Option<f32> {
    let b = bytes.get(at..at + 4)?;
    Some(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

impl BatteryState {
    /// Parses a PM_BATTERY_STATE packet: flags u8, VBAT f32 LE, ISET f32 LE, optional temperature f32 LE.
    pub fn parse(packet: &SyslinkPacket) -> Result<Self, BatteryError> {
        if packet.kind != kind::PM_BATTERY_STATE {
            return Err(BatteryError::WrongKind);
        }
        let p = &packet.payload;
        let (Some(&flags), Some(vbat), Some(iset_ma)) = (p.first(), f32_at(p, 1), f32_at(p, 5)) else {
            return Err(BatteryError::TooShort);
        };
        Ok(Self {
            flags,
            charging: flags & 0x01 != 0,
            usb_powered: flags & 0x02 != 0,
            can_charge: flags & 0x04 != 0,
            vbat,
            iset_ma,
            temperature: f32_at(p, 9),
        })
    }
}
