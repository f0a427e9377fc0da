//! CRTP: the packet layer cflib speaks, a reply router, and the link (15) and platform (13) services.
//!
//! Job: parse and build CRTP packets (one header byte + ≤ 30 data bytes), dispatch each uplink packet to the
//! service owning its port, and hand back at most one downlink packet per uplink packet.
//!
//! Non-goals: no transport (syslink RADIO_RAW or UDP datagrams are the caller's), no log, parameter, memory or
//! supervisor protocol (plug them in through [`Service`]), no continuous-wave test mode.
//!
//! Sources:
//! * `docs/hardware.md` §4, header: port bits 7..4, link-layer bits 3..2 (cflib sets both, `0x0C`),
//!   channel bits 1..0; max 30 data bytes; null packet `header & 0xF3 == 0xF3`; protocol version 12.
//! * `docs/hardware.md` §4: the nRF may send one RADIO_RAW only after receiving one ("one downlink per uplink"), host
//!   null packets are forwarded so the STM32 can answer on every poll; the STM32 may ignore bits 2–3.
//! * `docs/hardware.md` §4, link port 15: ch0 echo unchanged, ch1 source = 30 bytes "Bitcraze Crazyflie" + 12 zeros, ch2 sink
//!   (no reply), ch3 null (drop).
//! * `docs/hardware.md` §4, platform port 13, ch1: `[0]` → `[0, version i32 LE]` (5 bytes), `[1]` → `[1, ASCII tag]`,
//!   `[2]` → `[2, ASCII device type name]` (stock "Crazyflie 2.1").
//! * `docs/radio.md` (header bits, `(h & 0xF3) == 0xF3`; the first connection steps and their trace:
//!   `FD [00]` → 15/1 "Bitcraze Crazyflie"+12×00; `DD [00]` → 13/1 `[00 0C 00 00 00]`).
//! * `docs/radio.md`: report protocol version 12.
//!
//! Design choices not fixed by the references: requests this module does not know (other ports without a
//! registered service, platform channels 0 and 2, unknown version commands, empty version requests) get no
//! reply; downlink headers carry bits 2–3 set (`0x0C`, as cflib builds its packets, `docs/hardware.md` §4) — cflib ORs them in
//! on receipt anyway and crazyflie-lib masks them off.
//!
//! Memory: a packet is 33 bytes; the router holds a `Q`-deep reply queue of packets plus counters.

use heapless::{Deque, Vec};

/// Largest CRTP payload (`CRTP_MAX_DATA_SIZE`).
pub const MAX_DATA: usize = 30;
/// Largest packet on the wire: header + payload.
pub const MAX_PACKET: usize = MAX_DATA + 1;
/// The link-layer bits 3..2 this firmware sets on every downlink header.
pub const LINK_BITS: u8 = 0x0C;
/// The host's bare null packet (port 15, channel 3, bits 2–3 set); a UDP transport answers it so that cflib's
/// scan finds the drone (`docs/radio.md`).
pub const NULL_HEADER: u8 = 0xFF;
/// `CRTP_PROTOCOL_VERSION` (§4.1; `docs/radio.md`).
pub const PROTOCOL_VERSION: i32 = 12;

/// Link port.
pub const PORT_LINK: u8 = 15;
/// Platform port.
pub const PORT_PLATFORM: u8 = 13;

/// True if `header` is a null packet (`header & 0xF3 == 0xF3`, port 15 channel 3).
pub const fn is_null_header(header: u8) -> bool {
    header & 0xF3 == 0xF3
}

/// Why bytes are not a CRTP packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CrtpError {
    /// Zero bytes: there is no header.
    Empty,
    /// More than 31 bytes (header + 30).
    TooLong(usize),
    /// A null packet (port 15, channel 3): valid on the wire, but carries nothing to dispatch.
    Null,
    /// Port above 15, channel above 3 or more than 30 data bytes given to [`CrtpPacket::new`].
    OutOfRange,
}

