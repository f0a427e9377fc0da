//! cfnav: the pure, deterministic algorithm core of a standalone Crazyflie 2.1 navigation firmware.
//!
//! Everything here is `no_std`, allocation-free and sized at compile time, so the same code runs on the
//! STM32F405 (see `src/main.rs`), in the host simulator (`tools/`) and in `cargo test -p host-tests`.
//! Each module is a sans-IO state machine: inputs and time go in, outputs come out; nothing here touches a
//! peripheral or reads a clock.
//!
//! Frames: the *arena frame* has its origin at the arena's lower-left corner on the floor, x to the right,
//! y up the page, z up, metres. Grid cells are 5 cm squares indexed `(x, y)` from that corner.
#![no_std]
#![warn(missing_docs)]

pub mod avoidance;
pub mod config_block;
pub mod control;
pub mod cpu_load;
pub mod drivers;
pub mod dstar;
pub mod estimator;
pub mod flight;
pub mod grid;
pub mod map;
pub mod mission;
pub mod mission_start;
pub mod pad;
pub mod path;
pub mod queue;
pub mod radio;
pub mod status_led;
pub mod supervisor;
pub mod sweep;
pub mod types;
