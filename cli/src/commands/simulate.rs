//! `tilting simulate`: the closed loop offline for one scenario (by default the paper's
//! stabilised orbit), as a summary or JSON, with an optional plot.

use super::print_stdout;
use crate::CommandError;
use anyhow::Context as _;
use std::path::PathBuf;
use tilting_viz::plot::plot_run;

/// Flags of `tilting simulate`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SimulateArgs {
    /// The robot file (TOML, docs/guide/robot-file.md): its keys are the defaults of these
    /// flags, a flag given as well overrides its key [default: none]
    #[arg(value_name = "ROBOT.toml")]
    pub robot_file: Option<PathBuf>,
    /// What to run: scenario, network, imperfections, loop options, safe mode.
    #[command(flatten)]
    pub run: tilting_sim::flags::SimulateArgs,
    /// Print one JSON object (events, tilt_peaks, final, fault, stats) to stdout instead of the
    /// summary
    #[arg(long)]
    pub json: bool,
    /// Draw alpha(t) and beta(t) with the event times into this PNG file
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Record the run as `live` does (every measured state the controller read, the torque it
    /// answered, every mode transition) into this MCAP file, for `tilting identify` (sampled
    /// loop over a perfect link; the robot's imperfections are recorded as measured)
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// The robot name of the recording's channels (with --record)
    #[arg(long, value_name = "NAME", default_value = tilting_proto::keys::DEFAULT_ROBOT)]
    pub robot: String,
}

/// `tilting simulate`.
pub fn run(args: &SimulateArgs) -> Result<(), CommandError> {
    if let Some(p) = &args.plot {
        let png = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if !png {
            return Err(CommandError::Usage(anyhow::anyhow!(
                "invalid `--plot` = {}: must be a file name ending in .png",
                p.display()
            )));
        }
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            if !dir.is_dir() {
                return Err(CommandError::Usage(anyhow::anyhow!(
                    "invalid `--plot` = {}: the directory {} does not exist",
                    p.display(),
                    dir.display()
                )));
            }
        }
    }
    let (sc, opts) = args
        .run
        .prepare(args.plot.is_some())
        .map_err(|e| CommandError::Usage(anyhow::anyhow!(e)))?;
    let report = match &args.record {
        None => super::simulate_with_bar(&sc, opts, args.json)?,
        Some(path) => {
            tilting_proto::Keys::new(&args.robot).map_err(|e| {
                CommandError::Usage(anyhow::anyhow!("invalid `--robot` = {:?}: {e}", args.robot))
            })?;
            let (report, logged) = tilting_sim::recording::simulate_logged(&sc, opts, &mut |_| {})?;
            tilting_sim::recording::write_mcap(path, &args.robot, &logged).map_err(|e| {
                CommandError::Failed(anyhow::anyhow!("cannot write {}: {e}", path.display()))
            })?;
            report
        }
    };
    if args.json {
        let mut text = serde_json::to_string(&report)
            .context("cannot serialise the report")
            .map_err(CommandError::Failed)?;
        text.push('\n');
        print_stdout(&text)?;
    } else {
        print_stdout(&tilting_sim::closed_loop::summary(&sc, &report))?;
    }
    match &report.fault {
        Some(f @ tilting_plant::Fault::SafeMode { .. }) => {
            eprintln!("warning: the run ended in the plant's safe mode: {f}")
        }
        Some(f) => eprintln!("warning: the simulation stopped early: {f}"),
        None => {}
    }
    if let Some(p) = &args.plot {
        plot_run(p, &sc, &report)
            .with_context(|| format!("cannot draw the plot {}", p.display()))
            .map_err(CommandError::Failed)?;
        if !args.json {
            print_stdout(&format!("plot: {}\n", p.display()))?;
        }
    }
    Ok(())
}
