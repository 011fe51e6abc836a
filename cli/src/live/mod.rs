//! The `live` command: the main job in one command. It starts the plant (`tilting-plant`) and
//! the controller (`tilting-controller`) as child processes, runs the planner's reference
//! publisher in-process, all on 127.0.0.1 with explicit endpoints on free ports, and runs the
//! paper's stabilised tilting orbit in real time at 1 kHz:
//!
//! - a status line on stderr (mode, alpha, tilts, loop latency, deadline misses), refreshed
//!   5 times a second on a terminal and once a second otherwise;
//! - a clean stop after `--duration` (the plant ends its run itself) or at Ctrl-C/SIGTERM: the
//!   children get SIGINT, then SIGTERM, then SIGKILL if they do not exit in time (a second
//!   Ctrl-C kills at once);
//! - a recording in `--out DIR` (default `runs/<UTC timestamp>/`): `state.csv`, `torque.csv`,
//!   `events.csv` (see [`crate::record`]), `run.png`, `summary.json`, and the children's
//!   output (`plant.log`, `plant.json`, `controller.log`, `controller.json`);
//! - a summary on stdout: tilts, peak |alpha| of the last tilts, loop latency p50/p99/p99.9,
//!   deadline misses, faults.
//!
//! If a child dies during the run, the command says which one and how, stops the other, still
//! writes what was recorded, and exits with code 1.
//!
//! The topology: the plant listens on its port; the in-process planner session listens on its
//! own port and connects to the plant; the controller listens on a third port and connects to
//! both. Children run in their own process group (so a terminal's Ctrl-C reaches only this
//! process, which stops them in order) and get SIGTERM if this process dies.

use crate::publish::{check_seconds, describe, LawArgs, ReferencePublisher};
use crate::record::{self, Record, RecordView, Recorder};
use crate::scenario::Scenario;
use crate::CommandError;
use anyhow::{anyhow, Context as _};
use serde_json::{json, Value};
use std::io::{IsTerminal as _, Write as _};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tilting_net::{DropCounter, Role, ZenohArgs};
use tilting_plant::Mode;
use tilting_proto::{Keys, ModeEvent, PlantState, Reference, Status, TorqueCommand};

/// Name of the plant binary.
pub const PLANT_BIN: &str = "tilting-plant";
/// Name of the controller binary.
pub const CONTROLLER_BIN: &str = "tilting-controller";

/// Flags of `tilting-planner live`.
#[derive(Debug, Clone, clap::Args)]
pub struct LiveArgs {
    /// Run length (s of plant time, which is wall-clock time at real time)
    #[arg(long, default_value_t = 20.0, value_name = "SECONDS")]
    pub duration: f64,
    /// Output directory [default: runs/<UTC timestamp>/]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Control rate of the plant (Hz)
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    pub rate: f64,
    /// Robot name: keys are tilting/{robot}/...
    #[arg(long, default_value = tilting_proto::keys::DEFAULT_ROBOT, value_name = "NAME")]
    pub robot: String,
    /// The plant's port on 127.0.0.1 [default: a free port]
    #[arg(long, value_name = "PORT")]
    pub port: Option<u16>,
    /// The controller's law (also published as the planner's reference).
    #[command(flatten)]
    pub law: LawArgs,
}

/// The paths of the two node binaries.
#[derive(Debug, Clone)]
pub struct NodeBinaries {
    /// `tilting-plant`.
    pub plant: PathBuf,
    /// `tilting-controller`.
    pub controller: PathBuf,
}

impl NodeBinaries {
    /// Finds `tilting-plant` and `tilting-controller` next to the current executable.
    pub fn next_to_current_exe() -> anyhow::Result<Self> {
        let exe = std::env::current_exe().context("cannot locate the current executable")?;
        let dir = exe
            .parent()
            .ok_or_else(|| anyhow!("the executable {} has no directory", exe.display()))?;
        let find = |name: &str| {
            let p = dir.join(name);
            if p.is_file() {
                Ok(p)
            } else {
                Err(anyhow!(
                    "cannot find `{name}` next to {} (looked for {}): build the workspace first \
                     with `cargo build --release --workspace`",
                    exe.display(),
                    p.display()
                ))
            }
        };
        Ok(Self {
            plant: find(PLANT_BIN)?,
            controller: find(CONTROLLER_BIN)?,
        })
    }
}

