//! `tilting`: the front door. A thin shell: each subcommand parses its flags and calls the
//! library (see `tilting --help`).

use clap::{Parser, Subcommand};
use std::process::ExitCode;
use tilting::commands::{
    animate, certs, continuation, figures, identify, margins, plan, shard, simulate,
};
use tilting_live as live;
use tilting_live::bridge as ros2;
use tilting_live::{recording, topics};

/// The help page lists the subcommands in groups, by what a person wants to do.
const HELP: &str = "\
{about}

{usage-heading} {usage}

Run:
  live        The main job: plant, controller and planner live on localhost at 1 kHz on the
              paper's stabilised orbit; status line, recording, plot
  simulate    The closed loop offline for one scenario (default: the paper's orbit)
  config      A robot file (its robot, law, sensors, network, deployment) with flags over
              it, checked and printed as TOML; every command above takes one

Plan:
  plan        orbit | sinusoid | bifurcation | gains | margins | continuation | stability |
              merge: the paper's boundary value problems, stability, sweeps (--shard I/N
              for job arrays), continuation, and what the orbit survives on a network

Look:
  figures     The paper's Figs. 4 to 8, and 8b and 8c, as PNG files
  animate     The plate and the arm, moving, as an animated GIF (from a simulation or a live run)
  echo        Print a robot's topic live, decoded (one line or one JSON object per message)
  hz          Rate, largest gap and message size of a robot's topics
  record      Record a robot's topics into an MCAP file (opens in Foxglove, PlotJuggler)
  replay      Publish an MCAP recording back, byte for byte, at its pace or faster (or
              into Foxglove's 3D scene with --foxglove)
  view        Serve a robot on the network to Foxglove: its topics, a 3D scene, log entries
  info        Summarise an MCAP recording: span, channels, counts, tilts, faults

ROS 2:
  ros2        bridge | urdf: any robot on the network as a ROS 2 node (rmw_zenoh's conventions:
              joint_states, contact_mode, /rosout), and the robot's URDF (docs/ros2.md)

Identify:
  identify    The robot's physical parameters from a recording (least squares on the
              dynamics' regressor, per contact mode): estimates, standard errors, --params TOML

Secure:
  certs       A development CA, one certificate per node and the zenoh TLS + access-control
              configurations for a robot (then `live --secure`, or tilting-router + the nodes)

The nodes of the design are separate binaries: tilting-plant, tilting-controller and
tilting-planner (publishes the reference). `tilting <command> --help` tells more.

Options:
{options}";

#[derive(Debug, Parser)]
#[command(
    name = "tilting",
    version,
    about = "A tilting mechatronic system: run it live, simulate it, plan its motions, draw the paper's figures",
    help_template = HELP
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The main job: plant and controller as child processes and the planner in-process on
    /// localhost, the paper's stabilised orbit live at 1 kHz; status line, recording, plot
    Live(Box<live::LiveArgs>),
    /// Simulate the closed loop (plant + computed-torque controller) for one scenario; by
    /// default the paper's stabilised tilting orbit
    Simulate(Box<simulate::SimulateArgs>),
    /// A robot file with flags given over it, checked and printed as TOML (every key is the
    /// flag of its name: `[law] kd` is `--kd`)
    Config(Box<tilting::robot::ConfigArgs>),
    /// Plan: the paper's boundary value problems, stability and sweeps
    #[command(subcommand)]
    Plan(Plan),
    /// The paper's Figs. 4 to 8 as PNG files (fig4.png ... fig8.png), and the continued diagram
    /// with its Lyapunov exponents (fig8b.png) and the stability region (fig8c.png), in a directory
    Figures(figures::FiguresArgs),
    /// The plate and the arm, moving, as an animated GIF (or PNG frames): from a simulated
    /// scenario (the flags of `simulate`) or a live run's directory (--from DIR)
    Animate(Box<animate::AnimateArgs>),
    /// Print a robot's topic live, decoded: one line (or one JSON object) per message
    Echo(topics::EchoArgs),
    /// The rate, the largest gap and the message size of a robot's topics, every second
    Hz(topics::HzArgs),
    /// Record a robot's five topics into an MCAP file (Foxglove, PlotJuggler), until Ctrl-C
    Record(recording::RecordArgs),
    /// Publish an MCAP recording back over zenoh, byte for byte: at its pace, N times faster or
    /// as fast as possible; all topics or some (e.g. states into a controller under test)
    Replay(recording::ReplayArgs),
    /// Serve any robot on the network to Foxglove (WebSocket protocol): its five topics, a 3D
    /// scene of the plate and the arm, and log entries; until Ctrl-C
    View(Box<tilting_live::view::ViewArgs>),
    /// Summarise an MCAP recording: plant-time span, channels, counts, tilts, faults
    Info(recording::InfoArgs),
    /// The robot's physical parameters from a recording: least squares on the dynamics'
    /// regressor per contact mode; standard errors, condition number, the --params TOML
    Identify(identify::IdentifyArgs),
    /// A development certificate authority, one certificate per node (plant, controller,
    /// planner, logger, router) and the zenoh configurations with TLS and access control
    Certs(tilting_launch::CertsArgs),
    /// ROS 2 in rmw_zenoh's conventions: mirror a robot on the network as a ROS 2 node, and
    /// the robot's URDF (docs/ros2.md)
    #[command(subcommand)]
    Ros2(ros2::Ros2Command),
}

