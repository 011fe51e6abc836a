//! `tilting identify`: the physical parameters of a robot from a recording
//! ([`tilting_planner::identify`]): the estimates with their standard errors, the regressor's
//! condition number, what the data cannot fix; `--out` writes the `--params` TOML.

use super::{print_stdout, usage};
use crate::CommandError;
use clap::Args;
use std::path::PathBuf;
use tilting_planner::identify::{self, Identification, IdentifyError, Options, Velocities};
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
    if !(args.half_window.is_finite() && (0.002..=0.5).contains(&args.half_window)) {
        return Err(usage(format!(
            "invalid `--half-window` = {}: allowed a time in s in [0.002, 0.5]",
            args.half_window
        )));
    }
    if !(args.window.is_finite() && (0.01..=2.0).contains(&args.window)) {
        return Err(usage(format!(
            "invalid `--window` = {}: allowed a time in s in [0.01, 2]",
            args.window
        )));
    }
    if !(args.min_speed.is_finite() && (0.0..=10.0).contains(&args.min_speed)) {
        return Err(usage(format!(
            "invalid `--min-speed` = {}: allowed a speed in rad/s in [0, 10]",
            args.min_speed
        )));
    }
    if let Some(s) = args.settle {
        if !(s.is_finite() && (0.0..=1.0).contains(&s)) {
            return Err(usage(format!(
                "invalid `--settle` = {s}: allowed a time in s in [0, 1]"
            )));
        }
    }
    // The prior: --params, else the [prior] table of the robot file --out writes into.
    let prior = args
        .params
        .clone()
        .or_else(|| args.out.as_deref().and_then(crate::robot::prior_of));
    let base = match &prior {
        Some(p) => Params::from_toml_file(p).map_err(|e| CommandError::Usage(e.into()))?,
        None => Params::default(),
    };
    if !(args.fit_window.is_finite() && (0.01..=10.0).contains(&args.fit_window)) {
        return Err(usage(format!(
            "invalid `--fit-window` = {}: allowed a time in s in [0.01, 10]",
            args.fit_window
        )));
    }
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
    let mut id = identify::identify(
        &rec.trace,
        &rec.tau,
        &Options {
            base,
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
        },
    )
    .map_err(refused)?;
    let resim = id.check_fit(&rec.trace, &rec.tau, &base, args.fit_window);
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
        human(&id, &source, args.out.as_ref())
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

