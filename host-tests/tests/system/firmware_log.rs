//! The firmware's log table: the interfaces.md §5 variables with their ids unchanged, then the CPU-load and
//! loop-timing variables; values by id; the TOC the log service serves from it (count and CRC).

use cfnav::radio::crtp::{CrtpPacket, Service};
use cfnav::radio::log::{LogService, PORT_LOG};
use cfnav::radio::log_registry::{
    FIRMWARE_LOG_TABLE, FLIGHT_LOG_TABLE, FirmwareLogState, FlightLogState, ID_CPU_LOAD_PCT, ID_LOOP_JITTER_US,
    ID_LOOP_RATE_HZ, ID_LOOP_STEP_MAX_US, ID_MISSION_LOAD_PCT, ID_VBAT, ID_X, LOG_CRC_SEED, LogSource, LogType,
    LogValue, log_toc_crc,
};

#[test]
fn the_flight_variables_keep_their_ids() {
    assert_eq!(&FIRMWARE_LOG_TABLE[..FLIGHT_LOG_TABLE.len()], FLIGHT_LOG_TABLE);
    let names: Vec<(&str, &str, LogType)> = FIRMWARE_LOG_TABLE[FLIGHT_LOG_TABLE.len()..]
        .iter()
        .map(|e| (e.group, e.name, e.ty))
        .collect();
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

#[test]
fn values_by_id() {
    let s = FirmwareLogState {
        flight: FlightLogState {
            mission_state: 3,
            position_m: [1.0, 2.0, 0.5],
            ranges_mm: [1, 2, 3, 4, 5, 6],
            vbat_v: 3.9,
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
    assert_eq!(s.value(ID_LOOP_RATE_HZ + 1), None);
    // Every id of the table has a value whose type is the table's.
    for (id, e) in FIRMWARE_LOG_TABLE.iter().enumerate() {
        let v = s.value(id as u16).unwrap();
        let ty = match v {
            LogValue::U8(_) => LogType::U8,
            LogValue::U16(_) => LogType::U16,
            LogValue::F32(_) => LogType::F32,
            other => panic!("unexpected {other:?}"),
        };
        assert_eq!(ty, e.ty, "{}.{}", e.group, e.name);
    }
}

#[test]
fn the_toc_info_counts_every_variable_and_its_crc_differs_from_the_flight_table() {
    let mut log: LogService<FirmwareLogState> = LogService::new();
    let reply = log.handle(&CrtpPacket::new(PORT_LOG, 0, &[0x03]).unwrap()).unwrap();
    let count = u16::from_le_bytes([reply.data[1], reply.data[2]]);
    let crc = u32::from_le_bytes([reply.data[3], reply.data[4], reply.data[5], reply.data[6]]);
    assert_eq!(usize::from(count), FIRMWARE_LOG_TABLE.len());
    assert_eq!(crc, log_toc_crc(FIRMWARE_LOG_TABLE));
    assert_ne!(crc, log_toc_crc(FLIGHT_LOG_TABLE), "cflib caches the TOC by CRC");
    assert!(!LOG_CRC_SEED.is_empty());
}
