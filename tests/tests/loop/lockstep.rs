//! A lockstep run over zenoh (plant and controller as separate processes) is the offline
//! sampled-loop simulation: the same samples, torques and final state, bit for bit.

use std::time::Duration;
use tilting_tests::recording::{offline, parse_csv};
use tilting_tests::*;

const PERIOD: f64 = 0.001;
const DURATION: f64 = 2.0;

#[test]
fn lockstep_run_equals_offline_simulation() {
    let _turn = realtime_turn();
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("lockstep");
    let port = free_port();
    let robot = robot("lockstep");
    let csv = dir.path().join("plant.csv");
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
                "2",
                "--record",
                csv.to_str().unwrap(),
            ],
        ),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &ctl_bin,
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "plant: {status}\n{}", plant.logs());
    let summary = plant.plant_summary();
    eprintln!("plant summary: {summary:?}");
    assert_eq!(summary.result, RunResult::Completed);
    assert_eq!(summary.deadline_misses, 0, "{summary:?}");
    assert_eq!(summary.torques_dropped, 0);
    let c_status = ctl.interrupt(Duration::from_secs(10));
    assert!(c_status.success(), "{}", ctl.logs());

    let got = parse_csv(&std::fs::read_to_string(&csv).unwrap());
    let want = offline(DURATION, PERIOD);
    assert_eq!(got.len(), want.len(), "number of samples");
    let mut worst = 0.0f64;
    for (g, w) in got.iter().zip(&want) {
        assert_eq!((g.seq, g.mode), (w.seq, w.mode), "seq/mode at {w:?}");
        assert_eq!(g.t, w.t, "sample time of seq {}", w.seq);
        for i in 0..4 {
            worst = worst.max((g.x[i] - w.x[i]).abs());
        }
        match (g.tau, w.tau) {
            (Some(a), Some(b)) => worst = worst.max((a - b).abs()),
            (None, None) => {}
            other => panic!("tau presence differs at seq {}: {other:?}", w.seq),
        }
    }
    eprintln!(
        "lockstep vs offline: {} samples, largest difference {worst:e}",
        got.len()
    );
    assert!(worst <= 1e-12, "largest difference {worst:e}");
    // The state is transmitted as raw f64 bits and the code path is the same: bit-identical.
    assert_eq!(worst, 0.0, "expected a bit-identical reproduction");
    let last = want.last().unwrap();
    let x = summary.x.to_vec();
    assert_eq!(x, last.x.to_vec());
    assert_eq!(summary.time, DURATION);

    // And the offline `simulate` command itself, with the same control period: the same final
    // state, bit for bit.
    let report = simulate_json(&[
        "--control-period",
        &PERIOD.to_string(),
        "--duration",
        &DURATION.to_string(),
    ]);
    assert_eq!(report.final_state.t, DURATION);
    assert_eq!(
        report.final_state.x.to_vec(),
        x,
        "simulate --control-period vs the lockstep run"
    );
}

/// Issue 8 part 6 for the plant node: its summary's `tilt_peaks` include the peak of the last
/// tilt, reached before the end but not landed. The truth is the recorded samples: a peak is a
/// sign change of `alpha_dot` (from the tilt's direction to the other) between two samples of
/// the same tilted mode.
#[test]
fn plant_summary_reports_the_peak_of_the_unfinished_last_tilt() {
    let _turn = realtime_turn();
    let dir = Scratch::new("lockstep-peak");
    let port = free_port();
    let robot = robot("lockstep_peak");
    let csv = dir.path().join("plant.csv");
    // 2.1 s: the last tilt starts at 1.768 s and peaks at about 2.03 s.
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(
            &robot,
            port,
            &[
                "--clock",
                "lockstep",
                "--duration",
                "2.1",
                "--record",
                csv.to_str().unwrap(),
            ],
        ),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "plant: {status}\n{}", plant.logs());
    let summary = plant.plant_summary();
    assert!(ctl.interrupt(Duration::from_secs(10)).success());

    let rows = parse_csv(&std::fs::read_to_string(&csv).unwrap());
    let truth: Vec<(f64, f64)> = rows
        .windows(2)
        .filter(|w| {
            let s = match w[0].mode {
                1 => 1.0,
                2 => -1.0,
                _ => return false,
            };
            w[1].mode == w[0].mode && s * w[0].x[2] > 0.0 && s * w[1].x[2] <= 0.0
        })
        .map(|w| (w[0].t, w[1].t))
        .collect();
    let last = rows.last().unwrap();
    assert_ne!(last.mode, 0, "the run must end inside a tilt");
    let tilt_start = rows.iter().rev().find(|r| r.mode != last.mode).unwrap().t;
    assert!(
        truth.iter().any(|b| b.0 >= tilt_start),
        "no peak in the last tilt: {truth:?}"
    );
    assert_eq!(
        summary.tilt_peaks.len(),
        truth.len(),
        "peaks {:?}\nsign changes {truth:?}",
        summary.tilt_peaks
    );
    for (p, b) in summary.tilt_peaks.iter().zip(&truth) {
        assert!(p[0] >= b.0 && p[0] <= b.1, "peak {p:?} outside {b:?}");
    }
}

