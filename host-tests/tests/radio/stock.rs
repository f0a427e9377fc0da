//! The stock parameter names cfclient and cflib use: every `deck.*` name the stock cfclient
//! 2026.8.1 reads, `kalman.resetEstimation` (cflib's `MotionCommander`), `stabilizer.controller`
//! (`PositionHlCommander(controller=PID)`), `commander.enHighLevel`, the default-value request cfclient sends
//! when a parameter is selected, and the tables of docs/params.md and docs/logs.md generated from the
//! declarations.

use cfnav::mission::MissionParams;
use cfnav::radio::crtp::{CrtpPacket, Service};
use cfnav::radio::log_decl::write_log_table;
use cfnav::radio::param::ParamService;
use cfnav::radio::param_decl::{FLAG_READ_ONLY, ParamStore, ParamType, Refusal, write_param_table};
use cfnav::radio::toc::Value;
use cfnav::radio_binding::log_table::LOG_TABLE;
use cfnav::radio_binding::param_state::MissionParamState;
use cfnav::radio_binding::param_table::{ID_RESET_ESTIMATION, PARAM_TABLE};

type Params = ParamService<MissionParamState>;

fn service() -> Params {
    ParamService::new(MissionParamState::new(MissionParams::SEED, 128 * 64))
}

fn id(group: &str, name: &str) -> u16 {
    Params::find(group, name).unwrap_or_else(|| panic!("{group}.{name} missing"))
}

/// cflib `set_value`: 2/2 `[id u16, value]`; returns the echo's value bytes.
fn write(m: &mut Params, id: u16, value: &[u8]) -> Vec<u8> {
    let mut data = id.to_le_bytes().to_vec();
    data.extend_from_slice(value);
    let reply = m.handle(&CrtpPacket::new(2, 2, &data).unwrap()).expect("an echo");
    assert_eq!(&reply.data[..2], &id.to_le_bytes());
    reply.data[2..].to_vec()
}

fn refusal_line(m: &mut Params) -> Option<String> {
    m.take_refusal().map(|n| Params::console_line(&n).to_string())
}

/// Every `deck.*` name the stock cfclient 2026.8.1 reads (`ui/tabs/FlightTab.py`, `LEDRingTab.py`,
/// `ColorLEDTab.py`, `lighthouse_tab.py`, `locopositioning_tab.py`) plus the two decks cfnav flies with.
const CFCLIENT_DECKS: &[&str] = &[
    "bcFlow",
    "bcFlow2",
    "bcZRanger",
    "bcZRanger2",
    "bcMultiranger",
    "bcLighthouse4",
    "bcLoco",
    "bcDWM1000",
    "bcLedRing",
    "bcColorLedBot",
    "bcColorLedTop",
];

#[test]
fn every_deck_cfclient_reads_is_a_read_only_uint8_set_from_detection() {
    let mut m = service();
    for deck in CFCLIENT_DECKS {
        let e = Params::entry(id("deck", deck)).unwrap();
        assert_eq!((e.ty, e.flags), (ParamType::U8, FLAG_READ_ONLY), "deck.{deck}");
    }
    let read = |m: &Params, deck: &str| m.store().read(id("deck", deck));
    m.store_mut().set_decks(true, false);
    assert_eq!(read(&m, "bcFlow2"), Some(Value::U8(1)));
    assert_eq!(read(&m, "bcMultiranger"), Some(Value::U8(0)));
    assert!(!m.store().decks_ok, "a missing deck refuses a start");
    m.store_mut().set_decks(false, true);
    assert_eq!(read(&m, "bcFlow2"), Some(Value::U8(0)));
    assert_eq!(read(&m, "bcMultiranger"), Some(Value::U8(1)));
    for deck in CFCLIENT_DECKS
        .iter()
        .filter(|d| !matches!(**d, "bcFlow2" | "bcMultiranger"))
    {
        assert_eq!(
            read(&m, deck),
            Some(Value::U8(0)),
            "deck.{deck}: cfnav drives no such deck"
        );
    }
    // Read-only: a radio write gets no echo (stock) and changes nothing.
    let before = *m.store();
    let p = CrtpPacket::new(2, 2, &[id("deck", "bcFlow").to_le_bytes()[0], 0, 1]).unwrap();
    assert_eq!(m.handle(&p), None);
    assert_eq!(*m.store(), before);
}

