//! A hover test without cflib: the scripted CRTP parameter writes the nRF51 model
//! injects at a virtual time ([`Script`]), and the judge of the flight on the simulator's truth
//! ([`HoverJudge`]), plus the image's own load figures from its defmt log ([`LoadLine`]).
//!
//! Script: once the image has sent RADIO_READY and [`SCRIPT_DELAY_NS`] more have passed (the boot's last
//! tasks settle), one CRTP param write (port 2, channel 2: `[id u16 LE, value]`, the ids are the firmware's
//! own `cfnav::radio_binding::param_table` constants) per [`SCRIPT_GAP_NS`]: `mission.mode` = 1 (hover test),
//! `mission.hoverTime`, `mission.height`, then `mission.start` = 1. The nRF keeps polling (null packets,
//! as cflib's radio driver does when idle) so the image's answers leave it.
//!
//! Judge (truth, arena frame, metres), the simulator's hover test's (`host-tests/tests/sim/modes.rs`): took
//! off = the body rose [`TAKEOFF_M`] above where it stood; the hold = the image's own HoverHold phase, from
//! its "mission state 50" log line to the next state line (the image's timestamps); over the hold the truth's
//! worst horizontal distance from the take-off point and worst |z − (take-off z + target height)|; landed =
//! back on a surface with all four duties 0 after having flown. Passed: held the hover time (±0.1 s), worst
//! deviations under [`HOLD_DEV_XY_M`] / [`HOLD_DEV_Z_M`], landed within [`LANDING_OFFSET_M`] of the take-off
//! point, and the image's mission ended completed.

use cfnav::radio::crtp::CrtpPacket;
use cfnav::radio::log::{CH_DATA, CH_SETTINGS, CMD_CREATE_BLOCK_V2, CMD_START_BLOCK_V2, PORT_LOG};
use cfnav::radio::log_decl::log_id;
use cfnav::radio::param::{CH_WRITE, PORT_PARAM};
use cfnav::radio_binding::log_table::{ID_MISSION_STATE, ID_RANGE_ZRANGE, ID_X, ID_Y, ID_Z, LOG_TABLE};
use cfnav::radio_binding::param_table::{
    ID_GOAL_X, ID_GOAL_Y, ID_HEIGHT, ID_HOVER_TIME, ID_MODE, ID_SPEED, ID_START, ID_START_X, ID_START_Y,
};
use cfnav::types::MotorDuty;
use serde::Serialize;

/// After RADIO_READY, before the first scripted write, ns.
pub const SCRIPT_DELAY_NS: u64 = 500_000_000;
/// Between scripted writes, ns.
pub const SCRIPT_GAP_NS: u64 = 50_000_000;
/// How long the nRF keeps polling after the last write, ns.
pub const POLL_AFTER_NS: u64 = 200_000_000;
/// `MissionState::Completed` (`src/mission/mod.rs`).
pub const COMPLETED: u32 = 100;
/// Rise that counts as a take-off, m.
pub const TAKEOFF_M: f32 = 0.10;
/// The hold's bounds on the truth, m: the simulator's hover test's (`HOVER_TRUE_DEV_*` in
/// `host-tests/tests/sim/modes.rs`), so the emulated image is judged as the algorithms are in SITL.
pub const HOLD_DEV_XY_M: f32 = 0.10;
pub const HOLD_DEV_Z_M: f32 = 0.08;
pub const LANDING_OFFSET_M: f32 = 0.10;
/// How far the hold's length may differ from `mission.hoverTime`, s (the mission's 20 ms tick, plus margin).
pub const HOLD_TIME_TOLERANCE_S: f64 = 0.1;
/// `MissionState::HoverHold` (`src/mission/mod.rs`).
pub const HOVER_HOLD: u32 = 50;

/// The trace's log block id (`--trace`).
pub const TRACE_BLOCK: u8 = 1;
/// The trace's log period, ms (two z-ranger readings).
pub const TRACE_PERIOD_MS: u16 = 50;
/// While tracing, the nRF polls once per this many ns (ESB polls carry the log packets down).
pub const TRACE_POLL_NS: u64 = 5_000_000;

