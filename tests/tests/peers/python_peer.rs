//! The wire protocol is language-neutral: `tilting-plant` in lockstep against the stand-alone
//! Python controller `examples/python/controller.py` (eclipse-zenoh, `struct`, the law written
//! again in Python from the model notes) reproduces the offline sampled loop computed here with
//! the Rust libraries. Each side is told the other's zenoh id (`--plant-id`, `--controller-id`)
//! and believes only messages whose TSRC attachment names it: the Python controller's torques
//! carry a source the Rust plant accepts (`torques_foreign: 0`, no watchdog trip).
//!
//! Needs `python3` with the `zenoh` module (`.ci/run` installs `eclipse-zenoh`); without it the
//! tests print a SKIP line and pass.

use std::path::PathBuf;
use std::time::Duration;
use tilting_tests::recording::{largest_differences, offline, parse_csv};
use tilting_tests::*;

const PERIOD: f64 = 0.001;
const DURATION: f64 = 1.0;

/// Agreement required between the Python-controlled run and the offline Rust loop, on every
/// state component and torque. Not bit-identical: the Python law evaluates the same formulas in
/// another order (energy from the point-mass velocities rather than the mass matrix, powers
/// instead of products, ...), so the torques differ in the last bits and the closed loop carries
/// those differences along.
const TOLERANCE: f64 = 1e-9;

fn script() -> PathBuf {
    workspace_root().join("examples/python/controller.py")
}

/// The part of controller.py's summary this test reads.
#[derive(Debug, serde::Deserialize)]
struct PyControllerSummary {
    states_dropped: u64,
    torques_not_finite: u64,
    torques_published: u64,
    states_foreign: u64,
}

/// The zenoh ids of the Rust plant and the Python controller, chosen before either starts.
const PLANT_ID: &str = "9a17c0de0000000000000000000000c3";
const CONTROLLER_ID: &str = "7e417201000000000000000000000d4";

#[test]
fn python_controller_self_test() {
    // Encodings against the worked examples of docs/protocol.md and the law against the
    // equations of motion; needs no zenoh.
    python_self_test("python_controller_self_test", &script());
}

#[test]
fn python_controller_drives_the_plant_like_the_rust_one() {
    let _turn = realtime_turn();
    if !python_runs("import zenoh") {
        let why = format!(
            "`{} -c \"import zenoh\"` failed; install it with `python3 -m pip install \
             'eclipse-zenoh==1.10.2'`",
            python()
        );
        skip(
            "python_controller_drives_the_plant_like_the_rust_one",
            Missing::Package,
            &why,
        );
        return;
    }
    let plant_bin = bin("tilting-plant");
    let dir = Scratch::new("python-peer");
    let port = free_port();
    let robot = robot("python_peer");
    let csv = dir.path().join("rec.csv");
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(
            &robot,
            port,
            &[
                "--clock",
                "lockstep",
                "--duration",
                "1",
                "--record",
                csv.to_str().unwrap(),
                "--zenoh-id",
                PLANT_ID,
                "--controller-id",
                CONTROLLER_ID,
            ],
        ),
        dir.path(),
    );
    let mut args = vec![script().to_str().unwrap().to_owned()];
    args.extend(peer_args(
        &robot,
        port,
        &[
            "--kp",
            "100",
            "--kd",
            "14.14",
            "--k",
            "500",
            "--energy-avg",
            "19.963439703027",
            "--zenoh-id",
            CONTROLLER_ID,
            "--plant-id",
            PLANT_ID,
        ],
    ));
    let mut ctl = Proc::spawn(
        "controller.py",
        std::path::Path::new(&python()),
        &args,
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(
        status.success(),
        "plant: {status}\n{}\n{}",
        plant.logs(),
        ctl.logs()
    );
    let summary = plant.plant_summary();
    eprintln!("plant summary: {summary:?}");
    assert_eq!(summary.result, RunResult::Completed, "{summary:?}");
    assert_eq!(summary.steps, 1000, "{summary:?}");
    assert_eq!(summary.deadline_misses, 0, "{summary:?}");
    assert_eq!(summary.torques_dropped, 0, "{summary:?}");
    assert_eq!(summary.torques_stale, 0, "{summary:?}");
    assert_eq!(summary.watchdog_trips, 0, "{summary:?}");
    // Every torque named the Python controller's session, as the plant was told to expect.
    assert_eq!(summary.torques_foreign, 0, "{summary:?}");
    let c_status = ctl.interrupt(Duration::from_secs(10));
    assert!(c_status.success(), "{}", ctl.logs());
    let c_summary: PyControllerSummary =
        serde_json::from_value(ctl.summary_json()).expect("controller.py's summary");
    eprintln!("controller.py summary: {c_summary:?}");
    assert_eq!(c_summary.states_dropped, 0, "{c_summary:?}");
    assert_eq!(c_summary.torques_not_finite, 0, "{c_summary:?}");
    assert_eq!(c_summary.states_foreign, 0, "{c_summary:?}");
    assert!(c_summary.torques_published >= 1000, "{c_summary:?}");

    let got = parse_csv(&std::fs::read_to_string(&csv).unwrap());
    let want = offline(DURATION, PERIOD);
    // Sample times are the plant's own `k h`: the controller has no part in them.
    let (worst_x, worst_tau) = largest_differences(&got, &want);
    eprintln!(
        "python controller vs offline Rust loop: {} samples, largest difference: state {worst_x:e}, \
         torque {worst_tau:e} N m",
        got.len()
    );
    assert!(worst_x <= TOLERANCE, "largest state difference {worst_x:e}");
    assert!(
        worst_tau <= TOLERANCE,
        "largest torque difference {worst_tau:e}"
    );
    // The run really is closed-loop through Python: it tilted both ways.
    assert!(
        want.iter().any(|r| r.mode == 1) && want.iter().any(|r| r.mode == 2),
        "the reference run should tilt both ways within {DURATION} s"
    );
}
