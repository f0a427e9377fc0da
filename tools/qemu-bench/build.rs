//! Link the benchmark binary for QEMU's mps2-an386, for the MCU only: `memory.x` (4 MB code at 0x0, 4 MB RAM at
//! 0x2000_0000) and cortex-m-rt's linker script go to OUT_DIR, and the binary is linked with `-T<OUT_DIR>/link.x`.
//!
//! Both are named by absolute path: rust-lld looks up a linker script's `INCLUDE memory.x` in its working directory
//! (the workspace root, which holds the Crazyflie's memory.x) before any `-L` directory, so a plain `-Tlink.x` with
//! cortex-m-rt's script would link the benchmark at the Crazyflie's 0x0800_4000, where mps2-an386 has no memory.
//! `cortex-m-rt-link.x` is therefore cortex-m-rt's script with its `INCLUDE` pointed at this crate's memory.x.
use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=cortex-m-rt-link.x");
    println!("cargo:rerun-if-changed=build.rs");
    let target = env::var("TARGET").unwrap_or_default();
    if !target.starts_with("thumb") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let memory = out.join("memory.x");
    fs::copy("memory.x", &memory).expect("memory.x is next to build.rs");
    let template = fs::read_to_string("cortex-m-rt-link.x").expect("cortex-m-rt-link.x is next to build.rs");
    const PLACEHOLDER: &str = "@MEMORY_X@";
    assert_eq!(
        template.matches(PLACEHOLDER).count(),
        1,
        "cortex-m-rt-link.x must INCLUDE \"{PLACEHOLDER}\" once"
    );
    let memory_path = memory.to_str().expect("OUT_DIR is valid UTF-8");
    assert!(!memory_path.contains('"'), "OUT_DIR must not contain a double quote");
    let link = out.join("link.x");
    fs::write(&link, template.replace(PLACEHOLDER, memory_path)).expect("OUT_DIR is writable");
    println!("cargo:rustc-link-arg-bins=-T{}", link.display());
}
