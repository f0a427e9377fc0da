//! The checks CI applies to an emulator run (`cfnav-pil ... --check NAME`): each one a verdict over the
//! run's own [`Report`] in memory, so a renamed or retyped report field fails to compile instead of being
//! read as missing. One check per CI scenario (docs/pil.md describes the scenarios); [`NAMES`] lists them.
//!
//! A check returns the line CI prints when it passes, or the first assertion that failed with the values it
//! saw. Wall-clock figures are printed, never judged. `passed` is the run's own verdict (the exit status it
//! would have without `--check`); the checks of the scenarios whose run must also pass on its own require it.
//!
//! Non-goals: judging flights in general (the run's own `--hover`/`--mission` judges do that); the pair
//! check of two boots ([`same_boot`]) reads the two JSON reports back, as they come from two processes.

use std::path::Path;

use serde::Deserialize;

use crate::Report;
use crate::stuck::Release;

/// The checks `--check` takes.
pub const NAMES: [&str; 13] = [
    "boot",
    "nack",
    "dead",
    "stuck",
    "stuck-never",
    "rts",
    "tx-dead",
    "client",
    "hover",
    "flow-lost",
    "imu-lost",
    "mr-lost",
    "no-multiranger",
];

/// `Err(message)` unless `cond`.
fn ensure(cond: bool, message: impl FnOnce() -> String) -> Result<(), String> {
    if cond { Ok(()) } else { Err(message()) }
}

fn texts(r: &Report) -> Vec<&str> {
    r.log.iter().map(|l| l.text.as_str()).collect()
}

fn any_line(r: &Report, needle: &str) -> bool {
    r.log.iter().any(|l| l.text.contains(needle))
}

fn no_panic_or_hardfault(r: &Report) -> Result<(), String> {
    ensure(!any_line(r, "panicked") && !any_line(r, "HardFault"), || {
        format!("the image panicked or took a HardFault: {:?}", texts(r))
    })
}

fn one_boot_no_watchdog(r: &Report) -> Result<(), String> {
    ensure(!r.iwdg_reset_flag && r.boots_logged == 1, || {
        format!(
            "a watchdog reset or a second boot: iwdg_reset_flag {}, boots_logged {}",
            r.iwdg_reset_flag, r.boots_logged
        )
    })
}

fn ready_without_faults(r: &Report) -> Result<(), String> {
    ensure(
        r.ready && r.final_status == Some("ready") && r.faults_logged.is_empty(),
        || {
            format!(
                "not ready without faults: ready {}, final status {:?}, timeline {:?}, faults {:?}",
                r.ready, r.final_status, r.status_timeline, r.faults_logged
            )
        },
    )
}

fn motors_off(r: &Report) -> Result<(), String> {
    ensure(r.motor_ccr == [0, 0, 0, 0], || {
        format!("motors still driven at the end: CCR {:?}", r.motor_ccr)
    })
}

fn run_passed(passed: bool) -> Result<(), String> {
    ensure(passed, || {
        "the run's own verdict failed (it exits 1 without --check)".into()
    })
}

/// Applies check `name` to the run `r` (`passed`: the run's own verdict). `Ok(line to print)` or
/// `Err(the failed assertion)`; an unknown name is an error.
pub fn check(name: &str, r: &Report, passed: bool) -> Result<String, String> {
    match name {
        "boot" => boot(r, passed),
        "nack" => nack(r, passed),
        "dead" => dead(r, passed),
        "stuck" => stuck(r, passed),
        "stuck-never" => stuck_never(r, passed),
        "rts" => rts(r, passed),
        "tx-dead" => tx_dead(r, passed),
        "client" => client(r, passed),
        "hover" => hover(r, passed),
        "flow-lost" => flow_lost(r),
        "imu-lost" => imu_lost(r),
        "mr-lost" => mr_lost(r),
        "no-multiranger" => no_multiranger(r),
        _ => Err(format!("no check named {name:?} (checks: {})", NAMES.join(", "))),
    }
}