/// One CRTP packet.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CrtpPacket {
    /// Port, 0–15.
    pub port: u8,
    /// Channel, 0–3.
    pub channel: u8,
    /// Payload, ≤ 30 bytes.
    pub data: Vec<u8, MAX_DATA>,
}

impl CrtpPacket {
    /// A packet for `port` (0–15) and `channel` (0–3) carrying `data` (≤ 30 bytes).
    pub fn new(port: u8, channel: u8, data: &[u8]) -> Result<Self, CrtpError> {
        if port > 15 || channel > 3 {
            return Err(CrtpError::OutOfRange);
        }
        let data = Vec::from_slice(data).map_err(|_| CrtpError::OutOfRange)?;
        Ok(Self { port, channel, data })
    }

    /// Parses one packet as it arrives (syslink RADIO_RAW payload or one UDP datagram); header bits 2–3 are
    /// ignored.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, CrtpError> {
        let Some((&header, data)) = bytes.split_first() else {
            return Err(CrtpError::Empty);
        };
        if bytes.len() > MAX_PACKET {
            return Err(CrtpError::TooLong(bytes.len()));
        }
        if is_null_header(header) {
            return Err(CrtpError::Null);
        }
        let data = Vec::from_slice(data).map_err(|_| CrtpError::TooLong(bytes.len()))?;
        Ok(Self {
            port: header >> 4,
            channel: header & 0x03,
            data,
        })
    }

    /// The header byte: `port << 4 | 0x0C | channel` (out-of-range fields are masked).
    pub fn header(&self) -> u8 {
        ((self.port & 0x0F) << 4) | LINK_BITS | (self.channel & 0x03)
    }

    /// Writes header + data into `out` and returns the length used.
    pub fn to_bytes(&self, out: &mut [u8; 32]) -> usize {
        out[0] = self.header();
        let n = self.data.len();
        out[1..1 + n].copy_from_slice(&self.data);
        n + 1
    }
}

/// A CRTP service owning one port.
pub trait Service {
    /// The port this service answers.
    fn port(&self) -> u8;
    /// Handles one packet addressed to [`port`](Self::port); returns the reply, if any.
    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket>;
}

/// The link service, port 15.
#[derive(Debug, Clone, Copy, Default)]
pub struct LinkService;

/// The 30-byte link-source reply: "Bitcraze Crazyflie" then 12 zeros.
pub const LINK_SOURCE_REPLY: [u8; MAX_DATA] = {
    let magic = *b"Bitcraze Crazyflie";
    let mut out = [0u8; MAX_DATA];
    let mut i = 0;
    while i < magic.len() {
        out[i] = magic[i];
        i += 1;
    }
    out
};

impl Service for LinkService {
    fn port(&self) -> u8 {
        PORT_LINK
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        match packet.channel {
            0 => Some(packet.clone()),
            1 => CrtpPacket::new(PORT_LINK, 1, &LINK_SOURCE_REPLY).ok(),
            _ => None,
        }
    }
}

/// The platform service, port 13: version channel 1 only.
#[derive(Debug, Clone, Copy)]
pub struct PlatformService {
    firmware_version: &'static str,
    device_type_name: &'static str,
}

/// Device type name the stock firmware reports for a Crazyflie 2.1 (`docs/hardware.md` §4 example).
pub const DEVICE_TYPE_NAME: &str = "Crazyflie 2.1";

impl PlatformService {
    /// A platform service reporting `firmware_version` (an ASCII tag, truncated to 29 bytes) and the stock
    /// device type name [`DEVICE_TYPE_NAME`].
    pub const fn new(firmware_version: &'static str) -> Self {
        Self {
            firmware_version,
            device_type_name: DEVICE_TYPE_NAME,
        }
    }

