//! The robust option of the law (`--orbit-peak`, `tilting_controller::robust`): it holds the
//! orbit on robots the plain law loses, it brings a plate at rest back onto the orbit, and the
//! identity it rests on holds.

use std::f64::consts::FRAC_PI_2;
use tilting_controller::{ComputedTorque, LawSpec};
use tilting_plant::{Mode, Plant, State};
use tilting_sim::closed_loop::{simulate, SimOptions, SimulationReport};
use tilting_sim::robustness::{Goal, Parameter};
use tilting_sim::{run_sampled, Scenario};

/// The goal: 200 tilts (0.6 s each allowed, as `plan margins`), alternating, the last peaks
/// within 25 % of the nominal orbit's.
const TILTS: u64 = 200;
const TOLERANCE: f64 = 0.25;

fn scenario(duration: f64, peak: Option<f64>) -> Scenario {
    let mut sc = Scenario {
        control_period: 0.001,
        duration,
        ..Scenario::default()
    };
    sc.law.orbit_peak = peak;
    sc
}

fn run(sc: &Scenario) -> SimulationReport {
    simulate(sc, SimOptions::default()).unwrap()
}

/// The nominal orbit's last peaks (rad): the plain law on the exact model, 1 kHz.
fn nominal() -> f64 {
    let r = run(&scenario(TILTS as f64 * 0.6, None));
    Goal::of(&r, TILTS, 1.0, f64::INFINITY).last_peak
}

#[test]
fn the_robust_law_holds_arm_mass_errors_the_plain_law_loses() {
    let nominal = nominal();
    assert!((0.03..0.05).contains(&nominal), "{nominal}");
    for e in [0.05, -0.10] {
        let goal = |peak| {
            let mut sc = scenario(TILTS as f64 * 0.6, peak);
            sc.plant_params = Parameter::ML.perturbed(&sc.params, e);
            Goal::of(&run(&sc), TILTS, nominal, TOLERANCE)
        };
        let (plain, robust) = (goal(None), goal(Some(nominal)));
        assert!(
            !plain.holds,
            "arm mass {e:+}: the plain law holds: {plain:?}"
        );
        assert!(
            robust.holds,
            "arm mass {e:+}: the robust law fails: {robust:?}"
        );
        // It holds the peak it was given, not merely within the tolerance.
        assert!(robust.deviation.abs() < 0.02, "{robust:?}");
    }
}

/// The identity the scale rests on: a plant whose two masses are `s` times the model's, under
/// `s` times the law's torque, moves as the model under the law (every term of the dynamics and
/// of the tilting threshold is linear in the masses).
#[test]
fn scaling_both_masses_and_the_torque_leaves_the_motion_unchanged() {
    let sc = scenario(5.0, None);
    let law = ComputedTorque::new(sc.control_config()).unwrap();
    let s = 1.3;
    let mut heavy = sc.sim_config();
    heavy.params.m_f *= s;
    heavy.params.m_l *= s;
    let events = |cfg, scale: f64| {
        let mut plant = Plant::new(cfg, 0.0, sc.mode, sc.initial_state()).unwrap();
        let scaled = |t: f64, m: Mode, x: &State| scale * law.torque(t, m, x);
        let mut rec = Events(Vec::new());
        let (r, _) = run_sampled(&mut plant, &scaled, 0.001, 5.0, &mut rec, &mut |_| {});
        r.unwrap();
        rec.0
    };
    let (a, b) = (events(sc.sim_config(), 1.0), events(heavy, s));
    assert!(a.len() > 10, "{}", a.len());
    assert_eq!(a.len(), b.len());
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x.0 - y.0).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "{} transitions, largest time difference {worst:e} s",
        a.len()
    );
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.1, y.1);
        // Round-off of the scaled products (measured: 1.2e-12 s over 5 s), well inside the
        // event location's accuracy amplified by the held loop.
        assert!((x.0 - y.0).abs() < 1e-9, "{x:?} {y:?}");
    }
}

struct Events(Vec<(f64, Mode)>);

impl tilting_plant::Observer for Events {
    fn transition(&mut self, ev: &tilting_plant::Transition) {
        self.0.push((ev.t, ev.to));
    }
}

