//! The controller's state estimators (`tilting_controller::estimate`) against independent
//! truths: the true state of a re-simulated closed loop (the observer converges to it), the
//! mirror symmetry of the model (mirrored measurements give mirrored estimates), and the closed
//! form of a filtered finite difference on a sinusoid.

use std::f64::consts::PI;
use tilting_controller::estimate::{Estimator, Method, FD_TIME_CONSTANT};
use tilting_controller::{ControlConfig, Controller, LawSpec};
use tilting_plant::imperfect::{Imperfections, Measurement};
use tilting_plant::{paper, Mode, Plant, SimConfig, State};

/// One sample of a closed loop: time (s), measured mode, measured angles, torque sent (N m),
/// true state.
type Row = (f64, Mode, [f64; 2], f64, State);

/// The paper's loop at 1 kHz for `duration` s with the observer in the loop (`method`), the
/// plant measured by `imp` (angles only): the samples, with the estimates.
fn closed_loop(method: Method, imp: Imperfections, duration: f64) -> Vec<(Row, State)> {
    let cfg = SimConfig::default();
    let law = Controller::new(ControlConfig::new(cfg.params, LawSpec::default())).unwrap();
    let x0 = State::from(paper::orbit_x0());
    let mut plant = Plant::new(cfg, 0.0, paper::ORBIT_MODE, x0).unwrap();
    let mut hw = imp.hardware();
    let mut est = Estimator::new(method, cfg);
    let period = 1e-3;
    let n = (duration / period).round() as u64;
    let mut out = Vec::new();
    for k in 0..n {
        let t = k as f64 * period;
        let mode = plant.mode();
        let y: Measurement = hw.measure(&plant);
        let xh = est.update(t, mode, y.angles);
        let tau = law.torque(t, mode, &xh);
        est.sent(t, tau);
        out.push(((t, mode, y.angles, tau, plant.state()), xh));
        hw.advance(&mut plant, tau, (k + 1) as f64 * period, &mut ())
            .unwrap();
    }
    out
}

/// Noise-free angles and the exact model: from rates unknown (zero, 0.5 rad/s off in `beta_dot`)
/// the observer's rates converge to the true ones. Its error decays with the filter's time
/// constant (about 50 ms at `q = 0.3`, 1 mrad, 1 ms); after 1 s, over 4 s with about 18 landings
/// and lift-offs, the rates are within 1e-9 rad/s of the truth (the landings are estimated in the
/// same period as the plant's; the remaining error, 1e-13 measured, is the integrator's tolerance, 3e-11, and
/// round-off amplified by the loop). The loop survives: the closed loop through the estimate
/// keeps tilting.
#[test]
fn observer_converges_to_the_true_rates_with_exact_angles_and_model() {
    let imp = Imperfections {
        measure: tilting_plant::imperfect::Measure::Angles,
        ..Imperfections::default()
    };
    let run = closed_loop(Method::Observer, imp, 5.0);
    let first = run[0].1;
    assert_eq!((first[2], first[3]), (0.0, 0.0), "rates start unknown");
    let mut worst = 0.0f64;
    let mut landings = 0;
    for w in run.windows(2) {
        if w[0].0 .1 != Mode::Flat && w[1].0 .1 == Mode::Flat {
            landings += 1;
        }
    }
    for ((t, _, _, _, x), xh) in &run {
        if *t >= 1.0 {
            worst = worst.max((xh[2] - x[2]).abs()).max((xh[3] - x[3]).abs());
        }
    }
    eprintln!("{landings} landings; largest rate error after 1 s {worst:e} rad/s");
    assert!(landings >= 8, "{landings} landings");
    assert!(
        worst < 1e-9,
        "largest rate error after 1 s: {worst:e} rad/s"
    );
    // And it was not converged at the start.
    let early = run[5].0 .4[3] - run[5].1[3];
    assert!(early.abs() > 1e-2, "{early}");
}

