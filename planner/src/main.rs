//! `tilting-planner`: offline simulation, boundary value problems, sweeps and figures for the
//! tilting system. A thin shell: each subcommand parses its flags and calls its library module.

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use tilting_planner::simulate::{self, SimulateArgs};

#[derive(Debug, Parser)]
#[command(name = "tilting-planner", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Simulate the closed loop (plant + computed-torque controller) for one scenario; by
    /// default the paper's stabilised tilting orbit
    Simulate(SimulateArgs),
}

fn main() -> ExitCode {
    // Usage errors exit with code 2 (clap's convention), --help and --version with 0.
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Simulate(args) => simulate::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
