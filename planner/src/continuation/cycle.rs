//! The period-`n` boundary value problem: `n` consecutive tilts of the mirrored half-period map
//! `P` (approach 2's shooting, multiple-shooting form), its residual and Jacobian, and the
//! monodromy of the cycle.
//!
//! The unknowns are `z = (beta0_0, beta_dot0_0, t_0, ..., beta0_{n-1}, beta_dot0_{n-1},
//! t_{n-1})`: the start of each left tilt (the mirrored start of the tilts that run right) and
//! its duration. Tilt `i` lands with the impact map and must start tilt `i + 1 (mod n)` in the
//! mirrored state: `alpha(t_i) = 0`, `beta(t_i) = pi/2 - beta0_{i+1}`, `beta_dot+(t_i) =
//! -beta_dot0_{i+1}`, exactly [`orbit`](crate::orbit)'s conditions for `n = 1`.

use crate::orbit::{self, Flow, OrbitProblem};
use nalgebra::{DMatrix, DVector, Matrix2, Vector4};
use std::f64::consts::FRAC_PI_2;
use tilting_controller::PlannableLaw;
use tilting_plant::{Mode, State};

/// Residual, Jacobian `dR/dz` and the flows of the `n` tilts (with sensitivities).
pub(crate) struct Eval {
    /// `R(z)`, length `3 n`.
    pub r: DVector<f64>,
    /// `dR/dz`, `3 n x 3 n`.
    pub jac: DMatrix<f64>,
    /// The tilts' flows at their landing.
    pub flows: Vec<Flow>,
}

/// Start state of tilt `i` of `z`.
pub(crate) fn start(z: &DVector<f64>, i: usize) -> State {
    OrbitProblem::start(z[3 * i], z[3 * i + 1])
}

/// The residual of tilt `i`'s landing against the next start, from its landing state `x`.
fn landing_residual(pb: &OrbitProblem, z: &DVector<f64>, i: usize, x: &Vector4<f64>) -> [f64; 3] {
    let n = z.len() / 3;
    let j = (i + 1) % n;
    let c = pb.impact.coefficient(&pb.params, Mode::Left, x[1]);
    [
        x[0],
        x[1] - (FRAC_PI_2 - z[3 * j]),
        x[3] + c * x[2] + z[3 * j + 1],
    ]
}

/// Checks the shape of `z` and that every duration is positive.
fn check(z: &DVector<f64>) -> Result<(), orbit::OrbitError> {
    if z.is_empty() || !z.len().is_multiple_of(3) {
        return Err(orbit::OrbitError::Invalid(format!(
            "a cycle has 3 unknowns per tilt, not {}",
            z.len()
        )));
    }
    if (0..z.len() / 3).any(|i| z[3 * i + 2] <= 1e-3) {
        return Err(orbit::OrbitError::Integration(
            "a tilt duration fell below 1 ms".into(),
        ));
    }
    Ok(())
}

/// The residual alone (no sensitivities), for the parameter derivative.
pub(crate) fn residual(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    z: &DVector<f64>,
) -> Result<DVector<f64>, orbit::OrbitError> {
    check(z)?;
    let n = z.len() / 3;
    let mut r = DVector::zeros(3 * n);
    for i in 0..n {
        let fl = orbit::flow(pb, law, &start(z, i), z[3 * i + 2], false)?;
        let ri = landing_residual(pb, z, i, &fl.x);
        r.rows_mut(3 * i, 3).copy_from_slice(&ri);
    }
    Ok(r)
}

