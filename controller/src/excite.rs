//! The excitation's amplitude governor: the excitation's amplitude follows the arm's holding
//! torque, estimated on line from the torques the law commands and the angles it reads.
//!
//! **Why.** The excitation's torque is clipped at [`crate::excitation_torque_limit`] `L`
//! (6.87 N m for the paper's model), below the torque that lifts the plate. The clip keeps the
//! plate flat only while the arm can be held: an arm whose gravity torque `G sin(theta)`
//! (`G = m_l l_c g`, `theta = beta - pi/2`) passes `L` cannot be turned back, falls, and
//! unloads the plate until it tips. The reference asks for more than gravity: at its turning
//! points the torque that decelerates the arm adds to the one that holds it, so a robot can run
//! saturated and overshoot. Measured (docs/identify.md): the default excitation (0.3 rad) keeps
//! every robot flat whose gravity torque at the reference's largest excursion is below about
//! 0.8 `L`, and loses a 20 % heavier arm (0.97 `L`). The controller's model does not know the
//! robot's arm, so the governor measures it.
//!
//! **Estimate.** Flat, the arm's equation is linear in four numbers:
//! `tau = J beta_ddot + G cos(beta) + b beta_dot + tau_c sign(beta_dot)` (`J` the inertia about
//! the joint, `b`, `tau_c` the friction). The governor filters the held torque and the read
//! angles through the same second-order low pass `F = a^2 / (s + a)^2` ([`FILTER_RATE`]), which
//! gives `F[beta_ddot] = s^2 F[beta]` without differentiating, and solves the least squares of
//! `F[tau] = J s^2 F[beta] + G F[cos beta] + b s F[beta] + tau_c F[sign beta_dot]` over every
//! flat sample so far, with a weak prior at the model's values ([`PRIOR_WEIGHT`]: it decides
//! only while the arm has hardly moved).
//!
//! **Amplitude.** From the estimates `(J, G)` the governor takes the largest scale `r* <= 1`
//! of the amplitude `A` for which the reference's gravity torque at its largest excursion,
//! `G sin(r* A s_max)`, stays under [`GRAVITY_SHARE`] of `L`, and its whole feed-forward torque
//! `max |J beta_d_ddot + G cos(beta_d)|` under [`FEEDFORWARD_SHARE`] of `L`. The
//! amplitude's scale `r` follows `r*` through a critically damped second-order filter
//! ([`SCALE_RATE`]), so the reference keeps exact, continuous rates and accelerations
//! ([`crate::Trajectory::at_scaled`]). On the paper's robot the default excitation's `r*` is 1:
//! its reference and torques are those of the ungoverned law, bit for bit.
//!
//! The state lives in the law ([`GovernedExcitation`], interior mutability, as the robust
//! law's): it observes the states it answers at most once per [`MIN_INTERVAL`] of increasing
//! time, which in a sampled loop is every sample; the continuous coupling (whose law is
//! evaluated at the integrator's trial points) observes the trial states about once a
//! millisecond.

use std::cell::Cell;

use crate::trajectory::{ramp, series};
use crate::{excitation_torque_limit, ComputedTorque, Trajectory};
use tilting_plant::{Mode, State};

/// Bandwidth `a` (rad/s) of the estimate's low pass: above the excitation's harmonics (up to
/// 5 w = 3 rad/s for the default), below the noise.
pub const FILTER_RATE: f64 = 8.0;
/// Share of the torque clip `L` that the reference's gravity torque at its largest excursion
/// may use.
pub const GRAVITY_SHARE: f64 = 0.81;
/// Share of the torque clip `L` that the reference's feed-forward torque may use.
pub const FEEDFORWARD_SHARE: f64 = 1.35;
/// Rate (rad/s) of the critically damped filter that moves the amplitude's scale.
pub const SCALE_RATE: f64 = 3.0;
/// Weight of the prior (the model's `J`, `G`, no friction) in the least squares, in the units
/// of the filtered regressor's squares: about 0.5 s of the arm moving 0.05 rad.
pub const PRIOR_WEIGHT: f64 = 1e-2;
/// How far ahead (s) the governor looks at the ramp: the scale's filter settles in about
/// `5 / SCALE_RATE`.
pub const LOOKAHEAD: f64 = 2.0;
/// Shortest interval (s) between two observed states.
pub const MIN_INTERVAL: f64 = 0.9e-3;
/// Phases per period at which the series is tabulated for the feed-forward bound.
const PHASES: usize = 256;
/// The safe scale is recomputed every this many fitted samples (the estimates move slowly).
const TARGET_EVERY: u64 = 20;

