//! The radio protocol layer: the syslink wire codec to the nRF51, the CRTP packet layer above it, and the
//! generic CRTP services, with the stock firmware's exact byte layouts.
//!
//! Job: turn bytes into packets and packets into bytes, and answer the CRTP services every client needs
//! before anything else (link port 15, platform port 13). Services plug into [`crtp::Router`] through
//! [`crtp::Service`]: the parameter protocol [`param::ParamService`] (port 2) over a
//! [`param_decl::ParamStore`], the log protocol [`log::LogService`] (port 5) over a
//! [`log_decl::LogSource`] (both TOCs share [`toc`] and [`wire_type`]), the memory service
//! [`mem::MemService`] (port 4), the commander ports 3 and 7 through [`commander::CommanderService::ports`]
//! (decoded setpoint commands with the RPYT thrust lock; [`commander::SetpointFollower`] maps them to
//! [`crate::types::Setpoint`]) and the console port 0 [`console::ConsoleService`] (text lines cut into
//! ≤ 30-byte packets, handed out one per downlink opportunity). [`syslink_tx`] is the transmit side towards
//! the nRF51: frames in flow-controlled chunks, the boot settings confirmed by their echoes, the nRF
//! version.
//!
//! Non-goals: which parameters, log variables and memories cfnav has, and the ports that command the
//! flight (high-level commander, supervisor): that is [`crate::radio_binding`]; this layer never imports
//! `mission`, `flight` or `nav`. No UART, DMA, flow-control pin or UDP socket (the caller moves bytes), no
//! clock (the caller passes `now_ms`).
//!
//! Sources: `docs/hardware.md` §4 (syslink and CRTP, the setpoint watchdog), `docs/radio.md` (what cflib
//! sends and expects, protocol version 12).
//!
//! Memory: everything is fixed-size (`heapless`); the largest object is the syslink decoder's 70-byte frame
//! buffer, the router's reply queue (`Q` × 32 bytes) and the console queue (`N` × 31 bytes).

pub mod commander;
pub mod console;
pub mod crtp;
pub mod log;
pub mod log_decl;
pub mod mem;
pub mod param;
pub mod param_decl;
pub mod syslink;
pub mod syslink_tx;
pub mod toc;
pub mod wire_type;
