//! `tilting plan margins`: what the paper's stabilised orbit (`k = 500`) survives, mapped over
//! constant delay × loss, over the control rate, and over the robot's imperfections (sensor
//! noise, arm-mass error; see `tilting_planner::margins` for the criteria). The survey is
//! [`tilting_planner::margins::Survey`]; this command checks the flags, draws the progress bar,
//! the maps and the tables.

use super::shard::{self, ShardArgs, Shards};
use super::{bar, emit, usage};
use crate::CommandError;
use anyhow::Context as _;
use clap::Args;
use std::path::PathBuf;
use tilting_planner::margins::{Bands, Base, Criteria, MarginsReport, Survey, SurveyShard};

/// Flags of `tilting plan margins`.
#[derive(Debug, Clone, Args)]
pub struct MarginsArgs {
    /// Total constant delays, state and torque together (s), comma-separated, each in [0, 60]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.002,0.004,0.006,0.008,0.010,0.015,0.020",
        allow_negative_numbers = true
    )]
    pub delays: Vec<f64>,
    /// Loss probabilities of each direction, comma-separated, each in [0, 1]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.05,0.1,0.2,0.3,0.5",
        allow_negative_numbers = true
    )]
    pub losses: Vec<f64>,
    /// Control rate of the delay × loss map (Hz), in [1, 10000]
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub rate: f64,
    /// Control rates of the rate map (Hz), comma-separated, each in [1, 10000]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1000,500,250,200,150,100,75,60,50",
        allow_negative_numbers = true
    )]
    pub rates: Vec<f64>,
    /// Tilts a point must complete, in [10, 100000]
    #[arg(long, default_value_t = 200)]
    pub tilts: u64,
    /// Largest relative deviation of the last peaks from the nominal orbit's, in (0, 10]
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    pub tolerance: f64,
    /// Longest stretch of periods without a new torque (the plant's --watchdog), in [1, 1e6]
    #[arg(long, default_value_t = 50)]
    pub watchdog: u64,
    /// Seed of the links' random streams
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// The robot's imperfections to map (at --rate, perfect network).
    #[command(flatten)]
    pub robot: RobotMapArgs,
    /// The robot's parameter file; its `impact` is the landing law (needs --plan unless the
    /// paper's robot).
    #[command(flatten)]
    pub params: tilting_plant::flags::ParamsArgs,
    /// Landing impact law: paper, striking-edge or physical [default: the params file's
    /// `impact`, else paper]
    #[arg(long, value_name = "LAW", value_parser = super::parse_impact)]
    pub impact: Option<tilting_plant::ImpactLaw>,
    /// Survey the orbit of a plan (`tilting plan orbit [--peak P] --json > plan.json`, for the
    /// same --params): its gains, E_av and start, instead of the paper's stabilised orbit
    #[arg(long, value_name = "PLAN.json")]
    pub plan: Option<PathBuf>,
    /// Draw the maps (heat map with the survival boundary, and the rate map) into this PNG
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object instead of the tables
    #[arg(long)]
    pub json: bool,
    /// Run one shard of the survey (`--shard I/N`).
    #[command(flatten)]
    pub sharding: ShardArgs,
}

/// The command name in shard files.
pub const COMMAND: &str = "plan margins";

