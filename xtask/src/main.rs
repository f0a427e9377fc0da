//! cfnav's CI as named steps, run by `bash .ci/run` (which first installs the toolchain pieces and apt
//! packages a fresh machine lacks) or directly:
//!
//! ```text
//! cargo xtask ci                 every step, in order
//! cargo xtask ci --list          the steps' names and what each checks
//! cargo xtask ci --only A B      just those steps (in CI's order)
//! cargo xtask bless STEP...      run those steps and rewrite their ci/expected/ files from the run
//! ```
//!
//! A failed step does not stop the others (each says why it failed); the run ends with a table of the steps
//! and exits 1 if any failed. The emulator's runs start in the background at the `pil` step and are judged
//! after the other steps (their checks are `cfnav-pil --check NAME`, tools/pil/src/verdict.rs).
//! No step asserts an absolute time or rate; wall times are printed only.

mod expected;
mod readme;
mod steps;

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use steps::{Ci, STEPS};

fn usage() -> &'static str {
    "usage: cargo xtask ci [--list] [--only STEP...]\n       cargo xtask bless STEP...\n"
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (bless, names): (bool, Vec<String>) = match args.first().map(String::as_str) {
        Some("ci") => match args.get(1).map(String::as_str) {
            None => (false, Vec::new()),
            Some("--list") if args.len() == 2 => {
                for s in STEPS {
                    println!("{:<18} {}", s.name, s.about);
                }
                return ExitCode::SUCCESS;
            }
            Some("--only") if args.len() > 2 => (false, args[2..].to_vec()),
            _ => {
                eprint!("{}", usage());
                return ExitCode::from(2);
            }
        },
        Some("bless") if args.len() > 1 => {
            let names = args[1..].to_vec();
            if let Some(n) = names.iter().find(|n| !steps::BLESSABLE.contains(&n.as_str())) {
                eprintln!(
                    "`{n}` has no expected file (blessable steps: {})",
                    steps::BLESSABLE.join(", ")
                );
                return ExitCode::from(2);
            }
            (true, names)
        }
        _ => {
            eprint!("{}", usage());
            return ExitCode::from(2);
        }
    };
    if let Some(n) = names.iter().find(|n| !STEPS.iter().any(|s| s.name == n.as_str())) {
        eprintln!("no step named `{n}` (`cargo xtask ci --list` lists them)");
        return ExitCode::from(2);
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask/ sits in the repository")
        .to_path_buf();
    let mut ci = Ci::new(root, bless);
    let selected: Vec<_> = STEPS
        .iter()
        .filter(|s| names.is_empty() || names.iter().any(|n| n == s.name))
        .collect();
    let started = Instant::now();
    let mut results: Vec<(&str, Result<(), String>, u64)> = Vec::new();
    for s in &selected {
        ci.section(s.name, s.about);
        let t = Instant::now();
        let r = (s.run)(&mut ci);
        if let Err(e) = &r {
            println!("FAILED {}: {e}", s.name);
        }
        results.push((s.name, r, t.elapsed().as_secs()));
    }
    // The background work the steps left (the emulator queue's checks), in the order it was started.
    for (name, about, finish) in ci.take_deferred() {
        ci.section(name, about);
        let t = Instant::now();
        let r = finish(&mut ci);
        if let Err(e) = &r {
            println!("FAILED {name}: {e}");
        }
        results.push((name, r, t.elapsed().as_secs()));
    }
    ci.stop_background();
    println!("\n=== summary");
    let mut failed = 0;
    for (name, r, secs) in &results {
        let verdict = if r.is_ok() { "ok" } else { "FAILED" };
        println!("{name:<18} {verdict:<7} {secs:>5} s");
        failed += usize::from(r.is_err());
    }
    let total = started.elapsed().as_secs();
    if failed == 0 {
        println!("CI passed in {total} s");
        ExitCode::SUCCESS
    } else {
        println!("CI failed ({failed} step(s)) in {total} s");
        ExitCode::from(1)
    }
}
