//! The one log table the firmware and the simulator serve: the docs/radio.md variables with their ids
//! unchanged, then the CPU-load and loop-timing variables, then the stock names cfclient logs; values by id in
//! the stock units and signs; the TOC the log service serves from it (count and CRC).

use cfnav::flight::control::ControlOutput;
use cfnav::radio::crtp::{CrtpPacket, Service};
use cfnav::radio::log::{LogService, PORT_LOG};
use cfnav::radio::log_decl::{LOG_CRC_SEED, LogSource, LogType, LogValue, log_toc_crc};
use cfnav::radio_binding::log_table::{
    FirmwareLogState, FlightLogState, ID_CPU_LOAD_PCT, ID_LOOP_JITTER_US, ID_LOOP_RATE_HZ, ID_LOOP_STEP_MAX_US,
    ID_MISSION_LOAD_PCT, ID_VBAT, ID_X, LOG_TABLE, battery_level_pct,
};
use cfnav::types::{Setpoint, StateEstimate};

fn id(group: &str, name: &str) -> u16 {
    LOG_TABLE
        .iter()
        .position(|e| e.group == group && e.name == name)
        .unwrap_or_else(|| panic!("{group}.{name} missing")) as u16
}

fn f(s: &impl LogSource, group: &str, name: &str) -> f32 {
    match s.value(id(group, name)) {
        Some(LogValue::F32(v)) => v,
        other => panic!("{group}.{name}: {other:?}"),
    }
}

#[test]
fn the_load_variables_keep_their_ids() {
    let names: Vec<(&str, &str, LogType)> = LOG_TABLE[11..18].iter().map(|e| (e.group, e.name, e.ty)).collect();
    assert_eq!(
        names,
        vec![
            ("cfnav", "cpuLoadPct", LogType::U8),
            ("cfnav", "ctrlLoadPct", LogType::U8),
            ("cfnav", "ioLoadPct", LogType::U8),
            ("cfnav", "missionLoadPct", LogType::U8),
            ("cfnav", "loopJitterUs", LogType::U16),
            ("cfnav", "loopStepMaxUs", LogType::U16),
            ("cfnav", "loopRateHz", LogType::U16),
        ]
    );
}

/// Every variable the stock cfclient 2026.8.1 puts in a log block (`ui/main.py` battery block,
/// `ui/tabs/FlightTab.py` motors block, `ui/pose_logger.py`, the shipped `configs/log/**/*.json` Plotter
/// blocks), with the stock firmware's storage type (`LOG_ADD` lines of `bitcraze/crazyflie-firmware`).
const CFCLIENT_LOG_VARIABLES: &[(&str, &str, LogType)] = &[
    ("pm", "vbat", LogType::F32),
    ("pm", "state", LogType::I8),
    ("pm", "batteryLevel", LogType::U8),
    ("stabilizer", "thrust", LogType::F32),
    ("stabilizer", "roll", LogType::F32),
    ("stabilizer", "pitch", LogType::F32),
    ("stabilizer", "yaw", LogType::F32),
    ("motor", "m1", LogType::U16),
    ("motor", "m2", LogType::U16),
    ("motor", "m3", LogType::U16),
    ("motor", "m4", LogType::U16),
    ("sys", "canfly", LogType::U8),
    ("supervisor", "info", LogType::U16),
    ("stateEstimate", "x", LogType::F32),
    ("stateEstimate", "y", LogType::F32),
    ("stateEstimate", "z", LogType::F32),
    ("stateEstimate", "vx", LogType::F32),
    ("stateEstimate", "vy", LogType::F32),
    ("stateEstimate", "vz", LogType::F32),
    ("stateEstimate", "roll", LogType::F32),
    ("stateEstimate", "pitch", LogType::F32),
    ("stateEstimate", "yaw", LogType::F32),
    ("gyro", "x", LogType::F32),
    ("gyro", "y", LogType::F32),
    ("gyro", "z", LogType::F32),
    ("controller", "roll", LogType::F32),
    ("controller", "pitch", LogType::F32),
    ("controller", "yaw", LogType::F32),
    ("controller", "rollRate", LogType::F32),
    ("controller", "pitchRate", LogType::F32),
    ("controller", "yawRate", LogType::F32),
    ("posCtl", "targetVX", LogType::F32),
    ("posCtl", "targetVY", LogType::F32),
    ("posCtl", "targetVZ", LogType::F32),
    ("posCtl", "targetX", LogType::F32),
    ("posCtl", "targetY", LogType::F32),
    ("posCtl", "targetZ", LogType::F32),
];

