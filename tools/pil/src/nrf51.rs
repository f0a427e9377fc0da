//! The nRF51 end of the syslink: what the radio chip answers the image over USART6.
//!
//! Job: given each syslink packet the image sends and the virtual time, say what the nRF51 firmware sends
//! back; after PM_BATTERY_AUTOUPDATE, produce its periodic PM_BATTERY_STATE and RADIO_RSSI packets; forward
//! the radio host's packets to the image as RADIO_RAW once the image has sent RADIO_READY and hand the image's
//! RADIO_RAW replies to the radio host (the UDP bridge, `udp_bridge.rs`).
//! Non-goals: ESB timing, safelink (the nRF handles it alone; the image ignores header bits 2–3), one-wire
//! memories, power switching, P2P, BLE. Units: virtual time in ns.
//!
//! Facts (docs/hardware.md, from bitcraze/crazyflie2-nrf-firmware `src/main.c`):
//! * §3.3: RADIO_CHANNEL/DATARATE/ADDRESS/POWER are echoed; RADIO_READY is acknowledged with the same type
//!   (len 0) and the ESB receiver stays off until it arrives; SYS_NRF_VERSION is answered with a NUL-terminated
//!   "tag (platform)" string.
//! * §3.4 step 4 and §3.3 0x04/0x13: after PM_BATTERY_AUTOUPDATE the nRF sends PM_BATTERY_STATE and
//!   RADIO_RSSI every 10 ms (main.c L494-537), not before 1000 ms after its own boot
//!   (`SYSLINK_STARTUP_DELAY_TIME_MS`, interface/syslink.h L30-31). The nRF boots with the STM32 here (t = 0).
//! * §3.5: PM_BATTERY_STATE is 9 bytes: flags u8, VBAT f32 LE (V), ISET f32 LE (mA).
//! * §3.4 last paragraph: every ESB payload the host sends is forwarded as RADIO_RAW, null packets (0xFF)
//!   included, so the STM may answer each poll; the STM sends at most one RADIO_RAW per RADIO_RAW received
//!   and the nRF puts it in the next ESB ack.

use std::collections::VecDeque;

use cfnav::radio::crtp::is_null_header;
use cfnav::radio::syslink::{SyslinkPacket, kind};

/// The battery the emulated nRF reports: a charged 1S LiPo on the bench, not charging, no USB.
pub const VBAT_V: f32 = 4.0;
/// Period of the PM_BATTERY_STATE and RADIO_RSSI stream after PM_BATTERY_AUTOUPDATE (100 Hz).
pub const PM_PERIOD_NS: u64 = 10_000_000;
/// The nRF sends no PM stream before this long after its boot.
pub const PM_STARTUP_DELAY_NS: u64 = 1_000_000_000;
/// RSSI the nRF reports (u8, 40 ⇒ −40 dBm: a radio on the desk).
pub const RSSI: u8 = 40;
/// The version string the emulated nRF answers SYS_NRF_VERSION with (tag, then the platform).
pub const VERSION: &[u8] = b"pil (cf2)\0";

/// Counters for the report.
#[derive(Debug, Default, Clone, serde::Serialize)]
pub struct NrfStats {
    /// PM_BATTERY_STATE packets sent to the image.
    pub battery_packets: u64,
    /// RADIO_RSSI packets sent to the image.
    pub rssi_packets: u64,
    /// RADIO_RAW packets sent to the image (host packets and polls).
    pub radio_raw_up: u64,
    /// Of those, null polls (0xFF) generated because the host had nothing to send.
    pub null_polls: u64,
    /// RADIO_RAW packets received from the image.
    pub radio_raw_down: u64,
    /// Of those, non-null ones handed to the host.
    pub crtp_to_host: u64,
    /// Host packets dropped because the queue to the image was full.
    pub host_dropped: u64,
    /// SYS_NRF_VERSION requests answered.
    pub version_requests: u64,
    /// Virtual ms at which RADIO_READY arrived.
    pub radio_ready_at_ms: Option<u64>,
    /// Virtual ms at which PM_BATTERY_AUTOUPDATE arrived.
    pub autoupdate_at_ms: Option<u64>,
}

