//! The STM32's syslink transmit side: frames cut into short chunks with the nRF51's flow-control line
//! re-checked before each ([`FlowTx`]), the boot settings confirmed by their echoes and resent if missing
//! ([`BootSettings`]), and the nRF firmware version request and reply ([`nrf_version_request`],
//! [`nrf_version`]).
//!
//! Why chunks: the nRF51 drives its RTS (the STM32's PA4, high = stop) from its UART's hardware flow
//! control (`NRF_UART0->CONFIG = HWFC`, bitcraze crazyflie2-nrf-firmware `src/uart.c`), which deactivates
//! RTS when its RX FIFO can take only four more bytes (nRF51 Series Reference Manual v3.0, UART "Flow
//! control"); its receive interrupt drains the FIFO into a 128-byte queue but is held off while the
//! SoftDevice runs Bluetooth. A frame is up to 70 bytes: checking PA4 only before a frame (as this firmware
//! did) overruns the FIFO whenever RTS rises inside one. The stock firmware pauses its TX DMA from the PA4
//! edge interrupt (crazyflie-firmware `src/drivers/src/uart_syslink.c`, `uartslkPauseDma`); here the caller
//! sends at most [`CHUNK`] bytes after seeing PA4 low and waits until they have left the shift register
//! (USART TC) before looking again, so at most [`CHUNK`] bytes arrive after RTS rises.
//!
//! Why echoes: the nRF answers RADIO_CHANNEL, RADIO_DATARATE and RADIO_ADDRESS with the same packet
//! (crazyflie2-nrf-firmware `src/main.c`, `handleSyslinkEvents`); a setting lost on the wire (or sent before
//! the nRF listened) leaves the radio on its defaults, so each is resent until its echo arrives.
//!
//! Non-goals: no UART, pin or clock (the caller moves the bytes, reads PA4 and passes `now_ms`).
//!
//! Units: ms. Memory: [`FlowTx`] holds one 70-byte frame; [`BootSettings`] three packets (≈ 210 bytes).

use heapless::Vec;

use super::syslink::{EncodeError, MAX_FRAME, SyslinkPacket, encode, kind};

/// Bytes sent per PA4 check: the nRF51's RX FIFO accepts four more bytes after it deactivates RTS.
pub const CHUNK: usize = 4;

/// What the caller does next for the frame in [`FlowTx`].
#[derive(Debug, PartialEq, Eq)]
pub enum TxStep<'a> {
    /// Send these bytes, wait until the UART has shifted them all out, then call [`FlowTx::sent`].
    Send(&'a [u8]),
    /// PA4 is high: wait for it to fall (or give up with [`FlowTx::abandon`]), then ask again.
    WaitForClear,
    /// The frame has been sent (or nothing is loaded).
    Done,
}

/// Counters of [`FlowTx`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TxStats {
    /// Frames sent whole.
    pub frames: u32,
    /// Times PA4 was found high before a chunk.
    pub paused: u32,
    /// Times PA4 was found high inside a frame (after its first chunk): what per-frame checking missed.
    pub paused_mid_frame: u32,
    /// Frames given up part-way (or before their first byte).
    pub abandoned: u32,
}

/// One frame at a time, cut into chunks of at most `chunk` bytes with a flow-control check before each.
#[derive(Debug, Clone)]
pub struct FlowTx {
    frame: [u8; MAX_FRAME],
    len: usize,
    pos: usize,
    chunk: usize,
    stats: TxStats,
}

impl Default for FlowTx {
    fn default() -> Self {
        Self::new()
    }
}

impl FlowTx {
    /// A transmitter with [`CHUNK`]-byte chunks.
    pub const fn new() -> Self {
        Self::with_chunk(CHUNK)
    }

    /// A transmitter with chunks of `chunk` bytes (clamped to 1..=[`MAX_FRAME`]; [`MAX_FRAME`] is the old
    /// whole-frame behaviour, kept for comparison in the tests).
    pub const fn with_chunk(chunk: usize) -> Self {
        let chunk = if chunk == 0 {
            1
        } else if chunk > MAX_FRAME {
            MAX_FRAME
        } else {
            chunk
        };
        Self {
            frame: [0; MAX_FRAME],
            len: 0,
            pos: 0,
            chunk,
            stats: TxStats {
                frames: 0,
                paused: 0,
                paused_mid_frame: 0,
                abandoned: 0,
            },
        }
    }

    /// Encodes `packet` as the frame to send. A frame still in progress is abandoned (and counted).
    pub fn load(&mut self, packet: &SyslinkPacket) -> Result<(), EncodeError> {
        if self.pos < self.len {
            self.abandon();
        }
        self.len = 0;
        self.pos = 0;
        self.len = encode(packet, &mut self.frame)?;
        Ok(())
    }

