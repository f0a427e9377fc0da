//! Every parameter cfnav serves, declared once: one `const` line per parameter (group, name, type, flags,
//! range, unit, doc) in [`PARAM_TABLE`], and the `ID_*` constants of the parameters the firmware reads by id.
//!
//! Job: the TOC (type byte, names, CRC), the generic write checks (unknown id, read-only, type, range:
//! [`ParamEntry::check`]), the console line of a refusal and the parameter table of the docs
//! ([`write_param_table`]) all derive from these declarations; the store ([`super::param_state`]) adds only
//! what a declaration cannot say. Ids are the table's indices, and the `ID_*` constants are looked up in the
//! table at compile time ([`param_id`]), so they cannot drift from it.
//!
//! Non-goals: the declaration type and its checks (see [`crate::radio::param_decl`]), the values in effect (see
//! [`super::param_state`]).
//!
//! Sources: `docs/radio.md` (the `mission.*` parameters and the refusal rule). Stock names, types and
//! semantics of the other groups from `bitcraze/crazyflie-firmware` (`PARAM_ADD` lines): `deck.bc*` uint8
//! read-only, 1 when the deck was detected (`flowdeck_v1v2.c`, `multiranger.c`, `zranger*.c`,
//! `lighthouse.c`, `locodeck.c`, `ledring12.c`, `color_led_deck.c`); `kalman.resetEstimation` uint8
//! (`estimator_kalman.c`); `stabilizer.controller` uint8, 0 auto-select, 1 PID, 2 Mellinger, 3 INDI,
//! 4 Brescianini, 5 Lee (`stabilizer.c`, `controller.h`); `commander.enHighLevel` uint8 (`commander.c`);
//! `firmware.revision0` uint32, `revision1` uint16, `modified` uint8, all read-only (`version.tmpl`, values
//! from git as `tools/make/versionTemplate.py` cuts them). The deck names are every `deck.*` name the stock
//! cfclient 2026.8.1 reads (Flight, LED-ring, Color LED, Lighthouse and Loco tabs): a name it misses stalls
//! its parameter callback.
//!
//! Design choices: the `mission.*` ids 0–6 are those `docs/radio.md` lists and stay first; new parameters
//! are appended. `stabilizer.controller` accepts 0 and 1 only (cfnav flies one cascaded PID controller:
//! both mean it).
//!
//! Memory: the table is `'static` (flash).

use crate::mission::link_loss::{MAX_LINK_TIMEOUT_S, MIN_LINK_TIMEOUT_S};
use crate::mission::{COVERAGE_RANGE, HOVER_TIME_RANGE_S, MAX_HEIGHT_M, MAX_SPEED_M_S, MIN_HEIGHT_M};
use crate::radio::param_decl::{FLAG_READ_ONLY, ParamEntry, ParamType, Range, Refusal, param_id};

/// Read-only flag, shortened for the declarations below.
const RO: u8 = FLAG_READ_ONLY;
/// A 0/1 switch.
const SWITCH: Range = Range::Closed(0.0, 1.0);

