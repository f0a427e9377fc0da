//! Radio (src/radio): the syslink and CRTP codecs and every CRTP service (commander, console, log, param,
//! supervisor port).

mod codec;
mod commander;
mod console;
mod high_level;
mod log;
mod param;
mod supervisor_port;
