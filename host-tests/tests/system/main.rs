//! System services (src/system): the config block, CPU load, status LEDs, the mission-start hand-over, and the
//! firmware's log table.

mod config_block;
mod cpu_load;
mod firmware_log;
mod mission_start;
mod status_led;
