//! `cfnav sim`: fly the round-trip mission in the simulator (docs/formats.md (commands, report format)).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use cfnav::mission::{COVERAGE_RANGE, HOVER_TIME_RANGE_S, MissionMode};
use clap::Args;
use serde::{Deserialize, Serialize};

use cfnav::mission::link_loss::LinkLossConfig;

use crate::sim::runner::{RunOptions, RunReport, RunResult, run};
use cfnav_sim::stress::Stress;
use cfnav_sim::world::{Generator, World};

/// Arguments of `cfnav sim`.
#[derive(Args, Debug)]
pub struct SimArgs {
    /// A world file (TOML, docs/formats.md (world files)); without it the built-in default world flies.
    #[arg(long)]
    pub world: Option<PathBuf>,
    /// Fly N generated worlds instead, with a progress bar and a summary table.
    #[arg(long, value_name = "N")]
    pub random: Option<usize>,
    /// Fly the single generated world of this seed (as listed in a --random report's `seed`), e.g. to
    /// look at one run of a batch with --plot or --verbose.
    #[arg(long, value_name = "SEED")]
    pub random_world: Option<u64>,
    /// Seed: of the generated worlds with --random, else of the noise (overrides the world's sim.seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Apply the `[sensors]` and `[disturbances]` tables of FILE (a world file, or a file with only those
    /// tables) to every world flown: each key FILE sets replaces the world's own (docs/formats.md (commands, world files)).
    #[arg(long, value_name = "FILE")]
    pub stress: Option<PathBuf>,
    /// The random-world generator of --random and --random-world: `wide` (the default) or
    /// `classic` (the worlds of the figures before it, seed for seed).
    #[arg(long, value_enum, default_value_t = Generator::Wide)]
    pub generator: Generator,
    /// Write the JSON report here (`-` for stdout).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Draw the arena, the believed map, the paths and the track (.svg or .png).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Inject a flow-deck failure at this time, s (fault scenario).
    #[arg(long, value_name = "S")]
    pub flow_fails_at: Option<f64>,
    /// The Multi-ranger stops delivering sweeps at this time, s (its deck lost in flight).
    #[arg(long, value_name = "S")]
    pub ranger_fails_at: Option<f64>,
    /// Write `mission.start = 0` at this time, s (abort scenario).
    #[arg(long, value_name = "S")]
    pub abort_at: Option<f64>,
    /// The radio link goes silent at this time, s of simulated time (link-loss scenario; the simulated link
    /// delivers a packet every 10 ms until then).
    #[arg(long, value_name = "S")]
    pub link_loss_at: Option<f64>,
    /// `mission.linkLoss` for the run: 0 go on (default), 1 land where it is, 2 return home and land.
    #[arg(long, value_name = "POLICY", default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=2))]
    pub link_loss: u8,
    /// `mission.linkTimeout` for the run, s (0.5..60, default 2).
    #[arg(long, value_name = "S")]
    pub link_timeout: Option<f32>,
    /// Print every mission state change to stderr.
    #[arg(long)]
    pub verbose: bool,
    /// Serve CRTP over UDP on 127.0.0.1:PORT in (a multiple of) real time instead of flying at once; nothing
    /// flies until a client writes `mission.start`; runs until interrupted.
    #[arg(long)]
    pub serve: bool,
    /// With --serve: write the simulated drone's own map (JSON, read through the grid's queries) to FILE
    /// whenever a client starts downloading the map memory and when a mission ends (`cfnav map` compares).
    #[arg(long, value_name = "FILE", requires = "serve")]
    pub map_json: Option<PathBuf>,
    /// UDP port for --serve.
    #[arg(long, default_value_t = 19850)]
    pub port: u16,
    /// Speed factor for --serve (1 = real time).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// The mission to fly (`mission.mode`): `round-trip` (0, the default), `hover` (1, the hover test) or
    /// `explore` (2, frontier exploration, then home). With --serve, write `mission.mode` instead.
    #[arg(long, value_enum, default_value_t = ModeArg::RoundTrip)]
    pub mode: ModeArg,
    /// `mission.hoverTime` for --mode hover, s (1..60; default 5).
    #[arg(long, value_name = "S")]
    pub hover_time: Option<f32>,
    /// `mission.coverage` for --mode explore: the known fraction of the arena's cells that ends the
    /// exploration (0.05..1; default 0.8).
    #[arg(long, value_name = "FRACTION")]
    pub coverage: Option<f32>,
    /// For --serve: the drone's 8 KB EEPROM as a file, where persistent parameters are kept across runs
    /// (created when missing). Default: an EEPROM in memory, blank at every start.
    #[arg(long, value_name = "FILE")]
    pub param_store: Option<std::path::PathBuf>,
}

