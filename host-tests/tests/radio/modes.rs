//! The mission-mode parameters (`mission.mode`, `.hoverTime`, `.coverage`) over the
//! parameter service: declared ranges, the refusal of any change while a mission runs (the echo carries the
//! value in effect, the state is unchanged, a console line says why), the defaults, and what a start passes
//! on to the mission.

use super::param::{assert_refused, service, write_f32};
use super::send;
use cfnav::mission::{MissionMode, MissionParams};
use cfnav::radio::param_decl::{ParamStore, Refusal};
use cfnav::radio::toc::Value;
use cfnav::radio_binding::param_table::{ID_COVERAGE, ID_HOVER_TIME, ID_MODE, ID_START};

fn write_u8(id: u16, v: u8) -> Vec<u8> {
    let mut out = vec![0x2E];
    out.extend_from_slice(&id.to_le_bytes());
    out.push(v);
    out
}

#[test]
fn defaults_are_the_round_trip_five_seconds_and_80_percent() {
    let m = service();
    assert_eq!(m.store().read(ID_MODE), Some(Value::U8(0)));
    assert_eq!(m.store().read(ID_HOVER_TIME), Some(Value::F32(5.0)));
    assert_eq!(m.store().read(ID_COVERAGE), Some(Value::F32(0.8)));
    assert_eq!(m.store().default_value(ID_MODE), Some(Value::U8(0)));
    assert_eq!(MissionParams::SEED.mode, MissionMode::RoundTrip);
}

#[test]
fn each_mode_is_accepted_on_the_ground_and_reaches_the_start() {
    let mut m = service();
    for (code, mode) in [
        (1, MissionMode::HoverTest),
        (2, MissionMode::Explore),
        (0, MissionMode::RoundTrip),
    ] {
        let req = write_u8(ID_MODE, code);
        assert_eq!(send(&mut m, &req), Some(req));
        assert_eq!(m.store().params.mode, mode);
        assert_eq!(MissionMode::from_code(code), Some(mode));
    }
    let req = write_f32(ID_HOVER_TIME, 12.5);
    assert_eq!(send(&mut m, &req), Some(req));
    let req = write_f32(ID_COVERAGE, 0.6);
    assert_eq!(send(&mut m, &req), Some(req));
    assert_eq!(
        (m.store().params.hover_time_s, m.store().params.coverage_target),
        (12.5, 0.6)
    );
    assert!(m.take_refusal().is_none());
}

#[test]
fn values_outside_the_declared_ranges_are_refused() {
    let mut m = service();
    let line = "param mission.mode refused: not in [0, 2]\n";
    assert_refused(&mut m, &write_u8(ID_MODE, 3), Refusal::OutOfRange, line);
    assert_refused(&mut m, &write_u8(ID_MODE, 255), Refusal::OutOfRange, line);
    let line = "param mission.hoverTime refused: not in [1, 60] s\n";
    assert_refused(&mut m, &write_f32(ID_HOVER_TIME, 0.5), Refusal::OutOfRange, line);
    assert_refused(&mut m, &write_f32(ID_HOVER_TIME, 61.0), Refusal::OutOfRange, line);
    assert_refused(&mut m, &write_f32(ID_HOVER_TIME, f32::NAN), Refusal::OutOfRange, line);
    let line = "param mission.coverage refused: not in [0.05, 1]\n";
    assert_refused(&mut m, &write_f32(ID_COVERAGE, 0.0), Refusal::OutOfRange, line);
    assert_refused(&mut m, &write_f32(ID_COVERAGE, 1.5), Refusal::OutOfRange, line);
}

#[test]
fn mode_changes_are_refused_while_a_mission_runs() {
    let mut m = service();
    let req = write_u8(ID_MODE, 1);
    assert_eq!(send(&mut m, &req), Some(req));
    let start = write_u8(ID_START, 1);
    assert_eq!(send(&mut m, &start), Some(start));
    let line = "param mission.mode refused: mission already running\n";
    assert_refused(&mut m, &write_u8(ID_MODE, 2), Refusal::AlreadyRunning, line);
    assert_refused(&mut m, &write_u8(ID_MODE, 0), Refusal::AlreadyRunning, line);
    let line = "param mission.hoverTime refused: mission already running\n";
    assert_refused(&mut m, &write_f32(ID_HOVER_TIME, 9.0), Refusal::AlreadyRunning, line);
    let line = "param mission.coverage refused: mission already running\n";
    assert_refused(&mut m, &write_f32(ID_COVERAGE, 0.5), Refusal::AlreadyRunning, line);
    assert_eq!(m.store().params.mode, MissionMode::HoverTest);
    // Once the mission has ended (the firmware writes start back to 0) the mode can change again.
    m.store_mut().start = 0;
    let req = write_u8(ID_MODE, 2);
    assert_eq!(send(&mut m, &req), Some(req));
    assert_eq!(m.store().params.mode, MissionMode::Explore);
}

#[test]
fn a_start_refuses_mode_settings_outside_their_ranges() {
    // The declarations bound the radio writes; a start also checks the whole set (a direct caller).
    let params = MissionParams {
        hover_time_s: 0.0,
        ..MissionParams::SEED
    };
    assert_eq!(
        params.validate(128 * 64),
        Err(cfnav::mission::StartRefusal::BadModeSetting)
    );
    let params = MissionParams {
        coverage_target: f32::NAN,
        ..MissionParams::SEED
    };
    assert_eq!(
        params.validate(128 * 64),
        Err(cfnav::mission::StartRefusal::BadModeSetting)
    );
    assert!(MissionParams::SEED.validate(128 * 64).is_ok());
}

#[test]
fn generated_mode_table_is_the_declaration() {
    let page = super::stock::generated_section("docs/mission.md", "mode table", "src/mission");
    let mut table = String::new();
    cfnav::mission::write_mode_table(&mut table).unwrap();
    assert!(
        page == table,
        "docs/mission.md's mode table differs from the declaration; paste this between its markers:\n{table}"
    );
    // Every mode the parameter's declared range admits has a row, and no other.
    let e = cfnav::radio_binding::param_table::PARAM_TABLE
        .iter()
        .find(|e| e.group == "mission" && e.name == "mode")
        .unwrap();
    for code in 0..=u8::MAX {
        assert_eq!(
            e.check(Value::U8(code)).is_ok(),
            MissionMode::from_code(code).is_some(),
            "mode {code}"
        );
    }
}
