//! The `live` command: the main job in one command. It starts the plant (`tilting-plant`) and
//! the controller (`tilting-controller`) as child processes, runs the planner's reference
//! publisher in-process, all on 127.0.0.1 with explicit endpoints on free ports, and runs the
//! paper's stabilised tilting orbit in real time at 1 kHz:
//!
//! - a status line on stderr ([`status`]: mode, alpha, tilts, loop latency, deadline misses),
//!   refreshed 5 times a second on a terminal and once a second otherwise;
//! - a clean stop after `--duration` (the plant ends its run itself) or at Ctrl-C/SIGTERM: the
//!   children get SIGINT, then SIGTERM, then SIGKILL if they do not exit in time (a second
//!   Ctrl-C kills at once);
//! - a recording in `--out DIR` (default `runs/<UTC timestamp>/`): `run.mcap` (all five
//!   topics; with `--csv` also `state.csv`, `torque.csv`, `events.csv`, see [`crate::record`]),
//!   `run.png`, `run.gif` (the last 8 s, moving), `summary.json` ([`summary`]), and the
//!   children's output (`plant.log`, `plant.json`, `controller.log`, `controller.json`);
//! - a report on stdout: tilts, peak |alpha| of the last tilts, loop latency p50/p99/p99.9,
//!   deadline misses, faults.
//!
//! With the impairment flags of `simulate` (`--delay`, `--jitter`, `--loss`, `--loss-burst`, each
//! also `--state-...`/`--torque-...`, `--seed`) and `--max-age`, the plant emulates the link on
//! the wall clock (`tilting_plant::node`): its states reach the controller (and the recording,
//! which listens on the same key) delayed or not at all, and the torques reach its inbox
//! delayed or not at all. The status line then shows the torque ages and the losses, and
//! every line and the report say whether the orbit holds ([`orbit`]).
//!
//! If a child dies during the run, the command says which one and how, stops the other, still
//! writes what was recorded, and exits with code 1.
//!
//! With `--secure` (and optionally `--certs DIR` of `tilting certs`; by default certificates are
//! made in `OUT/certs`), a `tilting-router` child enforces mutual TLS and the robot's access
//! control, and the plant, the controller and the in-process planner (with the planner's
//! identity) are its clients ([`crate::security`]).
//!
//! The topology without `--secure`: the plant listens on its port; the in-process planner session listens on its
//! own port and connects to the plant; the controller listens on a third port and connects to
//! both. The children are started and stopped by [`crate::supervise`].

mod orbit;
pub mod status;
pub mod summary;

use crate::record::{self, Record, Recorder};
use crate::security;
use crate::supervise::{endpoint, free_port, utc_timestamp, Child, NodeBinaries};
use anyhow::{anyhow, Context as _};
use orbit::OrbitCheck;
use status::{status_line, LatestStatus};
use std::io::{IsTerminal as _, Write as _};
use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use summary::{Endpoints, LawRecord, LiveResult, LiveSummary, PlannerCounts, RecordCounts};
use tilting_controller::node::ControllerSummary;
use tilting_link::{Burst, Jitter, LinkSpec, NetworkArgs};
use tilting_net::{subscribe_decoded, DropCounter, Role, ZenohArgs};
use tilting_planner::margins::{self, Criteria};
use tilting_planner::node::{check_seconds, describe, LawArgs, ReferencePublisher};
use tilting_planner::CommandError;
use tilting_plant::node::PlantSummary;
use tilting_proto::{Keys, ModeEvent, PlantState, Reference, Status, TorqueCommand};
use tilting_sim::Scenario;

