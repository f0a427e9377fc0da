//! The tuning parameters' values ([`Tuning`]): the parts of the flight configuration users tune without
//! reflashing, and where each tuning parameter's value lives in them.
//!
//! Job: the block of [`super::param_table::PARAM_TABLE`] marked as tuning parameters, each persistent, each
//! maps to one field of [`Tuning`] through [`tune_field`]; a write is checked against its declaration, then
//! the whole tuning against itself ([`Tuning::consistent`]: the controller's validation, the avoidance's,
//! narrow inflation ≤ inflation, low landing speed ≤ high). `posCtlPid.x*`/`y*` and `velCtlPid.vx*`/`vy*`
//! name one horizontal gain each (cfnav's loops are symmetric): [`field_addr`] finds the field two names
//! share, for [`crate::radio::param_decl::ParamStore::aliases`].
//!
//! Non-goals: the parameter store (see [`super::param_state`]), the configurations' own validation (see
//! [`crate::flight::control`] and [`crate::nav::avoidance`]).
//!
//! Memory: [`Tuning`] is two configurations by value, a few hundred bytes.

use crate::flight::control::ControllerConfig;
use crate::flight::estimator::EstimatorConfig;
use crate::mission::MissionConfig;
use crate::nav::avoidance::{AvoidanceMethod, SpeedClamp};
use crate::radio::param_decl::{ParamEntry, Refusal};
use crate::radio::toc::Value;

/// The tuning parameters' values: the parts of the flight configuration users tune without reflashing.
/// The endpoint hands them to the flight stack (`FlightCore::set_tuning`) whenever
/// [`MissionParamState::tuning_generation`] changes: controller gains and the flow std from the next step
/// (in flight too, as stock), the mission's tuning from the next mission start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tuning {
    /// Controller gains and limits.
    pub controller: ControllerConfig,
    /// The estimator's flow measurement std, counts.
    pub flow_std_counts: f32,
    /// Mission, planner and avoidance tuning.
    pub mission: MissionConfig,
}

impl Default for Tuning {
    fn default() -> Self {
        Self::new(
            ControllerConfig::default(),
            &EstimatorConfig::default(),
            MissionConfig::default(),
        )
    }
}

impl Tuning {
    /// The tuning of a flight stack built with these configurations.
    pub fn new(controller: ControllerConfig, estimator: &EstimatorConfig, mission: MissionConfig) -> Self {
        Self {
            controller,
            flow_std_counts: estimator.flow_std_counts,
            mission,
        }
    }

    /// Whether the values work together: the controller's own validation, the avoidance's, the narrow
    /// inflation at most the full one, the low landing speed at most the high one.
    pub fn consistent(&self) -> bool {
        let m = &self.mission;
        self.controller.validate().is_ok()
            && m.avoidance.validate().is_ok()
            && m.narrow_inflation_radius_m <= m.inflation_radius_m
            && m.descent_speed_m_s <= m.high_descent_speed_m_s
    }
}

