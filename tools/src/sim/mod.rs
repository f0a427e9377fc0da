//! The software-in-the-loop simulator: a Crazyflie 2.1 in a walled arena, flown by exactly the firmware's
//! modules at the rates they run on the MCU.
//!
//! - [`world`]: world files (shared/spec/interfaces.md §3), the default world, random worlds, ray casting
//!   and collision geometry.
//! - [`physics`]: the rigid-body quadrotor, motors, battery, contacts.
//! - [`sensors`]: the drone's sensors as the drivers deliver them (types in `cfnav::types`).
//! - [`stress`]: the `[sensors]` and `[disturbances]` tables (world files and `--stress FILE`).
//! - [`serve`]: `cfnav sim --serve`, the drone in real time behind CRTP over UDP.

pub mod cli;
pub mod physics;
pub mod plot;
pub mod runner;
pub mod sensors;
pub mod serve;
pub mod stress;
pub mod world;
