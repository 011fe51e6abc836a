//! The watchdog: a controller that stops answering (SIGSTOP: still connected, token alive)
//! puts the plant in safe mode after `--watchdog` periods; a killed controller (SIGKILL: its
//! liveliness token disappears) does so at once; the answers coming back end the safe mode.

use std::time::{Duration, Instant};
use tilting_proto::Status;
use tilting_tests::*;

/// Periods without a valid torque before the safe mode (1 kHz: 50 ms).
const WATCHDOG: u64 = 50;
/// Slack for a loaded 2-core machine on top of the watchdog bound.
const MARGIN: Duration = Duration::from_millis(400);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn controller_loss_trips_safe_mode_and_its_return_resumes_the_loop() {
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("watchdog");
    let port = free_port();
    let robot = robot("watchdog");
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(&robot, port, &["--watchdog", &WATCHDOG.to_string()]),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let status = StatusWatch::new(&client).await;
    let ctl_args = peer_args(&robot, port, &[]);
    let ctl = Proc::spawn("controller", &ctl_bin, &ctl_args, dir.path());
    let bound = Duration::from_millis(WATCHDOG) + MARGIN;

    // Running and answered.
    let (_, s) = status
        .wait_for(Duration::from_secs(15), |s| {
            s.state == Status::RUNNING && s.steps > 500
        })
        .await
        .unwrap_or_else(|| panic!("never running\n{}\n{}", plant.logs(), ctl.logs()));
    assert_eq!(s.watchdog_trips, 0);

    // 1. The controller freezes: the token stays, only the watchdog can notice.
    ctl.signal(libc::SIGSTOP);
    let t0 = Instant::now();
    let (t1, s) = status
        .wait_for(bound + Duration::from_secs(2), |s| {
            s.state == Status::SAFE_MODE
        })
        .await
        .unwrap_or_else(|| panic!("no safe mode after SIGSTOP\n{}", plant.logs()));
    let frozen = t1 - t0;
    eprintln!("SIGSTOP -> safe mode status after {frozen:?}");
    assert!(frozen <= bound, "safe mode after {frozen:?} > {bound:?}");
    assert_eq!(s.watchdog_trips, 1);
    assert!(s.deadline_misses >= WATCHDOG);
    tokio::time::sleep(Duration::from_millis(300)).await;
    ctl.signal(libc::SIGCONT);
    let t0 = Instant::now();
    let (t1, _) = status
        .wait_for(Duration::from_secs(10), |s| s.state == Status::RUNNING)
        .await
        .unwrap_or_else(|| panic!("not running after SIGCONT\n{}", plant.logs()));
    eprintln!("SIGCONT -> running status after {:?}", t1 - t0);

    // 2. The controller dies: its token disappears.
    tokio::time::sleep(Duration::from_millis(500)).await;
    ctl.signal(libc::SIGKILL);
    let t0 = Instant::now();
    let (t1, s) = status
        .wait_for(bound + Duration::from_secs(2), |s| {
            s.state == Status::SAFE_MODE
        })
        .await
        .unwrap_or_else(|| panic!("no safe mode after SIGKILL\n{}", plant.logs()));
    let killed = t1 - t0;
    eprintln!("SIGKILL -> safe mode status after {killed:?}");
    assert!(killed <= bound, "safe mode after {killed:?} > {bound:?}");
    assert_eq!(s.watchdog_trips, 2);
    drop(ctl);

    // The plant keeps running in safe mode (holding PD): no fault while the controller is away.
    tokio::time::sleep(Duration::from_secs(1)).await;
    assert!(plant.try_wait().is_none(), "{}", plant.logs());
    let s = status.latest().unwrap();
    assert_eq!(s.state, Status::SAFE_MODE, "{s:?}");

    // 3. A new controller: the loop resumes.
    let mut ctl = Proc::spawn("controller2", &ctl_bin, &ctl_args, dir.path());
    let t0 = Instant::now();
    let (t1, s) = status
        .wait_for(Duration::from_secs(10), |s| s.state == Status::RUNNING)
        .await
        .unwrap_or_else(|| {
            panic!(
                "not running after the restart\n{}\n{}",
                plant.logs(),
                ctl.logs()
            )
        });
    eprintln!("restart -> running status after {:?}", t1 - t0);
    let steps = s.steps;
    // And stays running.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let s = status.latest().unwrap();
    assert_eq!(s.state, Status::RUNNING, "{s:?}");
    assert!(s.steps > steps + 300);
    assert_eq!(s.watchdog_trips, 2);

    let exit = plant.interrupt(Duration::from_secs(10));
    assert!(exit.success(), "{}", plant.logs());
    let summary = plant.plant_summary();
    eprintln!("plant summary: {summary:?}");
    assert_eq!(summary.result, RunResult::Stopped);
    assert!(summary.fault.is_none());
    assert!(ctl.interrupt(Duration::from_secs(10)).success());
}

/// Lockstep with a controller that dies (SIGKILL, token gone) or freezes (SIGSTOP, token kept):
/// the plant enters the safe mode at once (token gone) or after one `--lockstep-timeout-ms`
/// (frozen), then keeps running deterministically under the safe-mode torque, waiting at most
/// 1 ms per period for an answer. A 10 s run therefore ends in about 10 s of wall time or less,
/// not 10,000 timeouts (2.8 h at the default 1 s). Bound asserted: 60 s of wall time after the
/// controller stopped (6x the plant time, for a loaded 2-core machine).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn lockstep_without_a_controller_runs_on_in_safe_mode_and_never_crawls() {
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    for (case, sig) in [("killed", libc::SIGKILL), ("frozen", libc::SIGSTOP)] {
        let dir = Scratch::new(&format!("lockstep-{case}"));
        let port = free_port();
        let robot = robot(&format!("lockstep_{case}"));
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
                    "10",
                    "--lockstep-timeout-ms",
                    "1000",
                ],
            ),
            dir.path(),
        );
        let client = Client::open(&robot, None, Some(port)).await;
        let status = StatusWatch::new(&client).await;
        let ctl = Proc::spawn(
            "controller",
            &ctl_bin,
            &peer_args(&robot, port, &[]),
            dir.path(),
        );
        status
            .wait_for(Duration::from_secs(15), |s| {
                s.state == Status::RUNNING && s.steps > 500
            })
            .await
            .unwrap_or_else(|| panic!("{case}: never running\n{}", plant.logs()));
        let t0 = Instant::now();
        ctl.signal(sig);
        let (t1, s) = status
            .wait_for(Duration::from_secs(5), |s| s.state == Status::SAFE_MODE)
            .await
            .unwrap_or_else(|| panic!("{case}: no safe mode\n{}", plant.logs()));
        eprintln!("{case}: safe mode after {:?} at t = {} s", t1 - t0, s.time);
        let exit = plant.expect_exit(Duration::from_secs(60));
        let wall = t0.elapsed();
        eprintln!("{case}: the 10 s run ended {wall:?} after the controller stopped");
        assert!(exit.success(), "{case}: {}", plant.logs());
        let summary = plant.plant_summary();
        assert_eq!(summary.result, RunResult::Completed, "{case}: {summary:?}");
        assert_eq!(summary.time, 10.0);
        assert_eq!(summary.watchdog_trips, 1, "{case}: {summary:?}");
        assert!(summary.safe_periods > 1000, "{case}: {summary:?}");
        if sig == libc::SIGSTOP {
            ctl.signal(libc::SIGCONT);
        }
    }
}
