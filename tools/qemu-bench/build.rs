//! Link the benchmark binary for QEMU's mps2-an386, for the MCU only, with this crate's own linker script
//! `qemu-bench.x` (memory map, sections, vector table; see also `src/rt.rs`).
//!
//! The script is named by absolute path and includes no other file: rust-lld resolves a relative `-T` or
//! `INCLUDE` against its working directory (the workspace root, which holds the Crazyflie's memory.x at
//! 0x0800_4000, where mps2-an386 has no memory) before any `-L` directory.
use std::{env, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=qemu-bench.x");
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let dir = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let script = dir.join("qemu-bench.x");
    assert!(script.is_file(), "{} is missing", script.display());
    println!("cargo:rustc-link-arg-bins=-T{}", script.display());
}