/// Flags of `tilting live`.
#[derive(Debug, Clone, clap::Args)]
pub struct LiveArgs {
    /// Run length (s of plant time, which is wall-clock time at real time)
    #[arg(
        long,
        default_value_t = 20.0,
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub duration: f64,
    /// Output directory [default: runs/<UTC timestamp>/]
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Also write state.csv, torque.csv and events.csv (for spreadsheets) beside run.mcap
    #[arg(long)]
    pub csv: bool,
    /// Control rate of the plant (Hz)
    #[arg(
        long,
        default_value_t = 1000.0,
        value_name = "HZ",
        allow_negative_numbers = true
    )]
    pub rate: f64,
    /// Robot name: keys are tilting/{robot}/...
    #[arg(long, default_value = tilting_proto::keys::DEFAULT_ROBOT, value_name = "NAME")]
    pub robot: String,
    /// The plant's port on 127.0.0.1 [default: a free port]
    #[arg(long, value_name = "PORT")]
    pub port: Option<u16>,
    /// Mutual TLS and access control: a `tilting-router` child enforces which identity may
    /// publish which key, and every node connects to it as a client with its own certificate
    /// (from --certs, or created in OUT/certs)
    #[arg(long)]
    pub secure: bool,
    /// With --secure: the directory of `tilting certs --robot NAME --out DIR` [default: new
    /// certificates in OUT/certs]
    #[arg(long, value_name = "DIR", requires = "secure")]
    pub certs: Option<PathBuf>,
    /// The controller's law (also published as the planner's reference).
    #[command(flatten)]
    pub law: LawArgs,
    /// An impaired link between plant and controller, emulated by the plant on the wall clock
    /// (the flags of `simulate`).
    #[command(flatten)]
    pub network: NetworkArgs,
    /// The plant's --max-age: it applies the newest torque answering a state at most this many
    /// periods old
    #[arg(long, default_value_t = tilting_plant::node::DEFAULT_MAX_AGE, value_name = "PERIODS")]
    pub max_age: u64,
    /// The controller predicts the state over the round-trip delay (its --predict): `auto`
    /// (the default value) estimates the delay from the ages in the plant's status, or give it
    /// in seconds, in [0, 60]
    #[arg(long, value_name = "auto|SECONDS", num_args = 0..=1, default_missing_value = "auto",
          value_parser = tilting_controller::predict::parse_predict)]
    pub predict: Option<tilting_controller::predict::Predict>,
}

/// Largest `--max-age` (periods), as the plant allows.
const MAX_AGE: u64 = 1000;

/// The plant's flags for the impairment `net` (the same flags, spelled out again).
fn network_flags(net: &NetworkArgs) -> Vec<String> {
    fn jitter(j: Jitter) -> String {
        match j {
            Jitter::Uniform { max } => format!("uniform:{max}"),
            Jitter::Normal { sigma } => format!("normal:{sigma}"),
            Jitter::Exp { mean } => format!("exp:{mean}"),
        }
    }
    let burst = |b: Burst| format!("{},{}", b.p, b.r);
    let mut v = Vec::new();
    let mut flag = |name: &str, value: Option<String>| {
        if let Some(x) = value {
            v.extend([format!("--{name}"), x]);
        }
    };
    for (prefix, delay, jit, loss, bur) in [
        ("", net.delay, net.jitter, net.loss, net.loss_burst),
        (
            "state-",
            net.state_delay,
            net.state_jitter,
            net.state_loss,
            net.state_loss_burst,
        ),
        (
            "torque-",
            net.torque_delay,
            net.torque_jitter,
            net.torque_loss,
            net.torque_loss_burst,
        ),
    ] {
        flag(&format!("{prefix}delay"), delay.map(|x| x.to_string()));
        flag(&format!("{prefix}jitter"), jit.map(jitter));
        flag(&format!("{prefix}loss"), loss.map(|x| x.to_string()));
        flag(&format!("{prefix}loss-burst"), bur.map(burst));
    }
    flag("seed", Some(net.seed.to_string()));
    v
}