/// The image boots to ready: no fault, the boot syslink packets sent (RADIO_READY, 0x0b, after the radio
/// settings), both decks detected.
fn boot(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    ensure(r.ready && r.final_status == Some("ready"), || {
        format!("not ready: {:?}", r.status_timeline)
    })?;
    ensure(r.log_errors == 0 && r.faults_logged.is_empty(), || {
        format!("log errors {} or faults {:?}", r.log_errors, r.faults_logged)
    })?;
    let sent = &r.syslink_packets_from_image;
    let at = |t: &str| sent.iter().position(|s| s == t);
    ensure(
        ["0x01", "0x02", "0x05", "0x14", "0x0b"].iter().all(|t| at(t).is_some()),
        || format!("boot syslink packets missing: {sent:?}"),
    )?;
    ensure(at("0x0b") > at("0x05"), || {
        format!("RADIO_READY before the radio settings: {sent:?}")
    })?;
    ensure(r.deck_multiranger == Some(true) && r.deck_flow2 == Some(true), || {
        format!(
            "decks not detected: multiranger {:?}, flow2 {:?}",
            r.deck_multiranger, r.deck_flow2
        )
    })?;
    Ok(format!(
        "ready at {:?} ms virtual ({:.1} s wall), acr_caches_on={}, fingerprint {}",
        r.ready_at_ms, r.wall_s, r.acr_caches_on, r.fingerprint
    ))
}

/// The NACKed BMI088 soft reset: still ready, no fault.
fn nack(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    ensure(r.imu_bus.soft_resets > 0 && r.imu_bus.nacked_bytes > 0, || {
        format!("no NACKed soft reset seen: {:?}", r.imu_bus)
    })?;
    ready_without_faults(r)?;
    Ok(format!(
        "NACKed BMI088 reset: ready at {:?} ms virtual, no fault",
        r.ready_at_ms
    ))
}

/// A dead sensor bus: the IMU fault, the fault LEDs, no watchdog reset, the radio up.
fn dead(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    ensure(r.final_status == Some("fault") && r.expected_at_ms.is_some(), || {
        format!("no fault LEDs: {:?}", r.status_timeline)
    })?;
    one_boot_no_watchdog(r)?;
    ensure(r.faults_logged.iter().any(|f| f.contains("IMU init failed")), || {
        format!("no IMU fault logged: {:?}", r.faults_logged)
    })?;
    ensure(!any_line(r, "watchdog:"), || format!("a watchdog line: {:?}", texts(r)))?;
    ensure(r.syslink_packets_from_image.iter().any(|s| s == "0x0b"), || {
        format!("RADIO_READY not sent: {:?}", r.syslink_packets_from_image)
    })?;
    Ok(format!(
        "dead sensor bus: fault LEDs from {:?} ms virtual, no watchdog reset, radio up",
        r.expected_at_ms
    ))
}

/// Both buses held low from power-on and released after 9 clocks: recovered, logged, ready with both decks.
fn stuck(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    for (bus, s) in [("sensor_bus_sda", &r.sensor_bus_sda), ("deck_bus_sda", &r.deck_bus_sda)] {
        ensure(
            s.release == Some(Release::AfterClocks(9)) && !s.holding && s.clocks_seen == 9,
            || format!("{bus} not recovered by 9 clocks: {s:?}"),
        )?;
    }
    ready_without_faults(r)?;
    ensure(r.deck_multiranger == Some(true) && r.deck_flow2 == Some(true), || {
        format!(
            "decks not detected: multiranger {:?}, flow2 {:?}",
            r.deck_multiranger, r.deck_flow2
        )
    })?;
    ensure(r.imu_bus.soft_resets > 0, || {
        format!("no IMU soft reset: {:?}", r.imu_bus)
    })?;
    one_boot_no_watchdog(r)?;
    for name in ["I2C3 (IMU)", "I2C1 (deck)"] {
        let line = format!("{name}: bus recovery 1: 9 SCL clocks, SDA released");
        ensure(any_line(r, &line), || format!("no line {line:?}: {:?}", texts(r)))?;
    }
    Ok(format!(
        "stuck buses recovered: I2C3 released at {:?} ms, I2C1 at {:?} ms virtual, ready at {:?} ms ({:.1} s wall)",
        r.sensor_bus_sda.released_at_ms, r.deck_bus_sda.released_at_ms, r.ready_at_ms, r.wall_s
    ))
}

