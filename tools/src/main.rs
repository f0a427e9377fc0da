//! `cfnav`: the host-side tools of the cfnav firmware (simulator, planner replay, firmware image, emulator).
use std::process::ExitCode;

use cfnav_tools::{firmware, map, mission, nav, pil, sim};
use clap::{Parser, Subcommand};

/// cfnav host tools: planner replay, firmware image, simulator.
#[derive(Parser)]
#[command(name = "cfnav", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fly the round-trip mission in the simulator (exit 0 completed, 1 not, 2 bad input).
    Sim(sim::cli::SimArgs),
    /// Replay the D* Lite planner on a text map (exit 0 goal reached, 1 no path, 2 bad input).
    Plan(nav::replay::PlanArgs),
    /// Build the release firmware and write the raw image for the radio bootloader.
    Firmware(firmware::FirmwareArgs),
    /// Start a mission on a drone (radio://) or a simulator (udp://) and follow it until it ends.
    Mission(mission::MissionArgs),
    /// Download the map a drone or simulator built (grid, path, pads) and draw it (exit 0 done, 2 error).
    Map(map::MapArgs),
    /// Run the firmware image on the emulated Crazyflie (`cfnav-pil`, docs/pil.md): boot, cflib, hover,
    /// round trip, faults; the arguments go to the emulator (exit 0 passed, 1 not, 2 bad input).
    #[command(disable_help_flag = true)]
    Pil(pil::PilArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    match cli.command {
        Command::Sim(args) => sim::cli::run_cli(&args),
        Command::Plan(args) => nav::replay::run(&args),
        Command::Firmware(args) => firmware::run(&args),
        Command::Mission(args) => mission::run_cli(&args),
        Command::Map(args) => map::run_cli(&args),
        Command::Pil(args) => pil::run_cli(&args),
    }
}
