//! From the base parameters to a `--params` file, with the prior's `m_l`, `l`, `f`, `g`.

use super::N_BASE;
use tilting_plant::Params;

/// The always-true limits of what motion can tell (docs/model.md).
const STRUCTURAL: [&str; 4] = [
    "m_l, l_c and i_l separately: only m_l l_c and m_l l_c^2 + i_l enter the dynamics (m_l is \
     the prior's, weighed; l_c and i_l follow)",
    "m_f apart from m_l: only their sum m_f + m_l enters (m_f = sum - the prior's m_l)",
    "l: it only draws the arm (the prior's)",
    "f and g: the geometry and gravity are measured, not identified (the prior's)",
];

/// The parameters that move as `value` (and `sum35`, `pi3 + pi5` from flat motion alone) say,
/// with `(b_v, tau_c)` already checked; and what the data cannot fix. Out-of-range results
/// (a prior `m_l` that does not fit) are clamped with a warning.
pub(super) fn params(
    prior: &Params,
    value: &[Option<f64>; N_BASE],
    sum35: Option<f64>,
    friction: (f64, f64),
    warnings: &mut Vec<String>,
) -> (Params, Vec<String>) {
    let mut out: Vec<String> = STRUCTURAL.iter().map(|s| s.to_string()).collect();
    let mut p = Params {
        b_v: friction.0,
        tau_c: friction.1,
        ..*prior
    };
    let m_l = prior.m_l;
    if let Some(pi2) = value[1] {
        let lc = pi2 / m_l;
        // A centre of mass at the tip estimated a hair beyond it is the tip.
        if lc > 0.0 && lc <= p.l * (1.0 + 1e-4) {
            p.l_c = Some(lc.min(p.l));
        } else {
            warnings.push(format!(
                "l_c = m_l l_c / m_l = {lc:.4} m is outside (0, l = {}]: the prior m_l = {m_l} \
                 does not fit; l_c kept at the prior's",
                p.l
            ));
        }
    }
    if let Some(pi1) = value[0] {
        let m_f = pi1 - m_l;
        if m_f > 0.0 {
            p.m_f = m_f;
        } else {
            warnings.push(format!(
                "m_f = (m_f + m_l) - m_l = {m_f:.4} kg is not positive: the prior m_l = {m_l} \
                 is too large; m_f kept at the prior's"
            ));
        }
    }
    // The rotor: pi5 / pi4 = n_g + 1 when the rotor is seen (pi4 != 0).
    let (j_m, n_g) = match (value[3], value[4]) {
        (Some(p4), Some(p5)) if p4.abs() > 1e-9 * value[2].unwrap_or(1.0).abs() => {
            let n = p5 / p4 - 1.0;
            if n > 0.0 && (n - 1.0).abs() > 1e-6 && p4 / (n - 1.0) > 0.0 {
                (p4 / (n - 1.0), n)
            } else {
                warnings.push(format!(
                    "the rotor (pi4 = {p4:.3e}, pi5 = {p5:.3e}) gives no positive j_m and n_g: \
                     its inertia is left in i_l"
                ));
                (0.0, prior.n_g)
            }
        }
        _ => {
            out.push(
                "j_m and n_g: not separable from the arm's inertia in this recording. Flat, the \
                 columns of pi3 and pi5 are the same (beta_ddot): only pi3 + pi5 = m_l l_c^2 + \
                 i_l + n_g^2 j_m enters; tilted, pi4 and pi5 have their own columns, but the \
                 rotor's share is not seen (no tilts, a direct drive n_g = 1, or below the \
                 noise). The identified sum (pi3+pi5, the arm's inertia about the joint) is \
                 written as i_l with j_m = 0: the same inertia about the joint; tilted, the \
                 model then differs by the rotor's share (pi4, pi5)"
                    .into(),
            );
            (0.0, prior.n_g)
        }
    };
    p.j_m = j_m;
    p.n_g = n_g;
    // The plate's inertia: its own column (only positive estimates reach here).
    if let Some(i_f) = value[7] {
        p.i_f = i_f.max(0.0);
    }
    // The arm's inertia about its centre of mass: what pi3 (or pi3 + pi5) leaves.
    let lc = p.lc();
    let i_l = match (value[2], sum35) {
        (Some(pi3), _) => Some(pi3 - m_l * lc * lc - j_m),
        (None, Some(s)) => Some(s - m_l * lc * lc - n_g * n_g * j_m),
        _ => None,
    };
    if let Some(i_l) = i_l {
        let scale = m_l * lc * lc;
        if i_l >= 0.0 {
            p.i_l = i_l;
        } else {
            p.i_l = 0.0;
            if -i_l > 1e-9 * scale {
                warnings.push(format!(
                    "i_l = {i_l:.3e} kg m^2 is negative: the prior m_l = {m_l} (with l_c = \
                     {lc:.4} m) puts more inertia at the centre of mass than the motion shows; \
                     set to 0"
                ));
            }
        }
    }
    (p, out)
}
