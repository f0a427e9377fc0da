//! Exact Cortex-M4 instruction counts of the firmware's D* Lite planner on the seed scenario (and of the
//! estimator's flow and wall-anchor updates, the 1 kHz control step and a full planner slice), under QEMU.
//!
//! On `thumbv7em-none-eabihf` this is a bare-metal program for QEMU's `mps2-an386` (see `src/mcu.rs`, its
//! runtime `src/rt.rs` with the linker script `qemu-bench.x`, and `run.sh`); on the host it only prints how to run
//! it, so that `cargo clippy --workspace` and `cargo test --workspace` build it.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod control;
#[cfg(target_os = "none")]
mod map_fix;
#[cfg(target_os = "none")]
mod mcu;
#[cfg(target_os = "none")]
mod rt;

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "qemu-bench runs on a Cortex-M4 under QEMU (mps2-an386): run tools/qemu-bench/run.sh [--check]; \
         the scenario itself is tested on the host by `cargo test -p qemu-bench`"
    );
}
