//! `tilting live --secure`: the whole loop with mutual TLS and access control on (a
//! `tilting-router` child, the plant and the controller as its clients, the planner in-process),
//! with certificates made for the run or given with `--certs`; and `--certs` made for another
//! robot is refused with a message that says so.

use std::process::Command;
use tilting_live::summary::{LiveResult, LiveSummary};
use tilting_tests::*;

#[test]
fn live_secure_runs_the_loop_through_the_router() {
    let _turn = realtime_turn();
    let tilting = bin("tilting");
    bin("tilting-router");
    let dir = Scratch::new("live-secure");
    let out = dir.path().join("out");
    let robot = robot("live_secure");
    let o = Command::new(&tilting)
        .args([
            "live",
            "--secure",
            "--duration",
            "2",
            "--robot",
            &robot,
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("cannot run tilting live");
    let logs = || {
        let mut s = format!(
            "--- stdout ---\n{}\n--- stderr ---\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        for f in ["router.log", "plant.log", "controller.log"] {
            let t = std::fs::read_to_string(out.join(f)).unwrap_or_default();
            s.push_str(&format!("\n--- {f} ---\n{t}"));
        }
        s
    };
    assert!(o.status.success(), "{}", logs());
    let summary: LiveSummary =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary.result, LiveResult::Completed, "{}", logs());
    let router = summary.endpoints.router.clone().expect("a router endpoint");
    assert!(router.starts_with("tls/127.0.0.1:"), "{router}");
    // The loop ran through the router: states recorded, torques answered, tilts.
    assert!(summary.record.states >= 1900, "{:?}", summary.record);
    assert!(summary.record.torques >= 1500, "{:?}", summary.record);
    assert!(summary.record.tilts >= 2, "{:?}", summary.record);
    let ctl = summary.controller.expect("controller summary");
    assert!(
        ctl.references_applied >= 1,
        "the planner's identity may publish: {ctl:?}"
    );
    for f in [
        "ca.pem",
        "plant.pem",
        "plant.key",
        "router.json5",
        "certs.json",
    ] {
        assert!(out.join("certs").join(f).is_file(), "{f}");
    }
    // Certificates of another robot are refused before anything starts.
    let o = Command::new(&tilting)
        .args([
            "live",
            "--secure",
            "--duration",
            "1",
            "--robot",
            "other",
            "--certs",
        ])
        .arg(out.join("certs"))
        .arg("--out")
        .arg(dir.path().join("out2"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("--certs") && err.contains("not \"other\""),
        "{err}"
    );
}
