//! One branch: the predictor-corrector loop with step control, the test functions along it,
//! the location of each bifurcation, and the switch at a flip to the doubled-period branch.

use super::arclength::{self, Continuation, Solved};
use super::cycle;
use super::{Branch, EndReason, Event, EventKind, Point, Settings};
use crate::orbit::{eigenvalues2, OrbitError};
use nalgebra::{DVector, Matrix2};

/// Multipliers as `[re, im]` pairs and whether all lie inside the unit circle.
fn multipliers(m: &Matrix2<f64>) -> (Vec<[f64; 2]>, bool) {
    let mu = eigenvalues2(m);
    let stable = mu.iter().all(|v| v[0].hypot(v[1]) < 1.0);
    (mu, stable)
}

/// The public point of a solved `y` (with the simulator's peaks and re-simulation check).
fn point(c: &Continuation, s: &Solved) -> Result<Point, OrbitError> {
    let m = s.y.len() - 1;
    let z = s.y.rows(0, m).into_owned();
    let pb = c.problem(&s.y)?;
    let mismatch = cycle::resimulated_mismatch(&pb, &z)
        .ok_or_else(|| OrbitError::Invalid("a tilt does not land and tilt back at once".into()))?;
    let (mu, stable) = multipliers(&arclength::monodromy_of(s));
    Ok(Point {
        p: c.p(&s.y),
        z: z.iter().copied().collect(),
        peaks: cycle::peaks(&pb, &z),
        multipliers: mu,
        stable,
        residual: s.residual,
        resimulated_mismatch: mismatch,
    })
}

/// Locates the zero of test function `which` between the solved points `a` and `b` (whose
/// values have opposite signs) by the Illinois variant of regula falsi on the chord parameter
/// `theta` (each trial corrected onto the branch on the hyperplane through the chord point
/// orthogonal to the chord), until the parameter bracket is below `tol`.
fn locate(
    c: &Continuation,
    a: &Solved,
    b: &Solved,
    which: usize,
    tol: f64,
) -> Result<Solved, OrbitError> {
    let d = &b.y - &a.y;
    let t = d.normalize();
    let f = |s: &Solved| arclength::tests(&arclength::monodromy_of(s))[which];
    // The bracket along the chord, in parameter units (at a fold the parameter itself is
    // stationary, so its own bracket would close long before the point is found).
    illinois(
        (f(a), c.p(&a.y)),
        (f(b), c.p(&b.y)),
        d.norm() * c.scale,
        tol,
        |th| {
            let s = c.correct(&(&a.y + &d * th), &t)?;
            let (fs, ps) = (f(&s), c.p(&s.y));
            Ok((s, fs, ps))
        },
    )
}

/// The Illinois variant of regula falsi on the chord parameter `theta` in `[0, 1]` between two
/// points whose test-function values `f_a`, `f_b` have opposite signs (parameters `p_a`,
/// `p_b`): `at(theta)` returns the point there, its test value and its parameter. Ends when the
/// chord bracket times `width` (the chord's length in parameter units) is below `tol`, or the
/// parameter bracket below `tol / 1000`; returns the last trial point.
pub(crate) fn illinois<T>(
    (f_a, p_a): (f64, f64),
    (f_b, p_b): (f64, f64),
    width: f64,
    tol: f64,
    mut at: impl FnMut(f64) -> Result<(T, f64, f64), OrbitError>,
) -> Result<T, OrbitError> {
    let (mut t_lo, mut f_lo, mut p_lo) = (0.0, f_a, p_a);
    let (mut t_hi, mut f_hi, mut p_hi) = (1.0, f_b, p_b);
    let mut best = None;
    let mut side = 0i8;
    for _ in 0..60 {
        if (t_hi - t_lo) * width < tol || (p_hi - p_lo).abs() < 1e-3 * tol {
            break;
        }
        let mut th = (t_lo * f_hi - t_hi * f_lo) / (f_hi - f_lo);
        if !(th > t_lo && th < t_hi) {
            th = 0.5 * (t_lo + t_hi);
        }
        let (s, fs, ps) = at(th)?;
        if fs == 0.0 {
            return Ok(s);
        }
        if fs.signum() == f_lo.signum() {
            (t_lo, f_lo, p_lo) = (th, fs, ps);
            if side == -1 {
                f_hi *= 0.5;
            }
            side = -1;
        } else {
            (t_hi, f_hi, p_hi) = (th, fs, ps);
            if side == 1 {
                f_lo *= 0.5;
            }
            side = 1;
        }
        best = Some(s);
    }
    best.ok_or_else(|| OrbitError::Invalid("no test-function zero between the points".into()))
}

