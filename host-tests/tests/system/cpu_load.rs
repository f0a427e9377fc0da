//! CPU-load accounting with preemption excluded, and the control loop's period spread (jitter) and longest
//! step, on hand-made cycle-counter timelines (including a counter wrap).

use cfnav::system::cpu_load::{Level, LoadMeter, LoopTiming, cycles_to_us_u16, percent};

#[test]
fn a_preempting_section_is_not_counted_twice() {
    let m = LoadMeter::new();
    // Thread-mode mission work 0..1000, preempted by I/O 100..400, itself preempted by control 150..250.
    let mission = m.begin(Level::Mission, 0);
    let io = m.begin(Level::Io, 100);
    let ctrl = m.begin(Level::Control, 150);
    assert_eq!(m.end(ctrl, 250), 100);
    assert_eq!(m.end(io, 400), 200);
    // A second control step inside the mission section, after the I/O one.
    let ctrl = m.begin(Level::Control, 600);
    assert_eq!(m.end(ctrl, 650), 50);
    assert_eq!(m.end(mission, 1000), 1000 - 300 - 50);
    let busy = m.take();
    assert_eq!(busy, [150, 200, 650]);
    // The sum is the wall time the CPU was busy.
    assert_eq!(busy.iter().sum::<u32>(), 1000);
    // `take` restarts the count.
    assert_eq!(m.take(), [0, 0, 0]);
}

#[test]
fn sections_across_a_counter_wrap() {
    let m = LoadMeter::new();
    let start = u32::MAX - 99;
    let s = m.begin(Level::Control, start);
    assert_eq!(m.end(s, 100), 200);
    assert_eq!(m.take()[0], 200);
}

#[test]
fn nonsense_readings_count_nothing() {
    let m = LoadMeter::new();
    let outer = m.begin(Level::Mission, 1000);
    let inner = m.begin(Level::Control, 1000);
    assert_eq!(m.end(inner, 1500), 500);
    // The outer section claims to end before the preemption it saw finished.
    assert_eq!(m.end(outer, 1200), 0);
    assert_eq!(m.take(), [500, 0, 0]);
}

#[test]
fn percent_and_microseconds() {
    assert_eq!(percent(0, 168_000_000), 0);
    assert_eq!(percent(84_000_000, 168_000_000), 50);
    assert_eq!(percent(168_000_000, 168_000_000), 100);
    assert_eq!(percent(200, 100), 100, "capped");
    assert_eq!(percent(5, 0), 0, "empty window");
    assert_eq!(percent(1_679_999, 168_000_000), 0, "rounded down");
    // 168 cycles = 1 µs at 168 MHz.
    assert_eq!(cycles_to_us_u16(168, 168_000_000), 1);
    assert_eq!(cycles_to_us_u16(168_000, 168_000_000), 1000);
    assert_eq!(cycles_to_us_u16(u32::MAX, 168_000_000), u16::MAX, "saturates");
    assert_eq!(cycles_to_us_u16(1, 0), u16::MAX);
}

#[test]
fn loop_jitter_is_the_spread_of_the_period() {
    let mut t = LoopTiming::new();
    // Steps start at 0, 1000, 2010, 2990, 4000 (intervals 1000, 1010, 980, 1010) and last 50..120 cycles.
    for (start, len) in [(0u32, 50u32), (1000, 60), (2010, 120), (2990, 55), (4000, 70)] {
        t.record(start, start + len);
    }
    let w = t.take();
    assert_eq!(w.steps, 5);
    assert_eq!(w.min_interval, 980);
    assert_eq!(w.max_interval, 1010);
    assert_eq!(w.jitter(), 30);
    assert_eq!(w.max_step, 120);
    // The next window's first interval counts from the last start of the previous one.
    t.record(5000, 5040);
    let w = t.take();
    assert_eq!(
        (w.steps, w.min_interval, w.max_interval, w.max_step),
        (1, 1000, 1000, 40)
    );
    assert_eq!(w.jitter(), 0);
}

#[test]
fn a_single_step_has_no_interval() {
    let mut t = LoopTiming::new();
    t.record(10, 30);
    let w = t.take();
    assert_eq!((w.steps, w.min_interval, w.max_interval, w.max_step), (1, 0, 0, 20));
}

#[test]
fn loop_timing_across_a_counter_wrap() {
    let mut t = LoopTiming::new();
    let a = u32::MAX - 499;
    t.record(a, a.wrapping_add(100));
    t.record(a.wrapping_add(1000), a.wrapping_add(1100));
    let w = t.take();
    assert_eq!((w.min_interval, w.max_interval, w.max_step), (1000, 1000, 100));
}
