//! The sampled loop's Lyapunov exponents (`lyapunov::sampled`) against truths they did not
//! produce: the divergence of two nearby runs of the sampled loop (no Jacobian), and on a
//! stable orbit, above the hold's scale, the orbit's Floquet multiplier from the BVP's
//! variational equations (the continuous loop's exponent).

use nalgebra::Vector2;
use std::f64::consts::FRAC_PI_2;
use tilting_controller::ComputedTorque;
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::continuation::{self, Param};
use tilting_planner::lyapunov::sampled::{self, SampledLoop};
use tilting_planner::orbit::{self, OrbitProblem};
use tilting_plant::{
    mirror, ImpactLaw, Mode, Observer, Params, Plant, SimConfig, State, Transition,
};

fn base() -> (OrbitProblem, Sweep) {
    let pb = OrbitProblem::new(Params::default(), ImpactLaw::Paper, 100.0, 14.14);
    let st = continuation::start(&pb, 500.0).expect("the paper's orbit");
    (st.base, st.sweep)
}

/// Tilt starts `(beta0, beta_dot0)` (mirrored to a left tilt) of the sampled loop at period
/// `h` from the left-tilt start `x0`, over `tilts` tilts (one persistent plant, as the
/// simulator's sampled loop).
fn tilt_starts(q: &OrbitProblem, h: f64, x0: State, tilts: usize) -> Vec<Vector2<f64>> {
    struct Starts(Vec<Vector2<f64>>);
    impl Observer for Starts {
        fn transition(&mut self, ev: &Transition) {
            let x = match ev.to {
                Mode::Left => ev.x_after,
                Mode::Right => mirror(&ev.x_after),
                Mode::Flat => return,
            };
            self.0.push(Vector2::new(x[1] - FRAC_PI_2, x[3]));
        }
    }
    let law = ComputedTorque::new(q.control).unwrap();
    let cfg = SimConfig {
        params: q.params,
        impact: q.impact,
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
    let mut obs = Starts(vec![Vector2::new(x0[1] - FRAC_PI_2, x0[3])]);
    let mut n = 0u64;
    while obs.0.len() <= tilts {
        let tau = plant.torque_now(&law);
        plant
            .advance_held(tau, (n + 1) as f64 * h, &mut obs)
            .unwrap();
        n += 1;
    }
    obs.0
}

#[test]
fn on_a_stable_orbit_nearby_runs_approach_at_the_flows_rate_until_the_holds_scale() {
    let (pb, sw) = base();
    let k = 1000.0;
    let q = Param::K.set(&pb, k).unwrap();
    let s = orbit::solve(
        &q,
        bifurcation::attracting_orbit_guess(&sw, k, 300).unwrap(),
    )
    .unwrap();
    let mu = s
        .multipliers
        .iter()
        .map(|m| m[0].hypot(m[1]))
        .fold(0.0, f64::max);
    // Above the hold's scale the sampled loop is the continuous one: two runs 1e-3 apart
    // approach by the orbit's multiplier per tilt (a complex pair here, |mu| = 0.34: the
    // distance turns with it, so the rate is taken over 4 tilts, down to ~1e-5, still 10x the
    // scatter a 10 us hold leaves).
    let x0 = OrbitProblem::start(s.beta0, s.beta_dot0);
    let mut x1 = x0;
    x1[3] += 1e-3;
    let h = 1e-5;
    let (a, b) = (tilt_starts(&q, h, x0, 4), tilt_starts(&q, h, x1, 4));
    let d: Vec<f64> = a.iter().zip(&b).map(|(u, v)| (u - v).norm()).collect();
    let rate = (d[4] / d[0]).ln() / 4.0;
    assert!(
        (rate - mu.ln()).abs() < 0.15 * mu.ln().abs(),
        "per tilt {rate} vs ln|mu| = {}; distances {d:?}",
        mu.ln()
    );
    // Below it, the largest exponent is positive at any hold: after each landing the plate
    // rests flat until the next sample, a time that moves with the landing's (slope -1, a
    // jump of h at each sample instant), so two runs closer than the hold's scale part, and
    // the exponent does not shrink with h (what shrinks is the band they part within).
    let start = Vector2::new(s.beta0, s.beta_dot0);
    let l: Vec<f64> = [1e-3, 2.5e-4]
        .iter()
        .map(|&h| {
            let lp = SampledLoop::new(&q, h).unwrap();
            let sp = sampled::largest(&lp, start, 20, 200).unwrap();
            let fd = sampled::largest_fd(&lp, start, 20, 200, 1e-8, 20).unwrap();
            // The Jacobian's exponent against two runs 1e-8 apart (no Jacobian): the same
            // motion averaged over 200 tilts by two codes, agreeing to 1 %.
            assert!(
                (sp.lambda1 - fd).abs() < 0.01 * fd.abs(),
                "h = {h}: {sp:?} vs {fd}"
            );
            assert!(sp.lambda1 > 0.5, "h = {h}: {sp:?}");
            sp.lambda1
        })
        .collect();
    assert!((l[0] - l[1]).abs() < 0.1 * l[0], "{l:?}");
}

#[test]
fn past_the_cascade_the_sampled_loop_is_chaotic_and_matches_two_nearby_runs() {
    let (pb, sw) = base();
    let q = Param::K.set(&pb, 2400.0).unwrap();
    let lp = SampledLoop::new(&q, 1e-3).unwrap();
    let start = Vector2::new(sw.start_beta0, sw.start_beta_dot0);
    let sp = sampled::largest(&lp, start, 100, 500).unwrap();
    let fd = sampled::largest_fd(&lp, start, 100, 500, 1e-8, 20).unwrap();
    assert!(sp.lambda1 > 0.05, "{sp:?}");
    // Two averages over 500 tilts of a chaotic motion by two codes (a fresh plant per period
    // against one persistent plant): their runs part after dozens of tilts, so they agree as
    // averages (~1/sqrt(500) relative scatter each), not bit for bit.
    assert!(
        (sp.lambda1 - fd).abs() < 0.1 * sp.lambda1,
        "Jacobian {} vs two runs {fd}",
        sp.lambda1
    );
}

#[test]
fn a_bad_control_period_is_refused_naming_its_range() {
    let (pb, _) = base();
    for h in [0.0, -1e-3, 0.1, f64::NAN] {
        let e = SampledLoop::new(&pb, h).err().expect("refused");
        assert!(
            e.contains("control period") && e.contains("(0, 0.05]"),
            "{e}"
        );
    }
}
