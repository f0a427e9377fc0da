//! Estimation and control: the [`Stabilizer`] in an interrupt-priority executor, one step per gyro
//! data-ready edge (BMI088 INT3 → PC14, EXTI14 rising: `docs/hardware.md` §2), reading the IMU on
//! I2C3 and writing the motors.
//!
//! Each step: wait for the edge, read gyro + accelerometer (async I2C, ~0.5 ms of bus time during which
//! lower priorities run), then, without awaiting: drain [`super::FAST_INPUTS`] (at most one costly estimator
//! update, flow or Multi-ranger, per step: a second one waits one step in a [`HeavyInputGate`]), run
//! [`Stabilizer::on_imu`], write the motors (zero unless booted, no fault and the supervisor allows them),
//! publish the [`cfnav::stack::FastStatus`] (and, every tenth step, the log variables), account the cycles.
//! The IMU bus is guarded (every read has a 1 ms deadline, a hung bus is recovered:
//! `cfnav::drivers::i2c_guard`); a missing data-ready edge ([`DRDY_TIMEOUT`]) or a failed read is a missed
//! sample: the motors stay level for at most `cfnav::stack::IMU_LEVEL_US`, then stop and the supervisor
//! latches Crashed. Motors stop on any fault and [`MAX_IMU_ERRORS`] missed samples in a row raise one.

use core::sync::atomic::Ordering;

use cfnav::drivers::bmi088::{AccelTrim, Bmi088};
use cfnav::stack::{MissionCommand, Stabilizer, ZRANGE_MIDPOINT_US};
use cfnav::system::cpu_load::{Level, LoopTiming, LoopWindow};
use cfnav::system::step_pacing::HeavyInputGate;
use defmt::warn;
use embassy_executor::InterruptExecutor;
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::Priority;
use embassy_stm32::mode::Async;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, with_timeout};

use super::motors::Motors;
use super::{
    BOOTED, CONTROL_PASSES, CONTROL_STEPS, FAST_INPUTS, FAULT, FastInput, LOAD, NAV_INPUTS, NavInput, cycles, fault,
    now_us, publish_fast_status, update_log,
};

/// NVIC priority of the control executor (P0 is the most urgent; HAL interrupt handlers keep P0).
pub const PRIORITY: Priority = Priority::P6;
/// A gyro edge later than this (2 periods) counts as a missed sample (`Stabilizer::on_imu_missed`).
pub const DRDY_TIMEOUT: Duration = Duration::from_millis(2);
/// Consecutive failed IMU reads (or missed edges) that make a fault.
pub const MAX_IMU_ERRORS: u32 = 50;
/// The log state is refreshed every this many control steps (1 kHz / 10 = 100 Hz).
const LOG_DECIMATION: u32 = 10;

/// The control executor, on the otherwise unused UART4 vector (the Crazyflie 2.1's UARTs are USART2/3 on
/// the deck and USART6 for syslink: `docs/hardware.md` §2).
pub static EXECUTOR: InterruptExecutor = InterruptExecutor::new();

/// The loop-timing window of the last second, handed to the statistics task.
pub static TIMING: Signal<CriticalSectionRawMutex, LoopWindow> = Signal::new();

#[interrupt]
fn UART4() {
    // SAFETY: this is the UART4 handler, the only place `on_interrupt` is called, and UART4 is unmasked only
    // by `EXECUTOR.start()`, so the executor is initialised whenever this runs.
    unsafe { EXECUTOR.on_interrupt() }
}

/// The IMU on the sensor bus.
pub type Imu = Bmi088<super::i2c_bus::GuardedBus>;

/// The inputs whose estimator update is costly (flow ≈ 14 k, Multi-ranger with wall anchors ≈ 20 k
/// instructions, a sweep's map fixes about as much; QEMU counts in BENCHMARKS.md).
fn is_heavy(input: &FastInput) -> bool {
    matches!(
        input,
        FastInput::Flow(_) | FastInput::MultiRanger(_) | FastInput::Mission(MissionCommand::MapFixes(_))
    )
}

/// Drains the inputs queued for the stabilizer since the previous step, at most one costly one.
fn drain_inputs(stab: &mut Stabilizer, gate: &mut HeavyInputGate<FastInput>) {
    if let Some(input) = gate.begin_step() {
        apply_input(stab, input);
    }
    while !gate.holding() {
        let Ok(input) = FAST_INPUTS.try_receive() else {
            break;
        };
        let heavy = is_heavy(&input);
        if let Some(input) = gate.admit(input, heavy) {
            apply_input(stab, input);
        }
    }
}

