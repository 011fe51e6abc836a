//! A law the planner can plan (issue 30, item 3): a toy law written here, in a test, with no
//! line of library code for it, runs in `simulate`'s loop ([`tilting_sim::simulate_with`]) and
//! is planned by the planner's entry points ([`orbit::find_all_with`], [`orbit::solve_with`],
//! [`tilting_planner::continuation::follow_with`],
//! [`lyapunov::largest_with`], [`bifurcation::run_with`]) through
//! [`tilting_controller::PlannableLaw`], and crosses the wire: the planner's side encodes it as
//! a `tilting_proto::LawReference` (its name and parameters), the controller's side decodes
//! what the reference key carries and builds it by name through
//! [`tilting_controller::LawRegistry`], to the bit
//! ([`the_toy_crosses_the_wire_and_the_controller_builds_it_to_the_bit`]).
//!
//! Non-test files a new law touches (issue 30: at most 3): none to run, plan and encode it;
//! to be built by the controller node from a planner's message, 2: its module,
//! `controller/src/registry/plain_pd.rs` (the `PlainPd` below, moved there), and
//! `controller/src/registry.rs`, its `mod plain_pd;` and its `.register(PlainPd { .. })` line
//! in `LawRegistry::builtin` (the `register` call of the wire test here). The protocol, the
//! codec, the node and the planner are untouched.
//!
//! The toy is plain PD about upright, no feed-forward and no model:
//! `tau = K_p (pi/2 - beta) - K_d beta_dot` (N m). Upright is an equilibrium of the flat plate
//! (gravity's torque `m_l g l cos(beta)` vanishes there), so the flat hold is a fixed point,
//! and near it the arm is the linear oscillator
//! `m_l l^2 e'' + K_d e' + (K_p - m_l g l) e = 0` (`e = beta - pi/2`, docs/model.md's flat
//! equation with `cos(pi/2 + e) = -e`): the closed form the tests check the loops against.

use std::f64::consts::FRAC_PI_2;
use tilting_controller::{LawRegistry, LawSpec, PlannableLaw, Trajectory};
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::lyapunov;
use tilting_planner::orbit::{self, OrbitProblem};
use tilting_plant::{ConfigError, ImpactLaw, Mode, Params, State, TorqueLaw};
use tilting_proto::{codec, AnyReference, DecodeError, LawReference, Reference};
use tilting_sim::{simulate_with, Scenario, SimOptions};

/// Plain PD about upright: `tau = kp (pi/2 - beta) - kd beta_dot` (N m), `kp` in N m/rad and
/// `kd` in N m s/rad, both `>= 0`.
#[derive(Debug, Clone, PartialEq)]
struct PlainPd {
    model: Params,
    kp: f64,
    kd: f64,
}

impl TorqueLaw for PlainPd {
    fn torque(&self, _t: f64, _mode: Mode, x: &State) -> f64 {
        self.kp * (FRAC_PI_2 - x[1]) - self.kd * x[3]
    }
}

impl PlannableLaw for PlainPd {
    fn name(&self) -> &'static str {
        "plain-pd"
    }

    fn parameters(&self) -> Vec<(&'static str, f64)> {
        vec![("kp", self.kp), ("kd", self.kd)]
    }

    fn with_parameters(&self, model: &Params, values: &[f64]) -> Result<Self, ConfigError> {
        tilting_controller::plannable::check_count(&["kp", "kd"], values)?;
        for (field, v) in [("kp", values[0]), ("kd", values[1])] {
            tilting_plant::params::non_negative(field, v)?;
        }
        Ok(Self {
            model: *model,
            kp: values[0],
            kd: values[1],
        })
    }

    fn model(&self) -> &Params {
        &self.model
    }
}

/// The paper's model; the PD's gains are the paper's `K_P = 100 1/s^2`, `K_D = 14.14 1/s`
/// times the arm's inertia `m_l l^2` (4 kg m^2), so that without gravity it would be the
/// paper's law's arm.
fn toy() -> PlainPd {
    let p = Params::default();
    let inertia = p.m_l * p.l * p.l;
    PlainPd {
        model: p,
        kp: 100.0 * inertia,
        kd: 14.14 * inertia,
    }
}

