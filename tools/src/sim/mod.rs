//! The software-in-the-loop simulator: a Crazyflie 2.1 in a walled arena, flown by exactly the firmware's
//! modules at the rates they run on the MCU.
//!
//! The world, physics, sensor and stress models it flies against are the `cfnav_sim` crate's (`tools/sim`,
//! shared with the emulator). Here:
//! - [`runner`]: the lockstep loop and the run report.
//! - [`cli`]: `cfnav sim`'s command line and batch summary.
//! - [`plot`]: the run's figure.
//! - [`serve`]: `cfnav sim --serve`, the drone in real time behind CRTP over UDP.
//! - [`map_dump`]: the simulator's own map as `cfnav sim --serve --map-json` writes it.

pub mod cli;
pub mod map_dump;
pub mod plot;
pub mod runner;
pub mod serve;
