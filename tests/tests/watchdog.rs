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
