//! Runs the built `tilting identify` on an MCAP recording of an offline run of a robot whose
//! parameters differ from the paper's (written by `tilting_sim::recording`, the code behind
//! `simulate --record`): the parameters it writes are the hidden robot's within 1 % and load
//! with `--params`; a robot not in the file and a continuous run are refused.

use std::process::{Command, Output};
use tilting_plant::Params;
use tilting_sim::recording::{run_logged, write_mcap};
use tilting_sim::Scenario;

mod common;
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

#[test]
fn identifies_a_recording_and_writes_params_that_load() {
    let dir = Scratch::new("identify-cli");
    let truth = robot();
    let run = run_logged(&Scenario {
        params: truth,
        control_period: 1e-3,
        duration: 10.0,
        ..Scenario::default()
    })
    .unwrap();
    assert!(run.fault.is_none(), "{:?}", run.fault);
    let mcap = dir.path().join("run.mcap");
    write_mcap(&mcap, "lab", &run).unwrap();
    // The prior: the paper's geometry with the weighed arm mass.
    let prior = dir.path().join("prior.toml");
    std::fs::write(&prior, format!("m_l = {}\n", truth.m_l)).unwrap();
    let out = dir.path().join("params.toml");
    let (m, p, o) = (
        mcap.to_str().unwrap(),
        prior.to_str().unwrap(),
        out.to_str().unwrap(),
    );
    let r = tilting(&[
        "identify", m, "--robot", "lab", "--params", p, "--out", o, "--json",
    ]);
    assert!(r.status.success(), "{}", stderr(&r));
    let json: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert!(json["condition_number"].as_f64().unwrap() < 1e3, "{json}");
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