/// Both buses held low for ever: the IMU fault, fault LEDs, motors off, no watchdog reset, the radio up.
fn stuck_never(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    ensure(r.sensor_bus_sda.holding && r.deck_bus_sda.holding, || {
        format!("a bus was released: {:?}, {:?}", r.sensor_bus_sda, r.deck_bus_sda)
    })?;
    ensure(r.final_status == Some("fault") && r.expected_at_ms.is_some(), || {
        format!("no fault LEDs: {:?}", r.status_timeline)
    })?;
    ensure(r.faults_logged.iter().any(|f| f.contains("IMU init failed")), || {
        format!("no IMU fault logged: {:?}", r.faults_logged)
    })?;
    motors_off(r)?;
    one_boot_no_watchdog(r)?;
    ensure(!any_line(r, "watchdog:"), || format!("a watchdog line: {:?}", texts(r)))?;
    ensure(r.syslink_packets_from_image.iter().any(|s| s == "0x0b"), || {
        format!("RADIO_READY not sent: {:?}", r.syslink_packets_from_image)
    })?;
    ensure(r.deck_multiranger == Some(false), || {
        format!("the Multi-ranger seen on a dead deck bus: {:?}", r.deck_multiranger)
    })?;
    Ok(format!(
        "stuck buses never released: fault LEDs from {:?} ms virtual, motors off, no watchdog reset, radio up ({:.1} s wall)",
        r.expected_at_ms, r.wall_s
    ))
}

/// The nRF51 holds RTS high: nothing sent, frames dropped on their deadline (logged), still ready.
fn rts(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    ensure(r.gpioa_idr & (1 << 4) != 0, || {
        format!("PA4 low: GPIOA IDR {:#x}", r.gpioa_idr)
    })?;
    ensure(r.syslink_packets_from_image.is_empty(), || {
        format!("packets sent against RTS: {:?}", r.syslink_packets_from_image)
    })?;
    ensure(any_line(r, "RADIO_READY not sent: FlowControl"), || {
        format!("no flow-control drop logged: {:?}", texts(r))
    })?;
    ready_without_faults(r)?;
    one_boot_no_watchdog(r)?;
    Ok(format!(
        "RTS held high: nothing sent, frames dropped on the deadline, ready at {:?} ms virtual ({:.1} s wall)",
        r.ready_at_ms, r.wall_s
    ))
}

/// USART6's transmit DMA never moves a byte: every frame given up on its deadline (logged), still ready.
fn tx_dead(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    ensure(r.syslink_packets_from_image.is_empty(), || {
        format!("packets sent by a dead DMA: {:?}", r.syslink_packets_from_image)
    })?;
    for line in [
        "PM_BATTERY_AUTOUPDATE not sent: Stalled",
        "RADIO_READY not sent: Stalled",
    ] {
        ensure(any_line(r, line), || format!("no line {line:?}: {:?}", texts(r)))?;
    }
    ready_without_faults(r)?;
    one_boot_no_watchdog(r)?;
    Ok(format!(
        "syslink TX DMA dead: every frame given up on its deadline, RADIO_READY tried, ready at {:?} ms virtual ({:.1} s wall)",
        r.ready_at_ms, r.wall_s
    ))
}

