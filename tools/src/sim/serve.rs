//! `cfnav sim --serve`: the simulated Crazyflie in (a multiple of) real time, serving CRTP over UDP on
//! 127.0.0.1 so that unmodified cflib connects to it (interfaces.md §1, §5).
//!
//! The lockstep loop is [`super::runner`]'s (same sensors, physics, rates and [`FlightCore`]); instead of a
//! trigger time, the mission starts when a client writes `mission.start = 1` and aborts when it writes 0.
//!
//! Transport (`crtp-over-udp.md` §1, §5): one datagram is one CRTP packet. A null packet (a bare `0xFF` scan
//! probe, or `0xF3`/`0xF4`) is answered with `0xFF` to its sender without changing the client; any other
//! datagram makes its sender the client. Replies and unsolicited packets (log data, VALUE_UPDATED, console
//! lines) go to the client at once: UDP has no uplink pacing and cflib never retries, so nothing is held back.
//! Log blocks are stopped when the client has been silent for [`CLIENT_TIMEOUT`] (cflib pings every 100 ms).
//!
//! Clock: the simulated time (ms since power-on) is the drone's clock, also the log timestamps; it is paced
//! to `speed` × wall time, advancing in chunks of at most [`CHUNK_TICKS`] between network polls.

use std::io::ErrorKind;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use cfnav::radio::crtp::{CrtpPacket, MAX_DATA, NULL_HEADER, PlatformService, Router, Service, is_null_header};
use cfnav::radio::log::LogService;
use cfnav::radio::log_registry::FlightLogState;
use cfnav::radio::mem::MemService;
use cfnav::radio::param::ParamService;
use cfnav::radio::registry::{ID_START, MissionParamState};
use cfnav::types::RangeReading;

use super::runner::{Faults, SIM_CELLS, SimDrone, mission_params};
use super::world::World;

/// Simulated milliseconds run at most between two polls of the socket.
pub const CHUNK_TICKS: u64 = 20;
/// A client silent this long is gone: its log blocks are deleted.
pub const CLIENT_TIMEOUT: Duration = Duration::from_secs(3);
/// Firmware version tag the platform service reports.
const FIRMWARE_TAG: &str = concat!("cfnav-sim-", env!("CARGO_PKG_VERSION"));
/// Router reply queue depth (flushed after every uplink).
const ROUTER_QUEUE: usize = 8;
/// Port and channel of console text (stock: port 0, channel 0).
const PORT_CONSOLE: u8 = 0;
/// Range reported when a ranger has no valid return (stock multiranger.c, `crazyflie-hardware.md`).
const NO_RANGE_MM: u16 = 32767;

type Params = ParamService<MissionParamState>;
type Logs = LogService<FlightLogState>;

/// What the log service reads from the simulated drone.
fn log_state(drone: &SimDrone) -> FlightLogState {
    let mm = |r: RangeReading| match r {
        Some(m) if m.is_finite() && m >= 0.0 => (m * 1000.0).round().min(f32::from(NO_RANGE_MM)) as u16,
        _ => NO_RANGE_MM,
    };
    let mr = &drone.last_multiranger;
    FlightLogState {
        mission_state: drone.core.mission_state().code(),
        position_m: drone.core.estimate().position_m,
        ranges_mm: [
            mm(mr.front_m),
            mm(mr.back_m),
            mm(mr.left_m),
            mm(mr.right_m),
            mm(mr.up_m),
            mm(drone.last_zrange),
        ],
        vbat_v: drone.last_vbat,
    }
}

/// Simulated seconds since power-on.
fn seconds(drone: &SimDrone) -> f64 {
    drone.tick() as f64 * 1e-3
}

/// The radio side: the CRTP services and the client's address.
struct Radio {
    socket: UdpSocket,
    client: Option<SocketAddr>,
    last_uplink: Instant,
    router: Router<ROUTER_QUEUE>,
    param: Params,
    log: Logs,
    mem: MemService,
    send_errors: u64,
}

