//! Runs the built `tilting plan continuation`: the JSON carries the branches, the flips (the
//! first one at the project's k* = 1923.99) and the Lyapunov curve (negative on the stable
//! period-1 orbit); bad input is refused naming the flag and its range.

use std::process::Command;

use crate::common;
use common::BIN;

#[test]
fn a_short_continuation_reports_the_first_flip_and_the_exponent() {
    let o = Command::new(BIN)
        .args(["plan", "continuation", "--to", "2000", "--max-period", "2"])
        .args([
            "--lyapunov-step",
            "500",
            "--transient",
            "20",
            "--tilts",
            "50",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let flips = v["diagram"]["flips"].as_array().unwrap();
    let k1 = flips[0].as_f64().unwrap();
    assert!((k1 - 1923.99).abs() < 0.01, "k_1 = {k1}");
    let branches = v["diagram"]["branches"].as_array().unwrap();
    assert_eq!(branches.len(), 2);
    assert_eq!(branches[1]["tilts"], 2);
    assert!(v["steps"].as_u64().unwrap() > 10);
    // k = 500, 1000, 1500, 2000: the first three on the stable period-1 orbit.
    let ly = v["lyapunov"].as_array().unwrap();
    assert_eq!(ly.len(), 4);
    for e in &ly[..3] {
        assert!(e["lambda"].as_f64().unwrap() < 0.0, "{e}");
    }
}

#[test]
fn bad_input_names_the_flag_and_the_range() {
    for (args, want) in [
        (
            vec!["--param", "q"],
            "invalid parameter `q`: must be one of k, kp, kd",
        ),
        (vec!["--param", "kd"], "`--param kd` needs `--to`"),
        (vec!["--max-period", "3"], "invalid `--max-period` = 3"),
        (vec!["--to", "-5"], "invalid `--to` = -5"),
        (vec!["--kd", "0"], "invalid `--kd` = 0"),
        (
            vec!["--control-period", "0"],
            "invalid `--control-period` = 0: must be in (0, 0.05] s",
        ),
    ] {
        let o = Command::new(BIN)
            .args(["plan", "continuation"])
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn the_flip_continued_in_k_and_kd_passes_through_k_star() {
    let o = Command::new(BIN)
        .args([
            "plan",
            "stability",
            "--from2",
            "13.5",
            "--to2",
            "14.8",
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let flip: Vec<[f64; 2]> =
        serde_json::from_value(v["region"]["flip"]["points"].clone()).unwrap();
    // The curve starts from the one-parameter flip at the paper's K_D = 14.14: k* = 1923.99.
    let at = flip.iter().find(|p| p[1] == 14.14).expect("the base point");
    assert!((at[0] - 1923.99).abs() < 0.01, "{at:?}");
    // It reaches both ends of the K_D range, and more damping tolerates more adaptation.
    assert!(
        flip.first().unwrap()[1] < 13.5 && flip.last().unwrap()[1] > 14.8,
        "{flip:?}"
    );
    assert!(flip.windows(2).all(|w| w[1][0] > w[0][0]), "{flip:?}");
    let fold: Vec<[f64; 2]> =
        serde_json::from_value(v["region"]["fold"]["points"].clone()).unwrap();
    assert!(fold.iter().all(|p| p[0] > 0.0 && p[0] < 500.0), "{fold:?}");
}

#[test]
fn control_period_adds_the_sampled_loops_exponents() {
    let o = Command::new(BIN)
        .args(["plan", "continuation", "--to", "1000", "--max-period", "1"])
        .args([
            "--lyapunov-step",
            "500",
            "--transient",
            "10",
            "--tilts",
            "40",
        ])
        .args(["--control-period", "0.001", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let s = v["lyapunov_sampled"].as_array().unwrap();
    assert_eq!(s.len(), 2, "{s:?}");
    for (e, k) in s.iter().zip([500.0, 1000.0]) {
        assert_eq!(e["p"].as_f64(), Some(k));
        assert_eq!(e["period"].as_f64(), Some(0.001));
        // Positive below the hold's scale even on the stable orbit (planner/tests/
        // sampled_lyapunov.rs), the second exponent negative: both of the same run.
        assert!(e["lambda"].as_f64().unwrap() > 0.0, "{e}");
        assert!(e["lambda2"].as_f64().unwrap() < 0.0, "{e}");
    }
}
