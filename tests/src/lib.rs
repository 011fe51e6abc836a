//! Helpers of the process-level integration tests in `tests/tests/`.
//!
//! - The binaries of other packages are not available as `CARGO_BIN_EXE_*` here: [`bin`] finds
//!   `tilting-plant` and `tilting-controller` in the target directory next to the test
//!   executable (`target/release/deps/..` → `target/release/`) and, once per test binary, runs
//!   `cargo build --release -p tilting-plant -p tilting-controller` so they are never stale
//!   (set `TILTING_TESTS_NO_BUILD=1` to skip that and use what is there).
//! - [`Proc`]: a child process with stdout/stderr in files, killed (SIGKILL) on drop, so a
//!   failing test never leaves a node behind.
//! - [`free_port`]: a free loopback TCP port; each test uses its own ports and its own robot
//!   name, with multicast scouting off, so tests never see each other's traffic.
//! - [`Client`]: a zenoh session of the test itself (publishes garbage, plays the planner or
//!   the plant, watches the status).

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::Once;
use std::time::{Duration, Instant};

pub mod recording;

pub use tilting_net;
pub use tilting_proto;
pub use zenoh;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The directory of the binaries: the parent of the test executable's `deps/` directory.
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("current_exe");
    let deps = exe.parent().expect("exe dir");
    if deps.file_name().is_some_and(|n| n == "deps") {
        deps.parent().expect("profile dir").to_path_buf()
    } else {
        deps.to_path_buf()
    }
}

static BUILD: Once = Once::new();

/// Path of the binary `name` (`tilting-plant`, `tilting-controller` or `tilting-planner`), built
/// first if needed.
pub fn bin(name: &str) -> PathBuf {
    BUILD.call_once(|| {
        if std::env::var_os("TILTING_TESTS_NO_BUILD").is_some() {
            return;
        }
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let status = Command::new(cargo)
            .args([
                "build",
                "--release",
                "-p",
                "tilting-plant",
                "-p",
                "tilting-controller",
                "-p",
                "tilting-planner",
            ])
            .current_dir(workspace_root())
            .status()
            .expect("cannot run cargo build");
        assert!(status.success(), "cargo build of the node binaries failed");
    });
    let path = bin_dir().join(name);
    assert!(
        path.exists(),
        "{} does not exist: build it with `cargo build --release -p {name}`",
        path.display()
    );
    path
}

/// A free TCP port on 127.0.0.1 (the OS picks it; it is released before use).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .expect("bind 127.0.0.1:0")
        .local_addr()
        .expect("local_addr")
        .port()
}

/// `tcp/127.0.0.1:{port}`.
pub fn endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

/// A unique robot name for one test (`{tag}_{pid}`).
pub fn robot(tag: &str) -> String {
    format!("{tag}_{}", std::process::id())
}

/// A scratch directory for one test, removed on drop unless `TILTING_TESTS_KEEP` is set.
pub struct Scratch(PathBuf);

impl Scratch {
    /// Creates `$TMPDIR/tilting-tests-{tag}-{pid}`.
    pub fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("tilting-tests-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create scratch dir");
        Self(dir)
    }
    /// The directory.
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::env::var_os("TILTING_TESTS_KEEP").is_none() && !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A child process; killed with SIGKILL when dropped.
pub struct Proc {
    name: String,
    child: Child,
    stdout: PathBuf,
    stderr: PathBuf,
}

impl Proc {
    /// Starts `bin args...` with stdout and stderr redirected to `{dir}/{name}.{stdout,stderr}`.
    pub fn spawn(name: &str, bin: &Path, args: &[String], dir: &Path) -> Self {
        let stdout = dir.join(format!("{name}.stdout"));
        let stderr = dir.join(format!("{name}.stderr"));
        let child = Command::new(bin)
            .args(args)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&stdout).expect("stdout file"))
            .stderr(std::fs::File::create(&stderr).expect("stderr file"))
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", bin.display()));
        Self {
            name: name.to_owned(),
            child,
            stdout,
            stderr,
        }
    }

    /// The process id.
    pub fn pid(&self) -> i32 {
        self.child.id() as i32
    }

    /// Sends a signal (`libc::SIGINT`, `SIGKILL`, `SIGSTOP`, `SIGCONT`, ...).
    pub fn signal(&self, sig: i32) {
        // SAFETY: kill(2) with a pid we own and a valid signal number.
        let rc = unsafe { libc::kill(self.pid(), sig) };
        assert_eq!(rc, 0, "kill({}, {sig}) failed", self.pid());
    }

    /// Has it exited? (non-blocking)
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        self.child.try_wait().expect("try_wait")
    }

    /// Waits at most `timeout` for the exit.
    pub fn wait_timeout(&mut self, timeout: Duration) -> Option<ExitStatus> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(s) = self.try_wait() {
                return Some(s);
            }
            if Instant::now() >= end {
                return None;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Waits for the exit or panics with the logs after `timeout`.
    pub fn expect_exit(&mut self, timeout: Duration) -> ExitStatus {
        match self.wait_timeout(timeout) {
            Some(s) => s,
            None => panic!(
                "{} did not exit within {timeout:?}\n{}",
                self.name,
                self.logs()
            ),
        }
    }

    /// SIGINT, then the exit status (SIGKILL after `timeout`).
    pub fn interrupt(&mut self, timeout: Duration) -> ExitStatus {
        self.signal(libc::SIGINT);
        self.expect_exit(timeout)
    }

    /// Everything written to stdout so far.
    pub fn stdout(&self) -> String {
        read(&self.stdout)
    }

    /// Everything written to stderr so far.
    pub fn stderr(&self) -> String {
        read(&self.stderr)
    }

    /// stdout and stderr, labelled, for failure messages.
    pub fn logs(&self) -> String {
        format!(
            "--- {} stdout ---\n{}\n--- {} stderr ---\n{}",
            self.name,
            self.stdout(),
            self.name,
            self.stderr()
        )
    }

    /// The last line of stdout that parses as a JSON object (the summary of a node).
    pub fn summary(&self) -> serde_json::Value {
        let out = self.stdout();
        out.lines()
            .rev()
            .find_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .unwrap_or_else(|| panic!("no JSON summary on stdout\n{}", self.logs()))
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

fn read(path: &Path) -> String {
    let mut s = String::new();
    if let Ok(mut f) = std::fs::File::open(path) {
        let _ = f.read_to_string(&mut s);
    }
    s
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
