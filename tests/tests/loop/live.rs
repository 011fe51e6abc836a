//! Runs the built `tilting live` (and the planner node) with the real node binaries:
//!
//! - `live --duration 5 --csv --out DIR` exits 0 and writes the three CSV files with plausible
//!   content (about 5000 states, alternating left/right tilts, finite numbers), run.mcap with
//!   the same messages, the PNG and the summary;
//! - after SIGKILL of `live`, CSV files hold whole rows and run.mcap reads up to its last chunk;
//! - a controller killed during a `live` run is reported (which one, how), the plant is stopped,
//!   the recording is kept, and `live` exits with code 1;
//! - a controller started after the planner node gets the published law from its queryable;
//! - `live` without the node binaries next to it fails with a message that says how to build
//!   them;
//! - the old `tilting-planner live|simulate|...` names still work and say where the command
//!   went.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};
use tilting_live::summary::LiveResult;
use tilting_proto::{ModeEvent, PlantState, Topic, TorqueCommand};
use tilting_tests::*;

fn csv(path: &Path) -> (String, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    let mut lines = text.lines();
    let header = lines.next().expect("a header").to_owned();
    let n = header.split(',').count();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            let v: Vec<f64> = l
                .split(',')
                .map(|x| {
                    x.parse::<f64>()
                        .unwrap_or_else(|e| panic!("{}: `{x}` in `{l}`: {e}", path.display()))
                })
                .collect();
            assert_eq!(v.len(), n, "{}: `{l}`", path.display());
            assert!(v.iter().all(|x| x.is_finite()), "{}: `{l}`", path.display());
            v
        })
        .collect();
    (header, rows)
}

