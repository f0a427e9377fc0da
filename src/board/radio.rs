//! Syslink to the nRF51 on USART6 (TX PC6, RX PC7, 1 Mbaud 8N1, DMA both ways) with the PA4 flow-control
//! input (high = the nRF's buffer is full: pause sending), and the CRTP services answering over it
//! (`docs/hardware.md` §4).
//!
//! Flow control at byte granularity: every frame goes out through [`FlowTx`] in chunks of
//! [`cfnav::radio::syslink_tx::CHUNK`] bytes, PA4 read before each and each chunk awaited to the USART's
//! transmission-complete flag, so at most four bytes reach the nRF after it raises RTS (its FIFO's headroom;
//! see `cfnav::radio::syslink_tx`). A frame not gone within [`FRAME_TX_TIMEOUT`] (PA4 held high, or a TX
//! DMA transfer or TC flag that never completes) drops the rest of the frame. The RX DMA ring is started in `main` before anything is sent, so the nRF's echoes are kept.
//!
//! Boot order (`docs/hardware.md` §4): RADIO_CHANNEL, RADIO_DATARATE, RADIO_ADDRESS from the EEPROM config block (or the
//! defaults), each resent until the nRF echoes it ([`BootSettings`]), PM_BATTERY_AUTOUPDATE, SYS_NRF_VERSION
//! (the reply is logged), then RADIO_READY once the firmware has finished booting (the nRF keeps its
//! receiver off until then, or 3 s after its boot).
//!
//! Pacing (`docs/hardware.md` §4): one downlink RADIO_RAW per uplink RADIO_RAW, at most; log data, parameter updates and
//! console lines wait in the router's queue for the next uplink (cfclient and cflib poll continuously).
//!
//! Commander (ports 3 and 7): each accepted setpoint is mapped by [`SetpointFollower`] and handed to the
//! control task with its arrival time, once, and only while no mission runs (as `cfnav sim --serve` does).
//! High-level commander (port 8): each accepted command goes to the control task, whose stabilizer flies the
//! trajectory; refused ones (decoder, group mask, a running mission, a fault) get one console line.
//! Console (port 0): refusal notes and firmware messages through [`cfnav::radio::console::ConsoleService`].
//! Supervisor (port 9): state bits from the stabilizer's verdict; arming cannot be changed (auto-arming, as
//! the stock Crazyflie 2.1); an emergency stop (command or its watchdog) cuts the motors at once and is
//! latched until reset like a fault (stock: Locked, reboot required); a running mission is aborted.
//!
//! Tuning parameters go to the control and mission tasks (`super::publish_tuning`); a persistent store or
//! clear is written by the deck task (`super::eeprom`) and answered when it is done. The records read at
//! boot are applied through the same checks as a radio write before the first packet.
//!
//! `mission.start` writes become [`MissionRequest`]s for the mission task; a refusal by the flight core
//! comes back on [`START_OUTCOME`] and is reverted (`mission.start` back to 0, VALUE_UPDATED, console line),
//! and the end of a mission sets it back to 0 the same way (`docs/radio.md`).

use core::fmt::Write as _;
use core::sync::atomic::Ordering;

use cfnav::mission::MissionParams;
use cfnav::nav::map::ARENA_CELLS;
use cfnav::radio::commander::SetpointFollower;
use cfnav::radio::crtp::CrtpPacket;
use cfnav::radio::mem::MemService;
use cfnav::radio::param::ParamService;
use cfnav::radio::syslink::{BatteryState, DecodeError, SyslinkDecoder, SyslinkPacket, kind};
use cfnav::radio::syslink_tx::{BootSettings, FlowTx, TxStep, nrf_version, nrf_version_request};
use cfnav::radio_binding::endpoint::Endpoint;
use cfnav::radio_binding::log_table::FirmwareLogState;
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::{ID_RESET_ESTIMATION, ID_START};
use cfnav::radio_binding::supervisor_port::{SupervisorPortConfig, SupervisorStatus};
use cfnav::radio_binding::tuning::Tuning;
use cfnav::stack::{FlightConfig, MissionCommand};
use cfnav::system::config_block::RadioSettings;
use cfnav::system::cpu_load::Level;
use cfnav::system::mission_start::{StartDecision, StartTracker};
use cfnav::system::persistent_params::PersistentParams;
use defmt::{info, warn};
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::mode::Async;
use embassy_stm32::usart::{RingBufferedUartRx, UartTx};
use embassy_time::{Duration, Instant, with_deadline, with_timeout};
use heapless::String;