/// The scripted writes.
#[derive(Debug)]
pub struct Script {
    packets: Vec<Vec<u8>>,
    next: usize,
    next_at_ns: Option<u64>,
    last_at_ns: u64,
    /// `--trace`: a log block of the image's estimate and downward range, polled for the whole run.
    trace: bool,
    /// When each write went in, virtual ms.
    pub sent_at_ms: Vec<u64>,
}

fn write_packet(id: u16, value: &[u8]) -> Vec<u8> {
    let mut data = id.to_le_bytes().to_vec();
    data.extend_from_slice(value);
    let mut out = [0u8; 32];
    match CrtpPacket::new(PORT_PARAM, CH_WRITE, &data) {
        Ok(p) => {
            let n = p.to_bytes(&mut out);
            out[..n].to_vec()
        }
        Err(_) => Vec::new(),
    }
}

impl Script {
    /// The hover test: hold `hover_s` at `height_m`.
    pub fn hover(hover_s: f32, height_m: f32) -> Self {
        Self {
            packets: vec![
                write_packet(ID_MODE, &[1]),
                write_packet(ID_HOVER_TIME, &hover_s.to_le_bytes()),
                write_packet(ID_HEIGHT, &height_m.to_le_bytes()),
                write_packet(ID_START, &[1]),
            ],
            next: 0,
            next_at_ns: None,
            last_at_ns: 0,
            trace: false,
            sent_at_ms: Vec::new(),
        }
    }

    /// The round trip (`--mission`): `mission.mode` = 0, the world's start, goal, height and
    /// speed (as `cfnav sim` gives them, `mission_params`), then `mission.start` = 1. The arena size has no
    /// parameter: the image's default (6 × 3 m, the default world's) is what it flies.
    pub fn round_trip(world: &cfnav_sim::world::World) -> Self {
        let m = &world.mission;
        let mut s = Self::hover(1.0, m.height);
        let f = |id, v: f32| write_packet(id, &v.to_le_bytes());
        s.packets = vec![
            write_packet(ID_MODE, &[0]),
            f(ID_START_X, m.start[0]),
            f(ID_START_Y, m.start[1]),
            f(ID_GOAL_X, m.goal[0]),
            f(ID_GOAL_Y, m.goal[1]),
            f(ID_HEIGHT, m.height),
            f(ID_SPEED, m.speed),
            write_packet(ID_START, &[1]),
        ];
        s
    }

    /// Adds the trace (`--trace`): after the writes, a log block ([`TRACE_BLOCK`]: `stateEstimate.x/y/z/yaw`
    /// as floats, `range.zrange` u16 mm, `mission.state` u8) started at [`TRACE_PERIOD_MS`], and polls for the
    /// whole run so its packets come down. Decoded by [`TraceSample::parse`].
    pub fn with_trace(mut self) -> Self {
        const F32: u8 = 7;
        const U16: u8 = 2;
        const U8: u8 = 1;
        let yaw = log_id(LOG_TABLE, "stateEstimate", "yaw");
        let mut create = vec![CMD_CREATE_BLOCK_V2, TRACE_BLOCK];
        for (ty, id) in [
            (F32, ID_X),
            (F32, ID_Y),
            (F32, ID_Z),
            (F32, yaw),
            (U16, ID_RANGE_ZRANGE),
            (U8, ID_MISSION_STATE),
        ] {
            create.push(ty);
            create.extend_from_slice(&id.to_le_bytes());
        }
        let mut start = vec![CMD_START_BLOCK_V2, TRACE_BLOCK];
        start.extend_from_slice(&TRACE_PERIOD_MS.to_le_bytes());
        for data in [create, start] {
            let mut out = [0u8; 32];
            if let Ok(p) = CrtpPacket::new(PORT_LOG, CH_SETTINGS, &data) {
                let n = p.to_bytes(&mut out);
                self.packets.push(out[..n].to_vec());
            }
        }
        self.trace = true;
        self
    }

