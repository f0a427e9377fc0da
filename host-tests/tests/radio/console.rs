//! The console service (port 0 channel 0): text is cut into packets the way the stock console does
//! (docs/hardware.md §4: "text chunks ≤ 30 bytes, no terminator"; `console.c` sends a packet when it
//! is full or after a newline), packets come out in order one per call, and a full queue drops whole lines
//! and counts them. The oracle for line acceptance is written here from that rule: a line of L bytes plus
//! its newline needs ⌈(L + 1) / 30⌉ packets and is queued only if that many places are free.

use std::fmt::Write as _;

use cfnav::radio::console::ConsoleService;
use cfnav::radio::crtp::{CrtpPacket, PlatformService, Router, Service};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn drain<const N: usize>(c: &mut ConsoleService<N>) -> Vec<CrtpPacket> {
    std::iter::from_fn(|| c.next_packet()).collect()
}

fn text(packets: &[CrtpPacket]) -> String {
    packets
        .iter()
        .map(|p| String::from_utf8(p.data.to_vec()).unwrap())
        .collect()
}

fn assert_console_packets(packets: &[CrtpPacket]) {
    for p in packets {
        assert_eq!((p.port, p.channel), (0, 0), "console is port 0 channel 0");
        assert!(!p.data.is_empty() && p.data.len() <= 30, "{} bytes", p.data.len());
        let mut wire = [0u8; 32];
        assert_eq!(p.to_bytes(&mut wire), p.data.len() + 1);
        assert_eq!(wire[0], 0x0C, "header: port 0, link bits, channel 0");
    }
}

#[test]
fn a_short_line_is_one_packet_with_its_newline() {
    let mut c: ConsoleService<8> = ConsoleService::new();
    c.write_line("hello");
    let p = drain(&mut c);
    assert_console_packets(&p);
    assert_eq!(p.len(), 1);
    assert_eq!(p[0].data.as_slice(), b"hello\n");
}

#[test]
fn a_long_line_is_cut_into_30_byte_packets() {
    let mut c: ConsoleService<8> = ConsoleService::new();
    let line: String = (0..75).map(|i| char::from(b'a' + (i % 26) as u8)).collect();
    c.write_line(&line);
    let p = drain(&mut c);
    assert_console_packets(&p);
    let lens: Vec<usize> = p.iter().map(|p| p.data.len()).collect();
    assert_eq!(lens, [30, 30, 16], "76 bytes with the newline");
    assert_eq!(text(&p), format!("{line}\n"));
}

#[test]
fn print_waits_for_a_newline_or_a_full_packet() {
    let mut c: ConsoleService<8> = ConsoleService::new();
    c.print("abc");
    assert_eq!(c.pending(), 0, "no newline, not full: nothing sent yet");
    c.print("def\nxy");
    let p = drain(&mut c);
    assert_eq!(p.len(), 1);
    assert_eq!(p[0].data.as_slice(), b"abcdef\n");
    assert_eq!(c.partial_len(), 2);
    c.print(&"z".repeat(28));
    let p = drain(&mut c);
    assert_eq!(p.len(), 1, "30 bytes fill a packet: sent without a newline");
    assert_eq!(p[0].data.len(), 30);
    c.print("tail");
    c.flush();
    assert_eq!(drain(&mut c)[0].data.as_slice(), b"tail");
}

#[test]
fn packets_come_out_one_per_call_in_order() {
    let mut c: ConsoleService<8> = ConsoleService::new();
    c.write_line("one");
    c.write_line("two");
    c.write_line("three");
    assert_eq!(c.pending(), 3);
    assert_eq!(c.next_packet().unwrap().data.as_slice(), b"one\n");
    assert_eq!(c.pending(), 2);
    assert_eq!(c.next_packet().unwrap().data.as_slice(), b"two\n");
    assert_eq!(c.next_packet().unwrap().data.as_slice(), b"three\n");
    assert_eq!(c.next_packet(), None);
    assert_eq!(c.sent_packets(), 3);
}