/// cflib's connect sequence from the scripted host: every request answered (5 + log TOC + 2 × param TOC),
/// no syslink frame dropped, both decks.
fn client(r: &Report, passed: bool) -> Result<String, String> {
    run_passed(passed)?;
    let c = r.client.as_ref().ok_or("no client figures in the report")?;
    ensure(c.done && c.answered == c.sent, || format!("requests unanswered: {c:?}"))?;
    let (Some(log_toc), Some(param_toc)) = (c.log_toc.filter(|&n| n > 0), c.param_toc.filter(|&n| n > 0)) else {
        return Err(format!("a TOC is missing or empty: {c:?}"));
    };
    ensure(c.sent == 5 + u64::from(log_toc) + 2 * u64::from(param_toc), || {
        format!("not 5 + log TOC + 2 × param TOC requests: {c:?}")
    })?;
    ensure(!r.iwdg_reset_flag, || "a watchdog reset".into())?;
    no_panic_or_hardfault(r)?;
    ensure(!any_line(r, "syslink frame dropped"), || {
        format!("a syslink frame dropped: {:?}", texts(r))
    })?;
    ensure(r.deck_multiranger == Some(true) && r.deck_flow2 == Some(true), || {
        format!(
            "decks not detected: multiranger {:?}, flow2 {:?}",
            r.deck_multiranger, r.deck_flow2
        )
    })?;
    Ok(format!(
        "scripted cflib connect: {} requests answered by {:?} ms virtual (log TOC {log_toc}, param TOC {param_toc}), {:.0} s wall",
        c.answered, c.last_answer_ms, r.wall_s
    ))
}

/// The hover: takes off, holds 10 s within 10 cm horizontally and 8 cm in height at a 1 kHz loop, then
/// lands on its take-off pad within 10 cm, mission completed (state 100).
fn hover(r: &Report, passed: bool) -> Result<String, String> {
    let h = r.hover.as_ref().ok_or("no hover figures in the report")?;
    ensure(h.took_off && h.hold_start_s.is_some(), || {
        format!("no take-off or hold: {h:?}")
    })?;
    ensure((h.held_s - 10.0).abs() <= 0.1, || {
        format!("held {} s, not 10 s: {h:?}", h.held_s)
    })?;
    ensure(h.hold_dev_xy_m < 0.10 && h.hold_dev_z_m < 0.08, || {
        format!("hold deviation: {h:?}")
    })?;
    let l = r.load.ok_or("no load line from the image")?;
    ensure((950..=1050).contains(&l.loop_rate_hz), || {
        format!("control loop not at 1 kHz: {l:?}")
    })?;
    ensure(
        !r.iwdg_reset_flag && r.boots_logged == 1 && r.faults_logged.is_empty(),
        || format!("boots {}, faults {:?}", r.boots_logged, r.faults_logged),
    )?;
    no_panic_or_hardfault(r)?;
    ensure(!any_line(r, "flow read timed out"), || {
        format!("a flow read timed out: {:?}", texts(r))
    })?;
    let offset = h.landing_offset_m.unwrap_or(f32::INFINITY);
    ensure(h.landed && offset < 0.10 && h.mission_end_state == Some(100), || {
        format!("not landed within 10 cm with the mission completed: {h:?}")
    })?;
    ensure(h.passed, || format!("the hover judge failed: {h:?}"))?;
    run_passed(passed)?;
    Ok(format!(
        "hover: held {:.2} s, worst xy {:.1} cm, z {:.1} cm; landed {:.1} cm from take-off at {:?} s, state {:?}; \
         control {} Hz, jitter {} us, load {} %, {:.1} s virtual in {:.0} s wall",
        h.held_s,
        h.hold_dev_xy_m * 100.0,
        h.hold_dev_z_m * 100.0,
        offset * 100.0,
        h.landed_at_s,
        h.mission_end_state,
        l.loop_rate_hz,
        l.loop_jitter_us,
        l.cpu_load_pct,
        r.virtual_s,
        r.wall_s
    ))
}

