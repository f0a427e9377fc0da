//! The status LEDs as the GPIO model drives them, and which README status they show.
//!
//! Job: turn GPIOC/GPIOD's MODER and ODR into a [`LedFrame`] (BLUE_L PD2 active high; GREEN_L PC1, RED_L PC0,
//! GREEN_R PC2, RED_R PC3 active low, docs/hardware.md §1; a pin that is not an output lights nothing),
//! and classify a one-second window of samples against the firmware library's own pattern definition
//! ([`led_frame`]): a status is shown when every sample of the window equals its pattern at some instant of
//! the last [`LAG_MS`] (the LED task redraws every 25 ms).
//!
//! Non-goals: no blue LED of the nRF51, no brightness.

use cfnav::system::status_led::{BoardStatus, LedFrame, led_frame};

/// How far behind the pattern the pins may be: one LED-task period plus margin.
pub const LAG_MS: u64 = 40;
/// The patterns repeat every second.
pub const WINDOW_MS: u64 = 1000;

/// GPIOx_MODER (RM0090 §8.4.1) and ODR (§8.4.6) for ports C and D.
#[derive(Debug, Clone, Copy, Default)]
pub struct Pins {
    pub gpioc_moder: u32,
    pub gpioc_odr: u32,
    pub gpiod_moder: u32,
    pub gpiod_odr: u32,
}

fn is_output(moder: u32, pin: u32) -> bool {
    (moder >> (2 * pin)) & 0b11 == 0b01
}

fn high(odr: u32, pin: u32) -> bool {
    odr & (1 << pin) != 0
}

/// Which LEDs the pins light.
pub fn frame(p: Pins) -> LedFrame {
    let active_low = |pin: u32| is_output(p.gpioc_moder, pin) && !high(p.gpioc_odr, pin);
    LedFrame {
        blue_l: is_output(p.gpiod_moder, 2) && high(p.gpiod_odr, 2),
        green_l: active_low(1),
        red_l: active_low(0),
        green_r: active_low(2),
        red_r: active_low(3),
    }
}

/// Every status, for classification.
pub const STATUSES: [BoardStatus; 5] = [
    BoardStatus::Booting,
    BoardStatus::Ready,
    BoardStatus::MissionRunning,
    BoardStatus::LowBattery,
    BoardStatus::Fault,
];

/// The README's name of a status.
pub fn name(status: BoardStatus) -> &'static str {
    match status {
        BoardStatus::Booting => "booting",
        BoardStatus::Ready => "ready",
        BoardStatus::MissionRunning => "mission_running",
        BoardStatus::LowBattery => "battery_low",
        BoardStatus::Fault => "fault",
    }
}

/// Whether `observed` at `t_ms` is `status`'s pattern at some instant of the last [`LAG_MS`].
pub fn matches(status: BoardStatus, observed: LedFrame, t_ms: u64) -> bool {
    (0..=LAG_MS)
        .step_by(5)
        .any(|lag| t_ms >= lag && led_frame(status, t_ms - lag) == observed)
}

/// The status every sample of `samples` (time in ms, frame) matches, if exactly one does. The samples must
/// span at least [`WINDOW_MS`].
pub fn classify(samples: &[(u64, LedFrame)]) -> Option<BoardStatus> {
    let (first, last) = (samples.first()?.0, samples.last()?.0);
    if last - first + 1 < WINDOW_MS {
        return None;
    }
    let mut shown = STATUSES
        .into_iter()
        .filter(|&s| samples.iter().all(|&(t, f)| matches(s, f, t)));
    let status = shown.next()?;
    shown.next().is_none().then_some(status)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window(status: BoardStatus, start_ms: u64, lag_ms: u64) -> Vec<(u64, LedFrame)> {
        // One sample a millisecond, as the tool takes them.
        (start_ms..start_ms + WINDOW_MS)
            .map(|t| {
                // The LED task draws every 25 ms: the pins hold the frame of the last redraw.
                let drawn = (t.saturating_sub(lag_ms) / 25) * 25;
                (t, led_frame(status, drawn))
            })
            .collect()
    }

    #[test]
    fn every_status_is_recognised_from_its_own_pattern_and_only_as_itself() {
        for status in STATUSES {
            for start in [0, 1234, 5000] {
                assert_eq!(
                    classify(&window(status, start, 3)),
                    Some(status),
                    "{status:?} at {start}"
                );
            }
        }
    }

    #[test]
    fn a_short_or_mixed_window_is_not_classified() {
        let mut w = window(BoardStatus::Booting, 0, 0);
        assert_eq!(classify(&w[..100]), None, "less than a second");
        w.extend(window(BoardStatus::Ready, 1000, 0));
        assert_eq!(
            classify(&w),
            None,
            "booting then ready is neither over the whole window"
        );
    }

    #[test]
    fn pins_decode_with_polarity_and_direction() {
        // PC0..PC3 outputs, PC1 low (green left on), others high; PD2 output high (blue on).
        let p = Pins {
            gpioc_moder: 0b01_01_01_01,
            gpioc_odr: 0b1101,
            gpiod_moder: 0b01 << 4,
            gpiod_odr: 1 << 2,
        };
        let f = frame(p);
        assert!(f.blue_l && f.green_l && !f.red_l && !f.green_r && !f.red_r);
        // Inputs light nothing, whatever ODR holds.
        assert_eq!(frame(Pins::default()), LedFrame::default());
    }
}