#[test]
fn every_variable_cfclient_logs_exists_with_the_stock_type() {
    for &(g, n, ty) in CFCLIENT_LOG_VARIABLES {
        let e = &LOG_TABLE[usize::from(id(g, n))];
        assert_eq!(e.ty, ty, "{g}.{n}");
    }
    // No name twice.
    for (i, a) in LOG_TABLE.iter().enumerate() {
        for b in &LOG_TABLE[i + 1..] {
            assert!(
                !(a.group == b.group && a.name == b.name),
                "{}.{} twice",
                a.group,
                a.name
            );
        }
    }
}

#[test]
fn values_by_id() {
    let s = FirmwareLogState {
        flight: FlightLogState {
            mission_state: 3,
            position_m: [1.0, 2.0, 0.5],
            ranges_mm: [1, 2, 3, 4, 5, 6],
            vbat_v: 3.9,
            ..FlightLogState::default()
        },
        load_pct: [40, 12, 8, 20],
        loop_jitter_us: 7,
        loop_step_max_us: 85,
        loop_rate_hz: 1000,
    };
    assert_eq!(s.value(ID_X), Some(LogValue::F32(1.0)));
    assert_eq!(s.value(ID_VBAT), Some(LogValue::F32(3.9)));
    assert_eq!(s.value(ID_CPU_LOAD_PCT), Some(LogValue::U8(40)));
    assert_eq!(s.value(ID_MISSION_LOAD_PCT), Some(LogValue::U8(20)));
    assert_eq!(s.value(ID_LOOP_JITTER_US), Some(LogValue::U16(7)));
    assert_eq!(s.value(ID_LOOP_STEP_MAX_US), Some(LogValue::U16(85)));
    assert_eq!(s.value(ID_LOOP_RATE_HZ), Some(LogValue::U16(1000)));
    assert_eq!(s.value(LOG_TABLE.len() as u16), None);
    // Every id of the table has a value whose type is the table's.
    for (i, e) in LOG_TABLE.iter().enumerate() {
        let v = s
            .value(i as u16)
            .unwrap_or_else(|| panic!("{}.{} has no value", e.group, e.name));
        let ty = match v {
            LogValue::U8(_) => LogType::U8,
            LogValue::I8(_) => LogType::I8,
            LogValue::U16(_) => LogType::U16,
            LogValue::F32(_) => LogType::F32,
            other => panic!("unexpected {other:?}"),
        };
        assert_eq!(ty, e.ty, "{}.{}", e.group, e.name);
    }
}

