//! The output-error refinement of the flat arm's parameters, after the least squares.
//!
//! **Why.** The least squares of [`super::rows::build_from_angles`] is an equation error: its
//! rows carry velocities differentiated from the noisy angles, and the viscous column (the
//! arm's displacement over a window) is small beside the inertial and gravity terms the noise
//! enters. On a heavy arm, whose speed the excitation's torque clip holds near 0.3 rad/s, that
//! left `b_v` 14-23 % off under 1 mrad of angle noise in 300 s. Here the recorded angle itself
//! is compared with a simulation: the angle noise is white and enters each residual once,
//! undifferentiated, so it averages out.
//!
//! **What.** Flat, the arm alone obeys (docs/model.md)
//! `J beta_ddot = tau - G cos(beta) - b beta_dot - tau_c sign(beta_dot)` with `J = pi3 + pi5`
//! (the arm's inertia about the joint), `G = g pi2`, `b = pi6`, `tau_c = pi7`, and Karnopp's
//! rule where the joint stops (stuck while `|tau - G cos(beta)| < tau_c`). The flat segments
//! of the recording (no event, mode change, gap or unknown torque inside) are cut into windows
//! of about [`WINDOW`] s; each window is simulated from its own initial state `(beta0,
//! beta_dot0)` under the recorded torques (each held over its sample interval: one RK4 step per
//! interval, a zero crossing of `beta_dot` located inside it), and Levenberg-Marquardt
//! minimises the sum over all samples of `(beta simulated - beta recorded)^2` over the four
//! parameters and every window's initial state, started from the least squares and the smoothed
//! states. The windows are short because the upright arm is unstable (`sqrt(G / J)` about 2.2
//! 1/s): their initial states absorb the drift the unstable mode would amplify.
//!
//! **Standard errors** are the Gauss-Newton covariance `s^2 (A^T A)^-1` of the four
//! parameters with the initial states eliminated (the Schur complement), `s^2` the residual
//! variance over `samples - 4 - 2 windows` degrees of freedom: exact for white angle noise.
//!
//! Derivatives are forward differences of the simulation (each parameter's perturbation moves
//! every window at once; an initial state's moves only its window, so all windows' `beta0`
//! are perturbed in one pass, and all `beta_dot0` in another): seven simulations of the flat
//! data per iteration.

use super::rows::segments;
use nalgebra::{Matrix2, Matrix4, SMatrix, SVector, Vector2, Vector4};
use rayon::prelude::*;
use serde::Serialize;
use tilting_proto::Mode;
use tilting_record::Trace;

/// Default window length (s).
pub const WINDOW: f64 = 1.0;
/// Shortest flat segment (s) that gives a window.
pub const MIN_SEGMENT: f64 = 0.5;
/// Most Levenberg-Marquardt iterations per stage (measured: 5-10 free, 6-25 joined).
const MAX_ITER: usize = 60;
/// The joined fit has converged when no damped step lowers the cost by more than its 1e-12
/// and the undamped step is within this many standard errors of every parameter: what is
/// left to move is a quarter of the estimate's own uncertainty (it adds at most 6 % to its
/// variance).
const STALL_IN_SE: f64 = 0.25;

/// What the refinement did; the parameters in the order `(J, G, b_v, tau_c)`: the arm's
/// inertia about the joint `pi3 + pi5` (kg m^2), its gravity torque `m_l l_c g` (N m), the
/// viscous (N m s/rad) and the Coulomb (N m) friction.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Refinement {
    /// Window length asked for (s).
    pub window_s: f64,
    /// Windows simulated.
    pub windows: usize,
    /// Recorded angles compared.
    pub samples: usize,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Whether the cost stopped falling (relative change below 1e-10) within the iterations.
    pub converged: bool,
    /// RMS of `beta` simulated minus recorded, at the start (the least squares and the
    /// smoothed states) and at the end (rad).
    pub rms_start: f64,
    /// At the end (rad).
    pub rms: f64,
    /// The least squares' `(J, G, b_v, tau_c)`, the start.
    pub start: [f64; 4],
    /// The refined `(J, G, b_v, tau_c)`.
    pub value: [f64; 4],
    /// Their standard errors.
    pub std_error: [f64; 4],
}

