//! The planner checked against truths it did not produce: the orbit re-simulated by the hybrid
//! simulator, its multipliers against a finite-difference monodromy of the full hybrid return
//! map, the mirror symmetry, the sinusoid solution against a closed-loop simulation, and k*
//! against the onset of period two in the sweep.

use std::f64::consts::{FRAC_PI_2, PI};
use tilting_controller::{ComputedTorque, ControlConfig, LawSpec, Trajectory};
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::orbit::{self, eigenvalues2, OrbitProblem, OrbitSolution};
use tilting_planner::sinusoid::{self, Search};
use tilting_plant::{
    mirror, ImpactLaw, Mode, Observer, Params, Plant, SimConfig, State, Tolerance, Transition,
};

#[derive(Default)]
struct Events(Vec<Transition>);
impl Observer for Events {
    fn transition(&mut self, ev: &Transition) {
        self.0.push(*ev);
    }
}

fn tight() -> SimConfig {
    SimConfig {
        tol: Tolerance {
            rtol: 1e-12,
            atol: 1e-14,
        },
        ..SimConfig::default()
    }
}

fn paper_orbit() -> (OrbitProblem, OrbitSolution) {
    let pb = OrbitProblem::new(Params::default(), ImpactLaw::Paper, 100.0, 14.14);
    let sols = orbit::find_all(&pb);
    assert!(!sols.is_empty(), "no orbit found");
    let s = sols[0].clone();
    (pb, s)
}

/// Runs the hybrid loop from `x0` in `mode` until `n` transitions into `target` have happened.
fn run_until(
    law: &ComputedTorque,
    mode: Mode,
    x0: State,
    target: Mode,
    n: usize,
) -> Vec<Transition> {
    let mut plant = Plant::new(tight(), 0.0, mode, x0).unwrap();
    let mut ev = Events::default();
    let mut t = 0.0;
    while ev.0.iter().filter(|e| e.to == target).count() < n {
        t += 0.05;
        plant.advance_continuous(law, t, &mut ev).unwrap();
        assert!(t < 20.0, "no transition into {target}");
    }
    ev.0
}

#[test]
fn orbit_is_a_periodic_hybrid_solution_when_resimulated() {
    let (pb, s) = paper_orbit();
    let law = ComputedTorque::new(pb.control).unwrap();
    let x0 = OrbitProblem::start(s.beta0, s.beta_dot0);
    // Half a period: land at t_end and start the right tilt in the mirrored state.
    let ev = run_until(&law, Mode::Left, x0, Mode::Right, 1);
    let land = ev.iter().find(|e| e.from == Mode::Left).unwrap();
    let right = ev.iter().find(|e| e.to == Mode::Right).unwrap();
    assert!((land.t - s.t_end).abs() < 1e-9, "{} vs {}", land.t, s.t_end);
    assert_eq!(right.t, land.t, "the right tilt starts at the landing");
    assert!((right.x_after - mirror(&x0)).norm() < 1e-9);
    // A full period: back at the start.
    let ev = run_until(&law, Mode::Left, x0, Mode::Left, 1);
    let back = ev.iter().find(|e| e.to == Mode::Left).unwrap();
    assert!((back.t - s.period).abs() < 1e-8);
    assert!((back.x_after - x0).norm() < 1e-8);
    // The orbit of the paper is unstable (one multiplier outside the unit circle).
    assert!(!s.stable);
    assert!(s.max_tilt > 0.0 && s.max_tilt < 0.1);
}

#[test]
fn orbit_mirror_image_is_the_right_started_orbit() {
    let (pb, s) = paper_orbit();
    let law = ComputedTorque::new(pb.control).unwrap();
    let x0 = mirror(&OrbitProblem::start(s.beta0, s.beta_dot0));
    let ev = run_until(&law, Mode::Right, x0, Mode::Left, 1);
    let land = ev.iter().find(|e| e.from == Mode::Right).unwrap();
    let left = ev.iter().find(|e| e.to == Mode::Left).unwrap();
    assert!((land.t - s.t_end).abs() < 1e-9);
    assert!((left.x_after - OrbitProblem::start(s.beta0, s.beta_dot0)).norm() < 1e-9);
}

