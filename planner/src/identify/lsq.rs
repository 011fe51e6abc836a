//! The least squares on the regressor's columns ([`solve`]) and what its estimates tell about
//! which base parameters the recording sees: the rotor's share ([`rotor_unseen`],
//! [`plate_inertia_column`]) and the plate's inertia ([`plate_inertia_unseen`]).

use nalgebra::{DMatrix, DVector};

use super::{rows, IdentifyError, MAX_CONDITION};

/// Why `pi3` alone is not given when the rotor's share is lumped: the regressor's columns.
pub const ROTOR_LUMPED: &str = "pi3 alone is not separable from the rotor here: in the flat \
     rows the columns of pi3 and pi5 are both beta_ddot (identical), so flat motion fixes only \
     pi3 + pi5 = m_l l_c^2 + i_l + n_g^2 j_m, the arm's inertia about the joint; the columns \
     differ only while the plate tilts (the plate's row has pi3 (alpha_ddot + beta_ddot) + pi4 \
     beta_ddot, the arm's pi3 (alpha_ddot + beta_ddot) + pi4 alpha_ddot + pi5 beta_ddot), where \
     the rotor's share is below this recording's noise: the sum is estimated (pi3+pi5)";

/// Smallest ratio of an estimate of the rotor's share (`pi4`, `pi5`) to its standard error
/// for the share to count as seen.
pub const ROTOR_T_MIN: f64 = 3.0;

/// Why the rotor's share is not seen, if the fit cannot tell `pi4` or `pi5` from zero
/// (within [`ROTOR_T_MIN`] standard errors) or its shares fit no rotor (`j_m > 0`, `n_g > 0`).
pub(super) fn rotor_unseen(fit: &Fit, cols: &[usize], corr: f64) -> Option<String> {
    let at = |c: usize| cols.iter().position(|&k| k == c);
    let (i4, i5) = (at(3)?, at(4)?);
    let t = |i: usize| fit.x[i].abs() / (fit.se[i] * corr);
    let (p4, p5) = (fit.x[i4], fit.x[i5]);
    let (s4, s5) = (fit.se[i4] * corr, fit.se[i5] * corr);
    if t(i4) < ROTOR_T_MIN || t(i5) < ROTOR_T_MIN {
        return Some(format!(
            "the rotor's share is below this recording's noise (pi4 = {p4:.2e} +- {s4:.1e}, \
             pi5 = {p5:.2e} +- {s5:.1e} kg m^2): left out, its inertia lumped into pi3 (and \
             i_l); record larger tilts, or less noise, to see it"
        ));
    }
    // Seen above the noise but not a rotor: pi4 = (n_g - 1) j_m and pi5 = (n_g^2 - 1) j_m
    // with j_m > 0 and n_g > 0 need pi5 / pi4 > 1 and j_m = pi4^2 / (pi5 - 2 pi4) > 0. A fit
    // that breaks this has traded the rotor's columns against pi1 and pi3 (they are nearly
    // collinear when the tilts are few or alike), so it is redone without them rather than
    // keep a pi3 (and m_f) pulled by an impossible rotor.
    let physical = p5 / p4 > 1.0 && p5 - 2.0 * p4 != 0.0 && p4 * p4 / (p5 - 2.0 * p4) > 0.0;
    (!physical).then(|| {
        format!(
            "the rotor's share fitted no rotor (pi4 = {p4:.2e} +- {s4:.1e}, pi5 = {p5:.2e} +- \
             {s5:.1e} kg m^2 give no j_m > 0 and n_g > 0): left out, its inertia lumped into \
             pi3 (and i_l); record larger and more varied tilts to see it"
        )
    })
}

/// Why the rotor's columns are taken as the plate's inertia: `pi4` and `pi5` above the noise
/// but equal within [`ROTOR_T_MIN`] standard errors of their difference. `pi5 - pi4 =
/// n_g (n_g - 1) j_m` is zero for a direct drive (then both are) or for `n_g = 0`: an inertia
/// that turns with the plate and not with the arm, which is what `i_f` is (a plate inertia
/// `I` fits `pi4 = pi5 = -I` when `i_f` is held at 0).
pub(super) fn plate_inertia_column(fit: &Fit, cols: &[usize], corr: f64) -> Option<String> {
    let at = |c: usize| cols.iter().position(|&k| k == c);
    let (i4, i5) = (at(3)?, at(4)?);
    let (p4, p5) = (fit.x[i4], fit.x[i5]);
    let var = fit.cov[(i4, i4)] + fit.cov[(i5, i5)] - 2.0 * fit.cov[(i4, i5)];
    let sd = var.max(0.0).sqrt() * corr;
    ((p5 - p4).abs() < ROTOR_T_MIN * sd).then(|| {
        format!(
            "the rotor's share shows an inertia turning with the plate, not a rotor (pi4 = \
             {p4:.3e}, pi5 = {p5:.3e} kg m^2, equal within {ROTOR_T_MIN} standard errors of \
             their difference {sd:.1e}: n_g (n_g - 1) j_m = 0 with n_g != 1): estimated as the \
             plate's inertia i_f (pi8), the rotor lumped into pi3 (and i_l)"
        )
    })
}

