//! The adaptation's energy target for a wanted tilt: the `E_av` (J) for which the adapted loop
//! `K_P = K_P0 + k (E_av - E)` has a periodic tilting orbit with peak `|alpha| = P` (rad).
//!
//! The paper takes `E_av` from the `k = 0` orbit of the same loop. Under a landing law that
//! loses energy ([`tilting_plant::ImpactLaw::Physical`]) that orbit may not exist, and where it
//! does it is not the tilt a user wants: the energy target is what sets the tilt. So the orbit
//! is continued in `E_av` (natural continuation, each orbit by the Newton shooting of
//! [`crate::orbit::solve`] warm-started from the last two) until its peak brackets `P`, then
//! the peak is solved for by the secant method (to 1e-10 rad). When the peak turns back before
//! reaching `P` (a fold of the family) or the family ends, the largest peak met is reported
//! instead, with its `E_av`.
//!
//! The first orbit comes from the `k = 0` orbits when there are any (their `E_av`, continued in
//! `k` as [`crate::jobs::orbits`] does), else from a scan of `E_av` above the energy of the
//! robot at rest upright, each tried with [`crate::orbit::find_all`].

use crate::orbit::{self, OrbitProblem, OrbitSolution};
use serde::{Deserialize, Serialize};

/// An orbit of the adapted loop found for a wanted peak.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PeakOrbit {
    /// The wanted peak `P` (rad).
    pub peak: f64,
    /// The adaptation's energy target `E_av` (J) that gives it.
    pub energy_avg_adaptation: f64,
    /// The orbit: its period, peak, Floquet multipliers and stability.
    pub orbit: OrbitSolution,
    /// The family followed: `(E_av (J), peak (rad), stable)` per orbit met, in the order met.
    pub branch: Vec<(f64, f64, bool)>,
}

/// Why no orbit with the wanted peak was found.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PeakError {
    /// The family of orbits turns back (or ends) below the wanted peak.
    #[error(
        "no orbit of this loop tilts {peak} rad: the largest peak its family reaches is \
         {largest:.6} rad (E_av = {energy_avg:.6} J); ask for at most that, or change the gains"
    )]
    Unreachable {
        /// The wanted peak (rad).
        peak: f64,
        /// The largest peak met (rad).
        largest: f64,
        /// Its `E_av` (J).
        energy_avg: f64,
    },
    /// The family turns back (or ends) above the wanted peak.
    #[error(
        "no orbit of this loop tilts as little as {peak} rad: the smallest peak its family \
         reaches is {smallest:.6} rad (E_av = {energy_avg:.6} J)"
    )]
    TooSmall {
        /// The wanted peak (rad).
        peak: f64,
        /// The smallest peak met (rad).
        smallest: f64,
        /// Its `E_av` (J).
        energy_avg: f64,
    },
    /// No periodic tilting orbit of the adapted loop was found to start from.
    #[error(
        "no periodic tilting orbit of the adapted loop (k = {k}) was found for any E_av tried"
    )]
    NoOrbit {
        /// The adaptation gain.
        k: f64,
    },
}

/// Settings of the search.
#[derive(Debug, Clone, Copy)]
pub struct PeakSearch {
    /// The wanted peak `P` (rad).
    pub peak: f64,
    /// The first continuation step in `E_av` (J).
    pub step: f64,
    /// The smallest step before the family counts as ended (J).
    pub min_step: f64,
    /// The largest number of orbits computed along the family.
    pub max_orbits: usize,
}

impl PeakSearch {
    /// The defaults for peak `P` (rad): steps from 0.05 J down to 1e-5 J, at most 400 orbits.
    pub fn new(peak: f64) -> Self {
        Self {
            peak,
            step: 0.05,
            min_step: 1e-5,
            max_orbits: 400,
        }
    }
}

/// `(z, E_av, orbit)` of a point on the family.
type Point = ([f64; 3], f64, OrbitSolution);

fn z_of(s: &OrbitSolution) -> [f64; 3] {
    [s.beta0, s.beta_dot0, s.t_end]
}