use super::eeprom::{EEPROM_DONE, EEPROM_JOB};
use super::{
    BOOTED, DECK_FLOW2, DECK_MULTIRANGER, DECKS_OK, FAST_INPUTS, FAULT, FastInput, LINK, LOAD, MAP_READS, MAP_REPLIES,
    MISSION_NOTES, MISSION_REQUESTS, MISSION_RUNNING, MissionRequest, START_OUTCOME, cycles, fast_status, fault,
    log_state, update_log,
};

/// Firmware version the platform service reports.
pub const FIRMWARE_TAG: &str = concat!("cfnav-", env!("CARGO_PKG_VERSION"));
/// Router queue depth (log data, replies, parameter updates, console packets).
pub const ROUTER_QUEUE: usize = 16;
/// Console packets waiting for a downlink.
const CONSOLE_QUEUE: usize = 16;
/// How long one frame may take in total (PA4 hold-backs plus its chunks' DMA transfers, 0.7 ms for a
/// full frame at 1 Mbaud) before the rest of it is dropped.
const FRAME_TX_TIMEOUT: Duration = Duration::from_millis(20);
/// Log blocks are stopped when no uplink came for this long (cflib pings at least every 100 ms).
const LINK_TIMEOUT: Duration = Duration::from_secs(3);

/// USART6 through DMA, with the PA4 flow-control input.
pub struct SyslinkUart {
    /// USART6 TX (DMA2 stream 7).
    pub tx: UartTx<'static, Async>,
    /// USART6 RX into a DMA ring buffer (DMA2 stream 1).
    pub rx: RingBufferedUartRx<'static>,
    /// PA4, the nRF's RTS: high = stop sending.
    pub flow: ExtiInput<'static, Async>,
    /// The frame being sent, in flow-controlled chunks.
    pub frame_tx: FlowTx,
}

/// Why a frame was not sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
enum SendError {
    /// The nRF held PA4 high past the frame's [`FRAME_TX_TIMEOUT`].
    FlowControl,
    /// The UART/DMA transfer failed.
    Uart,
    /// A chunk's DMA transfer or its TC flush did not finish by the frame's deadline.
    Stalled,
    /// The packet does not fit a frame (cannot happen for the packets built here).
    Encode,
}

impl SyslinkUart {
    /// Sends one frame, chunk by chunk, pausing while PA4 is high.
    async fn send(&mut self, packet: &SyslinkPacket) -> Result<(), SendError> {
        self.frame_tx.load(packet).map_err(|_| SendError::Encode)?;
        let deadline = Instant::now() + FRAME_TX_TIMEOUT;
        loop {
            match self.frame_tx.next(self.flow.is_high()) {
                TxStep::Done => return Ok(()),
                TxStep::WaitForClear => {
                    if with_deadline(deadline, self.flow.wait_for_low()).await.is_err() {
                        self.frame_tx.abandon();
                        return Err(SendError::FlowControl);
                    }
                }
                TxStep::Send(bytes) => {
                    let n = bytes.len();
                    // `flush` waits for TC: the chunk has left the shift register before PA4 is read again.
                    // Both share the frame's deadline: a TX DMA or TC that never completes must not
                    // park the radio task (dropping the futures stops the DMA stream).
                    let tx = &mut self.tx;
                    let written = with_deadline(deadline, async move {
                        tx.write(bytes).await?;
                        tx.flush().await
                    })
                    .await;
                    match written {
                        Ok(Ok(())) => {}
                        Ok(Err(_)) => {
                            self.frame_tx.abandon();
                            return Err(SendError::Uart);
                        }
                        Err(_) => {
                            self.frame_tx.abandon();
                            return Err(SendError::Stalled);
                        }
                    }
                    self.frame_tx.sent(n);
                }
            }
        }
    }
}