/// `--mode`: the values of `mission.mode`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModeArg {
    /// 0: the round trip.
    RoundTrip,
    /// 1: the hover test.
    Hover,
    /// 2: frontier exploration.
    Explore,
}

impl ModeArg {
    fn mode(self) -> MissionMode {
        match self {
            Self::RoundTrip => MissionMode::RoundTrip,
            Self::Hover => MissionMode::HoverTest,
            Self::Explore => MissionMode::Explore,
        }
    }
}

/// Copies `--mode`, `--hover-time` and `--coverage` into `options`, refusing values outside the parameters'
/// ranges (bad input).
fn apply_mode(args: &SimArgs, options: &mut RunOptions) -> Result<(), String> {
    let within = |v: f32, (lo, hi): (f32, f32)| v >= lo && v <= hi;
    if let Some(t) = args.hover_time
        && !within(t, HOVER_TIME_RANGE_S)
    {
        return Err(format!(
            "--hover-time {t}: expected {} to {} s",
            HOVER_TIME_RANGE_S.0, HOVER_TIME_RANGE_S.1
        ));
    }
    if let Some(c) = args.coverage
        && !within(c, COVERAGE_RANGE)
    {
        return Err(format!(
            "--coverage {c}: expected {} to {}",
            COVERAGE_RANGE.0, COVERAGE_RANGE.1
        ));
    }
    options.mode = args.mode.mode();
    options.hover_time_s = args.hover_time;
    options.coverage = args.coverage;
    Ok(())
}

/// The `--random` report's summary (docs/formats.md, report format).
#[derive(Serialize, Deserialize, Debug, PartialEq)]
pub struct Summary {
    pub runs: usize,
    pub completed: usize,
    pub collisions: u32,
    pub median_mission_time_s: Option<f64>,
    pub median_landing_error_m: Option<f32>,
    pub p95_landing_error_m: Option<f32>,
    pub completed_fraction: f64,
    pub sim_seconds_per_wall_second: f64,
    /// Worlds whose arena has more cells than the default firmware build maps (120 × 60): only the
    /// `large-arena` build, which the simulator flies, can fly them.
    pub large_arena_runs: usize,
    /// Runs that ended by crossing an open side of the arena (reason `left_arena`).
    pub left_arena_runs: usize,
    /// Landings whose centre did not come to rest over the pad.
    pub off_pad_landings: usize,
    /// Median and largest RMS horizontal estimate error per run (airborne), m.
    pub median_rms_estimate_error_m: Option<f32>,
    pub max_estimate_error_m: Option<f32>,
}

#[derive(Serialize)]
struct BatchReport<'a> {
    runs: &'a [RunReport],
    summary: &'a Summary,
}

fn fail(msg: impl std::fmt::Display) -> ExitCode {
    eprintln!("error: {msg}");
    ExitCode::from(2)
}

fn write_json(path: &PathBuf, value: &impl Serialize) -> Result<(), String> {
    let text = serde_json::to_string_pretty(value).map_err(|e| format!("cannot encode the report: {e}"))?;
    if path.as_os_str() == "-" {
        println!("{text}");
        Ok(())
    } else {
        std::fs::write(path, text + "\n").map_err(|e| format!("{}: cannot write: {e}", path.display()))
    }
}

fn median<T: Copy + PartialOrd>(mut v: Vec<T>) -> Option<T> {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    v.get(v.len() / 2).copied()
}

fn percentile(mut v: Vec<f32>, p: f64) -> Option<f32> {
    v.sort_by(f32::total_cmp);
    if v.is_empty() {
        return None;
    }
    let i = ((v.len() - 1) as f64 * p).round() as usize;
    v.get(i).copied()
}