fn human(id: &Identification, source: &str, out: Option<&PathBuf>) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let r = id.rows;
    let _ = writeln!(
        s,
        "{source}: {} equations ({} flat and {} tilted intervals; {} skipped at events or \
         without a torque)",
        r.equations, r.flat, r.tilted, r.skipped
    );
    let _ = writeln!(
        s,
        "condition number {:.3e} (columns scaled), residual RMS {:.3e} N m\n",
        id.condition_number, id.residual_rms
    );
    let _ = writeln!(
        s,
        "{:<8} {:<28} {:>14} {:>11}  unit",
        "base", "", "estimate", "std err"
    );
    for e in &id.base {
        match (e.value, e.std_error) {
            (Some(v), Some(se)) => {
                let _ = writeln!(
                    s,
                    "{:<8} {:<28} {v:>14.6} {se:>11.2e}  {}",
                    e.name, e.combination, e.unit
                );
            }
            _ => {
                let why = e
                    .not_identifiable
                    .as_deref()
                    .unwrap_or("not fixed by the data");
                let _ = writeln!(
                    s,
                    "{:<8} {:<28} not identifiable: {why}",
                    e.name, e.combination
                );
            }
        }
    }
    if let Some(r) = &id.refinement {
        let _ = writeln!(
            s,
            "\noutput-error refinement ({} flat windows of {} s joined, {} angles, {} \
             iterations{}): beta RMS {:.3e} rad (least squares {:.3e}); J {:.6} +- {:.1e} kg m^2, \
             m_l l_c g {:.6} +- {:.1e} N m, b_v {:.6} +- {:.1e} N m s/rad, tau_c {:.6} +- \
             {:.1e} N m (b_v and tau_c above are these where their standard errors are smaller)",
            r.windows,
            r.window_s,
            r.samples,
            r.iterations,
            if r.converged { "" } else { ", not converged" },
            r.rms,
            r.rms_start,
            r.value[0],
            r.std_error[0],
            r.value[1],
            r.std_error[1],
            r.value[2],
            r.std_error[2],
            r.value[3],
            r.std_error[3]
        );
    }
    if let Some(l) = &id.landing {
        landing_summary(&mut s, l);
    }
    let p = &id.params;
    let _ = writeln!(
        s,
        "\nparameters: m_f {:.6} kg, m_l {:.6} kg (prior), l_c {:.6} m, i_l {:.6} kg m^2, \
         j_m {:.6} kg m^2, n_g {:.6}, b_v {:.6} N m s/rad, tau_c {:.6} N m, i_f {:.6} kg m^2, \
         impact {}, restitution {:.4}",
        p.m_f,
        p.m_l,
        p.lc(),
        p.i_l,
        p.j_m,
        p.n_g,
        p.b_v,
        p.tau_c,
        p.i_f,
        p.impact.as_str(),
        p.restitution
    );
    let _ = writeln!(s, "not identifiable from motion:");
    for n in &id.not_identifiable {
        let _ = writeln!(s, "  - {n}");
    }
    for w in &id.warnings {
        let _ = writeln!(s, "warning: {w}");
    }
    if let Some(f) = &id.fit {
        let _ = writeln!(
            s,
            "fit check (re-simulated under the recorded torques, restarted every {} s, {} \
             windows): RMS alpha {:.3e} rad, beta {:.3e} rad with the identified parameters; \
             {:.3e} rad, {:.3e} rad with the prior",
            f.identified.window_s,
            f.identified.windows,
            f.identified.rms_alpha,
            f.identified.rms_beta,
            f.prior.rms_alpha,
            f.prior.rms_beta
        );
    }
    if let Some(o) = out {
        let _ = writeln!(s, "wrote {} (use it with --params)", o.display());
    }
    s
}

/// The landings' lines of the human summary: the regressed `c`, the restitution, each law's
/// coefficient and residual, the best.
fn landing_summary(s: &mut String, l: &identify::landing::LandingFit) {
    use std::fmt::Write as _;
    let _ = writeln!(
        s,
        "\nlandings: {} used ({} skipped: a side shorter than {} samples), {} rebounds; \
         beta_dot+ = beta_dot- + c alpha_dot-: c = {:.5} +- {:.1e}; physical law's restitution \
         e = {:.4} +- {:.1e}",
        l.landings.len(),
        l.skipped,
        identify::landing::MIN_SIDE,
        l.rebounds,
        l.c,
        l.c_std_error,
        l.restitution,
        l.restitution_std_error
    );
    if let Some(t) = &l.by_tilts {
        let _ = writeln!(
            s,
            "  restitution by the tilts after the landings (the model's next peak as recorded): \
             e = {:.4} +- {:.1e} over {} landings{}",
            t.e,
            t.std_error,
            t.landings,
            if t.e < 0.0 {
                " (below 0: the plate passes on into the next tilt)"
            } else {
                ""
            }
        );
    }
    if let Some(d) = &l.contact_dwell {
        let _ = writeln!(
            s,
            "  the contact reports the plate flat for {:.2} ms on average (longest {:.2} ms) \
             at {} landings that pass on into the other tilt{}",
            d.mean * 1e3,
            d.longest * 1e3,
            d.spells,
            if d.outliers > 0 {
                format!(
                    " ({} longer than {} x the median left out: the plate at rest a moment)",
                    d.outliers,
                    identify::landing::DWELL_OUTLIER
                )
            } else {
                String::new()
            }
        );
    }
    for f in &l.laws {
        let _ = writeln!(
            s,
            "  {:<14} c {:.5}  residual RMS {:.3e} rad/s{}",
            f.law.as_str(),
            f.c,
            f.residual_rms,
            if f.law == l.best {
                "  <- fits best"
            } else {
                ""
            }
        );
    }
}
