//! Runs the built `tilting simulate --record` and `tilting identify` on a robot whose
//! parameters differ from the paper's by up to 20 % (in a `--plant-params` file that
//! identify never sees): the parameters it writes are the hidden robot's within 1 %
//! (noise-free, from the angles alone) and load with `--params`; the fit check re-simulates
//! the recording within the integrator's error; bad input is refused naming what is wrong.

use std::process::{Command, Output};
use tilting_plant::Params;

use crate::common;
use common::{Scratch, BIN};

fn tilting(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .output()
        .expect("cannot run tilting")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The hidden robot: up to 20 % from the paper's, with a geared motor and friction.
fn robot() -> Params {
    Params {
        m_f: 0.85,
        m_l: 1.1,
        l_c: Some(1.8),
        i_l: 0.08,
        j_m: 0.02,
        n_g: 0.8,
        b_v: 0.03,
        tau_c: 0.05,
        ..Params::default()
    }
}

/// `params` as a `--params` TOML.
fn toml(p: &Params) -> String {
    p.to_toml_string()
}

#[test]
fn identifies_a_recording_and_writes_params_that_load() {
    let dir = Scratch::new("identify-cli");
    let truth = robot();
    let plant = dir.path().join("robot.toml");
    std::fs::write(&plant, toml(&truth)).unwrap();
    let mcap = dir.path().join("run.mcap");
    let rec = tilting(&[
        "simulate",
        "--plant-params",
        plant.to_str().unwrap(),
        "--control-period",
        "0.001",
        "--duration",
        "10",
        "--record",
        mcap.to_str().unwrap(),
        "--robot",
        "lab",
    ]);
    assert!(rec.status.success(), "{}", stderr(&rec));
    // The prior: the paper's geometry with the weighed arm mass.
    let prior = dir.path().join("prior.toml");
    std::fs::write(&prior, format!("m_l = {}\n", truth.m_l)).unwrap();
    let out = dir.path().join("params.toml");
    let (m, p, o) = (
        mcap.to_str().unwrap(),
        prior.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let png = dir.path().join("fit.png");
    let r = tilting(&[
        "identify",
        m,
        "--robot",
        "lab",
        "--params",
        p,
        "--out",
        o,
        "--json",
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let json: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert!(json["condition_number"].as_f64().unwrap() < 1e3, "{json}");
    assert_eq!(json["velocities"], "angles");
    // The fit check: the true robot re-simulated under its own torques from the fit's states
    // stays within 1e-4 rad over 0.25 s (the differentiator's error at the restarts and the
    // integrator's), while the paper's robot (the prior) drifts by more than 1e-3 rad.
    let fit = &json["fit"];
    for a in ["rms_alpha", "rms_beta"] {
        let id = fit["identified"][a].as_f64().unwrap();
        let prior = fit["prior"][a].as_f64().unwrap();
        assert!(
            id < 1e-4 && prior > 1e-3,
            "{a}: {id} vs prior {prior}: {fit}"
        );
    }
    assert!(
        fit["identified"]["windows"].as_u64().unwrap() >= 30,
        "{fit}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000);
    let got = Params::from_toml_file(&out).unwrap();
    for (name, g, w) in [
        ("m_f", got.m_f, truth.m_f),
        ("l_c", got.lc(), truth.lc()),
        ("i_l", got.i_l, truth.i_l),
        ("j_m", got.j_m, truth.j_m),
        ("n_g", got.n_g, truth.n_g),
        ("b_v", got.b_v, truth.b_v),
        ("tau_c", got.tau_c, truth.tau_c),
    ] {
        assert!(((g - w) / w).abs() < 0.01, "{name}: {g} vs {w}");
    }
    // The file loads as --params.
    let s = tilting(&[
        "simulate",
        "--params",
        o,
        "--k",
        "0",
        "--duration",
        "0.5",
        "--json",
    ]);
    assert!(s.status.success(), "{}", stderr(&s));
    // The human summary names what motion cannot fix.
    let h = tilting(&["identify", m]);
    let text = String::from_utf8_lossy(&h.stdout);
    assert!(
        h.status.success() && text.contains("not identifiable"),
        "{text}"
    );

    let e = tilting(&["identify", m, "--robot", "other"]);
    assert_eq!(e.status.code(), Some(2));
    let msg = stderr(&e);
    assert!(
        msg.contains("\"other\" is not in the file") && msg.contains("\"lab\""),
        "{msg}"
    );
}

#[test]
fn refuses_a_file_that_is_not_a_recording() {
    let dir = Scratch::new("identify-cli-bad");
    let f = dir.path().join("x.mcap");
    std::fs::write(&f, "not mcap").unwrap();
    let e = tilting(&["identify", f.to_str().unwrap()]);
    assert_eq!(e.status.code(), Some(1));
    assert!(stderr(&e).contains("not an MCAP file"), "{}", stderr(&e));
}

#[test]
fn refuses_what_cannot_be_recorded_or_identified() {
    let dir = Scratch::new("identify-cli-refused");
    let mcap = dir.path().join("r.mcap");
    let m = mcap.to_str().unwrap();
    // A continuous run has no samples; a run over an impaired network holds torques that
    // answer other states.
    for (extra, field) in [
        (&["--control-period", "0"][..], "--control-period"),
        (
            &["--control-period", "0.001", "--delay", "0.01"][..],
            "--delay",
        ),
    ] {
        let mut a = vec!["simulate", "--duration", "0.5", "--record", m];
        a.extend_from_slice(extra);
        let e = tilting(&a);
        assert_eq!(e.status.code(), Some(2), "{a:?}");
        assert!(stderr(&e).contains(field), "{}", stderr(&e));
    }
    // Too short: 0.5 s of motion.
    let r = tilting(&[
        "simulate",
        "--control-period",
        "0.001",
        "--duration",
        "0.5",
        "--record",
        m,
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let e = tilting(&["identify", m]);
    assert_eq!(e.status.code(), Some(2));
    assert!(stderr(&e).contains("too short"), "{}", stderr(&e));
    // Out-of-range settings name the flag and the range.
    for (flag, v) in [
        ("--window", "0"),
        ("--half-window", "9"),
        ("--min-speed", "-1"),
        ("--settle", "2"),
    ] {
        let e = tilting(&["identify", m, flag, v]);
        assert_eq!(e.status.code(), Some(2));
        let msg = stderr(&e);
        assert!(msg.contains(flag) && msg.contains("allowed"), "{msg}");
    }
}

/// Measured as hardware measures (angles only, 1 mrad, 4,096 counts): 60 s of the excitation
/// and 10 s of the robust orbit. The rotor's share is below this noise, and the flat rows
/// carry `pi3` and `pi5` in one column: `identify` says so in the text and the JSON, and
/// reports their sum `pi3+pi5` (the arm's inertia about the joint, `m_l l_c^2 + i_l + n_g^2
/// j_m`), which must be the hidden robot's within the 3 % (measured 0.1 %); the file
/// it writes carries the sum in `i_l` with `j_m = 0`.
#[test]
fn says_the_rotor_is_lumped_under_noise_and_reports_the_sum() {
    let dir = Scratch::new("identify-cli-lumped");
    let truth = robot();
    let plant = dir.path().join("robot.toml");
    std::fs::write(&plant, toml(&truth)).unwrap();
    let noise = common::MEASURED_AS_HARDWARE;
    let (exc, orbit) = (dir.path().join("exc.mcap"), dir.path().join("orbit.mcap"));
    for (file, extra, secs) in [
        (&exc, ["--reference", "excitation"], "60"),
        (&orbit, ["--orbit-peak", "0.04"], "10"),
    ] {
        let mut a = vec![
            "simulate",
            "--plant-params",
            plant.to_str().unwrap(),
            "--control-period",
            "0.001",
            "--duration",
            secs,
            "--record",
            file.to_str().unwrap(),
        ];
        a.extend(extra);
        a.extend(noise);
        let r = tilting(&a);
        assert!(r.status.success(), "{}", stderr(&r));
    }
    let prior = dir.path().join("prior.toml");
    std::fs::write(&prior, format!("m_l = {}\n", truth.m_l)).unwrap();
    let out = dir.path().join("params.toml");
    let args = [
        "identify",
        exc.to_str().unwrap(),
        orbit.to_str().unwrap(),
        "--params",
        prior.to_str().unwrap(),
        "--window",
        "2",
        "--half-window",
        "0.05",
        "--out",
        out.to_str().unwrap(),
    ];
    let mut a = args.to_vec();
    a.push("--json");
    let r = tilting(&a);
    assert!(r.status.success(), "{}", stderr(&r));
    let json: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    let base = json["base"].as_array().unwrap();
    let pi3 = &base[2];
    assert!(
        pi3["value"].is_null()
            && pi3["not_identifiable"]
                .as_str()
                .unwrap()
                .contains("columns of pi3 and pi5"),
        "{pi3}"
    );
    let sum = base.iter().find(|e| e["name"] == "pi3+pi5").unwrap();
    let want = truth.joint_inertia();
    let got = sum["value"].as_f64().unwrap();
    assert!(
        ((got - want) / want).abs() < 0.03,
        "pi3+pi5: {got} vs {want}"
    );
    assert!(
        json["not_identifiable"]
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s
                .as_str()
                .unwrap()
                .starts_with("j_m and n_g: not separable")),
        "{json}"
    );
    let p = Params::from_toml_file(&out).unwrap();
    assert_eq!(p.j_m, 0.0);
    assert!(((p.joint_inertia() - want) / want).abs() < 0.03, "{p:?}");
    // The human summary says it too.
    let h = tilting(&args);
    let text = String::from_utf8_lossy(&h.stdout);
    assert!(
        h.status.success() && text.contains("pi3+pi5") && text.contains("not separable"),
        "{text}"
    );
    // The output-error refinement ran on the flat excitation: its b_v is the one reported,
    // with its standard error (smaller than the least squares' of `--no-refine`), and the
    // summary says so; `--no-refine` leaves it out.
    let r = &json["refinement"];
    assert!(r["converged"].as_bool().unwrap(), "{r}");
    let se = base[5]["std_error"].as_f64().unwrap();
    assert_eq!(base[5]["value"], r["value"][2], "{r}");
    assert_eq!(se, r["std_error"][2].as_f64().unwrap());
    assert!(text.contains("output-error refinement"), "{text}");
    let mut a = args.to_vec();
    a.extend(["--json", "--no-refine"]);
    let ls = tilting(&a);
    assert!(ls.status.success(), "{}", stderr(&ls));
    let ls: serde_json::Value = serde_json::from_slice(&ls.stdout).unwrap();
    assert!(ls.get("refinement").is_none(), "{ls}");
    let se_ls = ls["base"][5]["std_error"].as_f64().unwrap();
    assert!(se < se_ls, "{se} vs {se_ls}");
}

/// The landing law from the recorded landings: recordings simulated with each law (the params
/// file's `impact` key selects the plant's), 10 s of the adapted loop at E_av 20.0498 J (the
/// physical law's orbit of peak 0.018), are identified as the law they were made with (the
/// smallest residual of alpha_dot+ and beta_dot+ over the landings; measured: the law's own
/// 1e-10 to 2e-9 rad/s, the others' 1.8e-2 to 1.4e-1), and the rebound law's restitution
/// e = 0.3 comes back within 1e-6 (measured 0.3000 +- 2.4e-10: each side of a landing is
/// carried from its nearest recorded sample to the landing instant under the held torque with
/// RK4, 8 steps over under 1 ms, far below 1e-6), written as `impact` and `restitution`.
#[test]
fn identifies_the_landing_law_of_each_recording() {
    let dir = Scratch::new("identify-cli-landing");
    for (law, e) in [
        ("paper", 0.0),
        ("striking-edge", 0.0),
        ("physical", 0.0),
        ("physical", 0.3),
    ] {
        let params = dir.path().join("p.toml");
        let mut text = format!("impact = \"{law}\"\n");
        if e > 0.0 {
            text += &format!("restitution = {e}\n");
        }
        std::fs::write(&params, text).unwrap();
        let mcap = dir.path().join("l.mcap");
        let mut a = vec![
            "simulate",
            "--params",
            params.to_str().unwrap(),
            "--control-period",
            "0.001",
            "--duration",
            "10",
            "--record",
            mcap.to_str().unwrap(),
        ];
        if law != "paper" {
            a.extend(["--energy-avg", "20.0498"]);
        }
        let r = tilting(&a);
        assert!(r.status.success(), "{law}: {}", stderr(&r));
        let out = dir.path().join("out.toml");
        let r = tilting(&[
            "identify",
            mcap.to_str().unwrap(),
            "--json",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "{law}: {}", stderr(&r));
        let json: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
        let l = &json["landing"];
        assert_eq!(l["best"], law, "{l}");
        assert!(l["landings"].as_array().unwrap().len() >= 5, "{law}: {l}");
        let p = Params::from_toml_file(&out).unwrap();
        assert_eq!(p.impact.as_str(), law);
        if e > 0.0 {
            let got = l["restitution"].as_f64().unwrap();
            let se = l["restitution_std_error"].as_f64().unwrap();
            assert!((got - e).abs() < 1e-6 && se < 1e-6, "e = {got} +- {se}");
            assert!((p.restitution - e).abs() < 1e-6, "{p:?}");
        } else {
            assert_eq!(p.restitution, 0.0);
        }
    }
}
