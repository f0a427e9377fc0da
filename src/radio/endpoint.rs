//! The CRTP services every cfnav endpoint answers — the drone over the syslink and the simulator over UDP —
//! gathered in one place, so both dispatch exactly the same ports in the same order.
//!
//! Job: borrow the endpoint's services for one uplink packet and hand it to the [`Router`]. Non-goals: owning
//! the services (each endpoint keeps its own, with its own parameter store and log table), transport, time.
//! Memory: seven references on the stack for the duration of one call.

use super::commander::CommanderService;
use super::console::ConsoleService;
use super::crtp::{CrtpPacket, Router, Service};
use super::high_level::HighLevelService;
use super::log::LogService;
use super::log_registry::LogSource;
use super::mem::MemService;
use super::param::ParamService;
use super::registry::ParamStore;
use super::supervisor_port::SupervisorPortService;

/// The services of one endpoint, borrowed for one packet: parameters (port 2), logs (5), memory (4),
/// commander (3 and 7), high-level commander (8), supervisor (9) and console (0). Link (15) and platform (13) live in the router.
pub struct EndpointServices<'a, P: ParamStore, L: LogSource, const C: usize> {
    /// Parameter service.
    pub param: &'a mut ParamService<P>,
    /// Log service.
    pub log: &'a mut LogService<L>,
    /// Memory-count service.
    pub mem: &'a mut MemService,
    /// Setpoint commander (ports 3 and 7).
    pub commander: &'a mut CommanderService,
    /// High-level commander (port 8).
    pub high_level: &'a mut HighLevelService,
    /// Supervisor port.
    pub supervisor: &'a mut SupervisorPortService,
    /// Console.
    pub console: &'a mut ConsoleService<C>,
}

impl<P: ParamStore, L: LogSource, const C: usize> EndpointServices<'_, P, L, C> {
    /// Dispatches one uplink packet (`bytes`, header first) through `router`; returns the reply, if any.
    pub fn handle_uplink<const Q: usize>(self, router: &mut Router<Q>, bytes: &[u8]) -> Option<CrtpPacket> {
        let [mut rpyt, mut generic] = self.commander.ports();
        let mut services: [&mut dyn Service; 8] = [
            self.param,
            self.log,
            self.mem,
            &mut rpyt,
            &mut generic,
            self.high_level,
            self.supervisor,
            self.console,
        ];
        router.handle_uplink(bytes, &mut services)
    }
}