/// The half-period mirrored return map computed with the hybrid simulator: a left-tilt start
/// `(beta - pi/2, beta_dot)` to the mirrored state at the next right-tilt start.
fn return_map(law: &ComputedTorque, b: f64, bd: f64) -> [f64; 2] {
    let ev = run_until(law, Mode::Left, OrbitProblem::start(b, bd), Mode::Right, 1);
    let right = ev.iter().find(|e| e.to == Mode::Right).unwrap();
    let m = mirror(&right.x_after);
    [m[1] - FRAC_PI_2, m[3]]
}

fn check_multipliers(pb: &OrbitProblem, s: &OrbitSolution) {
    let law = ComputedTorque::new(pb.control).unwrap();
    // Central differences of the whole hybrid map: truncation ~h^2, round-off ~1e-12/h.
    let h = 1e-5;
    let mut jac = nalgebra::Matrix2::zeros();
    for (j, (db, dbd)) in [(h, 0.0), (0.0, h)].into_iter().enumerate() {
        let p = return_map(&law, s.beta0 + db, s.beta_dot0 + dbd);
        let m = return_map(&law, s.beta0 - db, s.beta_dot0 - dbd);
        jac[(0, j)] = (p[0] - m[0]) / (2.0 * h);
        jac[(1, j)] = (p[1] - m[1]) / (2.0 * h);
    }
    let mut fd = eigenvalues2(&jac);
    let mut ours = s.multipliers.clone();
    fd.sort_by(|a, b| a[0].total_cmp(&b[0]));
    ours.sort_by(|a, b| a[0].total_cmp(&b[0]));
    for (a, b) in ours.iter().zip(&fd) {
        assert!(
            (a[0] - b[0]).abs() < 1e-5 && (a[1] - b[1]).abs() < 1e-5,
            "sensitivities {ours:?} vs finite differences {fd:?}"
        );
    }
}

#[test]
fn multipliers_match_finite_difference_monodromy() {
    let (pb, s) = paper_orbit();
    check_multipliers(&pb, &s);
    // And on the adapted loop near the period doubling, where one multiplier is near -1.
    let pk = pb.with_adaptation(1900.0, s.energy_avg);
    let sw = sweep_settings(&pb, &s);
    let guess = bifurcation::attracting_orbit_guess(&sw, 1900.0, 300).unwrap();
    let sk = orbit::solve(&pk, guess).unwrap();
    assert!(
        sk.multipliers.iter().any(|m| m[0] < -0.8),
        "{:?}",
        sk.multipliers
    );
    check_multipliers(&pk, &sk);
}

fn sweep_settings(pb: &OrbitProblem, s: &OrbitSolution) -> Sweep {
    Sweep {
        problem: *pb,
        start_beta0: s.beta0,
        start_beta_dot0: s.beta_dot0,
        energy_avg: s.energy_avg,
        tilts: 500,
        keep: 100,
        period_tol: 1e-5,
    }
}

#[test]
fn k_star_marks_the_onset_of_period_two() {
    let (pb, s) = paper_orbit();
    let sw = sweep_settings(&pb, &s);
    let ks = bifurcation::k_star(&sw, 500.0, 1500.0, 2500.0, 1e-2).expect("a crossing");
    // The paper reports the first bifurcation at k = 1925.
    assert!((ks - 1925.0).abs() < 25.0, "k* = {ks}");
    // The simulated loop: period 1 a little below k*, period 2 a little above.
    let below = bifurcation::run_one(&sw, ks - 40.0);
    let above = bifurcation::run_one(&sw, ks + 40.0);
    assert_eq!(below.period, Some(1), "{:?}", &below.peaks[..4]);
    assert_eq!(above.period, Some(2), "{:?}", &above.peaks[..4]);
}

