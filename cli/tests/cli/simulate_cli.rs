//! Runs the built `tilting simulate` binary: JSON shape and content, usage and
//! configuration errors, the plot, and the convergence of the sampled coupling.

use std::process::{Command, Output};
use tilting_plant::Mode;
use tilting_sim::closed_loop::Coupling;
use tilting_sim::SimulationReport;

use crate::common;
use common::{Scratch, BIN};

fn simulate(args: &[&str]) -> Output {
    Command::new(BIN)
        .arg("simulate")
        .args(args)
        .output()
        .expect("cannot run tilting")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs with `--json`, checks success, and reads stdout as exactly one report; the report
/// written back is the same JSON (no field is lost or renamed on the way).
fn simulate_json(args: &[&str]) -> SimulationReport {
    let mut all = vec!["--json"];
    all.extend_from_slice(args);
    let o = simulate(&all);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    report(&o.stdout)
}

fn report(stdout: &[u8]) -> SimulationReport {
    let text = std::str::from_utf8(stdout).expect("stdout is UTF-8");
    let r: SimulationReport =
        serde_json::from_str(text).unwrap_or_else(|e| panic!("not one report: {e}\n{text}"));
    let raw: serde_json::Value = serde_json::from_str(text).expect("JSON");
    assert_eq!(serde_json::to_value(&r).expect("serialises"), raw);
    r
}

#[test]
fn json_report_of_the_default_orbit() {
    let r = simulate_json(&["--duration", "5"]);
    assert!(r.fault.is_none(), "{:?}", r.fault);
    assert_eq!(r.final_state.t, 5.0);

    // Transitions chain (each starts in the mode the previous one ended in), starting from the
    // initial left tilt, and the tilts alternate: left -> flat -> right -> flat -> left ...
    assert!(r.events.len() >= 20, "{} events in 5 s", r.events.len());
    let mut mode = Mode::Left;
    let mut tilts = vec![mode];
    let mut t_prev = 0.0;
    for e in &r.events {
        assert_eq!(e.from, mode, "{e:?}");
        assert_ne!(e.from, e.to);
        assert!(e.t >= t_prev && e.t <= 5.0, "{e:?}");
        t_prev = e.t;
        let (xb, xa) = (e.x_before, e.x_after);
        if e.to == Mode::Flat {
            // Landing: the plate comes to rest, beta is continuous.
            assert_eq!((xa[0], xa[2]), (0.0, 0.0), "{e:?}");
            assert_eq!(xb[1], xa[1]);
        } else {
            assert_eq!(e.from, Mode::Flat, "{e:?}");
            assert_eq!(xb, xa, "a tilt start keeps the state: {e:?}");
            tilts.push(e.to);
        }
        mode = e.to;
    }
    for w in tilts.windows(2) {
        assert_ne!(w[0], w[1], "tilts must alternate: {tilts:?}");
    }
    assert_eq!(r.final_state.mode, mode);

    assert_eq!(r.tilt_peaks.len() as u64, r.stats.tilts);
    for (p, &m) in r.tilt_peaks.iter().zip(&tilts) {
        assert_eq!(p.mode, m);
        assert!(
            if m == Mode::Left {
                p.alpha > 0.0
            } else {
                p.alpha < 0.0
            },
            "{p:?}"
        );
        assert!(p.t <= 5.0);
    }
}

#[test]
fn human_summary() {
    let o = simulate(&["--duration", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    for part in [
        "simulated 2 s",
        "tilts:",
        "last tilt peaks",
        "final: t = 2 s",
        "fault: none",
        "RHS evaluations:",
        "wall time",
    ] {
        assert!(out.contains(part), "missing {part:?} in\n{out}");
    }
}

#[test]
fn invalid_flags_exit_2_and_name_the_field() {
    for (args, field) in [
        (vec!["--kp", "-1"], "kp"),
        (vec!["--kd", "inf"], "kd"),
        (vec!["--duration", "nan"], "duration"),
        (vec!["--duration", "0"], "duration"),
        (vec!["--control-period", "10"], "control_period"),
        (vec!["--control-period", "-0.001"], "control_period"),
        (vec!["--mode", "upward"], "mode"),
        (vec!["--impact", "elastic"], "impact"),
        (vec!["--reference", "sinusoid:0.3"], "reference"),
        (vec!["--x0", "0,1.57,0"], "x0"),
        (vec!["--x0", "0,nan,0,0"], "x0[1]"),
        (vec!["--mode", "right", "--x0", "0.1,1.57,0,0"], "x0[0]"),
        (vec!["--rtol", "0"], "rtol"),
        (vec!["--torque-limit", "-5"], "torque_limit"),
        (vec!["--energy-avg", "nan"], "energy_avg"),
        // An adaptation other than the built-in one needs the energy of the orbit to
        // stabilise, and the error says what differs from the built-in case.
        (
            vec![
                "--mode",
                "flat",
                "--x0",
                "0,1.5707963267948966,0,0",
                "--k",
                "300",
            ],
            "missing `energy_avg` (--energy-avg): required when k != 0 (k = 300)",
        ),
        (vec!["--k", "300"], "here k = 300 (built-in 500)"),
        // So do gains the built-in E_av was not computed for.
        (vec!["--kp", "150"], "here kp = 150 (built-in 100)"),
        (vec!["--plot", "out.svg"], "--plot"),
        // The robot's imperfections name the flag and the range.
        (
            vec!["--control-period", "0.001", "--noise-alpha", "-0.1"],
            "invalid `--noise-alpha` = -0.1: allowed a standard deviation in rad in [0, 10]",
        ),
        (
            vec!["--control-period", "0.001", "--encoder-counts", "0"],
            "invalid `--encoder-counts` = 0: allowed counts per revolution in [2, 4294967296]",
        ),
        (
            vec!["--control-period", "0.001", "--torque-lag", "-0.01"],
            "invalid `--torque-lag` = -0.01: allowed a time constant in s in [0, 10]",
        ),
        (vec!["--mass-error", "-1"], "`--mass-error` = -1"),
        // Sensors are sampled.
        (vec!["--noise-beta", "0.001"], "--control-period"),
    ] {
        let o = simulate(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(field),
            "{args:?}: {err:?} does not name {field}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(o.stdout.is_empty(), "{args:?}");
    }
}

/// The report without its wall-clock time.
fn without_times(mut r: SimulationReport) -> SimulationReport {
    r.stats.wall_time_s = 0.0;
    r
}

#[test]
fn the_builtin_k_given_explicitly_is_the_default() {
    // `--k 500` is the built-in k: the run is the one without it, bit for bit, from the
    // built-in start and from a flat start.
    for start in [
        vec![],
        vec!["--mode", "flat", "--x0", "0,1.5707963267948966,0,0"],
    ] {
        let mut args = vec!["--duration", "2"];
        args.extend(&start);
        let plain = simulate_json(&args);
        args.extend(["--k", "500"]);
        let explicit = simulate_json(&args);
        assert_eq!(without_times(explicit), without_times(plain), "{start:?}");
    }
}

#[test]
fn invalid_files_exit_2_and_name_the_field() {
    let dir = Scratch::new("invalid-files");
    let unknown = dir.file("unknown.toml", "duration = 3\nduraton = 4\n");
    let bad_value = dir.file("bad.toml", "kd = -2\n");
    let bad_table = dir.file("bad_table.toml", "[params]\nl = 0\n");
    let bad_plant_table = dir.file("bad_plant.toml", "[plant_params]\nm_l = 0\n");
    let bad_params = dir.file("params.toml", "m_f = -1\n");
    let unknown_param = dir.file("params2.toml", "mass = 1\n");
    let missing = dir
        .path()
        .join("missing.toml")
        .to_string_lossy()
        .into_owned();
    for (args, field) in [
        (vec!["--scenario", &unknown], "duraton"),
        (vec!["--scenario", &bad_value], "kd"),
        (vec!["--scenario", &bad_table], "params.l"),
        (vec!["--params", &bad_params], "m_f"),
        (vec!["--params", &unknown_param], "mass"),
        (vec!["--plant-params", &bad_params], "--plant-params"),
        (vec!["--scenario", &bad_plant_table], "plant_params.m_l"),
        (vec!["--scenario", &missing], "missing.toml"),
    ] {
        let o = simulate(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(field),
            "{args:?}: {err:?} does not name {field}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn files_and_flags_stack() {
    let dir = Scratch::new("stack");
    let sc = dir.file(
        "s.toml",
        "duration = 3\nk = 0\ncontrol_period = 0.001\n[params]\ng = 9.81\n",
    );
    let params = dir.file("p.toml", "m_l = 1.0\n");
    // The flag wins over the file; k = 0 from the file needs no energy.
    let r = simulate_json(&["--scenario", &sc, "--params", &params, "--duration", "1.5"]);
    assert_eq!(r.final_state.t, 1.5);
    assert_eq!(r.stats.coupling, Coupling::Sampled);
    assert_eq!(r.stats.controller_samples, 1500);
}

#[test]
fn a_physics_fault_is_reported_with_exit_code_0() {
    // Tipped far over the left edge and still rotating: the plate falls.
    let o = simulate(&[
        "--json",
        "--k",
        "0",
        "--mode",
        "left",
        "--x0",
        "1.4,1.5707963267948966,2,0",
        "--duration",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r = report(&o.stdout);
    let fault = r.fault.expect("a fault").to_string();
    assert!(fault.contains("fall"), "{fault}");
    assert!(r.final_state.t < 2.0);
    assert!(stderr(&o).contains("fall"));
}

#[test]
fn plot_writes_a_png() {
    let dir = Scratch::new("plot");
    let png = dir.path().join("out.png");
    let o = simulate(&["--duration", "2", "--plot", png.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&png).expect("the PNG was written");
    assert!(bytes.len() > 10_000, "{} bytes", bytes.len());
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
}

fn first_landing(period: &str) -> f64 {
    let r = simulate_json(&["--duration", "1", "--control-period", period]);
    let e = &r.events[0];
    assert_eq!(e.to, Mode::Flat, "{e:?}");
    e.t
}

#[test]
fn zero_order_hold_converges_to_the_continuous_coupling() {
    let t_cont = first_landing("0");
    let d4 = (first_landing("1e-4") - t_cont).abs();
    let d3 = (first_landing("1e-3") - t_cont).abs();
    assert!(d4 < 1e-3, "T = 1e-4 s: landing off by {d4} s");
    // The hold delays the control by T/2 on average: the error is first order in T.
    assert!(d4 < 2e-5, "T = 1e-4 s: landing off by {d4} s");
    let ratio = d3 / d4;
    assert!(
        (5.0..20.0).contains(&ratio),
        "error ratio {ratio} between T = 1e-3 and 1e-4 s is not first order ({d3} vs {d4})"
    );
}