/// Smallest ratio of the plate's inertia `i_f` (`pi8`) to its standard error for it to count
/// as seen: 1, its standard error must not exceed its value.
pub const PLATE_T_MIN: f64 = 1.0;

/// Why the plate's inertia is not seen, if the fit's `i_f` has a standard error above its
/// value ([`PLATE_T_MIN`]) or is negative (no plate has that: a negative estimate is noise, or
/// the model's other terms traded against it).
pub(super) fn plate_inertia_unseen(fit: &Fit, cols: &[usize], corr: f64) -> Option<String> {
    let i = cols.iter().position(|&k| k == 7)?;
    let (v, s) = (fit.x[i], fit.se[i] * corr);
    if v <= 0.0 || v.abs() < PLATE_T_MIN * s {
        return Some(format!(
            "the plate's inertia is not seen in this recording's tilts (i_f = {v:.2e} +- \
             {s:.1e} kg m^2: its standard error exceeds its value{}): left out, the prior's \
             i_f kept; record more and larger tilts to see it",
            if v < 0.0 { ", or it is negative" } else { "" }
        ));
    }
    None
}

pub(super) struct Fit {
    pub(super) x: Vec<f64>,
    pub(super) se: Vec<f64>,
    /// Covariance of the estimates (the residual variance's, uncorrected).
    pub(super) cov: DMatrix<f64>,
    pub(super) condition: f64,
    pub(super) residual_rms: f64,
}

/// Least squares on the columns `cols`, scaled to unit norm (the condition number is the
/// scaled one); refused when singular, naming the weakest direction. Without the plate's
/// inertia's column (7), its term with `i_f` (the prior's) is moved to the right-hand side.
pub(super) fn solve(
    r: &rows::Rows,
    cols: &[usize],
    names: &[String],
    i_f: f64,
) -> Result<Fit, IdentifyError> {
    let (n, p) = (r.y.len(), cols.len());
    let mut a = DMatrix::from_fn(n, p, |i, j| r.y[i][cols[j]]);
    let fixed = if cols.contains(&7) { 0.0 } else { i_f };
    let b = DVector::from_fn(n, |i, _| r.rhs[i] - fixed * r.y[i][7]);
    let scale: Vec<f64> = (0..p).map(|j| a.column(j).norm()).collect();
    for (j, s) in scale.iter().enumerate() {
        if *s > 0.0 {
            a.column_mut(j).scale_mut(1.0 / s);
        }
    }
    let svd = a.clone().svd(true, true);
    let sv = &svd.singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    if condition.is_nan() || condition > MAX_CONDITION || scale.contains(&0.0) {
        let weak = sv.imin();
        let v_t = svd.v_t.as_ref().expect("v_t computed");
        let dir: Vec<usize> = (0..p)
            .filter(|&j| v_t[(weak, j)].abs() > 0.2 || scale[j] == 0.0)
            .collect();
        return Err(IdentifyError::Singular {
            condition,
            direction: dir
                .iter()
                .map(|&j| names[j].as_str())
                .collect::<Vec<_>>()
                .join(", "),
            advice: advice(&dir.iter().map(|&j| cols[j]).collect::<Vec<_>>()),
        });
    }
    let xs = svd.solve(&b, 0.0).expect("u and v_t computed");
    let resid = &b - &a * &xs;
    let rss = resid.norm_squared();
    let dof = (n - p).max(1) as f64;
    let sigma2 = rss / dof;
    let v_t = svd.v_t.as_ref().expect("v_t computed");
    let x = (0..p).map(|j| xs[j] / scale[j]).collect();
    let cov = DMatrix::from_fn(p, p, |i, j| {
        let c: f64 = (0..p)
            .map(|k| v_t[(k, i)] * v_t[(k, j)] / (sv[k] * sv[k]))
            .sum();
        sigma2 * c / (scale[i] * scale[j])
    });
    let se = (0..p).map(|j| cov[(j, j)].max(0.0).sqrt()).collect();
    Ok(Fit {
        x,
        se,
        cov,
        condition,
        residual_rms: (rss / n as f64).sqrt(),
    })
}

/// What to record to excite the base parameters `idx`.
fn advice(idx: &[usize]) -> String {
    let mut a: Vec<&str> = idx
        .iter()
        .map(|&i| match i {
            0 => "tilts with varying amplitude (the plate's equation carries m_f + m_l)",
            1 | 2 => "arm motion with varying acceleration over a range of angles",
            3 | 4 => "arm accelerations both while flat and while tilted (the rotor's share)",
            5 => "the arm moving at a range of speeds (viscous friction)",
            7 => "tilts with varying plate acceleration (the plate's inertia i_f)",
            _ => "the arm moving both ways (Coulomb friction is an offset of the sign of beta_dot)",
        })
        .collect();
    a.dedup();
    format!("record {}", a.join("; "))
}
