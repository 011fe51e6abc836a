//! Identification against independent truths: a robot simulated in process (the sim crate's
//! sampled closed loop at 1 kHz, the controller knowing the robot) whose parameters differ from
//! the paper's by up to 20 %, identified from its trace alone.
//!
//! These tests use the recorded (exact) velocities ([`Velocities::Recorded`]): on this
//! robot's orbit the joint sticks or reverses within every 0.1 s, so the angles-only weak
//! form (`cli/tests/cli/identify_cli.rs`, `simulate --record`) has no torque window here.
//!
//! Compared: the seven base parameters (docs/model.md, "Linear in the parameters"), the only
//! combinations the motion fixes, computed here from the hidden robot by their definitions; and
//! the physical parameters derived from them with the robot's weighed arm mass `m_l` as the
//! prior (the motion cannot tell `m_l` from `l_c` and `i_l`), which must be the hidden ones.

use tilting_controller::trajectory::EXCITATION_DEFAULT;
use tilting_controller::{LawArgs, LawSpec};
use tilting_planner::identify::{identify, IdentifyError, Options, Velocities};
use tilting_plant::imperfect::Imperfections;
use tilting_plant::{Mode, Params};
use tilting_record::{Sample, Trace};
use tilting_sim::recording::simulate_logged;
use tilting_sim::{Scenario, ScenarioFile, SimOptions};

/// The hidden robot: every physical parameter the identification estimates changed from the
/// paper's (`m_f = m_l = 1`, `l_c = l = 2`, no inertia, motor or friction) by up to 20 %, or
/// given where the paper's is zero. The geometry (`l`, `f`, `g`) is measured and kept.
fn robot() -> Params {
    Params {
        m_f: 1.15,
        m_l: 0.85,
        l_c: Some(1.7),
        i_l: 0.06,
        j_m: 0.03,
        n_g: 1.2,
        b_v: 0.05,
        tau_c: 0.08,
        ..Params::default()
    }
}

/// The base parameters of `p` by their definitions.
fn base_of(p: &Params) -> [f64; 7] {
    let lc = p.l_c.unwrap_or(p.l);
    [
        p.m_f + p.m_l,
        p.m_l * lc,
        p.m_l * lc * lc + p.i_l + p.j_m,
        (p.n_g - 1.0) * p.j_m,
        (p.n_g * p.n_g - 1.0) * p.j_m,
        p.b_v,
        p.tau_c,
    ]
}

/// Runs the robot on the orbit's controller (with the robot as its model) at 1 kHz for
/// `duration` s (the sim crate's logged run, as `simulate --record` does): the trace as a
/// recording holds it, the held torques, and the number of tilts.
fn record(p: Params, duration: f64) -> (Trace, Vec<Option<f64>>, u64) {
    let sc = Scenario {
        params: p,
        control_period: 1e-3,
        duration,
        ..Scenario::default()
    };
    let (report, logged) = simulate_logged(&sc, SimOptions::default(), &mut |_| {}).unwrap();
    assert!(report.fault.is_none(), "{:?}", report.fault);
    let tau = logged.tau.into_iter().map(Some).collect();
    (logged.trace, tau, report.stats.tilts)
}

#[test]
fn identifies_a_changed_robot_within_one_percent() {
    let truth = robot();
    truth.validate().unwrap();
    let (trace, tau, tilts) = record(truth, 20.0);
    assert!(tilts >= 4, "the robot must tilt: {tilts} tilts");
    // The prior: the paper's, with the weighed arm mass.
    let opts = Options {
        base: Params {
            m_l: truth.m_l,
            ..Params::default()
        },
        velocities: Velocities::Recorded,
        ..Options::default()
    };
    let id = identify(&trace, &tau, &opts).unwrap();
    eprintln!("{}", serde_json::to_string_pretty(&id).unwrap());
    let want = base_of(&truth);
    for (i, w) in want.iter().enumerate() {
        let got = id.base[i].value.unwrap();
        assert!(
            ((got - w) / w).abs() < 0.01,
            "{}: {got} vs {w} ({:+.3} %)",
            id.base[i].name,
            100.0 * (got - w) / w
        );
    }
    let p = id.params;
    for (name, got, w) in [
        ("m_f", p.m_f, truth.m_f),
        ("l_c", p.lc(), truth.lc()),
        ("i_l", p.i_l, truth.i_l),
        ("j_m", p.j_m, truth.j_m),
        ("n_g", p.n_g, truth.n_g),
        ("b_v", p.b_v, truth.b_v),
        ("tau_c", p.tau_c, truth.tau_c),
    ] {
        assert!(((got - w) / w).abs() < 0.01, "{name}: {got} vs {w}");
    }
    assert!(id.condition_number.is_finite() && id.condition_number > 1.0);
    p.validate().unwrap();
}

