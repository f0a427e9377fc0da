//! System services the firmware needs around the flight: stored radio settings, CPU accounting, the
//! status LEDs and the `mission.start` hand-over.
//!
//! Holds the EEPROM config block codec ([`config_block`]), CPU load and control-loop jitter accounting from
//! a cycle counter ([`cpu_load`]), the LED patterns for each firmware state ([`status_led`]), the rules
//! by which a `mission.start` write becomes a started mission ([`mission_start`]), the flash accelerator's
//! expected register value ([`flash_acr`]), the watchdog's timeout and feeding rule ([`watchdog`]), the
//! pacing of the control step's costly inputs ([`step_pacing`]) and the persistent parameters' EEPROM
//! records ([`persistent_params`]), the build's git revision ([`version`]).
//!
//! May depend on: [`crate::types`], [`crate::math`] and the radio codecs of [`crate::radio`] (the config
//! block carries syslink radio settings). No peripheral access: the board layer reads the cycle counter,
//! the EEPROM and drives the pins.

pub mod config_block;
pub mod cpu_load;
pub mod flash_acr;
pub mod mission_start;
pub mod persistent_params;
pub mod status_led;
pub mod step_pacing;
pub mod version;
pub mod watchdog;
