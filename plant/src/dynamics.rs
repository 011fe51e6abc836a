//! Equations of motion of the three contact modes, the ground force, the ZMP and inverse
//! dynamics (the computed-torque map).
//!
//! State `x = (alpha, beta, alpha_dot, beta_dot)` in rad and rad/s; torque `tau` in N m on the arm
//! joint, positive accelerating `beta` positively. Tilted equations are those of a double
//! pendulum about the pivot; the right tilt is the left one with `f -> -f`.
//!
//! Two torques at the joint: the motor's `tau` (what a controller commands) and the net joint
//! torque `tau_j = tau - b_v beta_dot` (the motor's less the friction). The rigid-body functions
//! ending in `_t` ([`accelerations_t`]) take the net torque; the others ([`accelerations`],
//! [`rhs`], [`torque_for_beta_ddot`], [`support_margins`], ...) take the motor's and apply the
//! friction themselves. With the paper's parameters the two are the same number.

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
    /// The angles' sums from the sines and cosines of `alpha` (`sa`, `ca`) and `beta` (`sb`,
    /// `cb`) by the angle-sum formulas.
    #[inline(always)]
    fn from_sin_cos(sa: f64, ca: f64, sb: f64, cb: f64) -> Self {
        Self {
            sa,
            ca,
            sb,
            cb,
            sab: sa * cb + ca * sb,
            cab: ca * cb - sa * sb,
        }
    }

    /// The sines and cosines of `x`'s angles.
    #[inline(always)]
    pub fn new(x: &State) -> Self {
        let (sa, ca) = x[0].sin_cos();
        let (sb, cb) = x[1].sin_cos();
        Self::from_sin_cos(sa, ca, sb, cb)
    }
}

impl Trig {
    /// The sines and cosines of `x`'s angles from those of a nearby state `x0` (`tr0 =
    /// Trig::new(x0)`) by the angle-sum formulas, with the sine and cosine of the small
    /// differences from their Taylor series: about five times cheaper than [`Trig::new`] and
    /// within a few ulp of it (the series are cut where their remainder is below 1e-19 for
    /// differences up to [`Trig::NEAR`] rad). Falls back to [`Trig::new`] for larger
    /// differences.
    #[inline(always)]
    pub fn near(x: &State, x0: &State, tr0: &Trig) -> Self {
        let (da, db) = (x[0] - x0[0], x[1] - x0[1]);
        if da.abs().max(db.abs()) > Self::NEAR {
            return Self::new(x);
        }
        let (sda, cma) = sin_cosm1_small(da);
        let (sdb, cmb) = sin_cosm1_small(db);
        let sa = tr0.sa + (tr0.sa * cma + tr0.ca * sda);
        let ca = tr0.ca + (tr0.ca * cma - tr0.sa * sda);
        let sb = tr0.sb + (tr0.sb * cmb + tr0.cb * sdb);
        let cb = tr0.cb + (tr0.cb * cmb - tr0.sb * sdb);
        Self::from_sin_cos(sa, ca, sb, cb)
    }

    /// Largest angle difference (rad) [`Trig::near`] takes by the series.
    pub const NEAR: f64 = 1.0 / 32.0;
}

/// `(sin d, cos d - 1)` for `|d| <= 1/32` by their Taylor series: the first omitted terms,
/// `d^11 / 11!` and `d^12 / 12!`, are below 1e-24.
#[inline(always)]
fn sin_cosm1_small(d: f64) -> (f64, f64) {
    let z = d * d;
    let s =
        d + d * z * (-1.0 / 6.0 + z * (1.0 / 120.0 + z * (-1.0 / 5040.0 + z * (1.0 / 362_880.0))));
    let c = z
        * (-0.5
            + z * (1.0 / 24.0
                + z * (-1.0 / 720.0 + z * (1.0 / 40_320.0 - z * (1.0 / 3_628_800.0)))));
    (s, c)
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
        Self::from_trig(p, mode, x, Trig::new(x))
    }

    /// The terms of `mode` at state `x` whose sines and cosines `trig` are already known.
    #[inline(always)]
    pub fn from_trig(p: &Params, mode: Mode, x: &State, trig: Trig) -> Self {
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
    let l = p.lc();
    let m11 = p.m_f * sf * sf + p.m_l * (sf * sf + 2.0 * sf * l * cb + l * l);
    let m12 = p.m_l * l * (l + sf * cb);
    let m22 = p.m_l * l * l;
    // Skipped, not added as zeros, for point masses: the paper's numbers stay the same bits.
    if p.has_inertia() {
        let (i11, i12, i22) = p.inertia();
        (m11 + i11, m12 + i12, m22 + i22)
    } else {
        (m11, m12, m22)
    }
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
    let (ml, l) = (p.m_l, p.lc());
    let h1 = -ml * sf * l * tr.sb * (2.0 * ad * bd + bd * bd)
        + p.total_mass() * p.g * sf * tr.ca
        + ml * p.g * l * tr.cab;
    let h2 = ml * l * (sf * tr.sb * ad * ad + p.g * tr.cab);
    (h1, h2)
}

