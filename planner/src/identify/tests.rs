use super::*;
use nalgebra::DMatrix;

fn fit(p4: f64, p5: f64, se: f64) -> Fit {
    Fit {
        x: vec![2.0, 1.7, 3.3, p4, p5],
        se: vec![se; 5],
        cov: DMatrix::from_diagonal_element(5, 5, se * se),
        condition: 1.0,
        residual_rms: 0.0,
    }
}

/// A friction estimate negative within its noise is set to 0 (MuJoCo's flat excitation:
/// tau_c = -8.8e-5 N m at many standard errors of 1e-5, below the floor of 1e-4 of a 5 N m
/// RMS torque); one clearly negative is refused naming the field and the value.
#[test]
fn friction_zero_within_its_noise_is_clamped_and_a_negative_one_refused() {
    let mut value = [None; N_BASE];
    let mut se = [None; N_BASE];
    value[6] = Some(-8.8e-5);
    se[6] = Some(1e-5);
    let noise = FRICTION_FLOOR * 5.0;
    let mut w = Vec::new();
    assert_eq!(
        check_friction(&value, &se, noise, 1.0, &mut w).unwrap(),
        (0.0, 0.0)
    );
    assert!(w[0].contains("tau_c") && w[0].contains("set to 0"), "{w:?}");
    // Within 2 standard errors, whatever the floor.
    value[6] = Some(-0.019);
    se[6] = Some(0.01);
    assert!(check_friction(&value, &se, 0.0, 1.0, &mut w).is_ok());
    // b_v is judged by its torque at the recording's rates: -4.4e-3 N m s at 86 standard
    // errors is 8.8e-4 N m at 0.2 rad/s, under a residual of 2.8e-3 N m, and 8.8e-3 N m,
    // over it, at 2 rad/s.
    let mut bv = [None; N_BASE];
    let mut bv_se = [None; N_BASE];
    bv[5] = Some(-4.4e-3);
    bv_se[5] = Some(5.1e-5);
    assert_eq!(
        check_friction(&bv, &bv_se, 2.8e-3, 0.2, &mut w).unwrap(),
        (0.0, 0.0)
    );
    let e = check_friction(&bv, &bv_se, 2.8e-3, 2.0, &mut w).unwrap_err();
    assert!(e.to_string().contains("b_v = -4.4000e-3"), "{e}");
    // Clearly negative: 5 standard errors and 100 times the floor.
    value[6] = Some(-0.05);
    let e = check_friction(&value, &se, noise, 1.0, &mut w).unwrap_err();
    let m = e.to_string();
    assert!(
        m.contains("tau_c = -5.0000e-2") && m.contains(">= 0"),
        "{m}"
    );
}

/// A rotor with j_m = 0.01 kg m^2 and n_g = 1.2 (pi4 = (n_g - 1) j_m = 0.002, pi5 =
/// (n_g^2 - 1) j_m = 0.0044) seen above the noise is kept; the same shares below 3 standard
/// errors are lumped; and shares that no j_m > 0, n_g > 0 produce (the recording of a heavy
/// arm gave pi4 = 1.951, pi5 = 1.956 at 3.8 standard errors, and m_f 0.106 for 1.15 kg) are
/// lumped too.
#[test]
fn an_impossible_rotor_is_lumped_like_an_unseen_one() {
    let cols = [0, 1, 2, 3, 4];
    assert_eq!(rotor_unseen(&fit(0.002, 0.0044, 1e-5), &cols, 1.0), None);
    let low = rotor_unseen(&fit(0.002, 0.0044, 1e-3), &cols, 1.0).unwrap();
    assert!(low.contains("below this recording's noise"), "{low}");
    let bad = rotor_unseen(&fit(1.951, 1.956, 0.51), &cols, 1.0).unwrap();
    assert!(bad.contains("fitted no rotor"), "{bad}");
    // pi5 / pi4 > 1 but j_m = pi4^2 / (pi5 - 2 pi4) < 0 (n_g < 1 with j_m < 0).
    assert!(rotor_unseen(&fit(0.01, 0.015, 1e-5), &cols, 1.0).is_some());
    // A reduction gear n_g = 0.5 is a rotor: pi4 = -0.5 j_m, pi5 = -0.75 j_m.
    assert_eq!(rotor_unseen(&fit(-0.005, -0.0075, 1e-5), &cols, 1.0), None);
}

/// Each option's range has two ends and a refusal past each that names the flag: the ends
/// themselves pass, a hair beyond (and NaN) does not.
#[test]
fn options_out_of_range_are_refused_naming_the_flag() {
    let ok = Options::default();
    assert!(ok.check().is_ok());
    type Set = fn(&mut Options, f64);
    let cases: [(&str, f64, f64, Set); 4] = [
        ("half-window", 0.002, 0.5, |o, v| o.half_window = v),
        ("window", 0.01, 2.0, |o, v| o.window = v),
        ("min-speed", 0.0, 10.0, |o, v| o.v_min = v),
        ("settle", 0.0, 1.0, |o, v| o.settle = Some(v)),
    ];
    for (flag, lo, hi, set) in cases {
        for v in [lo, hi] {
            let mut o = ok;
            set(&mut o, v);
            assert!(o.check().is_ok(), "{flag} = {v}");
        }
        for v in [lo - 1e-9, hi * (1.0 + 1e-9), f64::NAN] {
            let mut o = ok;
            set(&mut o, v);
            let e = o.check().unwrap_err().to_string();
            assert!(e.contains(&format!("`--{flag}` = {v}")), "{e}");
        }
    }
    assert!(check_fit_window(0.01).is_ok() && check_fit_window(10.0).is_ok());
    let e = check_fit_window(10.5).unwrap_err().to_string();
    assert!(
        e.contains("`--fit-window` = 10.5") && e.contains("[0.01, 10]"),
        "{e}"
    );
}