    fn string_reply(cmd: u8, text: &str) -> Option<CrtpPacket> {
        let mut data: Vec<u8, MAX_DATA> = Vec::new();
        data.push(cmd).ok()?;
        let bytes = text.as_bytes();
        let n = bytes.len().min(MAX_DATA - 1);
        data.extend_from_slice(&bytes[..n]).ok()?;
        Some(CrtpPacket {
            port: PORT_PLATFORM,
            channel: 1,
            data,
        })
    }
}

impl Service for PlatformService {
    fn port(&self) -> u8 {
        PORT_PLATFORM
    }

    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        if packet.channel != 1 {
            return None;
        }
        match packet.data.first()? {
            0 => {
                let v = PROTOCOL_VERSION.to_le_bytes();
                CrtpPacket::new(PORT_PLATFORM, 1, &[0, v[0], v[1], v[2], v[3]]).ok()
            }
            1 => Self::string_reply(1, self.firmware_version),
            2 => Self::string_reply(2, self.device_type_name),
            _ => None,
        }
    }
}

/// Counters kept by [`Router`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RouterStats {
    /// Packets dispatched to a service.
    pub dispatched: u32,
    /// Null packets received.
    pub null: u32,
    /// Empty or over-long uplinks.
    pub malformed: u32,
    /// Packets for a port with no service.
    pub unknown_port: u32,
    /// Replies or queued packets dropped because the queue was full.
    pub dropped: u32,
}

/// Dispatches uplink packets and releases at most one downlink packet per uplink packet (`docs/hardware.md` §4: the nRF may
/// send one RADIO_RAW only after receiving one; null packets count as uplinks).
///
/// Replies and packets [`enqueue`](Self::enqueue)d by other code (console, log data) wait in a FIFO of `Q`.
#[derive(Debug, Clone)]
pub struct Router<const Q: usize> {
    link: LinkService,
    platform: PlatformService,
    queue: Deque<CrtpPacket, Q>,
    stats: RouterStats,
}

impl<const Q: usize> Router<Q> {
    /// A router with the link service and `platform`, and an empty queue.
    pub fn new(platform: PlatformService) -> Self {
        Self {
            link: LinkService,
            platform,
            queue: Deque::new(),
            stats: RouterStats::default(),
        }
    }

    /// The counters.
    pub fn stats(&self) -> RouterStats {
        self.stats
    }

    /// Packets waiting for an uplink to carry them down.
    pub fn pending(&self) -> usize {
        self.queue.len()
    }

    /// Queues a downlink packet not caused by a request; gives it back if the queue is full.
    pub fn enqueue(&mut self, packet: CrtpPacket) -> Result<(), CrtpPacket> {
        self.queue
            .push_back(packet)
            .inspect_err(|_| self.stats.dropped = self.stats.dropped.saturating_add(1))
    }

    /// Handles one uplink packet's bytes. Port 15 and 13 go to the built-in services, other ports to the first
    /// of `services` owning them. Returns the one downlink packet this uplink may carry, if any is waiting.
    pub fn handle_uplink(&mut self, bytes: &[u8], services: &mut [&mut dyn Service]) -> Option<CrtpPacket> {
        match CrtpPacket::from_bytes(bytes) {
            Ok(packet) => {
                let reply = match packet.port {
                    PORT_LINK => Some(self.link.handle(&packet)),
                    PORT_PLATFORM => Some(self.platform.handle(&packet)),
                    port => services
                        .iter_mut()
                        .find(|s| s.port() == port)
                        .map(|s| s.handle(&packet)),
                };
                match reply {
                    Some(reply) => {
                        self.stats.dispatched = self.stats.dispatched.saturating_add(1);
                        if let Some(reply) = reply {
                            let _ = self.enqueue(reply);
                        }
                    }
                    None => self.stats.unknown_port = self.stats.unknown_port.saturating_add(1),
                }
            }
            Err(CrtpError::Null) => self.stats.null = self.stats.null.saturating_add(1),
            Err(_) => self.stats.malformed = self.stats.malformed.saturating_add(1),
        }
        self.queue.pop_front()
    }
}