/// One window: the sample range `[a, b)` of the trace, its initial state, and whether the
/// next window starts at `b` in the same segment (then the state is carried over sample
/// interval `b - 1` and must equal the next window's initial state).
#[derive(Debug, Clone, Copy)]
struct Window {
    a: usize,
    b: usize,
    z: [f64; 2],
    linked: bool,
}

/// Weights of the continuity residuals: a jump of 1e-6 rad, or of 1e-5 rad/s, costs as much
/// as one angle residual of 1e-3 rad (1 mrad, the noise the refinement is for).
const LINK: [f64; 2] = [1e3, 1e2];

/// Refines `(J, G, b_v, tau_c)` from `start` on the flat segments of `trace` (torques `tau`
/// held over the sample intervals), with `states` the smoothed state of each sample (the
/// windows' first guesses; `None` falls back to the recorded angle at rest). `None` when the
/// recording has no flat segment of [`MIN_SEGMENT`] s, or the fit fails (a non-finite cost,
/// a singular normal matrix).
pub fn refine(
    trace: &Trace,
    tau: &[Option<f64>],
    states: &[Option<[f64; 4]>],
    start: [f64; 4],
    window: f64,
) -> Option<Refinement> {
    let s = &trace.samples;
    let mut wins = Vec::new();
    let mut segments_used = 0;
    for (a, b) in segments(trace, tau) {
        if s[a].mode != Mode::Flat || b - a < 3 {
            continue;
        }
        let span = s[b - 1].t - s[a].t;
        if span < MIN_SEGMENT {
            continue;
        }
        segments_used += 1;
        let count = ((span / window).round() as usize).max(1);
        let n = b - a;
        for c in 0..count {
            let (lo, hi) = (a + c * n / count, a + (c + 1) * n / count);
            let z = match states.get(lo).copied().flatten() {
                Some(x) if x[1].is_finite() && x[3].is_finite() => [x[1], x[3]],
                _ => [s[lo].x[1], 0.0],
            };
            wins.push(Window {
                a: lo,
                b: hi,
                z,
                linked: c + 1 < count,
            });
        }
    }
    if wins.is_empty() {
        return None;
    }
    let data = Data {
        t: s.iter().map(|x| x.t).collect(),
        y: s.iter().map(|x| x.x[1]).collect(),
        tau: tau.iter().map(|t| t.unwrap_or(0.0)).collect(),
    };
    let samples: usize = wins.iter().map(|w| w.b - w.a).sum();
    let mut p = start;
    let (cost0, _) = data.cost(&wins, &p, false);
    if !cost0.is_finite() {
        return None;
    }
    // First every window on its own (its initial state free), then the windows joined into
    // one motion per segment (multiple shooting: the continuity residuals).
    let mut iterations = 0;
    let mut converged = false;
    let mut normal = None;
    for link in [false, true] {
        let (it, conv, n) = data.levenberg_marquardt(&mut wins, &mut p, link);
        iterations += it;
        converged = conv;
        normal = n;
    }
    let (_, rss) = data.cost(&wins, &p, true);
    let dof = samples.saturating_sub(4 + 2 * segments_used).max(1) as f64;
    let s2 = rss / dof;
    let cov = normal?.covariance()?;
    let std_error = std::array::from_fn(|j| (s2 * cov[(j, j)]).max(0.0).sqrt());
    Some(Refinement {
        window_s: window,
        windows: wins.len(),
        samples,
        iterations,
        converged,
        rms_start: (cost0 / samples as f64).sqrt(),
        rms: (rss / samples as f64).sqrt(),
        start,
        value: p,
        std_error,
    })
}

/// The normal equations of the unknowns `p` (4) and the windows' states `z_k` (2 each):
/// `[[pp, zp^T], [zp, Z]]`, `Z` block tridiagonal (`zz` on the diagonal, `up[k]` between
/// `z_k` and `z_(k+1)`), gradient `(gp, gz)`.
struct Normal {
    pp: Matrix4<f64>,
    gp: Vector4<f64>,
    zp: Vec<SMatrix<f64, 2, 4>>,
    zz: Vec<Matrix2<f64>>,
    up: Vec<Matrix2<f64>>,
    gz: Vec<Vector2<f64>>,
}

