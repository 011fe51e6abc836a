//! `tilting echo` and `tilting hz` against a running plant and controller: echo decodes the
//! states (consecutive `seq`, 50-byte messages) and reports a malformed payload instead of
//! dying on it; hz measures the 1 kHz loop (rates within 30 % of 1000 Hz on a loaded 2-core
//! machine, sizes exactly the wire sizes).

use std::process::Command;
use std::time::Duration;
use tilting_live::topics::{HzReport, InvalidPayload};
use tilting_proto::{PlantState, Topic, TorqueCommand};
use tilting_tests::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn echo_and_hz_look_at_a_running_loop() {
    let _turn = realtime_turn();
    let tilting = bin("tilting");
    let dir = Scratch::new("topics");
    let port = free_port();
    let robot = robot("topics");
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(&robot, port, &["--duration", "20"]),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    let connect = endpoint(port);
    let look = |args: &[&str]| {
        let o = Command::new(&tilting)
            .args(args)
            .args(["--robot", &robot, "--connect", &connect])
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8(o.stdout).unwrap()
    };

    // echo: 200 states as JSON, decoded by an independent reader (serde_json into the message
    // type), consecutive sequence numbers.
    let text = look(&["echo", "state", "--json", "--count", "200"]);
    let states: Vec<PlantState> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert_eq!(states.len(), 200);
    let gaps = states
        .windows(2)
        .filter(|w| w[1].seq != w[0].seq + 1)
        .count();
    assert!(gaps <= 2, "{gaps} gaps in 200 states");

    // A malformed payload on the torque key is reported, and echo goes on.
    let client = Client::open(&robot, None, Some(port)).await;
    let key = client.keys.controller_torque().to_owned();
    let echo = {
        let (t, r, c) = (tilting.clone(), robot.clone(), connect.clone());
        std::thread::spawn(move || {
            Command::new(t)
                .args(["echo", "torque", "--json", "--seconds", "3"])
                .args(["--robot", &r, "--connect", &c])
                .output()
                .unwrap()
        })
    };
    tokio::time::sleep(Duration::from_millis(1500)).await;
    client.session.put(key, vec![1u8, 2, 3]).await.unwrap();
    let o = echo.join().unwrap();
    let text = String::from_utf8(o.stdout).unwrap();
    let invalid: Vec<InvalidPayload> = text
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    assert_eq!(invalid.len(), 1, "{invalid:?}");
    assert!(invalid[0].invalid.contains("TorqueCommand"), "{invalid:?}");
    let torques = text
        .lines()
        .filter(|l| serde_json::from_str::<TorqueCommand>(l).is_ok())
        .count();
    assert!(torques > 1000, "{torques} torques in 3 s");

    // hz: two reports of the state and torque topics.
    let text = look(&["hz", "--topics", "state,torque", "--json", "--seconds", "2"]);
    let last: HzReport = serde_json::from_str(text.lines().last().unwrap()).unwrap();
    for (topic, size) in [("state", 50.0), ("torque", 16.0)] {
        let t = last.topics.iter().find(|t| t.topic == topic).unwrap();
        let rate = t.rate_hz;
        assert!(
            (700.0..1300.0).contains(&rate),
            "{topic}: {rate} Hz\n{text}"
        );
        assert_eq!(t.bytes_per_msg, Some(size), "{topic}");
    }

    // record: 2 s of every topic as received, into an MCAP file that reads back complete with
    // the counts the command printed.
    let mcap = dir.path().join("record.mcap");
    let text = look(&["record", "--out", mcap.to_str().unwrap(), "--seconds", "2"]);
    let run = tilting_record::read(&mcap).unwrap();
    assert!(run.complete());
    let (states, torques) = (run.count(Topic::State), run.count(Topic::Torque));
    assert!(states > 1000 && torques > 1000, "{text}");
    assert!(
        text.contains(&format!("{states} state, {torques} torque")),
        "{text}"
    );
    let _ = client.session.close().await;
    assert!(ctl.interrupt(Duration::from_secs(10)).success());
    assert!(plant.interrupt(Duration::from_secs(10)).success());
}

