//! `tilting record` checks whose messages it records (issue 22), as `tilting live`'s recorder
//! does: the plant's topics only from the plant's zenoh session, the torques only from the
//! controller's.
//!
//! Nodes started by hand, as in the README's three-host deployment: the plant and the
//! controller get their zenoh ids in advance (`--zenoh-id`) and each other's (`--controller-id`,
//! `--plant-id`). A rogue peer publishes plausible-looking states and torques *before the plant
//! starts*, half naming no source and half a made-up session, then again mid-run:
//!
//! - recorder A, told both ids (`--plant-id`, `--controller-id`), refuses every rogue message,
//!   those sent before the plant existed included, counts and reports them;
//! - recorder B, told nothing and started after the rogue's first burst, pins the plant's and
//!   the controller's sessions at their first messages and refuses the mid-run burst.
//!
//! The truth is the rogue's own count of what it sent, and a marker (`beta`, `tau`) no honest
//! message carries: no marker may be in either recording. Delivery is exact: every rogue put
//! goes over a reliable link to a subscriber known to match before the first put.

use std::time::{Duration, Instant};
use tilting_proto::{codec, Topic};
use tilting_tests::*;
use zenoh::Wait as _;

const PLANT_ID: &str = "9a5e11d0000000000000000000000e1";
const CONTROLLER_ID: &str = "c0de0000000000000000000000000e2";

/// Puts `n` marker states and `n` marker torques from `rogue`, half with no attachment and half
/// naming a made-up session.
fn burst(rogue: &Client, n: u64, first_seq: u64) {
    let made_up = MADE_UP_SOURCE.attachment().to_vec();
    let s = &rogue.session;
    for i in 0..n {
        let seq = first_seq + i;
        let (state, torque) = (
            codec::encode(&marked_state(seq)),
            codec::encode(&marked_torque(seq)),
        );
        let (sk, tk) = (rogue.keys.plant_state(), rogue.keys.controller_torque());
        if i % 2 == 0 {
            s.put(sk, state).wait().unwrap();
            s.put(tk, torque).wait().unwrap();
        } else {
            s.put(sk, state).attachment(made_up.clone()).wait().unwrap();
            s.put(tk, torque)
                .attachment(made_up.clone())
                .wait()
                .unwrap();
        }
    }
}

/// Messages of `file` carrying the rogue's marker, and its states.
fn marked_and_states(file: &std::path::Path) -> (u64, u64) {
    let run = tilting_record::read(file).unwrap();
    let marked = rogue_marked(&run);
    (marked, run.count(Topic::State))
}

