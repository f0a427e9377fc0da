//! System housekeeping: the flash accelerator, the independent watchdog, the panic and HardFault handlers,
//! and the CPU-load / loop-timing statistics.
//!
//! Watchdog: the IWDG is programmed for [`NOMINAL_TIMEOUT_US`] at the nominal 32 kHz LSI, which is 102–282 ms
//! over the datasheet's 17–47 kHz (`cfnav::system::watchdog`). It is fed every [`FEED_PERIOD_US`] from the
//! I/O executor (P9), which preempts thread mode, so no planner slice can delay a feed; the
//! [`FeedGate`] withholds the feed once thread mode (the mission task's heartbeat) has made no progress for
//! `THREAD_STALL_US` (500 ms, three times the longest planner slice at CPI 3) or the running control loop
//! for `CONTROL_STALL_US` (50 ms).

use core::sync::atomic::{AtomicBool, Ordering};

use cfnav::system::cpu_load::{cycles_to_us_u16, percent};
use cfnav::system::flash_acr::{DCRST, ICRST, cache_reset_word, check_acr, expected_acr};
use cfnav::system::watchdog::{FEED_PERIOD_US, FeedGate, FeedInputs, NOMINAL_TIMEOUT_US, Starved};
use defmt::{error, info};
use embassy_stm32::pac;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_time::{Duration, Ticker};

use super::control::TIMING;
use super::{BOOTED, CONTROL_PASSES, CONTROL_RUNNING, CPU_HZ, LOAD, THREAD_BEATS, cycles, motors, now_us, update_log};

/// IWDG timeout asked of embassy, µs (nominal: embassy assumes a 32 kHz LSI).
pub const WATCHDOG_TIMEOUT_US: u32 = NOMINAL_TIMEOUT_US;

/// Resets and enables the flash's instruction and data caches and prefetch (embassy's clock setup writes
/// `FLASH_ACR` with the latency alone, clearing them), then reads the register back. `Err(value read)` if it
/// does not hold what `cfnav::system::flash_acr::expected_acr` says.
pub fn enable_flash_accelerator() -> Result<(), u32> {
    let (Some(reset), Some(run)) = (cache_reset_word(CPU_HZ), expected_acr(CPU_HZ)) else {
        return Err(pac::FLASH.acr().read().0);
    };
    // RM0090 §3.9.1: the reset bits work only with the caches disabled, and must be cleared again.
    pac::FLASH.acr().write_value(pac::flash::regs::Acr(reset));
    pac::FLASH
        .acr()
        .write_value(pac::flash::regs::Acr(reset & !(ICRST | DCRST)));
    pac::FLASH.acr().write_value(pac::flash::regs::Acr(run));
    let read = pac::FLASH.acr().read().0;
    match check_acr(read, CPU_HZ) {
        Some(findings) if findings.is_ok() => Ok(()),
        _ => Err(read),
    }
}

/// Feeds the IWDG every [`FEED_PERIOD_US`] while the [`FeedGate`] allows it. Runs on the I/O executor.
#[embassy_executor::task]
pub async fn watchdog_task(mut wdg: IndependentWatchdog<'static, IWDG>) {
    wdg.unleash();
    let mut ticker = Ticker::every(Duration::from_micros(u64::from(FEED_PERIOD_US)));
    let mut gate = FeedGate::new();
    let mut reported = false;
    loop {
        let decision = gate.decide(FeedInputs {
            now_us: now_us(),
            booted: BOOTED.load(Ordering::Acquire),
            control_running: CONTROL_RUNNING.load(Ordering::Acquire),
            control_passes: CONTROL_PASSES.load(Ordering::Relaxed),
            thread_beats: THREAD_BEATS.load(Ordering::Relaxed),
        });
        match decision {
            Ok(()) => wdg.pet(),
            Err(why) if !reported => {
                reported = true;
                match why {
                    Starved::ThreadMode => error!("watchdog: thread mode stalled, reset follows"),
                    Starved::Control => error!("watchdog: control loop stalled, reset follows"),
                }
            }
            Err(_) => {}
        }
        ticker.next().await;
    }
}

/// Set by the first panic, so a panic inside the handler (the logger taken re-entrantly) goes straight to the
/// reset.
static PANICKING: AtomicBool = AtomicBool::new(false);

/// Motors first (interrupts off, so no control step can write them again), then the message, then a reset
/// (which also leaves the motor pins unpowered).
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    motors::zero_compare_registers();
    if !PANICKING.swap(true, Ordering::Relaxed) {
        error!("panic: {}", defmt::Display2Format(info));
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// HardFault (priority -1: nothing but NMI preempts it): motors, message, reset.
#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    motors::zero_compare_registers();
    if !PANICKING.swap(true, Ordering::Relaxed) {
        error!("HardFault: pc {=u32:#010x} lr {=u32:#010x}", frame.pc(), frame.lr());
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// Once a second: CPU load per level and the control loop's jitter, longest step and rate → log variables.
#[embassy_executor::task]
pub async fn stats_task() {
    let mut ticker = Ticker::every(Duration::from_secs(1));
    let mut window_start = cycles();
    let _ = LOAD.take();
    let mut seconds = 0u32;
    loop {
        ticker.next().await;
        let now = cycles();
        let window = u64::from(now.wrapping_sub(window_start));
        window_start = now;
        let busy = LOAD.take();
        let total: u64 = busy.iter().map(|&b| u64::from(b)).sum();
        let load = [
            percent(total, window),
            percent(u64::from(busy[0]), window),
            percent(u64::from(busy[1]), window),
            percent(u64::from(busy[2]), window),
        ];
        let timing = TIMING.try_take().unwrap_or_default();
        let jitter_us = cycles_to_us_u16(timing.jitter(), CPU_HZ);
        let step_max_us = cycles_to_us_u16(timing.max_step, CPU_HZ);
        let rate_hz = u16::try_from(timing.steps).unwrap_or(u16::MAX);
        update_log(|s| {
            s.load_pct = load;
            s.loop_jitter_us = jitter_us;
            s.loop_step_max_us = step_max_us;
            s.loop_rate_hz = rate_hz;
        });
        seconds = seconds.wrapping_add(1);
        if seconds.is_multiple_of(10) {
            info!(
                "load {}% (control {}%, io {}%, mission {}%), control {} Hz, jitter {} us, step max {} us",
                load[0], load[1], load[2], load[3], rate_hz, jitter_us, step_max_us
            );
        }
    }
}