/// The nRF51's state as the image sees it.
#[derive(Debug)]
pub struct Nrf51 {
    /// Answer nothing at all (`--silent-nrf`).
    silent: bool,
    /// When the next PM packet pair is due, once the image asked for the stream.
    next_pm_ns: Option<u64>,
    radio_ready: bool,
    /// Host packets waiting for the ESB receiver (it is off until RADIO_READY).
    host_queue: VecDeque<Vec<u8>>,
    /// The battery voltage the PM packets carry, V ([`VBAT_V`] on the bench; the simulator's battery with
    /// `--world`/`--hover`).
    pub vbat_v: f32,
    /// Counters.
    pub stats: NrfStats,
}

/// The host queue's depth (ESB: the Crazyradio retries unacknowledged packets; cflib over UDP does not, so
/// packets sent before the receiver is on wait here instead of being lost).
const HOST_QUEUE: usize = 64;

impl Nrf51 {
    /// A freshly booted nRF; `silent` answers nothing.
    pub fn new(silent: bool) -> Self {
        Self {
            silent,
            next_pm_ns: None,
            radio_ready: false,
            host_queue: VecDeque::new(),
            vbat_v: VBAT_V,
            stats: NrfStats::default(),
        }
    }

    /// One packet from the image at `now_ns`: the packets the nRF sends back to the image, and the CRTP
    /// packet (`[header, data…]`) to hand to the radio host, if one.
    pub fn on_image_packet(&mut self, packet: &SyslinkPacket, now_ns: u64) -> (Vec<SyslinkPacket>, Option<Vec<u8>>) {
        if self.silent {
            return (Vec::new(), None);
        }
        let mut back = Vec::new();
        let mut to_host = None;
        match packet.kind {
            kind::RADIO_CHANNEL | kind::RADIO_DATARATE | kind::RADIO_ADDRESS | kind::RADIO_POWER => {
                back.extend(SyslinkPacket::new(packet.kind, &packet.payload).ok());
            }
            kind::RADIO_READY => {
                if !self.radio_ready {
                    self.stats.radio_ready_at_ms = Some(now_ns / 1_000_000);
                }
                self.radio_ready = true;
                back.extend(SyslinkPacket::new(kind::RADIO_READY, &[]).ok());
            }
            kind::PM_BATTERY_AUTOUPDATE if self.next_pm_ns.is_none() => {
                self.stats.autoupdate_at_ms = Some(now_ns / 1_000_000);
                self.next_pm_ns = Some(now_ns.max(PM_STARTUP_DELAY_NS));
            }
            kind::SYS_NRF_VERSION => {
                self.stats.version_requests += 1;
                back.extend(SyslinkPacket::new(kind::SYS_NRF_VERSION, VERSION).ok());
            }
            kind::RADIO_RAW => {
                self.stats.radio_raw_down += 1;
                let p = &packet.payload;
                // An empty payload or a lone null header is an empty ack: nothing for the host.
                if let Some(&header) = p.first()
                    && !(p.len() == 1 && is_null_header(header))
                {
                    self.stats.crtp_to_host += 1;
                    to_host = Some(p.to_vec());
                }
            }
            _ => {}
        }
        (back, to_host)
    }

    /// A CRTP packet from the radio host, to be forwarded once the receiver is on. Returns false when dropped.
    pub fn host_packet(&mut self, crtp: &[u8]) -> bool {
        if self.host_queue.len() >= HOST_QUEUE || crtp.is_empty() || crtp.len() > 31 {
            self.stats.host_dropped += 1;
            return false;
        }
        self.host_queue.push_back(crtp.to_vec());
        true
    }

