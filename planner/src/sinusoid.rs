//! Approach 1 (paper Sec. III-A): the arm tracks `beta_d(t) = A sin(w t) + pi/2` exactly (ideal
//! control, no impact), and `w` is chosen so that the tilt that this motion causes lands at a
//! prescribed time.
//!
//! Times are absolute from `t = 0`, where the plate is flat and `beta = pi/2`. The plate tilts at
//! `t_t`, the first time the zero moment point leaves the support, and lands at `t_l`, when
//! `alpha` returns to 0. The boundary condition is `t_l = T/2 + s t_t` with `T = 2 pi / w`
//! (the paper's Fig. 4 curves use `s = -1, 0, 1`, Fig. 5 `s = -1/2, -1/4, -1/6, -1/8`).

use nalgebra::Vector2;
use serde::Serialize;
use std::f64::consts::{FRAC_PI_2, PI};
use tilting_plant::dynamics::{bias, mass_matrix, support_margins, torque_for_beta_ddot};
use tilting_plant::ode::{Dop853, Tolerance};
use tilting_plant::{Mode, Params, State};

/// The ideal arm motion for amplitude `a` (rad) and frequency `w` (rad/s) at time `t`:
/// `(beta, beta_dot, beta_ddot)`.
#[inline]
pub fn arm(a: f64, w: f64, t: f64) -> (f64, f64, f64) {
    let (s, c) = (w * t).sin_cos();
    (a * s + FRAC_PI_2, a * w * c, -a * w * w * s)
}

/// The first tilt caused by the ideal arm motion.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tilt {
    /// Which edge the plate tilts over.
    pub side: Mode,
    /// Tilt start `t_t` (s).
    pub tilt_time: f64,
    /// Landing `t_l` (s), if the plate lands within one period.
    pub landing_time: Option<f64>,
    /// Largest `|alpha|` of the tilt (rad).
    pub max_tilt: f64,
}

/// Why there is no tilt or no landing.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SinusoidError {
    /// The ZMP stays in the support for a whole period.
    #[error("no tilt: with A = {a} rad and w = {w} rad/s the ZMP stays inside the support")]
    NoTilt {
        /// Amplitude.
        a: f64,
        /// Frequency.
        w: f64,
    },
    /// No frequency in the searched range meets the landing condition.
    #[error("no solution: no w in [{w_min}, {w_max}] rad/s gives t_l = T/2 + {s} t_t for A = {a} rad{hint}")]
    NoSolution {
        /// Amplitude.
        a: f64,
        /// The landing-time factor.
        s: f64,
        /// Searched range.
        w_min: f64,
        /// Searched range.
        w_max: f64,
        /// What was seen, in words.
        hint: String,
    },
    /// Invalid input.
    #[error("invalid `{field}` = {value}: must be {allowed}")]
    Invalid {
        /// Field name.
        field: &'static str,
        /// The value.
        value: f64,
        /// Allowed range.
        allowed: &'static str,
    },
}

/// The first time in `[0, T]` the ZMP leaves the support under the ideal arm motion, with the
/// side, located to 1e-13 s; `None` when it stays inside.
pub fn tilt_start(p: &Params, a: f64, w: f64) -> Option<(f64, Mode)> {
    let period = 2.0 * PI / w;
    let margins = |t: f64| {
        let (b, bd, bdd) = arm(a, w, t);
        let x = State::new(0.0, b, 0.0, bd);
        let tau = torque_for_beta_ddot(p, Mode::Flat, &x, bdd);
        support_margins(p, &x, tau)
    };
    let n = 400;
    let mut t0 = 0.0;
    let (mut l0, mut r0) = margins(0.0);
    for i in 1..=n {
        let t1 = period * i as f64 / n as f64;
        // The margins add up to 2 f F_y, so an edge is always crossed before the ground force
        // could vanish: the flat phase ends with a tilt, never with a contact loss.
        let (l1, r1) = margins(t1);
        if l1 <= 0.0 || r1 <= 0.0 {
            // Bisect the earliest of the two crossings.
            let left_first = l1 <= 0.0 && (r1 > 0.0 || l1 / (l1 - l0) >= r1 / (r1 - r0));
            let g = |t: f64| {
                let (l, r) = margins(t);
                if left_first {
                    l
                } else {
                    r
                }
            };
            let side = if left_first { Mode::Left } else { Mode::Right };
            return Some((bisect(g, t0, t1), side));
        }
        t0 = t1;
        l0 = l1;
        r0 = r1;
    }
    None
}