/// Waits until `p`'s stderr says it subscribed (`record: ... (Ctrl-C stops)`).
fn wait_subscribed(p: &Proc) {
    let t0 = Instant::now();
    while !p.stderr().contains("Ctrl-C stops") {
        assert!(t0.elapsed() < Duration::from_secs(20), "{}", p.logs());
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn record_keeps_a_rogue_out_even_one_that_talks_before_the_plant() {
    let _turn = realtime_turn();
    let dir = Scratch::new("record-sources");
    let robot = robot("record_sources");
    let (plant_port, rogue_port) = (free_port(), free_port());
    // The recorders listen where the plant dials them: linked before its first state.
    let (a_port, b_port) = (free_port(), free_port());
    let rt = tokio::runtime::Runtime::new().unwrap();
    let rogue = rt.block_on(Client::open(&robot, Some(rogue_port), None));
    let record = |name: &str, port: u16, ids: &[&str]| {
        let out = dir.path().join(format!("{name}.mcap"));
        let mut args: Vec<String> = [
            "record",
            "--robot",
            &robot,
            "--listen",
            &endpoint(port),
            "--connect",
            &endpoint(rogue_port),
            "--wait",
            "60",
            "--out",
            out.to_str().unwrap(),
        ]
        .map(String::from)
        .into();
        args.extend(ids.iter().map(|s| s.to_string()));
        (Proc::spawn(name, &bin("tilting"), &args, dir.path()), out)
    };

    // A, told both ids, subscribes; the rogue talks before any plant exists.
    let ids = ["--plant-id", PLANT_ID, "--controller-id", CONTROLLER_ID];
    let (mut a, a_out) = record("record-a", a_port, &ids);
    wait_subscribed(&a);
    let matched = rt.block_on(async {
        let p = rogue
            .session
            .declare_publisher(rogue.keys.controller_torque().to_owned())
            .await
            .unwrap();
        let q = rogue
            .session
            .declare_publisher(rogue.keys.plant_state().to_owned())
            .await
            .unwrap();
        let t0 = Instant::now();
        loop {
            let a = p.matching_status().await.is_ok_and(|m| m.matching());
            let b = q.matching_status().await.is_ok_and(|m| m.matching());
            if a && b {
                break Some(());
            }
            if t0.elapsed() > Duration::from_secs(20) {
                break None;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    });
    assert!(matched.is_some(), "record A never subscribed\n{}", a.logs());
    let early = 40;
    burst(&rogue, early, 0);

    // B, told nothing, starts after that burst; then the plant and the controller.
    let (mut b, b_out) = record("record-b", b_port, &[]);
    wait_subscribed(&b);
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(
            &robot,
            plant_port,
            &[
                "--duration",
                "3",
                "--connect",
                &endpoint(a_port),
                "--connect",
                &endpoint(b_port),
                "--zenoh-id",
                PLANT_ID,
                "--controller-id",
                CONTROLLER_ID,
            ],
        ),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(
            &robot,
            plant_port,
            &["--zenoh-id", CONTROLLER_ID, "--plant-id", PLANT_ID],
        ),
        dir.path(),
    );
    // Mid-run: once a watcher sees the loop 200 periods in, a second burst.
    let running = rt.block_on(async {
        let watcher = Client::open(&robot, None, Some(plant_port)).await;
        let watch = StatusWatch::new(&watcher).await;
        let seen = poll_until(Duration::from_secs(30), || {
            watch.latest().filter(|s| s.seq >= 200).map(|_| ())
        })
        .await;
        (seen, watcher)
    });
    assert!(
        running.0.is_some(),
        "the loop did not run\n{}",
        plant.logs()
    );
    let late = 30;
    burst(&rogue, late, 1_000_000);

    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "{}\n{}", plant.logs(), ctl.logs());
    assert!(ctl.interrupt(Duration::from_secs(10)).success());
    let (sa, sb) = (
        a.interrupt(Duration::from_secs(20)),
        b.interrupt(Duration::from_secs(20)),
    );
    assert!(sa.success() && sb.success(), "{}\n{}", a.logs(), b.logs());
    let plant_summary = plant.plant_summary();
    let ctl_summary = ctl.controller_summary();
    let (a_text, b_text) = (a.stdout(), b.stdout());
    eprintln!("A: {a_text}B: {b_text}plant {plant_summary:?}\ncontroller {ctl_summary:?}");

    // A: every rogue message refused (early and late), counted and said; none recorded.
    let a_foreign = 2 * (early + late);
    assert!(
        a_text.contains(&format!("foreign {a_foreign}\n")),
        "{a_text}"
    );
    assert!(
        a_text.contains("not recorded, from a foreign source"),
        "{a_text}"
    );
    let (marked, states) = marked_and_states(&a_out);
    assert_eq!(marked, 0, "rogue messages in A's recording");
    assert!(states >= plant_summary.steps, "{states} states in A");
    // B: the mid-run burst refused against the pins of the first messages; none recorded.
    assert!(
        b_text.contains(&format!("foreign {}\n", 2 * late)),
        "{b_text}"
    );
    let (marked, states) = marked_and_states(&b_out);
    assert_eq!(marked, 0, "rogue messages in B's recording");
    assert!(states >= plant_summary.steps, "{states} states in B");
    // The nodes were told each other's ids and ran the loop (the rogue's messages, if gossip
    // linked it to them, are theirs to refuse: tests/tests/front/front_door.rs).
    assert_eq!(
        plant_summary.result,
        RunResult::Completed,
        "{plant_summary:?}"
    );
    assert_eq!(plant_summary.steps, 3000, "{plant_summary:?}");
    drop(running);
}