/// Every parameter cfnav serves, in id order: one declaration each (see the module docs). The `mission.*`
/// ids 0–6 are those `docs/radio.md` lists.
pub const PARAM_TABLE: &[ParamEntry] = &[
    ParamEntry::declare(
        "mission",
        "start",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "write 1 to start the mission from idle; 0 during a mission aborts it (land where it is)",
    )
    .refused_as(Refusal::BadStartValue),
    ParamEntry::declare(
        "mission",
        "goalX",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "nominal goal x, arena frame; must lie inside the arena, 0.1 m from the walls",
    ),
    ParamEntry::declare(
        "mission",
        "goalY",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "nominal goal y, arena frame; must lie inside the arena, 0.1 m from the walls",
    ),
    ParamEntry::declare(
        "mission",
        "startX",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "where the drone stands at power-on, x, arena frame; inside the arena",
    ),
    ParamEntry::declare(
        "mission",
        "startY",
        ParamType::F32,
        0,
        Range::Any,
        "m",
        "where the drone stands at power-on, y, arena frame; inside the arena",
    ),
    ParamEntry::declare(
        "mission",
        "height",
        ParamType::F32,
        0,
        Range::Closed(MIN_HEIGHT_M, MAX_HEIGHT_M),
        "m",
        "cruise height",
    )
    .refused_as(Refusal::BadHeight),
    ParamEntry::declare(
        "mission",
        "speed",
        ParamType::F32,
        0,
        Range::LeftOpen(0.0, MAX_SPEED_M_S),
        "m/s",
        "cruise speed",
    )
    .refused_as(Refusal::BadSpeed),
    ParamEntry::declare(
        "deck",
        "bcFlow",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Flow deck v1 detected: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcFlow2",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Flow deck v2 detected (its PMW3901 answered at boot)",
    ),
    ParamEntry::declare(
        "deck",
        "bcZRanger",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Z-ranger deck v1: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcZRanger2",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Z-ranger deck v2 (a separate deck; the Flow v2's own ranger counts as bcFlow2): always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcMultiranger",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Multi-ranger deck detected (all five beams answered at boot)",
    ),
    ParamEntry::declare(
        "deck",
        "bcLighthouse4",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Lighthouse deck: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcLoco",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Loco positioning deck: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcDWM1000",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Loco deck, old name: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcLedRing",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "LED-ring deck: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcColorLedBot",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Color LED deck, bottom: always 0",
    ),
    ParamEntry::declare(
        "deck",
        "bcColorLedTop",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "Color LED deck, top: always 0",
    ),
    ParamEntry::declare(
        "kalman",
        "resetEstimation",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "write 1 on the ground: the estimate's x, y go back to mission.startX/startY (heading kept); reads 0 again when done",
    ),
    ParamEntry::declare(
        "stabilizer",
        "controller",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "0 auto-select or 1 PID: both are cfnav's cascaded PID (2..5, stock's other controllers, are refused)",
    )
    .refused_as(Refusal::UnsupportedController),
    ParamEntry::declare(
        "commander",
        "enHighLevel",
        ParamType::U8,
        0,
        SWITCH,
        "",
        "stock's high-level-commander switch, kept for clients that write it",
    ),
    // Mission modes
    ParamEntry::declare(
        "mission",
        "mode",
        ParamType::U8,
        0,
        Range::Closed(0.0, 2.0),
        "",
        "0 round trip, 1 hover test, 2 explore (README mode table); refused while a mission runs",
    ),
    ParamEntry::declare(
        "mission",
        "hoverTime",
        ParamType::F32,
        0,
        Range::Closed(HOVER_TIME_RANGE_S.0, HOVER_TIME_RANGE_S.1),
        "s",
        "hover test: how long to hold over the take-off point; refused while a mission runs",
    ),
    ParamEntry::declare(
        "mission",
        "coverage",
        ParamType::F32,
        0,
        Range::Closed(COVERAGE_RANGE.0, COVERAGE_RANGE.1),
        "",
        "explore: fly home once this fraction of the arena's cells is known; refused while a mission runs",
    ),
    // Tuning parameters: stock names and types where stock has the parameter
    // (`attitude_pid_controller.c`, `position_controller_pid.c`, `flowdeck_v1v2.c`), cfnav's own groups
    // `avoid`, `plan` and `mission` otherwise. Each is persistent and maps to one field of [`Tuning`]
    // ([`tune_field`]). Bounds are sanity limits (no negative gain, no NaN), not a stability guarantee.
    ParamEntry::declare("pid_rate", "roll_kp", ParamType::F32, 0, Range::Closed(0.0, 1000.0), "", "roll-rate loop, torque counts per deg/s; P gain (stock 250)").persistent(),
    ParamEntry::declare("pid_rate", "roll_ki", ParamType::F32, 0, Range::Closed(0.0, 2000.0), "", "roll-rate loop, torque counts per deg/s; I gain (stock 500)").persistent(),
    ParamEntry::declare("pid_rate", "roll_kd", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "roll-rate loop, torque counts per deg/s; D gain (stock 2.5)").persistent(),
    ParamEntry::declare("pid_rate", "pitch_kp", ParamType::F32, 0, Range::Closed(0.0, 1000.0), "", "pitch-rate loop, torque counts per deg/s; P gain (stock 250)").persistent(),
    ParamEntry::declare("pid_rate", "pitch_ki", ParamType::F32, 0, Range::Closed(0.0, 2000.0), "", "pitch-rate loop, torque counts per deg/s; I gain (stock 500)").persistent(),
    ParamEntry::declare("pid_rate", "pitch_kd", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "pitch-rate loop, torque counts per deg/s; D gain (stock 2.5)").persistent(),
    ParamEntry::declare("pid_rate", "yaw_kp", ParamType::F32, 0, Range::Closed(0.0, 1000.0), "", "yaw-rate loop, torque counts per deg/s; P gain (stock 120)").persistent(),
    ParamEntry::declare("pid_rate", "yaw_ki", ParamType::F32, 0, Range::Closed(0.0, 2000.0), "", "yaw-rate loop, torque counts per deg/s; I gain (stock 16.7)").persistent(),
    ParamEntry::declare("pid_rate", "yaw_kd", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "yaw-rate loop, torque counts per deg/s; D gain (stock 0)").persistent(),
    ParamEntry::declare("pid_attitude", "roll_kp", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "roll-angle loop, deg/s per deg; P gain (stock 6)").persistent(),
    ParamEntry::declare("pid_attitude", "roll_ki", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "roll-angle loop, deg/s per deg; I gain (stock 3)").persistent(),
    ParamEntry::declare("pid_attitude", "roll_kd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "roll-angle loop, deg/s per deg; D gain (stock 0)").persistent(),
    ParamEntry::declare("pid_attitude", "pitch_kp", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "pitch-angle loop, deg/s per deg; P gain (stock 6)").persistent(),
    ParamEntry::declare("pid_attitude", "pitch_ki", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "pitch-angle loop, deg/s per deg; I gain (stock 3)").persistent(),
    ParamEntry::declare("pid_attitude", "pitch_kd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "pitch-angle loop, deg/s per deg; D gain (stock 0)").persistent(),
    ParamEntry::declare("pid_attitude", "yaw_kp", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "yaw-angle loop, deg/s per deg; P gain (stock 6)").persistent(),
    ParamEntry::declare("pid_attitude", "yaw_ki", ParamType::F32, 0, Range::Closed(0.0, 50.0), "", "yaw-angle loop, deg/s per deg; I gain (stock 1)").persistent(),
    ParamEntry::declare("pid_attitude", "yaw_kd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "yaw-angle loop, deg/s per deg; D gain (stock 0.35)").persistent(),
    ParamEntry::declare("velCtlPid", "vxKp", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; P gain (stock 25) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vxKi", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; I gain (stock 1) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vxKd", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "velocity loop, deg of tilt per m/s; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vyKp", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; P gain (stock 25) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vyKi", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "velocity loop, deg of tilt per m/s; I gain (stock 1) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vyKd", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "velocity loop, deg of tilt per m/s; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("velCtlPid", "vzKp", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "vertical-speed loop, thrust/1000 per m/s; P gain (stock 25)").persistent(),
    ParamEntry::declare("velCtlPid", "vzKi", ParamType::F32, 0, Range::Closed(0.0, 100.0), "", "vertical-speed loop, thrust/1000 per m/s; I gain (stock 15)").persistent(),
    ParamEntry::declare("velCtlPid", "vzKd", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "vertical-speed loop, thrust/1000 per m/s; D gain (stock 0)").persistent(),
    ParamEntry::declare("posCtlPid", "xKp", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; P gain (stock 2) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "xKi", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; I gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "xKd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "position loop, m/s per m; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "yKp", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; P gain (stock 2) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "yKi", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "position loop, m/s per m; I gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "yKd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "position loop, m/s per m; D gain (stock 0) (x and y share one horizontal gain in cfnav: writing either sets both)").persistent(),
    ParamEntry::declare("posCtlPid", "zKp", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "height loop, m/s per m (cfnav default 2/0/0.5, D on the measured vertical speed); P gain (stock 2)").persistent(),
    ParamEntry::declare("posCtlPid", "zKi", ParamType::F32, 0, Range::Closed(0.0, 20.0), "", "height loop, m/s per m (cfnav default 2/0/0.5, D on the measured vertical speed); I gain (stock 0.5)").persistent(),
    ParamEntry::declare("posCtlPid", "zKd", ParamType::F32, 0, Range::Closed(0.0, 10.0), "", "height loop, m/s per m (cfnav default 2/0/0.5, D on the measured vertical speed); D gain (stock 0)").persistent(),
    ParamEntry::declare("posCtlPid", "xVelMax", ParamType::F32, 0, Range::LeftOpen(0.0, 2.0), "m/s", "largest horizontal speed target (stock 1; cfnav: one limit for x and y)").persistent(),
    ParamEntry::declare("posCtlPid", "yVelMax", ParamType::F32, 0, Range::LeftOpen(0.0, 2.0), "m/s", "same value as xVelMax (one horizontal limit in cfnav)").persistent(),
    ParamEntry::declare("posCtlPid", "zVelMax", ParamType::F32, 0, Range::LeftOpen(0.0, 2.0), "m/s", "largest vertical speed target (stock 1)").persistent(),
    ParamEntry::declare("posCtlPid", "thrustBase", ParamType::U16, 0, Range::Closed(10000.0, 65000.0), "", "hover thrust feed-forward, counts (cfnav: the hover of 33 g, ~44200; stock 36000)").persistent(),
    ParamEntry::declare("posCtlPid", "thrustMin", ParamType::U16, 0, Range::Closed(0.0, 40000.0), "", "smallest collective thrust while flying, counts (stock 20000)").persistent(),
    ParamEntry::declare("motion", "flowStdFixed", ParamType::F32, 0, Range::Closed(0.1, 20.0), "", "flow measurement std, sensor counts (stock name and default 2.0)").persistent(),
    ParamEntry::declare("avoid", "mode", ParamType::U8, 0, SWITCH, "", "reactive avoidance law: 0 potential field, 1 virtual force field").persistent(),
    ParamEntry::declare("avoid", "clamp", ParamType::U8, 0, SWITCH, "", "speed clamp: 0 by the nearest range, 1 the speed towards each range").persistent(),
    ParamEntry::declare("avoid", "gain", ParamType::F32, 0, Range::Closed(0.0, 2.0), "m/s", "push-back speed per unit repulsion").persistent(),
    ParamEntry::declare("avoid", "dangerDist", ParamType::F32, 0, Range::Closed(0.05, 1.0), "m", "ranges closer than this repel (below slowDist)").persistent(),
    ParamEntry::declare("avoid", "slowDist", ParamType::F32, 0, Range::Closed(0.05, 2.0), "m", "ranges closer than this slow the drone (at least dangerDist)").persistent(),
    ParamEntry::declare("avoid", "minSpeed", ParamType::F32, 0, Range::Closed(0.0, 1.0), "m/s", "speed allowed at the danger distance (at most the avoidance cruise cap, 0.4)").persistent(),
    ParamEntry::declare("plan", "inflation", ParamType::F32, 0, Range::Closed(0.06, 0.5), "m", "obstacles grow by this for planning (drone radius 0.06 + margin)").persistent(),
    ParamEntry::declare("plan", "narrowInfl", ParamType::F32, 0, Range::Closed(0.06, 0.5), "m", "fallback inflation when no path exists (at most plan.inflation)").persistent(),
    ParamEntry::declare("plan", "narrowSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "speed cap while the narrow inflation is in use").persistent(),
    ParamEntry::declare("mission", "searchSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "speed along the pad search's sweep lines").persistent(),
    ParamEntry::declare("mission", "climbSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "take-off climb rate").persistent(),
    ParamEntry::declare("mission", "landSpeed", ParamType::F32, 0, Range::LeftOpen(0.0, 0.5), "m/s", "descent rate in the last 0.2 m of a landing (at most landSpeedHigh)").persistent(),
    ParamEntry::declare("mission", "landSpeedHigh", ParamType::F32, 0, Range::LeftOpen(0.0, 1.0), "m/s", "descent rate above 0.2 m").persistent(),
    ParamEntry::declare("mission", "goalTol", ParamType::F32, 0, Range::Closed(0.05, 1.0), "m", "distance to the goal at which the pad search begins").persistent(),
    ParamEntry::declare("mission", "padTol", ParamType::F32, 0, Range::Closed(0.01, 0.3), "m", "horizontal error to the pad centre accepted before descending").persistent(),
    ParamEntry::declare("mission", "padPause", ParamType::F32, 0, Range::Closed(0.0, 30.0), "s", "pause on the goal pad, motors off").persistent(),
    ParamEntry::declare("mission", "sweepSpacing", ParamType::F32, 0, Range::Closed(0.05, 0.5), "m", "spacing of the pad search's sweep lines").persistent(),
    ParamEntry::declare("mission", "batReserve", ParamType::F32, 0, Range::Closed(1.0, 5.0), "", "explore turns home once the battery, at the discharge rate measured in flight, no longer lasts this many times the flight home (planned path at cruise speed + 15 s for the pad search and landing)").persistent(),
    // Link loss
    ParamEntry::declare(
        "mission",
        "linkLoss",
        ParamType::U8,
        0,
        Range::Closed(0.0, 2.0),
        "",
        "after mission.linkTimeout s without any radio packet in a mission: 0 go on (default), 1 land where it is, 2 return home and land on the home pad",
    ),
    ParamEntry::declare(
        "mission",
        "linkTimeout",
        ParamType::F32,
        0,
        Range::Closed(MIN_LINK_TIMEOUT_S, MAX_LINK_TIMEOUT_S),
        "s",
        "radio silence that counts as a lost link during a mission (default 2)",
    ),
    // The build's revision (stock `version.tmpl`; values from git via build.rs, `crate::system::version`)
    ParamEntry::declare(
        "firmware",
        "revision0",
        ParamType::U32,
        RO,
        Range::Any,
        "",
        "the build's git commit, first 8 hex digits as a number (stock; cfclient shows it in hex)",
    ),
    ParamEntry::declare(
        "firmware",
        "revision1",
        ParamType::U16,
        RO,
        Range::Any,
        "",
        "the build's git commit, hex digits 9 to 12 as a number (stock)",
    ),
    ParamEntry::declare(
        "firmware",
        "modified",
        ParamType::U8,
        RO,
        SWITCH,
        "",
        "1 when the firmware's tracked sources differed from that commit at build time (stock)",
    ),
    // The room (appended: the ids above stay). Checked against the map's capacity with the other side in
    // effect; refused while a mission runs (the grid is shaped at the start).
    ParamEntry::declare("mission", "arenaX", ParamType::F32, 0, Range::Any, "m", "arena size along x, from the west wall (x = 0) to the east; the map must hold arenaX × arenaY").persistent(),
    ParamEntry::declare("mission", "arenaY", ParamType::F32, 0, Range::Any, "m", "arena size along y, from the south wall (y = 0) to the north; the map must hold arenaX × arenaY").persistent(),
    ParamEntry::declare("mission", "walls", ParamType::U8, 0, Range::Closed(0.0, 15.0), "", "which sides are walls: south (y = 0) 1, east 2, north 4, west (x = 0) 8; an open side is a geofence 0.3 m inside it").persistent(),
];

/// Id of `mission.start` (uint8).
pub const ID_START: u16 = param_id(PARAM_TABLE, "mission", "start");
/// Id of `mission.goalX` (float).
pub const ID_GOAL_X: u16 = param_id(PARAM_TABLE, "mission", "goalX");
/// Id of `mission.goalY` (float).
pub const ID_GOAL_Y: u16 = param_id(PARAM_TABLE, "mission", "goalY");
/// Id of `mission.startX` (float).
pub const ID_START_X: u16 = param_id(PARAM_TABLE, "mission", "startX");
/// Id of `mission.startY` (float).
pub const ID_START_Y: u16 = param_id(PARAM_TABLE, "mission", "startY");
/// Id of `mission.height` (float).
pub const ID_HEIGHT: u16 = param_id(PARAM_TABLE, "mission", "height");
/// Id of `mission.speed` (float).
pub const ID_SPEED: u16 = param_id(PARAM_TABLE, "mission", "speed");
/// Id of `deck.bcFlow2` (uint8, read-only).
pub const ID_DECK_FLOW2: u16 = param_id(PARAM_TABLE, "deck", "bcFlow2");
/// Id of `deck.bcMultiranger` (uint8, read-only).
pub const ID_DECK_MULTIRANGER: u16 = param_id(PARAM_TABLE, "deck", "bcMultiranger");
/// Id of `kalman.resetEstimation` (uint8).
pub const ID_RESET_ESTIMATION: u16 = param_id(PARAM_TABLE, "kalman", "resetEstimation");
/// Id of `stabilizer.controller` (uint8).
pub const ID_CONTROLLER: u16 = param_id(PARAM_TABLE, "stabilizer", "controller");
/// Id of `commander.enHighLevel` (uint8).
pub const ID_EN_HIGH_LEVEL: u16 = param_id(PARAM_TABLE, "commander", "enHighLevel");
/// Id of `mission.mode` (uint8: 0 round trip, 1 hover test, 2 explore).
pub const ID_MODE: u16 = param_id(PARAM_TABLE, "mission", "mode");
/// Id of `mission.hoverTime` (float, s).
pub const ID_HOVER_TIME: u16 = param_id(PARAM_TABLE, "mission", "hoverTime");
/// Id of `mission.coverage` (float, fraction).
pub const ID_COVERAGE: u16 = param_id(PARAM_TABLE, "mission", "coverage");
/// Id of `mission.linkLoss` (uint8).
pub const ID_LINK_LOSS: u16 = param_id(PARAM_TABLE, "mission", "linkLoss");
/// Id of `mission.linkTimeout` (float).
pub const ID_LINK_TIMEOUT: u16 = param_id(PARAM_TABLE, "mission", "linkTimeout");
/// Id of `firmware.revision0` (uint32, read-only).
pub const ID_FW_REVISION0: u16 = param_id(PARAM_TABLE, "firmware", "revision0");
/// Id of `firmware.revision1` (uint16, read-only).
pub const ID_FW_REVISION1: u16 = param_id(PARAM_TABLE, "firmware", "revision1");
/// Id of `firmware.modified` (uint8, read-only).
pub const ID_FW_MODIFIED: u16 = param_id(PARAM_TABLE, "firmware", "modified");
/// Id of `mission.arenaX` (float, m, persistent).
pub const ID_ARENA_X: u16 = param_id(PARAM_TABLE, "mission", "arenaX");
/// Id of `mission.arenaY` (float, m, persistent).
pub const ID_ARENA_Y: u16 = param_id(PARAM_TABLE, "mission", "arenaY");
/// Id of `mission.walls` (uint8 bitmask, persistent).
pub const ID_WALLS: u16 = param_id(PARAM_TABLE, "mission", "walls");
