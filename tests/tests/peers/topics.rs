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