/// A free TCP port on 127.0.0.1 (chosen by the OS, released before use).
pub fn free_port() -> anyhow::Result<u16> {
    Ok(std::net::TcpListener::bind("127.0.0.1:0")
        .context("cannot bind 127.0.0.1:0")?
        .local_addr()?
        .port())
}

fn endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

/// `YYYY-MM-DDTHH-MM-SSZ` of the current UTC time (no colons, so it is a valid file name
/// everywhere).
pub fn utc_timestamp() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}-{:02}-{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// Ctrl-C/SIGTERM count, updated by a task that starts with the runtime.
#[derive(Clone, Default)]
struct Signals(Arc<AtomicU32>);

impl Signals {
    fn start(rt: &tokio::runtime::Runtime) -> Self {
        let s = Self::default();
        let c = s.0.clone();
        rt.spawn(async move {
            loop {
                tilting_net::shutdown_signal().await;
                c.fetch_add(1, Ordering::AcqRel);
            }
        });
        s
    }
    fn count(&self) -> u32 {
        self.0.load(Ordering::Acquire)
    }
}

/// A child node: own process group, SIGTERM when this process dies, stdout and stderr in
/// files. Killed on drop if still running.
struct Child {
    name: &'static str,
    child: std::process::Child,
    stdout: PathBuf,
    stderr: PathBuf,
    status: Option<ExitStatus>,
}

impl Child {
    fn spawn(name: &'static str, bin: &Path, args: &[String], dir: &Path) -> anyhow::Result<Self> {
        use std::os::unix::process::CommandExt as _;
        let stdout = dir.join(format!("{name}.json"));
        let stderr = dir.join(format!("{name}.log"));
        let mut cmd = Command::new(bin);
        cmd.args(args)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&stdout)?)
            .stderr(std::fs::File::create(&stderr)?)
            .env("NO_COLOR", "1")
            .process_group(0);
        // SAFETY: the closure runs in the child between fork and exec and only calls
        // prctl(2), which is async-signal-safe, and allocates nothing.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(
                    libc::PR_SET_PDEATHSIG,
                    libc::SIGTERM as libc::c_ulong,
                    0,
                    0,
                    0,
                );
                Ok(())
            });
        }
        let child = cmd
            .spawn()
            .with_context(|| format!("cannot start {}", bin.display()))?;
        Ok(Self {
            name,
            child,
            stdout,
            stderr,
            status: None,
        })
    }

    fn signal(&self, sig: i32) {
        if self.status.is_none() {
            // SAFETY: kill(2) on the pid of our own child, which has not been reaped yet.
            unsafe { libc::kill(self.child.id() as libc::pid_t, sig) };
        }
    }

    fn try_wait(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            self.status = self.child.try_wait().ok().flatten();
        }
        self.status
    }

    /// Waits up to `timeout`; gives up early on a second Ctrl-C (`force`).
    async fn wait_for(
        &mut self,
        timeout: Duration,
        force: &dyn Fn() -> bool,
    ) -> Option<ExitStatus> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(s) = self.try_wait() {
                return Some(s);
            }
            if Instant::now() >= end || force() {
                return None;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }

    /// SIGINT, wait 5 s; SIGTERM, wait 2 s; SIGKILL. Returns the exit status and whether it
    /// had to be killed.
    async fn stop(&mut self, force: &dyn Fn() -> bool) -> (ExitStatus, bool) {
        if let Some(s) = self.try_wait() {
            return (s, false);
        }
        for (sig, secs) in [(libc::SIGINT, 5), (libc::SIGTERM, 2)] {
            self.signal(sig);
            if let Some(s) = self.wait_for(Duration::from_secs(secs), force).await {
                return (s, false);
            }
        }
        let _ = self.child.kill();
        let s = self.child.wait().unwrap_or_else(|_| {
            use std::os::unix::process::ExitStatusExt as _;
            ExitStatus::from_raw(9)
        });
        self.status = Some(s);
        (s, true)
    }

    /// The last line of stdout that parses as a JSON object (the node's summary).
    fn summary(&self) -> Option<Value> {
        let out = std::fs::read_to_string(&self.stdout).ok()?;
        out.lines().rev().find_map(|l| {
            serde_json::from_str::<Value>(l)
                .ok()
                .filter(Value::is_object)
        })
    }

    /// The last `n` lines of stderr.
    fn log_tail(&self, n: usize) -> String {
        let log = std::fs::read_to_string(&self.stderr).unwrap_or_default();
        let lines: Vec<&str> = log.lines().collect();
        lines[lines.len().saturating_sub(n)..].join("\n")
    }
}

