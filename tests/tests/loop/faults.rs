//! Faults of a running `tilting live` and what the user sees (issue 22, README "Faults"):
//!
//! - a 300 ms SIGSTOP of the controller trips the plant's watchdog once; the robot keeps
//!   tilting, so the orbit holds and `live` exits 0, with the safe-mode stay (start, duration,
//!   cause) reported beside the verdict;
//! - a link delay the loop cannot carry ends in a fault (exit code 3) or a lost orbit (exit
//!   code 4), as the summary says;
//! - the output on a full filesystem (a 256 kB tmpfs; root only): the alarm names ENOSPC and
//!   the file within 1 s of the disk filling, the loop goes on, the report is printed and the
//!   summary written to the fallback path, and no node panics: the plant's and the
//!   controller's own summaries go to their fallback files, named to the user;
//! - SIGKILL of the router of `--secure`: the alarm within 1 s;
//! - SIGSTOP of the plant: the silence alarm within 1 s;
//! - SIGSTOP of the controller beyond zenoh's lease: the token alarm, and the run goes on;
//! - a fault of the model (the plate loses contact) ends the plant's run cleanly: the status
//!   says `faulted` with the reason, the summary too, and the exit code is 3.
//!
//! Each test prints the figure it measured.

use std::path::Path;
use std::time::{Duration, Instant};
use tilting_live::summary::{LiveSummary, OrbitState};
use tilting_proto::{codec, PlantState, Status, TorqueCommand};
use tilting_tests::*;

fn summary_at(path: &Path) -> LiveSummary {
    let text = std::fs::read_to_string(path).expect("the summary");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}\n{text}", path.display()))
}

fn signal(pid: i32, sig: i32) {
    // SAFETY: kill(2) on a pid read from our child's children list.
    unsafe { libc::kill(pid, sig) };
}

#[test]
fn a_short_stall_of_the_controller_is_a_safe_mode_stay_not_a_lost_orbit() {
    let _turn = realtime_turn();
    let dir = Scratch::new("stall");
    let out = dir.path().join("out");
    let mut live = start_live(&dir, &out, "stall", &["--duration", "8"]);
    std::thread::sleep(Duration::from_millis(2500));
    let ctl = child_named(live.pid() as u32, "tilting-controller").expect("the controller");
    signal(ctl, libc::SIGSTOP);
    std::thread::sleep(Duration::from_millis(300));
    signal(ctl, libc::SIGCONT);
    let status = live.expect_exit(Duration::from_secs(60));
    let (stdout, stderr) = (live.stdout(), live.stderr());
    let s = summary_at(&out.join("summary.json"));
    let plant = s.plant.as_ref().expect("the plant's summary");
    eprintln!(
        "stall: exit {:?}, safe modes {:?}, orbit {:?}",
        status.code(),
        plant.safe_modes,
        s.orbit
    );
    assert_eq!(plant.watchdog_trips, 1, "{stderr}");
    let e = &plant.safe_modes[0];
    let stay = e.end.expect("left the safe mode") - e.start;
    // The watchdog trips after --watchdog periods (50 ms at 1 kHz) of the 300 ms stall and
    // the stay ends with the first answer after SIGCONT: about 0.25 s, longer when this
    // test's own 300 ms sleep overshoots on a loaded machine (hence the 2 s upper bound: the
    // claim is that the stay ends, not how fast the machine is).
    assert!((0.1..2.0).contains(&stay), "{stay} s");
    assert!(e.cause.contains("no valid torque"), "{}", e.cause);
    assert_eq!(
        s.orbit.as_ref().unwrap().state,
        OrbitState::Holds,
        "{stdout}"
    );
    assert!(stdout.contains("safe mode: 1 entry"), "{stdout}");
    assert_eq!(status.code(), Some(0), "{stderr}");
}

#[test]
fn a_delay_the_loop_cannot_carry_exits_non_zero_as_the_summary_says() {
    let _turn = realtime_turn();
    let dir = Scratch::new("toolate");
    let out = dir.path().join("out");
    let mut live = start_live(
        &dir,
        &out,
        "toolate",
        &["--duration", "10", "--delay", "0.012", "--max-age", "30"],
    );
    let status = live.expect_exit(Duration::from_secs(60));
    let s = summary_at(&out.join("summary.json"));
    let fault = s.plant.as_ref().and_then(|p| p.fault.clone());
    let orbit = s.orbit.as_ref().expect("a verdict");
    eprintln!(
        "12 ms delay: exit {:?}, fault {fault:?}, orbit {orbit:?}",
        status.code()
    );
    match fault {
        Some(_) => assert_eq!(status.code(), Some(3), "{}", live.stderr()),
        None => {
            assert_eq!(orbit.state, OrbitState::Lost, "{orbit:?}");
            assert_eq!(status.code(), Some(4), "{}", live.stderr());
        }
    }
}

