//! A `udp://HOST:PORT` link for crazyflie-lib: CRTP over UDP as cflib's UDP driver and `cfnav sim --serve`
//! speak it, plugged into crazyflie-link's public [`ConnectionTrait`].
//!
//! Job: carry CRTP packets between [`crazyflie_lib::Crazyflie`] and a simulator. crazyflie-link 0.5.1 only
//! knows `radio://` and `usb://` (docs/radio.md), but `Connection::new(Box<dyn ConnectionTrait>)` and
//! `Crazyflie::connect_from_link` are public, so this adapter is all a UDP transport needs.
//!
//! Framing (cflib `cflib/crtp/udpdriver.py`, docs/radio.md): one datagram is one CRTP packet,
//! `[header][0..=30 payload bytes]`, no length, no checksum, no connect or disconnect datagram. Received null
//! packets (`header & 0xF3 == 0xF3`: the answer to the `0xFF` probe, keep-alives) are not passed up.
//!
//! Non-goals: retries and flow control (UDP on localhost does not lose packets, and cflib does not resend
//! over UDP either); radio statistics ([`ConnectionTrait::link_statistics`] is `None`, as for USB).
//!
//! Link loss: the socket is connected to the peer, so a peer that is gone makes the kernel answer with ICMP
//! port-unreachable and the next receive fails with `ConnectionRefused`; the link then closes with that
//! reason (a frozen peer is not detected here: the caller pings).
//!
//! Memory: one socket, one 64-byte receive buffer per call, the status string.

use std::net::SocketAddr;
use std::sync::Mutex;
use std::time::Duration;

use async_trait::async_trait;
use crazyflie_lib::crazyflie_link::{
    ConnectionStatus, ConnectionTrait, Error as LinkError, Packet, RadioLinkStatistics,
};
use tokio::net::UdpSocket;
use tokio::sync::watch;

/// The largest CRTP packet: one header byte and 30 payload bytes (docs/radio.md, cflib
/// `CRTPPacket.MAX_DATA_SIZE`).
pub const MAX_PACKET_BYTES: usize = 31;
/// The scan probe and keep-alive cflib sends: a bare null header.
pub const NULL_PROBE: u8 = 0xFF;

/// Whether `header` is a null packet's (port 15, channel 3, any link bits), as the firmware's `crtp.h` tests
/// it: `(h & 0xF3) == 0xF3`.
pub fn is_null_header(header: u8) -> bool {
    header & 0xF3 == 0xF3
}

/// Splits `udp://HOST:PORT` (the port is required; IPv6 hosts in brackets) into its host and port.
pub fn parse_udp_uri(uri: &str) -> Result<(String, u16), String> {
    let rest = uri
        .strip_prefix("udp://")
        .ok_or_else(|| format!("{uri}: a UDP URI starts with udp://"))?;
    let rest = rest.trim_end_matches('/');
    let (host, port) = rest
        .rsplit_once(':')
        .ok_or_else(|| format!("{uri}: expected udp://HOST:PORT, e.g. udp://127.0.0.1:19850"))?;
    let host = host.trim_start_matches('[').trim_end_matches(']');
    if host.is_empty() {
        return Err(format!("{uri}: the host is missing (expected udp://HOST:PORT)"));
    }
    let port: u16 = port
        .parse()
        .map_err(|_| format!("{uri}: the port '{port}' is not a number in 1..=65535"))?;
    if port == 0 {
        return Err(format!("{uri}: the port must be in 1..=65535"));
    }
    Ok((host.to_string(), port))
}

/// A CRTP link over one connected UDP socket.
pub struct UdpLink {
    socket: UdpSocket,
    uri: String,
    status: Mutex<ConnectionStatus>,
    closed: watch::Sender<bool>,
}

