//! The host side of cfnav: planner replay, firmware image, and (later) the simulator. The `cfnav` binary
//! (`src/main.rs`) is a thin command-line front end over these modules; benches and tests use them too.

pub mod firmware;
pub mod mission;
pub mod plan;
pub mod sim;
pub mod sim_cli;
