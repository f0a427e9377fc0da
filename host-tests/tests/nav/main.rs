//! Navigation (src/nav): the occupancy grid, the indexed queue, D* Lite against the Dijkstra oracle, path read-off
//! and smoothing, reactive avoidance, and the planner replay of `cfnav plan`.

mod avoidance;
mod dstar;
mod grid;
mod path;
mod plan_replay;
mod queue;
