//! Connecting crazyflie-lib to a link URI: the one connection step `cfnav map` and `cfnav mission` share.
//!
//! Job: `udp://` through [`UdpLink`] (crazyflie-link has no UDP link), `radio://` and `usb://` through
//! crazyflie-link once libusb is known to start, the whole connection bounded by a timeout. Non-goals: no
//! URI validation beyond the scheme (the callers check their own forms and word their own errors).

use std::time::Duration;

use crazyflie_lib::Crazyflie;
use crazyflie_lib::crazyflie_link::{Connection, LinkContext};

use super::toc_cache::DirTocCache;
use super::udp_link::UdpLink;

/// Why [`connect_uri`] gave no connection.
#[derive(Debug)]
pub enum ConnectError {
    /// The link could not be opened: the `udp://` socket, or libusb for a `radio://`/`usb://` link (the text
    /// says which, with the URI).
    Open(String),
    /// crazyflie-lib's own error.
    Link(crazyflie_lib::Error),
    /// Not connected within the timeout.
    TimedOut,
}

/// Connects to `uri` within `timeout`: `udp://` over [`UdpLink`] (opened within min(timeout, 3 s)), any other
/// URI through crazyflie-link after checking that libusb starts (rusb panics if its global context cannot).
pub async fn connect_uri(uri: &str, timeout: Duration, cache: DirTocCache) -> Result<Crazyflie, ConnectError> {
    let connected = if uri.starts_with("udp://") {
        let link = UdpLink::open(uri, timeout.min(Duration::from_secs(3)))
            .await
            .map_err(ConnectError::Open)?;
        tokio::time::timeout(
            timeout,
            Crazyflie::connect_from_link(Connection::new(Box::new(link)), cache),
        )
        .await
    } else {
        // rusb panics if its global libusb context cannot start: ask libusb first, with a context of our own.
        if let Err(e) = rusb::Context::new() {
            return Err(ConnectError::Open(format!(
                "{uri}: USB is not available here (libusb: {e}); a radio:// link needs a Crazyradio on USB"
            )));
        }
        let context = LinkContext::new();
        tokio::time::timeout(timeout, Crazyflie::connect_from_uri(&context, uri, cache)).await
    };
    match connected {
        Ok(Ok(cf)) => Ok(cf),
        Ok(Err(e)) => Err(ConnectError::Link(e)),
        Err(_) => Err(ConnectError::TimedOut),
    }
}
