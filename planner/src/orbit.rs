//! Approach 2 (paper Sec. III-B): periodic tilting orbits of the closed loop as a boundary
//! value problem, and their stability.
//!
//! The orbit starts at the beginning of a left tilt, `x0 = (0, pi/2 + beta0, 0, beta_dot0)`, and
//! after one left tilt (of duration `t_end`) lands with the impact map and starts a right tilt
//! in the mirrored state: `alpha(t_end) = 0`, `beta(t_end) = pi/2 - beta0`,
//! `beta_dot+(t_end) = -beta_dot0`. Mirroring makes it periodic with period `2 t_end`.
//!
//! Newton shooting on `z = (beta0, beta_dot0, t_end)` uses the exact Jacobian of the shooting
//! map from the variational equations of the left-tilt flow (the vector field's Jacobian by
//! central differences, `h ~ eps^(1/3)`). The same sensitivities, with the saltation of the
//! landing event, give the monodromy of the half-period mirrored return map
//! `P: (beta, beta_dot) at a left-tilt start -> the mirrored state at the next right-tilt start`,
//! whose eigenvalues are the Floquet multipliers reported here.

use nalgebra::{Matrix2, Matrix3, Matrix4, SVector, Vector3, Vector4};
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;
use tilting_controller::{ComputedTorque, ControlConfig, LawSpec, PlannableLaw};
use tilting_plant::dynamics::rhs;
use tilting_plant::ode::{Dop853, Tolerance};
use tilting_plant::{
    energy, ImpactLaw, Mode, Observer, Params, Plant, SimConfig, State, TiltPeak, TorqueLaw,
    Transition,
};

/// The problem: model, impact law and closed loop (the reference must be `Hold`). The loop is
/// the paper's law of `control` ([`OrbitProblem::law`]); the `*_with` functions take any
/// [`PlannableLaw`] instead, with this problem's model, impact law and tolerance.
#[derive(Debug, Clone, Copy)]
pub struct OrbitProblem {
    /// Physical parameters.
    pub params: Params,
    /// Landing impact law.
    pub impact: ImpactLaw,
    /// The controller: gains `kp`, `kd`, and for the adapted loop `k` and `energy_avg`.
    pub control: ControlConfig,
    /// Integrator tolerance for the shooting.
    pub tol: Tolerance,
}

impl OrbitProblem {
    /// The paper's loop: `K_P`, `K_D` given, hold reference, no adaptation.
    pub fn new(params: Params, impact: ImpactLaw, kp: f64, kd: f64) -> Self {
        Self {
            params,
            impact,
            control: ControlConfig {
                params,
                law: LawSpec {
                    kp,
                    kd,
                    ..LawSpec::without_adaptation()
                },
            },
            tol: Tolerance {
                rtol: 1e-12,
                atol: 1e-14,
            },
        }
    }

    /// The same loop with the energy adaptation `K_P = K_P0 + k (E_av - E)`.
    pub fn with_adaptation(mut self, k: f64, energy_avg: f64) -> Self {
        self.control.law.k = k;
        self.control.law.energy_avg = energy_avg;
        self
    }

    /// The paper's law of `control`.
    pub fn law(&self) -> ComputedTorque {
        ComputedTorque::new(self.control).expect("validated control settings")
    }

    /// Start of the left tilt for the unknowns `beta0`, `beta_dot0`.
    pub fn start(beta0: f64, beta_dot0: f64) -> State {
        State::new(0.0, FRAC_PI_2 + beta0, 0.0, beta_dot0)
    }
}

/// One periodic orbit.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OrbitSolution {
    /// `beta(0) - pi/2` at the start of the left tilt (rad).
    pub beta0: f64,
    /// `beta_dot(0)` (rad/s).
    pub beta_dot0: f64,
    /// Duration of one tilt, start to landing (s).
    pub t_end: f64,
    /// Period of the orbit, `2 t_end` (s).
    pub period: f64,
    /// Maximal tilt angle `alpha` in the tilt (rad).
    pub max_tilt: f64,
    /// Time average of the total energy over one period (J).
    pub energy_avg: f64,
    /// Floquet multipliers of the half-period mirrored return map, `[re, im]`.
    pub multipliers: Vec<[f64; 2]>,
    /// All multipliers inside the unit circle.
    pub stable: bool,
    /// Norm of the shooting residual at the solution.
    pub residual: f64,
    /// Norm of the mismatch when the orbit is re-simulated by the hybrid simulator (landing
    /// state after impact vs the mirrored start), an independent check of the solution.
    pub resimulated_mismatch: f64,
}

