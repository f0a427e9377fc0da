//! System housekeeping: the independent watchdog and the CPU-load / loop-timing statistics.

use core::sync::atomic::Ordering;

use cfnav::system::cpu_load::{cycles_to_us_u16, percent};
use defmt::info;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_time::{Duration, Ticker};

use super::control::TIMING;
use super::{BOOTED, CONTROL_RUNNING, CONTROL_STEPS, CPU_HZ, LOAD, cycles, update_log};

/// IWDG timeout, µs. Stock uses ≈188 ms (`crazyflie-hardware.md` §2); this firmware's longest thread-mode
/// step is a planner slice of `planner_budget` expansions (≈ 40 ms worst case, BENCHMARKS.md), so 250 ms
/// leaves a margin.
pub const WATCHDOG_TIMEOUT_US: u32 = 250_000;
/// How often the watchdog is fed.
pub const WATCHDOG_PET: Duration = Duration::from_millis(50);

/// Feeds the IWDG from thread mode (the lowest priority: a stuck planner or a starved thread mode resets
/// the MCU), and, once the control loop was started, only while it makes progress (an IMU that stops or a
/// stuck control executor resets too; the reset leaves the motor pins unpowered). If the control loop never
/// started (a boot fault), the watchdog is fed so the fault stays on the LEDs instead of a reset loop.
#[embassy_executor::task]
pub async fn watchdog_task(mut wdg: IndependentWatchdog<'static, IWDG>) {
    wdg.unleash();
    let mut ticker = Ticker::every(WATCHDOG_PET);
    let mut last_steps = CONTROL_STEPS.load(Ordering::Relaxed);
    loop {
        ticker.next().await;
        let steps = CONTROL_STEPS.load(Ordering::Relaxed);
        let control_expected = BOOTED.load(Ordering::Acquire) && CONTROL_RUNNING.load(Ordering::Acquire);
        if !control_expected || steps != last_steps {
            wdg.pet();
        }
        last_steps = steps;
    }
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
