//! `tilting plan orbit|sinusoid|bifurcation|gains`: the planning commands of the paper's
//! Sec. III. The computations live in `tilting_planner`'s [`orbit`], [`sinusoid`],
//! [`bifurcation`] and [`gains`].

use super::{bar, check, emit, usage, ModelArgs};
use crate::CommandError;
use anyhow::anyhow;
use clap::Args;
use serde::Serialize;
use std::time::Instant;
use tilting_controller::{LawArgs, LawSpec, Trajectory};
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::orbit::{self, OrbitProblem, OrbitSolution};
use tilting_planner::{gains, sinusoid};
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
    /// The law: the gains K_P (--kp) and K_D (--kd), and the adaptation (--k, --energy-avg);
    /// the orbits hold the arm upright without a torque limit.
    #[command(flatten)]
    pub law: LawArgs,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
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

/// The JSON of `orbit`.
#[derive(Debug, Serialize)]
pub struct OrbitReport {
    /// K_P (1/s^2).
    pub kp: f64,
    /// K_D (1/s).
    pub kd: f64,
    /// k.
    pub k: f64,
    /// E_av used by the adaptation (J), if any.
    pub energy_avg_adaptation: Option<f64>,
    /// The orbits found, by increasing maximal tilt.
    pub solutions: Vec<OrbitSolution>,
}

/// Runs `orbit`.
pub fn orbit(args: &OrbitArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    let law = args.law()?;
    check("kp", law.kp, law.kp > 0.0, "finite and > 0")?;
    check("kd", law.kd, law.kd > 0.0, "finite and > 0")?;
    check("k", law.k, law.k >= 0.0, "finite and >= 0")?;
    let pb = OrbitProblem::new(params, args.model.impact, law.kp, law.kd);
    let base = orbit::find_all(&pb);
    let (solutions, e_av) = if law.k > 0.0 {
        let e_av = match args.law.energy_avg {
            Some(e) => check("energy-avg", e, e > 0.0, "finite and > 0 (J)")?,
            None => base.first().map(|s| s.energy_avg).ok_or_else(|| {
                usage("no k = 0 orbit to take E_av from: give --energy-avg".into())
            })?,
        };
        let mut sols: Vec<OrbitSolution> = base
            .iter()
            .filter_map(|s| {
                // Continue each branch from k = 0 in steps, the orbit moves with k.
                let mut g = [s.beta0, s.beta_dot0, s.t_end];
                let n = (law.k / 100.0).ceil().max(1.0) as usize;
                let mut last = None;
                for i in 1..=n {
                    let kk = law.k * i as f64 / n as f64;
                    let sol = orbit::solve(&pb.with_adaptation(kk, e_av), g).ok()?;
                    g = [sol.beta0, sol.beta_dot0, sol.t_end];
                    last = Some(sol);
                }
                last
            })
            .collect();
        sols.sort_by(|a, b| a.max_tilt.total_cmp(&b.max_tilt));
        (sols, Some(e_av))
    } else {
        (base, None)
    };
    let report = OrbitReport {
        kp: law.kp,
        kd: law.kd,
        k: law.k,
        energy_avg_adaptation: e_av,
        solutions,
    };
    emit(args.model.json, &report, || {
        let mut s = format!(
            "periodic orbits for K_P = {}, K_D = {}, k = {} ({} found)\n",
            law.kp,
            law.kd,
            law.k,
            report.solutions.len()
        );
        if let Some(e) = report.energy_avg_adaptation {
            // The orbit's own E_av below is its mean energy; the adaptation's is the k = 0
            // orbit's, the one `simulate`/`live --energy-avg` need to run this orbit.
            s += &format!(
                "  adaptation E_av = {e:.9} J (the k = 0 orbit's): run it with --k {} \
                 --energy-avg {e:.9}\n",
                law.k
            );
        }
        for o in &report.solutions {
            let mult: Vec<String> = o
                .multipliers
                .iter()
                .map(|m| {
                    if m[1] == 0.0 {
                        format!("{:.6}", m[0])
                    } else {
                        format!("{:.6}{:+.6}i", m[0], m[1])
                    }
                })
                .collect();
            s += &format!(
                "  beta0 = {:+.9} rad, beta_dot0 = {:.9} rad/s, t_end = {:.9} s, period = {:.6} s, \
                 max tilt = {:.6} rad, E_av = {:.9} J, multipliers [{}] ({})\n",
                o.beta0,
                o.beta_dot0,
                o.t_end,
                o.period,
                o.max_tilt,
                o.energy_avg,
                mult.join(", "),
                if o.stable { "stable" } else { "unstable" }
            );
        }
        s
    })
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
    let search = sinusoid::Search {
        omega_min: args.omega_min,
        omega_max: args.omega_max,
        ..sinusoid::Search::default()
    };
    check(
        "omega-min",
        args.omega_min,
        args.omega_min > 0.0,
        "finite and > 0 (rad/s)",
    )?;
    check(
        "omega-max",
        args.omega_max,
        args.omega_max > args.omega_min,
        "finite and > --omega-min (rad/s)",
    )?;
    let sol = sinusoid::solve(&params, args.amplitude, args.landing_offset, &search).map_err(
        |e| match e {
            sinusoid::SinusoidError::Invalid { .. } => CommandError::Usage(e.into()),
            other => CommandError::Failed(other.into()),
        },
    )?;
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
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
}

