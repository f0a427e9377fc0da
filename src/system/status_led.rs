//! What the Crazyflie's four STM32-driven status LEDs (plus the left blue one) show, as a pure function of
//! the firmware's status and the time, so the patterns can be tested on the host.
//!
//! Job: pick the one status to show ([`BoardStatus::resolve`]) and the LEDs lit for it at a given time
//! ([`led_frame`]).
//!
//! Non-goals: no pins (the board layer maps a [`LedFrame`] to PD2/PC0–PC3 and their polarity,
//! stock `led.h`), no nRF-driven blue LED.
//!
//! Patterns (all periodic in 1 s, sampled at ≥ 40 Hz by the board's LED task); each status uses a colour or a
//! rhythm no other status uses, so they can be told apart from across the room:
//!
//! | status | blue L | greens | reds |
//! |---|---|---|---|
//! | booting | on | blink together at 4 Hz | off |
//! | ready (idle, mission can start) | off | on, 100 ms dark once a second | off |
//! | mission running | off | alternate left/right at 2 Hz | off |
//! | low battery | off | off | right red double-flash once a second |
//! | fault | off | off | both blink together at 2 Hz |
//!
//! Precedence: fault > low battery > booting > mission running > ready.
//!
//! Memory: a [`LedFrame`] is 5 bytes.

/// What the firmware is doing, as the LEDs show it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardStatus {
    /// Initialising (clocks, radio, sensors, deck probing).
    Booting,
    /// Idle and ready: a mission may be started.
    Ready,
    /// A mission runs.
    MissionRunning,
    /// The supervisor reports a low battery.
    LowBattery,
    /// Something failed (see the defmt log / console); the motors are off.
    Fault,
}

/// The inputs of [`BoardStatus::resolve`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct StatusInputs {
    /// Initialisation has finished.
    pub booted: bool,
    /// A fault was recorded (final until reset).
    pub fault: bool,
    /// The supervisor's low-battery flag.
    pub battery_low: bool,
    /// A mission runs.
    pub mission_running: bool,
}

impl BoardStatus {
    /// The status to show, by the precedence in the module documentation.
    pub fn resolve(inputs: StatusInputs) -> Self {
        if inputs.fault {
            Self::Fault
        } else if inputs.battery_low {
            Self::LowBattery
        } else if !inputs.booted {
            Self::Booting
        } else if inputs.mission_running {
            Self::MissionRunning
        } else {
            Self::Ready
        }
    }
}

/// Which LEDs are lit (`true` = light on, whatever the pin polarity).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LedFrame {
    /// BLUE_L (PD2).
    pub blue_l: bool,
    /// GREEN_L (PC1).
    pub green_l: bool,
    /// RED_L (PC0).
    pub red_l: bool,
    /// GREEN_R (PC2).
    pub green_r: bool,
    /// RED_R (PC3).
    pub red_r: bool,
}

/// The LEDs for `status` at `t_ms` milliseconds since boot.
pub fn led_frame(status: BoardStatus, t_ms: u64) -> LedFrame {
    const OFF: LedFrame = LedFrame {
        blue_l: false,
        green_l: false,
        red_l: false,
        green_r: false,
        red_r: false,
    };
    let phase_ms = t_ms % 1000;
    match status {
        BoardStatus::Booting => {
            let blink = (t_ms / 125).is_multiple_of(2);
            LedFrame {
                blue_l: true,
                green_l: blink,
                green_r: blink,
                ..OFF
            }
        }
        BoardStatus::Ready => {
            let lit = phase_ms >= 100;
            LedFrame {
                green_l: lit,
                green_r: lit,
                ..OFF
            }
        }
        BoardStatus::MissionRunning => {
            let left = (t_ms / 250).is_multiple_of(2);
            LedFrame {
                green_l: left,
                green_r: !left,
                ..OFF
            }
        }
        BoardStatus::LowBattery => {
            // Two 100 ms flashes, at 0 and 200 ms of each second.
            let flash = phase_ms < 100 || (200..300).contains(&phase_ms);
            LedFrame { red_r: flash, ..OFF }
        }
        BoardStatus::Fault => {
            let blink = (t_ms / 250).is_multiple_of(2);
            LedFrame {
                red_l: blink,
                red_r: blink,
                ..OFF
            }
        }
    }
}