/// The linear oscillator's `e(t)` from `e(0) = e0`, `e'(0) = 0`: `M e'' + c e' + s e = 0`,
/// underdamped.
fn oscillator(m: f64, c: f64, s: f64, e0: f64, t: f64) -> f64 {
    let sigma = c / (2.0 * m);
    let wd = (s / m - sigma * sigma).sqrt();
    assert!(wd > 0.0, "underdamped");
    e0 * (-sigma * t).exp() * ((wd * t).cos() + sigma / wd * (wd * t).sin())
}

/// The scenario of a `duration` s run from `(mode, x0)` in the paper's model, continuous
/// coupling (`control_period` 0) or sampled.
fn scenario(mode: Mode, x0: State, duration: f64, control_period: f64) -> Scenario {
    Scenario {
        mode,
        x0: [x0[0], x0[1], x0[2], x0[3]],
        duration,
        control_period,
        ..Scenario::default()
    }
}

fn recorded() -> SimOptions {
    SimOptions {
        record_samples: true,
        ..SimOptions::default()
    }
}

#[test]
fn in_simulates_loop_plain_pd_holds_the_flat_plate_as_the_closed_form_oscillator() {
    let law = toy();
    let p = law.model;
    let (m, s) = (p.m_l * p.l * p.l, law.kp - p.m_l * p.g * p.l);
    let e0 = 1e-3;
    let x0 = State::new(0.0, FRAC_PI_2 + e0, 0.0, 0.0);
    // Continuous coupling: the oscillator to the integrator's accuracy (the cubic term of
    // cos is 1e-8 of e0 here).
    let r = simulate_with(&scenario(Mode::Flat, x0, 3.0, 0.0), recorded(), &law).unwrap();
    assert!(r.fault.is_none() && r.events.is_empty(), "{:?}", r.fault);
    assert!(r.samples.len() >= 10, "{} samples", r.samples.len());
    for smp in &r.samples {
        assert_eq!(smp.mode, Mode::Flat);
        let e = oscillator(m, law.kd, s, e0, smp.t);
        assert!(
            (smp.x[1] - FRAC_PI_2 - e).abs() < 1e-6 * e0,
            "t = {}: e = {} vs {e}",
            smp.t,
            smp.x[1] - FRAC_PI_2
        );
    }
    // Sampled at 1 kHz, as the nodes run it: the same decay to the hold (the envelope
    // exp(-K_d t / 2 M) = 9e-4 at 1 s; the hold's half-sample lag changes it by ~1 %).
    let r = simulate_with(&scenario(Mode::Flat, x0, 1.0, 0.001), recorded(), &law).unwrap();
    assert!(r.fault.is_none() && r.events.is_empty(), "{:?}", r.fault);
    let envelope = e0 * (-law.kd / (2.0 * m)).exp();
    let e_end = r.final_state.x[1] - FRAC_PI_2;
    assert!(e_end.abs() < 2.0 * envelope, "{e_end} vs {envelope}");
    assert!(e_end.abs() > 0.0);
}

#[test]
fn planned_plain_pd_has_no_tilting_orbit_every_tilt_dies_into_the_flat_hold() {
    let law = toy();
    let pb = OrbitProblem::new(law.model, ImpactLaw::Paper, 100.0, 14.14);
    // The orbit search over its whole grid of starts: none.
    assert!(orbit::find_all_with(&pb, &law).is_empty());
    // Why: from the grid's starts the tilt lands, the plate stays flat, and the arm settles at
    // upright (the fixed point) in `simulate`'s loop; the planner's first landing is the
    // simulation's.
    let mut landed = 0;
    for bd0 in [0.3, 0.5, 1.0] {
        let Some(t_land) = orbit::landing_time_guess_with(&pb, &law, 0.0, bd0) else {
            continue;
        };
        landed += 1;
        let x0 = OrbitProblem::start(0.0, bd0);
        let r = simulate_with(&scenario(Mode::Left, x0, 20.0, 0.0), recorded(), &law).unwrap();
        assert!(r.fault.is_none(), "{bd0}: {:?}", r.fault);
        let first = r.events.iter().find(|e| e.from == Mode::Left).unwrap();
        assert!((first.t - t_land).abs() < 1e-7, "{} vs {t_land}", first.t);
        let f = &r.final_state;
        assert_eq!(f.mode, Mode::Flat, "{bd0}");
        assert!((f.x[1] - FRAC_PI_2).abs() < 1e-6, "{bd0}: {:?}", f.x);
        assert!(f.x[3].abs() < 1e-5, "{bd0}: {:?}", f.x);
    }
    assert!(landed >= 2);
    // The sweep's entry point sees the loop come to rest, and the tilt map is undefined (the
    // plate does not tilt back after the landing).
    let sw = Sweep {
        problem: pb,
        start_beta0: 0.0,
        start_beta_dot0: 0.5,
        energy_avg: 0.0,
        tilts: 10,
        keep: 5,
        period_tol: 1e-5,
    };
    let row = bifurcation::run_with(&sw, &law, 0.0);
    assert!(
        matches!(row.fault, Some(bifurcation::RowFault::NoTilt { .. })),
        "{:?}",
        row.fault
    );
    let e = lyapunov::largest_with(&pb, &law, nalgebra::Vector2::new(0.0, 0.5), 0, 10);
    assert!(e.unwrap_err().contains("tilt back"));
}

