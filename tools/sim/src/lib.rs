//! The models of the world a simulated Crazyflie 2.1 flies in, shared by the software-in-the-loop simulator
//! (`cfnav-tools`, `cfnav sim`) and the processor-in-the-loop emulator (`tools/pil`), so that both fly the
//! same physics against the same worlds and write the same records.
//!
//! - [`world`]: world files (docs/formats.md, world files), the default world, random worlds, ray casting
//!   and collision geometry.
//! - [`physics`]: the rigid-body quadrotor, motors, battery, contacts.
//! - [`sensors`]: the drone's sensors as the drivers deliver them (types in `cfnav::types`).
//! - [`stress`]: the `[sensors]` and `[disturbances]` tables (world files and `--stress FILE`).
//! - [`report`]: the landing and track records both tools write and `cfnav pil --plot` reads.
//!
//! Non-goals: flying the firmware (the simulator's runner and the emulator do that), drawing, I/O beyond
//! reading world and stress files. Units: SI, arena frame.

pub mod physics;
pub mod report;
pub mod sensors;
pub mod stress;
pub mod world;