fn prior() -> Options {
    Options {
        base: Params {
            m_l: robot().m_l,
            ..Params::default()
        },
        velocities: Velocities::Recorded,
        ..Options::default()
    }
}

#[test]
fn refuses_a_short_recording_and_negative_friction() {
    let (trace, tau, _) = record(robot(), 3.0);
    let short = Trace {
        samples: trace.samples[..500].to_vec(),
        ..trace.clone()
    };
    let e = identify(&short, &tau[..500], &prior()).unwrap_err();
    assert!(matches!(e, IdentifyError::TooShort { .. }), "{e}");
    assert!(e.to_string().contains("too short"), "{e}");
    // A torque that lacks 0.5 N m s/rad of the viscous friction the arm feels: b_v < 0.
    let off: Vec<Option<f64>> = tau
        .iter()
        .zip(&trace.samples)
        .map(|(t, s)| t.map(|t| t - 0.5 * s.x[3]))
        .collect();
    let e = identify(&trace, &off, &prior()).unwrap_err();
    assert!(
        matches!(e, IdentifyError::NegativeFriction { field: "b_v", .. }),
        "{e}"
    );
    assert!(
        e.to_string().contains("b_v") && e.to_string().contains(">= 0"),
        "{e}"
    );
}

/// A flat recording of the arm alone, its torque from the flat equation (a closed form) for
/// the motion `beta = pi/2 + 0.6 sin(w t) + 0.3 t`-like, sampled at 1 kHz.
fn flat_trace(beta: impl Fn(f64) -> [f64; 3], p: &Params, secs: f64) -> (Trace, Vec<Option<f64>>) {
    rocking_trace(beta, |_| [0.0; 3], p, secs)
}

/// A recording in the flat mode whose plate rocks about its centre (the joint) by `alpha(t)`
/// (`[alpha, alpha_dot, alpha_ddot]`), as on a compliant contact; the torque from the arm's
/// equation about a joint that turns with the plate, derived here (a pendulum on a turning
/// base): the arm turns by `alpha + beta`, the rotor by `alpha + n_g beta` (reflected through
/// the gear, `n_g j_m (alpha_ddot + n_g beta_ddot)` at the joint), so `tau = (m_l l_c^2 + i_l)
/// (alpha_ddot + beta_ddot) + n_g j_m (alpha_ddot + n_g beta_ddot) + m_l l_c g cos(alpha +
/// beta) + b_v beta_dot + tau_c sign(beta_dot)`, with each interval's mean accelerations and
/// the other terms at its midpoint.
fn rocking_trace(
    beta: impl Fn(f64) -> [f64; 3],
    alpha: impl Fn(f64) -> [f64; 3],
    p: &Params,
    secs: f64,
) -> (Trace, Vec<Option<f64>>) {
    let n = (secs * 1e3) as usize;
    let (lc, h) = (p.lc(), 1e-3);
    let arm = p.m_l * lc * lc + p.i_l;
    let mut samples = Vec::new();
    let mut tau = Vec::new();
    for k in 0..=n {
        let t = k as f64 * h;
        let ([b, bd, _], [a, ad, _]) = (beta(t), alpha(t));
        samples.push(Sample {
            t,
            mode: Mode::Flat,
            x: [a, b, ad, bd],
        });
        let tm = t + 0.5 * h;
        let ([bm, bdm, _], [am, _, _]) = (beta(tm), alpha(tm));
        let bdd = (beta(t + h)[1] - bd) / h;
        let add = (alpha(t + h)[1] - ad) / h;
        tau.push(Some(
            arm * (add + bdd)
                + p.n_g * p.j_m * (add + p.n_g * bdd)
                + p.m_l * lc * p.g * (am + bm).cos()
                + p.b_v * bdm
                + p.tau_c * bdm.signum(),
        ));
    }
    let end = samples.last().unwrap().t;
    (
        Trace {
            samples,
            events: Vec::new(),
            end,
            stopped_early: false,
        },
        tau,
    )
}

