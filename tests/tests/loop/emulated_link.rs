//! The real-time plant emulating an impaired link on the wall clock (`--delay`, `--loss` with
//! `--clock realtime`), with the controller node unchanged.
//!
//! - 1 ms each way at 1 kHz: the emulator (`tilting_link::ImpairedHold`, the hold `simulate`
//!   uses) applies every torque exactly 2 periods old. On the wall clock the plant publishes
//!   state `k` a step's computation after deadline `k` and hands its answer to the inbox at
//!   least 2 ms later, so (unless the pacing thread itself stalls) no torque is applied younger
//!   than 2 periods; the controller and zenoh add 0.1-0.4 ms on loopback, and a loaded machine
//!   wakes the link thread late now and then, so a real age is 2 or 3 where the emulator says 2: the median must be within one
//!   period of the emulator's, and hardly any torque may be on time (age 0: at most 2 %, the
//!   answers found after a stall of the pacing thread itself). The 99th percentile may reach
//!   4 periods beyond it (a loaded 2-core machine delays 1 % of the hand-overs by up to 4 ms).
//! - 10 % loss each way: the plant draws the same streams as the offline emulator (`--seed`,
//!   stream 0 for states, 1 for torques), so the number of lost states is exactly the number of
//!   losses in the first `states_sent` draws of stream 0 (replayed here with `tilting_link::Link`),
//!   and likewise for torques on stream 1. As a check of the fraction: the binomial standard
//!   deviation of the loss count over n ~ 3,000 messages is sqrt(0.09 / n) ~ 0.55 %, and the
//!   fraction must be within 4.5 of them of 10 %.
//! - A negative delay given to `tilting live` is refused before anything starts, naming the
//!   flag and its range (exit code 2).

use std::time::Duration;
use tilting_link::{Impairment, Link, LinkSpec};
use tilting_tests::*;

/// A 3 s real-time plant with `flags`, driven by the controller node over loopback; its
/// summary and the last status it published.
async fn run(tag: &str, flags: &[&str]) -> (PlantSummary, tilting_proto::Status) {
    let dir = Scratch::new(tag);
    let port = free_port();
    let robot = robot(tag);
    let mut extra = vec!["--duration", "3"];
    extra.extend_from_slice(flags);
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(&robot, port, &extra),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let status = StatusWatch::new(&client).await;
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    let exit = plant.expect_exit(Duration::from_secs(60));
    assert!(exit.success(), "plant: {exit}\n{}", plant.logs());
    // The final status (state stopped) leaves just before the plant exits.
    let last = status
        .wait_for(Duration::from_millis(500), |s| {
            s.state == tilting_proto::Status::STOPPED
        })
        .await
        .map(|(_, s)| s)
        .or_else(|| status.latest())
        .expect("a status of the plant");
    ctl.interrupt(Duration::from_secs(10));
    let _ = client.session.close().await;
    (plant.plant_summary(), last)
}

/// The losses among the first `n` draws of `stream` of `seed` for `spec` (the offline
/// emulator's own link).
fn losses(spec: LinkSpec, seed: u64, stream: u64, n: u64) -> u64 {
    let mut l = Link::new(spec, seed, stream);
    (0..n).filter(|_| l.send(0.0).is_none()).count() as u64
}

/// A runtime for the test's zenoh client (the real-time turn is held outside it).
fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("a tokio runtime")
}

