//! A real-time run (1 kHz, wall-clock paced) over zenoh tilts periodically and stays on the
//! paper's orbit for 10 s; the events arrive on the event topic.

use std::sync::{Arc, Mutex};
use std::time::Duration;
use tilting_proto::ModeEvent;
use tilting_tests::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn realtime_run_stays_on_the_orbit_for_10_s() {
    let _turn = realtime_turn();
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("realtime");
    let port = free_port();
    let robot = robot("realtime");
    let csv = dir.path().join("plant.csv");
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(
            &robot,
            port,
            &["--duration", "10", "--record", csv.to_str().unwrap()],
        ),
        dir.path(),
    );
    // The test listens to the events like any other peer.
    let client = Client::open(&robot, None, Some(port)).await;
    let events: Arc<Mutex<Vec<ModeEvent>>> = Arc::default();
    let ev = events.clone();
    let _sub = client
        .session
        .declare_subscriber(client.keys.plant_event().to_owned())
        .callback(move |s| {
            if let Ok(e) = tilting_proto::decode::<ModeEvent>(&s.payload().to_bytes()) {
                ev.lock().unwrap().push(e);
            }
        })
        .await
        .unwrap();
    let status = StatusWatch::new(&client).await;
    let mut ctl = Proc::spawn(
        "controller",
        &ctl_bin,
        &peer_args(&robot, port, &[]),
        dir.path(),
    );

    let exit = tokio::task::spawn_blocking(move || {
        let s = plant.expect_exit(Duration::from_secs(40));
        (s, plant)
    })
    .await
    .unwrap();
    let (exit, plant) = exit;
    assert!(exit.success(), "plant: {exit}\n{}", plant.logs());
    let summary = plant.plant_summary();
    eprintln!("plant summary: {summary:?}");
    assert_eq!(summary.result, RunResult::Completed, "{summary:?}");
    assert!(ctl.interrupt(Duration::from_secs(10)).success());

    // Timing, for the record (the machine is shared: only gross failures are errors).
    let misses = summary.deadline_misses;
    let trips = summary.watchdog_trips;
    eprintln!(
        "jitter us {:?} | loop latency us {:?} | overruns {} (max {} us) | deadline misses {misses} | watchdog trips {trips}",
        summary.jitter_us, summary.latency_us, summary.overruns, summary.max_overrun_us
    );
    assert!(
        misses < 1000,
        "more than 10% of the periods missed their torque"
    );

    // Periodic tilting, alternating sides, every ~0.44 s, peaks on the orbit (~0.040 rad).
    let tilts = summary.tilts;
    assert!((20..=24).contains(&tilts), "tilts in 10 s: {tilts}");
    let peaks: Vec<(f64, f64)> = summary.tilt_peaks.iter().map(|p| (p[0], p[1])).collect();
    assert!(peaks.len() >= 20);
    for w in peaks.windows(2) {
        assert!(w[0].1.signum() != w[1].1.signum(), "tilts alternate: {w:?}");
        let dt = w[1].0 - w[0].0;
        assert!((0.40..0.48).contains(&dt), "tilt spacing {dt} s: {w:?}");
    }
    for &(t, a) in &peaks {
        assert!(
            (0.03..0.06).contains(&a.abs()),
            "peak |alpha| = {} at t = {t}",
            a.abs()
        );
    }

    // The event topic saw every transition: tilt starts and landings.
    tokio::time::sleep(Duration::from_millis(200)).await;
    let events = events.lock().unwrap().clone();
    let starts = events.iter().filter(|e| e.from == 0 && e.to != 0).count() as u64;
    assert_eq!(starts, tilts, "tilt starts on the event topic");
    assert_eq!(
        events.len() as u64,
        summary.transitions,
        "all transitions published"
    );
    // The last status says stopped, without a fault.
    let last = status.latest().expect("a status was received");
    assert_eq!(last.state, tilting_proto::Status::STOPPED, "{last:?}");
    assert!(last.fault.is_empty());
    assert_eq!(last.tilts, tilts);

    // The record has every period.
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count();
    assert_eq!(rows, 1 + 10_001);
}
