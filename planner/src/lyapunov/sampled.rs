//! The Lyapunov exponents of the sampled loop (issue 19, item 3's last sentence): the plant under
//! the controller's zero-order hold, the law evaluated on the state at `t_n = n h` and its torque
//! held over `[t_n, t_{n+1}]` ([`Plant::advance_held`], as `tilting_sim::closed_loop::run_sampled`
//! does at 1 kHz).
//!
//! That loop is a map `F: (mode, x)(t_n) -> (mode, x)(t_{n+1})` of the hybrid plant's state at the
//! sample instants (the law here has no state of its own), smooth wherever no event falls on a
//! sample instant: inside a period the plant may land, take the impact and tilt back, all under
//! the held torque, exactly as the simulator does. Its Jacobian is taken by forward differences
//! of `F` along the tangent vectors (each evaluation a fresh [`Plant`] over one period, so
//! nominal and perturbed runs take the same integrator steps and the quotient is smooth), with a
//! backward difference when the forward one leaves the nominal mode (a landing that moves across
//! the sample instant). Benettin's method with two vectors, re-orthonormalised after every
//! period, gives the two largest exponents (1/s):
//!
//! `lambda_i = sum_n ln r_ii(n) / (N h)`.
//!
//! What the hold changes (measured, `planner/tests/planner/sampled_lyapunov.rs`): after each landing
//! the plate rests flat under the torque held from the last sample until the next sample
//! switches it and it tilts back. That rest lasts from the landing to the next sample instant:
//! a sawtooth in the landing time (slope -1, a jump of `h` at each sample instant). Between the
//! jumps it stretches the tangent space, so the largest exponent is positive at every `k`
//! (about 1.8-1.9 1/s at 1 kHz, the same at 0.25 and 0.1 ms: it does not shrink with `h`),
//! even where the continuous loop's orbit is stable. What shrinks with `h` is the band the
//! motion wanders in: the jumps fold it back, so two runs part only up to the hold's scale (the
//! tilt peaks scatter by 5e-4 rad at 1 ms, 8e-5 at 0.25 ms, 3e-5 at 0.1 ms around the
//! continuous orbit's). Above that scale the sampled loop is the continuous one: two runs 1e-3
//! apart approach by the orbit's Floquet multiplier per tilt. [`largest_fd`] measures the
//! largest exponent from two nearby runs of the sampled loop itself.

use crate::orbit::OrbitProblem;
use nalgebra::{Vector2, Vector4};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tilting_controller::{ComputedTorque, PlannableLaw};
use tilting_plant::{Mode, Plant, SimConfig, State};

/// The relative step of the forward differences: the map over one period is the same sequence
/// of integrator steps for the nominal and the perturbed state (a fresh plant each), so its
/// quotient carries truncation `~1e-7` and rounding `~1e-16 / 1e-7` relative.
const EPS: f64 = 1e-7;

/// The sampled loop: the plant's configuration, the law (the paper's by default, any
/// [`PlannableLaw`] by [`SampledLoop::with_law`]) and the control period.
pub struct SampledLoop<L = ComputedTorque> {
    cfg: SimConfig,
    law: L,
    /// Control period `h` (s).
    pub period: f64,
}

/// The hybrid state at a sample instant.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    /// The plate's contact mode.
    pub mode: Mode,
    /// The state `(alpha, beta, alpha_dot, beta_dot)` (rad, rad/s).
    pub x: State,
}

impl SampledLoop {
    /// The loop of `pb` (model, impact law and controller) sampled every `period` seconds.
    /// Errors name the period's allowed range.
    pub fn new(pb: &OrbitProblem, period: f64) -> Result<Self, String> {
        Self::with_law(pb, pb.law(), period)
    }
}

impl<L: PlannableLaw> SampledLoop<L> {
    /// The loop of `pb`'s model and impact law closed by `law`, sampled every `period`
    /// seconds. Errors name the period's allowed range.
    pub fn with_law(pb: &OrbitProblem, law: L, period: f64) -> Result<Self, String> {
        if !(period.is_finite() && period > 0.0 && period <= 0.05) {
            return Err(format!(
                "invalid control period {period} s: must be in (0, 0.05]"
            ));
        }
        Ok(Self {
            cfg: SimConfig {
                params: pb.params,
                impact: pb.impact,
                ..SimConfig::default()
            },
            law,
            period,
        })
    }

