//! `cfnav sim --serve`: the simulated Crazyflie in (a multiple of) real time, serving CRTP over UDP on
//! 127.0.0.1 so that unmodified cflib connects to it (docs/formats.md (commands), docs/radio.md).
//!
//! The lockstep loop is [`super::runner`]'s (same sensors, physics, rates and [`FlightCore`]); instead of a
//! trigger time, the mission starts when a client writes `mission.start = 1` and aborts when it writes 0.
//!
//! Transport (docs/radio.md): one datagram is one CRTP packet. A null packet (a bare `0xFF` scan
//! probe, or `0xF3`/`0xF4`) is answered with `0xFF` to its sender without changing the client; any other
//! datagram makes its sender the client. Replies and unsolicited packets (log data, VALUE_UPDATED, console
//! lines) go to the client at once: UDP has no uplink pacing and cflib never retries, so nothing is held back.
//! Log blocks are stopped when the client has been silent for [`CLIENT_TIMEOUT`] (cflib pings every 100 ms).
//!
//! Clock: the simulated time (ms since power-on) is the drone's clock, also the log timestamps; it is paced
//! to `speed` × wall time, advancing in chunks of at most [`CHUNK_TICKS`] between network polls.
//!
//! Commander (ports 3 and 7): each accepted setpoint packet is mapped by [`SetpointFollower`] and handed to
//! `FlightCore::commander_setpoint` with its arrival time, once (so the supervisor's 500 ms / 2 s setpoint
//! watchdog sees the real packet age), and only while no mission runs. Packets cfnav cannot fly (manual
//! roll/pitch rates, tilted z-distance, full state) or that are refused get a rate-limited console note;
//! RPYT (cflib `send_setpoint`) flies as an attitude/thrust setpoint.
//!
//! High-level commander (port 8): each accepted command goes to `FlightCore::high_level_command` with its
//! arrival time; the flight core flies the trajectory and keeps its setpoint fresh. A command refused (by
//! the decoder, the group mask, a running mission or the trajectory follower) gets one console line.
//!
//! Supervisor (port 9): answered from the flight core's supervisor verdict. Arming cannot be changed (the
//! core auto-arms), recovery is refused while crashed (the core has no supervisor reset). An emergency stop
//! (command or watchdog) is latched: with no mission running a Stop setpoint is flown and every later
//! commander setpoint becomes Stop; during a mission the core offers no motor cut, so the mission is aborted
//! (it lands) — the console says so. `mission.start` is refused after an emergency stop (stock: Locked, reboot).
//!
//! Console (port 0): refusal notes and these messages go through [`ConsoleService`] and are sent at once.
//!
//! Tuning and persistent parameters: an accepted tuning write is handed to the flight core
//! at once (`FlightCore::set_tuning`). `--param-store FILE` is the drone's 8 KB EEPROM as a file (created
//! blank, 0xFF, when missing): at start the persistent records are read from it and applied through the
//! same checks as a radio write; `persistent_store`/`persistent_clear` write their slot into it (the whole
//! file rewritten through a temporary file and a rename) before they are answered. Without the option the
//! EEPROM lives in memory and is lost when the simulator stops.
//!
//! Link loss (`mission.linkLoss`, `mission.linkTimeout`): every datagram from the client, its null
//! keep-alives included, is a radio packet for the flight core's link-loss watch; a client that falls
//! silent during a mission for `mission.linkTimeout` s of simulated time triggers the policy (a line on
//! stderr says when).
//!
//! Truth (for end-to-end checks, tools/e2e/cflib_modes.py): every mission state change, every change of the
//! supervisor's is-flying verdict (`flying`/`landed`) and the link-loss timeout print one stderr line with the
//! estimate and the simulated body's true position (arena frame, z of its underside above the floor, m).
//! Nothing of it goes over the radio: a client sees what it would see from a real drone.
//!
//! Memory (port 4): memory 0 is the drone's map (`cfnav::radio_binding::map_mem`), each read answered at once from
//! the live map; with `--map-json FILE`, every read of its CRC field (a download starting) and the end of a
//! mission also write the simulator's own map of that moment to FILE ([`super::map_dump::SimMapDump`]).

use std::io::ErrorKind;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use cfnav::mission::MissionState;
use cfnav::radio::commander::{Command, SetpointFollower};
use cfnav::radio::crtp::{CrtpPacket, NULL_HEADER, is_null_header};
use cfnav::radio::mem::MemService;
use cfnav::radio::param::ParamService;
use cfnav::radio_binding::endpoint::Endpoint;
use cfnav::radio_binding::log_table::FlightLogState;
use cfnav::radio_binding::map_mem::{CRC_OFFSET, MapView};
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::{ID_RESET_ESTIMATION, ID_START};
use cfnav::radio_binding::supervisor_port::{SupervisorPortConfig, SupervisorStatus};
use cfnav::radio_binding::tuning::Tuning;
use cfnav::stack::FlightConfig;
use cfnav::stack::HighLevelError;
use cfnav::system::persistent_params::{PersistentParams, REGION_LEN, REGION_START};
use cfnav::types::{RangeReading, Setpoint};

use super::runner::{Faults, SIM_CELLS, SimDrone, power_on_params, world_walls, write_room};
use cfnav_sim::world::World;