/// What the governor knows and does.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Memory {
    /// Time of the last observed state (s).
    t: Option<f64>,
    /// The torque answered to it (N m), held since.
    tau: f64,
    /// Filter states `(F[u], s F[u])` of `beta`, `tau`, `cos(beta)`, `sign(beta_dot)`.
    f: [[f64; 2]; 4],
    /// Normal equations of the least squares (upper triangle used) and right-hand side.
    ata: [[f64; 4]; 4],
    aty: [f64; 4],
    /// The estimates `(J, G, b, tau_c)`.
    est: [f64; 4],
    /// The inputs at the last observed state.
    u: [f64; 4],
    /// Flat samples fitted.
    n: u64,
    /// The largest scale the arm can take (from the estimates, every [`TARGET_EVERY`] fitted
    /// samples).
    safe: f64,
    /// Target scale, scale, its rate and acceleration.
    target: f64,
    r: (f64, f64, f64),
    /// Smallest scale reached.
    min_scale: f64,
}

/// The excitation law with its amplitude governor (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct GovernedExcitation {
    law: ComputedTorque,
    /// `A s_max` (rad): the reference's largest excursion at scale 1.
    reach: f64,
    /// `(s(phi), w^2 s''(phi))` at [`PHASES`] phases.
    table: Vec<(f64, f64)>,
    memory: Cell<Memory>,
}

/// What the governor has found (for reports).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GovernorStatus {
    /// The amplitude's scale in force (1: the requested amplitude).
    pub scale: f64,
    /// The smallest scale so far.
    pub min_scale: f64,
    /// The arm's estimated gravity torque coefficient `G = m_l l_c g` (N m).
    pub gravity: f64,
    /// The arm's estimated inertia about the joint `J` (kg m^2).
    pub inertia: f64,
}

impl GovernedExcitation {
    /// The governed version of `law`, whose reference must be the excitation.
    pub fn new(law: ComputedTorque) -> Self {
        let Trajectory::Excitation { amplitude, omega } = law.config().law.reference else {
            panic!("the amplitude governor needs the excitation");
        };
        let table: Vec<(f64, f64)> = (0..PHASES)
            .map(|i| {
                let (s, _, dds) = series(std::f64::consts::TAU * i as f64 / PHASES as f64);
                (s, omega * omega * dds)
            })
            .collect();
        let s_max = table.iter().fold(0.0f64, |m, &(s, _)| m.max(s.abs()));
        let p = law.config().params;
        let j = p.joint_inertia();
        let g = p.m_l * p.lc() * p.g;
        let prior = [j, g, p.b_v, p.tau_c];
        let mut ata = [[0.0; 4]; 4];
        let mut aty = [0.0; 4];
        for i in 0..4 {
            ata[i][i] = PRIOR_WEIGHT;
            aty[i] = PRIOR_WEIGHT * prior[i];
        }
        Self {
            law,
            reach: amplitude.abs() * s_max,
            table,
            memory: Cell::new(Memory {
                t: None,
                tau: 0.0,
                f: [[0.0; 2]; 4],
                ata,
                aty,
                est: prior,
                u: [0.0; 4],
                n: 0,
                safe: 1.0,
                target: 1.0,
                r: (1.0, 0.0, 0.0),
                min_scale: 1.0,
            }),
        }
    }

    /// The law without its memory (the settings).
    pub fn law(&self) -> &ComputedTorque {
        &self.law
    }

    /// What the governor has found so far.
    pub fn status(&self) -> GovernorStatus {
        let m = self.memory.get();
        GovernorStatus {
            scale: m.r.0,
            min_scale: m.min_scale,
            gravity: m.est[1],
            inertia: m.est[0],
        }
    }

