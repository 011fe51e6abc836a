//! The paper's numbers, in one place: the stabilised tilting orbit that every command and node
//! starts from by default, and the gains it was computed with.
//!
//! The orbit is approach 2 of the paper's Sec. III-B with the default [`Params`](crate::Params)
//! and the paper's impact law under continuous coupling: the periodic orbit of the hybrid system
//! under the computed-torque PD law with `K_P0 = 100`, `K_D = 14.14` and `beta_d = pi/2`, and the
//! time average of its energy over one period, which the adaptation `K_P = K_P0 + k (E_av - E)`
//! uses. The `tilting plan orbit` command recomputes them (Newton shooting on
//! `(beta0, beta_dot0, t_end)`), and the planner's tests check that it finds these values; keep
//! them in step.
//!
//! Everything else (the scenario defaults, the nodes' flag defaults, the figures, the help
//! texts) refers to these constants instead of repeating the digits.

use crate::{Mode, State};
use std::f64::consts::FRAC_PI_2;

/// Mode at the start of the orbit: the beginning of a left tilt.
pub const ORBIT_MODE: Mode = Mode::Left;
/// `beta0` (rad): the orbit starts at `beta = pi/2 + ORBIT_BETA0`.
pub const ORBIT_BETA0: f64 = -0.000214877415;
/// `beta_dot0` (rad/s) at the start of the orbit.
pub const ORBIT_BETA_DOT0: f64 = 0.498257789692;
/// Duration of the left tilt (s): half the orbit's period. The orbit lands at this time and
/// tilts right at once (the mirror image of the left half).
pub const ORBIT_HALF_PERIOD: f64 = 0.435260234280;
/// The stiffness gain `K_P0` (1/s^2) the orbit was computed with.
pub const ORBIT_KP: f64 = 100.0;
/// The damping gain `K_D` (1/s) the orbit was computed with.
pub const ORBIT_KD: f64 = 14.14;
/// The energy adaptation gain `k` (1/(J s^2)) of the default run: it stabilises the orbit
/// (period doubling sets in near `k = 1925`).
pub const ORBIT_K: f64 = 500.0;
/// The time average `E_av` (J) of the energy over one period of the orbit.
pub const ORBIT_ENERGY_AVG: f64 = 19.963439703027;

/// The largest joint torque `|tau|` (N m) along the stabilised orbit (`k = ORBIT_K`, continuous
/// coupling), rounded up: 11.64 N m measured over 20 s. The plant's default bound on commanded
/// torques is a multiple of it (`tilting-plant --max-torque`).
pub const ORBIT_MAX_TORQUE: f64 = 11.65;

/// The initial state of the orbit `(alpha, beta, alpha_dot, beta_dot)` (rad, rad/s).
pub fn orbit_x0() -> [f64; 4] {
    [0.0, FRAC_PI_2 + ORBIT_BETA0, 0.0, ORBIT_BETA_DOT0]
}

/// [`orbit_x0`] as a [`State`].
pub fn orbit_state() -> State {
    State::from(orbit_x0())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_orbit_starts_a_left_tilt_from_flat() {
        // A tilt starts with the plate on the ground and at rest: alpha = alpha_dot = 0.
        let x = orbit_state();
        assert_eq!((x[0], x[2]), (0.0, 0.0));
        assert!(ORBIT_MODE.is_tilted());
        // The simulator accepts it as the start of a tilt (a tilted state with alpha = 0 that
        // moves out of the ground, not into it).
        let plant = crate::Plant::new(crate::SimConfig::default(), 0.0, ORBIT_MODE, x);
        assert!(plant.is_ok(), "{:?}", plant.err());
    }
}
