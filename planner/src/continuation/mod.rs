//! Pseudo-arclength continuation of the periodic tilting orbits (issue 19): the period-1 orbit
//! of approach 2 followed in a parameter (`k` by default), its Floquet multipliers along the
//! branch, flips (period doubling), folds and Neimark–Sacker points located by a test function,
//! and branch switching at each flip to the doubled-period orbit, solved as its own boundary
//! value problem ([`cycle`]: `n` tilts of the mirrored half-period map by multiple shooting).
//!
//! The method is the one of AUTO-07p, MatCont, COCO (its `hspo` toolbox for hybrid periodic
//! orbits) and BifurcationKit.jl, applied to the hybrid shooting map of [`orbit`](crate::orbit):
//! the landing event, the impact map and the mirror sit inside the residual, and the
//! multipliers come from the same variational equations with the landing's saltation.
//! - Predictor: the unit tangent of `R(z, p) = 0` (null vector of `[dR/dz, dR/dp]`, `dR/dp` by
//!   central differences), corrector: Newton on `R = 0` with the hyperplane through the
//!   predictor orthogonal to the tangent; step doubled by 1.5 after an easy corrector, halved
//!   after a failure or a jump.
//! - Test functions of the cycle's 2x2 monodromy `M`: `det(I + M)` (flip), `det(I - M)`
//!   (fold), `det M - 1` with complex multipliers (Neimark–Sacker), each zero located by the
//!   Illinois regula falsi along the chord between the two bracketing points until the
//!   parameter bracket is below [`Settings::locate_tol`].
//! - Branch switching at a flip: the doubled cycle plus `eps (w, -w)` with `w` the flip
//!   eigenvector carried along the tilts, corrected on the hyperplane orthogonal to `(w, -w)`.

pub(crate) mod arclength;
mod branch;
pub(crate) mod cycle;
pub mod param;
pub mod twopar;

pub use param::Param;

use crate::bifurcation::{self, Sweep};
use crate::orbit::{self, OrbitError, OrbitProblem, OrbitSolution};
use arclength::Continuation;
use nalgebra::DVector;
use serde::{Deserialize, Serialize};
use tilting_controller::PlannableLaw;

/// Feigenbaum's constant `delta` for period-doubling cascades of one-humped maps.
pub const FEIGENBAUM_DELTA: f64 = 4.669_201_609_102_99;

/// How to continue.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Lowest parameter value: a branch stops when it leaves `[p_min, p_max]`.
    pub p_min: f64,
    /// Highest parameter value.
    pub p_max: f64,
    /// First step, in parameter units (arclength scaled by the parameter's scale).
    pub ds: f64,
    /// Smallest step before a branch is given up.
    pub ds_min: f64,
    /// Largest step.
    pub ds_max: f64,
    /// Most steps per branch.
    pub max_steps: usize,
    /// Width of the parameter bracket a bifurcation is located to.
    pub locate_tol: f64,
    /// Switch at flips until the branches reach this period (in tilts): 16 follows the
    /// period-1, 2, 4, 8 and 16 orbits and locates the flip of the last one too.
    pub max_period: usize,
    /// End each branch at its first located bifurcation.
    pub stop_at_first_event: bool,
}

impl Settings {
    /// `plan continuation`'s settings from `p0` to `to` up to period `max_period`: first step
    /// 1/200 of the range, largest 1/50, smallest 1e-4 of the first, at most 2000 steps per
    /// branch, bifurcations located to 1e-7.
    pub fn over(p0: f64, to: f64, max_period: usize) -> Self {
        let span = (to - p0).abs();
        Self {
            p_min: p0.min(to),
            p_max: p0.max(to),
            ds: span / 200.0,
            ds_min: span / 200.0 * 1e-4,
            ds_max: span / 50.0,
            max_steps: 2000,
            locate_tol: 1e-7,
            max_period,
            stop_at_first_event: false,
        }
    }
}