/// The batch summary of `--random`.
pub fn summarise(reports: &[RunReport], wall_s: f64) -> Summary {
    let completed: Vec<&RunReport> = reports.iter().filter(|r| r.outcome == "completed").collect();
    let errors: Vec<f32> = completed
        .iter()
        .flat_map(|r| r.landings.iter().map(|l| l.error_m))
        .collect();
    let sim_s: f64 = reports.iter().map(|r| r.sim_time_s).sum();
    Summary {
        runs: reports.len(),
        completed: completed.len(),
        collisions: reports.iter().map(|r| r.collisions).sum(),
        median_mission_time_s: median(completed.iter().filter_map(|r| r.mission_time_s).collect()),
        median_landing_error_m: median(errors.clone()),
        p95_landing_error_m: percentile(errors, 0.95),
        completed_fraction: if reports.is_empty() {
            0.0
        } else {
            completed.len() as f64 / reports.len() as f64
        },
        sim_seconds_per_wall_second: if wall_s > 0.0 { sim_s / wall_s } else { 0.0 },
        large_arena_runs: reports.iter().filter(|r| r.needs_large_arena).count(),
        left_arena_runs: reports.iter().filter(|r| r.reason == Some("left_arena")).count(),
        off_pad_landings: reports
            .iter()
            .flat_map(|r| r.landings.iter())
            .filter(|l| !l.on_pad)
            .count(),
        median_rms_estimate_error_m: median(reports.iter().map(|r| r.rms_estimate_error_m).collect()),
        max_estimate_error_m: reports.iter().map(|r| r.max_estimate_error_m).reduce(f32::max),
    }
}

fn one_line(r: &RunReport) -> String {
    let landings: Vec<String> = r
        .landings
        .iter()
        .map(|l| {
            format!(
                "pad {} {:.1} cm{}",
                l.pad,
                l.error_m * 100.0,
                if l.on_pad { "" } else { " OFF" }
            )
        })
        .collect();
    format!(
        "{}: {}{} in {} s (sim {:.1} s, wall {:.2} s), landings [{}], collisions {}, min clearance {}, replans {}, estimate error max {:.1} cm",
        r.world,
        r.outcome,
        r.reason.map(|x| format!(" ({x})")).unwrap_or_default(),
        r.mission_time_s.map_or("-".into(), |t| format!("{t:.1}")),
        r.sim_time_s,
        r.wall_time_s,
        landings.join(", "),
        r.collisions,
        r.min_clearance_m.map_or("-".into(), |c| format!("{:.2} m", c)),
        r.replans,
        r.max_estimate_error_m * 100.0,
    ) + &mode_line(r)
}

/// The mode's figures for the one-line summary (empty for the round trip).
fn mode_line(r: &RunReport) -> String {
    if let Some(h) = &r.hover {
        return format!(
            ", hover {:.1} s: deviation xy {:.1} cm, z {:.1} cm (truth {:.1} cm, {:.1} cm)",
            h.held_s,
            h.dev_xy_m * 100.0,
            h.dev_z_m * 100.0,
            h.true_dev_xy_m * 100.0,
            h.true_dev_z_m * 100.0
        );
    }
    if let Some(e) = &r.explore {
        return format!(
            ", explored {:.0} % of the cells ({:.0} % of the free ones) in {} s, end {}, frontiers {} reached, {} dropped",
            e.coverage * 100.0,
            e.true_free_known * 100.0,
            e.explore_time_s.map_or("-".into(), |t| format!("{t:.1}")),
            e.end.unwrap_or("-"),
            e.frontiers_reached,
            e.frontiers_dropped
        );
    }
    String::new()
}