/// The orbits of the adapted loop to start from (`pb` carries `k` and the gains; its
/// `energy_avg` is ignored), lazily, each batch nearest the wanted peak first: the `k = 0`
/// orbits continued in `k` at their own `E_av`, then, `E_av` by `E_av` upwards from the energy
/// of the robot at rest upright, the orbits [`orbit::find_all`] finds.
fn seeds<'a>(
    pb: &'a OrbitProblem,
    target: f64,
    tick: &'a dyn Fn(&str),
) -> impl Iterator<Item = Point> + 'a {
    let k = pb.control.law.k;
    let nearest_first = move |mut v: Vec<Point>| {
        v.sort_by(|a, b| {
            (a.2.max_tilt.abs() - target)
                .abs()
                .total_cmp(&(b.2.max_tilt.abs() - target).abs())
        });
        v
    };
    let from_k0 = std::iter::once_with(move || {
        let mut base = *pb;
        base.control.law.k = 0.0;
        tick("the k = 0 orbits");
        let mut found = Vec::new();
        for s in orbit::find_all(&base) {
            let e = s.energy_avg;
            let mut g = z_of(&s);
            let n = (k / 100.0).ceil().max(1.0) as usize;
            let mut last = None;
            for i in 1..=n {
                let kk = k * i as f64 / n as f64;
                let Ok(sol) = orbit::solve(&pb.with_adaptation(kk, e), g) else {
                    last = None;
                    break;
                };
                g = z_of(&sol);
                last = Some(sol);
            }
            if let Some(sol) = last {
                found.push((z_of(&sol), e, sol));
            }
        }
        nearest_first(found)
    });
    // The rest energy upright (the plate flat, the arm's mass at l_c above the joint): a
    // tilting orbit's average lies above it.
    let p = pb.params;
    let rest = p.m_l * p.g * p.lc();
    let scan = (0..40).map(move |i| {
        let e = rest + 0.1 * (i + 1) as f64;
        tick(&format!("scanning E_av = {e:.2} J"));
        let found = orbit::find_all(&pb.with_adaptation(k, e));
        nearest_first(found.into_iter().map(|s| (z_of(&s), e, s)).collect())
    });
    from_k0.chain(scan).flatten()
}

/// The relative step of the arm's mass in [`arm_mass_sensitivity`]'s central difference: small,
/// because such orbits can be steep and near the end of their family (the physical law's
/// 0.018 rad orbit of the paper's gains and robot: 0.5 % lighter, peak +18.7 %; 0.5 % heavier,
/// no orbit; 0.1 % either way, -4.3 % and +4.0 %).
pub const ARM_MASS_STEP: f64 = 1e-3;

/// How steep the peak of the orbit `sol` of the loop `pb` is in the robot's arm mass:
/// `d ln(peak) / d ln(m_l)`, the controller's model (`pb.control.params`) kept, by a central
/// difference over `m_l (1 +- ARM_MASS_STEP)` (each neighbouring orbit by the Newton shooting
/// of [`orbit::solve`] from `sol`). The robust trim (`--orbit-peak`) and the plain law both hold
/// the peak only as well as the robot matches the model: an orbit with `-28` (a 1 % heavier
/// arm, 28 % lower peaks) is one a 1 % model error moves out of a 10 % band. `None` when a
/// neighbouring orbit is not found.
pub fn arm_mass_sensitivity(pb: &OrbitProblem, sol: &OrbitSolution) -> Option<f64> {
    let peak_at = |scale: f64| -> Option<f64> {
        let mut p = *pb;
        p.params.m_l *= scale;
        orbit::solve(&p, z_of(sol)).ok().map(|s| s.max_tilt.abs())
    };
    let (up, down) = (1.0 + ARM_MASS_STEP, 1.0 - ARM_MASS_STEP);
    let (p_up, p_down) = (peak_at(up)?, peak_at(down)?);
    Some((p_up.ln() - p_down.ln()) / (up.ln() - down.ln()))
}

/// The most seeds [`energy_for_peak`] follows before it gives up.
const MAX_SEEDS: usize = 8;

