//! The harness of the process-level integration tests in `tests/tests/` and of the loop
//! benchmark: real binaries as separate processes over loopback.
//!
//! - The binaries of other packages are not available as `CARGO_BIN_EXE_*` here: [`bin`] finds
//!   them in the profile directory next to the test executable (`target/release/deps/..`) and,
//!   once per test binary, runs `cargo build --release --workspace --bins` (the README's build)
//!   so they are never stale (set `TILTING_TESTS_NO_BUILD=1` to skip that and use what is
//!   there).
//! - [`Proc`]: a child process started by the product's own supervisor
//!   ([`tilting_launch::Child`]: stdout and stderr in files, own process group, killed on
//!   drop), with the waits and panics a test wants.
//! - [`free_port`]: a free loopback TCP port; each test uses its own ports and its own robot
//!   name, with multicast scouting off, so tests never see each other's traffic.
//! - [`Client`]: a zenoh session of the test itself (publishes garbage, plays the planner or
//!   the plant, watches the status).

use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus};
use std::sync::{Mutex, MutexGuard, Once};
use std::time::{Duration, Instant};

pub mod proxy;
pub mod recording;
mod scratch;

pub use scratch::Scratch;

pub use tilting_controller::node::ControllerSummary;
pub use tilting_launch::endpoint;
pub use tilting_net;
pub use tilting_plant::node::{PlantSummary, RunResult};
pub use tilting_proto;
pub use tilting_sim::SimulationReport;
pub use zenoh;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The directory of the binaries: the cargo profile directory of the running test or example.
pub fn bin_dir() -> PathBuf {
    tilting_launch::profile_dir().expect("profile dir")
}

static BUILD: Once = Once::new();

/// Path of the binary `name` (`tilting`, `tilting-plant`, `tilting-controller` or
/// `tilting-planner`), built first if needed.
pub fn bin(name: &str) -> PathBuf {
    BUILD.call_once(|| {
        if std::env::var_os("TILTING_TESTS_NO_BUILD").is_some() {
            return;
        }
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut command = Command::new(cargo);
        // `cargo test` sets these for the test process; a nested cargo that inherits them hands
        // them on to build scripts, and some (ring's) re-run on any change of `CARGO_PKG_*`,
        // which would rebuild ring and everything above it (zenoh) inside the test run.
        for (key, _) in std::env::vars_os() {
            let key = key.to_string_lossy();
            let inherited_from_test = [
                "CARGO_PKG_",
                "CARGO_MANIFEST_",
                "CARGO_CRATE_",
                "CARGO_BIN_",
            ]
            .iter()
            .any(|prefix| key.starts_with(prefix))
                || ["CARGO_PRIMARY_PACKAGE", "CARGO_TARGET_TMPDIR", "OUT_DIR"]
                    .contains(&key.as_ref());
            if inherited_from_test {
                command.env_remove(key.as_ref());
            }
        }
        let status = command
            // The README's build (every binary of the workspace): with the workspace-hack crate
            // every build resolves the same features, so after `cargo test --workspace` this
            // compiles nothing but the binaries `cargo test` did not link.
            .args(["build", "--release", "--workspace", "--bins"])
            .current_dir(workspace_root())
            .status()
            .expect("cannot run cargo build");
        assert!(status.success(), "cargo build of the binaries failed");
    });
    let path = bin_dir().join(name);
    assert!(
        path.exists(),
        "{} does not exist: build it with `cargo build --release --workspace`",
        path.display()
    );
    path
}

/// Runs on the wall clock take turns within one test binary: two 1 kHz loops at once on a
/// 2-core machine would measure each other, and a test binary holds many modules (issue 30:
/// `tests/tests/loop/`, `peers/`, `front/`, `records/`) whose tests run side by side on
/// threads. Every test that runs a real-time loop, or asserts misses, latencies or deadlines,
/// takes a turn first and holds it for the whole run; a test that panicked while holding it
/// (a poisoned lock) does not stop the others.
///
/// Panics if the calling thread holds a turn already (the lock is not re-entrant: a second
/// call would wait for itself forever).
pub fn realtime_turn() -> Turn {
    static REALTIME: Mutex<()> = Mutex::new(());
    assert!(
        !HOLDS_TURN.get(),
        "realtime_turn taken twice on one thread: the test would wait for itself"
    );
    let guard = REALTIME.lock().unwrap_or_else(|e| e.into_inner());
    HOLDS_TURN.set(true);
    Turn { _guard: guard }
}