/// One point of a branch: a solved period-`n` cycle.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Point {
    /// Parameter value.
    pub p: f64,
    /// The cycle `(beta0_i - ..., beta_dot0_i, t_i)` per tilt (rad, rad/s, s): `beta0` is
    /// `beta - pi/2` at the (mirrored) start of tilt `i`, `t_i` its duration.
    pub z: Vec<f64>,
    /// Maximal `|alpha|` (rad) of each tilt, by the hybrid simulator.
    pub peaks: Vec<f64>,
    /// Floquet multipliers of the cycle's map (the `n`-fold mirrored half-period map), `[re,
    /// im]`.
    pub multipliers: Vec<[f64; 2]>,
    /// All multipliers inside the unit circle.
    pub stable: bool,
    /// 2-norm of the BVP residual.
    pub residual: f64,
    /// Largest mismatch when each tilt is re-simulated by the hybrid simulator (post-impact
    /// state against the next mirrored start, and landing time), an independent check.
    pub resimulated_mismatch: f64,
}

/// What a test function found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A real multiplier crosses -1: period doubling.
    Flip = 0,
    /// A real multiplier crosses +1: a fold (limit point) of the branch.
    Fold = 1,
    /// A complex pair crosses the unit circle.
    NeimarkSacker = 2,
}

/// A located bifurcation.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Event {
    /// Its kind.
    pub kind: EventKind,
    /// Parameter value, located to [`Settings::locate_tol`].
    pub p: f64,
    /// The test function's value there (0 at the exact point).
    pub test: f64,
    /// The orbit there.
    pub point: Point,
}

/// Why a branch ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EndReason {
    /// It left the parameter range.
    Range,
    /// It took the most steps allowed.
    Steps,
    /// It stopped at its first bifurcation, as asked.
    Event,
    /// The corrector failed at the smallest step (the message says why).
    Failed(String),
}

/// One continued branch.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Branch {
    /// Tilts per period of its orbits (1, 2, 4, ...).
    pub tilts: usize,
    /// Its points, in continuation order.
    pub points: Vec<Point>,
    /// The bifurcations located along it.
    pub events: Vec<Event>,
    /// Continuation steps taken.
    pub steps: usize,
    /// Newton iterations of its correctors (location and switching not included).
    pub newton_iterations: usize,
    /// Why it ended.
    pub end: EndReason,
}

/// The period-doubling cascade: the branches, the flip sequence and its ratios.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Diagram {
    /// The continuation parameter.
    pub param: Param,
    /// The branches: period 1, then each doubled one.
    pub branches: Vec<Branch>,
    /// `p_1 < p_2 < ...`: the first flip of each branch.
    pub flips: Vec<f64>,
    /// `(p_n - p_{n-1}) / (p_{n+1} - p_n)`, to compare with [`FEIGENBAUM_DELTA`].
    pub ratios: Vec<f64>,
    /// The accumulation point extrapolated from the last three flips with their own ratio,
    /// `p_n + (p_n - p_{n-1}) / (delta_n - 1)`.
    pub p_inf: Option<f64>,
    /// The same from the last two flips with Feigenbaum's `delta`.
    pub p_inf_feigenbaum: Option<f64>,
}

impl Diagram {
    /// Continuation steps over all branches.
    pub fn steps(&self) -> usize {
        self.branches.iter().map(|b| b.steps).sum()
    }
}

/// Where the continuation commands and figures start: the paper's loop, its smallest orbit
/// (whose average energy `E_av` the adaptation targets), the loop adapted at `k`, and the orbit
/// the adapted loop settles on.
#[derive(Debug, Clone)]
pub struct Start {
    /// The smallest periodic orbit of the loop without adaptation.
    pub orbit: OrbitSolution,
    /// The loop with the adaptation gain `k` towards the orbit's `E_av`.
    pub base: OrbitProblem,
    /// A sweep of the adapted loop from that orbit (0 tilts: set `tilts` and `keep` to run it).
    pub sweep: Sweep,
    /// A Newton guess `(beta0, beta_dot0, t_end)` (rad, rad/s, s) of the orbit the loop
    /// adapted at `k` settles on after 200 tilts.
    pub guess: [f64; 3],
    /// The adaptation's target `E_av` (J): the `k = 0` orbit's mean energy, or the one
    /// [`start_at_peak`] found.
    pub energy_avg: f64,
}

