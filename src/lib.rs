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

// The folders follow the README's module table. Dependencies point one way: `nav`, `landing`, `flight` and
// `drivers` need only `types` and `math` (the shared vectors, rotations and quaternions), `crc` (the CRC-32
// several formats share) nothing; `mission` composes `nav` and `landing`; `stack` wires `flight` to
// `mission`; `radio` (the protocol layer) needs none of `mission`, `flight` or `nav`, and `radio_binding` binds
// their parameters, logs, map and commands to it; `system` serves all of them. Each folder's `mod.rs` states
// its own rule.
pub mod crc;
pub mod drivers;
pub mod flight;
pub mod landing;
pub mod math;
pub mod mission;
pub mod nav;
pub mod radio;
pub mod radio_binding;
pub mod stack;
pub mod system;
pub mod types;