/// `cfnav sim`.
pub fn run_cli(args: &SimArgs) -> ExitCode {
    let stress = match &args.stress {
        Some(path) => match Stress::load(path) {
            Ok(s) => Some(s),
            Err(e) => return fail(e),
        },
        None => None,
    };
    if args.param_store.is_some() && !args.serve {
        return fail("--param-store applies to --serve only");
    }
    if args.serve {
        return run_serve(args, stress.as_ref());
    }
    if let Some(n) = args.random {
        if args.world.is_some() {
            return fail("--random generates its own worlds; drop --world");
        }
        if let Err(e) = link_loss_options(args) {
            return fail(e);
        }
        return run_random(n, args.seed.unwrap_or(0), args, stress.as_ref());
    }
    let mut world = match (&args.world, args.random_world) {
        (Some(_), Some(_)) => return fail("--world and --random-world exclude each other"),
        (Some(path), None) => match World::load(path) {
            Ok(w) => w,
            Err(e) => return fail(e),
        },
        (None, Some(seed)) => World::random_with(args.generator, seed),
        (None, None) => World::default_world(),
    };
    if let Some(s) = &stress {
        world.stress = world.stress.overlaid(s);
    }
    let mut options = RunOptions::for_world(&world);
    if let Some(s) = args.random_world {
        options.seed = s;
    }
    if let Some(s) = args.seed {
        options.seed = s;
    }
    options.record = args.plot.is_some();
    options.verbose = args.verbose;
    options.faults.flow_fails_at_s = args.flow_fails_at;
    if let Some(t) = args.ranger_fails_at
        && !(t.is_finite() && t >= 0.0)
    {
        return fail(format!("--ranger-fails-at: expected a time >= 0 s, got {t}"));
    }
    options.faults.ranger_fails_at_s = args.ranger_fails_at;
    options.faults.abort_at_s = args.abort_at;
    if let Err(e) = apply_mode(args, &mut options) {
        return fail(e);
    }
    match link_loss_options(args) {
        Ok((at, config)) => {
            options.faults.link_loss_at_s = at;
            options.link_loss = config;
        }
        Err(e) => return fail(e),
    }
    let result = match run(&world, &options) {
        Ok(r) => r,
        Err(e) => return fail(e),
    };
    println!("{}", one_line(&result.report));
    if let Some(path) = &args.json
        && let Err(e) = write_json(path, &result.report)
    {
        return fail(e);
    }
    if let Some(path) = &args.plot
        && let Err(e) = crate::sim::plot::draw(&world, &result, path)
    {
        return fail(e);
    }
    ExitCode::from(if result.report.outcome == "completed" { 0 } else { 1 })
}

/// `--link-loss-at`, `--link-loss`, `--link-timeout`: the silence time and the parameters, checked.
fn link_loss_options(args: &SimArgs) -> Result<(Option<f64>, LinkLossConfig), String> {
    use cfnav::mission::link_loss::{LinkLossPolicy, MAX_LINK_TIMEOUT_S, MIN_LINK_TIMEOUT_S};
    if let Some(t) = args.link_loss_at
        && !(t.is_finite() && t >= 0.0)
    {
        return Err(format!("--link-loss-at: expected a time >= 0 s, got {t}"));
    }
    let mut config = LinkLossConfig::DEFAULT;
    config.policy = LinkLossPolicy::from_code(args.link_loss)
        .ok_or_else(|| format!("--link-loss: expected 0, 1 or 2, got {}", args.link_loss))?;
    if let Some(t) = args.link_timeout {
        if !(MIN_LINK_TIMEOUT_S..=MAX_LINK_TIMEOUT_S).contains(&t) {
            return Err(format!(
                "--link-timeout: expected {MIN_LINK_TIMEOUT_S}..{MAX_LINK_TIMEOUT_S} s, got {t}"
            ));
        }
        config.timeout_s = t;
    }
    Ok((args.link_loss_at, config))
}

/// `cfnav sim --serve [--port P] [--world FILE | --random-world SEED] [--speed X] [--stress FILE]
/// [--param-store FILE]`.
fn run_serve(args: &SimArgs, stress: Option<&Stress>) -> ExitCode {
    if args.random.is_some() {
        return fail("--serve flies one world; drop --random");
    }
    if args.json.is_some()
        || args.plot.is_some()
        || args.flow_fails_at.is_some()
        || args.ranger_fails_at.is_some()
        || args.abort_at.is_some()
    {
        return fail("--json, --plot, --flow-fails-at, --ranger-fails-at and --abort-at do not apply to --serve");
    }
    if args.mode != ModeArg::RoundTrip || args.hover_time.is_some() || args.coverage.is_some() {
        return fail(
            "--mode, --hover-time and --coverage do not apply to --serve: write mission.mode, mission.hoverTime, mission.coverage",
        );
    }
    if args.link_loss_at.is_some() || args.link_loss != 0 || args.link_timeout.is_some() {
        return fail(
            "--link-loss-at, --link-loss and --link-timeout do not apply to --serve (the client's packets are the \
             link; it writes mission.linkLoss and mission.linkTimeout)",
        );
    }
    let mut world = match (&args.world, args.random_world) {
        (Some(_), Some(_)) => return fail("--world and --random-world exclude each other"),
        (Some(path), None) => match World::load(path) {
            Ok(w) => w,
            Err(e) => return fail(e),
        },
        (None, Some(seed)) => World::random_with(args.generator, seed),
        (None, None) => World::default_world(),
    };
    if let Some(s) = stress {
        world.stress = world.stress.overlaid(s);
    }
    match crate::sim::serve::serve(
        &world,
        args.port,
        args.speed,
        args.param_store.as_deref(),
        args.map_json.as_deref(),
    ) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => fail(e),
    }
}

