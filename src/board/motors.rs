//! The four brushed motors: M1 PA1 TIM2_CH2, M2 PB11 TIM2_CH4, M3 PA15 TIM2_CH1, M4 PB9 TIM4_CH4, PWM1
//! active high at the stock 328.125 kHz with 8-bit resolution (84 MHz timer clock, prescaler 0, ARR 255),
//! so a [`MotorDuty`] byte is the compare value as is (`docs/hardware.md` §3; bitcraze
//! crazyflie-firmware `src/drivers/interface/motors.h`, `motors_def.c`).
//!
//! Safety: the outputs are low from construction; [`Motors::stop`] is what every fault path calls, and
//! [`zero_compare_registers`] is what the panic and HardFault handlers call, without the driver object.

use cfnav::types::MotorDuty;
use embassy_stm32::gpio::OutputType;
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::Channel;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::{Peri, pac, peripherals};

/// Stock PWM frequency: 84 MHz / 256.
pub const PWM_HZ: u32 = 328_125;
/// Compare values per period (8-bit).
pub const PWM_STEPS: u32 = 256;

/// Why the motor timers could not be set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct PwmResolutionError {
    /// Steps per period TIM2 got.
    pub tim2_steps: u32,
    /// Steps per period TIM4 got.
    pub tim4_steps: u32,
}

/// The motor PWM outputs.
pub struct Motors {
    tim2: SimplePwm<'static, peripherals::TIM2>,
    tim4: SimplePwm<'static, peripherals::TIM4>,
}

impl Motors {
    /// Sets up TIM2 and TIM4 at the stock frequency with all duties 0. Fails (outputs left at 0) if the
    /// timers did not get exactly 256 steps per period (a clock tree other than the expected 84 MHz).
    pub fn new(
        tim2: Peri<'static, peripherals::TIM2>,
        tim4: Peri<'static, peripherals::TIM4>,
        pa1: Peri<'static, peripherals::PA1>,
        pb11: Peri<'static, peripherals::PB11>,
        pa15: Peri<'static, peripherals::PA15>,
        pb9: Peri<'static, peripherals::PB9>,
    ) -> Result<Self, PwmResolutionError> {
        let m1 = PwmPin::new(pa1, OutputType::PushPull);
        let m2 = PwmPin::new(pb11, OutputType::PushPull);
        let m3 = PwmPin::new(pa15, OutputType::PushPull);
        let m4 = PwmPin::new(pb9, OutputType::PushPull);
        let freq = Hertz(PWM_HZ);
        let tim2 = SimplePwm::new(
            tim2,
            Some(m3),
            Some(m1),
            None,
            Some(m2),
            freq,
            CountingMode::EdgeAlignedUp,
        );
        let tim4 = SimplePwm::new(tim4, None, None, None, Some(m4), freq, CountingMode::EdgeAlignedUp);
        let mut motors = Self { tim2, tim4 };
        motors.stop();
        let (tim2_steps, tim4_steps) = (motors.tim2.max_duty_cycle(), motors.tim4.max_duty_cycle());
        if tim2_steps != PWM_STEPS || tim4_steps != PWM_STEPS {
            return Err(PwmResolutionError { tim2_steps, tim4_steps });
        }
        for ch in [Channel::Ch1, Channel::Ch2, Channel::Ch4] {
            motors.tim2.channel(ch).enable();
        }
        motors.tim4.channel(Channel::Ch4).enable();
        Ok(motors)
    }

    /// Writes the duties (M1..M4).
    pub fn set(&mut self, duty: MotorDuty) {
        let [m1, m2, m3, m4] = duty.0;
        self.tim2.channel(Channel::Ch2).set_duty_cycle(u32::from(m1));
        self.tim2.channel(Channel::Ch4).set_duty_cycle(u32::from(m2));
        self.tim2.channel(Channel::Ch1).set_duty_cycle(u32::from(m3));
        self.tim4.channel(Channel::Ch4).set_duty_cycle(u32::from(m4));
    }

    /// All motors off.
    pub fn stop(&mut self) {
        self.set(MotorDuty::default());
    }
}

/// Writes 0 to every compare register of TIM2 and TIM4 (CCR1..CCR4 at offsets 0x34..0x40, RM0090 §18.4):
/// with PWM mode 1 active high a compare value of 0 holds the output low from the next period (3 µs). For
/// the panic and HardFault handlers, which cannot reach the [`Motors`] object; plain register writes, no
/// lock, no allocation, safe to call in any state.
pub fn zero_compare_registers() {
    for n in 0..4 {
        pac::TIM2.ccr(n).write_value(Default::default());
        pac::TIM4.ccr(n).write_value(Default::default());
    }
}