/// The right-hand side of the tilt `(alpha, alpha_dot)` over `side` with the arm on the ideal
/// motion: the unactuated row `M11 alpha_ddot = -(M12 beta_ddot + h1)` with `beta` prescribed.
fn tilt_rhs(
    p: &Params,
    side: Mode,
    a: f64,
    w: f64,
) -> impl FnMut(f64, &Vector2<f64>) -> Vector2<f64> + '_ {
    move |t: f64, y: &Vector2<f64>| {
        let (b, bd, bdd) = arm(a, w, t);
        let x = State::new(y[0], b, y[1], bd);
        let (m11, m12, _) = mass_matrix(p, side, b);
        let (h1, _) = bias(p, side, &x);
        Vector2::new(y[1], -(m12 * bdd + h1) / m11)
    }
}

/// The tilt of the ideal motion: start, landing (within one period after the start) and
/// largest angle. The tilt obeys the unactuated row of the tilted equations with `beta`
/// prescribed: `M11 alpha_ddot = -(M12 beta_ddot + h1)`.
pub fn ideal_tilt(p: &Params, a: f64, w: f64, tol: Tolerance) -> Result<Tilt, SinusoidError> {
    let (t_t, side) = tilt_start(p, a, w).ok_or(SinusoidError::NoTilt { a, w })?;
    let sgn = if side == Mode::Left { 1.0 } else { -1.0 };
    let mut f = tilt_rhs(p, side, a, w);
    let mut st = Dop853::new(tol);
    let t_end = t_t + 2.0 * PI / w;
    let (mut t, mut y) = (t_t, Vector2::zeros());
    let mut f0 = f(t, &y);
    let mut max_tilt: f64 = 0.0;
    while t < t_end {
        let s = st
            .step(&mut f, t, &y, &f0, t_end)
            .map_err(|_| SinusoidError::NoTilt { a, w })?;
        let (g0, g1) = (sgn * y[0], sgn * s.y1[0]);
        let (v0, v1) = (sgn * y[1], sgn * s.y1[1]);
        if (v0 > 0.0 && v1 <= 0.0) || (g0 > 0.0 && g1 <= 0.0) {
            let d = st.dense(&mut f, &s);
            if v0 > 0.0 && v1 <= 0.0 {
                let tp = bisect(|tt| sgn * d.eval(tt)[1], s.t0, s.t1);
                max_tilt = max_tilt.max(sgn * d.eval(tp)[0]);
            }
            if g0 > 0.0 && g1 <= 0.0 {
                let tl = bisect(|tt| sgn * d.eval(tt)[0], s.t0, s.t1);
                return Ok(Tilt {
                    side,
                    tilt_time: t_t,
                    landing_time: Some(tl),
                    max_tilt,
                });
            }
        }
        if sgn * s.y1[0] >= FRAC_PI_2 {
            break;
        }
        t = s.t1;
        y = s.y1;
        f0 = *s.f1();
    }
    Ok(Tilt {
        side,
        tilt_time: t_t,
        landing_time: None,
        max_tilt,
    })
}

