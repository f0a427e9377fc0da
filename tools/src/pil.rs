//! `cfnav pil`: the unmodified firmware image on the emulated Crazyflie (processor in the loop,
//! docs/pil.md). The emulator is its own binary, `cfnav-pil`, built by `bash tools/pil/cargo.sh build`
//! (its own cargo workspace: it builds a patched rsemu); this subcommand finds it beside `cfnav` (or in the
//! sibling `debug`/`release` directory of the same target directory, or at `$CFNAV_PIL`) and runs it with
//! the arguments as given, so `cfnav pil --mission --seed 1 --json r.json --sim-json s.json` is
//! `cfnav sim --seed 1 --json s.json`'s counterpart. Exit code: the emulator's (0 passed, 1 not, 2 bad input
//! or no emulator).
//!
//! One option is this subcommand's own: `--plot FILE` (`.svg` or `.png`, with `--hover` or `--mission`) asks
//! the emulator for its `--track` file and draws it with `cfnav sim --plot`'s figure: the world, the true
//! track coloured by the image's mission state, the image's estimate (from its trace log block, through the
//! emulated radio) and the landings. The map and the planned paths stay inside the image and are not drawn.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use cfnav_sim::report::{Track, TrackPoint};

/// `cfnav pil [ARGS]...`
#[derive(clap::Args, Debug)]
pub struct PilArgs {
    /// The emulator's options, passed on unchanged (`cfnav pil --help` lists them): --elf, --world, --seed,
    /// --hover, --mission, --json, --sim-json, --serve, --speed, --fault, --log, ...; and `--plot FILE`
    /// (.svg or .png; with --hover or --mission): the flight drawn as `cfnav sim --plot` draws a run.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, value_name = "ARGS")]
    pub args: Vec<OsString>,
}

/// The places `cfnav-pil` may be, in order: `$CFNAV_PIL`, beside `exe`, then in the sibling profile
/// directories of the same target directory.
pub fn candidates(exe: &Path, env: Option<PathBuf>) -> Vec<PathBuf> {
    let name = format!("cfnav-pil{}", std::env::consts::EXE_SUFFIX);
    let mut out: Vec<PathBuf> = env.into_iter().collect();
    if let Some(dir) = exe.parent() {
        out.push(dir.join(&name));
        if let Some(target) = dir.parent() {
            for profile in ["debug", "release"] {
                let p = target.join(profile).join(&name);
                if !out.contains(&p) {
                    out.push(p);
                }
            }
        }
    }
    out
}

/// `args` without `--plot FILE` / `--plot=FILE`, and that file (the last one given). `Err` when `--plot`
/// has no value.
pub fn split_plot(args: &[OsString]) -> Result<(Vec<OsString>, Option<PathBuf>), String> {
    let mut rest = Vec::with_capacity(args.len());
    let mut plot = None;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        if a == "--plot" {
            match it.next() {
                Some(v) if !v.to_string_lossy().starts_with("--") => plot = Some(PathBuf::from(v)),
                _ => return Err("--plot needs a file name (ending in .svg or .png)".into()),
            }
        } else if let Some(v) = a.to_str().and_then(|t| t.strip_prefix("--plot=")) {
            if v.is_empty() {
                return Err("--plot needs a file name (ending in .svg or .png)".into());
            }
            plot = Some(PathBuf::from(v));
        } else {
            rest.push(a.clone());
        }
    }
    Ok((rest, plot))
}

/// Horizontal estimate error over the airborne points: (max, RMS), m.
pub fn estimate_error_m(points: &[TrackPoint]) -> (f32, f32) {
    let errors: Vec<f32> = points
        .iter()
        .filter(|p| p.airborne)
        .map(|p| (p.estimate[0] - p.truth[0]).hypot(p.estimate[1] - p.truth[1]))
        .collect();
    let max = errors.iter().copied().fold(0.0, f32::max);
    let rms = (errors.iter().map(|e| e * e).sum::<f32>() / errors.len().max(1) as f32).sqrt();
    (max, rms)
}

