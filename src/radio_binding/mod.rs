//! cfnav's own parameters, log variables, map memory and flight-command ports, bound to the generic CRTP
//! services of [`crate::radio`].
//!
//! Job: say what cfnav serves over the radio and how each item reaches the flight stack and the mission:
//! the parameter table ([`param_table`]) and the values in effect ([`param_state`], with the flight
//! tuning of [`tuning`]), the log table and the states it samples ([`log_table`]), the drone's map as
//! memory 0 ([`map_mem`]), the high-level commander port 8 ([`high_level`]), the supervisor port 9
//! ([`supervisor_port`]), and one endpoint that answers every port in the same order on the drone, in the
//! simulator and in the fuzz target ([`endpoint`]).
//!
//! May depend on: [`crate::radio`] (the protocol layer, which never depends on this module),
//! [`crate::mission`], [`crate::flight`], [`crate::nav`], [`crate::system`] and the shared types. No
//! transport and no clock: the caller moves the bytes and passes the time.
//!
//! Memory: everything is fixed-size; the largest objects are the parameter store (about 2 KB) and the
//! endpoint's queues (see [`endpoint`]).

pub mod endpoint;
pub mod high_level;
pub mod log_table;
pub mod map_mem;
pub mod param_state;
pub mod param_table;
pub mod supervisor_port;
pub mod tuning;