/// `firmware.revision0/revision1/modified` as stock's `version.tmpl` declares them, with the values stock's
/// `versionTemplate.py` cuts from `git rev-parse HEAD` (the oracle: git itself, asked here).
#[test]
fn firmware_revision_parameters_are_the_git_commit_of_the_build() {
    let git = |args: &[&str]| {
        let out = std::process::Command::new("git")
            .args(args)
            .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
            .output()
            .expect("git runs");
        assert!(out.status.success(), "git {args:?}");
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    };
    let head = git(&["rev-parse", "HEAD"]);
    // build.rs's rule: the firmware's own tracked inputs differ from HEAD.
    let modified = !git(&[
        "status",
        "--porcelain",
        "--untracked-files=no",
        "--",
        "src",
        "build.rs",
        "Cargo.toml",
        "memory.x",
    ])
    .is_empty();
    let mut m = service();
    for (name, ty) in [
        ("revision0", ParamType::U32),
        ("revision1", ParamType::U16),
        ("modified", ParamType::U8),
    ] {
        let e = Params::entry(id("firmware", name)).unwrap();
        assert_eq!((e.ty, e.flags), (ty, FLAG_READ_ONLY), "firmware.{name}");
    }
    // Over the wire, as cflib reads a value: 2/1 [id u16] -> [id u16, status 0, value].
    let read = |m: &mut Params, name: &str| {
        let i = id("firmware", name);
        let reply = m
            .handle(&CrtpPacket::new(2, 1, &i.to_le_bytes()).unwrap())
            .expect("a reply");
        assert_eq!(&reply.data[..3], &[i.to_le_bytes()[0], i.to_le_bytes()[1], 0]);
        reply.data[3..].to_vec()
    };
    let rev0 = u32::from_str_radix(&head[0..8], 16).unwrap();
    let rev1 = u16::from_str_radix(&head[8..12], 16).unwrap();
    assert_eq!(read(&mut m, "revision0"), rev0.to_le_bytes(), "HEAD {head}");
    assert_eq!(read(&mut m, "revision1"), rev1.to_le_bytes(), "HEAD {head}");
    assert_eq!(read(&mut m, "modified"), [u8::from(modified)]);
    // Read-only: a write changes nothing.
    let p = CrtpPacket::new(
        2,
        2,
        &[&id("firmware", "revision0").to_le_bytes()[..], &[0, 0, 0, 0]].concat(),
    )
    .unwrap();
    assert_eq!(m.handle(&p), None);
    assert_eq!(read(&mut m, "revision0"), rev0.to_le_bytes());
}

#[test]
fn kalman_reset_estimation_is_accepted_on_the_ground_and_refused_in_the_air() {
    let mut m = service();
    let reset = id("kalman", "resetEstimation");
    assert_eq!(reset, ID_RESET_ESTIMATION);
    // MotionCommander: 1, then 0 (cflib positioning/motion_commander.py `_reset_position_estimator`).
    assert_eq!(write(&mut m, reset, &[1]), vec![1]);
    assert_eq!(
        m.store().pending_reset(),
        Some(MissionParams::SEED.start_m),
        "re-anchored at the start"
    );
    assert_eq!(write(&mut m, reset, &[0]), vec![0]);
    assert_eq!(m.store().pending_reset(), None);
    // Flying: refused, the echo carries 0, a console line says why.
    m.store_mut().flying = true;
    assert_eq!(write(&mut m, reset, &[1]), vec![0]);
    assert_eq!(
        refusal_line(&mut m).as_deref(),
        Some("param kalman.resetEstimation refused: reset while flying\n")
    );
    assert_eq!(m.store().pending_reset(), None);
    // Only 0 and 1 (declared range).
    m.store_mut().flying = false;
    assert_eq!(write(&mut m, reset, &[2]), vec![0]);
    assert_eq!(
        refusal_line(&mut m).as_deref(),
        Some("param kalman.resetEstimation refused: not in [0, 1]\n")
    );
}