#[derive(Debug, Subcommand)]
enum Plan {
    /// Approach 2: every periodic tilting orbit for a gain pair, with Floquet multipliers
    Orbit(plan::OrbitArgs),
    /// Approach 1: the frequency w of beta_d = A sin(w t) + pi/2 whose ideal-tracking tilt lands
    /// at t_l = T/2 + s t_t
    Sinusoid(plan::SinusoidArgs),
    /// Sweep the energy-adaptation gain k (Fig. 8): tilt peaks, their period, and k*
    Bifurcation(plan::BifurcationArgs),
    /// Maximal tilt angle of the orbits over a (K_P, K_D) grid (Fig. 6)
    Gains(plan::GainsArgs),
    /// Which gains (K_D, k) reach a wanted tilt peak, and how stably: plan orbit --peak on a grid
    Reach(plan::ReachArgs),
    /// What the stabilised orbit survives: maps over delay × loss and over the control rate
    Margins(margins::MarginsArgs),
    /// Pseudo-arclength continuation of the orbit in k (or --param), its flips, the
    /// period-doubling cascade to period 16 and the largest Lyapunov exponent
    Continuation(continuation::ContinuationArgs),
    /// Merge the shard files of a sweep run with --shard I/N into the whole sweep's JSON (what
    /// the unsharded command prints with --json, bit for bit)
    Merge(shard::MergeArgs),
    /// The stability region of the period-1 orbit: its flip and fold continued in (k, K_D) or
    /// (k, the arm mass), drawn as a chart with --plot
    Stability(continuation::StabilityArgs),
}

fn main() -> ExitCode {
    // Usage errors exit with code 2 (clap's convention), --help and --version with 0.
    // A command given a robot file reads its keys as the defaults of its flags.
    let cli: Cli = tilting::robot::parse();
    let result = match &cli.command {
        Command::Live(args) => live::run(args, tilting::robot::merged()).map_err(Into::into),
        Command::Simulate(args) => simulate::run(args),
        Command::Config(args) => tilting::robot::config(args),
        Command::Plan(Plan::Orbit(args)) => plan::orbit(args),
        Command::Plan(Plan::Sinusoid(args)) => plan::sinusoid(args),
        Command::Plan(Plan::Bifurcation(args)) => plan::bifurcation(args),
        Command::Plan(Plan::Gains(args)) => plan::gains(args),
        Command::Plan(Plan::Reach(args)) => plan::reach(args),
        Command::Plan(Plan::Margins(args)) => margins::margins(args),
        Command::Plan(Plan::Continuation(args)) => continuation::continuation(args),
        Command::Plan(Plan::Merge(args)) => shard::merge(args),
        Command::Plan(Plan::Stability(args)) => continuation::stability(args),
        Command::Figures(args) => figures::figures(args),
        Command::Animate(args) => animate::run(args),
        Command::Echo(args) => topics::echo(args).map_err(Into::into),
        Command::Hz(args) => topics::hz(args).map_err(Into::into),
        Command::Record(args) => recording::record(args).map_err(Into::into),
        Command::Replay(args) => recording::replay(args).map_err(Into::into),
        Command::Info(args) => recording::info(args).map_err(Into::into),
        Command::View(args) => tilting_live::view::view(args).map_err(Into::into),
        Command::Identify(args) => identify::run(args),
        Command::Certs(args) => certs::run(args),
        Command::Ros2(ros2::Ros2Command::Bridge(args)) => ros2::bridge(args).map_err(Into::into),
        Command::Ros2(ros2::Ros2Command::Urdf(args)) => ros2::urdf(args).map_err(Into::into),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// The hand-written help lists every subcommand exactly once (a merge once left `plan`
    /// there twice) and nothing that is not one.
    #[test]
    fn help_lists_each_subcommand_once() {
        let help = Cli::command().render_help().to_string();
        let listed: Vec<&str> = help
            .lines()
            .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
            .filter_map(|l| l.split_whitespace().next())
            .filter(|w| !w.starts_with('-'))
            .collect();
        let mut names: Vec<String> = Cli::command()
            .get_subcommands()
            .map(|c| c.get_name().to_owned())
            .filter(|n| n != "help")
            .collect();
        names.sort();
        let mut sorted: Vec<String> = listed.iter().map(|s| s.to_string()).collect();
        sorted.sort();
        assert_eq!(sorted, names, "help lines: {listed:?}");
    }
}
