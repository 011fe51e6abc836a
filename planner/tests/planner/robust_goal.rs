//! Issue 17 §5's goal for the robust law (`--orbit-peak`, `controller/src/robust.rs`) at the
//! two parameters whose error it used to miss: gravity `g` and the plate's half-length `f`,
//! each 10 % low and 10 % high in the plant, the controller on the paper's model.
//!
//! The truth the peaks are judged against is not the simulator's: it is the planner's periodic
//! orbit of the paper's adapted loop (`k = 500`), a boundary value problem solved by Newton
//! shooting (`plan orbit`), whose largest tilt is the peak the robust law is told to hold. The
//! goal, as stated in the issue and judged as `plan margins` does: at least 200 tilts (0.6 s
//! of plant time allowed per tilt), every tilt to the other side than the one before, no
//! fault, and the mean |peak| of the last 10 tilts within 25 % of the planned peak. The same
//! robots under the paper's law (no `--orbit-peak`) fail it, so the runs can tell.

use tilting_planner::jobs;
use tilting_plant::{ImpactLaw, Params};
use tilting_sim::closed_loop::{simulate, SimOptions};
use tilting_sim::robustness::{Goal, Parameter};
use tilting_sim::Scenario;

const TILTS: u64 = 200;
/// The tolerance on the last peaks (relative).
const TOLERANCE: f64 = 0.25;

/// The largest tilt (rad) of the paper's adapted orbit (`K_P = 100`, `K_D = 14.14`, `k = 500`,
/// `E_av` of the `k = 0` orbit), from the planner's boundary value problem.
fn planned_peak() -> f64 {
    let report = jobs::orbits(
        Params::default(),
        ImpactLaw::Paper,
        100.0,
        14.14,
        500.0,
        None,
    )
    .expect("the paper's orbit");
    let orbit = report.solutions.first().expect("one orbit");
    assert!(orbit.stable, "{orbit:?}");
    orbit.max_tilt
}

fn goal(p: Parameter, e: f64, peak: Option<f64>, planned: f64) -> Goal {
    let mut sc = Scenario {
        control_period: 0.001,
        duration: TILTS as f64 * 0.6,
        ..Scenario::default()
    };
    sc.law.orbit_peak = peak;
    sc.plant_params = p.perturbed(&sc.params, e);
    assert!(sc.plant_params.is_some());
    let r = simulate(&sc, SimOptions::default()).expect("valid scenario");
    Goal::of(&r, TILTS, planned, TOLERANCE)
}

#[test]
fn the_robust_law_holds_g_and_f_ten_percent_off() {
    let planned = planned_peak();
    // The paper's orbit tilts by about 0.04 rad (its Fig. 5); a wrong branch would be far off.
    assert!((0.03..0.05).contains(&planned), "{planned}");
    for p in [Parameter::G, Parameter::F] {
        for e in [-0.10, 0.10] {
            let robust = goal(p, e, Some(planned), planned);
            eprintln!("{} {e:+}: robust {robust:?}", p.key());
            assert!(robust.holds, "{} {e:+}: {robust:?}", p.key());
            let plain = goal(p, e, None, planned);
            assert!(
                !plain.holds,
                "{} {e:+}: the paper's law holds: {plain:?}",
                p.key()
            );
        }
    }
}