/// A plate rocking while flat (a compliant contact: the plate turns about its centre under the
/// arm's reaction, `alpha = -c beta_ddot`, up to 4e-3 rad) is in the flat equations through the
/// recorded `alpha`: the arm's inertia about the joint, `m_l l_c` and the friction come out
/// within 0.1 % by both paths (recorded velocities, and the angles' weak form); the same
/// recording with `alpha` read as 0 (a plate at rest, the flat equation before) shows the
/// rocking as a spurious inertia (+1.5 %) and an `m_l l_c` 2 % low.
#[test]
fn a_plate_rocking_while_flat_is_in_the_flat_equations() {
    let p = robot();
    let (w, c) = (3.0, 2.5e-4);
    let beta = |t: f64| {
        let (s1, c1, s2, c2) = (
            (w * t).sin(),
            (w * t).cos(),
            (2.3 * w * t).sin(),
            (2.3 * w * t).cos(),
        );
        let w2 = 2.3 * w;
        [
            1.5 + 0.8 * s1 + 0.2 * s2,
            0.8 * w * c1 + 0.2 * w2 * c2,
            -0.8 * w * w * s1 - 0.2 * w2 * w2 * s2,
        ]
    };
    // alpha = -c beta_ddot and its derivatives, in closed form.
    let alpha = |t: f64| {
        let w2 = 2.3 * w;
        let (a1, a2) = (c * 0.8 * w.powi(2), c * 0.2 * w2.powi(2));
        [
            a1 * (w * t).sin() + a2 * (w2 * t).sin(),
            a1 * w * (w * t).cos() + a2 * w2 * (w2 * t).cos(),
            -a1 * w * w * (w * t).sin() - a2 * w2 * w2 * (w2 * t).sin(),
        ]
    };
    let (trace, tau) = rocking_trace(beta, alpha, &p, 20.0);
    let peak = trace
        .samples
        .iter()
        .map(|s| s.x[0].abs())
        .fold(0.0, f64::max);
    assert!(peak > 1e-3 && peak < 5e-3, "rocking {peak} rad");
    let pi = base_of(&p);
    let want = [pi[2] + pi[4], pi[1], pi[5], pi[6]];
    let angles = Options {
        velocities: Velocities::Angles,
        refine: None,
        ..prior()
    };
    let got = |trace: &Trace, opts: &Options| -> [f64; 4] {
        let id = identify(trace, &tau, opts).unwrap();
        let sum = id.base.iter().find(|e| e.name == "pi3+pi5").unwrap();
        [
            sum.value.unwrap(),
            id.base[1].value.unwrap(),
            id.base[5].value.unwrap(),
            id.base[6].value.unwrap(),
        ]
    };
    for opts in [prior(), angles] {
        let g = got(&trace, &opts);
        for i in 0..4 {
            let err = (g[i] - want[i]) / want[i];
            eprintln!(
                "{:?} {i}: {} vs {} ({err:+.2e})",
                opts.velocities, g[i], want[i]
            );
            assert!(
                err.abs() < 1e-3,
                "{:?} {i}: {} vs {}",
                opts.velocities,
                g[i],
                want[i]
            );
        }
    }
    let mut at_rest = trace.clone();
    for s in &mut at_rest.samples {
        s.x[0] = 0.0;
        s.x[2] = 0.0;
    }
    let g = got(&at_rest, &prior());
    eprintln!("alpha read as 0: {g:?} vs {want:?}");
    assert!(((g[0] - want[0]) / want[0]).abs() > 1e-2, "{g:?}");
    assert!(((g[1] - want[1]) / want[1]).abs() > 1e-2, "{g:?}");
}

#[test]
fn flat_motion_sees_the_arm_only_and_says_why() {
    let p = robot();
    let w = 3.0;
    // Moves both ways with varying speed: every flat parameter excited.
    let (trace, tau) = flat_trace(
        |t| {
            [
                1.5 + 0.8 * (w * t).sin() + 0.2 * (2.3 * w * t).sin(),
                0.8 * w * (w * t).cos() + 0.46 * w * (2.3 * w * t).cos(),
                0.0,
            ]
        },
        &p,
        8.0,
    );
    let id = identify(&trace, &tau, &prior()).unwrap();
    let pi = base_of(&p);
    for i in [0, 2, 3, 4] {
        assert!(id.base[i].value.is_none(), "{:?}", id.base[i]);
        assert!(id.base[i]
            .not_identifiable
            .as_deref()
            .unwrap()
            .contains("tilt"));
    }
    let sum = id.base.iter().find(|e| e.name == "pi3+pi5").unwrap();
    for (got, want) in [
        (sum.value.unwrap(), pi[2] + pi[4]),
        (id.base[1].value.unwrap(), pi[1]),
        (id.base[5].value.unwrap(), pi[5]),
        (id.base[6].value.unwrap(), pi[6]),
    ] {
        assert!(((got - want) / want).abs() < 0.01, "{got} vs {want}");
    }
    assert!(id
        .not_identifiable
        .iter()
        .any(|s| s.starts_with("j_m and n_g")));
}

#[test]
fn refuses_motion_without_excitation_saying_what_to_record() {
    // The arm turning at a constant 1 rad/s: no acceleration (pi3 + pi5 unseen) and viscous
    // and Coulomb friction both a constant.
    let (trace, tau) = flat_trace(|t| [t, 1.0, 0.0], &robot(), 4.0);
    let e = identify(&trace, &tau, &prior()).unwrap_err();
    let m = e.to_string();
    assert!(matches!(e, IdentifyError::Singular { .. }), "{m}");
    eprintln!("{m}");
    assert!(m.contains("pi3") && m.contains("record"), "{m}");
}

