//! The board layer of the firmware: peripherals, tasks and the messages between them. Only compiled for the
//! MCU (`target_os = "none"`); every algorithm it runs lives in the library and is tested on the host.
//!
//! Priorities (NVIC: lower number = more urgent; thread mode is below every interrupt):
//!
//! | level | where | runs |
//! |---|---|---|
//! | P0 (HAL default) | interrupt handlers | TIM5 time driver, DMA, USART6, I2C, EXTI: they only wake tasks |
//! | [`control::PRIORITY`] (P6) | interrupt executor on the UART4 vector | estimation + control, paced by the gyro data-ready edge (PC14) |
//! | [`IO_PRIORITY`] (P9) | interrupt executor on the UART5 vector | syslink + CRTP services, deck sensors, CPU-load statistics, the watchdog feeder |
//! | thread mode | `#[embassy_executor::main]` | mission + planner (budgeted slices), LEDs |
//!
//! Messages (each crossing holds a critical section for a copy of at most a few hundred bytes, i.e.
//! microseconds; nothing is locked while a task computes):
//! * [`FAST_INPUTS`]: sensors, radio and mission → control task (flow, height, battery, mission commands,
//!   commander setpoints); the control task drains it before each step.
//! * [`FAST_STATUS`]: control task → everyone (the [`FastStatus`] after the latest step).
//! * [`NAV_INPUTS`]: control and sensor tasks → mission task (height + estimate, Multi-ranger + estimate).
//! * [`MISSION_REQUESTS`] / [`START_OUTCOME`]: radio ⇄ mission task (`mission.start` writes).
//! * [`MAP_READS`] / [`MAP_REPLIES`]: radio ⇄ mission task (reads of the map memory on CRTP port 4).
//! * [`LOG_STATE`]: what the log service samples; each task writes its own fields.
//! * [`TUNING`] / [`TUNING_GENERATION`]: radio → control and mission tasks (the tuning parameters; each task
//!   copies them when the generation changes). [`eeprom::EEPROM_JOB`] / [`eeprom::EEPROM_DONE`]: radio ⇄
//!   deck task (persistent-parameter writes on the deck bus).
//! * [`LINK`]: radio → mission task: when the latest uplink packet came and the link-loss parameters.
//!
//! Non-goals here: any flight logic (see `cfnav::stack`), any protocol logic (see `cfnav::radio`).
//! Memory: the navigator (map + planner, ≈ 47 KB) sits in CCM; everything else is static SRAM (see the
//! `cfnav firmware` report).

pub mod control;
pub mod eeprom;
pub mod i2c_bus;
pub mod leds;
pub mod mission;
pub mod motors;
pub mod radio;
pub mod sensors;
pub mod system;

use core::cell::Cell;
use core::future::poll_fn;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use core::task::Poll;

use cfnav::flight::high_level::HlCommand;
use cfnav::mission::link_loss::LinkLossConfig;
use cfnav::mission::{MissionNote, MissionParams};
use cfnav::radio::crtp::CrtpPacket;
use cfnav::radio::mem::MapRead;
use cfnav::radio_binding::log_table::FirmwareLogState;
use cfnav::radio_binding::tuning::Tuning;
use cfnav::stack::{FastStatus, MissionCommand, StartError};
use cfnav::system::cpu_load::LoadMeter;
use cfnav::system::status_led::{BoardStatus, StatusInputs};
use cfnav::types::{FlowSample, Micros, MultiRangerSample, RangeReading, Setpoint, StateEstimate};
use defmt::error;
use embassy_stm32::interrupt::Priority;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;

/// SYSCLK, Hz (`clock_config` in `main.rs`): the DWT cycle counter's rate.
pub const CPU_HZ: u32 = 168_000_000;
/// NVIC priority of the sensors + radio executor: below control, above thread mode.
pub const IO_PRIORITY: Priority = Priority::P9;

/// Inputs of the control task.
#[derive(Clone, Copy, Debug)]
pub enum FastInput {
    /// An optical-flow reading.
    Flow(FlowSample),
    /// A downward-range reading and when it was found ready, µs (forwarded to the navigator with the new
    /// estimate, backdated to when the range was measured).
    ZRange(RangeReading, Micros),
    /// A Multi-ranger sweep (wall anchors while the commander holds a position).
    MultiRanger(MultiRangerSample),
    /// Battery voltage from the nRF, V.
    Battery(f32),
    /// A message from the navigator.
    Mission(MissionCommand),
    /// A radio commander setpoint and when it arrived, µs (the radio task drops them while a mission runs).
    Commander(Setpoint, Micros),
    /// A high-level commander command (port 8) and when it arrived, µs (dropped while a mission runs).
    HighLevel(HlCommand, Micros),
}