/// The imperfection maps of `plan margins`: one imperfection at a time, at `--rate` over a
/// perfect network, the noise seeded with `--seed`.
#[derive(Debug, Clone, Args)]
pub struct RobotMapArgs {
    /// Sensor noise of both angles, alpha and beta: standard deviations (rad), comma-separated,
    /// each in [0, 10]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.001,0.003,0.005,0.007,0.01,0.02",
        allow_negative_numbers = true
    )]
    pub angle_noises: Vec<f64>,
    /// Sensor noise of both rates, alpha_dot and beta_dot: standard deviations (rad/s),
    /// comma-separated, each in [0, 10]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,0.01,0.02,0.03,0.04,0.05,0.1",
        allow_negative_numbers = true
    )]
    pub rate_noises: Vec<f64>,
    /// Arm-mass errors of the plant against the controller's model (relative),
    /// comma-separated, each in (-1, 10]
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "-0.1,-0.05,-0.03,-0.02,-0.01,0,0.01,0.02,0.05,0.1",
        allow_negative_numbers = true
    )]
    pub mass_errors: Vec<f64>,
    /// The plant's parameters whose error band is searched by bisection, each way, with the
    /// paper's law and with the robust one (--orbit-peak): comma-separated keys of m_f, m_l,
    /// l, f, g, l_c, or none
    #[arg(long, value_delimiter = ',', default_value = "m_f,m_l,l,f,g,l_c")]
    pub param_bands: Vec<String>,
    /// Largest relative parameter error searched each way, in (0, 0.9]
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    pub param_span: f64,
    /// Largest viscous joint friction b_v of the plant searched (N m s/rad; the controller's
    /// model has none), in [0, 100]; 0 for no row
    #[arg(long, default_value_t = 40.0, allow_negative_numbers = true)]
    pub viscous_span: f64,
    /// Largest Coulomb joint friction tau_c of the plant searched (N m; the controller's
    /// model has none), in [0, 100]; 0 for no row
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    pub coulomb_span: f64,
    /// Largest angle noise searched with --measure angles, for the hybrid observer and the
    /// finite-difference baseline (rad), in [0, 1]; 0 for no row
    #[arg(long, default_value_t = 0.005, allow_negative_numbers = true)]
    pub noise_span: f64,
    /// Encoder resolutions searched with --measure angles, fine to coarse, in bits (2^bits
    /// counts per revolution), each in [1, 32], or none
    #[arg(long, default_value = "16,6", value_name = "FINE,COARSE|none")]
    pub encoder_bits: String,
    /// Halvings of each search's interval, in [0, 20]: an edge is located within the
    /// interval's length / 2^bisections
    #[arg(long, default_value_t = 6)]
    pub bisections: u32,
}

/// The robot rows the flags describe, or the flag that is wrong.
fn bands(r: &RobotMapArgs) -> Result<Bands, String> {
    Ok(Bands {
        parameters: Bands::parameters_from_keys(&r.param_bands)?,
        param_span: r.param_span,
        viscous_span: r.viscous_span,
        coulomb_span: r.coulomb_span,
        noise_span: r.noise_span,
        encoder_bits: Bands::encoder_bits_from(&r.encoder_bits)?,
        bisections: r.bisections,
    })
}

/// The PNG of the imperfection maps beside `--plot FILE.png`: `FILE-robot.png`.
pub fn robot_plot_path(plot: &std::path::Path) -> PathBuf {
    let stem = plot
        .file_stem()
        .map_or("margins".into(), |s| s.to_string_lossy());
    plot.with_file_name(format!("{stem}-robot.png"))
}

/// Checks the flags: every grid value in range, not too many points
/// ([`Survey::check`]), a PNG for `--plot`.
fn check_args(args: &MarginsArgs) -> Result<(), CommandError> {
    survey(args)?.check()?;
    if let Some(p) = &args.plot {
        if !p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
            return Err(usage(format!(
                "invalid `--plot` = {}: must be a file name ending in .png",
                p.display()
            )));
        }
    }
    Ok(())
}

/// The survey the flags describe.
fn survey(args: &MarginsArgs) -> Result<Survey, CommandError> {
    Ok(Survey {
        delays: args.delays.clone(),
        losses: args.losses.clone(),
        rate: args.rate,
        rates: args.rates.clone(),
        angle_noises: args.robot.angle_noises.clone(),
        rate_noises: args.robot.rate_noises.clone(),
        mass_errors: args.robot.mass_errors.clone(),
        seed: args.seed,
        criteria: Criteria {
            tilts: args.tilts,
            watchdog: args.watchdog,
            tolerance: args.tolerance,
        },
        bands: bands(&args.robot).map_err(usage)?,
        base: base(args)?,
    })
}

