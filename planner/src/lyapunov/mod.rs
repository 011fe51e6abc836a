//! The largest Lyapunov exponent of the tilting loop (issue 19, item 3).
//!
//! The loop's motion is a sequence of tilts: each left tilt (or mirrored right tilt) starts at
//! `alpha = alpha_dot = 0` with the arm at `(pi/2 + beta0, beta_dot0)`, lands, and the impact
//! and the mirror give the next start. So the flow's exponents other than its trivial zero (along
//! the motion) are those of the mirrored half-period map `P` on `(beta0, beta_dot0)`, divided
//! by the time a tilt takes. The variational equations of the tilt's flow are carried through
//! each landing with its saltation (the event time's sensitivity `d tau = -d alpha /
//! alpha_dot`), the impact map's Jacobian and the mirror: exactly [`orbit`](crate::orbit)'s
//! monodromy, here along an arbitrary motion. Benettin's method renormalises one tangent vector
//! after each tilt:
//!
//! `lambda = sum_n ln |J_n v_n| / sum_n t_n` (1/s),
//!
//! which on a stable period-`m` orbit is `ln |mu_max| / T` (`T` the time of its `m` tilts).
//! [`largest_fd`] measures the same from two nearby trajectories of the hybrid simulator.
//!
//! A landing after which the plate does not tilt back at once (it rests flat for a while, or
//! tilts the same way again) leaves the tilt map: the exponent is then reported as not defined.
//!
//! [`sampled`]: the same for the loop sampled at a control period (the torque held between
//! samples), where the hold adds a phase against the sample grid.

pub mod sampled;

