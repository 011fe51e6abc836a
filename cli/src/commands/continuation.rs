//! `tilting plan continuation`: the orbits continued in a parameter, their flips, the
//! period-doubling cascade and the largest Lyapunov exponent (issue 19). The computations live
//! in `tilting_planner::continuation` and `tilting_planner::lyapunov`.

use super::{bar, check, emit, usage, ModelArgs};
use crate::CommandError;
use anyhow::anyhow;
use clap::Args;
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;
use tilting_planner::continuation::twopar::{self, Region};
use tilting_planner::continuation::{self, Diagram, EventKind, Param, Settings};
use tilting_planner::lyapunov::sampled::{self, SampledExponent};
use tilting_planner::lyapunov::{self, Exponent};
use tilting_planner::orbit::OrbitProblem;
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

/// The JSON of `continuation`.
#[derive(Debug, Serialize)]
pub struct ContinuationReport {
    /// E_av of the k = 0 orbit (J), the adaptation's target.
    pub energy_avg: f64,
    /// Where the continuation started.
    pub p_start: f64,
    /// The branches, flips, ratios and accumulation point.
    pub diagram: Diagram,
    /// The largest Lyapunov exponent against the parameter.
    pub lyapunov: Vec<Exponent>,
    /// With `--control-period`: the sampled loop's two largest exponents on the same values.
    pub lyapunov_sampled: Vec<SampledExponent>,
    /// Continuation steps over all branches.
    pub steps: usize,
    /// Wall times (s).
    pub timing: ContinuationTiming,
}

/// Wall times of one `continuation` command (s).
#[derive(Debug, Serialize)]
pub struct ContinuationTiming {
    /// The base orbit and the attracting start (s).
    pub setup_s: f64,
    /// All branches with their events and switches (s).
    pub continuation_s: f64,
    /// The Lyapunov curve on all cores (s).
    pub lyapunov_s: f64,
    /// The sampled loop's curve on all cores (s), 0 without `--control-period`.
    pub lyapunov_sampled_s: f64,
    /// `continuation_s` per step (ms).
    pub per_step_ms: f64,
}

/// Runs `continuation`.
pub fn continuation(args: &ContinuationArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    check("kp", args.kp, args.kp > 0.0, "finite and > 0")?;
    check("kd", args.kd, args.kd > 0.0, "finite and > 0")?;
    check("k", args.k, args.k >= 0.0, "finite and >= 0")?;
    if !(1..=64).contains(&args.max_period) || !args.max_period.is_power_of_two() {
        return Err(usage(format!(
            "invalid `--max-period` = {}: must be a power of two in 1..=64",
            args.max_period
        )));
    }
    if args.tilts == 0 || args.tilts > 100_000 || args.transient > 100_000 {
        return Err(usage(format!(
            "invalid `--tilts` = {} / `--transient` = {}: allowed 1..=100000 and 0..=100000",
            args.tilts, args.transient
        )));
    }
    if args.plot.is_some() && args.param != Param::K {
        return Err(usage(
            "`--plot` draws Fig. 8b over k: it needs `--param k`".into(),
        ));
    }
    if let Some(h) = args.control_period {
        check("control-period", h, h > 0.0 && h <= 0.05, "in (0, 0.05] s")?;
    }
    let pb = OrbitProblem::new(params, params.impact, args.kp, args.kd);
    // The parameter's start value (the adaptation's E_av does not enter any parameter).
    let p0 = args.param.get(&pb.with_adaptation(args.k, 0.0));
    let to = match (args.to, args.param) {
        (Some(v), _) => v,
        (None, Param::K) => 2400.0,
        (None, p) => {
            return Err(usage(format!(
                "`--param {p}` needs `--to` (where to continue to)"
            )))
        }
    };
    let (ok, range) = args.param.allows(to);
    check(
        "to",
        to,
        ok && to != p0,
        &format!("{range} and not the start {p0}"),
    )?;
    let span = (to - p0).abs();
    let ds = check(
        "step",
        args.step.unwrap_or(span / 200.0),
        args.step.is_none_or(|s| s > 0.0),
        "finite and > 0",
    )?;
    let ds_max = args.max_step.unwrap_or(span / 50.0).max(ds);
    let lstep = args.lyapunov_step.unwrap_or(span / 200.0);
    check("lyapunov-step", lstep, lstep >= 0.0, "finite and >= 0")?;
    let start = Instant::now();
    let st = match args.peak {
        Some(p) => continuation::start_at_peak(&pb, args.k, p),
        None => continuation::start(&pb, args.k),
    }
    .map_err(|e| CommandError::Failed(anyhow!(e)))?;
    let (o, sw, base, guess) = (&st.orbit, &st.sweep, st.base, st.guess);
    let setup_s = start.elapsed().as_secs_f64();
    let set = Settings {
        ds,
        ds_min: ds * 1e-4,
        ds_max,
        ..Settings::over(p0, to, args.max_period)
    };
    let b = bar(1000, "continuation", args.model.json);
    let at = AtomicU64::new(0);
    let start = Instant::now();
    let diagram = continuation::diagram(&base, args.param, p0, guess, &set, &|tilts, p| {
        // Position: the branch's share of the range, in blocks per period.
        let block =
            (tilts.trailing_zeros() as u64) * 1000 / (args.max_period.trailing_zeros() as u64 + 1);
        let frac = ((p - p0) / (to - p0)).clamp(0.0, 1.0);
        let pos = block + (frac * 1000.0 / (args.max_period.trailing_zeros() as f64 + 1.0)) as u64;
        at.fetch_max(pos, Ordering::Relaxed);
        b.set_position(at.load(Ordering::Relaxed));
    })
    .map_err(|e| CommandError::Failed(anyhow!("continuation failed: {e}")))?;
    let continuation_s = start.elapsed().as_secs_f64();
    b.finish_and_clear();
    let ps = continuation::grid(p0, to, lstep);
    let b = bar(ps.len() as u64, "lyapunov", args.model.json);
    let start = Instant::now();
    let param = args.param;
    let lyap = lyapunov::curve(
        &ps,
        &|p| param.set(&base, p),
        [o.beta0, o.beta_dot0],
        args.transient,
        args.tilts,
        &|| b.inc(1),
    );
    let lyapunov_s = start.elapsed().as_secs_f64();
    b.finish_and_clear();
    let start = Instant::now();
    let lyap_sampled = match args.control_period {
        Some(h) => {
            let b = bar(ps.len() as u64, "sampled", args.model.json);
            let c = sampled::curve(
                &ps,
                &|p| param.set(&base, p),
                h,
                [o.beta0, o.beta_dot0],
                args.transient,
                args.tilts,
                &|| b.inc(1),
            );
            b.finish_and_clear();
            c
        }
        None => Vec::new(),
    };
    let lyapunov_sampled_s = start.elapsed().as_secs_f64();
    if let Some(path) = &args.plot {
        let range = (ps.first().copied().unwrap_or(p0), to);
        plot(args, path, sw, range, &diagram, (&lyap, &lyap_sampled))?;
    }
    let steps = diagram.steps();
    let report = ContinuationReport {
        energy_avg: st.energy_avg,
        p_start: p0,
        steps,
        timing: ContinuationTiming {
            setup_s,
            continuation_s,
            lyapunov_s,
            lyapunov_sampled_s,
            per_step_ms: 1e3 * continuation_s / steps.max(1) as f64,
        },
        diagram,
        lyapunov: lyap,
        lyapunov_sampled: lyap_sampled,
    };
    emit(args.model.json, &report, || human(&report))
}