    /// The next step, given the PA4 level now (`true` = high = the nRF asks to stop).
    pub fn next(&mut self, rts_high: bool) -> TxStep<'_> {
        if self.pos >= self.len {
            return TxStep::Done;
        }
        if rts_high {
            self.stats.paused = self.stats.paused.saturating_add(1);
            if self.pos > 0 {
                self.stats.paused_mid_frame = self.stats.paused_mid_frame.saturating_add(1);
            }
            return TxStep::WaitForClear;
        }
        let end = (self.pos + self.chunk).min(self.len);
        TxStep::Send(&self.frame[self.pos..end])
    }

    /// The caller sent `n` bytes of the chunk [`next`](Self::next) gave (all of it, normally).
    pub fn sent(&mut self, n: usize) {
        if self.pos >= self.len {
            return;
        }
        let end = (self.pos + self.chunk).min(self.len);
        self.pos = (self.pos + n).min(end);
        if self.pos == self.len {
            self.stats.frames = self.stats.frames.saturating_add(1);
        }
    }

    /// Gives the rest of the frame up (PA4 held too long, or the UART failed); returns the bytes dropped.
    pub fn abandon(&mut self) -> usize {
        let dropped = self.len - self.pos;
        if dropped > 0 {
            self.stats.abandoned = self.stats.abandoned.saturating_add(1);
        }
        self.pos = self.len;
        dropped
    }

    /// Bytes of the frame not sent yet.
    pub fn remaining(&self) -> usize {
        self.len - self.pos
    }

    /// The counters.
    pub fn stats(&self) -> TxStats {
        self.stats
    }
}

/// How long an echo may take before the setting is sent again, ms (the nRF answers within its main loop,
/// well under a millisecond when idle; Bluetooth start-up can hold it for tens of ms).
pub const ECHO_TIMEOUT_MS: u32 = 100;
/// Sends of each setting before giving up (the radio then keeps the nRF's own setting).
pub const MAX_SENDS: u8 = 5;

/// Where one boot setting stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SettingState {
    /// Not sent yet.
    Unsent,
    /// Sent `sends` times, the last at `at_ms`; no echo yet.
    Sent {
        /// Time of the last send, ms.
        at_ms: u32,
        /// Sends so far.
        sends: u8,
    },
    /// The nRF echoed it.
    Confirmed,
    /// [`MAX_SENDS`] sends without an echo.
    GaveUp,
}

/// The radio settings sent at boot (RADIO_CHANNEL, RADIO_DATARATE, RADIO_ADDRESS), each until its echo.
#[derive(Debug, Clone)]
pub struct BootSettings {
    packets: Vec<(SyslinkPacket, SettingState), 3>,
}

/// The packet kinds the nRF echoes back unchanged.
fn echoed(kind_: u8) -> bool {
    matches!(kind_, kind::RADIO_CHANNEL | kind::RADIO_DATARATE | kind::RADIO_ADDRESS)
}

impl BootSettings {
    /// Tracks the echoed packets among `packets` (others are ignored; at most three are kept).
    pub fn new(packets: &[SyslinkPacket]) -> Self {
        let mut kept = Vec::new();
        for p in packets.iter().filter(|p| echoed(p.kind)) {
            if kept.push((p.clone(), SettingState::Unsent)).is_err() {
                break;
            }
        }
        Self { packets: kept }
    }

    /// The next packet to send now (first sends, then resends after [`ECHO_TIMEOUT_MS`]); it is counted as
    /// sent at `now_ms`.
    pub fn poll(&mut self, now_ms: u32) -> Option<SyslinkPacket> {
        for (packet, state) in self.packets.iter_mut() {
            let sends = match *state {
                SettingState::Unsent => 0,
                SettingState::Sent { at_ms, sends } if now_ms.wrapping_sub(at_ms) >= ECHO_TIMEOUT_MS => {
                    if sends >= MAX_SENDS {
                        *state = SettingState::GaveUp;
                        continue;
                    }
                    sends
                }
                _ => continue,
            };
            *state = SettingState::Sent {
                at_ms: now_ms,
                sends: sends + 1,
            };
            return Some(packet.clone());
        }
        None
    }

    /// A received packet: returns `true` if it confirmed a setting (same kind and payload as sent). An echo
    /// with a different payload confirms nothing, so the setting goes out again.
    pub fn on_received(&mut self, received: &SyslinkPacket) -> bool {
        for (packet, state) in self.packets.iter_mut() {
            if packet.kind == received.kind
                && matches!(state, SettingState::Sent { .. })
                && packet.payload == received.payload
            {
                *state = SettingState::Confirmed;
                return true;
            }
        }
        false
    }

    /// Every setting is confirmed or given up.
    pub fn is_settled(&self) -> bool {
        self.packets
            .iter()
            .all(|(_, s)| matches!(s, SettingState::Confirmed | SettingState::GaveUp))
    }

    /// The state of the setting of packet kind `kind_`, if tracked.
    pub fn state(&self, kind_: u8) -> Option<SettingState> {
        self.packets.iter().find(|(p, _)| p.kind == kind_).map(|(_, s)| *s)
    }

    /// Settings confirmed so far.
    pub fn confirmed(&self) -> usize {
        self.packets
            .iter()
            .filter(|(_, s)| *s == SettingState::Confirmed)
            .count()
    }

    /// Settings given up.
    pub fn gave_up(&self) -> usize {
        self.packets.iter().filter(|(_, s)| *s == SettingState::GaveUp).count()
    }
}

/// SYS_NRF_VERSION with no payload: the nRF answers with its version string (stock `systemRequestNRFVersion`).
pub fn nrf_version_request() -> SyslinkPacket {
    SyslinkPacket {
        kind: kind::SYS_NRF_VERSION,
        payload: Vec::new(),
    }
}

/// The version text of a SYS_NRF_VERSION reply (e.g. `2025.02 (NRF51)`), up to its NUL terminator; `None` for
/// another kind or text that is not UTF-8.
pub fn nrf_version(packet: &SyslinkPacket) -> Option<&str> {
    if packet.kind != kind::SYS_NRF_VERSION {
        return None;
    }
    let bytes = &packet.payload;
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    core::str::from_utf8(&bytes[..end]).ok()
}