#[test]
fn the_toy_is_set_through_its_named_parameters_and_refuses_bad_ones_by_name() {
    let law = toy();
    let stiffer = law.with_parameter("kp", 500.0).unwrap();
    assert_eq!((stiffer.kp, stiffer.kd), (500.0, law.kd));
    assert_eq!(stiffer.parameter("kp"), Some(500.0));
    let e = law.with_parameter("kd", -1.0).unwrap_err().to_string();
    assert!(e.contains("kd"), "{e}");
    let e = law
        .with_parameters(&law.model, &[1.0])
        .unwrap_err()
        .to_string();
    assert!(e.contains("parameters"), "{e}");
    assert_eq!(stiffer.stiffness(Mode::Flat, &State::zeros()), None);
}

#[test]
fn continued_in_a_named_parameter_any_law_follows_the_problems_own_orbits() {
    use tilting_planner::continuation::follow_with;
    use tilting_plant::paper;
    let params = Params::default();
    let pb = OrbitProblem::new(params, ImpactLaw::Paper, paper::ORBIT_KP, paper::ORBIT_KD);
    let guess = [
        paper::ORBIT_BETA0,
        paper::ORBIT_BETA_DOT0,
        paper::ORBIT_HALF_PERIOD,
    ];
    // The paper's law, stepped through the trait's named parameter, against the orbit problem
    // built with each K_D directly (another path to the law): the same orbits, bit for bit.
    let kds = [14.14, 14.6, 15.2];
    let (found, stop) = follow_with(&pb, &pb.law(), "kd", &kds, guess);
    assert!(stop.is_none(), "{stop:?}");
    assert_eq!(found.len(), kds.len());
    let mut z = guess;
    for (kd, o) in &found {
        let direct = orbit::solve(
            &OrbitProblem::new(params, ImpactLaw::Paper, paper::ORBIT_KP, *kd),
            z,
        )
        .unwrap();
        assert_eq!(
            (o.beta0, o.beta_dot0, o.t_end, &o.multipliers),
            (
                direct.beta0,
                direct.beta_dot0,
                direct.t_end,
                &direct.multipliers
            )
        );
        z = [o.beta0, o.beta_dot0, o.t_end];
    }
    // The toy from the paper's orbit start: no orbit there, and its parameters are checked by
    // name.
    let law = toy();
    let (found, stop) = follow_with(&pb, &law, "kp", &[law.kp], guess);
    assert!(found.is_empty() && stop.is_some());
    let (_, stop) = follow_with(&pb, &law, "kp", &[-1.0], guess);
    assert!(stop.unwrap().contains("kp"));
    let (_, stop) = follow_with(&pb, &law, "k", &[1.0], guess);
    assert!(stop.unwrap().contains("parameters"));
}

/// The toy's message, as a planner would publish it: its name and its parameters in the order
/// of its list, holding upright.
fn toy_message(law: &PlainPd) -> LawReference {
    LawReference {
        trajectory: Reference::HOLD,
        amplitude: 0.0,
        omega: 0.0,
        law: law.name().to_owned(),
        parameters: law.parameters().into_iter().map(|(_, v)| v).collect(),
    }
}