/// The event of a located point.
fn event(c: &Continuation, s: &Solved, kind: EventKind) -> Result<Event, OrbitError> {
    let m = arclength::monodromy_of(s);
    let pt = point(c, s)?;
    Ok(Event {
        kind,
        p: pt.p,
        test: arclength::tests(&m)[kind as usize],
        point: pt,
    })
}

/// The kinds whose test function changes sign from `a` to `b` (a Neimark–Sacker point only
/// while the pair of multipliers is complex on both sides).
pub(crate) fn crossings(a: &Matrix2<f64>, b: &Matrix2<f64>, skip_fold: bool) -> Vec<EventKind> {
    let (ta, tb) = (arclength::tests(a), arclength::tests(b));
    let complex = |m: &Matrix2<f64>| m.trace().powi(2) < 4.0 * m.determinant();
    let mut out = Vec::new();
    for (i, kind) in [EventKind::Flip, EventKind::Fold, EventKind::NeimarkSacker]
        .into_iter()
        .enumerate()
    {
        let changed = ta[i] * tb[i] < 0.0;
        let relevant = match kind {
            EventKind::Flip => true,
            EventKind::Fold => !skip_fold,
            EventKind::NeimarkSacker => complex(a) && complex(b),
        };
        if changed && relevant {
            out.push(kind);
        }
    }
    out
}

/// Locates each bifurcation of `kinds` between the neighbouring points `cur` and `next` of a
/// branch (to `tol`, as [`locate`]) and appends it to `events`; the first that fails ends the
/// search with the reason (`locating a <kind>: <why>`).
fn locate_all(
    c: &Continuation,
    (cur, next): (&Solved, &Solved),
    kinds: Vec<EventKind>,
    tol: f64,
    events: &mut Vec<Event>,
) -> Result<(), String> {
    for kind in kinds {
        let ev = locate(c, cur, next, kind as usize, tol)
            .and_then(|s| event(c, &s, kind))
            .map_err(|e| format!("locating a {kind:?}: {e}"))?;
        events.push(ev);
    }
    Ok(())
}

/// Continues from the solved `first` along `dir` until the parameter leaves the settings'
/// range, the step count runs out, or the corrector fails at the smallest step. `born_at_flip`
/// skips fold detection on the first step (a doubled branch starts with a multiplier at +1).
pub(crate) fn follow(
    c: &Continuation,
    first: Solved,
    dir: DVector<f64>,
    set: &Settings,
    born_at_flip: bool,
    tick: &(dyn Fn(usize, f64) + Sync),
) -> Branch {
    let tilts = (first.y.len() - 1) / 3;
    let mut br = Branch {
        tilts,
        points: Vec::new(),
        events: Vec::new(),
        steps: 0,
        newton_iterations: first.iterations,
        end: EndReason::Steps,
    };
    match point(c, &first) {
        Ok(p) => br.points.push(p),
        Err(e) => {
            br.end = EndReason::Failed(e.to_string());
            return br;
        }
    }
    let mut ds = set.ds / c.scale;
    let (ds_min, ds_max) = (set.ds_min / c.scale, set.ds_max / c.scale);
    let mut cur = first;
    let mut t = match c.tangent(&cur.y, &dir) {
        Ok(t) => t,
        Err(e) => {
            br.end = EndReason::Failed(e.to_string());
            return br;
        }
    };
    while br.steps < set.max_steps {
        let trial = c.correct(&(&cur.y + &t * ds), &t);
        let next = match trial {
            // A corrector that lands far from its predictor jumped to another branch.
            Ok(s) if (&s.y - &cur.y).norm() <= 2.0 * ds => s,
            other => {
                if ds <= ds_min {
                    br.end = EndReason::Failed(match other {
                        Err(e) => e.to_string(),
                        Ok(_) => "the corrector jumped".into(),
                    });
                    return br;
                }
                ds = (ds * 0.5).max(ds_min);
                continue;
            }
        };
        br.steps += 1;
        br.newton_iterations += next.iterations;
        let (ma, mb) = (
            arclength::monodromy_of(&cur),
            arclength::monodromy_of(&next),
        );
        let kinds = crossings(&ma, &mb, born_at_flip && br.steps == 1);
        if let Err(e) = locate_all(c, (&cur, &next), kinds, set.locate_tol, &mut br.events) {
            br.end = EndReason::Failed(e);
            return br;
        }
        let pt = match point(c, &next) {
            Ok(p) => p,
            Err(e) => {
                br.end = EndReason::Failed(e.to_string());
                return br;
            }
        };
        let p = pt.p;
        br.points.push(pt);
        if set.stop_at_first_event && !br.events.is_empty() {
            br.end = EndReason::Event;
            return br;
        }
        tick(tilts, p);
        if p > set.p_max || p < set.p_min {
            br.end = EndReason::Range;
            return br;
        }
        let t_new = match c.tangent(&next.y, &t) {
            Ok(v) => v,
            Err(e) => {
                br.end = EndReason::Failed(e.to_string());
                return br;
            }
        };
        ds = if next.iterations <= 3 {
            (ds * 1.5).min(ds_max)
        } else {
            ds
        };
        t = t_new;
        cur = next;
    }
    br
}