/// The end `hi` of the bracket `[lo, hi]` (s) of a sign change of `g` from positive (at `lo`)
/// to non-positive (at `hi`), halved until it is at most 1e-13 s wide.
fn bisect(g: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    while hi - lo > 1e-13 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The solution of approach 1 for one amplitude and landing condition.
#[derive(Debug, Clone, Serialize)]
pub struct SinusoidSolution {
    /// Amplitude `A` (rad).
    pub amplitude: f64,
    /// The landing-time factor `s` in `t_l = T/2 + s t_t`.
    pub landing_offset: f64,
    /// Frequency `w` (rad/s).
    pub omega: f64,
    /// Period `T = 2 pi / w` (s).
    pub period: f64,
    /// Tilt start `t_t` (s).
    pub tilt_time: f64,
    /// Landing `t_l` (s).
    pub landing_time: f64,
    /// Largest tilt angle (rad), positive.
    pub max_tilt: f64,
    /// Side of the first tilt.
    pub side: Mode,
    /// Other frequencies in the range that also meet the condition (rad/s).
    pub other_roots: Vec<f64>,
}

/// Search settings for [`solve`].
#[derive(Debug, Clone, Copy)]
pub struct Search {
    /// Lowest frequency searched (rad/s).
    pub omega_min: f64,
    /// Highest frequency searched (rad/s).
    pub omega_max: f64,
    /// Scan points (log-spaced) before the bisection.
    pub points: usize,
    /// Integrator tolerance.
    pub tol: Tolerance,
}

impl Default for Search {
    fn default() -> Self {
        Self {
            omega_min: 0.5,
            omega_max: 30.0,
            points: 120,
            tol: Tolerance {
                rtol: 1e-11,
                atol: 1e-13,
            },
        }
    }
}

/// `t_l - (T/2 + s t_t)` at frequency `w`, or `None` when the motion does not tilt and land.
pub fn landing_residual(p: &Params, a: f64, s: f64, w: f64, tol: Tolerance) -> Option<f64> {
    let tilt = ideal_tilt(p, a, w, tol).ok()?;
    let tl = tilt.landing_time?;
    Some(tl - (PI / w + s * tilt.tilt_time))
}

/// Solves for `w` so that the ideal-tracking tilt lands at `t_l = T/2 + s t_t`.
pub fn solve(
    p: &Params,
    a: f64,
    s: f64,
    search: &Search,
) -> Result<SinusoidSolution, SinusoidError> {
    if !(a.is_finite() && a > 0.0 && a < FRAC_PI_2) {
        return Err(SinusoidError::Invalid {
            field: "amplitude",
            value: a,
            allowed: "in (0, pi/2) rad",
        });
    }
    if !(s.is_finite() && s > -1.0 && s < 1.0) {
        return Err(SinusoidError::Invalid {
            field: "landing_offset",
            value: s,
            allowed: "in (-1, 1): the landing must fall between T/2 - t_t and T/2 + t_t",
        });
    }
    let (w0, w1) = (search.omega_min, search.omega_max);
    if !(w0 > 0.0 && w1 > w0 && w1.is_finite()) {
        return Err(SinusoidError::Invalid {
            field: "omega_min",
            value: w0,
            allowed: "0 < omega_min < omega_max (finite)",
        });
    }
    let n = search.points.max(8);
    let ws: Vec<f64> = (0..n)
        .map(|i| w0 * (w1 / w0).powf(i as f64 / (n - 1) as f64))
        .collect();
    let rs: Vec<Option<f64>> = ws
        .iter()
        .map(|&w| landing_residual(p, a, s, w, search.tol))
        .collect();
    let mut roots = Vec::new();
    for i in 1..n {
        if let (Some(r0), Some(r1)) = (rs[i - 1], rs[i]) {
            if (r0 > 0.0) != (r1 > 0.0) {
                let g = |w: f64| landing_residual(p, a, s, w, search.tol);
                if let Some(w) = bisect_opt(g, ws[i - 1], r0, ws[i], search.tol) {
                    roots.push(w);
                }
            }
        }
    }
    let Some(&omega) = roots.first() else {
        let tilting = rs.iter().filter(|r| r.is_some()).count();
        let hint = if tilting == 0 {
            format!(" (no w in the range makes the plate tilt and land; {n} values tried)")
        } else {
            format!(" (the plate tilts and lands for {tilting} of {n} values tried, but the landing time never crosses the target)")
        };
        return Err(SinusoidError::NoSolution {
            a,
            s,
            w_min: w0,
            w_max: w1,
            hint,
        });
    };
    let tilt = ideal_tilt(p, a, omega, search.tol)?;
    Ok(SinusoidSolution {
        amplitude: a,
        landing_offset: s,
        omega,
        period: 2.0 * PI / omega,
        tilt_time: tilt.tilt_time,
        landing_time: tilt.landing_time.unwrap_or(f64::NAN),
        max_tilt: tilt.max_tilt,
        side: tilt.side,
        other_roots: roots[1..].to_vec(),
    })
}

/// Bisection on a residual that may be undefined (`None`) inside the bracket; secant-guided.
fn bisect_opt(
    g: impl Fn(f64) -> Option<f64>,
    mut lo: f64,
    r_lo: f64,
    mut hi: f64,
    _tol: Tolerance,
) -> Option<f64> {
    let pos_lo = r_lo > 0.0;
    for _ in 0..200 {
        if hi - lo <= 1e-12 * hi {
            break;
        }
        let mid = 0.5 * (lo + hi);
        let r = g(mid)?;
        if (r > 0.0) == pos_lo {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(0.5 * (lo + hi))
}

/// The desired tilt angle of the ideal periodic motion at time `t` (rad): the first tilt on
/// `[t_t, t_l]`, flat until `t_t + T/2`, then its mirror image, and so on with period `T`.
/// `samples` is the first tilt sampled as `(t, alpha)`.
pub fn desired_alpha(samples: &[(f64, f64)], period: f64, t: f64) -> f64 {
    let Some(&(t_t, _)) = samples.first() else {
        return 0.0;
    };
    let t_l = samples.last().map(|s| s.0).unwrap_or(t_t);
    let half = period / 2.0;
    let k = ((t - t_t) / half).floor();
    let tau = t - k * half;
    let sign = if (k as i64).rem_euclid(2) == 0 {
        1.0
    } else {
        -1.0
    };
    if t < t_t || tau > t_l {
        return 0.0;
    }
    let i = samples
        .partition_point(|s| s.0 <= tau)
        .clamp(1, samples.len() - 1);
    let (ta, aa) = samples[i - 1];
    let (tb, ab) = samples[i];
    let u = if tb > ta { (tau - ta) / (tb - ta) } else { 0.0 };
    sign * (aa + u * (ab - aa))
}

/// Samples the first ideal tilt at `n` points between `t_t` and `t_l`.
pub fn sample_ideal_tilt(p: &Params, a: f64, w: f64, n: usize) -> Vec<(f64, f64)> {
    let tol = Search::default().tol;
    let Ok(tilt) = ideal_tilt(p, a, w, tol) else {
        return Vec::new();
    };
    let Some(t_l) = tilt.landing_time else {
        return Vec::new();
    };
    let side = tilt.side;
    let mut f = tilt_rhs(p, side, a, w);
    let mut out = Vec::with_capacity(n);
    let mut st = Dop853::new(tol);
    let (mut t, mut y) = (tilt.tilt_time, Vector2::zeros());
    out.push((t, 0.0));
    for i in 1..n {
        let target = tilt.tilt_time + (t_l - tilt.tilt_time) * i as f64 / (n - 1) as f64;
        let mut f0 = f(t, &y);
        while t < target {
            let Ok(s) = st.step(&mut f, t, &y, &f0, target) else {
                return out;
            };
            t = s.t1;
            y = s.y1;
            f0 = *s.f1();
        }
        out.push((t, y[0]));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// The (A, w) partition of Fig. 4.

/// Tilt start `t_t` and landing `t_l` (s) of the ideal motion `beta = A sin(w t) + pi/2` (`a` in
/// rad, `w` in rad/s), if it tilts and lands.
pub fn tilt_and_landing(p: &Params, a: f64, w: f64) -> Option<(f64, f64)> {
    let tol = Search::default().tol;
    let t = ideal_tilt(p, a, w, tol).ok()?;
    Some((t.tilt_time, t.landing_time?))
}

/// The lowest frequency (rad/s) in `[lo, hi]` at which the ideal motion of amplitude `a`
/// makes the plate tilt; `Some(lo)` if it tilts at `lo` already, `None` if never.
pub fn no_tilt_boundary(p: &Params, a: f64, lo: f64, hi: f64) -> Option<f64> {
    let no_tilt = |w: f64| tilt_start(p, a, w).is_none();
    if !no_tilt(lo) {
        return Some(lo);
    }
    let n = 200;
    let mut w0 = lo;
    for i in 1..=n {
        let w1 = lo * (hi / lo).powf(i as f64 / n as f64);
        if !no_tilt(w1) {
            let (mut a0, mut a1) = (w0, w1);
            while a1 - a0 > 1e-12 * a1 {
                let m = 0.5 * (a0 + a1);
                if no_tilt(m) {
                    a0 = m;
                } else {
                    a1 = m;
                }
            }
            return Some(a1);
        }
        w0 = w1;
    }
    None
}

/// The partition of Fig. 4, for one amplitude `a` (rad): the first `w` (rad/s) above the
/// no-tilt boundary solving `t_l = T/2 + s t_t` for each of `ss`, over `scan` trial points. The scan is geometric in the distance to the boundary, where the
/// solutions for `s` near -1 crowd.
pub fn landing_curves(p: &Params, a: f64, ss: &[f64], scan: usize) -> Vec<Option<f64>> {
    let (lo, hi) = (0.05, 60.0);
    let Some(w_nt) = no_tilt_boundary(p, a, lo, hi) else {
        return vec![None; ss.len()];
    };
    let ws: Vec<f64> = if w_nt > lo {
        // Distances from 1e-9 to 1.5 times the boundary frequency.
        (0..scan)
            .map(|i| w_nt * (1.0 + 1e-9 * (1.5e9f64).powf(i as f64 / (scan - 1) as f64)))
            .collect()
    } else {
        (0..scan)
            .map(|i| lo * (hi / lo).powf(i as f64 / (scan - 1) as f64))
            .collect()
    };
    let tl: Vec<Option<(f64, f64)>> = ws.iter().map(|&w| tilt_and_landing(p, a, w)).collect();
    let residual = |s: f64, w: f64, tt: (f64, f64)| tt.1 - (PI / w + s * tt.0);
    ss.iter()
        .map(|&s| {
            for i in 1..ws.len() {
                let (Some(t0), Some(t1)) = (tl[i - 1], tl[i]) else {
                    continue;
                };
                let (r0, r1) = (residual(s, ws[i - 1], t0), residual(s, ws[i], t1));
                if (r0 > 0.0) == (r1 > 0.0) {
                    continue;
                }
                let (mut w0, mut w1) = (ws[i - 1], ws[i]);
                let pos0 = r0 > 0.0;
                let mut ok = true;
                while w1 - w0 > 1e-11 * w1 {
                    let m = 0.5 * (w0 + w1);
                    let Some(tm) = tilt_and_landing(p, a, m) else {
                        ok = false;
                        break;
                    };
                    if (residual(s, m, tm) > 0.0) == pos0 {
                        w0 = m;
                    } else {
                        w1 = m;
                    }
                }
                if ok {
                    return Some(0.5 * (w0 + w1));
                }
            }
            None
        })
        .collect()
}
