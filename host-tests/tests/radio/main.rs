//! Radio (src/radio): the syslink and CRTP codecs and every CRTP service (commander, console, log, param,
//! supervisor port), and the syslink transmitter (flow control, boot-setting echoes).

mod codec;
mod commander;
mod console;
mod flow_control;
mod log;
mod param;
mod supervisor_port;
