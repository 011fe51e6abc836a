//! Equations of motion of the three contact modes, the ground force, the ZMP and inverse
//! dynamics (the computed-torque map).
//!
//! State `x = (alpha, beta, alpha_dot, beta_dot)` in rad and rad/s; torque `tau` in N m on the arm
//! joint, positive accelerating `beta` positively. Tilted equations are those of a double
//! pendulum about the pivot; the right tilt is the left one with `f -> -f`.

use crate::{Mode, Params, State};

// The functions here run about a thousand times per simulated second inside the integrator,
// through generic code instantiated in other crates; `#[inline(always)]` keeps them inlined
// there whatever the caller's size (measured: the planner's `simulate` went from 17,800 to
// 24,300 simulated s per wall s).

/// Sines and cosines of one configuration, computed once and shared by every formula below
/// (the right-hand side is evaluated about a thousand times per simulated second).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trig {
    /// `sin alpha`
    pub sa: f64,
    /// `cos alpha`
    pub ca: f64,
    /// `sin beta`
    pub sb: f64,
    /// `cos beta`
    pub cb: f64,
    /// `sin(alpha + beta)`
    pub sab: f64,
    /// `cos(alpha + beta)`
    pub cab: f64,
}

impl Trig {
    /// The sines and cosines of `x`'s angles.
    #[inline(always)]
    pub fn new(x: &State) -> Self {
        let (sa, ca) = x[0].sin_cos();
        let (sb, cb) = x[1].sin_cos();
        Self {
            sa,
            ca,
            sb,
            cb,
            sab: sa * cb + ca * sb,
            cab: ca * cb - sa * sb,
        }
    }
}

/// Everything the right-hand side, the inverse dynamics and the energy share at one state:
/// the sines and cosines, the mass matrix and the bias terms, computed once per evaluation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Terms {
    /// Sines and cosines.
    pub trig: Trig,
    /// Mass matrix `(M11, M12, M22)` (kg m^2); the left-tilt values in the flat mode.
    pub m: (f64, f64, f64),
    /// Bias `(h1, h2)` (N m).
    pub h: (f64, f64),
}

impl Terms {
    /// The terms of `mode` at state `x`.
    #[inline(always)]
    pub fn new(p: &Params, mode: Mode, x: &State) -> Self {
        let trig = Trig::new(x);
        Self {
            trig,
            m: mass_matrix_cb(p, mode, trig.cb),
            h: bias_t(p, mode, x, &trig),
        }
    }
}

/// Mass matrix entries `(M11, M12, M22)` of a tilted mode (kg m^2) at arm angle `beta`.
/// For [`Mode::Flat`] these are the left-tilt values (the plate is held by the ground).
#[inline(always)]
pub fn mass_matrix(p: &Params, mode: Mode, beta: f64) -> (f64, f64, f64) {
    mass_matrix_cb(p, mode, beta.cos())
}

#[inline(always)]
fn mass_matrix_cb(p: &Params, mode: Mode, cb: f64) -> (f64, f64, f64) {
    let sf = mode.signed_f(p.f);
    let m11 = p.m_f * sf * sf + p.m_l * (sf * sf + 2.0 * sf * p.l * cb + p.l * p.l);
    let m12 = p.m_l * p.l * (p.l + sf * cb);
    let m22 = p.m_l * p.l * p.l;
    (m11, m12, m22)
}

/// Coriolis, centrifugal and gravity terms `(h1, h2)` of a tilted mode (N m).
#[inline(always)]
pub fn bias(p: &Params, mode: Mode, x: &State) -> (f64, f64) {
    bias_t(p, mode, x, &Trig::new(x))
}

#[inline(always)]
fn bias_t(p: &Params, mode: Mode, x: &State, tr: &Trig) -> (f64, f64) {
    let (ad, bd) = (x[2], x[3]);
    let sf = mode.signed_f(p.f);
    let ml = p.m_l;
    let h1 = -ml * sf * p.l * tr.sb * (2.0 * ad * bd + bd * bd)
        + p.total_mass() * p.g * sf * tr.ca
        + ml * p.g * p.l * tr.cab;
    let h2 = ml * p.l * (sf * tr.sb * ad * ad + p.g * tr.cab);
    (h1, h2)
}

/// Accelerations `(alpha_ddot, beta_ddot)` (rad/s^2) under torque `tau`.
#[inline(always)]
pub fn accelerations(p: &Params, mode: Mode, x: &State, tau: f64) -> (f64, f64) {
    accelerations_t(p, mode, &Terms::new(p, mode, x), tau)
}