/// A window's block of `Z^-1 [zp | gz]`.
type Block = SMatrix<f64, 2, 5>;

impl Normal {
    /// The states eliminated with damping `lambda` (times the diagonal): `Z` solved by block
    /// elimination (Thomas) for `[zp | gz]`; returns the parameters' Schur complement, their
    /// reduced gradient and the solved blocks.
    fn eliminate(&self, lambda: f64) -> Option<(Matrix4<f64>, Vector4<f64>, Vec<Block>)> {
        let nw = self.zz.len();
        // Forward: M_k = D_k - U_(k-1)^T M_(k-1)^-1 U_(k-1), R_k likewise.
        let mut minv: Vec<Matrix2<f64>> = Vec::with_capacity(nw);
        let mut rr: Vec<Block> = Vec::with_capacity(nw);
        for k in 0..nw {
            let mut m = self.zz[k];
            for i in 0..2 {
                m[(i, i)] += lambda * self.zz[k][(i, i)].max(1e-300);
            }
            let mut r = Block::zeros();
            r.fixed_view_mut::<2, 4>(0, 0).copy_from(&self.zp[k]);
            r.fixed_view_mut::<2, 1>(0, 4).copy_from(&self.gz[k]);
            if k > 0 {
                let u = self.up[k - 1];
                m -= u.transpose() * minv[k - 1] * u;
                r -= u.transpose() * minv[k - 1] * rr[k - 1];
            }
            minv.push(m.try_inverse()?);
            rr.push(r);
        }
        // Back: X_k = M_k^-1 (R_k - U_k X_(k+1)).
        let mut x = vec![Block::zeros(); nw];
        for k in (0..nw).rev() {
            let mut r = rr[k];
            if k + 1 < nw {
                r -= self.up[k] * x[k + 1];
            }
            x[k] = minv[k] * r;
        }
        let mut s = self.pp;
        for i in 0..4 {
            s[(i, i)] += lambda * self.pp[(i, i)].max(1e-300);
        }
        let mut g = self.gp;
        for (zp, xk) in self.zp.iter().zip(&x) {
            s -= zp.transpose() * xk.fixed_view::<2, 4>(0, 0);
            g -= zp.transpose() * xk.fixed_view::<2, 1>(0, 4);
        }
        Some((s, g, x))
    }

    /// The Levenberg-Marquardt step with damping `lambda`: the parameters' and each window's
    /// state's.
    fn solve(&self, lambda: f64) -> Option<(Vector4<f64>, Vec<Vector2<f64>>)> {
        let (s, g, x) = self.eliminate(lambda)?;
        let dp = s.lu().solve(&(-g))?;
        let dz = x
            .iter()
            .map(|xk| -xk.fixed_view::<2, 1>(0, 4) - xk.fixed_view::<2, 4>(0, 0) * dp)
            .collect();
        Some((dp, dz))
    }

    /// The parameters' covariance per unit residual variance: the inverse of the undamped
    /// Schur complement of the states.
    fn covariance(&self) -> Option<Matrix4<f64>> {
        self.eliminate(0.0)?.0.try_inverse()
    }
}

/// The recording's times, angles `beta` and held torques.
struct Data {
    t: Vec<f64>,
    y: Vec<f64>,
    tau: Vec<f64>,
}

/// The arm's state `(beta, beta_dot)` (rad, rad/s) and its sensitivities to `(J, G, b, tau_c,
/// beta0, beta_dot0)`, or their derivatives in time.
type Sens = (f64, f64, SVector<f64, 6>, SVector<f64, 6>);

/// The augmented field of the arm's joint with parameters `p = [J, G, b, tau_c]`: the
/// derivative of `x = (q, v, sq, sv)` (rad, rad/s and their sensitivities) under the torque `u`
/// (N m) in the friction phase `s` (the sign of the sliding velocity; 0 stuck).
fn sens_field(p: &[f64; 4], x: &Sens, u: f64, s: f64) -> Sens {
    type V6 = SVector<f64, 6>;
    let [j, g, b, tc] = *p;
    let (q, v, sq, sv) = x;
    let (sn, cs) = q.sin_cos();
    let a = (u - g * cs - b * v - tc * s) / j;
    let mut da = V6::zeros();
    da[0] = -a / j;
    da[1] = -cs / j;
    da[2] = -v / j;
    da[3] = -s / j;
    let dsv = da + sq * (g * sn / j) - sv * (b / j);
    (*v, a, *sv, dsv)
}