/// The phase of the joint's Coulomb friction: what the friction torque is while it lasts.
/// Without Coulomb friction (`tau_c = 0`) the joint is always [`Joint::Free`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Joint {
    /// No Coulomb friction.
    #[default]
    Free,
    /// Sliding with `beta_dot > 0`: the friction torque on the arm is `-tau_c`.
    Forward,
    /// Sliding with `beta_dot < 0`: the friction torque on the arm is `+tau_c`.
    Backward,
    /// Stuck: `beta_dot = 0` and the friction holds the arm to the plate (the arm and the plate
    /// move as one body), taking whatever torque in `[-tau_c, tau_c]` that needs.
    Stuck,
}

impl Joint {
    /// The phase at state `x` under the motor torque `tau` (N m) (Karnopp's rule): sliding the
    /// way `beta_dot` points; at `beta_dot = 0` stuck while the torque needed to hold the arm
    /// ([`hold_torque`]) differs from `tau` by less than `tau_c`, else sliding the way the
    /// excess pushes. `tm` are the shared terms of `x`.
    #[inline(always)]
    pub fn of(p: &Params, mode: Mode, x: &State, tm: &Terms, tau: f64) -> Joint {
        if p.tau_c == 0.0 {
            Joint::Free
        } else if x[3] > 0.0 {
            Joint::Forward
        } else if x[3] < 0.0 {
            Joint::Backward
        } else {
            let excess = tau - hold_torque(p, mode, tm);
            if excess.abs() < p.tau_c {
                Joint::Stuck
            } else if excess > 0.0 {
                Joint::Forward
            } else {
                Joint::Backward
            }
        }
    }

    /// A short name: `free`, `forward`, `backward` or `stuck`.
    pub fn as_str(self) -> &'static str {
        match self {
            Joint::Free => "free",
            Joint::Forward => "forward",
            Joint::Backward => "backward",
            Joint::Stuck => "stuck",
        }
    }
}

/// Accelerations `(alpha_ddot, beta_ddot)` (rad/s^2) under the motor torque `tau`, friction
/// included (Coulomb's by [`Joint::of`]).
#[inline(always)]
pub fn accelerations(p: &Params, mode: Mode, x: &State, tau: f64) -> (f64, f64) {
    let tm = Terms::new(p, mode, x);
    joint_accelerations(p, mode, Joint::of(p, mode, x, &tm, tau), x, &tm, tau)
}

/// [`accelerations`] in the joint phase `joint`, with the shared terms already at hand. Stuck,
/// the arm and the plate move as one body (`beta_ddot = 0`; tilted, `M11 alpha_ddot = -h1`).
#[inline(always)]
pub fn joint_accelerations(
    p: &Params,
    mode: Mode,
    joint: Joint,
    x: &State,
    tm: &Terms,
    tau: f64,
) -> (f64, f64) {
    match (joint, mode) {
        (Joint::Stuck, Mode::Flat) => (0.0, 0.0),
        (Joint::Stuck, _) => (-tm.h.0 / tm.m.0, 0.0),
        _ => accelerations_t(p, mode, tm, net_torque(p, joint, x[3], tau)),
    }
}

/// The net joint torque `tau_j` (N m) on the arm while it slides (or is [`Joint::Free`]): the
/// motor torque `tau` less the viscous friction `b_v beta_dot` at the arm rate `bd` (rad/s)
/// and less the Coulomb friction `tau_c` the way it slides.
#[inline(always)]
pub fn net_torque(p: &Params, joint: Joint, bd: f64, tau: f64) -> f64 {
    // Each term skipped when absent: the paper's numbers stay the same bits.
    let tau = if p.b_v != 0.0 { tau - p.b_v * bd } else { tau };
    match joint {
        Joint::Forward => tau - p.tau_c,
        Joint::Backward => tau + p.tau_c,
        Joint::Free | Joint::Stuck => tau,
    }
}