/// Draws Fig. 8b of `continuation --plot` into `path`: the sweep of `sw` over `range` of `k`
/// with the diagram and the exponents.
fn plot(
    args: &ContinuationArgs,
    path: &std::path::Path,
    sw: &tilting_planner::bifurcation::Sweep,
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

/// The human summary.
fn human(r: &ContinuationReport) -> String {
    let d = &r.diagram;
    let name = d.param.name();
    let mut s = format!(
        "continuation in {name} from {} (E_av = {:.9} J): {} branches, {} steps\n",
        r.p_start,
        r.energy_avg,
        d.branches.len(),
        r.steps
    );
    for br in &d.branches {
        let (lo, hi) = br
            .points
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.p), b.max(p.p))
            });
        let worst = br.points.iter().map(|p| p.residual).fold(0.0, f64::max);
        s += &format!(
            "  period {:>2}: {} points in {name} [{lo:.4}, {hi:.4}], {} steps, {} Newton iterations, \
             largest residual {worst:.1e}, end: {:?}\n",
            br.tilts,
            br.points.len(),
            br.steps,
            br.newton_iterations,
            br.end
        );
        for ev in &br.events {
            let mu: Vec<String> = ev
                .point
                .multipliers
                .iter()
                .map(|m| format!("{:.6}{:+.6}i", m[0], m[1]))
                .collect();
            s += &format!(
                "    {}: {name} = {:.7}, multipliers {}\n",
                match ev.kind {
                    EventKind::Flip => "flip",
                    EventKind::Fold => "fold",
                    EventKind::NeimarkSacker => "Neimark-Sacker",
                },
                ev.p,
                mu.join(", ")
            );
        }
    }
    s += "flips (period 2^(n-1) -> 2^n):\n";
    for (i, k) in d.flips.iter().enumerate() {
        let ratio = (i >= 2).then(|| d.ratios[i - 2]);
        s += &format!(
            "  {name}_{} = {k:.7}{}\n",
            i + 1,
            ratio.map_or(String::new(), |q| format!(
                "   ratio ({name}_{} - {name}_{}) / ({name}_{} - {name}_{}) = {q:.4} (Feigenbaum {:.4})",
                i,
                i - 1,
                i + 1,
                i,
                continuation::FEIGENBAUM_DELTA
            ))
        );
    }
    if let Some(pi) = d.p_inf {
        s += &format!("accumulation point {name}_inf = {pi:.4} (own ratio)");
        if let Some(pf) = d.p_inf_feigenbaum {
            s += &format!(", {pf:.4} (Feigenbaum's)");
        }
        s += "\n";
    }
    if !r.lyapunov.is_empty() {
        let pos = r
            .lyapunov
            .iter()
            .find(|e| e.lambda.is_some_and(|l| l > 0.01));
        s += &format!(
            "Lyapunov: {} values; first exponent above 0.01 1/s at {name} = {}\n",
            r.lyapunov.len(),
            pos.map_or("none".into(), |e| format!(
                "{} ({:.4} 1/s)",
                e.p,
                e.lambda.unwrap_or(0.0)
            ))
        );
    }
    if let Some(h) = r.lyapunov_sampled.first().map(|e| e.period) {
        let pos = r
            .lyapunov_sampled
            .iter()
            .find(|e| e.lambda.is_some_and(|l| l > 0.01));
        let faults = r
            .lyapunov_sampled
            .iter()
            .filter(|e| e.fault.is_some())
            .count();
        s += &format!(
            "Lyapunov of the loop sampled every {} ms: {} values ({faults} faulted); first largest exponent above 0.01 1/s at {name} = {}\n",
            h * 1e3,
            r.lyapunov_sampled.len(),
            pos.map_or("none".into(), |e| format!(
                "{} ({:.4} 1/s)",
                e.p,
                e.lambda.unwrap_or(0.0)
            ))
        );
    }
    let tm = &r.timing;
    s += &format!(
        "wall time: set-up {:.3} s, continuation {:.3} s ({:.2} ms per step), Lyapunov {:.3} s, sampled {:.3} s\n",
        tm.setup_s, tm.continuation_s, tm.per_step_ms, tm.lyapunov_s, tm.lyapunov_sampled_s
    );
    s
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