/// Milliseconds since boot, wrapping (the echo timer's clock).
fn now_ms() -> u32 {
    Instant::now().as_millis() as u32
}

type Params = ParamService<MissionParamState>;

/// The CRTP side: router, services and the `mission.start` bookkeeping.
struct Crtp {
    ep: Endpoint<MissionParamState, FirmwareLogState, CONSOLE_QUEUE, ROUTER_QUEUE>,
    follower: SetpointFollower,
    commander_dropped: u32,
    /// `mission.start` requests in flight.
    start: StartTracker,
    last_uplink: Option<Instant>,
    dropped_downlinks: u32,
    /// The tuning generation last handed to the control and mission tasks.
    tuning_published: u32,
    /// A persistent write is with the deck task.
    eeprom_busy: bool,
}

impl Crtp {
    /// The services, with the persistent parameters read at boot applied through the radio's checks.
    fn new(stored: PersistentParams) -> Self {
        let config = FlightConfig::default();
        let tuning = Tuning::new(config.controller, &config.estimator, config.mission);
        let mut ep = Endpoint::new(
            FIRMWARE_TAG,
            MissionParamState::new(MissionParams::SEED, ARENA_CELLS).with_tuning(tuning),
            SupervisorPortConfig {
                auto_arm: true,
                can_recover: false,
            },
        );
        // The map memory (port 4): listed to clients, read through the mission task.
        ep.mem = MemService::with_map(ARENA_CELLS);
        let mut crtp = Self {
            ep,
            follower: SetpointFollower::new(),
            commander_dropped: 0,
            start: StartTracker::new(),
            last_uplink: None,
            dropped_downlinks: 0,
            tuning_published: 0,
            eeprom_busy: false,
        };
        let summary = crtp.ep.param.load_persistent(stored);
        if summary.applied + summary.unknown + summary.refused > 0 {
            info!(
                "persistent parameters: {} applied, {} unknown, {} refused",
                summary.applied, summary.unknown, summary.refused
            );
        }
        crtp
    }

    /// Tuning writes to the control and mission tasks; persistent writes to the deck task and their
    /// answers back.
    fn tuning_and_eeprom(&mut self) {
        let generation = self.ep.param.store().tuning_generation;
        if generation != self.tuning_published {
            self.tuning_published = generation;
            super::publish_tuning(self.ep.param.store().tuning);
        }
        if !self.eeprom_busy
            && let Some(write) = self.ep.param.eeprom_write()
        {
            EEPROM_JOB.signal(*write);
            self.eeprom_busy = true;
        }
        if self.eeprom_busy
            && let Some(ok) = EEPROM_DONE.try_take()
        {
            self.eeprom_busy = false;
            if !ok {
                self.console("persistent store: EEPROM write failed\n");
            }
            if let Some(reply) = self.ep.param.eeprom_write_done(ok)
                && self.ep.router.enqueue(reply).is_err()
            {
                self.dropped_downlinks = self.dropped_downlinks.saturating_add(1);
            }
        }
    }

    /// Queues a console line.
    fn console(&mut self, text: &str) {
        self.ep.console.print(text);
    }

    /// Hands the commander's new setpoint to the control task, if one arrived and no mission runs.
    fn apply_commander(&mut self) {
        let Some((command, received_us)) = self.ep.commander.take_fresh() else {
            return;
        };
        if MISSION_RUNNING.load(Ordering::Acquire) || self.start.pending() {
            return;
        }
        let estimate = fast_status().estimate;
        if let Some(setpoint) = self.follower.to_setpoint(&command, received_us, &estimate)
            && FAST_INPUTS
                .try_send(FastInput::Commander(setpoint, received_us))
                .is_err()
        {
            // The next packet (cflib sends them at 10–100 Hz) carries the same intent.
            self.commander_dropped = self.commander_dropped.saturating_add(1);
        }
    }

