//! Mission and planning in thread mode: the [`Navigator`] (map, D* Lite planner, pad detector), kept in CCM,
//! ticked at 50 Hz. A tick runs at most one planner slice of `MissionConfig::planner_budget` expansions and
//! then yields, so the LED and watchdog tasks run between ticks; the control and I/O executors preempt it
//! at any instruction.
//!
//! Messages: takes [`super::MISSION_REQUESTS`] (start/abort from the radio), [`super::LINK`] (the latest
//! uplink packet's time and the link-loss parameters) and [`super::NAV_INPUTS`]
//! (height and Multi-ranger readings with their estimates), reads [`super::fast_status`], sends
//! [`MissionCommand`]s to the control task through [`super::FAST_INPUTS`] (awaiting a free slot while the
//! control loop runs, so a start or a setpoint is never dropped; dropped when no control loop was started,
//! e.g. after an IMU fault: nothing drains the channel then, and awaiting it would stop thread mode, the
//! watchdog would reset the MCU and the fault LEDs would never show), answers start requests on
//! [`super::START_OUTCOME`].

use core::cell::Cell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

use cfnav::mission::Mission;
use cfnav::nav::dstar::ARENA_QUEUE;
use cfnav::nav::map::ARENA_CELLS;
use cfnav::radio_binding::map_mem::MapView;
use cfnav::stack::{FlightConfig, MissionCommand, Navigator};
use cfnav::system::cpu_load::Level;
use defmt::{info, warn};
use embassy_time::{Duration, Ticker, Timer};

use super::{
    CONTROL_RUNNING, CONTROL_STEPS, DECKS_OK, FAST_INPUTS, FastInput, LINK, LOAD, MAP_READS, MAP_REPLIES,
    MISSION_NOTES, MISSION_REQUESTS, MISSION_RUNNING, MissionRequest, NAV_INPUTS, NavInput, START_OUTCOME,
    THREAD_BEATS, cycles, fast_status, now_us, update_log, yield_now,
};

/// The navigator sized for the firmware's arena.
pub type FwNavigator = Navigator<ARENA_CELLS, ARENA_QUEUE>;

/// Mission tick period (50 Hz, as the simulator).
pub const TICK: Duration = Duration::from_millis(20);

/// The navigator (≈ 47 KB: grid + planner + path), in CCM: CPU-only memory that nothing DMAs from. The
/// section is NOLOAD, so it holds garbage at reset until [`take_navigator`] writes it.
// SAFETY: `.ccmram` is the NOLOAD output section memory.x places in CCM; the linker lays this static out there
// like any other, and the only consequence of NOLOAD (no initial value) is handled by `take_navigator`.
#[unsafe(link_section = ".ccmram")]
static mut NAVIGATOR: MaybeUninit<FwNavigator> = MaybeUninit::uninit();
/// Set once [`NAVIGATOR`] has been handed out (kept in `.bss`, which is zeroed at reset, not in CCM).
static NAVIGATOR_TAKEN: AtomicBool = AtomicBool::new(false);

/// Builds the navigator in CCM and hands out the only reference to it; `None` on a second call or if the
/// configuration is invalid.
pub fn take_navigator(config: &FlightConfig) -> Option<&'static mut FwNavigator> {
    if NAVIGATOR_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // Checked first, then written field by field straight into the slot: built by value (in a `Result`, or
    // even returned directly) the ≈ 57 KB navigator went through the stack, a 104 KB frame that overran the
    // stack into `.bss` at boot (seen in the emulator: a corrupted clock table, a panic at 2 ms).
    let (avoidance, pad) = Mission::<ARENA_CELLS, ARENA_QUEUE>::checked_parts(config.mission).ok()?;
    let slot: *mut MaybeUninit<FwNavigator> = &raw mut NAVIGATOR;
    // SAFETY: `NAVIGATOR_TAKEN` lets exactly one caller past this point, and `NAVIGATOR` is named nowhere
    // else, so this is the only reference ever made to it; the slot is valid, aligned, 'static storage, and
    // writing a fully initialised value into a `MaybeUninit` is always sound.
    // `init_at` writes every field (its contract), so the slot is initialised afterwards.
    unsafe {
        FwNavigator::init_at((*slot).as_mut_ptr(), config, avoidance, pad);
        Some((*slot).assume_init_mut())
    }
}

/// Hands a command to the control task: waits for a free slot while the control loop runs (it drains the
/// channel every millisecond; if it stops, the watchdog's control rule resets the MCU); without a control
/// loop (a boot fault: the motors stay off) the command is dropped when the channel is full, so the
/// mission task, thread mode's heartbeat, never waits for a reader that does not exist.
async fn send_to_control(command: MissionCommand) {
    if CONTROL_RUNNING.load(Ordering::Acquire) {
        FAST_INPUTS.send(FastInput::Mission(command)).await;
    } else {
        let _ = FAST_INPUTS.try_send(FastInput::Mission(command));
    }
}

