//! The tuning parameters and the persistent-parameter commands: writes land in the
//! flight configuration they name, bad ones are refused with a console line and change nothing; misc 3/4/5
//! answer byte for byte as stock `param_logic.c` (and cflib `param.py` decodes), with the EEPROM write done
//! by the caller before the answer; stored values come back at boot through the radio's checks.

use super::send;
use cfnav::flight::control::{Controller, ControllerConfig};
use cfnav::mission::MissionParams;
use cfnav::nav::avoidance::AvoidanceMethod;
use cfnav::radio::param::{EBUSY, EIO, ENOENT, ENOSPC, ParamService};
use cfnav::radio::param_decl::{ParamStore, ParamType, Refusal};
use cfnav::radio::toc::Value;
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::{ID_GOAL_X, PARAM_TABLE};
use cfnav::radio_binding::tuning::{Tuning, tune_field};
use cfnav::system::persistent_params::{MAX_RECORDS, PersistentParams, SLOT_LEN, param_key};

type Svc = ParamService<MissionParamState>;

fn service() -> Svc {
    ParamService::new(MissionParamState::new(MissionParams::SEED, 128 * 64))
}

fn id(group: &str, name: &str) -> u16 {
    Svc::find(group, name).unwrap_or_else(|| panic!("{group}.{name} missing"))
}

/// A float write on port 2 channel 2: `[hdr, id u16, value]`.
fn write_f32(s: &mut Svc, id: u16, v: f32) -> Option<Vec<u8>> {
    let mut b = vec![0x2E];
    b.extend_from_slice(&id.to_le_bytes());
    b.extend_from_slice(&v.to_le_bytes());
    send(s, &b)
}

fn write_u8(s: &mut Svc, id: u16, v: u8) -> Option<Vec<u8>> {
    let mut b = vec![0x2E];
    b.extend_from_slice(&id.to_le_bytes());
    b.push(v);
    send(s, &b)
}

/// A misc command `[hdr, cmd, id u16]` on port 2 channel 3.
fn misc(s: &mut Svc, cmd: u8, id: u16) -> Option<Vec<u8>> {
    let b = id.to_le_bytes();
    send(s, &[0x2F, cmd, b[0], b[1]])
}

/// The EEPROM a test keeps: the service's pending write is copied in (or fails).
fn finish_write(s: &mut Svc, eeprom: &mut [u8], ok: bool) -> Vec<u8> {
    let w = *s.eeprom_write().expect("a write waits");
    if ok {
        let at = usize::from(w.address()) - 0x400;
        eeprom[at..at + SLOT_LEN].copy_from_slice(w.bytes());
    }
    let reply = s.eeprom_write_done(ok).unwrap();
    super::wire(&reply)
}

#[test]
fn every_tuning_parameter_maps_to_one_field_is_persistent_and_reads_its_default() {
    let s = service();
    let mut n = 0;
    for (i, e) in PARAM_TABLE.iter().enumerate() {
        let mut t = Tuning::default();
        if tune_field(&mut t, e.group, e.name).is_none() {
            continue;
        }
        n += 1;
        assert!(e.is_persistent(), "{}.{}", e.group, e.name);
        assert!(!e.read_only());
        assert!(!e.doc.is_empty());
        let id = i as u16;
        // The default (power-on) value lies in the declared range and equals the value in effect.
        let v = s.store().read(id).unwrap();
        assert!(
            e.range.contains(v),
            "{}.{} default {v:?} outside {}",
            e.group,
            e.name,
            e.range
        );
        assert_eq!(s.store().default_value(id), Some(v));
    }
    assert!(n >= 50, "{n} tuning parameters");
    assert!(n <= MAX_RECORDS, "every tuning parameter must fit the store at once");
    // Keys are unique over the whole table (a collision would apply one parameter's value to another).
    let mut keys: Vec<u32> = PARAM_TABLE.iter().map(|e| param_key(e.group, e.name)).collect();
    keys.sort_unstable();
    keys.dedup();
    assert_eq!(keys.len(), PARAM_TABLE.len());
}