/// One direction of a link in words: `2 ms + exp:0.5 ms, loss 5 %`.
fn describe_link(s: &LinkSpec) -> String {
    let mut parts = vec![format!("{} ms", s.delay * 1e3)];
    match s.jitter {
        Some(Jitter::Uniform { max }) => parts.push(format!("+ uniform:{} ms", max * 1e3)),
        Some(Jitter::Normal { sigma }) => parts.push(format!("+ normal:{} ms", sigma * 1e3)),
        Some(Jitter::Exp { mean }) => parts.push(format!("+ exp:{} ms", mean * 1e3)),
        None => {}
    }
    let mut text = parts.join(" ");
    if s.loss > 0.0 {
        text.push_str(&format!(", loss {} %", s.loss * 100.0));
    }
    if let Some(b) = s.burst {
        text.push_str(&format!(", bursts {},{}", b.p, b.r));
    }
    text
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

/// `tilting live`.
pub fn run(args: &LiveArgs) -> Result<(), CommandError> {
    tilting_net::init_tracing("warn");
    check_seconds("--duration", args.duration, false)?;
    let (lo, hi) = tilting_plant::node::PERIOD_RANGE;
    if !(args.rate.is_finite() && (1.0 / hi..=1.0 / lo).contains(&args.rate)) {
        return Err(CommandError::Usage(anyhow!(
            "invalid `--rate` = {}: allowed {} to {} Hz",
            args.rate,
            1.0 / hi,
            1.0 / lo
        )));
    }
    let impairment = args
        .network
        .impairment(args.max_age)
        .map_err(|e| CommandError::Usage(e.into()))?;
    if args.max_age > MAX_AGE {
        return Err(CommandError::Usage(anyhow!(
            "invalid `--max-age` = {}: allowed 0 to {MAX_AGE} periods",
            args.max_age
        )));
    }
    if args.port == Some(0) {
        return Err(CommandError::Usage(anyhow!(
            "invalid `--port` = 0: allowed 1 to 65535 (omit it for a free port)"
        )));
    }
    let keys = Keys::new(&args.robot).map_err(|e| CommandError::Usage(anyhow!("--robot: {e}")))?;
    if let Some(c) = &args.certs {
        security::read_manifest(c, keys.robot())
            .map_err(|e| CommandError::Usage(e.context(format!("--certs {}", c.display()))))?;
    }
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
        .block_on(live(
            args, keys, reference, impairment, &bins, &dir, signals,
        ))
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
    impairment: Option<tilting_link::Impairment>,
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
    let recorder = Recorder::create(dir, &keys, args.csv)?;
    let period = 1.0 / args.rate;
    eprintln!(
        "live: {} s at {} Hz in real time, robot {}; law: {}",
        args.duration,
        args.rate,
        keys.robot(),
        describe(&reference)
    );
    eprintln!("live: recording to {}", dir.display());
    if let Some(imp) = &impairment {
        eprintln!(
            "live: the plant emulates the link: states {}; torques {}; seed {}, --max-age {}",
            describe_link(&imp.state),
            describe_link(&imp.torque),
            imp.seed,
            args.max_age
        );
    }
    // The nominal orbit the run is judged against (`tilting plan margins`' criterion): the
    // same law at 1 kHz over a perfect network, simulated here (about 0.1 s).
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
    let criteria = Criteria::default();
    let check = {
        let (sc, c) = (scenario.clone(), criteria);
        let nominal = tokio::task::spawn_blocking(move || margins::nominal_peak(&sc, &c))
            .await
            .context("the nominal orbit")?;
        (nominal > 0.0).then_some(OrbitCheck { nominal, criteria })
    };
    if check.is_none() {
        eprintln!("live: the law has no nominal orbit to compare with (no orbit verdict)");
    }

    // 0. With --secure: the certificates and the router every node connects to.
    let mut secure = match args.secure {
        false => None,
        true => Some(start_router(args, &keys, bins, dir).await?),
    };
    // The session flags of `node`: its certificate and the router, or loopback peers.
    let session_flags = |node: &str, listen: u16, connect: &[u16]| -> Vec<String> {
        match &secure {
            Some(s) => vec![
                "--zenoh-config".into(),
                s.certs.join(format!("{node}.json5")).display().to_string(),
                "--connect".into(),
                s.endpoint.clone(),
            ],
            None => {
                let mut v = vec!["--listen".into(), endpoint(listen)];
                for c in connect {
                    v.extend(["--connect".into(), endpoint(*c)]);
                }
                v
            }
        }
    };

    let router_endpoint = secure.as_ref().map(|s| s.endpoint.clone());

    // 1. The plant; it publishes state 0 until a controller shows up.
    let mut plant_args: Vec<String> = vec!["--robot".into(), keys.robot().into()];
    plant_args.extend(session_flags("plant", plant_port, &[]));
    plant_args.extend([
        "--rate".into(),
        args.rate.to_string(),
        "--duration".into(),
        args.duration.to_string(),
    ]);
    if let Some(l) = (reference.torque_limit > 0.0).then_some(reference.torque_limit) {
        // The controller saturates already; the plant's hard limit is the same.
        plant_args.extend(["--torque-limit".into(), l.to_string()]);
    }
    plant_args.extend(["--max-age".into(), args.max_age.to_string()]);
    if impairment.is_some() {
        plant_args.extend(network_flags(&args.network));
    }
    let mut plant = Child::spawn("plant", &bins.plant, &plant_args, dir)?;

    // 2. The planner's session: subscribers first, then the reference publisher.
    let zargs = match &secure {
        Some(s) => ZenohArgs {
            zenoh_config: Some(s.certs.join("planner.json5")),
            ..ZenohArgs::new(keys.robot(), &[], &[&s.endpoint])
        },
        None => ZenohArgs::new(
            keys.robot(),
            &[&endpoint(my_port)],
            &[&endpoint(plant_port)],
        ),
    };
    let session = tilting_net::open_session(&zargs, Role::Peer).await?;
    let latest: LatestStatus = Arc::default();
    let counters = [
        keys.plant_state(),
        keys.controller_torque(),
        keys.plant_event(),
        keys.plant_status(),
        keys.planner_reference(),
    ]
    .map(|k| Arc::new(DropCounter::new(k)));
    let tx = recorder.sender();
    let state_sub = subscribe_decoded(&session, counters[0].clone(), move |m: PlantState| {
        tx.send(Record::State(m))
    })
    .await?;
    let tx = recorder.sender();
    let torque_sub = subscribe_decoded(&session, counters[1].clone(), move |m: TorqueCommand| {
        tx.send(Record::Torque(m))
    })
    .await?;
    let tx = recorder.sender();
    let event_sub = subscribe_decoded(&session, counters[2].clone(), move |m: ModeEvent| {
        tx.send(Record::Event(m))
    })
    .await?;
    let l = latest.clone();
    let tx = recorder.sender();
    let status_sub = subscribe_decoded(&session, counters[3].clone(), move |m: Status| {
        tx.send(Record::Status(m.clone()));
        *l.lock().unwrap_or_else(|e| e.into_inner()) = Some(m)
    })
    .await?;
    let tx = recorder.sender();
    let reference_sub = subscribe_decoded(&session, counters[4].clone(), move |m: Reference| {
        tx.send(Record::Reference(m))
    })
    .await?;
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
        let mut ctl_args: Vec<String> = vec!["--robot".into(), keys.robot().into()];
        ctl_args.extend(session_flags(
            "controller",
            ctl_port,
            &[plant_port, my_port],
        ));
        ctl_args.extend(LawArgs::controller_flags(&reference));
        match args.predict {
            Some(tilting_controller::predict::Predict::Estimated) => {
                ctl_args.extend(["--predict".into(), "auto".into()]);
            }
            Some(tilting_controller::predict::Predict::Given(d)) => {
                ctl_args.extend(["--predict".into(), d.to_string()]);
            }
            None => {}
        }
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
            let view = recorder.view();
            let verdict = check.zip(st.as_ref()).map(|(c, st)| {
                let fault = (!st.fault.is_empty()).then_some(st.fault.as_str());
                let peaks: Vec<(f64, f64)> = view.peaks.iter().copied().collect();
                c.judge(&peaks, st.time, st.watchdog_trips, fault)
            });
            let line = status_line(
                st.as_ref(),
                &view,
                recorder.dropped(),
                impairment.is_some(),
                verdict.as_ref(),
            );
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
            plant.stderr_path().display()
        )),
        End::Timeout => problems.push(format!(
            "the plant did not finish within {} s of wall-clock time",
            args.duration + 30.0
        )),
    }
    let (plant_status, plant_killed) = tokio::task::block_in_place(|| plant.stop(&force));
    let ctl_status = controller
        .as_mut()
        .map(|c| tokio::task::block_in_place(|| c.stop(&force)));
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

    // 6. Let the last messages arrive, then close the recording (and stop the router).
    tokio::time::sleep(Duration::from_millis(150)).await;
    let (puts, queries) = (publisher.puts(), publisher.queries_answered());
    drop((
        state_sub,
        torque_sub,
        event_sub,
        status_sub,
        reference_sub,
        publisher,
    ));
    let _ = session.close().await;
    if let Some(mut s) = secure.take() {
        let (status, killed) = tokio::task::block_in_place(|| s.router.stop(&force));
        if killed || !status.success() {
            problems.push(format!(
                "the router exited with {status} (see {})",
                s.router.stderr_path().display()
            ));
        }
    }
    let dropped = recorder.dropped();
    let view = recorder.finish()?;
    let last_status = latest.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let plant_summary: Option<PlantSummary> = plant.summary();
    let ctl_summary: Option<ControllerSummary> = controller.as_ref().and_then(Child::summary);
    let fault = plant_summary
        .as_ref()
        .and_then(|s| s.fault.clone())
        .or_else(|| {
            last_status
                .as_ref()
                .filter(|s| !s.fault.is_empty())
                .map(|s| s.fault.clone())
        });
    for child in std::iter::once(&plant).chain(controller.as_ref()) {
        let failed = child.status().is_some_and(|s| !s.success());
        if failed {
            eprintln!(
                "--- last lines of {} ({}) ---\n{}",
                child.name(),
                child.stderr_path().display(),
                child.log_tail(15)
            );
        }
    }

    // 7. The figure and the summary.
    let png = dir.join(record::RUN_PNG);
    let early = fault.is_some() || !problems.is_empty();
    let plot_result = if view.states > 0 {
        record::plot_recording(dir, &png, &scenario, early)
    } else {
        Err(anyhow!("no state was recorded"))
    };
    if let Err(e) = &plot_result {
        problems.push(format!("cannot draw {}: {e:#}", png.display()));
    }
    // The last seconds of the run, moving, beside the figure.
    if view.states > 0 {
        let gif = dir.join("run.gif");
        if let Err(e) = crate::commands::animate::live_clip(dir, &gif, &scenario.params) {
            problems.push(format!("cannot animate {}: {e:#}", gif.display()));
        }
    }
    // The orbit verdict from the plant's own peaks (every tilt, not the sampled states), or
    // the recording's without a plant summary.
    let orbit = check.map(|c| match &plant_summary {
        Some(p) => {
            let peaks: Vec<(f64, f64)> = p.tilt_peaks.iter().map(|x| (x[0], x[1])).collect();
            c.judge(&peaks, p.time, p.watchdog_trips, fault.as_deref())
        }
        None => {
            let peaks: Vec<(f64, f64)> = view.peaks.iter().copied().collect();
            let now = view.last_state.map_or(0.0, |s| s.time);
            let trips = last_status.as_ref().map_or(0, |s| s.watchdog_trips);
            c.judge(&peaks, now, trips, fault.as_deref())
        }
    });
    let ok = problems.is_empty();
    let result = match (&end, ok) {
        (End::Interrupted, true) => LiveResult::Interrupted,
        (_, true) => LiveResult::Completed,
        (_, false) => LiveResult::Failed,
    };
    let summary = LiveSummary {
        result,
        problems: problems.clone(),
        duration: args.duration,
        rate: args.rate,
        robot: keys.robot().to_owned(),
        out: dir.to_path_buf(),
        reference: LawRecord::from(&reference),
        endpoints: match &router_endpoint {
            Some(ep) => Endpoints {
                plant: String::new(),
                controller: String::new(),
                planner: String::new(),
                router: Some(ep.clone()),
            },
            None => Endpoints {
                plant: endpoint(plant_port),
                controller: endpoint(ctl_port),
                planner: endpoint(my_port),
                router: None,
            },
        },
        record: RecordCounts {
            states: view.states,
            torques: view.torques,
            events: view.events,
            statuses: view.statuses,
            references: view.references,
            csv: args.csv,
            tilts: view.tilts,
            dropped,
            missing_states: view.missing_states,
            repeated_states: view.repeated_states,
            repeated_torques: view.repeated_torques,
            invalid: counters.iter().map(|c| c.dropped()).sum(),
            peaks: view.peaks.iter().map(|p| [p.0, p.1]).collect(),
        },
        planner: PlannerCounts {
            puts,
            queries_answered: queries,
        },
        png: plot_result.is_ok(),
        plant_exit: plant_status.to_string(),
        controller_exit: ctl_status.map(|s| s.0.to_string()),
        plant: plant_summary,
        controller: ctl_summary,
        orbit,
    };
    let summary_path = dir.join("summary.json");
    let text = serde_json::to_string_pretty(&summary).context("cannot serialise the summary")?;
    std::fs::write(&summary_path, format!("{text}\n"))
        .with_context(|| format!("cannot write {}", summary_path.display()))?;
    print!(
        "{}",
        summary.report(&view, last_status.as_ref(), fault.as_deref())
    );
    let _ = std::io::stdout().flush();
    for p in &problems {
        eprintln!("live: error: {p}");
    }
    Ok(ok)
}

