//! The way back after a fault (issue 22): a controller with the robust option (`--orbit-peak`)
//! is killed (SIGKILL: the plant enters its safe mode and the safe hold lands the plate), then
//! started again. The robot gets back onto the orbit by itself: the new controller finds the
//! plate at rest, runs the re-entry motion and hands over to the orbit law. Real time, 1 kHz.

use std::time::Duration;
use tilting_proto::Status;
use tilting_sim::closed_loop::{simulate, SimOptions};
use tilting_sim::robustness::Goal;
use tilting_sim::Scenario;
use tilting_tests::*;

/// Plant time of the run (s).
const DURATION: f64 = 16.0;
/// Time from the controller's return to peaks within 10 % of the nominal ones: the target is
/// 5 s (offline from rest: 4.7 s); the bound allows a loaded 2-core machine some missed
/// deadlines.
const BOUND: f64 = 8.0;

/// The nominal last peaks (rad): the plain law on the exact model at 1 kHz, offline.
fn nominal() -> f64 {
    let sc = Scenario {
        control_period: 0.001,
        duration: 60.0,
        ..Scenario::default()
    };
    let r = simulate(&sc, SimOptions::default()).unwrap();
    Goal::of(&r, 0, 1.0, f64::INFINITY).last_peak
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn after_a_controller_restart_the_robot_gets_back_onto_the_orbit() {
    let _turn = realtime_turn();
    let nominal = nominal();
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("reentry");
    let port = free_port();
    let robot = robot("reentry");
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(&robot, port, &["--duration", &DURATION.to_string()]),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let status = StatusWatch::new(&client).await;
    let peak = format!("--orbit-peak={nominal}");
    let ctl_args = peer_args(&robot, port, &[&peak]);
    let ctl = Proc::spawn("controller", &ctl_bin, &ctl_args, dir.path());
    status
        .wait_for(Duration::from_secs(20), |s| {
            s.state == Status::RUNNING && s.tilts >= 4
        })
        .await
        .unwrap_or_else(|| panic!("never tilting\n{}\n{}", plant.logs(), ctl.logs()));

    // The controller dies: safe mode, and the safe hold lands the plate.
    ctl.signal(libc::SIGKILL);
    drop(ctl);
    status
        .wait_for(Duration::from_secs(10), |s| {
            s.state == Status::SAFE_MODE && s.mode == 0
        })
        .await
        .unwrap_or_else(|| panic!("the plate never landed in safe mode\n{}", plant.logs()));
    tokio::time::sleep(Duration::from_millis(500)).await;
    let before = status.latest().unwrap();
    assert_eq!(
        (before.state, before.mode),
        (Status::SAFE_MODE, 0),
        "{before:?}"
    );

    // It returns.
    let mut ctl = Proc::spawn("controller2", &ctl_bin, &ctl_args, dir.path());
    let (_, back) = status
        .wait_for(Duration::from_secs(10), |s| s.state == Status::RUNNING)
        .await
        .unwrap_or_else(|| panic!("not running after the restart\n{}", plant.logs()));
    let t_back = back.time;
    assert!(
        t_back + BOUND < DURATION,
        "the restart came late in the run: t = {t_back} s\n{}",
        plant.logs()
    );

    let exit = plant.expect_exit(Duration::from_secs(60));
    assert!(exit.success(), "{}", plant.logs());
    let summary = plant.plant_summary();
    assert!(summary.fault.is_none(), "{summary:?}");
    let after: Vec<[f64; 2]> = summary
        .tilt_peaks
        .iter()
        .copied()
        .filter(|p| p[0] > t_back)
        .collect();
    assert!(
        after.len() >= 8,
        "{} peaks after the return: {after:?}",
        after.len()
    );
    // From the first peak after which every peak is within 10 % of the nominal ones, and the
    // tilts alternate.
    let within = |p: &[f64; 2]| (p[1].abs() / nominal - 1.0).abs() <= 0.10;
    let settled = after.iter().rposition(|p| !within(p)).map_or(0, |i| i + 1);
    assert!(settled < after.len(), "never within 10 %: {after:?}");
    let t = after[settled][0] - t_back;
    eprintln!(
        "controller back at t = {t_back:.3} s; first peak after {:.3} s; peaks within 10 % of \
         {nominal:.5} rad after {t:.3} s",
        after[0][0] - t_back
    );
    assert!(t < BOUND, "{t} s: {after:?}");
    assert!(
        after
            .windows(2)
            .all(|w| w[0][1].signum() != w[1][1].signum()),
        "{after:?}"
    );
    let c = ctl.interrupt(Duration::from_secs(10));
    assert!(c.success(), "{}", ctl.logs());
    let robust = ctl
        .controller_summary()
        .robust
        .expect("the robust option's report");
    assert_eq!(robust.reentries, 1, "{robust:?}");
}
