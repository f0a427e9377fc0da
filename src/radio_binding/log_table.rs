//! Every log variable cfnav serves, declared once: one `const` line per variable (group, name, storage
//! type, unit, doc) in [`LOG_TABLE`], the `ID_*` constants, and what the firmware and the simulator publish
//! ([`FlightLogState`], [`FirmwareLogState`]).
//!
//! Job: the TOC (type code, names, CRC), the `ID_*` constants (looked up in the table at compile time,
//! [`log_id`]) and the log table of the docs ([`write_log_table`]) derive from these declarations.
//!
//! Non-goals: the declaration type and the type conversion (see [`crate::radio::log_decl`]), the wire
//! protocol (see [`crate::radio::log`]).
//!
//! Sources: `docs/radio.md` (the `mission.*`, `stateEstimate.*`, `range.*` and `pm.vbat` ids 0–10). Stock
//! names, types and units from `bitcraze/crazyflie-firmware` (`LOG_ADD` lines): `stateEstimate.*` floats,
//! attitude in degrees with pitch exported with the opposite sign (`kalman_core.c`:
//! `.pitch = -pitch*RAD_TO_DEG`); `stabilizer.roll/pitch/yaw` the same attitude, `stabilizer.thrust` the
//! collective thrust in motor counts; `motor.m1..m4` uint16 ratios (`motors.c`); `sys.canfly` uint8
//! (`supervisor.c`); `supervisor.info` uint16 bitfield (`supervisor.c`, the same bits as the supervisor
//! port); `pm.state` int8 (0 battery, 1 charging, 2 charged, 3 low power, 4 shutdown) and `pm.batteryLevel`
//! uint8 % from `LiPoTypicalChargeCurve` (`pm_stm32f4.c`); `gyro.x/y/z` float deg/s (`stabilizer.c`);
//! `controller.roll/pitch/yaw` and `controller.rollRate/pitchRate/yawRate` float, deg and deg/s
//! (`controller_pid.c`, `attitude_pid_controller.c`); `posCtl.targetX/Y/Z/VX/VY/VZ` float
//! (`position_controller_pid.c`). Every variable the stock cfclient 2026.8.1 puts in a log block (battery,
//! Flight tab, pose logger, the shipped Plotter configurations) is here: one missing variable makes cflib
//! refuse the whole block.
//!
//! Design choices: one table serves the firmware and the simulator: the `cfnav.*` CPU and loop-timing
//! variables (ids 11–17) read 0 in the simulator, which has no CPU to measure. The stock variables are
//! appended after them, so every older id is unchanged.
//!
//! Memory: the table is `'static`; [`FlightLogState`] is about 200 bytes.

use crate::flight::control::ControlOutput;
use crate::radio::log_decl::{LogEntry, LogSource, LogType, LogValue, log_id};
use crate::types::{Setpoint, StateEstimate};

const F: LogType = LogType::F32;

