//! The high-level commander's trajectory follower: take-off, land, go-to and stop as the stock firmware's
//! `crtp_commander_high_level.c` + `planner.c` fly them, turned into cfnav [`Setpoint`]s at any rate.
//!
//! Job: keep one trajectory segment (start and end position and heading, start time, duration, smooth or
//! linear) and evaluate it at `now`. Smooth segments follow the 7th-order polynomial with zero velocity,
//! acceleration and jerk at both ends, `s(τ) = 35τ⁴ − 84τ⁵ + 70τ⁶ − 20τ⁷` (the rest-to-rest case of
//! stock `plan_takeoff` / `plan_land` / `plan_go_to`, which call `piecewise_plan_7th_order_no_jerk`
//! in `pptraj.c`); linear go-tos (`GO_TO_2` with `linear = 1`) interpolate at constant speed. After a
//! segment ends the end point is held, as in stock; after a landing segment the drone descends at
//! [`TOUCHDOWN_SPEED_M_S`] until the supervisor sees the touchdown, then the caller stops the motors.
//!
//! Non-goals: no uploaded trajectories (`START_TRAJECTORY`, `DEFINE_TRAJECTORY`), no spiral: the radio
//! decoder refuses them with a console line. Go-tos start from the **current setpoint** at rest (stock
//! starts from the current setpoint's velocity and acceleration too; cfnav's setpoints carry no
//! acceleration, so a go-to sent mid-segment restarts with zero speed). No watchdog: a trajectory keeps
//! its setpoint fresh, as stock's planner does; the supervisor's other rules (min height, tumble,
//! battery) apply unchanged.
//!
//! Units and frames: arena frame, metres, radians, seconds for durations, µs for times.
//! Memory: [`HighLevel`] is under 64 bytes.

use crate::math::wrap_angle;
use crate::types::{Micros, Setpoint, StateEstimate};

/// Descent speed once a landing segment has ended below the minimum flying height, m/s.
pub const TOUCHDOWN_SPEED_M_S: f32 = 0.3;
/// Longest duration accepted, s (longer is refused; stock accepts any float).
pub const MAX_DURATION_S: f32 = 600.0;
/// Below this height a landing hands over to a Descend (the supervisor's minimum height for position
/// setpoints is 0.2 m above the floor), m.
pub const LAND_HANDOVER_M: f32 = 0.25;

/// A high-level command in cfnav's units (what the port 8 decoder produces).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HlCommand {
    /// Take off vertically to `height_m` (arena frame) in `duration_s`; heading `yaw_rad`, or the current
    /// heading when `None`.
    Takeoff {
        /// Target height above the arena floor, m.
        height_m: f32,
        /// Target heading, rad (`None`: keep the current one).
        yaw_rad: Option<f32>,
        /// Duration, s.
        duration_s: f32,
    },
    /// Descend vertically to `height_m` in `duration_s`, then touch down and stop the motors.
    Land {
        /// Target height, m (cflib passes 0 for the floor).
        height_m: f32,
        /// Target heading, rad (`None`: keep the current one).
        yaw_rad: Option<f32>,
        /// Duration, s.
        duration_s: f32,
    },
    /// Fly to a point.
    GoTo {
        /// Target (or offset, when `relative`), arena frame, m.
        position_m: [f32; 3],
        /// Target heading (or offset), rad.
        yaw_rad: f32,
        /// Duration, s.
        duration_s: f32,
        /// Relative to the current setpoint.
        relative: bool,
        /// Constant speed instead of the smooth polynomial.
        linear: bool,
    },
    /// Stop the motors now (stock `COMMAND_STOP`).
    Stop,
}

/// Why a command was refused (nothing changed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HlRefusal {
    /// A duration that is negative, not finite or longer than [`MAX_DURATION_S`].
    BadDuration,
    /// A target that is not finite.
    BadTarget,
    /// Go-to or land while the high-level commander is not flying (take off first).
    NotFlying,
}

/// What the commander is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HlPhase {
    /// Not in control (never started, stopped, landed, or a low-level setpoint took over).
    Idle,
    /// Flying a segment or holding its end.
    Flying,
    /// Flying a landing segment, then descending to the touchdown.
    Landing,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Segment {
    from: [f32; 4],
    to: [f32; 4],
    start_us: Micros,
    duration_s: f32,
    linear: bool,
}

impl Segment {
    /// Progress 0..=1 along the segment at `now`, shaped (smooth or linear).
    fn progress(&self, now: Micros) -> f32 {
        let t = now.saturating_sub(self.start_us) as f32 * 1e-6;
        if self.duration_s <= 0.0 || t >= self.duration_s {
            return 1.0;
        }
        let tau = t / self.duration_s;
        if self.linear { tau } else { smooth_step(tau) }
    }

    fn at(&self, now: Micros) -> [f32; 4] {
        let s = self.progress(now);
        let mut p = [0.0; 4];
        for (i, v) in p.iter_mut().enumerate().take(3) {
            *v = self.from[i] + s * (self.to[i] - self.from[i]);
        }
        p[3] = wrap_angle(self.from[3] + s * wrap_angle(self.to[3] - self.from[3]));
        p
    }

    fn ended(&self, now: Micros) -> bool {
        now.saturating_sub(self.start_us) as f32 * 1e-6 >= self.duration_s
    }
}

