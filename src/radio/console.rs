//! The console, CRTP port 0 channel 0: text from the firmware to the client, in packets of ≤ 30 bytes.
//!
//! Job: collect text ([`ConsoleService::print`], [`ConsoleService::write_line`], `core::fmt::Write`), cut it
//! into console packets the way the stock console does, and hand them out one per downlink opportunity
//! ([`ConsoleService::next_packet`]).
//!
//! Non-goals: no uplink (stock ignores packets to port 0; so does this service), no timed flush (stock
//! flushes a partial packet from a timer; here the caller calls [`ConsoleService::flush`]), no character
//! encoding checks (bytes are sent as given; a multi-byte UTF-8 character may straddle two packets, cflib
//! reassembles the text per packet, as with stock).
//!
//! Format (`docs/hardware.md` §4: "ch0: text chunks ≤ 30 bytes, no terminator"; firmware
//! `src/modules/src/console.c` `consolePutchar`): bytes accumulate in the current packet, which is sent when
//! it holds 30 bytes or right after a `'\n'` (the newline is part of the packet).
//!
//! Overflow policy: the queue holds `N` finished packets. A line handed over whole (`write_line`, or a
//! newline-terminated piece of `print` text that starts a fresh line) is queued only if all its packets fit:
//! otherwise the **whole line is dropped** and [`ConsoleService::dropped_lines`] counts it. Text printed in
//! pieces without a newline goes out 30 bytes at a time as in stock; if such a packet finds the queue full,
//! the rest of that line (up to its newline) is dropped and counted once: the client may then see the line's
//! first packets without an end. Nothing already queued is ever discarded.
//!
//! Memory: `N` + 1 packet buffers of 30 bytes plus a length each, and the queue's indices: 720 bytes for
//! `N` = 16 on the 64-bit host (less on the MCU, where lengths are 4 bytes).

use core::fmt;

use heapless::{Deque, Vec};

use super::crtp::{CrtpPacket, MAX_DATA, Service};

/// Console port.
pub const PORT_CONSOLE: u8 = 0;
/// Console channel.
pub const CH_CONSOLE: u8 = 0;

/// The console service with a queue of `N` packets.
#[derive(Debug, Clone)]
pub struct ConsoleService<const N: usize> {
    queue: Deque<Vec<u8, MAX_DATA>, N>,
    current: Vec<u8, MAX_DATA>,
    /// The rest of the current line is being dropped (a packet of it found the queue full).
    dropping: bool,
    dropped_lines: u32,
    sent: u32,
}

impl<const N: usize> Default for ConsoleService<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> ConsoleService<N> {
    /// An empty console.
    pub const fn new() -> Self {
        Self {
            queue: Deque::new(),
            current: Vec::new(),
            dropping: false,
            dropped_lines: 0,
            sent: 0,
        }
    }

    /// Lines (or line remainders) dropped because the queue was full.
    pub fn dropped_lines(&self) -> u32 {
        self.dropped_lines
    }

    /// Packets handed out so far.
    pub fn sent_packets(&self) -> u32 {
        self.sent
    }

    /// Finished packets waiting.
    pub fn pending(&self) -> usize {
        self.queue.len()
    }

    /// Bytes waiting in the packet being filled.
    pub fn partial_len(&self) -> usize {
        self.current.len()
    }

    /// Writes `text` followed by a newline (dropped whole if it does not fit, see the module docs).
    pub fn write_line(&mut self, text: &str) {
        let bytes = text.as_bytes();
        // Lines inside `text` go out as `print` would send them; the last one ends with the added newline.
        let split = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        self.print_bytes(&bytes[..split]);
        self.finish_line(&bytes[split..]);
    }

    /// Writes `text`: complete lines are queued whole or dropped whole; an unterminated tail waits in the
    /// current packet (sent when it fills up, on its newline, or on [`flush`](Self::flush)).
    pub fn print(&mut self, text: &str) {
        self.print_bytes(text.as_bytes());
    }

    /// Sends the partly filled packet now (stock `consoleFlush`), if the queue has room.
    pub fn flush(&mut self) {
        if !self.current.is_empty() && self.queue.push_back(self.current.clone()).is_ok() {
            self.current.clear();
        }
    }

    /// The next console packet for the downlink, if any.
    pub fn next_packet(&mut self) -> Option<CrtpPacket> {
        let data = self.queue.pop_front()?;
        // A full packet that found the queue full waits in `current`: it takes the freed place.
        if self.current.is_full() {
            let _ = self.queue.push_back(core::mem::take(&mut self.current));
        }
        self.sent = self.sent.saturating_add(1);
        Some(CrtpPacket {
            port: PORT_CONSOLE,
            channel: CH_CONSOLE,
            data,
        })
    }

    fn free(&self) -> usize {
        N - self.queue.len()
    }

    fn print_bytes(&mut self, mut bytes: &[u8]) {
        while !bytes.is_empty() {
            let (piece, ends_line) = match bytes.iter().position(|&b| b == b'\n') {
                Some(i) => (&bytes[..=i], true),
                None => (bytes, false),
            };
            bytes = &bytes[piece.len()..];
            if ends_line {
                self.finish_line(&piece[..piece.len() - 1]);
            } else if self.dropping {
                continue;
            } else if !self.append(piece) {
                // A full packet of an unterminated line found the queue full: drop the rest of the line.
                self.current.clear();
                self.dropping = true;
                self.dropped_lines = self.dropped_lines.saturating_add(1);
            }
        }
    }

    /// Ends the current line with `body` and a newline: all its packets are queued, or none (counted as a
    /// dropped line). A line already being dropped just ends.
    fn finish_line(&mut self, body: &[u8]) {
        if self.dropping {
            self.dropping = false;
            return;
        }
        let packets = (self.current.len() + body.len() + 1).div_ceil(MAX_DATA);
        if packets > self.free() {
            self.current.clear();
            self.dropped_lines = self.dropped_lines.saturating_add(1);
            return;
        }
        self.append(body);
        self.append(b"\n");
        // `append` pushed every full packet; the newline ends the last one.
        if !self.current.is_empty() {
            let _ = self.queue.push_back(core::mem::take(&mut self.current));
        }
    }

    /// Appends bytes, pushing each packet that fills up; false if a full packet found the queue full.
    fn append(&mut self, bytes: &[u8]) -> bool {
        for &b in bytes {
            if self.current.is_full() {
                if self.queue.is_full() {
                    return false;
                }
                let _ = self.queue.push_back(core::mem::take(&mut self.current));
            }
            let _ = self.current.push(b);
        }
        if self.current.is_full() {
            if self.queue.is_full() {
                // Keep it: it goes out with the next packet opportunity that finds room.
                return true;
            }
            let _ = self.queue.push_back(core::mem::take(&mut self.current));
        }
        true
    }
}

impl<const N: usize> fmt::Write for ConsoleService<N> {
    /// Never fails: text that does not fit is dropped and counted.
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.print(s);
        Ok(())
    }
}

impl<const N: usize> Service for ConsoleService<N> {
    fn port(&self) -> u8 {
        PORT_CONSOLE
    }

    /// Uplink console packets are ignored (stock has no console input).
    fn handle(&mut self, _packet: &CrtpPacket) -> Option<CrtpPacket> {
        None
    }
}