/// The plant in lockstep emulating an impaired network (delay, jitter, loss; seeded) equals the
/// offline `simulate` with the same flags, bit for bit: both run the same impaired hold
/// (`tilting_link::ImpairedHold`) on the same answers, and the controller's law is the same
/// code.
#[test]
fn lockstep_over_an_emulated_link_equals_simulate_with_the_same_flags() {
    let _turn = realtime_turn();
    let net = [
        "--state-delay",
        "0.0005",
        "--torque-delay",
        "0.001",
        "--jitter",
        "exp:0.0007",
        "--loss",
        "0.03",
        "--seed",
        "11",
    ];
    lockstep_equals_simulate("locknet", &net, &[]);
}

/// The same with a controller that predicts over a given delay (`--predict 0.008`, 8 ms of
/// torque delay): the node's predictor learns the period from the states' times and runs the
/// same code as `simulate --predict 0.008`, so the runs agree bit for bit, and the node reports
/// that it predicted. (Without loss: in lockstep the controller answers every state and the
/// emulation drops the answer to a state it "loses", so a predicting controller counts on
/// torques that never act; offline, a lost state is never answered.)
#[test]
fn a_predicting_controller_in_lockstep_equals_simulate_with_the_same_flags() {
    let _turn = realtime_turn();
    let net = ["--torque-delay", "0.008"];
    lockstep_equals_simulate("lockpred", &net, &["--predict", "0.008"]);
}

/// Runs the plant in lockstep with `net` and a controller with `ctl`, then `simulate` with
/// `net` and `ctl`, and compares the final states bit for bit and the network counters.
fn lockstep_equals_simulate(name: &str, net: &[&str], ctl_flags: &[&str]) {
    let dir = Scratch::new(name);
    let mut extra = vec!["--clock", "lockstep", "--duration", "2"];
    extra.extend(net);
    let (summary, c) = run_loop(dir.path(), &robot(name), free_port(), &extra, ctl_flags);
    if !ctl_flags.is_empty() {
        let p = c.prediction.expect("the prediction counters");
        assert!(p.predictions > 1000 && p.fallbacks == 0, "{p:?}");
    }
    let got_net = summary
        .network
        .clone()
        .expect("the plant's network counters");
    let mut args = vec!["--control-period", "0.001", "--duration", "2"];
    args.extend(net);
    args.extend(ctl_flags);
    let want = simulate_json(&args);
    let want_x = want.final_state.x;
    eprintln!("network: {got_net:?}");
    assert!(got_net.torques_late > 0, "{got_net:?}");
    if net.contains(&"--loss") {
        assert!(got_net.states_lost > 0, "{got_net:?}");
    }
    assert_eq!(summary.time, 2.0);
    for (i, (g, w)) in summary.x.iter().zip(&want_x).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "component {i}: {g} vs {w}");
    }
    let want_net = want.network.expect("simulate's network counters");
    assert_eq!(got_net, want_net);
}

/// `tilting simulate --sample-on-event` over `seconds` at 100 Hz: its final state and its
/// controller's sample count (periodic and extra states).
fn simulate_sampling_on_events(seconds: &str) -> ([f64; 4], u64) {
    let r = simulate_json(&[
        "--control-period",
        "0.01",
        "--duration",
        seconds,
        "--sample-on-event",
    ]);
    (r.final_state.x, r.stats.controller_samples)
}

/// A 2 s run of the plant at 100 Hz with `--sample-on-event` and `clock_args` against a
/// controller node: the plant's and the controller's summaries.
fn sampling_on_events_run(name: &str, clock_args: &[&str]) -> (PlantSummary, ControllerSummary) {
    let dir = Scratch::new(name);
    let mut extra = vec!["--duration", "2", "--rate", "100", "--sample-on-event"];
    extra.extend_from_slice(clock_args);
    run_loop(dir.path(), &robot(name), free_port(), &extra, &[])
}

/// The plant in lockstep with `--sample-on-event` publishes an extra state at each mode
/// transition and switches to its answer at once; `simulate --sample-on-event` over a perfect
/// link does the same offline, so the two runs agree bit for bit.
#[test]
fn lockstep_sampling_on_events_equals_simulate() {
    let _turn = realtime_turn();
    let (summary, c) = sampling_on_events_run("lockevent", &["--clock", "lockstep"]);
    let (want_x, samples) = simulate_sampling_on_events("2");
    // The controller answered the 200 periodic states and one extra state per stop, as many
    // as simulate's controller did, plus the final state (t = 2 s) the plant publishes last.
    assert!(samples > 200, "no extra sample offline: {samples}");
    assert_eq!(c.torques_published, samples + 1, "{c:?}");
    // One stop per landing (the plate lifts off again at the same instant, without a stop of
    // its own), as offline: simulate's samples are the 200 periodic ones and the extra ones.
    assert_eq!(summary.extra_states, samples - 200, "{summary:?}");
    assert_eq!(summary.extra_answers, summary.extra_states, "{summary:?}");
    assert_eq!(summary.time, 2.0);
    for (i, (g, w)) in summary.x.iter().zip(&want_x).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "component {i}: {g} vs {w}");
    }
}

