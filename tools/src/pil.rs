//! `cfnav pil`: the unmodified firmware image on the emulated Crazyflie (processor in the loop, issue 15;
//! docs/pil.md). The emulator is its own binary, `cfnav-pil`, built by `bash tools/pil/cargo.sh build`
//! (its own cargo workspace: it builds a patched rsemu); this subcommand finds it beside `cfnav` (or in the
//! sibling `debug`/`release` directory of the same target directory, or at `$CFNAV_PIL`) and runs it with
//! the arguments as given, so `cfnav pil --mission --seed 1 --json r.json --sim-json s.json` is
//! `cfnav sim --seed 1 --json s.json`'s counterpart. Exit code: the emulator's (0 passed, 1 not, 2 bad input
//! or no emulator).

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// `cfnav pil [ARGS]...`
#[derive(clap::Args, Debug)]
pub struct PilArgs {
    /// The emulator's options, passed on unchanged (`cfnav pil --help` lists them): --elf, --world, --seed,
    /// --hover, --mission, --json, --sim-json, --serve, --speed, --fault, --log, ...
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

pub fn run_cli(args: &PilArgs) -> ExitCode {
    let exe = std::env::current_exe().unwrap_or_default();
    let env = std::env::var_os("CFNAV_PIL").map(PathBuf::from);
    let Some(pil) = candidates(&exe, env).into_iter().find(|p| p.is_file()) else {
        eprintln!(
            "error: the emulator (cfnav-pil) is not built: run `bash tools/pil/cargo.sh build` in the repository \
             (it builds target/debug/cfnav-pil), or point CFNAV_PIL at it"
        );
        return ExitCode::from(2);
    };
    match std::process::Command::new(&pil).args(&args.args).status() {
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
}
