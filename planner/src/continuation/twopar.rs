//! Two-parameter continuation of a flip or a fold of the period-`n` orbit: the curve in a
//! parameter plane `(p1, p2)` where the test function of the cycle's monodromy vanishes, by
//! pseudo-arclength on the minimally augmented system `R(z; p1, p2) = 0`, `psi(z; p1, p2) = 0`
//! (`psi = det(I + M)` for a flip, `det(I - M)` for a fold), whose Jacobian is taken by central
//! differences (the multipliers carry ~1e-8 noise, see `orbit`, so `psi` is converged to that).

use super::arclength::{self, tangent_of};
use super::cycle;
use super::{EndReason, EventKind, Param};
use crate::orbit::{OrbitError, OrbitProblem};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// A continued bifurcation curve.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Curve {
    /// Flip or fold.
    pub kind: EventKind,
    /// The first parameter (the branch's).
    pub p1: Param,
    /// The second parameter.
    pub p2: Param,
    /// Points `(p1, p2)` along the curve, in curve order (from the low-`p2` end).
    pub points: Vec<[f64; 2]>,
    /// Continuation steps taken.
    pub steps: usize,
    /// Why each of the two directions ended (decreasing `p2`, increasing `p2`).
    pub ends: [EndReason; 2],
}

/// A step that moves `(p1, p2)` (scaled) by less than this share of its arclength counts as
/// stalled.
const STALL: f64 = 0.1;
/// This many stalled steps in a row end a direction of the curve.
const STALL_STEPS: usize = 5;

/// The plane: base problem, the two parameters and their scales.
struct Plane {
    base: OrbitProblem,
    kind: EventKind,
    p1: Param,
    p2: Param,
    s1: f64,
    s2: f64,
}

impl Plane {
    fn problem(&self, u: &DVector<f64>) -> Result<OrbitProblem, OrbitError> {
        let m = u.len() - 2;
        let q = self
            .p1
            .set(&self.base, u[m] * self.s1)
            .map_err(OrbitError::Invalid)?;
        self.p2
            .set(&q, u[m + 1] * self.s2)
            .map_err(OrbitError::Invalid)
    }

    /// `F(u) = (R, psi)`.
    fn f(&self, u: &DVector<f64>) -> Result<DVector<f64>, OrbitError> {
        let m = u.len() - 2;
        let pb = self.problem(u)?;
        let z = u.rows(0, m).into_owned();
        let e = cycle::evaluate(&pb, &pb.law(), &z)?;
        let mono = cycle::monodromy(&cycle::tilt_maps(&pb, &e.flows));
        let mut out = DVector::zeros(m + 1);
        out.rows_mut(0, m).copy_from(&e.r);
        out[m] = arclength::tests(&mono)[self.kind as usize];
        Ok(out)
    }

    /// `F` and its Jacobian by central differences (`h = 1e-6` in the scaled unknowns).
    fn eval(&self, u: &DVector<f64>) -> Result<(DVector<f64>, DMatrix<f64>), OrbitError> {
        let f0 = self.f(u)?;
        let mut jac = DMatrix::zeros(f0.len(), u.len());
        for j in 0..u.len() {
            let h = 1e-6 * (1.0 + u[j].abs());
            let (mut up, mut um) = (u.clone(), u.clone());
            up[j] += h;
            um[j] -= h;
            jac.set_column(j, &((self.f(&up)? - self.f(&um)?) / (2.0 * h)));
        }
        Ok((f0, jac))
    }

    /// The chord method on `F = 0`, `t . (u - pred) = 0`: the Jacobian `jac` (taken at the
    /// last point, with the tangent) is kept for every iteration, so each costs one evaluation
    /// of `F` instead of `2 dim + 1`.
    fn correct(
        &self,
        pred: &DVector<f64>,
        t: &DVector<f64>,
        jac: &DMatrix<f64>,
    ) -> Result<DVector<f64>, OrbitError> {
        let n = pred.len();
        let mut a = DMatrix::zeros(n, n);
        a.view_mut((0, 0), (n - 1, n)).copy_from(jac);
        a.row_mut(n - 1).copy_from(&t.transpose());
        let lu = a.lu();
        let mut u = pred.clone();
        for _ in 0..12 {
            let f = self.f(&u)?;
            // The residual part converges to ~1e-11, psi to its ~1e-8 noise.
            if f.rows(0, n - 2).norm() < arclength::ACCEPTED && f[n - 2].abs() < 1e-7 {
                return Ok(u);
            }
            let mut rhs = DVector::zeros(n);
            rhs.rows_mut(0, n - 1).copy_from(&(-&f));
            rhs[n - 1] = -t.dot(&(&u - pred));
            let du = lu
                .solve(&rhs)
                .ok_or_else(|| OrbitError::Invalid("singular two-parameter Jacobian".into()))?;
            u += &du;
        }
        Err(OrbitError::Invalid(
            "the two-parameter corrector did not converge".into(),
        ))
    }