thread_local! {
    /// Does this thread hold a [`Turn`]?
    static HOLDS_TURN: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// A turn of [`realtime_turn`], given back when dropped. An async test may hold it across its
/// awaits: it takes the turn before its first await, on the thread that blocks on the test's
/// own runtime, and no other task of that runtime takes it, so it cannot deadlock.
pub struct Turn {
    _guard: MutexGuard<'static, ()>,
}

impl Drop for Turn {
    fn drop(&mut self) {
        HOLDS_TURN.set(false);
    }
}

/// The headline's sensors (issue 17) as flags, beside `Imperfections::measured_as_hardware`.
pub use tilting_plant::imperfect::MEASURED_AS_HARDWARE;

/// A free TCP port on 127.0.0.1 (the OS picks it; it is released before use).
pub fn free_port() -> u16 {
    tilting_launch::free_port().expect("a free port")
}

/// A unique robot name for one test (`{tag}_{pid}`).
pub fn robot(tag: &str) -> String {
    format!("{tag}_{}", std::process::id())
}

/// `summary.json` of a `tilting live` run whose output directory is `out`.
pub fn live_summary(out: &Path) -> tilting_live::summary::LiveSummary {
    let text = std::fs::read_to_string(out.join("summary.json")).expect("summary.json");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("summary.json: {e}\n{text}"))
}