/// The mirror map `(alpha, beta) -> (-alpha, pi - beta)`, rates negated, left and right
/// swapped, the torque negated, maps the model onto itself; so the estimators, fed the mirrored
/// measurements and torques of a noisy run with landings, give the mirrored estimates (to
/// 1e-9 rad, rad/s: the two runs take mirrored but not bit-identical floating-point paths).
#[test]
fn mirrored_measurements_give_mirrored_estimates() {
    let imp = Imperfections::measured_as_hardware(11);
    let run = closed_loop(Method::Observer, imp, 2.0);
    let mirror_mode = |m: Mode| match m {
        Mode::Flat => Mode::Flat,
        Mode::Left => Mode::Right,
        Mode::Right => Mode::Left,
    };
    for method in [Method::Observer, Method::Fd] {
        let cfg = SimConfig::default();
        let (mut a, mut b) = (Estimator::new(method, cfg), Estimator::new(method, cfg));
        let mut worst = 0.0f64;
        let mut tilted_right = 0;
        for ((t, mode, y, tau, _), _) in &run {
            let xa = a.update(*t, *mode, *y);
            a.sent(*t, *tau);
            let xb = b.update(*t, mirror_mode(*mode), [-y[0], PI - y[1]]);
            b.sent(*t, -tau);
            let want = [-xa[0], PI - xa[1], -xa[2], -xa[3]];
            for i in 0..4 {
                worst = worst.max((xb[i] - want[i]).abs());
            }
            if *mode == Mode::Right {
                tilted_right += 1;
            }
        }
        eprintln!("{method:?}: largest mirror mismatch {worst:e}");
        assert!(tilted_right > 100, "{tilted_right}");
        assert!(worst < 1e-9, "{method:?}: {worst:e}");
    }
}

/// The filtered finite difference on `theta(t) = A sin(w t)` sampled every `T`: the difference
/// `d_k = (2 A / T) sin(w T / 2) cos(w t_k - w T / 2)` through `r_k = r_{k-1} + g (d_k -
/// r_{k-1})`, `g = T / (T_f + T)`, settles on `Re(H U e^{i w t_k})` with `U = (2 A / T) sin(w T /
/// 2) e^{-i w T / 2}` and `H = g / (1 - (1 - g) e^{-i w T})`; its error against the true rate
/// `A w cos(w t_k)` is that closed form minus the rate. Checked to 1e-9 rad/s once the start's
/// transient, `(1 - g)^k`, is below 1e-12; the error itself is of the order of the filter's lag
/// (`w T_f`), far above that.
#[test]
fn finite_difference_error_matches_its_closed_form_on_a_sinusoid() {
    let (a, w, t_s) = (0.3, 2.0 * PI * 2.0, 1e-3);
    let g = t_s / (FD_TIME_CONSTANT + t_s);
    // Complex arithmetic by hand: (re, im).
    let mul = |x: (f64, f64), y: (f64, f64)| (x.0 * y.0 - x.1 * y.1, x.0 * y.1 + x.1 * y.0);
    let div = |x: (f64, f64), y: (f64, f64)| {
        let d = y.0 * y.0 + y.1 * y.1;
        ((x.0 * y.0 + x.1 * y.1) / d, (x.1 * y.0 - x.0 * y.1) / d)
    };
    let h = div(
        (g, 0.0),
        (
            1.0 - (1.0 - g) * (w * t_s).cos(),
            (1.0 - g) * (w * t_s).sin(),
        ),
    );
    let amp = 2.0 * a / t_s * (w * t_s / 2.0).sin();
    let u = (amp * (w * t_s / 2.0).cos(), -amp * (w * t_s / 2.0).sin());
    let hu = mul(h, u);
    let mut est = Estimator::new(Method::Fd, SimConfig::default());
    let settle = (1e-12f64.ln() / (1.0 - g).ln()).ceil() as u64;
    let (mut worst, mut largest_error) = (0.0f64, 0.0f64);
    for k in 0..(settle + 2000) {
        let t = k as f64 * t_s;
        let th = a * (w * t).sin();
        // Both angles follow the sinusoid (alpha offset to stay in the left tilt).
        let x = est.update(t, Mode::Left, [0.5 + th, 1.5 + th]);
        if k > settle {
            let closed = hu.0 * (w * t).cos() - hu.1 * (w * t).sin();
            let rate = a * w * (w * t).cos();
            for i in [2, 3] {
                worst = worst.max(((x[i] - rate) - (closed - rate)).abs());
            }
            largest_error = largest_error.max((closed - rate).abs());
        }
    }
    eprintln!("closed form matched to {worst:e} rad/s; lag error up to {largest_error} rad/s");
    assert!(worst < 1e-9, "{worst:e}");
    assert!(largest_error > 0.1, "the lag is visible: {largest_error}");
}

