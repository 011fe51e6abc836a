//! `tilting plan orbit|sinusoid|bifurcation|gains`: the planning commands of the paper's
//! Sec. III. The computations live in `tilting_planner`'s [`orbit`], [`sinusoid`],
//! [`bifurcation`] and [`gains`].

use super::shard::{self, ShardArgs, Shards};
use super::{bar, emit, usage, ModelArgs};
use crate::CommandError;
use clap::Args;

use tilting_controller::{LawArgs, LawSpec, Trajectory};
use tilting_planner::jobs::{
    self, BifurcationJob, BifurcationRange, BifurcationShard, GainsJob, GainsShard,
};
pub use tilting_planner::jobs::{BifurcationReport, GainsReport, OrbitReport};
use tilting_planner::shard::Shard;
use tilting_plant::paper::{ORBIT_K, ORBIT_KD, ORBIT_KP};

/// `orbit`: the periodic orbits of approach 2 for one gain pair.
#[derive(Debug, Clone, Args)]
#[command(mut_arg("k", |a| a.help(
    "Energy adaptation gain k (1/(J s^2)); with k > 0 the orbit of the adapted loop \
     K_P = K_P0 + k (E_av - E) is computed, E_av taken from the k = 0 orbit unless given \
     [default: 0]"
)))]
#[command(mut_arg("energy_avg", |a| a.help(
    "Average energy E_av (J) for the adaptation [default: that of the k = 0 orbit]"
)))]
#[command(mut_arg("reference", |a| a.hide(true)))]
#[command(mut_arg("torque_limit", |a| a.hide(true)))]
pub struct OrbitArgs {
    /// The robot file (TOML, docs/guide/robot-file.md): its [robot] and [law] are the
    /// defaults of --params and the law's flags [default: none]
    #[arg(value_name = "ROBOT.toml")]
    pub robot_file: Option<std::path::PathBuf>,
    /// The law: the gains K_P (--kp) and K_D (--kd), and the adaptation (--k, --energy-avg);
    /// the orbits hold the arm upright without a torque limit.
    #[command(flatten)]
    pub law: LawArgs,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
    /// Find the adaptation's E_av (J) for which the adapted loop tilts with this peak |alpha|
    /// (rad), for any landing law; k defaults to the paper's 500 [default: off]
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    pub peak: Option<f64>,
    /// With --peak: refine E_av so the loop sampled every S seconds (the robot's control
    /// period; 0 for a continuous law), simulated with the robot's own landings
    /// (`restitution`), settles at the peak on average (a robot file with `restitution` other
    /// than 0 is refined at 0 s when this is not given) [default: off]
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub control_period: Option<f64>,
    /// With --peak: calibrate E_av on the robot from runs of the plain adapted law at or near
    /// this plan (`tilting live --plan plan.json --out RUN_DIR`, without --orbit-peak): each
    /// run's mean peak against the model's at its E_av gives the robot's bias, and the model's
    /// loop is settled that much below the peak (docs/guide/planning.md) [default: none]
    #[arg(long, value_name = "RUN_DIR", num_args = 1.., requires = "peak")]
    pub calibrate: Vec<std::path::PathBuf>,
}

impl OrbitArgs {
    /// The law of the flags over the paper's gains without adaptation (`k = 0`); a reference
    /// other than hold or a torque limit is a usage error.
    pub fn law(&self) -> Result<LawSpec, CommandError> {
        let law = self.law.over(LawSpec::without_adaptation());
        if law.reference != Trajectory::Hold || law.torque_limit.is_some() {
            return Err(usage(
                "`plan orbit` takes no --reference or --torque-limit: its orbits hold the arm \
                 upright without a torque limit"
                    .into(),
            ));
        }
        Ok(law)
    }
}

