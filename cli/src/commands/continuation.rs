//! `tilting plan continuation`: the orbits continued in a parameter, their flips, the
//! period-doubling cascade and the largest Lyapunov exponent, and the stability region. The
//! jobs are `tilting_planner::jobs::{ContinuationJob, StabilityJob}`; this parses, draws and
//! prints.

use super::{bar, emit, usage, Bars, ModelArgs};
use crate::CommandError;
use anyhow::anyhow;
use clap::Args;
use tilting_planner::bifurcation::Sweep;
use tilting_planner::continuation::{Diagram, Param};
use tilting_planner::jobs::{ContinuationJob, StabilityJob};
pub use tilting_planner::jobs::{ContinuationReport, StabilityReport};
use tilting_planner::lyapunov::sampled::SampledExponent;
use tilting_planner::lyapunov::Exponent;
use tilting_plant::paper::{ORBIT_K, ORBIT_KD, ORBIT_KP};
use tilting_viz::continuation::CascadeSweep;

/// `continuation`: pseudo-arclength continuation of the period-1 orbit, branch switching at
/// each flip, and the Lyapunov exponent.
#[derive(Debug, Clone, Args)]
pub struct ContinuationArgs {
    /// The parameter to continue in: k, kp, kd, m_l (robot and model), m_l_plant (the robot's
    /// arm mass with the model's kept: the model error), m_f
    #[arg(long, default_value = "k", value_parser = parse_param)]
    pub param: Param,
    /// Where to continue to (in the parameter's units) [default: 2400 for k; required otherwise]
    #[arg(long, allow_negative_numbers = true)]
    pub to: Option<f64>,
    /// The adaptation gain k (1/(J s^2)) of the loop when the parameter is another one; the
    /// continuation in k starts at this value too (the orbit attracts there)
    #[arg(long, default_value_t = ORBIT_K, allow_negative_numbers = true)]
    pub k: f64,
    /// K_P0 (1/s^2)
    #[arg(long, default_value_t = ORBIT_KP, allow_negative_numbers = true)]
    pub kp: f64,
    /// K_D (1/s)
    #[arg(long, default_value_t = ORBIT_KD, allow_negative_numbers = true)]
    pub kd: f64,
    /// First continuation step (parameter units) [default: 1/200 of the range]
    #[arg(long)]
    pub step: Option<f64>,
    /// Largest continuation step (parameter units) [default: 1/50 of the range]
    #[arg(long)]
    pub max_step: Option<f64>,
    /// Switch branches at flips until this period (tilts): 1 follows the period-1 orbit only
    #[arg(long, default_value_t = 16)]
    pub max_period: usize,
    /// Spacing of the Lyapunov curve in the parameter (0: no curve) [default: 1/200 of the
    /// range, from the continuation's start]
    #[arg(long)]
    pub lyapunov_step: Option<f64>,
    /// Lyapunov: tilts discarded before averaging
    #[arg(long, default_value_t = 200)]
    pub transient: usize,
    /// Lyapunov: tilts averaged
    #[arg(long, default_value_t = 400)]
    pub tilts: usize,
    /// Also the exponents of the loop sampled at this control period (s; 0.001 for 1 kHz): the
    /// torque held between samples, as `simulate --control-period` and the live loop run it
    /// (on the Lyapunov curve's values, with its --transient and --tilts)
    #[arg(long, value_name = "SECONDS")]
    pub control_period: Option<f64>,
    /// Draw Fig. 8b into this PNG file: the branches over a sweep of the loop (k from the
    /// Lyapunov curve's first value to --to, step 5, 600 tilts, 150 kept) with the exponent
    /// below (--param k only)
    #[arg(long)]
    pub plot: Option<std::path::PathBuf>,
    /// Start from the adapted loop's orbit with this peak (rad; `plan orbit --peak`) and its
    /// E_av, instead of the k = 0 orbit's (which the physical landing law has not)
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    pub peak: Option<f64>,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
}

fn parse_param(s: &str) -> Result<Param, String> {
    s.parse()
}

impl ContinuationArgs {
    /// The job of these flags.
    pub fn job(&self) -> ContinuationJob {
        ContinuationJob {
            param: self.param,
            to: self.to,
            k: self.k,
            kp: self.kp,
            kd: self.kd,
            step: self.step,
            max_step: self.max_step,
            max_period: self.max_period,
            lyapunov_step: self.lyapunov_step,
            transient: self.transient,
            tilts: self.tilts,
            control_period: self.control_period,
            peak: self.peak,
        }
    }
}

