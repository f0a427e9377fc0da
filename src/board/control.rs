//! Estimation and control: the [`Stabilizer`] in an interrupt-priority executor, one step per gyro
//! data-ready edge (BMI088 INT3 → PC14, EXTI14 rising: `crazyflie-hardware.md` §8.1), reading the IMU on
//! I2C3 and writing the motors.
//!
//! Each step: wait for the edge, read gyro + accelerometer (async I2C, ~0.5 ms of bus time during which
//! lower priorities run), then, without awaiting: drain [`super::FAST_INPUTS`], run
//! [`Stabilizer::on_imu`], write the motors (zero unless booted, no fault and the supervisor allows them),
//! publish the [`cfnav::stack::FastStatus`], account the cycles. Motors stop on any fault, on a missing
//! data-ready edge ([`DRDY_TIMEOUT`]) and after [`MAX_IMU_ERRORS`] failed reads in a row.

use core::sync::atomic::Ordering;

use cfnav::drivers::bmi088::Bmi088;
use cfnav::stack::Stabilizer;
use cfnav::system::cpu_load::{Level, LoopTiming, LoopWindow};
use defmt::warn;
use embassy_executor::InterruptExecutor;
use embassy_stm32::exti::ExtiInput;
use embassy_stm32::i2c::I2c;
use embassy_stm32::i2c::mode::Master as I2cMaster;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::Priority;
use embassy_stm32::mode::Async;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, with_timeout};

use super::motors::Motors;
use super::{
    BOOTED, CONTROL_STEPS, FAST_INPUTS, FAULT, FastInput, LOAD, NAV_INPUTS, NavInput, cycles, fault, now_us,
    publish_fast_status,
};

/// NVIC priority of the control executor (P0 is the most urgent; HAL interrupt handlers keep P0).
pub const PRIORITY: Priority = Priority::P6;
/// A gyro edge later than this (5 periods) stops the motors for that step and counts as a miss.
pub const DRDY_TIMEOUT: Duration = Duration::from_millis(5);
/// Consecutive failed IMU reads (or missed edges) that make a fault.
pub const MAX_IMU_ERRORS: u32 = 50;

/// The control executor, on the otherwise unused UART4 vector (the Crazyflie 2.1's UARTs are USART2/3 on
/// the deck and USART6 for syslink: `crazyflie-hardware.md` §5).
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
pub type Imu = Bmi088<I2c<'static, Async, I2cMaster>>;

/// Drains the inputs queued for the stabilizer since the previous step.
fn drain_inputs(stab: &mut Stabilizer) {
    while let Ok(input) = FAST_INPUTS.try_receive() {
        match input {
            FastInput::Flow(sample) => stab.on_flow(&sample),
            FastInput::ZRange(range) => {
                let estimate = stab.on_zrange(range);
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
pub async fn control_task(mut stab: Stabilizer, mut imu: Imu, mut drdy: ExtiInput<'static, Async>, mut motors: Motors) {
    motors.stop();
    let mut timing = LoopTiming::new();
    let mut window_start = cycles();
    let mut errors = 0u32;
    loop {
        let edge = with_timeout(DRDY_TIMEOUT, drdy.wait_for_rising_edge()).await;
        let wake = cycles();
        let sample = match edge {
            Ok(()) => imu.read().await.ok(),
            Err(_) => None,
        };
        let Some(sample) = sample else {
            motors.stop();
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
        drain_inputs(&mut stab);
        let duty = stab.on_imu(&sample, now_us());
        if BOOTED.load(Ordering::Acquire) && !FAULT.load(Ordering::Acquire) {
            motors.set(duty);
        } else {
            motors.stop();
        }
        publish_fast_status(stab.status());
        CONTROL_STEPS.fetch_add(1, Ordering::Relaxed);
        let end = cycles();
        LOAD.end(section, end);
        timing.record(wake, end);
        if end.wrapping_sub(window_start) >= super::CPU_HZ {
            window_start = end;
            TIMING.signal(timing.take());
        }
    }
}