/// `tmpfs` of `size` mounted at `at`, or `None` when this process may not mount (not root).
fn tmpfs(at: &Path, size: &str) -> Option<()> {
    std::fs::create_dir_all(at).ok()?;
    let ok = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
        .arg(at)
        .status()
        .ok()?
        .success();
    ok.then_some(())
}

/// Free bytes on the filesystem of `p` (statvfs(3)).
fn free_bytes(p: &Path) -> u64 {
    let c = std::ffi::CString::new(p.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: statvfs on a NUL-terminated path into a zeroed struct.
    unsafe {
        let mut v: libc::statvfs = std::mem::zeroed();
        if libc::statvfs(c.as_ptr(), &mut v) != 0 {
            return u64::MAX;
        }
        v.f_bavail * v.f_bsize
    }
}

#[test]
fn a_full_disk_is_said_at_once_and_the_report_survives() {
    let _turn = realtime_turn();
    let dir = Scratch::new("full");
    let mnt = dir.path().join("disk");
    if tmpfs(&mnt, "256k").is_none() {
        eprintln!("skipped: cannot mount a tmpfs (not root)");
        return;
    }
    struct Unmount<'a>(&'a Path);
    impl Drop for Unmount<'_> {
        fn drop(&mut self) {
            let _ = std::process::Command::new("umount").arg(self.0).status();
        }
    }
    let _unmount = Unmount(&mnt);
    let out = mnt.join("run");
    // 4 s (it was 12; issue 30's test time): the 256 kB disk fills 0.1 s after the start
    // (measured), so the loop still runs most of its time on a full disk and must reach its end.
    let mut live = start_live(&dir, &out, "full", &["--duration", "4", "--csv"]);
    // When the disk fills (less than one 4 kB block free) and when the alarm is on stderr.
    let (mut full, mut said) = (None, None);
    let t0 = Instant::now();
    while live.try_wait().is_none() && t0.elapsed() < Duration::from_secs(40) {
        if full.is_none() && free_bytes(&mnt) < 4096 {
            full = Some(Instant::now());
        }
        if said.is_none() && live.stderr().contains("ALARM: RECORDING FAILED") {
            said = Some(Instant::now());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let status = live.expect_exit(Duration::from_secs(60));
    let (stdout, stderr) = (live.stdout(), live.stderr());
    let (full, said) = (full.expect("the disk filled"), said.expect("an alarm"));
    let delay = said.saturating_duration_since(full).as_secs_f64();
    eprintln!(
        "full disk: filled {:.3} s after the start, alarm {delay:.3} s later; exit {status}",
        full.saturating_duration_since(t0).as_secs_f64()
    );
    assert!(delay < 1.0, "{delay} s\n{stderr}");
    let alarm = stderr
        .lines()
        .find(|l| l.contains("ALARM: RECORDING FAILED"))
        .unwrap();
    assert!(
        alarm.contains("ENOSPC") && alarm.contains(&*out.display().to_string()),
        "{alarm}"
    );
    // The loop went on to its end; the report is on stdout, the summary in the fallback.
    assert!(
        stdout.contains("live run failed: 4 s planned"),
        "{stdout}\n{stderr}"
    );
    assert!(stdout.contains("orbit: holds"), "{stdout}");
    let fallback = std::env::temp_dir().join("tilting-live-run-summary.json");
    let s = summary_at(&fallback);
    let _ = std::fs::remove_file(&fallback);
    // The nodes did not panic on their full stdout: both exited cleanly.
    assert_eq!(s.plant_exit, "exit status: 0", "{stderr}");
    assert_eq!(
        s.controller_exit.as_deref(),
        Some("exit status: 0"),
        "{stderr}"
    );
    assert!(
        s.problems.iter().any(|p| p.contains("ENOSPC")),
        "{:?}",
        s.problems
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(status.code(), Some(1));
    // The nodes' own summaries, whose stdout was on the full disk, went to their fallback
    // files, said in the problems (and on stderr), and are in the live summary: the plant ran
    // its 4 s, the controller answered.
    let fallbacks: Vec<std::path::PathBuf> = ["tilting-plant-", "tilting-controller-"]
        .iter()
        .map(|node| {
            let p = s
                .problems
                .iter()
                .find(|p| p.contains("could not print its summary") && p.contains(node))
                .unwrap_or_else(|| panic!("no fallback of {node}: {:?}", s.problems));
            std::path::PathBuf::from(p.rsplit("it is in ").next().unwrap())
        })
        .collect();
    for f in &fallbacks {
        assert!(f.is_file(), "{}", f.display());
        assert!(stderr.contains(&*f.display().to_string()), "{stderr}");
        let _ = std::fs::remove_file(f);
    }
    let plant = s
        .plant
        .as_ref()
        .expect("the plant's summary, from its fallback");
    assert!((plant.time - 4.0).abs() < 0.01, "{}", plant.time);
    let ctl = s.controller.as_ref().expect("the controller's summary");
    assert!(ctl.torques_published > 1000, "{ctl:?}");
}

#[test]
fn a_killed_router_is_said_within_a_second() {
    let _turn = realtime_turn();
    let dir = Scratch::new("router");
    let out = dir.path().join("out");
    // 5 s (it was 8; issue 30's test time): the kill comes at about 3 s, the alarm is asserted
    // within 1 s of it, and the run still ends after that, by itself, not with exit code 0.
    let mut live = start_live(&dir, &out, "router", &["--duration", "5", "--secure"]);
    std::thread::sleep(Duration::from_millis(2000));
    let router = child_named(live.pid() as u32, "tilting-router").expect("the router");
    signal(router, libc::SIGKILL);
    let killed = Instant::now();
    let said = loop {
        if live.stderr().contains("ALARM: ROUTER EXITED") {
            break killed.elapsed().as_secs_f64();
        }
        assert!(
            killed.elapsed() < Duration::from_secs(5),
            "{}",
            live.stderr()
        );
        std::thread::sleep(Duration::from_millis(10));
    };
    let status = live.expect_exit(Duration::from_secs(60));
    eprintln!("router killed: alarm after {said:.3} s; exit {status}");
    assert!(said < 1.0, "{said} s");
    assert_ne!(status.code(), Some(0));
}

/// A plant that stops publishing while its process lives (SIGSTOP: its liveliness token stays)
/// is said by the silence alarm: no state for [`STATE_SILENCE`] s, seen at the next of the
/// monitor's 200 ms ticks, so within about 0.7 s (asserted: 1.5 s, for a loaded machine).
/// After SIGCONT the run goes on to its end and `live` reports it. A 5 s run (it was 8; issue
/// 30's test time): stopped at about 2.5 s, the plant cannot reach its end before the alarm
/// (asserted within 1.5 s of the stop), and the run after SIGCONT is still checked.
#[test]
fn a_silent_plant_is_said_within_a_second() {
    const STATE_SILENCE: f64 = 0.5;
    let _turn = realtime_turn();
    let dir = Scratch::new("silent");
    let out = dir.path().join("out");
    let mut live = start_live(&dir, &out, "silent", &["--duration", "5"]);
    std::thread::sleep(Duration::from_millis(1500));
    let plant = child_named(live.pid() as u32, "tilting-plant").expect("the plant");
    signal(plant, libc::SIGSTOP);
    let stopped = Instant::now();
    let said = loop {
        if live.stderr().contains("ALARM: no state from the plant") {
            break stopped.elapsed().as_secs_f64();
        }
        if stopped.elapsed() > Duration::from_secs(5) {
            signal(plant, libc::SIGCONT);
            panic!("no silence alarm\n{}", live.stderr());
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    signal(plant, libc::SIGCONT);
    let status = live.expect_exit(Duration::from_secs(60));
    eprintln!("plant stopped: alarm after {said:.3} s; exit {status}");
    assert!(
        said >= STATE_SILENCE,
        "an alarm before the silence: {said} s"
    );
    assert!(said < 1.5, "{said} s");
    // The run ended by itself and reported: completed (0), faulted (3) or orbit lost (4),
    // whatever the verdict after a 0.5+ s stall; never a failure of `live` itself (1).
    assert!(
        matches!(status.code(), Some(0 | 3 | 4)),
        "{status}\n{}",
        live.logs()
    );
    assert!(out.join("summary.json").exists());
}

/// A controller that stops answering while its process lives (SIGSTOP), for longer than
/// zenoh's lease (10 s by default: its peers then close its transport and its liveliness token
/// goes away), is said by the token alarm, on its own line, at the next of the monitor's
/// 200 ms ticks after the loss: "controller link LOST". After SIGCONT the controller's session
/// reconnects, the plant leaves the safe mode and the run goes on to its end.
///
/// Only generous bounds on time: the alarm within 20 s of the stop (twice the lease: measured
/// 10.06 s), before the run's end, and the run's end within 60 s of its planned length. The
/// run is 25 s (it was 40 s; issue 30's test time): stopped at about 1 s, alarmed at about 11 s,
/// it still has 14 s after SIGCONT to reconnect and leave the safe mode (the assertions below:
/// the safe mode ended, the plant ran to its end), and a lost alarm or a reconnection that never
/// comes fails as before.
#[test]
fn a_lost_controller_token_is_said_and_the_run_goes_on() {
    let _turn = realtime_turn();
    let dir = Scratch::new("token");
    let out = dir.path().join("out");
    let duration = 25.0;
    let mut live = start_live(&dir, &out, "token", &["--duration", &duration.to_string()]);
    std::thread::sleep(Duration::from_millis(1000));
    let ctl = child_named(live.pid() as u32, "tilting-controller").expect("the controller");
    signal(ctl, libc::SIGSTOP);
    let stopped = Instant::now();
    let said = loop {
        if let Some(l) = live
            .stderr()
            .lines()
            .find(|l| l.contains("ALARM") && l.contains("controller link LOST"))
        {
            break (stopped.elapsed().as_secs_f64(), l.to_owned());
        }
        if stopped.elapsed() > Duration::from_secs(20) || live.try_wait().is_some() {
            signal(ctl, libc::SIGCONT);
            panic!("no token alarm\n{}", live.stderr());
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    signal(ctl, libc::SIGCONT);
    let resumed = stopped.elapsed().as_secs_f64();
    let status = live.expect_exit(Duration::from_secs_f64(duration + 60.0));
    let stderr = live.stderr();
    eprintln!(
        "controller stopped: token alarm after {:.3} s ({}), resumed at {resumed:.3} s; exit {status}",
        said.0, said.1
    );
    assert!(
        said.1.contains("its liveliness token is gone"),
        "{}",
        said.1
    );
    // The run went on to its planned end and reported: completed (0), orbit lost (4) or a
    // fault (3) after the long safe hold; never a failure of `live` itself (1).
    assert!(
        matches!(status.code(), Some(0 | 3 | 4)),
        "{status}\n{}",
        live.logs()
    );
    let s = summary_at(&out.join("summary.json"));
    let plant = s.plant.as_ref().expect("the plant's summary");
    assert_eq!(
        s.controller_exit.as_deref(),
        Some("exit status: 0"),
        "{stderr}"
    );
    if plant.fault.is_none() {
        assert!(
            (plant.time - duration).abs() < 0.01,
            "the plant ran to its end: {} s",
            plant.time
        );
    }
    // The stop tripped the watchdog, and the controller's return ended the safe mode.
    let first = plant.safe_modes.first().expect("a safe-mode stay");
    eprintln!("safe modes: {:?}", plant.safe_modes);
    assert!(first.end.is_some(), "{:?}", plant.safe_modes);
    assert!(plant.token_losses >= 1, "{plant:?}");
}

/// A fault of the model ends the run cleanly: the status says `faulted` with the reason, the
/// summary too, and the exit code is 3.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_fault_is_published_and_ends_the_run_with_exit_code_3() {
    let _turn = realtime_turn();
    let plant_bin = bin("tilting-plant");
    let dir = Scratch::new("fault");
    let port = free_port();
    let robot = robot("fault");
    // Tilted far over with the arm low and no torque in safe mode: the plate loses contact.
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(
            &robot,
            port,
            &[
                "--safe-mode",
                "zero",
                "--mode",
                "left",
                "--x0",
                "0.3,1.2,0,0",
            ],
        ),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let status = StatusWatch::new(&client).await;
    // The test is a controller without a liveliness token: it answers state 0 once, which
    // starts the plant's clock, and then falls silent.
    let torque = client
        .session
        .declare_publisher(client.keys.controller_torque().to_owned())
        .await
        .unwrap();
    let states = client
        .session
        .declare_subscriber(client.keys.plant_state().to_owned())
        .await
        .unwrap();
    let s0 = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let s = states.recv_async().await.unwrap();
            if let Ok(s) = tilting_proto::decode::<PlantState>(&s.payload().to_bytes()) {
                break s;
            }
        }
    })
    .await
    .expect("no state 0");
    assert_eq!(s0.seq, 0);
    torque
        .put(codec::encode(&TorqueCommand { seq: 0, tau: 0.0 }))
        .await
        .unwrap();

    let (_, s) = status
        .wait_for(Duration::from_secs(10), |s| s.state == Status::FAULTED)
        .await
        .unwrap_or_else(|| panic!("no faulted status\n{}", plant.logs()));
    assert!(s.fault.contains("contact loss"), "{s:?}");
    assert_eq!(s.watchdog_trips, 1);
    let exit = plant.expect_exit(Duration::from_secs(10));
    assert_eq!(exit.code(), Some(3), "{}", plant.logs());
    let summary = plant.plant_summary();
    assert_eq!(summary.result, RunResult::Faulted);
    assert!(summary.fault.as_deref().unwrap().contains("contact loss"));
}
