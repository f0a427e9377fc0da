//! The stress tables (`cfnav_sim::stress`, docs/formats.md: world files `[sensors]`/`[disturbances]`, commands
//! `--stress FILE`): every key's range (bad input names the key, in world files, in stress files and at the
//! command line with exit 2), absent keys = the simulator's defaults (explicit defaults fly the identical
//! run), `--stress` overrides key by key, and each effect measured on the sensor or physics model against
//! its definition.

use std::path::PathBuf;
use std::process::ExitCode;

use cfnav_sim::physics::{Geometry, QuadParams, Quadrotor};
use cfnav_sim::sensors::{
    FlowParams, FlowSensor, Imu, ImuParams, MultiRanger, MultiRangerParams, ZRanger, ZRangerParams,
};
use cfnav_sim::stress::{GUST_PERIOD_S, GUST_TAU_S, Gusts, Stress, state_of_charge_for_ocv};
use cfnav_sim::world::{Generator, World};
use cfnav_tools::sim::cli::{SimArgs, run_cli};
use cfnav_tools::sim::runner::{Faults, RunOptions, SimDrone, run};
use rand::SeedableRng;
use rand::rngs::SmallRng;

fn worlds_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../worlds")
}

fn default_text() -> String {
    std::fs::read_to_string(worlds_dir().join("default.toml")).expect("default.toml")
}

