//! The status LED patterns: each status is recognisable (its own colour or rhythm), the patterns match the
//! table in `status_led.rs`, faults win over everything, and no status ever lights a red LED unless it is a
//! fault or a low battery.

use cfnav::system::status_led::{BoardStatus, LedFrame, StatusInputs, led_frame};

const ALL: [BoardStatus; 5] = [
    BoardStatus::Booting,
    BoardStatus::Ready,
    BoardStatus::MissionRunning,
    BoardStatus::LowBattery,
    BoardStatus::Fault,
];

/// Frames every 5 ms over 2 s.
fn trace(status: BoardStatus) -> Vec<LedFrame> {
    (0..400).map(|i| led_frame(status, i * 5)).collect()
}

fn share(frames: &[LedFrame], f: impl Fn(&LedFrame) -> bool) -> f32 {
    frames.iter().filter(|x| f(x)).count() as f32 / frames.len() as f32
}

fn rising_edges(frames: &[LedFrame], f: impl Fn(&LedFrame) -> bool) -> usize {
    frames.windows(2).filter(|w| !f(&w[0]) && f(&w[1])).count()
}

#[test]
fn booting_shows_blue_and_fast_green_blinks() {
    let t = trace(BoardStatus::Booting);
    assert_eq!(share(&t, |f| f.blue_l), 1.0);
    assert!(t.iter().all(|f| f.green_l == f.green_r && !f.red_l && !f.red_r));
    // 4 Hz: 8 rising edges in 2 s (the trace starts lit).
    assert_eq!(rising_edges(&t, |f| f.green_l), 7);
    assert!((share(&t, |f| f.green_l) - 0.5).abs() < 0.02);
}

#[test]
fn ready_is_steady_green_with_a_short_heartbeat() {
    let t = trace(BoardStatus::Ready);
    assert!(
        t.iter()
            .all(|f| !f.blue_l && !f.red_l && !f.red_r && f.green_l == f.green_r)
    );
    assert!((share(&t, |f| f.green_l) - 0.9).abs() < 0.02);
    assert_eq!(rising_edges(&t, |f| f.green_l), 2, "one dark gap per second");
}

#[test]
fn mission_running_alternates_the_greens() {
    let t = trace(BoardStatus::MissionRunning);
    assert!(
        t.iter()
            .all(|f| f.green_l != f.green_r && !f.red_l && !f.red_r && !f.blue_l)
    );
    assert!((share(&t, |f| f.green_l) - 0.5).abs() < 0.02);
}

#[test]
fn low_battery_double_flashes_the_right_red() {
    let t = trace(BoardStatus::LowBattery);
    assert!(t.iter().all(|f| !f.green_l && !f.green_r && !f.blue_l && !f.red_l));
    // Two flashes per second: edges at 0 (trace start), 200, 1000, 1200 ms → 3 rising edges after the start.
    assert_eq!(rising_edges(&t, |f| f.red_r), 3);
    assert!((share(&t, |f| f.red_r) - 0.2).abs() < 0.02);
}

#[test]
fn fault_blinks_both_reds_and_nothing_else() {
    let t = trace(BoardStatus::Fault);
    assert!(
        t.iter()
            .all(|f| !f.green_l && !f.green_r && !f.blue_l && f.red_l == f.red_r)
    );
    assert!((share(&t, |f| f.red_l) - 0.5).abs() < 0.02);
    assert_eq!(rising_edges(&t, |f| f.red_l), 3, "2 Hz");
}

#[test]
fn every_status_has_its_own_pattern() {
    for (i, a) in ALL.iter().enumerate() {
        for b in &ALL[i + 1..] {
            assert_ne!(trace(*a), trace(*b), "{a:?} and {b:?} look the same");
        }
    }
}

#[test]
fn precedence_fault_low_battery_booting_mission_ready() {
    let s = |booted, fault, battery_low, mission_running| {
        BoardStatus::resolve(StatusInputs {
            booted,
            fault,
            battery_low,
            mission_running,
        })
    };
    assert_eq!(s(true, true, true, true), BoardStatus::Fault);
    assert_eq!(s(false, true, false, false), BoardStatus::Fault);
    assert_eq!(s(true, false, true, true), BoardStatus::LowBattery);
    assert_eq!(s(false, false, false, true), BoardStatus::Booting);
    assert_eq!(s(true, false, false, true), BoardStatus::MissionRunning);
    assert_eq!(s(true, false, false, false), BoardStatus::Ready);
}
