//! The simulator (tools/src/sim): world files, physics and sensor models, and whole missions flown in it.

mod collide;
mod commander;
mod latency;
mod link_loss;
mod mission;
mod modes;
mod pads;
mod physics;
mod stress;
mod world;