#[test]
fn stock_names_have_stock_types() {
    // From attitude_pid_controller.c, position_controller_pid.c and flowdeck_v1v2.c (PARAM_ADD lines).
    for (g, n, ty) in [
        ("pid_rate", "roll_kp", ParamType::F32),
        ("pid_rate", "yaw_kd", ParamType::F32),
        ("pid_attitude", "pitch_ki", ParamType::F32),
        ("velCtlPid", "vzKp", ParamType::F32),
        ("posCtlPid", "xKp", ParamType::F32),
        ("posCtlPid", "zKd", ParamType::F32),
        ("posCtlPid", "thrustBase", ParamType::U16),
        ("posCtlPid", "thrustMin", ParamType::U16),
        ("posCtlPid", "xVelMax", ParamType::F32),
        ("motion", "flowStdFixed", ParamType::F32),
    ] {
        assert_eq!(Svc::entry(id(g, n)).unwrap().ty, ty, "{g}.{n}");
    }
}

#[test]
fn a_gain_write_lands_in_the_controller_config_and_the_flight_stack_applies_it() {
    let mut s = service();
    let generation = s.store().tuning_generation;
    let reply = write_f32(&mut s, id("pid_rate", "roll_kp"), 180.0).unwrap();
    assert_eq!(&reply[3..], &180f32.to_le_bytes());
    let t = s.store().tuning;
    assert_eq!(t.controller.roll_rate.kp, 180.0);
    assert_eq!(t.controller.pitch_rate.kp, ControllerConfig::default().pitch_rate.kp);
    assert_ne!(s.store().tuning_generation, generation);
    // The default cfclient shows stays the power-on one.
    assert_eq!(
        s.store().default_value(id("pid_rate", "roll_kp")),
        Some(Value::F32(250.0))
    );
    // The controller takes the new gains in place.
    let mut c = Controller::new(ControllerConfig::default()).unwrap();
    c.set_config(t.controller).unwrap();
    assert_eq!(c.config().roll_rate.kp, 180.0);
    // Integer and enum-like fields.
    write_u8(&mut s, id("avoid", "mode"), 1).unwrap();
    assert_eq!(
        s.store().tuning.mission.avoidance.method,
        AvoidanceMethod::VirtualForceField
    );
    let mut b = vec![0x2E];
    b.extend_from_slice(&id("posCtlPid", "thrustBase").to_le_bytes());
    b.extend_from_slice(&40000u16.to_le_bytes());
    send(&mut s, &b).unwrap();
    assert_eq!(s.store().tuning.controller.thrust_base, 40000.0);
    write_f32(&mut s, id("motion", "flowStdFixed"), 3.5).unwrap();
    assert_eq!(s.store().tuning.flow_std_counts, 3.5);
    write_f32(&mut s, id("plan", "inflation"), 0.3).unwrap();
    assert_eq!(s.store().tuning.mission.inflation_radius_m, 0.3);
}

#[test]
fn out_of_range_and_inconsistent_tuning_writes_are_refused_with_a_console_line_and_change_nothing() {
    let mut s = service();
    let before = s.store().tuning;
    for (g, n, v) in [
        ("pid_rate", "roll_kp", -1.0),
        ("pid_rate", "roll_kp", f32::NAN),
        ("pid_attitude", "yaw_kd", 1e6),
        ("posCtlPid", "xVelMax", 0.0),
        ("plan", "inflation", 0.01),
    ] {
        let reply = write_f32(&mut s, id(g, n), v).unwrap();
        let note = s.take_refusal().unwrap();
        assert_eq!(note.refusal, Refusal::OutOfRange, "{g}.{n} = {v}");
        let line = Svc::console_line(&note);
        assert!(line.starts_with(&format!("param {g}.{n} refused: not in ")), "{line}");
        // The echo carries the value in effect.
        assert_eq!(Value::from_le(ParamType::F32, &reply[3..]), s.store().read(id(g, n)));
    }
    // In range, but against a related setting.
    for (g, n, v) in [
        ("avoid", "slowDist", 0.1),     // below dangerDist 0.2
        ("plan", "narrowInfl", 0.4),    // above inflation 0.25
        ("mission", "landSpeed", 0.45), // above landSpeedHigh 0.4
        ("avoid", "minSpeed", 0.9),     // above the avoidance cruise cap 0.4
    ] {
        write_f32(&mut s, id(g, n), v).unwrap();
        let note = s.take_refusal().unwrap();
        assert_eq!(note.refusal, Refusal::Inconsistent, "{g}.{n} = {v}");
        assert!(Svc::console_line(&note).contains("inconsistent with others"));
    }
    assert_eq!(s.store().tuning, before);
    assert_eq!(s.store().tuning_generation, 0);
}

