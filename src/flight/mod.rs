//! Flight: the fast loop that keeps the drone in the air.
//!
//! Holds the 9-state error-state EKF with its flow, height and wall updates and the surface tracker
//! ([`estimator`]), the cascaded PID controller, mixer and battery compensation ([`control`]) and the
//! safety state machine that decides whether the motors may run ([`supervisor`]), the high-level
//! commander's trajectory follower ([`high_level`]: take-off, land, go-to as smooth 7th-order segments); the
//! controller and the supervisor report their ticks with one bit-flag type ([`flags`]).
//!
//! May depend on: [`crate::types`] and [`crate::math`] only. Nothing here plans, maps or talks to the radio;
//! the stabilizer in [`crate::stack`] wires these three together at the gyro's rate.
//! Memory: under 2 KB together (the EKF's 9 × 9 covariance is most of it).

pub mod control;
pub mod estimator;
pub mod flags;
pub mod high_level;
pub mod supervisor;
