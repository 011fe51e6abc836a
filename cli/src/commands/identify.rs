//! `tilting identify`: the physical parameters of a robot from a recording
//! ([`tilting_planner::identify`]): the estimates with their standard errors, the regressor's
//! condition number, what the data cannot fix; `--out` writes the `--params` TOML.

use super::{print_stdout, usage};
use crate::CommandError;
use clap::Args;
use std::path::PathBuf;
use tilting_planner::identify::{self, IdentifyError, Options, Velocities};
use tilting_plant::Params;

/// Flags of `tilting identify`.
#[derive(Debug, Clone, Args)]
pub struct IdentifyArgs {
    /// The recording: an MCAP file (`tilting record`, `live`, `simulate --record`) or a live
    /// run's directory holding run.mcap; several recordings of one robot (an excitation run
    /// and an orbit run, say) enter one fit
    #[arg(value_name = "FILE.mcap|RUN_DIR", required = true, num_args = 1..)]
    pub file: Vec<PathBuf>,
    /// The robot to identify; refused if the file holds another
    #[arg(long, value_name = "NAME")]
    pub robot: Option<String>,
    /// The prior: TOML with the measured geometry (l, f, g) and the weighed arm mass m_l,
    /// which the motion cannot tell from l_c and i_l; default the paper's
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    /// Write the identified robot's parameters here, as `--params` reads them; into a robot
    /// file (docs/guide/robot-file.md), as its [robot] table, its other tables kept (and its
    /// [prior] is the prior unless --params)
    #[arg(long, value_name = "params.toml")]
    pub out: Option<PathBuf>,
    /// Where the velocities and accelerations come from: `angles` (differentiated from the
    /// recorded angles, a zero-phase Savitzky-Golay filter: works with or without recorded
    /// velocities, e.g. `--measure angles`) or `recorded` (the recorded velocities, taken as
    /// exact)
    #[arg(long, value_enum, default_value = "angles")]
    pub velocities: VelocitiesArg,
    /// Half width of the differentiator's window (s), in [0.002, 0.5]: wider smooths more
    /// noise, narrower follows faster motion
    #[arg(long, value_name = "SECONDS", default_value_t = identify::HALF_WINDOW)]
    pub half_window: f64,
    /// Length of the weak form's windows (s), in [0.01, 2]: each equation is integrated
    /// against a smooth bump this long; longer averages more noise (2 s for 1 mrad of angle
    /// noise on the excitation), a tilt shorter than it gives one window of its length
    #[arg(long, value_name = "SECONDS", default_value_t = identify::WINDOW)]
    pub window: f64,
    /// Slowest joint speed (rad/s), in [0, 10]: a window where the arm is slower at more than
    /// 1 sample in 50 gives no torque equation (the joint may stick there)
    #[arg(long, value_name = "RAD/S", default_value_t = Options::default().v_min, allow_negative_numbers = true)]
    pub min_speed: f64,
    /// Skip the output-error refinement of the flat arm (b_v, tau_c re-fitted against the
    /// recorded angles after the least squares; angles path only): the least squares alone
    #[arg(long)]
    pub no_refine: bool,
    /// Time left out after each landing and before each lift-off (s), in [0, 1]: a compliant
    /// contact settles there (the plate sinks, rocks and bounces), which neither mode's
    /// equations describe; default measured from the recording (the plate's equations'
    /// residual against the distance from the mode change; 0 for a rigid contact); angles
    /// path only
    #[arg(long, value_name = "SECONDS")]
    pub settle: Option<f64>,
    /// Draw the fit check into this PNG: the recorded angles beside their re-simulation with
    /// the identified parameters under the recorded torques (restarted from the recorded state
    /// every --fit-window s); its RMS error is reported either way
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Restart interval of the fit check's re-simulation (s), in [0.01, 10]
    #[arg(long, value_name = "SECONDS", default_value_t = identify::fit::WINDOW)]
    pub fit_window: f64,
    /// Print one JSON object instead of a human summary
    #[arg(long)]
    pub json: bool,
}

/// `--velocities`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum VelocitiesArg {
    /// Differentiated from the angles.
    Angles,
    /// The recorded ones.
    Recorded,
}

/// Runs `tilting identify`.
pub fn run(args: &IdentifyArgs) -> Result<(), CommandError> {
    let mut opts = Options {
        velocities: match args.velocities {
            VelocitiesArg::Angles => Velocities::Angles,
            VelocitiesArg::Recorded => Velocities::Recorded,
        },
        half_window: args.half_window,
        window: args.window,
        v_min: args.min_speed,
        refine: if args.no_refine {
            None
        } else {
            Options::default().refine
        },
        settle: args.settle,
        ..Options::default()
    };
    opts.check().map_err(refused)?;
    // The prior: --params, else the [prior] table of the robot file --out writes into.
    let prior = args
        .params
        .clone()
        .or_else(|| args.out.as_deref().and_then(crate::robot::prior_of));
    if let Some(p) = &prior {
        opts.base = Params::from_toml_file(p).map_err(|e| CommandError::Usage(e.into()))?;
    }
    identify::check_fit_window(args.fit_window).map_err(refused)?;
    if let Some(p) = &args.plot {
        if !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            return Err(usage(format!(
                "invalid `--plot` = {}: must be a file name ending in .png",
                p.display()
            )));
        }
    }
    let mut rec = identify::load(&args.file[0], args.robot.as_deref()).map_err(refused)?;
    for f in &args.file[1..] {
        rec.append(identify::load(f, args.robot.as_deref()).map_err(refused)?);
    }
    let source = args
        .file
        .iter()
        .map(|f| f.display().to_string())
        .collect::<Vec<_>>()
        .join(" + ");
    let mut id = identify::identify(&rec.trace, &rec.tau, &opts).map_err(refused)?;
    let resim = id.check_fit(&rec.trace, &rec.tau, &opts.base, args.fit_window);
    if let Some(p) = &args.plot {
        let f = id.fit.as_ref().map(|f| &f.identified);
        let title = f.map_or(String::new(), |f| {
            format!(
                "Fit check: re-simulated with the identified parameters, restarted every {} s \
                 (RMS α {:.2e} rad, β {:.2e} rad)",
                f.window_s, f.rms_alpha, f.rms_beta
            )
        });
        tilting_viz::plot::plot_fit(p, &rec.trace, &resim, &title).map_err(|e| {
            CommandError::Failed(anyhow::anyhow!("cannot draw {}: {e}", p.display()))
        })?;
    }
    if let Some(out) = &args.out {
        // A robot file gets the robot as its [robot] table; anything else a parameter file.
        let into_robot = crate::robot::write_params_into(out, &id.params)
            .map_err(|e| CommandError::Usage(anyhow::anyhow!("--out: {e}")))?;
        if !into_robot {
            std::fs::write(out, id.params.to_toml_string()).map_err(|e| {
                CommandError::Failed(anyhow::anyhow!("cannot write {}: {e}", out.display()))
            })?;
        }
    }
    let text = if args.json {
        serde_json::to_string_pretty(&id).map_err(|e| CommandError::Failed(e.into()))? + "\n"
    } else {
        let mut s = id.human(&source);
        if let Some(o) = &args.out {
            s += &format!("wrote {} (use it with --params)\n", o.display());
        }
        s
    };
    print_stdout(&text)
}

/// A recording that cannot be read is a failure; one that cannot be identified, bad input.
fn refused(e: IdentifyError) -> CommandError {
    match e {
        IdentifyError::Load(_) | IdentifyError::Read(_) => CommandError::Failed(e.into()),
        e => usage(e.to_string()),
    }
}