#[test]
fn the_toy_crosses_the_wire_and_the_controller_builds_it_to_the_bit() {
    let law = toy();
    let msg = toy_message(&law);
    msg.validate().unwrap();
    let bytes = codec::encode(&msg);
    assert_eq!(bytes.len(), LawReference::SIZE);
    // A protocol-2 peer (the unchanged `Reference` decoding) refuses it by its size.
    assert_eq!(
        codec::decode::<Reference>(&bytes),
        Err(DecodeError::WrongSize {
            message: "Reference",
            expected: 57,
            got: 107
        })
    );
    // The controller node's path: decode the key's payload as either layout, then build the
    // law by name from its generic form. The toy's registry line:
    let registry = LawRegistry::builtin().register(toy());
    let received = codec::decode::<AnyReference>(&bytes).unwrap().law();
    assert_eq!(received, msg);
    let built = registry
        .build(&law.model, &LawSpec::default(), &received)
        .unwrap();
    let registered = built.registered().expect("a registered law");
    assert_eq!(registered.name(), "plain-pd");
    assert_eq!(registered.parameters(), &law.parameters()[..]);
    // Its torque is the direct law's, bit for bit, across modes, times and states.
    let mut n = 0;
    for mode in [Mode::Flat, Mode::Left, Mode::Right] {
        for (i, t) in [0.0, 0.37, 12.5].into_iter().enumerate() {
            for b in [-0.4, 0.0, 1.1, FRAC_PI_2, 2.9] {
                let x = State::new(0.01 * i as f64, b, -0.3 + b, 1.7 - b);
                let (got, want) = (built.torque(t, mode, &x), law.torque(t, mode, &x));
                assert_eq!(got.to_bits(), want.to_bits(), "{mode:?} t = {t} x = {x:?}");
                n += 1;
            }
        }
    }
    assert_eq!(n, 45);
    // And in `simulate`'s sampled loop (the node's rate): the same run to the last bit.
    let x0 = OrbitProblem::start(0.0, 0.5);
    let sc = scenario(Mode::Left, x0, 2.0, 0.001);
    let direct = simulate_with(&sc, recorded(), &law).unwrap();
    let over_wire = simulate_with(&sc, recorded(), &built).unwrap();
    assert!(!direct.events.is_empty(), "the run lands at least once");
    assert_eq!(direct.samples.len(), over_wire.samples.len());
    for (a, b) in direct.samples.iter().zip(&over_wire.samples) {
        assert_eq!((a.t.to_bits(), a.mode), (b.t.to_bits(), b.mode));
        for k in 0..4 {
            assert_eq!(a.x[k].to_bits(), b.x[k].to_bits(), "t = {}", a.t);
        }
    }
}

#[test]
fn the_controller_refuses_a_toy_it_cannot_build_naming_the_field() {
    let law = toy();
    let msg = toy_message(&law);
    let build = |registry: &LawRegistry, m: &LawReference| {
        registry
            .build(&law.model, &LawSpec::default(), m)
            .unwrap_err()
            .to_string()
    };
    // A controller without the toy's registry line names the law and the laws it has.
    let e = build(&LawRegistry::builtin(), &msg);
    assert!(
        e.contains("`law` = plain-pd") && e.contains("computed-torque"),
        "{e}"
    );
    let registry = LawRegistry::builtin().register(toy());
    assert_eq!(registry.names(), ["computed-torque", "plain-pd"]);
    // A bad value, named by the law; a list of another length; a trajectory it does not track.
    let bad = LawReference {
        parameters: vec![law.kp, -1.0],
        ..msg.clone()
    };
    assert!(build(&registry, &bad).contains("`kd` = -1"));
    let short = LawReference {
        parameters: vec![law.kp],
        ..msg.clone()
    };
    assert!(build(&registry, &short).contains("`parameters`"));
    let sine = LawReference {
        trajectory: Reference::SINUSOID,
        amplitude: 0.3,
        omega: 2.0,
        ..msg.clone()
    };
    assert!(build(&registry, &sine).contains("`trajectory` = sinusoid:0.3,2"));
    // The paper's law through the same registry is the controller's law of before: the
    // protocol-2 message's own conversion, from the 57-byte layout or the generic one.
    let paper = Reference {
        kind: Reference::SINUSOID,
        amplitude: 0.33,
        omega: 1.8,
        kp: 100.0,
        kd: 14.14,
        k: 500.0,
        energy_avg: 19.9,
        torque_limit: 40.0,
    };
    let want = tilting_controller::ControlConfig::from_wire(law.model, &paper).unwrap();
    for bytes in [
        codec::encode(&paper),
        codec::encode(&LawReference::from(&paper)),
    ] {
        let r = codec::decode::<AnyReference>(&bytes).unwrap().law();
        let c = registry.build(&law.model, &LawSpec::default(), &r).unwrap();
        assert!(c.registered().is_none());
        assert_eq!(*c.config(), want);
        assert_eq!(
            c.config().law.reference,
            Trajectory::Sinusoid {
                amplitude: 0.33,
                omega: 1.8
            }
        );
    }
}