/// Where a tuning parameter's value lives in [`Tuning`].
pub enum TuneField<'a> {
    /// A float, as is.
    F32(&'a mut f32),
    /// A thrust in counts, a uint16 on the wire (rounded when read).
    Thrust(&'a mut f32),
    /// The avoidance law: 0 potential field, 1 virtual force field.
    Method(&'a mut AvoidanceMethod),
    /// The avoidance speed clamp: 0 nearest, 1 towards each range.
    Clamp(&'a mut SpeedClamp),
}

/// The field of `t` that tuning parameter `group.name` sets; `None` for the other parameters. The
/// `PARAM_TABLE` block "Tuning parameters" declares each; this says only where its value goes.
pub fn tune_field<'a>(t: &'a mut Tuning, group: &str, name: &str) -> Option<TuneField<'a>> {
    Some(match (group, name) {
        ("pid_rate", "roll_kp") => TuneField::F32(&mut t.controller.roll_rate.kp),
        ("pid_rate", "roll_ki") => TuneField::F32(&mut t.controller.roll_rate.ki),
        ("pid_rate", "roll_kd") => TuneField::F32(&mut t.controller.roll_rate.kd),
        ("pid_rate", "pitch_kp") => TuneField::F32(&mut t.controller.pitch_rate.kp),
        ("pid_rate", "pitch_ki") => TuneField::F32(&mut t.controller.pitch_rate.ki),
        ("pid_rate", "pitch_kd") => TuneField::F32(&mut t.controller.pitch_rate.kd),
        ("pid_rate", "yaw_kp") => TuneField::F32(&mut t.controller.yaw_rate.kp),
        ("pid_rate", "yaw_ki") => TuneField::F32(&mut t.controller.yaw_rate.ki),
        ("pid_rate", "yaw_kd") => TuneField::F32(&mut t.controller.yaw_rate.kd),
        ("pid_attitude", "roll_kp") => TuneField::F32(&mut t.controller.roll.kp),
        ("pid_attitude", "roll_ki") => TuneField::F32(&mut t.controller.roll.ki),
        ("pid_attitude", "roll_kd") => TuneField::F32(&mut t.controller.roll.kd),
        ("pid_attitude", "pitch_kp") => TuneField::F32(&mut t.controller.pitch.kp),
        ("pid_attitude", "pitch_ki") => TuneField::F32(&mut t.controller.pitch.ki),
        ("pid_attitude", "pitch_kd") => TuneField::F32(&mut t.controller.pitch.kd),
        ("pid_attitude", "yaw_kp") => TuneField::F32(&mut t.controller.yaw.kp),
        ("pid_attitude", "yaw_ki") => TuneField::F32(&mut t.controller.yaw.ki),
        ("pid_attitude", "yaw_kd") => TuneField::F32(&mut t.controller.yaw.kd),
        ("velCtlPid", "vxKp") => TuneField::F32(&mut t.controller.vel_xy.kp),
        ("velCtlPid", "vxKi") => TuneField::F32(&mut t.controller.vel_xy.ki),
        ("velCtlPid", "vxKd") => TuneField::F32(&mut t.controller.vel_xy.kd),
        ("velCtlPid", "vyKp") => TuneField::F32(&mut t.controller.vel_xy.kp),
        ("velCtlPid", "vyKi") => TuneField::F32(&mut t.controller.vel_xy.ki),
        ("velCtlPid", "vyKd") => TuneField::F32(&mut t.controller.vel_xy.kd),
        ("velCtlPid", "vzKp") => TuneField::F32(&mut t.controller.vel_z.kp),
        ("velCtlPid", "vzKi") => TuneField::F32(&mut t.controller.vel_z.ki),
        ("velCtlPid", "vzKd") => TuneField::F32(&mut t.controller.vel_z.kd),
        ("posCtlPid", "xKp") => TuneField::F32(&mut t.controller.pos_xy.kp),
        ("posCtlPid", "xKi") => TuneField::F32(&mut t.controller.pos_xy.ki),
        ("posCtlPid", "xKd") => TuneField::F32(&mut t.controller.pos_xy.kd),
        ("posCtlPid", "yKp") => TuneField::F32(&mut t.controller.pos_xy.kp),
        ("posCtlPid", "yKi") => TuneField::F32(&mut t.controller.pos_xy.ki),
        ("posCtlPid", "yKd") => TuneField::F32(&mut t.controller.pos_xy.kd),
        ("posCtlPid", "zKp") => TuneField::F32(&mut t.controller.pos_z.kp),
        ("posCtlPid", "zKi") => TuneField::F32(&mut t.controller.pos_z.ki),
        ("posCtlPid", "zKd") => TuneField::F32(&mut t.controller.pos_z.kd),
        ("posCtlPid", "xVelMax") => TuneField::F32(&mut t.controller.max_xy_speed_m_s),
        ("posCtlPid", "yVelMax") => TuneField::F32(&mut t.controller.max_xy_speed_m_s),
        ("posCtlPid", "zVelMax") => TuneField::F32(&mut t.controller.max_vz_m_s),
        ("posCtlPid", "thrustBase") => TuneField::Thrust(&mut t.controller.thrust_base),
        ("posCtlPid", "thrustMin") => TuneField::Thrust(&mut t.controller.thrust_min),
        ("motion", "flowStdFixed") => TuneField::F32(&mut t.flow_std_counts),
        ("avoid", "mode") => TuneField::Method(&mut t.mission.avoidance.method),
        ("avoid", "clamp") => TuneField::Clamp(&mut t.mission.avoidance.clamp),
        ("avoid", "gain") => TuneField::F32(&mut t.mission.avoidance.gain_mps),
        ("avoid", "dangerDist") => TuneField::F32(&mut t.mission.avoidance.danger_distance_m),
        ("avoid", "slowDist") => TuneField::F32(&mut t.mission.avoidance.slow_down_distance_m),
        ("avoid", "minSpeed") => TuneField::F32(&mut t.mission.avoidance.min_speed_mps),
        ("plan", "inflation") => TuneField::F32(&mut t.mission.inflation_radius_m),
        ("plan", "narrowInfl") => TuneField::F32(&mut t.mission.narrow_inflation_radius_m),
        ("plan", "narrowSpeed") => TuneField::F32(&mut t.mission.narrow_speed_m_s),
        ("mission", "searchSpeed") => TuneField::F32(&mut t.mission.search_speed_m_s),
        ("mission", "climbSpeed") => TuneField::F32(&mut t.mission.climb_speed_m_s),
        ("mission", "landSpeed") => TuneField::F32(&mut t.mission.descent_speed_m_s),
        ("mission", "landSpeedHigh") => TuneField::F32(&mut t.mission.high_descent_speed_m_s),
        ("mission", "goalTol") => TuneField::F32(&mut t.mission.goal_tolerance_m),
        ("mission", "padTol") => TuneField::F32(&mut t.mission.settle_tolerance_m),
        ("mission", "padPause") => TuneField::F32(&mut t.mission.pause_s),
        ("mission", "sweepSpacing") => TuneField::F32(&mut t.mission.sweep.spacing_m),
        ("mission", "batReserve") => TuneField::F32(&mut t.mission.battery_reserve),
        _ => return None,
    })
}

/// The value of tuning parameter `e` in `t`.
pub(super) fn tune_read(t: &Tuning, e: &ParamEntry) -> Option<Value> {
    let mut t = *t;
    Some(match tune_field(&mut t, e.group, e.name)? {
        TuneField::F32(v) => Value::F32(*v),
        TuneField::Thrust(v) => Value::U16(libm::roundf(v.clamp(0.0, 65535.0)) as u16),
        TuneField::Method(m) => Value::U8(u8::from(*m == AvoidanceMethod::VirtualForceField)),
        TuneField::Clamp(c) => Value::U8(u8::from(*c == SpeedClamp::TowardsEachRange)),
    })
}

/// `t` with tuning parameter `e` set to `value` (already checked against the declaration).
pub(super) fn tune_write(t: &Tuning, e: &ParamEntry, value: Value) -> Result<Tuning, Refusal> {
    let mut t = *t;
    match (tune_field(&mut t, e.group, e.name).ok_or(Refusal::UnknownId)?, value) {
        (TuneField::F32(f), Value::F32(v)) => *f = v,
        (TuneField::Thrust(f), Value::U16(v)) => *f = f32::from(v),
        (TuneField::Method(m), Value::U8(v)) => {
            *m = if v == 0 {
                AvoidanceMethod::PotentialField
            } else {
                AvoidanceMethod::VirtualForceField
            }
        }
        (TuneField::Clamp(c), Value::U8(v)) => {
            *c = if v == 0 {
                SpeedClamp::Nearest
            } else {
                SpeedClamp::TowardsEachRange
            }
        }
        _ => return Err(Refusal::WrongType),
    }
    if t.consistent() {
        Ok(t)
    } else {
        Err(Refusal::Inconsistent)
    }
}

/// The address of tuning parameter `e`'s field inside `t` (as an offset), to find two names of one field.
pub(super) fn field_addr(t: &mut Tuning, e: &ParamEntry) -> Option<usize> {
    let base = t as *const Tuning as usize;
    let addr = match tune_field(t, e.group, e.name)? {
        TuneField::F32(f) | TuneField::Thrust(f) => f as *const f32 as usize,
        TuneField::Method(m) => m as *const AvoidanceMethod as usize,
        TuneField::Clamp(c) => c as *const SpeedClamp as usize,
    };
    Some(addr - base)
}