/// The [`Start`] of the loop `pb` (no adaptation) adapted at `k` (1/(J s^2)). Errors: no
/// periodic orbit, or the adapted loop does not settle on a tilting orbit.
pub fn start(pb: &OrbitProblem, k: f64) -> Result<Start, String> {
    let law = pb.control.law;
    let o = orbit::smallest(pb)
        .ok_or_else(|| format!("no periodic orbit for K_P = {}, K_D = {}", law.kp, law.kd))?;
    let sweep = Sweep {
        problem: *pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: o.energy_avg,
        tilts: 0,
        keep: 1,
        period_tol: 1e-5,
    };
    let guess = bifurcation::attracting_orbit_guess(&sweep, k, 200).ok_or_else(|| {
        format!("the adapted loop at k = {k} does not settle on a tilting orbit to start from")
    })?;
    Ok(Start {
        base: pb.with_adaptation(k, o.energy_avg),
        energy_avg: o.energy_avg,
        orbit: o,
        sweep,
        guess,
    })
}

/// The [`Start`] of the loop `pb` adapted at `k` about its orbit with the tilt peak `peak`
/// (rad): `E_av` from [`crate::peak::energy_for_peak`] instead of a `k = 0` orbit, which a
/// landing law that loses energy does not have; `orbit` is then the adapted orbit itself.
pub fn start_at_peak(pb: &OrbitProblem, k: f64, peak: f64) -> Result<Start, String> {
    let search = crate::peak::PeakSearch::new(peak);
    let f = crate::peak::energy_for_peak(&pb.with_adaptation(k, 0.0), &search, &|_| {})
        .map_err(|e| e.to_string())?;
    let (o, e) = (f.orbit, f.energy_avg_adaptation);
    let sweep = Sweep {
        problem: *pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: e,
        tilts: 0,
        keep: 1,
        period_tol: 1e-5,
    };
    Ok(Start {
        base: pb.with_adaptation(k, e),
        guess: [o.beta0, o.beta_dot0, o.t_end],
        energy_avg: e,
        orbit: o,
        sweep,
    })
}

/// The values `p0, p0 + step, ...` towards `to` (the sign of `to - p0`), at most to `to`: the
/// grid of a Lyapunov curve; empty when `step` is 0.
pub fn grid(p0: f64, to: f64, step: f64) -> Vec<f64> {
    if step <= 0.0 || !step.is_finite() {
        return Vec::new();
    }
    let n = ((to - p0).abs() / step).floor() as usize;
    (0..=n)
        .map(|i| p0 + (to - p0).signum() * step * i as f64)
        .collect()
}

/// The continuation of `base` in `param` from `p0`, its first point (the period-1 orbit from
/// `guess` `(beta0, beta_dot0, t_end)`) and the first direction: the parameter decreasing when
/// `down`, increasing otherwise.
fn begin(
    base: &OrbitProblem,
    param: Param,
    p0: f64,
    guess: [f64; 3],
    down: bool,
) -> Result<(Continuation, arclength::Solved, DVector<f64>), OrbitError> {
    let c = Continuation {
        base: *base,
        param,
        scale: p0.abs().max(1.0),
    };
    let pb = c.param.set(&c.base, p0).map_err(OrbitError::Invalid)?;
    let s = orbit::solve(&pb, guess)?;
    let y = c.join(&DVector::from_vec(vec![s.beta0, s.beta_dot0, s.t_end]), p0);
    let mut t = DVector::zeros(4);
    t[3] = 1.0;
    let first = c.correct(&y, &t)?;
    let mut dir = DVector::zeros(4);
    dir[3] = if down { -1.0 } else { 1.0 };
    Ok((c, first, dir))
}

/// The period-1 branch alone from `p0`, increasing the parameter (decreasing with `down`).
pub fn one_branch(
    base: &OrbitProblem,
    param: Param,
    p0: f64,
    guess: [f64; 3],
    set: &Settings,
    down: bool,
) -> Result<Branch, OrbitError> {
    let (c, first, dir) = begin(base, param, p0, guess, down)?;
    Ok(branch::follow(&c, first, dir, set, false, &|_, _| {}))
}

