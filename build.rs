//! The build's git revision for every target (`CFNAV_GIT_REVISION`, `CFNAV_GIT_MODIFIED`: the
//! `firmware.revision0/revision1/modified` parameters, `cfnav::system::version`), and link arguments for the
//! firmware binary only, and only when building for the MCU.
use std::{env, fs, path::PathBuf, process::Command};

/// `git args...` in the crate's directory: its trimmed stdout, `None` when git is missing or fails (a
/// source tarball: the revision then reads 0).
fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// Exports the revision as stock's `tools/make/versionTemplate.py` derives it: the 40-digit hash of HEAD and
/// whether the firmware's tracked inputs differ from it. Rebuilt when HEAD, the branch it names or the index changes.
fn git_revision() {
    let revision = git(&["rev-parse", "HEAD"])
        .filter(|r| r.len() >= 12 && r.bytes().all(|b| b.is_ascii_hexdigit()))
        .unwrap_or_default();
    // "Modified" counts the firmware's own inputs (the host tools and tests are other packages), each also
    // watched below so the flag is recomputed whenever one of them changes.
    let mut status = vec!["status", "--porcelain", "--untracked-files=no", "--"];
    status.extend_from_slice(FIRMWARE_INPUTS);
    let modified = git(&status).is_some_and(|s| !s.is_empty());
    println!("cargo:rustc-env=CFNAV_GIT_REVISION={revision}");
    println!("cargo:rustc-env=CFNAV_GIT_MODIFIED={}", u8::from(modified));
    for path in [
        git(&["rev-parse", "--git-path", "HEAD"]),
        git(&["rev-parse", "--git-path", "index"]),
        git(&["rev-parse", "--symbolic-full-name", "HEAD"]).and_then(|r| git(&["rev-parse", "--git-path", &r])),
    ]
    .into_iter()
    .flatten()
    .chain(FIRMWARE_INPUTS.iter().map(|p| p.to_string()))
    {
        println!("cargo:rerun-if-changed={path}");
    }
}

/// What the firmware is built from (the `firmware.modified` flag looks at these).
const FIRMWARE_INPUTS: &[&str] = &["src", "build.rs", "Cargo.toml", "memory.x"];

fn main() {
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    git_revision();
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("memory.x is next to build.rs");
    println!("cargo:rustc-link-search={}", out.display());
    // Without --nmagic rust-lld emits a LOAD segment holding the ELF headers at 0x08000000, inside the
    // bootloader's sector, because FLASH starts at 0x08004000 (see `docs/hardware.md` §1).
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