impl Drop for Child {
    fn drop(&mut self) {
        if self.try_wait().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Why the monitoring loop ended.
#[derive(Debug)]
enum End {
    /// The plant ended by itself (its `--duration`, or a fault).
    PlantExited(ExitStatus),
    /// The controller exited while the plant was running.
    ControllerExited(ExitStatus),
    /// Ctrl-C or SIGTERM.
    Interrupted,
    /// The plant's first state did not arrive within 15 s.
    StartTimeout,
    /// The plant did not finish in time.
    Timeout,
}

/// The shared latest status of the plant.
type LatestStatus = Arc<Mutex<Option<Status>>>;

fn state_name(s: u8) -> &'static str {
    match s {
        Status::STARTING => "starting",
        Status::RUNNING => "running",
        Status::SAFE_MODE => "SAFE MODE",
        Status::FAULTED => "FAULTED",
        Status::STOPPED => "stopped",
        _ => "?",
    }
}

fn mode_name(q: u8) -> &'static str {
    Mode::from_index(q).map_or("?", Mode::as_str)
}

/// The status line.
fn status_line(st: Option<&Status>, v: &RecordView, dropped: u64) -> String {
    let Some(st) = st else {
        return format!(
            "waiting for the plant's status | recorded {} states",
            v.states
        );
    };
    let (alpha, mode) = v.last_state.map_or((0.0, st.mode), |s| (s.alpha, s.mode));
    let peaks: Vec<String> = v
        .peaks
        .iter()
        .rev()
        .take(2)
        .rev()
        .map(|p| format!("{:+.4}", p.1))
        .collect();
    let mut line = format!(
        "t {:7.2} s | {} | {:<5} alpha {:+.4} rad | tilts {:3} (last peaks {}) | latency p50 {:.0} us p99 {:.0} us | misses {}",
        st.time,
        state_name(st.state),
        mode_name(mode),
        alpha,
        st.tilts,
        if peaks.is_empty() { "-".to_owned() } else { peaks.join(" ") },
        st.latency_p50_us,
        st.latency_p99_us,
        st.deadline_misses,
    );
    if st.watchdog_trips > 0 {
        line.push_str(&format!(" | watchdog trips {}", st.watchdog_trips));
    }
    if dropped > 0 || v.missing_states > 0 {
        line.push_str(&format!(
            " | recording dropped {dropped}, missing {}",
            v.missing_states
        ));
    }
    line
}

/// `tilting-planner live`.
pub fn run(args: &LiveArgs) -> Result<(), CommandError> {
    tilting_net::init_tracing("warn");
    check_seconds("--duration", args.duration, false)?;
    if !(args.rate.is_finite() && args.rate > 0.0 && args.rate <= 100_000.0) {
        return Err(CommandError::Usage(anyhow!(
            "invalid `--rate` = {}: must be in (0, 100000] Hz",
            args.rate
        )));
    }
    let keys = Keys::new(&args.robot).map_err(|e| CommandError::Usage(anyhow!("--robot: {e}")))?;
    let bins = NodeBinaries::next_to_current_exe().map_err(CommandError::Failed)?;
    let reference = args.law.resolve()?;
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(utc_timestamp()));
    std::fs::create_dir_all(&dir)
        .with_context(|| format!("cannot create the output directory {}", dir.display()))
        .map_err(CommandError::Failed)?;
    let rt = tilting_net::runtime().map_err(CommandError::Failed)?;
    let signals = Signals::start(&rt);
    let ok = rt
        .block_on(live(args, keys, reference, &bins, &dir, signals))
        .map_err(CommandError::Failed)?;
    if ok {
        Ok(())
    } else {
        Err(CommandError::Failed(anyhow!(
            "the live run did not end cleanly (see above; logs in {})",
            dir.display()
        )))
    }
}