/// The net joint torque (N m) that holds the arm still relative to the plate (`beta_ddot = 0`)
/// at the state whose shared terms are `tm`: what a stuck joint must transmit.
#[inline(always)]
pub fn hold_torque(p: &Params, mode: Mode, tm: &Terms) -> f64 {
    rigid_torque(p, mode, tm, 0.0)
}

/// The rigid-body accelerations `(alpha_ddot, beta_ddot)` (rad/s^2) under the net joint torque
/// `tau_j` (N m; friction not included, see [`net_torque`]), with the shared terms at hand.
#[inline(always)]
pub fn accelerations_t(p: &Params, mode: Mode, tm: &Terms, tau_j: f64) -> (f64, f64) {
    let tau = tau_j;
    match mode {
        Mode::Flat if p.has_inertia() => {
            let l = p.lc();
            (0.0, (tau - p.m_l * l * p.g * tm.trig.cb) / tm.m.2)
        }
        Mode::Flat => {
            let l = p.lc();
            let bdd = (tau / (p.m_l * l) - p.g * tm.trig.cb) / l;
            (0.0, bdd)
        }
        _ => {
            let (m11, m12, m22) = tm.m;
            let (h1, h2) = tm.h;
            // The reciprocal first: it depends on the mass matrix alone, so the division
            // runs while the bias terms are still being computed instead of after them (the
            // right-hand side is a chain of dependent stages, latency-bound).
            let inv_det = 1.0 / (m11 * m22 - m12 * m12);
            let r1 = -h1;
            let r2 = tau - h2;
            (
                (m22 * r1 - m12 * r2) * inv_det,
                (m11 * r2 - m12 * r1) * inv_det,
            )
        }
    }
}

/// Time derivative of the state, `x_dot = f_q(x, tau)`.
#[inline(always)]
pub fn rhs(p: &Params, mode: Mode, x: &State, tau: f64) -> State {
    let (add, bdd) = accelerations(p, mode, x, tau);
    State::new(x[2], x[3], add, bdd)
}

/// The motor torque (N m) that gives `beta_ddot = v` (rad/s^2) in `mode` at state `x`: the
/// computed-torque (inverse dynamics) map, friction compensated. In a tilted mode
/// `alpha_ddot` is eliminated with the first (unactuated) row of the equations of motion.
#[inline(always)]
pub fn torque_for_beta_ddot(p: &Params, mode: Mode, x: &State, v: f64) -> f64 {
    torque_for_beta_ddot_t(p, mode, x, &Terms::new(p, mode, x), v)
}

/// [`torque_for_beta_ddot`] with the shared terms of `x` already at hand.
#[inline(always)]
pub fn torque_for_beta_ddot_t(p: &Params, mode: Mode, x: &State, tm: &Terms, v: f64) -> f64 {
    let tau_j = rigid_torque(p, mode, tm, v);
    // The friction the motor must overcome (each skipped when absent: the same bits).
    let tau = if p.b_v != 0.0 {
        tau_j + p.b_v * x[3]
    } else {
        tau_j
    };
    if p.tau_c != 0.0 {
        // Sliding, against the motion; from rest, against the commanded acceleration (then
        // the excess over the hold torque is `M_s v + tau_c sign(v)`: it slides, and with
        // `beta_ddot = v`). At rest with `v = 0` the joint sticks.
        let s = if x[3] != 0.0 { x[3] } else { v };
        if s > 0.0 {
            return tau + p.tau_c;
        } else if s < 0.0 {
            return tau - p.tau_c;
        }
    }
    tau
}