/// Finds `E_av` (J) for which the adapted loop of `pb` (gains and `k > 0`; its own `E_av` is
/// not used) has a periodic orbit with peak `search.peak` (rad). `tick` is called with a short
/// description of each stage (for a progress display). Follows the family of each seed
/// ([`seeds`]) in turn, at most [`MAX_SEEDS`], until one reaches the peak; otherwise reports
/// the largest peak below it (or the smallest above it) that any family reached.
pub fn energy_for_peak(
    pb: &OrbitProblem,
    search: &PeakSearch,
    tick: &dyn Fn(&str),
) -> Result<PeakOrbit, PeakError> {
    let target = search.peak;
    // The largest peak below the target and the smallest above it, with their E_av (rad, J).
    let mut below: Option<(f64, f64)> = None;
    let mut above: Option<(f64, f64)> = None;
    for seed in seeds(pb, target, tick).take(MAX_SEEDS) {
        match follow(pb, search, seed, tick) {
            Ok(o) => return Ok(o),
            Err(PeakError::Unreachable {
                largest,
                energy_avg,
                ..
            }) => {
                if below.is_none_or(|b| largest > b.0) {
                    below = Some((largest, energy_avg));
                }
            }
            Err(PeakError::TooSmall {
                smallest,
                energy_avg,
                ..
            }) => {
                if above.is_none_or(|a| smallest < a.0) {
                    above = Some((smallest, energy_avg));
                }
            }
            Err(e) => return Err(e),
        }
    }
    match (below, above) {
        (Some((largest, energy_avg)), _) => Err(PeakError::Unreachable {
            peak: target,
            largest,
            energy_avg,
        }),
        (None, Some((smallest, energy_avg))) => Err(PeakError::TooSmall {
            peak: target,
            smallest,
            energy_avg,
        }),
        (None, None) => Err(PeakError::NoOrbit {
            k: pb.control.law.k,
        }),
    }
}

/// Follows the family of orbits through `seed` in `E_av` towards the peak.
fn follow(
    pb: &OrbitProblem,
    search: &PeakSearch,
    (z0, e0, s0): Point,
    tick: &dyn Fn(&str),
) -> Result<PeakOrbit, PeakError> {
    let k = pb.control.law.k;
    let target = search.peak;
    let mut branch = vec![(e0, s0.max_tilt.abs(), s0.stable)];
    let peak_of = |s: &OrbitSolution| s.max_tilt.abs();
    // The direction of E_av that moves the peak towards the target: from a small probe.
    let probe = |e: f64, g: [f64; 3]| orbit::solve(&pb.with_adaptation(k, e), g).ok();
    let mut prev: Point = (z0, e0, s0);
    let dir = direction(&probe, &prev, target, search.step * 0.1);
    let mut last: Option<Point> = None;
    let mut step = search.step;
    let mut best = prev.clone();
    for _ in 0..search.max_orbits {
        let here = peak_of(&prev.2);
        if (here - target).abs() < 1e-10 {
            break;
        }
        // Bracketed between `last` and `prev`: secant in E_av from here on.
        if let Some(l) = &last {
            let there = peak_of(&l.2);
            if (here - target) * (there - target) < 0.0 {
                return secant(pb, target, l.clone(), prev, branch, tick);
            }
        }
        let e = prev.1 + dir * step;
        // Warm start: linear extrapolation along the family from the last two points.
        let guess = match &last {
            Some(l) if (prev.1 - l.1).abs() > 0.0 => {
                let r = (e - prev.1) / (prev.1 - l.1);
                [0, 1, 2].map(|i| prev.0[i] + r * (prev.0[i] - l.0[i]))
            }
            _ => prev.0,
        };
        tick(&format!("E_av = {e:.5} J, peak {here:.5} rad"));
        match probe(e, guess).or_else(|| probe(e, prev.0)) {
            Some(s) if (peak_of(&s) - here).abs() < 0.25 * here.max(1e-3) => {
                branch.push((e, peak_of(&s), s.stable));
                let moved_away = (peak_of(&s) - target).abs() > (here - target).abs();
                if moved_away && last.is_some() {
                    // The peak turned back: a fold. Refine it with smaller steps once.
                    if step > search.min_step {
                        step *= 0.25;
                        continue;
                    }
                    break;
                }
                last = Some(prev);
                prev = (z_of(&s), e, s);
                if (peak_of(&prev.2) - target).abs() < (peak_of(&best.2) - target).abs() {
                    best = prev.clone();
                }
                step = (step * 1.5).min(search.step * 4.0);
            }
            _ => {
                step *= 0.5;
                if step < search.min_step {
                    break;
                }
            }
        }
    }
    best_or_refusal(best, target, branch)
}