fn apply_input(stab: &mut Stabilizer, input: FastInput) {
    {
        match input {
            FastInput::Flow(sample) => stab.on_flow(&sample),
            FastInput::ZRange(range, ready_us) => {
                let age_us = now_us().saturating_sub(ready_us) + ZRANGE_MIDPOINT_US;
                let estimate = stab.on_zrange(range).backdated(age_us as f32 * 1e-6);
                // The mission drains this every 20 ms; if it is full the pad detector loses one reading.
                let _ = NAV_INPUTS.try_send(NavInput::ZRange(range, estimate));
            }
            FastInput::MultiRanger(sample) => stab.on_multiranger(&sample),
            FastInput::Battery(volts) => stab.on_battery(volts),
            FastInput::Mission(command) => stab.apply(command),
            FastInput::Commander(setpoint, time) => stab.commander_setpoint(setpoint, time),
            FastInput::HighLevel(command, time) => {
                if let Err(e) = stab.high_level_command(command, time) {
                    defmt::warn!("high-level command refused: {}", defmt::Debug2Format(&e));
                }
            }
        }
    }
}

/// The 1 kHz loop. Never returns; on a fault the motors stay off and the loop keeps publishing the estimate.
#[embassy_executor::task]
pub async fn control_task(
    mut stab: Stabilizer,
    mut imu: Imu,
    trim: AccelTrim,
    mut drdy: ExtiInput<'static, Async>,
    mut motors: Motors,
) {
    motors.stop();
    let mut timing = LoopTiming::new();
    let mut window_start = cycles();
    let mut errors = 0u32;
    let mut gate = HeavyInputGate::new();
    let mut tuning_seen = 0u32;
    loop {
        let edge = with_timeout(DRDY_TIMEOUT, drdy.wait_for_rising_edge()).await;
        let wake = cycles();
        CONTROL_PASSES.fetch_add(1, Ordering::Relaxed);
        let sample = match edge {
            // The config block's board trim, on the accelerometer (stock `sensorsAccAlignToGravity`).
            Ok(()) => imu.read().await.ok().map(|s| trim.apply_to(s)),
            Err(_) => None,
        };
        let Some(sample) = sample else {
            // The inputs are still taken, so the tasks that queue them never wait on a full queue (the
            // mission task awaits room for its setpoints: with the IMU lost it blocked there, and the
            // watchdog reset the board, undoing the latched fault; found in the emulator,
            // `cfnav-pil --fault imu-lost`).
            drain_inputs(&mut stab, &mut gate);
            // Level for a few periods, then off and latched (`Stabilizer::on_imu_missed`).
            let duty = stab.on_imu_missed(now_us());
            if BOOTED.load(Ordering::Acquire) && !FAULT.load(Ordering::Acquire) {
                motors.set(duty);
            } else {
                motors.stop();
            }
            publish_fast_status(stab.status());
            errors += 1;
            if errors == MAX_IMU_ERRORS {
                fault("IMU: no data-ready edge or read failures");
            } else if errors % 10 == 1 {
                warn!("IMU: missed a sample ({} in a row)", errors);
            }
            continue;
        };
        errors = 0;

        let section = LOAD.begin(Level::Control, cycles());
        drain_inputs(&mut stab, &mut gate);
        // The tuning parameters (radio writes), from this step on; the radio validated them.
        if let Some(t) = super::tuning_since(&mut tuning_seen)
            && stab.set_tuning(t.controller, t.flow_std_counts).is_err()
        {
            warn!("tuning parameters refused by the controller");
        }
        let duty = stab.on_imu(&sample, now_us());
        if BOOTED.load(Ordering::Acquire) && !FAULT.load(Ordering::Acquire) {
            motors.set(duty);
        } else {
            motors.stop();
        }
        publish_fast_status(stab.status());
        let step = CONTROL_STEPS.fetch_add(1, Ordering::Relaxed);
        if step.is_multiple_of(LOG_DECIMATION) {
            // The log variables at 100 Hz (the fastest period cflib asks for is 10 ms).
            let (estimate, control, setpoint) = (stab.estimate(), *stab.control(), stab.setpoint());
            let battery_low = stab.supervisor().battery_low;
            update_log(|s| {
                s.flight.record_flight(&estimate, &control, &setpoint);
                s.flight.battery_low = battery_low;
            });
        }
        let end = cycles();
        LOAD.end(section, end);
        timing.record(wake, end);
        if end.wrapping_sub(window_start) >= super::CPU_HZ {
            window_start = end;
            TIMING.signal(timing.take());
        }
    }
}