/// Simulated milliseconds run at most between two polls of the socket.
pub const CHUNK_TICKS: u64 = 20;
/// A client silent this long is gone: its log blocks are deleted.
pub const CLIENT_TIMEOUT: Duration = Duration::from_secs(3);
/// Firmware version tag the platform service reports.
const FIRMWARE_TAG: &str = concat!("cfnav-sim-", env!("CARGO_PKG_VERSION"));
/// Router reply queue depth (flushed after every uplink).
const ROUTER_QUEUE: usize = 8;
/// Console queue depth, packets (sent at once after every uplink and simulation chunk).
const CONSOLE_QUEUE: usize = 32;
/// Shortest simulated time between two console notes about commander packets, µs.
const COMMANDER_NOTE_INTERVAL_US: u64 = 2_000_000;
/// Range reported when a ranger has no valid return (stock multiranger.c, docs/hardware.md).
const NO_RANGE_MM: u16 = 32767;

type Params = ParamService<MissionParamState>;

/// What the log service reads from the simulated drone; `supervisor_info` is the supervisor port's bitfield.
fn log_state(drone: &SimDrone, supervisor_info: u16) -> FlightLogState {
    let mm = |r: RangeReading| match r {
        Some(m) if m.is_finite() && m >= 0.0 => (m * 1000.0).round().min(f32::from(NO_RANGE_MM)) as u16,
        _ => NO_RANGE_MM,
    };
    let mr = &drone.last_multiranger;
    let mut s = FlightLogState {
        mission_state: drone.core.mission_state().code(),
        ranges_mm: [
            mm(mr.front_m),
            mm(mr.back_m),
            mm(mr.left_m),
            mm(mr.right_m),
            mm(mr.up_m),
            mm(drone.last_zrange),
        ],
        vbat_v: drone.last_vbat,
        supervisor_info,
        battery_low: drone.core.supervisor().battery_low,
        hover_dev_m: {
            let stats = drone.core.mission().stats();
            [stats.hover_dev_xy_m, stats.hover_dev_z_m]
        },
        coverage: drone.core.mission().stats().coverage,
        ..FlightLogState::default()
    };
    s.record_flight(&drone.core.estimate(), drone.core.control(), &drone.core.setpoint());
    s
}

/// Simulated µs since power-on.
fn now_us(drone: &SimDrone) -> u64 {
    drone.tick() * 1000
}

/// What the supervisor port reports.
fn supervisor_status(drone: &SimDrone) -> SupervisorStatus {
    SupervisorStatus {
        output: *drone.core.supervisor(),
        mission_running: drone.core.mission().is_running(),
        mission_finished: drone.core.mission_state().is_final(),
        decks_ok: true,
    }
}

/// Short name of a command kind, for console notes.
fn command_name(command: &Command) -> &'static str {
    match command {
        Command::Stop => "stop",
        Command::Attitude { .. } => "manual roll/pitch-rate",
        Command::VelocityWorld { .. } => "velocity",
        Command::ZDistance { .. } => "z-distance",
        Command::Hover { .. } => "hover",
        Command::Position { .. } => "position",
    }
}

/// Simulated seconds since power-on.
fn seconds(drone: &SimDrone) -> f64 {
    drone.tick() as f64 * 1e-3
}

/// `estimate (x, y, z) truth (x, y, z)` for the stderr lines end-to-end checks read (module docs, Truth):
/// the flight core's estimate and the simulated body's true position, both arena frame, z above the floor, m.
fn estimate_and_truth(drone: &SimDrone) -> String {
    let e = drone.core.estimate().position_m;
    let p = drone.quad.position();
    let bottom = drone.quad.params().bottom_offset_m;
    format!(
        "estimate ({:.3}, {:.3}, {:.3}) truth ({:.3}, {:.3}, {:.3})",
        e[0],
        e[1],
        e[2],
        p[0],
        p[1],
        p[2] - bottom
    )
}

/// Where the radio's downlink datagrams go: the UDP socket, or a list the caller takes them from
/// ([`InProcess`]).
enum Downlink {
    Udp(UdpSocket),
    Memory(Vec<(SocketAddr, Vec<u8>)>),
}

/// The radio side: the CRTP services and the client's address.
struct Radio {
    downlink: Downlink,
    client: Option<SocketAddr>,
    last_uplink: Instant,
    ep: Endpoint<MissionParamState, FlightLogState, CONSOLE_QUEUE, ROUTER_QUEUE>,
    follower: SetpointFollower,
    commander_refused: u32,
    last_commander_note_us: Option<u64>,
    send_errors: u64,
    /// The simulated EEPROM (8 KB) and the file it lives in, if any.
    eeprom: Vec<u8>,
    eeprom_file: Option<PathBuf>,
    /// The tuning generation last handed to the flight core.
    tuning_applied: u32,
    /// `--map-json`: where the simulator's own map is written.
    map_json: Option<PathBuf>,
}

/// What [`Radio::after_step`] compares with to print the truth lines of changes.
struct Watch {
    last_state: MissionState,
    link_fired: Option<u64>,
    last_flying: bool,
}

impl Watch {
    /// The drone as it is now (prints its state line).
    fn new(drone: &SimDrone) -> Self {
        let last_state = drone.core.mission_state();
        eprintln!("{:8.3} s  state {:3} {last_state:?}", seconds(drone), last_state.code());
        Self {
            last_state,
            link_fired: None,
            last_flying: drone.core.supervisor().flying,
        }
    }
}