#[test]
fn sinusoid_solution_lands_on_time_in_a_closed_loop_simulation() {
    let p = Params::default();
    for s_off in [-0.5, -0.25, -1.0 / 6.0, -0.125] {
        let sol = sinusoid::solve(&p, 0.33, s_off, &Search::default()).unwrap();
        // Independent path: the full hybrid simulator, with a computed-torque law that tracks
        // the reference exactly because the start is on it (zero tracking error stays zero
        // until the first impact).
        let law = ComputedTorque::new(ControlConfig {
            law: LawSpec {
                reference: Trajectory::Sinusoid {
                    amplitude: 0.33,
                    omega: sol.omega,
                },
                ..LawSpec::without_adaptation()
            },
            ..ControlConfig::default()
        })
        .unwrap();
        let x0 = State::new(0.0, FRAC_PI_2, 0.0, 0.33 * sol.omega);
        let mut plant = Plant::new(tight(), 0.0, Mode::Flat, x0).unwrap();
        let mut ev = Events::default();
        let mut t = 0.0;
        while ev.0.len() < 2 {
            t += 0.05;
            plant.advance_continuous(&law, t, &mut ev).unwrap();
        }
        let (tilt, land) = (ev.0[0], ev.0[1]);
        assert_eq!((tilt.from, tilt.to), (Mode::Flat, sol.side));
        assert_eq!(land.to, Mode::Flat);
        assert!(
            (tilt.t - sol.tilt_time).abs() < 1e-9,
            "t_t {} vs {}",
            tilt.t,
            sol.tilt_time
        );
        assert!(
            (land.t - sol.landing_time).abs() < 1e-8,
            "t_l {} vs {}",
            land.t,
            sol.landing_time
        );
        let period = 2.0 * PI / sol.omega;
        assert!((land.t - (period / 2.0 + s_off * tilt.t)).abs() < 1e-8);
    }
}

#[test]
fn no_tilt_region_does_not_tilt_in_simulation() {
    let p = Params::default();
    let (a, w) = (0.1, 3.0);
    assert_eq!(sinusoid::tilt_start(&p, a, w), None);
    let law = ComputedTorque::new(ControlConfig {
        law: LawSpec {
            reference: Trajectory::Sinusoid {
                amplitude: a,
                omega: w,
            },
            ..LawSpec::without_adaptation()
        },
        ..ControlConfig::default()
    })
    .unwrap();
    let mut plant = Plant::new(
        tight(),
        0.0,
        Mode::Flat,
        State::new(0.0, FRAC_PI_2, 0.0, a * w),
    )
    .unwrap();
    let mut ev = Events::default();
    plant
        .advance_continuous(&law, 2.0 * PI / w, &mut ev)
        .unwrap();
    assert!(ev.0.is_empty());
    assert!(matches!(
        sinusoid::solve(&p, 0.0, 0.0, &Search::default()),
        Err(sinusoid::SinusoidError::Invalid {
            field: "amplitude",
            ..
        })
    ));
}

/// Tilt peaks and the landing time each was reported at.
#[derive(Default)]
struct PeakLog(Vec<f64>, Vec<f64>);
impl Observer for PeakLog {
    fn tilt_peak(&mut self, p: &tilting_plant::TiltPeak) {
        self.0.push(p.alpha.abs());
    }
    fn transition(&mut self, ev: &Transition) {
        if ev.to == Mode::Flat && self.1.len() < self.0.len() {
            self.1.push(ev.t);
        }
    }
}

#[test]
fn a_sweep_row_is_a_plain_simulation_of_the_loop() {
    // Each row's peaks are the last `keep` tilt peaks of the adapted loop from the orbit
    // start. A plain simulation (one `advance_continuous` call per 50 s, peaks from the
    // plant's own observer) must give them again: the two differ only in where the integrator
    // cuts its steps, so on an attracting orbit (period 1 at k = 1000, period 2 at k = 2100)
    // they agree to the integration error, far below the 1e-9 rad asked here (the peaks are
    // about 0.04 rad; rtol 3e-11).
    let (pb, s) = paper_orbit();
    let sw = sweep_settings(&pb, &s);
    for k in [1000.0, 2100.0] {
        let row = bifurcation::run_one(&sw, k);
        assert!(row.fault.is_none(), "{:?}", row.fault);
        let law = ComputedTorque::new(ControlConfig {
            law: LawSpec {
                k,
                energy_avg: sw.energy_avg,
                ..pb.control.law
            },
            ..pb.control
        })
        .unwrap();
        let cfg = SimConfig {
            params: pb.params,
            impact: pb.impact,
            ..SimConfig::default()
        };
        let x0 = OrbitProblem::start(sw.start_beta0, sw.start_beta_dot0);
        let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
        let mut log = PeakLog::default();
        let mut t = 0.0;
        while log.0.len() < sw.tilts {
            t += 50.0;
            plant.advance_continuous(&law, t, &mut log).unwrap();
        }
        // The sweep runs in 10 s slices until `tilts` peaks and keeps the last `keep` peaks
        // reported by the end of that slice: take the same window of the plain run.
        assert_eq!(log.0.len(), log.1.len());
        let t_row = 10.0 * (log.1[sw.tilts - 1] / 10.0).ceil();
        let count = log.1.iter().filter(|&&t| t <= t_row).count();
        assert_eq!(row.peaks.len(), sw.keep);
        let worst = row
            .peaks
            .iter()
            .zip(&log.0[count - sw.keep..count])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "k = {k}: peaks differ by {worst:e} rad");
        assert!(row.peaks.iter().all(|p| (0.01..0.2).contains(p)));
    }
}

