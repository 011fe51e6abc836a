//! The watchdog: a controller that stops answering (SIGSTOP: still connected, token alive)
//! puts the plant in safe mode after `--watchdog` periods; a killed controller (SIGKILL: its
//! liveliness token disappears) does so at once; the answers coming back end the safe mode.

use std::time::{Duration, Instant};
use tilting_proto::Status;
use tilting_tests::*;

/// Periods without a valid torque before the safe mode (1 kHz: 50 ms).
const WATCHDOG: u64 = 50;
/// The plant's `--max-age` and `--watchdog` (periods, 1 kHz: 200 ms) in the cut-link test: a
/// reconnect shorter than this must not be a trip, whatever the machine's load.
const RECONNECT_GRACE: u64 = 200;
/// Slack for a loaded 2-core machine on top of the watchdog bound.
const MARGIN: Duration = Duration::from_millis(400);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn controller_loss_trips_safe_mode_and_its_return_resumes_the_loop() {
    let _turn = realtime_turn();
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
/// 1 ms per period for an answer. A 6 s run therefore ends in about 6 s of wall time or less
/// (measured: 0.13 s killed, 20 s frozen for the 7.7 s left of a 10 s run on a loaded machine),
/// not 6,000 timeouts (1.7 h at the default 1 s). Bound asserted: 60 s of wall time after the
/// controller stopped (10x the plant time, for a loaded 2-core machine). The run was 10 s
/// (issue 30's test time): 6 s still leaves the frozen case about 3,500 periods in safe mode
/// (stopped at t = 1.5 to 2.4 s), over the 1,000 asserted, and a crawl still fails by hours.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn lockstep_without_a_controller_runs_on_in_safe_mode_and_never_crawls() {
    /// Plant time of each run (s).
    const DURATION: f64 = 6.0;
    let _turn = realtime_turn();
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
                    &DURATION.to_string(),
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
        eprintln!("{case}: the {DURATION} s run ended {wall:?} after the controller stopped");
        assert!(exit.success(), "{case}: {}", plant.logs());
        let summary = plant.plant_summary();
        assert_eq!(summary.result, RunResult::Completed, "{case}: {summary:?}");
        assert_eq!(summary.time, DURATION);
        assert_eq!(summary.watchdog_trips, 1, "{case}: {summary:?}");
        assert!(summary.safe_periods > 1000, "{case}: {summary:?}");
        if sig == libc::SIGSTOP {
            ctl.signal(libc::SIGCONT);
        }
    }
}

/// "Link renegotiated" is not "peer gone": the controller's zenoh link is cut under it (a TCP
/// proxy closes the connection both ways) while it keeps running. Its transport closes, its
/// liveliness token disappears at the plant, and it reconnects at once. The plant counts the
/// token's loss (`token_losses`) but does not enter the safe mode: the token is back, or torques
/// arrive again, within `max(--max-age, 2)` periods (10 ms at 1 kHz), and the age rule covers
/// the periods without an answer meanwhile. (Before issue 22 the first period without an
/// answer after the token's loss tripped the watchdog.) Then the controller is killed: the
/// token goes for good, no torque comes, and the safe mode follows within the watchdog bound.
///
/// The rule is what is under test, not this machine's reconnect time: on an idle machine the
/// controller is back within 2-5 ms, but a loaded CI machine took about 40 ms per cut (124
/// torques lost over 3 cuts), which at the default 10-period grace is rightly a trip. So the
/// plant runs with a grace (`--max-age`) and a `--watchdog` of [`RECONNECT_GRACE`] periods.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cut_link_that_reconnects_is_not_a_controller_gone() {
    let _turn = realtime_turn();
    let dir = Scratch::new("renegotiated");
    let port = free_port();
    let robot = robot("renegotiated");
    let proxy = tilting_tests::proxy::DelayProxy::start(
        format!("127.0.0.1:{port}").parse().unwrap(),
        Duration::ZERO,
        Duration::ZERO,
    );
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(
            &robot,
            port,
            &[
                "--max-age",
                &RECONNECT_GRACE.to_string(),
                "--watchdog",
                &RECONNECT_GRACE.to_string(),
            ],
        ),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let status = StatusWatch::new(&client).await;
    // Connects through the proxy only, and listens nowhere the plant could reach it directly
    // (no listener, no gossip): every link it has crosses the proxy.
    let cfg = dir.path().join("controller.json5");
    let text = format!(
        r#"{{ mode: "peer", listen: {{ endpoints: [] }},
             connect: {{ endpoints: ["tcp/127.0.0.1:{}"],
                         retry: {{ period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2 }} }},
             scouting: {{ multicast: {{ enabled: false }}, gossip: {{ enabled: false }} }} }}"#,
        proxy.port
    );
    std::fs::write(&cfg, text).unwrap();
    let ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &[
            "--robot".to_string(),
            robot.clone(),
            "--zenoh-config".into(),
            cfg.display().to_string(),
        ],
        dir.path(),
    );
    status
        .wait_for(Duration::from_secs(15), |s| {
            s.state == Status::RUNNING && s.steps > 1000
        })
        .await
        .unwrap_or_else(|| panic!("never running\n{}\n{}", plant.logs(), ctl.logs()));

    // Cut the controller's link three times, 600 ms apart (well past the grace, so each cut is
    // judged on its own).
    let mut cut = 0;
    for _ in 0..3 {
        cut += proxy.cut();
        tokio::time::sleep(Duration::from_millis(600)).await;
    }
    assert!(cut >= 3, "the proxy carried no connection to cut");
    let s = status.latest().unwrap();
    assert_eq!(s.state, Status::RUNNING, "{s:?}\n{}", plant.logs());

    // Now the controller dies for good.
    let t0 = Instant::now();
    ctl.signal(libc::SIGKILL);
    let (t1, s) = status
        .wait_for(
            Duration::from_millis(RECONNECT_GRACE) + MARGIN + Duration::from_secs(2),
            |s| s.state == Status::SAFE_MODE,
        )
        .await
        .unwrap_or_else(|| panic!("no safe mode after SIGKILL\n{}", plant.logs()));
    eprintln!("SIGKILL -> safe mode status after {:?}", t1 - t0);
    assert_eq!(s.watchdog_trips, 1, "{s:?}");
    let exit = plant.interrupt(Duration::from_secs(10));
    assert!(exit.success(), "{}", plant.logs());
    let p = plant.plant_summary();
    eprintln!("plant: {p:?}\n{}", plant.stderr());
    // Three cuts, three losses of the token (the kill is the fourth); one trip, the kill's.
    assert!(p.token_losses >= 4, "{p:?}");
    assert_eq!(p.watchdog_trips, 1, "{p:?}");
}