use crate::orbit::{self, Flow, OrbitProblem};
use nalgebra::{Matrix2, Matrix4, SVector, Vector2, Vector4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;
use tilting_controller::PlannableLaw;
use tilting_plant::dynamics::support_margins;
use tilting_plant::ode::{Dop853, Tolerance};
use tilting_plant::{Mode, Params, State};

/// Tolerance of the tilt map's integration with its variational equations (the vector field's
/// Jacobian by central differences carries ~1e-11 noise, see `orbit`).
const TOL: Tolerance = Tolerance {
    rtol: 1e-10,
    atol: 1e-12,
};

/// Tolerance of the exponent's runs: an average over hundreds of tilts of a motion that, when
/// chaotic, forgets its start within dozens, needs no more (checked against [`TOL`] and the
/// simulator's two trajectories in the tests).
const FAST_TOL: Tolerance = Tolerance {
    rtol: 1e-9,
    atol: 1e-11,
};

/// One tilt of the map: the next start `(beta0, beta_dot0)`, the tilt's duration and the map's
/// Jacobian on `(beta0, beta_dot0)`.
#[derive(Debug, Clone, Copy)]
pub struct TiltStep {
    /// Next start `(beta0, beta_dot0)` (rad, rad/s), mirrored.
    pub next: Vector2<f64>,
    /// Duration of the tilt (s).
    pub t: f64,
    /// `d next / d start`.
    pub jac: Matrix2<f64>,
}

/// The state with `Phi` (column-major), as in `orbit`.
type Aug = SVector<f64, 20>;

/// The Jacobian of the closed loop's vector field at `x` by central differences, `h ~
/// eps^(1/3)` (as `orbit`'s variational equations).
fn field_jacobian(p: &Params, law: &impl PlannableLaw, x: &State) -> Matrix4<f64> {
    let mut jac = Matrix4::zeros();
    for j in 0..4 {
        let h = 6e-6 * (1.0 + x[j].abs());
        let (mut xp, mut xm) = (*x, *x);
        xp[j] += h;
        xm[j] -= h;
        let col = (orbit::closed_loop(p, law, &xp) - orbit::closed_loop(p, law, &xm)) / (2.0 * h);
        jac.set_column(j, &col);
    }
    jac
}

/// Integrates `y' = f(y)` (the first 4 components the tilt's state) from `y` until the tilt
/// lands (`alpha` back to 0 after leaving it), located on the dense output to 1e-14 s: the
/// landing time and `y` there.
fn land<const N: usize>(
    f: &mut impl FnMut(f64, &SVector<f64, N>) -> SVector<f64, N>,
    mut y: SVector<f64, N>,
    tol: Tolerance,
) -> Result<(f64, SVector<f64, N>), String> {
    let mut st = Dop853::new(tol);
    let (mut t, mut f0) = (0.0, f(0.0, &y));
    let mut lifted = false;
    loop {
        let s = st.step(f, t, &y, &f0, 5.0).map_err(|e| e.to_string())?;
        lifted |= s.y1[0] > 0.0;
        if lifted && s.y1[0] <= 0.0 {
            let d = st.dense(f, &s);
            let (mut lo, mut hi) = (s.t0, s.t1);
            // Bisection on the dense output's alpha (positive at lo, not at hi).
            while hi - lo > 1e-14 * (1.0 + hi) {
                let mid = 0.5 * (lo + hi);
                if d.eval(mid)[0] > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return Ok((hi, d.eval(hi)));
        }
        if s.y1[0].abs() > FRAC_PI_2 || s.t1 >= 5.0 {
            return Err(format!(
                "the tilt does not land (alpha = {:.3} rad at t = {:.3} s)",
                s.y1[0], s.t1
            ));
        }
        t = s.t1;
        y = s.y1;
        f0 = *s.f1();
    }
}

/// The impact at the landing state `x` (time `te`) and the mirror: the next start, or an error
/// when the plate does not tilt back at once (the simulator's rule: flat, it tilts right when
/// the right support margin is negative and the left one is not).
fn next_start(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    te: f64,
    x: &State,
) -> Result<Vector2<f64>, String> {
    let mut xm = *x;
    xm[0] = 0.0;
    let after = pb.impact.apply(&pb.params, Mode::Left, &xm);
    let tau = law.torque(te, Mode::Flat, &after);
    let (left, right) = support_margins(&pb.params, &after, tau);
    if left < 0.0 || right >= 0.0 {
        return Err(format!(
            "after the landing at t = {te:.4} s the plate does not tilt back at once (support margins {left:.3e}, {right:.3e} N m)"
        ));
    }
    Ok(Vector2::new(FRAC_PI_2 - after[1], -after[3]))
}

/// The map's Jacobian applied to the start deviations in the columns 1 and 3 of `phi` (the
/// sensitivities of the landing state), through the saltation, the impact and the mirror:
/// `orbit`'s monodromy.
fn through_landing(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    x: State,
    phi: Matrix4<f64>,
) -> Matrix2<f64> {
    let fl = Flow {
        x,
        phi,
        f: orbit::closed_loop(&pb.params, law, &x),
        energy_integral: 0.0,
    };
    orbit::monodromy(pb, &fl)
}

/// One tilt of the map from the start `(beta0, beta_dot0)` with its full Jacobian (the
/// variational equations of the tilt's flow, then the landing's saltation, the impact map's
/// Jacobian and the mirror). Errors: the tilt does not land within 5 s, leaves the tilting
/// range, or the plate does not tilt back at once after the impact.
pub fn tilt(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    start: Vector2<f64>,
) -> Result<TiltStep, String> {
    let p = pb.params;
    let mut f = |_t: f64, y: &Aug| {
        let x: State = y.fixed_rows::<4>(0).into_owned();
        let phi = Matrix4::from_column_slice(&y.as_slice()[4..20]);
        let mut d = Aug::zeros();
        d.fixed_rows_mut::<4>(0)
            .copy_from(&orbit::closed_loop(&p, law, &x));
        d.as_mut_slice()[4..20].copy_from_slice((field_jacobian(&p, law, &x) * phi).as_slice());
        d
    };
    let mut y = Aug::zeros();
    y.fixed_rows_mut::<4>(0)
        .copy_from(&OrbitProblem::start(start[0], start[1]));
    for i in 0..4 {
        y[4 + 5 * i] = 1.0;
    }
    let (te, ye) = land(&mut f, y, TOL)?;
    let x: State = ye.fixed_rows::<4>(0).into_owned();
    let jac = through_landing(
        pb,
        law,
        x,
        Matrix4::from_column_slice(&ye.as_slice()[4..20]),
    );
    Ok(TiltStep {
        next: next_start(pb, law, te, &x)?,
        t: te,
        jac,
    })
}

/// One tilt carrying one tangent vector `v` (a deviation of the start `(beta0, beta_dot0)`):
/// the directional derivative of the vector field by central differences along the tangent
/// (two evaluations instead of eight). Returns the step with `jac` holding `J v` in its first
/// column.
fn tilt_tangent(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    start: Vector2<f64>,
    v: Vector2<f64>,
) -> Result<TiltStep, String> {
    let p = pb.params;
    let mut f = |_t: f64, y: &SVector<f64, 8>| {
        let x: State = y.fixed_rows::<4>(0).into_owned();
        let dx: Vector4<f64> = y.fixed_rows::<4>(4).into_owned();
        let n = dx.norm().max(1e-300);
        let h = 6e-6 * (1.0 + x.norm()) / n;
        let jv = (orbit::closed_loop(&p, law, &(x + dx * h))
            - orbit::closed_loop(&p, law, &(x - dx * h)))
            / (2.0 * h);
        let fx = orbit::closed_loop(&p, law, &x);
        SVector::<f64, 8>::from_iterator(fx.iter().chain(jv.iter()).copied())
    };
    let x0 = OrbitProblem::start(start[0], start[1]);
    let y = SVector::<f64, 8>::from_iterator(x0.iter().copied().chain([0.0, v[0], 0.0, v[1]]));
    let (te, ye) = land(&mut f, y, FAST_TOL)?;
    let x: State = ye.fixed_rows::<4>(0).into_owned();
    let mut phi = Matrix4::zeros();
    phi.set_column(1, &ye.fixed_rows::<4>(4));
    Ok(TiltStep {
        next: next_start(pb, law, te, &x)?,
        t: te,
        jac: through_landing(pb, law, x, phi),
    })
}

/// One tilt without sensitivities (the transient).
fn tilt_plain(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    start: Vector2<f64>,
) -> Result<Vector2<f64>, String> {
    let p = pb.params;
    let mut f = |_t: f64, x: &State| orbit::closed_loop(&p, law, x);
    let (te, x) = land(&mut f, OrbitProblem::start(start[0], start[1]), FAST_TOL)?;
    next_start(pb, law, te, &x)
}

/// The exponent at one parameter value.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Exponent {
    /// Parameter value.
    pub p: f64,
    /// Largest Lyapunov exponent (1/s), or `None` when the motion leaves the tilt map.
    pub lambda: Option<f64>,
    /// The same per tilt (dimensionless), `None` likewise.
    pub per_tilt: Option<f64>,
    /// Tilts averaged over.
    pub tilts: usize,
    /// Why the exponent is not defined, if it is not.
    pub fault: Option<String>,
}

/// Benettin's largest exponent of the tilt map from `start`: `transient` tilts discarded, then
/// `tilts` averaged. Returns `(lambda (1/s), per tilt)`.
pub fn largest(
    pb: &OrbitProblem,
    start: Vector2<f64>,
    transient: usize,
    tilts: usize,
) -> Result<(f64, f64), String> {
    largest_with(pb, &pb.law(), start, transient, tilts)
}

/// [`largest`] of the loop closed by `law` (with `pb`'s model and impact law): the exponent
/// of any [`PlannableLaw`].
pub fn largest_with(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    start: Vector2<f64>,
    transient: usize,
    tilts: usize,
) -> Result<(f64, f64), String> {
    let mut z = start;
    for _ in 0..transient {
        z = tilt_plain(pb, law, z)?;
    }
    let mut v = Vector2::new(1.0, 1.0).normalize();
    let (mut sum, mut time) = (0.0, 0.0);
    for _ in 0..tilts {
        let s = tilt_tangent(pb, law, z, v)?;
        v = s.jac.column(0).into_owned();
        let n = v.norm();
        sum += n.ln();
        v /= n;
        time += s.t;
        z = s.next;
    }
    Ok((sum / time, sum / tilts as f64))
}

/// One tilt of the hybrid simulator: the next mirrored start and the tilt's duration.
fn simulated_tilt(pb: &OrbitProblem, z: Vector2<f64>) -> Result<(Vector2<f64>, f64), String> {
    let (t, after) = orbit::first_landing(pb, &OrbitProblem::start(z[0], z[1]), 5.0)
        .ok_or("the simulated tilt does not land and tilt back at once")?;
    Ok((Vector2::new(FRAC_PI_2 - after[1], -after[3]), t))
}

/// The same exponent from two nearby trajectories of the hybrid simulator (no variational
/// equations): after each tilt the distance `d` of the neighbour (started `delta` away) is
/// measured and reset to `delta` along the same direction. Returns `(lambda (1/s), per tilt)`.
pub fn largest_fd(
    pb: &OrbitProblem,
    start: Vector2<f64>,
    transient: usize,
    tilts: usize,
    delta: f64,
) -> Result<(f64, f64), String> {
    let mut z = start;
    for _ in 0..transient {
        z = simulated_tilt(pb, z)?.0;
    }
    let mut w = z + Vector2::new(1.0, 1.0).normalize() * delta;
    let (mut sum, mut time) = (0.0, 0.0);
    for _ in 0..tilts {
        let (zn, t) = simulated_tilt(pb, z)?;
        let (wn, _) = simulated_tilt(pb, w)?;
        let d = wn - zn;
        sum += (d.norm() / delta).ln();
        time += t;
        z = zn;
        w = zn + d * (delta / d.norm());
    }
    Ok((sum / time, sum / tilts as f64))
}

/// The exponent over the values `ps` of a parameter set by `at` (on all cores), each from
/// the tilt start `(beta0, beta_dot0)` (rad, rad/s); `tick` after each value.
pub fn curve(
    ps: &[f64],
    at: &(dyn Fn(f64) -> Result<OrbitProblem, String> + Sync),
    start: [f64; 2],
    transient: usize,
    tilts: usize,
    tick: &(dyn Fn() + Sync),
) -> Vec<Exponent> {
    ps.par_iter()
        .map(|&p| {
            let r = at(p).and_then(|pb| largest(&pb, Vector2::from(start), transient, tilts));
            tick();
            match r {
                Ok((l, n)) => Exponent {
                    p,
                    lambda: Some(l),
                    per_tilt: Some(n),
                    tilts,
                    fault: None,
                },
                Err(e) => Exponent {
                    p,
                    lambda: None,
                    per_tilt: None,
                    tilts,
                    fault: Some(e),
                },
            }
        })
        .collect()
}