/// The 50 Hz mission loop.
#[embassy_executor::task]
pub async fn mission_task(nav: &'static mut FwNavigator) {
    let mut ticker = Ticker::every(TICK);
    let mut was_running = false;
    // The last state logged: one line per change, so a probe's log (and the emulator's judges) see the
    // mission's phases with the image's own timestamps (a few lines per flight, nothing per tick).
    let mut logged_state = None;
    let mut tuning_seen = 0u32;
    loop {
        ticker.next().await;
        // Thread mode's heartbeat for the watchdog feeder (`system::watchdog_task`).
        THREAD_BEATS.fetch_add(1, Ordering::Relaxed);
        nav.set_decks_ok(DECKS_OK.load(Ordering::Acquire));
        // The tuning parameters: in force from the next mission start.
        if let Some(t) = super::tuning_since(&mut tuning_seen) {
            nav.set_mission_config(t.mission);
        }

        let section = LOAD.begin(Level::Mission, cycles());
        let mut started = None;
        while let Ok(request) = MISSION_REQUESTS.try_receive() {
            match request {
                MissionRequest::Start(params) => {
                    let outcome = nav.start(params, &fast_status());
                    match outcome {
                        Ok(command) => {
                            started = Some(command);
                            // Before the outcome goes out, so the radio never sees "started, not running".
                            MISSION_RUNNING.store(true, Ordering::Release);
                        }
                        Err(e) => warn!("mission start refused: {}", defmt::Debug2Format(&e)),
                    }
                    START_OUTCOME.signal(outcome.map(|_| ()));
                }
                MissionRequest::Abort => nav.abort(&fast_status()),
            }
        }
        while let Ok(input) = NAV_INPUTS.try_receive() {
            match input {
                NavInput::ZRange(range, estimate) => nav.on_zrange(range, &estimate),
                NavInput::MultiRanger(sample, estimate) => {
                    if let Some(fixes) = nav.on_multiranger(&sample, &estimate) {
                        // The sweep's map fixes (a full queue drops them: the next sweep brings new ones).
                        let _ = FAST_INPUTS.try_send(FastInput::Mission(fixes));
                    }
                }
            }
        }
        LOAD.end(section, cycles());
        // The start message must reach the stabilizer before the first mission tick: the tick reads the
        // re-anchored estimate. Wait until the control loop has run a few steps since it was queued.
        if let Some(command) = started {
            send_to_control(command).await;
            let queued_at = CONTROL_STEPS.load(Ordering::Acquire);
            // Bounded: with the control loop down (a fault) nothing flies anyway.
            for _ in 0..50 {
                if CONTROL_STEPS.load(Ordering::Acquire).wrapping_sub(queued_at) >= 2 {
                    break;
                }
                Timer::after_millis(1).await;
            }
            info!("mission started");
        }

        // The link-loss watch: the latest uplink packet and the parameters, from the radio task.
        let (last_packet, link_loss) = LINK.lock(Cell::get);
        if let Some(t) = last_packet {
            nav.on_radio_packet(t);
        }
        nav.set_link_loss(link_loss);
        let section = LOAD.begin(Level::Mission, cycles());
        let command = nav.tick(now_us(), &fast_status());
        let running = nav.is_running();
        let state = nav.state();
        LOAD.end(section, cycles());
        if let Some(command @ MissionCommand::Setpoint { .. }) = command {
            send_to_control(command).await;
        }
        MISSION_RUNNING.store(running, Ordering::Release);
        if running && logged_state != Some(state) {
            info!("mission state {}", state.code());
            logged_state = Some(state);
        }
        if was_running && !running {
            info!("mission ended: state {}", state.code());
            logged_state = None;
        }
        was_running = running;
        // Map memory reads from the radio (port 4), answered from the map as it is between two ticks.
        while let Ok(read) = MAP_READS.try_receive() {
            let reply = read.answer(&MapView::of_mission(nav.mission()));
            if MAP_REPLIES.try_send(reply).is_err() {
                warn!("map memory reply dropped (radio behind)");
            }
        }
        if let Some(note) = nav.take_mission_note()
            && MISSION_NOTES.try_send(note).is_err()
        {
            warn!("mission console note dropped (radio behind)");
        }
        let stats = nav.mission().stats();
        update_log(|s| {
            s.flight.mission_state = state.code();
            s.flight.hover_dev_m = [stats.hover_dev_xy_m, stats.hover_dev_z_m];
            s.flight.coverage = stats.coverage;
        });
        // Let the other thread-mode tasks (LEDs, watchdog) run before the next slice.
        yield_now().await;
    }
}