/// The JSON of `bifurcation`.
#[derive(Debug, Serialize)]
pub struct BifurcationReport {
    /// E_av of the k = 0 orbit (J).
    pub energy_avg: f64,
    /// Where a multiplier of the adapted orbit crosses -1 (null if not in the range).
    pub k_star: Option<f64>,
    /// The first k of the sweep whose peaks are not period 1 (null if none).
    pub k_onset_observed: Option<f64>,
    /// One row per k.
    pub rows: Vec<bifurcation::Row>,
    /// Where the wall time went.
    pub timing: BifurcationTiming,
}

/// Wall times of one `bifurcation` command (s): a fixed set-up, the sweep (which grows with
/// the number of values of k and of tilts) and `k*`.
#[derive(Debug, Serialize)]
pub struct BifurcationTiming {
    /// Finding the `k = 0` base orbit the sweep starts from (s).
    pub setup_s: f64,
    /// The sweep over k on all cores (s).
    pub sweep_s: f64,
    /// Locating `k*` (s).
    pub k_star_s: f64,
}

/// Most cells of a `gains` grid (each one is an orbit search of about 0.1 s: 100,000 cells are
/// hours on 2 cores).
pub const MAX_GAIN_CELLS: f64 = 100_000.0;
/// Most values of `k` in one `bifurcation` sweep (each keeps `--keep` peaks in memory).
pub const MAX_SWEEP_VALUES: f64 = 100_000.0;
/// Most tilts simulated per `k`.
pub const MAX_TILTS: usize = 1_000_000;

/// The `k = 0` orbit the sweep starts from (the one with the smallest tilt).
fn base_orbit(pb: &OrbitProblem) -> Result<OrbitSolution, CommandError> {
    orbit::smallest(pb).ok_or_else(|| {
        CommandError::Failed(anyhow!(
            "no periodic orbit for K_P = {}, K_D = {}",
            pb.control.law.kp,
            pb.control.law.kd
        ))
    })
}