/// Runs `sc` with the hidden robot as the plant (the controller keeps the paper's model), its
/// angles only measured with 1 mrad of Gaussian noise and a 4,096-count encoder: the
/// recording as `simulate --record --measure angles --noise-alpha 0.001 --noise-beta 0.001
/// --encoder-counts 4096` writes it.
fn record_noisy(sc: Scenario, seed: u64) -> tilting_planner::identify::Recorded {
    let opts = SimOptions {
        imperfect: Some(Imperfections::measured_as_hardware(seed)),
        ..SimOptions::default()
    };
    let (report, logged) = simulate_logged(&sc, opts, &mut |_| {}).unwrap();
    assert!(report.fault.is_none(), "{:?}", report.fault);
    // The excitation keeps the plate flat (the simulator's contact logic, with the true robot,
    // decides: a tilt is a zero moment point past an edge).
    if !sc.law.reference.adapts() {
        assert_eq!(report.stats.tilts, 0, "the excitation tilted the plate");
    }
    // The recording holds what the sensors gave (absent rates), not the observer's estimate.
    assert!(logged.trace.samples.iter().all(|s| s.x[3].is_nan()));
    tilting_planner::identify::Recorded {
        trace: logged.trace,
        tau: logged.tau.into_iter().map(Some).collect(),
        robot: None,
        source: Default::default(),
    }
}

/// The noisy recordings of `truth` ([`record_noisy`]): 300 s of the excitation `reference`
/// (flat: the arm's equation) and 30 s of the robust orbit (the tilts, which carry `m_f`),
/// noise seeds `seed` and `seed + 1`, appended as `identify A.mcap B.mcap` joins them.
fn excitation_and_orbit(
    truth: Params,
    reference: tilting_controller::trajectory::Trajectory,
    seed: u64,
) -> tilting_planner::identify::Recorded {
    let (excitation, orbit) = excitation_and_orbit_scenarios(truth, reference, 300.0, 30.0);
    let mut rec = record_noisy(excitation, seed);
    rec.append(record_noisy(orbit, seed + 1));
    rec
}

/// The scenarios of [`excitation_and_orbit`]: `excitation` s of the excitation `reference`
/// (flat), `orbit` s of the robust orbit, the plant `truth`.
fn excitation_and_orbit_scenarios(
    truth: Params,
    reference: tilting_controller::trajectory::Trajectory,
    excitation: f64,
    orbit: f64,
) -> (Scenario, Scenario) {
    let excitation = Scenario {
        plant_params: Some(truth),
        control_period: 1e-3,
        duration: excitation,
        ..Scenario::resolve(&[&ScenarioFile {
            law: LawArgs {
                reference: Some(reference),
                ..LawArgs::default()
            },
            ..ScenarioFile::default()
        }])
    };
    assert_eq!(excitation.mode, Mode::Flat, "the excitation starts flat");
    let orbit = Scenario {
        plant_params: Some(truth),
        control_period: 1e-3,
        duration: orbit,
        law: LawSpec {
            orbit_peak: Some(0.04),
            ..LawSpec::default()
        },
        ..Scenario::default()
    };
    (excitation, orbit)
}

/// The noisy tests' options: the weighed `m_l` as the prior, 2 s windows, velocities over
/// 0.1 s (`--window 2 --half-window 0.05`).
fn noisy_options(truth: &Params) -> Options {
    Options {
        base: Params {
            m_l: truth.m_l,
            ..Params::default()
        },
        half_window: 0.05,
        window: 2.0,
        ..Options::default()
    }
}

