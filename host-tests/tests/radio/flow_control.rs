//! The syslink transmitter against a model of the nRF51's receive side, the boot-setting echoes and the nRF
//! version reply.
//!
//! The model (the oracle, written from the nRF51 Series Reference Manual v3.0, UART: a 6-byte RX FIFO; with
//! hardware flow control RTS is deactivated while the FIFO can take only four more bytes; a byte arriving on
//! a full FIFO is lost, an overrun) and from crazyflie2-nrf-firmware `src/uart.c` (an interrupt drains the
//! FIFO, one byte per microsecond here, except while the SoftDevice runs a Bluetooth event and holds it
//! off). The STM32 side sends one byte per 10 µs (1 Mbaud 8N1), checks PA4 (= the nRF's RTS) when
//! [`FlowTx`] asks, and, as the firmware does, waits for the transmission to complete plus a few µs of
//! software latency before the next check.

use cfnav::radio::syslink::{MAX_FRAME, SyslinkDecoder, SyslinkPacket, kind};
use cfnav::radio::syslink_tx::{
    BootSettings, CHUNK, ECHO_TIMEOUT_MS, FlowTx, MAX_SENDS, SettingState, TxStep, nrf_version, nrf_version_request,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// The nRF51 UART's hardware RX FIFO, bytes.
const NRF_FIFO: usize = 6;
/// RTS is deactivated when this many bytes (or fewer) still fit.
const RTS_ROOM: usize = 4;
/// One byte on the wire at 1 Mbaud 8N1, µs.
const BYTE_US: u64 = 10;
/// The STM32's software latency from "transmission complete" to the next PA4 check, µs.
const CHECK_LATENCY_US: u64 = 3;

/// The nRF's receive side, stepped in µs.
struct Nrf {
    fifo: usize,
    /// Time of the last drain, µs.
    drained_at: u64,
    /// Windows [start, end) in which the receive interrupt cannot run, µs.
    blocked: Vec<(u64, u64)>,
    received: Vec<u8>,
    overruns: usize,
    fifo_high_water: usize,
}

impl Nrf {
    fn new(blocked: Vec<(u64, u64)>) -> Self {
        Self {
            fifo: 0,
            drained_at: 0,
            blocked,
            received: Vec::new(),
            overruns: 0,
            fifo_high_water: 0,
        }
    }

    fn is_blocked(&self, t: u64) -> bool {
        self.blocked.iter().any(|&(a, b)| (a..b).contains(&t))
    }

    /// Runs the drain interrupt up to `t` (one byte per µs while not blocked).
    fn advance(&mut self, t: u64) {
        while self.drained_at < t {
            self.drained_at += 1;
            if self.fifo > 0 && !self.is_blocked(self.drained_at) {
                self.fifo -= 1;
            }
        }
    }

    /// PA4 at time `t`: high while only [`RTS_ROOM`] bytes or fewer fit.
    fn rts_high(&mut self, t: u64) -> bool {
        self.advance(t);
        NRF_FIFO - self.fifo <= RTS_ROOM
    }

    /// A byte's stop bit arrives at `t`.
    fn receive(&mut self, t: u64, byte: u8) {
        self.advance(t);
        if self.fifo == NRF_FIFO {
            self.overruns += 1;
        } else {
            self.fifo += 1;
            self.fifo_high_water = self.fifo_high_water.max(self.fifo);
            self.received.push(byte);
        }
    }
}

/// Sends `packets` through `tx` to `nrf` starting at `t0`, µs; returns the time the last one was done.
fn send_all(tx: &mut FlowTx, nrf: &mut Nrf, packets: &[SyslinkPacket], t0: u64) -> u64 {
    let mut t = t0;
    for p in packets {
        tx.load(p).unwrap();
        loop {
            let rts = nrf.rts_high(t);
            match tx.next(rts) {
                TxStep::Send(bytes) => {
                    let n = bytes.len();
                    for &b in bytes {
                        t += BYTE_US;
                        nrf.receive(t, b);
                    }
                    t += CHECK_LATENCY_US;
                    tx.sent(n);
                }
                TxStep::WaitForClear => t += 1,
                TxStep::Done => break,
            }
        }
    }
    t
}

fn radio_raw(seed: u8, len: usize) -> SyslinkPacket {
    let bytes: Vec<u8> = (0..len).map(|i| seed.wrapping_mul(31).wrapping_add(i as u8)).collect();
    SyslinkPacket::radio_raw(&bytes).unwrap()
}

fn decoded(bytes: &[u8]) -> Vec<SyslinkPacket> {
    let mut d = SyslinkDecoder::new();
    let mut out = Vec::new();
    for &b in bytes {
        let mut e = d.push(b);
        while let Some(r) = e {
            if let Ok(p) = r {
                out.push(p);
            }
            e = d.poll();
        }
    }
    out
}

/// Twenty 32-byte RADIO_RAW frames while Bluetooth holds the nRF's interrupt off for 150 µs every 400 µs,
/// starting inside the first frame.
fn ble_scenario() -> (Vec<SyslinkPacket>, Vec<(u64, u64)>) {
    let packets: Vec<_> = (0..20).map(|k| radio_raw(k, 31)).collect();
    let blocked = (0..40).map(|k| (120 + 400 * k, 270 + 400 * k)).collect();
    (packets, blocked)
}

#[test]
fn chunks_with_a_pa4_check_never_overrun_the_nrf() {
    let (packets, blocked) = ble_scenario();
    let mut nrf = Nrf::new(blocked);
    let mut tx = FlowTx::new();
    send_all(&mut tx, &mut nrf, &packets, 0);
    assert_eq!(nrf.overruns, 0);
    assert_eq!(decoded(&nrf.received), packets);
    let s = tx.stats();
    assert_eq!(s.frames, 20);
    assert!(
        s.paused_mid_frame > 0,
        "the scenario must raise RTS inside frames: {s:?}"
    );
    assert_eq!(s.abandoned, 0);
}

#[test]
fn checking_only_before_each_frame_overruns_the_nrf() {
    // The old transmitter: wait for PA4 low, then the whole frame in one DMA transfer.
    let (packets, blocked) = ble_scenario();
    let mut nrf = Nrf::new(blocked);
    let mut tx = FlowTx::with_chunk(MAX_FRAME);
    send_all(&mut tx, &mut nrf, &packets, 0);
    assert!(nrf.overruns > 0);
    assert!(decoded(&nrf.received).len() < packets.len());
    assert_eq!(tx.stats().paused_mid_frame, 0);
}

#[test]
fn random_bluetooth_stalls_never_overrun_with_the_chunk_size() {
    let mut rng = SmallRng::seed_from_u64(12);
    for case in 0..200 {
        let mut blocked = Vec::new();
        let mut t = rng.random_range(0..300u64);
        while t < 60_000 {
            let len = rng.random_range(1..3000u64);
            blocked.push((t, t + len));
            t += len + rng.random_range(1..2000u64);
        }
        let packets: Vec<_> = (0..30).map(|k| radio_raw(k, rng.random_range(0..=30usize))).collect();
        let mut nrf = Nrf::new(blocked);
        let mut tx = FlowTx::new();
        send_all(&mut tx, &mut nrf, &packets, 0);
        assert_eq!(nrf.overruns, 0, "case {case}");
        assert!(nrf.fifo_high_water <= NRF_FIFO);
        assert_eq!(decoded(&nrf.received), packets, "case {case}");
    }
}

#[test]
fn chunks_are_at_most_chunk_bytes_and_cover_the_frame() {
    let p = radio_raw(7, 30);
    let mut tx = FlowTx::new();
    tx.load(&p).unwrap();
    let mut wire = Vec::new();
    // PA4 toggles every call: high answers WaitForClear and sends nothing.
    let mut high = false;
    loop {
        match tx.next(high) {
            TxStep::Send(b) => {
                assert!(!high && !b.is_empty() && b.len() <= CHUNK);
                let n = b.len();
                wire.extend_from_slice(b);
                tx.sent(n);
            }
            TxStep::WaitForClear => assert!(high),
            TxStep::Done => break,
        }
        high = !high;
    }
    let mut frame = [0u8; MAX_FRAME];
    let n = cfnav::radio::syslink::encode(&p, &mut frame).unwrap();
    assert_eq!(wire, frame[..n]);
    assert_eq!(tx.remaining(), 0);
    // `sent` after the end, and a partial `sent`, stay consistent.
    tx.sent(3);
    assert_eq!(tx.stats().frames, 1);
    tx.load(&p).unwrap();
    let TxStep::Send(b) = tx.next(false) else {
        panic!("expected a chunk")
    };
    assert_eq!(b.len(), CHUNK);
    tx.sent(1);
    assert_eq!(tx.remaining(), n - 1);
    tx.sent(100);
    assert_eq!(tx.remaining(), n - 1 - CHUNK);
}

#[test]
fn abandoning_and_reloading_count_the_lost_frame() {
    let p = radio_raw(1, 20);
    let mut tx = FlowTx::new();
    assert_eq!(tx.next(false), TxStep::Done);
    assert_eq!(tx.abandon(), 0);
    tx.load(&p).unwrap();
    tx.sent(CHUNK);
    assert_eq!(tx.abandon(), p.frame_len() - CHUNK);
    assert_eq!(tx.next(false), TxStep::Done);
    tx.load(&p).unwrap();
    tx.sent(CHUNK);
    // Loading over a frame in progress abandons it.
    tx.load(&p).unwrap();
    assert_eq!(tx.remaining(), p.frame_len());
    assert_eq!(tx.stats().abandoned, 2);
    // Zero and oversized chunk sizes are clamped.
    let mut one = FlowTx::with_chunk(0);
    one.load(&p).unwrap();
    assert!(matches!(one.next(false), TxStep::Send(b) if b.len() == 1));
    let mut big = FlowTx::with_chunk(10_000);
    big.load(&p).unwrap();
    assert!(matches!(big.next(false), TxStep::Send(b) if b.len() == p.frame_len()));
}

fn boot_packets() -> Vec<SyslinkPacket> {
    vec![
        SyslinkPacket::radio_channel(80).unwrap(),
        SyslinkPacket::radio_datarate(cfnav::radio::syslink::Datarate::Rate2M),
        SyslinkPacket::radio_address(0xE7E7E7E7E7).unwrap(),
    ]
}

/// The nRF's answer to a setting (crazyflie2-nrf-firmware `main.c`: the same type and data back).
fn echo(p: &SyslinkPacket) -> SyslinkPacket {
    SyslinkPacket::new(p.kind, &p.payload).unwrap()
}

#[test]
fn settings_go_out_once_and_are_confirmed_by_their_echoes() {
    let sent_order = boot_packets();
    let mut b = BootSettings::new(&sent_order);
    let mut sent = Vec::new();
    while let Some(p) = b.poll(0) {
        sent.push(p);
    }
    assert_eq!(sent, sent_order);
    assert!(!b.is_settled());
    // Echoes in another order; an unrelated packet and a battery report confirm nothing.
    assert!(!b.on_received(&SyslinkPacket::radio_ready()));
    for p in sent.iter().rev() {
        assert!(b.on_received(&echo(p)));
    }
    assert!(b.is_settled());
    assert_eq!(b.confirmed(), 3);
    // Nothing is resent once confirmed, however long it waits.
    assert_eq!(b.poll(10 * ECHO_TIMEOUT_MS), None);
}

#[test]
fn a_missing_or_wrong_echo_is_resent_then_given_up() {
    let mut b = BootSettings::new(&boot_packets());
    while b.poll(0).is_some() {}
    assert!(b.on_received(&echo(&boot_packets()[0])));
    // The data-rate echo carries another value: not a confirmation.
    assert!(!b.on_received(&SyslinkPacket::radio_datarate(
        cfnav::radio::syslink::Datarate::Rate250K
    )));
    assert_eq!(b.poll(ECHO_TIMEOUT_MS - 1), None);
    let again: Vec<_> = std::iter::from_fn(|| b.poll(ECHO_TIMEOUT_MS)).collect();
    assert_eq!(again, boot_packets()[1..]);
    assert!(b.on_received(&echo(&boot_packets()[2])));
    // The data rate never comes back: MAX_SENDS sends in all, then the radio keeps its own.
    let mut sends = 2;
    let mut t = ECHO_TIMEOUT_MS;
    loop {
        t += ECHO_TIMEOUT_MS;
        match b.poll(t) {
            Some(p) => {
                assert_eq!(p.kind, kind::RADIO_DATARATE);
                sends += 1;
            }
            None => break,
        }
    }
    assert_eq!(sends, MAX_SENDS);
    assert_eq!(b.state(kind::RADIO_DATARATE), Some(SettingState::GaveUp));
    assert!(b.is_settled());
    assert_eq!((b.confirmed(), b.gave_up()), (2, 1));
    // Packets the nRF does not echo are not tracked.
    let b = BootSettings::new(&[SyslinkPacket::pm_battery_autoupdate()]);
    assert!(b.is_settled());
}

#[test]
fn settings_lost_on_the_wire_arrive_on_a_resend() {
    // An nRF that misses everything sent in its first 150 ms (Bluetooth start-up) and echoes the rest.
    let mut b = BootSettings::new(&boot_packets());
    let mut applied = Vec::new();
    for t in (0..2000).step_by(10) {
        while let Some(p) = b.poll(t) {
            if t >= 150 {
                applied.push(p.kind);
                b.on_received(&echo(&p));
            }
        }
    }
    assert_eq!(b.confirmed(), 3);
    assert_eq!(
        applied,
        [kind::RADIO_CHANNEL, kind::RADIO_DATARATE, kind::RADIO_ADDRESS]
    );
}

#[test]
fn the_nrf_version_reply_is_read_up_to_its_nul() {
    let req = nrf_version_request();
    assert_eq!(req.kind, kind::SYS_NRF_VERSION);
    assert!(req.payload.is_empty());
    // As crazyflie2-nrf-firmware builds it: tag, " (", 4 platform bytes, ")", NUL.
    let reply = SyslinkPacket::new(kind::SYS_NRF_VERSION, b"2025.02 (CF2 )\0").unwrap();
    assert_eq!(nrf_version(&reply), Some("2025.02 (CF2 )"));
    let unterminated = SyslinkPacket::new(kind::SYS_NRF_VERSION, b"2024.2*").unwrap();
    assert_eq!(nrf_version(&unterminated), Some("2024.2*"));
    assert_eq!(
        nrf_version(&SyslinkPacket::new(kind::SYS_NRF_VERSION, &[0xFF, 0xFE]).unwrap()),
        None
    );
    assert_eq!(nrf_version(&SyslinkPacket::radio_ready()), None);
}
