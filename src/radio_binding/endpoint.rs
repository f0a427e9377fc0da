//! The CRTP services every cfnav endpoint answers — the drone over the syslink, the simulator over UDP and
//! the router fuzz target — gathered in one place, so all of them dispatch exactly the same ports in the
//! same order.
//!
//! Job: own one endpoint's router and services and hand each uplink packet to them at the caller's time;
//! remember when the latest uplink packet came ([`Endpoint::last_uplink_us`]: the link-loss watch's input,
//! `crate::mission::link_loss`).
//! Non-goals: transport, the clock, what the caller does with commander setpoints, supervisor requests or
//! `mission.start` (each endpoint reads those from the public services afterwards).
//! Memory: the router's reply queue (`Q` × 32 bytes), the console queue (`C` × 31 bytes) and the services'
//! own fixed state; nothing is allocated.

use crate::radio::commander::CommanderService;
use crate::radio::console::ConsoleService;
use crate::radio::crtp::{CrtpPacket, PlatformService, Router, Service};
use crate::radio::log::LogService;
use crate::radio::log_decl::LogSource;
use crate::radio::mem::MemService;
use crate::radio::param::ParamService;
use crate::radio::param_decl::ParamStore;
use crate::types::Micros;

use super::high_level::HighLevelService;
use super::supervisor_port::{SupervisorPortConfig, SupervisorPortService};

/// One endpoint's router and services: parameters (port 2), logs (5), memory (4), commander (3 and 7),
/// high-level commander (8), supervisor (9) and console (0); link (15) and platform (13) live in the router.
pub struct Endpoint<P: ParamStore, L: LogSource, const C: usize, const Q: usize> {
    /// The router (link and platform services, reply queue).
    pub router: Router<Q>,
    /// Parameter service.
    pub param: ParamService<P>,
    /// Log service.
    pub log: LogService<L>,
    /// Memory service (no memories unless the endpoint's owner serves the map: `MemService::with_map`).
    pub mem: MemService,
    /// Setpoint commander (ports 3 and 7).
    pub commander: CommanderService,
    /// High-level commander (port 8).
    pub high_level: HighLevelService,
    /// Supervisor port.
    pub supervisor: SupervisorPortService,
    /// Console.
    pub console: ConsoleService<C>,
    /// When the latest uplink packet (any port, null packets too) arrived, µs.
    last_uplink_us: Option<Micros>,
}

impl<P: ParamStore, L: LogSource, const C: usize, const Q: usize> Endpoint<P, L, C, Q> {
    /// An endpoint reporting `firmware_tag` on the platform port, with this parameter store and supervisor
    /// port configuration; logs, console and commander start empty.
    pub fn new(firmware_tag: &'static str, store: P, supervisor: SupervisorPortConfig) -> Self {
        Self {
            router: Router::new(PlatformService::new(firmware_tag)),
            param: ParamService::new(store),
            log: LogService::new(),
            mem: MemService::new(),
            commander: CommanderService::new(),
            high_level: HighLevelService::new(),
            supervisor: SupervisorPortService::new(supervisor),
            console: ConsoleService::new(),
            last_uplink_us: None,
        }
    }

    /// When the latest uplink packet arrived (through [`Self::handle_uplink`] or [`Self::note_uplink`]), µs.
    pub fn last_uplink_us(&self) -> Option<Micros> {
        self.last_uplink_us
    }

    /// An uplink packet the caller answered itself (e.g. a null packet) arrived at `now_us`: the link is alive.
    pub fn note_uplink(&mut self, now_us: Micros) {
        if self.last_uplink_us.is_none_or(|t| now_us > t) {
            self.last_uplink_us = Some(now_us);
        }
    }

    /// Dispatches one uplink packet (`bytes`, header first) received at `now_us` (the commander and the
    /// supervisor port time-stamp what it carries); returns the reply, if any.
    pub fn handle_uplink(&mut self, bytes: &[u8], now_us: Micros) -> Option<CrtpPacket> {
        self.note_uplink(now_us);
        self.commander.set_now(now_us);
        self.supervisor.set_now(now_us);
        self.high_level.set_now(now_us);
        let [mut rpyt, mut generic] = self.commander.ports();
        let mut services: [&mut dyn Service; 8] = [
            &mut self.param,
            &mut self.log,
            &mut self.mem,
            &mut rpyt,
            &mut generic,
            &mut self.high_level,
            &mut self.supervisor,
            &mut self.console,
        ];
        self.router.handle_uplink(bytes, &mut services)
    }
}