fn run_random(n: usize, seed: u64, args: &SimArgs, stress: Option<&Stress>) -> ExitCode {
    let mut mode_options = RunOptions::for_world(&World::default_world());
    if let Err(e) = apply_mode(args, &mut mode_options) {
        return fail(e);
    }
    let started = std::time::Instant::now();
    let bar = indicatif::ProgressBar::new(n as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} worlds, {elapsed} elapsed, {eta} left {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<RunReport>>> = Mutex::new((0..n).map(|_| None).collect());
    let errors: Mutex<Vec<String>> = Mutex::new(Vec::new());
    let workers = std::thread::available_parallelism()
        .map_or(1, |p| p.get())
        .min(n.max(1));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n {
                        break;
                    }
                    let world_seed = seed.wrapping_mul(1_000_003).wrapping_add(i as u64);
                    let mut world = World::random_with(args.generator, world_seed);
                    if let Some(s) = stress {
                        world.stress = world.stress.overlaid(s);
                    }
                    let mut options = RunOptions::for_world(&world);
                    options.seed = world_seed;
                    options.mode = mode_options.mode;
                    options.hover_time_s = mode_options.hover_time_s;
                    options.coverage = mode_options.coverage;
                    if let Ok((at, config)) = link_loss_options(args) {
                        options.faults.link_loss_at_s = at;
                        options.link_loss = config;
                    }
                    match run(&world, &options) {
                        Ok(RunResult { report, .. }) => {
                            if let Ok(mut r) = results.lock() {
                                r[i] = Some(report);
                            }
                        }
                        Err(e) => {
                            if let Ok(mut errs) = errors.lock() {
                                errs.push(e);
                            }
                        }
                    }
                    bar.inc(1);
                }
            });
        }
    });
    bar.finish_and_clear();
    if let Some(e) = errors.lock().ok().and_then(|e| e.first().cloned()) {
        return fail(e);
    }
    let reports: Vec<RunReport> = results.into_inner().unwrap_or_default().into_iter().flatten().collect();
    let summary = summarise(&reports, started.elapsed().as_secs_f64());
    print_table(&reports, &summary);
    if let Some(path) = &args.json
        && let Err(e) = write_json(
            path,
            &BatchReport {
                runs: &reports,
                summary: &summary,
            },
        )
    {
        return fail(e);
    }
    ExitCode::SUCCESS
}

fn print_table(reports: &[RunReport], s: &Summary) {
    let mut by_outcome: std::collections::BTreeMap<String, usize> = std::collections::BTreeMap::new();
    for r in reports {
        let key = match r.reason {
            Some(reason) => format!("{} ({reason})", r.outcome),
            None => r.outcome.to_string(),
        };
        *by_outcome.entry(key).or_default() += 1;
    }
    println!("{:<32} {:>6}", "outcome", "runs");
    for (k, v) in &by_outcome {
        println!("{k:<32} {v:>6}");
    }
    let fmt_m = |v: Option<f32>| v.map_or("-".to_string(), |x| format!("{:.1} cm", x * 100.0));
    println!("{:<32} {:>6}", "runs", s.runs);
    println!("{:<32} {:>5.1} %", "completed", 100.0 * s.completed_fraction);
    println!("{:<32} {:>6}", "collisions", s.collisions);
    println!(
        "{:<32} {:>6}",
        "median mission time",
        s.median_mission_time_s.map_or("-".into(), |t| format!("{t:.1} s"))
    );
    println!("{:<32} {:>6}", "median landing error", fmt_m(s.median_landing_error_m));
    println!("{:<32} {:>6}", "p95 landing error", fmt_m(s.p95_landing_error_m));
    println!(
        "{:<32} {:>6}",
        "median RMS estimate error",
        fmt_m(s.median_rms_estimate_error_m)
    );
    println!("{:<32} {:>6}", "worst estimate error", fmt_m(s.max_estimate_error_m));
    println!("{:<32} {:>6}", "landings off the pad", s.off_pad_landings);
    println!("{:<32} {:>6}", "worlds for the large-arena build", s.large_arena_runs);
    println!("{:<32} {:>6}", "runs that left the arena", s.left_arena_runs);
    println!(
        "{:<32} {:>6.0}×",
        "simulation speed (real time)", s.sim_seconds_per_wall_second
    );
}