/// One classical RK4 step of `h` seconds of [`sens_field`] from `x = (q, v, sq, sv)` under the
/// torque `u` (N m) in the friction phase `s`.
fn sens_step(p: &[f64; 4], x: &Sens, h: f64, u: f64, s: f64) -> Sens {
    let (q, v, sq, sv) = x;
    let k1 = sens_field(p, x, u, s);
    let k2 = sens_field(
        p,
        &(
            q + 0.5 * h * k1.0,
            v + 0.5 * h * k1.1,
            sq + k1.2 * (0.5 * h),
            sv + k1.3 * (0.5 * h),
        ),
        u,
        s,
    );
    let k3 = sens_field(
        p,
        &(
            q + 0.5 * h * k2.0,
            v + 0.5 * h * k2.1,
            sq + k2.2 * (0.5 * h),
            sv + k2.3 * (0.5 * h),
        ),
        u,
        s,
    );
    let k4 = sens_field(
        p,
        &(q + h * k3.0, v + h * k3.1, sq + k3.2 * h, sv + k3.3 * h),
        u,
        s,
    );
    (
        q + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0),
        v + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1),
        sq + (k1.2 + k2.2 * 2.0 + k3.2 * 2.0 + k4.2) * (h / 6.0),
        sv + (k1.3 + k2.3 * 2.0 + k3.3 * 2.0 + k4.3) * (h / 6.0),
    )
}

impl Data {
    /// Levenberg-Marquardt on `(p, wins' initial states)`, with the continuity residuals when
    /// `link`: the iterations, whether the cost settled, and the normal equations at the end.
    fn levenberg_marquardt(
        &self,
        wins: &mut Vec<Window>,
        p: &mut [f64; 4],
        link: bool,
    ) -> (usize, bool, Option<Normal>) {
        let mut cost = self.cost(wins, p, link).0;
        let mut lambda = 1e-4;
        let mut normal = None;
        for it in 1..=MAX_ITER {
            let n = self.linearise(wins, p, link);
            // Joined: at the minimum when the undamped (Gauss-Newton) step moves every
            // parameter by less than 1e-2 of its standard error (the valley along b_v and
            // tau_c is flat: a criterion on the cost's fall stopped half a standard error
            // short; one on the damped step stopped wherever the damping was large).
            // `gn_in_se`: the largest undamped step in standard errors (joined only).
            let s2 = cost / self.samples(wins) as f64;
            let gn_in_se = link
                .then(|| n.solve(0.0).zip(n.covariance()))
                .flatten()
                .map(|(gn, cov)| {
                    (0..4)
                        .map(|j| gn.0[j].abs() / (s2 * cov[(j, j)]).sqrt())
                        .fold(0.0, f64::max)
                });
            if gn_in_se.is_some_and(|r| r <= 1e-2) {
                return (it, true, Some(n));
            }
            let mut accepted = false;
            let mut settled = false;
            for _ in 0..12 {
                let Some((dp, dz)) = n.solve(lambda) else {
                    lambda *= 10.0;
                    continue;
                };
                let mut tp = *p;
                for j in 0..4 {
                    tp[j] += dp[j];
                }
                let tw: Vec<Window> = wins
                    .iter()
                    .zip(&dz)
                    .map(|(w, d)| Window {
                        z: [w.z[0] + d[0], w.z[1] + d[1]],
                        ..*w
                    })
                    .collect();
                let valid = tp[0] > 0.0 && tp[1] > 0.0 && tp[3] >= 0.0;
                let c = if valid {
                    self.cost(&tw, &tp, link).0
                } else {
                    f64::INFINITY
                };
                if c.is_finite() && c <= cost {
                    // Settled, free windows (the start of the joined fit): the cost fell by
                    // less than 1e-5 of itself. Joined: see the undamped step above; or
                    // stalled within STALL_IN_SE standard errors of it: the cost of noisy
                    // angles through Coulomb friction's stick/slip switches is not smooth at
                    // that scale, and the damped steps that still lower it move nothing
                    // (measured: 0.12 standard errors away, 30 iterations at lambda 1e7
                    // without a change of the cost in its 13th digit).
                    settled = if link {
                        cost - c <= 1e-12 * cost && gn_in_se.is_some_and(|r| r <= STALL_IN_SE)
                    } else {
                        cost - c <= 1e-5 * cost
                    };
                    // Exact data: an RMS of 1e-10 rad is round-off.
                    settled |= c <= 1e-20 * self.samples(wins) as f64;
                    *p = tp;
                    *wins = tw;
                    cost = c;
                    lambda = (lambda / 10.0).max(1e-12);
                    accepted = true;
                    break;
                }
                lambda *= 10.0;
            }
            normal = Some(n);
            if !accepted || settled {
                // No step lowers the cost, or the last one hardly did: at the minimum.
                return (it, true, Some(self.linearise(wins, p, link)));
            }
        }
        (MAX_ITER, false, normal)
    }