/// Every log variable cfnav serves, in id order: one declaration each (see the module docs).
pub const LOG_TABLE: &[LogEntry] = &[
    LogEntry::declare(
        "mission",
        "state",
        LogType::U8,
        "",
        "0 idle; 1..99 the phases; 100 completed; 200 and above ended without completing (the code says why)",
    ),
    LogEntry::declare("stateEstimate", "x", F, "m", "position estimate x, arena frame"),
    LogEntry::declare("stateEstimate", "y", F, "m", "position estimate y, arena frame"),
    LogEntry::declare(
        "stateEstimate",
        "z",
        F,
        "m",
        "position estimate z (height above the floor)",
    ),
    LogEntry::declare(
        "range",
        "front",
        LogType::U16,
        "mm",
        "Multi-ranger front (32767: no return)",
    ),
    LogEntry::declare("range", "back", LogType::U16, "mm", "Multi-ranger back"),
    LogEntry::declare("range", "left", LogType::U16, "mm", "Multi-ranger left"),
    LogEntry::declare("range", "right", LogType::U16, "mm", "Multi-ranger right"),
    LogEntry::declare("range", "up", LogType::U16, "mm", "Multi-ranger up"),
    LogEntry::declare("range", "zrange", LogType::U16, "mm", "Flow deck's downward ranger"),
    LogEntry::declare("pm", "vbat", F, "V", "battery voltage"),
    LogEntry::declare(
        "cfnav",
        "cpuLoadPct",
        LogType::U8,
        "%",
        "instrumented work of all levels over the last second (firmware; 0 in the simulator)",
    ),
    LogEntry::declare(
        "cfnav",
        "ctrlLoadPct",
        LogType::U8,
        "%",
        "estimation + control (firmware)",
    ),
    LogEntry::declare("cfnav", "ioLoadPct", LogType::U8, "%", "sensors and radio (firmware)"),
    LogEntry::declare(
        "cfnav",
        "missionLoadPct",
        LogType::U8,
        "%",
        "mission and planner (firmware)",
    ),
    LogEntry::declare(
        "cfnav",
        "loopJitterUs",
        LogType::U16,
        "µs",
        "peak-to-peak spread of the control period over the last second (firmware)",
    ),
    LogEntry::declare(
        "cfnav",
        "loopStepMaxUs",
        LogType::U16,
        "µs",
        "longest control step over the last second (firmware)",
    ),
    LogEntry::declare(
        "cfnav",
        "loopRateHz",
        LogType::U16,
        "Hz",
        "control steps in the last second (firmware)",
    ),
    LogEntry::declare("stateEstimate", "vx", F, "m/s", "velocity estimate x, arena frame"),
    LogEntry::declare("stateEstimate", "vy", F, "m/s", "velocity estimate y, arena frame"),
    LogEntry::declare("stateEstimate", "vz", F, "m/s", "velocity estimate z"),
    LogEntry::declare("stateEstimate", "roll", F, "deg", "roll estimate"),
    LogEntry::declare(
        "stateEstimate",
        "pitch",
        F,
        "deg",
        "pitch estimate, stock sign (positive: nose up)",
    ),
    LogEntry::declare(
        "stateEstimate",
        "yaw",
        F,
        "deg",
        "yaw estimate (0 along +x, counter-clockwise)",
    ),
    LogEntry::declare(
        "stabilizer",
        "roll",
        F,
        "deg",
        "as stateEstimate.roll (stock keeps both)",
    ),
    LogEntry::declare("stabilizer", "pitch", F, "deg", "as stateEstimate.pitch"),
    LogEntry::declare("stabilizer", "yaw", F, "deg", "as stateEstimate.yaw"),
    LogEntry::declare(
        "stabilizer",
        "thrust",
        F,
        "counts",
        "collective thrust command, 0..65535 per motor",
    ),
    LogEntry::declare(
        "motor",
        "m1",
        LogType::U16,
        "",
        "motor 1 ratio after battery compensation, 0..65535",
    ),
    LogEntry::declare("motor", "m2", LogType::U16, "", "motor 2 ratio"),
    LogEntry::declare("motor", "m3", LogType::U16, "", "motor 3 ratio"),
    LogEntry::declare("motor", "m4", LogType::U16, "", "motor 4 ratio"),
    LogEntry::declare(
        "sys",
        "canfly",
        LogType::U8,
        "",
        "1 when the supervisor lets the motors run",
    ),
    LogEntry::declare(
        "supervisor",
        "info",
        LogType::U16,
        "",
        "supervisor bitfield, stock bits (as the supervisor port's)",
    ),
    LogEntry::declare(
        "pm",
        "state",
        LogType::I8,
        "",
        "0 on battery, 3 low power (latched by the supervisor)",
    ),
    LogEntry::declare(
        "pm",
        "batteryLevel",
        LogType::U8,
        "%",
        "charge from pm.vbat, stock's 10 % steps",
    ),
    LogEntry::declare("gyro", "x", F, "deg/s", "body rate about x (filtered gyro)"),
    LogEntry::declare("gyro", "y", F, "deg/s", "body rate about y"),
    LogEntry::declare("gyro", "z", F, "deg/s", "body rate about z"),
    LogEntry::declare("controller", "roll", F, "deg", "attitude target roll"),
    LogEntry::declare("controller", "pitch", F, "deg", "attitude target pitch, stock sign"),
    LogEntry::declare("controller", "yaw", F, "deg", "attitude target yaw"),
    LogEntry::declare("controller", "rollRate", F, "deg/s", "body-rate target about x"),
    LogEntry::declare("controller", "pitchRate", F, "deg/s", "body-rate target about y"),
    LogEntry::declare("controller", "yawRate", F, "deg/s", "body-rate target about z"),
    LogEntry::declare("posCtl", "targetVX", F, "m/s", "velocity target x, arena frame"),
    LogEntry::declare("posCtl", "targetVY", F, "m/s", "velocity target y"),
    LogEntry::declare("posCtl", "targetVZ", F, "m/s", "velocity target z"),
    LogEntry::declare(
        "posCtl",
        "targetX",
        F,
        "m",
        "position target x (the estimate when the setpoint is not a position)",
    ),
    LogEntry::declare("posCtl", "targetY", F, "m", "position target y"),
    LogEntry::declare("posCtl", "targetZ", F, "m", "position target z"),
    // Mission modes
    LogEntry::declare(
        "mission",
        "hoverDevXY",
        F,
        "m",
        "hover test: worst horizontal distance of the estimate from the take-off point while holding",
    ),
    LogEntry::declare(
        "mission",
        "hoverDevZ",
        F,
        "m",
        "hover test: worst |estimated height - mission.height| while holding",
    ),
    LogEntry::declare(
        "mission",
        "covered",
        F,
        "",
        "explore: fraction of the arena's cells known at the latest frontier scan",
    ),
];