/// A robot that lands by the physical law lifts off at another arm speed than the paper's
/// (0.33 rad/s for a 0.018 rad orbit, against 0.498). From a plate at rest, the robust law's
/// re-entry hands over at the start it is given (`orbit_start`, the planned orbit's): the
/// tilts that follow are the planned orbit's at once. Handed over at the paper's speed instead,
/// the first tilt overshoots the plan.
#[test]
fn the_reentry_hands_over_at_the_planned_orbits_start() {
    use std::f64::consts::FRAC_PI_2;
    use tilting_planner::orbit::OrbitProblem;
    use tilting_planner::peak::{energy_for_peak, PeakSearch};
    use tilting_plant::Mode;
    let params = Params {
        impact: ImpactLaw::Physical,
        ..Params::default()
    };
    let peak = 0.018;
    let pb =
        OrbitProblem::new(params, ImpactLaw::Physical, 100.0, 14.14).with_adaptation(500.0, 0.0);
    let found = energy_for_peak(&pb, &PeakSearch::new(peak), &|_| {}).expect("a 0.018 orbit");
    let start = [FRAC_PI_2 + found.orbit.beta0, found.orbit.beta_dot0];
    let run = |orbit_start: Option<[f64; 2]>| {
        let mut sc = Scenario {
            params,
            impact: ImpactLaw::Physical,
            control_period: 0.001,
            duration: 12.0,
            mode: Mode::Flat,
            x0: [0.0, FRAC_PI_2, 0.0, 0.0],
            ..Scenario::default()
        };
        sc.law.energy_avg = found.energy_avg_adaptation;
        sc.law.orbit_peak = Some(peak);
        sc.law.orbit_start = orbit_start;
        simulate(&sc, SimOptions::default()).expect("valid scenario")
    };
    let err = |a: f64| (a.abs() / peak - 1.0).abs();
    let planned = run(Some(start));
    assert!(planned.fault.is_none(), "{:?}", planned.fault);
    let peaks: Vec<f64> = planned.tilt_peaks.iter().map(|p| p.alpha).collect();
    eprintln!("handed over at the plan's start: peaks {peaks:?}");
    // At least 15 tilts after the idle plate's 0.5 s and the 2 s re-entry, alternating.
    assert!(peaks.len() >= 15, "{peaks:?}");
    assert!(peaks.windows(2).all(|w| w[0] * w[1] < 0.0), "{peaks:?}");
    // Every tilt within 10 % of the plan, the first included: the hand-over is on the orbit
    // (its remaining error is the 1 kHz sampling of the hand-over and of the landings).
    let worst = peaks.iter().map(|&a| err(a)).fold(0.0, f64::max);
    assert!(worst < 0.10, "worst {worst}: {peaks:?}");
    // The paper's hand-over speed on this robot: the first tilt is far above the plan.
    let papers = run(None);
    let first = papers.tilt_peaks.first().map_or(0.0, |p| p.alpha);
    eprintln!("handed over at the paper's speed: first peak {first}");
    assert!(err(first) > 0.3, "first peak {first} against {peak}");
}

/// `plan margins` of a planned orbit of the physical law (`--params`, `--plan`): the survey
/// runs that loop (its nominal last peaks are the plan's, to the 1 kHz sampling), its JSON
/// (the grid of a shard) carries the loop and reads back, and the paper's survey carries none.
#[test]
fn margins_survey_the_planned_orbit_of_another_robot() {
    use std::f64::consts::FRAC_PI_2;
    use tilting_planner::margins::{Bands, Base, Criteria, Survey};
    use tilting_planner::orbit::OrbitProblem;
    use tilting_planner::peak::{energy_for_peak, PeakSearch};
    let params = Params {
        impact: ImpactLaw::Physical,
        ..Params::default()
    };
    let pb =
        OrbitProblem::new(params, ImpactLaw::Physical, 100.0, 14.14).with_adaptation(500.0, 0.0);
    let found = energy_for_peak(&pb, &PeakSearch::new(0.018), &|_| {}).expect("a 0.018 orbit");
    let law = tilting_controller::LawSpec {
        energy_avg: found.energy_avg_adaptation,
        orbit_start: Some([FRAC_PI_2 + found.orbit.beta0, found.orbit.beta_dot0]),
        ..tilting_controller::LawSpec::default()
    };
    let paper = Survey {
        delays: vec![0.0],
        losses: vec![0.0],
        rate: 1000.0,
        rates: vec![1000.0],
        angle_noises: vec![],
        rate_noises: vec![],
        mass_errors: vec![],
        seed: 0,
        criteria: Criteria {
            tilts: 40,
            ..Criteria::default()
        },
        bands: Bands::default(),
        base: None,
    };
    let text = serde_json::to_string(&paper).unwrap();
    assert!(!text.contains("base"), "{text}");
    let s = Survey {
        base: Some(Base { params, law }),
        ..paper.clone()
    };
    let back: Survey = serde_json::from_str(&serde_json::to_string(&s).unwrap()).unwrap();
    assert_eq!(back, s);
    let r = s.run(&|| {}).expect("a nominal orbit");
    let p = paper.run(&|| {}).expect("the paper's orbit");
    eprintln!(
        "nominal last peaks: planned {}, paper's {}",
        r.nominal_peak, p.nominal_peak
    );
    assert!(
        (r.nominal_peak / 0.018 - 1.0).abs() < 0.05,
        "{}",
        r.nominal_peak
    );
    assert!(p.nominal_peak > 0.03, "{}", p.nominal_peak);
    assert!(r.delay_loss[0].survived, "{:?}", r.delay_loss[0]);
}