/// A scratch file for the command-line tests (unique per test and process).
fn scratch(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cfnav-stress-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

fn sim_args() -> SimArgs {
    SimArgs {
        world: None,
        random: None,
        random_world: None,
        seed: None,
        stress: None,
        generator: Generator::Wide,
        json: None,
        plot: None,
        flow_fails_at: None,
        ranger_fails_at: None,
        abort_at: None,
        link_loss_at: None,
        link_loss: 0,
        link_timeout: None,
        verbose: false,
        serve: false,
        map_json: None,
        port: 19850,
        speed: 1.0,
        mode: cfnav_tools::sim::cli::ModeArg::RoundTrip,
        hover_time: None,
        coverage: None,
        param_store: None,
    }
}

/// (table, key, value text) that are out of range per the world-file format of docs/formats.md (and this simulator's wind limit).
const BAD: &[(&str, &str, &str)] = &[
    ("sensors", "flow_noise_counts", "-0.1"),
    ("sensors", "flow_noise_counts", "nan"),
    ("sensors", "flow_noise_counts", "inf"),
    ("sensors", "flow_scale_error", "0.31"),
    ("sensors", "flow_scale_error", "-0.31"),
    ("sensors", "flow_scale_error_max", "-0.01"),
    ("sensors", "flow_scale_error_max", "0.31"),
    ("sensors", "flow_dropout", "-0.01"),
    ("sensors", "flow_dropout", "0.51"),
    ("sensors", "zrange_outlier_rate", "-0.01"),
    ("sensors", "zrange_outlier_rate", "0.6"),
    ("sensors", "ranger_outlier_rate", "-1"),
    ("sensors", "ranger_outlier_rate", "0.51"),
    ("sensors", "ranger_dropout", "-0.01"),
    ("sensors", "ranger_dropout", "1.0"),
    ("sensors", "gyro_bias_max", "-0.01"),
    ("sensors", "gyro_bias_max", "nan"),
    ("sensors", "accel_bias_max", "-0.15"),
    ("disturbances", "wind", "[2.5, 0.0]"),
    ("disturbances", "wind", "[0.0, nan]"),
    ("disturbances", "wind", "[0.3]"),
    ("disturbances", "wind", "[0.3, 0.1, 0.0]"),
    ("disturbances", "gust_m_s", "-0.2"),
    ("disturbances", "gust_m_s", "inf"),
    ("disturbances", "mass_scale", "0.79"),
    ("disturbances", "mass_scale", "1.31"),
    ("disturbances", "motor_scale", "[1.0, 0.69, 1.0, 1.0]"),
    ("disturbances", "motor_scale", "[1.0, 1.0, 1.0, 1.11]"),
    ("disturbances", "motor_scale", "[1.0, 1.0, 1.0]"),
    ("disturbances", "battery_start_v", "3.29"),
    ("disturbances", "battery_start_v", "4.21"),
];

/// In-range values, the ends of each range included.
const GOOD: &[(&str, &str, &str)] = &[
    ("sensors", "flow_noise_counts", "0.0"),
    ("sensors", "flow_noise_counts", "2.0"),
    ("sensors", "flow_scale_error", "0.3"),
    ("sensors", "flow_scale_error", "-0.3"),
    ("sensors", "flow_scale_error_max", "0.3"),
    ("sensors", "flow_dropout", "0.5"),
    ("sensors", "zrange_outlier_rate", "0.0"),
    ("sensors", "ranger_outlier_rate", "0.5"),
    ("sensors", "ranger_dropout", "0.05"),
    ("sensors", "gyro_bias_max", "0.05"),
    ("sensors", "accel_bias_max", "0.15"),
    ("disturbances", "wind", "[0.3, -0.1]"),
    ("disturbances", "wind", "[-2.0, 2.0]"),
    ("disturbances", "gust_m_s", "0.2"),
    ("disturbances", "mass_scale", "0.8"),
    ("disturbances", "mass_scale", "1.3"),
    ("disturbances", "motor_scale", "[0.7, 0.95, 1.0, 1.1]"),
    ("disturbances", "battery_start_v", "3.3"),
    ("disturbances", "battery_start_v", "4.2"),
];

fn with_table(table: &str, key: &str, value: &str) -> String {
    format!("{}\n[{table}]\n{key} = {value}\n", default_text())
}

#[test]
fn every_bad_stress_value_is_bad_input_naming_its_key_and_line() {
    for &(table, key, value) in BAD {
        let field = format!("{table}.{key}");
        // In a world file: the error names the key and the line it is written on.
        let text = with_table(table, key, value);
        let line = text.lines().count();
        let e = World::from_toml_str(&text, "w.toml").expect_err(&format!("{field} = {value} accepted"));
        let msg = e.to_string();
        println!("{msg}");
        assert!(!msg.contains('\n'), "one line: {msg}");
        assert_eq!(e.field.as_deref(), Some(field.as_str()), "{field} = {value}: {msg}");
        assert_eq!(e.line, Some(line), "{field} = {value}: {msg}");
        // In a stress-only file: the same.
        let only = format!("[{table}]\n{key} = {value}\n");
        let e = Stress::from_toml_str(&only, "s.toml").expect_err(&format!("{field} = {value} accepted"));
        assert!(e.contains(&field) && e.contains("line 2"), "{field} = {value}: {e}");
        assert!(e.starts_with("s.toml"), "names the file: {e}");
    }
}

#[test]
fn in_range_stress_values_load_with_their_value() {
    for &(table, key, value) in GOOD {
        let w = World::from_toml_str(&with_table(table, key, value), "w.toml")
            .unwrap_or_else(|e| panic!("{table}.{key} = {value}: {e}"));
        let s = Stress::from_toml_str(&format!("[{table}]\n{key} = {value}\n"), "s.toml")
            .unwrap_or_else(|e| panic!("{table}.{key} = {value}: {e}"));
        assert_eq!(w.stress, s, "{table}.{key}: world file and stress file agree");
        assert!(!s.is_empty());
        // Written back out and read again: the same settings.
        let back = World::from_toml_str(&w.to_toml_string(), "back.toml").unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(back.stress, w.stress, "{table}.{key} round trip");
    }
    let s = Stress::from_toml_str("[disturbances]\nwind = [0.3, -0.1]\n", "s.toml").expect("wind");
    assert_eq!(s.disturbances.wind, Some([0.3, -0.1]));
    let s = Stress::from_toml_str("[sensors]\nflow_noise_counts = 2\n", "s.toml").expect("an integer is a number");
    assert_eq!(s.sensors.flow_noise_counts, Some(2.0));
}

#[test]
fn unknown_keys_and_the_scale_error_sum_are_refused() {
    for (text, words) in [
        ("[sensors]\nflow_noise = 1.0\n", &["flow_noise"][..]),
        ("[disturbances]\nwind_m_s = [0.1, 0.0]\n", &["wind_m_s"][..]),
        ("[weather]\nrain = 1\n", &["weather"][..]),
        (
            "[sensors]\nflow_scale_error = 0.2\nflow_scale_error_max = 0.2\n",
            &["sensors.flow_scale_error_max", "0.3"][..],
        ),
        ("[sensors]\nflow_noise_counts = \"lots\"\n", &["line 2"][..]),
    ] {
        let e = Stress::from_toml_str(text, "s.toml").expect_err(text);
        println!("{e}");
        for w in words {
            assert!(e.contains(w), "{text:?}: {e}");
        }
        let e = World::from_toml_str(&format!("{}\n{text}", default_text()), "w.toml").expect_err(text);
        for w in words.iter().filter(|w| !w.starts_with("line")) {
            assert!(e.to_string().contains(w), "{text:?}: {e}");
        }
    }
}

#[test]
fn the_command_line_exits_2_on_a_bad_stress_file_and_flies_a_good_one() {
    for (i, &(table, key, value)) in BAD.iter().enumerate() {
        let path = scratch(&format!("bad-{i}.toml"), &format!("[{table}]\n{key} = {value}\n"));
        let mut args = sim_args();
        args.random = Some(1);
        args.stress = Some(path.clone());
        assert_eq!(
            run_cli(&args),
            ExitCode::from(2),
            "--random --stress with {table}.{key} = {value}"
        );
        let mut args = sim_args();
        args.stress = Some(path);
        assert_eq!(
            run_cli(&args),
            ExitCode::from(2),
            "sim --stress with {table}.{key} = {value}"
        );
        // The same value inside a world file.
        let world = scratch(&format!("bad-world-{i}.toml"), &with_table(table, key, value));
        let mut args = sim_args();
        args.world = Some(world);
        assert_eq!(
            run_cli(&args),
            ExitCode::from(2),
            "--world with {table}.{key} = {value}"
        );
    }
    let mut args = sim_args();
    args.random = Some(1);
    args.stress = Some(worlds_dir().join("no-such-stress.toml"));
    assert_eq!(run_cli(&args), ExitCode::from(2), "a missing stress file");
    // A good batch: exit 0 (a batch reports, it does not judge).
    let json = scratch("batch.json", "");
    let mut args = sim_args();
    args.random = Some(2);
    args.seed = Some(5);
    args.stress = Some(worlds_dir().join("stress.toml"));
    args.json = Some(json.clone());
    assert_eq!(run_cli(&args), ExitCode::SUCCESS);
    let report = std::fs::read_to_string(json).expect("report");
    assert!(
        report.contains("\"runs\"") && report.contains("\"summary\""),
        "{report}"
    );
}

#[test]
fn the_shipped_stress_file_has_the_issues_values() {
    let s = Stress::load(worlds_dir().join("stress.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.sensors.flow_noise_counts, Some(1.5));
    assert_eq!(s.sensors.flow_scale_error_max, Some(0.03));
    assert_eq!(s.sensors.ranger_outlier_rate, Some(0.01));
    assert_eq!(s.sensors.ranger_dropout, Some(0.03));
    assert_eq!(s.disturbances.gust_m_s, Some(0.1));
    assert_eq!(s.disturbances.mass_scale, Some(1.05));
    // It is also a world: the default world's layout under that stress.
    let w = World::load(worlds_dir().join("stress.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(w.stress, s);
    let mut plain = w.clone();
    plain.stress = Stress::default();
    plain.name = "default".into();
    assert_eq!(plain, World::default_world());
    // Every single-key file of the baseline sets exactly one key.
    let mut n = 0;
    for entry in std::fs::read_dir(worlds_dir().join("stress-keys")).expect("stress-keys/") {
        let path = entry.expect("entry").path();
        let s = Stress::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let set = s.to_toml_string().lines().filter(|l| l.contains(" = ")).count();
        assert_eq!(set, 1, "{}: {s:?}", path.display());
        n += 1;
    }
    assert!(n >= 13, "{n} single-key files");
}

#[test]
fn a_stress_file_overrides_the_worlds_keys_one_by_one() {
    let world = Stress::from_toml_str(
        "[sensors]\nflow_noise_counts = 2.0\nflow_dropout = 0.1\n[disturbances]\nmass_scale = 1.2\n",
        "w",
    )
    .expect("world tables");
    let over = Stress::from_toml_str(
        "[sensors]\nflow_noise_counts = 0.5\n[disturbances]\ngust_m_s = 0.1\n",
        "o",
    )
    .expect("stress file");
    let s = world.overlaid(&over);
    assert_eq!(s.sensors.flow_noise_counts, Some(0.5), "the stress file's key wins");
    assert_eq!(s.sensors.flow_dropout, Some(0.1), "the world's own key stays");
    assert_eq!(s.disturbances.mass_scale, Some(1.2));
    assert_eq!(s.disturbances.gust_m_s, Some(0.1));
    assert_eq!(Stress::default().overlaid(&over), over);
    assert_eq!(over.overlaid(&Stress::default()), over);
}

/// Absent keys keep the simulator's defaults: a world whose tables spell out every default flies exactly
/// the run of the world without them (same noise streams, same report).
#[test]
fn explicit_defaults_fly_the_same_run_as_no_tables() {
    let text = "[sensors]\nflow_noise_counts = 1.0\nflow_scale_error = 0.0\nflow_scale_error_max = 0.0\n\
                flow_dropout = 0.0\nzrange_outlier_rate = 0.0\nranger_outlier_rate = 0.0\nranger_dropout = 0.005\n\
                gyro_bias_max = 0.02\naccel_bias_max = 0.05\n[disturbances]\nwind = [0.0, 0.0]\ngust_m_s = 0.0\n\
                mass_scale = 1.0\nmotor_scale = [1.0, 1.0, 1.0, 1.0]\n";
    let explicit = Stress::from_toml_str(text, "defaults").expect("defaults");
    assert!(!explicit.is_empty());
    for world in [World::default_world(), World::random(3)] {
        let a = run(&world, &RunOptions::for_world(&world)).expect("runs").report;
        let mut w = world.clone();
        w.stress = explicit;
        let b = run(&w, &RunOptions::for_world(&w)).expect("runs").report;
        println!("{}: {} {:?} s", world.name, a.outcome, a.mission_time_s);
        assert_eq!(
            (a.outcome, a.mission_time_s, a.landings.clone(), a.replans, a.distance_m),
            (b.outcome, b.mission_time_s, b.landings.clone(), b.replans, b.distance_m),
            "{}",
            world.name
        );
    }
}

// ---------------------------------------------------------------------------------------------------------
// Each effect against its definition

/// An open floor with nothing else (a flat floor at z = 0, nothing within 100 m).
struct Floor;

impl Geometry for Floor {
    fn ray_cast(&self, o: [f32; 3], d: [f32; 3], max_range_m: f32) -> Option<f32> {
        // Only the floor (z = 0) and a wall at x = 102 m (out of range).
        let mut best: Option<f32> = None;
        if d[2] < -1e-6 {
            best = Some(-o[2] / d[2]);
        }
        if d[0] > 1e-6 {
            let t = (102.0 - o[0]) / d[0];
            best = Some(best.map_or(t, |b| b.min(t)));
        }
        best.filter(|t| *t >= 0.0 && *t <= max_range_m)
    }
    fn surface_height(&self, _x: f32, _y: f32) -> f32 {
        0.0
    }
}

/// A wall 1.5 m ahead along +x (for the Multi-ranger's front beam), and the floor.
struct WallAhead;

impl Geometry for WallAhead {
    fn ray_cast(&self, o: [f32; 3], d: [f32; 3], max_range_m: f32) -> Option<f32> {
        let mut best: Option<f32> = None;
        if d[2] < -1e-6 {
            best = Some(-o[2] / d[2]);
        }
        if d[0] > 1e-6 {
            let t = 1.5 / d[0];
            best = Some(best.map_or(t, |b| b.min(t)));
        }
        best.filter(|t| *t >= 0.0 && *t <= max_range_m)
    }
    fn surface_height(&self, _x: f32, _y: f32) -> f32 {
        0.0
    }
}

/// Binomial bounds: `k` of `n` with probability `p`, within 5σ.
fn binomial_ok(k: usize, n: usize, p: f64) -> bool {
    let mean = n as f64 * p;
    let sd = (n as f64 * p * (1.0 - p)).sqrt();
    (k as f64 - mean).abs() <= 5.0 * sd + 1.0
}

#[test]
fn flow_scale_error_scales_the_reading() {
    let mut rng = SmallRng::seed_from_u64(3);
    for scale in [-0.05f32, 0.0, 0.03, 0.3] {
        let params = FlowParams {
            noise_counts: 0.0,
            scale_error: scale,
            ..FlowParams::default()
        };
        let mut q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.5], 0.0);
        q.set_velocity([1.0, 0.0, 0.0]);
        let mut flow = FlowSensor::new(params);
        // The stock model (interfaces: 10·dt·(35/0.71674)·v/h counts), times (1 + scale), summed over 100
        // readings (the carried remainder makes the sum exact to one count).
        let per_reading = 0.01 * (35.0 / 0.716_74) * (1.0 / 0.5) * 10.0 * (1.0 + scale);
        let mut sum = 0i32;
        for _ in 0..100 {
            let s = flow.sample(&q, &Floor, &mut rng).expect("reading");
            assert!(s.motion_valid);
            sum += i32::from(s.dpixel_x);
        }
        let want = 100.0 * per_reading;
        println!("scale error {scale}: {sum} counts over 100 readings, model {want:.1}");
        assert!((sum as f32 - want).abs() <= 1.0, "scale {scale}: {sum} vs {want}");
    }
    // Through the stress table, and the per-seed draw of flow_scale_error_max stays within its bounds.
    let s = Stress::from_toml_str("[sensors]\nflow_scale_error = 0.05\nflow_scale_error_max = 0.03\n", "s").expect("s");
    let mut seen = (f32::INFINITY, f32::NEG_INFINITY);
    for seed in 0..400 {
        let p = s.flow_params(&mut SmallRng::seed_from_u64(seed));
        assert!(
            (0.02 - 1e-6..=0.08 + 1e-6).contains(&p.scale_error),
            "{}",
            p.scale_error
        );
        seen = (seen.0.min(p.scale_error), seen.1.max(p.scale_error));
    }
    assert!(
        seen.0 < 0.025 && seen.1 > 0.075,
        "the draw spans ±0.03 around 0.05: {seen:?}"
    );
}

#[test]
fn flow_dropout_invalidates_that_share_of_readings() {
    let mut rng = SmallRng::seed_from_u64(9);
    let p = 0.2;
    let mut flow = FlowSensor::new(FlowParams {
        dropout_probability: p as f32,
        ..FlowParams::default()
    });
    let q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.5], 0.0);
    let n = 20_000;
    let invalid = (0..n)
        .filter(|_| !flow.sample(&q, &Floor, &mut rng).expect("reading").motion_valid)
        .count();
    println!("flow dropout {p}: {invalid} of {n} invalid");
    assert!(binomial_ok(invalid, n, p), "{invalid} of {n}");
}

#[test]
fn zranger_outliers_are_uniform_in_the_span() {
    let mut rng = SmallRng::seed_from_u64(5);
    let rate = 0.1;
    let mut z = ZRanger::new(ZRangerParams {
        invalid_probability: 0.0,
        outlier_probability: rate as f32,
        ..ZRangerParams::default()
    });
    let q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.5], 0.0);
    let n = 20_000;
    let mut wrong = Vec::new();
    for _ in 0..n {
        let r = z.sample(&q, &Floor, &mut rng).expect("a reading");
        if (r - 0.5).abs() > 0.05 {
            wrong.push(r);
        }
    }
    // An outlier lands within 5 cm of the truth with probability 0.1/4: expect rate × (1 − 0.025).
    let mean = wrong.iter().sum::<f32>() / wrong.len() as f32;
    println!("z-ranger outliers {rate}: {} of {n}, mean {mean:.2} m", wrong.len());
    assert!(binomial_ok(wrong.len(), n, rate * 0.975), "{} of {n}", wrong.len());
    assert!(wrong.iter().all(|r| (0.0..=4.0).contains(r)));
    assert!(
        (mean - 2.0).abs() < 0.12,
        "uniform in 0..4 m has mean 2 (the band around 0.5 m excluded)"
    );
}