/// Runs `orbit`.
pub fn orbit(args: &OrbitArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    let law = args.law()?;
    let energy_avg = args.law.energy_avg.filter(|_| law.k > 0.0);
    let report = match args.peak {
        Some(peak) => {
            if args.law.energy_avg.is_some() {
                return Err(usage(
                    "`--peak` finds E_av: give --peak or --energy-avg, not both".into(),
                ));
            }
            let k = if law.k > 0.0 { law.k } else { ORBIT_K };
            let runs = args
                .calibrate
                .iter()
                .map(|d| {
                    let file = d.join("robot.toml");
                    let law = tilting_sim::robot::RobotFile::load(&file)
                        .and_then(|f| f.law())
                        .map_err(|e| usage(format!("`--calibrate`: {e}")))?
                        .ok_or_else(|| {
                            usage(format!(
                                "`--calibrate`: {} has no [law] table (a `tilting live --out \
                                 DIR` run writes it)",
                                file.display()
                            ))
                        })?;
                    tilting_planner::calibrate::recorded_orbit(d, &law)
                        .map_err(|e| usage(format!("`--calibrate`: {e}")))
                })
                .collect::<Result<Vec<_>, _>>()?;
            let b = spinner(args.model.json);
            let tick = |what: &str| b.set_message(what.to_owned());
            let r = jobs::orbit_for_peak(
                params,
                params.impact,
                [law.kp, law.kd, k],
                peak,
                args.control_period,
                &runs,
                &tick,
            );
            b.finish_and_clear();
            r
        }
        None => jobs::orbits(params, params.impact, law.kp, law.kd, law.k, energy_avg),
    }?;
    emit(args.model.json, &report, || report.human(args.peak))
}

/// `reach`: which gains reach a wanted tilt peak.
#[derive(Debug, Clone, Args)]
pub struct ReachArgs {
    /// The robot file (TOML, docs/guide/robot-file.md): its [robot] is the default of
    /// --params [default: none]
    #[arg(value_name = "ROBOT.toml")]
    pub robot_file: Option<std::path::PathBuf>,
    /// The wanted tilt peak |alpha| (rad)
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    pub peak: f64,
    /// First K_D (1/s)
    #[arg(long, default_value_t = 6.0, allow_negative_numbers = true)]
    pub kd_from: f64,
    /// Last K_D (1/s)
    #[arg(long, default_value_t = 16.0, allow_negative_numbers = true)]
    pub kd_to: f64,
    /// Step of K_D (1/s)
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub kd_step: f64,
    /// First k (1/(J s^2))
    #[arg(long, default_value_t = 250.0, allow_negative_numbers = true)]
    pub k_from: f64,
    /// Last k (1/(J s^2))
    #[arg(long, default_value_t = 1500.0, allow_negative_numbers = true)]
    pub k_to: f64,
    /// Step of k (1/(J s^2))
    #[arg(long, default_value_t = 250.0, allow_negative_numbers = true)]
    pub k_step: f64,
    /// K_P0 (1/s^2): not a dimension of the map (the law depends on K_P0 + k E_av only); it
    /// sets the E_av reported
    #[arg(long, default_value_t = ORBIT_KP, allow_negative_numbers = true)]
    pub kp: f64,
    /// Draw the map into this PNG file
    #[arg(long)]
    pub plot: Option<std::path::PathBuf>,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
}

/// The JSON of `reach`.
#[derive(Debug, serde::Serialize)]
pub struct ReachReport {
    /// The wanted peak (rad).
    pub peak: f64,
    /// K_P0 (1/s^2).
    pub kp: f64,
    /// The landing law.
    pub impact: &'static str,
    /// One cell per (K_D, k).
    pub cells: Vec<tilting_planner::peak::ReachCell>,
}

