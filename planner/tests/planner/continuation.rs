//! Continuation, branch switching and the Lyapunov exponent checked against truths they did
//! not produce: every point re-simulated by the hybrid simulator, the multipliers against a
//! finite-difference monodromy of the simulator's return map, the tilt map's saltation against
//! finite differences across one impact, the flip against the natural-parameter bisection of
//! `bifurcation::k_star` and the sweep's period changes, the exponent of a stable orbit against
//! its multiplier and of a chaotic motion against two nearby simulated trajectories.

use nalgebra::{Matrix2, Vector2};
use std::f64::consts::FRAC_PI_2;
use tilting_controller::ComputedTorque;
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::continuation::{self, Diagram, EventKind, Param, Point, Settings};
use tilting_planner::lyapunov;
use tilting_planner::orbit::{self, eigenvalues2, OrbitProblem};
use tilting_plant::{
    mirror, ImpactLaw, Mode, Observer, Params, Plant, SimConfig, Tolerance, Transition,
};

fn base() -> (OrbitProblem, Sweep) {
    let pb = OrbitProblem::new(Params::default(), ImpactLaw::Paper, 100.0, 14.14);
    let o = orbit::smallest(&pb).expect("the paper's orbit");
    let sw = Sweep {
        problem: pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: o.energy_avg,
        tilts: 600,
        keep: 64,
        period_tol: 1e-5,
    };
    (pb.with_adaptation(500.0, o.energy_avg), sw)
}

fn settings(p_max: f64, max_period: usize) -> Settings {
    Settings {
        p_min: 0.0,
        p_max,
        ds: 10.0,
        ds_min: 1e-3,
        ds_max: 20.0,
        max_steps: 500,
        locate_tol: 1e-7,
        max_period,
        stop_at_first_event: false,
    }
}

fn cascade_to(p_max: f64, max_period: usize) -> (OrbitProblem, Sweep, Diagram) {
    let (pb, sw) = base();
    let guess = bifurcation::attracting_orbit_guess(&sw, 500.0, 200).unwrap();
    let d = continuation::diagram(
        &pb,
        Param::K,
        500.0,
        guess,
        &settings(p_max, max_period),
        &|_, _| {},
    )
    .expect("continuation");
    (pb, sw, d)
}

#[derive(Default)]
struct Events(Vec<Transition>);
impl Observer for Events {
    fn transition(&mut self, ev: &Transition) {
        self.0.push(*ev);
    }
}

/// The mirrored half-period map by the hybrid simulator (tight tolerance): a left-tilt start
/// `(beta0, beta_dot0)` to the mirrored start of the next tilt, and the tilt's duration.
fn simulated_map(pb: &OrbitProblem, z: [f64; 2]) -> ([f64; 2], f64) {
    let law = ComputedTorque::new(pb.control).unwrap();
    let cfg = SimConfig {
        params: pb.params,
        impact: pb.impact,
        tol: Tolerance {
            rtol: 1e-12,
            atol: 1e-14,
        },
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, OrbitProblem::start(z[0], z[1])).unwrap();
    let mut ev = Events::default();
    let mut t = 0.0;
    while !ev.0.iter().any(|e| e.to == Mode::Right) {
        t += 0.05;
        plant.advance_continuous(&law, t, &mut ev).unwrap();
        assert!(t < 5.0, "no landing");
    }
    let right = ev.0.iter().find(|e| e.to == Mode::Right).unwrap();
    let m = mirror(&right.x_after);
    ([m[1] - FRAC_PI_2, m[3]], right.t)
}

/// Central differences of `n` simulated tilts from `z` (h = 1e-5: truncation ~h^2 with the
/// map's curvature, round-off ~1e-12/h = 1e-7).
fn fd_jacobian(pb: &OrbitProblem, z: [f64; 2], n: usize) -> Matrix2<f64> {
    let iterate = |mut z: [f64; 2]| {
        for _ in 0..n {
            z = simulated_map(pb, z).0;
        }
        z
    };
    let h = 1e-5;
    let mut jac = Matrix2::zeros();
    for j in 0..2 {
        let (mut zp, mut zm) = (z, z);
        zp[j] += h;
        zm[j] -= h;
        let (p, m) = (iterate(zp), iterate(zm));
        jac[(0, j)] = (p[0] - m[0]) / (2.0 * h);
        jac[(1, j)] = (p[1] - m[1]) / (2.0 * h);
    }
    jac
}

fn sorted(mut v: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    v.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    v
}

/// The point's multipliers against the eigenvalues of the simulator's finite-difference
/// monodromy over its tilts.
fn check_multipliers(pb: &OrbitProblem, pt: &Point) {
    let q = Param::K.set(pb, pt.p).unwrap();
    let fd = sorted(eigenvalues2(&fd_jacobian(
        &q,
        [pt.z[0], pt.z[1]],
        pt.z.len() / 3,
    )));
    let ours = sorted(pt.multipliers.clone());
    for (a, b) in ours.iter().zip(&fd) {
        assert!(
            (a[0] - b[0]).abs() < 1e-4 && (a[1] - b[1]).abs() < 1e-4,
            "k = {}: sensitivities {ours:?} vs finite differences {fd:?}",
            pt.p
        );
    }
}