    /// The packets due at `now_ns` (RADIO_READY seen at `radio_ready_ns`).
    pub fn due(&mut self, now_ns: u64, radio_ready_ns: Option<u64>) -> Vec<Vec<u8>> {
        let Some(ready) = radio_ready_ns else {
            return Vec::new();
        };
        let at = *self.next_at_ns.get_or_insert(ready + SCRIPT_DELAY_NS);
        if self.next >= self.packets.len() || now_ns < at {
            return Vec::new();
        }
        let p = self.packets[self.next].clone();
        self.next += 1;
        self.next_at_ns = Some(now_ns + SCRIPT_GAP_NS);
        self.last_at_ns = now_ns;
        self.sent_at_ms.push(now_ns / 1_000_000);
        vec![p]
    }

    /// Whether the nRF should poll for the image's answers now.
    pub fn polling(&self, now_ns: u64) -> bool {
        self.next > 0
            && (now_ns < self.last_at_ns + POLL_AFTER_NS || (self.trace && now_ns % TRACE_POLL_NS < 1_000_000))
    }

    #[cfg(test)]
    pub fn done(&self) -> bool {
        self.next >= self.packets.len()
    }
}

/// One trace packet from the image (`--trace`): what its estimator and mission saw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceSample {
    /// The image's log timestamp, ms.
    pub at_ms: u32,
    pub position_m: [f32; 3],
    /// `stateEstimate.yaw`, degrees.
    pub yaw_deg: f32,
    /// `range.zrange`, mm (the firmware's no-reading value when it has none).
    pub zrange_mm: u16,
    pub mission_state: u8,
}

impl TraceSample {
    /// Decodes a CRTP packet (header byte first) if it is the trace block's data.
    pub fn parse(crtp: &[u8]) -> Option<Self> {
        let (&header, data) = crtp.split_first()?;
        if header >> 4 != PORT_LOG || header & 0x03 != CH_DATA || data.len() < 4 + 19 || data[0] != TRACE_BLOCK {
            return None;
        }
        let at_ms = u32::from_le_bytes([data[1], data[2], data[3], 0]);
        let f = |k: usize| f32::from_le_bytes([data[4 + 4 * k], data[5 + 4 * k], data[6 + 4 * k], data[7 + 4 * k]]);
        Some(Self {
            at_ms,
            position_m: [f(0), f(1), f(2)],
            yaw_deg: f(3),
            zrange_mm: u16::from_le_bytes([data[20], data[21]]),
            mission_state: data[22],
        })
    }
}

/// The flight as the truth saw it.
#[derive(Debug, Clone, Default, Serialize)]
pub struct HoverReport {
    pub target_height_m: f32,
    pub hover_time_s: f32,
    pub took_off: bool,
    pub took_off_at_s: Option<f64>,
    pub max_height_m: f32,
    /// The hold: the image's HoverHold phase (its "mission state 50" line to the next state line); the
    /// search for the pad's edges that follows is not judged.
    pub hold_start_s: Option<f64>,
    pub hold_end_s: Option<f64>,
    pub held_s: f64,
    /// Worst horizontal distance from the take-off point during the hold, m.
    pub hold_dev_xy_m: f32,
    /// Worst |z − target| over the hold, m (target: the take-off point's z + the target height).
    pub hold_dev_z_m: f32,
    /// RMS horizontal deviation over the hold, m.
    pub hold_rms_xy_m: f32,
    pub landed: bool,
    pub landed_at_s: Option<f64>,
    /// Horizontal distance of the landing point from the take-off point, m.
    pub landing_offset_m: Option<f32>,
    /// The mission's end state as the image logged it ("mission ended: state N"; 100 = completed).
    pub mission_end_state: Option<u32>,
    pub passed: bool,
}