#[test]
fn the_flight_readouts_are_logged_in_stock_units_and_signs() {
    let estimate = StateEstimate {
        position_m: [1.5, 2.5, 0.4],
        velocity_m_s: [0.1, -0.2, 0.3],
        // cfnav: positive pitch = nose down; stock exports pitch with the opposite sign (kalman_core.c).
        attitude_rad: [0.1, 0.2, -0.3],
        rates_rad_s: [1.0, -0.5, 0.25],
        ..StateEstimate::default()
    };
    let control = ControlOutput {
        motor_ratio: [100, 200, 300, 400],
        collective: 30000.0,
        attitude_target_rad: [0.05, 0.1, 0.0],
        rate_target_rad_s: [0.5, 0.0, -0.5],
        velocity_target_m_s: [0.3, 0.0, 0.0],
        ..ControlOutput::default()
    };
    let setpoint = Setpoint::Position {
        x_m: 3.0,
        y_m: 1.0,
        z_m: 0.5,
        yaw_rad: 0.0,
    };
    let mut s = FlightLogState {
        vbat_v: 3.90,
        supervisor_info: 0b1_1010, // armed, can fly, flying
        ..FlightLogState::default()
    };
    s.record_flight(&estimate, &control, &setpoint);
    let close = |a: f32, b: f32| (a - b).abs() < 1e-4;
    assert!(close(f(&s, "stateEstimate", "roll"), 0.1f32.to_degrees()));
    assert!(close(f(&s, "stateEstimate", "pitch"), -(0.2f32.to_degrees())));
    assert!(close(f(&s, "stateEstimate", "yaw"), -(0.3f32.to_degrees())));
    assert!(close(f(&s, "stabilizer", "pitch"), -(0.2f32.to_degrees())));
    assert!(close(f(&s, "stateEstimate", "vy"), -0.2));
    assert!(
        close(f(&s, "gyro", "y"), -(0.5f32.to_degrees())),
        "body rates keep their sign"
    );
    assert!(close(f(&s, "controller", "pitch"), -(0.1f32.to_degrees())));
    assert!(close(f(&s, "controller", "yawRate"), -(0.5f32.to_degrees())));
    assert!(close(f(&s, "stabilizer", "thrust"), 30000.0));
    assert!(close(f(&s, "posCtl", "targetX"), 3.0));
    assert!(close(f(&s, "posCtl", "targetVX"), 0.3));
    assert_eq!(s.value(id("motor", "m3")), Some(LogValue::U16(300)));
    assert_eq!(s.value(id("sys", "canfly")), Some(LogValue::U8(1)));
    assert_eq!(s.value(id("supervisor", "info")), Some(LogValue::U16(0b1_1010)));
    assert_eq!(s.value(id("pm", "state")), Some(LogValue::I8(0)));
    s.battery_low = true;
    s.supervisor_info = 0;
    assert_eq!(s.value(id("pm", "state")), Some(LogValue::I8(3)), "stock lowPower");
    assert_eq!(s.value(id("sys", "canfly")), Some(LogValue::U8(0)));
    // Not a position setpoint: the target is the estimate.
    s.record_flight(&estimate, &control, &Setpoint::Stop);
    assert!(close(f(&s, "posCtl", "targetX"), 1.5));
}

#[test]
fn battery_level_follows_the_stock_charge_curve() {
    // pm_stm32f4.c: LiPoTypicalChargeCurve {3.00, 3.78, 3.83, 3.87, 3.89, 3.92, 3.96, 4.00, 4.04, 4.10},
    // level = 10 × the first index whose voltage is not below the battery's, 0 below 3.00 V, 90 above 4.10 V.
    let cases = [
        (2.5, 0),
        (3.0, 0),
        (3.5, 10),
        (3.78, 10),
        (3.80, 20),
        (3.90, 50),
        (4.00, 70),
        (4.05, 90),
        (4.2, 90),
        (f32::NAN, 0),
    ];
    for (v, want) in cases {
        assert_eq!(battery_level_pct(v), want, "{v} V");
    }
}

#[test]
fn the_toc_info_counts_every_variable_and_its_crc_is_the_tables() {
    let mut log: LogService<FirmwareLogState> = LogService::new();
    let reply = log.handle(&CrtpPacket::new(PORT_LOG, 0, &[0x03]).unwrap()).unwrap();
    let count = u16::from_le_bytes([reply.data[1], reply.data[2]]);
    let crc = u32::from_le_bytes([reply.data[3], reply.data[4], reply.data[5], reply.data[6]]);
    assert_eq!(usize::from(count), LOG_TABLE.len());
    assert_eq!(crc, log_toc_crc(LOG_TABLE));
    assert_ne!(crc, log_toc_crc(&LOG_TABLE[..11]), "cflib caches the TOC by CRC");
    assert!(!LOG_CRC_SEED.is_empty());
}