/// The take-off of the fault scenarios: airborne at 0.4 m or more before the fault.
fn took_off(h: &crate::hover::HoverReport) -> Result<(), String> {
    ensure(h.took_off && h.max_height_m >= 0.40, || {
        format!("did not take off to 0.4 m: {h:?}")
    })
}

/// The Flow deck lost at 4.5 s in the hold: blind descent, motors off within 5.6 s, state 204.
fn flow_lost(r: &Report) -> Result<String, String> {
    let h = r.hover.as_ref().ok_or("no hover figures in the report")?;
    ensure(r.flow_deck_lost_at_ms == Some(4500), || {
        format!("the deck was not lost at 4500 ms: {:?}", r.flow_deck_lost_at_ms)
    })?;
    took_off(h)?;
    ensure(h.mission_end_state == Some(204), || format!("end state not 204: {h:?}"))?;
    let landed_at = h.landed_at_s.unwrap_or(f64::NAN);
    ensure(h.landed && 4.5 < landed_at && landed_at <= 4.5 + 5.6, || {
        format!("motors not off within 5.6 s of the loss: {h:?}")
    })?;
    motors_off(r)?;
    one_boot_no_watchdog(r)?;
    no_panic_or_hardfault(r)?;
    Ok(format!(
        "flow deck lost at 4.5 s: state 204, motors off at {landed_at:.2} s, {:.1} s virtual in {:.0} s wall",
        r.virtual_s, r.wall_s
    ))
}

/// The BMI088 lost at 4.5 s in the hold: motors off within 10 ms, state 205, fault latched, one boot.
fn imu_lost(r: &Report) -> Result<String, String> {
    let h = r.hover.as_ref().ok_or("no hover figures in the report")?;
    ensure(r.imu_lost_at_ms == Some(4500), || {
        format!("the IMU was not lost at 4500 ms: {:?}", r.imu_lost_at_ms)
    })?;
    took_off(h)?;
    let stopped = r.motors_stopped_at_ms;
    ensure(stopped.is_some_and(|t| (4500..=4500 + 10).contains(&t)), || {
        format!("motors not stopped within 10 ms of the loss: {stopped:?}")
    })?;
    motors_off(r)?;
    ensure(h.mission_end_state == Some(205), || format!("end state not 205: {h:?}"))?;
    ensure(r.final_status == Some("fault"), || {
        format!("no fault LEDs: {:?}", r.status_timeline)
    })?;
    one_boot_no_watchdog(r)?;
    ensure(any_line(r, "fault: IMU: no data-ready edge or read failures"), || {
        format!("no IMU fault line: {:?}", texts(r))
    })?;
    ensure(
        !any_line(r, "watchdog") && !any_line(r, "panicked") && !any_line(r, "HardFault"),
        || format!("a watchdog, panic or HardFault line: {:?}", texts(r)),
    )?;
    Ok(format!(
        "IMU lost at 4.5 s: motors off at {:.3} s, state 205, fault LEDs, one boot, {:.1} s virtual in {:.0} s wall",
        stopped.unwrap_or(0) as f64 / 1e3,
        r.virtual_s,
        r.wall_s
    ))
}