/// Runs `reach`.
pub fn reach(args: &ReachArgs) -> Result<(), CommandError> {
    use tilting_planner::peak::Reach;
    let params = args.model.params()?;
    let n = ((args.kd_to - args.kd_from) / args.kd_step + 1.5).max(1.0)
        * ((args.k_to - args.k_from) / args.k_step + 1.5).max(1.0);
    let b = bar(n.floor().clamp(1.0, 1e6) as u64, "reach", args.model.json);
    let cells = jobs::reach(
        params,
        params.impact,
        args.kp,
        [args.kd_from, args.kd_to, args.kd_step],
        [args.k_from, args.k_to, args.k_step],
        args.peak,
        &|| b.inc(1),
    )?;
    b.finish_and_clear();
    if let Some(path) = &args.plot {
        tilting_viz::reach::draw_reach(path, &cells, args.peak, params.impact.as_str()).map_err(
            |e| CommandError::Failed(anyhow::anyhow!("cannot draw {}: {e:#}", path.display())),
        )?;
    }
    let report = ReachReport {
        peak: args.peak,
        kp: args.kp,
        impact: params.impact.as_str(),
        cells,
    };
    emit(args.model.json, &report, || {
        let mut s = format!(
            "which (K_D, k) reach a tilt peak of {} rad ({} landing law, K_P0 = {}):\n",
            report.peak, report.impact, report.kp
        );
        for c in &report.cells {
            let what = match c.reach {
                Reach::Reached {
                    energy_avg,
                    stable,
                    rho,
                    peak_per_arm_mass,
                } => format!(
                    "reached at E_av = {energy_avg:.9} J, {} (largest |multiplier| {rho:.3}; \
                     peak per arm mass {})",
                    if stable { "stable" } else { "unstable" },
                    peak_per_arm_mass.map_or("at a fold".into(), |s| format!("{s:.1}"))
                ),
                Reach::Below { largest } => format!("not reached: at most {largest:.5} rad"),
                Reach::Above { smallest } => format!("not reached: at least {smallest:.5} rad"),
                Reach::None => "no tilting orbit found".into(),
            };
            s += &format!("  K_D = {:6.2}, k = {:7.1}: {what}\n", c.kd, c.k);
        }
        s
    })
}

/// A spinner on stderr with a message per stage (hidden with `--json` or off a terminal).
fn spinner(json: bool) -> indicatif::ProgressBar {
    if json || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new_spinner();
    b.enable_steady_tick(std::time::Duration::from_millis(200));
    b
}

// ---------------------------------------------------------------------------------------------

/// `sinusoid`: approach 1, the frequency for a landing condition.
#[derive(Debug, Clone, Args)]
pub struct SinusoidArgs {
    /// Amplitude A of beta_d = A sin(w t) + pi/2 (rad)
    #[arg(long, default_value_t = 0.33, allow_negative_numbers = true)]
    pub amplitude: f64,
    /// s in the landing condition t_l = T/2 + s t_t, in (-1, 1)
    #[arg(long, default_value_t = -0.5, allow_hyphen_values = true)]
    pub landing_offset: f64,
    /// Lowest frequency searched (rad/s)
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub omega_min: f64,
    /// Highest frequency searched (rad/s)
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub omega_max: f64,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
}

/// Runs `sinusoid`.
pub fn sinusoid(args: &SinusoidArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    let (a, s) = (args.amplitude, args.landing_offset);
    let sol = jobs::sinusoid(&params, a, s, args.omega_min, args.omega_max)?;
    emit(args.model.json, &sol, || {
        format!(
            "A = {} rad, t_l = T/2 + ({}) t_t: w = {:.9} rad/s (T = {:.6} s), tilt {} at t_t = {:.6} s, \
             landing at t_l = {:.6} s, max tilt {:.6} rad{}\n",
            sol.amplitude,
            sol.landing_offset,
            sol.omega,
            sol.period,
            sol.side,
            sol.tilt_time,
            sol.landing_time,
            sol.max_tilt,
            if sol.other_roots.is_empty() {
                String::new()
            } else {
                format!("; other solutions at w = {:?}", sol.other_roots)
            }
        )
    })
}

// ---------------------------------------------------------------------------------------------

