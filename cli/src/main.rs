//! `tilting-planner`: offline simulation, boundary value problems, sweeps and figures for the
//! tilting system. A thin shell: each subcommand parses its flags and calls its library module.

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use tilting_planner::commands;
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
    /// Approach 1: the frequency w of beta_d = A sin(w t) + pi/2 whose ideal-tracking tilt lands
    /// at t_l = T/2 + s t_t
    Sinusoid(commands::SinusoidArgs),
    /// Approach 2: every periodic tilting orbit for a gain pair, with Floquet multipliers
    Orbit(commands::OrbitArgs),
    /// Sweep the energy-adaptation gain k (Fig. 8): tilt peaks, their period, and k*
    Bifurcation(commands::BifurcationArgs),
    /// Maximal tilt angle of the orbits over a (K_P, K_D) grid (Fig. 6)
    Gains(commands::GainsArgs),
    /// The paper's Figs. 4 to 8 as PNG files (fig4.png ... fig8.png) in a directory
    Figures(tilting_planner::figures::FiguresArgs),
    /// Publish the controller's law as the planner's reference over zenoh (put on change and
    /// every second, a queryable for late joiners, the planner's liveliness token)
    Publish(tilting_planner::publish::PublishArgs),
    /// The main job: plant and controller as child processes and the planner in-process on
    /// localhost, the paper's stabilised orbit live at 1 kHz; status line, recording, plot
    Live(tilting_planner::live::LiveArgs),
}

fn main() -> ExitCode {
    // Usage errors exit with code 2 (clap's convention), --help and --version with 0.
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Simulate(args) => simulate::run(args),
        Command::Sinusoid(args) => commands::sinusoid(args),
        Command::Orbit(args) => commands::orbit(args),
        Command::Bifurcation(args) => commands::bifurcation(args),
        Command::Gains(args) => commands::gains(args),
        Command::Figures(args) => tilting_planner::figures::figures(args),
        Command::Publish(args) => tilting_planner::publish::run(args),
        Command::Live(args) => tilting_planner::live::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
