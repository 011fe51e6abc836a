//! MCAP recordings, checked from outside and used as a regression test:
//!
//! - the plant's `--record run.mcap` opens in the independent Python `mcap` reader, which lists
//!   one JSON channel with a JSON Schema per topic and counts exactly the messages the plant's
//!   summary counted (`steps + 1` states, `torques_applied` torques, `transitions` events);
//! - a plant killed with SIGKILL in the middle of a run leaves a recording the same reader
//!   reads up to its last chunk: consecutive states from 0;
//! - `tilting replay FILE --topics state --fast` into a fresh controller reproduces the recorded
//!   torques bit for bit (the regression test of a controller developer);
//! - `tilting info` and `tilting replay` refuse missing, foreign and truncated-to-nothing
//!   files with clear errors.
//!
//! The Python checks need `python3` with the `mcap` and `zstandard` packages (`.ci/run`
//! installs them); without them they print a SKIP line and pass.

use std::collections::BTreeMap;
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tilting_proto::{codec, Topic, TorqueCommand};
use tilting_tests::*;

fn python_has_mcap() -> bool {
    python_runs("import mcap.stream_reader, zstandard")
}

/// What tests/python/check_mcap.py prints about a file.
#[derive(Debug, serde::Deserialize)]
struct PyCheck {
    /// The file has its footer (closed normally).
    complete: bool,
    /// The channels by topic.
    channels: BTreeMap<String, PyChannel>,
    /// The states' `seq` are 0, 1, 2, ...
    state_seq_consecutive: bool,
}

/// One channel as the Python reader sees it.
#[derive(Debug, serde::Deserialize)]
struct PyChannel {
    message_encoding: String,
    schema_encoding: String,
    schema_name: String,
    count: u64,
    /// Every message has exactly the schema's required fields, of the schema's types.
    fields_ok: bool,
    last_log_time: Option<u64>,
}

/// The Python reader's view of `file` (see tests/python/check_mcap.py).
fn python_check(file: &std::path::Path) -> PyCheck {
    let out = Command::new(python())
        .arg(workspace_root().join("tests/python/check_mcap.py"))
        .arg(file)
        .stdin(Stdio::null())
        .output()
        .expect("run check_mcap.py");
    assert!(
        out.status.success(),
        "check_mcap.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("check_mcap.py prints JSON")
}

/// A lockstep run of `seconds` recorded by the plant into `file`; returns the plant's summary.
fn recorded_run(dir: &Scratch, robot: &str, file: &std::path::Path, seconds: &str) -> PlantSummary {
    let port = free_port();
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(
            robot,
            port,
            &[
                "--clock",
                "lockstep",
                "--duration",
                seconds,
                "--record",
                file.to_str().unwrap(),
            ],
        ),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(robot, port, &[]),
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "plant: {status}\n{}", plant.logs());
    ctl.interrupt(Duration::from_secs(10));
    plant.plant_summary()
}

#[test]
fn the_plants_recording_opens_in_the_python_mcap_reader_with_the_plants_counts() {
    if !python_has_mcap() {
        let why = format!("`{}` has no `mcap`/`zstandard` module", python());
        skip(
            "the_plants_recording_opens_in_the_python_mcap_reader",
            Missing::Package,
            &why,
        );
        return;
    }
    let dir = Scratch::new("mcap-py");
    let robot = robot("mcappy");
    let file = dir.path().join("run.mcap");
    let summary = recorded_run(&dir, &robot, &file, "3");
    assert_eq!(summary.result, RunResult::Completed);
    let v = python_check(&file);
    assert!(v.complete, "{v:?}");
    let ch = |key: &str| &v.channels[&format!("/tilting/{robot}/{key}")];
    let want: BTreeMap<&str, (&str, u64)> = BTreeMap::from([
        ("plant/state", ("tilting.PlantState", summary.steps + 1)),
        (
            "controller/torque",
            ("tilting.TorqueCommand", summary.torques_applied),
        ),
        ("plant/event", ("tilting.ModeEvent", summary.transitions)),
    ]);
    for (key, (schema, count)) in &want {
        let c = ch(key);
        assert_eq!(c.message_encoding, "json", "{key}: {c:?}");
        assert_eq!(c.schema_encoding, "jsonschema", "{key}: {c:?}");
        assert_eq!(c.schema_name, *schema, "{key}: {c:?}");
        assert_eq!(c.count, *count, "{key}: {c:?}");
        assert!(c.fields_ok, "{key}: {c:?}");
    }
    // 3 s of the orbit: about 7 tilts, two events each; every period applied a torque.
    assert!(summary.transitions >= 10, "{summary:?}");
    assert_eq!(summary.torques_applied, summary.steps);
    let status = ch("plant/status");
    assert!(status.count >= 2, "{status:?}");
    assert!(status.fields_ok);
    // Log times are plant time: the last state at 3 s.
    assert_eq!(ch("plant/state").last_log_time, Some(3_000_000_000));
    assert!(v.state_seq_consecutive);
}