/// Residual and exact Jacobian (from the variational equations) of the period-`n` BVP.
pub(crate) fn evaluate(
    pb: &OrbitProblem,
    law: &impl PlannableLaw,
    z: &DVector<f64>,
) -> Result<Eval, orbit::OrbitError> {
    check(z)?;
    let n = z.len() / 3;
    let mut r = DVector::zeros(3 * n);
    let mut jac = DMatrix::zeros(3 * n, 3 * n);
    let mut flows = Vec::with_capacity(n);
    for i in 0..n {
        let fl = orbit::flow(pb, law, &start(z, i), z[3 * i + 2], true)?;
        let x = fl.x;
        r.rows_mut(3 * i, 3)
            .copy_from_slice(&landing_residual(pb, z, i, &x));
        let c = pb.impact.coefficient(&pb.params, Mode::Left, x[1]);
        // Gradient of the post-impact beta_dot with respect to the pre-impact state.
        let grad_g = Vector4::new(0.0, orbit::impact_slope(pb, x[1]) * x[2], c, 1.0);
        let phi = &fl.phi;
        let (row, col) = (3 * i, 3 * i);
        jac[(row, col)] = phi[(0, 1)];
        jac[(row, col + 1)] = phi[(0, 3)];
        jac[(row, col + 2)] = fl.f[0];
        jac[(row + 1, col)] = phi[(1, 1)];
        jac[(row + 1, col + 1)] = phi[(1, 3)];
        jac[(row + 1, col + 2)] = fl.f[1];
        jac[(row + 2, col)] = grad_g.dot(&phi.column(1));
        jac[(row + 2, col + 1)] = grad_g.dot(&phi.column(3));
        jac[(row + 2, col + 2)] = grad_g.dot(&fl.f);
        let next = 3 * ((i + 1) % n);
        jac[(row + 1, next)] += 1.0;
        jac[(row + 2, next + 1)] += 1.0;
        flows.push(fl);
    }
    Ok(Eval { r, jac, flows })
}

/// The Jacobians `P_i` (2x2, on `(beta, beta_dot)`) of the tilts' mirrored half-period maps.
pub(crate) fn tilt_maps(pb: &OrbitProblem, flows: &[Flow]) -> Vec<Matrix2<f64>> {
    flows.iter().map(|fl| orbit::monodromy(pb, fl)).collect()
}

/// The cycle's monodromy `P_{n-1} ... P_0` (at the start of tilt 0).
pub(crate) fn monodromy(maps: &[Matrix2<f64>]) -> Matrix2<f64> {
    maps.iter().fold(Matrix2::identity(), |m, p| p * m)
}

/// The derivative of the landing time of a tilt with respect to its start `(beta0, beta_dot0)`
/// (the saltation's time part, `d tau = -d alpha / alpha_dot`).
pub(crate) fn landing_time_gradient(fl: &Flow) -> [f64; 2] {
    [-fl.phi[(0, 1)] / fl.f[0], -fl.phi[(0, 3)] / fl.f[0]]
}

/// The cycle `z` repeated twice (the period-`2n` problem's trivial solution).
pub(crate) fn doubled(z: &DVector<f64>) -> DVector<f64> {
    let n = z.len();
    DVector::from_fn(2 * n, |i, _| z[i % n])
}

/// The maximal `|alpha|` of each tilt of the cycle (rad), by the hybrid simulator.
pub(crate) fn peaks(pb: &OrbitProblem, z: &DVector<f64>) -> Vec<f64> {
    (0..z.len() / 3)
        .map(|i| {
            orbit::first_tilt_peak(pb, &start(z, i), z[3 * i + 2] + 0.01).map_or(f64::NAN, f64::abs)
        })
        .collect()
}

/// Re-simulates each tilt of the cycle with the hybrid simulator and returns the largest
/// mismatch between its post-impact state and the mirrored start of the next tilt (with the
/// landing time's error), an independent check of a solution: `None` when a tilt does not land
/// and tilt back at once.
pub(crate) fn resimulated_mismatch(pb: &OrbitProblem, z: &DVector<f64>) -> Option<f64> {
    let n = z.len() / 3;
    let mut worst = 0.0f64;
    for i in 0..n {
        let (t, x_after) = orbit::first_landing(pb, &start(z, i), z[3 * i + 2] + 0.01)?;
        let next = tilting_plant::mirror(&start(z, (i + 1) % n));
        worst = worst
            .max((x_after - next).norm())
            .max((t - z[3 * i + 2]).abs());
    }
    Some(worst)
}