// ---- The energy target for a wanted peak ------------------------------------------------------

/// Records the tilt extremes.
#[derive(Default)]
struct Peaks(Vec<f64>);
impl Observer for Peaks {
    fn tilt_peak(&mut self, p: &tilting_plant::TiltPeak) {
        self.0.push(p.alpha);
    }
}

/// The adapted loop run by the hybrid simulator (not the shooting) from the paper's orbit
/// start for `t_end` s: the tilt peaks (rad).
fn adapted_peaks(
    params: Params,
    impact: ImpactLaw,
    kd: f64,
    energy_avg: f64,
    t_end: f64,
) -> Vec<f64> {
    adapted_peaks_on(params, params, impact, kd, energy_avg, t_end)
}

/// [`adapted_peaks`] with the law's model `params` on a robot `plant`.
fn adapted_peaks_on(
    params: Params,
    plant: Params,
    impact: ImpactLaw,
    kd: f64,
    energy_avg: f64,
    t_end: f64,
) -> Vec<f64> {
    let law = ComputedTorque::new(ControlConfig {
        params,
        law: LawSpec {
            kd,
            k: 500.0,
            energy_avg,
            ..LawSpec::default()
        },
    })
    .unwrap();
    let cfg = SimConfig {
        params: plant,
        impact,
        ..tight()
    };
    let x0 = OrbitProblem::start(
        tilting_plant::paper::ORBIT_BETA0,
        tilting_plant::paper::ORBIT_BETA_DOT0,
    );
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
    let mut peaks = Peaks::default();
    plant.advance_continuous(&law, t_end, &mut peaks).unwrap();
    peaks.0
}

/// The paper's robot with the physical law, its loop with the paper's gains (`k` = 500, `E_av`
/// 0 until found), and the adapted loop's orbit with peak 0.018 rad.
fn physical_0018() -> (Params, OrbitProblem, tilting_planner::peak::PeakOrbit) {
    use tilting_planner::peak::{energy_for_peak, PeakSearch};
    let params = Params {
        impact: ImpactLaw::Physical,
        ..Params::default()
    };
    let pb =
        OrbitProblem::new(params, ImpactLaw::Physical, 100.0, 14.14).with_adaptation(500.0, 0.0);
    let found = energy_for_peak(&pb, &PeakSearch::new(0.018), &|_| {}).unwrap();
    (params, pb, found)
}

#[test]
fn the_peaks_steepness_in_the_arm_mass_is_what_the_simulator_gives() {
    use tilting_planner::peak::{arm_mass_sensitivity, ARM_MASS_STEP};
    // The physical law's 0.018 rad orbit of the paper's gains: the shooting's
    // d ln(peak) / d ln(m_l) against the same central difference of the settled peaks of the
    // hybrid simulator (time integration with event location, not the shooting), the robot's
    // arm ARM_MASS_STEP heavier and lighter than the law's model.
    let (params, pb, found) = physical_0018();
    let e_av = found.energy_avg_adaptation;
    let s = arm_mass_sensitivity(&pb.with_adaptation(500.0, e_av), &found.orbit).unwrap();
    let settled = |scale: f64| {
        let plant = Params {
            m_l: params.m_l * scale,
            ..params
        };
        let peaks = adapted_peaks_on(params, plant, ImpactLaw::Physical, 14.14, e_av, 40.0);
        peaks[peaks.len() - 1].abs()
    };
    let (up, down) = (1.0 + ARM_MASS_STEP, 1.0 - ARM_MASS_STEP);
    let sim = (settled(up).ln() - settled(down).ln()) / (up.ln() - down.ln());
    // The transient decays by the largest multiplier per half period (below 0.9 here: 1e-5
    // after 110 tilts); both differences have the same step, so they agree to that.
    assert!(
        (s - sim).abs() < 1e-3 * sim.abs(),
        "shooting {s}, simulator {sim}"
    );
    // A heavier arm under the same law tilts less.
    assert!(s < 0.0, "{s}");
}