/// The flip's eigenvector carried along the cycle: for each tilt `i` the start deviation
/// `(d beta0_i, d beta_dot0_i, d t_i)`, with `v_{i+1} = P_i v_i` and the landing-time shift.
fn flip_direction(s: &Solved) -> Result<DVector<f64>, OrbitError> {
    let m = arclength::monodromy_of(s);
    // The eigenvector of the real eigenvalue nearest -1.
    let mu = eigenvalues2(&m)
        .into_iter()
        .min_by(|a, b| (a[0] + 1.0).abs().total_cmp(&(b[0] + 1.0).abs()))
        .expect("two eigenvalues")[0];
    let a = m - Matrix2::identity() * mu;
    // A null vector of the 2x2 `a`: orthogonal to its larger row.
    let row = if a.row(0).norm() >= a.row(1).norm() {
        a.row(0).into_owned()
    } else {
        a.row(1).into_owned()
    };
    let mut v = nalgebra::Vector2::new(-row[1], row[0]);
    if v.norm() == 0.0 {
        return Err(OrbitError::Invalid("no flip eigenvector".into()));
    }
    v /= v.norm();
    let n = s.maps.len();
    let mut w = DVector::zeros(3 * n);
    for i in 0..n {
        let g = cycle::landing_time_gradient(&s.flows[i]);
        w[3 * i] = v[0];
        w[3 * i + 1] = v[1];
        w[3 * i + 2] = g[0] * v[0] + g[1] * v[1];
        v = s.maps[i] * v;
    }
    Ok(w)
}

/// Switches at the located flip `s` of a period-`n` branch to the period-`2 n` branch: the
/// doubled cycle plus `eps` times the flip direction `(w, -w, 0)`, corrected on the hyperplane
/// orthogonal to that direction (which the doubled period-`n` cycle never meets: its two
/// halves are equal, so its projection on `(w, -w)` is zero). `eps` is halved from 2e-3 until
/// the new branch's first point lies within `max_dp` of the flip in the parameter (the branch
/// bends away as `eps^2`, more sharply the deeper in the cascade). Returns the first point of
/// the new branch and the direction to continue in.
pub(crate) fn switch(
    c: &Continuation,
    s: &Solved,
    max_dp: f64,
) -> Result<(Solved, DVector<f64>), OrbitError> {
    let w = flip_direction(s)?;
    let m = s.y.len() - 1;
    let z2 = cycle::doubled(&s.y.rows(0, m).into_owned());
    let p_star = c.p(&s.y);
    let y_star = c.join(&z2, p_star);
    let mut d = DVector::zeros(2 * m + 1);
    d.rows_mut(0, m).copy_from(&w);
    d.rows_mut(m, m).copy_from(&(-&w));
    let d = d.normalize();
    let mut last = OrbitError::Invalid("no switch tried".into());
    let mut eps = 2e-3;
    while eps > 1e-7 {
        match c.correct(&(&y_star + &d * eps), &d) {
            Ok(first) => {
                // Not the doubled cycle: the halves differ by about eps.
                let gap = (first.y.rows(0, m) - first.y.rows(m, m)).norm();
                let dp = (c.p(&first.y) - p_star).abs();
                if gap > 0.1 * eps && dp <= max_dp {
                    return Ok((first, d));
                }
                last = OrbitError::Invalid(format!(
                    "branch switching at {p_star}: halves {gap:e} apart, {dp} from the flip"
                ));
            }
            Err(e) => last = e,
        }
        eps *= 0.5;
    }
    Err(last)
}

/// Locates a single flip again from a branch's event for switching: the `Solved` form.
pub(crate) fn resolve(c: &Continuation, ev: &Event) -> Result<Solved, OrbitError> {
    let y = c.join(&DVector::from_vec(ev.point.z.clone()), ev.p);
    // Corrected at fixed parameter: the tangent hyperplane `p = const`.
    let mut t = DVector::zeros(y.len());
    t[y.len() - 1] = 1.0;
    c.correct(&y, &t)
}