#[test]
fn one_gain_behind_two_stock_names_reads_the_same_and_notifies_the_other() {
    let mut s = service();
    write_f32(&mut s, id("posCtlPid", "xKp"), 3.0).unwrap();
    assert_eq!(s.store().read(id("posCtlPid", "yKp")), Some(Value::F32(3.0)));
    let p = s.next_notification().expect("VALUE_UPDATED for yKp");
    let y = id("posCtlPid", "yKp").to_le_bytes();
    assert_eq!(&p.data[..3], &[1, y[0], y[1]]);
    assert_eq!(&p.data[3..], &3f32.to_le_bytes());
    assert!(s.next_notification().is_none());
    // A parameter with no alias notifies nothing.
    write_f32(&mut s, id("posCtlPid", "zKp"), 2.5).unwrap();
    assert!(s.next_notification().is_none());
}

#[test]
fn extended_type_marks_the_tuning_parameters_persistent_and_no_other() {
    let mut s = service();
    let kp = id("pid_rate", "roll_kp");
    let b = kp.to_le_bytes();
    assert_eq!(misc(&mut s, 7, kp).unwrap(), vec![0x2F, 7, b[0], b[1], 0, 1]);
    let g = ID_GOAL_X.to_le_bytes();
    assert_eq!(misc(&mut s, 7, ID_GOAL_X).unwrap(), vec![0x2F, 7, g[0], g[1], 0, 0]);
}

#[test]
fn store_get_state_clear_round_trip_byte_for_byte() {
    let mut s = service();
    let mut eeprom = vec![0xFFu8; 2 * SLOT_LEN];
    let kp = id("pid_rate", "roll_kp");
    let b = kp.to_le_bytes();
    let default = 250f32.to_le_bytes();
    // Nothing stored: [4, id, 0, default].
    let mut want = vec![0x2F, 4, b[0], b[1], 0];
    want.extend_from_slice(&default);
    assert_eq!(misc(&mut s, 4, kp).unwrap(), want);
    // Set, store: no answer until the EEPROM write is done, then [3, id, 0].
    write_f32(&mut s, kp, 200.0).unwrap();
    assert_eq!(misc(&mut s, 3, kp), None);
    // A second persistent command while the write is under way: EBUSY.
    assert_eq!(misc(&mut s, 5, kp).unwrap(), vec![0x2F, 5, b[0], b[1], EBUSY]);
    assert_eq!(finish_write(&mut s, &mut eeprom, true), vec![0x2F, 3, b[0], b[1], 0]);
    // Stored: [4, id, 1, default, stored]; cflib unpacks '<ff' from data[4:].
    let mut want = vec![0x2F, 4, b[0], b[1], 1];
    want.extend_from_slice(&default);
    want.extend_from_slice(&200f32.to_le_bytes());
    assert_eq!(misc(&mut s, 4, kp).unwrap(), want);
    // The EEPROM now holds it: a reboot reads it back.
    let (stored, _) = PersistentParams::load(&eeprom);
    let mut rebooted = service();
    let summary = rebooted.load_persistent(stored);
    assert_eq!((summary.applied, summary.unknown, summary.refused), (1, 0, 0));
    assert_eq!(rebooted.store().tuning.controller.roll_rate.kp, 200.0);
    assert_eq!(rebooted.store().read(kp), Some(Value::F32(200.0)));
    assert_eq!(misc(&mut rebooted, 4, kp).unwrap(), want);
    // Clear: [5, id, 0] after the write; then not stored, and a reboot keeps the default.
    assert_eq!(misc(&mut rebooted, 5, kp), None);
    assert_eq!(
        finish_write(&mut rebooted, &mut eeprom, true),
        vec![0x2F, 5, b[0], b[1], 0]
    );
    let mut want = vec![0x2F, 4, b[0], b[1], 0];
    want.extend_from_slice(&default);
    assert_eq!(misc(&mut rebooted, 4, kp).unwrap(), want);
    let mut again = service();
    again.load_persistent(PersistentParams::load(&eeprom).0);
    assert_eq!(again.store().tuning.controller.roll_rate.kp, 250.0);
    // Clearing what is not stored: success at once, no write.
    assert_eq!(misc(&mut again, 5, kp).unwrap(), vec![0x2F, 5, b[0], b[1], 0]);
    assert!(again.eeprom_write().is_none());
}

