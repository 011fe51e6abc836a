//! The hardware terms of the model (the arm's own inertia and an offset centre of mass, the
//! rotor's inertia through a gear, joint friction) checked against truths they did not produce:
//! the kinetic energy of the bodies written from the geometry (`kinematics`), Lagrange's
//! equations by finite differences, conservation and dissipation laws, closed forms and the
//! mirror symmetry.

use std::f64::consts::{FRAC_PI_2, PI};
use tilting_plant::dynamics::{accelerations, bias, mass_matrix, rhs, torque_for_beta_ddot, zmp};
use tilting_plant::kinematics::{angular_momentum, energy, mirror, pivot, point_masses};
use tilting_plant::ode::{Dop853, Tolerance};
use tilting_plant::{
    ConfigError, ImpactLaw, Joint, JointEvent, Mode, Observer, Params, Plant, SimConfig, State,
    Transition,
};

/// A robot unlike the paper's point masses: the centre of mass 0.6 m short of the tip, an arm
/// inertia of 0.25 kg m^2 about it, a 2 g cm^2-class rotor behind a 9:1 gear, a plate with its
/// own inertia (0.09 kg m^2, about a uniform 1 kg plate's 0.083).
fn hw() -> Params {
    Params {
        l_c: Some(1.4),
        i_l: 0.25,
        j_m: 0.002,
        n_g: 9.0,
        i_f: 0.09,
        ..Params::default()
    }
}

/// [`hw`] with viscous friction at the joint.
fn hw_viscous(b_v: f64) -> Params {
    Params { b_v, ..hw() }
}

