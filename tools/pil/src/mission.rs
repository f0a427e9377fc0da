//! The round trip in the emulator (`--mission`): the judge of the flight on the
//! simulator's truth, scored the way `cfnav sim` scores it (`tools/src/sim/runner.rs` `Score`), so that the
//! two reports can be compared line by line (`tools/pil/compare_sitl.py`).
//!
//! Job: from the truth samples of each host slice and the image's defmt lines, count collisions (the body's
//! clearance to the world below zero, `BODY_RADIUS_M` as the simulator), the smallest clearance, the
//! horizontal distance flown while airborne, the landings (on the ground with all duties 0 for 200 ms, the
//! pad under it and the error from its centre), the mission time (the image's "mission started" line to the
//! last time the duties went to 0, as the simulator counts from its start trigger) and the end state the
//! image logged ("mission ended: state N"). Non-goals: the estimate's error (the image's estimate is not
//! read here; `--trace` prints it), replans, the believed map.
//!
//! Units: SI, arena frame, time in virtual seconds.

use cfnav::types::MotorDuty;
use serde::Serialize;

use cfnav_sim::report::Landing;
use cfnav_sim::world::{BODY_RADIUS_M, World};

/// A landing counts once the drone rested with its motors stopped this long (the simulator's 200 ticks).
pub const REST_S: f64 = 0.2;

/// The round trip as the truth saw it (the fields of `cfnav sim --json` that can be compared).
#[derive(Debug, Clone, Default, Serialize)]
pub struct MissionReport {
    /// "completed", "aborted", "crashed" (a collision or a tumble) or "timeout" (no end state logged within
    /// the run), as the simulator decides.
    pub outcome: String,
    /// Why it did not complete, in the simulator's words (docs/formats.md (report format): `no_path`, `pad_not_found`,
    /// `battery`, `collision`, ...); `None` when completed.
    pub reason: Option<String>,
    /// The end state the image logged (100 = completed).
    pub mission_state: Option<u32>,
    /// "mission started" to the last motor stop, s.
    pub mission_time_s: Option<f64>,
    pub collisions: u32,
    pub min_clearance_m: Option<f32>,
    pub landings: Vec<Landing>,
    /// Horizontal distance flown while airborne, m.
    pub distance_m: f64,
    /// Virtual time of the "mission started" line, s.
    pub started_at_s: Option<f64>,
    pub passed: bool,
}

/// Scores the round trip from truth samples.
#[derive(Debug, Default)]
pub struct MissionJudge {
    report: MissionReport,
    min_clearance: f32,
    in_collision: bool,
    last_airborne: Option<[f32; 3]>,
    was_on_ground: bool,
    pending_landing_s: Option<f64>,
    last_duty: MotorDuty,
    last_motor_stop_s: Option<f64>,
    now_s: f64,
}

impl MissionJudge {
    pub fn new() -> Self {
        Self {
            min_clearance: f32::INFINITY,
            was_on_ground: true,
            ..Self::default()
        }
    }

    /// One truth sample at `t_s`.
    pub fn sample(&mut self, world: &World, t_s: f64, p: [f32; 3], on_ground: bool, duty: MotorDuty) {
        self.now_s = t_s;
        let started = self.report.started_at_s.is_some();
        if on_ground {
            self.last_airborne = None;
            self.in_collision = false;
        } else {
            let clearance = world.clearance(p[0], p[1], p[2]) - BODY_RADIUS_M;
            self.min_clearance = self.min_clearance.min(clearance);
            if clearance < 0.0 && !self.in_collision {
                self.report.collisions += 1;
            }
            self.in_collision = clearance < 0.0;
            if let Some(q) = self.last_airborne {
                self.report.distance_m += f64::from((p[0] - q[0]).hypot(p[1] - q[1]));
            }
            self.last_airborne = Some(p);
            self.pending_landing_s = None;
        }
        if on_ground && !self.was_on_ground && started {
            self.pending_landing_s = Some(t_s);
        }
        if let Some(t0) = self.pending_landing_s
            && on_ground
            && duty == MotorDuty::default()
            && t_s >= t0 + REST_S
        {
            self.pending_landing_s = None;
            self.land(world, p);
        }
        if self.last_duty != MotorDuty::default() && duty == MotorDuty::default() {
            self.last_motor_stop_s = Some(t_s);
        }
        self.last_duty = duty;
        self.was_on_ground = on_ground;
    }

    fn land(&mut self, world: &World, p: [f32; 3]) {
        let (pad, on_pad) = world.landing_pad_at(p[0], p[1]);
        let c = world.pads.get(pad).map_or([p[0], p[1]], |pd| pd.center);
        self.report.landings.push(Landing {
            pad,
            error_m: (c[0] - p[0]).hypot(c[1] - p[1]),
            on_pad,
        });
    }