    /// One control period from `s` at sample `n` (time `n h`): the state at the next sample and
    /// the tilts started inside the period.
    pub fn step(&self, n: u64, s: &Sample) -> Result<(Sample, u64), String> {
        let t = n as f64 * self.period;
        let mut plant = Plant::new(self.cfg, t, s.mode, s.x).map_err(|e| e.to_string())?;
        let tau = plant.torque_now(&self.law);
        plant
            .advance_held(tau, (n + 1) as f64 * self.period, &mut ())
            .map_err(|e| e.to_string())?;
        Ok((
            Sample {
                mode: plant.mode(),
                x: plant.state(),
            },
            plant.tilts(),
        ))
    }

    /// `DF v` at `s` (whose image is `next`) by a forward difference, or a backward one when
    /// the forward image is in another mode than `next` (or the perturbed start is not a valid
    /// state of its mode). On the flat plate (`alpha = alpha_dot = 0`, the map defined on
    /// `(beta, beta_dot)` only) the tilt part of `v` is dropped.
    fn directional(
        &self,
        n: u64,
        s: &Sample,
        next: &Sample,
        v: &Vector4<f64>,
    ) -> Result<Vector4<f64>, String> {
        let mut v = *v;
        if s.mode == Mode::Flat {
            v[0] = 0.0;
            v[2] = 0.0;
        }
        let h = EPS * (1.0 + s.x.norm());
        for sign in [1.0, -1.0] {
            let p = Sample {
                mode: s.mode,
                x: s.x + v * (sign * h),
            };
            if let Ok((q, _)) = self.step(n, &p) {
                if q.mode == next.mode {
                    return Ok((q.x - next.x) / (sign * h));
                }
            }
        }
        Err(format!(
            "no one-sided difference stays in mode {:?} at t = {:.4} s",
            next.mode,
            n as f64 * self.period
        ))
    }
}

/// The two largest exponents of the sampled loop and what they were averaged over.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spectrum {
    /// Largest exponent (1/s).
    pub lambda1: f64,
    /// Second exponent (1/s).
    pub lambda2: f64,
    /// Control periods averaged.
    pub periods: u64,
    /// Tilts in them.
    pub tilts: u64,
}

/// Runs the loop from `s` at sample `n` until `tilts` tilts have ended, calling `each(n, s,
/// next)` on every period; returns the sample reached and its index. Errors: a step fails, or no
/// tilt for 10 s (the loop came to rest).
fn run<L: PlannableLaw>(
    lp: &SampledLoop<L>,
    mut s: Sample,
    mut n: u64,
    tilts: usize,
    mut each: impl FnMut(u64, &Sample, &Sample) -> Result<(), String>,
) -> Result<(Sample, u64), String> {
    let limit = (10.0 / lp.period) as u64;
    let (mut seen, mut last_tilt) = (0u64, n);
    while seen < tilts as u64 {
        let (next, k) = lp.step(n, &s)?;
        each(n, &s, &next)?;
        s = next;
        n += 1;
        seen += k;
        if k > 0 {
            last_tilt = n;
        }
        if n - last_tilt > limit {
            return Err(format!(
                "no tilt for 10 s after t = {:.3} s",
                last_tilt as f64 * lp.period
            ));
        }
    }
    Ok((s, n))
}

/// Benettin's two largest exponents of the sampled loop `lp` from the tilt start `(beta0,
/// beta_dot0)` (rad, rad/s; a left tilt at rest): `transient` tilts discarded, then averaged
/// over the periods of `tilts` tilts.
pub fn largest<L: PlannableLaw>(
    lp: &SampledLoop<L>,
    start: Vector2<f64>,
    transient: usize,
    tilts: usize,
) -> Result<Spectrum, String> {
    let s0 = Sample {
        mode: Mode::Left,
        x: OrbitProblem::start(start[0], start[1]),
    };
    let (s, n0) = run(lp, s0, 0, transient, |_, _, _| Ok(()))?;
    let mut v1 = Vector4::new(0.0, 1.0, 0.0, 1.0).normalize();
    let mut v2 = Vector4::new(1.0, 0.0, 1.0, -0.5).normalize();
    v2 = (v2 - v1 * v1.dot(&v2)).normalize();
    let (mut sum1, mut sum2) = (0.0, 0.0);
    let (_, n) = run(lp, s, n0, tilts, |n, s, next| {
        let w1 = lp.directional(n, s, next, &v1)?;
        let w2 = lp.directional(n, s, next, &v2)?;
        // Gram-Schmidt: the growth of the line, then of the plane over the line.
        let r11 = w1.norm();
        let u2 = w2 - (w1 / r11) * (w1 / r11).dot(&w2);
        let r22 = u2.norm();
        if !(r11 > 0.0 && r11.is_finite() && r22 > 0.0 && r22.is_finite()) {
            return Err(format!(
                "the tangent plane collapsed at t = {:.4} s",
                n as f64 * lp.period
            ));
        }
        (v1, v2) = (w1 / r11, u2 / r22);
        sum1 += r11.ln();
        sum2 += r22.ln();
        Ok(())
    })?;
    let time = (n - n0) as f64 * lp.period;
    Ok(Spectrum {
        lambda1: sum1 / time,
        lambda2: sum2 / time,
        periods: n - n0,
        tilts: tilts as u64,
    })
}

