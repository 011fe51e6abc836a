//! Issue 17's headline chain through the built `tilting`, as the README runs it: a robot 20 %
//! off the paper's (a `--plant-params` file `identify` never sees), measured as hardware
//! measures (angles only, 1 mrad of noise, a 4,096-count encoder), recorded on the excitation
//! and the robust orbit, identified, its orbit planned, then run with the identified model
//! over a 50 ms round trip with `--predict`.
//!
//! Asserted against independent truths: the identified parameters against the hidden robot
//! (3 % where the excitation fixes them: `m_f`, `l_c`, `tau_c`); the run against the planned
//! orbit of the identified robot (`plan orbit`, a BVP, not the simulator), run with the robust
//! law's peak trim on that plan (`--orbit-peak`): at least 200 tilts above 0.01 rad in 100 s,
//! alternating, **every** peak after the first 10 tilts within 10 % of the planned peak, their
//! mean within 4 %, and at most 10 lift-offs below 0.01 rad (sensor noise). Measured on this
//! robot and another one, 4 noise seeds each (`bench/headline.sh`, README): 226-227 tilts, the
//! last peak more than 10 % off is the 7th at worst, the worst after the 10th 4.2-7.2 % off,
//! the mean -0.8 to -1.1 %, 0 or 1 noise lift-off (bench/decisions-2026-11-28.md, "State estimation in
//! the controller"). Tilts
//! counted: lift-offs whose peak exceeds 0.01 rad, a quarter of the orbit's; the first 10 are
//! the settling of the trim (the first tilt starts from the paper's initial state, 15-30 %
//! off the identified robot's orbit, and the trim changes the torque scale by 2 % of the
//! peak's error per tilt).

use std::process::{Command, Output};

use crate::common;
use common::{Scratch, BIN};

fn tilting(args: &[&str]) -> Output {
    let o = Command::new(BIN)
        .args(args)
        .output()
        .expect("cannot run tilting");
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

const ROBOT: &str = "m_f = 0.85\nm_l = 1.1\nl_c = 1.8\ni_l = 0.08\nj_m = 0.02\nn_g = 0.8\n\
                     b_v = 0.03\ntau_c = 0.05\n";

#[test]
fn identified_robot_keeps_its_planned_orbit_over_a_50_ms_round_trip() {
    let dir = Scratch::new("headline");
    let path = |n: &str| dir.path().join(n).to_str().unwrap().to_owned();
    std::fs::write(path("robot.toml"), ROBOT).unwrap();
    std::fs::write(path("prior.toml"), "m_l = 1.1\n").unwrap();
    let noise = common::MEASURED_AS_HARDWARE;
    let robot = path("robot.toml");
    let (exc, orbit) = (path("exc.mcap"), path("orbit.mcap"));
    let mut a = vec![
        "simulate",
        "--plant-params",
        &robot,
        "--control-period",
        "0.001",
        "--duration",
        "300",
        "--reference",
        "excitation",
        "--record",
        &exc,
    ];
    a.extend(noise);
    tilting(&a);
    let mut a = vec![
        "simulate",
        "--plant-params",
        &robot,
        "--control-period",
        "0.001",
        "--duration",
        "30",
        "--orbit-peak",
        "0.04",
        "--record",
        &orbit,
    ];
    a.extend(noise);
    tilting(&a);
    let (prior, id) = (path("prior.toml"), path("identified.toml"));
    tilting(&[
        "identify",
        &exc,
        &orbit,
        "--params",
        &prior,
        "--window",
        "2",
        "--half-window",
        "0.05",
        "--out",
        &id,
    ]);
    let got = tilting_plant::Params::from_toml_file(std::path::Path::new(&id)).unwrap();
    for (name, g, w) in [
        ("m_f", got.m_f, 0.85),
        ("l_c", got.lc(), 1.8),
        ("tau_c", got.tau_c, 0.05),
    ] {
        assert!(((g - w) / w).abs() < 0.03, "{name}: {g} vs {w}");
    }
    let plan = tilting(&["plan", "orbit", "--params", &id, "--k", "500", "--json"]);
    let plan: serde_json::Value = serde_json::from_slice(&plan.stdout).unwrap();
    let (e_av, peak) = planned(&plan);
    let (e, p) = (e_av.to_string(), peak.to_string());
    let mut a = vec![
        "simulate",
        "--params",
        &id,
        "--plant-params",
        &robot,
        "--k",
        "500",
        "--energy-avg",
        &e,
        "--control-period",
        "0.001",
        "--duration",
        "100",
        "--delay",
        "0.025",
        "--predict",
        "0.05",
        "--max-age",
        "60",
        "--orbit-peak",
        &p,
        "--json",
    ];
    a.extend(noise);
    let run = tilting(&a);
    let run: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert!(run["fault"].is_null(), "{}", run["fault"]);
    let all: Vec<f64> = run["tilt_peaks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["alpha"].as_f64().unwrap())
        .collect();
    let peaks: Vec<f64> = all.iter().copied().filter(|a| a.abs() > 0.01).collect();
    let lift_offs = all.len() - peaks.len();
    assert!(peaks.len() >= 200, "{} tilts above 0.01 rad", peaks.len());
    assert!(lift_offs <= 10, "{lift_offs} lift-offs below 0.01 rad");
    assert!(
        peaks.windows(2).all(|w| (w[0] > 0.0) != (w[1] > 0.0)),
        "the tilts alternate"
    );
    for (i, a) in peaks.iter().enumerate().skip(10) {
        let err = (a.abs() - peak) / peak;
        assert!(
            err.abs() < 0.10,
            "tilt {i}: peak {a} vs planned {peak} ({:+.1} %)",
            100.0 * err
        );
    }
    let mean = peaks[10..].iter().map(|a| a.abs()).sum::<f64>() / (peaks.len() - 10) as f64;
    assert!(
        ((mean - peak) / peak).abs() < 0.04,
        "mean peak {mean} vs planned {peak}"
    );
}

/// The adaptation's `E_av` (J) and the orbit's largest tilt (rad) from `plan orbit --json`.
fn planned(v: &serde_json::Value) -> (f64, f64) {
    let find = |key: &str| -> f64 {
        fn walk(v: &serde_json::Value, key: &str) -> Option<f64> {
            match v {
                serde_json::Value::Object(m) => m
                    .get(key)
                    .and_then(|x| x.as_f64())
                    .or_else(|| m.values().find_map(|x| walk(x, key))),
                serde_json::Value::Array(a) => a.iter().find_map(|x| walk(x, key)),
                _ => None,
            }
        }
        walk(v, key).unwrap_or_else(|| panic!("no {key} in {v}"))
    };
    (find("energy_avg_adaptation"), find("max_tilt"))
}
