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
