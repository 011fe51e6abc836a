//! The physical landing law on the hardware robot ([`super::hw`]): the arm's momentum about the
//! joint kept, the closed-form energy lost, mirror symmetry, rebounds and pass-throughs.

use super::*;

/// The momentum conjugate to `beta`, `dT / d beta_dot`, from the geometric kinetic energy
/// (`kinematics`, which knows nothing of the mass matrix): `T` is quadratic in the rates, so
/// the central difference is exact up to rounding.
fn p_beta(p: &Params, mode: Mode, x: &State) -> f64 {
    let h = 0.5;
    let t = |bd: f64| kinetic(p, mode, x[0], x[1], x[2], bd);
    (t(x[3] + h) - t(x[3] - h)) / (2.0 * h)
}

/// The physical law on [`hw`], with restitution `e`.
fn physical(e: f64) -> Params {
    Params {
        impact: ImpactLaw::Physical,
        restitution: e,
        ..hw()
    }
}

/// A pre-impact state of a tilt from `from`: `alpha = 0`, the plate moving into the ground.
fn striking(rng: &mut Rng, from: Mode) -> State {
    let s = if from == Mode::Left { 1.0 } else { -1.0 };
    State::new(
        0.0,
        rng.uniform(0.3, PI - 0.3),
        -s * rng.uniform(0.05, 2.0),
        rng.uniform(-2.0, 2.0),
    )
}

#[test]
fn a_physical_landing_keeps_the_arms_momentum_about_the_joint() {
    // Without a rotor, p_beta is the arm's angular momentum about the joint, the only point
    // where an impulse reaches the arm: computed here from the bodies' positions and
    // velocities (the joint is the plate's centre, `foot`), before (tilted) and after (flat).
    let p = Params {
        j_m: 0.0,
        ..physical(0.0)
    };
    let mut rng = Rng(0xa11);
    for from in [Mode::Left, Mode::Right] {
        for _ in 0..100 {
            let x = striking(&mut rng, from);
            let arm_about_joint = |mode: Mode, x: &State| {
                let q = point_masses(&p, mode, x);
                let d = q.arm - q.foot;
                p.m_l * (d.x * q.arm_vel.y - d.y * q.arm_vel.x) + p.i_l * (x[2] + x[3])
            };
            let xp = ImpactLaw::Physical.apply(&p, from, &x);
            let (h0, h1) = (arm_about_joint(from, &x), arm_about_joint(Mode::Flat, &xp));
            assert!(
                (h1 - h0).abs() < 1e-12 * (1.0 + h0.abs()),
                "{from}: {h0} -> {h1}"
            );
            // The plate is at rest after a plastic landing.
            assert_eq!((xp[0], xp[2]), (0.0, 0.0));
            // A pass-through (e < 0): the arm's momentum about the joint is the same in the
            // other tilt, computed with that tilt's geometry (the joint moves with the plate
            // about the new pivot).
            let q = Params {
                restitution: -0.4,
                ..p
            };
            let tilting_plant::Landing::PassThrough(xq) = ImpactLaw::Physical.land(&q, from, &x)
            else {
                panic!("{from} {x:?}: no pass-through");
            };
            let h2 = arm_about_joint(from.mirrored(), &xq);
            assert!(
                (h2 - h0).abs() < 1e-12 * (1.0 + h0.abs()),
                "{from}: {h0} -> {h2}"
            );
        }
    }
}