#[test]
fn multiranger_outliers_and_dropouts_per_beam() {
    let mut rng = SmallRng::seed_from_u64(6);
    let (rate, drop) = (0.05, 0.1);
    let mut mr = MultiRanger::new(MultiRangerParams {
        invalid_probability: drop as f32,
        outlier_probability: rate as f32,
        ..MultiRangerParams::default()
    });
    let q = Quadrotor::new(QuadParams::default(), [5.0, 5.0, 0.5], 0.0);
    let n = 20_000;
    let (mut none, mut wrong) = (0, 0);
    for _ in 0..n {
        match mr.sample(&q, &WallAhead, &mut rng).front_m {
            None => none += 1,
            Some(r) if (r - 1.5).abs() > 0.1 => wrong += 1,
            Some(_) => {}
        }
    }
    println!("front beam: {none} missing, {wrong} wrong of {n}");
    // Outliers replace the reading whether or not it dropped out: missing = drop·(1 − rate); wrong ≈ rate
    // × (1 − the 0.2 m band's 5 %).
    assert!(binomial_ok(none, n, drop * (1.0 - rate)), "missing {none}");
    assert!(binomial_ok(wrong, n, rate * 0.95), "wrong {wrong}");
    // Through the table: ranger_dropout replaces the default invalid probability, the outlier rate is set.
    let s = Stress::from_toml_str("[sensors]\nranger_dropout = 0.05\nranger_outlier_rate = 0.01\n", "s").expect("s");
    assert_eq!(s.multiranger_params().invalid_probability, 0.05);
    assert_eq!(s.multiranger_params().outlier_probability, 0.01);
    assert_eq!(Stress::default().multiranger_params(), MultiRangerParams::default());
    let s = Stress::from_toml_str("[sensors]\nzrange_outlier_rate = 0.01\n", "s").expect("s");
    assert_eq!(s.zranger_params().outlier_probability, 0.01);
}