impl UdpLink {
    /// Resolves `uri`, connects a socket to it and checks that something answers: a `0xFF` probe is sent
    /// (up to three times within `timeout`) and any reply counts, as in cflib's scan. A refused or silent
    /// peer is a one-line error.
    pub async fn open(uri: &str, timeout: Duration) -> Result<Self, String> {
        let (host, port) = parse_udp_uri(uri)?;
        let peer: SocketAddr = tokio::net::lookup_host((host.as_str(), port))
            .await
            .map_err(|e| format!("{uri}: cannot resolve {host}: {e}"))?
            .next()
            .ok_or_else(|| format!("{uri}: {host} has no address"))?;
        let local: SocketAddr = if peer.is_ipv4() {
            ([0, 0, 0, 0], 0).into()
        } else {
            ([0u16; 8], 0).into()
        };
        let socket = UdpSocket::bind(local)
            .await
            .map_err(|e| format!("{uri}: cannot open a UDP socket: {e}"))?;
        socket
            .connect(peer)
            .await
            .map_err(|e| format!("{uri}: cannot connect the UDP socket: {e}"))?;
        let link = Self {
            socket,
            uri: uri.to_string(),
            status: Mutex::new(ConnectionStatus::Connecting),
            closed: watch::Sender::new(false),
        };
        link.probe(timeout).await?;
        *link.status.lock().unwrap_or_else(|p| p.into_inner()) = ConnectionStatus::Connected;
        Ok(link)
    }

    async fn probe(&self, timeout: Duration) -> Result<(), String> {
        let tries = 3u32;
        let mut buf = [0u8; 64];
        let mut last_error = None;
        for _ in 0..tries {
            if let Err(e) = self.socket.send(&[NULL_PROBE]).await {
                last_error = Some(e);
                continue;
            }
            match tokio::time::timeout(timeout / tries, self.socket.recv(&mut buf)).await {
                Ok(Ok(_)) => return Ok(()),
                Ok(Err(e)) => last_error = Some(e),
                Err(_) => {}
            }
        }
        Err(match last_error {
            Some(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => {
                format!(
                    "{}: nothing listens there (connection refused); is `cfnav sim --serve` running?",
                    self.uri
                )
            }
            Some(e) => format!("{}: {e}", self.uri),
            None => format!("{}: no answer to the link probe within {timeout:?}", self.uri),
        })
    }

    /// Marks the link closed with `reason` (the first reason wins).
    fn close_with(&self, reason: String) {
        {
            let mut status = self.status.lock().unwrap_or_else(|p| p.into_inner());
            if !matches!(*status, ConnectionStatus::Disconnected(_)) {
                *status = ConnectionStatus::Disconnected(reason);
            }
        }
        self.closed.send_replace(true);
    }

    fn is_closed(&self) -> bool {
        *self.closed.borrow()
    }

    async fn wait_closed(&self) {
        let mut rx = self.closed.subscribe();
        // An error means the sender is gone, i.e. the link is being dropped: closed as well.
        let _ = rx.wait_for(|closed| *closed).await;
    }

    fn disconnected_error() -> LinkError {
        LinkError::ChannelRecvError(flume::RecvError::Disconnected)
    }
}

#[async_trait]
impl ConnectionTrait for UdpLink {
    async fn wait_close(&self) -> String {
        self.wait_closed().await;
        match self.status().await {
            ConnectionStatus::Disconnected(reason) => reason,
            _ => "closed".to_string(),
        }
    }

    async fn close(&self) {
        self.close_with("closed by the client".to_string());
    }