#[cfg(test)]
mod tests {
    //! The detection path (the test functions, [`crossings`] and the [`illinois`] locator) on
    //! synthetic map Jacobians whose bifurcation points are known in closed form: the orbit's
    //! branches never meet a Neimark–Sacker point, so this is where it is checked.
    use super::*;

    /// Runs the detection as [`follow`] does between two parameter values: which test
    /// functions change sign, then each zero located on the chord `p(theta) = a + theta (b - a)`.
    fn detect(
        family: impl Fn(f64) -> Matrix2<f64>,
        (a, b): (f64, f64),
        tol: f64,
    ) -> Vec<(EventKind, f64)> {
        let (ma, mb) = (family(a), family(b));
        crossings(&ma, &mb, false)
            .into_iter()
            .map(|kind| {
                let f = |p: f64| arclength::tests(&family(p))[kind as usize];
                let p = illinois((f(a), a), (f(b), b), (b - a).abs(), tol, |th| {
                    let p = a + th * (b - a);
                    Ok((p, f(p), p))
                })
                .expect("located");
                (kind, p)
            })
            .collect()
    }

    fn moduli(m: &Matrix2<f64>) -> Vec<f64> {
        eigenvalues2(m).iter().map(|v| v[0].hypot(v[1])).collect()
    }

    #[test]
    fn a_complex_pair_leaving_the_unit_circle_is_a_neimark_sacker_point_located_to_1e_6() {
        // The companion matrix of mu^2 - t mu + q: det = q(p) = 1/2 + p^2 reaches 1 at
        // p* = 1/sqrt(2), where the trace t(p) = 0.6 + 0.1 p is far below 2 sqrt(q): the pair
        // (q^(1/2) e^(+-i w)) crosses the circle there and nowhere else in [0, 2].
        let family = |p: f64| Matrix2::new(0.0, -1.0, 0.5 + p * p, 0.6 + 0.1 * p);
        let p_star = std::f64::consts::FRAC_1_SQRT_2;
        // Wide and lopsided brackets: regula falsi alone would stall on the convex side.
        for (a, b) in [(0.1, 1.9), (0.0, 0.75), (1.2, 0.3)] {
            let found = detect(family, (a, b), 1e-7);
            assert_eq!(found.len(), 1, "[{a}, {b}]: {found:?}");
            let (kind, p) = found[0];
            assert_eq!(kind, EventKind::NeimarkSacker);
            assert!((p - p_star).abs() < 1e-6, "[{a}, {b}]: {p} vs {p_star}");
            // Independently: both multipliers on the unit circle there, as a complex pair.
            let m = family(p);
            assert!(moduli(&m).iter().all(|r| (r - 1.0).abs() < 2e-6), "{m}");
            assert!(eigenvalues2(&m)[0][1].abs() > 0.5);
        }
    }

    #[test]
    fn a_real_pair_with_unit_product_is_not_a_neimark_sacker_point() {
        // diag(2, s): det - 1 = 2 s - 1 changes sign at s = 1/2 with both multipliers real (a
        // neutral saddle): no multiplier crosses the circle, so nothing may be reported.
        let family = |p: f64| Matrix2::new(2.0, 0.0, 0.0, p);
        assert!(detect(family, (0.3, 0.7), 1e-7).is_empty());
    }

    #[test]
    fn flip_and_fold_are_located_where_a_real_multiplier_crosses_minus_and_plus_one() {
        // A triangular family with the multipliers mu_1(p) = p^3 - 1.3 and mu_2(p) = 1.7 p: the
        // flip where mu_1 = -1, p = 0.3^(1/3), and the fold where mu_2 = 1, p = 1/1.7.
        let family = |p: f64| Matrix2::new(p.powi(3) - 1.3, 0.4, 0.0, 1.7 * p);
        let found = detect(family, (0.4, 1.2), 1e-7);
        let (flip, fold) = (0.3f64.cbrt(), 1.0 / 1.7);
        assert_eq!(found.len(), 2, "{found:?}");
        assert_eq!(found[0].0, EventKind::Flip);
        assert!((found[0].1 - flip).abs() < 1e-6, "{found:?} vs {flip}");
        assert_eq!(found[1].0, EventKind::Fold);
        assert!((found[1].1 - fold).abs() < 1e-6, "{found:?} vs {fold}");
    }
}