struct Rng(u64);
impl Rng {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn random_state(rng: &mut Rng, mode: Mode) -> State {
    let (a, ad) = match mode {
        Mode::Flat => (0.0, 0.0),
        Mode::Left => (rng.uniform(0.0, 1.2), rng.uniform(-2.0, 2.0)),
        Mode::Right => (-rng.uniform(0.0, 1.2), rng.uniform(-2.0, 2.0)),
    };
    State::new(a, rng.uniform(0.3, PI - 0.3), ad, rng.uniform(-2.0, 2.0))
}

/// Kinetic energy (J) at configuration `(a, b)` with rates `(ad, bd)`, from the geometric
/// energy of `kinematics` (which knows nothing of the mass matrix).
fn kinetic(p: &Params, mode: Mode, a: f64, b: f64, ad: f64, bd: f64) -> f64 {
    energy(p, mode, &State::new(a, b, ad, bd)) - energy(p, mode, &State::new(a, b, 0.0, 0.0))
}

/// The mass matrix as the Hessian of the kinetic energy in the rates (exact for a quadratic
/// form, up to rounding).
fn hessian(p: &Params, mode: Mode, a: f64, b: f64) -> (f64, f64, f64) {
    let t10 = kinetic(p, mode, a, b, 1.0, 0.0);
    let t01 = kinetic(p, mode, a, b, 0.0, 1.0);
    let t11 = kinetic(p, mode, a, b, 1.0, 1.0);
    (2.0 * t10, t11 - t10 - t01, 2.0 * t01)
}

#[test]
fn mass_matrix_is_the_hessian_of_the_kinetic_energy() {
    let p = hw();
    let mut rng = Rng(0x5eed);
    for mode in [Mode::Left, Mode::Right] {
        for _ in 0..200 {
            let x = random_state(&mut rng, mode);
            let (h11, h12, h22) = hessian(&p, mode, x[0], x[1]);
            let (m11, m12, m22) = mass_matrix(&p, mode, x[1]);
            // Differences of energies of about 30 J: rounding near 1e-14 J.
            for (h, m) in [(h11, m11), (h12, m12), (h22, m22)] {
                assert!((h - m).abs() < 1e-12, "{mode}: {h} vs {m}");
            }
        }
    }
    // The point-mass terms alone would miss the rotational ones by I22 = 0.412 kg m^2.
    let (_, _, m22) = mass_matrix(&p, Mode::Left, 1.0);
    assert!((m22 - (1.4 * 1.4 + 0.25 + 81.0 * 0.002)).abs() < 1e-14);
}

/// `Params::joint_inertia` against two truths it does not use: the curvature
/// `d^2 T / d beta_dot^2` of the geometric kinetic energy (`kinematics`, a second difference in
/// `beta_dot` at `alpha_dot = 0`) and the mass matrix's `M22`, in every mode, at random angles,
/// for point masses, an offset centre of mass, an arm inertia, a direct-drive rotor and a
/// geared one.
#[test]
fn joint_inertia_is_the_kinetic_energys_curvature_in_beta_dot_and_m22() {
    let robots = [
        Params::default(),
        Params {
            l_c: Some(1.4),
            ..Params::default()
        },
        Params {
            i_l: 0.3,
            ..Params::default()
        },
        Params {
            j_m: 0.05,
            ..Params::default()
        },
        hw(),
        Params {
            m_l: 2.5,
            l: 1.0,
            l_c: Some(0.45),
            i_l: 0.07,
            j_m: 3e-4,
            n_g: 50.0,
            ..Params::default()
        },
    ];
    let mut rng = Rng(0x1e27);
    for p in robots {
        let j = p.joint_inertia();
        for mode in [Mode::Flat, Mode::Left, Mode::Right] {
            for _ in 0..20 {
                let x = random_state(&mut rng, mode);
                let (a, b) = (x[0], x[1]);
                // T(h) - 2 T(0) + T(-h) = J h^2 exactly for a quadratic form (T(0) = 0):
                // h = 1 rad/s; differences of energies of up to ~60 J: rounding ~1e-14 J.
                let curvature =
                    kinetic(&p, mode, a, b, 0.0, 1.0) + kinetic(&p, mode, a, b, 0.0, -1.0);
                assert!(
                    (curvature - j).abs() < 1e-12 * j,
                    "{p:?} {mode}: d2T/dbd2 = {curvature} vs J = {j}"
                );
                let (_, _, m22) = mass_matrix(&p, mode, b);
                assert!(
                    (m22 - j).abs() < 1e-14 * j,
                    "{p:?} {mode}: M22 = {m22} vs J = {j}"
                );
            }
        }
    }
    // The rotor counts through the gear squared: 81 j_m for hw()'s 9:1, 0.162 of 2.372 kg m^2.
    let p = hw();
    let rotorless = Params { j_m: 0.0, ..p }.joint_inertia();
    assert!((p.joint_inertia() - rotorless - 81.0 * p.j_m).abs() < 1e-14);
}

#[test]
fn bias_terms_follow_from_lagranges_equations_by_finite_differences() {
    // h = M_dot q_dot - dT/dq + dV/dq, every term by central differences of the geometric
    // energy: truncation O(d^2) ~ 1e-10, rounding ~ 1e-14 J / d ~ 1e-9; 1e-6 leaves room.
    let p = hw();
    let d = 1e-5;
    let mut rng = Rng(4242);
    for mode in [Mode::Left, Mode::Right] {
        for _ in 0..100 {
            let x = random_state(&mut rng, mode);
            let (a, b, ad, bd) = (x[0], x[1], x[2], x[3]);
            let t = |a: f64, b: f64| kinetic(&p, mode, a, b, ad, bd);
            let v = |a: f64, b: f64| energy(&p, mode, &State::new(a, b, 0.0, 0.0));
            let (mp, mm) = (
                hessian(&p, mode, a + d * ad, b + d * bd),
                hessian(&p, mode, a - d * ad, b - d * bd),
            );
            let md = (
                (mp.0 - mm.0) / (2.0 * d),
                (mp.1 - mm.1) / (2.0 * d),
                (mp.2 - mm.2) / (2.0 * d),
            );
            let dt_da = (t(a + d, b) - t(a - d, b)) / (2.0 * d);
            let dt_db = (t(a, b + d) - t(a, b - d)) / (2.0 * d);
            let dv_da = (v(a + d, b) - v(a - d, b)) / (2.0 * d);
            let dv_db = (v(a, b + d) - v(a, b - d)) / (2.0 * d);
            let h1 = md.0 * ad + md.1 * bd - dt_da + dv_da;
            let h2 = md.1 * ad + md.2 * bd - dt_db + dv_db;
            let (b1, b2) = bias(&p, mode, &x);
            assert!(
                (h1 - b1).abs() < 1e-6 * (1.0 + b1.abs()),
                "{mode}: {h1} vs {b1}"
            );
            assert!(
                (h2 - b2).abs() < 1e-6 * (1.0 + b2.abs()),
                "{mode}: {h2} vs {b2}"
            );
        }
    }
}

/// Integrates `mode`'s equations with `tau = 0` for `t_end` seconds without any event, and
/// returns the end state and `int b_v beta_dot^2 dt` (J) by 5-point Gauss-Legendre quadrature
/// on each step's dense output.
fn passive_flow(p: &Params, mode: Mode, x0: State, t_end: f64) -> (State, f64) {
    let mut f = |_t: f64, x: &State| rhs(p, mode, x, 0.0);
    let mut st = Dop853::new(Tolerance::default());
    let (mut t, mut x) = (0.0, x0);
    let mut f0 = f(t, &x);
    let mut dissipated = 0.0;
    let nodes = [
        (0.0, 128.0 / 225.0),
        (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
        (0.906_179_845_938_664, 0.236_926_885_056_189_1),
    ];
    while t < t_end {
        let s = st.step(&mut f, t, &x, &f0, t_end).unwrap();
        let dense = st.dense(&mut f, &s);
        let (mid, half) = (0.5 * (s.t0 + s.t1), 0.5 * (s.t1 - s.t0));
        for (u, w) in nodes {
            let bd = dense.eval(mid + half * u)[3];
            dissipated += half * w * p.b_v * bd * bd;
        }
        t = s.t1;
        x = s.y1;
        f0 = *s.f1();
    }
    (x, dissipated)
}

#[test]
fn passive_motion_with_arm_and_rotor_inertia_conserves_energy() {
    let p = hw();
    for (mode, x0) in [
        (Mode::Left, State::new(0.4, 1.2, 0.0, 0.5)),
        (Mode::Right, State::new(-0.3, 2.0, 0.3, -0.2)),
        (Mode::Left, State::new(0.1, FRAC_PI_2, 1.0, -1.0)),
        // The plate held flat: the arm a pendulum (here whirling over the top).
        (Mode::Flat, State::new(0.0, 0.3, 0.0, 4.0)),
    ] {
        let (x1, _) = passive_flow(&p, mode, x0, 10.0);
        let (e0, e1) = (energy(&p, mode, &x0), energy(&p, mode, &x1));
        // As for the point masses (plant/tests/plant/physics.rs): 1e-9 relative over 10 s.
        assert!(((e1 - e0) / e0).abs() < 1e-9, "{mode}: E0 {e0} E1 {e1}");
        // Not a trivial motion: the arm turned.
        assert!((x1[1] - x0[1]).abs() > 0.1 || (x1[3] - x0[3]).abs() > 0.1);
    }
}

#[test]
fn viscous_friction_dissipates_b_beta_dot_squared() {
    // dE/dt = -b_v beta_dot^2 with tau = 0: the energy lost over 5 s equals the integral along
    // the trajectory. Both sides carry the integrator's error (1e-10 relative of E ~ 30 J) and
    // the quadrature's (far below): 1e-8 J.
    let p = hw_viscous(0.3);
    for (mode, x0) in [
        (Mode::Left, State::new(0.4, 1.2, 0.0, 0.5)),
        (Mode::Right, State::new(-0.3, 2.0, 0.3, -0.2)),
        (Mode::Flat, State::new(0.0, 0.3, 0.0, 4.0)),
    ] {
        let (x1, w) = passive_flow(&p, mode, x0, 5.0);
        let (e0, e1) = (energy(&p, mode, &x0), energy(&p, mode, &x1));
        assert!(w > 0.5, "{mode}: little dissipation ({w} J), a weak test");
        assert!(
            (e0 - e1 - w).abs() < 1e-8,
            "{mode}: lost {} J, dissipated {w} J",
            e0 - e1
        );
    }
}

#[test]
fn gravity_compensated_arm_with_viscous_friction_decays_exponentially() {
    // Flat, tau = m_l g l_c cos(beta) cancels gravity: J beta_ddot = -b_v beta_dot with
    // J = m_l l_c^2 + i_l + n_g^2 j_m, so beta_dot = w0 exp(-b t / J) and beta = beta0 +
    // w0 J / b (1 - exp(-b t / J)). The plant runs the hybrid simulator (the plate stays
    // flat: the ZMP moves by tau / F_y < 0.25 m); its error is near its tolerance (1e-10).
    let p = hw_viscous(0.5);
    let lc = 1.4;
    let j = p.m_l * lc * lc + p.i_l + p.n_g * p.n_g * p.j_m;
    let (b0, w0) = (FRAC_PI_2 - 0.3, 0.1);
    let law = move |_t: f64, _m: Mode, x: &State| p.m_l * p.g * lc * x[1].cos();
    let mut plant = Plant::new(
        SimConfig {
            params: p,
            ..SimConfig::default()
        },
        0.0,
        Mode::Flat,
        State::new(0.0, b0, 0.0, w0),
    )
    .unwrap();
    for k in 1..=20 {
        let t = 0.2 * k as f64;
        plant.advance_continuous(&law, t, &mut ()).unwrap();
        let x = plant.state();
        let e = (-p.b_v * t / j).exp();
        assert_eq!(plant.mode(), Mode::Flat);
        assert!(
            (x[3] - w0 * e).abs() < 1e-10,
            "t {t}: {} vs {}",
            x[3],
            w0 * e
        );
        let beta = b0 + w0 * j / p.b_v * (1.0 - e);
        assert!((x[1] - beta).abs() < 1e-10, "t {t}: {} vs {beta}", x[1]);
    }
}

#[test]
fn hanging_arm_in_the_plant_loses_what_viscous_friction_dissipates() {
    // The hybrid plant under a held zero torque, the arm hanging below the flat plate (the ZMP
    // stays near the centre): E(t) - E(0) = -int b_v beta_dot^2 dt, the integral by Simpson's
    // rule on samples every 1 ms (error ~ h^4, far below the integrator's 1e-9 J).
    let p = hw_viscous(0.5);
    let x0 = State::new(0.0, -FRAC_PI_2 + 0.3, 0.0, 0.0);
    let cfg = SimConfig {
        params: p,
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, Mode::Flat, x0).unwrap();
    let h = 2e-3;
    let mut w = 0.0;
    let bd2 = |pl: &Plant| p.b_v * pl.state()[3] * pl.state()[3];
    let mut prev = bd2(&plant);
    for k in 0..1500 {
        let t0 = h * k as f64;
        plant.advance_held(0.0, t0 + 0.5 * h, &mut ()).unwrap();
        let mid = bd2(&plant);
        plant.advance_held(0.0, t0 + h, &mut ()).unwrap();
        let end = bd2(&plant);
        w += h / 6.0 * (prev + 4.0 * mid + end);
        prev = end;
    }
    assert_eq!(plant.transitions(), 0, "the plate stayed flat");
    let (e0, e1) = (
        energy(&p, Mode::Flat, &x0),
        energy(&p, Mode::Flat, &plant.state()),
    );
    assert!(w > 0.2, "little dissipation: {w} J");
    assert!(
        (e0 - e1 - w).abs() < 1e-8,
        "lost {} J, dissipated {w} J",
        e0 - e1
    );
}

#[test]
fn the_mirror_image_of_a_motion_is_a_motion_with_inertia_and_friction() {
    let p = Params {
        tau_c: 0.4,
        ..hw_viscous(0.3)
    };
    let mut rng = Rng(99);
    for (from, to) in [(Mode::Left, Mode::Right), (Mode::Flat, Mode::Flat)] {
        for _ in 0..300 {
            let x = random_state(&mut rng, from);
            let tau = rng.uniform(-30.0, 30.0);
            let d = rhs(&p, from, &x, tau);
            let dm = rhs(&p, to, &mirror(&x), -tau);
            for i in 0..4 {
                assert!(
                    (dm[i] + d[i]).abs() < 1e-12 * (1.0 + d[i].abs()),
                    "{from} {i}"
                );
            }
            let (e, em) = (energy(&p, from, &x), energy(&p, to, &mirror(&x)));
            assert!((e - em).abs() < 1e-12 * e.abs());
        }
    }
}

#[test]
fn impact_laws_keep_their_angular_momentum_with_inertia() {
    // The paper's law keeps the momentum about the pivot edge, the striking-edge law about the
    // other edge; both with the arm's and the rotor's spin counted (kinematics).
    let p = hw();
    let mut rng = Rng(7);
    for from in [Mode::Left, Mode::Right] {
        let other = if from == Mode::Left {
            Mode::Right
        } else {
            Mode::Left
        };
        for _ in 0..100 {
            let mut x = random_state(&mut rng, from);
            x[0] = 0.0;
            for (law, about) in [
                (ImpactLaw::Paper, pivot(&p, from)),
                (ImpactLaw::StrikingEdge, pivot(&p, other)),
            ] {
                let xp = law.apply(&p, from, &x);
                let l0 = angular_momentum(&p, from, &x, about);
                let l1 = angular_momentum(&p, Mode::Flat, &xp, about);
                assert!((l1 - l0).abs() < 1e-12 * (1.0 + l0.abs()), "{law:?} {from}");
            }
        }
    }
}

#[test]
fn zmp_of_the_resting_plate_is_the_centre_of_mass_with_an_offset_arm() {
    let p = hw_viscous(0.4);
    for i in 0..50 {
        let beta = 0.2 + (PI - 0.4) * i as f64 / 49.0;
        let x = State::new(0.0, beta, 0.0, 0.0);
        let tau = torque_for_beta_ddot(&p, Mode::Flat, &x, 0.0);
        let q = point_masses(&p, Mode::Flat, &x);
        let com_x = (p.m_f * q.foot.x + p.m_l * q.arm.x) / p.total_mass();
        assert!((zmp(&p, &x, tau) - com_x).abs() < 1e-14, "beta {beta}");
        // The tip is not the centre of mass here.
        assert!((q.tip - q.arm).norm() > 0.5);
    }
}

#[test]
fn computed_torque_is_the_inverse_of_the_dynamics_with_friction() {
    let p = hw_viscous(0.3);
    let pc = Params { tau_c: 0.7, ..p };
    let mut rng = Rng(31337);
    for mode in [Mode::Flat, Mode::Left, Mode::Right] {
        for k in 0..200 {
            let mut x = random_state(&mut rng, mode);
            // With Coulomb friction, from rest too (the compensation then follows v), and
            // v = 0 at rest (the joint sticks: beta_ddot = 0).
            if k % 3 == 0 {
                x[3] = 0.0;
            }
            let v = if k % 9 == 0 {
                0.0
            } else {
                rng.uniform(-30.0, 30.0)
            };
            let tau = torque_for_beta_ddot(&pc, mode, &x, v);
            let (_, bdd) = accelerations(&pc, mode, &x, tau);
            assert!(
                (bdd - v).abs() < 1e-10 * (1.0 + v.abs()),
                "{mode} {x:?}: {bdd} vs {v}"
            );
            let x = random_state(&mut rng, mode);
            let v = rng.uniform(-30.0, 30.0);
            let tau = torque_for_beta_ddot(&p, mode, &x, v);
            let (_, bdd) = accelerations(&p, mode, &x, tau);
            assert!(
                (bdd - v).abs() < 1e-10 * (1.0 + v.abs()),
                "{mode}: {bdd} vs {v}"
            );
            // The friction is really compensated: without it the torque is off by b_v beta_dot.
            let rigid = torque_for_beta_ddot(&hw(), mode, &x, v);
            assert!((tau - rigid - 0.3 * x[3]).abs() < 1e-10 * (1.0 + tau.abs()));
        }
    }
}

#[test]
fn the_papers_parameters_serialize_as_before() {
    // The hardware keys are left out at their defaults: a saved paper parameter file, and every
    // JSON that embeds the parameters, keeps its five keys.
    let text = toml::to_string(&Params::default()).unwrap();
    let keys: Vec<&str> = text
        .lines()
        .filter_map(|l| l.split('=').next())
        .map(str::trim)
        .collect();
    assert_eq!(keys, ["m_f", "m_l", "l", "f", "g"], "{text}");
    // And a hardware file round-trips.
    let p = hw_viscous(0.1);
    assert_eq!(
        Params::from_toml_str(&toml::to_string(&p).unwrap()).unwrap(),
        p
    );
}

#[test]
fn bad_hardware_values_are_refused_with_the_field_and_its_range() {
    for (text, field, range) in [
        ("i_l = -0.1", "i_l", ">= 0"),
        ("j_m = -1e-3", "j_m", ">= 0"),
        ("b_v = -0.5", "b_v", ">= 0"),
        ("n_g = 0.0", "n_g", "> 0"),
        ("l_c = 2.5", "l_c", "<= l"),
        ("l_c = 0.0", "l_c", "> 0"),
        ("b_v = nan", "b_v", "finite"),
        ("tau_c = -0.2", "tau_c", ">= 0"),
    ] {
        match Params::from_toml_str(text) {
            Err(e @ ConfigError::OutOfRange { field: f, .. }) => {
                assert_eq!(f, field, "{text}");
                let msg = e.to_string();
                assert!(msg.contains(field) && msg.contains(range), "{text}: {msg}");
            }
            other => panic!("{text}: {other:?}"),
        }
    }
    // A longer arm makes room for the centre of mass.
    assert!(Params::from_toml_str("l = 3.0\nl_c = 2.5").is_ok());
    // A centre of mass inside the plate's half-length and no inertia: the impact laws would
    // divide by zero at some arm angle; the simulator refuses it, naming l_c.
    let p = Params::from_toml_str("l_c = 0.3").unwrap();
    let cfg = SimConfig {
        params: p,
        ..SimConfig::default()
    };
    match Plant::new(cfg, 0.0, Mode::Flat, State::new(0.0, 1.0, 0.0, 0.0)) {
        Err(ConfigError::OutOfRange { field: "l_c", .. }) => {}
        other => panic!("{other:?}"),
    }
    // With enough inertia it is fine.
    let p = Params::from_toml_str("l_c = 0.3\ni_l = 0.1").unwrap();
    assert!(SimConfig {
        params: p,
        ..SimConfig::default()
    }
    .validate()
    .is_ok());
}

// --- Coulomb friction: stick and slip as hybrid events ------------------------------------

#[derive(Default)]
struct Log {
    joint: Vec<JointEvent>,
    transitions: Vec<Transition>,
}
impl Observer for Log {
    fn joint(&mut self, ev: &JointEvent) {
        self.joint.push(*ev);
    }
    fn transition(&mut self, ev: &Transition) {
        self.transitions.push(*ev);
    }
}

fn coulomb(tau_c: f64, b_v: f64) -> Params {
    Params { tau_c, b_v, ..hw() }
}

/// Tolerances as tight as the mode-transition test's (plant/tests/plant/physics.rs), so event times
/// can be compared with closed forms to 1e-10 s.
fn tight(p: Params) -> SimConfig {
    SimConfig {
        params: p,
        tol: Tolerance {
            rtol: 1e-12,
            atol: 1e-14,
        },
        ..SimConfig::default()
    }
}

/// The hold torque of a flat arm at `beta`, written out: `m_l g l_c cos(beta)` (N m).
fn flat_hold(p: &Params, beta: f64) -> f64 {
    p.m_l * p.g * 1.4 * beta.cos()
}

#[test]
fn an_arm_inside_the_static_band_stays_exactly_still() {
    // Flat: a sampled controller's torques all within tau_c of the hold torque: no state bit
    // changes over 1 s of 1 kHz samples, and no event.
    let p = coulomb(2.0, 0.3);
    let x0 = State::new(0.0, 1.2, 0.0, 0.0);
    let mut plant = Plant::new(tight(p), 0.0, Mode::Flat, x0).unwrap();
    let mut log = Log::default();
    for k in 0..1000 {
        let tau = flat_hold(&p, 1.2) + 1.99 * (k as f64).sin();
        plant
            .advance_held(tau, 1e-3 * (k + 1) as f64, &mut log)
            .unwrap();
        assert_eq!(plant.joint(), Joint::Stuck);
    }
    let bits = |x: State| x.map(f64::to_bits);
    assert_eq!(bits(plant.state()), bits(x0));
    assert!(log.joint.is_empty() && log.transitions.is_empty());
    // Just outside the band it slides, the way the excess pushes.
    plant
        .advance_held(flat_hold(&p, 1.2) - 2.01, 1.1, &mut log)
        .unwrap();
    assert_eq!((log.joint.len(), log.joint[0].to), (1, Joint::Backward));
    assert!(plant.state()[3] < 0.0);
}

#[test]
fn a_stuck_arm_tilts_with_the_plate_as_one_body() {
    // Tilted left and stuck (the torque holds within a wide band): beta and beta_dot keep
    // their bits while the plate rocks, and the energy of the rigid body is conserved (the
    // joint does no work: it does not turn). The plate lands; the impact unsticks the arm.
    let p = coulomb(40.0, 0.0);
    let x0 = State::new(0.05, 1.9, 0.4, 0.0);
    let mut plant = Plant::new(tight(p), 0.0, Mode::Left, x0).unwrap();
    let mut log = Log::default();
    let tau = 3.0;
    let e0 = energy(&p, Mode::Left, &x0);
    let mut t = 0.0;
    while plant.mode() == Mode::Left && t < 3.0 {
        let x = plant.state();
        assert_eq!((x[1].to_bits(), x[3]), (1.9f64.to_bits(), 0.0), "t {t}");
        let e = energy(&p, Mode::Left, &x);
        assert!((e - e0).abs() < 1e-9 * e0, "t {t}: {e} vs {e0}");
        t += 1e-3;
        plant.advance_held(tau, t, &mut log).unwrap();
    }
    assert_eq!(log.transitions[0].to, Mode::Flat, "it landed");
    assert!(
        log.transitions[0].x_after[3] != 0.0,
        "the impact moved the arm"
    );
    assert_eq!(log.joint[0].from, Joint::Stuck, "and unstuck it");
}

#[test]
fn a_swinging_arm_loses_tau_c_times_the_angle_it_travels() {
    // Tau = 0, the arm swinging below the flat plate: dE = -tau_c |d beta| on every slide, so
    // E(0) - E(end) = tau_c * (total variation of beta), the slides' ends given by the joint
    // events; it ends stuck where gravity's torque is inside the band. Both sides are exact
    // but for the integrator (1e-10 relative of E): 1e-9 J.
    let p = coulomb(0.3, 0.0);
    let x0 = State::new(0.0, -FRAC_PI_2 + 0.4, 0.0, 0.0);
    let mut plant = Plant::new(tight(p), 0.0, Mode::Flat, x0).unwrap();
    let mut log = Log::default();
    plant.advance_held(0.0, 20.0, &mut log).unwrap();
    assert_eq!(plant.joint(), Joint::Stuck);
    assert!(log.joint.len() >= 6, "a few swings: {:?}", log.joint.len());
    let mut travel = 0.0;
    let mut b = x0[1];
    for ev in &log.joint {
        travel += (ev.x[1] - b).abs();
        b = ev.x[1];
        if ev.to == Joint::Stuck || ev.from == Joint::Forward || ev.from == Joint::Backward {
            assert_eq!(ev.x[3], 0.0, "slides end at rest exactly");
        }
    }
    travel += (plant.state()[1] - b).abs();
    let lost = energy(&p, Mode::Flat, &x0) - energy(&p, Mode::Flat, &plant.state());
    assert!(
        (lost - p.tau_c * travel).abs() < 1e-9,
        "lost {lost} J, tau_c * travel = {} J",
        p.tau_c * travel
    );
    // It stopped inside the band.
    assert!(flat_hold(&p, plant.state()[1]).abs() < p.tau_c);
}

#[test]
fn stick_and_slip_times_match_closed_forms() {
    // Flat, gravity compensated (tau = m_l g l_c cos(beta) + u): M22 beta_ddot = u - b_v
    // beta_dot - tau_c sign(beta_dot) with M22 = m_l l_c^2 + i_l + n_g^2 j_m.
    let (tau_c, b_v) = (0.5, 0.8);
    let p = coulomb(tau_c, b_v);
    let j = p.m_l * 1.4 * 1.4 + p.i_l + p.n_g * p.n_g * p.j_m;
    // 1) u = 0 from beta_dot = w0 > 0: it stops at t* = (J / b) ln(1 + b w0 / tau_c), and
    //    sticks there (u = 0 is inside the band).
    let w0 = 0.3;
    let comp = move |_t: f64, _m: Mode, x: &State| p.m_l * p.g * 1.4 * x[1].cos();
    let x0 = State::new(0.0, 1.3, 0.0, w0);
    let mut plant = Plant::new(tight(p), 0.0, Mode::Flat, x0).unwrap();
    let mut log = Log::default();
    plant.advance_continuous(&comp, 3.0, &mut log).unwrap();
    let t_stick = j / b_v * (1.0 + b_v * w0 / tau_c).ln();
    let ev = log.joint[0];
    assert_eq!(
        (ev.from, ev.to, log.joint.len()),
        (Joint::Forward, Joint::Stuck, 1)
    );
    // The mode transitions' accuracy at these tolerances (plant/tests/plant/physics.rs): 1e-10 s.
    assert!((ev.t - t_stick).abs() < 1e-10, "{} vs {t_stick}", ev.t);
    let travel = j / b_v * (w0 - tau_c / b_v * (1.0 + b_v * w0 / tau_c).ln());
    assert!((plant.state()[1] - 1.3 - travel).abs() < 1e-10);

    // 2) Stuck at rest, u = r t: it slides when u reaches tau_c, at t = tau_c / r exactly (the
    //    state is constant until then: only the location's width, 1e-13 s, remains); then
    //    M22 beta_ddot = r t - tau_c - b beta_dot.
    let r = 0.8;
    let ramp = move |t: f64, _m: Mode, x: &State| p.m_l * p.g * 1.4 * x[1].cos() + r * t;
    let x0 = State::new(0.0, 1.3, 0.0, 0.0);
    let mut plant = Plant::new(tight(p), 0.0, Mode::Flat, x0).unwrap();
    let mut log = Log::default();
    plant.advance_continuous(&ramp, 0.6, &mut log).unwrap();
    assert_eq!(plant.state(), x0, "still stuck at t = 0.6 s");
    plant.advance_continuous(&ramp, 1.2, &mut log).unwrap();
    let ev = log.joint[log.joint.len() - 1];
    assert_eq!((ev.from, ev.to), (Joint::Stuck, Joint::Forward));
    assert!(
        (ev.t - tau_c / r).abs() < 1e-12,
        "{} vs {}",
        ev.t,
        tau_c / r
    );
    // After the release: with s = t - t_r and k = b / J, beta_dot = (r / b)(s - (1 -
    // exp(-k s)) / k).
    let (s, k) = (1.2 - tau_c / r, b_v / j);
    let bd = r / b_v * (s - (1.0 - (-k * s).exp()) / k);
    assert!(
        (plant.state()[3] - bd).abs() < 1e-10,
        "{} vs {bd}",
        plant.state()[3]
    );
}

#[test]
fn a_sampled_pd_loop_with_coulomb_friction_in_plant_and_model_holds_the_arm() {
    // The computed torque of a model that knows the friction, sampled at 1 kHz, drives the
    // flat arm to upright: the joint alternates between sliding and sticking and ends still
    // near pi/2; the Zeno guard never trips.
    let p = coulomb(0.8, 0.2);
    let mut plant = Plant::new(
        SimConfig {
            params: p,
            ..SimConfig::default()
        },
        0.0,
        Mode::Flat,
        State::new(0.0, 1.4, 0.0, 0.0),
    )
    .unwrap();
    let mut log = Log::default();
    for k in 0..3000 {
        let x = plant.state();
        let v = 14.14 * (0.0 - x[3]) + 100.0 * (FRAC_PI_2 - x[1]);
        let tau = torque_for_beta_ddot(&p, Mode::Flat, &x, v);
        plant
            .advance_held(tau, 1e-3 * (k + 1) as f64, &mut log)
            .unwrap();
    }
    assert!(!log.joint.is_empty());
    assert!(
        (plant.state()[1] - FRAC_PI_2).abs() < 1e-3,
        "{:?}",
        plant.state()
    );
    assert_eq!(plant.mode(), Mode::Flat);
}

#[test]
fn mirrored_runs_with_friction_and_inertia_mirror_each_other() {
    // A PD loop whose model leaves out the plant's Coulomb friction: tilts, landings and
    // stick/slip events. Its mirror image (tau -> -tau through the mirror) has the mirrored
    // mode transitions and the joint events with forward and backward swapped, at the same
    // times (1e-9 s: the run is chaotic enough that round-off grows over the 3 s).
    let plant_p = coulomb(0.3, 0.1);
    let model = Params {
        tau_c: 0.0,
        ..plant_p
    };
    let law = move |_t: f64, m: Mode, x: &State| {
        torque_for_beta_ddot(
            &model,
            m,
            x,
            14.14 * (0.0 - x[3]) + 100.0 * (FRAC_PI_2 - x[1]),
        )
    };
    let mirrored = move |t: f64, m: Mode, x: &State| -law(t, m.mirrored(), &mirror(x));
    let x0 = State::new(0.0, FRAC_PI_2 - 0.0003, 0.0, 0.6);
    let run = |mode: Mode, x: State, mirror_law: bool| {
        let mut plant = Plant::new(tight(plant_p), 0.0, mode, x).unwrap();
        let mut log = Log::default();
        if mirror_law {
            plant.advance_continuous(&mirrored, 3.0, &mut log).unwrap();
        } else {
            plant.advance_continuous(&law, 3.0, &mut log).unwrap();
        }
        log
    };
    let a = run(Mode::Left, x0, false);
    let b = run(Mode::Right, mirror(&x0), true);
    assert!(
        a.transitions.len() >= 3,
        "{} transitions",
        a.transitions.len()
    );
    assert!(!a.joint.is_empty(), "no joint event");
    assert_eq!(a.transitions.len(), b.transitions.len());
    for (u, v) in a.transitions.iter().zip(&b.transitions) {
        assert_eq!((u.from.mirrored(), u.to.mirrored()), (v.from, v.to));
        assert!((u.t - v.t).abs() < 1e-9, "{} vs {}", u.t, v.t);
    }
    let swap = |j: Joint| match j {
        Joint::Forward => Joint::Backward,
        Joint::Backward => Joint::Forward,
        other => other,
    };
    assert_eq!(a.joint.len(), b.joint.len());
    for (u, v) in a.joint.iter().zip(&b.joint) {
        assert_eq!(
            (swap(u.from), swap(u.to), u.mode.mirrored()),
            (v.from, v.to, v.mode)
        );
        assert!((u.t - v.t).abs() < 1e-9, "{} vs {}", u.t, v.t);
    }
}

#[test]
fn the_dynamics_are_linear_in_seven_base_parameters() {
    // docs/model.md's regressor form, written out here from the base parameters alone, against
    // the model's mass matrix and bias terms at random states and accelerations (the plate's
    // inertia `i_f`, an eighth, enters the plate's row alone, as `i_f alpha_ddot`).
    let p = hw();
    let (f, g) = (p.f, p.g);
    let (lc, jm, n) = (1.4, p.j_m, p.n_g);
    let pi = [
        p.m_f + p.m_l,
        p.m_l * lc,
        p.m_l * lc * lc + p.i_l + jm,
        (n - 1.0) * jm,
        (n * n - 1.0) * jm,
    ];
    let mut rng = Rng(2718);
    for mode in [Mode::Left, Mode::Right] {
        let sf = if mode == Mode::Left { f } else { -f };
        for _ in 0..200 {
            let x = random_state(&mut rng, mode);
            let (a, b, ad, bd) = (x[0], x[1], x[2], x[3]);
            let (add, bdd) = (rng.uniform(-20.0, 20.0), rng.uniform(-20.0, 20.0));
            let row1 = (sf * sf * pi[0] + 2.0 * sf * b.cos() * pi[1] + pi[2] + p.i_f) * add
                + (sf * b.cos() * pi[1] + pi[2] + pi[3]) * bdd
                - sf * b.sin() * (2.0 * ad * bd + bd * bd) * pi[1]
                + g * sf * a.cos() * pi[0]
                + g * (a + b).cos() * pi[1];
            let row2 = (sf * b.cos() * pi[1] + pi[2] + pi[3]) * add
                + (pi[2] + pi[4]) * bdd
                + sf * b.sin() * ad * ad * pi[1]
                + g * (a + b).cos() * pi[1];
            let (m11, m12, m22) = mass_matrix(&p, mode, b);
            let (h1, h2) = bias(&p, mode, &x);
            let (r1, r2) = (m11 * add + m12 * bdd + h1, m12 * add + m22 * bdd + h2);
            assert!(
                (row1 - r1).abs() < 1e-11 * (1.0 + r1.abs()),
                "{mode}: {row1} vs {r1}"
            );
            assert!(
                (row2 - r2).abs() < 1e-11 * (1.0 + r2.abs()),
                "{mode}: {row2} vs {r2}"
            );
        }
    }
    // The rotor and its gear come back from pi4 and pi5 (N + 1 = pi5 / pi4).
    let n_back = pi[4] / pi[3] - 1.0;
    assert!((n_back - n).abs() < 1e-12 && (pi[3] / (n_back - 1.0) - jm).abs() < 1e-15);
}

// ---- The physical landing law: landing.rs ---------------------------------------------------

mod landing;