/// The real-time plant samples on events too: it integrates each period when the period ends,
/// stops at each transition, publishes the state there and waits up to half a period for the
/// answer, which then acts from the transition's instant. So when every answer comes in time
/// (the controller answers in well under a millisecond on loopback, the budget at 100 Hz is
/// 5 ms) the run is the lockstep one, bit for bit; on a loaded machine a late answer makes it
/// differ, and the test then checks the counts only.
#[test]
fn realtime_sampling_on_events_answers_each_transition() {
    let _turn = realtime_turn();
    let (summary, c) = sampling_on_events_run("rtevent", &["--clock", "realtime"]);
    eprintln!("{summary:?}");
    assert_eq!(summary.result, RunResult::Completed, "{summary:?}");
    assert!(summary.tilts >= 4, "{summary:?}");
    // One stop per landing, as in lockstep and offline (while the answers come in time, the
    // run and so its landings are the same).
    let (want_x, samples) = simulate_sampling_on_events("2");
    assert!(
        summary.extra_states >= summary.tilts && summary.extra_states <= summary.transitions,
        "{summary:?}"
    );
    assert!(
        summary.extra_answers as f64 >= 0.8 * summary.extra_states as f64,
        "{summary:?}"
    );
    // The controller answered every periodic and extra state.
    assert_eq!(
        c.torques_published,
        summary.seq + 1 + summary.extra_states,
        "{c:?}"
    );
    if summary.extra_answers == summary.extra_states
        && summary.deadline_misses == 0
        && summary.watchdog_trips == 0
    {
        assert_eq!(summary.extra_states, samples - 200, "{summary:?}");
        for (i, (g, w)) in summary.x.iter().zip(&want_x).enumerate() {
            assert_eq!(g.to_bits(), w.to_bits(), "component {i}: {g} vs {w}");
        }
    } else {
        eprintln!("an answer came late on this machine: the run is not compared bit for bit");
    }
}

/// The controller started from a robot file (`--robot-file`, as `tilting live` starts it with
/// the run's robot.toml) runs the same loop as one given the same settings as flags: a file
/// written by `tilting config` from the flags (a model, other gains, `--predict`, `--estimator`),
/// in lockstep over a delayed link, ends in the same state, bit for bit, with the same
/// predictions.
#[test]
fn a_controller_from_a_robot_file_equals_one_from_flags() {
    let _turn = realtime_turn();
    let dir = Scratch::new("lockfile");
    let params = dir.path().join("model.toml");
    std::fs::write(&params, "m_f = 1.0\n").unwrap();
    let params = params.to_str().unwrap();
    let file = dir.path().join("robot.toml");
    let flags = [
        "--params",
        params,
        "--kd",
        "14",
        "--k",
        "400",
        "--predict",
        "0.008",
        "--estimator",
        "fd",
    ];
    let out = std::process::Command::new(bin("tilting"))
        .arg("config")
        .args(flags)
        .output()
        .expect("run tilting config");
    assert!(
        out.status.success(),
        "config: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(&file, &out.stdout).unwrap();
    let plant = [
        "--clock",
        "lockstep",
        "--duration",
        "2",
        "--torque-delay",
        "0.008",
    ];
    let run = |name: &str, ctl: &[&str]| {
        let d = Scratch::new(name);
        run_loop(d.path(), &robot(name), free_port(), &plant, ctl)
    };
    let (from_file, c_file) = run("lockfile-a", &["--robot-file", file.to_str().unwrap()]);
    let (from_flags, c_flags) = run("lockfile-b", &flags);
    assert_eq!((from_file.time, from_flags.time), (2.0, 2.0));
    for (i, (a, b)) in from_file.x.iter().zip(&from_flags.x).enumerate() {
        assert_eq!(a.to_bits(), b.to_bits(), "component {i}: {a} vs {b}");
    }
    let (pa, pb) = (c_file.prediction.unwrap(), c_flags.prediction.unwrap());
    assert!(pa.predictions > 1000, "{pa:?}");
    assert_eq!(
        (pa.predictions, pa.fallbacks),
        (pb.predictions, pb.fallbacks)
    );
    // And a law other than the default's: the file's law moved the run.
    let (paper, _) = run("lockfile-c", &["--predict", "0.008"]);
    assert_ne!(paper.x, from_file.x);
}