/// Judges the hover from truth samples.
#[derive(Debug)]
pub struct HoverJudge {
    start: Option<[f32; 3]>,
    /// (t, x, y, z) while airborne.
    track: Vec<(f64, [f32; 3])>,
    /// The image's HoverHold phase as its log lines timed it, s.
    hold_from_s: Option<f64>,
    hold_until_s: Option<f64>,
    report: HoverReport,
}

/// The defmt timestamp a decoded line starts with ("3.300123 INFO ..."), s.
fn line_time_s(text: &str) -> Option<f64> {
    text.split_whitespace().next()?.parse().ok()
}

/// The number after `key` in `text`.
fn number_after(text: &str, key: &str) -> Option<u32> {
    let rest = &text[text.find(key)? + key.len()..];
    rest.split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
}

impl HoverJudge {
    pub fn new(target_height_m: f32, hover_time_s: f32) -> Self {
        Self {
            start: None,
            track: Vec::new(),
            hold_from_s: None,
            hold_until_s: None,
            report: HoverReport {
                target_height_m,
                hover_time_s,
                ..HoverReport::default()
            },
        }
    }

    /// One truth sample.
    pub fn sample(&mut self, t_s: f64, pos: [f32; 3], on_ground: bool, duty: MotorDuty) {
        let start = *self.start.get_or_insert(pos);
        let r = &mut self.report;
        if !r.took_off && pos[2] > start[2] + TAKEOFF_M {
            r.took_off = true;
            r.took_off_at_s = Some(t_s);
        }
        if r.took_off && !r.landed {
            self.track.push((t_s, pos));
            r.max_height_m = r.max_height_m.max(pos[2] - start[2]);
            if on_ground && duty.0 == [0; 4] && pos[2] < start[2] + TAKEOFF_M {
                r.landed = true;
                r.landed_at_s = Some(t_s);
                r.landing_offset_m = Some(((pos[0] - start[0]).powi(2) + (pos[1] - start[1]).powi(2)).sqrt());
            }
        }
    }

    /// A defmt line of the image, read at `read_at_s` (virtual): the mission's state changes (the hold's
    /// window, at the line's own timestamp when it has one) and its end state.
    pub fn log_line(&mut self, read_at_s: f64, text: &str) {
        let at_s = line_time_s(text).unwrap_or(read_at_s);
        let ended = number_after(text, "mission ended: state ");
        if ended.is_some() {
            self.report.mission_end_state = ended;
        }
        let state = number_after(text, "mission state ").or(ended);
        match state {
            Some(HOVER_HOLD) if self.hold_from_s.is_none() => self.hold_from_s = Some(at_s),
            Some(s) if s != HOVER_HOLD && self.hold_from_s.is_some() && self.hold_until_s.is_none() => {
                self.hold_until_s = Some(at_s);
            }
            _ => {}
        }
    }

    /// Whether the drone has landed after flying.
    pub fn landed(&self) -> bool {
        self.report.landed
    }

    /// The verdict.
    pub fn finish(mut self) -> HoverReport {
        let Some(start) = self.start else {
            return self.report;
        };
        let r = &mut self.report;
        let target_z = start[2] + r.target_height_m;
        // The hold is the image's HoverHold phase; after it the hover test searches for its pad's edges at the
        // same height, which is not part of the hold. A hold still open at the end runs to the last sample.
        if let Some(from) = self.hold_from_s {
            let until = self
                .hold_until_s
                .or_else(|| self.track.last().map(|s| s.0))
                .unwrap_or(from)
                .max(from);
            r.hold_start_s = Some(from);
            r.hold_end_s = Some(until);
            r.held_s = until - from;
            let mut sum = 0.0f64;
            let mut n = 0usize;
            for (_, p) in self.track.iter().filter(|(t, _)| (from..=until).contains(t)) {
                let dxy = ((p[0] - start[0]).powi(2) + (p[1] - start[1]).powi(2)).sqrt();
                r.hold_dev_xy_m = r.hold_dev_xy_m.max(dxy);
                r.hold_dev_z_m = r.hold_dev_z_m.max((p[2] - target_z).abs());
                sum += f64::from(dxy * dxy);
                n += 1;
            }
            r.hold_rms_xy_m = (sum / n.max(1) as f64).sqrt() as f32;
        }
        r.passed = r.took_off
            && r.landed
            && r.hold_start_s.is_some()
            && (r.held_s - f64::from(r.hover_time_s)).abs() <= HOLD_TIME_TOLERANCE_S
            && r.hold_dev_xy_m < HOLD_DEV_XY_M
            && r.hold_dev_z_m < HOLD_DEV_Z_M
            && r.landing_offset_m.is_some_and(|d| d < LANDING_OFFSET_M)
            && r.mission_end_state == Some(COMPLETED);
        self.report
    }
}