#[test]
fn a_physical_landing_keeps_p_beta_and_loses_the_closed_form_energy() {
    // With the rotor behind its gear and the plate's inertia: p_beta (from the geometric
    // energy) is kept, for a plastic landing and for rebounds, and the kinetic energy lost is
    // (1 - e^2) (M11 - M12^2 / M22) alpha_dot-^2 / 2 >= 0 (the Schur complement: M is
    // positive definite), never a gain.
    let mut rng = Rng(0xe1a5);
    for e in [0.0, 0.3, 0.8, -0.3, -0.8] {
        let p = physical(e);
        for from in [Mode::Left, Mode::Right] {
            for _ in 0..100 {
                let x = striking(&mut rng, from);
                let (to, xp) = match ImpactLaw::Physical.land(&p, from, &x) {
                    tilting_plant::Landing::Plastic(xp) => (Mode::Flat, xp),
                    tilting_plant::Landing::Rebound(xp) => (from, xp),
                    tilting_plant::Landing::PassThrough(xp) => (from.mirrored(), xp),
                };
                // Above the threshold (2 f |e alpha_dot| >= 1 cm/s) every rebound (e > 0) and
                // every pass-through (e < 0) happens.
                let leaves = (e * x[2]).abs() >= 0.01;
                assert_eq!(to == from, e > 0.0 && leaves, "e {e} {x:?}");
                assert_eq!(to == from.mirrored(), e < 0.0 && leaves, "e {e} {x:?}");
                if to == from {
                    assert!(
                        (xp[2] + e * x[2]).abs() < 1e-15,
                        "alpha_dot+ = -e alpha_dot-"
                    );
                }
                if to == from.mirrored() {
                    // The plate turns on into the other tilt: its alpha_dot keeps its sign
                    // (alpha crosses 0 and leaves the ground on the other side).
                    assert!(xp[2] * x[2] > 0.0, "e {e}: {x:?} -> {xp:?}");
                }
                let (b0, b1) = (p_beta(&p, from, &x), p_beta(&p, to, &xp));
                assert!((b1 - b0).abs() < 1e-11 * (1.0 + b0.abs()), "e {e} {from}");
                let t0 = kinetic(&p, from, x[0], x[1], x[2], x[3]);
                let t1 = kinetic(&p, to, xp[0], xp[1], xp[2], xp[3]);
                let (m11, m12, m22) = mass_matrix(&p, from, x[1]);
                let e_eff = if to == Mode::Flat { 0.0 } else { e };
                let lost = 0.5 * (1.0 - e_eff * e_eff) * (m11 - m12 * m12 / m22) * x[2] * x[2];
                assert!(lost > 0.0);
                assert!(
                    ((t0 - t1) - lost).abs() < 1e-12 * (1.0 + t0),
                    "e {e}: {t0} -> {t1}"
                );
            }
        }
    }
}

#[test]
fn the_physical_landing_is_mirror_symmetric() {
    let mut rng = Rng(0x5a11);
    for e in [0.0, 0.5, -0.5] {
        let p = physical(e);
        for _ in 0..100 {
            let x = striking(&mut rng, Mode::Left);
            let (l, r) = (
                ImpactLaw::Physical.land(&p, Mode::Left, &x),
                ImpactLaw::Physical.land(&p, Mode::Right, &mirror(&x)),
            );
            use tilting_plant::Landing::{PassThrough, Plastic, Rebound};
            let (xl, xr) = match (l, r) {
                (Plastic(a), Plastic(b))
                | (Rebound(a), Rebound(b))
                | (PassThrough(a), PassThrough(b)) => (a, b),
                other => panic!("the mirror lands differently: {other:?}"),
            };
            assert!((mirror(&xl) - xr).norm() < 1e-13, "{xl:?} vs {xr:?}");
        }
    }
}

#[test]
fn the_papers_law_gains_energy_where_the_physical_law_loses_it() {
    // On the paper's robot at the orbit's landing (beta near pi/2, the plate striking at
    // -0.2 rad/s, the arm at 0.5 rad/s): the paper's law keeps the momentum about the pivot
    // edge and ends with more kinetic energy than it started with, about 12 %; the physical
    // law with less.
    let p = Params::default();
    let x = State::new(0.0, FRAC_PI_2 - 2e-4, -0.2, -0.5);
    let t = |mode: Mode, x: &State| kinetic(&p, mode, x[0], x[1], x[2], x[3]);
    let t0 = t(Mode::Left, &x);
    let paper = t(Mode::Flat, &ImpactLaw::Paper.apply(&p, Mode::Left, &x)) / t0;
    let phys = t(Mode::Flat, &ImpactLaw::Physical.apply(&p, Mode::Left, &x)) / t0;
    assert!(paper > 1.05, "the paper's law: T+/T- = {paper}");
    assert!(phys < 1.0, "the physical law: T+/T- = {phys}");
}

/// Records every transition.
#[derive(Default)]
struct Transitions(Vec<Transition>);
impl Observer for Transitions {
    fn transition(&mut self, ev: &Transition) {
        self.0.push(*ev);
    }
}

/// The arm held upright by a PD through the computed torque (the plate left to itself).
struct Upright(Params);
impl tilting_plant::TorqueLaw for Upright {
    fn torque(&self, _t: f64, mode: Mode, x: &State) -> f64 {
        let v = -100.0 * (x[1] - FRAC_PI_2) - 20.0 * x[3];
        torque_for_beta_ddot(&self.0, mode, x, v)
    }
}

