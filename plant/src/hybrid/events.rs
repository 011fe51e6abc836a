//! The events of the hybrid flow: the event functions of each mode ([`Ev`]), their location on a
//! step's dense output ([`locate`], regula falsi) and what the plant does at one.

use super::{Fault, Observer, Plant, TorqueLaw, NG};
use crate::dynamics::{hold_torque, plate_torque, vertical_force_t, Joint, Terms, Trig};
use crate::ode::Dense;
use crate::{Mode, State};

/// Event function slots. Each is positive inside the mode and fires when it reaches zero from
/// above.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Ev {
    /// Flat: ZMP leaves through the left edge. Tilted: landing (`alpha` back to 0).
    A,
    /// Flat: ZMP leaves through the right edge. Tilted: extreme of `alpha` (not terminal).
    B,
    /// Vertical contact force.
    Contact,
    /// Tilted: fall angle.
    Fall,
    /// The joint's friction phase ends: a sliding arm's `beta_dot` reaches 0 (`s beta_dot`,
    /// `s` the sliding direction), or a stuck arm's torque leaves the friction band (`tau_c -
    /// |tau - hold torque|`). Constant 1 without Coulomb friction.
    Joint,
}

pub(super) const EVS: [Ev; NG] = [Ev::A, Ev::B, Ev::Contact, Ev::Fall, Ev::Joint];

impl Plant {
    /// Event function values at state `x` with derivative `xd = f_q(x, tau)` in the current
    /// mode. Everything is read off `(x, xd)`: in the flat mode the torque is recovered from
    /// `beta_ddot` by inverting the flat equation, so the torque law is not evaluated again;
    /// only a stuck joint's band needs the motor torque, `tau()` (called only then).
    #[inline]
    pub(super) fn events(&self, x: &State, xd: &State, tau: impl FnOnce() -> f64) -> [f64; NG] {
        self.events_t(x, xd, &Trig::new(x), tau)
    }

    /// [`Plant::events`] with the sines and cosines of `x` at hand.
    #[inline]
    pub(super) fn events_t(
        &self,
        x: &State,
        xd: &State,
        tr: &Trig,
        tau: impl FnOnce() -> f64,
    ) -> [f64; NG] {
        let p = &self.cfg.params;
        let fy = vertical_force_t(p, self.mode, x, tr, xd[2], xd[3]);
        let joint = match self.joint {
            Joint::Free => 1.0,
            Joint::Forward => x[3],
            Joint::Backward => -x[3],
            Joint::Stuck => {
                let tm = Terms::from_trig(p, self.mode, x, *tr);
                p.tau_c - (tau() - hold_torque(p, self.mode, &tm)).abs()
            }
        };
        let [a, b, c, d] = self.events4(x, xd, tr, fy);
        [a, b, c, d, joint]
    }

    /// The contact events: the flat support margins or the tilt's landing and extreme, the
    /// contact force `fy` and the fall angle.
    #[inline(always)]
    pub(super) fn events4(&self, x: &State, xd: &State, tr: &Trig, fy: f64) -> [f64; 4] {
        let p = &self.cfg.params;
        match self.mode {
            Mode::Flat => {
                // The torque the plate feels, from the arm's acceleration (the motor's less
                // the friction, for point masses).
                let tau = plate_torque(p, tr.cb, xd[3]);
                [p.f * fy + tau, p.f * fy - tau, fy, 1.0]
            }
            m => {
                let s = if m == Mode::Left { 1.0 } else { -1.0 };
                [s * x[0], s * x[2], fy, self.cfg.fall_angle - s * x[0]]
            }
        }
    }

    /// Does event `i` need the derivative (and so a right-hand-side evaluation)?
    #[inline]
    pub(super) fn needs_derivative(&self, i: usize) -> bool {
        self.mode == Mode::Flat || i == 2
    }

    /// The first terminal event inside a DOP853 step over `[t0, t1]` in which some event
    /// functions fired (`g0` to `g1`), located on the step's dense output; records the tilt's
    /// extremes met before it. `None` when only extremes fired.
    pub(super) fn first_event<F: Fn(f64, &State) -> State, T: TorqueLaw + ?Sized>(
        &mut self,
        f: &F,
        tau_of: &T,
        dense: &Dense<4>,
        (t0, g0): (f64, &[f64; NG]),
        (t1, g1): (f64, &[f64; NG]),
    ) -> Option<(f64, Ev)> {
        let mode = self.mode;
        let mut roots = [(f64::INFINITY, Ev::A); NG];
        let mut n_roots = 0;
        let g_at = |i: usize, t: f64| {
            let x = dense.eval(t);
            let xd = if self.needs_derivative(i) {
                f(t, &x)
            } else {
                x
            };
            self.events(&x, &xd, || tau_of.torque(t, mode, &x))[i]
        };
        for i in (0..NG).filter(|&i| fires_in(mode != Mode::Flat, i, g0, g1)) {
            let gi = |t: f64| g_at(i, t);
            // A rebound that lands within its first step: the landing lies after the extreme,
            // where `alpha` is positive.
            let r = if i == 0 && g0[0] == 0.0 && mode != Mode::Flat {
                let te = locate(&|t| g_at(1, t), t0, g0[1], t1, g1[1], self.cfg.event_tol);
                match gi(te) {
                    ga if ga > 0.0 => locate(&gi, te, ga, t1, g1[i], self.cfg.event_tol),
                    _ => te,
                }
            } else {
                // As before the rebounds: the joint's event also from g0 = 0 (a slide that
                // turns back at once), located from t0.
                locate(&gi, t0, g0[i], t1, g1[i], self.cfg.event_tol)
            };
            roots[n_roots] = (r, EVS[i]);
            n_roots += 1;
        }
        let roots = &mut roots[..n_roots];
        roots.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut first_terminal = roots
            .iter()
            .find(|(_, e)| mode == Mode::Flat || *e != Ev::B)
            .copied();
        // A landing located within the location width of another terminal event (the pivot
        // force reaching zero as the plate lands, say) is taken as the landing: their order
        // inside that width is round-off, and the impact resets the state.
        if let Some((t_first, _)) = first_terminal.filter(|_| mode != Mode::Flat) {
            if let Some(&land) = roots
                .iter()
                .find(|(t, e)| *e == Ev::A && *t <= t_first + self.cfg.event_tol)
            {
                first_terminal = Some(land);
            }
        }
        for &(tr, e) in roots.iter() {
            if e == Ev::B && mode != Mode::Flat {
                if first_terminal.is_some_and(|(tt, _)| tt < tr) {
                    continue;
                }
                let a = dense.eval(tr)[0];
                if self.extreme.is_none_or(|(_, old)| a.abs() > old.abs()) {
                    self.extreme = Some((tr, a));
                }
            }
        }
        first_terminal
    }

