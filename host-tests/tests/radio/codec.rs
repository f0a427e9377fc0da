//! The radio codecs: syslink framing (docs/hardware.md §4) and CRTP packets, router and the link and
//! platform services (docs/hardware.md §4, docs/radio.md), checked against the byte-exact traces in the
//! reference documents, independent oracles written here, and seeded random streams.

use super::{hex, wire};
use cfnav::radio::crtp::{
    CrtpError, CrtpPacket, DEVICE_TYPE_NAME, LINK_SOURCE_REPLY, PlatformService, Router, Service, is_null_header,
};
use cfnav::radio::syslink::{
    BatteryError, BatteryState, Datarate, DecodeError, EncodeError, MAX_FRAME, MTU, SyslinkDecoder, SyslinkPacket,
    checksum, encode, kind,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

const FW_VERSION: &str = "cfnav-0.1.0";

/// Trailing filler that lets a candidate started in garbage fail. Not zero: `BC CF 00 00 00 00` is a valid
/// empty RADIO_RAW frame, so zeros after a stray `BC CF` would be a real packet.
const PAD: u8 = 0x11;

fn router() -> Router<4> {
    Router::new(PlatformService::new(FW_VERSION))
}

// ---------------------------------------------------------------------------------------------------------
// CRTP: the connect sequence (docs/radio.md, connect sequence and probe trace; docs/hardware.md §4)
// ---------------------------------------------------------------------------------------------------------

#[test]
fn connect_step_1_link_source_matches_the_trace() {
    let mut r = router();
    // Probe trace: `RX 15/1 hdr=FD [00] -> TX 15/1 "Bitcraze Crazyflie"+12x00`.
    let reply = r.handle_uplink(&[0xFD, 0x00], &mut []).expect("source reply");
    let mut expected = vec![0xFD];
    expected.extend_from_slice(b"Bitcraze Crazyflie");
    expected.extend_from_slice(&[0u8; 12]);
    assert_eq!(expected.len(), 31);
    assert_eq!(wire(&reply), expected);
    assert_eq!(&LINK_SOURCE_REPLY[..], &expected[1..]);
    // crazyflie-lib sends headers with bits 2–3 clear: same reply.
    let reply = r.handle_uplink(&[0xF1, 0x00], &mut []).expect("source reply");
    assert_eq!(wire(&reply), expected);
}

#[test]
fn connect_step_2_protocol_version_matches_the_trace() {
    let mut r = router();
    // Probe trace: `RX 13/1 hdr=DD [00] -> TX 13/1 [00 0C 00 00 00]` (version 12, i32 LE, size 5).
    let reply = r.handle_uplink(&[0xDD, 0x00], &mut []).expect("version reply");
    assert_eq!(wire(&reply), hex("DD 00 0C 00 00 00"));
    let reply = r.handle_uplink(&[0xD1, 0x00], &mut []).expect("version reply");
    assert_eq!(wire(&reply), hex("DD 00 0C 00 00 00"));
}

#[test]
fn scan_probe_null_packet_gets_no_service_reply() {
    let mut r = router();
    // The bare 0xFF scan probe is a null packet (§4.1): nothing to dispatch; a UDP transport answers it itself.
    assert_eq!(r.handle_uplink(&[0xFF], &mut []), None);
    assert_eq!(r.handle_uplink(&[0xF3], &mut []), None);
    assert_eq!(r.handle_uplink(&hex("FF 05 01"), &mut []), None);
    assert_eq!(r.stats().null, 3);
    assert_eq!(r.stats().dispatched, 0);
}

#[test]
fn platform_firmware_version_and_device_type_name() {
    let mut r = router();
    let reply = r.handle_uplink(&[0xDD, 0x01], &mut []).unwrap();
    let mut expected = vec![0xDD, 0x01];
    expected.extend_from_slice(FW_VERSION.as_bytes());
    assert_eq!(wire(&reply), expected);

    let reply = r.handle_uplink(&[0xDD, 0x02], &mut []).unwrap();
    let mut expected = vec![0xDD, 0x02];
    expected.extend_from_slice(b"Crazyflie 2.1");
    assert_eq!(DEVICE_TYPE_NAME, "Crazyflie 2.1");
    assert_eq!(wire(&reply), expected);

    // A firmware tag longer than 29 bytes is cut so the reply fits in 30 data bytes.
    let mut long: Router<2> = Router::new(PlatformService::new("0123456789abcdefghijklmnopqrstuvwxyz"));
    let reply = long.handle_uplink(&[0xDD, 0x01], &mut []).unwrap();
    assert_eq!(reply.data.len(), 30);
    assert_eq!(&reply.data[1..], b"0123456789abcdefghijklmnopqrs");
}

#[test]
fn link_echo_sink_and_unknowns() {
    let mut r = router();
    // cflib's latency ping: 15/0 [00 + f64] echoed unchanged (docs/hardware.md §4, docs/radio.md).
    let mut ping = vec![0xFC, 0x00];
    ping.extend_from_slice(&1_700_000_000.25f64.to_le_bytes());
    let reply = r.handle_uplink(&ping, &mut []).unwrap();
    assert_eq!(wire(&reply), ping);
    // A 30-byte echo is echoed whole.
    let mut big = vec![0xFC];
    big.extend(0u8..30);
    assert_eq!(wire(&r.handle_uplink(&big, &mut []).unwrap()), big);
    // Sink: no reply.
    assert_eq!(r.handle_uplink(&[0xFE, 1, 2, 3], &mut []), None);
    // Platform: unknown version command, empty request, channels 0 and 2: no reply.
    assert_eq!(r.handle_uplink(&[0xDD, 0x07], &mut []), None);
    assert_eq!(r.handle_uplink(&[0xDD], &mut []), None);
    assert_eq!(r.handle_uplink(&[0xDC, 0x00, 0x01], &mut []), None);
    assert_eq!(r.handle_uplink(&[0xDE, 0x00], &mut []), None);
    // Ports without a service: no reply, counted.
    for port in [0u8, 2, 3, 4, 5, 7, 9] {
        assert_eq!(r.handle_uplink(&[(port << 4) | 0x0C, 0x00], &mut []), None);
    }
    assert_eq!(r.stats().unknown_port, 7);
    // Malformed: no panic, no reply.
    assert_eq!(r.handle_uplink(&[], &mut []), None);
    assert_eq!(r.handle_uplink(&[0xFC; 32], &mut []), None);
    assert_eq!(r.stats().malformed, 2);
}

struct Counter {
    seen: usize,
}

impl Service for Counter {
    fn port(&self) -> u8 {
        5
    }
    fn handle(&mut self, packet: &CrtpPacket) -> Option<CrtpPacket> {
        self.seen += 1;
        CrtpPacket::new(5, packet.channel, &[packet.data.first().copied().unwrap_or(0), 0, 0]).ok()
    }
}

#[test]
fn router_dispatches_to_registered_services() {
    let mut r = router();
    let mut log = Counter { seen: 0 };
    // Trace step 3: `RX 5/1 hdr=5D [05] -> TX 5/1 [05 00 00]`.
    let reply = r.handle_uplink(&[0x5D, 0x05], &mut [&mut log]).unwrap();
    assert_eq!(wire(&reply), hex("5D 05 00 00"));
    assert_eq!(log.seen, 1);
}

#[test]
fn router_releases_one_downlink_per_uplink_in_fifo_order() {
    let mut r: Router<3> = Router::new(PlatformService::new(FW_VERSION));
    let console = |i: u8| CrtpPacket::new(0, 0, &[b'a' + i]).unwrap();
    assert!(r.enqueue(console(0)).is_ok());
    assert!(r.enqueue(console(1)).is_ok());
    assert_eq!(r.pending(), 2);
    // A version request while two console packets wait: the reply goes behind them.
    assert_eq!(r.handle_uplink(&[0xDD, 0x00], &mut []), Some(console(0)));
    assert_eq!(r.handle_uplink(&[0xFF], &mut []), Some(console(1)));
    assert_eq!(
        wire(&r.handle_uplink(&[0xFF], &mut []).unwrap()),
        hex("DD 00 0C 00 00 00")
    );
    assert_eq!(r.handle_uplink(&[0xFF], &mut []), None);
    // A full queue gives the packet back and counts it.
    for i in 0..3 {
        assert!(r.enqueue(console(i)).is_ok());
    }
    assert_eq!(r.enqueue(console(9)), Err(console(9)));
    assert_eq!(r.stats().dropped, 1);
}

// ---------------------------------------------------------------------------------------------------------
// CRTP packets
// ---------------------------------------------------------------------------------------------------------

#[test]
fn crtp_header_round_trips_for_all_ports_and_channels_ignoring_bits_2_3() {
    for port in 0u8..16 {
        for channel in 0u8..4 {
            let p = CrtpPacket::new(port, channel, &[port, channel, 0xAA]).unwrap();
            let bytes = wire(&p);
            // Downlink headers carry bits 2–3 set, like cflib's (§4.1).
            assert_eq!(bytes[0], (port << 4) | 0x0C | channel);
            if port == 15 && channel == 3 {
                assert_eq!(CrtpPacket::from_bytes(&bytes), Err(CrtpError::Null));
                continue;
            }
            for link_bits in 0u8..4 {
                let mut b = bytes.clone();
                b[0] = (port << 4) | (link_bits << 2) | channel;
                assert_eq!(CrtpPacket::from_bytes(&b).unwrap(), p);
            }
        }
    }
}

#[test]
fn crtp_null_packets_and_sizes() {
    for h in 0u8..=255 {
        let is_null = h & 0xF3 == 0xF3;
        assert_eq!(is_null_header(h), is_null);
        assert_eq!(
            CrtpPacket::from_bytes(&[h]).is_err_and(|e| e == CrtpError::Null),
            is_null,
            "header {h:#04x}"
        );
    }
    assert_eq!(CrtpPacket::from_bytes(&[]), Err(CrtpError::Empty));
    for len in 1..=31 {
        let p = CrtpPacket::from_bytes(&vec![0x3C; len]).unwrap();
        assert_eq!(p.data.len(), len - 1);
    }
    for len in [32, 33, 64, 300] {
        assert_eq!(CrtpPacket::from_bytes(&vec![0x3C; len]), Err(CrtpError::TooLong(len)));
        assert_eq!(CrtpPacket::from_bytes(&vec![0xFF; len]), Err(CrtpError::TooLong(len)));
    }
    assert_eq!(CrtpPacket::new(16, 0, &[]), Err(CrtpError::OutOfRange));
    assert_eq!(CrtpPacket::new(0, 4, &[]), Err(CrtpError::OutOfRange));
    assert_eq!(CrtpPacket::new(0, 0, &[0; 31]), Err(CrtpError::OutOfRange));
    assert!(CrtpPacket::new(0, 0, &[0; 30]).is_ok());
}

// ---------------------------------------------------------------------------------------------------------
// Syslink
// ---------------------------------------------------------------------------------------------------------

/// Independent checksum: the closed form of the §3.2 Fletcher sums (A = Σ b, B = Σ (n − i)·b, mod 256).
fn oracle_checksum(body: &[u8]) -> [u8; 2] {
    let n = body.len() as u64;
    let a: u64 = body.iter().map(|&b| u64::from(b)).sum();
    let b: u64 = body
        .iter()
        .enumerate()
        .map(|(i, &x)| (n - i as u64) * u64::from(x))
        .sum();
    [(a % 256) as u8, (b % 256) as u8]
}

/// Independent frame builder.
fn oracle_frame(kind: u8, payload: &[u8]) -> Vec<u8> {
    let mut body = vec![kind, payload.len() as u8];
    body.extend_from_slice(payload);
    let ck = oracle_checksum(&body);
    let mut f = vec![0xBC, 0xCF];
    f.extend_from_slice(&body);
    f.extend_from_slice(&ck);
    f
}

fn encoded(p: &SyslinkPacket) -> Vec<u8> {
    let mut out = [PAD; MAX_FRAME];
    let n = encode(p, &mut out).unwrap();
    out[..n].to_vec()
}

/// Feeds bytes and drains every event.
fn decode_all(dec: &mut SyslinkDecoder, bytes: &[u8]) -> Vec<Result<SyslinkPacket, DecodeError>> {
    let mut events = Vec::new();
    for &b in bytes {
        if let Some(e) = dec.push(b) {
            events.push(e);
        }
        while let Some(e) = dec.poll() {
            events.push(e);
        }
    }
    events
}

fn good(events: &[Result<SyslinkPacket, DecodeError>]) -> Vec<SyslinkPacket> {
    events.iter().filter_map(|e| e.as_ref().ok().cloned()).collect()
}

#[test]
fn syslink_worked_examples_and_boot_packets() {
    // §3.2 worked examples.
    assert_eq!(encoded(&SyslinkPacket::radio_ready()), hex("BC CF 0B 00 0B 16"));
    assert_eq!(
        encoded(&SyslinkPacket::pm_battery_autoupdate()),
        hex("BC CF 14 00 14 28")
    );
    assert_eq!(
        encoded(&SyslinkPacket::radio_channel(80).unwrap()),
        hex("BC CF 01 01 50 52 55")
    );
    // The other boot packets (§3.3 / §3.4), against the independent builder.
    assert_eq!(
        encoded(&SyslinkPacket::radio_datarate(Datarate::Rate2M)),
        oracle_frame(kind::RADIO_DATARATE, &[2])
    );
    assert_eq!(
        encoded(&SyslinkPacket::radio_datarate(Datarate::Rate250K)),
        oracle_frame(0x02, &[0])
    );
    assert_eq!(
        encoded(&SyslinkPacket::radio_address(0xE7_E7E7_E7E7).unwrap()),
        oracle_frame(kind::RADIO_ADDRESS, &[0xE7; 5])
    );
    assert_eq!(
        SyslinkPacket::radio_address(0x01_0203_0405).unwrap().payload.as_slice(),
        &[0x05, 0x04, 0x03, 0x02, 0x01]
    );
    assert_eq!(encoded(&SyslinkPacket::pm_shutdown_ack()), oracle_frame(0x16, &[]));
    assert_eq!(SyslinkPacket::radio_channel(125).unwrap().payload.as_slice(), &[125]);
    assert_eq!(SyslinkPacket::radio_channel(126), Err(EncodeError::OutOfRange));
    assert_eq!(SyslinkPacket::radio_address(1 << 40), Err(EncodeError::OutOfRange));
    assert_eq!(SyslinkPacket::new(0, &[0; 65]), Err(EncodeError::PayloadTooLong));
    assert_eq!(SyslinkPacket::radio_raw(&[0xFD, 0]).unwrap().kind, kind::RADIO_RAW);
    // Too small an output buffer.
    let p = SyslinkPacket::new(0, &[1, 2, 3]).unwrap();
    let mut small = [0u8; 8];
    assert_eq!(encode(&p, &mut small), Err(EncodeError::BufferTooSmall { needed: 9 }));
    let mut exact = [0u8; 9];
    assert_eq!(encode(&p, &mut exact), Ok(9));
}

#[test]
fn syslink_checksum_matches_the_independent_oracle() {
    let mut rng = SmallRng::seed_from_u64(0x5EED_0001);
    for _ in 0..20_000 {
        let len = rng.random_range(0..=MTU + 2);
        let body: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        assert_eq!(checksum(&body), oracle_checksum(&body));
    }
    assert_eq!(checksum(&[]), [0, 0]);
    assert_eq!(checksum(&[0xFF; 66]), oracle_checksum(&[0xFF; 66]));
}

#[test]
fn syslink_round_trips_random_packets() {
    let mut rng = SmallRng::seed_from_u64(0x5EED_0002);
    let mut dec = SyslinkDecoder::new();
    for i in 0..20_000 {
        let len = if i <= MTU { i } else { rng.random_range(0..=MTU) };
        let payload: Vec<u8> = (0..len).map(|_| rng.random()).collect();
        let p = SyslinkPacket::new(rng.random(), &payload).unwrap();
        let bytes = encoded(&p);
        assert_eq!(bytes, oracle_frame(p.kind, &payload));
        assert_eq!(bytes.len(), p.frame_len());
        assert_eq!(decode_all(&mut dec, &bytes), vec![Ok(p)]);
    }
    let s = dec.stats();
    assert_eq!(
        (s.packets, s.skipped_bytes, s.oversized, s.bad_checksum),
        (20_000, 0, 0, 0)
    );
}

#[test]
fn syslink_oversized_length_is_rejected_and_the_next_packet_survives() {
    let mut dec = SyslinkDecoder::new();
    let ready = hex("BC CF 0B 00 0B 16");
    for len in 65u8..=255 {
        let mut bytes = vec![0xBC, 0xCF, 0x00, len];
        bytes.extend_from_slice(&ready);
        let events = decode_all(&mut dec, &bytes);
        assert_eq!(
            events,
            vec![Err(DecodeError::Oversized(len)), Ok(SyslinkPacket::radio_ready())]
        );
    }
    // Exactly 64 is legal.
    let p = SyslinkPacket::new(0x13, &[7; 64]).unwrap();
    assert_eq!(decode_all(&mut dec, &encoded(&p)), vec![Ok(p)]);
    assert_eq!(dec.stats().oversized, 191);
}

#[test]
fn syslink_truncated_and_corrupted_frames_do_not_hide_the_next_packet() {
    let battery = SyslinkPacket::new(kind::PM_BATTERY_STATE, &[1, 0, 0, 0x80, 0x40, 0, 0, 0, 0]).unwrap();
    let frame = encoded(&battery);
    let ready = encoded(&SyslinkPacket::radio_ready());
    let mut dec = SyslinkDecoder::new();
    // Every truncation of a frame followed by a good one (the truncated frame's length swallows the good
    // one's bytes, the checksum fails, and the decoder rescans them).
    for cut in 1..frame.len() {
        let mut bytes = frame[..cut].to_vec();
        bytes.extend_from_slice(&ready);
        bytes.extend_from_slice(&[PAD; MAX_FRAME]);
        let events = decode_all(&mut dec, &bytes);
        assert_eq!(good(&events), vec![SyslinkPacket::radio_ready()], "cut at {cut}");
    }
    // Every single-byte corruption of a frame followed by a good one.
    for at in 0..frame.len() {
        for flip in [0x01u8, 0x80, 0xFF] {
            let mut bytes = frame.clone();
            bytes[at] ^= flip;
            bytes.extend_from_slice(&ready);
            bytes.extend_from_slice(&[PAD; MAX_FRAME]);
            let events = decode_all(&mut dec, &bytes);
            assert_eq!(
                good(&events),
                vec![SyslinkPacket::radio_ready()],
                "corrupt byte {at} ^ {flip:#x}"
            );
        }
    }
    assert!(dec.stats().bad_checksum > 0);
}

/// Reference decoder over a whole buffer (the specification of the streaming one): commit to the candidate
/// at the first `BC CF`; if it fails, restart one byte after its start.
fn oracle_decode(bytes: &[u8]) -> Vec<Result<SyslinkPacket, DecodeError>> {
    let mut out = Vec::new();
    let mut i = 0;
    while i + 1 < bytes.len() {
        if bytes[i] != 0xBC || bytes[i + 1] != 0xCF {
            i += 1;
            continue;
        }
        let Some(&len) = bytes.get(i + 3) else { break };
        if len as usize > MTU {
            out.push(Err(DecodeError::Oversized(len)));
            i += 1;
            continue;
        }
        let end = i + 6 + len as usize;
        if end > bytes.len() {
            break;
        }
        let body = &bytes[i + 2..end - 2];
        if oracle_checksum(body) == [bytes[end - 2], bytes[end - 1]] {
            out.push(Ok(SyslinkPacket::new(bytes[i + 2], &body[2..]).unwrap()));
            i = end;
        } else {
            out.push(Err(DecodeError::BadChecksum));
            i += 1;
        }
    }
    out
}

fn garbage_byte(rng: &mut SmallRng) -> u8 {
    match rng.random_range(0..10) {
        0 => 0xBC,
        1 => 0xCF,
        _ => rng.random(),
    }
}

#[test]
fn syslink_resynchronises_in_random_streams_of_packets_and_garbage() {
    let mut total_good = 0usize;
    for seed in 0..3_000u64 {
        let mut rng = SmallRng::seed_from_u64(0xA11CE ^ (seed << 8));
        let mut stream = Vec::new();
        let mut expected = Vec::new();
        for _ in 0..rng.random_range(1..12) {
            let len = rng.random_range(0..=MTU);
            let payload: Vec<u8> = (0..len).map(|_| rng.random()).collect();
            let p = SyslinkPacket::new(rng.random(), &payload).unwrap();
            let frame = encoded(&p);
            match rng.random_range(0..6) {
                // A good packet.
                0 | 1 => {
                    stream.extend_from_slice(&frame);
                    expected.push(p);
                }
                // Random garbage, biased towards start bytes.
                2 => (0..rng.random_range(0..100)).for_each(|_| stream.push(garbage_byte(&mut rng))),
                // A truncated frame.
                3 => stream.extend_from_slice(&frame[..rng.random_range(1..frame.len())]),
                // A frame with one byte changed.
                4 => {
                    let mut f = frame;
                    let at = rng.random_range(0..f.len());
                    f[at] ^= rng.random_range(1..=255u8);
                    stream.extend_from_slice(&f);
                }
                // A header with an oversized length and some bytes.
                _ => {
                    stream.extend_from_slice(&[0xBC, 0xCF, rng.random(), rng.random_range(65..=255u8)]);
                    (0..rng.random_range(0..80)).for_each(|_| stream.push(garbage_byte(&mut rng)));
                }
            }
        }
        // Trailing bytes so a candidate started in garbage near the end fails and is rescanned.
        stream.extend_from_slice(&[PAD; MAX_FRAME]);

        let mut dec = SyslinkDecoder::new();
        let events = decode_all(&mut dec, &stream);
        assert_eq!(
            events,
            oracle_decode(&stream),
            "seed {seed}: streaming decoder differs from the oracle"
        );
        assert_eq!(good(&events), expected, "seed {seed}: a good packet was lost");
        assert_eq!(dec.stats().packets as usize, expected.len());
        total_good += expected.len();
    }
    assert!(total_good > 5_000);
}

#[test]
fn syslink_decoder_recovers_after_push_without_poll() {
    // A caller that never calls `poll` still gets every event eventually and never overflows the buffer.
    let mut stream = vec![0xBC, 0xCF, 0x00, 20];
    for _ in 0..4 {
        stream.extend_from_slice(&encoded(&SyslinkPacket::radio_ready()));
    }
    stream.extend_from_slice(&[0u8; 200]);
    let mut dec = SyslinkDecoder::new();
    let mut got = Vec::new();
    for &b in &stream {
        if let Some(Ok(p)) = dec.push(b) {
            got.push(p);
        }
    }
    assert_eq!(got, vec![SyslinkPacket::radio_ready(); 4]);
}

#[test]
fn battery_state_parses_voltage_and_flags() {
    let mut payload = vec![0b101];
    payload.extend_from_slice(&3.95f32.to_le_bytes());
    payload.extend_from_slice(&500.0f32.to_le_bytes());
    let p = SyslinkPacket::new(kind::PM_BATTERY_STATE, &payload).unwrap();
    let s = BatteryState::parse(&p).unwrap();
    assert_eq!(
        (s.flags, s.charging, s.usb_powered, s.can_charge),
        (5, true, false, true)
    );
    assert_eq!((s.vbat, s.iset_ma, s.temperature), (3.95, 500.0, None));

    payload[0] = 0b010;
    payload.extend_from_slice(&31.5f32.to_le_bytes());
    let p = SyslinkPacket::new(kind::PM_BATTERY_STATE, &payload).unwrap();
    let s = BatteryState::parse(&p).unwrap();
    assert_eq!(
        (s.charging, s.usb_powered, s.can_charge, s.temperature),
        (false, true, false, Some(31.5))
    );

    // Through the wire and the decoder.
    let mut dec = SyslinkDecoder::new();
    let events = decode_all(&mut dec, &oracle_frame(0x13, &payload));
    assert_eq!(BatteryState::parse(events[0].as_ref().unwrap()).unwrap().vbat, 3.95);

    for short in 0..9 {
        let p = SyslinkPacket::new(kind::PM_BATTERY_STATE, &payload[..short]).unwrap();
        assert_eq!(BatteryState::parse(&p), Err(BatteryError::TooShort));
    }
    let p = SyslinkPacket::new(kind::PM_BATTERY_VOLTAGE, &payload).unwrap();
    assert_eq!(BatteryState::parse(&p), Err(BatteryError::WrongKind));
}

#[test]
fn one_megabyte_of_random_bytes_never_panics_either_decoder() {
    let mut rng = SmallRng::seed_from_u64(0xF022);
    let mut bytes = vec![0u8; 1 << 20];
    rng.fill(&mut bytes[..]);
    // Sprinkle start pairs so the syslink decoder exercises every state.
    for _ in 0..20_000 {
        let at = rng.random_range(0..bytes.len() - 1);
        bytes[at] = 0xBC;
        bytes[at + 1] = 0xCF;
    }
    let mut dec = SyslinkDecoder::new();
    let events = decode_all(&mut dec, &bytes);
    let s = dec.stats();
    assert_eq!(events.len() as u32, s.packets + s.oversized + s.bad_checksum);
    assert!(s.oversized > 0 && s.bad_checksum > 0 && s.skipped_bytes > 0);

    let mut r = router();
    let mut log = Counter { seen: 0 };
    let mut at = 0;
    while at < bytes.len() {
        let n = rng.random_range(0..40).min(bytes.len() - at);
        let chunk = &bytes[at..at + n];
        let parsed = CrtpPacket::from_bytes(chunk);
        if let Ok(p) = &parsed {
            assert!(n <= 31);
            assert_eq!(wire(p)[1..], chunk[1..]);
        }
        if let Some(reply) = r.handle_uplink(chunk, &mut [&mut log]) {
            assert!(reply.data.len() <= 30);
        }
        at += n;
    }
    assert!(r.stats().dispatched > 0);
}