    /// One decoded defmt line of the image.
    pub fn log_line(&mut self, text: &str) {
        if text.contains("mission started") && self.report.started_at_s.is_none() {
            self.report.started_at_s = Some(self.now_s);
        }
        if let Some(rest) = text.split("mission ended: state ").nth(1) {
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            self.report.mission_state = digits.parse().ok();
        }
    }

    /// The mission ended and the drone rests with its motors off (its last landing counted).
    pub fn done(&self) -> bool {
        self.report.mission_state.is_some()
            && self.was_on_ground
            && self.last_duty == MotorDuty::default()
            && self.pending_landing_s.is_none()
    }

    /// The verdict, as the simulator's: a collision is a crash; completed needs state 100, the first
    /// landing on the goal pad and the last on the home pad.
    pub fn finish(mut self, world: &World) -> MissionReport {
        let r = &mut self.report;
        r.min_clearance_m = self.min_clearance.is_finite().then_some(self.min_clearance);
        r.mission_time_s = match (r.started_at_s, self.last_motor_stop_s) {
            (Some(s), Some(t)) if t > s => Some(t - s),
            _ => None,
        };
        let on_pads = r.landings.len() >= 2
            && r.landings[0].on_pad
            && r.landings[0].pad == world.goal_pad_index()
            && r.landings.last().is_some_and(|l| l.on_pad && l.pad == 0);
        let (outcome, reason) = outcome_and_reason(r.collisions, r.mission_state, on_pads);
        r.outcome = outcome.to_string();
        r.reason = reason.map(str::to_string);
        r.passed = r.outcome == "completed";
        self.report
    }
}