/// Id of `mission.state` (uint8).
pub const ID_MISSION_STATE: u16 = log_id(LOG_TABLE, "mission", "state");
/// Id of `stateEstimate.x` (float).
pub const ID_X: u16 = log_id(LOG_TABLE, "stateEstimate", "x");
/// Id of `stateEstimate.y` (float).
pub const ID_Y: u16 = log_id(LOG_TABLE, "stateEstimate", "y");
/// Id of `stateEstimate.z` (float).
pub const ID_Z: u16 = log_id(LOG_TABLE, "stateEstimate", "z");
/// Id of `range.front` (uint16, mm); `range.back`, `.left`, `.right`, `.up`, `.zrange` follow.
pub const ID_RANGE_FRONT: u16 = log_id(LOG_TABLE, "range", "front");
/// Id of `range.zrange` (uint16, mm).
pub const ID_RANGE_ZRANGE: u16 = log_id(LOG_TABLE, "range", "zrange");
/// Id of `pm.vbat` (float).
pub const ID_VBAT: u16 = log_id(LOG_TABLE, "pm", "vbat");
/// Id of `cfnav.cpuLoadPct` (uint8, %): instrumented work of all levels over the last second.
pub const ID_CPU_LOAD_PCT: u16 = log_id(LOG_TABLE, "cfnav", "cpuLoadPct");
/// Id of `cfnav.missionLoadPct` (uint8, %): mission and planner (thread mode).
pub const ID_MISSION_LOAD_PCT: u16 = log_id(LOG_TABLE, "cfnav", "missionLoadPct");
/// Id of `cfnav.loopJitterUs` (uint16, µs): peak-to-peak spread of the control period over the last second.
pub const ID_LOOP_JITTER_US: u16 = log_id(LOG_TABLE, "cfnav", "loopJitterUs");
/// Id of `cfnav.loopStepMaxUs` (uint16, µs): the longest control step over the last second.
pub const ID_LOOP_STEP_MAX_US: u16 = log_id(LOG_TABLE, "cfnav", "loopStepMaxUs");
/// Id of `cfnav.loopRateHz` (uint16): control steps in the last second.
pub const ID_LOOP_RATE_HZ: u16 = log_id(LOG_TABLE, "cfnav", "loopRateHz");
/// Id of `stateEstimate.vx` (float); `.vy`, `.vz` follow.
pub const ID_VX: u16 = log_id(LOG_TABLE, "stateEstimate", "vx");
/// Id of `stateEstimate.roll` (float, deg); `.pitch`, `.yaw` follow.
pub const ID_ROLL: u16 = log_id(LOG_TABLE, "stateEstimate", "roll");
/// Id of `stabilizer.roll` (float, deg); `.pitch`, `.yaw` follow.
pub const ID_STAB_ROLL: u16 = log_id(LOG_TABLE, "stabilizer", "roll");
/// Id of `stabilizer.thrust` (float, counts).
pub const ID_THRUST: u16 = log_id(LOG_TABLE, "stabilizer", "thrust");
/// Id of `motor.m1` (uint16); `m2`..`m4` follow.
pub const ID_MOTOR_M1: u16 = log_id(LOG_TABLE, "motor", "m1");
/// Id of `sys.canfly` (uint8).
pub const ID_CAN_FLY: u16 = log_id(LOG_TABLE, "sys", "canfly");
/// Id of `supervisor.info` (uint16).
pub const ID_SUPERVISOR_INFO: u16 = log_id(LOG_TABLE, "supervisor", "info");
/// Id of `pm.state` (int8).
pub const ID_PM_STATE: u16 = log_id(LOG_TABLE, "pm", "state");
/// Id of `pm.batteryLevel` (uint8, %).
pub const ID_BATTERY_LEVEL: u16 = log_id(LOG_TABLE, "pm", "batteryLevel");
/// Id of `gyro.x` (float, deg/s); `.y`, `.z` follow.
pub const ID_GYRO_X: u16 = log_id(LOG_TABLE, "gyro", "x");
/// Id of `controller.roll` (float, deg); `.pitch`, `.yaw` follow.
pub const ID_CTRL_ROLL: u16 = log_id(LOG_TABLE, "controller", "roll");
/// Id of `controller.rollRate` (float, deg/s); `.pitchRate`, `.yawRate` follow.
pub const ID_CTRL_ROLL_RATE: u16 = log_id(LOG_TABLE, "controller", "rollRate");
/// Id of `posCtl.targetVX` (float, m/s); `VY`, `VZ` follow.
pub const ID_TARGET_VX: u16 = log_id(LOG_TABLE, "posCtl", "targetVX");
/// Id of `posCtl.targetX` (float, m); `Y`, `Z` follow.
pub const ID_TARGET_X: u16 = log_id(LOG_TABLE, "posCtl", "targetX");
/// Id of `mission.hoverDevXY` (float, m).
pub const ID_HOVER_DEV_XY: u16 = log_id(LOG_TABLE, "mission", "hoverDevXY");
/// Id of `mission.hoverDevZ` (float, m).
pub const ID_HOVER_DEV_Z: u16 = log_id(LOG_TABLE, "mission", "hoverDevZ");
/// Id of `mission.covered` (float, fraction).
pub const ID_COVERED: u16 = log_id(LOG_TABLE, "mission", "covered");