/// Why a shooting run failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OrbitError {
    /// Newton did not converge.
    #[error("Newton shooting did not converge from beta0 = {beta0}, beta_dot0 = {beta_dot0} (residual {residual:e})")]
    NoConvergence {
        /// Start guess.
        beta0: f64,
        /// Start guess.
        beta_dot0: f64,
        /// Last residual norm.
        residual: f64,
    },
    /// The integration failed (fall, contact loss, non-finite values).
    #[error("integration failed: {0}")]
    Integration(String),
    /// The converged solution is not a valid hybrid orbit.
    #[error("not a hybrid orbit: {0}")]
    Invalid(String),
}

/// The state with its sensitivity matrix `Phi = dx/dx0` (column-major): `[x (4), Phi (16)]`.
type Aug = SVector<f64, 20>;

/// Flow of the left-tilt closed loop over `[0, t]` from `x0`, with sensitivities.
pub(crate) struct Flow {
    pub(crate) x: Vector4<f64>,
    pub(crate) phi: Matrix4<f64>,
    pub(crate) f: Vector4<f64>,
    pub(crate) energy_integral: f64,
}

pub(crate) fn closed_loop(p: &Params, law: &impl TorqueLaw, x: &State) -> State {
    rhs(p, Mode::Left, x, law.torque(0.0, Mode::Left, x))
}

/// Tolerance of the variational equations. The Jacobian of the vector field is taken by
/// central differences, so it carries noise of about 1e-11 relative; integrating it at a
/// tolerance below that noise would only shrink the steps. Newton's final accuracy does not
/// depend on the Jacobian's (the residual is integrated at the problem's tolerance), and the
/// multipliers come out to about 1e-8.
pub(crate) const SENSITIVITY_TOL: Tolerance = Tolerance {
    rtol: 1e-9,
    atol: 1e-11,
};

fn integrate<const N: usize>(
    tol: Tolerance,
    f: &mut impl FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
    mut y: SVector<f64, N>,
    t: f64,
) -> Result<SVector<f64, N>, OrbitError> {
    let mut st = Dop853::new(tol);
    let (mut tt, mut f0) = (0.0, f(0.0, &y));
    while tt < t {
        let s = st
            .step(f, tt, &y, &f0, t)
            .map_err(|e| OrbitError::Integration(e.to_string()))?;
        tt = s.t1;
        y = s.y1;
        f0 = *s.f1();
        // A shooting trial far from any orbit can tumble (the flow ignores the ground): stop
        // it early instead of integrating a wild motion to the end.
        if y[0].abs() > FRAC_PI_2 || st.stats.steps > 20_000 {
            return Err(OrbitError::Integration(format!(
                "trial motion leaves the tilting range (alpha = {:.3} rad at t = {tt:.3} s)",
                y[0]
            )));
        }
    }
    Ok(y)
}

/// The left-tilt flow over `[0, t]` from `x0` with the energy integral, at the problem's
/// tolerance; with `sensitivities`, also `Phi` (at [`SENSITIVITY_TOL`]).
pub(crate) fn flow(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    x0: &State,
    t: f64,
    sensitivities: bool,
) -> Result<Flow, OrbitError> {
    let p = pb.params;
    let mut plain = |_t: f64, y: &SVector<f64, 5>| {
        let x: State = y.fixed_rows::<4>(0).into_owned();
        let fx = closed_loop(&p, law, &x);
        SVector::<f64, 5>::new(fx[0], fx[1], fx[2], fx[3], energy(&p, Mode::Left, &x))
    };
    let y0 = SVector::<f64, 5>::new(x0[0], x0[1], x0[2], x0[3], 0.0);
    let y = integrate(pb.tol, &mut plain, y0, t)?;
    let x: State = y.fixed_rows::<4>(0).into_owned();
    let phi = if sensitivities {
        let mut aug = Aug::zeros();
        aug.fixed_rows_mut::<4>(0).copy_from(x0);
        for i in 0..4 {
            aug[4 + 4 * i + i] = 1.0;
        }
        let mut f = |_t: f64, y: &Aug| {
            let x: State = y.fixed_rows::<4>(0).into_owned();
            let fx = closed_loop(&p, law, &x);
            // Jacobian of the vector field by central differences, h ~ eps^(1/3).
            let mut jac = Matrix4::zeros();
            for j in 0..4 {
                let h = 6e-6 * (1.0 + x[j].abs());
                let mut xp = x;
                let mut xm = x;
                xp[j] += h;
                xm[j] -= h;
                let col = (closed_loop(&p, law, &xp) - closed_loop(&p, law, &xm)) / (2.0 * h);
                jac.set_column(j, &col);
            }
            let phi = Matrix4::from_column_slice(&y.as_slice()[4..20]);
            let dphi = jac * phi;
            let mut d = Aug::zeros();
            d.fixed_rows_mut::<4>(0).copy_from(&fx);
            d.as_mut_slice()[4..20].copy_from_slice(dphi.as_slice());
            d
        };
        let ya = integrate(SENSITIVITY_TOL, &mut f, aug, t)?;
        Matrix4::from_column_slice(&ya.as_slice()[4..20])
    } else {
        Matrix4::zeros()
    };
    Ok(Flow {
        x,
        phi,
        f: closed_loop(&p, law, &x),
        energy_integral: y[4],
    })
}