    /// Hands a high-level command (port 8) to the control task, or says on the console why not: every port 8
    /// packet not acted on gets one line.
    fn apply_high_level(&mut self) {
        let mut line: String<96> = String::new();
        if let Some(e) = self.ep.high_level.take_error() {
            let _ = writeln!(line, "high-level commander: packet not flown: {e:?}");
        } else if let Some((command, received_us)) = self.ep.high_level.take() {
            if MISSION_RUNNING.load(Ordering::Acquire) || self.start.pending() {
                let _ = writeln!(line, "high-level command refused: a mission is running");
            } else if FAULT.load(Ordering::Acquire) {
                let _ = writeln!(line, "high-level command refused: fault latched (power-cycle)");
            } else if FAST_INPUTS
                .try_send(FastInput::HighLevel(command, received_us))
                .is_err()
            {
                let _ = writeln!(line, "high-level command dropped: control queue full, send it again");
            }
        }
        if !line.is_empty() {
            self.console(&line);
        }
    }

    /// One uplink CRTP packet: returns the one downlink packet it may carry.
    fn on_uplink(&mut self, bytes: &[u8], now: Instant) -> Option<CrtpPacket> {
        self.last_uplink = Some(now);
        {
            let store = self.ep.param.store_mut();
            store.flying = fast_status().supervisor.flying;
            store.decks_ok = DECKS_OK.load(Ordering::Acquire);
            store.flow2_deck = DECK_FLOW2.load(Ordering::Acquire);
            store.multiranger_deck = DECK_MULTIRANGER.load(Ordering::Acquire);
        }
        let before = self.ep.param.store().start;
        let running = MISSION_RUNNING.load(Ordering::Acquire);
        self.ep.supervisor.set_status(SupervisorStatus {
            output: fast_status().supervisor,
            mission_running: running,
            mission_finished: !running && log_state().flight.mission_state != 0,
            decks_ok: DECKS_OK.load(Ordering::Acquire),
        });
        let reply = self.ep.handle_uplink(bytes, now.as_micros());
        // A map read goes to the mission task, which owns the map; its answer comes back through
        // `MAP_REPLIES` (drained in `housekeeping`). cflib waits for each answer, so the queue never fills; if a
        // client did not wait, the extra read is dropped and the client's own timeout retries it.
        if let Some(read) = self.ep.mem.take_map_read()
            && MAP_READS.try_send(read).is_err()
        {
            warn!("map memory read dropped (one already waiting)");
        }
        // The mission task's link-loss watch: this packet, and the parameters in effect after it.
        let link = (self.ep.last_uplink_us(), self.ep.param.store().link_loss);
        LINK.lock(|c| c.set(link));
        self.apply_commander();
        self.apply_high_level();
        let after = self.ep.param.store().start;
        let fault = FAULT.load(Ordering::Acquire);
        match self.start.on_write(before, after, fault) {
            StartDecision::RequestStart => {
                let params = self.ep.param.store().params;
                let queued = MISSION_REQUESTS.try_send(MissionRequest::Start(params)).is_ok();
                if let Some(reason) = self.start.request_queued(queued) {
                    self.revert_start(reason);
                }
            }
            StartDecision::RequestAbort if MISSION_REQUESTS.try_send(MissionRequest::Abort).is_err() => {
                warn!("abort request dropped (queue full)");
            }
            StartDecision::Refuse(reason) => self.revert_start(reason),
            StartDecision::RequestAbort | StartDecision::None => {}
        }
        reply
    }

    /// Emergency stop: motors off now, latched until reset; a running mission is aborted so its state ends.
    fn emergency_stop(&mut self) {
        fault("emergency stop (supervisor port)");
        let _ = MISSION_REQUESTS.try_send(MissionRequest::Abort);
        if self.ep.param.store().start != 0 {
            self.ep.param.store_mut().start = 0;
            self.ep.param.notify(ID_START);
        }
        self.console("emergency stop: motors stopped; power-cycle to fly again\n");
    }

    fn revert_start(&mut self, line: &str) {
        self.ep.param.store_mut().start = 0;
        self.ep.param.notify(ID_START);
        warn!("{}", line.trim_end());
        self.console(line);
    }