impl Radio {
    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) {
        if let Err(e) = self.socket.send_to(bytes, to) {
            self.send_errors += 1;
            if self.send_errors.is_power_of_two() {
                eprintln!(
                    "serve: cannot send to {to}: {e} ({} send errors so far)",
                    self.send_errors
                );
            }
        }
    }

    /// Sends `packet` to the client, if there is one.
    fn send(&mut self, packet: &CrtpPacket) {
        if let Some(to) = self.client {
            let mut buf = [0u8; 32];
            let n = packet.to_bytes(&mut buf);
            self.send_to(&buf[..n], to);
        }
    }

    /// Sends `text` as console packets (port 0, channel 0, ≤ 30 bytes each).
    fn console(&mut self, text: &str) {
        for chunk in text.as_bytes().chunks(MAX_DATA) {
            if let Ok(p) = CrtpPacket::new(PORT_CONSOLE, 0, chunk) {
                self.send(&p);
            }
        }
    }

    /// Sends every pending VALUE_UPDATED and refusal console line.
    fn flush_param_events(&mut self) {
        while let Some(p) = self.param.next_notification() {
            self.send(&p);
        }
        while let Some(note) = self.param.take_refusal() {
            let line = Params::console_line(&note);
            eprintln!("serve: {}", line.trim_end());
            self.console(&line);
        }
    }

    /// One datagram from `from`.
    fn on_datagram(&mut self, bytes: &[u8], from: SocketAddr, drone: &mut SimDrone) {
        let Some(&header) = bytes.first() else {
            return;
        };
        if is_null_header(header) {
            // Scan probe or keep-alive: answer its sender, keep the client (cflib scans from another socket).
            self.send_to(&[NULL_HEADER], from);
            return;
        }
        if self.client != Some(from) {
            eprintln!("{:8.3} s  client {from}", seconds(drone));
            self.client = Some(from);
        }
        self.last_uplink = Instant::now();
        {
            let store = self.param.store_mut();
            store.flying = drone.core.supervisor().flying;
            store.decks_ok = true;
        }
        let before = self.param.store().start;
        let reply = {
            let mut services: [&mut dyn Service; 3] = [&mut self.param, &mut self.log, &mut self.mem];
            self.router.handle_uplink(bytes, &mut services)
        };
        if let Some(reply) = reply {
            self.send(&reply);
        }
        // Everything else the router holds goes down at once (UDP has no uplink pacing).
        while self.router.pending() > 0 {
            match self.router.handle_uplink(&[NULL_HEADER], &mut []) {
                Some(p) => self.send(&p),
                None => break,
            }
        }
        let after = self.param.store().start;
        match (before, after) {
            (0, 1) => {
                let params = self.param.store().params;
                match drone.core.start_mission(params) {
                    Ok(()) => eprintln!(
                        "{:8.3} s  mission.start = 1: mission started, goal ({:.2}, {:.2})",
                        seconds(drone),
                        params.goal_m.0,
                        params.goal_m.1
                    ),
                    Err(e) => {
                        let line = format!("mission.start refused by the flight core: {e:?}\n");
                        eprintln!("{:8.3} s  {}", seconds(drone), line.trim_end());
                        self.param.store_mut().start = 0;
                        self.param.notify(ID_START);
                        self.console(&line);
                    }
                }
            }
            (1, 0) => {
                eprintln!("{:8.3} s  mission.start = 0: aborting", seconds(drone));
                drone.core.abort_mission();
            }
            _ => {}
        }
        self.flush_param_events();
    }
}

/// Serves CRTP over UDP on 127.0.0.1:`port` and flies `world` at `speed` × real time until interrupted.
pub fn serve(world: &World, port: u16, speed: f64) -> Result<(), String> {
    if !(speed.is_finite() && speed > 0.0) {
        return Err(format!("--speed must be a positive number, got {speed}"));
    }
    let socket = UdpSocket::bind(("127.0.0.1", port)).map_err(|e| format!("cannot bind UDP 127.0.0.1:{port}: {e}"))?;
    socket
        .set_nonblocking(true)
        .map_err(|e| format!("cannot make the UDP socket non-blocking: {e}"))?;
    let mut drone = SimDrone::new(world, world.sim.seed, &Faults::default())?;
    let mut radio = Radio {
        socket,
        client: None,
        last_uplink: Instant::now(),
        router: Router::new(PlatformService::new(FIRMWARE_TAG)),
        param: ParamService::new(MissionParamState::new(mission_params(world), SIM_CELLS)),
        log: LogService::new(),
        mem: MemService,
        send_errors: 0,
    };
    eprintln!(
        "serving CRTP on udp://127.0.0.1:{port} ({} at {speed}× real time); write mission.start = 1 to fly",
        world.name
    );
    let mut last_state = drone.core.mission_state();
    eprintln!(
        "{:8.3} s  state {:3} {last_state:?}",
        seconds(&drone),
        last_state.code()
    );
    let mut buf = [0u8; 64];
    let wall = Instant::now();
    loop {
        // The network: every datagram waiting.
        loop {
            match radio.socket.recv_from(&mut buf) {
                Ok((n, from)) => {
                    let n = n.min(buf.len());
                    radio.on_datagram(&buf[..n], from, &mut drone);
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                // ICMP errors from a vanished peer, signals: not the server's problem.
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::ConnectionRefused | ErrorKind::ConnectionReset | ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(format!("UDP receive failed: {e}")),
            }
        }
        if radio.client.is_some() && radio.last_uplink.elapsed() > CLIENT_TIMEOUT {
            eprintln!(
                "{:8.3} s  client silent for {CLIENT_TIMEOUT:?}: log blocks stopped",
                seconds(&drone)
            );
            radio.log.reset();
            radio.client = None;
        }

        // The drone: catch up with the wall clock, at most one chunk before polling again.
        let target = (wall.elapsed().as_secs_f64() * speed * 1000.0) as u64;
        let end = target.min(drone.tick() + CHUNK_TICKS);
        while drone.tick() < end {
            drone.step(world);
            let log_state = log_state(&drone);
            let now_ms = drone.tick() as u32;
            while let Some(p) = radio.log.tick(now_ms, &log_state) {
                radio.send(&p);
            }
            let state = drone.core.mission_state();
            if state != last_state {
                let e = drone.core.estimate().position_m;
                eprintln!(
                    "{:8.3} s  state {:3} {state:?}  estimate ({:.2}, {:.2}, {:.2})",
                    seconds(&drone),
                    state.code(),
                    e[0],
                    e[1],
                    e[2]
                );
                if state.is_final() && radio.param.store().start != 0 {
                    radio.param.store_mut().start = 0;
                    radio.param.notify(ID_START);
                    radio.flush_param_events();
                }
                last_state = state;
            }
        }
        if drone.tick() >= target {
            std::thread::sleep(Duration::from_micros(500));
        }
    }
}