/// `dc/dbeta` of the impact coefficient, by central difference (`c` is smooth; error ~1e-11).
pub(crate) fn impact_slope(pb: &OrbitProblem, beta: f64) -> f64 {
    let h = 1e-5;
    (pb.impact.coefficient(&pb.params, Mode::Left, beta + h)
        - pb.impact.coefficient(&pb.params, Mode::Left, beta - h))
        / (2.0 * h)
}

/// Shooting residual and its Jacobian with respect to `(beta0, beta_dot0, t_end)`.
fn residual(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    z: &Vector3<f64>,
) -> Result<(Vector3<f64>, Matrix3<f64>, Flow), OrbitError> {
    let x0 = OrbitProblem::start(z[0], z[1]);
    let fl = flow(pb, law, &x0, z[2], true)?;
    let x = fl.x;
    let c = pb.impact.coefficient(&pb.params, Mode::Left, x[1]);
    let r = Vector3::new(x[0], x[1] - (FRAC_PI_2 - z[0]), x[3] + c * x[2] + z[1]);
    // Gradient of the post-impact beta_dot with respect to the pre-impact state.
    let grad_g = Vector4::new(0.0, impact_slope(pb, x[1]) * x[2], c, 1.0);
    let phi = &fl.phi;
    let mut j = Matrix3::zeros();
    j[(0, 0)] = phi[(0, 1)];
    j[(0, 1)] = phi[(0, 3)];
    j[(0, 2)] = fl.f[0];
    j[(1, 0)] = phi[(1, 1)] + 1.0;
    j[(1, 1)] = phi[(1, 3)];
    j[(1, 2)] = fl.f[1];
    j[(2, 0)] = grad_g.dot(&phi.column(1));
    j[(2, 1)] = grad_g.dot(&phi.column(3)) + 1.0;
    j[(2, 2)] = grad_g.dot(&fl.f);
    Ok((r, j, fl))
}

/// The monodromy (2x2 Jacobian) of the half-period mirrored return map on `(beta, beta_dot)`
/// at a left-tilt start, from the sensitivities at the landing: the saltation of the event
/// `alpha = 0`, the impact map's Jacobian and the mirror `(beta, beta_dot) -> (pi - beta,
/// -beta_dot)`.
pub(crate) fn monodromy(pb: &OrbitProblem, fl: &Flow) -> Matrix2<f64> {
    let x = fl.x;
    // Event time sensitivity: d tau / d x0 = -(d alpha / d x0) / alpha_dot.
    let dtau = -fl.phi.row(0) / fl.f[0];
    let dx_event = fl.phi + fl.f * dtau;
    let c = pb.impact.coefficient(&pb.params, Mode::Left, x[1]);
    let mut dh = Matrix4::zeros();
    dh[(1, 1)] = 1.0;
    dh[(3, 1)] = impact_slope(pb, x[1]) * x[2];
    dh[(3, 2)] = c;
    dh[(3, 3)] = 1.0;
    let full = -(dh * dx_event); // the mirror negates beta and beta_dot deviations
    Matrix2::new(full[(1, 1)], full[(1, 3)], full[(3, 1)], full[(3, 3)])
}

/// Eigenvalues of a real 2x2 matrix as `[re, im]` pairs.
pub fn eigenvalues2(m: &Matrix2<f64>) -> Vec<[f64; 2]> {
    let tr = m.trace();
    let det = m.determinant();
    let disc = tr * tr / 4.0 - det;
    if disc >= 0.0 {
        let s = disc.sqrt();
        vec![[tr / 2.0 + s, 0.0], [tr / 2.0 - s, 0.0]]
    } else {
        let s = (-disc).sqrt();
        vec![[tr / 2.0, s], [tr / 2.0, -s]]
    }
}