/// `supervisor.info` bit 3: can fly (stock `supervisor.c`).
const INFO_CAN_FLY: u16 = 1 << 3;
/// Stock `pm.state` values.
const PM_BATTERY: i8 = 0;
/// Stock `pm.state`: low power.
const PM_LOW_POWER: i8 = 3;
/// Stock `LiPoTypicalChargeCurve`, V: 0 %, 10 %, ..., 90 % (`pm_stm32f4.c`).
const LIPO_CHARGE_CURVE_V: [f32; 10] = [3.00, 3.78, 3.83, 3.87, 3.89, 3.92, 3.96, 4.00, 4.04, 4.10];

/// Stock `pm.batteryLevel`: 10 × the first step of [`LIPO_CHARGE_CURVE_V`] at or above `vbat_v`, 0 below 3.00 V,
/// 90 above 4.10 V (`pmBatteryChargeFromVoltage`); 0 for NaN.
pub fn battery_level_pct(vbat_v: f32) -> u8 {
    if vbat_v.is_nan() || vbat_v < LIPO_CHARGE_CURVE_V[0] {
        return 0;
    }
    let step = LIPO_CHARGE_CURVE_V.iter().position(|&v| vbat_v <= v).unwrap_or(9);
    (step as u8) * 10
}

/// Radians to degrees.
fn deg(rad: f32) -> f32 {
    rad.to_degrees()
}

