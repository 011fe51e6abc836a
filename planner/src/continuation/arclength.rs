//! Pseudo-arclength continuation of the period-`n` BVP in one parameter: Keller's predictor
//! along the tangent and a Newton corrector on the hyperplane orthogonal to it, with the
//! parameter derivative of the residual by central differences.
//!
//! The unknown is `y = (z, p / s)`: the cycle's `3 n` unknowns and the parameter over its scale
//! `s = max(|p0|, 1)`, so that one unit of arclength moves the orbit and the parameter alike.

use super::cycle;
use super::param::Param;
use crate::orbit::{Flow, OrbitError, OrbitProblem};
use nalgebra::{DMatrix, DVector, Matrix2};

/// A residual below this 2-norm is converged: each tilt's residual is integrated at rtol 1e-12,
/// so about 1e-12 per component is its noise floor.
pub(crate) const CONVERGED: f64 = 1e-11;
/// Accepted when Newton stagnates (the noise floor of a long cycle): the bound.
pub(crate) const ACCEPTED: f64 = 1e-10;

/// The continuation problem: the base orbit problem, the parameter and its scale.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Continuation {
    pub base: OrbitProblem,
    pub param: Param,
    pub scale: f64,
}

/// A corrected point: `y`, its residual norm, the flows and Newton's iteration count.
pub(crate) struct Solved {
    pub y: DVector<f64>,
    pub residual: f64,
    pub flows: Vec<Flow>,
    pub iterations: usize,
    /// The tilts' Jacobians on `(beta, beta_dot)`.
    pub maps: Vec<Matrix2<f64>>,
}

impl Continuation {
    /// The parameter value of `y`.
    pub fn p(&self, y: &DVector<f64>) -> f64 {
        y[y.len() - 1] * self.scale
    }

    /// The problem at the parameter of `y`.
    pub fn problem(&self, y: &DVector<f64>) -> Result<OrbitProblem, OrbitError> {
        self.param
            .set(&self.base, self.p(y))
            .map_err(OrbitError::Invalid)
    }

    /// `y` from a cycle `z` and a parameter value `p`.
    pub fn join(&self, z: &DVector<f64>, p: f64) -> DVector<f64> {
        let mut y = DVector::zeros(z.len() + 1);
        y.rows_mut(0, z.len()).copy_from(z);
        y[z.len()] = p / self.scale;
        y
    }

    /// Residual `R(y)` (length `3 n`), its Jacobian `[dR/dz, dR/d(p/s)]` and the flows.
    #[allow(clippy::type_complexity)]
    fn eval(
        &self,
        y: &DVector<f64>,
    ) -> Result<(DVector<f64>, DMatrix<f64>, Vec<Flow>), OrbitError> {
        let m = y.len() - 1;
        let z = y.rows(0, m).into_owned();
        let pb = self.problem(y)?;
        let e = cycle::evaluate(&pb, &pb.law(), &z)?;
        let mut jac = DMatrix::zeros(m, m + 1);
        jac.view_mut((0, 0), (m, m)).copy_from(&e.jac);
        // dR/dp by central differences: the residual's noise (~1e-12) over 2h gives ~1e-10
        // relative error in the column, far below what Newton or the tangent needs.
        let p = self.p(y);
        let h = 1e-5 * (1.0 + p.abs());
        let side = |v: f64| -> Result<DVector<f64>, OrbitError> {
            let q = self.param.set(&self.base, v).map_err(OrbitError::Invalid)?;
            cycle::residual(&q, &q.law(), &z)
        };
        let (lo, hi) = if self.param.allows(p - h).0 {
            (p - h, p + h)
        } else {
            (p, p + h)
        };
        let dr = (side(hi)? - side(lo)?) / (hi - lo) * self.scale;
        jac.set_column(m, &dr);
        Ok((e.r, jac, e.flows))
    }

    /// The unit tangent at a solved `y` whose dot product with `dir` is positive.
    pub fn tangent(
        &self,
        y: &DVector<f64>,
        dir: &DVector<f64>,
    ) -> Result<DVector<f64>, OrbitError> {
        let (_, jac, _) = self.eval(y)?;
        tangent_of(&jac, dir)
    }

    /// Newton on `R(y) = 0`, `t . (y - y_pred) = 0` from `y_pred`.
    pub fn correct(&self, y_pred: &DVector<f64>, t: &DVector<f64>) -> Result<Solved, OrbitError> {
        let m = y_pred.len() - 1;
        let mut y = y_pred.clone();
        let mut last = f64::INFINITY;
        for it in 0..12 {
            let (r, jac, flows) = self.eval(&y)?;
            let norm = r.norm();
            let done = norm < CONVERGED || (norm < ACCEPTED && norm >= 0.5 * last);
            if done {
                let pb = self.problem(&y)?;
                let maps = cycle::tilt_maps(&pb, &flows);
                return Ok(Solved {
                    y,
                    residual: norm,
                    flows,
                    iterations: it,
                    maps,
                });
            }
            if !norm.is_finite() || (it > 3 && norm > last) {
                break;
            }
            last = norm;
            let mut a = DMatrix::zeros(m + 1, m + 1);
            a.view_mut((0, 0), (m, m + 1)).copy_from(&jac);
            a.row_mut(m).copy_from(&t.transpose());
            let mut rhs = DVector::zeros(m + 1);
            rhs.rows_mut(0, m).copy_from(&(-&r));
            rhs[m] = -t.dot(&(&y - y_pred));
            let dy = a
                .lu()
                .solve(&rhs)
                .ok_or_else(|| OrbitError::Invalid("singular continuation Jacobian".into()))?;
            y += dy;
        }
        Err(OrbitError::NoConvergence {
            beta0: y[0],
            beta_dot0: y[1],
            residual: last,
        })
    }
}

/// The unit null vector of the `m x (m + 1)` Jacobian, oriented along `dir`.
pub(crate) fn tangent_of(
    jac: &DMatrix<f64>,
    dir: &DVector<f64>,
) -> Result<DVector<f64>, OrbitError> {
    let m = jac.nrows();
    let mut a = DMatrix::zeros(m + 1, m + 1);
    a.view_mut((0, 0), (m, m + 1)).copy_from(jac);
    a.row_mut(m).copy_from(&dir.transpose());
    let mut rhs = DVector::zeros(m + 1);
    rhs[m] = 1.0;
    let t = a
        .lu()
        .solve(&rhs)
        .ok_or_else(|| OrbitError::Invalid("singular tangent system".into()))?;
    let t = t.normalize();
    Ok(if t.dot(dir) < 0.0 { -t } else { t })
}

/// The test functions of a 2x2 monodromy `M`: flip `det(I + M)`, fold `det(I - M)`,
/// Neimark–Sacker `det(M) - 1` (a crossing only while the pair is complex).
pub(crate) fn tests(m: &Matrix2<f64>) -> [f64; 3] {
    let (tr, det) = (m.trace(), m.determinant());
    [1.0 + tr + det, 1.0 - tr + det, det - 1.0]
}

/// The cycle's monodromy of a solved point.
pub(crate) fn monodromy_of(s: &Solved) -> Matrix2<f64> {
    cycle::monodromy(&s.maps)
}