#[test]
fn the_period_one_branch_flips_at_k_star_and_its_points_solve_the_bvp() {
    let (pb, sw, d) = cascade_to(2000.0, 1);
    let br = &d.branches[0];
    assert_eq!(br.tilts, 1);
    assert!(br.points.len() > 20, "{} points", br.points.len());
    for pt in &br.points {
        // The BVP's residual, and the hybrid simulator's own landing against the next start
        // (integrated at rtol 1e-12: 1e-9 covers its error over one tilt).
        assert!(
            pt.residual < 1e-10,
            "k = {}: residual {:e}",
            pt.p,
            pt.residual
        );
        assert!(
            pt.resimulated_mismatch < 1e-9,
            "k = {}: mismatch {:e}",
            pt.p,
            pt.resimulated_mismatch
        );
    }
    let flips: Vec<_> = br
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Flip)
        .collect();
    assert_eq!(
        flips.len(),
        1,
        "{:?}",
        br.events.iter().map(|e| (e.kind, e.p)).collect::<Vec<_>>()
    );
    let k1 = flips[0].p;
    // The paper's k* as the project reproduces it (README, docs/model.md): 1923.99.
    assert!((k1 - 1923.99).abs() < 0.01, "k_1 = {k1}");
    // The natural-parameter bisection of the lowest multiplier (a different algorithm).
    let ks = bifurcation::k_star(&sw, 500.0, 1900.0, 1950.0, 1e-6).unwrap();
    assert!(
        (k1 - ks).abs() < 1e-5,
        "continuation {k1} vs bisection {ks}"
    );
    // At the located point a multiplier is -1.
    let mu = &flips[0].point.multipliers;
    assert!(
        mu.iter().any(|m| (m[0] + 1.0).abs() < 1e-6 && m[1] == 0.0),
        "{mu:?}"
    );
    // Stable before the flip, unstable after.
    for pt in &br.points {
        assert_eq!(pt.stable, pt.p < k1, "k = {}: {:?}", pt.p, pt.multipliers);
    }
    // Multipliers against the simulator's finite-difference monodromy, at the start, near the
    // flip and on the unstable part.
    for k in [500.0, 1900.0, 1990.0] {
        let pt = br
            .points
            .iter()
            .min_by(|a, b| (a.p - k).abs().total_cmp(&(b.p - k).abs()))
            .unwrap();
        check_multipliers(&pb, pt);
    }
}

#[test]
fn the_tilt_maps_saltation_matches_finite_differences_across_one_impact() {
    let (pb, _) = base();
    let law = ComputedTorque::new(pb.control).unwrap();
    // Off any orbit: a start the map moves.
    for z in [[0.01, 0.45], [-0.02, 0.55]] {
        let s = lyapunov::tilt(&pb, &law, Vector2::from(z)).unwrap();
        let (next, t) = simulated_map(&pb, z);
        assert!(
            (s.next - Vector2::from(next)).norm() < 1e-8,
            "{:?} vs {next:?}",
            s.next
        );
        assert!((s.t - t).abs() < 1e-9);
        let fd = fd_jacobian(&pb, z, 1);
        assert!(
            (s.jac - fd).abs().max() < 1e-5,
            "saltation {} vs finite differences {fd}",
            s.jac
        );
    }
}

#[test]
fn the_lyapunov_exponent_of_a_stable_orbit_is_its_multiplier_per_period() {
    let (pb, sw) = base();
    for k in [1000.0, 1800.0] {
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
        let expect = mu.ln() / s.t_end;
        let (lambda, per_tilt) =
            lyapunov::largest(&q, Vector2::new(s.beta0, s.beta_dot0), 0, 3000).unwrap();
        // Started on the orbit: the average converges as 1/n (the second multiplier's share,
        // or a complex pair's rotation, bounds the sum of the logs), 3000 tilts give 1e-3.
        assert!(
            (lambda - expect).abs() < 1e-3 * expect.abs(),
            "k = {k}: {lambda} vs {expect}"
        );
        assert!((per_tilt - mu.ln()).abs() < 1e-3 * mu.ln().abs());
        assert!(lambda < 0.0);
    }
}

