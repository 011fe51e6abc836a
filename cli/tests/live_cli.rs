//! Runs the built `tilting-planner live` and `publish` with the real node binaries:
//!
//! - `live --duration 5 --out DIR` exits 0 and writes the three CSV files with plausible content
//!   (about 5000 states, alternating left/right tilts, finite numbers), the PNG and the summary;
//! - a controller killed during a `live` run is reported (which one, how), the plant is stopped,
//!   the recording is kept, and `live` exits with code 1;
//! - a controller started after `publish` gets the published law from the planner's queryable;
//! - `live` without the node binaries next to it fails with a message that says how to build
//!   them.
//!
//! `tilting-plant` and `tilting-controller` are built once per test binary (`cargo build
//! --release -p tilting-plant -p tilting-controller`) so they sit next to `tilting-planner`;
//! set `TILTING_TESTS_NO_BUILD=1` to skip that.

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, Once};
use std::time::{Duration, Instant};

mod common;
use common::TempDir;

const BIN: &str = env!("CARGO_BIN_EXE_tilting-planner");

static BUILD: Once = Once::new();

/// The real-time runs of this file take turns (two 1 kHz loops at once on a 2-core machine
/// would measure each other).
static REALTIME: Mutex<()> = Mutex::new(());

fn realtime_turn() -> std::sync::MutexGuard<'static, ()> {
    REALTIME.lock().unwrap_or_else(|e| e.into_inner())
}

/// The directory of `tilting-planner`, with the node binaries built into it.
fn bin_dir() -> PathBuf {
    let dir = Path::new(BIN).parent().unwrap().to_path_buf();
    BUILD.call_once(|| {
        if std::env::var_os("TILTING_TESTS_NO_BUILD").is_some() {
            return;
        }
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
        let status = Command::new(cargo)
            .args([
                "build",
                "--release",
                "-p",
                "tilting-plant",
                "-p",
                "tilting-controller",
            ])
            .current_dir(root)
            .status()
            .expect("cannot run cargo build");
        assert!(status.success(), "cargo build of the node binaries failed");
    });
    for name in ["tilting-plant", "tilting-controller"] {
        assert!(
            dir.join(name).is_file(),
            "{name} is not next to {BIN}: build it with `cargo build --release --workspace`"
        );
    }
    dir
}

/// A child killed on drop.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

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
    bin_dir();
    let _turn = realtime_turn();
    let dir = TempDir::new("run");
    let out = dir.path().join("out");
    let robot = format!("live_{}", std::process::id());
    let o = Command::new(BIN)
        .args(["live", "--duration", "5", "--robot", &robot, "--out"])
        .arg(&out)
        .output()
        .expect("cannot run tilting-planner live");
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

    // The figure and the summary.
    let png = std::fs::read(out.join("run.png")).expect("run.png");
    assert!(png.starts_with(b"\x89PNG"), "not a PNG");
    assert!(png.len() > 20_000, "run.png is {} bytes", png.len());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["result"], "completed", "{summary:#}");
    assert_eq!(summary["plant"]["result"], "completed", "{summary:#}");
    assert_eq!(summary["record"]["states"], states.len() as u64);
    assert_eq!(summary["record"]["dropped"], 0);
    assert!(
        summary["controller"]["references_applied"]
            .as_u64()
            .unwrap()
            >= 1
    );
}