#[test]
fn live_runs_the_orbit_for_5_s_and_records_it() {
    let tilting = bin("tilting");
    let _turn = realtime_turn();
    let dir = Scratch::new("run");
    let out = dir.path().join("out");
    let robot = robot("live");
    let o = Command::new(tilting)
        .args([
            "live",
            "--duration",
            "5",
            "--csv",
            "--robot",
            &robot,
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("cannot run tilting live");
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    let logs = || {
        let mut s = format!("--- stdout ---\n{stdout}\n--- stderr ---\n{stderr}");
        for f in ["plant.log", "controller.log"] {
            let t = std::fs::read_to_string(out.join(f)).unwrap_or_default();
            s.push_str(&format!("\n--- {f} ---\n{t}"));
        }
        s
    };
    assert!(o.status.success(), "live failed: {}\n{}", o.status, logs());
    eprintln!("{stdout}");
    assert!(stdout.contains("live run completed"), "{}", logs());
    assert!(stdout.contains("loop latency"), "{}", logs());
    assert!(stderr.contains("latency p50"), "no status line\n{}", logs());

    // state.csv: seq 0..=5000, time k ms, on the orbit.
    let (header, states) = csv(&out.join("state.csv"));
    assert_eq!(header, "seq,t,mode,alpha,beta,alpha_dot,beta_dot");
    assert!(
        (4500..=5500).contains(&states.len()),
        "{} state rows",
        states.len()
    );
    for w in states.windows(2) {
        assert!(w[1][0] > w[0][0] && w[1][1] > w[0][1], "{w:?}");
    }
    let last = states.last().unwrap();
    assert!((last[1] - 5.0).abs() < 1e-9, "last t = {}", last[1]);
    for r in &states {
        assert!((0.0..=2.0).contains(&r[2]), "mode {r:?}");
        assert!(r[3].abs() < 0.1, "|alpha| stays small on the orbit: {r:?}");
        assert!(
            (r[4] - std::f64::consts::FRAC_PI_2).abs() < 0.5,
            "beta {r:?}"
        );
    }

    // torque.csv: one answer per state.
    let (header, torques) = csv(&out.join("torque.csv"));
    assert_eq!(header, "seq,tau");
    assert!(
        torques.len() + 10 >= states.len() && torques.len() <= states.len(),
        "{} torques for {} states",
        torques.len(),
        states.len()
    );

    // events.csv: landings and tilt starts; the tilts alternate left/right.
    let (header, events) = csv(&out.join("events.csv"));
    assert!(header.starts_with("t,from,to,alpha_before"), "{header}");
    let tilts: Vec<u8> = events
        .iter()
        .filter(|e| e[1] == 0.0 && e[2] != 0.0)
        .map(|e| e[2] as u8)
        .collect();
    assert!(
        (9..=13).contains(&tilts.len()),
        "about 11 tilts in 5 s (the first one starts before t = 0 and has no event): {tilts:?}"
    );
    for w in tilts.windows(2) {
        assert_ne!(w[0], w[1], "tilts alternate: {tilts:?}");
    }
    let landings = events.iter().filter(|e| e[1] != 0.0 && e[2] == 0.0).count();
    assert!(landings.abs_diff(tilts.len()) <= 1, "{events:?}");

    // run.mcap, closed normally, holds the same messages as the CSV files, number for number
    // (both written from the same decoded messages; the MCAP side goes through JSON and back),
    // plus the plant's status (10 Hz) and the planner's reference.
    let run = tilting_record::read(&out.join("run.mcap")).expect("run.mcap opens");
    assert!(run.complete(), "{:?}", run.truncation());
    assert_eq!(run.count(Topic::State), states.len() as u64);
    assert_eq!(run.count(Topic::Torque), torques.len() as u64);
    assert_eq!(run.count(Topic::Event), events.len() as u64);
    assert!(
        run.count(Topic::Status) >= 40,
        "{} status",
        run.count(Topic::Status)
    );
    assert!(run.count(Topic::Reference) >= 1);
    let (mut si, mut ti, mut ei) = (0, 0, 0);
    for e in run.messages() {
        match e.topic {
            Topic::State => {
                let s: PlantState = tilting_proto::decode(&e.wire).unwrap();
                let r = &states[si];
                let row = [
                    s.seq as f64,
                    s.time,
                    f64::from(s.mode),
                    s.alpha,
                    s.beta,
                    s.alpha_dot.expect("live measures the rates"),
                    s.beta_dot.expect("live measures the rates"),
                ];
                assert_eq!(&row[..], &r[..], "state {si}");
                si += 1;
            }
            Topic::Torque => {
                let c: TorqueCommand = tilting_proto::decode(&e.wire).unwrap();
                assert_eq!([c.seq as f64, c.tau], [torques[ti][0], torques[ti][1]]);
                ti += 1;
            }
            Topic::Event => {
                let v: ModeEvent = tilting_proto::decode(&e.wire).unwrap();
                assert_eq!(v.time, events[ei][0]);
                assert_eq!(v.x_after[3], events[ei][10]);
                ei += 1;
            }
            _ => {}
        }
    }
    assert_eq!((si, ti, ei), (states.len(), torques.len(), events.len()));
    assert_eq!(run.tilts(), tilts.len() as u64);

    // The figure and the summary.
    let png = std::fs::read(out.join("run.png")).expect("run.png");
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    assert!(png.len() > 20_000, "run.png is {} bytes", png.len());
    // The animation of the last seconds: a GIF of 480 x 360 px (logical screen, little-endian).
    let gif = std::fs::read(out.join("run.gif")).expect("run.gif");
    assert!(gif.starts_with(b"GIF89a"), "not a GIF");
    assert_eq!(&gif[6..10], &[224, 1, 104, 1], "480 x 360 px");
    assert!(gif.len() > 50_000, "run.gif is {} bytes", gif.len());
    let summary = live_summary(&out);
    assert_eq!(summary.result, LiveResult::Completed, "{summary:#?}");
    let plant = summary.plant.as_ref().expect("the plant's summary");
    assert_eq!(plant.result, RunResult::Completed, "{summary:#?}");
    assert_eq!(summary.record.states, states.len() as u64);
    assert_eq!(summary.record.dropped, 0);
    let controller = summary
        .controller
        .as_ref()
        .expect("the controller's summary");
    assert!(controller.references_applied >= 1);
}

#[test]
fn a_late_controller_gets_the_published_reference() {
    let _turn = realtime_turn();
    let dir = Scratch::new("publish");
    let (pub_port, ctl_port) = (free_port(), free_port());
    let robot = robot("publish");
    // No repetition: only the queryable can hand the law to a controller that starts later.
    let args: Vec<String> = [
        "--robot",
        &robot,
        "--listen",
        &endpoint(pub_port),
        "--connect",
        &endpoint(ctl_port),
        "--reference",
        "sinusoid:0.2,4",
        "--kp",
        "60",
        "--kd",
        "12",
        "--k",
        "0",
        "--torque-limit",
        "5",
        "--repeat",
        "0",
        "--duration",
        "60",
    ]
    .map(String::from)
    .to_vec();
    let mut publisher = Proc::spawn("planner", &bin("tilting-planner"), &args, dir.path());
    // Start the controller only once the reference is out (its only put has no subscriber).
    let end = Instant::now() + Duration::from_secs(20);
    while !publisher.stderr().contains("publishing on") {
        assert!(
            Instant::now() < end,
            "the planner did not start\n{}",
            publisher.logs()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let args: Vec<String> = [
        "--robot",
        &robot,
        "--listen",
        &endpoint(ctl_port),
        "--connect",
        &endpoint(pub_port),
    ]
    .map(String::from)
    .to_vec();
    let mut ctl = Proc::spawn("controller", &bin("tilting-controller"), &args, dir.path());
    // The controller logs each law it applies.
    let end = Instant::now() + Duration::from_secs(20);
    loop {
        let text = ctl.stderr();
        if text.contains("planner reference applied") {
            assert!(
                text.contains("source=\"query\""),
                "the law must come from the queryable: {text}"
            );
            break;
        }
        assert!(Instant::now() < end, "no reference applied:\n{text}");
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );
    let c = ctl.controller_summary();
    assert_eq!(c.law.kp, 60.0, "{c:?}");
    assert_eq!(c.law.kd, 12.0, "{c:?}");
    assert_eq!(c.law.torque_limit, Some(5.0), "{c:?}");
    assert_eq!(
        c.law.reference,
        tilting_controller::Trajectory::Sinusoid {
            amplitude: 0.2,
            omega: 4.0
        },
        "{c:?}"
    );
    assert!(
        publisher.interrupt(Duration::from_secs(10)).success(),
        "{}",
        publisher.logs()
    );
    let p: tilting_planner::node::PublishSummary =
        serde_json::from_value(publisher.summary_json()).expect("the planner's summary");
    assert!(p.queries_answered >= 1, "{p:?}");
    assert_eq!(p.puts, 1, "{p:?}");
}

#[test]
fn a_controller_dying_mid_run_is_reported_and_the_recording_kept() {
    let _turn = realtime_turn();
    let dir = Scratch::new("death");
    let out = dir.path().join("out");
    let mut live = start_live(&dir, &out, "death", &["--duration", "30", "--csv"]);
    // Wait until the loop runs (states are being recorded), then kill the controller.
    let end = Instant::now() + Duration::from_secs(20);
    let ctl = loop {
        let rows = std::fs::read_to_string(out.join("torque.csv"))
            .map(|t| t.lines().count())
            .unwrap_or(0);
        if rows > 1 {
            if let Some(pid) = child_named(live.pid() as u32, "tilting-controller") {
                break pid;
            }
        }
        assert!(Instant::now() < end, "the live loop did not start");
        std::thread::sleep(Duration::from_millis(100));
    };
    let plant = child_named(live.pid() as u32, "tilting-plant").expect("the plant runs");
    std::thread::sleep(Duration::from_millis(1500));
    // SAFETY: kill(2) on a pid read from our child's children list.
    unsafe { libc::kill(ctl, libc::SIGKILL) };
    let status = live.expect_exit(Duration::from_secs(20));
    let err = live.stderr();
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("the controller exited during the run") && err.contains("SIGKILL"),
        "{err}"
    );
    // The plant was stopped, not left running; what was recorded is there.
    assert!(
        !Path::new(&format!("/proc/{plant}")).exists(),
        "the plant is still there"
    );
    let (_, states) = csv(&out.join("state.csv"));
    assert!(states.len() > 1000, "{} states", states.len());
    assert!(out.join("run.png").is_file());
    let summary = live_summary(&out);
    assert_eq!(summary.result, LiveResult::Failed);
    let plant = summary.plant.as_ref().expect("the plant's summary");
    assert_eq!(plant.result, RunResult::Stopped, "{summary:#?}");
}

#[test]
fn live_without_the_node_binaries_says_how_to_build_them() {
    let dir = Scratch::new("nobin");
    let exe = dir.path().join("tilting");
    std::fs::copy(bin("tilting"), &exe).unwrap();
    let o = Command::new(&exe)
        .args(["live", "--duration", "1", "--out"])
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("tilting-plant"), "{err}");
    assert!(err.contains("cargo build --release --workspace"), "{err}");
}

#[test]
fn the_old_planner_commands_still_work_and_say_where_they_went() {
    let args = ["--duration", "0.5", "--json", "--control-period", "0.001"];
    let old = Command::new(bin("tilting-planner"))
        .arg("simulate")
        .args(args)
        .output()
        .unwrap();
    let new = Command::new(bin("tilting"))
        .arg("simulate")
        .args(args)
        .output()
        .unwrap();
    assert!(old.status.success() && new.status.success());
    let err = String::from_utf8_lossy(&old.stderr);
    assert!(err.contains("is now `tilting simulate`"), "{err}");
    // The same command: the same report, but for the wall-clock time it took.
    let strip = |o: &[u8]| {
        let mut r: SimulationReport = serde_json::from_slice(o).unwrap();
        r.stats.wall_time_s = 0.0;
        r
    };
    assert_eq!(strip(&old.stdout), strip(&new.stdout));
    // A planning command moved under `plan`; its usage errors keep exit code 2.
    let o = Command::new(bin("tilting-planner"))
        .args(["orbit", "--kp", "-3"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("is now `tilting plan orbit`"), "{err}");
    assert!(err.contains("--kp"), "{err}");
}

#[test]
fn a_recording_survives_sigkill_of_live_with_whole_rows() {
    let _turn = realtime_turn();
    let dir = Scratch::new("sigkill");
    let out = dir.path().join("out");
    let mut live = start_live(&dir, &out, "sigkill", &["--duration", "30", "--csv"]);
    // Let the loop run for about 3 s of recorded states, then kill `live` without warning.
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let rows = std::fs::read_to_string(out.join("state.csv"))
            .map(|t| t.lines().count())
            .unwrap_or(0);
        if rows > 3000 {
            break;
        }
        assert!(
            Instant::now() < end,
            "the live loop did not start\n{}",
            live.logs()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let nodes: Vec<i32> = ["tilting-plant", "tilting-controller"]
        .iter()
        .filter_map(|n| child_named(live.pid() as u32, n))
        .collect();
    assert_eq!(nodes.len(), 2, "both nodes run under live");
    live.signal(libc::SIGKILL);
    live.expect_exit(Duration::from_secs(5));
    // Its children are told to stop when it dies (Linux: PR_SET_PDEATHSIG).
    let end = Instant::now() + Duration::from_secs(10);
    while nodes
        .iter()
        .any(|p| Path::new(&format!("/proc/{p}/cmdline")).exists())
    {
        assert!(Instant::now() < end, "a node outlived live: {nodes:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
    // Every file holds whole rows only (`csv` checks the column count and parses every field),
    // and nothing older than the last flush interval (100 ms, so about 100 periods) is lost.
    let (_, states) = csv(&out.join("state.csv"));
    let (_, torques) = csv(&out.join("torque.csv"));
    let (_, events) = csv(&out.join("events.csv"));
    assert!(states.len() > 3000, "{} states", states.len());
    for w in states.windows(2) {
        assert_eq!(w[1][0], w[0][0] + 1.0, "consecutive seq: {w:?}");
    }
    // The torque file is flushed by the same writer: at most a few intervals behind.
    assert!(
        torques.len() + 300 >= states.len(),
        "{} torques for {} states",
        torques.len(),
        states.len()
    );
    // A tilt starts every 0.435 s on the orbit: the events of the first 3 s are there.
    assert!(events.len() >= 10, "{} events", events.len());
    // run.mcap has no summary section but reads up to its last chunk, flushed by the same
    // writer at the same interval as the CSV files: consecutive states from 0, as many as
    // state.csv within a few flush intervals.
    let run = tilting_record::read(&out.join("run.mcap")).expect("run.mcap opens");
    assert!(!run.complete() && run.truncation().is_some());
    for (seq, e) in run
        .messages()
        .filter(|e| e.topic == Topic::State)
        .enumerate()
    {
        let s: PlantState = tilting_proto::decode(&e.wire).expect("a valid state");
        assert_eq!(s.seq, seq as u64);
        assert_eq!(e.log_time, (s.time * 1e9).round() as u64);
    }
    let n = run.count(Topic::State);
    assert!(
        // Not `n > 3000`: the kill came when state.csv passed 3000 rows, and run.mcap may be
        // one flush behind it (2,991 against 3,062 seen), which the window below allows.
        n + 300 >= states.len() as u64 && states.len() as u64 + 300 >= n,
        "{n} states in run.mcap, {} in state.csv",
        states.len()
    );
}

/// `live --reference excitation` (the identification's motion, issue 17) for 3 s: the plant
/// starts at rest upright on the flat plate and the plate stays flat (every state flat with
/// `alpha = 0`, no transition); the arm follows `beta_d(t)` of the default excitation, computed
/// here from `tilting_controller::Trajectory` (the computed-torque law on the exact model
/// tracks it up to the hold's error: measured 1.6e-6 rad; 0.01 rad allowed, half the
/// motion, for a loaded machine's late torques), and really moves (by at least half of
/// `beta_d`'s excursion).
#[test]
fn live_excitation_keeps_the_plate_flat_and_the_arm_on_the_excitation() {
    use tilting_controller::trajectory::EXCITATION_DEFAULT;
    let _turn = realtime_turn();
    let dir = Scratch::new("excitation");
    let out = dir.path().join("out");
    let robot = robot("excite");
    let o = Command::new(bin("tilting"))
        .args([
            "live",
            "--duration",
            "3",
            "--reference",
            "excitation",
            "--csv",
            "--robot",
            &robot,
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("cannot run tilting live");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{}\n{stdout}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
    let (_, states) = csv(&out.join("state.csv"));
    let (_, events) = csv(&out.join("events.csv"));
    assert!(states.len() > 1000, "{} states", states.len());
    assert!(events.is_empty(), "the plate moved: {events:?}");
    let (mut err, mut moved, mut wanted) = (0.0f64, 0.0f64, 0.0f64);
    for r in &states {
        assert_eq!((r[2], r[3]), (0.0, 0.0), "the plate is not flat: {r:?}");
        let (bd, _, _) = EXCITATION_DEFAULT.at(r[1]);
        err = err.max((r[4] - bd).abs());
        moved = moved.max((r[4] - std::f64::consts::FRAC_PI_2).abs());
        wanted = wanted.max((bd - std::f64::consts::FRAC_PI_2).abs());
    }
    eprintln!("excitation: largest |beta - beta_d| {err:.2e} rad, excursion {moved:.4} of {wanted:.4} rad");
    assert!(err < 0.01, "the arm does not follow: {err} rad");
    assert!(
        wanted > 0.01 && moved > 0.5 * wanted,
        "{moved} of {wanted} rad"
    );
    assert!(!stdout.contains("E_av = 0 J"), "{stdout}");
}

/// `summary.json` and the report name the zenoh sessions the plant and the controller
/// published from. The independent truth is on the wire: an outside peer that joins the
/// plant's port reads the source each state and each torque names in its attachment (set by
/// the publisher from its own session's `ZenohId`, not from the flags `live` keeps), and
/// every state it hears names one session, every torque another, the ones in the summary.
#[test]
fn the_summary_names_the_sessions_the_nodes_published_from() {
    use std::collections::BTreeMap;
    use std::sync::{Arc, Mutex};
    use tilting_proto::SourceId;
    let _turn = realtime_turn();
    let dir = Scratch::new("ids");
    let (mut live, robot, port, out) = live_with_open_port(&dir, "ids", 4.0);
    type Seen = Arc<Mutex<BTreeMap<Option<String>, u64>>>;
    let (states, torques): (Seen, Seen) = Default::default();
    let rt = tokio::runtime::Runtime::new().unwrap();
    let _watch = rt.block_on(async {
        let watcher = Client::open(&robot, None, Some(port)).await;
        let count = |seen: &Seen| {
            let seen = seen.clone();
            move |source: Option<SourceId>| {
                let mut m = seen.lock().unwrap();
                *m.entry(source.map(|s| s.to_string())).or_default() += 1;
            }
        };
        let (on_state, on_torque) = (count(&states), count(&torques));
        let k = &watcher.keys;
        let drops = |key: &str| Arc::new(tilting_net::DropCounter::new(key));
        let s = &watcher.session;
        let a = tilting_net::subscribe_decoded_from(
            s,
            drops(k.plant_state()),
            move |_: PlantState, from| on_state(from),
        )
        .await
        .unwrap();
        let b = tilting_net::subscribe_decoded_from(
            s,
            drops(k.controller_torque()),
            move |_: TorqueCommand, from| on_torque(from),
        )
        .await
        .unwrap();
        (watcher, a, b)
    });
    let status = live.expect_exit(Duration::from_secs(40));
    assert!(status.success(), "{status}\n{}", live.logs());
    let s = live_summary(&out);
    let ids = s.zenoh_ids.as_ref().expect("zenoh_ids in summary.json");
    let (plant, ctl) = (
        ids.plant.as_ref().expect("the plant's id"),
        ids.controller.as_ref().expect("the controller's id"),
    );
    let (states, torques) = (
        states.lock().unwrap().clone(),
        torques.lock().unwrap().clone(),
    );
    eprintln!("summary {ids:?}; on the wire: states {states:?}, torques {torques:?}");
    // Each stream named one session (hundreds of messages each), the summary's.
    let only = |seen: &BTreeMap<Option<String>, u64>| {
        assert_eq!(seen.len(), 1, "{seen:?}");
        let (id, n) = seen.iter().next().unwrap();
        assert!(*n > 100, "{seen:?}");
        id.clone().expect("a source attached")
    };
    assert_eq!(only(&states), plant.id);
    assert_eq!(only(&torques), ctl.id);
    assert_ne!(plant.id, ctl.id);
    // As `tilting record --plant-id` takes them, and nothing refused as foreign.
    for id in [&plant.id, &ctl.id] {
        assert!(id.parse::<SourceId>().is_ok(), "{id}");
    }
    assert_eq!((plant.foreign, ctl.foreign, s.record.foreign), (0, 0, 0));
    // The report says them.
    let stdout = live.stdout();
    let line = format!(
        "zenoh ids: plant {} (0 foreign refused), controller {} (0 foreign refused)",
        plant.id, ctl.id
    );
    assert!(stdout.contains(&line), "{stdout}");
}