/// The router of a `--secure` run.
struct Secure {
    /// The certificate directory (its `{node}.json5` files).
    certs: PathBuf,
    /// The router's endpoint, `tls/127.0.0.1:{port}`.
    endpoint: String,
    /// The `tilting-router` child.
    router: Child,
}

/// Finds or creates the certificates, starts `tilting-router` on a free loopback port and
/// waits until it listens (the nodes, clients, give up at once when no router answers).
async fn start_router(
    args: &LiveArgs,
    keys: &Keys,
    bins: &NodeBinaries,
    dir: &Path,
) -> anyhow::Result<Secure> {
    let certs = match &args.certs {
        Some(c) => {
            // Checked by `run` already.
            c.canonicalize()
                .with_context(|| format!("--certs {}", c.display()))?
        }
        None => {
            let c = dir.join("certs");
            security::generate(keys, &c, &[], security::DEFAULT_ROUTER_ENDPOINT, &[])?;
            c.canonicalize()?
        }
    };
    let endpoint = format!("tls/127.0.0.1:{}", free_port()?);
    let mut router = Child::spawn(
        "router",
        &bins.router,
        &[
            "--config".into(),
            certs.join("router.json5").display().to_string(),
            "--listen".into(),
            endpoint.clone(),
        ],
        dir,
    )?;
    let t0 = Instant::now();
    while !router.stdout().contains("\"ready\"") {
        if let Some(s) = router.try_wait() {
            anyhow::bail!(
                "the router exited at start with {s}:\n{}",
                router.log_tail(15)
            );
        }
        if t0.elapsed() > Duration::from_secs(10) {
            anyhow::bail!(
                "the router did not start within 10 s (see {})",
                router.stderr_path().display()
            );
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    eprintln!(
        "live: secure: router on {endpoint}, certificates in {}",
        certs.display()
    );
    Ok(Secure {
        certs,
        endpoint,
        router,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser as _;

    #[derive(clap::Parser)]
    struct Flags {
        #[command(flatten)]
        net: NetworkArgs,
    }

    /// The flags handed to the plant say what the user's flags say: parsed again, they give
    /// the same impairment (both directions, every field, the seed).
    #[test]
    fn network_flags_round_trip() {
        for argv in [
            &["--delay", "0.002"][..],
            &["--jitter", "exp:0.0005", "--loss", "0.05", "--seed", "9"][..],
            &[
                "--state-delay",
                "0.001",
                "--torque-jitter",
                "normal:0.0003",
                "--loss-burst",
                "0.01,0.25",
                "--torque-loss",
                "0.125",
                "--state-jitter",
                "uniform:0.004",
                "--torque-delay",
                "0.0015",
            ][..],
        ] {
            let given = Flags::try_parse_from(std::iter::once("x").chain(argv.iter().copied()))
                .unwrap()
                .net;
            let flags = network_flags(&given);
            let again =
                Flags::try_parse_from(std::iter::once("x".to_owned()).chain(flags.iter().cloned()))
                    .unwrap()
                    .net;
            let (a, b) = (given.impairment(10).unwrap(), again.impairment(10).unwrap());
            assert!(a.is_some(), "{argv:?}");
            assert_eq!(a, b, "{argv:?} -> {flags:?}");
        }
    }
}