    /// Samples compared in `wins`.
    fn samples(&self, wins: &[Window]) -> usize {
        wins.iter().map(|w| w.b - w.a).sum()
    }

    /// The cost (data residuals, and the continuity residuals when `link`) and the data
    /// residuals' sum of squares alone.
    fn cost(&self, wins: &[Window], p: &[f64; 4], link: bool) -> (f64, f64) {
        let per: Vec<(f64, f64)> = wins
            .par_iter()
            .enumerate()
            .map(|(k, w)| {
                let mut out = vec![0.0; w.b - w.a];
                let end = self.simulate(w, p, &mut out);
                let d: f64 = (w.a..w.b)
                    .zip(&out)
                    .map(|(i, q)| (q - self.y[i]).powi(2))
                    .sum();
                let mut c = 0.0;
                if link && w.linked {
                    let z = wins[k + 1].z;
                    c = (0..2)
                        .map(|i| (LINK[i] * (end[i] - z[i])).powi(2))
                        .sum::<f64>();
                }
                (d + c, d)
            })
            .collect();
        per.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// The normal equations at `(wins, p)` ([`Data::sensitivities`]).
    fn linearise(&self, wins: &[Window], p: &[f64; 4], link: bool) -> Normal {
        type M6 = SMatrix<f64, 6, 6>;
        type V6 = SVector<f64, 6>;
        type Local = (M6, V6, ([f64; 2], [V6; 2]));
        let local: Vec<Local> = wins
            .par_iter()
            .map(|w| {
                let mut rows = Vec::with_capacity(w.b - w.a);
                let end = self.sensitivities(w, p, &mut rows);
                let mut m = M6::zeros();
                let mut g = V6::zeros();
                for (i, (q, jr)) in (w.a..w.b).zip(&rows) {
                    m += jr * jr.transpose();
                    g += jr * (q - self.y[i]);
                }
                (m, g, end)
            })
            .collect();
        let nw = wins.len();
        let mut n = Normal {
            pp: Matrix4::zeros(),
            gp: Vector4::zeros(),
            zp: vec![SMatrix::zeros(); nw],
            zz: vec![Matrix2::zeros(); nw],
            up: vec![Matrix2::zeros(); nw],
            gz: vec![Vector2::zeros(); nw],
        };
        for (k, (m, g, end)) in local.iter().enumerate() {
            n.pp += m.fixed_view::<4, 4>(0, 0);
            n.zp[k] += m.fixed_view::<2, 4>(4, 0);
            n.zz[k] += m.fixed_view::<2, 2>(4, 4);
            n.gp += g.fixed_rows::<4>(0);
            n.gz[k] += g.fixed_rows::<2>(4);
            if link && wins[k].linked {
                // r_c = LINK (end(p, z_k) - z_(k+1)): a row over p, z_k and z_(k+1).
                let z = wins[k + 1].z;
                for c in 0..2 {
                    let r = LINK[c] * (end.0[c] - z[c]);
                    let row = end.1[c] * LINK[c];
                    let (rp, rz) = (row.fixed_rows::<4>(0), row.fixed_rows::<2>(4));
                    let mut e = Vector2::zeros();
                    e[c] = -LINK[c];
                    n.pp += rp * rp.transpose();
                    n.gp += rp * r;
                    n.zp[k] += rz * rp.transpose();
                    n.zp[k + 1] += e * rp.transpose();
                    n.zz[k] += rz * rz.transpose();
                    n.zz[k + 1] += e * e.transpose();
                    n.up[k] += rz * e.transpose();
                    n.gz[k] += rz * r;
                    n.gz[k + 1] += e * r;
                }
            }
        }
        n
    }

    /// [`Data::simulate`] with the forward sensitivities of `beta` to `(J, G, b, tau_c,
    /// beta0, beta_dot0)` integrated beside the state (the same RK4 steps; at a reversal the
    /// rate's sensitivity jumps by the change of acceleration times the crossing time's
    /// sensitivity; stuck, the rate's sensitivity is 0): `rows` gets `(beta, d beta)` per
    /// sample of the window; returns the carried state and its sensitivities.
    fn sensitivities(
        &self,
        w: &Window,
        p: &[f64; 4],
        rows: &mut Vec<(f64, SVector<f64, 6>)>,
    ) -> ([f64; 2], [SVector<f64, 6>; 2]) {
        type V6 = SVector<f64, 6>;
        let [j, g, b, tc] = *p;
        let (mut q, mut v) = (w.z[0], w.z[1]);
        let mut sq = V6::zeros();
        let mut sv = V6::zeros();
        sq[4] = 1.0;
        sv[5] = 1.0;
        let karnopp = |q: f64, u: f64| karnopp_phase(u, g, q, tc);
        let mut phase = if v != 0.0 { v.signum() } else { 0.0 };
        rows.clear();
        rows.push((q, sq));
        let last = if w.linked { w.b } else { w.b - 1 };
        let step = |q: f64, v: f64, sq: &V6, sv: &V6, h: f64, u: f64, s: f64| {
            sens_step(p, &(q, v, *sq, *sv), h, u, s)
        };
        let acc = |q: f64, v: f64, u: f64, s: f64| (u - g * q.cos() - b * v - tc * s) / j;
        for k in w.a..last {
            let u = self.tau[k];
            let h = self.t[k + 1] - self.t[k];
            if v == 0.0 {
                phase = karnopp(q, u);
            }
            if phase != 0.0 {
                let (q1, v1, sq1, sv1) = step(q, v, &sq, &sv, h, u, phase);
                if v1 * phase >= 0.0 {
                    (q, v, sq, sv) = (q1, v1, sq1, sv1);
                } else {
                    // As in simulate: locate the stop, Karnopp's rule, the rest.
                    let mut frac = v / (v - v1);
                    let mut st = step(q, v, &sq, &sv, frac * h, u, phase);
                    let a0 = acc(st.0, st.1, u, phase);
                    if a0 != 0.0 {
                        frac = (frac - st.1 / (a0 * h)).clamp(0.0, 1.0);
                        st = step(q, v, &sq, &sv, frac * h, u, phase);
                    }
                    let a_minus = acc(st.0, 0.0, u, phase);
                    (q, v, sq, sv) = (st.0, 0.0, st.2, st.3);
                    let old = phase;
                    phase = karnopp(q, u);
                    if phase == 0.0 {
                        sv = V6::zeros();
                    } else {
                        if phase != old && a_minus != 0.0 {
                            let a_plus = acc(q, 0.0, u, phase);
                            sv *= a_plus / a_minus;
                        }
                        let rest = (1.0 - frac) * h;
                        (q, v, sq, sv) = step(q, 0.0, &sq, &sv, rest, u, phase);
                        if v * phase < 0.0 {
                            v = 0.0;
                            phase = 0.0;
                            sv = V6::zeros();
                        }
                    }
                }
            }
            if k + 1 < w.b {
                rows.push((q, sq));
            }
        }
        ([q, v], [sq, sv])
    }

    /// The window `w` simulated with the parameters `p`: `beta` at its samples into
    /// `out[..w.b - w.a]`; returns the state `(beta, beta_dot)` carried to sample `w.b` when the
    /// window is linked to the next (else the state at its last sample).
    fn simulate(&self, w: &Window, p: &[f64; 4], out: &mut [f64]) -> [f64; 2] {
        let [j, g, b, tc] = *p;
        let (mut q, mut v) = (w.z[0], w.z[1]);
        let karnopp = |q: f64, u: f64| karnopp_phase(u, g, q, tc);
        let mut phase = if v != 0.0 { v.signum() } else { 0.0 };
        out[0] = q;
        let last = if w.linked { w.b } else { w.b - 1 };
        for k in w.a..last {
            let u = self.tau[k];
            let h = self.t[k + 1] - self.t[k];
            if v == 0.0 {
                phase = karnopp(q, u);
            }
            if phase != 0.0 {
                let acc = |q: f64, v: f64, s: f64| (u - g * q.cos() - b * v - tc * s) / j;
                let (q1, v1) = rk4(q, v, h, |q, v| acc(q, v, phase));
                if v1 * phase >= 0.0 {
                    (q, v) = (q1, v1);
                } else {
                    // The slide ends inside the interval: locate beta_dot = 0 (secant on the
                    // step's fraction, then one Newton correction), stop there, apply
                    // Karnopp's rule and go on over the rest of the interval.
                    let mut frac = v / (v - v1);
                    let (mut qa, va) = rk4(q, v, frac * h, |q, v| acc(q, v, phase));
                    let a0 = acc(qa, va, phase);
                    if a0 != 0.0 {
                        frac = (frac - va / (a0 * h)).clamp(0.0, 1.0);
                        qa = rk4(q, v, frac * h, |q, v| acc(q, v, phase)).0;
                    }
                    q = qa;
                    v = 0.0;
                    phase = karnopp(q, u);
                    if phase != 0.0 {
                        let rest = (1.0 - frac) * h;
                        (q, v) = rk4(q, 0.0, rest, |q, v| acc(q, v, phase));
                        if v * phase < 0.0 {
                            // Turned back within the remainder: the joint sticks there.
                            v = 0.0;
                            phase = 0.0;
                        }
                    }
                }
            }
            if k + 1 < w.b {
                out[k + 1 - w.a] = q;
            }
        }
        [q, v]
    }
}

/// The flat arm's joint phase by Karnopp's rule, as the plant applies it when the arm is at
/// rest: +1 or -1 when the net torque `u - g cos(q)` (N m; `g` = m_l l_c g) exceeds the
/// Coulomb friction `tc` (N m) and the arm starts to slide that way, 0 while it sticks.
fn karnopp_phase(u: f64, g: f64, q: f64, tc: f64) -> f64 {
    let net = u - g * q.cos();
    if net.abs() < tc {
        0.0
    } else {
        net.signum()
    }
}

/// One classical Runge-Kutta step of `q' = v`, `v' = a(q, v)` over `h`.
fn rk4(q: f64, v: f64, h: f64, a: impl Fn(f64, f64) -> f64) -> (f64, f64) {
    let k1 = (v, a(q, v));
    let k2 = (
        v + 0.5 * h * k1.1,
        a(q + 0.5 * h * k1.0, v + 0.5 * h * k1.1),
    );
    let k3 = (
        v + 0.5 * h * k2.1,
        a(q + 0.5 * h * k2.0, v + 0.5 * h * k2.1),
    );
    let k4 = (v + h * k3.1, a(q + h * k3.0, v + h * k3.1));
    (
        q + h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0),
        v + h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A swinging flat arm over 2 s (1 kHz): the torque of `beta = 1.6 + 0.2 sin(3 t)` by
    /// the flat equation at each interval's midpoint; it reverses (the friction switches
    /// sign) twice.
    fn data(p: &[f64; 4]) -> (Data, Window) {
        let n = 2001;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let tau = t
            .iter()
            .map(|t| {
                let m = t + 0.5e-3;
                let (q, v, a) = (
                    1.6 + 0.2 * (3.0 * m).sin(),
                    0.6 * (3.0 * m).cos(),
                    -1.8 * (3.0 * m).sin(),
                );
                p[0] * a + p[1] * q.cos() + p[2] * v + p[3] * v.signum()
            })
            .collect();
        let w = Window {
            a: 0,
            b: n - 1,
            z: [1.6, 0.6],
            linked: true,
        };
        let d = Data {
            t,
            y: vec![0.0; n],
            tau,
        };
        (d, w)
    }

    /// The sensitivities integrated beside the state equal central differences of the
    /// simulation (an independent computation: no sensitivity equation), reversals included,
    /// at every sample and at the carried end state; and the arm does reverse.
    #[test]
    fn sensitivities_match_finite_differences() {
        let p = [4.8, 23.5, 0.05, 0.08];
        let (d, w) = data(&p);
        let mut rows = Vec::new();
        let (end, ends) = d.sensitivities(&w, &p, &mut rows);
        let mut out = vec![0.0; w.b - w.a];
        let e0 = d.simulate(&w, &p, &mut out);
        assert_eq!(e0, end, "simulate and sensitivities take the same steps");
        let reversals = out
            .windows(3)
            .filter(|x| (x[1] - x[0]) * (x[2] - x[1]) < 0.0)
            .count();
        assert!(reversals >= 2, "{reversals} reversals");
        let steps = [1e-6, 1e-5, 1e-7, 1e-7, 1e-7, 1e-7];
        for (j, h) in steps.iter().enumerate() {
            let run = |s: f64| {
                let (mut q, mut v) = (p, w);
                if j < 4 {
                    q[j] += s;
                } else {
                    v.z[j - 4] += s;
                }
                let mut o = vec![0.0; w.b - w.a];
                let e = d.simulate(&v, &q, &mut o);
                (o, e)
            };
            let ((op, ep), (om, em)) = (run(*h), run(-*h));
            let scale = rows.iter().fold(0.0f64, |m, r| m.max(r.1[j].abs()));
            // Tolerance: central differences are O(h^2) plus round-off 1e-16 / h; a reversal
            // inside an interval is located to O(h^3) of the 1 ms step: 1e-4 of the largest.
            for (i, r) in rows.iter().enumerate() {
                let fd = (op[i] - om[i]) / (2.0 * h);
                assert!(
                    (r.1[j] - fd).abs() < 1e-4 * scale,
                    "column {j} sample {i}: {} vs {fd}",
                    r.1[j]
                );
            }
            for c in 0..2 {
                let fd = (ep[c] - em[c]) / (2.0 * h);
                let sc = ends[c][j].abs().max(1e-3 * scale);
                assert!(
                    (ends[c][j] - fd).abs() < 1e-3 * sc.max(scale),
                    "end {c} column {j}: {} vs {fd}",
                    ends[c][j]
                );
            }
        }
    }

    /// Noise-free angles of the same arm: the refinement started 10 % off in every parameter
    /// (and from initial states off by 1 mrad and 10 mrad/s) returns the simulated arm's
    /// parameters to 1e-6.
    #[test]
    fn recovers_the_parameters_from_exact_angles() {
        let p = [4.8, 23.5, 0.05, 0.08];
        let (d, w) = data(&p);
        let mut y = vec![0.0; w.b - w.a];
        d.simulate(&w, &p, &mut y);
        let samples = (0..y.len())
            .map(|k| tilting_record::Sample {
                t: d.t[k],
                mode: Mode::Flat,
                x: [0.0, y[k], 0.0, f64::NAN],
            })
            .collect();
        let trace = Trace {
            samples,
            events: Vec::new(),
            end: d.t[y.len() - 1],
            stopped_early: false,
        };
        let tau: Vec<Option<f64>> = d.tau[..y.len()].iter().map(|t| Some(*t)).collect();
        let states: Vec<Option<[f64; 4]>> = vec![None; y.len()];
        let mut states = states;
        states[0] = Some([0.0, w.z[0] + 1e-3, 0.0, w.z[1] + 1e-2]);
        let start = p.map(|v| 1.1 * v);
        let r = refine(&trace, &tau, &states, start, 0.5).expect("refined");
        assert!(r.converged, "{r:?}");
        for (j, (got, want)) in r.value.iter().zip(p).enumerate() {
            assert!(((got - want) / want).abs() < 1e-6, "{j}: {got} vs {want}");
        }
        assert!(r.rms < 1e-9, "{r:?}");
    }
}