#[test]
fn a_full_queue_drops_whole_lines_and_counts_them() {
    let mut c: ConsoleService<4> = ConsoleService::new();
    let two_packets = "x".repeat(40);
    c.write_line(&two_packets);
    c.write_line(&two_packets);
    assert_eq!(c.pending(), 4);
    c.write_line("short");
    c.write_line(&two_packets);
    assert_eq!(c.dropped_lines(), 2);
    assert_eq!(c.pending(), 4, "nothing of the dropped lines was queued");
    assert_eq!(c.partial_len(), 0);
    // One place frees up: a one-packet line fits, a two-packet line still does not.
    c.next_packet();
    c.write_line(&two_packets);
    assert_eq!(c.dropped_lines(), 3);
    c.write_line("fits");
    let p = drain(&mut c);
    assert_console_packets(&p);
    assert_eq!(
        text(&p),
        format!("{}\n{two_packets}\nfits\n", &two_packets[30..]),
        "the first line's first packet went out before the drops"
    );
}

#[test]
fn an_unterminated_line_that_overflows_drops_its_rest() {
    let mut c: ConsoleService<1> = ConsoleService::new();
    c.print(&"a".repeat(30)); // one full packet: queued
    assert_eq!(c.pending(), 1);
    c.print(&"b".repeat(31)); // the next full packet finds the queue full
    assert_eq!(c.dropped_lines(), 1);
    c.print("still the same line\n");
    assert_eq!(c.dropped_lines(), 1, "counted once per line");
    assert_eq!(drain(&mut c).len(), 1);
    c.write_line("next");
    assert_eq!(drain(&mut c)[0].data.as_slice(), b"next\n", "the next line is whole");
}

#[test]
fn formatting_and_router_downlink() {
    let mut c: ConsoleService<8> = ConsoleService::new();
    let reason = "outside the arena";
    writeln!(c, "param mission.goalX refused: {reason}").unwrap();
    // Uplink console packets are ignored, as in stock.
    let mut router: Router<4> = Router::new(PlatformService::new("t"));
    assert_eq!(
        router.handle_uplink(&[0x0C, b'h', b'i'], &mut [&mut c as &mut dyn Service]),
        None
    );
    assert_eq!(router.stats().dispatched, 1);
    // One console packet per downlink opportunity: the caller queues one when the router has nothing.
    let mut got = Vec::new();
    for _ in 0..5 {
        if router.pending() == 0
            && let Some(p) = c.next_packet()
        {
            router.enqueue(p).unwrap();
        }
        if let Some(p) = router.handle_uplink(&[0xFF], &mut []) {
            got.push(p);
        }
    }
    assert_console_packets(&got);
    assert_eq!(got.len(), 2, "48 bytes: two packets");
    assert_eq!(text(&got), "param mission.goalX refused: outside the arena\n");
}

#[test]
fn random_lines_and_draining_match_the_oracle() {
    let mut rng = SmallRng::seed_from_u64(0x5EED_C0DE);
    let mut c: ConsoleService<6> = ConsoleService::new();
    let mut expected = String::new();
    let mut delivered = Vec::new();
    let mut expected_drops = 0;
    for _ in 0..20_000 {
        if rng.random_bool(0.5) {
            let len = rng.random_range(0..100usize);
            let line: String = (0..len).map(|_| char::from(rng.random_range(b' '..=b'~'))).collect();
            let needed = (len + 1).div_ceil(30);
            if needed <= 6 - c.pending() {
                expected.push_str(&line);
                expected.push('\n');
            } else {
                expected_drops += 1;
            }
            c.write_line(&line);
        } else {
            for _ in 0..rng.random_range(0..4) {
                if let Some(p) = c.next_packet() {
                    delivered.push(p);
                }
            }
        }
        assert!(c.pending() <= 6);
    }
    delivered.extend(drain(&mut c));
    assert_console_packets(&delivered);
    assert_eq!(c.dropped_lines(), expected_drops);
    assert!(
        expected_drops > 100,
        "the queue overflowed often enough to test the rule"
    );
    assert_eq!(text(&delivered), expected);
}

#[test]
fn random_pieces_never_panic_and_keep_packet_sizes() {
    let mut rng = SmallRng::seed_from_u64(0x5EED_0C0C);
    let mut c: ConsoleService<3> = ConsoleService::new();
    for _ in 0..50_000 {
        let len = rng.random_range(0..70usize);
        let piece: String = (0..len)
            .map(|_| {
                if rng.random_bool(0.05) {
                    '\n'
                } else {
                    char::from(rng.random_range(b'a'..=b'z'))
                }
            })
            .collect();
        c.print(&piece);
        if rng.random_bool(0.1) {
            c.flush();
        }
        if rng.random_bool(0.5) {
            let p: Vec<CrtpPacket> = c.next_packet().into_iter().collect();
            assert_console_packets(&p);
        }
        assert!(c.pending() <= 3 && c.partial_len() <= 30);
    }
}
