use super::*;
use nalgebra::Vector2;

/// Harmonic oscillator: the exact solution is known, so both the step and the dense output
/// can be checked against it.
#[test]
fn harmonic_oscillator_matches_closed_form() {
    let mut f = |_t: f64, y: &Vector2<f64>| Vector2::new(y[1], -y[0]);
    let mut st = Dop853::new(Tolerance::default());
    let (mut t, mut y) = (0.0, Vector2::new(1.0, 0.0));
    let mut f0 = f(t, &y);
    let mut worst_dense: f64 = 0.0;
    while t < 20.0 {
        let s = st.step(&mut f, t, &y, &f0, 20.0).unwrap();
        let d = st.dense(&mut f, &s);
        for i in 1..10 {
            let tt = s.t0 + s.h * i as f64 / 10.0;
            worst_dense = worst_dense.max((d.eval(tt)[0] - tt.cos()).abs());
        }
        assert!((d.eval(s.t1) - s.y1).norm() < 1e-14);
        t = s.t1;
        y = s.y1;
        f0 = *s.f1();
    }
    assert_eq!(t, 20.0);
    // Global error of a rtol = 1e-10 run over ~3 periods: a few 1e-10 at most.
    assert!((y[0] - 20f64.cos()).abs() < 1e-9, "{}", y[0] - 20f64.cos());
    assert!(worst_dense < 1e-9, "dense error {worst_dense}");
}

/// Order check: halving the tolerance's step sizes must shrink the error by about 2^8.
#[test]
fn fixed_steps_converge_at_eighth_order() {
    let mut f = |_t: f64, y: &Vector2<f64>| Vector2::new(y[1], -y[0]);
    let run = |n: usize, f: &mut dyn FnMut(f64, &Vector2<f64>) -> Vector2<f64>| {
        let mut st = Dop853::new(Tolerance {
            rtol: 1.0,
            atol: 1.0,
        });
        let h = 4.0 / n as f64;
        let (mut t, mut y) = (0.0, Vector2::new(1.0, 0.0));
        let mut g = |t: f64, y: &Vector2<f64>| f(t, y);
        let mut f0 = g(t, &y);
        for i in 0..n {
            st.h_next = h;
            let s = st.step(&mut g, t, &y, &f0, (i + 1) as f64 * h).unwrap();
            t = s.t1;
            y = s.y1;
            f0 = *s.f1();
        }
        (y[0] - 4f64.cos()).abs()
    };
    let e1 = run(8, &mut f);
    let e2 = run(16, &mut f);
    let order = (e1 / e2).log2();
    assert!(order > 7.5 && order < 9.5, "observed order {order}");
}

/// The 5(4) pair: a tolerance-controlled run of the harmonic oscillator meets the closed
/// form, and the auxiliary value at a step's end is the one of its end state.
#[test]
fn dopri5_harmonic_oscillator_matches_closed_form() {
    let mut f = |_t: f64, y: &Vector2<f64>, _end: bool| (Vector2::new(y[1], -y[0]), y[0] * y[0]);
    let mut st = Dopri5::new(Tolerance::default());
    let (mut t, mut y) = (0.0, Vector2::new(1.0, 0.0));
    let mut f0 = f(t, &y, true).0;
    while t < 20.0 {
        let s = st.step(&mut f, t, &y, &f0, 20.0).unwrap();
        assert_eq!(s.aux1, s.y1[0] * s.y1[0]);
        t = s.t1;
        y = s.y1;
        f0 = s.f1;
    }
    assert_eq!(t, 20.0);
    // rtol 3e-11 per step over ~3 periods: the global error stays in the 1e-9 class.
    assert!((y[0] - 20f64.cos()).abs() < 1e-8, "{}", y[0] - 20f64.cos());
    assert!((y[1] + 20f64.sin()).abs() < 1e-8, "{}", y[1] + 20f64.sin());
}

/// Order check of the 5th-order solution: halving the step shrinks the error by about 2^5.
#[test]
fn dopri5_fixed_steps_converge_at_fifth_order() {
    let run = |n: usize| {
        let mut f = |_t: f64, y: &Vector2<f64>, _end: bool| (Vector2::new(y[1], -y[0]), ());
        let mut st = Dopri5::new(Tolerance {
            rtol: 1.0,
            atol: 1.0,
        });
        let h = 4.0 / n as f64;
        let (mut t, mut y) = (0.0, Vector2::new(1.0, 0.0));
        let mut f0 = f(t, &y, true).0;
        for i in 0..n {
            st.h_next = h;
            let s = st.step(&mut f, t, &y, &f0, (i + 1) as f64 * h).unwrap();
            assert_eq!(s.h, h, "a step was rejected");
            t = s.t1;
            y = s.y1;
            f0 = s.f1;
        }
        (y[0] - 4f64.cos()).abs()
    };
    let order = (run(16) / run(32)).log2();
    assert!(order > 4.7 && order < 5.5, "observed order {order}");
}