/// The controller's mode at a pass-through landing: a robot whose contact reports the plate
/// flat for up to 2 ms between two tilts ([`tilting_plant::Params::contact_dwell`]). The
/// flat reports of that spell are the tilt passed into; a longer flat spell turns flat after
/// 2 ms; the next tilt's report ends the spell; a flat start stays flat.
#[test]
fn flat_reports_of_a_pass_through_are_the_tilt_passed_into() {
    use tilting_controller::{Estimation, EstimatorChoice};
    let params = tilting_plant::Params::from_toml_str(
        "impact = \"physical\"\nrestitution = -0.11\ncontact_dwell = 0.002",
    )
    .unwrap();
    let model = SimConfig {
        params,
        ..SimConfig::default()
    };
    let mut e = Estimation::new(EstimatorChoice::Auto, model);
    let (l, r, f) = (Mode::Left, Mode::Right, Mode::Flat);
    // (time on the 1 kHz grid, reported, the mode the law answers in).
    let steps = [
        (f, f), // a flat start: no tilt before, flat
        (l, l),
        (l, l),
        (f, r), // the spell's first report: 0 ms
        (f, r), // 1 ms
        (f, r), // 2 ms
        (r, r), // the tilt shows
        (f, l), // the next landing's spell, from the right tilt
        (l, l),
        (f, r), // a spell that lasts: 0, 1, 2 ms into the right tilt ...
        (f, r),
        (f, r),
        (f, f), // ... then the plate is flat
        (f, f),
    ];
    for (k, (reported, want)) in steps.into_iter().enumerate() {
        let t = k as f64 * 1e-3;
        assert_eq!(e.mode(t, reported), want, "report {k} at {t} s: {reported}");
    }
    // Without a dwell (the paper's robot), every report is the mode.
    let mut e = Estimation::new(EstimatorChoice::Auto, SimConfig::default());
    for (k, (reported, _)) in steps.into_iter().enumerate() {
        assert_eq!(e.mode(k as f64 * 1e-3, reported), reported);
    }
}

/// Inside the contact's flat spell the law answers for the last tilted state carried by the
/// model under the torques sent, not for the spell's measurements (the contact's spring
/// motion): checked against the model run directly, from a state 1 ms before its
/// pass-through landing, with a held torque.
#[test]
fn inside_the_flat_spell_the_last_tilted_state_is_carried_by_the_model() {
    use tilting_controller::{Estimation, EstimatorChoice};
    let params = tilting_plant::Params::from_toml_str(
        "impact = \"physical\"\nrestitution = -0.11\ncontact_dwell = 0.002",
    )
    .unwrap();
    let model = SimConfig {
        params,
        impact: params.impact,
        ..SimConfig::default()
    };
    // A left tilt 1 ms before it lands (alpha falling at 0.42 rad/s), the arm moving.
    let x0 = State::new(0.0003, 1.56, -0.42, 0.02);
    let (t0, tau) = (10.0, 9.5);
    let mut e = Estimation::new(EstimatorChoice::Auto, model);
    let y = |x: &State| Measurement {
        angles: [x[0], x[1]],
        rates: Some([x[2], x[3]]),
    };
    assert_eq!(e.observe(t0, Mode::Left, &y(&x0)), (Mode::Left, x0));
    e.sent(t0, tau);
    // The truth: the model from x0 under the held torque.
    let truth = |t: f64| {
        let mut p = Plant::new(model, t0, Mode::Left, x0).unwrap();
        p.advance_held(tau, t, &mut ()).unwrap();
        (p.mode(), p.state())
    };
    // Two flat reports whose measurements are the contact's (a plate bouncing back).
    let spring = State::new(-0.00015, 1.56, 0.05, -0.49);
    for t in [t0 + 0.001, t0 + 0.002] {
        let (m, x) = e.observe(t, Mode::Flat, &y(&spring));
        let (tm, tx) = truth(t);
        assert_eq!(m, tm, "at {t} s");
        assert_eq!(m, Mode::Right, "the model has passed through by {t} s");
        for i in 0..4 {
            assert!((x[i] - tx[i]).abs() < 1e-12, "at {t} s: {x:?} vs {tx:?}");
        }
        e.sent(t, tau);
    }
    // The tilt's own report: measured again.
    let x3 = State::new(-0.0001, 1.559, -0.03, -0.45);
    assert_eq!(
        e.observe(t0 + 0.003, Mode::Right, &y(&x3)),
        (Mode::Right, x3)
    );
}