/// Starts `tilting live --robot robot(tag) --out out` with `extra` flags and waits (at most
/// 30 s) until its status line counts tilts.
pub fn start_live(dir: &Scratch, out: &Path, tag: &str, extra: &[&str]) -> Proc {
    let mut args: Vec<String> = vec![
        "live".into(),
        "--robot".into(),
        robot(tag),
        "--out".into(),
        out.display().to_string(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let mut live = Proc::spawn("live", &bin("tilting"), &args, dir.path());
    let t0 = Instant::now();
    while !live.stderr().contains("tilts") {
        assert!(
            t0.elapsed() < Duration::from_secs(30) && live.try_wait().is_none(),
            "{}",
            live.logs()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    live
}

/// [`start_live`] of `duration` s with the plant on a free port and the output in
/// `{dir}/out`. Returns it, the robot's name, the plant's port and the output directory.
pub fn live_with_open_port(
    dir: &Scratch,
    tag: &str,
    duration: f64,
) -> (Proc, String, u16, PathBuf) {
    let out = dir.path().join("out");
    let port = free_port();
    let flags = [
        "--duration".to_owned(),
        duration.to_string(),
        "--port".to_owned(),
        port.to_string(),
    ];
    let flags: Vec<&str> = flags.iter().map(String::as_str).collect();
    let live = start_live(dir, &out, tag, &flags);
    (live, robot(tag), port, out)
}

/// A child of process `pid` (started by its main thread; Linux `/proc`) whose command line
/// contains `name`.
pub fn child_named(pid: u32, name: &str) -> Option<i32> {
    let list = std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/children")).ok()?;
    list.split_whitespace().find_map(|c| {
        let cmd = std::fs::read(format!("/proc/{c}/cmdline")).ok()?;
        String::from_utf8_lossy(&cmd)
            .contains(name)
            .then(|| c.parse().ok())
            .flatten()
    })
}

/// A child process of a test, started by the product's supervisor; killed when dropped.
pub struct Proc(tilting_launch::Child);

impl Proc {
    /// Starts `bin args...` with stdout and stderr in `{dir}/{name}.json` and `{dir}/{name}.log`.
    pub fn spawn(name: &str, bin: &Path, args: &[String], dir: &Path) -> Self {
        Self::spawn_fifo(name, bin, args, dir, None)
    }

    /// [`Proc::spawn`] under `SCHED_FIFO` at `fifo` (1..=99, every thread of the process, as
    /// `tilting live --realtime` runs its nodes); `None`: the normal scheduler.
    pub fn spawn_fifo(
        name: &str,
        bin: &Path,
        args: &[String],
        dir: &Path,
        fifo: Option<i32>,
    ) -> Self {
        Self(
            tilting_launch::Child::spawn_with(name, bin, args, dir, fifo)
                .unwrap_or_else(|e| panic!("{e:#}")),
        )
    }

    /// The process id.
    pub fn pid(&self) -> i32 {
        self.0.pid() as i32
    }

    /// Sends a signal (`libc::SIGINT`, `SIGKILL`, `SIGSTOP`, `SIGCONT`, ...).
    pub fn signal(&self, sig: i32) {
        self.0.signal(sig);
    }

    /// Has it exited? (non-blocking)
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        self.0.try_wait()
    }

    /// Waits at most `timeout` for the exit.
    pub fn wait_timeout(&mut self, timeout: Duration) -> Option<ExitStatus> {
        self.0.wait_timeout(timeout, &|| false)
    }

    /// Waits for the exit or panics with the logs after `timeout`.
    pub fn expect_exit(&mut self, timeout: Duration) -> ExitStatus {
        match self.wait_timeout(timeout) {
            Some(s) => s,
            None => panic!(
                "{} did not exit within {timeout:?}\n{}",
                self.0.name(),
                self.logs()
            ),
        }
    }

    /// SIGINT, then the exit status (panics after `timeout`).
    pub fn interrupt(&mut self, timeout: Duration) -> ExitStatus {
        self.signal(libc::SIGINT);
        self.expect_exit(timeout)
    }

    /// Everything written to stdout so far.
    pub fn stdout(&self) -> String {
        self.0.stdout()
    }

    /// Everything written to stderr so far.
    pub fn stderr(&self) -> String {
        self.0.stderr()
    }

    /// stdout and stderr, labelled, for failure messages.
    pub fn logs(&self) -> String {
        self.0.logs()
    }

    /// The plant's summary (the last JSON line of stdout); panics with the logs if there is none.
    pub fn plant_summary(&self) -> PlantSummary {
        self.0
            .summary()
            .unwrap_or_else(|| panic!("no plant summary on stdout\n{}", self.logs()))
    }

    /// The controller's summary; panics with the logs if there is none.
    pub fn controller_summary(&self) -> ControllerSummary {
        self.0
            .summary()
            .unwrap_or_else(|| panic!("no controller summary on stdout\n{}", self.logs()))
    }

    /// The last JSON object on stdout (a node without a summary type of its own, like the
    /// planner or a Python peer); panics with the logs if there is none.
    pub fn summary_json(&self) -> serde_json::Value {
        self.0
            .summary()
            .unwrap_or_else(|| panic!("no JSON summary on stdout\n{}", self.logs()))
    }
}

/// Arguments of a plant listening on `port` for `robot`, followed by `extra`.
pub fn plant_args(robot: &str, port: u16, extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = vec![
        "--robot".into(),
        robot.into(),
        "--listen".into(),
        endpoint(port),
    ];
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

/// Runs `tilting simulate --json ARGS` (the arguments given in full: control period, duration,
/// flags), asserting it succeeded: its report (`final_state.x` is the final state
/// `[alpha, beta, alpha_dot, beta_dot]`).
pub fn simulate_json(args: &[&str]) -> SimulationReport {
    let out = Command::new(bin("tilting"))
        .args(["simulate", "--json"])
        .args(args)
        .output()
        .expect("run tilting simulate");
    assert!(
        out.status.success(),
        "simulate {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("simulate's report")
}

/// Starts a plant (`plant_args` with `plant_extra`) and a controller node connecting to it
/// (`peer_args` with `ctl_extra`) in `dir`, waits up to 60 s for the plant to end (it must
/// succeed), stops the controller and returns both summaries.
pub fn run_loop(
    dir: &Path,
    robot: &str,
    port: u16,
    plant_extra: &[&str],
    ctl_extra: &[&str],
) -> (PlantSummary, ControllerSummary) {
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(robot, port, plant_extra),
        dir,
    );
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(robot, port, ctl_extra),
        dir,
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "plant: {status}\n{}", plant.logs());
    ctl.interrupt(Duration::from_secs(10));
    (plant.plant_summary(), ctl.controller_summary())
}

/// Arguments of a controller (or any peer) connecting to `port` for `robot`, followed by
/// `extra`.
pub fn peer_args(robot: &str, port: u16, extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = vec![
        "--robot".into(),
        robot.into(),
        "--listen".into(),
        "tcp/127.0.0.1:0".into(),
        "--connect".into(),
        endpoint(port),
    ];
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

/// The zenoh session of a test.
pub struct Client {
    /// The session.
    pub session: zenoh::Session,
    /// The robot's keys.
    pub keys: tilting_proto::Keys,
}

impl Client {
    /// A peer listening on `listen` (default: an ephemeral loopback port) and connecting to
    /// `connect` (default: nowhere; never the default port 7447).
    pub async fn open(robot: &str, listen: Option<u16>, connect: Option<u16>) -> Self {
        let listen = listen
            .map(endpoint)
            .unwrap_or_else(|| "tcp/127.0.0.1:0".into());
        let connect: Vec<String> = connect.map(endpoint).into_iter().collect();
        let connect: Vec<&str> = connect.iter().map(String::as_str).collect();
        let args = tilting_net::ZenohArgs::new(robot, &[&listen], &connect);
        // Role::Plant has no default connect endpoint: without `connect` the session connects
        // nowhere (the explicit `listen` replaces the role's default).
        let role = if connect.is_empty() {
            tilting_net::Role::Plant
        } else {
            tilting_net::Role::Peer
        };
        let session = tilting_net::open_session(&args, role)
            .await
            .expect("test session");
        Self {
            session,
            keys: args.keys().expect("keys"),
        }
    }
}

impl Client {
    /// A session opened from a zenoh configuration file (e.g. a node's `{node}.json5` of
    /// `tilting certs`), connecting to `connect`.
    pub async fn open_config(robot: &str, config: &Path, connect: &str) -> Self {
        let args = tilting_net::ZenohArgs {
            zenoh_config: Some(config.to_path_buf()),
            ..tilting_net::ZenohArgs::new(robot, &[], &[connect])
        };
        let session = tilting_net::open_session(&args, tilting_net::Role::Peer)
            .await
            .unwrap_or_else(|e| panic!("test session from {}: {e:#}", config.display()));
        Self {
            session,
            keys: args.keys().expect("keys"),
        }
    }
}

/// Starts `tilting-router --config {certs}/router.json5 --listen {endpoint}` and waits until it
/// listens (it prints `"ready"`); panics with its logs after 10 s.
pub fn start_router(dir: &Path, certs: &Path, endpoint: &str) -> Proc {
    start_router_with(dir, certs, endpoint, &[])
}

/// [`start_router`] with a command prefix (e.g. `ip netns exec NAME`).
pub fn start_router_with(dir: &Path, certs: &Path, endpoint: &str, prefix: &[&str]) -> Proc {
    let router = bin("tilting-router");
    let mut args: Vec<String> = prefix
        .get(1..)
        .unwrap_or(&[])
        .iter()
        .map(|s| s.to_string())
        .collect();
    if !prefix.is_empty() {
        args.push(router.display().to_string());
    }
    args.extend([
        "--config".into(),
        certs.join("router.json5").display().to_string(),
        "--listen".into(),
        endpoint.into(),
    ]);
    let program = match prefix.first() {
        Some(p) => PathBuf::from(p),
        None => router,
    };
    let mut p = Proc::spawn("router", &program, &args, dir);
    let t0 = Instant::now();
    while !p.stdout().contains("\"ready\"") {
        if let Some(s) = p.try_wait() {
            panic!("the router exited with {s}\n{}", p.logs());
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the router did not start\n{}",
            p.logs()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    p
}

/// Polls `f` every 5 ms until it returns `Some` or `timeout` passes.
pub async fn poll_until<T>(timeout: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let end = Instant::now() + timeout;
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if Instant::now() >= end {
            return None;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}

/// Keeps the latest valid `Status` of a plant (invalid payloads are ignored).
pub struct StatusWatch {
    latest: std::sync::Arc<std::sync::Mutex<Vec<(Instant, tilting_proto::Status)>>>,
    _sub: zenoh::pubsub::Subscriber<()>,
}

impl StatusWatch {
    /// Subscribes to the plant's status.
    pub async fn new(client: &Client) -> Self {
        let latest = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let l = latest.clone();
        let sub = client
            .session
            .declare_subscriber(client.keys.plant_status().to_owned())
            .callback(move |s| {
                if let Ok(st) =
                    tilting_proto::decode::<tilting_proto::Status>(&s.payload().to_bytes())
                {
                    let mut v = l.lock().unwrap();
                    if v.len() >= 4096 {
                        v.drain(..2048);
                    }
                    v.push((Instant::now(), st));
                }
            })
            .await
            .expect("status subscriber");
        Self { latest, _sub: sub }
    }

    /// The latest status received.
    pub fn latest(&self) -> Option<tilting_proto::Status> {
        self.latest.lock().unwrap().last().map(|(_, s)| s.clone())
    }

    /// Waits for a status received from now on that satisfies `pred`; returns it with its
    /// arrival time.
    pub async fn wait_for(
        &self,
        timeout: Duration,
        mut pred: impl FnMut(&tilting_proto::Status) -> bool,
    ) -> Option<(Instant, tilting_proto::Status)> {
        let since = Instant::now();
        poll_until(timeout, || {
            let v = self.latest.lock().unwrap();
            v.iter()
                .rev()
                .take_while(|(t, _)| *t >= since)
                .filter(|(_, s)| pred(s))
                .last()
                .cloned()
        })
        .await
    }
}

/// The Python interpreter of the tests that pair our nodes with Python code: `$TILTING_PYTHON`
/// or `python3`.
pub fn python() -> String {
    std::env::var("TILTING_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// Does `python -c code` run and exit 0? (The Python tests print SKIP when it does not.)
pub fn python_runs(code: &str) -> bool {
    std::process::Command::new(python())
        .args(["-c", code])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Runs `python SCRIPT --self-test` (a Python peer's own checks, which need no zenoh) and
/// asserts that it exits 0, with its output on failure; [`skip`]s `test` without a Python.
pub fn python_self_test(test: &str, script: &Path) {
    if !python_runs("import struct") {
        let why = format!("`{}` not found", python());
        skip(test, Missing::Package, &why);
        return;
    }
    let out = Command::new(python())
        .arg(script)
        .arg("--self-test")
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap_or_else(|e| panic!("run {} --self-test: {e}", script.display()));
    assert!(
        out.status.success(),
        "{} --self-test: {}\n{}\n{}",
        script.display(),
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The arm angle (rad) that marks a rogue's forged states in the front-door and recorder tests.
pub const ROGUE_MARK_BETA: f64 = 1.234567;
/// The torque (N m) that marks a rogue's forged torques in the same tests.
pub const ROGUE_MARK_TAU: f64 = 3.25;

/// How many states and torques of `run` carry the rogue's mark ([`ROGUE_MARK_BETA`],
/// [`ROGUE_MARK_TAU`]): what the recording believed of a forger.
pub fn rogue_marked(run: &tilting_record::Recording) -> u64 {
    use tilting_proto::{codec, PlantState, Topic, TorqueCommand};
    run.messages()
        .map(|m| match m.topic {
            Topic::State => {
                u64::from(codec::decode::<PlantState>(&m.wire).unwrap().beta == ROGUE_MARK_BETA)
            }
            Topic::Torque => {
                u64::from(codec::decode::<TorqueCommand>(&m.wire).unwrap().tau == ROGUE_MARK_TAU)
            }
            _ => 0,
        })
        .sum()
}

/// The session id a rogue names when it claims one: made up, so no node ever pinned it.
pub const MADE_UP_SOURCE: tilting_proto::SourceId = tilting_proto::SourceId([0xee; 16]);

/// A plausible state marked as a rogue's: `seq` on the 1 kHz time grid (`time = seq` ms),
/// tilted left by 0.3 rad with `beta = ROGUE_MARK_BETA`, at rest. Within every rule of the
/// front door but the source's.
pub fn marked_state(seq: u64) -> tilting_proto::PlantState {
    tilting_proto::PlantState {
        seq,
        time: seq as f64 * 1e-3,
        alpha: 0.3,
        beta: ROGUE_MARK_BETA,
        alpha_dot: Some(0.0),
        beta_dot: Some(0.0),
        mode: 1,
    }
}

/// A plausible torque marked as a rogue's ([`ROGUE_MARK_TAU`]) answering state `seq`.
pub fn marked_torque(seq: u64) -> tilting_proto::TorqueCommand {
    tilting_proto::TorqueCommand {
        seq,
        tau: ROGUE_MARK_TAU,
    }
}

/// An outside zenoh peer that dials a node's listening port with a session of its own (an id
/// no node was told) and publishes on the plant's state key and the controller's torque key:
/// the attacker of the front-door tests.
pub struct Rogue {
    /// Its session and the robot's keys.
    pub client: Client,
    newest: std::sync::Arc<std::sync::atomic::AtomicU64>,
    _follow: Option<zenoh::pubsub::Subscriber<()>>,
}

impl Rogue {
    /// A peer of `robot` dialling `127.0.0.1:port`.
    pub async fn dial(robot: &str, port: u16) -> Self {
        Self {
            client: Client::open(robot, None, Some(port)).await,
            newest: Default::default(),
            _follow: None,
        }
    }

    /// Also subscribes to the plant's states, so that [`Rogue::newest`] and [`Rogue::lie`]
    /// follow the run.
    pub async fn following(mut self) -> Self {
        use std::sync::atomic::Ordering;
        let newest = self.newest.clone();
        let keys = &self.client.keys;
        let counter = std::sync::Arc::new(tilting_net::DropCounter::new(keys.plant_state()));
        let sub = tilting_net::subscribe_decoded(
            &self.client.session,
            counter,
            move |s: tilting_proto::PlantState| {
                newest.fetch_max(s.seq, Ordering::Relaxed);
            },
        )
        .await
        .expect("the rogue's subscription");
        self._follow = Some(sub);
        self
    }

    /// The newest state's `seq` heard since [`Rogue::following`] (0 before, or without it).
    pub fn newest(&self) -> u64 {
        self.newest.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Puts `state` on the plant's state key, then `torque` on the controller's torque key,
    /// each naming `source` in its attachment (`None`: no attachment at all).
    pub async fn put(
        &self,
        state: &tilting_proto::PlantState,
        torque: &tilting_proto::TorqueCommand,
        source: Option<tilting_proto::SourceId>,
    ) {
        use tilting_proto::codec::encode;
        let (s, keys) = (&self.client.session, &self.client.keys);
        let attachment = source.map(|id| id.attachment().to_vec());
        for (key, payload) in [
            (keys.plant_state(), encode(state)),
            (keys.controller_torque(), encode(torque)),
        ] {
            match &attachment {
                None => s.put(key, payload).await,
                Some(a) => s.put(key, payload).attachment(a.clone()).await,
            }
            .unwrap_or_else(|e| panic!("the rogue's put on {key}: {e}"));
        }
    }

    /// Puts the marked lies answering the newest state heard ([`Rogue::following`]): the state
    /// one period ahead ([`marked_state`] of `newest + 1`) and the torque answering the newest
    /// ([`marked_torque`] of `newest`), naming `source` as [`Rogue::put`] does.
    pub async fn lie(&self, source: Option<tilting_proto::SourceId>) {
        let seq = self.newest();
        self.put(&marked_state(seq + 1), &marked_torque(seq), source)
            .await;
    }
}

/// The environment variable that makes a skip a failure: `1` for a missing package or tool
/// (what `.ci/run` installs: Python packages, npm modules, the ROS 2 wheels), `all` also for a
/// missing right (root, `SCHED_FIFO`, network namespaces). `.ci/run` sets `1`, so that CI
/// proves what the tests claim; unset, a test without its package prints `SKIP` and passes.
pub const NO_SKIP: &str = "TILTING_NO_SKIP";

/// What a skipped test lacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Missing {
    /// A package or tool that `.ci/run` installs.
    Package,
    /// A right of the machine (root, real-time scheduling, namespaces).
    Right,
}

/// Skips `test` for `why`: prints `SKIP test: why` on stderr, or panics with it when
/// [`NO_SKIP`] asks for `missing` to fail.
pub fn skip(test: &str, missing: Missing, why: &str) {
    let strict = match std::env::var(NO_SKIP).as_deref() {
        Ok("all") => true,
        Ok("1") => missing == Missing::Package,
        _ => false,
    };
    if strict {
        panic!("{test} cannot run here ({NO_SKIP} forbids skipping it): {why}");
    }
    eprintln!("SKIP {test}: {why}");
}