/// [`accelerations`] with the shared terms already at hand.
#[inline(always)]
pub fn accelerations_t(p: &Params, mode: Mode, tm: &Terms, tau: f64) -> (f64, f64) {
    match mode {
        Mode::Flat => {
            let bdd = (tau / (p.m_l * p.l) - p.g * tm.trig.cb) / p.l;
            (0.0, bdd)
        }
        _ => {
            let (m11, m12, m22) = tm.m;
            let (h1, h2) = tm.h;
            let det = m11 * m22 - m12 * m12;
            let r1 = -h1;
            let r2 = tau - h2;
            ((m22 * r1 - m12 * r2) / det, (m11 * r2 - m12 * r1) / det)
        }
    }
}

/// Time derivative of the state, `x_dot = f_q(x, tau)`.
#[inline(always)]
pub fn rhs(p: &Params, mode: Mode, x: &State, tau: f64) -> State {
    let (add, bdd) = accelerations(p, mode, x, tau);
    State::new(x[2], x[3], add, bdd)
}

/// The torque (N m) that gives `beta_ddot = v` (rad/s^2) in `mode` at state `x`: the
/// computed-torque (inverse dynamics) map. In a tilted mode `alpha_ddot` is eliminated with the
/// first (unactuated) row of the equations of motion.
#[inline(always)]
pub fn torque_for_beta_ddot(p: &Params, mode: Mode, x: &State, v: f64) -> f64 {
    torque_for_beta_ddot_t(p, mode, &Terms::new(p, mode, x), v)
}

/// [`torque_for_beta_ddot`] with the shared terms already at hand.
#[inline(always)]
pub fn torque_for_beta_ddot_t(p: &Params, mode: Mode, tm: &Terms, v: f64) -> f64 {
    match mode {
        Mode::Flat => p.m_l * p.l * (p.l * v + p.g * tm.trig.cb),
        _ => {
            let (m11, m12, m22) = tm.m;
            let (h1, h2) = tm.h;
            let add = -(m12 * v + h1) / m11;
            m12 * add + m22 * v + h2
        }
    }
}

/// Total energy `E = T + V` (J) from the mass matrix, with the shared terms at hand. Equal
/// to [`crate::kinematics::energy`] (which works from the positions and velocities of the
/// masses; the tests compare them).
#[inline(always)]
pub fn energy_t(p: &Params, mode: Mode, x: &State, tm: &Terms) -> f64 {
    let (ad, bd) = (x[2], x[3]);
    let (m11, m12, m22) = tm.m;
    let sf = mode.signed_f(p.f);
    let t = 0.5 * (m11 * ad * ad + 2.0 * m12 * ad * bd + m22 * bd * bd);
    let v = p.g * (p.total_mass() * sf * tm.trig.sa + p.m_l * p.l * tm.trig.sab);
    t + v
}

/// Vertical ground (or pivot) reaction force `F_y` (N) given the accelerations: the total
/// weight plus the masses times their vertical accelerations.
#[inline(always)]
pub fn vertical_force(p: &Params, mode: Mode, x: &State, add: f64, bdd: f64) -> f64 {
    let (a, b, ad, bd) = (x[0], x[1], x[2], x[3]);
    let sf = mode.signed_f(p.f);
    let (sa, ca) = a.sin_cos();
    let (sab, cab) = (a + b).sin_cos();
    let yf_dd = sf * (ca * add - sa * ad * ad);
    let yl_dd = yf_dd + p.l * (cab * (add + bdd) - sab * (ad + bd) * (ad + bd));
    p.total_mass() * p.g + p.m_f * yf_dd + p.m_l * yl_dd
}

/// Flat-mode support margins `(s_left, s_right)` (N m) for torque `tau`: `s_left = r_z F_y` and
/// `s_right = (2 f - r_z) F_y`, with `r_z` the ZMP. Both are positive while the ZMP lies inside
/// the support `[0, 2 f]`; the plate tilts left when `s_left` reaches 0 and right when
/// `s_right` does. Written without the division so that they stay smooth when `F_y` is small.
#[inline(always)]
pub fn support_margins(p: &Params, x: &State, tau: f64) -> (f64, f64) {
    let fy = flat_vertical_force(p, x, tau);
    (p.f * fy + tau, p.f * fy - tau)
}

/// Flat-mode vertical ground force `F_y` (N) under torque `tau`.
#[inline(always)]
pub fn flat_vertical_force(p: &Params, x: &State, tau: f64) -> f64 {
    let (_, bdd) = accelerations(p, Mode::Flat, x, tau);
    vertical_force(p, Mode::Flat, x, 0.0, bdd)
}

/// Zero moment point `r_z = M_z / F_y` (m, world x) of the flat plate under torque `tau`.
pub fn zmp(p: &Params, x: &State, tau: f64) -> f64 {
    let fy = flat_vertical_force(p, x, tau);
    p.f + tau / fy
}