/// The Multi-ranger lost at 4.5 s in the hold: lands where it is (its pad, within 10 cm) after 1 s without
/// a sweep, state 209.
fn mr_lost(r: &Report) -> Result<String, String> {
    let h = r.hover.as_ref().ok_or("no hover figures in the report")?;
    ensure(r.multiranger_lost_at_ms == Some(4500), || {
        format!(
            "the Multi-ranger was not lost at 4500 ms: {:?}",
            r.multiranger_lost_at_ms
        )
    })?;
    took_off(h)?;
    ensure(h.mission_end_state == Some(209), || format!("end state not 209: {h:?}"))?;
    let landed_at = h.landed_at_s.unwrap_or(f64::NAN);
    let offset = h.landing_offset_m.unwrap_or(f32::INFINITY);
    ensure(
        h.landed && 5.5 < landed_at && landed_at <= 4.5 + 6.0 && offset < 0.10,
        || format!("not landed in place 1 to 6 s after the loss: {h:?}"),
    )?;
    motors_off(r)?;
    one_boot_no_watchdog(r)?;
    ensure(any_line(r, "deck ranger read errors"), || {
        format!("no ranger read errors logged: {:?}", texts(r))
    })?;
    no_panic_or_hardfault(r)?;
    Ok(format!(
        "Multi-ranger lost at 4.5 s: state 209, landed {:.1} cm from take-off at {landed_at:.2} s, {:.1} s virtual in {:.0} s wall",
        offset * 100.0,
        r.virtual_s,
        r.wall_s
    ))
}

/// The Multi-ranger not fitted: boots, names the missing sensor, refuses the start: the motors never turn.
fn no_multiranger(r: &Report) -> Result<String, String> {
    let h = r.hover.as_ref().ok_or("no hover figures in the report")?;
    ensure(r.deck_multiranger == Some(false) && r.deck_flow2 == Some(true), || {
        format!("decks: multiranger {:?}, flow2 {:?}", r.deck_multiranger, r.deck_flow2)
    })?;
    ensure(!h.took_off && h.max_height_m < 0.01, || {
        format!("took off without the Multi-ranger: {h:?}")
    })?;
    motors_off(r)?;
    ensure(
        !r.iwdg_reset_flag && r.boots_logged == 1 && r.faults_logged.is_empty(),
        || format!("boots {}, faults {:?}", r.boots_logged, r.faults_logged),
    )?;
    ensure(
        any_line(r, "a deck sensor is missing: the mission will refuse to start"),
        || format!("the missing deck is not named: {:?}", texts(r)),
    )?;
    no_panic_or_hardfault(r)?;
    Ok(format!(
        "Multi-ranger missing: stayed on the ground, motors off, {:.1} s virtual in {:.0} s wall",
        r.virtual_s, r.wall_s
    ))
}

/// What two boots of the same image must share: [`Report`]'s `fingerprint` and `ready_at_ms`.
#[derive(Debug, Deserialize, PartialEq)]
struct BootIdentity {
    fingerprint: String,
    ready_at_ms: Option<u64>,
}

fn identity(path: &Path) -> Result<BootIdentity, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// `--same-boot FIRST SECOND`: the two reports have the same fingerprint and ready time.
pub fn same_boot(first: &Path, second: &Path) -> Result<String, String> {
    let (a, b) = (identity(first)?, identity(second)?);
    ensure(a == b, || format!("two boots differ: {a:?} vs {b:?}"))?;
    Ok(format!(
        "fingerprint {} and ready at {:?} ms, twice",
        a.fingerprint, a.ready_at_ms
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_boot_compares_fingerprint_and_ready_time() {
        let dir = std::env::temp_dir().join(format!("cfnav-pil-verdict-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let write = |name: &str, fp: &str, ready: u64| {
            let p = dir.join(name);
            let text = format!(r#"{{"fingerprint": "{fp}", "ready_at_ms": {ready}, "other": 1}}"#);
            std::fs::write(&p, text).unwrap();
            p
        };
        let a = write("a.json", "abc", 1200);
        let b = write("b.json", "abc", 1200);
        let c = write("c.json", "abd", 1200);
        let d = write("d.json", "abc", 1300);
        assert!(same_boot(&a, &b).is_ok());
        assert!(same_boot(&a, &c).is_err());
        assert!(same_boot(&a, &d).is_err());
        let missing = dir.join("e.json");
        std::fs::write(&missing, r#"{"ready_at_ms": 1200}"#).unwrap();
        assert!(
            same_boot(&a, &missing).is_err(),
            "a report without its fingerprint must fail"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