/// The JSON of `stability`.
#[derive(Debug, Serialize)]
pub struct StabilityReport {
    /// The region: the flip and fold curves.
    pub region: Region,
    /// Wall time (s).
    pub seconds: f64,
}

/// Runs `stability`.
pub fn stability(args: &StabilityArgs) -> Result<(), CommandError> {
    let params = args.model.params()?;
    check("kp", args.kp, args.kp > 0.0, "finite and > 0")?;
    check("kd", args.kd, args.kd > 0.0, "finite and > 0")?;
    check(
        "k-max",
        args.k_max,
        args.k_max > ORBIT_K,
        &format!("finite and > {ORBIT_K}"),
    )?;
    let p2 = args.param2;
    if p2 == Param::K {
        return Err(usage("invalid `--param2` = k: the first parameter is k; choose kd, kp, m_l, m_l_plant or m_f".into()));
    }
    let (lo, hi) = match (args.from2, args.to2, p2) {
        (Some(a), Some(b), _) => (a, b),
        (a, b, Param::Kd) => (a.unwrap_or(8.0), b.unwrap_or(18.0)),
        (a, b, Param::MlPlant) => (a.unwrap_or(0.7), b.unwrap_or(1.4)),
        _ => {
            return Err(usage(format!(
                "`--param2 {p2}` needs `--from2` and `--to2`"
            )))
        }
    };
    let (ok, range) = p2.allows(lo);
    check("from2", lo, ok, range)?;
    check("to2", hi, hi > lo, "finite and > --from2")?;
    let pb = OrbitProblem::new(params, params.impact, args.kp, args.kd);
    let base_p2 = p2.get(&pb);
    if !(lo..=hi).contains(&base_p2) {
        return Err(usage(format!(
            "invalid range [--from2 {lo}, --to2 {hi}]: it must contain the base value {p2} = {base_p2}"
        )));
    }
    let start = Instant::now();
    let b = bar(400, "stability", args.model.json);
    let region = match args.peak {
        Some(p) => continuation::start_at_peak(&pb, ORBIT_K, p).and_then(|st| {
            twopar::region_from(&st, ORBIT_K, args.k_max, (p2, (lo, hi)), &|| b.inc(1))
        }),
        None => twopar::region(&pb, ORBIT_K, args.k_max, (p2, (lo, hi)), &|| b.inc(1)),
    }
    .map_err(|e| CommandError::Failed(anyhow!(e)))?;
    b.finish_and_clear();
    if let Some(path) = &args.plot {
        tilting_viz::continuation::draw_stability(path, &region)
            .map_err(|e| CommandError::Failed(anyhow!("cannot draw {}: {e:#}", path.display())))?;
    }
    let report = StabilityReport {
        region,
        seconds: start.elapsed().as_secs_f64(),
    };
    emit(args.model.json, &report, || {
        let r = &report.region;
        let mut s = format!(
            "stability region of the period-1 orbit in (k, {p2}) ({:.2} s); base {p2} = {}\n",
            report.seconds, r.p2_base
        );
        for (name, c) in [("flip (upper k)", &r.flip), ("fold (lower k)", &r.fold)] {
            let Some(c) = c else { continue };
            s += &format!("  {name}: {} points, ends {:?}\n", c.points.len(), c.ends);
            let step = (c.points.len() / 12).max(1);
            for p in c.points.iter().step_by(step) {
                s += &format!("    {p2} = {:>9.4}  k = {:>10.3}\n", p[1], p[0]);
            }
        }
        for n in &r.notes {
            s += &format!("  note: {n}\n");
        }
        s
    })
}