#[test]
fn a_plant_killed_mid_run_leaves_a_recording_readable_to_its_last_chunk() {
    if !python_has_mcap() {
        let why = format!("`{}` has no `mcap`/`zstandard` module", python());
        skip(
            "a_plant_killed_mid_run_leaves_a_recording_readable",
            Missing::Package,
            &why,
        );
        return;
    }
    let dir = Scratch::new("mcap-kill");
    let robot = robot("mcapkill");
    let file = dir.path().join("run.mcap");
    let port = free_port();
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
                "600",
                "--record",
                file.to_str().unwrap(),
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
    // Let a few chunks (100 ms each) reach the file, then kill without warning.
    let end = Instant::now() + Duration::from_secs(30);
    while std::fs::metadata(&file).map_or(0, |m| m.len()) < 200_000 {
        assert!(
            Instant::now() < end,
            "the recording does not grow\n{}",
            plant.logs()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(250));
    plant.signal(libc::SIGKILL);
    plant.expect_exit(Duration::from_secs(5));
    ctl.interrupt(Duration::from_secs(10));
    let v = python_check(&file);
    assert!(!v.complete, "{v:?}");
    let states = v.channels[&format!("/tilting/{robot}/plant/state")].count;
    assert!(states > 1000, "{v:?}");
    assert!(v.state_seq_consecutive, "{v:?}");
    // Our reader agrees with the independent one.
    let run = tilting_record::read(&file).expect("opens");
    assert!(!run.complete());
    assert_eq!(run.count(Topic::State), states);
}

#[test]
fn replayed_states_reproduce_the_recorded_torques_bit_for_bit() {
    let dir = Scratch::new("replay");
    let robot_a = robot("recorded");
    let file = dir.path().join("run.mcap");
    let summary = recorded_run(&dir, &robot_a, &file, "2");
    assert_eq!(summary.torques_applied, 2000);
    // The recorded torques, by seq.
    let run = tilting_record::read(&file).unwrap();
    let recorded: BTreeMap<u64, u64> = run
        .messages()
        .filter(|e| e.topic == Topic::Torque)
        .map(|e| {
            let c: TorqueCommand = codec::decode(&e.wire).unwrap();
            (c.seq, c.tau.to_bits())
        })
        .collect();
    assert_eq!(recorded.len(), 2000);

    // A fresh controller under test, listening; the test collects its torques.
    let robot_b = robot("undertest");
    let (ctl_port, my_port) = (free_port(), free_port());
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap();
    let client = rt.block_on(Client::open(&robot_b, Some(my_port), None));
    let got: Arc<Mutex<BTreeMap<u64, u64>>> = Arc::default();
    let g = got.clone();
    let _sub = rt
        .block_on(tilting_net::subscribe_bytes(
            &client.session,
            client.keys.controller_torque(),
            move |b| {
                if let Ok(c) = codec::decode::<TorqueCommand>(b) {
                    g.lock().unwrap().insert(c.seq, c.tau.to_bits());
                }
            },
        ))
        .unwrap();
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &[
            "--robot",
            &robot_b,
            "--listen",
            &format!("tcp/127.0.0.1:{ctl_port}"),
            "--connect",
            &format!("tcp/127.0.0.1:{my_port}"),
        ]
        .map(String::from),
        dir.path(),
    );
    // Only the states, at the recorded pace: the controller is a real-time node, and its
    // torques drop on a link that falls 16 messages behind (net's "Never blocking the loop"),
    // which `--fast` provokes on a loaded machine (580 of 2,001 came back once).
    let out = Command::new(bin("tilting"))
        .args(["replay", file.to_str().unwrap(), "--topics", "state"])
        .args(["--robot", &robot_b, "--listen", "tcp/127.0.0.1:0"])
        .args(["--connect", &format!("tcp/127.0.0.1:{ctl_port}")])
        .output()
        .expect("run tilting replay");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "replay failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        ctl.logs()
    );
    assert!(stdout.contains("2001 state"), "{stdout}");
    let done = rt.block_on(poll_until(Duration::from_secs(10), || {
        (got.lock().unwrap().len() >= 2001).then_some(())
    }));
    ctl.interrupt(Duration::from_secs(10));
    let got = got.lock().unwrap();
    // A torque dropped on a stalled link is allowed (at most 1 %: none at this pace unless
    // the machine stalls the controller's sending for 16 ms); every one that came back must be
    // the recorded one, bit for bit.
    assert!(
        done.is_some() || got.len() * 100 >= 2001 * 99,
        "{} torques came back",
        got.len()
    );
    let mut differ = 0;
    for (seq, bits) in &recorded {
        if got.get(seq).is_some_and(|b| b != bits) {
            differ += 1;
        }
    }
    let compared = recorded.keys().filter(|k| got.contains_key(k)).count();
    assert!(compared * 100 >= recorded.len() * 99, "{compared} compared");
    assert_eq!(differ, 0, "{differ} of {compared} torques differ");
}

#[test]
fn bad_recordings_get_clear_errors() {
    let dir = Scratch::new("badmcap");
    let run = |args: &[&str]| {
        let o = Command::new(bin("tilting")).args(args).output().unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let missing = dir.path().join("missing.mcap");
    let (code, err) = run(&["info", missing.to_str().unwrap()]);
    assert_eq!(code, Some(1));
    assert!(
        err.contains("missing.mcap") && err.contains("No such file"),
        "{err}"
    );
    let text = dir.path().join("notes.mcap");
    std::fs::write(&text, "seq,t\n").unwrap();
    let (_, err) = run(&["info", text.to_str().unwrap()]);
    assert!(err.contains("not an MCAP file"), "{err}");
    // Only the magic and part of the header: nothing to replay.
    let torn = dir.path().join("torn.mcap");
    std::fs::write(&torn, b"\x89MCAP0\r\n\x01\x20").unwrap();
    let (code, err) = run(&["replay", torn.to_str().unwrap(), "--wait", "1"]);
    assert_ne!(code, Some(0));
    assert!(err.contains("torn.mcap"), "{err}");
    let (code, err) = run(&["replay", torn.to_str().unwrap(), "--topics", "torques"]);
    assert_eq!(code, Some(2));
    assert!(err.contains("unknown topic `torques`"), "{err}");
}