#[test]
fn the_lyapunov_exponent_is_positive_past_the_cascade_and_matches_nearby_trajectories() {
    let (pb, sw) = base();
    let q = Param::K.set(&pb, 2400.0).unwrap();
    let start = Vector2::new(sw.start_beta0, sw.start_beta_dot0);
    let (lambda, _) = lyapunov::largest(&q, start, 200, 1500).unwrap();
    let (fd, _) = lyapunov::largest_fd(&q, start, 200, 1500, 1e-8).unwrap();
    assert!(lambda > 0.05, "lambda = {lambda}");
    // Two estimates over 1500 tilts of a chaotic motion: their trajectories part after a few
    // dozen tilts, so they agree as averages (~1/sqrt(1500) relative scatter), not bit for bit.
    assert!(
        (lambda - fd).abs() < 0.15 * lambda,
        "variational {lambda} vs two trajectories {fd}"
    );
}

#[test]
fn the_later_flips_lie_where_the_sweep_changes_period() {
    let (_, sw, d) = cascade_to(2240.0, 8);
    assert!(d.flips.len() >= 4, "flips {:?}", d.flips);
    // Period 2^(n-1) a little below flip n, 2^n a little above, in plain simulations of the
    // loop (3000 tilts: near a flip the transient decays slowly); the margins are a third of
    // the distance to the neighbouring flips.
    let sweep = Sweep {
        tilts: 3000,
        keep: 64,
        period_tol: 1e-6,
        ..sw
    };
    for n in 1..3 {
        let (k, next) = (d.flips[n], d.flips[n + 1]);
        let m = (next - k) / 3.0;
        let below = bifurcation::run_one(&sweep, k - m);
        let above = bifurcation::run_one(&sweep, k + m);
        assert_eq!(
            below.period,
            Some(1 << n),
            "k = {}: {:?}",
            k - m,
            &below.peaks[..8]
        );
        assert_eq!(
            above.period,
            Some(2 << n),
            "k = {}: {:?}",
            k + m,
            &above.peaks[..8]
        );
    }
    // The period-2 branch at k = 2100 is the orbit the loop converges to: same peaks.
    let br = &d.branches[1];
    let pt = br
        .points
        .iter()
        .min_by(|a, b| (a.p - 2100.0).abs().total_cmp(&(b.p - 2100.0).abs()))
        .unwrap();
    let row = bifurcation::run_one(&sweep, pt.p);
    let (mut ours, mut sim) = (pt.peaks.clone(), row.peaks[row.peaks.len() - 2..].to_vec());
    ours.sort_by(f64::total_cmp);
    sim.sort_by(f64::total_cmp);
    for (a, b) in ours.iter().zip(&sim) {
        assert!(
            (a - b).abs() < 1e-8,
            "branch {ours:?} vs simulation {sim:?}"
        );
    }
    // Its points re-simulate as 2-cycles, and its multipliers match the simulator's
    // finite-difference monodromy of two tilts.
    for pt in &br.points {
        assert!(
            pt.residual < 1e-10 && pt.resimulated_mismatch < 1e-9,
            "k = {}",
            pt.p
        );
    }
    let (pb, _) = base();
    check_multipliers(&pb, pt);
}

#[test]
fn the_physical_laws_cascade_about_a_planned_peak_is_feigenbaums_and_the_simulations() {
    // The physical landing law (no k = 0 orbit): the loop K_D = 10 adapted at k = 500 about
    // its orbit with the peak 0.04 rad (`start_at_peak`), continued in k. Truths it did not
    // produce: the flips' ratios approach Feigenbaum's universal delta, and plain simulations
    // of the loop (the sweep) change period where the flips lie.
    let params = Params {
        impact: ImpactLaw::Physical,
        ..Params::default()
    };
    let pb = OrbitProblem::new(params, ImpactLaw::Physical, 100.0, 10.0);
    let st = continuation::start_at_peak(&pb, 500.0, 0.04).unwrap();
    assert!((st.orbit.max_tilt - 0.04).abs() < 1e-9 && st.orbit.stable);
    let d = continuation::diagram(
        &st.base,
        Param::K,
        500.0,
        st.guess,
        &Settings {
            ds: 5.0,
            ds_max: 10.0,
            ..settings(1300.0, 8)
        },
        &|_, _| {},
    )
    .unwrap();
    assert!(d.flips.len() >= 4, "flips {:?}", d.flips);
    // delta_n -> 4.6692: the third ratio within 5 % (the paper's law's converge as fast).
    let r = d.ratios[1];
    assert!(
        (r - continuation::FEIGENBAUM_DELTA).abs() < 0.05 * continuation::FEIGENBAUM_DELTA,
        "ratios {:?}",
        d.ratios
    );
    let sweep = Sweep {
        tilts: 3000,
        keep: 64,
        period_tol: 1e-6,
        ..st.sweep
    };
    for n in 0..2 {
        let (k, next) = (d.flips[n], d.flips[n + 1]);
        let m = (next - k) / 3.0;
        let (below, above) = (
            bifurcation::run_one(&sweep, k - m),
            bifurcation::run_one(&sweep, k + m),
        );
        assert_eq!(below.period, Some(1 << n), "k = {}", k - m);
        assert_eq!(above.period, Some(2 << n), "k = {}", k + m);
    }
}