/// The period-1 orbit of any [`PlannableLaw`] followed in one of its named parameters
/// (natural-parameter continuation): solved by Newton shooting ([`orbit::solve_with`], with
/// `pb`'s model, impact law and tolerance) at each of `values` in turn, from `guess` `(beta0,
/// beta_dot0, t_end)` (rad, rad/s, s) and then from the previous orbit. Returns the orbits
/// found, each with its parameter value, and why it stopped early: the law refused the value
/// (the error names the parameter and its range, or `parameters` for a name the law lacks) or
/// the shooting failed. It does not pass folds: the paper's law has the pseudo-arclength
/// continuation ([`diagram`], [`one_branch`]).
pub fn follow_with<L: PlannableLaw>(
    pb: &OrbitProblem,
    law: &L,
    name: &str,
    values: &[f64],
    guess: [f64; 3],
) -> (Vec<(f64, OrbitSolution)>, Option<String>) {
    let mut out: Vec<(f64, OrbitSolution)> = Vec::with_capacity(values.len());
    let mut z = guess;
    for &v in values {
        let step = law
            .with_parameter(name, v)
            .map_err(|e| e.to_string())
            .and_then(|l| orbit::solve_with(pb, &l, z).map_err(|e| format!("{name} = {v}: {e}")));
        match step {
            Ok(o) => {
                z = [o.beta0, o.beta_dot0, o.t_end];
                out.push((v, o));
            }
            Err(e) => return (out, Some(e)),
        }
    }
    (out, None)
}

/// The flip sequence's ratios and accumulation estimates.
pub fn cascade(flips: &[f64]) -> (Vec<f64>, Option<f64>, Option<f64>) {
    let ratios: Vec<f64> = flips
        .windows(3)
        .map(|w| (w[1] - w[0]) / (w[2] - w[1]))
        .collect();
    let n = flips.len();
    let p_inf = ratios
        .last()
        .map(|d| flips[n - 1] + (flips[n - 1] - flips[n - 2]) / (d - 1.0));
    let p_inf_f =
        (n >= 2).then(|| flips[n - 1] + (flips[n - 1] - flips[n - 2]) / (FEIGENBAUM_DELTA - 1.0));
    (ratios, p_inf, p_inf_f)
}

/// Continues the period-1 orbit of `base` with `param` from `p0` (the orbit near `guess`)
/// towards `p_max` (or `p_min` when `p0` is above `p_max`... the direction is the one of
/// increasing `p` unless `p0 >= p_max`), switching at the first flip of each branch until the
/// period reaches `set.max_period`. `tick(tilts, p)` is called after each step.
pub fn diagram(
    base: &OrbitProblem,
    param: Param,
    p0: f64,
    guess: [f64; 3],
    set: &Settings,
    tick: &(dyn Fn(usize, f64) + Sync),
) -> Result<Diagram, OrbitError> {
    let (c, first, dir) = begin(base, param, p0, guess, p0 >= set.p_max)?;
    let mut branches = vec![branch::follow(&c, first, dir, set, false, tick)];
    let mut flips = Vec::new();
    loop {
        let br = branches.last().expect("one branch");
        let Some(flip) = br.events.iter().find(|e| e.kind == EventKind::Flip) else {
            break;
        };
        flips.push(flip.p);
        if br.tilts >= set.max_period {
            break;
        }
        // The next flip comes about 1/4.67 of the last gap later: the new branch starts well
        // before it, and its first steps are a small share of that gap.
        let gap = flips
            .windows(2)
            .last()
            .map_or(set.ds * 10.0, |w| (w[1] - w[0]).abs());
        let s = branch::resolve(&c, flip)?;
        let (first, d) = branch::switch(&c, &s, gap / 50.0)?;
        let local = Settings {
            ds: set.ds.min(gap / 50.0),
            ..*set
        };
        branches.push(branch::follow(&c, first, d, &local, true, tick));
    }
    let (ratios, p_inf, p_inf_feigenbaum) = cascade(&flips);
    Ok(Diagram {
        param,
        branches,
        flips,
        ratios,
        p_inf,
        p_inf_feigenbaum,
    })
}
