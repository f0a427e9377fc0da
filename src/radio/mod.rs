//! The radio side of the firmware: the syslink wire codec to the nRF51 and the CRTP packet layer above it.
//!
//! Job: turn bytes into packets and packets into bytes, and answer the CRTP services every client needs
//! before anything else (link port 15, platform port 13), with the stock firmware's exact byte layouts.
//!
//! Non-goals: no UART, DMA, flow-control pin or UDP socket (the caller moves bytes), no clock (the caller
//! passes `now_ms`). Services plug into [`crtp::Router`] through [`crtp::Service`]: the parameter protocol is
//! [`param::ParamService`] (port 2) over a [`param_decl::ParamStore`], the log protocol [`log::LogService`]
//! (port 5) over a [`log_registry::LogSource`], the memory service [`mem::MemService`] (port 4: the count, and the map of [`map_mem`] where the owner serves it), the commander
//! ports 3 and 7 through [`commander::CommanderService::ports`] (decoded setpoint commands with the RPYT
//! thrust lock; [`commander::SetpointFollower`] maps them to [`crate::types::Setpoint`]), the high-level
//! commander port 8 [`high_level::HighLevelService`] (take-off, land, go-to, stop, group masks), the supervisor port 9
//! [`supervisor_port::SupervisorPortService`] (state bits, arming, recovery, emergency stop and its watchdog,
//! as requests for the caller) and the console port 0 [`console::ConsoleService`] (text lines cut into
//! ≤ 30-byte packets, handed out one per downlink opportunity). [`syslink_tx`] is the transmit side towards the
//! nRF51: frames in flow-controlled chunks, the boot settings confirmed by their echoes, the nRF version.
//!
//! Sources: `/work/shared/reference/crazyflie-hardware.md` §3 (syslink), §4 (CRTP) and §10 (setpoint
//! watchdog, emergency stop),
//! `/work/shared/reference/crtp-over-udp.md` §1–§2 (what cflib sends and expects), and
//! `/work/shared/spec/interfaces.md` §5 (protocol version 12).
//!
//! Memory: everything is fixed-size (`heapless`); the largest object is the syslink decoder's 70-byte frame
//! buffer, the router's reply queue (`Q` × 32 bytes) and the console queue (`N` × 31 bytes).

pub mod commander;
pub mod console;
pub mod crtp;
pub mod endpoint;
pub mod high_level;
pub mod log;
pub mod log_registry;
pub mod map_mem;
pub mod mem;
pub mod param;
pub mod param_decl;
pub mod param_state;
pub mod param_table;
pub mod supervisor_port;
pub mod syslink;
pub mod syslink_tx;
pub mod toc;
pub mod tuning;
pub mod wire_type;