    /// [`Plane::correct`] from `pred`, the point kept only where its orbit still tilts back at
    /// once after each landing (the hybrid simulator's mismatch below 1e-6).
    fn correct_tilting(
        &self,
        pred: &DVector<f64>,
        t: &DVector<f64>,
        jac: &DMatrix<f64>,
    ) -> Result<DVector<f64>, OrbitError> {
        let v = self.correct(pred, t, jac)?;
        let pb = self.problem(&v)?;
        let m = v.len() - 2;
        match cycle::resimulated_mismatch(&pb, &v.rows(0, m).into_owned()) {
            Some(x) if x < 1e-6 => Ok(v),
            _ => Err(OrbitError::Invalid(
                "the orbit no longer tilts back at once after each landing".into(),
            )),
        }
    }
}

/// Continues the bifurcation `kind` located on a branch in `p1` (at `p1_value` with the cycle
/// `z`) in the plane `(p1, p2)`, both ways in `p2` within `p2_range` (and `p1` within
/// `p1_range`), with steps from `ds` up to `4 ds` (in `p2` units), at most `max_steps` each
/// way; `tick` after each step. Each point's orbit must still tilt back at once after each
/// landing (checked with the hybrid simulator).
#[allow(clippy::too_many_arguments)]
pub fn curve(
    base: &OrbitProblem,
    kind: EventKind,
    (p1, p1_value, p1_range): (Param, f64, (f64, f64)),
    (p2, p2_range): (Param, (f64, f64)),
    z: &[f64],
    ds: f64,
    max_steps: usize,
    tick: &(dyn Fn() + Sync),
) -> Result<Curve, OrbitError> {
    let pl = Plane {
        base: *base,
        kind,
        p1,
        p2,
        s1: p1_value.abs().max(1.0),
        s2: p2.get(base).abs().max(1.0),
    };
    let m = z.len();
    let mut u0 = DVector::zeros(m + 2);
    u0.rows_mut(0, m).copy_from_slice(z);
    u0[m] = p1_value / pl.s1;
    u0[m + 1] = p2.get(base) / pl.s2;
    let mut steps = 0;
    let mut halves = Vec::new();
    let mut ends = Vec::new();
    for sign in [-1.0, 1.0] {
        let mut dir = DVector::zeros(m + 2);
        dir[m + 1] = sign;
        let mut u = u0.clone();
        let mut pts = Vec::new();
        let mut h = ds / pl.s2;
        let mut stalled = 0;
        let end = loop {
            if steps >= 2 * max_steps {
                break EndReason::Steps;
            }
            let (t, jac) = match pl
                .eval(&u)
                .and_then(|(_, j)| Ok((tangent_of(&j, &dir)?, j)))
            {
                Ok(tj) => tj,
                Err(e) => break EndReason::Failed(e.to_string()),
            };
            let next = pl.correct_tilting(&(&u + &t * h), &t, &jac);
            match next {
                Ok(v) if (&v - &u).norm() <= 2.0 * h => {
                    steps += 1;
                    tick();
                    let (a, b) = (v[m] * pl.s1, v[m + 1] * pl.s2);
                    pts.push([a, b]);
                    // The share of the step that moved the parameters (scaled): where the
                    // curve runs towards orbits with ever longer tilts (K_D below 8), the
                    // orbit takes the whole arclength while (k, p2) creep on, each step
                    // dearer than the last (minutes, issue 19): end there instead.
                    let moved = (v.rows(m, 2) - u.rows(m, 2)).norm() / h;
                    stalled = if moved < STALL { stalled + 1 } else { 0 };
                    if stalled >= STALL_STEPS {
                        break EndReason::Failed(format!(
                            "the curve stalls at ({p1} = {a:.4}, {p2} = {b:.4}): {STALL_STEPS} steps moved the parameters by less than {STALL} of the step (the orbit changes alone; its tilt lasts {:.3} s)",
                            v[2]
                        ));
                    }
                    dir = t;
                    u = v;
                    h = (h * 1.5).min(4.0 * ds / pl.s2);
                    if !(p2_range.0..=p2_range.1).contains(&b)
                        || !(p1_range.0..=p1_range.1).contains(&a)
                    {
                        break EndReason::Range;
                    }
                }
                other => {
                    if h < 1e-3 * ds / pl.s2 {
                        break EndReason::Failed(match other {
                            Err(e) => e.to_string(),
                            Ok(_) => "the corrector jumped".into(),
                        });
                    }
                    h *= 0.5;
                }
            }
        };
        halves.push(pts);
        ends.push(end);
    }
    let mut points: Vec<[f64; 2]> = halves[0].iter().rev().copied().collect();
    points.push([p1_value, p2.get(base)]);
    points.extend(halves[1].iter().copied());
    Ok(Curve {
        kind,
        p1,
        p2,
        points,
        steps,
        ends: [ends[0].clone(), ends[1].clone()],
    })
}