/// What the firmware or the simulator publishes for logging; fill it every control cycle (or at the log rate).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FlightLogState {
    /// `mission.state` (codes in `docs/radio.md`).
    pub mission_state: u8,
    /// `stateEstimate.x/.y/.z`, arena frame, m.
    pub position_m: [f32; 3],
    /// `range.front, .back, .left, .right, .up, .zrange`, mm, in that order.
    pub ranges_mm: [u16; 6],
    /// `pm.vbat`, V (also gives `pm.batteryLevel`).
    pub vbat_v: f32,
    /// `stateEstimate.vx/.vy/.vz`, arena frame, m/s.
    pub velocity_m_s: [f32; 3],
    /// Roll, pitch, yaw, rad, cfnav's convention (converted to stock degrees and sign when logged).
    pub attitude_rad: [f32; 3],
    /// Body rates, rad/s (`gyro.*`).
    pub rates_rad_s: [f32; 3],
    /// `stabilizer.thrust`, counts.
    pub thrust: f32,
    /// `motor.m1..m4`.
    pub motor_ratio: [u16; 4],
    /// `supervisor.info` (also gives `sys.canfly`).
    pub supervisor_info: u16,
    /// Battery low, latched by the supervisor (`pm.state` 3).
    pub battery_low: bool,
    /// Attitude target, rad, cfnav's convention.
    pub attitude_target_rad: [f32; 3],
    /// Body-rate target, rad/s, cfnav's convention.
    pub rate_target_rad_s: [f32; 3],
    /// `posCtl.targetVX/VY/VZ`, m/s.
    pub velocity_target_m_s: [f32; 3],
    /// `posCtl.targetX/Y/Z`, m.
    pub position_target_m: [f32; 3],
    /// `mission.hoverDevXY`, `mission.hoverDevZ`, m (the hover test's worst deviations).
    pub hover_dev_m: [f32; 2],
    /// `mission.covered`: the exploration's known fraction of the arena.
    pub coverage: f32,
}

impl FlightLogState {
    /// Copies the flight stack's readouts: the estimate, the controller's output and the setpoint in force
    /// (the same call in the firmware and the simulator).
    pub fn record_flight(&mut self, estimate: &StateEstimate, control: &ControlOutput, setpoint: &Setpoint) {
        self.position_m = estimate.position_m;
        self.velocity_m_s = estimate.velocity_m_s;
        self.attitude_rad = estimate.attitude_rad;
        self.rates_rad_s = estimate.rates_rad_s;
        self.thrust = control.collective;
        self.motor_ratio = control.motor_ratio;
        self.attitude_target_rad = control.attitude_target_rad;
        self.rate_target_rad_s = control.rate_target_rad_s;
        self.velocity_target_m_s = control.velocity_target_m_s;
        self.position_target_m = match *setpoint {
            Setpoint::Position { x_m, y_m, z_m, .. } => [x_m, y_m, z_m],
            _ => estimate.position_m,
        };
    }

    /// A roll, pitch, yaw triple in stock degrees and signs (pitch negated: module docs).
    fn stock_deg(v: [f32; 3], axis: u16) -> Option<LogValue> {
        let x = *v.get(usize::from(axis))?;
        Some(LogValue::F32(if axis == 1 { -deg(x) } else { deg(x) }))
    }
}

impl LogSource for FlightLogState {
    const TABLE: &'static [LogEntry] = LOG_TABLE;