#[test]
fn a_late_controller_gets_the_published_reference() {
    let dir = TempDir::new("publish");
    let ctl_bin = bin_dir().join("tilting-controller");
    let (pub_port, ctl_port) = (free_port(), free_port());
    let robot = format!("publish_{}", std::process::id());
    let ep = |p: u16| format!("tcp/127.0.0.1:{p}");
    // No repetition: only the queryable can hand the law to a controller that starts later.
    let publisher = Proc(
        Command::new(BIN)
            .args([
                "publish",
                "--robot",
                &robot,
                "--listen",
                &ep(pub_port),
                "--connect",
                &ep(ctl_port),
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
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.path().join("publish.log")).unwrap())
            .spawn()
            .expect("cannot start publish"),
    );
    // Start the controller only once the reference is out (its only put has no subscriber).
    let plog = dir.path().join("publish.log");
    let end = Instant::now() + Duration::from_secs(20);
    while !std::fs::read_to_string(&plog)
        .unwrap_or_default()
        .contains("publishing on")
    {
        assert!(Instant::now() < end, "publish did not start");
        std::thread::sleep(Duration::from_millis(20));
    }
    let ctl = Proc(
        Command::new(&ctl_bin)
            .args([
                "--robot",
                &robot,
                "--listen",
                &ep(ctl_port),
                "--connect",
                &ep(pub_port),
            ])
            .env("NO_COLOR", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(dir.path().join("controller.log")).unwrap())
            .spawn()
            .expect("cannot start the controller"),
    );
    // The controller logs each law it applies.
    let log = dir.path().join("controller.log");
    let end = Instant::now() + Duration::from_secs(20);
    loop {
        let text = std::fs::read_to_string(&log).unwrap_or_default();
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
    let stop = |mut p: Proc| -> String {
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(p.0.id() as i32, libc::SIGINT) };
        let end = Instant::now() + Duration::from_secs(10);
        let status = loop {
            if let Some(s) = p.0.try_wait().unwrap() {
                break s;
            }
            assert!(Instant::now() < end, "did not stop at SIGINT");
            std::thread::sleep(Duration::from_millis(20));
        };
        assert!(status.success(), "{status}");
        let mut out = String::new();
        p.0.stdout.take().unwrap().read_to_string(&mut out).unwrap();
        out
    };
    let c: serde_json::Value =
        serde_json::from_str(stop(ctl).lines().last().expect("controller summary")).unwrap();
    assert_eq!(c["law"]["kp"], 60.0, "{c}");
    assert_eq!(c["law"]["kd"], 12.0, "{c}");
    assert_eq!(c["law"]["torque_limit"], 5.0, "{c}");
    assert_eq!(c["law"]["reference"]["kind"], "sinusoid", "{c}");
    assert_eq!(c["law"]["reference"]["amplitude"], 0.2, "{c}");
    let p: serde_json::Value =
        serde_json::from_str(stop(publisher).lines().last().expect("publish summary")).unwrap();
    assert!(p["queries_answered"].as_u64().unwrap() >= 1, "{p}");
    assert_eq!(p["puts"], 1, "{p}");
}

/// The children of `pid` whose command line contains `name`.
fn child_named(pid: u32, name: &str) -> Option<i32> {
    let list = std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/children")).ok()?;
    list.split_whitespace().find_map(|c| {
        let cmd = std::fs::read(format!("/proc/{c}/cmdline")).ok()?;
        String::from_utf8_lossy(&cmd)
            .contains(name)
            .then(|| c.parse().ok())
            .flatten()
    })
}

#[test]
fn a_controller_dying_mid_run_is_reported_and_the_recording_kept() {
    bin_dir();
    let _turn = realtime_turn();
    let dir = TempDir::new("death");
    let out = dir.path().join("out");
    let robot = format!("death_{}", std::process::id());
    let mut live = Proc(
        Command::new(BIN)
            .args(["live", "--duration", "30", "--robot", &robot, "--out"])
            .arg(&out)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("cannot start live"),
    );
    // Wait until the loop runs (states are being recorded), then kill the controller.
    let end = Instant::now() + Duration::from_secs(20);
    let ctl = loop {
        let rows = std::fs::read_to_string(out.join("torque.csv"))
            .map(|t| t.lines().count())
            .unwrap_or(0);
        if rows > 1 {
            if let Some(pid) = child_named(live.0.id(), "tilting-controller") {
                break pid;
            }
        }
        assert!(Instant::now() < end, "the live loop did not start");
        std::thread::sleep(Duration::from_millis(100));
    };
    let plant = child_named(live.0.id(), "tilting-plant").expect("the plant runs");
    std::thread::sleep(Duration::from_millis(1500));
    // SAFETY: kill(2) on a pid read from our child's children list.
    unsafe { libc::kill(ctl, libc::SIGKILL) };
    let end = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(s) = live.0.try_wait().unwrap() {
            break s;
        }
        assert!(
            Instant::now() < end,
            "live did not stop after the controller died"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut err = String::new();
    live.0
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
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
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["result"], "failed");
    assert_eq!(summary["plant"]["result"], "stopped", "{summary:#}");
}

#[test]
fn live_without_the_node_binaries_says_how_to_build_them() {
    let dir = TempDir::new("nobin");
    let exe = dir.path().join("tilting-planner");
    std::fs::copy(BIN, &exe).unwrap();
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