/// Inputs of the mission task from the sensors.
#[derive(Clone, Copy, Debug)]
pub enum NavInput {
    /// A height reading with the estimate of the pose it was measured from: the stabilizer's right after
    /// it used the reading, backdated by the reading's age (`cfnav::stack::ZRANGE_MIDPOINT_US` plus the
    /// wait to be read).
    ZRange(RangeReading, StateEstimate),
    /// The Multi-ranger's beams with the estimate of the pose they were measured from (the latest,
    /// backdated by `cfnav::stack::BEAM_MIDPOINT_US` plus the sweep's mean wait).
    MultiRanger(MultiRangerSample, StateEstimate),
}

/// What the radio asks of the mission task.
#[derive(Clone, Copy, Debug)]
pub enum MissionRequest {
    /// `mission.start = 1` with these parameters.
    Start(MissionParams),
    /// `mission.start = 0` during a mission.
    Abort,
}

/// Sensors, radio and mission → control task. Eight slots: a control step (1 ms) drains it, while the
/// producers add at most ~2 items per ms (flow 100 Hz, height 40 Hz, battery 100 Hz, 50 Hz mission).
pub static FAST_INPUTS: Channel<CriticalSectionRawMutex, FastInput, 8> = Channel::new();
/// The stabilizer's latest status (copied out under a critical section); `None` before the first step.
pub static FAST_STATUS: Mutex<CriticalSectionRawMutex, Cell<Option<FastStatus>>> = Mutex::new(Cell::new(None));
/// Sensors → mission task (the mission drains it every tick, 50 Hz; 40 + 10 readings per second arrive).
pub static NAV_INPUTS: Channel<CriticalSectionRawMutex, NavInput, 8> = Channel::new();
/// Radio → mission task.
pub static MISSION_REQUESTS: Channel<CriticalSectionRawMutex, MissionRequest, 2> = Channel::new();
/// Radio → mission task: a read of the map memory (CRTP port 4, `cfnav::radio_binding::map_mem`); the map lives in
/// the mission task, which answers it between ticks. cflib keeps one read in flight at a time.
pub static MAP_READS: Channel<CriticalSectionRawMutex, MapRead, 2> = Channel::new();
/// Mission task → radio: the answers to [`MAP_READS`], ready to send.
pub static MAP_REPLIES: Channel<CriticalSectionRawMutex, CrtpPacket, 2> = Channel::new();
/// Mission task → radio: decisions of the mission for the console (explore's battery reserve).
pub static MISSION_NOTES: Channel<CriticalSectionRawMutex, MissionNote, 2> = Channel::new();
/// Mission task → radio: the outcome of the latest start request.
pub static START_OUTCOME: Signal<CriticalSectionRawMutex, Result<(), StartError>> = Signal::new();
/// What the log service samples; `None` until a task first writes it (see [`log_state`]).
pub static LOG_STATE: Mutex<CriticalSectionRawMutex, Cell<Option<FirmwareLogState>>> = Mutex::new(Cell::new(None));
/// Busy cycles per priority level.
pub static LOAD: LoadMeter = LoadMeter::new();
/// The tuning parameters in effect (radio → control and mission tasks); `None` until the radio's first.
pub static TUNING: Mutex<CriticalSectionRawMutex, Cell<Option<Tuning>>> = Mutex::new(Cell::new(None));
/// Bumped after each change of [`TUNING`].
pub static TUNING_GENERATION: AtomicU32 = AtomicU32::new(0);

/// Publishes new tuning parameters to the control and mission tasks.
pub fn publish_tuning(tuning: Tuning) {
    TUNING.lock(|c| c.set(Some(tuning)));
    TUNING_GENERATION.fetch_add(1, Ordering::Release);
}

/// The tuning parameters if they changed since generation `seen` (which is updated).
pub fn tuning_since(seen: &mut u32) -> Option<Tuning> {
    let now = TUNING_GENERATION.load(Ordering::Acquire);
    if now == *seen {
        return None;
    }
    *seen = now;
    TUNING.lock(Cell::get)
}
/// Radio → mission task: (when the latest uplink packet arrived, µs; `mission.linkLoss`/`linkTimeout`).
pub static LINK: Mutex<CriticalSectionRawMutex, Cell<(Option<Micros>, LinkLossConfig)>> =
    Mutex::new(Cell::new((None, LinkLossConfig::DEFAULT)));