#[test]
fn a_rebounding_plate_tilts_again_over_the_same_edge_and_settles() {
    // The plate let go 0.05 rad tilted over its left edge, the arm held upright, the physical
    // law with e = 0.5: each landing above the threshold is a touch (Left -> Flat) and a new
    // left tilt at the same instant with alpha_dot+ = -e alpha_dot- and p_beta kept; the
    // bounces shrink by e until one lands plastically (the arm's reaction then rocks the
    // plate over the other edge, where the same happens).
    let p = physical(0.5);
    let cfg = SimConfig {
        impact: ImpactLaw::Physical,
        ..tight(p)
    };
    let x0 = State::new(0.05, FRAC_PI_2, 0.0, 0.0);
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
    let mut obs = Transitions::default();
    plant
        .advance_continuous(&Upright(p), 0.5, &mut obs)
        .unwrap();
    let ev = &obs.0;
    let (mut bounced, mut plastic) = (0, 0);
    for (i, w) in ev.iter().enumerate().filter(|(_, w)| w.to == Mode::Flat) {
        let before = w.x_before;
        let next = ev.get(i + 1).filter(|n| n.t == w.t && n.to == w.from);
        match next.filter(|n| n.x_after[2] != 0.0) {
            // A rebound: over the same edge, alpha_dot+ = -e alpha_dot-, p_beta kept.
            Some(n) => {
                let after = n.x_after;
                assert!(
                    (after[2] + 0.5 * before[2]).abs() < 1e-12,
                    "{before:?} -> {after:?}"
                );
                let (b0, b1) = (p_beta(&p, w.from, &before), p_beta(&p, w.from, &after));
                assert!((b1 - b0).abs() < 1e-11 * (1.0 + b0.abs()));
                assert!(2.0 * p.f * 0.5 * before[2].abs() >= tilting_plant::REBOUND_MIN_SPEED);
                bounced += 1;
            }
            // Plastic: only below the threshold (the plate may then tip over either edge
            // under the arm's torque, starting at rest).
            None => {
                assert!(2.0 * p.f * 0.5 * before[2].abs() < tilting_plant::REBOUND_MIN_SPEED);
                assert_eq!((w.x_after[0], w.x_after[2]), (0.0, 0.0));
                plastic += 1;
            }
        }
    }
    // From 0.58 rad/s down to the 0.02 rad/s threshold by halving: 5 rebounds, then plastic.
    assert_eq!(
        ev[..11].iter().filter(|e| e.to == Mode::Left).count(),
        5,
        "{ev:#?}"
    );
    assert!(bounced >= 5 && plastic >= 1, "{bounced} {plastic}");
}

#[test]
fn a_passing_plate_tilts_on_over_the_striking_edge_and_settles() {
    // The plate let go 0.05 rad tilted over its left edge, the arm held upright, the physical
    // law with e = -0.5: each landing above the threshold is a touch (tilt -> Flat) and at the
    // same instant a tilt over the other edge, alpha_dot+ = 0.5 sqrt(S_from / S_to)
    // alpha_dot- (same sign: the plate turns on), p_beta kept; so the tilts alternate, each
    // landing's rate half the one before (what the arm's reaction adds aside), until one
    // lands plastically.
    let p = physical(-0.5);
    let cfg = SimConfig {
        impact: ImpactLaw::Physical,
        ..tight(p)
    };
    let x0 = State::new(0.05, FRAC_PI_2, 0.0, 0.0);
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
    let mut obs = Transitions::default();
    plant
        .advance_continuous(&Upright(p), 2.0, &mut obs)
        .unwrap();
    let ev = &obs.0;
    let mut passed = Vec::new();
    for (i, w) in ev.iter().enumerate().filter(|(_, w)| w.to == Mode::Flat) {
        let before = w.x_before;
        let next = ev
            .get(i + 1)
            .filter(|n| n.t == w.t && n.to == w.from.mirrored());
        if let Some(n) = next.filter(|n| n.x_after[2] != 0.0) {
            let after = n.x_after;
            let (f11, f12, f22) = mass_matrix(&p, w.from, before[1]);
            let (t11, t12, t22) = mass_matrix(&p, n.to, before[1]);
            let k = ((f11 - f12 * f12 / f22) / (t11 - t12 * t12 / t22)).sqrt();
            assert!(
                (after[2] - 0.5 * k * before[2]).abs() < 1e-12,
                "{before:?} -> {after:?}"
            );
            let (b0, b1) = (p_beta(&p, w.from, &before), p_beta(&p, n.to, &after));
            assert!((b1 - b0).abs() < 1e-11 * (1.0 + b0.abs()));
            passed.push(before[2].abs());
        }
    }
    // Alternating edges, the landing rate shrinking: at least 3 pass-throughs, each slower
    // than the one before.
    assert!(passed.len() >= 3, "{ev:#?}");
    assert!(passed.windows(2).all(|w| w[1] < w[0]), "{passed:?}");
}