/// Draws `track` to `path` with the simulator's figure.
pub fn draw_track(track: &Track, path: &Path) -> Result<(), String> {
    use crate::sim::plot::{Labels, draw_labelled};
    use crate::sim::runner::{RunReport, RunResult, TracePoint};
    use cfnav_sim::world::World;

    let world = match &track.world_path {
        Some(p) => World::load(p).map_err(|e| format!("{p}: {e}"))?,
        None => World::default_world(),
    };
    let (max_err, rms_err) = estimate_error_m(&track.points);
    let landings = track.landings.clone();
    let outcome = match &track.reason {
        Some(r) => format!("{} ({r})", track.outcome),
        None => track.outcome.clone(),
    };
    let time = track
        .mission_time_s
        .map_or_else(|| "-".to_string(), |t| format!("{t:.1} s"));
    let goal = world.goal_pad_index();
    let landed: Vec<String> = landings
        .iter()
        .map(|l| {
            let pad = match l.pad {
                0 => "home".to_string(),
                i if i == goal => "goal".to_string(),
                i => format!("pad {i}"),
            };
            format!("{pad} {:.3} m{}", l.error_m, if l.on_pad { "" } else { " off pad" })
        })
        .collect();
    let clearance = track
        .min_clearance_m
        .map_or_else(|| "-".to_string(), |c| format!("{c:.2} m"));
    let labels = Labels {
        title: format!(
            "cfnav pil (the firmware image, emulated): {} \"{}\", seed {}: {outcome}, mission time {time}",
            if track.mode == "hover" {
                "hover test, world"
            } else {
                "world"
            },
            track.world,
            track.seed
        ),
        subtitle: [
            format!(
                "landing errors: {};  collisions {}, min clearance {clearance};  end state {}",
                if landed.is_empty() {
                    "none".to_string()
                } else {
                    landed.join(", ")
                },
                track.collisions,
                track.mission_state.map_or_else(|| "-".to_string(), |s| s.to_string())
            ),
            format!(
                "flown {:.1} m;  estimate error max {max_err:.2} m, rms {rms_err:.2} m (the image's trace block, airborne);  \
                 {:.1} s virtual in {:.0} s wall",
                track.distance_m, track.virtual_s, track.wall_s
            ),
        ],
        world_known: true,
    };
    let result = RunResult {
        report: RunReport {
            seed: track.seed,
            mission_time_s: track.mission_time_s,
            collisions: track.collisions,
            min_clearance_m: track.min_clearance_m,
            landings,
            distance_m: track.distance_m,
            sim_time_s: track.virtual_s,
            wall_time_s: track.wall_s,
            mission_state: track.mission_state.and_then(|s| u8::try_from(s).ok()).unwrap_or(0),
            max_estimate_error_m: max_err,
            rms_estimate_error_m: rms_err,
            ..RunReport::without_flight(
                track.world.clone(),
                "emulated",
                if track.mode == "hover" { "hover" } else { "round_trip" },
            )
        },
        trace: track
            .points
            .iter()
            .map(|p| TracePoint {
                t_s: p.t_s,
                truth: p.truth,
                estimate: p.estimate,
                state: p.state,
            })
            .collect(),
        paths: Vec::new(),
        believed: None,
        pad_locks: Vec::new(),
    };
    draw_labelled(&world, &result, path, Some(&labels))
}

pub fn run_cli(args: &PilArgs) -> ExitCode {
    let (pass_on, plot) = match split_plot(&args.args) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    if let Some(p) = &plot {
        let ext = p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        if !matches!(ext.as_deref(), Some("svg" | "png")) {
            eprintln!(
                "error: {}: cannot plot to this file; expected a name ending in .svg or .png",
                p.display()
            );
            return ExitCode::from(2);
        }
    }
    let track_path = plot
        .as_ref()
        .map(|_| std::env::temp_dir().join(format!("cfnav-pil-track-{}.json", std::process::id())));
    let mut pass_on = pass_on;
    if let Some(t) = &track_path {
        pass_on.push(OsString::from("--track"));
        pass_on.push(t.clone().into_os_string());
    }
    let code = run_emulator(&pass_on);
    if let (Some(plot), Some(t)) = (plot, track_path) {
        let drawn = std::fs::read_to_string(&t)
            .map_err(|e| format!("the emulator wrote no track ({e})"))
            .and_then(|text| serde_json::from_str::<Track>(&text).map_err(|e| format!("reading the track: {e}")))
            .and_then(|track| draw_track(&track, &plot));
        let _ = std::fs::remove_file(&t);
        match drawn {
            Ok(()) => println!("plot written to {}", plot.display()),
            // Bad input already said why (exit 2); otherwise the figure's failure is this command's.
            Err(e) if code != ExitCode::from(2) => {
                eprintln!("error: {}: {e}", plot.display());
                return ExitCode::from(2);
            }
            Err(_) => {}
        }
    }
    code
}