/// Range logged when a ranger has no valid reading (stock multiranger.c reports 32767 mm).
pub const NO_RANGE_MM: u16 = 32767;

/// Initialisation has finished (LEDs leave "booting"; the motors may run from now on).
pub static BOOTED: AtomicBool = AtomicBool::new(false);
/// A fault was recorded: the motors stay off until reset. Final.
pub static FAULT: AtomicBool = AtomicBool::new(false);
/// A mission runs (the radio drops commander setpoints meanwhile).
pub static MISSION_RUNNING: AtomicBool = AtomicBool::new(false);
/// Both decks the mission needs answered their probes.
pub static DECKS_OK: AtomicBool = AtomicBool::new(false);
/// The Flow deck v2's PMW3901 answered at boot (`deck.bcFlow2`).
pub static DECK_FLOW2: AtomicBool = AtomicBool::new(false);
/// The Multi-ranger's beams answered at boot (`deck.bcMultiranger`).
pub static DECK_MULTIRANGER: AtomicBool = AtomicBool::new(false);
/// The control task was started (the watchdog then wants [`CONTROL_PASSES`] to advance).
pub static CONTROL_RUNNING: AtomicBool = AtomicBool::new(false);
/// Control steps run since boot (one per IMU sample flown).
pub static CONTROL_STEPS: AtomicU32 = AtomicU32::new(0);
/// Passes of the control loop since boot, a sample flown or a missed one (the watchdog is fed only while
/// this advances: it watches the loop run, not the IMU answer; a lost IMU is the loop's own fault, which
/// stops the motors and latches, and a reset would undo the latch).
pub static CONTROL_PASSES: AtomicU32 = AtomicU32::new(0);
/// Mission ticks run since boot: thread mode's heartbeat (the watchdog is fed only while this advances).
pub static THREAD_BEATS: AtomicU32 = AtomicU32::new(0);

/// The latest stabilizer status.
pub fn fast_status() -> FastStatus {
    FAST_STATUS.lock(Cell::get).unwrap_or_default()
}

/// Publishes the stabilizer's status.
pub fn publish_fast_status(status: FastStatus) {
    FAST_STATUS.lock(|cell| cell.set(Some(status)));
}

/// The log state now (rangers read "no range" until their first reading).
pub fn log_state() -> FirmwareLogState {
    LOG_STATE.lock(Cell::get).unwrap_or_else(initial_log_state)
}

fn initial_log_state() -> FirmwareLogState {
    let mut s = FirmwareLogState::default();
    s.flight.ranges_mm = [NO_RANGE_MM; 6];
    s
}

/// Changes the log state under the lock (a copy of ~60 bytes).
pub fn update_log(f: impl FnOnce(&mut FirmwareLogState)) {
    LOG_STATE.lock(|cell| {
        let mut s = cell.get().unwrap_or_else(initial_log_state);
        f(&mut s);
        cell.set(Some(s));
    });
}

/// Records a fault: motors off from the next control step, red LEDs. Final until reset.
pub fn fault(what: &str) {
    error!("fault: {}", what);
    FAULT.store(true, Ordering::Release);
}

/// What the LEDs show now.
pub fn board_status() -> BoardStatus {
    BoardStatus::resolve(StatusInputs {
        booted: BOOTED.load(Ordering::Acquire),
        fault: FAULT.load(Ordering::Acquire),
        battery_low: fast_status().supervisor.battery_low,
        mission_running: MISSION_RUNNING.load(Ordering::Acquire),
    })
}

/// The DWT cycle counter (enabled in `main`; reads 0 if it could not be).
pub fn cycles() -> u32 {
    cortex_m::peripheral::DWT::cycle_count()
}

/// Microseconds since boot (the embassy time driver on TIM5).
pub fn now_us() -> Micros {
    embassy_time::Instant::now().as_micros()
}

/// Yields once to the executor, so its other tasks run (the planner is CPU-bound).
pub async fn yield_now() {
    let mut yielded = false;
    poll_fn(|cx| {
        if yielded {
            Poll::Ready(())
        } else {
            yielded = true;
            cx.waker().wake_by_ref();
            Poll::Pending
        }
    })
    .await;
}
