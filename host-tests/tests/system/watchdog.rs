//! The IWDG's real timeout over the datasheet's LSI range (17–47 kHz), against RM0090's timeout table and
//! embassy-stm32's arithmetic, and the feed rule: a long planner slice is tolerated, a stuck thread mode or
//! control loop is not.

use cfnav::system::watchdog::{
    CONTROL_STALL_US, FEED_PERIOD_US, FeedGate, FeedInputs, IwdgSetting, LSI_MAX_HZ, LSI_MIN_HZ, LSI_TYP_HZ,
    MIN_TIMEOUT_US, NOMINAL_TIMEOUT_US, Starved, THREAD_STALL_US,
};

#[test]
fn embassy_settings_match_rm0090s_timeout_table() {
    // RM0090 table 107 (LSI 32 kHz): prescaler /4 gives 0.125 ms at RL 0 and 512 ms at RL 0xFFF; /256 gives
    // 8 ms and 32 768 ms.
    let s = IwdgSetting::embassy(512_000).unwrap();
    assert_eq!((s.prescaler, s.reload), (4, 0xFFF));
    assert_eq!(s.timeout_us(LSI_TYP_HZ), 512_000);
    let s = IwdgSetting::embassy(32_768_000).unwrap();
    assert_eq!((s.prescaler, s.reload), (256, 0xFFF));
    assert_eq!(
        IwdgSetting {
            prescaler: 4,
            reload: 0
        }
        .timeout_us(LSI_TYP_HZ),
        125
    );
    assert_eq!(
        IwdgSetting {
            prescaler: 256,
            reload: 0
        }
        .timeout_us(LSI_TYP_HZ),
        8_000
    );
    // Just above 512 ms the next prescaler is needed.
    assert_eq!(IwdgSetting::embassy(512_001).unwrap().prescaler, 8);
    // Where embassy would panic (too long, or rounds to no count at all) there is no setting.
    assert_eq!(IwdgSetting::embassy(32_768_001), None);
    assert_eq!(IwdgSetting::embassy(100), None);
}

#[test]
fn the_real_timeout_scales_with_the_lsi() {
    let s = IwdgSetting::embassy(NOMINAL_TIMEOUT_US).unwrap();
    let nominal = s.timeout_us(LSI_TYP_HZ);
    assert!(nominal.abs_diff(NOMINAL_TIMEOUT_US) <= 125, "{nominal}");
    // Independent oracle: timeout ∝ 1 / f_LSI.
    let fast = f64::from(nominal) * f64::from(LSI_TYP_HZ) / f64::from(LSI_MAX_HZ);
    let slow = f64::from(nominal) * f64::from(LSI_TYP_HZ) / f64::from(LSI_MIN_HZ);
    assert!((f64::from(s.worst_case_timeout_us()) - fast).abs() <= 1.0);
    assert!((f64::from(s.longest_timeout_us()) - slow).abs() <= 1.0);
    assert_eq!(s.timeout_us(0), u32::MAX);
}

#[test]
fn the_shortest_real_timeout_covers_the_feeder() {
    let s = IwdgSetting::embassy(NOMINAL_TIMEOUT_US).unwrap();
    assert!(
        s.worst_case_timeout_us() >= MIN_TIMEOUT_US,
        "{}",
        s.worst_case_timeout_us()
    );
    assert!(s.worst_case_timeout_us() >= 4 * FEED_PERIOD_US);
    // Like stock (100–353 ms): a hung MCU is reset within 0.4 s at the slowest LSI.
    assert!(s.longest_timeout_us() <= 400_000, "{}", s.longest_timeout_us());
    // The old nominal 250 ms (fed from thread mode every 50 ms) is 170 ms at 47 kHz: a thread-mode planner
    // slice of 121 ms or more between two feeds reset the MCU.
    let old = IwdgSetting::embassy(250_000).unwrap();
    assert_eq!(old.worst_case_timeout_us(), 170_212);
}

fn inputs(now_us: u64, thread_beats: u32, control_passes: u32) -> FeedInputs {
    FeedInputs {
        now_us,
        booted: true,
        control_running: true,
        control_passes,
        thread_beats,
    }
}