    /// The packets the nRF sends on its own at `now_ns` (called once per host slice): the PM stream when due,
    /// and one RADIO_RAW per slice when the receiver is on and `host_polling` (a host is connected): the
    /// host's next packet, or a null poll (0xFF) as cflib's radio driver sends when it has nothing.
    pub fn tick(&mut self, now_ns: u64, host_polling: bool) -> Vec<SyslinkPacket> {
        let mut out = Vec::new();
        if self.silent {
            return out;
        }
        if let Some(due) = self.next_pm_ns
            && now_ns >= due
        {
            let mut state = [0u8; 9];
            state[1..5].copy_from_slice(&self.vbat_v.to_le_bytes());
            state[5..9].copy_from_slice(&0.0f32.to_le_bytes());
            out.extend(SyslinkPacket::new(kind::PM_BATTERY_STATE, &state).ok());
            out.extend(SyslinkPacket::new(kind::RADIO_RSSI, &[RSSI]).ok());
            self.stats.battery_packets += 1;
            self.stats.rssi_packets += 1;
            // Catch up without a burst if the caller's slices are coarser than the period.
            let mut next = due + PM_PERIOD_NS;
            while next <= now_ns {
                next += PM_PERIOD_NS;
            }
            self.next_pm_ns = Some(next);
        }
        if self.radio_ready {
            if let Some(p) = self.host_queue.pop_front() {
                out.extend(SyslinkPacket::radio_raw(&p).ok());
                self.stats.radio_raw_up += 1;
            } else if host_polling {
                out.extend(SyslinkPacket::radio_raw(&[0xFF]).ok());
                self.stats.radio_raw_up += 1;
                self.stats.null_polls += 1;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pkt(k: u8, p: &[u8]) -> SyslinkPacket {
        SyslinkPacket::new(k, p).unwrap()
    }

    #[test]
    fn pm_stream_starts_after_autoupdate_and_startup_delay_at_100_hz() {
        let mut n = Nrf51::new(false);
        assert!(n.tick(1_500_000_000, false).is_empty(), "no stream before AUTOUPDATE");
        let mut n = Nrf51::new(false);
        n.on_image_packet(&pkt(kind::PM_BATTERY_AUTOUPDATE, &[]), 200_000_000);
        let mut count = 0;
        let mut first = None;
        for ms in 200..2000u64 {
            for p in n.tick(ms * 1_000_000, false) {
                if p.kind == kind::PM_BATTERY_STATE {
                    first.get_or_insert(ms);
                    count += 1;
                    assert_eq!(p.payload.len(), 9);
                    let v = f32::from_le_bytes(p.payload[1..5].try_into().unwrap());
                    assert_eq!(v, VBAT_V);
                }
            }
        }
        assert_eq!(first, Some(1000));
        assert_eq!(count, 100, "1000..2000 ms at 100 Hz");
    }

    #[test]
    fn host_packets_wait_for_radio_ready_then_one_per_tick_then_null_polls() {
        let mut n = Nrf51::new(false);
        assert!(n.host_packet(&[0x5C, 0x03]));
        assert!(n.host_packet(&[0x2C, 0x03]));
        assert!(n.tick(1_000_000, true).is_empty(), "receiver off before RADIO_READY");
        let (back, _) = n.on_image_packet(&pkt(kind::RADIO_READY, &[]), 2_000_000);
        assert_eq!(back[0].kind, kind::RADIO_READY);
        let a = n.tick(3_000_000, true);
        let b = n.tick(4_000_000, true);
        let c = n.tick(5_000_000, true);
        let d = n.tick(6_000_000, false);
        assert_eq!(&a[0].payload[..], &[0x5C, 0x03]);
        assert_eq!(&b[0].payload[..], &[0x2C, 0x03]);
        assert_eq!(&c[0].payload[..], &[0xFF]);
        assert!(d.is_empty(), "no polls without a host");
    }

    #[test]
    fn image_radio_raw_goes_to_host_unless_empty_ack() {
        let mut n = Nrf51::new(false);
        let (_, h) = n.on_image_packet(&pkt(kind::RADIO_RAW, &[0x5C, 3, 1]), 0);
        assert_eq!(h, Some(vec![0x5C, 3, 1]));
        assert_eq!(n.on_image_packet(&pkt(kind::RADIO_RAW, &[0xF3]), 0).1, None);
        assert_eq!(n.on_image_packet(&pkt(kind::RADIO_RAW, &[]), 0).1, None);
        let (back, _) = n.on_image_packet(&pkt(kind::SYS_NRF_VERSION, &[]), 0);
        assert_eq!(&back[0].payload[..], VERSION);
        let (back, _) = n.on_image_packet(&pkt(kind::RADIO_CHANNEL, &[80]), 0);
        assert_eq!(&back[0].payload[..], &[80]);
    }

    #[test]
    fn silent_nrf_answers_nothing() {
        let mut n = Nrf51::new(true);
        assert!(n.on_image_packet(&pkt(kind::RADIO_READY, &[]), 0).0.is_empty());
        n.on_image_packet(&pkt(kind::PM_BATTERY_AUTOUPDATE, &[]), 0);
        assert!(n.tick(2_000_000_000, true).is_empty());
    }
}