/// The net joint torque (N m) that gives `beta_ddot = v`: the rigid-body inverse dynamics.
#[inline(always)]
fn rigid_torque(p: &Params, mode: Mode, tm: &Terms, v: f64) -> f64 {
    match mode {
        Mode::Flat => {
            let l = p.lc();
            if p.has_inertia() {
                tm.m.2 * v + p.m_l * l * p.g * tm.trig.cb
            } else {
                p.m_l * l * (l * v + p.g * tm.trig.cb)
            }
        }
        _ => {
            let (m11, m12, m22) = tm.m;
            let (h1, h2) = tm.h;
            let add = -(m12 * v + h1) * (1.0 / m11); // reciprocal first, as above
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
    let v = p.g * (p.total_mass() * sf * tm.trig.sa + p.m_l * p.lc() * tm.trig.sab);
    t + v
}

/// Vertical ground (or pivot) reaction force `F_y` (N) given the accelerations: the total
/// weight plus the masses times the vertical accelerations of their centres (the plate's and
/// the arm's at `l_c`).
#[inline(always)]
pub fn vertical_force(p: &Params, mode: Mode, x: &State, add: f64, bdd: f64) -> f64 {
    let (a, b, ad, bd) = (x[0], x[1], x[2], x[3]);
    let sf = mode.signed_f(p.f);
    let (sa, ca) = a.sin_cos();
    let (sab, cab) = (a + b).sin_cos();
    let yf_dd = sf * (ca * add - sa * ad * ad);
    let yl_dd = yf_dd + p.lc() * (cab * (add + bdd) - sab * (ad + bd) * (ad + bd));
    p.total_mass() * p.g + p.m_f * yf_dd + p.m_l * yl_dd
}

/// [`vertical_force`] with the sines and cosines of `x` at hand (`tr = Trig::new(x)`; the sine
/// of `alpha + beta` then comes from the sum formula, so the result may differ from
/// [`vertical_force`] in the last bits).
#[inline(always)]
pub fn vertical_force_t(p: &Params, mode: Mode, x: &State, tr: &Trig, add: f64, bdd: f64) -> f64 {
    let (ad, bd) = (x[2], x[3]);
    let sf = mode.signed_f(p.f);
    let yf_dd = sf * (tr.ca * add - tr.sa * ad * ad);
    let yl_dd = yf_dd + p.lc() * (tr.cab * (add + bdd) - tr.sab * (ad + bd) * (ad + bd));
    p.total_mass() * p.g + p.m_f * yf_dd + p.m_l * yl_dd
}

/// Flat-mode support margins `(s_left, s_right)` (N m) for the motor torque `tau`: `s_left =
/// r_z F_y` and `s_right = (2 f - r_z) F_y`, with `r_z` the ZMP. Both are positive while the ZMP
/// lies inside the support `[0, 2 f]`; the plate tilts left when `s_left` reaches 0 and right
/// when `s_right` does. Written without the division so that they stay smooth when `F_y` is
/// small. They are `f F_y +- tau_z` with `tau_z` the [`plate_torque`].
#[inline(always)]
pub fn support_margins(p: &Params, x: &State, tau: f64) -> (f64, f64) {
    let (fy, tz) = flat_loads(p, x, tau);
    (p.f * fy + tz, p.f * fy - tz)
}

/// The flat plate's loads under the motor torque `tau`: the vertical ground force `F_y` (N)
/// and the [`plate_torque`] `tau_z` (N m).
#[inline(always)]
fn flat_loads(p: &Params, x: &State, tau: f64) -> (f64, f64) {
    let (_, bdd) = accelerations(p, Mode::Flat, x, tau);
    let fy = vertical_force(p, Mode::Flat, x, 0.0, bdd);
    let tz = if p.has_inertia() || p.b_v != 0.0 || p.tau_c != 0.0 {
        plate_torque(p, x[1].cos(), bdd)
    } else {
        tau // the same number for point masses without friction, and the same bits as before
    };
    (fy, tz)
}

/// The torque `tau_z` (N m) the arm and the rotor exert on the flat plate about the joint (as
/// a moment about the plate's centre: counter-clockwise on the arm's side), from the cosine of
/// the arm angle `cb` and the arm's acceleration `bdd` (rad/s^2): the moment needed to turn the
/// arm's centre of mass and spin the arm and the rotor, `tau_z = m_l l_c (l_c beta_ddot + g cos
/// beta) + (i_l + n_g j_m) beta_ddot`. For point masses it is the net joint torque.
#[inline(always)]
pub fn plate_torque(p: &Params, cb: f64, bdd: f64) -> f64 {
    let l = p.lc();
    let t = p.m_l * l * (l * bdd + p.g * cb);
    if p.has_inertia() {
        t + p.inertia().1 * bdd
    } else {
        t
    }
}

/// Flat-mode vertical ground force `F_y` (N) under torque `tau`.
#[inline(always)]
pub fn flat_vertical_force(p: &Params, x: &State, tau: f64) -> f64 {
    let (_, bdd) = accelerations(p, Mode::Flat, x, tau);
    vertical_force(p, Mode::Flat, x, 0.0, bdd)
}

/// Zero moment point `r_z = M_z / F_y` (m, world x) of the flat plate under the motor torque
/// `tau`.
pub fn zmp(p: &Params, x: &State, tau: f64) -> f64 {
    let (fy, tz) = flat_loads(p, x, tau);
    p.f + tz / fy
}