/// The image's load figures from its once-every-10-s defmt line (`src/board/system.rs` `stats_task`):
/// "load {}% (control {}%, io {}%, mission {}%), control {} Hz, jitter {} us, step max {} us".
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LoadLine {
    pub cpu_load_pct: u32,
    pub loop_rate_hz: u32,
    pub loop_jitter_us: u32,
    pub step_max_us: u32,
}

impl LoadLine {
    /// Parses the line's text (after the defmt timestamp and level); `None` for any other line.
    pub fn parse(text: &str) -> Option<Self> {
        let rest = &text[text.find("load ")? + 5..];
        let nums: Vec<u32> = rest
            .split(|c: char| !c.is_ascii_digit())
            .filter(|s| !s.is_empty())
            .filter_map(|s| s.parse().ok())
            .collect();
        // load, control %, io %, mission %, rate, jitter, step max
        (nums.len() == 7 && rest.contains(" Hz, jitter ")).then(|| Self {
            cpu_load_pct: nums[0],
            loop_rate_hz: nums[4],
            loop_jitter_us: nums[5],
            step_max_us: nums[6],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_script_writes_the_firmwares_param_ids_after_radio_ready() {
        let mut s = Script::hover(10.0, 0.5);
        assert!(s.due(5_000_000_000, None).is_empty(), "nothing before RADIO_READY");
        assert!(s.due(1_100_000_000, Some(1_000_000_000)).is_empty());
        let p = s.due(1_500_000_000, Some(1_000_000_000));
        // The firmware's own decoder reads it as a write of mission.mode = 1.
        let crtp = CrtpPacket::from_bytes(&p[0]).unwrap();
        assert_eq!((crtp.port, crtp.channel), (PORT_PARAM, CH_WRITE));
        assert_eq!(&crtp.data[..], &[ID_MODE.to_le_bytes()[0], ID_MODE.to_le_bytes()[1], 1]);
        assert!(s.due(1_520_000_000, Some(1_000_000_000)).is_empty(), "one per gap");
        for t in [1_550, 1_600, 1_650] {
            assert_eq!(s.due(t * 1_000_000, Some(1_000_000_000)).len(), 1);
        }
        assert!(s.done());
        let last = CrtpPacket::from_bytes(&s.packets[3]).unwrap();
        assert_eq!(&last.data[..2], &ID_START.to_le_bytes());
    }

    type Sample = (f64, [f32; 3], bool, MotorDuty);

    /// A hover flight: take off at 1 s, the image's hold 2.0–4.0 s (target 0.5 m above the start), a search
    /// flying off at the hold's height at 4.5 s, landed at 6 s 2 cm from the take-off point. `z_at_3` is the
    /// truth's height at 3 s, in the hold.
    fn flight(z_at_3: f32) -> Vec<Sample> {
        let on = MotorDuty([150; 4]);
        vec![
            (0.0, [1.0, 1.0, 0.1], true, MotorDuty::default()),
            (1.0, [1.0, 1.0, 0.4], false, on),
            (2.0, [1.05, 1.0, 0.58], false, on),
            (3.0, [1.0, 1.04, z_at_3], false, on),
            (4.0, [1.0, 1.0, 0.6], false, on),
            (4.5, [1.5, 1.0, 0.6], false, on),
            (5.0, [1.0, 1.0, 0.3], false, on),
            (6.0, [1.02, 1.0, 0.1], true, MotorDuty::default()),
        ]
    }

    fn judge(samples: &[Sample], lines: &[&str]) -> HoverReport {
        let mut j = HoverJudge::new(0.5, 2.0);
        for &(t, p, g, d) in samples {
            j.sample(t, p, g, d);
        }
        for (k, l) in lines.iter().enumerate() {
            j.log_line(10.0 + k as f64, l);
        }
        j.finish()
    }

    const HOLD_LINES: [&str; 4] = [
        "0.900000 INFO mission state 10",
        "2.000000 INFO mission state 50",
        "4.000000 INFO mission state 51",
        "6.100000 INFO mission ended: state 100",
    ];

    #[test]
    fn the_judge_measures_the_images_hold_against_the_truth() {
        let r = judge(&flight(0.63), &HOLD_LINES);
        assert!(r.took_off && r.landed && r.passed, "{r:?}");
        assert_eq!(
            (r.hold_start_s, r.hold_end_s),
            (Some(2.0), Some(4.0)),
            "the lines' own timestamps"
        );
        assert!((r.held_s - 2.0).abs() < 1e-9, "{}", r.held_s);
        // The search at 4.5 s (0.5 m off) is outside the hold.
        assert!((r.hold_dev_xy_m - 0.05).abs() < 1e-6, "{}", r.hold_dev_xy_m);
        assert!((r.hold_dev_z_m - 0.03).abs() < 1e-6, "{}", r.hold_dev_z_m);
        assert!((r.landing_offset_m.unwrap() - 0.02).abs() < 1e-6);
        assert_eq!(r.mission_end_state, Some(100));
    }

    #[test]
    fn the_judge_fails_a_hold_off_height_an_unfinished_mission_or_no_hold() {
        // 9 cm low during the hold.
        let r = judge(&flight(0.51), &HOLD_LINES);
        assert!((r.hold_dev_z_m - 0.09).abs() < 1e-6 && !r.passed, "{r:?}");
        // The same flight ended by the image in an estimator fault.
        let mut lines = HOLD_LINES;
        lines[3] = "6.1 INFO mission ended: state 204";
        let r = judge(&flight(0.63), &lines);
        assert!(
            r.took_off && r.landed && r.mission_end_state == Some(204) && !r.passed,
            "{r:?}"
        );
        // A hold cut short (1.5 s of 2).
        let mut lines = HOLD_LINES;
        lines[2] = "3.5 INFO mission state 51";
        let r = judge(&flight(0.63), &lines);
        assert!((r.held_s - 1.5).abs() < 1e-9 && !r.passed, "{r:?}");
        // An image that never logs its hold (no state lines): nothing to judge, not passed.
        let r = judge(&flight(0.63), &["6.1 INFO mission ended: state 100"]);
        assert!(r.hold_start_s.is_none() && !r.passed, "{r:?}");
        // Never took off.
        let ground = [
            (0.0, [1.0, 1.0, 0.0], true, MotorDuty::default()),
            (9.0, [1.0, 1.0, 0.0], true, MotorDuty::default()),
        ];
        assert!(!judge(&ground, &HOLD_LINES).passed);
    }

    #[test]
    fn the_load_line_parses() {
        let l = LoadLine::parse(
            "load 23% (control 12%, io 5%, mission 6%), control 1000 Hz, jitter 14 us, step max 310 us",
        );
        assert_eq!(
            l,
            Some(LoadLine {
                cpu_load_pct: 23,
                loop_rate_hz: 1000,
                loop_jitter_us: 14,
                step_max_us: 310
            })
        );
        assert_eq!(LoadLine::parse("booted in 1078 ms"), None);
    }
}
