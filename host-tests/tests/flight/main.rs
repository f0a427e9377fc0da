//! Flight (src/flight): the estimator against the simulator's ground truth, the controller and mixer, the
//! supervisor's safety rules, the wall anchors, the map-relative fixes.

mod control;
mod estimator;
mod heading;
mod high_level;
mod map_fix;
mod supervisor;
mod wall_hold;