#[test]
fn stabilizer_controller_takes_auto_or_pid_and_refuses_the_others() {
    let mut m = service();
    let controller = id("stabilizer", "controller");
    // PositionHlCommander(controller=CONTROLLER_PID) writes 1 (cflib position_hl_commander.py).
    assert_eq!(write(&mut m, controller, &[1]), vec![1]);
    assert_eq!(refusal_line(&mut m), None);
    for other in 2..=5u8 {
        assert_eq!(write(&mut m, controller, &[other]), vec![1], "controller {other}");
        assert_eq!(
            refusal_line(&mut m).as_deref(),
            Some("param stabilizer.controller refused: only 0 (auto) or 1 (PID)\n")
        );
    }
    assert_eq!(write(&mut m, controller, &[0]), vec![0]);
}

#[test]
fn commander_en_high_level_is_a_switch() {
    let mut m = service();
    let en = id("commander", "enHighLevel");
    assert_eq!(write(&mut m, en, &[1]), vec![1]);
    assert_eq!(m.store().en_high_level, 1);
    assert_eq!(write(&mut m, en, &[7]), vec![1]);
    assert_eq!(
        refusal_line(&mut m).as_deref(),
        Some("param commander.enHighLevel refused: not in [0, 1]\n")
    );
    // Set-by-name refuses it the same way (EINVAL).
    let mut data = vec![0u8];
    data.extend_from_slice(b"commander\0enHighLevel\0");
    data.extend_from_slice(&[0x08, 9]);
    let reply = m.handle(&CrtpPacket::new(2, 3, &data).unwrap()).unwrap();
    assert_eq!(*reply.data.last().unwrap(), 22);
    assert_eq!(m.store().en_high_level, 1);
}

#[test]
fn default_values_are_the_power_on_values() {
    let mut m = service();
    let goal_x = id("mission", "goalX");
    write(&mut m, goal_x, &4.5f32.to_le_bytes());
    let b = goal_x.to_le_bytes();
    // v2 (protocol ≥ 11): [8, id u16, status 0, value]; v1: [6, id u16, value] (stock param_logic.c).
    let reply = m.handle(&CrtpPacket::new(2, 3, &[8, b[0], b[1]]).unwrap()).unwrap();
    let mut want = vec![8, b[0], b[1], 0];
    want.extend_from_slice(&MissionParams::SEED.goal_m.0.to_le_bytes());
    assert_eq!(reply.data.to_vec(), want);
    let reply = m.handle(&CrtpPacket::new(2, 3, &[6, b[0], b[1]]).unwrap()).unwrap();
    assert_eq!(&reply.data[3..], &MissionParams::SEED.goal_m.0.to_le_bytes());
    // Read-only (no default, as stock) and unknown ids: ENOENT.
    let ro = id("deck", "bcFlow2").to_le_bytes();
    let reply = m.handle(&CrtpPacket::new(2, 3, &[8, ro[0], ro[1]]).unwrap()).unwrap();
    assert_eq!(reply.data.to_vec(), vec![8, ro[0], ro[1], 2]);
    let reply = m.handle(&CrtpPacket::new(2, 3, &[8, 0xFF, 0xFF]).unwrap()).unwrap();
    assert_eq!(reply.data.to_vec(), vec![8, 0xFF, 0xFF, 2]);
    // Every writable parameter has one (cfclient asks whenever one is selected; cflib's queue waits).
    for (i, e) in PARAM_TABLE.iter().enumerate() {
        if !e.read_only() {
            assert!(m.store().default_value(i as u16).is_some(), "{}.{}", e.group, e.name);
        }
    }
}