#[test]
fn persistent_refusals_unknown_not_persistent_failed_write_and_full_store() {
    let mut s = service();
    // Unknown id and a parameter that is not persistent: ENOENT (stock), nothing to write.
    assert_eq!(misc(&mut s, 3, 0xFFFF).unwrap(), vec![0x2F, 3, 0xFF, 0xFF, ENOENT]);
    assert_eq!(misc(&mut s, 4, 0xFFFF).unwrap(), vec![0x2F, 4, 0xFF, 0xFF, ENOENT]);
    let g = ID_GOAL_X.to_le_bytes();
    assert_eq!(misc(&mut s, 3, ID_GOAL_X).unwrap(), vec![0x2F, 3, g[0], g[1], ENOENT]);
    assert!(s.eeprom_write().is_none());
    // A truncated command gets no answer.
    assert_eq!(send(&mut s, &[0x2F, 3, 1]), None);
    // A failed EEPROM write: EIO, nothing stored.
    let kp = id("pid_rate", "roll_kp");
    let b = kp.to_le_bytes();
    assert_eq!(misc(&mut s, 3, kp), None);
    let mut eeprom = vec![0xFFu8; 2 * SLOT_LEN];
    assert_eq!(finish_write(&mut s, &mut eeprom, false), vec![0x2F, 3, b[0], b[1], EIO]);
    assert_eq!(s.store().stored_value(kp), None);
    assert!(s.store().persistent.is_empty());
    // While flying: EBUSY and a console line, nothing to write.
    s.store_mut().flying = true;
    assert_eq!(misc(&mut s, 3, kp).unwrap(), vec![0x2F, 3, b[0], b[1], EBUSY]);
    assert_eq!(misc(&mut s, 5, kp).unwrap(), vec![0x2F, 5, b[0], b[1], EBUSY]);
    assert!(s.eeprom_write().is_none());
    assert_eq!(
        Svc::console_line(&s.take_refusal().unwrap()).as_str(),
        "param pid_rate.roll_kp refused: not while flying\n"
    );
    // Full: every record taken by other keys, a new one is refused with ENOSPC and a console line.
    let mut full = PersistentParams::empty();
    for i in 0..MAX_RECORDS as u32 {
        let w = full.prepare_store(0x1000 + i, 0x08, [0; 4]).unwrap();
        full.commit(w);
    }
    let mut s = service();
    s.load_persistent(full);
    assert_eq!(misc(&mut s, 3, kp).unwrap(), vec![0x2F, 3, b[0], b[1], ENOSPC]);
    let note = s.take_refusal().unwrap();
    assert_eq!(note.refusal, Refusal::StoreFull);
    assert_eq!(
        Svc::console_line(&note).as_str(),
        "param pid_rate.roll_kp refused: persistent store full\n"
    );
}

#[test]
fn stored_values_are_applied_at_boot_through_the_radio_checks() {
    let rec = |g: &str, n: &str, ty: u8, v: [u8; 4]| (param_key(g, n), ty, v);
    let records = [
        rec("pid_rate", "roll_kp", 0x06, 300f32.to_le_bytes()),
        // Out of today's bounds: ignored with a console line.
        rec("pid_rate", "yaw_kp", 0x06, (-5f32).to_le_bytes()),
        // In range but inconsistent with the defaults: ignored.
        rec("avoid", "slowDist", 0x06, 0.1f32.to_le_bytes()),
        // Another type than the declaration's: ignored.
        rec("pid_rate", "pitch_kp", 0x08, [7, 0, 0, 0]),
        // A parameter this firmware does not have: ignored.
        (0xABCD_0123, 0x06, 1f32.to_le_bytes()),
        // Not persistent (a goal): ignored.
        rec("mission", "goalX", 0x06, 2f32.to_le_bytes()),
    ];
    let mut p = PersistentParams::empty();
    for (k, t, v) in records {
        let w = p.prepare_store(k, t, v).unwrap();
        p.commit(w);
    }
    let mut s = service();
    let before = s.store().tuning;
    let summary = s.load_persistent(p);
    assert_eq!((summary.applied, summary.unknown, summary.refused), (1, 3, 2));
    let t = s.store().tuning;
    assert_eq!(t.controller.roll_rate.kp, 300.0);
    assert_eq!(t.controller.yaw_rate.kp, before.controller.yaw_rate.kp);
    assert_eq!(t.mission.avoidance, before.mission.avoidance);
    assert_eq!(t.controller.pitch_rate, before.controller.pitch_rate);
    assert_eq!(s.store().params, MissionParams::SEED);
    let lines: Vec<String> = std::iter::from_fn(|| s.take_refusal())
        .map(|n| Svc::console_line(&n).to_string())
        .collect();
    assert_eq!(
        lines,
        [
            "param pid_rate.yaw_kp refused: not in [0, 1000]\n",
            "param avoid.slowDist refused: inconsistent with others\n"
        ]
    );
    // The records stay stored (a client can see and clear them).
    assert_eq!(s.store().persistent.len(), records.len());
}