#[test]
fn before_boot_it_always_feeds() {
    let mut g = FeedGate::new();
    for k in 0..100u64 {
        let mut i = inputs(k * 1_000_000, 0, 0);
        i.booted = false;
        assert_eq!(g.decide(i), Ok(()));
    }
    // Booting counts as progress: the counters have their full allowance from then on.
    let t0 = 100_000_000;
    assert_eq!(g.decide(inputs(t0, 0, 0)), Ok(()));
    assert_eq!(g.decide(inputs(t0 + u64::from(CONTROL_STALL_US), 0, 1)), Ok(()));
}

/// Feeds the gate every [`FEED_PERIOD_US`] for `duration_us` with thread mode busy for `slice_us` (no
/// heartbeat) once, then beating every 20 ms; the control loop steps every millisecond. Returns the longest
/// gap between feeds.
fn longest_gap(slice_us: u64, control_dies_at_us: Option<u64>) -> (u64, Option<Starved>) {
    let mut g = FeedGate::new();
    let (mut beats, mut last_feed, mut gap, mut why) = (0u32, 0u64, 0u64, None);
    let slice_start = 100_000;
    let mut t = 0;
    while t < 2_000_000 {
        if !(slice_start..slice_start + slice_us).contains(&t) && t % 20_000 == 0 {
            beats = beats.wrapping_add(1);
        }
        let steps = (control_dies_at_us.map_or(t, |d| t.min(d)) / 1000) as u32;
        match g.decide(inputs(t, beats, steps)) {
            Ok(()) => {
                gap = gap.max(t - last_feed);
                last_feed = t;
            }
            Err(e) => why = why.or(Some(e)),
        }
        t += u64::from(FEED_PERIOD_US);
    }
    gap = gap.max(t - last_feed);
    (gap, why)
}

#[test]
fn a_long_planner_slice_is_tolerated() {
    let s = IwdgSetting::embassy(NOMINAL_TIMEOUT_US).unwrap();
    // 155 ms: 6.5 M instructions at CPI 3 with a quarter of the core taken by interrupts (BENCHMARKS §6);
    // and anything up to the stall limit.
    for slice in [155_000, u64::from(THREAD_STALL_US) - u64::from(FEED_PERIOD_US)] {
        let (gap, why) = longest_gap(slice, None);
        assert_eq!(why, None, "slice {slice} us");
        assert!(gap < u64::from(s.worst_case_timeout_us()), "gap {gap} us");
    }
}

#[test]
fn a_stuck_thread_mode_or_control_loop_starves_the_watchdog() {
    let s = IwdgSetting::embassy(NOMINAL_TIMEOUT_US).unwrap();
    let (gap, why) = longest_gap(10_000_000, None);
    assert_eq!(why, Some(Starved::ThreadMode));
    assert!(gap > u64::from(s.longest_timeout_us()));
    let (gap, why) = longest_gap(0, Some(500_000));
    assert_eq!(why, Some(Starved::Control));
    assert!(gap > u64::from(s.longest_timeout_us()));
}

#[test]
fn stall_limits_are_exact_and_counters_may_wrap() {
    let mut g = FeedGate::new();
    let t0 = 1_000;
    assert_eq!(g.decide(inputs(t0, u32::MAX, u32::MAX)), Ok(()));
    // Control: still fine at exactly the limit, starved just after (thread mode beat meanwhile).
    let limit = u64::from(CONTROL_STALL_US);
    assert_eq!(g.decide(inputs(t0 + limit, u32::MAX, u32::MAX)), Ok(()));
    assert_eq!(g.decide(inputs(t0 + limit + 1, 0, u32::MAX)), Err(Starved::Control));
    // A wrapped counter is progress.
    assert_eq!(g.decide(inputs(t0 + limit + 2, 0, 0)), Ok(()));
    // Without a control loop only thread mode counts; its last beat was at t0 + limit + 1.
    let mut i = inputs(t0 + limit + 1 + u64::from(THREAD_STALL_US), 0, 0);
    i.control_running = false;
    assert_eq!(g.decide(i), Ok(()));
    i.now_us += 1;
    assert_eq!(g.decide(i), Err(Starved::ThreadMode));
}