#[test]
fn every_declared_range_is_enforced_on_the_wire() {
    // For each writable declaration with a range, a value just outside is refused and changes nothing.
    for (i, e) in PARAM_TABLE.iter().enumerate() {
        let outside = match (e.range, e.ty) {
            (cfnav::radio::param_decl::Range::Closed(_, hi), ParamType::U8) => Value::U8(hi as u8 + 1),
            (cfnav::radio::param_decl::Range::Closed(_, hi), ParamType::F32) => Value::F32(hi + 0.5),
            (cfnav::radio::param_decl::Range::LeftOpen(lo, _), ParamType::F32) => Value::F32(lo),
            _ => continue,
        };
        if e.read_only() {
            continue;
        }
        let mut m = service();
        let before = *m.store();
        let (bytes, n) = outside.to_le();
        let mut data = (i as u16).to_le_bytes().to_vec();
        data.extend_from_slice(&bytes[..n]);
        m.handle(&CrtpPacket::new(2, 2, &data).unwrap()).unwrap();
        assert_eq!(*m.store(), before, "{}.{} = {outside:?}", e.group, e.name);
        let note = m.take_refusal().unwrap();
        assert_eq!(note.refusal, e.out_of_range, "{}.{}", e.group, e.name);
        assert_ne!(note.refusal, Refusal::UnknownId);
    }
}

/// The text between `<!-- begin: NAME (generated from SOURCE; ...) -->` and `<!-- end: NAME -->` in the
/// repository page `page` (a path from the repository's root).
pub(super) fn generated_section(page: &str, name: &str, source: &str) -> String {
    let path = format!("{}/../{page}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let begin = format!(
        "<!-- begin: {name} (generated from {source}; `cargo test -p host-tests --test radio generated` checks it) -->\n"
    );
    let end = format!("<!-- end: {name} -->");
    let a = text
        .find(&begin)
        .unwrap_or_else(|| panic!("{page} has no line {begin}"))
        + begin.len();
    let b = text[a..]
        .find(&end)
        .unwrap_or_else(|| panic!("{page} has no line {end}"))
        + a;
    text[a..b].to_string()
}

#[test]
fn generated_parameter_and_log_pages_are_the_declarations() {
    let mut params = String::new();
    write_param_table(&mut params, PARAM_TABLE).unwrap();
    let mut logs = String::new();
    write_log_table(&mut logs, LOG_TABLE).unwrap();
    assert!(
        generated_section("docs/params.md", "parameter table", "src/radio") == params,
        "docs/params.md's table differs from the declarations; paste this between its markers:\n{params}"
    );
    assert!(
        generated_section("docs/logs.md", "log table", "src/radio") == logs,
        "docs/logs.md's table differs from the declarations; paste this between its markers:\n{logs}"
    );
}

#[test]
fn every_refusal_line_fits_the_console_untruncated() {
    use cfnav::radio::param::RefusalNote;
    let all = [
        Refusal::UnknownId,
        Refusal::WrongType,
        Refusal::ReadOnly,
        Refusal::GoalOutsideArena,
        Refusal::StartOutsideArena,
        Refusal::BadHeight,
        Refusal::BadSpeed,
        Refusal::BadStartValue,
        Refusal::StartWhileFlying,
        Refusal::DeckMissing,
        Refusal::AlreadyRunning,
        Refusal::BadArena,
        Refusal::OutOfRange,
        Refusal::UnsupportedController,
        Refusal::ResetWhileFlying,
        Refusal::Inconsistent,
        Refusal::StoreFull,
        Refusal::NotPersistent,
        Refusal::StoreWhileFlying,
    ];
    // The refusals each parameter can get: the declaration's for all, the store's for the groups it checks.
    for (i, e) in PARAM_TABLE.iter().enumerate() {
        let possible = all.iter().copied().filter(|r| match r {
            Refusal::UnknownId | Refusal::WrongType | Refusal::ReadOnly | Refusal::OutOfRange => true,
            Refusal::ResetWhileFlying => e.group == "kalman",
            Refusal::Inconsistent | Refusal::StoreFull | Refusal::StoreWhileFlying => e.is_persistent(),
            Refusal::NotPersistent => true,
            _ if *r == e.out_of_range => true,
            // The start and arena rules concern the mission's own parameters, not its tuning ones.
            _ => e.group == "mission" && !e.is_persistent(),
        });
        for refusal in possible {
            let line = Params::console_line(&RefusalNote { id: i as u16, refusal });
            assert!(
                line.ends_with('\n'),
                "{}.{} {refusal:?}: {line:?} was cut",
                e.group,
                e.name
            );
        }
    }
}