    /// Everything that is not a reply: start outcomes, the end of a mission, parameter updates and refusal
    /// lines, due log data.
    fn housekeeping(&mut self, now: Instant) {
        self.tuning_and_eeprom();
        let fired = self.ep.supervisor.poll(now.as_micros());
        if fired || self.ep.supervisor.take_requests().emergency_stop {
            self.emergency_stop();
        }
        if let Some(outcome) = START_OUTCOME.try_take()
            && self.start.on_outcome(outcome.is_ok())
            && let Err(e) = outcome
        {
            let mut line: String<192> = String::new();
            let _ = writeln!(line, "mission.start refused: {e}");
            self.revert_start(&line);
        }
        if self
            .start
            .must_clear(self.ep.param.store().start, MISSION_RUNNING.load(Ordering::Acquire))
        {
            // The mission ended (or never ran): `docs/radio.md` wants mission.start back at 0.
            self.ep.param.store_mut().start = 0;
            self.ep.param.notify(ID_START);
        }
        while let Some(p) = self.ep.param.next_notification() {
            if self.ep.router.enqueue(p).is_err() {
                self.dropped_downlinks = self.dropped_downlinks.saturating_add(1);
            }
        }
        while let Some(note) = self.ep.param.take_refusal() {
            let line = Params::console_line(&note);
            self.console(&line);
        }
        while let Ok(note) = MISSION_NOTES.try_receive() {
            let mut line: String<128> = String::new();
            let _ = writeln!(line, "{note}");
            info!("{}", line.as_str().trim_end());
            self.console(&line);
        }
        if self
            .last_uplink
            .is_some_and(|t| now.saturating_duration_since(t) > LINK_TIMEOUT)
        {
            info!("radio link silent: log blocks stopped");
            self.ep.log.reset();
            self.last_uplink = None;
        }
        while self.ep.router.pending() < ROUTER_QUEUE
            && let Ok(p) = MAP_REPLIES.try_receive()
        {
            let _ = self.ep.router.enqueue(p);
        }
        self.ep.console.flush();
        while self.ep.router.pending() < ROUTER_QUEUE / 2
            && let Some(p) = self.ep.console.next_packet()
        {
            let _ = self.ep.router.enqueue(p);
        }
        // kalman.resetEstimation: the control task re-anchors the estimate (as a mission start does); the
        // parameter reads 0 again once the request is queued (retried next time if the queue is full).
        if let Some(xy) = self.ep.param.store().pending_reset()
            && FAST_INPUTS
                .try_send(FastInput::Mission(MissionCommand::Started { start_m: xy }))
                .is_ok()
        {
            self.ep.param.store_mut().reset_estimation = 0;
            self.ep.param.notify(ID_RESET_ESTIMATION);
        }
        let mut state = log_state();
        state.flight.supervisor_info = self.ep.supervisor.bitfield();
        let now_ms = now.as_millis() as u32;
        while let Some(p) = self.ep.log.tick(now_ms, &state) {
            if self.ep.router.enqueue(p).is_err() {
                self.dropped_downlinks = self.dropped_downlinks.saturating_add(1);
                break;
            }
        }
    }
}

/// What one received syslink packet asks to send back.
fn on_syslink(crtp: &mut Crtp, packet: &SyslinkPacket, now: Instant) -> Option<SyslinkPacket> {
    match packet.kind {
        kind::RADIO_RAW => {
            let reply = crtp.on_uplink(&packet.payload, now)?;
            let mut bytes = [0u8; 32];
            let n = reply.to_bytes(&mut bytes);
            SyslinkPacket::radio_raw(&bytes[..n]).ok()
        }
        kind::PM_BATTERY_STATE => {
            if let Ok(battery) = BatteryState::parse(packet) {
                // Dropped if the control task is behind; the next report comes 10 ms later.
                let _ = FAST_INPUTS.try_send(FastInput::Battery(battery.vbat));
                update_log(|s| s.flight.vbat_v = battery.vbat);
            }
            None
        }
        kind::PM_SHUTDOWN_REQUEST => {
            // The nRF powers everything off 100 ms after the request unless acknowledged; the motors stop now.
            fault("power-off requested by the nRF (button)");
            Some(SyslinkPacket::pm_shutdown_ack())
        }
        _ => None,
    }
}

