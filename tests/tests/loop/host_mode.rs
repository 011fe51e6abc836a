//! Host mode (issue 32): one `tilting-plant --robots A,B,C` and one `tilting-controller
//! --robots A,B,C` serve three robots over one zenoh session each. In lockstep every robot's
//! run is the one robot's run alone (the offline sampled loop, which a one-robot lockstep run
//! equals bit for bit: `lockstep.rs`), bit for bit; each robot's messages reach only its own
//! counterpart; bad `--robots` are refused naming the flag and its range.

use std::time::Duration;
use tilting_net::HostedSummary;
use tilting_tests::recording::{offline, parse_csv};
use tilting_tests::*;

const PERIOD: f64 = 0.001;
const DURATION: f64 = 1.0;

#[test]
fn three_hosted_robots_in_lockstep_each_equal_one_robot_alone() {
    let _turn = realtime_turn();
    let dir = Scratch::new("host-mode");
    let port = free_port();
    let names: Vec<String> = ["a", "b", "c"]
        .iter()
        .map(|t| robot(&format!("host_{t}")))
        .collect();
    let list = names.join(",");
    let csv = dir.path().join("plant.csv");
    let plant_argv: Vec<String> = [
        "--robots",
        &list,
        "--listen",
        &endpoint(port),
        "--clock",
        "lockstep",
        "--duration",
        &DURATION.to_string(),
        "--record",
        csv.to_str().unwrap(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let mut plant = Proc::spawn("plant", &bin("tilting-plant"), &plant_argv, dir.path());
    let ctl_argv: Vec<String> = [
        "--robots",
        &list,
        "--listen",
        "tcp/127.0.0.1:0",
        "--connect",
        &endpoint(port),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &ctl_argv,
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(90));
    assert!(status.success(), "plant: {status}\n{}", plant.logs());
    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );

    let plants = HostedSummary::<PlantSummary>::all_from_stdout(&plant.stdout());
    let ctls = HostedSummary::<ControllerSummary>::all_from_stdout(&ctl.stdout());
    assert_eq!(
        plants.iter().map(|s| s.robot.clone()).collect::<Vec<_>>(),
        names,
        "one plant summary per robot, in order\n{}",
        plant.logs()
    );
    assert_eq!(
        ctls.iter().map(|s| s.robot.clone()).collect::<Vec<_>>(),
        names,
        "one controller summary per robot\n{}",
        ctl.logs()
    );
    let want = offline(DURATION, PERIOD);
    for ((name, p), c) in names.iter().zip(&plants).zip(&ctls) {
        let (p, c) = (&p.summary, &c.summary);
        assert_eq!(p.result, RunResult::Completed, "{name}: {p:?}");
        assert_eq!((p.deadline_misses, p.torques_dropped), (0, 0), "{name}");
        // Each robot's torques come from its own controller only: a robot wired to another's
        // keys would receive two or three answers per state.
        // (The answer to the last state may arrive after the plant stopped listening.)
        assert!(
            (c.torques_published - 1..=c.torques_published).contains(&p.torques_received),
            "{name}: {} torques received, {} published",
            p.torques_received,
            c.torques_published
        );
        assert!(
            c.states_received < 2 * p.steps && p.torques_received < 2 * p.steps,
            "{name}: {} states, {} torques for {} steps",
            c.states_received,
            p.torques_received,
            p.steps
        );
        // Bit for bit the one robot alone.
        let path = dir.path().join(format!("plant-{name}.csv"));
        let got = parse_csv(&std::fs::read_to_string(&path).unwrap());
        assert_eq!(got.len(), want.len(), "{name}: number of samples");
        for (g, w) in got.iter().zip(&want) {
            assert_eq!((g.seq, g.mode), (w.seq, w.mode), "{name}: at {w:?}");
            assert_eq!(
                g.t.to_bits(),
                w.t.to_bits(),
                "{name}: time of seq {}",
                w.seq
            );
            for i in 0..4 {
                assert_eq!(
                    g.x[i].to_bits(),
                    w.x[i].to_bits(),
                    "{name}: x of seq {}",
                    w.seq
                );
            }
            assert_eq!(
                g.tau.map(f64::to_bits),
                w.tau.map(f64::to_bits),
                "{name}: tau of seq {}",
                w.seq
            );
        }
        assert_eq!(p.x.to_vec(), want.last().unwrap().x.to_vec(), "{name}");
    }
}

/// `--robots` out of 1 to 32, with a name twice or a bad name, and `--host-pacing one` in
/// lockstep: refused by both nodes before anything starts, naming the flag and the range.
#[test]
fn bad_robots_are_refused_naming_the_flag_and_range() {
    let dir = Scratch::new("host-mode-bad");
    let many: Vec<String> = (0..33).map(|i| format!("r{i}")).collect();
    let many = many.join(",");
    let cases: [(&str, &[&str], &[&str]); 5] = [
        (
            "tilting-plant",
            &["--robots", "a,b,a"],
            &["--robots", "\"a\" given twice", "1 to 32"],
        ),
        (
            "tilting-controller",
            &["--robots", "a,b,a"],
            &["--robots", "\"a\" given twice"],
        ),
        (
            "tilting-plant",
            &["--robots", &many],
            &["--robots", "33 names", "1 to 32"],
        ),
        (
            "tilting-controller",
            &["--robots", &many],
            &["--robots", "33 names", "1 to 32"],
        ),
        (
            "tilting-plant",
            &[
                "--robots",
                "a,b",
                "--host-pacing",
                "one",
                "--clock",
                "lockstep",
            ],
            &["--host-pacing one", "--clock realtime"],
        ),
    ];
    for (node, args, wanted) in cases {
        let argv: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        let mut p = Proc::spawn(node, &bin(node), &argv, dir.path());
        let status = p.expect_exit(Duration::from_secs(20));
        assert!(
            !status.success(),
            "{node} {args:?} was accepted\n{}",
            p.logs()
        );
        let err = p.stderr();
        for w in wanted {
            assert!(err.contains(w), "{node} {args:?}: no {w:?} in\n{err}");
        }
    }
}
