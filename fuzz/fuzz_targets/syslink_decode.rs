//! Fuzz target: arbitrary bytes from the nRF51 UART into the syslink decoder.
//!
//! Checks: no panic; every decoded packet re-encodes to a frame that decodes to the same packet (framing and
//! checksum of docs/hardware.md §4); RADIO_RAW payloads parse as CRTP or are refused; battery packets
//! parse or are refused; the decoder's counters only grow.
#![no_main]

use cfnav::radio::crtp::CrtpPacket;
use cfnav::radio::syslink::{BatteryState, MAX_FRAME, SyslinkDecoder, SyslinkPacket, encode};
use libfuzzer_sys::fuzz_target;

fn check(packet: &SyslinkPacket) {
    let mut frame = [0u8; MAX_FRAME];
    let n = encode(packet, &mut frame).expect("a decoded packet re-encodes");
    let mut again = SyslinkDecoder::new();
    let mut decoded = None;
    for &b in &frame[..n] {
        if let Some(event) = again.push(b) {
            decoded = Some(event);
        }
    }
    assert_eq!(decoded, Some(Ok(packet.clone())), "round trip");
    let _ = CrtpPacket::from_bytes(&packet.payload);
    let _ = BatteryState::parse(packet);
}

fuzz_target!(|data: &[u8]| {
    let mut decoder = SyslinkDecoder::new();
    let mut before = decoder.stats();
    for &byte in data {
        let mut event = decoder.push(byte);
        while let Some(result) = event {
            if let Ok(packet) = &result {
                check(packet);
            }
            event = decoder.poll();
        }
        let now = decoder.stats();
        assert!(now.packets >= before.packets && now.skipped_bytes >= before.skipped_bytes);
        before = now;
    }
});