/// A reference of either layout on the planner's key (protocol 3): the toy law's
/// `LawReference` (`plain-pd`, its `kp` and `kd`, as `planner/tests/planner/toy_law.rs` sends
/// it) and the paper's 57-byte `Reference`. `tilting echo` shows the law's name and its
/// parameters; `tilting record` keeps both payloads as sent, byte for byte, under one JSON
/// schema that passes the viewers' strict check (the record crate's unit tests walk it).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn echo_and_record_read_both_reference_layouts() {
    use tilting_proto::{codec, LawReference, Reference};
    let tilting = bin("tilting");
    let dir = Scratch::new("law-reference");
    let port = free_port();
    let robot = robot("lawref");
    let client = Client::open(&robot, Some(port), None).await;
    let toy = LawReference {
        trajectory: Reference::HOLD,
        amplitude: 0.0,
        omega: 0.0,
        law: "plain-pd".into(),
        parameters: vec![400.0, 56.56],
    };
    let paper = Reference {
        kind: Reference::SINUSOID,
        amplitude: 0.25,
        omega: 7.0,
        kp: 100.0,
        kd: 14.14,
        k: 500.0,
        energy_avg: 0.1875,
        torque_limit: 0.0,
    };
    let wires = [codec::encode(&toy), codec::encode(&paper)];
    assert_eq!(
        (wires[0].len(), wires[1].len()),
        (LawReference::SIZE, Reference::SIZE)
    );
    let connect = endpoint(port);
    let mcap = dir.path().join("refs.mcap");
    let spawn = |args: Vec<String>| {
        let (t, r, c) = (tilting.clone(), robot.clone(), connect.clone());
        std::thread::spawn(move || {
            Command::new(t)
                .args(args)
                .args(["--robot", &r, "--connect", &c])
                .output()
                .unwrap()
        })
    };
    let echo = spawn(
        ["echo", "reference", "--seconds", "3"]
            .map(String::from)
            .to_vec(),
    );
    let echo_json = spawn(
        ["echo", "reference", "--json", "--seconds", "3"]
            .map(String::from)
            .to_vec(),
    );
    let record = spawn(vec![
        "record".into(),
        "--out".into(),
        mcap.display().to_string(),
        "--seconds".into(),
        "3".into(),
    ]);
    // Both layouts, in turn, until the lookers stop (they join within the first second).
    let key = client.keys.planner_reference().to_owned();
    for _ in 0..20 {
        for w in &wires {
            client.session.put(&key, w.clone()).await.unwrap();
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let text = |o: std::process::Output| {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8(o.stdout).unwrap()
    };
    let human = text(echo.join().unwrap());
    assert!(
        human.contains("law plain-pd [p0 400, p1 56.56], hold"),
        "{human}"
    );
    assert!(human.contains("K_P0 = 100"), "the paper's gains: {human}");
    // The JSON lines read back as the messages sent (an independent reader: serde_json into
    // the message types).
    let json = text(echo_json.join().unwrap());
    let laws: Vec<LawReference> = json
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let papers: Vec<Reference> = json
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    assert!(!laws.is_empty() && laws.iter().all(|l| *l == toy), "{json}");
    assert!(
        !papers.is_empty() && papers.iter().all(|p| *p == paper),
        "{json}"
    );
    // The recording: every reference as sent, 107 or 57 bytes.
    let said = text(record.join().unwrap());
    let run = tilting_record::read(&mcap).unwrap();
    assert_eq!(run.invalid().0, 0, "{said}");
    let got: Vec<Vec<u8>> = run
        .messages()
        .filter(|e| e.topic == Topic::Reference)
        .map(|e| e.wire.clone())
        .collect();
    assert!(got.len() >= 2, "{said}");
    assert!(got.iter().any(|w| *w == wires[0]), "no LawReference");
    assert!(got.iter().any(|w| *w == wires[1]), "no Reference");
    assert!(got.iter().all(|w| wires.contains(w)));
    let _ = client.session.close().await;
}