/// The direction of `E_av` (+1 or -1) that moves the peak of the orbit `prev` towards
/// `target` (rad), from an orbit `probe`d `h` (J) above it; +1 where the probe fails.
fn direction(
    probe: &dyn Fn(f64, [f64; 3]) -> Option<OrbitSolution>,
    prev: &Point,
    target: f64,
    h: f64,
) -> f64 {
    let peak_of = |s: &OrbitSolution| s.max_tilt.abs();
    match probe(prev.1 + h, prev.0) {
        Some(s) => {
            let up = peak_of(&s) > peak_of(&prev.2);
            let want_up = target > peak_of(&prev.2);
            if up == want_up {
                1.0
            } else {
                -1.0
            }
        }
        None => 1.0,
    }
}

/// The orbit `best` found by [`follow`] if its peak is `target` (rad, within 1e-10), else the
/// refusal naming the largest (or smallest) peak reached and its `E_av`.
fn best_or_refusal(
    best: Point,
    target: f64,
    branch: Vec<(f64, f64, bool)>,
) -> Result<PeakOrbit, PeakError> {
    let peak_of = |s: &OrbitSolution| s.max_tilt.abs();
    let (bp, be) = (peak_of(&best.2), best.1);
    if (bp - target).abs() < 1e-10 {
        return Ok(PeakOrbit {
            peak: target,
            energy_avg_adaptation: be,
            orbit: best.2,
            branch,
        });
    }
    if bp < target {
        Err(PeakError::Unreachable {
            peak: target,
            largest: bp,
            energy_avg: be,
        })
    } else {
        Err(PeakError::TooSmall {
            peak: target,
            smallest: bp,
            energy_avg: be,
        })
    }
}

/// The secant method on `peak(E_av) - P` from a bracket `(a, b)`, kept bracketing (Illinois).
fn secant(
    pb: &OrbitProblem,
    target: f64,
    a: Point,
    b: Point,
    mut branch: Vec<(f64, f64, bool)>,
    tick: &dyn Fn(&str),
) -> Result<PeakOrbit, PeakError> {
    let k = pb.control.law.k;
    let f = |p: &Point| p.2.max_tilt.abs() - target;
    let (mut a, mut b) = (a, b);
    let (mut fa, mut fb) = (f(&a), f(&b));
    let mut side = 0i32;
    for _ in 0..60 {
        let e = (a.1 * fb - b.1 * fa) / (fb - fa);
        let w = (e - a.1) / (b.1 - a.1);
        let guess = [0, 1, 2].map(|i| a.0[i] + w * (b.0[i] - a.0[i]));
        tick(&format!("E_av = {e:.8} J"));
        let Ok(s) = orbit::solve(&pb.with_adaptation(k, e), guess) else {
            break;
        };
        let c: Point = (z_of(&s), e, s);
        let fc = f(&c);
        branch.push((e, c.2.max_tilt.abs(), c.2.stable));
        if fc.abs() < 1e-10 || (b.1 - a.1).abs() < 1e-12 {
            return Ok(PeakOrbit {
                peak: target,
                energy_avg_adaptation: e,
                orbit: c.2,
                branch,
            });
        }
        if fc * fb < 0.0 {
            a = b;
            fa = fb;
            side = 0;
        } else {
            side += 1;
            if side >= 2 {
                fa *= 0.5; // Illinois: the stale end's weight halves
            }
        }
        b = c;
        fb = fc;
    }
    let best = if fa.abs() < fb.abs() { a } else { b };
    Ok(PeakOrbit {
        peak: target,
        energy_avg_adaptation: best.1,
        orbit: best.2,
        branch,
    })
}