/// The noisy target: the hidden robot (up to 20 % off the paper's), angles only with
/// 1 mrad of noise and a 4,096-count encoder, recorded on the excitation (300 s, flat: the
/// arm's equation) and on the robust orbit (30 s: the tilts, which carry `m_f`), identified
/// from the two recordings in one fit (2 s windows, velocities over 0.1 s).
///
/// Within the 3 %: `m_f`, `l_c`, the arm's inertia about the joint and `tau_c`
/// (measured over four noise seeds: within 1.1 %, 0.02 %, 0.08 % and 1.9 %). The rotor's share
/// (`pi4`, `pi5`: 0.2 % and 0.5 % of the arm's inertia) is below this noise: said so, and
/// lumped into the arm's inertia about the joint, compared as such (`m_l l_c^2 + i_l + n_g^2
/// j_m`, what flat motion sees). `b_v`: the least squares alone left it +1.6, +3.4, -20.7,
/// +3.1 % off over four seeds (the plate stays flat only while the torque stays under about
/// 7 N m, which bounds the arm's speed near 0.4 rad/s and the viscous torque near 0.02 N m, and
/// the velocities are differentiated from the noisy angles); the output-error refinement
/// (`identify::refine`, the default) gets +2.05 % on this seed (standard error 1.8 %), held to
/// the 3 % with the others.
#[test]
fn identifies_a_noisy_angles_only_robot_from_the_excitation_within_three_percent() {
    let truth = robot();
    let rec = excitation_and_orbit(truth, EXCITATION_DEFAULT, 3);
    let opts = noisy_options(&truth);
    let id = identify(&rec.trace, &rec.tau, &opts).unwrap();
    let p = id.params;
    for (name, got, w, tol) in [
        ("m_f", p.m_f, truth.m_f, 0.03),
        ("l_c", p.lc(), truth.lc(), 0.03),
        (
            "arm inertia about the joint",
            p.joint_inertia(),
            truth.joint_inertia(),
            0.03,
        ),
        ("tau_c", p.tau_c, truth.tau_c, 0.03),
        ("b_v", p.b_v, truth.b_v, 0.03),
    ] {
        eprintln!("{name}: {got} vs {w} ({:+.2} %)", 100.0 * (got - w) / w);
        assert!(((got - w) / w).abs() < tol, "{name}: {got} vs {w}");
    }
    assert!(
        id.base[3].value.is_none()
            && id.base[3]
                .not_identifiable
                .as_deref()
                .is_some_and(|w| w.contains("below this recording's noise")),
        "{:?}",
        id.base[3]
    );
    // What is identified instead is the sum, reported as its own estimate (pi3 alone is not,
    // and says why from the regressor's columns); checked against the hidden robot's sum.
    assert!(
        id.base[2].value.is_none()
            && id.base[2]
                .not_identifiable
                .as_deref()
                .is_some_and(|w| w.contains("columns of pi3 and pi5")),
        "{:?}",
        id.base[2]
    );
    let sum = id.base.iter().find(|e| e.name == "pi3+pi5").unwrap();
    let want = base_of(&truth)[2] + base_of(&truth)[4];
    let got = sum.value.unwrap();
    assert!(
        ((got - want) / want).abs() < 0.03,
        "pi3+pi5: {got} vs {want}"
    );
    assert!(id
        .not_identifiable
        .iter()
        .any(|s| s.starts_with("j_m and n_g")));
}

/// `b_v` within the 3 %: the tests' robot (a light arm: `m_l l_c` 28 % below the
/// paper's) on a larger, faster excitation, `excitation:0.4,0.8` (its arm held at 0.4 rad
/// needs 5.5 N m, 80 % of the excitation's torque limit; the default's 0.3 rad at 0.6 rad/s
/// leaves the viscous column under the noise). Four noise seeds, each 300 s of excitation
/// (flat throughout: asserted) + 30 s of robust orbit, identified as above: every parameter
/// within 3 % of the hidden robot (measured: `b_v` +2.0, -0.8, +1.8, -2.6 % by the least
/// squares alone, +0.1, -0.8, +1.9, +0.8 % with the output-error refinement, the default;
/// the amplitude governor leaves this light arm at scale 1; `tau_c` within 0.5 %, `m_f` 1.0 %,
/// `l_c` 0.01 %, the arm's inertia about the joint 0.03 %). Not for a heavy
/// arm: the README's robot (`m_l l_c` 1 % above the paper's) falls over at 0.35 rad (docs/
/// identify.md).
#[test]
fn a_larger_excitation_gets_b_v_within_three_percent_on_a_light_arm() {
    let truth = robot();
    let reference: tilting_controller::trajectory::Trajectory =
        "excitation:0.4,0.8".parse().unwrap();
    let opts = noisy_options(&truth);
    for seed in [3, 13, 23, 33] {
        let rec = excitation_and_orbit(truth, reference, seed);
        let p = identify(&rec.trace, &rec.tau, &opts).unwrap().params;
        assert_identifiable_within_3_percent(&p, &truth, seed);
    }
}

/// Asserts that `p` has every identifiable parameter (m_f, l_c, the arm's inertia about the
/// joint, tau_c, b_v) within 3 % of the hidden robot `truth`, printing each error.
fn assert_identifiable_within_3_percent(p: &Params, truth: &Params, seed: u64) {
    for (name, got, w) in [
        ("m_f", p.m_f, truth.m_f),
        ("l_c", p.lc(), truth.lc()),
        (
            "arm inertia about the joint",
            p.joint_inertia(),
            truth.joint_inertia(),
        ),
        ("tau_c", p.tau_c, truth.tau_c),
        ("b_v", p.b_v, truth.b_v),
    ] {
        eprintln!(
            "seed {seed} {name}: {got} vs {w} ({:+.2} %)",
            100.0 * (got - w) / w
        );
        assert!(
            ((got - w) / w).abs() < 0.03,
            "seed {seed} {name}: {got} vs {w}"
        );
    }
}