/// The radio task: boot sequence, then receive, dispatch and answer forever.
#[embassy_executor::task]
pub async fn radio_task(mut uart: SyslinkUart, settings: RadioSettings, stored: PersistentParams) {
    let mut boot = match settings.boot_packets() {
        Ok(packets) => BootSettings::new(&packets),
        Err(_) => {
            warn!("radio settings out of range: nRF keeps its own");
            BootSettings::new(&[])
        }
    };
    send_boot_settings(&mut uart, &mut boot).await;
    if let Err(e) = uart.send(&SyslinkPacket::pm_battery_autoupdate()).await {
        warn!("PM_BATTERY_AUTOUPDATE not sent: {}", e);
    }
    if let Err(e) = uart.send(&nrf_version_request()).await {
        warn!("SYS_NRF_VERSION not sent: {}", e);
    }
    let mut boot_reported = false;
    let mut crtp = Crtp::new(stored);
    let mut decoder = SyslinkDecoder::new();
    let mut chunk = [0u8; 64];
    let mut ready_sent = false;
    let mut rx_errors = 0u32;
    let mut frames_dropped = 0u32;
    loop {
        if !ready_sent && BOOTED.load(Ordering::Acquire) {
            match uart.send(&SyslinkPacket::radio_ready()).await {
                Ok(()) => info!("RADIO_READY sent: the nRF opens its receiver"),
                Err(e) => warn!("RADIO_READY not sent: {}", e),
            }
            ready_sent = true;
        }
        let n = match with_timeout(Duration::from_millis(10), uart.rx.read(&mut chunk)).await {
            Ok(Ok(n)) => n,
            Ok(Err(e)) => {
                rx_errors = rx_errors.saturating_add(1);
                if rx_errors.is_power_of_two() {
                    warn!("syslink RX error {} ({} so far)", e, rx_errors);
                }
                0
            }
            Err(_) => 0,
        };
        let now = Instant::now();
        for &byte in &chunk[..n] {
            let mut event = decoder.push(byte);
            while let Some(result) = event {
                if let Err(e) = &result {
                    // A frame lost on the wire is one request the host never gets an answer to (cflib does
                    // not retry TOC or parameter requests): say so, at 1, 2, 4, … so a noisy line cannot flood.
                    frames_dropped = frames_dropped.saturating_add(1);
                    if frames_dropped.is_power_of_two() {
                        match e {
                            DecodeError::Oversized(len) => {
                                warn!("syslink frame dropped: length {} ({} so far)", len, frames_dropped)
                            }
                            DecodeError::BadChecksum => {
                                warn!("syslink frame dropped: bad checksum ({} so far)", frames_dropped)
                            }
                        }
                    }
                }
                if let Ok(packet) = result {
                    if boot.on_received(&packet) {
                        info!("nRF confirmed radio setting {=u8:#x}", packet.kind);
                    } else if let Some(version) = nrf_version(&packet) {
                        info!("nRF51 firmware {}", version);
                    }
                    let section = LOAD.begin(Level::Io, cycles());
                    let answer = on_syslink(&mut crtp, &packet, now);
                    LOAD.end(section, cycles());
                    if let Some(answer) = answer
                        && let Err(e) = uart.send(&answer).await
                    {
                        warn!("syslink answer not sent: {}", e);
                    }
                }
                event = decoder.poll();
            }
        }
        send_boot_settings(&mut uart, &mut boot).await;
        if !boot_reported && boot.is_settled() {
            boot_reported = true;
            if boot.gave_up() > 0 {
                warn!(
                    "{} radio setting(s) never echoed: the nRF may use its defaults",
                    boot.gave_up()
                );
            }
        }
        let section = LOAD.begin(Level::Io, cycles());
        crtp.housekeeping(now);
        LOAD.end(section, cycles());
    }
}

/// Sends the boot settings that are due: first sends, and resends of those whose echo is late.
async fn send_boot_settings(uart: &mut SyslinkUart, boot: &mut BootSettings) {
    while let Some(p) = boot.poll(now_ms()) {
        if let Err(e) = uart.send(&p).await {
            warn!("syslink radio setting {=u8:#x} not sent: {}", p.kind, e);
        }
    }
}
