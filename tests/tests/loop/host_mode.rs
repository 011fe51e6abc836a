//! Host mode (issue 32): one `tilting-plant --robots A,B,C` and one `tilting-controller
//! --robots A,B,C` serve three robots over one zenoh session each. In lockstep every robot's
//! run is the one robot's run alone (the offline sampled loop, which a one-robot lockstep run
//! equals bit for bit: `lockstep.rs`), bit for bit; each robot's messages reach only its own
//! counterpart; bad `--robots` are refused naming the flag and its range. `tilting live
//! --robots A,B` runs the same two hosts with a front door per robot, each robot's run its
//! one-robot `tilting live` run's, bit for bit in lockstep.

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

/// The secure deployment's node configurations (`tilting certs`: a TLS identity of one
/// robot's node, access control for its keys) are refused by both nodes in host mode before
/// anything starts, naming both flags.
#[test]
fn host_mode_refuses_a_secure_nodes_configuration() {
    let dir = Scratch::new("host-mode-secure");
    let certs = dir.path().join("certs");
    let o = std::process::Command::new(bin("tilting"))
        .args(["certs", "--robot", "a", "--out"])
        .arg(&certs)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (node, config) in [
        ("tilting-plant", "plant-direct.json5"),
        ("tilting-plant", "plant.json5"),
        ("tilting-controller", "controller.json5"),
    ] {
        let file = certs.join(config).display().to_string();
        let argv: Vec<String> = ["--robots", "a,b", "--zenoh-config", &file]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let mut p = Proc::spawn(node, &bin(node), &argv, dir.path());
        let status = p.expect_exit(Duration::from_secs(20));
        assert!(
            !status.success(),
            "{node} {config} was accepted\n{}",
            p.logs()
        );
        let err = p.stderr();
        for w in ["`--robots` (host mode)", "`--zenoh-config`", "TLS identity"] {
            assert!(err.contains(w), "{node} {config}: no {w:?} in\n{err}");
        }
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

/// The states and torques of a `tilting live` robot's `run.mcap`, by `seq` (wire bytes).
fn recorded(mcap: &std::path::Path) -> [std::collections::BTreeMap<u64, Vec<u8>>; 2] {
    use tilting_proto::{PlantState, Topic, TorqueCommand};
    let run = tilting_record::read(mcap).unwrap_or_else(|e| panic!("{}: {e}", mcap.display()));
    let mut states = std::collections::BTreeMap::new();
    let mut torques = std::collections::BTreeMap::new();
    for m in run.messages() {
        match m.topic {
            Topic::State => {
                let s: PlantState = tilting_proto::decode(&m.wire).unwrap();
                states.insert(s.seq, m.wire.clone());
            }
            Topic::Torque => {
                let c: TorqueCommand = tilting_proto::decode(&m.wire).unwrap();
                torques.insert(c.seq, m.wire.clone());
            }
            _ => {}
        }
    }
    [states, torques]
}

/// `tilting live --robots A,B --lockstep`: one plant host and one controller host (one
/// summary line per robot each), each robot's recording, report and summary in OUT/NAME/, and
/// each robot's run bit for bit the one-robot `tilting live --lockstep` run of the same flags
/// (an independent path: a plant and a controller serving that robot alone): every state and
/// torque both recorded has the same bytes, the plant's final state and step count are the
/// same bits, and the orbit holds.
#[test]
fn live_robots_in_lockstep_each_equal_its_solo_run() {
    let _turn = realtime_turn();
    let dir = Scratch::new("live-host");
    let names: Vec<String> = ["a", "b"]
        .iter()
        .map(|t| robot(&format!("livehost_{t}")))
        .collect();
    let run = |extra: &[&str], out: &std::path::Path| {
        let o = std::process::Command::new(bin("tilting"))
            .args(["live", "--lockstep", "--duration", "3", "--out"])
            .arg(out)
            .args(extra)
            .output()
            .unwrap();
        let text = format!(
            "{}\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(o.status.success(), "live {extra:?}: {}\n{text}", o.status);
        text
    };
    let host = dir.path().join("host");
    let said = run(&["--robots", &names.join(",")], &host);
    // One process each, one summary line per robot.
    let plants = HostedSummary::<PlantSummary>::all_from_stdout(
        &std::fs::read_to_string(host.join("plant.json")).unwrap(),
    );
    let ctls = HostedSummary::<ControllerSummary>::all_from_stdout(
        &std::fs::read_to_string(host.join("controller.json")).unwrap(),
    );
    let served = |v: Vec<&String>| v.into_iter().cloned().collect::<Vec<_>>();
    assert_eq!(
        served(plants.iter().map(|s| &s.robot).collect()),
        names,
        "{said}"
    );
    assert_eq!(
        served(ctls.iter().map(|s| &s.robot).collect()),
        names,
        "{said}"
    );
    for (name, p) in names.iter().zip(&plants) {
        let solo = dir.path().join(format!("solo-{name}"));
        let solo_said = run(&["--robot", name], &solo);
        let (h, s) = (live_summary(&host.join(name)), live_summary(&solo));
        assert_eq!(h.robot, *name);
        assert_eq!(
            h.result,
            tilting_live::summary::LiveResult::Completed,
            "{said}"
        );
        let verdict = h.orbit.as_ref().expect("an orbit verdict");
        assert_eq!(
            verdict.state,
            tilting_live::summary::OrbitState::Holds,
            "{name}: {verdict:?}\n{said}"
        );
        // The summary's plant is the host's line for this robot.
        let (hp, sp) = (h.plant.as_ref().unwrap(), s.plant.as_ref().unwrap());
        assert_eq!(hp.x.map(f64::to_bits), p.summary.x.map(f64::to_bits));
        assert_eq!(hp.steps, sp.steps, "{name}\n{said}\n{solo_said}");
        assert_eq!(
            hp.x.map(f64::to_bits),
            sp.x.map(f64::to_bits),
            "{name}: final state"
        );
        assert!(
            hp.tilts >= 2 && hp.tilts == sp.tilts,
            "{name}: {} tilts",
            hp.tilts
        );
        let [hs, ht] = recorded(&host.join(name).join("run.mcap"));
        let [ss, st] = recorded(&solo.join("run.mcap"));
        for (what, a, b) in [("state", &hs, &ss), ("torque", &ht, &st)] {
            // A recorder may miss a message the loop did not wait for; nearly all are there.
            let steps = hp.steps as usize;
            assert!(
                a.len() * 100 >= steps * 95 && b.len() * 100 >= steps * 95,
                "{name}: {} and {} {what}s of {steps} steps",
                a.len(),
                b.len()
            );
            let mut common = 0;
            for (seq, wire) in a {
                if let Some(w) = b.get(seq) {
                    assert_eq!(wire, w, "{name}: {what} {seq}");
                    common += 1;
                }
            }
            assert!(
                common * 100 >= steps * 90,
                "{name}: {common} common {what}s"
            );
        }
    }
    assert!(
        said.contains(&format!(
            "live: robots: {} clean, {} clean",
            names[0], names[1]
        )),
        "{said}"
    );
}

/// `tilting live --robots` refused before anything starts, naming the flag and the range: no
/// robot, 33 robots, a name twice, and the flags host mode cannot honour (naming both).
#[test]
fn live_bad_robots_are_refused_naming_the_flag_and_range() {
    let dir = Scratch::new("live-host-bad");
    let many: Vec<String> = (0..33).map(|i| format!("r{i}")).collect();
    let many = many.join(",");
    let cases: [(&[&str], &[&str]); 6] = [
        (&["--robots", ""], &["--robots", "0 names", "1 to 32"]),
        (&["--robots", &many], &["--robots", "33 names", "1 to 32"]),
        (
            &["--robots", "a,b,a"],
            &["--robots", "\"a\" given twice", "1 to 32"],
        ),
        (
            &["--robots", "a,b", "--secure"],
            &[
                "`--robots` (host mode) does not take `--secure`",
                "tilting certs",
            ],
        ),
        (
            &["--robots", "a,b", "--plant-cmd", "python3 -m x"],
            &["`--robots`", "`--plant-cmd`"],
        ),
        (
            &["--robots", "a,b", "--foxglove", "127.0.0.1:0"],
            &["`--robots`", "`--foxglove`"],
        ),
    ];
    for (args, wanted) in cases {
        let o = std::process::Command::new(bin("tilting"))
            .arg("live")
            .args(args)
            .arg("--out")
            .arg(dir.path().join("never"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?} was accepted\n{err}");
        for w in wanted {
            assert!(err.contains(w), "{args:?}: no {w:?} in\n{err}");
        }
        assert!(!dir.path().join("never").exists(), "{args:?} started");
    }
}