#[test]
fn a_position_gain_written_by_radio_changes_the_controller_output_by_the_p_law() {
    use cfnav::types::{Setpoint, StateEstimate};
    // Hovering at (1, 1, 0.5), target 0.1 m ahead in x: the position loop's output (the velocity target) is
    // Kp · 0.1 m (no I or D by default), so doubling xKp by radio doubles it.
    let state = StateEstimate {
        position_m: [1.0, 1.0, 0.5],
        valid: true,
        ..StateEstimate::default()
    };
    let target = Setpoint::Position {
        x_m: 1.1,
        y_m: 1.0,
        z_m: 0.5,
        yaw_rad: 0.0,
    };
    let mut s = service();
    let mut c = Controller::new(s.store().tuning.controller).unwrap();
    let before = c.update(&target, &state, [0.0; 3], 4.0, 1_000).velocity_target_m_s[0];
    assert!((before - 2.0 * 0.1).abs() < 1e-4, "{before}");
    write_f32(&mut s, id("posCtlPid", "xKp"), 4.0).unwrap();
    c.set_config(s.store().tuning.controller).unwrap();
    // The position loop runs on every 10th call (100 Hz): ten more steps at 1 kHz.
    let mut after = f32::NAN;
    for k in 1..=10u64 {
        after = c
            .update(&target, &state, [0.0; 3], 4.0, 1_000 + k * 1_000)
            .velocity_target_m_s[0];
    }
    assert!((after - 4.0 * 0.1).abs() < 1e-4, "{after}");
}

#[test]
fn the_flight_core_takes_gains_and_flow_std_now_and_mission_tuning_at_the_next_start() {
    use cfnav::stack::{FlightConfig, FlightCore};
    let config = FlightConfig::default();
    let mut core: Box<FlightCore<{ 128 * 64 }, 1024>> = Box::new(FlightCore::new(&config, (0.6, 1.3), 0.0).unwrap());
    let mut s = service();
    write_f32(&mut s, id("pid_attitude", "roll_kp"), 5.0).unwrap();
    write_f32(&mut s, id("motion", "flowStdFixed"), 4.0).unwrap();
    write_f32(&mut s, id("plan", "inflation"), 0.3).unwrap();
    write_u8(&mut s, id("avoid", "mode"), 1).unwrap();
    let t = s.store().tuning;
    core.set_tuning(t.controller, t.flow_std_counts, t.mission).unwrap();
    assert_eq!(core.estimator().config().flow_std_counts, 4.0);
    // Mission tuning waits for the next start.
    assert_eq!(
        core.mission().config().inflation_radius_m,
        config.mission.inflation_radius_m
    );
    core.start_mission(MissionParams::SEED).unwrap();
    assert_eq!(core.mission().config().inflation_radius_m, 0.3);
    assert_eq!(
        core.mission().config().avoidance.method,
        AvoidanceMethod::VirtualForceField
    );
    // An invalid controller configuration (bypassing the registry's checks) is refused whole.
    let mut bad = t.controller;
    bad.roll.kp = f32::NAN;
    assert!(core.set_tuning(bad, 2.0, t.mission).is_err());
    assert_eq!(core.estimator().config().flow_std_counts, 4.0);
}