/// `bifurcation`: the sweep of the adaptation gain k (Fig. 8) and k*.
#[derive(Debug, Clone, Args)]
pub struct BifurcationArgs {
    /// First k (1/(J s^2))
    #[arg(long, default_value_t = 1500.0, allow_negative_numbers = true)]
    pub k_from: f64,
    /// Last k
    #[arg(long, default_value_t = 2500.0, allow_negative_numbers = true)]
    pub k_to: f64,
    /// Step of k
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    pub k_step: f64,
    /// Tilts simulated for each k
    #[arg(long, default_value_t = 500)]
    pub tilts: usize,
    /// Tilts kept (the last ones) for each k
    #[arg(long, default_value_t = 200)]
    pub keep: usize,
    /// K_P0 (1/s^2)
    #[arg(long, default_value_t = ORBIT_KP, allow_negative_numbers = true)]
    pub kp: f64,
    /// K_D (1/s)
    #[arg(long, default_value_t = ORBIT_KD, allow_negative_numbers = true)]
    pub kd: f64,
    /// Peaks closer than this (rad) count as equal when classifying the period
    #[arg(long, default_value_t = 1e-5)]
    pub period_tol: f64,
    /// Sweep about the k = 500 loop's orbit with this peak (rad; `plan orbit --peak`): its E_av
    /// and start, instead of the k = 0 orbit's (which the physical landing law has not)
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    pub peak: Option<f64>,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
    /// Run one shard of the sweep (`--shard I/N`); shard 0 also locates k*.
    #[command(flatten)]
    pub sharding: ShardArgs,
}

/// The command name of `bifurcation` in shard files.
pub const BIFURCATION: &str = "plan bifurcation";
/// The command name of `gains` in shard files.
pub const GAINS: &str = "plan gains";

/// Checks the flags of `bifurcation` and returns its job.
fn bifurcation_job(args: &BifurcationArgs) -> Result<BifurcationJob, CommandError> {
    let range = BifurcationRange {
        k_from: args.k_from,
        k_to: args.k_to,
        k_step: args.k_step,
        tilts: args.tilts,
        keep: args.keep,
        kp: args.kp,
        kd: args.kd,
        period_tol: args.period_tol,
    };
    let params = args.model.params()?;
    let job = BifurcationJob::new(params, params.impact, &range)?;
    match args.peak {
        Some(p) => Ok(job.with_peak(p)?),
        None => Ok(job),
    }
}

/// Runs `bifurcation` (or one shard of it with `--shard`).
pub fn bifurcation(args: &BifurcationArgs) -> Result<(), CommandError> {
    let job = bifurcation_job(args)?;
    if let Some(s) = args.sharding.shard {
        let part = job.run_shard(s)?;
        return shard::emit_shard(BIFURCATION, s, &job, &part);
    }
    let b = bar(job.ks.len() as u64, "bifurcation", args.model.json);
    let report = job.run(&|| b.inc(1));
    b.finish_and_clear();
    let report = report?;
    emit(args.model.json, &report, || bifurcation_text(&report))
}

/// `tilting plan merge` of the shards of `bifurcation`: the report `--json` prints, the
/// timing summed over the shards.
pub fn merge_bifurcation(shards: Shards) -> Result<(), CommandError> {
    let job: BifurcationJob = serde_json::from_value(shards.grid)
        .map_err(|e| usage(format!("the shards' grid is not a bifurcation sweep: {e}")))?;
    let parts = own_parts::<BifurcationShard>(shards.parts, |p| p.shard)?;
    let report = job.merge(parts)?;
    emit(true, &report, String::new)
}

/// The parts of the shard files as `T`, each checked to be the shard its file says.
pub fn own_parts<T: serde::de::DeserializeOwned>(
    parts: Vec<(Shard, serde_json::Value)>,
    shard_of: impl Fn(&T) -> Shard,
) -> Result<Vec<T>, CommandError> {
    let parts: Vec<(Shard, T)> = shard::parts(parts)?;
    parts
        .into_iter()
        .map(|(s, p)| {
            if shard_of(&p) == s {
                Ok(p)
            } else {
                Err(usage(format!(
                    "the shard file of shard {s} holds shard {}",
                    shard_of(&p)
                )))
            }
        })
        .collect()
}