/// What a cell of the reach map ([`reach_map`]) found for the wanted peak.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "reach", rename_all = "snake_case")]
pub enum Reach {
    /// An orbit with the peak: its `E_av` (J), whether it is stable, its largest Floquet
    /// multiplier's modulus and how steep its peak is in the arm's mass.
    Reached {
        /// `E_av` (J).
        energy_avg: f64,
        /// All multipliers inside the unit circle.
        stable: bool,
        /// The largest multiplier's modulus.
        rho: f64,
        /// `d ln(peak) / d ln(m_l)` ([`arm_mass_sensitivity`]): how far a model error of the
        /// arm's mass moves the peak; rank stable cells by it (smaller magnitude holds a band
        /// better). `None` when a neighbouring orbit is not found (the cell is at a fold).
        #[serde(skip_serializing_if = "Option::is_none")]
        peak_per_arm_mass: Option<f64>,
    },
    /// The family turns back below the peak: the largest peak it reaches (rad).
    Below {
        /// The largest peak (rad).
        largest: f64,
    },
    /// The family turns back above the peak: the smallest peak it reaches (rad).
    Above {
        /// The smallest peak (rad).
        smallest: f64,
    },
    /// No periodic tilting orbit found.
    None,
}

/// One cell of the reach map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReachCell {
    /// `K_D` (1/s).
    pub kd: f64,
    /// `k` (1/(J s^2)).
    pub k: f64,
    /// What the search found.
    #[serde(flatten)]
    pub reach: Reach,
}

/// Which gains reach the peak `peak` (rad): [`energy_for_peak`] on every `(K_D, k)` of the
/// grid, in parallel (`tick` after each cell), for the loop `pb` (its `K_P0`; its `K_D`, `k`
/// and `E_av` replaced). `K_P0` is not a dimension: the law depends on `K_P0 + k E_av` only,
/// so another `K_P0` moves `E_av` by `-dK_P0 / k` and leaves every orbit as it is.
pub fn reach_map(
    pb: &OrbitProblem,
    kds: &[f64],
    ks: &[f64],
    peak: f64,
    tick: &(dyn Fn() + Sync),
) -> Vec<ReachCell> {
    use rayon::prelude::*;
    let cells: Vec<(f64, f64)> = kds
        .iter()
        .flat_map(|&kd| ks.iter().map(move |&k| (kd, k)))
        .collect();
    cells
        .par_iter()
        .map(|&(kd, k)| {
            let mut p = pb.with_adaptation(k, 0.0);
            p.control.law.kd = kd;
            let reach = match energy_for_peak(&p, &PeakSearch::new(peak), &|_| {}) {
                Ok(f) => Reach::Reached {
                    peak_per_arm_mass: arm_mass_sensitivity(
                        &p.with_adaptation(k, f.energy_avg_adaptation),
                        &f.orbit,
                    ),
                    energy_avg: f.energy_avg_adaptation,
                    stable: f.orbit.stable,
                    rho: f
                        .orbit
                        .multipliers
                        .iter()
                        .map(|m| m[0].hypot(m[1]))
                        .fold(0.0, f64::max),
                },
                Err(PeakError::Unreachable { largest, .. }) => Reach::Below { largest },
                Err(PeakError::TooSmall { smallest, .. }) => Reach::Above { smallest },
                Err(PeakError::NoOrbit { .. }) => Reach::None,
            };
            tick();
            ReachCell { kd, k, reach }
        })
        .collect()
}

/// What the hybrid simulator's adapted loop settles at, with the robot's own landing law and
/// control period ([`settle_energy_for_peak`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SettledPeak {
    /// The control period simulated (s): the torque held between samples (zero-order hold);
    /// 0: the law evaluated continuously.
    pub control_period: f64,
    /// The landings' restitution simulated (1): `> 0` rebounds, `< 0` pass-throughs.
    pub restitution: f64,
    /// `E_av` (J) at which the settled peaks' mean is the wanted peak.
    pub energy_avg: f64,
    /// Mean |peak| of the settled tilts (rad).
    pub peak_mean: f64,
    /// Smallest |peak| of the settled tilts (rad).
    pub peak_min: f64,
    /// Largest |peak| of the settled tilts (rad).
    pub peak_max: f64,
    /// Mean time from a tilt to the next of the same side (s).
    pub period: f64,
    /// Tilts averaged, after [`SETTLE_TILTS`] left out.
    pub tilts: usize,
    /// Simulations run by the search.
    pub runs: usize,
}

