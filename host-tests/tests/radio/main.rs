//! Radio (src/radio): the syslink and CRTP codecs and every CRTP service (commander, console, log, param,
//! supervisor port) and the stock parameter and log names clients use.

mod codec;
mod commander;
mod console;
mod log;
mod param;
mod stock;
mod supervisor_port;