/// The report of `bifurcation` as text.
fn bifurcation_text(report: &BifurcationReport) -> String {
    let mut s =
        format!(
        "E_av = {:.9} J; k* (multiplier crosses -1) = {}; first k not period 1 in the sweep = {}\n",
        report.energy_avg,
        report.k_star.map_or("none in range".into(), |k| format!("{k:.3}")),
        report.k_onset_observed.map_or("none".into(), |k| format!("{k}"))
    );
    let tm = &report.timing;
    s += &format!(
        "wall time: set-up (base orbit) {:.3} s, sweep of {} values of k {:.3} s, k* {:.3} s\n",
        tm.setup_s,
        report.rows.len(),
        tm.sweep_s,
        tm.k_star_s
    );
    for r in &report.rows {
        let (lo, hi) = r
            .peaks
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        s += &format!(
            "  k = {:>8.2}: period {:>9}  |alpha| peaks in [{:.6}, {:.6}] rad{}\n",
            r.k,
            r.period.map_or("irregular".to_string(), |p| p.to_string()),
            lo,
            hi,
            r.fault
                .as_ref()
                .map_or(String::new(), |f| format!("  fault: {f}"))
        );
    }
    s
}

// ---------------------------------------------------------------------------------------------

/// `gains`: the maximal tilt angle over a grid of (K_P, K_D) (Fig. 6).
#[derive(Debug, Clone, Args)]
pub struct GainsArgs {
    /// First K_P (1/s^2)
    #[arg(long, default_value_t = 60.0, allow_negative_numbers = true)]
    pub kp_from: f64,
    /// Last K_P
    #[arg(long, default_value_t = 140.0, allow_negative_numbers = true)]
    pub kp_to: f64,
    /// Step of K_P
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    pub kp_step: f64,
    /// First K_D (1/s)
    #[arg(long, default_value_t = 8.0, allow_negative_numbers = true)]
    pub kd_from: f64,
    /// Last K_D
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    pub kd_to: f64,
    /// Step of K_D
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub kd_step: f64,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
    /// Run one shard of the grid (`--shard I/N`): its units are the rows of constant K_P.
    #[command(flatten)]
    pub sharding: ShardArgs,
}

/// `tilting plan merge` of the shards of `gains`: the report `--json` prints.
pub fn merge_gains(shards: Shards) -> Result<(), CommandError> {
    let job: GainsJob = serde_json::from_value(shards.grid)
        .map_err(|e| usage(format!("the shards' grid is not a gains grid: {e}")))?;
    let parts = own_parts::<GainsShard>(shards.parts, |p| p.shard)?;
    let report = job.merge(parts)?;
    emit(true, &report, String::new)
}

/// Checks the grid flags and returns the job.
pub fn gains_job(args: &GainsArgs) -> Result<GainsJob, CommandError> {
    let params = args.model.params()?;
    GainsJob::new(
        params,
        params.impact,
        [args.kp_from, args.kp_to, args.kp_step],
        [args.kd_from, args.kd_to, args.kd_step],
    )
    .map_err(CommandError::from)
}

/// Runs `gains`.
pub fn gains(args: &GainsArgs) -> Result<(), CommandError> {
    let job = gains_job(args)?;
    if let Some(s) = args.sharding.shard {
        return shard::emit_shard(GAINS, s, &job, &job.run_shard(s));
    }
    let b = bar(job.kps.len() as u64, "gains", args.model.json);
    let report = job.run(&|| b.inc(1));
    b.finish_and_clear();
    emit(args.model.json, &report, || {
        let mut s = String::from("maximal tilt angle (rad) of the periodic orbits\n");
        for c in &report.cells {
            s += &format!(
                "  K_P = {:>7.2}, K_D = {:>6.2}: {}\n",
                c.kp,
                c.kd,
                if c.max_tilt.is_empty() {
                    "no orbit found".to_string()
                } else {
                    c.max_tilt
                        .iter()
                        .zip(&c.stable)
                        .map(|(m, st)| format!("{m:.6}{}", if *st { " (stable)" } else { "" }))
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            );
        }
        s
    })
}