#[test]
fn the_energy_for_a_peak_gives_that_peak_in_a_closed_loop_simulation() {
    use tilting_planner::peak::{energy_for_peak, PeakSearch};
    // The physical law (the plate lands plastically, p_beta kept): the paper's k = 0 orbit
    // does not exist, the family of the adapted loop is found from a scan of E_av. The
    // simulated loop, started from the paper's orbit (not this one), settles on the peak.
    let (params, _, found) = physical_0018();
    assert!(orbit::find_all(&OrbitProblem::new(
        params,
        ImpactLaw::Physical,
        100.0,
        14.14
    ))
    .is_empty());
    assert!(
        (found.orbit.max_tilt - 0.018).abs() < 1e-9,
        "{:?}",
        found.orbit
    );
    assert!(found.orbit.stable);
    let peaks = adapted_peaks(
        params,
        ImpactLaw::Physical,
        14.14,
        found.energy_avg_adaptation,
        30.0,
    );
    // After 25 s (multipliers 0.85 and 0.07: the transient decays by 0.85 per half period,
    // 1e-17 over 86 tilts), the last peaks are the orbit's, alternating, to 1e-6 rad.
    let last = &peaks[peaks.len() - 6..];
    for w in last.windows(2) {
        assert!(w[0] * w[1] < 0.0, "alternating: {last:?}");
    }
    for p in last {
        assert!((p.abs() - 0.018).abs() < 1e-6, "{last:?}");
    }
    // And with the paper's law, asked for the peak of the paper's own adapted orbit, the
    // search gives back the paper's E_av (the k = 0 orbit's, 19.963439703 J).
    let paper = OrbitProblem::new(Params::default(), ImpactLaw::Paper, 100.0, 14.14)
        .with_adaptation(500.0, tilting_plant::paper::ORBIT_ENERGY_AVG);
    use tilting_plant::paper::{ORBIT_BETA0, ORBIT_BETA_DOT0, ORBIT_HALF_PERIOD};
    let s = orbit::solve(&paper, [ORBIT_BETA0, ORBIT_BETA_DOT0, ORBIT_HALF_PERIOD]).unwrap();
    let back = energy_for_peak(&paper, &PeakSearch::new(s.max_tilt), &|_| {}).unwrap();
    assert!(
        (back.energy_avg_adaptation - tilting_plant::paper::ORBIT_ENERGY_AVG).abs() < 1e-7,
        "{}",
        back.energy_avg_adaptation
    );
}

