//! Radio (src/radio): the syslink and CRTP codecs and every CRTP service (commander, console, log, param,
//! supervisor port), the syslink transmitter (flow control, boot-setting echoes), and the stock parameter and
//! log names clients use.

mod codec;
mod commander;
mod console;
mod flow_control;
mod high_level;
mod log;
mod map_mem;
mod modes;
mod param;
mod room;
mod stock;
mod supervisor_port;
mod tuning;

use cfnav::radio::crtp::{CrtpPacket, Service};

/// Bytes from space-separated hex (`"5D 01 ff"`).
fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace()
        .map(|b| u8::from_str_radix(b, 16).unwrap())
        .collect()
}

/// A packet's wire form: header byte, then its data.
fn wire(p: &CrtpPacket) -> Vec<u8> {
    let mut out = [0u8; 32];
    let n = p.to_bytes(&mut out);
    out[..n].to_vec()
}

/// Sends raw uplink bytes straight to a service (header parsed as the router does); returns the reply's
/// wire form.
fn send<S: Service>(s: &mut S, bytes: &[u8]) -> Option<Vec<u8>> {
    let p = CrtpPacket::from_bytes(bytes).unwrap();
    s.handle(&p).map(|r| wire(&r))
}
