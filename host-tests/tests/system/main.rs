//! System services (src/system): the config block, CPU load, status LEDs, the mission-start hand-over, the
//! flash accelerator value, the watchdog timeout and feed rule, and the
//! firmware's log table.

mod config_block;
mod cpu_load;
mod firmware_log;
mod flash_acr;
mod mission_start;
mod persistent_params;
mod status_led;
mod step_pacing;
mod watchdog;