/// `b_v` within the 3 % on a heavy arm (`m_f` 0.8, `m_l` 1.2 of the paper's, with
/// `i_l` 0.06, `b_v` 0.05, `tau_c` 0.08) on the default excitation, which the amplitude
/// governor holds to about 0.25 rad and 0.32 rad/s: 300 s (flat throughout) + 30 s of robust
/// orbit, angles only with 1 mrad of noise and a 4,096-count encoder, four noise seeds.
///
/// The least squares alone left `b_v` at +19.0, +3.7, -6.6, +23.0 % (its differentiated
/// velocities); the output-error refinement (`identify::refine`, on by default) measured
/// -0.1, +2.0, -2.7, +1.9 %, with a standard error of 2.8 % (0.0014 N m s/rad): the
/// information 300 s of this excitation hold, so 3 % is met on these seeds, not guaranteed on
/// every seed (docs/identify.md). Asserted: every parameter within 3 % of the hidden robot,
/// `b_v` within 3 of its reported standard errors (the errors coherent), that standard error
/// below the least squares' own, and the refinement's arm inertia and gravity torque within
/// 0.5 % of the robot's (measured 0.02 %).
#[test]
fn the_output_error_refinement_gets_b_v_within_three_percent_on_a_heavy_arm() {
    let truth = Params {
        m_f: 0.8,
        m_l: 1.2,
        i_l: 0.06,
        b_v: 0.05,
        tau_c: 0.08,
        ..Params::default()
    };
    let opts = noisy_options(&truth);
    for seed in [3, 13, 23, 33] {
        let rec = excitation_and_orbit(truth, EXCITATION_DEFAULT, seed);
        let id = identify(&rec.trace, &rec.tau, &opts).unwrap();
        let ls = identify(
            &rec.trace,
            &rec.tau,
            &Options {
                refine: None,
                ..opts
            },
        )
        .unwrap();
        let p = id.params;
        assert_identifiable_within_3_percent(&p, &truth, seed);
        let se = id.base[5].std_error.unwrap();
        let se_ls = ls.base[5].std_error.unwrap();
        eprintln!(
            "seed {seed} b_v: least squares {} +- {se_ls}, refined +- {se}",
            ls.params.b_v
        );
        assert!((p.b_v - truth.b_v).abs() < 3.0 * se, "seed {seed}: {se}");
        assert!(se < se_ls, "seed {seed}: {se} vs {se_ls}");
        let r = id.refinement.as_ref().expect("the refinement ran");
        assert!(r.converged, "{r:?}");
        for (got, w) in [
            (r.value[0], truth.joint_inertia()),
            (r.value[1], truth.m_l * truth.lc() * truth.g),
        ] {
            assert!(((got - w) / w).abs() < 5e-3, "seed {seed}: {got} vs {w}");
        }
    }
}

/// The second robot of the README's headline chain (`bench/headline.sh`: a heavier plate, a
/// lighter arm, a geared rotor, more viscous and less Coulomb friction), noisy as the issue
/// measures: the joined refinement must end converged. On noisy angles through Coulomb
/// friction's stick/slip switches its cost is not smooth near the minimum: before the stall
/// rule (`refine::STALL_IN_SE`) it ran into its iteration limit 0.12 standard errors from the
/// undamped step on two of four seeds of the chain, and `identify` fell back to the least
/// squares' `tau_c` (-2.7 % instead of +0.7 %). Asserted: converged, `b_v` within 3 of its
/// standard errors and `tau_c` within 3 % of the hidden robot.
#[test]
fn the_refinement_converges_on_noisy_coulomb_friction() {
    let truth = Params {
        m_f: 1.15,
        m_l: 0.9,
        l_c: Some(1.9),
        i_l: 0.05,
        j_m: 0.01,
        n_g: 1.2,
        b_v: 0.05,
        tau_c: 0.03,
        ..Params::default()
    };
    let opts = noisy_options(&truth);
    for seed in [0, 2] {
        let rec = excitation_and_orbit(truth, EXCITATION_DEFAULT, seed);
        let id = identify(&rec.trace, &rec.tau, &opts).unwrap();
        let r = id.refinement.as_ref().expect("the refinement ran");
        eprintln!(
            "seed {seed}: {} iterations, converged {}, b_v {} +- {:?}, tau_c {}",
            r.iterations, r.converged, id.params.b_v, id.base[5].std_error, id.params.tau_c
        );
        assert!(r.converged, "seed {seed}: {r:?}");
        // No warning but the landing's: under 1 mrad of angle noise the rates around a
        // landing cannot tell the laws apart, and identify says so (the prior's law kept).
        let others: Vec<_> = id
            .warnings
            .iter()
            .filter(|w| !w.contains("landings do not tell the laws apart"))
            .collect();
        assert!(others.is_empty(), "seed {seed}: {others:?}");
        assert_eq!(id.params.impact, truth.impact);
        let se = id.base[5].std_error.unwrap();
        assert!(
            (id.params.b_v - truth.b_v).abs() < 3.0 * se,
            "seed {seed}: {se}"
        );
        assert!(
            ((id.params.tau_c - truth.tau_c) / truth.tau_c).abs() < 0.03,
            "seed {seed}: tau_c {}",
            id.params.tau_c
        );
    }
}