/// The loop surveyed: `None` for the paper's stabilised orbit, else the robot of `--params`
/// and `--impact` under the law of `--plan`.
fn base(args: &MarginsArgs) -> Result<Option<Base>, CommandError> {
    let p = args
        .params
        .params()
        .map_err(|e| usage(format!("invalid `--params`: {e}")))?;
    let params = p.with_impact(p.impact_or(args.impact));
    let Some(plan) = &args.plan else {
        if params != tilting_plant::Params::default() {
            return Err(usage(
                "`--params` or `--impact` other than the paper's robot needs `--plan` (the \
                 paper's E_av belongs to the paper's robot): `tilting plan orbit --params \
                 FILE --peak P --json > plan.json`"
                    .into(),
            ));
        }
        return Ok(None);
    };
    let law = tilting_planner::jobs::law_of_plan(plan).map_err(|e| usage(format!("{e:#}")))?;
    Ok(Some(Base { params, law }))
}

/// `tilting plan margins`.
pub fn margins(args: &MarginsArgs) -> Result<(), CommandError> {
    check_args(args)?;
    let survey = survey(args)?;
    if let Some(s) = args.sharding.shard {
        if args.plot.is_some() {
            return Err(usage(
                "`--plot` draws the whole survey: give it to no shard (merge the shards, \
                 then plot)"
                    .into(),
            ));
        }
        let b = bar(s.len(survey.points()) as u64, "margins", true);
        let part = survey.run_shard(s, &|| b.inc(1))?;
        return shard::emit_shard(COMMAND, s, &survey, &part);
    }
    let b = bar(survey.units(), "margins", args.json);
    let report = survey.run(&|| b.inc(1));
    b.finish_and_clear();
    let report = report?;
    if let Some(p) = &args.plot {
        plot(p, &report)?;
    }
    emit(args.json, &report, || human(args, &report))
}

/// `tilting plan merge` of the shards of `plan margins`: the report `--json` prints.
pub fn merge(shards: Shards) -> Result<(), CommandError> {
    let survey: Survey = serde_json::from_value(shards.grid)
        .map_err(|e| usage(format!("the shards' grid is not a margins survey: {e}")))?;
    let parts: Vec<(_, SurveyShard)> = shard::parts(shards.parts)?;
    if let Some((s, p)) = parts.iter().find(|(s, p)| *s != p.shard) {
        return Err(usage(format!(
            "the shard file of shard {s} holds the points of shard {}",
            p.shard
        )));
    }
    let parts = parts.into_iter().map(|(_, p)| p).collect();
    let report = survey.merge(parts)?;
    emit(true, &report, String::new)
}

/// Draws the maps into `p` and the imperfection maps beside it ([`robot_plot_path`]).
fn plot(p: &std::path::Path, report: &MarginsReport) -> Result<(), CommandError> {
    let (nominal, c) = (report.nominal_peak, &report.criteria);
    let maps = tilting_viz::margins::Maps {
        delay_loss: &report.delay_loss,
        delay_loss_predict: &report.delay_loss_predict,
        rates: &report.rates,
        rates_events: &report.rates_events,
    };
    tilting_viz::margins::plot(p, &maps, nominal, c)
        .with_context(|| format!("cannot draw {}", p.display()))
        .map_err(CommandError::Failed)?;
    let rp = robot_plot_path(p);
    let r = &report.robot;
    tilting_viz::margins::plot_imperfections(
        &rp,
        &[&r.angle_noise, &r.rate_noise, &r.mass_error],
        nominal,
        c,
    )
    .with_context(|| format!("cannot draw {}", rp.display()))
    .map_err(CommandError::Failed)
}

/// The report as tables ([`MarginsReport::summary`]) and the plots' paths.
fn human(args: &MarginsArgs, report: &MarginsReport) -> String {
    let mut s = report.summary(&args.delays, &args.losses);
    if let Some(p) = &args.plot {
        s += &format!(
            "plot: {} and {}\n",
            p.display(),
            robot_plot_path(p).display()
        );
    }
    s
}