#[test]
fn a_delay_on_the_wall_clock_ages_torques_like_the_emulator() {
    let _turn = realtime_turn();
    let (s, st) = runtime().block_on(run("emu_delay", &["--delay", "0.001"]));
    eprintln!("{s:?}");
    assert_eq!(s.result, RunResult::Completed);
    assert_eq!(s.watchdog_trips, 0, "{s:?}");

    // The emulator's age for the same delay, from its own hold.
    let spec = LinkSpec {
        delay: 0.001,
        ..LinkSpec::default()
    };
    let mut hold = Impairment {
        state: spec,
        torque: spec,
        seed: 0,
        max_age: 10,
    }
    .hold(0.001);
    for k in 0..3000u64 {
        hold.step(k, k as f64 * 0.001, || 0.0);
    }
    let hist = &hold.stats().age_histogram;
    let emulated = hist
        .iter()
        .enumerate()
        .max_by_key(|(_, n)| **n)
        .map(|(a, _)| a as f64)
        .unwrap();
    assert_eq!(emulated, 2.0, "{hist:?}");

    let link = s.link.as_ref().expect("the plant emulated the link");
    assert_eq!((link.states_lost, link.torques_lost), (0, 0), "{link:?}");
    assert!(link.states_sent >= 3000, "{link:?}");
    let age = s.age_periods.expect("ages");
    assert!(
        (age.p50 - emulated).abs() <= 1.0,
        "median age {} periods, emulated {emulated}",
        age.p50
    );
    assert!(
        age.p99 <= emulated + 4.0,
        "age p99 {} periods, emulated {emulated}",
        age.p99
    );
    // Hardly anything on time (age 0): only a pacing thread that stalls for more than the
    // 2 ms round trip right after publishing a state (a loaded machine) finds that state's
    // answer in before its next deadline; at most 2 % of the applied torques.
    // Nearly every torque arrives (the link loses none). How many are applied depends on the
    // pacing: on a loaded machine (2,999 deadline misses in a run beside a build) the plant
    // applied 2,263 of 2,998 and skipped 735 sequence numbers (a newer torque was in first), so
    // only a floor that load does not break is asserted on the applied count.
    assert!(s.torques_received > 2500, "{s:?}");
    assert!(s.torques_applied * 2 > s.torques_received, "{s:?}");
    let on_time = s.torques_applied - s.torques_late;
    assert!(
        on_time * 50 <= s.torques_applied,
        "{on_time} on time: {s:?}"
    );
    // The status says the same as the summary.
    assert_eq!(st.state, tilting_proto::Status::STOPPED, "{st:?}");
    assert_eq!((st.age_p50, st.age_p99), (age.p50, age.p99), "{st:?}");
    assert!(s.tilts >= 5, "the orbit goes on: {} tilts", s.tilts);
}

#[test]
fn losses_on_the_wall_clock_are_the_emulators_draws() {
    let _turn = realtime_turn();
    let seed = 7;
    let (s, st) = runtime().block_on(run(
        "emu_loss",
        &["--loss", "0.1", "--seed", &seed.to_string()],
    ));
    eprintln!("{s:?}");
    assert_eq!(s.result, RunResult::Completed);
    assert_eq!(s.watchdog_trips, 0, "{s:?}");
    let link = s.link.as_ref().expect("the plant emulated the link");
    let spec = LinkSpec {
        loss: 0.1,
        ..LinkSpec::default()
    };
    assert_eq!(link.state, spec);
    assert_eq!(
        link.states_lost,
        losses(spec, seed, 0, link.states_sent),
        "{link:?}"
    );
    assert_eq!(
        link.torques_lost,
        losses(spec, seed, 1, link.torques_sent),
        "{link:?}"
    );
    for (lost, n) in [
        (link.states_lost, link.states_sent),
        (link.torques_lost, link.torques_sent),
    ] {
        assert!(n > 2500, "{link:?}");
        let sigma = (0.1 * 0.9 / n as f64).sqrt();
        let frac = lost as f64 / n as f64;
        assert!(
            (frac - 0.1).abs() <= 4.5 * sigma,
            "{lost} of {n} lost: {frac:.4}, expected 0.1 +- {:.4}",
            4.5 * sigma
        );
    }
    // A lost state is never answered and a lost torque never applied: each is a state whose
    // answer the plant did not apply (up to the first and last few, outside the counted span).
    assert!(
        s.torques_lost + 3 >= link.states_lost + link.torques_lost,
        "{s:?}"
    );
    assert_eq!(st.torques_lost, s.torques_lost, "{st:?}");
}

#[test]
fn live_refuses_a_bad_impairment_naming_the_flag() {
    let dir = Scratch::new("live_bad_link");
    for (flag, value, needle) in [
        (
            "--delay",
            "-0.001",
            "`--delay` = -0.001: a delay in seconds in [0, 60]",
        ),
        (
            "--torque-loss",
            "1.5",
            "`--torque-loss` = 1.5: a probability in [0, 1]",
        ),
        ("--jitter", "gamma:0.001", "unknown distribution `gamma`"),
    ] {
        let out = std::process::Command::new(bin("tilting"))
            .args(["live", "--duration", "1", "--out"])
            .arg(dir.path().join("run"))
            .args([flag, value])
            .output()
            .expect("run tilting live");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(err.contains(needle), "{flag} {value}: {err}");
        assert!(
            !dir.path().join("run").join("plant.log").exists(),
            "no plant was started"
        );
    }
}