/// Runs `cfnav-pil` with `args`; its exit code.
fn run_emulator(args: &[OsString]) -> ExitCode {
    let exe = std::env::current_exe().unwrap_or_default();
    let env = std::env::var_os("CFNAV_PIL").map(PathBuf::from);
    let Some(pil) = candidates(&exe, env).into_iter().find(|p| p.is_file()) else {
        eprintln!(
            "error: the emulator (cfnav-pil) is not built: run `bash tools/pil/cargo.sh build` in the repository \
             (it builds target/debug/cfnav-pil), or point CFNAV_PIL at it"
        );
        return ExitCode::from(2);
    };
    match std::process::Command::new(&pil).args(args).status() {
        Ok(status) => match status.code() {
            Some(code) => ExitCode::from(u8::try_from(code).unwrap_or(2)),
            // Killed by a signal: not a verdict.
            None => ExitCode::from(2),
        },
        Err(e) => {
            eprintln!("error: running {}: {e}", pil.display());
            ExitCode::from(2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_emulator_is_looked_for_by_override_then_beside_cfnav_then_in_the_other_profile() {
        let exe = Path::new("/repo/target/release/cfnav");
        let name = format!("cfnav-pil{}", std::env::consts::EXE_SUFFIX);
        assert_eq!(
            candidates(exe, Some(PathBuf::from("/opt/cfnav-pil"))),
            vec![
                PathBuf::from("/opt/cfnav-pil"),
                PathBuf::from("/repo/target/release").join(&name),
                PathBuf::from("/repo/target/debug").join(&name),
            ]
        );
        // Beside a debug `cfnav` the debug emulator is not listed twice.
        assert_eq!(
            candidates(Path::new("/t/debug/cfnav"), None),
            vec![
                PathBuf::from("/t/debug").join(&name),
                PathBuf::from("/t/release").join(&name),
            ]
        );
    }

    fn os(v: &[&str]) -> Vec<OsString> {
        v.iter().map(OsString::from).collect()
    }

    #[test]
    fn plot_is_taken_out_of_the_emulators_arguments() {
        let (rest, plot) = split_plot(&os(&["--mission", "--plot", "a.svg", "--seed", "2"])).unwrap();
        assert_eq!(rest, os(&["--mission", "--seed", "2"]));
        assert_eq!(plot, Some(PathBuf::from("a.svg")));
        let (rest, plot) = split_plot(&os(&["--plot=b.png", "--hover"])).unwrap();
        assert_eq!((rest, plot), (os(&["--hover"]), Some(PathBuf::from("b.png"))));
        assert_eq!(split_plot(&os(&["--hover"])).unwrap(), (os(&["--hover"]), None));
        for bad in [&["--plot"][..], &["--plot", "--hover"], &["--plot="]] {
            assert!(split_plot(&os(bad)).is_err(), "{bad:?}");
        }
    }

    fn point(t_s: f64, truth: [f32; 3], estimate: [f32; 3], airborne: bool, state: u8) -> TrackPoint {
        TrackPoint {
            t_s,
            truth,
            estimate,
            airborne,
            state,
        }
    }

    #[test]
    fn the_estimate_error_counts_only_airborne_points() {
        let points = [
            point(0.0, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], false, 0),
            point(0.1, [1.0, 1.0, 0.5], [1.03, 1.04, 0.5], true, 11),
            point(0.2, [2.0, 1.0, 0.5], [2.0, 1.0, 0.5], true, 11),
        ];
        let (max, rms) = estimate_error_m(&points);
        assert!((max - 0.05).abs() < 1e-5, "{max}");
        assert!((rms - (0.05f32 * 0.05 / 2.0).sqrt()).abs() < 1e-5, "{rms}");
        assert_eq!(estimate_error_m(&[]), (0.0, 0.0));
    }

    #[test]
    fn a_track_is_drawn_with_the_simulators_figure() {
        let world = cfnav_sim::world::World::default_world();
        let s = world.mission.start;
        let g = world.mission.goal;
        let points: Vec<TrackPoint> = (0..=100)
            .map(|k| {
                let f = k as f32 / 100.0;
                let at = [s[0] + (g[0] - s[0]) * f, s[1] + (g[1] - s[1]) * f, 0.5];
                point(
                    f64::from(f) * 20.0,
                    at,
                    [at[0] + 0.02, at[1], at[2]],
                    true,
                    if k < 90 { 11 } else { 15 },
                )
            })
            .collect();
        let track = Track {
            world_path: None,
            world: world.name.clone(),
            seed: 3,
            mode: "round_trip".into(),
            outcome: "aborted".into(),
            reason: Some("pad_not_found".into()),
            mission_time_s: Some(20.0),
            mission_state: Some(202),
            collisions: 0,
            min_clearance_m: Some(0.31),
            landings: vec![cfnav_sim::report::Landing {
                pad: 1,
                error_m: 0.012,
                on_pad: true,
            }],
            distance_m: 3.5,
            virtual_s: 25.0,
            wall_s: 300.0,
            points,
        };
        let dir = std::env::temp_dir().join(format!("cfnav-pil-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let svg = dir.join("t.svg");
        draw_track(&track, &svg).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("cfnav pil (the firmware image, emulated)"), "title");
        assert!(
            text.contains("aborted (pad_not_found)") && text.contains("goal 0.012 m"),
            "score"
        );
        assert!(text.contains("estimate error max 0.02 m"), "estimate error");
        assert!(text.contains("position estimate"), "legend");
        draw_track(&track, &dir.join("t.png")).unwrap();
        assert!(std::fs::metadata(dir.join("t.png")).unwrap().len() > 1000);
        // A world file that does not load is an error, not a panic.
        let broken = Track {
            world_path: Some(dir.join("missing.toml").display().to_string()),
            ..track
        };
        assert!(draw_track(&broken, &svg).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
