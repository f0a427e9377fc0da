//! `cfnav mission start` against the real simulator server (`crate::sim::serve`, in a thread of the test
//! process, on a free UDP port picked at run time): the same client code path as the command, with exit
//! statuses checked. The server thread runs until the test process ends.

use std::time::Duration;

use super::{EXIT_ERROR, StartArgs, parse_start, run_start};
use cfnav_sim::world::World;

/// A UDP port nobody uses right now (the system picks it; released at once for the server to bind).
fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .expect("a free UDP port")
}

fn args(port: u16, extra: &[&str]) -> StartArgs {
    let uri = format!("udp://127.0.0.1:{port}");
    let mut argv = vec!["mission", "start", "--uri", uri.as_str(), "--no-toc-cache"];
    argv.extend_from_slice(extra);
    parse_start(&argv).expect("valid options")
}

/// Starts a simulator server and returns its port.
fn start_server() -> u16 {
    let port = free_udp_port();
    std::thread::spawn(move || {
        let world = World::default_world();
        // 50× real time: a round trip of about 90 simulated seconds takes about 2 s.
        let r = crate::sim::serve::serve(&world, port, 50.0, None, None);
        panic!("the test server stopped: {r:?}");
    });
    std::thread::sleep(Duration::from_millis(300));
    port
}

#[test]
fn refused_goal_then_a_flight_over_udp() {
    let port = start_server();
    // docs/radio.md: a goal outside the arena is refused (the echo carries the value in effect) → exit 2,
    // and nothing starts.
    assert_eq!(run_start(&args(port, &["--goal", "50,1"])), EXIT_ERROR);
    // A height below 0.2 m is refused as well.
    assert_eq!(run_start(&args(port, &["--height", "0.1"])), EXIT_ERROR);
    // The flight: exit 0 if it completes, 1 if it ends otherwise (the sim completes about nine in ten);
    // never 2 (that would be a protocol or link failure) and it must end within the timeout.
    let began = std::time::Instant::now();
    let code = run_start(&args(
        port,
        &["--goal", "5.0,1.5", "--start", "0.6,1.3", "--timeout", "60"],
    ));
    assert!(code == 0 || code == 1, "exit {code}");
    // Ended by itself, not by --timeout (which also exits 1).
    assert!(began.elapsed() < Duration::from_secs(30), "took {:?}", began.elapsed());
}

#[test]
fn nothing_listening_is_exit_2() {
    // A port nobody serves (picked free and released).
    assert_eq!(run_start(&args(free_udp_port(), &[])), EXIT_ERROR);
}