/// The largest exponent from two nearby runs of the sampled loop (no Jacobian): each run one
/// persistent [`Plant`] under the held torques, as the simulator's sampled loop. Every
/// `renorm` periods, when both are in the same mode, the distance `d` of the neighbour is
/// measured and the neighbour restarted `delta` from the reference along `d`. Returns the
/// exponent (1/s).
pub fn largest_fd<L: PlannableLaw>(
    lp: &SampledLoop<L>,
    start: Vector2<f64>,
    transient: usize,
    tilts: usize,
    delta: f64,
    renorm: u64,
) -> Result<f64, String> {
    let cfg = lp.cfg;
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let mut a = Plant::new(
        cfg,
        0.0,
        Mode::Left,
        OrbitProblem::start(start[0], start[1]),
    )
    .map_err(|e| err(&e))?;
    let mut n = 0u64;
    let run = |p: &mut Plant, n: u64| -> Result<(), String> {
        let tau = p.torque_now(&lp.law);
        p.advance_held(tau, (n + 1) as f64 * lp.period, &mut ())
            .map_err(|e| err(&e))
    };
    while (a.tilts() as usize) < transient {
        run(&mut a, n)?;
        n += 1;
        if n as f64 * lp.period > 10.0 * (transient as f64 + 1.0) {
            return Err("the transient does not tilt".into());
        }
    }
    let dir = Vector4::new(0.0, 1.0, 0.0, 1.0).normalize();
    let restart = |a: &Plant, d: Vector4<f64>, n: u64| {
        Plant::new(cfg, n as f64 * lp.period, a.mode(), a.state() + d).map_err(|e| err(&e))
    };
    let mut b = restart(&a, dir * delta, n)?;
    let (t0, tilts0) = (n, a.tilts());
    let mut since = 0u64;
    let mut sum = 0.0;
    let mut measured_to = n;
    while ((a.tilts() - tilts0) as usize) < tilts {
        run(&mut a, n)?;
        run(&mut b, n)?;
        n += 1;
        since += 1;
        if since >= renorm && a.mode() == b.mode() {
            let d = b.state() - a.state();
            let r = d.norm();
            if r > 0.0 && r.is_finite() {
                if let Ok(nb) = restart(&a, d * (delta / r), n) {
                    sum += (r / delta).ln();
                    b = nb;
                    since = 0;
                    measured_to = n;
                }
            }
        }
    }
    let _ = t0;
    Ok(sum / ((measured_to - t0) as f64 * lp.period))
}

/// The sampled loop's two largest exponents at one parameter value.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SampledExponent {
    /// Parameter value.
    pub p: f64,
    /// Control period (s).
    pub period: f64,
    /// Largest exponent (1/s), `None` when the run faulted.
    pub lambda: Option<f64>,
    /// Second exponent (1/s).
    pub lambda2: Option<f64>,
    /// Control periods averaged.
    pub periods: u64,
    /// Tilts averaged over.
    pub tilts: u64,
    /// Why the exponents are not defined, if they are not.
    pub fault: Option<String>,
}

/// The sampled loop's two largest exponents over the values `ps` of a parameter set by `at`
/// (on all cores), each from the tilt start `(beta0, beta_dot0)` (rad, rad/s); `tick` after
/// each value.
pub fn curve(
    ps: &[f64],
    at: &(dyn Fn(f64) -> Result<OrbitProblem, String> + Sync),
    period: f64,
    start: [f64; 2],
    transient: usize,
    tilts: usize,
    tick: &(dyn Fn() + Sync),
) -> Vec<SampledExponent> {
    ps.par_iter()
        .map(|&p| {
            let r = at(p)
                .and_then(|pb| SampledLoop::new(&pb, period))
                .and_then(|lp| largest(&lp, Vector2::from(start), transient, tilts));
            tick();
            match r {
                Ok(s) => SampledExponent {
                    p,
                    period,
                    lambda: Some(s.lambda1),
                    lambda2: Some(s.lambda2),
                    periods: s.periods,
                    tilts: s.tilts,
                    fault: None,
                },
                Err(e) => SampledExponent {
                    p,
                    period,
                    lambda: None,
                    lambda2: None,
                    periods: 0,
                    tilts: 0,
                    fault: Some(e),
                },
            }
        })
        .collect()
}