    /// The joint torque (N m) for the state `x` in `mode` at `t` (s); observes the state.
    pub fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        let mut m = self.memory.get();
        let observe = m.t.is_none_or(|t0| t - t0 >= MIN_INTERVAL);
        if observe {
            self.observe(&mut m, t, mode, x);
        }
        let reference = self.law.config().law.reference.at_scaled(t, m.r);
        let tau = self.law.torque_for_reference(mode, x, reference);
        if observe {
            m.tau = tau;
            self.memory.set(m);
        }
        tau
    }

    /// Moves the filters, the least squares and the scale to the state `x` at `t`.
    fn observe(&self, m: &mut Memory, t: f64, mode: Mode, x: &State) {
        let inputs = [
            x[1],
            m.tau,
            x[1].cos(),
            x[3].signum() * f64::from(x[3] != 0.0),
        ];
        let Some(t0) = m.t else {
            // The filters start at rest on the first inputs (the held torque: the first answer).
            m.t = Some(t);
            m.u = inputs;
            for (f, u) in m.f.iter_mut().zip(inputs) {
                *f = [u, 0.0];
            }
            m.f[1] = [f64::NAN, 0.0];
            return;
        };
        let dt = t - t0;
        m.t = Some(t);
        if m.f[1][0].is_nan() {
            m.f[1] = [m.tau, 0.0];
        }
        let a = FILTER_RATE;
        // The filter's exact step over `dt` with the input held at `u` (critically damped:
        // `exp(A dt) = exp(-a dt) [[1 + a dt, dt], [-a^2 dt, 1 - a dt]]` about the rest point
        // `(u, 0)`). The torque is held over the interval (exact); the angles' inputs are the
        // interval's midpoint values (second order).
        let decay = (-a * dt).exp();
        for (i, f) in m.f.iter_mut().enumerate() {
            let u = if i == 1 {
                m.tau
            } else {
                0.5 * (m.u[i] + inputs[i])
            };
            let (d1, d2) = (f[0] - u, f[1]);
            f[0] = u + decay * ((1.0 + a * dt) * d1 + dt * d2);
            f[1] = decay * (-a * a * dt * d1 + (1.0 - a * dt) * d2);
        }
        m.u = inputs;
        if mode == Mode::Flat && dt < 10.0 * MIN_INTERVAL.max(1e-3) {
            let [b, tau, c, sg] = m.f;
            let row = [a * a * (x[1] - b[0]) - 2.0 * a * b[1], c[0], b[1], sg[0]];
            for i in 0..4 {
                for j in i..4 {
                    m.ata[i][j] += row[i] * row[j];
                }
                m.aty[i] += row[i] * tau[0];
            }
            if let Some(est) = solve(&m.ata, &m.aty) {
                m.est = est;
            }
            // The ramp's share of the amplitude [`LOOKAHEAD`] from now: while the ramp keeps
            // the motion below what the arm can take, the scale stays 1 (the estimate is
            // still forming then).
            let Trajectory::Excitation { omega, .. } = self.law.config().law.reference else {
                unreachable!("the governor runs the excitation")
            };
            let e = ramp_share((t + LOOKAHEAD) * omega / std::f64::consts::TAU);
            m.n += 1;
            if m.n.is_multiple_of(TARGET_EVERY) {
                m.safe = self.target(m.est[0], m.est[1]);
            }
            m.target = (m.safe / e.max(1e-9)).min(1.0);
        }
        // The scale follows the target, critically damped.
        let k = SCALE_RATE;
        let (r, rd) = (m.r.0, m.r.1);
        let rdd = k * k * (m.target - r) - 2.0 * k * rd;
        let rd = rd + dt * rdd;
        let r = r + dt * rd;
        m.r = (r, rd, k * k * (m.target - r) - 2.0 * k * rd);
        if m.target == 1.0 && (r - 1.0).abs() < 1e-12 && rd.abs() < 1e-12 {
            m.r = (1.0, 0.0, 0.0);
        }
        m.min_scale = m.min_scale.min(m.r.0);
    }

    /// The largest scale in `(0, 1]` whose reference the arm `(J, G)` can take (module docs).
    fn target(&self, j: f64, g: f64) -> f64 {
        let limit = excitation_torque_limit(&self.law.config().params);
        let mut r: f64 = 1.0;
        if g > 0.0 && self.reach > 0.0 {
            let s = GRAVITY_SHARE * limit / g;
            if s < 1.0 {
                r = r.min(s.asin() / self.reach);
            }
        }
        let Trajectory::Excitation { amplitude, .. } = self.law.config().law.reference else {
            return r;
        };
        // The feed-forward torque at scale `x`: max over the period of |J x A w^2 s'' - G
        // sin(x A s)| (cos(beta_d) = -sin(theta_d)); found by bisection (it grows with `x`).
        let ff = |x: f64| {
            self.table.iter().fold(0.0f64, |m, &(s, dds)| {
                m.max((j * x * amplitude * dds - g * (x * amplitude * s).sin()).abs())
            })
        };
        let cap = FEEDFORWARD_SHARE * limit;
        if ff(r) > cap {
            let (mut lo, mut hi) = (0.0, r);
            for _ in 0..12 {
                let mid = 0.5 * (lo + hi);
                if ff(mid) > cap {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            r = lo;
        }
        r.clamp(0.05, 1.0)
    }
}

/// Solves the symmetric positive definite `A x = b` (upper triangle of `A` given) by
/// Cholesky; `None` if it is not positive definite.
#[allow(clippy::needless_range_loop)] // the textbook's indices read best here
fn solve(a: &[[f64; 4]; 4], b: &[f64; 4]) -> Option<[f64; 4]> {
    let mut l = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..=i {
            let mut s = a[j][i];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s <= 0.0 {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0; 4];
    for i in 0..4 {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; 4];
    for i in (0..4).rev() {
        let mut s = y[i];
        for k in i + 1..4 {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    Some(x)
}

/// The ramp's value `e(u)` (its share of the amplitude).
fn ramp_share(u: f64) -> f64 {
    ramp(u).0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ControlConfig, LawSpec};
    use tilting_plant::Params;

    /// What a run of [`run`] saw after `settled` s.
    #[derive(Debug)]
    struct Seen {
        status: GovernorStatus,
        /// Largest `|beta - pi/2|` (rad).
        reach: f64,
    }

    /// Runs the governed default excitation at 1 kHz on a flat arm `J beta_ddot + G cos(beta)
    /// + b beta_dot = tau` (the plant's flat equation, integrated by RK4 with 10 steps per
    /// sample under the held torque) for `secs` s.
    fn run(j: f64, g: f64, b: f64, secs: f64, settled: f64) -> Seen {
        let law = ComputedTorque::new(ControlConfig::new(
            Params::default(),
            LawSpec {
                reference: crate::trajectory::EXCITATION_DEFAULT,
                ..LawSpec::without_adaptation()
            },
        ))
        .unwrap();
        let gov = GovernedExcitation::new(law);
        let (mut q, mut v) = (std::f64::consts::FRAC_PI_2, 0.0);
        let mut reach: f64 = 0.0;
        let h = 1e-3;
        let acc = |q: f64, v: f64, tau: f64| (tau - g * q.cos() - b * v) / j;
        for k in 0..(secs / h) as usize {
            let t = k as f64 * h;
            let tau = gov.torque(t, Mode::Flat, &State::new(0.0, q, 0.0, v));
            if t >= settled {
                reach = reach.max((q - std::f64::consts::FRAC_PI_2).abs());
            }
            let dt = h / 10.0;
            for _ in 0..10 {
                let (k1q, k1v) = (v, acc(q, v, tau));
                let (k2q, k2v) = (
                    v + 0.5 * dt * k1v,
                    acc(q + 0.5 * dt * k1q, v + 0.5 * dt * k1v, tau),
                );
                let (k3q, k3v) = (
                    v + 0.5 * dt * k2v,
                    acc(q + 0.5 * dt * k2q, v + 0.5 * dt * k2v, tau),
                );
                let (k4q, k4v) = (v + dt * k3v, acc(q + dt * k3q, v + dt * k3v, tau));
                q += dt / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
                v += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            }
        }
        Seen {
            status: gov.status(),
            reach,
        }
    }

    /// The estimate finds each arm's `G` and `J` within 0.1 % (the filter's step is exact for
    /// the held torque and second order in `a dt` = 0.008 for the angles' midpoint inputs;
    /// measured 1e-5). On the model's own arm (`J = 4`,
    /// `G = 19.62`: the paper's point mass at 2 m) and on a light arm the scale never leaves 1:
    /// the reference is the ungoverned one, bit for bit. On an arm 20 % heavier (with
    /// friction) the scale settles where the gravity torque at the reference's largest
    /// excursion is [`GRAVITY_SHARE`] of the clip, computed here from the true `G` and the
    /// excursion of [`Trajectory::at`] sampled over a period (within 1 %), and the arm stays
    /// where it can be held (`G sin(theta)` below the clip).
    #[test]
    fn the_governor_finds_the_arm_and_scales_only_a_heavy_one() {
        let limit = excitation_torque_limit(&Params::default());
        let tr = crate::trajectory::EXCITATION_DEFAULT;
        let Trajectory::Excitation { omega, .. } = tr else {
            unreachable!()
        };
        let period = std::f64::consts::TAU / omega;
        let reach = (0..20_000)
            .map(|i| {
                (tr.at(period * (1.0 + i as f64 / 20_000.0)).0 - std::f64::consts::FRAC_PI_2).abs()
            })
            .fold(0.0, f64::max);
        for (name, j, g, b) in [
            ("model", 4.0, 19.62, 0.0),
            ("heavy", 4.8, 1.2 * 19.62, 0.05),
            ("light", 2.56, 14.18, 0.05),
        ] {
            let seen = run(j, g, b, 40.0, 20.0);
            let st = seen.status;
            eprintln!("{name}: {seen:?}");
            assert!((st.gravity / g - 1.0).abs() < 1e-3, "{name}: {seen:?}");
            assert!((st.inertia / j - 1.0).abs() < 1e-3, "{name}: {seen:?}");
            if name == "heavy" {
                let want = (GRAVITY_SHARE * limit / g).asin() / reach;
                assert!(
                    (st.scale / want - 1.0).abs() < 0.01,
                    "want {want}: {seen:?}"
                );
                assert!(g * seen.reach.sin() < limit, "{seen:?}");
            } else {
                assert_eq!((st.scale, st.min_scale), (1.0, 1.0), "{name}: {seen:?}");
            }
        }
    }
}