#[derive(Default)]
struct FirstTilt {
    events: Vec<Transition>,
    peak: Option<TiltPeak>,
}

impl Observer for FirstTilt {
    fn transition(&mut self, ev: &Transition) {
        self.events.push(*ev);
    }
    fn tilt_peak(&mut self, p: &TiltPeak) {
        self.peak.get_or_insert(*p);
    }
}

/// Runs the hybrid simulator from the left-tilt start until the first landing (or `t_max`).
fn simulate_first_tilt(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    x0: &State,
    t_max: f64,
) -> Result<FirstTilt, OrbitError> {
    let cfg = SimConfig {
        params: pb.params,
        impact: pb.impact,
        tol: pb.tol,
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, *x0)
        .map_err(|e| OrbitError::Integration(e.to_string()))?;
    let mut obs = FirstTilt::default();
    let mut t = 0.0;
    while t < t_max && !obs.events.iter().any(|e| e.from == Mode::Left) {
        t = (t + 0.05).min(t_max);
        plant
            .advance_continuous(law, t, &mut obs)
            .map_err(|e| OrbitError::Integration(e.to_string()))?;
    }
    Ok(obs)
}

/// The landing of the first tilt from the left-tilt start `x0` within `t_max` (s): its time and
/// the post-impact state, when the plate tilts right at once (`None` otherwise).
pub(crate) fn first_landing(pb: &OrbitProblem, x0: &State, t_max: f64) -> Option<(f64, State)> {
    first_landing_with(pb, &pb.law(), x0, t_max)
}

/// [`first_landing`] of the loop closed by `law`.
pub(crate) fn first_landing_with(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    x0: &State,
    t_max: f64,
) -> Option<(f64, State)> {
    let obs = simulate_first_tilt(pb, law, x0, t_max).ok()?;
    let land = obs.events.iter().position(|e| e.from == Mode::Left)?;
    let ev = obs.events[land];
    let next = obs.events.get(land + 1)?;
    (next.to == Mode::Right && next.t == ev.t).then_some((ev.t, ev.x_after))
}

/// The tilt extreme `alpha` (rad) of the first tilt from the left-tilt start `x0`.
pub(crate) fn first_tilt_peak(pb: &OrbitProblem, x0: &State, t_max: f64) -> Option<f64> {
    simulate_first_tilt(pb, &pb.law(), x0, t_max)
        .ok()?
        .peak
        .map(|p| p.alpha)
}

/// The first landing time from a left-tilt start, as a guess for `t_end`.
pub fn landing_time_guess(pb: &OrbitProblem, beta0: f64, beta_dot0: f64) -> Option<f64> {
    landing_time_guess_with(pb, &pb.law(), beta0, beta_dot0)
}

/// [`landing_time_guess`] for the loop closed by `law`.
pub fn landing_time_guess_with(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    beta0: f64,
    beta_dot0: f64,
) -> Option<f64> {
    let x0 = OrbitProblem::start(beta0, beta_dot0);
    let obs = simulate_first_tilt(pb, law, &x0, 5.0).ok()?;
    obs.events
        .iter()
        .find(|e| e.from == Mode::Left)
        .map(|e| e.t)
}

/// Newton shooting from the guess `(beta0, beta_dot0, t_end)`.
pub fn solve(pb: &OrbitProblem, guess: [f64; 3]) -> Result<OrbitSolution, OrbitError> {
    solve_with(pb, &pb.law(), guess)
}

/// [`solve`] for the loop closed by `law` (with `pb`'s model, impact law and tolerance).
pub fn solve_with(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    guess: [f64; 3],
) -> Result<OrbitSolution, OrbitError> {
    let mut z = Vector3::from(guess);
    let (mut r, mut j, mut fl) = residual(pb, law, &z)?;
    let fail = |res: f64| OrbitError::NoConvergence {
        beta0: guess[0],
        beta_dot0: guess[1],
        residual: res,
    };
    // The residual is computed to about 1e-12 (integration at rtol 1e-12, Jacobian of the
    // vector field by differences), so 1e-11 is converged; a Newton step below 1e-12 too.
    let mut converged = false;
    for _ in 0..30 {
        if r.norm() < 1e-11 {
            converged = true;
            break;
        }
        let dz = j.lu().solve(&(-r)).ok_or_else(|| fail(r.norm()))?;
        if dz.norm() < 1e-12 * (1.0 + z.norm()) {
            converged = r.norm() < 1e-9;
            break;
        }
        // Damped step: halve until the residual decreases (keep t_end positive).
        let mut lambda = 1.0;
        let mut accepted = false;
        for _ in 0..8 {
            let zt = z + dz * lambda;
            if zt[2] > 1e-3 {
                if let Ok((rt, jt, ft)) = residual(pb, law, &zt) {
                    if rt.norm() < r.norm() || rt.norm() < 1e-11 {
                        z = zt;
                        r = rt;
                        j = jt;
                        fl = ft;
                        accepted = true;
                        break;
                    }
                }
            }
            lambda *= 0.5;
        }
        if !accepted {
            // The residual cannot be decreased further: converged to round-off or stuck.
            converged = r.norm() < 1e-9;
            break;
        }
    }
    if !converged {
        return Err(fail(r.norm()));
    }
    finish(pb, law, &z, r.norm(), &fl)
}