    /// Acts on the terminal event `e` the flow stopped at (the state is at its located time):
    /// a fault, a tilt, a landing or a joint event, each followed by the settling checks.
    pub(super) fn on_event<T: TorqueLaw + ?Sized, O: Observer>(
        &mut self,
        e: Ev,
        tau_of: &T,
        obs: &mut O,
    ) -> Result<(), Fault> {
        match (e, self.mode) {
            (Ev::Contact, m) => {
                let tau = tau_of.torque(self.t, m, &self.x);
                let xd = self.rhs_here(tau);
                Err(Fault::ContactLoss {
                    t: self.t,
                    mode: m,
                    force: self.events(&self.x, &xd, || tau)[2],
                })
            }
            (Ev::Fall, _) => Err(Fault::Fall {
                t: self.t,
                alpha: self.x[0],
                limit: self.cfg.fall_angle,
            }),
            (Ev::A, Mode::Flat) => {
                self.start_tilt_checked(Mode::Left, tau_of, obs)?;
                self.settle(tau_of, obs)
            }
            (Ev::B, Mode::Flat) => {
                self.start_tilt_checked(Mode::Right, tau_of, obs)?;
                self.settle(tau_of, obs)
            }
            (Ev::A, _) => {
                self.land(obs)?;
                self.settle(tau_of, obs)
            }
            (Ev::B, _) => unreachable!("alpha extremes are not terminal"),
            (Ev::Joint, _) => {
                if self.joint != Joint::Stuck {
                    // A sliding arm came to rest: located to round-off, like a landing.
                    self.x[3] = 0.0;
                }
                self.settle(tau_of, obs)
            }
        }
    }
}

/// Did event `e` fire between two successive values? Each fires when it reaches zero from
/// above; a tilt starts with `alpha = alpha_dot = 0`, so the landing and extreme functions start
/// at exactly zero and must first become positive: a landing never fires at a tilt's start.
#[inline]
pub(super) fn crossed(g0: f64, g1: f64) -> bool {
    g0 > 0.0 && g1 <= 0.0
}

/// Did event slot `i` fire? [`crossed`], and for the joint's event also a slide that starts at
/// rest (`g0 = 0`) and at once turns the other way (`g1 < 0`, a torque law that reverses): the
/// friction would then push the arm, so the slide ends there.
#[inline(always)]
pub(super) fn fires(i: usize, g0: f64, g1: f64) -> bool {
    crossed(g0, g1) || (i == NG - 1 && g0 == 0.0 && g1 < 0.0)
}

/// Did slot `i` fire in a step from `g0` to `g1`? [`fires`], and in a tilted mode also a landing
/// inside the very step a tilt started with the plate moving up (a rebound): `alpha` starts at
/// exactly 0 (`g0[0] = 0`), rises (`g0[1] > 0`), turns (the extreme fired) and is below the
/// ground at the step's end. A tilt that starts at rest (`alpha_dot = 0`, the paper's tilts)
/// never takes this path.
#[inline(always)]
pub(super) fn fires_in(tilted: bool, i: usize, g0: &[f64; NG], g1: &[f64; NG]) -> bool {
    fires(i, g0[i], g1[i])
        || (tilted && i == 0 && g0[0] == 0.0 && g1[0] < 0.0 && crossed(g0[1], g1[1]))
}

/// Locates the zero of `g` in `[a, b]` with `g(a) > 0 >= g(b)` to width `tol` (s) by the
/// Illinois variant of regula falsi, with a bisection every eighth trial so the bracket always
/// shrinks. Returns the right end of the final bracket, so the state there is already past the
/// event. Public so that benchmarks locate events the same way.
pub fn locate<G: Fn(f64) -> f64>(
    g: &G,
    mut a: f64,
    mut ga: f64,
    mut b: f64,
    mut gb: f64,
    tol: f64,
) -> f64 {
    let mut last_side = 0i8;
    for iter in 0..300 {
        if b - a <= tol.max(4.0 * f64::EPSILON * b.abs()) {
            break;
        }
        let mut c = (a * gb - b * ga) / (gb - ga);
        if iter % 8 == 7 || !(c > a && c < b) {
            c = 0.5 * (a + b);
        }
        let gc = g(c);
        if gc > 0.0 {
            a = c;
            ga = gc;
            if last_side == 1 {
                gb *= 0.5;
            }
            last_side = 1;
        } else {
            b = c;
            gb = gc;
            if last_side == -1 {
                ga *= 0.5;
            }
            last_side = -1;
        }
    }
    b
}