/// Runs the live job; `Ok(false)` when a child failed (the recording is written anyway).
async fn live(
    args: &LiveArgs,
    keys: Keys,
    reference: Reference,
    bins: &NodeBinaries,
    dir: &Path,
    signals: Signals,
) -> anyhow::Result<bool> {
    let force = {
        let s = signals.clone();
        move || s.count() >= 2
    };
    let plant_port = match args.port {
        Some(p) => p,
        None => free_port()?,
    };
    let (ctl_port, my_port) = (free_port()?, free_port()?);
    let recorder = Recorder::create(dir)?;
    let period = 1.0 / args.rate;
    eprintln!(
        "live: {} s at {} Hz in real time, robot {}; law: {}",
        args.duration,
        args.rate,
        keys.robot(),
        describe(&reference)
    );
    eprintln!("live: recording to {}", dir.display());

    // 1. The plant; it publishes state 0 until a controller shows up.
    let mut plant_args: Vec<String> = vec![
        "--robot".into(),
        keys.robot().into(),
        "--listen".into(),
        endpoint(plant_port),
        "--rate".into(),
        args.rate.to_string(),
        "--duration".into(),
        args.duration.to_string(),
    ];
    if let Some(l) = (reference.torque_limit > 0.0).then_some(reference.torque_limit) {
        // The controller saturates already; the plant's hard limit is the same.
        plant_args.extend(["--torque-limit".into(), l.to_string()]);
    }
    let mut plant = Child::spawn("plant", &bins.plant, &plant_args, dir)?;

    // 2. The planner's session: subscribers first, then the reference publisher.
    let zargs = ZenohArgs::new(
        keys.robot(),
        &[&endpoint(my_port)],
        &[&endpoint(plant_port)],
    );
    let session = tilting_net::open_session(&zargs, Role::Peer).await?;
    let latest: LatestStatus = Arc::default();
    let counters = Arc::new([
        DropCounter::new(keys.plant_state()),
        DropCounter::new(keys.controller_torque()),
        DropCounter::new(keys.plant_event()),
        DropCounter::new(keys.plant_status()),
    ]);
    let (tx, c) = (recorder.sender(), counters.clone());
    let state_sub = session
        .declare_subscriber(keys.plant_state().to_owned())
        .callback(move |s| {
            if let Some(m) = c[0].decode_sample::<PlantState>(&s) {
                tx.send(Record::State(m));
            }
        })
        .await
        .map_err(|e| anyhow!("cannot subscribe to the state: {e}"))?;
    let (tx, c) = (recorder.sender(), counters.clone());
    let torque_sub = session
        .declare_subscriber(keys.controller_torque().to_owned())
        .callback(move |s| {
            if let Some(m) = c[1].decode_sample::<TorqueCommand>(&s) {
                tx.send(Record::Torque(m));
            }
        })
        .await
        .map_err(|e| anyhow!("cannot subscribe to the torque: {e}"))?;
    let (tx, c) = (recorder.sender(), counters.clone());
    let event_sub = session
        .declare_subscriber(keys.plant_event().to_owned())
        .callback(move |s| {
            if let Some(m) = c[2].decode_sample::<ModeEvent>(&s) {
                tx.send(Record::Event(m));
            }
        })
        .await
        .map_err(|e| anyhow!("cannot subscribe to the events: {e}"))?;
    let (l, c) = (latest.clone(), counters.clone());
    let status_sub = session
        .declare_subscriber(keys.plant_status().to_owned())
        .callback(move |s| {
            if let Some(m) = c[3].decode_sample::<Status>(&s) {
                *l.lock().unwrap_or_else(|e| e.into_inner()) = Some(m);
            }
        })
        .await
        .map_err(|e| anyhow!("cannot subscribe to the status: {e}"))?;
    let publisher = ReferencePublisher::start(&session, &keys, reference).await?;

    // 3. Wait until the plant's state 0 reaches us (our subscription is in place), then start
    // the controller; the plant starts its clock when the controller's token appears.
    let t0 = Instant::now();
    let mut end: Option<End> = None;
    while recorder.view().states == 0 {
        if let Some(s) = plant.try_wait() {
            end = Some(End::PlantExited(s));
            break;
        }
        if signals.count() > 0 {
            end = Some(End::Interrupted);
            break;
        }
        if t0.elapsed() > Duration::from_secs(15) {
            end = Some(End::StartTimeout);
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let mut controller = None;
    if end.is_none() {
        let mut ctl_args: Vec<String> = vec![
            "--robot".into(),
            keys.robot().into(),
            "--listen".into(),
            endpoint(ctl_port),
            "--connect".into(),
            endpoint(plant_port),
            "--connect".into(),
            endpoint(my_port),
        ];
        ctl_args.extend(LawArgs::controller_flags(&reference));
        controller = Some(Child::spawn(
            "controller",
            &bins.controller,
            &ctl_args,
            dir,
        )?);
    }

    // 4. Monitor: status line, children, reference repetition, signals.
    let tty = std::io::stderr().is_terminal();
    let tick = Duration::from_millis(200);
    let started = Instant::now();
    let give_up = started + Duration::from_secs_f64(args.duration + 30.0);
    let mut ticks: u64 = 0;
    let mut printed = String::new();
    while end.is_none() {
        tokio::time::sleep(tick).await;
        // Five ticks a second: `second` marks one of them.
        ticks = (ticks + 1) % 5;
        let second = ticks == 0;
        if let Some(s) = plant.try_wait() {
            end = Some(End::PlantExited(s));
        } else if let Some(s) = controller.as_mut().and_then(Child::try_wait) {
            end = Some(End::ControllerExited(s));
        } else if signals.count() > 0 {
            end = Some(End::Interrupted);
        } else if Instant::now() >= give_up {
            end = Some(End::Timeout);
        }
        if second {
            if let Err(e) = publisher.repeat() {
                tracing::warn!("{e}");
            }
        }
        if tty || second || end.is_some() {
            let st = latest.lock().unwrap_or_else(|e| e.into_inner()).clone();
            let line = status_line(st.as_ref(), &recorder.view(), recorder.dropped());
            if line != printed {
                let mut err = std::io::stderr().lock();
                let _ = if tty {
                    write!(err, "\r{line}\x1b[K")
                } else {
                    writeln!(err, "{line}")
                };
                let _ = err.flush();
                printed = line;
            }
        }
    }
    if tty && !printed.is_empty() {
        eprintln!();
    }
    let end = end.expect("the loop ends with a reason");

    // 5. Stop the children in order: the plant first (its final status and summary), then
    // the controller.
    let mut problems: Vec<String> = Vec::new();
    match &end {
        End::PlantExited(s) if s.success() => {}
        End::PlantExited(s) => problems.push(format!(
            "the plant exited during the run with {s}{}",
            if s.code() == Some(3) {
                " (a fault of the model)"
            } else {
                ""
            }
        )),
        End::ControllerExited(s) => {
            problems.push(format!("the controller exited during the run with {s}"))
        }
        End::Interrupted => eprintln!("live: interrupted, stopping the nodes"),
        End::StartTimeout => problems.push(format!(
            "no state of the plant arrived within 15 s (see {})",
            plant.stderr.display()
        )),
        End::Timeout => problems.push(format!(
            "the plant did not finish within {} s of wall-clock time",
            args.duration + 30.0
        )),
    }
    let (plant_status, plant_killed) = plant.stop(&force).await;
    let ctl_status = match controller.as_mut() {
        Some(c) => Some(c.stop(&force).await),
        None => None,
    };
    if plant_killed {
        problems.push(format!("the plant had to be killed ({plant_status})"));
    } else if !plant_status.success() && !matches!(end, End::PlantExited(_)) {
        problems.push(format!("the plant exited with {plant_status}"));
    }
    match ctl_status {
        Some((s, true)) => problems.push(format!("the controller had to be killed ({s})")),
        Some((s, false)) if !s.success() && !matches!(end, End::ControllerExited(_)) => {
            problems.push(format!("the controller exited with {s}"))
        }
        _ => {}
    }

    // 6. Let the last messages arrive, then close the recording.
    tokio::time::sleep(Duration::from_millis(150)).await;
    let (puts, queries) = (publisher.puts(), publisher.queries_answered());
    drop((state_sub, torque_sub, event_sub, status_sub, publisher));
    let _ = session.close().await;
    let dropped = recorder.dropped();
    let view = recorder.finish()?;
    let last_status = latest.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let plant_summary = plant.summary();
    let ctl_summary = controller.as_ref().and_then(Child::summary);
    let fault = plant_summary
        .as_ref()
        .and_then(|s| s["fault"].as_str().map(str::to_owned))
        .or_else(|| {
            last_status
                .as_ref()
                .filter(|s| !s.fault.is_empty())
                .map(|s| s.fault.clone())
        });
    for child in std::iter::once(&plant).chain(controller.as_ref()) {
        let failed = child.status.is_some_and(|s| !s.success());
        if failed {
            eprintln!(
                "--- last lines of {} ({}) ---\n{}",
                child.name,
                child.stderr.display(),
                child.log_tail(15)
            );
        }
    }

    // 7. The figure and the summary.
    let png = dir.join(record::RUN_PNG);
    let scenario = Scenario {
        kp: reference.kp,
        kd: reference.kd,
        k: reference.k,
        energy_avg: Some(reference.energy_avg),
        control_period: period,
        duration: args.duration,
        torque_limit: (reference.torque_limit > 0.0).then_some(reference.torque_limit),
        ..Scenario::default()
    };
    let early = fault
        .clone()
        .or_else(|| (!problems.is_empty()).then(|| problems.join("; ")));
    let plot_result = if view.states > 0 {
        record::plot_recording(dir, &png, view.states, &scenario, early)
    } else {
        Err(anyhow!("no state was recorded"))
    };
    if let Err(e) = &plot_result {
        problems.push(format!("cannot draw {}: {e:#}", png.display()));
    }
    let ok = problems.is_empty();
    let result = match (&end, ok) {
        (End::Interrupted, true) => "interrupted",
        (_, true) => "completed",
        (_, false) => "failed",
    };
    let summary = json!({
        "result": result,
        "problems": problems,
        "duration": args.duration,
        "rate": args.rate,
        "robot": keys.robot(),
        "out": dir,
        "reference": {
            "kind": if reference.kind == Reference::SINUSOID { "sinusoid" } else { "hold" },
            "amplitude": reference.amplitude, "omega": reference.omega,
            "kp": reference.kp, "kd": reference.kd, "k": reference.k,
            "energy_avg": reference.energy_avg, "torque_limit": reference.torque_limit,
        },
        "endpoints": {"plant": endpoint(plant_port), "controller": endpoint(ctl_port), "planner": endpoint(my_port)},
        "record": {
            "states": view.states, "torques": view.torques, "events": view.events,
            "tilts": view.tilts, "dropped": dropped, "missing_states": view.missing_states,
            "repeated_states": view.repeated_states, "repeated_torques": view.repeated_torques,
            "invalid": counters.iter().map(DropCounter::dropped).sum::<u64>(),
            "peaks": view.peaks.iter().map(|p| [p.0, p.1]).collect::<Vec<_>>(),
        },
        "planner": {"puts": puts, "queries_answered": queries},
        "png": plot_result.is_ok(),
        "plant_exit": plant_status.to_string(),
        "controller_exit": ctl_status.map(|s| s.0.to_string()),
        "plant": plant_summary,
        "controller": ctl_summary,
    });
    let summary_path = dir.join("summary.json");
    std::fs::write(&summary_path, format!("{summary:#}\n"))
        .with_context(|| format!("cannot write {}", summary_path.display()))?;
    print!(
        "{}",
        report(&summary, &view, last_status.as_ref(), fault.as_deref(), dir)
    );
    let _ = std::io::stdout().flush();
    for p in &problems {
        eprintln!("live: error: {p}");
    }
    Ok(ok)
}

/// The human-readable summary printed at the end.
fn report(
    s: &Value,
    view: &RecordView,
    status: Option<&Status>,
    fault: Option<&str>,
    dir: &Path,
) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let p = &s["plant"];
    let _ = writeln!(
        out,
        "live run {}: {} s planned at {} Hz, robot {}; plant {}, controller {}",
        s["result"].as_str().unwrap_or("?"),
        s["duration"],
        s["rate"],
        s["robot"].as_str().unwrap_or("?"),
        s["plant_exit"].as_str().unwrap_or("?"),
        s["controller_exit"].as_str().unwrap_or("not started"),
    );
    if p.is_object() {
        let _ = writeln!(
            out,
            "plant: {} at t = {} s after {} periods, mode {}",
            p["result"].as_str().unwrap_or("?"),
            p["time"],
            p["steps"],
            p["mode"].as_str().unwrap_or("?")
        );
    }
    let tilts = p["tilts"]
        .as_u64()
        .or(status.map(|s| s.tilts))
        .unwrap_or(view.tilts);
    let peaks: Vec<f64> = match p["tilt_peaks"].as_array() {
        Some(a) if !a.is_empty() => a.iter().filter_map(|x| x[1].as_f64()).collect(),
        _ => view.peaks.iter().map(|x| x.1).collect(),
    };
    let last: Vec<String> = peaks[peaks.len().saturating_sub(6)..]
        .iter()
        .map(|a| format!("{:.5}", a.abs()))
        .collect();
    let _ = writeln!(
        out,
        "tilts: {tilts}; peak |alpha| of the last {} tilts (rad): {}",
        last.len(),
        if last.is_empty() {
            "-".to_owned()
        } else {
            last.join(" ")
        }
    );
    let lat = &p["latency_us"];
    if lat.is_object() {
        let _ = writeln!(
            out,
            "loop latency (state out -> torque back, us, last {} periods): p50 {:.1}, p99 {:.1}, p99.9 {:.1}, max {:.1}",
            lat["count"].as_u64().unwrap_or(0).min(lat["window"].as_u64().unwrap_or(4096)),
            lat["p50"].as_f64().unwrap_or(f64::NAN),
            lat["p99"].as_f64().unwrap_or(f64::NAN),
            lat["p999"].as_f64().unwrap_or(f64::NAN),
            lat["max"].as_f64().unwrap_or(f64::NAN),
        );
        let _ = writeln!(
            out,
            "deadline misses: {}, watchdog trips: {}, overruns: {} (max {:.0} us), jitter p99 {:.1} us",
            p["deadline_misses"],
            p["watchdog_trips"],
            p["overruns"],
            p["max_overrun_us"].as_f64().unwrap_or(0.0),
            p["jitter_us"]["p99"].as_f64().unwrap_or(f64::NAN),
        );
    } else if let Some(st) = status {
        let _ = writeln!(
            out,
            "loop latency (us, from the last status): p50 {:.1}, p99 {:.1}; deadline misses {}, watchdog trips {}",
            st.latency_p50_us, st.latency_p99_us, st.deadline_misses, st.watchdog_trips
        );
    }
    let _ = writeln!(out, "faults: {}", fault.unwrap_or("none"));
    let r = &s["record"];
    let _ = writeln!(
        out,
        "recorded in {}: state.csv {} rows, torque.csv {} rows, events.csv {} rows, {}summary.json (dropped {}, missing states {})",
        dir.display(),
        r["states"],
        r["torques"],
        r["events"],
        if s["png"] == true { "run.png, " } else { "" },
        r["dropped"],
        r["missing_states"],
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamp_is_a_file_name() {
        let t = utc_timestamp();
        assert_eq!(t.len(), "2026-11-21T21-35-48Z".len(), "{t}");
        assert!(t.starts_with("20"), "{t}");
        assert!(!t.contains(':'));
    }

    #[test]
    fn status_line_shows_the_essentials() {
        let st = Status {
            seq: 1000,
            time: 1.0,
            state: Status::RUNNING,
            mode: 1,
            tilts: 3,
            steps: 1000,
            torques_received: 1000,
            torques_dropped: 0,
            torques_stale: 0,
            deadline_misses: 2,
            watchdog_trips: 0,
            jitter_p50_us: 1.0,
            jitter_p99_us: 2.0,
            max_overrun_us: 0.0,
            latency_p50_us: 40.0,
            latency_p99_us: 90.0,
            fault: String::new(),
        };
        let v = RecordView {
            peaks: [(0.2, 0.04), (0.6, -0.041)].into_iter().collect(),
            ..RecordView::default()
        };
        let l = status_line(Some(&st), &v, 0);
        for needle in [
            "running",
            "left",
            "tilts   3",
            "p50 40 us",
            "p99 90 us",
            "misses 2",
            "-0.0410",
        ] {
            assert!(l.contains(needle), "{needle:?} not in {l:?}");
        }
        assert!(status_line(None, &v, 0).contains("waiting"));
    }
}