/// The plate's inertia `i_f` (`pi8`, its column `alpha_ddot` in the plate's row): a robot with
/// a uniform 1 kg, 1 m plate (`i_f = 0.083` kg m^2) and no rotor (with a rotor seen, `i_f` is
/// not separable from its share: docs/identify.md), 20 s of the orbit with exact velocities.
/// Asserted: `i_f` identified (standard error below a tenth of its value) and within 3 of its
/// standard errors of the robot's or 1e-4 relative, whichever is larger: noise-free, the
/// standard error (measured 1.3e-9) only measures the rows' scatter, not the bias of their
/// midpoint rule over the 1 ms intervals (`O(h^2)`; measured 6.7e-8, 8e-7 relative); written to
/// the parameters; the other base parameters within 1 % as without it.
#[test]
fn identifies_the_plates_inertia_from_the_tilts() {
    let truth = Params {
        i_f: 0.083,
        j_m: 0.0,
        n_g: 1.0,
        ..robot()
    };
    let (trace, tau, tilts) = record(truth, 20.0);
    assert!(tilts >= 4, "{tilts} tilts");
    let id = identify(&trace, &tau, &prior()).unwrap();
    let e = &id.base[7];
    let (v, se) = (e.value.unwrap(), e.std_error.unwrap());
    eprintln!("i_f = {v} +- {se} (truth 0.083)");
    assert!(se < 0.0083, "{e:?}");
    assert!((v - 0.083).abs() < (3.0 * se).max(0.083e-4), "{e:?}");
    assert!((id.params.i_f - v).abs() < 1e-15);
    let want = base_of(&truth);
    for i in [0, 1, 5, 6] {
        let got = id.base[i].value.unwrap();
        assert!(((got - want[i]) / want[i]).abs() < 0.01, "{i}: {got}");
    }
}

/// A compliant contact's settling after each lift-off, imposed on our rigid plant's exact
/// recording (60 s of the excitation, 20 s of the orbit, a plate of i_f = 0.083): the plate's
/// angle rings by `2e-3 e^(-t / 10 ms) sin(2 pi 30 Hz t)` after each mode change into a tilt,
/// as MuJoCo's softer contacts do (about 3e-3 rad), which no mode's equations describe. The
/// rigid recording is measured to settle at once (0 left out: its estimates as before, i_f and
/// m_f within 1 %); the ringing one to settle in 30 to 150 ms (the ringing is under 2 % of its
/// size after 40 ms, the weak form's windows are 100 ms), said in a warning, and with those
/// left out i_f and m_f come out nearer the truth than with none left out (`settle: 0`).
#[test]
fn the_contacts_settling_at_lift_offs_is_measured_and_left_out() {
    let truth = Params {
        i_f: 0.083,
        j_m: 0.0,
        n_g: 1.0,
        ..robot()
    };
    let (excitation, orbit) = excitation_and_orbit_scenarios(truth, EXCITATION_DEFAULT, 60.0, 20.0);
    let exact = |sc: Scenario| {
        let (report, logged) = simulate_logged(&sc, SimOptions::default(), &mut |_| {}).unwrap();
        assert!(report.fault.is_none(), "{:?}", report.fault);
        tilting_planner::identify::Recorded {
            trace: logged.trace,
            tau: logged.tau.into_iter().map(Some).collect(),
            robot: None,
            source: Default::default(),
        }
    };
    let mut rigid = exact(excitation);
    rigid.append(exact(orbit));
    let mut ringing = rigid.clone();
    let mut since = None;
    for k in 1..ringing.trace.samples.len() {
        let (prev, s) = (
            ringing.trace.samples[k - 1].mode,
            &mut ringing.trace.samples[k],
        );
        if s.mode != prev && s.mode != Mode::Flat {
            since = Some(s.t);
        }
        if let (Some(t0), true) = (since, s.mode != Mode::Flat) {
            let u = s.t - t0;
            let w = 2.0 * std::f64::consts::PI * 30.0;
            s.x[0] += 2e-3 * (-u / 0.01).exp() * (w * u).sin();
        }
    }
    let opts = Options {
        base: Params {
            m_l: truth.m_l,
            ..Params::default()
        },
        refine: None,
        ..Options::default()
    };
    // The plate's inertia as the fit saw it: pi8, or, when the rotor's columns carried it
    // (exact data: pi4 = pi5 = -i_f to 1e-6, told apart by their tiny standard errors), -pi4.
    let err = |id: &tilting_planner::identify::Identification| {
        let i_f = id.base[7].value.or(id.base[3].value.map(|v| -v)).unwrap();
        [
            (i_f - truth.i_f) / truth.i_f,
            (id.params.m_f - truth.m_f) / truth.m_f,
        ]
    };
    let left_out = |id: &tilting_planner::identify::Identification| {
        id.warnings
            .iter()
            .find(|w| w.contains("left out after each landing"))
            .cloned()
    };
    let id = identify(&rigid.trace, &rigid.tau, &opts).unwrap();
    eprintln!("rigid: {:?} {:?}", err(&id), left_out(&id));
    assert!(left_out(&id).is_none(), "{:?}", id.warnings);
    assert!(err(&id).iter().all(|e| e.abs() < 0.01), "{:?}", err(&id));
    let measured = identify(&ringing.trace, &ringing.tau, &opts).unwrap();
    let none = identify(
        &ringing.trace,
        &ringing.tau,
        &Options {
            settle: Some(0.0),
            ..opts
        },
    )
    .unwrap();
    let note = left_out(&measured).expect("the settling measured");
    let ms: f64 = note.split(' ').next().unwrap().parse().unwrap();
    eprintln!(
        "ringing: measured {ms} ms {:?}, none left out {:?}",
        err(&measured),
        err(&none)
    );
    assert!((30.0..=150.0).contains(&ms), "{note}");
    for i in 0..2 {
        assert!(
            err(&measured)[i].abs() < err(&none)[i].abs(),
            "{:?} vs {:?}",
            err(&measured),
            err(&none)
        );
    }
}