/// The outcome and reason words `cfnav sim` gives the same ending (`tools/src/sim/runner.rs`): a collision
/// first, then the image's logged end state (`None`: it never logged one within the run).
pub fn outcome_and_reason(
    collisions: u32,
    end_state: Option<u32>,
    on_pads: bool,
) -> (&'static str, Option<&'static str>) {
    use cfnav::mission::MissionState as S;
    if collisions > 0 {
        return ("crashed", Some("collision"));
    }
    let Some(code) = end_state else {
        return ("timeout", Some("time_limit"));
    };
    let is = |s: S| u32::from(s.code()) == code;
    if is(S::Completed) {
        return if on_pads {
            ("completed", None)
        } else {
            ("aborted", Some("missed_pad"))
        };
    }
    let words = [
        (S::Crashed, "crashed", "tumble"),
        (S::Aborted, "aborted", "aborted"),
        (S::NoPath, "aborted", "no_path"),
        (S::PadNotFound, "aborted", "pad_not_found"),
        (S::BatteryLow, "aborted", "battery"),
        (S::EstimatorFault, "aborted", "estimator_fault"),
        (S::PlannerFault, "aborted", "planner_fault"),
        (S::LinkLost, "aborted", "link_lost"),
        (S::LinkLostHome, "aborted", "link_lost_home"),
        (S::RangerLost, "aborted", "ranger_lost"),
    ];
    words
        .iter()
        .find(|(s, _, _)| is(*s))
        .map_or(("aborted", Some("unknown")), |&(_, o, r)| (o, Some(r)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn duty(on: bool) -> MotorDuty {
        MotorDuty(if on { [170; 4] } else { [0; 4] })
    }

    /// Flies `path` at 0.5 m in 1 cm steps; returns its length.
    fn fly(j: &mut MissionJudge, world: &World, t: &mut f64, path: &[[f32; 2]]) -> f64 {
        let mut len = 0.0;
        for w in path.windows(2) {
            let d = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
            len += f64::from(d);
            let n = (d / 0.01).ceil() as usize;
            for k in 0..=n {
                let f = k as f32 / n as f32;
                *t += 0.01;
                let p = [
                    w[0][0] + f * (w[1][0] - w[0][0]),
                    w[0][1] + f * (w[1][1] - w[0][1]),
                    0.5,
                ];
                j.sample(world, *t, p, false, duty(true));
            }
        }
        len
    }

    fn rest(j: &mut MissionJudge, world: &World, t: &mut f64, at: [f32; 2], motors: bool, n: usize) {
        for _ in 0..n {
            *t += 0.01;
            j.sample(world, *t, [at[0], at[1], 0.1], true, duty(motors));
        }
    }

    /// A scripted round trip on the default world, around its walls, box and cylinder: the oracle is the
    /// path's own length and the landing points' offsets from the world file's pad centres.
    #[test]
    fn endings_get_the_simulators_words() {
        assert_eq!(outcome_and_reason(0, Some(100), true), ("completed", None));
        assert_eq!(outcome_and_reason(0, Some(100), false), ("aborted", Some("missed_pad")));
        assert_eq!(outcome_and_reason(1, Some(100), true), ("crashed", Some("collision")));
        assert_eq!(
            outcome_and_reason(0, Some(202), false),
            ("aborted", Some("pad_not_found"))
        );
        assert_eq!(outcome_and_reason(0, Some(205), false), ("crashed", Some("tumble")));
        assert_eq!(
            outcome_and_reason(0, Some(208), true),
            ("aborted", Some("link_lost_home"))
        );
        assert_eq!(
            outcome_and_reason(0, Some(209), false),
            ("aborted", Some("ranger_lost"))
        );
        assert_eq!(outcome_and_reason(0, None, false), ("timeout", Some("time_limit")));
        assert_eq!(outcome_and_reason(0, Some(77), false), ("aborted", Some("unknown")));
    }

    #[test]
    fn a_round_trip_scores_like_the_simulator() {
        let world = World::default_world();
        let home = [0.6f32, 1.3];
        let goal = [5.12f32, 1.41];
        let out = [
            home,
            [0.6, 2.6],
            [3.6, 2.6],
            [3.6, 0.5],
            [5.12, 0.5],
            [goal[0] + 0.02, goal[1]],
        ];
        let back: Vec<[f32; 2]> = [
            [goal[0] + 0.02, goal[1]],
            [5.12, 0.5],
            [3.6, 0.5],
            [3.6, 2.6],
            [0.6, 2.6],
            [0.6, 1.25],
        ]
        .to_vec();
        let mut j = MissionJudge::new();
        let mut t = 0.0;
        rest(&mut j, &world, &mut t, home, false, 10);
        j.log_line("1.76 INFO mission started");
        let started = t;
        rest(&mut j, &world, &mut t, home, true, 10);
        let mut len = fly(&mut j, &world, &mut t, &out);
        rest(&mut j, &world, &mut t, out[5], false, 30);
        assert_eq!(
            j.report.landings.len(),
            1,
            "the goal landing counts after 200 ms at rest"
        );
        rest(&mut j, &world, &mut t, out[5], true, 10);
        len += fly(&mut j, &world, &mut t, &back);
        rest(&mut j, &world, &mut t, [0.6, 1.25], true, 5);
        let stop = t + 0.01;
        rest(&mut j, &world, &mut t, [0.6, 1.25], false, 30);
        assert!(!j.done(), "no end state logged yet");
        j.log_line("64.0 INFO mission ended: state 100 (Completed)");
        assert!(j.done());
        let r = j.finish(&world);
        assert_eq!(r.collisions, 0, "min clearance {:?}", r.min_clearance_m);
        assert_eq!(r.landings.len(), 2);
        assert_eq!(r.landings[0].pad, world.goal_pad_index());
        assert!(r.landings[0].on_pad && r.landings[1].on_pad);
        assert!((r.landings[0].error_m - 0.02).abs() < 1e-4);
        assert_eq!(r.landings[1].pad, 0);
        assert!((r.landings[1].error_m - 0.05).abs() < 1e-4);
        assert!((r.distance_m - len).abs() < 1e-3, "{} vs {len}", r.distance_m);
        let time = r.mission_time_s.unwrap_or(f64::NAN);
        assert!((time - (stop - started)).abs() < 1e-9, "{time}");
        assert_eq!(r.outcome, "completed");
        assert!(r.passed);
    }

    #[test]
    fn flying_into_a_wall_is_a_collision_and_no_end_state_is_not_completed() {
        let world = World::default_world();
        let mut j = MissionJudge::new();
        j.log_line("mission started");
        // Inside the first wall (x 2.0..2.2, y 0..2).
        j.sample(&world, 1.0, [2.1, 1.0, 0.5], false, duty(true));
        j.sample(&world, 1.01, [2.1, 1.0, 0.5], false, duty(true));
        j.sample(&world, 1.02, [1.5, 1.0, 0.5], false, duty(true));
        j.sample(&world, 1.03, [2.1, 1.0, 0.5], false, duty(true));
        j.log_line("mission ended: state 205");
        assert!(!j.done(), "still airborne");
        let r = j.finish(&world);
        assert_eq!(r.collisions, 2);
        assert!(r.min_clearance_m.is_some_and(|c| c < 0.0));
        assert_eq!(r.outcome, "crashed");
        assert_eq!(r.mission_state, Some(205));
        assert!(!r.passed);
    }
}