#[test]
fn imu_biases_are_drawn_within_their_bound() {
    let s = Stress::from_toml_str("[sensors]\ngyro_bias_max = 0.05\naccel_bias_max = 0.15\n", "s").expect("s");
    let params = ImuParams {
        gyro_noise_rad_s: 0.0,
        accel_noise_m_s2: 0.0,
        gyro_bias_walk_rad_s_sqrt_s: 0.0,
        accel_bias_walk_m_s2_sqrt_s: 0.0,
        quantise: false,
        ..s.imu_params()
    };
    let q = Quadrotor::new(QuadParams::default(), [1.0, 1.0, 0.5], 0.0);
    let (mut g_max, mut a_max) = (0.0f32, 0.0f32);
    for seed in 0..200 {
        let mut rng = SmallRng::seed_from_u64(seed);
        let mut imu = Imu::new(params, &mut rng);
        let r = imu.sample(&q, &mut rng);
        // At rest and level: the gyro reads its bias, the accelerometer g plus its bias.
        for i in 0..3 {
            let g = r.gyro_rad_s[i];
            let a = r.accel_m_s2[i] - if i == 2 { cfnav::types::GRAVITY_M_S2 } else { 0.0 };
            assert!(g.abs() <= 0.05 + 1e-5 && a.abs() <= 0.15 + 1e-4, "seed {seed}: {r:?}");
            g_max = g_max.max(g.abs());
            a_max = a_max.max(a.abs());
        }
    }
    println!("largest bias over 200 seeds: gyro {g_max:.4} rad/s, accel {a_max:.4} m/s²");
    assert!(g_max > 0.045 && a_max > 0.135, "the draws reach the bound");
}

