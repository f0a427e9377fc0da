//! Navigation: from range beams to a collision-free path and a velocity that follows it.
//!
//! Holds the grid geometry and its arena-frame ↔ cell transform ([`map`]), the log-odds occupancy grid with
//! its inflated "blocked" layer ([`grid`]), the indexed priority queue ([`queue`]) under D\* Lite
//! ([`dstar`], Koenig & Likhachev's optimized version with `km`), path read-off, shortening and smoothing
//! ([`path`]), and the reactive layer that turns the path's next waypoint and the live beams into a bounded
//! velocity ([`avoidance`]).
//!
//! May depend on: [`crate::types`] and [`crate::math`] only. Nothing here knows the mission, the flight
//! stack or the radio; the mission composes these pieces, and the planner replay and the benches use them
//! alone.
//! Memory: the grid (1 byte a cell) and the planner (8 bytes a cell plus its heap) dominate; see each
//! module for its size at the firmware's capacity.

pub mod avoidance;
pub mod dstar;
pub mod grid;
pub mod map;
pub mod path;
pub mod queue;
