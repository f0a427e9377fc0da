//! The radio host as a UDP socket: cflib's `udp://` link talks to the emulated image
//! as it does to `cfnav sim --serve`.
//!
//! Job: bind a UDP socket, take datagrams without blocking (one datagram = one CRTP packet `[header, data…]`,
//! no length or checksum: docs/radio.md, the framing `tools/src/sim/serve.rs`
//! uses), remember the latest client, send the image's packets to it. A null packet (a bare 0xFF scan probe,
//! `0xF3`/`0xF4`) is answered with 0xFF at once, as `sim --serve` does, so cflib's scan finds the emulator.
//! Non-goals: more than one client, retries (cflib's UDP driver has none; nor does this). Memory: one
//! 64-byte receive buffer.

use std::net::{SocketAddr, UdpSocket};

use anyhow::{Context, Result};
use cfnav::radio::crtp::is_null_header;

/// The bound socket and the client that last sent a CRTP packet.
pub struct UdpBridge {
    socket: UdpSocket,
    client: Option<SocketAddr>,
    /// Datagrams received (null probes included).
    pub received: u64,
    /// Datagrams sent.
    pub sent: u64,
}

impl UdpBridge {
    /// Binds `addr` (e.g. `127.0.0.1:19850`), non-blocking.
    pub fn bind(addr: &str) -> Result<Self> {
        let socket = UdpSocket::bind(addr).with_context(|| format!("cannot bind UDP {addr}"))?;
        socket.set_nonblocking(true).context("non-blocking UDP socket")?;
        Ok(Self {
            socket,
            client: None,
            received: 0,
            sent: 0,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.socket.local_addr().ok()
    }

    /// Whether a client has sent a CRTP packet (the radio host is "connected" and polls).
    pub fn has_client(&self) -> bool {
        self.client.is_some()
    }

    /// Every CRTP packet waiting on the socket, in order; null probes are answered here and not returned.
    pub fn receive(&mut self) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        let mut buf = [0u8; 64];
        loop {
            match self.socket.recv_from(&mut buf) {
                Ok((n, from)) => {
                    self.received += 1;
                    let d = &buf[..n];
                    let probe = d.len() == 1 && is_null_header(d[0]);
                    if probe {
                        if self.socket.send_to(&[0xFF], from).is_ok() {
                            self.sent += 1;
                        }
                    } else if !d.is_empty() {
                        self.client = Some(from);
                        out.push(d.to_vec());
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => break,
                Err(_) => break,
            }
        }
        out
    }

    /// Sends one CRTP packet to the client, if there is one.
    pub fn send(&mut self, crtp: &[u8]) {
        if let Some(to) = self.client
            && self.socket.send_to(crtp, to).is_ok()
        {
            self.sent += 1;
        }
    }
}