/// The rest-to-rest 7th-order polynomial on τ ∈ [0, 1]: zero velocity, acceleration and jerk at both ends.
pub fn smooth_step(tau: f32) -> f32 {
    let t = if tau.is_finite() { tau.clamp(0.0, 1.0) } else { 1.0 };
    // s(τ) = 1 − s(1 − τ): the second half from the symmetric first, so that f32 rounding near τ = 1
    // (where the four terms nearly cancel) cannot make the curve step backwards.
    let half = |t: f32| {
        let t4 = t * t * t * t;
        t4 * (35.0 + t * (-84.0 + t * (70.0 - 20.0 * t)))
    };
    if t <= 0.5 { half(t) } else { 1.0 - half(1.0 - t) }
}

/// The high-level commander's state: idle or one segment. See the module documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HighLevel {
    phase: HlPhase,
    segment: Option<Segment>,
}

impl Default for HighLevel {
    fn default() -> Self {
        Self::new()
    }
}

fn valid_duration(d: f32) -> bool {
    d.is_finite() && (0.0..=MAX_DURATION_S).contains(&d)
}

impl HighLevel {
    /// Idle.
    pub const fn new() -> Self {
        Self {
            phase: HlPhase::Idle,
            segment: None,
        }
    }

    /// What it is doing.
    pub fn phase(&self) -> HlPhase {
        self.phase
    }

    /// Whether it is in control (flying or landing).
    pub fn is_active(&self) -> bool {
        self.phase != HlPhase::Idle
    }

    /// Whether the current segment has ended (stock "trajectory finished"); true when idle.
    pub fn finished(&self, now: Micros) -> bool {
        self.segment.is_none_or(|s| s.ended(now))
    }

    /// Gives up control (a low-level setpoint took over, a mission started, the drone landed).
    pub fn disable(&mut self) {
        *self = Self::new();
    }

    /// Applies `command` at `now`, starting from the current setpoint when flying, from `estimate` when not.
    /// A refused command changes nothing. Returns the setpoint to fly at once for [`HlCommand::Stop`].
    pub fn command(&mut self, command: HlCommand, now: Micros, estimate: &StateEstimate) -> Result<(), HlRefusal> {
        let here = match (self.phase, self.segment) {
            (HlPhase::Flying | HlPhase::Landing, Some(seg)) => seg.at(now),
            _ => {
                let p = estimate.position_m;
                let p = if p.iter().all(|v| v.is_finite()) { p } else { [0.0; 3] };
                [p[0], p[1], p[2], wrap_angle(estimate.attitude_rad[2])]
            }
        };
        let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
        match command {
            HlCommand::Stop => {
                self.disable();
                Ok(())
            }
            HlCommand::Takeoff {
                height_m,
                yaw_rad,
                duration_s,
            }
            | HlCommand::Land {
                height_m,
                yaw_rad,
                duration_s,
            } => {
                if !valid_duration(duration_s) {
                    return Err(HlRefusal::BadDuration);
                }
                if !finite(&[height_m, yaw_rad.unwrap_or(0.0)]) {
                    return Err(HlRefusal::BadTarget);
                }
                let landing = matches!(command, HlCommand::Land { .. });
                if landing && self.phase == HlPhase::Idle {
                    return Err(HlRefusal::NotFlying);
                }
                let yaw = yaw_rad.map_or(here[3], wrap_angle);
                self.segment = Some(Segment {
                    from: here,
                    to: [here[0], here[1], height_m, yaw],
                    start_us: now,
                    duration_s,
                    linear: false,
                });
                self.phase = if landing { HlPhase::Landing } else { HlPhase::Flying };
                Ok(())
            }
            HlCommand::GoTo {
                position_m,
                yaw_rad,
                duration_s,
                relative,
                linear,
            } => {
                if !valid_duration(duration_s) {
                    return Err(HlRefusal::BadDuration);
                }
                if !finite(&[position_m[0], position_m[1], position_m[2], yaw_rad]) {
                    return Err(HlRefusal::BadTarget);
                }
                if self.phase == HlPhase::Idle {
                    return Err(HlRefusal::NotFlying);
                }
                let to = if relative {
                    [
                        here[0] + position_m[0],
                        here[1] + position_m[1],
                        here[2] + position_m[2],
                        wrap_angle(here[3] + yaw_rad),
                    ]
                } else {
                    [position_m[0], position_m[1], position_m[2], wrap_angle(yaw_rad)]
                };
                if !finite(&to) {
                    return Err(HlRefusal::BadTarget);
                }
                self.segment = Some(Segment {
                    from: here,
                    to,
                    start_us: now,
                    duration_s,
                    linear,
                });
                self.phase = HlPhase::Flying;
                Ok(())
            }
        }
    }

    /// The setpoint at `now`, or `None` when idle. A landing below [`LAND_HANDOVER_M`] (or whose segment
    /// ended) becomes a Descend at [`TOUCHDOWN_SPEED_M_S`] over its point; the caller disables the commander
    /// once the supervisor reports the touchdown.
    pub fn setpoint(&self, now: Micros) -> Option<Setpoint> {
        let seg = self.segment?;
        let p = seg.at(now);
        match self.phase {
            HlPhase::Idle => None,
            HlPhase::Landing if seg.ended(now) || p[2] < LAND_HANDOVER_M => Some(Setpoint::Descend {
                x_m: p[0],
                y_m: p[1],
                vz_m_s: -TOUCHDOWN_SPEED_M_S,
                yaw_rad: p[3],
            }),
            HlPhase::Flying | HlPhase::Landing => Some(Setpoint::Position {
                x_m: p[0],
                y_m: p[1],
                z_m: p[2],
                yaw_rad: p[3],
            }),
        }
    }
}