#[test]
fn a_peak_beyond_the_family_is_refused_naming_the_largest() {
    use tilting_planner::peak::{energy_for_peak, PeakError, PeakSearch};
    let params = Params {
        impact: ImpactLaw::Physical,
        ..Params::default()
    };
    let pb =
        OrbitProblem::new(params, ImpactLaw::Physical, 100.0, 14.14).with_adaptation(500.0, 0.0);
    match energy_for_peak(&pb, &PeakSearch::new(0.04), &|_| {}) {
        Err(PeakError::Unreachable {
            largest,
            energy_avg,
            ..
        }) => {
            // 0.018 was reached above; the largest lies between it and the wanted 0.04, and
            // an orbit with it exists at the E_av named.
            assert!(largest > 0.018 && largest < 0.04, "{largest}");
            let s = orbit::find_all(&pb.with_adaptation(500.0, energy_avg));
            assert!(
                s.iter().any(|o| (o.max_tilt - largest).abs() < 1e-6),
                "{largest} at {energy_avg}: {s:?}"
            );
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn the_reach_maps_stable_and_unstable_cells_are_what_the_simulated_loop_does() {
    use tilting_planner::bifurcation::{run_one, Sweep};
    use tilting_planner::peak::{reach_map, Reach};
    // The physical law, K_D = 10, the peak 0.04 rad: reached at k = 500 and 1500, the first
    // stable, the second not. The loop run by the simulator from each orbit (300 tilts) keeps
    // the peak at k = 500 and leaves period 1 at k = 1500.
    let params = Params {
        impact: ImpactLaw::Physical,
        ..Params::default()
    };
    let pb = OrbitProblem::new(params, ImpactLaw::Physical, 100.0, 10.0);
    let cells = reach_map(&pb, &[10.0], &[500.0, 1500.0], 0.04, &|| {});
    for (c, want_stable) in cells.iter().zip([true, false]) {
        let Reach::Reached {
            energy_avg,
            stable,
            rho,
            peak_per_arm_mass,
        } = c.reach
        else {
            panic!("{c:?}");
        };
        assert_eq!(stable, want_stable, "{c:?}");
        assert_eq!(rho < 1.0, stable);
        // Away from a fold both neighbouring orbits exist, and a heavier arm under the same
        // law tilts less (the simulator checks the figure itself in the test above).
        let s = peak_per_arm_mass.expect("both neighbours of the cell's orbit");
        assert!(s < 0.0 && s.is_finite(), "{c:?}");
        let o = orbit::find_all(&pb.with_adaptation(c.k, energy_avg))
            .into_iter()
            .find(|o| (o.max_tilt - 0.04).abs() < 1e-8)
            .expect("the orbit of the cell");
        let sweep = Sweep {
            problem: pb,
            start_beta0: o.beta0,
            start_beta_dot0: o.beta_dot0,
            energy_avg,
            tilts: 300,
            keep: 20,
            period_tol: 1e-6,
        };
        let row = run_one(&sweep, c.k);
        if stable {
            assert_eq!(row.period, Some(1), "{row:?}");
            assert!(row.peaks.iter().all(|p| (p - 0.04).abs() < 1e-6), "{row:?}");
        } else {
            assert_ne!(row.period, Some(1), "{row:?}");
        }
    }
}

#[test]
fn the_simulated_loop_settles_where_the_shooting_puts_the_orbit_and_moves_with_the_robot() {
    use tilting_planner::peak::{settle_energy_for_peak, SETTLE_TOL};
    // The physical law's 0.018 rad orbit of the paper's gains: the hybrid simulator (time
    // integration with event location), run continuously with plastic landings from the
    // orbit's start, settles at the shooting's peak with the shooting's E_av: one run, the
    // peaks and the period the orbit's (it is stable, multipliers below 0.9: 30 tilts
    // left out leave 1e-3 of any start error, the integration's own error is 1e-9).
    let (params, pb, found) = physical_0018();
    let e_av = found.energy_avg_adaptation;
    let o = &found.orbit;
    let x0 = OrbitProblem::start(o.beta0, o.beta_dot0);
    let robot = pb.with_adaptation(500.0, 0.0);
    let s = settle_energy_for_peak(&robot, &x0, e_av, 0.018, 0.0, o.period, &|_| {}).unwrap();
    assert_eq!((s.runs, s.energy_avg), (1, e_av), "{s:?}");
    for p in [s.peak_mean, s.peak_min, s.peak_max] {
        assert!((p - 0.018).abs() < 1e-6, "{s:?}");
    }
    assert!(
        (s.period - o.period).abs() < 1e-6 * o.period,
        "{s:?} {}",
        o.period
    );
    // A robot whose landings pass on into the next tilt (restitution -0.3) keeps less of the
    // tilt at the same E_av, and the refinement finds the E_av at which its mean peak is
    // 0.018 again, to the secant's tolerance.
    let passing = OrbitProblem {
        params: Params {
            restitution: -0.3,
            ..params
        },
        ..robot
    };
    let r = settle_energy_for_peak(&passing, &x0, e_av, 0.018, 0.0, o.period, &|_| {}).unwrap();
    assert!(r.runs > 1, "{r:?}");
    assert!((r.peak_mean - 0.018).abs() <= SETTLE_TOL * 0.018, "{r:?}");
    assert_ne!(r.energy_avg, e_av);
}