/// Runs `bifurcation`.
pub fn bifurcation(args: &BifurcationArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    check("k-from", args.k_from, args.k_from >= 0.0, "finite and >= 0")?;
    check(
        "k-to",
        args.k_to,
        args.k_to >= args.k_from,
        "finite and >= --k-from",
    )?;
    check("k-step", args.k_step, args.k_step > 0.0, "finite and > 0")?;
    check(
        "period-tol",
        args.period_tol,
        args.period_tol > 0.0,
        "finite and > 0 (rad)",
    )?;
    if args.keep == 0 || args.keep > args.tilts {
        return Err(usage(format!(
            "invalid `--keep` = {}: must be in 1..=--tilts ({})",
            args.keep, args.tilts
        )));
    }
    let n = gains::range_len(args.k_from, args.k_to, args.k_step);
    if n > MAX_SWEEP_VALUES {
        return Err(usage(format!(
            "invalid `--k-step` = {}: the sweep from --k-from {} to --k-to {} has {n:.0} values of \
             k; allowed: at most {MAX_SWEEP_VALUES}",
            args.k_step, args.k_from, args.k_to
        )));
    }
    if args.tilts > MAX_TILTS {
        return Err(usage(format!(
            "invalid `--tilts` = {}: allowed 1..={MAX_TILTS}",
            args.tilts
        )));
    }
    let pb = OrbitProblem::new(params, args.model.impact, args.kp, args.kd);
    let start = Instant::now();
    let o = base_orbit(&pb)?;
    let setup_s = start.elapsed().as_secs_f64();
    let ks = gains::range(args.k_from, args.k_to, args.k_step);
    let sw = Sweep {
        problem: pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: o.energy_avg,
        tilts: args.tilts,
        keep: args.keep,
        period_tol: args.period_tol,
    };
    let b = bar(ks.len() as u64, "bifurcation", args.model.json);
    let start = Instant::now();
    let rows = bifurcation::sweep(&sw, &ks, &|| b.inc(1));
    let sweep_s = start.elapsed().as_secs_f64();
    b.finish_and_clear();
    // The attracting adapted orbit is found by simulation at k = 500 (the paper's stabilised
    // case), or at k_from if that is lower, and continued from there.
    let start = Instant::now();
    let k_star = bifurcation::k_star(&sw, ORBIT_K, args.k_from, args.k_to, 1e-3);
    let k_star_s = start.elapsed().as_secs_f64();
    let report = BifurcationReport {
        energy_avg: o.energy_avg,
        k_star,
        k_onset_observed: rows.iter().find(|r| r.period != Some(1)).map(|r| r.k),
        rows,
        timing: BifurcationTiming {
            setup_s,
            sweep_s,
            k_star_s,
        },
    };
    emit(args.model.json, &report, || {
        let mut s = format!(
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
    })
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
}

/// The JSON of `gains`.
#[derive(Debug, Serialize)]
pub struct GainsReport {
    /// One entry per (K_P, K_D).
    pub cells: Vec<gains::Cell>,
}

/// Checks the grid flags and returns `(kps, kds)`.
pub fn grid_axes(args: &GainsArgs) -> Result<(Vec<f64>, Vec<f64>), CommandError> {
    check(
        "kp-from",
        args.kp_from,
        args.kp_from > 0.0,
        "finite and > 0",
    )?;
    check(
        "kp-to",
        args.kp_to,
        args.kp_to >= args.kp_from,
        "finite and >= --kp-from",
    )?;
    check(
        "kp-step",
        args.kp_step,
        args.kp_step > 0.0,
        "finite and > 0",
    )?;
    check(
        "kd-from",
        args.kd_from,
        args.kd_from > 0.0,
        "finite and > 0",
    )?;
    check(
        "kd-to",
        args.kd_to,
        args.kd_to >= args.kd_from,
        "finite and >= --kd-from",
    )?;
    check(
        "kd-step",
        args.kd_step,
        args.kd_step > 0.0,
        "finite and > 0",
    )?;
    // The grid is counted before it is allocated: a tiny step must be an error, not an abort.
    let cells = gains::range_len(args.kp_from, args.kp_to, args.kp_step)
        * gains::range_len(args.kd_from, args.kd_to, args.kd_step);
    if cells > MAX_GAIN_CELLS {
        return Err(usage(format!(
            "the (--kp-from..--kp-to step --kp-step) x (--kd-from..--kd-to step --kd-step) grid \
             has {cells:.0} cells; allowed: at most {MAX_GAIN_CELLS} (make a step larger)"
        )));
    }
    let kps = gains::range(args.kp_from, args.kp_to, args.kp_step);
    let kds = gains::range(args.kd_from, args.kd_to, args.kd_step);
    Ok((kps, kds))
}

/// Runs `gains`.
pub fn gains(args: &GainsArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    let (kps, kds) = grid_axes(args)?;
    let b = bar(kps.len() as u64, "gains", args.model.json);
    let cells = gains::grid(params, args.model.impact, &kps, &kds, &|| b.inc(1));
    b.finish_and_clear();
    let report = GainsReport { cells };
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