/// Runs `continuation`.
pub fn continuation(args: &ContinuationArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    if args.plot.is_some() && args.param != Param::K {
        return Err(usage(
            "`--plot` draws Fig. 8b over k: it needs `--param k`".into(),
        ));
    }
    let run = args.job().run(&params, &Bars::new(args.model.json))?;
    if let Some(path) = &args.plot {
        let r = &run.report;
        let curves = (&r.lyapunov[..], &r.lyapunov_sampled[..]);
        plot(args, path, &run.sweep, run.range, &r.diagram, curves)?;
    }
    emit(args.model.json, &run.report, || run.report.human())
}

/// Draws Fig. 8b of `continuation --plot` into `path`: the sweep of `sw` over `range` of `k`
/// with the diagram and the exponents.
fn plot(
    args: &ContinuationArgs,
    path: &std::path::Path,
    sw: &Sweep,
    range: (f64, f64),
    diagram: &Diagram,
    (lyap, lyap_sampled): (&[Exponent], &[SampledExponent]),
) -> Result<(), CommandError> {
    // The paper's figure from k = 1500; about a planned peak, from where the curve starts.
    let grid = match args.peak {
        Some(_) => CascadeSweep {
            k_min: f64::NEG_INFINITY,
            ..CascadeSweep::FULL
        },
        None => CascadeSweep::FULL,
    };
    let ks = grid.ks(range);
    let b = bar(ks.len() as u64, "sweep", args.model.json);
    tilting_viz::continuation::cascade_figure(
        path,
        sw,
        range,
        grid,
        diagram,
        lyap,
        lyap_sampled,
        &|| b.inc(1),
    )
    .map_err(|e| CommandError::Failed(anyhow!("cannot draw {}: {e:#}", path.display())))?;
    b.finish_and_clear();
    Ok(())
}

// ---------------------------------------------------------------------------------------------

/// `stability`: the flip and the fold of the period-1 orbit continued in two parameters,
/// `(k, --param2)`: the stability region of the orbit.
#[derive(Debug, Clone, Args)]
pub struct StabilityArgs {
    /// The second parameter: kd, kp, m_l, m_l_plant (the robot's arm mass, the model's kept:
    /// the model error), m_f
    #[arg(long, default_value = "kd", value_parser = parse_param)]
    pub param2: Param,
    /// Lowest value of the second parameter [default: kd 8, m_l_plant 0.7; required otherwise]
    #[arg(long, allow_negative_numbers = true)]
    pub from2: Option<f64>,
    /// Highest value of the second parameter [default: kd 18, m_l_plant 1.4; required otherwise]
    #[arg(long, allow_negative_numbers = true)]
    pub to2: Option<f64>,
    /// Highest k (1/(J s^2)) searched for the flip (the lowest, for the fold, is 0)
    #[arg(long, default_value_t = 4000.0)]
    pub k_max: f64,
    /// K_P0 (1/s^2)
    #[arg(long, default_value_t = ORBIT_KP, allow_negative_numbers = true)]
    pub kp: f64,
    /// K_D (1/s)
    #[arg(long, default_value_t = ORBIT_KD, allow_negative_numbers = true)]
    pub kd: f64,
    /// Draw the chart into this PNG file
    #[arg(long)]
    pub plot: Option<std::path::PathBuf>,
    /// Start from the adapted loop's orbit with this peak (rad; `plan orbit --peak`) and its
    /// E_av, instead of the k = 0 orbit's (which the physical landing law has not)
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    pub peak: Option<f64>,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
}

impl StabilityArgs {
    /// The job of these flags.
    pub fn job(&self) -> StabilityJob {
        StabilityJob {
            param2: self.param2,
            from2: self.from2,
            to2: self.to2,
            k_max: self.k_max,
            kp: self.kp,
            kd: self.kd,
            peak: self.peak,
        }
    }
}

/// Runs `stability`.
pub fn stability(args: &StabilityArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    let report = args.job().run(&params, &Bars::new(args.model.json))?;
    if let Some(path) = &args.plot {
        tilting_viz::continuation::draw_stability(path, &report.region)
            .map_err(|e| CommandError::Failed(anyhow!("cannot draw {}: {e:#}", path.display())))?;
    }
    emit(args.model.json, &report, || report.human())
}