/// The paper's robot under the physical law with restitution `e`, on the 0.04 rad orbit's
/// gains of that law (`K_D` 10, `k` 750, `E_av` from `plan reach`), started on the paper's
/// orbit start, 20 s at 1 kHz.
fn physical_run(e: f64) -> (Trace, Vec<Option<f64>>, u64) {
    use tilting_plant::ImpactLaw;
    let truth = Params {
        impact: ImpactLaw::Physical,
        restitution: e,
        ..Params::default()
    };
    let sc = Scenario {
        params: truth,
        impact: ImpactLaw::Physical,
        mode: Mode::Left,
        x0: [
            0.0,
            std::f64::consts::FRAC_PI_2 + tilting_plant::paper::ORBIT_BETA0,
            0.0,
            tilting_plant::paper::ORBIT_BETA_DOT0,
        ],
        law: LawSpec {
            kd: 10.0,
            k: 750.0,
            energy_avg: 19.914796758,
            ..LawSpec::default()
        },
        control_period: 1e-3,
        duration: 20.0,
        ..Scenario::default()
    };
    let (report, logged) = simulate_logged(&sc, SimOptions::default(), &mut |_| {}).unwrap();
    assert!(report.fault.is_none(), "{:?}", report.fault);
    let tau = logged.tau.into_iter().map(Some).collect();
    (logged.trace, tau, report.stats.tilts)
}

#[test]
fn a_landings_pass_through_is_found_from_the_tilts_that_follow() {
    // Our rigid plant, the physical law: plastic landings (e = 0) and landings that pass on
    // into the next tilt (e = -0.15, as MuJoCo's stiff contact acts). The restitution that
    // makes the model's next tilt as high as the recorded one is the plant's, to 0.01 (the
    // model replays the recorded torques from the state just before each landing, estimated
    // from the samples: its error is what is left); written only where the tilts show it.
    for e in [0.0, -0.15] {
        let (trace, tau, tilts) = physical_run(e);
        assert!(tilts >= 20, "e {e}: {tilts} tilts");
        let opts = Options {
            base: Params {
                impact: tilting_plant::ImpactLaw::Physical,
                ..Params::default()
            },
            velocities: Velocities::Recorded,
            ..Options::default()
        };
        let id = identify(&trace, &tau, &opts).unwrap();
        let landing = id.landing.as_ref().expect("landings");
        let t = landing.by_tilts.as_ref().expect("tilts after landings");
        eprintln!("e {e}: by tilts {t:?}, rows {}", landing.restitution);
        assert!(t.landings >= 15, "{t:?}");
        assert!((t.e - e).abs() < 0.01, "e {e}: {t:?}");
        assert_eq!(id.params.impact, tilting_plant::ImpactLaw::Physical);
        if e == 0.0 {
            assert_eq!(id.params.restitution, 0.0);
        } else {
            assert!(
                (id.params.restitution - e).abs() < 0.01,
                "{}",
                id.params.restitution
            );
        }
    }
}