    async fn status(&self) -> ConnectionStatus {
        self.status.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    async fn wait_disconnect(&self) {
        self.wait_closed().await;
    }

    async fn send_packet(&self, packet: Packet) -> crazyflie_lib::crazyflie_link::error::Result<()> {
        if self.is_closed() {
            return Err(Self::disconnected_error());
        }
        let bytes: Vec<u8> = packet.into();
        if bytes.is_empty() || bytes.len() > MAX_PACKET_BYTES {
            return Err(LinkError::InvalidData);
        }
        match self.socket.send(&bytes).await {
            Ok(_) => Ok(()),
            Err(e) => {
                self.close_with(format!("{}: send failed: {e}", self.uri));
                Err(Self::disconnected_error())
            }
        }
    }

    async fn recv_packet(&self) -> crazyflie_lib::crazyflie_link::error::Result<Packet> {
        let mut buf = [0u8; 64];
        loop {
            if self.is_closed() {
                return Err(Self::disconnected_error());
            }
            let received = tokio::select! {
                r = self.socket.recv(&mut buf) => r,
                _ = self.wait_closed() => return Err(Self::disconnected_error()),
            };
            match received {
                Ok(0) => continue,
                Ok(n) => {
                    let n = n.min(buf.len());
                    if is_null_header(buf[0]) || n > MAX_PACKET_BYTES {
                        continue;
                    }
                    return Ok(Packet::from(buf[..n].to_vec()));
                }
                Err(e) => {
                    let reason = if e.kind() == std::io::ErrorKind::ConnectionRefused {
                        format!("{}: the simulator is gone (connection refused)", self.uri)
                    } else {
                        format!("{}: receive failed: {e}", self.uri)
                    };
                    self.close_with(reason);
                    return Err(Self::disconnected_error());
                }
            }
        }
    }

    async fn link_statistics(&self) -> Option<RadioLinkStatistics> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn null_headers_follow_the_firmware_test() {
        // crtp.h: a null packet is port 15 channel 3 whatever the two link bits are.
        for h in [0xF3u8, 0xF7, 0xFB, 0xFF] {
            assert!(is_null_header(h), "{h:#04x}");
        }
        // Port 15 channels 0..2 (link echo, source, sink) and port 2 channel 3 are real packets.
        for h in [0xF0u8, 0xF1, 0xF2, 0xFC, 0x23, 0x2F, 0x00] {
            assert!(!is_null_header(h), "{h:#04x}");
        }
    }

    #[test]
    fn uri_parsing() {
        assert_eq!(
            parse_udp_uri("udp://127.0.0.1:19850").unwrap(),
            ("127.0.0.1".into(), 19850)
        );
        assert_eq!(
            parse_udp_uri("udp://localhost:19851/").unwrap(),
            ("localhost".into(), 19851)
        );
        assert_eq!(parse_udp_uri("udp://[::1]:19850").unwrap(), ("::1".into(), 19850));
        for bad in [
            "radio://0/80/2M",
            "udp://127.0.0.1",
            "udp://:19850",
            "udp://h:0",
            "udp://h:70000",
            "udp://h:x",
        ] {
            assert!(parse_udp_uri(bad).is_err(), "{bad}");
        }
    }

    /// Over a real loopback socket: the probe, header framing both ways, null packets filtered, and a vanished
    /// peer closing the link.
    #[tokio::test]
    async fn frames_one_packet_per_datagram() {
        let peer = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        peer.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        let port = peer.local_addr().unwrap().port();
        let uri = format!("udp://127.0.0.1:{port}");
        let server = std::thread::spawn(move || {
            let mut buf = [0u8; 64];
            // The probe: one byte 0xFF, answered with 0xFF.
            let (n, from) = peer.recv_from(&mut buf).unwrap();
            assert_eq!(&buf[..n], &[NULL_PROBE]);
            peer.send_to(&[NULL_PROBE], from).unwrap();
            // A param write, port 2 channel 2: header 0x22, then the payload as is.
            let (n, from) = peer.recv_from(&mut buf).unwrap();
            let got = buf[..n].to_vec();
            // A null packet first (must be skipped), then a reply with the link bits set as the firmware does.
            peer.send_to(&[0xF3], from).unwrap();
            peer.send_to(&[0x2E, 0x01, 0x00, 0x42], from).unwrap();
            got
        });
        let link = UdpLink::open(&uri, Duration::from_secs(2)).await.unwrap();
        link.send_packet(Packet::new(2, 2, vec![0x01, 0x00, 0x42]))
            .await
            .unwrap();
        let reply = link.recv_packet().await.unwrap();
        assert_eq!(server.join().unwrap(), vec![0x22, 0x01, 0x00, 0x42]);
        assert_eq!((reply.get_port(), reply.get_channel()), (2, 2));
        assert_eq!(reply.get_data(), &vec![0x01, 0x00, 0x42]);
        // The peer's socket is closed now: the next send draws an ICMP error and the link closes.
        let _ = link.send_packet(Packet::new(15, 0, vec![1])).await;
        let r = tokio::time::timeout(Duration::from_secs(2), link.recv_packet())
            .await
            .unwrap();
        assert!(r.is_err());
        assert!(matches!(link.status().await, ConnectionStatus::Disconnected(_)));
    }

    #[tokio::test]
    async fn nothing_listening_is_a_clear_error() {
        // Bind and drop: the port is (almost surely) free for the moment of the test.
        let port = std::net::UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let e = UdpLink::open(&format!("udp://127.0.0.1:{port}"), Duration::from_millis(600))
            .await
            .err()
            .expect("nothing listens there");
        assert!(e.contains("connection refused"), "{e}");
    }
}
