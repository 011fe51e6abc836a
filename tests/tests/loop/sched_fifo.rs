//! `tilting live --realtime P`: the plant and the controller run under `SCHED_FIFO` at P, every
//! thread of both (zenoh's included), while `live` itself stays a normal process; a user who may
//! not use `SCHED_FIFO` gets a clear error before anything starts.
//!
//! Read from `/proc/PID/task/TID/stat` (fields 40 `rt_priority` and 41 `policy`, proc(5)) while
//! the run is under way. The first test needs the right to use `SCHED_FIFO` (root here); the
//! second runs `live` as `nobody` with util-linux's `setpriv`. Without them they print `SKIP`.

use std::process::Command;
use std::time::Duration;
use tilting_tests::*;

/// `(policy, rt_priority)` of every thread of process `pid`.
fn thread_policies(pid: i32) -> Vec<(u32, u32)> {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    tasks
        .filter_map(|t| {
            let stat = std::fs::read_to_string(t.ok()?.path().join("stat")).ok()?;
            // The command name (field 2) is in parentheses and may hold spaces: count from
            // after its closing one, where field 3 starts.
            let rest = &stat[stat.rfind(')')? + 2..];
            let f: Vec<&str> = rest.split_whitespace().collect();
            Some((f.get(41 - 3)?.parse().ok()?, f.get(40 - 3)?.parse().ok()?))
        })
        .collect()
}

const SCHED_OTHER: u32 = 0;
const SCHED_FIFO: u32 = 1;

#[test]
fn realtime_runs_every_thread_of_the_plant_and_the_controller_fifo() {
    if let Err(e) = tilting::supervise::check_fifo(7) {
        let why = e.to_string();
        skip(
            "realtime_runs_every_thread_of_the_plant_and_the_controller_fifo",
            Missing::Right,
            &why,
        );
        return;
    }
    let _turn = realtime_turn();
    let dir = Scratch::new("fifo");
    let out = dir.path().join("out");
    // Once the loop tilts, zenoh's threads in both nodes have all started.
    let mut live = start_live(&dir, &out, "fifo", &["--duration", "4", "--realtime", "7"]);
    let mut seen = Vec::new();
    for node in ["tilting-plant", "tilting-controller"] {
        let pid = child_named(live.pid() as u32, node)
            .unwrap_or_else(|| panic!("no {node} under live\n{}", live.logs()));
        let threads = thread_policies(pid);
        // The pacing thread, the main thread and zenoh's runtime threads at least.
        assert!(threads.len() >= 3, "{node}: {threads:?}");
        assert!(
            threads.iter().all(|&t| t == (SCHED_FIFO, 7)),
            "{node}: every thread SCHED_FIFO 7: {threads:?}"
        );
        seen.push((node, threads.len()));
    }
    let own = thread_policies(live.pid());
    assert!(
        own.iter().all(|&(policy, _)| policy == SCHED_OTHER),
        "live itself stays SCHED_OTHER: {own:?}"
    );
    eprintln!(
        "threads under SCHED_FIFO 7: {seen:?}; live's own {}",
        own.len()
    );
    let status = live.expect_exit(Duration::from_secs(40));
    assert!(status.success(), "{status}\n{}", live.logs());
    assert!(live.stderr().contains("SCHED_FIFO 7"), "{}", live.logs());
    assert_eq!(live_summary(&out).realtime, Some(7));
}

#[test]
fn realtime_without_the_right_is_refused_before_anything_starts() {
    // SAFETY: geteuid(2) has no preconditions.
    if unsafe { libc::geteuid() } != 0 || Command::new("setpriv").arg("--version").output().is_err()
    {
        skip(
            "realtime_without_the_right_is_refused_before_anything_starts",
            Missing::Right,
            "needs root and setpriv",
        );
        return;
    }
    let dir = Scratch::new("fifo-refused");
    let out = dir.path().join("out");
    let as_nobody = || {
        let mut c = Command::new("setpriv");
        c.args(["--reuid=65534", "--regid=65534", "--clear-groups"])
            .arg(bin("tilting"));
        c
    };
    // Whether `nobody` can run the binary at all (a clone under /root, or a container without
    // the right to change uid, cannot): then there is nothing to test here.
    let probe = as_nobody().arg("--version").output().expect("run setpriv");
    if !probe.status.success() {
        let why = String::from_utf8_lossy(&probe.stderr).into_owned();
        skip(
            "realtime_without_the_right_is_refused_before_anything_starts",
            Missing::Right,
            &why,
        );
        return;
    }
    let run = as_nobody()
        .args(["live", "--realtime", "--duration", "1", "--out"])
        .arg(&out)
        .output()
        .expect("run setpriv");
    let err = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{err}");
    for said in [
        "--realtime",
        "SCHED_FIFO at priority 20",
        "not permitted",
        "ulimit -r 20",
    ] {
        assert!(err.contains(said), "{said:?} in {err}");
    }
    assert!(!out.exists(), "nothing started: {}", out.display());
}
