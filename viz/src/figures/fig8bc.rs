//! Figs. 8b and 8c (issue 19): the continued orbits over the sweep with the Lyapunov exponent,
//! and the stability region of the period-1 orbit in `(k, K_D)`, computed and drawn by the same
//! functions as `plan continuation --plot` and `plan stability --plot`.

use super::*;
use crate::continuation::{cascade_figure, draw_stability};
use tilting_planner::continuation::{self as cont, twopar, Param};
use tilting_planner::lyapunov::{self, sampled};
use tilting_plant::paper::ORBIT_K;

/// What Fig. 8b shows (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig8bSummary {
    /// The branches' periods (tilts), in continuation order.
    pub branch_periods: Vec<usize>,
    /// Continuation steps over all branches.
    pub continuation_steps: usize,
    /// The flip sequence `k_1 < k_2 < ...` (1/(J s^2)).
    pub flips_k: Vec<f64>,
    /// The accumulation point from the flips' own ratio, if three flips were found.
    pub k_inf: Option<f64>,
    /// The first `k` of the Lyapunov curve whose exponent is above 0.01 1/s, if any.
    pub lyapunov_positive_from: Option<f64>,
    /// Values of the Lyapunov curve.
    pub lyapunov_values: usize,
    /// One line of text.
    pub text: String,
}

/// What Fig. 8c shows (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig8cSummary {
    /// The flip curve's points `(k, K_D)`.
    pub flip_curve: Vec<[f64; 2]>,
    /// The fold curve's points `(k, K_D)`.
    pub fold_curve: Vec<[f64; 2]>,
    /// Why a curve is missing, if one is.
    pub notes: Vec<String>,
    /// One line of text.
    pub text: String,
}

/// Fig. 8b's sampled loop: the control period (s) and the tilts of each exponent.
const SAMPLED: (f64, usize, usize) = (1e-3, 50, 200);

/// Progress units of Fig. 8b: one per continued branch, per Lyapunov value (of both loops) and
/// per `k` of the sweep.
pub(super) fn units_8b(ctx: &Ctx) -> usize {
    let s = &ctx.set;
    let branches = s.cascade_period.trailing_zeros() as usize + 1;
    let lyap = cont::grid(ORBIT_K, s.cascade_to, s.lyapunov_step).len();
    let sweep = s.cascade_sweep.ks((ORBIT_K, s.cascade_to)).len();
    branches + lyap + cont::grid(ORBIT_K, s.cascade_to, s.sampled_step).len() + sweep
}

/// Progress units of Fig. 8c: an upper bound, two curves of at most 80 steps each.
pub(super) fn units_8c() -> usize {
    160
}

pub(super) fn fig8b(ctx: &Ctx, tick: &(dyn Fn() + Sync)) -> Result<Fig8bSummary> {
    let s = &ctx.set;
    let st = cont::start(&ctx.orbit_problem(), ORBIT_K).map_err(|e| anyhow!(e))?;
    let set = cont::Settings::over(ORBIT_K, s.cascade_to, s.cascade_period);
    // A tick when each new branch starts (the steps per branch are not known beforehand).
    let last = std::sync::atomic::AtomicUsize::new(0);
    let d = cont::diagram(&st.base, Param::K, ORBIT_K, st.guess, &set, &|tilts, _| {
        if last.fetch_max(tilts, std::sync::atomic::Ordering::Relaxed) < tilts {
            tick();
        }
    })
    .map_err(|e| anyhow!("continuation failed: {e}"))?;
    let ps = cont::grid(ORBIT_K, s.cascade_to, s.lyapunov_step);
    let lyap = lyapunov::curve(
        &ps,
        &|p| Param::K.set(&st.base, p),
        [st.orbit.beta0, st.orbit.beta_dot0],
        s.lyapunov_transient,
        s.lyapunov_tilts,
        tick,
    );
    let sampled = sampled::curve(
        &cont::grid(ORBIT_K, s.cascade_to, s.sampled_step),
        &|p| Param::K.set(&st.base, p),
        SAMPLED.0,
        [st.orbit.beta0, st.orbit.beta_dot0],
        SAMPLED.1,
        SAMPLED.2,
        tick,
    );
    cascade_figure(
        &ctx.path("8b"),
        &st.sweep,
        (ORBIT_K, s.cascade_to),
        s.cascade_sweep,
        &d,
        &lyap,
        &sampled,
        tick,
    )?;
    let positive = lyap
        .iter()
        .find(|e| e.lambda.is_some_and(|l| l > 0.01))
        .map(|e| e.p);
    let text = format!(
        "{} branches (periods {}) continued in k from {ORBIT_K} to {} in {} steps; flips at k = {}; k_inf = {}; Lyapunov exponent over {} values, positive from k = {}",
        d.branches.len(),
        d.branches
            .iter()
            .map(|b| b.tilts.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        s.cascade_to,
        d.steps(),
        d.flips
            .iter()
            .map(|k| format!("{k:.3}"))
            .collect::<Vec<_>>()
            .join(", "),
        d.p_inf.map_or("not estimated".into(), |k| format!("{k:.2}")),
        lyap.len(),
        positive.map_or("none".into(), |k| format!("{k}")),
    );
    Ok(Fig8bSummary {
        branch_periods: d.branches.iter().map(|b| b.tilts).collect(),
        continuation_steps: d.steps(),
        flips_k: d.flips.clone(),
        k_inf: d.p_inf,
        lyapunov_positive_from: positive,
        lyapunov_values: lyap.len(),
        text,
    })
}

pub(super) fn fig8c(ctx: &Ctx, tick: &(dyn Fn() + Sync)) -> Result<Fig8cSummary> {
    let r = twopar::region(
        &ctx.orbit_problem(),
        ORBIT_K,
        4000.0,
        (Param::Kd, ctx.set.kd_range),
        tick,
    )
    .map_err(|e| anyhow!(e))?;
    draw_stability(&ctx.path("8c"), &r)?;
    let pts = |c: &Option<twopar::Curve>| c.as_ref().map_or(Vec::new(), |c| c.points.clone());
    let (flip, fold) = (pts(&r.flip), pts(&r.fold));
    let span = |v: &[[f64; 2]]| {
        v.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p[0]), b.max(p[0]))
            })
    };
    let ((f0, f1), (g0, g1)) = (span(&flip), span(&fold));
    let text = format!(
        "stability region of the period-1 orbit for K_D in [{}, {}]: flip curve {} points (k from {f0:.1} to {f1:.1}), fold curve {} points (k from {g0:.1} to {g1:.1}){}",
        ctx.set.kd_range.0,
        ctx.set.kd_range.1,
        flip.len(),
        fold.len(),
        if r.notes.is_empty() {
            String::new()
        } else {
            format!("; {}", r.notes.join("; "))
        }
    );
    Ok(Fig8cSummary {
        flip_curve: flip,
        fold_curve: fold,
        notes: r.notes,
        text,
    })
}