#[test]
fn bad_landing_values_are_refused_with_the_field_and_its_range() {
    for (text, field) in [
        ("i_f = -0.1", "i_f"),
        ("impact = \"physical\"\nrestitution = 1.0", "restitution"),
        ("impact = \"physical\"\nrestitution = -1.0", "restitution"),
        ("impact = \"physical\"\nrestitution = nan", "restitution"),
        ("restitution = 0.2", "restitution"),
        ("impact = \"bouncy\"", "impact"),
        // The contact's flat spell: only beside a pass-through, and at most 50 ms.
        (
            "impact = \"physical\"\nrestitution = -0.1\ncontact_dwell = -0.001",
            "contact_dwell",
        ),
        (
            "impact = \"physical\"\nrestitution = -0.1\ncontact_dwell = 0.06",
            "contact_dwell",
        ),
        (
            "impact = \"physical\"\nrestitution = 0.2\ncontact_dwell = 0.002",
            "contact_dwell",
        ),
        ("contact_dwell = 0.002", "contact_dwell"),
    ] {
        let e = Params::from_toml_str(text).unwrap_err().to_string();
        assert!(e.contains(field), "{text}: {e}");
    }
    let p = Params::from_toml_str("impact = \"physical\"\nrestitution = 0.2\ni_f = 0.08").unwrap();
    assert_eq!(
        (p.impact, p.restitution, p.i_f),
        (ImpactLaw::Physical, 0.2, 0.08)
    );
    // Written back and read again, the same robot.
    assert_eq!(Params::from_toml_str(&p.to_toml_string()).unwrap(), p);
    let p =
        Params::from_toml_str("impact = \"physical\"\nrestitution = -0.1\ncontact_dwell = 0.002")
            .unwrap();
    assert_eq!(Params::from_toml_str(&p.to_toml_string()).unwrap(), p);
    // Another landing law has neither.
    let q = p.with_impact(ImpactLaw::Paper);
    assert_eq!((q.restitution, q.contact_dwell), (0.0, 0.0));
    q.validate().unwrap();
}

/// A flat report at a pass-through is the other tilt for `contact_dwell` from the spell's
/// first report, then flat; every report is itself without a dwell.
#[test]
fn a_flat_report_within_the_contact_dwell_is_the_tilt_passed_into() {
    let p =
        Params::from_toml_str("impact = \"physical\"\nrestitution = -0.1\ncontact_dwell = 0.002")
            .unwrap();
    let spell = Some((1.0, Mode::Left));
    // 1 kHz samples of the spell: the first (1.000), 1.001 and 1.002 (by sums of the period,
    // 1.002 lies a rounding error above 1 + 0.002) are the right tilt; 1.003 is flat.
    let t2 = 1.0 + 0.001 + 0.001;
    assert_eq!(p.sensed_mode(1.0, Mode::Flat, spell), Mode::Right);
    assert_eq!(p.sensed_mode(1.001, Mode::Flat, spell), Mode::Right);
    assert_eq!(p.sensed_mode(t2, Mode::Flat, spell), Mode::Right);
    assert_eq!(p.sensed_mode(1.003, Mode::Flat, spell), Mode::Flat);
    // Mirror: from the right tilt into the left.
    assert_eq!(
        p.sensed_mode(1.001, Mode::Flat, Some((1.0, Mode::Right))),
        Mode::Left
    );
    // A tilted report is taken as it is; without a spell (a flat start) flat is flat.
    for m in [Mode::Left, Mode::Right] {
        assert_eq!(p.sensed_mode(1.001, m, spell), m);
    }
    assert_eq!(p.sensed_mode(1.001, Mode::Flat, None), Mode::Flat);
    // The paper's robot: no dwell, every report as it is.
    let paper = Params::default();
    assert_eq!(paper.sensed_mode(1.0, Mode::Flat, spell), Mode::Flat);
}