/// Bytes of the Crazyflie's EEPROM (24AA64, docs/hardware.md §1).
pub const EEPROM_LEN: usize = 8192;

/// The EEPROM image in `path` (blank, 0xFF, if the file does not exist; padded with 0xFF if short).
fn read_eeprom(path: &Path) -> Result<Vec<u8>, String> {
    let mut bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(format!("cannot read --param-store {}: {e}", path.display())),
    };
    if bytes.len() > EEPROM_LEN {
        return Err(format!(
            "--param-store {} is {} bytes, more than the {EEPROM_LEN}-byte EEPROM",
            path.display(),
            bytes.len()
        ));
    }
    bytes.resize(EEPROM_LEN, 0xFF);
    Ok(bytes)
}

/// Replaces `path` with `bytes` (a temporary file renamed over it).
fn write_eeprom(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

impl Radio {
    /// The radio of a drone flying `world`, answering through `downlink`.
    fn new(downlink: Downlink, world: &World, eeprom_file: Option<&Path>) -> Result<Self, String> {
        let eeprom = match eeprom_file {
            Some(path) => read_eeprom(path)?,
            None => vec![0xFF; EEPROM_LEN],
        };
        let config = FlightConfig::default();
        let tuning = Tuning::new(config.controller, &config.estimator, config.mission);
        // The sim's flight core auto-arms and has no supervisor reset.
        let mut ep = Endpoint::new(
            FIRMWARE_TAG,
            MissionParamState::new(power_on_params(world), SIM_CELLS).with_tuning(tuning),
            SupervisorPortConfig {
                auto_arm: true,
                can_recover: false,
            },
        );
        ep.mem = MemService::with_map(SIM_CELLS);
        Ok(Self {
            downlink,
            client: None,
            last_uplink: Instant::now(),
            ep,
            follower: SetpointFollower::new(),
            commander_refused: 0,
            last_commander_note_us: None,
            send_errors: 0,
            eeprom,
            eeprom_file: eeprom_file.map(Path::to_path_buf),
            tuning_applied: 0,
            map_json: None,
        })
    }

    /// Boot: the persistent records from the EEPROM, applied through the radio's checks, and the tuning
    /// handed to the flight core.
    fn load_persistent(&mut self, drone: &mut SimDrone) {
        let start = usize::from(REGION_START);
        let (stored, report) = PersistentParams::load(&self.eeprom[start..start + REGION_LEN]);
        let summary = self.ep.param.load_persistent(stored);
        eprintln!(
            "persistent parameters: {} applied, {} unknown, {} refused (slots {:?})",
            summary.applied, summary.unknown, summary.refused, report.slots
        );
        self.apply_tuning(drone);
        self.flush_param_events();
    }

    /// Hands the tuning to the flight core when a write changed it.
    fn apply_tuning(&mut self, drone: &mut SimDrone) {
        let store = self.ep.param.store();
        if store.tuning_generation == self.tuning_applied {
            return;
        }
        self.tuning_applied = store.tuning_generation;
        let t = store.tuning;
        if let Err(e) = drone.core.set_tuning(t.controller, t.flow_std_counts, t.mission) {
            let line = format!("tuning refused by the flight core: {e:?}\n");
            eprintln!("{:8.3} s  {}", seconds(drone), line.trim_end());
            self.console(&line);
        }
    }

    /// Does the EEPROM write a persistent command waits for, then sends its reply.
    fn run_eeprom_write(&mut self, drone: &SimDrone) {
        let Some(write) = self.ep.param.eeprom_write().copied() else {
            return;
        };
        let at = usize::from(write.address());
        self.eeprom[at..at + write.bytes().len()].copy_from_slice(write.bytes());
        let ok = match &self.eeprom_file {
            Some(path) => match write_eeprom(path, &self.eeprom) {
                Ok(()) => true,
                Err(e) => {
                    let line = format!("persistent store: cannot write {}: {e}\n", path.display());
                    eprintln!("{:8.3} s  {}", seconds(drone), line.trim_end());
                    self.console(&line);
                    false
                }
            },
            None => true,
        };
        if let Some(reply) = self.ep.param.eeprom_write_done(ok) {
            self.send(&reply);
        }
    }

    /// Answers a read of the map memory from the drone's live map; a read of its CRC field also writes the
    /// simulator's own map to `--map-json`.
    fn answer_map_read(&mut self, drone: &SimDrone) {
        let Some(read) = self.ep.mem.take_map_read() else {
            return;
        };
        let view = MapView::of_mission(drone.core.mission());
        self.send(&read.answer(&view));
        let end = read.addr as usize + usize::from(read.len);
        if (read.addr as usize) < CRC_OFFSET + 4 && end > CRC_OFFSET {
            self.dump_map(drone, view.crc32());
        }
    }

    /// Writes the simulator's own map to `--map-json`, if given.
    fn dump_map(&self, drone: &SimDrone, crc32: u32) {
        if let Some(path) = &self.map_json
            && let Err(e) = super::map_dump::write_sim_dump(path, drone.core.mission(), drone.tick(), crc32)
        {
            eprintln!("serve: {e}");
        }
    }

    fn send_to(&mut self, bytes: &[u8], to: SocketAddr) {
        let socket = match &mut self.downlink {
            Downlink::Udp(socket) => socket,
            Downlink::Memory(out) => {
                out.push((to, bytes.to_vec()));
                return;
            }
        };
        if let Err(e) = socket.send_to(bytes, to) {
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

    /// Queues `text` on the console (port 0, channel 0, ≤ 30-byte packets) and sends it.
    fn console(&mut self, text: &str) {
        self.ep.console.print(text);
        self.flush_console();
    }

    /// Sends every waiting console packet (UDP has no downlink pacing).
    fn flush_console(&mut self) {
        while let Some(p) = self.ep.console.next_packet() {
            self.send(&p);
        }
    }

    /// A console note about the commander, at most one per [`COMMANDER_NOTE_INTERVAL_US`] of simulated time.
    fn commander_note(&mut self, drone: &SimDrone, text: &str) {
        let now = now_us(drone);
        if self
            .last_commander_note_us
            .is_some_and(|t| now.saturating_sub(t) < COMMANDER_NOTE_INTERVAL_US)
        {
            return;
        }
        self.last_commander_note_us = Some(now);
        eprintln!("{:8.3} s  {text}", seconds(drone));
        self.ep.console.write_line(text);
        self.flush_console();
    }

    /// Flies the commander's new setpoint, if one arrived.
    fn apply_commander(&mut self, drone: &mut SimDrone) {
        if let Some((meta, _)) = self.ep.commander.take_meta() {
            eprintln!(
                "{:8.3} s  commander: {meta:?} (no high-level commander: the last setpoint ages out)",
                seconds(drone)
            );
        }
        let refused = self.ep.commander.stats().refused;
        if refused != self.commander_refused {
            self.commander_refused = refused;
            if let Some(e) = self.ep.commander.last_error() {
                self.commander_note(drone, &format!("commander packet refused: {e:?}"));
            }
        }
        let Some((command, received_us)) = self.ep.commander.take_fresh() else {
            return;
        };
        if self.ep.supervisor.emergency_stopped() {
            drone.core.commander_setpoint(Setpoint::Stop, received_us);
            return;
        }
        if drone.core.mission().is_running() {
            self.commander_note(
                drone,
                "commander setpoint ignored: a mission is running (write mission.start = 0 to abort it)",
            );
            return;
        }
        match self.follower.to_setpoint(&command, received_us, &drone.core.estimate()) {
            Some(setpoint) => drone.core.commander_setpoint(setpoint, received_us),
            None => {
                let note = format!(
                    "commander: {} setpoint not flown (cfnav flies stop, attitude/thrust, position, velocity, hover, level z-distance)",
                    command_name(&command)
                );
                self.commander_note(drone, &note);
            }
        }
    }

    /// Flies the high-level commander's new command (port 8), or says on the console why not: every
    /// port 8 packet cfnav does not act on gets one line.
    fn apply_high_level(&mut self, drone: &mut SimDrone) {
        if let Some(e) = self.ep.high_level.take_error() {
            let line = format!("high-level commander: packet not flown: {e:?}\n");
            eprintln!("{:8.3} s  {}", seconds(drone), line.trim_end());
            self.console(&line);
        }
        let Some((command, received_us)) = self.ep.high_level.take() else {
            return;
        };
        let refusal = if self.ep.supervisor.emergency_stopped() {
            Some("emergency stop latched (restart the simulator)".to_string())
        } else {
            match drone.core.high_level_command(command, received_us) {
                Ok(()) => None,
                Err(HighLevelError::MissionRunning) => {
                    Some("a mission is running (write mission.start = 0 to abort it)".to_string())
                }
                Err(HighLevelError::Refused(r)) => Some(format!("{r:?}")),
            }
        };
        match refusal {
            None => eprintln!("{:8.3} s  high-level commander: {command:?}", seconds(drone)),
            Some(why) => {
                let line = format!("high-level command refused: {why}\n");
                eprintln!("{:8.3} s  {}", seconds(drone), line.trim_end());
                self.console(&line);
            }
        }
    }

    /// Acts on the supervisor port's requests (emergency stop; arming and recovery are never granted here).
    fn apply_supervisor(&mut self, drone: &mut SimDrone) {
        let requests = self.ep.supervisor.take_requests();
        if !requests.emergency_stop {
            return;
        }
        let line = if drone.core.mission().is_running() {
            drone.core.abort_mission();
            "emergency stop: the flight core cannot cut the motors of a running mission; mission aborted (landing)"
        } else {
            drone.core.commander_setpoint(Setpoint::Stop, now_us(drone));
            "emergency stop: motors stopped; restart the simulator to fly again"
        };
        eprintln!("{:8.3} s  {line}", seconds(drone));
        self.ep.console.write_line(line);
        if self.ep.param.store().start != 0 {
            self.ep.param.store_mut().start = 0;
            self.ep.param.notify(ID_START);
        }
        self.flush_param_events();
        self.flush_console();
    }

    /// Sends every pending VALUE_UPDATED and refusal console line.
    fn flush_param_events(&mut self) {
        while let Some(p) = self.ep.param.next_notification() {
            self.send(&p);
        }
        while let Some(note) = self.ep.param.take_refusal() {
            let line = Params::console_line(&note);
            eprintln!("serve: {}", line.trim_end());
            self.ep.console.print(&line);
        }
        self.flush_console();
    }

    /// What the server does after every simulated millisecond: the mission's console notes, the
    /// supervisor port's watchdog, due log packets, and the truth lines of state and flying changes (module
    /// docs, Truth); a final state writes `mission.start` back to 0.
    fn after_step(&mut self, drone: &mut SimDrone, watch: &mut Watch) {
        // The mission's decisions the user should hear about (explore's battery reserve).
        if let Some(note) = drone.core.take_mission_note() {
            self.console(&format!("{note}\n"));
        }
        if self.ep.supervisor.poll(now_us(drone)) {
            self.apply_supervisor(drone);
        }
        self.ep.supervisor.set_status(supervisor_status(drone));
        let log_state = log_state(drone, self.ep.supervisor.bitfield());
        let now_ms = drone.tick() as u32;
        while let Some(p) = self.ep.log.tick(now_ms, &log_state) {
            self.send(&p);
        }
        let fired = drone.core.navigator().link_watch().fired_at();
        if fired != watch.link_fired && fired.is_some() {
            let policy = drone.core.navigator().link_watch().config().policy;
            eprintln!(
                "{:8.3} s  link lost: no packet for mission.linkTimeout, policy {policy:?}  {}",
                seconds(drone),
                estimate_and_truth(drone)
            );
        }
        watch.link_fired = fired;
        let state = drone.core.mission_state();
        let flying = drone.core.supervisor().flying;
        if flying != watch.last_flying {
            let what = if flying { "flying" } else { "landed" };
            eprintln!("{:8.3} s  {what}  {}", seconds(drone), estimate_and_truth(drone));
            watch.last_flying = flying;
        }
        if state != watch.last_state {
            eprintln!(
                "{:8.3} s  state {:3} {state:?}  {}",
                seconds(drone),
                state.code(),
                estimate_and_truth(drone)
            );
            if state.is_final() {
                let crc = MapView::of_mission(drone.core.mission()).crc32();
                self.dump_map(drone, crc);
            }
            if state.is_final() && self.ep.param.store().start != 0 {
                self.ep.param.store_mut().start = 0;
                self.ep.param.notify(ID_START);
                self.flush_param_events();
            }
            watch.last_state = state;
        }
    }

    /// One datagram from `from`.
    fn on_datagram(&mut self, bytes: &[u8], from: SocketAddr, drone: &mut SimDrone) {
        let Some(&header) = bytes.first() else {
            return;
        };
        if is_null_header(header) {
            // Scan probe or keep-alive: answer its sender, keep the client (cflib scans from another socket).
            // The client's own keep-alives are radio packets: its link is alive.
            if self.client == Some(from) {
                self.ep.note_uplink(now_us(drone));
                drone.core.on_radio_packet(now_us(drone));
            }
            self.send_to(&[NULL_HEADER], from);
            return;
        }
        if self.client != Some(from) {
            eprintln!("{:8.3} s  client {from}", seconds(drone));
            self.client = Some(from);
        }
        self.last_uplink = Instant::now();
        {
            let store = self.ep.param.store_mut();
            store.flying = drone.core.supervisor().flying;
            // The simulated drone carries both decks.
            store.set_decks(true, true);
        }
        let before = self.ep.param.store().start;
        self.ep.supervisor.set_status(supervisor_status(drone));
        let reply = self.ep.handle_uplink(bytes, now_us(drone));
        // The link-loss watch: this packet, and the parameters in effect after it.
        drone.core.on_radio_packet(now_us(drone));
        drone.core.set_link_loss(self.ep.param.store().link_loss);
        if let Some(reply) = reply {
            self.send(&reply);
        }
        self.answer_map_read(drone);
        // Everything else the router holds goes down at once (UDP has no uplink pacing).
        while self.ep.router.pending() > 0 {
            match self.ep.router.handle_uplink(&[NULL_HEADER], &mut []) {
                Some(p) => self.send(&p),
                None => break,
            }
        }
        self.run_eeprom_write(drone);
        self.apply_tuning(drone);
        self.apply_commander(drone);
        self.apply_high_level(drone);
        self.apply_supervisor(drone);
        if let Some(xy) = self.ep.param.store().pending_reset() {
            drone.core.reset_estimate(xy);
            eprintln!(
                "{:8.3} s  kalman.resetEstimation: estimate re-anchored at ({:.2}, {:.2})",
                seconds(drone),
                xy.0,
                xy.1
            );
            self.ep.param.store_mut().reset_estimation = 0;
            self.ep.param.notify(ID_RESET_ESTIMATION);
        }
        let after = self.ep.param.store().start;
        match (before, after) {
            (0, 1) if self.ep.supervisor.emergency_stopped() => {
                let line = "mission.start refused: emergency stop latched (restart the simulator)\n";
                eprintln!("{:8.3} s  {}", seconds(drone), line.trim_end());
                self.ep.param.store_mut().start = 0;
                self.ep.param.notify(ID_START);
                self.console(line);
            }
            (0, 1) => {
                let params = self.ep.param.store().params;
                match drone.core.start_mission(params) {
                    Ok(()) => eprintln!(
                        "{:8.3} s  mission.start = 1: mission started, goal ({:.2}, {:.2})",
                        seconds(drone),
                        params.goal_m.0,
                        params.goal_m.1
                    ),
                    Err(e) => {
                        let line = format!("mission.start refused: {e}\n");
                        eprintln!("{:8.3} s  {}", seconds(drone), line.trim_end());
                        self.ep.param.store_mut().start = 0;
                        self.ep.param.notify(ID_START);
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

/// Serves CRTP over UDP on 127.0.0.1:`port` and flies `world` at `speed` × real time until interrupted;
/// `param_store` is the EEPROM's file; with `map_json`, the simulator's own map is written there (module
/// docs, Memory).
pub fn serve(
    world: &World,
    port: u16,
    speed: f64,
    param_store: Option<&Path>,
    map_json: Option<&Path>,
) -> Result<(), String> {
    if !(speed.is_finite() && speed > 0.0) {
        return Err(format!("--speed must be a positive number, got {speed}"));
    }
    let socket = UdpSocket::bind(("127.0.0.1", port)).map_err(|e| format!("cannot bind UDP 127.0.0.1:{port}: {e}"))?;
    socket
        .set_nonblocking(true)
        .map_err(|e| format!("cannot make the UDP socket non-blocking: {e}"))?;
    let mut drone = SimDrone::new(world, world.sim.seed, &Faults::default())?;
    let downlink = socket
        .try_clone()
        .map_err(|e| format!("cannot share the UDP socket: {e}"))?;
    let mut radio = Radio::new(Downlink::Udp(downlink), world, param_store)?;
    radio.map_json = map_json.map(Path::to_path_buf);
    radio.load_persistent(&mut drone);
    // The world's room reaches the drone as a user gives it: parameter writes after boot, before any start
    // (so it wins over a room stored in the EEPROM file).
    let size = (world.arena.size[0], world.arena.size[1]);
    write_room(&mut radio.ep.param, size, world_walls(world))
        .map_err(|lines| format!("the drone refused the world's room: {}", lines.trim_end()))?;
    eprintln!(
        "serving CRTP on udp://127.0.0.1:{port} ({} at {speed}× real time); write mission.start = 1 to fly",
        world.name
    );
    let mut watch = Watch::new(&drone);
    let mut buf = [0u8; 64];
    let wall = Instant::now();
    loop {
        // The network: every datagram waiting.
        loop {
            match socket.recv_from(&mut buf) {
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
            radio.ep.log.reset();
            radio.client = None;
        }

        // The drone: catch up with the wall clock, at most one chunk before polling again.
        let target = (wall.elapsed().as_secs_f64() * speed * 1000.0) as u64;
        let end = target.min(drone.tick() + CHUNK_TICKS);
        while drone.tick() < end {
            drone.step(world);
            radio.after_step(&mut drone, &mut watch);
        }
        if drone.tick() >= target {
            std::thread::sleep(Duration::from_micros(500));
        }
    }
}

/// `cfnav sim --serve` without its socket and clock: the same radio services and simulated drone, fed
/// datagrams and stepped by the caller, the downlink kept for the caller to read (the radio-level tests
/// fly client sequences through it). Not modelled: the wall-clock pacing and the client timeout that stops
/// log blocks after [`CLIENT_TIMEOUT`] of wall time; the EEPROM lives in memory.
pub struct InProcess {
    world: World,
    drone: SimDrone,
    radio: Radio,
    watch: Watch,
}

impl InProcess {
    /// A drone at power-on in `world` with noise seed `seed`, the persistent records (none) applied.
    pub fn new(world: &World, seed: u64) -> Result<Self, String> {
        let mut drone = SimDrone::new(world, seed, &Faults::default())?;
        let mut radio = Radio::new(Downlink::Memory(Vec::new()), world, None)?;
        radio.load_persistent(&mut drone);
        let watch = Watch::new(&drone);
        Ok(Self {
            world: world.clone(),
            drone,
            radio,
            watch,
        })
    }

    /// One datagram from `from`, handled as the server handles it (its replies go to the downlink).
    pub fn datagram(&mut self, bytes: &[u8], from: SocketAddr) {
        self.radio.on_datagram(bytes, from, &mut self.drone);
    }

    /// One simulated millisecond and what the server does after it.
    pub fn step(&mut self) {
        self.drone.step(&self.world);
        self.radio.after_step(&mut self.drone, &mut self.watch);
    }

    /// Every datagram sent since the last call, with its destination, in order.
    pub fn take_downlink(&mut self) -> Vec<(SocketAddr, Vec<u8>)> {
        match &mut self.radio.downlink {
            Downlink::Memory(out) => std::mem::take(out),
            Downlink::Udp(_) => Vec::new(),
        }
    }

    /// The simulated drone (flight core and body).
    pub fn drone(&self) -> &SimDrone {
        &self.drone
    }

    /// The world it flies in.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The parameters in effect.
    pub fn params(&self) -> &MissionParamState {
        self.radio.ep.param.store()
    }

    /// The client (the latest sender of a non-null datagram).
    pub fn client(&self) -> Option<SocketAddr> {
        self.radio.client
    }
}

#[cfg(test)]
mod tests {
    //! The server's wiring of the commander, supervisor and console services into the simulated drone,
    //! driven through `on_datagram` with packets laid out as cflib 0.1.34 packs them.

    use super::*;

    struct Bench {
        world: World,
        drone: SimDrone,
        radio: Radio,
        client: UdpSocket,
        from: SocketAddr,
    }

    impl Bench {
        fn new() -> Self {
            let world = World::default_world();
            let drone = SimDrone::new(&world, 7, &Faults::default()).unwrap();
            let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
            let radio = Radio::new(Downlink::Udp(socket), &world, None).unwrap();
            let client = UdpSocket::bind("127.0.0.1:0").unwrap();
            client.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
            let from = client.local_addr().unwrap();
            Self {
                world,
                drone,
                radio,
                client,
                from,
            }
        }

        /// One uplink packet `[header, data…]` (cflib header: port << 4 | 0x0C | channel).
        fn uplink(&mut self, port: u8, channel: u8, data: &[u8]) {
            let mut bytes = vec![(port << 4) | 0x0C | channel];
            bytes.extend_from_slice(data);
            self.radio.on_datagram(&bytes, self.from, &mut self.drone);
        }

        /// cflib `send_hover_setpoint(vx, vy, yawrate, z)`: port 7 ch 0, `<Bffff` (10, …).
        fn hover(&mut self, z_m: f32) {
            let mut data = vec![10u8];
            for v in [0.0f32, 0.0, 0.0, z_m] {
                data.extend_from_slice(&v.to_le_bytes());
            }
            self.uplink(7, 0, &data);
        }

        fn step_ms(&mut self, ms: u64) {
            for _ in 0..ms {
                self.drone.step(&self.world);
                if self.radio.ep.supervisor.poll(now_us(&self.drone)) {
                    self.radio.apply_supervisor(&mut self.drone);
                }
            }
        }

        /// Hover setpoints every 20 ms for `ms` milliseconds.
        fn hover_for(&mut self, z_m: f32, ms: u64) {
            for _ in 0..ms / 20 {
                self.hover(z_m);
                self.step_ms(20);
            }
        }

        /// The next datagram the client received on `port`, skipping others.
        fn received(&self, port: u8) -> Vec<u8> {
            let mut buf = [0u8; 64];
            loop {
                let n = self.client.recv(&mut buf).expect("a reply");
                if buf[0] >> 4 == port {
                    return buf[..n].to_vec();
                }
            }
        }
    }

    #[test]
    fn hover_setpoints_fly_the_drone_and_an_emergency_stop_latches() {
        let mut b = Bench::new();
        b.step_ms(1500); // estimator settles on the ground
        b.hover_for(0.5, 4000);
        let z = b.drone.core.estimate().position_m[2];
        assert!(b.drone.core.supervisor().flying, "hover setpoints took off");
        assert!((z - 0.5).abs() < 0.1, "hovering at {z} m");

        // Supervisor bitfield: armed, auto-armed, can fly, flying (bits 1, 2, 3, 4).
        b.uplink(9, 0, &[0x0C]);
        let reply = b.received(9);
        assert_eq!(reply[1], 0x8C);
        let bits = u16::from_le_bytes([reply[2], reply[3]]);
        assert_eq!(bits & 0b1_1110, 0b1_1110, "{bits:#06x}");

        // cflib send_emergency_stop(): port 9 ch 1 (0x03,).
        b.uplink(9, 1, &[0x03]);
        assert_eq!(b.drone.core.setpoint(), Setpoint::Stop);
        b.hover_for(0.5, 500);
        assert_eq!(
            b.drone.core.setpoint(),
            Setpoint::Stop,
            "later setpoints are replaced by Stop"
        );
        assert_eq!(b.drone.core.duty(), cfnav::types::MotorDuty::default(), "motors off");
        b.uplink(9, 0, &[0x0C]);
        let reply = b.received(9);
        let bits = u16::from_le_bytes([reply[2], reply[3]]);
        assert!(bits & (1 << 6) != 0, "locked bit after the emergency stop: {bits:#06x}");
    }

    #[test]
    fn the_emergency_stop_watchdog_fires_without_keepalives() {
        let mut b = Bench::new();
        b.step_ms(100);
        // cflib send_emergency_stop_watchdog(): port 9 ch 1 (0x04,).
        b.uplink(9, 1, &[0x04]);
        b.step_ms(900);
        b.uplink(9, 1, &[0x04]);
        b.step_ms(1000);
        assert!(!b.radio.ep.supervisor.emergency_stopped(), "kept alive");
        b.step_ms(2);
        assert!(
            b.radio.ep.supervisor.emergency_stopped(),
            "1000 ms after the last keepalive"
        );
        // mission.start = 1 (param write, port 2 ch 2: id u16 LE, u8) is refused afterwards.
        b.uplink(2, 2, &[0, 0, 1]);
        assert_eq!(b.radio.ep.param.store().start, 0);
        assert_eq!(b.drone.core.mission_state().code(), 0, "no mission started");
    }

    #[test]
    fn kalman_reset_estimation_re_anchors_the_estimate_at_the_start_parameters() {
        let mut b = Bench::new();
        b.step_ms(1500); // estimator settles on the ground
        // cflib set_value: port 2 ch 2, `<H` id then the value; the ids come from the declarations.
        let write = |b: &mut Bench, id: u16, value: &[u8]| {
            let mut data = id.to_le_bytes().to_vec();
            data.extend_from_slice(value);
            b.uplink(2, 2, &data);
        };
        use cfnav::radio_binding::param_table::{ID_START_X, ID_START_Y};
        write(&mut b, ID_START_X, &1.5f32.to_le_bytes());
        write(&mut b, ID_START_Y, &2.0f32.to_le_bytes());
        let before = b.drone.core.estimate().position_m;
        assert!(
            (before[0] - 1.5).abs() > 0.5,
            "the estimate starts elsewhere: {before:?}"
        );
        write(&mut b, ID_RESET_ESTIMATION, &[1]);
        let after = b.drone.core.estimate().position_m;
        assert!(
            (after[0] - 1.5).abs() < 1e-4 && (after[1] - 2.0).abs() < 1e-4,
            "{after:?}"
        );
        // The parameter reads 0 again, announced by a VALUE_UPDATED (2/3 `[1, id u16, 0]`).
        assert_eq!(b.radio.ep.param.store().reset_estimation, 0);
        let id = ID_RESET_ESTIMATION.to_le_bytes();
        loop {
            let p = b.received(2);
            if p[0] & 0x03 == 3 && p[1] == 1 {
                assert_eq!(&p[2..], &[id[0], id[1], 0]);
                break;
            }
        }
    }

    /// The link-loss policy through the server: `mission.linkLoss = 1` written by the client, a mission
    /// started; the client's null keep-alives (cflib's idle traffic) keep the link alive for 4 s, then the
    /// client falls silent: 2 s later the drone lands where it is (40) and ends `link lost` (207), and the
    /// client coming back does not undo it.
    #[test]
    fn a_silent_client_triggers_the_link_loss_policy_and_keep_alives_count() {
        use cfnav::mission::MissionState;
        use cfnav::radio_binding::param_table::ID_LINK_LOSS;
        let mut b = Bench::new();
        b.step_ms(1500);
        let write_u8 = |b: &mut Bench, id: u16, v: u8| {
            let mut data = id.to_le_bytes().to_vec();
            data.push(v);
            b.uplink(2, 2, &data);
        };
        write_u8(&mut b, ID_LINK_LOSS, 1);
        assert_eq!(b.radio.ep.param.store().link_loss.policy.code(), 1);
        write_u8(&mut b, ID_START, 1);
        assert!(b.drone.core.mission().is_running(), "mission started");
        // 4 s of null packets only, every 20 ms.
        for _ in 0..200 {
            b.radio.on_datagram(&[NULL_HEADER], b.from, &mut b.drone);
            b.step_ms(20);
        }
        let state = b.drone.core.mission_state();
        assert!(
            matches!(state, MissionState::TakeOffOutbound | MissionState::NavigateToGoal),
            "keep-alives kept the link: {state:?}"
        );
        b.step_ms(1900);
        assert_eq!(
            b.drone.core.mission_state(),
            MissionState::NavigateToGoal,
            "1.9 s of silence"
        );
        b.step_ms(200);
        assert_eq!(
            b.drone.core.mission_state(),
            MissionState::EmergencyLanding,
            "2.1 s of silence"
        );
        // The client is back: the landing goes on.
        for _ in 0..300 {
            b.radio.on_datagram(&[NULL_HEADER], b.from, &mut b.drone);
            b.step_ms(20);
            let state = b.drone.core.mission_state();
            assert!(
                matches!(state, MissionState::EmergencyLanding | MissionState::LinkLost),
                "{state:?}"
            );
        }
        assert_eq!(b.drone.core.mission_state(), MissionState::LinkLost);
    }

    /// cflib `send_setpoint` as stock flies it: thrust 0 unlocks, a thrust above the hover command climbs
    /// (before: not flown, one console line); a manual packet in roll/pitch-rate mode is not flown and says so.
    #[test]
    fn rpyt_with_thrust_flies_and_a_rate_mode_manual_packet_says_why_not() {
        let mut b = Bench::new();
        b.step_ms(1500); // estimator settles on the ground
        let bottom = b.drone.quad.params().bottom_offset_m;
        let z0 = b.drone.quad.position()[2] - bottom;
        // cflib send_setpoint(roll, pitch, yawrate, thrust): port 3, `<fffH`.
        let rpyt = |thrust: u16| {
            let mut d = Vec::new();
            for v in [0.0f32, 0.0, 0.0] {
                d.extend_from_slice(&v.to_le_bytes());
            }
            d.extend_from_slice(&thrust.to_le_bytes());
            d
        };
        b.uplink(3, 0, &rpyt(0));
        assert_eq!(b.drone.core.setpoint(), Setpoint::Stop, "thrust 0 is a stop");
        for _ in 0..75 {
            b.uplink(3, 0, &rpyt(50000));
            b.step_ms(20);
        }
        assert!(
            matches!(b.drone.core.setpoint(), Setpoint::Attitude { thrust: 50000, .. }),
            "{:?}",
            b.drone.core.setpoint()
        );
        assert!(b.drone.core.supervisor().flying);
        let climbed = b.drone.quad.position()[2] - bottom - z0;
        assert!(climbed > 0.2, "climbed {climbed} m in 1.5 s");
        b.uplink(3, 0, &rpyt(0));
        assert_eq!(b.drone.core.setpoint(), Setpoint::Stop, "thrust 0 stops again");
        b.step_ms(2500);
        // cflib send_setpoint_manual(roll_rate, pitch_rate, yaw_rate, thrust_percentage, rate=True): port 7 ch 0,
        // type 11, `<BfffHB` with the rate flag 1.
        let mut manual = vec![11u8];
        for v in [0.0f32, 0.0, 0.0] {
            manual.extend_from_slice(&v.to_le_bytes());
        }
        manual.extend_from_slice(&30000u16.to_le_bytes());
        manual.push(1);
        b.uplink(7, 0, &manual);
        let mut text = String::new();
        while !text.ends_with('\n') {
            let p = b.received(0);
            text.push_str(std::str::from_utf8(&p[1..]).unwrap());
        }
        assert!(text.contains("manual roll/pitch-rate setpoint not flown"), "{text}");
    }
}
