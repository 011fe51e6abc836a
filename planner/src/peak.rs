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

/// The first orbit of the adapted loop (`pb` carries `k` and the gains; its `energy_avg` is
/// ignored): from a `k = 0` orbit continued in `k`, else from a scan of `E_av`.
fn seed(pb: &OrbitProblem, target: f64, tick: &dyn Fn(&str)) -> Option<Point> {
    let k = pb.control.law.k;
    let mut base = *pb;
    base.control.law.k = 0.0;
    tick("the k = 0 orbits");
    let mut cands: Vec<Point> = Vec::new();
    for s in orbit::find_all(&base) {
        let e = s.energy_avg;
        let mut g = z_of(&s);
        let n = (k / 100.0).ceil().max(1.0) as usize;
        let mut last = None;
        for i in 1..=n {
            let Ok(sol) = orbit::solve(&pb.with_adaptation(k * i as f64 / n as f64, e), g) else {
                last = None;
                break;
            };
            g = z_of(&sol);
            last = Some(sol);
        }
        if let Some(sol) = last {
            cands.push((z_of(&sol), e, sol));
        }
    }
    if cands.is_empty() {
        // The rest energy upright (the plate flat, the arm's mass at l_c above the joint):
        // a tilting orbit's average lies above it.
        let p = &pb.params;
        let rest = p.m_l * p.g * p.lc();
        for i in 0..40 {
            let e = rest + 0.1 * (i + 1) as f64;
            tick(&format!("scanning E_av = {e:.2} J"));
            let found = orbit::find_all(&pb.with_adaptation(k, e));
            cands.extend(found.into_iter().map(|s| (z_of(&s), e, s)));
            if !cands.is_empty() {
                break;
            }
        }
    }
    // The orbit nearest the wanted peak.
    cands.into_iter().min_by(|a, b| {
        (a.2.max_tilt.abs() - target)
            .abs()
            .total_cmp(&(b.2.max_tilt.abs() - target).abs())
    })
}

/// Finds `E_av` (J) for which the adapted loop of `pb` (gains and `k > 0`; its own `E_av` is
/// not used) has a periodic orbit with peak `search.peak` (rad). `tick` is called with a short
/// description of each stage (for a progress display).
pub fn energy_for_peak(
    pb: &OrbitProblem,
    search: &PeakSearch,
    tick: &dyn Fn(&str),
) -> Result<PeakOrbit, PeakError> {
    let k = pb.control.law.k;
    let target = search.peak;
    let (z0, e0, s0) = seed(pb, target, tick).ok_or(PeakError::NoOrbit { k })?;
    let mut branch = vec![(e0, s0.max_tilt.abs(), s0.stable)];
    let peak_of = |s: &OrbitSolution| s.max_tilt.abs();
    // The direction of E_av that moves the peak towards the target: from a small probe.
    let probe = |e: f64, g: [f64; 3]| orbit::solve(&pb.with_adaptation(k, e), g).ok();
    let mut prev: Point = (z0, e0, s0);
    let dir = {
        let h = search.step * 0.1;
        match probe(e0 + h, z0) {
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
    };
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