/// Tilts a simulated run leaves out before averaging its peaks (the start's transient: the
/// largest multiplier of a stable orbit of the maps here is below 0.9, 0.9^30 = 0.04).
pub const SETTLE_TILTS: usize = 30;
/// Tilts a simulated run averages.
pub const AVERAGE_TILTS: usize = 40;
/// The search stops when the mean settled peak is this close to the wanted one (relative): the
/// sampled loop's peaks scatter by a few % about their mean (a quasi-periodic motion), and
/// the mean of [`AVERAGE_TILTS`] of them moves by about 0.1-0.3 % from one `E_av` to the next
/// for that reason alone.
pub const SETTLE_TOL: f64 = 5e-3;
/// The most simulations of the search.
const MAX_RUNS: usize = 20;
/// After [`MAX_RUNS`] with runs on both sides of the peak, the last run stands if its mean is
/// this close (relative): on the steepest orbits (MuJoCo robot b's 0.018 rad, -39 per % of arm
/// mass) the scatter of the mean of [`AVERAGE_TILTS`] tilts outgrows [`SETTLE_TOL`].
pub const NOISE_TOL: f64 = 2e-2;

/// Records the tilts' peaks `(t, alpha)`.
#[derive(Default)]
struct TiltPeaks(Vec<(f64, f64)>);
impl tilting_plant::Observer for TiltPeaks {
    fn tilt_peak(&mut self, p: &tilting_plant::TiltPeak) {
        self.0.push((p.t, p.alpha));
    }
}

/// The loop `pb` (its gains and `k`; `E_av = energy_avg`, J) run by the hybrid simulator from
/// the left-tilt start `x0`, its torque sampled every `dt` s
/// ([`tilting_sim::closed_loop::run_sampled`], the loop a lockstep plant node runs) or, with
/// `dt = 0`, evaluated continuously, long enough for `average` tilts after the first
/// [`SETTLE_TILTS`] with room for a loop slower than the orbit's period `orbit_period` (s):
/// `(mean, min, max |peak| (rad), period (s))` of those `average` tilts; all 0 (period NaN)
/// when the loop stops tilting before.
fn settled(
    pb: &OrbitProblem,
    x0: &tilting_plant::State,
    energy_avg: f64,
    dt: f64,
    orbit_period: f64,
    average: usize,
) -> Result<(f64, f64, f64, f64), String> {
    use tilting_plant::{Mode, Plant, SimConfig};
    let t_run = 1.5 * orbit_period * (SETTLE_TILTS + average) as f64 / 2.0 + 2.0;
    let law = pb.with_adaptation(pb.control.law.k, energy_avg).law();
    let cfg = SimConfig {
        params: pb.params,
        impact: pb.impact,
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, *x0).map_err(|e| e.to_string())?;
    let mut obs = TiltPeaks::default();
    if dt > 0.0 {
        tilting_sim::closed_loop::run_sampled(&mut plant, &law, dt, t_run, &mut obs, &mut |_| {}).0
    } else {
        plant.advance_continuous(&law, t_run, &mut obs)
    }
    .map_err(|e| format!("{e} (E_av = {energy_avg} J)"))?;
    let want = SETTLE_TILTS + average;
    if obs.0.len() < want {
        // The tilting died out: no settled peak, below any wanted one (near the end of an
        // orbit family a step of the search can land there; the search then steps back up).
        return Ok((0.0, 0.0, 0.0, f64::NAN));
    }
    let last = &obs.0[SETTLE_TILTS..want];
    let peaks: Vec<f64> = last.iter().map(|p| p.1.abs()).collect();
    let mean = peaks.iter().sum::<f64>() / peaks.len() as f64;
    let (lo, hi) = peaks.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), &p| {
        (lo.min(p), hi.max(p))
    });
    let period = (last[last.len() - 1].0 - last[0].0) / (last.len() - 1) as f64 * 2.0;
    Ok((mean, lo, hi, period))
}

/// The mean |peak| (rad) of `tilts` tilts of the loop `pb` at `E_av = energy_avg` (J) after
/// the first [`SETTLE_TILTS`], run as [`settle_energy_for_peak`] runs it (from `x0`, sampled
/// every `dt` s or continuous at 0; `orbit_period` (s) sizes the run); 0 when it stops tilting.
pub fn settled_mean(
    pb: &OrbitProblem,
    x0: &tilting_plant::State,
    energy_avg: f64,
    dt: f64,
    orbit_period: f64,
    tilts: usize,
) -> Result<f64, String> {
    Ok(settled(pb, x0, energy_avg, dt, orbit_period, tilts)?.0)
}