/// A plate at rest, arm upright: an equilibrium of the plain law (it never tilts); the robust
/// law re-enters the orbit and its peaks are within 10 % of the nominal ones in under 5 s.
#[test]
fn a_plate_at_rest_reenters_the_orbit() {
    let nominal = nominal();
    let at_rest = |peak| {
        let mut sc = scenario(20.0, peak);
        sc.mode = Mode::Flat;
        sc.x0 = [0.0, FRAC_PI_2, 0.0, 0.0];
        run(&sc)
    };
    let plain = at_rest(None);
    assert_eq!(plain.stats.tilts, 0);
    assert!(plain.events.is_empty());
    let r = at_rest(Some(nominal));
    assert!(r.fault.is_none(), "{:?}", r.fault);
    let within =
        |p: &tilting_sim::closed_loop::PeakRecord| (p.alpha.abs() / nominal - 1.0).abs() <= 0.10;
    // From the first peak after which every peak is within 10 %.
    let settled = r
        .tilt_peaks
        .iter()
        .rposition(|p| !within(p))
        .map_or(0, |i| i + 1);
    let t = r.tilt_peaks[settled].t;
    let first = r.events.first().map_or(f64::NAN, |e| e.t);
    eprintln!("re-entry from rest: first tilt at {first} s, peaks within 10 % from {t} s");
    assert!(t < 5.0, "peaks within 10 % from t = {t} s");
    let sides: Vec<Mode> = r
        .events
        .iter()
        .map(|e| e.to)
        .filter(|m| m.is_tilted())
        .collect();
    assert!(sides.windows(2).all(|w| w[0] != w[1]), "{sides:?}");
    assert!(r.stats.tilts > 30, "{}", r.stats.tilts);
}

#[test]
fn bad_settings_are_refused_naming_the_field() {
    let mut sc = scenario(1.0, Some(0.04));
    sc.control_period = 0.0;
    let e = simulate(&sc, SimOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("orbit_peak") && e.contains("control"), "{e}");
    for law in [
        LawSpec {
            orbit_peak: Some(0.04),
            ..LawSpec::without_adaptation()
        },
        LawSpec {
            orbit_peak: Some(-0.1),
            ..LawSpec::default()
        },
        LawSpec {
            orbit_peak: Some(0.04),
            reference: tilting_controller::Trajectory::Sinusoid {
                amplitude: 0.1,
                omega: 2.0,
            },
            ..LawSpec::default()
        },
    ] {
        let e = law.validate().unwrap_err().to_string();
        assert!(e.contains("orbit_peak"), "{e}");
    }
    // Off by default: the paper's law.
    assert_eq!(LawSpec::default().orbit_peak, None);
}

/// A law given its orbit's start (`orbit_start`) is the plain law launched from rest
/// (`RobustLaw::launcher`): on the orbit it is the plain law bit for bit (no scale, no trim),
/// and from a plate at rest, where the plain law never tilts, it runs the re-entry motion and
/// hands over at that start.
#[test]
fn a_law_with_an_orbit_start_is_the_plain_law_launched_from_rest() {
    let up = FRAC_PI_2;
    let start = [
        up + tilting_plant::paper::ORBIT_BETA0,
        tilting_plant::paper::ORBIT_BETA_DOT0,
    ];
    let run_with = |orbit_start, rest: bool| {
        let mut sc = scenario(30.0, None);
        sc.law.orbit_start = orbit_start;
        if rest {
            sc.mode = Mode::Flat;
            sc.x0 = [0.0, up, 0.0, 0.0];
        }
        run(&sc)
    };
    let plain = run_with(None, false);
    let launched = run_with(Some(start), false);
    assert_eq!(plain.tilt_peaks.len(), launched.tilt_peaks.len());
    for (a, b) in plain.tilt_peaks.iter().zip(&launched.tilt_peaks) {
        assert_eq!((a.t, a.alpha), (b.t, b.alpha));
    }
    assert!(plain.stats.tilts > 50, "{}", plain.stats.tilts);
    // From rest: the plain law stays there; the launched one tilts, alternating, and every
    // peak is within 10 % of the orbit's from the first (the 1 kHz sampling of the hand-over).
    assert_eq!(run_with(None, true).stats.tilts, 0);
    let r = run_with(Some(start), true);
    assert!(r.fault.is_none(), "{:?}", r.fault);
    let nominal = plain.tilt_peaks.last().unwrap().alpha.abs();
    let peaks: Vec<f64> = r.tilt_peaks.iter().map(|p| p.alpha).collect();
    assert!(peaks.len() > 40, "{peaks:?}");
    assert!(peaks.windows(2).all(|w| w[0] * w[1] < 0.0), "{peaks:?}");
    let worst = peaks
        .iter()
        .map(|a| (a.abs() / nominal - 1.0).abs())
        .fold(0.0, f64::max);
    eprintln!("launched from rest: first peak {}, worst {worst}", peaks[0]);
    assert!(worst < 0.10, "worst {worst}: {peaks:?}");
}
