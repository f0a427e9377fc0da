//! The five STM32-driven LEDs (from bitcraze crazyflie-firmware
//! `src/drivers/interface/led.h`): BLUE_L on PD2 is active high; GREEN_L PC1, RED_L PC0, GREEN_R PC2 and
//! RED_R PC3 are active low. The patterns are `cfnav::system::status_led`'s; this task samples them at 40 Hz.

use cfnav::system::status_led::{LedFrame, led_frame};
use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::{Peri, peripherals};
use embassy_time::{Instant, Timer};

/// The LED pins.
pub struct Leds {
    blue_l: Output<'static>,
    green_l: Output<'static>,
    red_l: Output<'static>,
    green_r: Output<'static>,
    red_r: Output<'static>,
}

impl Leds {
    /// Takes the pins, all LEDs off.
    pub fn new(
        pd2: Peri<'static, peripherals::PD2>,
        pc1: Peri<'static, peripherals::PC1>,
        pc0: Peri<'static, peripherals::PC0>,
        pc2: Peri<'static, peripherals::PC2>,
        pc3: Peri<'static, peripherals::PC3>,
    ) -> Self {
        Self {
            blue_l: Output::new(pd2, Level::Low, Speed::Low),
            green_l: Output::new(pc1, Level::High, Speed::Low),
            red_l: Output::new(pc0, Level::High, Speed::Low),
            green_r: Output::new(pc2, Level::High, Speed::Low),
            red_r: Output::new(pc3, Level::High, Speed::Low),
        }
    }

    /// Lights the LEDs of `frame`.
    pub fn show(&mut self, frame: LedFrame) {
        let active_high = |on: bool| if on { Level::High } else { Level::Low };
        let active_low = |on: bool| if on { Level::Low } else { Level::High };
        self.blue_l.set_level(active_high(frame.blue_l));
        self.green_l.set_level(active_low(frame.green_l));
        self.red_l.set_level(active_low(frame.red_l));
        self.green_r.set_level(active_low(frame.green_r));
        self.red_r.set_level(active_low(frame.red_r));
    }
}

/// Shows [`super::board_status`] forever (thread mode: a stalled LED pattern means thread mode is stuck).
#[embassy_executor::task]
pub async fn led_task(mut leds: Leds) {
    loop {
        leds.show(led_frame(super::board_status(), Instant::now().as_millis()));
        Timer::after_millis(25).await;
    }
}