/// Refines the `E_av` (J) of a planned orbit so that the loop the robot runs, simulated by the
/// hybrid simulator with the robot's own landings (`pb.params.restitution`, which the shooting
/// does not plan: it plans plastic landings) and its control period `dt` (s, 0: continuous),
/// settles with a mean peak of `peak` (rad): the secant method on `E_av` from `energy_avg`,
/// regula falsi once bracketed (the plan's), each step one run from the orbit's start `x0`
/// ([`SETTLE_TILTS`] tilts left out, [`AVERAGE_TILTS`] averaged), to [`SETTLE_TOL`] (or
/// [`NOISE_TOL`] after [`MAX_RUNS`] inside a bracket). `tick` after each run. The sampled
/// loop's peaks scatter about their mean (a quasi-periodic motion of the zero-order hold):
/// `peak_min` and `peak_max` say how far.
pub fn settle_energy_for_peak(
    pb: &OrbitProblem,
    x0: &tilting_plant::State,
    energy_avg: f64,
    peak: f64,
    dt: f64,
    orbit_period: f64,
    tick: &dyn Fn(&str),
) -> Result<SettledPeak, String> {
    let run = |e: f64, runs: &mut usize| {
        *runs += 1;
        tick(&format!(
            "simulating the loop at E_av = {e:.6} J (run {runs})"
        ));
        settled(pb, x0, e, dt, orbit_period, AVERAGE_TILTS)
    };
    let mut runs = 0;
    // (E_av, its run) of the last two runs, and the nearest runs below and above the peak:
    // the secant while no run is on each side, then regula falsi (Illinois) inside that
    // bracket, which the sampled loop's scatter about its mean cannot throw the search out of.
    let r = run(energy_avg, &mut runs)?;
    let (mut prev, mut last) = ((energy_avg, r), (energy_avg, r));
    let mut below: Option<(f64, f64)> = None;
    let mut above = below;
    let mut side = 0i8;
    loop {
        let (e1, r1) = last;
        let f1 = r1.0 - peak;
        if f1.abs() <= SETTLE_TOL * peak {
            break;
        }
        if f1 < 0.0 {
            below = Some((e1, f1));
        } else {
            above = Some((e1, f1));
        }
        // Bracketed and still outside the tolerance after MAX_RUNS: the bracket has shrunk to
        // where the scatter of the sampled loop's mean decides each step; the last step,
        // inside the bracket, stands if within NOISE_TOL.
        if runs >= MAX_RUNS && below.is_some() && above.is_some() && f1.abs() <= NOISE_TOL * peak {
            break;
        }
        if runs >= MAX_RUNS {
            return Err(format!(
                "the simulated loop's mean peak did not reach {peak} rad within {MAX_RUNS} \
                 runs (last: {:.6} rad at E_av = {e1:.6} J)",
                r1.0
            ));
        }
        let next = match (below, above) {
            (Some((ea, fa)), Some((eb, fb))) => {
                // Illinois: halve the weight of an end that stays.
                let (fa, fb) = match side {
                    -1 => (fa, fb * 0.5),
                    1 => (fa * 0.5, fb),
                    _ => (fa, fb),
                };
                side = if f1 < 0.0 { -1 } else { 1 };
                ea - fa * (eb - ea) / (fb - fa)
            }
            _ => {
                let (e0, r0) = prev;
                let slope = (r1.0 - r0.0) / (e1 - e0);
                // The peak grows with E_av near a stable orbit; a first step of 0.01 J moves
                // it by a few %.
                let step = if e1 != e0 && slope.is_finite() && slope > 0.0 {
                    (-f1 / slope).clamp(-0.2, 0.2)
                } else {
                    -0.01 * f1.signum()
                };
                e1 + step
            }
        };
        prev = last;
        last = (next, run(next, &mut runs)?);
    }
    let (e1, r1) = last;
    Ok(SettledPeak {
        control_period: dt,
        restitution: pb.params.restitution,
        energy_avg: e1,
        peak_mean: r1.0,
        peak_min: r1.1,
        peak_max: r1.2,
        period: r1.3,
        tilts: AVERAGE_TILTS,
        runs,
    })
}
