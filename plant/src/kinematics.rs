//! Positions and velocities of the plate's and the arm's centres of mass in the world frame,
//! and the energy and angular momentum of the bodies (with the arm's and the rotor's own
//! rotational inertia).
//!
//! World frame: origin at the left plate edge when the plate lies flat, `x` to the right, `y` up
//! (metres). These formulas are written from the geometry alone and serve as the independent
//! reference for energy and angular momentum in the tests.

use crate::{Mode, Params, State};
use nalgebra::Vector2;

/// Positions (m) and velocities (m/s) of the plate centre, the arm tip and the arm's centre of
/// mass in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointMasses {
    /// Plate centre (mass `m_f`).
    pub foot: Vector2<f64>,
    /// Arm tip, at `l` from the joint (the arm's mass when `l_c` is not set).
    pub tip: Vector2<f64>,
    /// Velocity of the plate centre.
    pub foot_vel: Vector2<f64>,
    /// Velocity of the arm tip.
    pub tip_vel: Vector2<f64>,
    /// The arm's centre of mass (mass `m_l`), at `l_c` from the joint.
    pub arm: Vector2<f64>,
    /// Velocity of the arm's centre of mass.
    pub arm_vel: Vector2<f64>,
}

/// The contact point the plate rotates about in `mode` (world frame, m): the left edge `(0, 0)`
/// for flat and left, the right edge `(2 f, 0)` for right.
pub fn pivot(p: &Params, mode: Mode) -> Vector2<f64> {
    match mode {
        Mode::Right => Vector2::new(2.0 * p.f, 0.0),
        _ => Vector2::zeros(),
    }
}

/// Positions and velocities of both masses for state `x` in `mode`.
pub fn point_masses(p: &Params, mode: Mode, x: &State) -> PointMasses {
    let (a, b, ad, bd) = (x[0], x[1], x[2], x[3]);
    let sf = mode.signed_f(p.f);
    let (sa, ca) = a.sin_cos();
    let (sab, cab) = (a + b).sin_cos();
    let foot = pivot(p, mode) + sf * Vector2::new(ca, sa);
    let (u, du) = (Vector2::new(cab, sab), (ad + bd) * Vector2::new(-sab, cab));
    let foot_vel = sf * ad * Vector2::new(-sa, ca);
    PointMasses {
        foot,
        tip: foot + p.l * u,
        foot_vel,
        tip_vel: foot_vel + p.l * du,
        arm: foot + p.lc() * u,
        arm_vel: foot_vel + p.lc() * du,
    }
}

/// Angular velocities (rad/s) of the arm (`alpha_dot + beta_dot`) and of the rotor
/// (`alpha_dot + n_g beta_dot`: its stator turns with the plate).
fn spins(p: &Params, x: &State) -> (f64, f64) {
    (x[2] + x[3], x[2] + p.n_g * x[3])
}

/// Total energy `E = T + V` (J), ground at `y = 0`: the centres of mass' kinetic and potential
/// energy and the arm's, the rotor's and the plate's rotational energy.
pub fn energy(p: &Params, mode: Mode, x: &State) -> f64 {
    let q = point_masses(p, mode, x);
    let (wa, wr) = spins(p, x);
    let t = 0.5 * (p.m_f * q.foot_vel.norm_squared() + p.m_l * q.arm_vel.norm_squared())
        + 0.5 * (p.i_l * wa * wa + p.j_m * wr * wr + p.i_f * x[2] * x[2]);
    let v = p.g * (p.m_f * q.foot.y + p.m_l * q.arm.y);
    t + v
}

/// Angular momentum of the system about the fixed world point `about` (kg m^2/s, counter-
/// clockwise positive).
pub fn angular_momentum(p: &Params, mode: Mode, x: &State, about: Vector2<f64>) -> f64 {
    let q = point_masses(p, mode, x);
    let cross = |r: Vector2<f64>, v: Vector2<f64>| {
        let d = r - about;
        d.x * v.y - d.y * v.x
    };
    let (wa, wr) = spins(p, x);
    p.m_f * cross(q.foot, q.foot_vel)
        + p.m_l * cross(q.arm, q.arm_vel)
        + p.i_l * wa
        + p.j_m * wr
        + p.i_f * x[2]
}

/// Mirror image of a state: `(alpha, beta) -> (-alpha, pi - beta)`, rates negated. Maps a
/// left-tilt motion onto a right-tilt one (and flat onto flat) when the torque is negated.
pub fn mirror(x: &State) -> State {
    State::new(-x[0], std::f64::consts::PI - x[1], -x[2], -x[3])
}