    fn value(&self, id: u16) -> Option<LogValue> {
        let f = |v: [f32; 3], base: u16| v.get(usize::from(id - base)).map(|&x| LogValue::F32(x));
        // Body rates: stock's gyro axes are cfnav's body axes, so only the unit changes.
        let rate_deg = |v: [f32; 3], base: u16| v.get(usize::from(id - base)).map(|&x| LogValue::F32(deg(x)));
        match id {
            ID_MISSION_STATE => Some(LogValue::U8(self.mission_state)),
            ID_X..=ID_Z => f(self.position_m, ID_X),
            ID_RANGE_FRONT..=ID_RANGE_ZRANGE => {
                Some(LogValue::U16(*self.ranges_mm.get(usize::from(id - ID_RANGE_FRONT))?))
            }
            ID_VBAT => Some(LogValue::F32(self.vbat_v)),
            // The simulator measures no CPU: the cfnav.* load and timing variables are sent as zeros.
            ID_CPU_LOAD_PCT..=ID_LOOP_RATE_HZ => None,
            _ if (ID_VX..ID_VX + 3).contains(&id) => f(self.velocity_m_s, ID_VX),
            _ if (ID_ROLL..ID_ROLL + 3).contains(&id) => Self::stock_deg(self.attitude_rad, id - ID_ROLL),
            _ if (ID_STAB_ROLL..ID_STAB_ROLL + 3).contains(&id) => {
                Self::stock_deg(self.attitude_rad, id - ID_STAB_ROLL)
            }
            ID_THRUST => Some(LogValue::F32(self.thrust)),
            _ if (ID_MOTOR_M1..ID_MOTOR_M1 + 4).contains(&id) => {
                Some(LogValue::U16(*self.motor_ratio.get(usize::from(id - ID_MOTOR_M1))?))
            }
            ID_CAN_FLY => Some(LogValue::U8(u8::from(self.supervisor_info & INFO_CAN_FLY != 0))),
            ID_SUPERVISOR_INFO => Some(LogValue::U16(self.supervisor_info)),
            ID_PM_STATE => Some(LogValue::I8(if self.battery_low { PM_LOW_POWER } else { PM_BATTERY })),
            ID_BATTERY_LEVEL => Some(LogValue::U8(battery_level_pct(self.vbat_v))),
            _ if (ID_GYRO_X..ID_GYRO_X + 3).contains(&id) => rate_deg(self.rates_rad_s, ID_GYRO_X),
            _ if (ID_CTRL_ROLL..ID_CTRL_ROLL + 3).contains(&id) => {
                Self::stock_deg(self.attitude_target_rad, id - ID_CTRL_ROLL)
            }
            _ if (ID_CTRL_ROLL_RATE..ID_CTRL_ROLL_RATE + 3).contains(&id) => {
                rate_deg(self.rate_target_rad_s, ID_CTRL_ROLL_RATE)
            }
            _ if (ID_TARGET_VX..ID_TARGET_VX + 3).contains(&id) => f(self.velocity_target_m_s, ID_TARGET_VX),
            _ if (ID_TARGET_X..ID_TARGET_X + 3).contains(&id) => f(self.position_target_m, ID_TARGET_X),
            ID_HOVER_DEV_XY => Some(LogValue::F32(self.hover_dev_m[0])),
            ID_HOVER_DEV_Z => Some(LogValue::F32(self.hover_dev_m[1])),
            ID_COVERED => Some(LogValue::F32(self.coverage)),
            _ => None,
        }
    }
}

/// What the firmware publishes: the flight variables plus CPU load and control-loop timing.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FirmwareLogState {
    /// The flight variables.
    pub flight: FlightLogState,
    /// `cfnav.cpuLoadPct`, `.ctrlLoadPct`, `.ioLoadPct`, `.missionLoadPct`, %.
    pub load_pct: [u8; 4],
    /// `cfnav.loopJitterUs`, µs.
    pub loop_jitter_us: u16,
    /// `cfnav.loopStepMaxUs`, µs.
    pub loop_step_max_us: u16,
    /// `cfnav.loopRateHz`.
    pub loop_rate_hz: u16,
}

impl LogSource for FirmwareLogState {
    const TABLE: &'static [LogEntry] = LOG_TABLE;

    fn value(&self, id: u16) -> Option<LogValue> {
        Some(match id {
            ID_CPU_LOAD_PCT..=ID_MISSION_LOAD_PCT => {
                LogValue::U8(*self.load_pct.get(usize::from(id - ID_CPU_LOAD_PCT))?)
            }
            ID_LOOP_JITTER_US => LogValue::U16(self.loop_jitter_us),
            ID_LOOP_STEP_MAX_US => LogValue::U16(self.loop_step_max_us),
            ID_LOOP_RATE_HZ => LogValue::U16(self.loop_rate_hz),
            _ => return self.flight.value(id),
        })
    }
}