#[test]
fn wind_drags_on_the_air_relative_velocity() {
    let p = QuadParams::default();
    let hover = p.hover_thrust_per_motor_n();
    for (air, vel) in [
        ([0.3f32, -0.1], [0.0f32, 0.0]),
        ([0.3, -0.1], [0.3, -0.1]),
        ([0.0, 0.0], [0.5, 0.0]),
    ] {
        let mut q = Quadrotor::new(p, [5.0, 5.0, 1.0], 0.0);
        q.set_motor_thrusts([hover; 4]);
        q.set_velocity([vel[0], vel[1], 0.0]);
        q.set_air_velocity([air[0], air[1], 0.0]);
        // Held at hover thrust for one step: the duties keep the thrusts (set them to hover's duty).
        q.step(0.001, &Floor);
        let v = q.velocity();
        let acc = [(v[0] - vel[0]) / 0.001, (v[1] - vel[1]) / 0.001];
        // The model (physics.rs): rotor drag K·s·v_rel + body drag c·|v_rel|·v_rel, s = 1 at hover thrust,
        // per axis in the (level) body frame.
        let want: Vec<f32> = (0..2)
            .map(|i| {
                let rel = vel[i] - air[i];
                -(p.rotor_drag_n_s_m[i] + p.body_drag_n_s2_m2[i] * rel.abs()) * rel / p.mass_kg
            })
            .collect();
        println!("air {air:?}, velocity {vel:?}: acceleration {acc:?}, model {want:?}");
        for i in 0..2 {
            assert!(
                (acc[i] - want[i]).abs() < 0.01 + 0.05 * want[i].abs(),
                "axis {i}: {acc:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn gusts_are_first_order_with_the_stated_spread() {
    let sigma = 0.2f32;
    let mut g = Gusts::new(sigma, 42);
    assert!(g.is_active());
    let n = 200_000;
    let lag = (GUST_TAU_S / GUST_PERIOD_S).round() as usize;
    let mut xs = Vec::with_capacity(n);
    for _ in 0..n {
        g.step();
        xs.push(g.value()[0]);
    }
    let var = xs.iter().map(|x| x * x).sum::<f32>() / n as f32;
    let cov = xs.windows(lag + 1).map(|w| w[0] * w[lag]).sum::<f32>() / (n - lag) as f32;
    let (sd, rho) = (var.sqrt(), cov / var);
    println!("gusts σ {sigma}: std {sd:.3} m/s, autocorrelation at τ {rho:.3} (e⁻¹ = 0.368)");
    // 2000 s of gusts hold ≈ 1000 independent τ-long pieces: a few percent of sampling error.
    assert!((sd - sigma).abs() < 0.15 * sigma, "std {sd}");
    assert!((rho - (-1.0f32).exp()).abs() < 0.1, "autocorrelation {rho}");
    let mut still = Gusts::new(0.0, 1);
    still.step();
    assert!(!still.is_active() && still.value() == [0.0; 2]);
}

#[test]
fn mass_motor_and_battery_settings_reach_the_vehicle() {
    let s = Stress::from_toml_str(
        "[disturbances]\nmass_scale = 1.15\nmotor_scale = [1.0, 0.95, 1.0, 1.0]\nbattery_start_v = 3.9\n",
        "s",
    )
    .expect("s");
    let p = s.quad_params();
    let d = QuadParams::default();
    assert!((p.mass_kg - 1.15 * d.mass_kg).abs() < 1e-7);
    assert_eq!(p.motor_thrust_scale, [1.0, 0.95, 1.0, 1.0]);
    // The battery's open-circuit voltage at power-on is the key's value (the inverse of the OCV table).
    let mut world = World::default_world();
    world.stress = s;
    let drone = SimDrone::new(&world, 1, &Faults::default()).expect("drone");
    let ocv = drone.quad.battery().open_circuit_voltage();
    println!(
        "battery_start_v 3.9: OCV {ocv:.4} V, loaded {:.3} V",
        drone.quad.battery_voltage()
    );
    assert!((ocv - 3.9).abs() < 1e-3, "{ocv}");
    assert!((drone.quad.params().mass_kg - 1.15 * d.mass_kg).abs() < 1e-7);
    let table = d.battery.ocv_table_v;
    for v in [3.3f32, 3.5, 3.85, 3.9, 4.0, 4.2] {
        let soc = state_of_charge_for_ocv(&table, v);
        let mut b = cfnav_sim::physics::Battery::new(d.battery);
        b.set_state_of_charge(soc);
        assert!((b.open_circuit_voltage() - v).abs() < 1e-3, "{v} V -> soc {soc}");
    }
    // A heavier drone needs more thrust: with the motors at the default drone's hover duty it sinks.
    let heavy = Quadrotor::new(p, [2.0, 2.0, 1.0], 0.0);
    assert!(heavy.params().hover_thrust_per_motor_n() > d.hover_thrust_per_motor_n() * 1.14);
}

/// A whole mission under the single-key upper values of the spec's example ends without a panic, and the
/// runs differ from the unstressed one (each key does something in flight).
#[test]
fn each_key_alone_changes_the_flight() {
    let world = World::default_world();
    let base = run(&world, &RunOptions::for_world(&world)).expect("runs").report;
    let mut files: Vec<PathBuf> = std::fs::read_dir(worlds_dir().join("stress-keys"))
        .expect("stress-keys/")
        .map(|e| e.expect("entry").path())
        .collect();
    files.sort();
    for path in files {
        let mut w = world.clone();
        w.stress = Stress::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let r = run(&w, &RunOptions::for_world(&w)).expect("runs").report;
        println!(
            "{}: {} {:?} in {:?} s, landings {:?}, collisions {}",
            path.file_name().and_then(|n| n.to_str()).unwrap_or("?"),
            r.outcome,
            r.reason,
            r.mission_time_s,
            r.landings
                .iter()
                .map(|l| (l.error_m * 1000.0).round() / 10.0)
                .collect::<Vec<_>>(),
            r.collisions
        );
        assert!(
            (r.mission_time_s, r.distance_m) != (base.mission_time_s, base.distance_m),
            "{}: flies exactly the unstressed run",
            path.display()
        );
    }
}