/// The stability region of the period-1 orbit in the plane `(k, p2)`: the flip curve above it
/// and the fold curve below it (the period-1 branch in `k` from `k0` loses its stability
/// through a flip going up and ends in a fold going down).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Region {
    /// The second parameter.
    pub p2: Param,
    /// Its value in the base problem.
    pub p2_base: f64,
    /// The flip on the branch at the base `p2`, and its curve.
    pub flip: Option<Curve>,
    /// The fold on the branch at the base `p2`, and its curve.
    pub fold: Option<Curve>,
    /// Why a curve is missing, if one is.
    pub notes: Vec<String>,
}

/// Locates the flip (continuing the period-1 orbit of `base` up in `k` from `k0` to
/// `k_range.1`) and the fold (down to `k_range.0`), then continues each in `(k, p2)` over
/// `p2_range` with steps of `ds2` (in `p2` units).
pub fn stability_region(
    base: &OrbitProblem,
    k0: f64,
    guess: [f64; 3],
    k_range: (f64, f64),
    (p2, p2_range): (Param, (f64, f64)),
    ds2: f64,
    tick: &(dyn Fn() + Sync),
) -> Result<Region, OrbitError> {
    let mut region = Region {
        p2,
        p2_base: p2.get(base),
        flip: None,
        fold: None,
        notes: Vec::new(),
    };
    for (kind, end) in [(EventKind::Flip, k_range.1), (EventKind::Fold, k_range.0)] {
        let span = (end - k0).abs();
        let set = super::Settings {
            p_min: k_range.0.min(k0),
            p_max: k_range.1.max(k0),
            ds: span / 100.0,
            ds_min: span * 1e-7,
            ds_max: span / 25.0,
            max_steps: 400,
            locate_tol: 1e-7,
            max_period: 1,
            stop_at_first_event: true,
        };
        let set = if end < k0 {
            super::Settings { p_max: k0, ..set }
        } else {
            set
        };
        let d = super::one_branch(base, Param::K, k0, guess, &set, end < k0)?;
        let Some(ev) = d.events.iter().find(|e| e.kind == kind) else {
            region.notes.push(format!(
                "no {kind:?} on the period-1 branch between k = {k0} and {end}"
            ));
            continue;
        };
        let c = curve(
            base,
            kind,
            (Param::K, ev.p, k_range),
            (p2, p2_range),
            &ev.point.z,
            ds2,
            40,
            tick,
        )?;
        match kind {
            EventKind::Flip => region.flip = Some(c),
            _ => region.fold = Some(c),
        }
    }
    Ok(region)
}

/// The stability region as `plan stability` and `figures` compute it: the loop `pb` (no
/// adaptation) adapted at `k0` ([`super::start`]), its flip searched up to `k_max` and its fold
/// down to `k = 0`, both continued over `p2` in `[lo, hi]` (which must contain `pb`'s value) in
/// steps of `(hi - lo) / 60`. `tick` after each step of the curves.
pub fn region(
    pb: &OrbitProblem,
    k0: f64,
    k_max: f64,
    (p2, (lo, hi)): (Param, (f64, f64)),
    tick: &(dyn Fn() + Sync),
) -> Result<Region, String> {
    let here = p2.get(pb);
    if !(lo..=hi).contains(&here) || p2 == Param::K {
        return Err(format!(
            "the range [{lo}, {hi}] of `{p2}` must contain the loop's value {here} (and not be k)"
        ));
    }
    region_from(&super::start(pb, k0)?, k0, k_max, (p2, (lo, hi)), tick)
}

/// [`region`] from a given [`super::Start`] (say [`super::start_at_peak`]'s) of the loop
/// adapted at `k0`.
pub fn region_from(
    st: &super::Start,
    k0: f64,
    k_max: f64,
    (p2, (lo, hi)): (Param, (f64, f64)),
    tick: &(dyn Fn() + Sync),
) -> Result<Region, String> {
    stability_region(
        &st.base,
        k0,
        st.guess,
        (0.0, k_max),
        (p2, (lo, hi)),
        (hi - lo) / 60.0,
        tick,
    )
    .map_err(|e| format!("two-parameter continuation failed: {e}"))
}