/// Checks a converged solution with the hybrid simulator and fills in its characteristics.
fn finish(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    z: &Vector3<f64>,
    res: f64,
    fl: &Flow,
) -> Result<OrbitSolution, OrbitError> {
    let (beta0, beta_dot0, t_end) = (z[0], z[1], z[2]);
    let x0 = OrbitProblem::start(beta0, beta_dot0);
    let obs = simulate_first_tilt(pb, law, &x0, t_end + 0.01)?;
    let land = obs
        .events
        .iter()
        .position(|e| e.from == Mode::Left)
        .ok_or_else(|| OrbitError::Invalid("no landing within t_end".into()))?;
    let ev = obs.events[land];
    if (ev.t - t_end).abs() > 1e-7 {
        return Err(OrbitError::Invalid(format!(
            "the tilt lands at t = {} s, not at t_end = {t_end} s (alpha changes sign inside)",
            ev.t
        )));
    }
    match obs.events.get(land + 1) {
        Some(next) if next.to == Mode::Right && next.t == ev.t => {}
        _ => {
            return Err(OrbitError::Invalid(
                "after the landing the plate does not tilt right at once".into(),
            ))
        }
    }
    let mirrored = tilting_plant::mirror(&x0);
    let mismatch = (ev.x_after - mirrored).norm();
    let peak = obs
        .peak
        .ok_or_else(|| OrbitError::Invalid("no tilt extreme".into()))?;
    let multipliers = eigenvalues2(&monodromy(pb, fl));
    let stable = multipliers
        .iter()
        .all(|m| (m[0] * m[0] + m[1] * m[1]).sqrt() < 1.0);
    Ok(OrbitSolution {
        beta0,
        beta_dot0,
        t_end,
        period: 2.0 * t_end,
        max_tilt: peak.alpha,
        energy_avg: fl.energy_integral / t_end,
        multipliers,
        stable,
        residual: res,
        resimulated_mismatch: mismatch,
    })
}

/// The orbit with the smallest tilt among [`find_all`]'s: the `k = 0` orbit the paper starts
/// from, which the bifurcation sweep and the adaptation's `E_av` use.
pub fn smallest(pb: &OrbitProblem) -> Option<OrbitSolution> {
    find_all(pb).into_iter().next()
}

/// Finds every orbit reachable from a set of starts `beta0 = 0`, `beta_dot0` on a grid in
/// `[0.05, 3]` rad/s, with `t_end` guessed from the first landing; distinct solutions only,
/// sorted by maximal tilt.
pub fn find_all(pb: &OrbitProblem) -> Vec<OrbitSolution> {
    find_all_with(pb, &pb.law())
}

/// [`find_all`] for the loop closed by `law` (with `pb`'s model, impact law and tolerance):
/// the orbits of any [`PlannableLaw`].
pub fn find_all_with(pb: &OrbitProblem, law: &impl PlannableLaw) -> Vec<OrbitSolution> {
    let mut out: Vec<OrbitSolution> = Vec::new();
    for i in 0..60 {
        let bd0 = 0.05 * (i + 1) as f64;
        let Some(te) = landing_time_guess_with(pb, law, 0.0, bd0) else {
            continue;
        };
        if let Ok(s) = solve_with(pb, law, [0.0, bd0, te]) {
            let dup = out.iter().any(|o| {
                (o.beta0 - s.beta0).abs() < 1e-7
                    && (o.beta_dot0 - s.beta_dot0).abs() < 1e-7
                    && (o.t_end - s.t_end).abs() < 1e-7
            });
            if !dup {
                out.push(s);
            }
        }
    }
    out.sort_by(|a, b| a.max_tilt.total_cmp(&b.max_tilt));
    out
}
