//! A robot live on the network. [`run`] is `tilting live`, the main job in one command (below);
//! the tools that look at a running robot, ours or not, are here too: [`topics`] (`tilting echo`,
//! `tilting hz`), [`recording`] (`tilting record`, `replay`, `info`) and [`view`] (`tilting view`,
//! `replay --foxglove`, over [`foxglove`]) and [`bridge`] (`tilting ros2 bridge`, `tilting ros2
//! urdf`). Each takes its clap flags and returns a
//! [`LiveError`], which the front door maps to an exit code.
//!
//! `tilting live` starts the plant (`tilting-plant`) and
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
//!   topics; with `--csv` also `state.csv`, `torque.csv`, `events.csv`, see [`record`]),
//!   `run.png`, `run.gif` (the last 8 s, moving), `summary.json` ([`summary`]), `robot.toml`
//!   (the robot file with the flags given over it, as `tilting config` prints it), and the
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
//! made in `OUT/certs`), every link is mutual TLS and each session that accepts links holds
//! access control ([`tilting_launch`]): the plant listens on its own TLS endpoint, the
//! controller dials it, the recorder (a session of its own with the logger's identity) listens
//! on another and dials the plant, and the controller dials it too; a `tilting-router` child
//! carries the rest (the in-process planner, with the planner's identity, is its client) and
//! none of the loop's messages.
//!
//! The topology without `--secure`: the plant listens on its port; the in-process planner session listens on its
//! own port and connects to the plant; the controller listens on a third port and connects to
//! both. The children are started and stopped by [`tilting_launch`].
//!
//! The run is a composition of its steps, one module each: `nodes` (spawn the router, the plant
//! and the controller, which read the run's robot file), `tap` (the planner's
//! session: record the five topics, publish the reference), `monitor` (status line and health),
//! `shutdown` (stop the children in order) and `report` (figure, `summary.json`, report).

#![warn(missing_docs)]

pub mod bridge;
mod error;
pub mod foxglove;
pub mod host;
mod monitor;
mod nodes;
mod orbit;
pub mod out;
pub mod record;
pub mod recording;
mod report;
pub mod ros2;
mod shutdown;
pub mod status;
pub mod summary;
mod tap;
pub mod topics;
pub mod view;

pub use error::LiveError;

use anyhow::{anyhow, Context as _};
use monitor::{Signals, Watch};
use nodes::Topology;
use record::Recorder;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tap::Tap;
use tilting_controller::LawSpec;
use tilting_launch as security;
use tilting_launch::{utc_timestamp, NodeBinaries};
use tilting_link::{Impairment, Jitter, LinkSpec, NetworkArgs};
use tilting_planner::node::{check_seconds, PlannerLawArgs};
use tilting_proto::Keys;
use tilting_sim::robot::RobotFile;

/// Flags of `tilting live`.
#[derive(Debug, Clone, clap::Args)]
pub struct LiveArgs {
    /// The robot file (TOML, docs/guide/robot-file.md): its keys are the defaults of these
    /// flags, a flag given as well overrides its key [default: none]
    #[arg(value_name = "ROBOT.toml")]
    pub robot_file: Option<PathBuf>,
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
    /// Host mode: these robots (1 to 32 distinct names, comma-separated, each with its keys
    /// tilting/NAME/...) from ONE plant process (`tilting-plant --robots`) and ONE controller
    /// process (`tilting-controller --robots`); each robot gets its own recording, status
    /// line, report, orbit verdict and summary.json in OUT/NAME/. Not with --secure,
    /// --plant-cmd, --ros2 or --foxglove
    #[arg(
        long,
        value_name = "A,B,...",
        value_delimiter = ',',
        conflicts_with = "robot"
    )]
    pub robots: Vec<String>,
    /// Pace the plant by the controller's answers instead of the wall clock (the plant's
    /// `--clock lockstep`): each period waits for its torque, so the run is the same bit for
    /// bit however loaded the machine; --duration is plant time. Not with --plant-cmd
    #[arg(long)]
    pub lockstep: bool,
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
    pub law: PlannerLawArgs,
    /// An impaired link between plant and controller, emulated by the plant on the wall clock
    /// (the flags of `simulate`).
    #[command(flatten)]
    pub network: NetworkArgs,
    /// The plant's --max-age: it applies the newest torque answering a state at most this many
    /// periods old
    #[arg(long, default_value_t = tilting_plant::node::DEFAULT_MAX_AGE, value_name = "PERIODS")]
    pub max_age: u64,
    /// The controller's --predict.
    #[command(flatten)]
    pub predict: tilting_controller::predict::PredictArgs,
    /// The controller's --estimator.
    #[command(flatten)]
    pub estimator: tilting_controller::EstimatorArgs,
    /// The plant's sensors and actuator (`--measure angles`, noise, encoder, ...), as in
    /// `simulate`; the noise draws from --seed.
    #[command(flatten)]
    pub imperfect: tilting_plant::imperfect::ImperfectArgs,
    /// The controller's model (TOML, the keys of docs/model.md, e.g. `tilting identify
    /// --out`); also the robot the plant simulates unless --plant-params [default: the
    /// paper's]
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    /// The robot the plant simulates (TOML), when it differs from the controller's model
    /// [default: --params]
    #[arg(long, value_name = "FILE.toml")]
    pub plant_params: Option<PathBuf>,
    /// Run the plant and the controller under SCHED_FIFO at this priority (1-99; 20 when the
    /// flag has no value): every thread of both, so other work on a busy machine cannot delay
    /// the loop. Needs root, CAP_SYS_NICE or an rtprio limit (`ulimit -r`) of at least it
    #[arg(long, value_name = "1-99", num_args = 0..=1, default_missing_value = "20")]
    pub realtime: Option<i32>,
    /// Run this command as the plant instead of `tilting-plant` (a MuJoCo model, a real robot's
    /// driver): a shell command line, run as `sh -c 'exec CMD "$@"'` with the flags
    /// `tilting-plant` would get appended (session, ids, rate, duration, ...; docs/mujoco.md).
    /// Its stdout is `plant.json` (its last JSON line the summary), its stderr `plant.log`
    #[arg(long, value_name = "CMD")]
    pub plant_cmd: Option<String>,
    /// Where the plant starts a planned orbit (--plan, --orbit-start): `orbit`, at its
    /// lift-off, or `rest`, the plate flat and the arm upright at rest, from where the law
    /// launches the orbit (its re-entry motion, about 2 s) as a robot standing on the floor
    /// starts [default: rest with --plant-cmd, else orbit]
    #[arg(long, value_name = "orbit|rest", value_parser = ["orbit", "rest"])]
    pub start: Option<String>,
    /// `--ros2`: the plant as a ROS 2 node too.
    #[command(flatten)]
    pub ros2: ros2::LiveRos2Args,
    /// Serve the run to Foxglove (`crate::foxglove`).
    #[command(flatten)]
    pub foxglove: foxglove::FoxgloveArgs,
}

impl LiveArgs {
    /// The plant's and the controller's parameter files, absolute (the children run in the
    /// output directory).
    pub(crate) fn params_files(&self) -> (Option<PathBuf>, Option<PathBuf>) {
        let abs = |p: &PathBuf| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        let ctl = self.params.as_ref().map(abs);
        let plant = self.plant_params.as_ref().map(abs).or_else(|| ctl.clone());
        (plant, ctl)
    }
}

/// Largest `--max-age` (periods), as the plant allows.
const MAX_AGE: u64 = tilting_link::MAX_AGE;

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

/// A live run as `run` checked it: the flags, and what they resolve to.
struct Job<'a> {
    /// The flags.
    args: &'a LiveArgs,
    /// The robot's keys.
    keys: Keys,
    /// The law, published by the planner and given to the controller.
    reference: LawSpec,
    /// The link the plant emulates, if impaired.
    impairment: Option<Impairment>,
    /// Why most torques may come too late over that link ([`Impairment::check_round_trip`]).
    link_warning: Option<String>,
    /// The output directory.
    dir: PathBuf,
    /// The zenoh ids the plant and the controller are started with (`--zenoh-id`), drawn at
    /// random before either starts: each node, the recorder and the status line believe the
    /// other's messages only from that session, from the first message on.
    ids: tilting_record::Sources,
}

impl Job<'_> {
    /// The plausibility rules of the recording and the status line: the plant's own
    /// (`tilting_proto::plausible`), with this run's period, the plant's torque bound and fall
    /// angle; the plant starts after the recorder.
    fn rules(&self) -> tilting_record::Rules {
        tilting_record::Rules {
            period: Some(1.0 / self.args.rate),
            min_period: tilting_plant::node::PERIOD_RANGE.0,
            max_torque: tilting_plant::node::DEFAULT_MAX_TORQUE,
            fall_angle: tilting_plant::SimConfig::default().fall_angle,
            from_start: true,
        }
    }

    /// The controller's model and the robot the plant simulates (checked by `check`; the
    /// paper's without a file).
    fn params(&self) -> (tilting_plant::Params, tilting_plant::Params) {
        let (_, ctl) = self.args.params_files();
        let model = ctl
            .and_then(|f| tilting_plant::Params::from_toml_file(&f).ok())
            .unwrap_or_default();
        (model, self.plant_params())
    }

    /// The robot of the nominal run the orbit verdict compares with: the controller's model
    /// and the plant's parameters; with an external plant (`--plant-cmd`), whose landings are
    /// its own physics and not the landing law of its parameter file (MuJoCo's file names the
    /// geometry only), the plant landing by the model's law and restitution, the best account
    /// of them there is (identified from the robot: `identify --out`).
    fn nominal_params(&self) -> (tilting_plant::Params, tilting_plant::Params) {
        let (model, plant) = self.params();
        if self.args.plant_cmd.is_some() {
            (model, lands_as_modelled(&model, plant))
        } else {
            (model, plant)
        }
    }

    /// The recorder of this robot's run, into its directory.
    fn recorder(&self) -> anyhow::Result<Recorder> {
        Recorder::create(
            &self.dir,
            &self.keys,
            self.args.csv,
            Some(self.rules()),
            self.ids,
        )
        .map_err(Into::into)
    }

    /// The nominal run the orbit verdict compares with, and the check (said on stderr when
    /// the law has no orbit to compare with).
    async fn nominal(&self) -> anyhow::Result<(tilting_sim::Scenario, Option<orbit::OrbitCheck>)> {
        let (scenario, check) = orbit::nominal(
            &self.reference,
            self.nominal_params(),
            (self.args.rate, self.args.duration),
            self.args.law.plan.as_deref(),
        )
        .await?;
        if check.is_none() {
            eprintln!("live: the law has no nominal orbit to compare with (no orbit verdict)");
        }
        Ok((scenario, check))
    }

    /// The robot the plant simulates (checked by `check`; the paper's without a file).
    fn plant_params(&self) -> tilting_plant::Params {
        let (plant, _) = self.args.params_files();
        plant
            .and_then(|f| tilting_plant::Params::from_toml_file(&f).ok())
            .unwrap_or_default()
    }
}

/// `plant` landing by `model`'s law and restitution.
fn lands_as_modelled(
    model: &tilting_plant::Params,
    plant: tilting_plant::Params,
) -> tilting_plant::Params {
    tilting_plant::Params {
        impact: model.impact,
        restitution: model.restitution,
        ..plant
    }
}

/// An I/O error in words, naming ENOSPC for a full disk.
pub(crate) fn describe_io(e: &std::io::Error) -> String {
    if e.kind() == std::io::ErrorKind::StorageFull {
        format!("{e} (ENOSPC: the disk is full)")
    } else {
        e.to_string()
    }
}

/// `tilting live`: checks `args`, runs the robot live until `--duration` s of plant time (or
/// Ctrl-C), and writes the recording and the report into the output directory. `robot` is the
/// robot file given at the front door, its keys merged under the flags (`tilting config`), if
/// any; it is written with the flags over it to `OUT/robot.toml`, which the nodes read.
pub fn run(args: &LiveArgs, robot: Option<&RobotFile>) -> Result<(), LiveError> {
    tilting_net::init_tracing("warn");
    if !args.robots.is_empty() {
        return host::run(args, robot);
    }
    let job = check(args)?;
    let bins = NodeBinaries::next_to_current_exe().map_err(LiveError::Failed)?;
    prepare(&job, robot)?;
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    let signals = Signals::start(&rt);
    let ending = rt
        .block_on(live(&job, &bins, signals))
        .map_err(LiveError::Failed)?;
    ending_result(ending, &job.dir)
}

/// Creates `job`'s directory and writes its robot file there: the file given (`robot`, if
/// any) with the flags over it and the law resolved (`nodes::run_file`), which the nodes read.
fn prepare(job: &Job, robot: Option<&RobotFile>) -> Result<(), LiveError> {
    std::fs::create_dir_all(&job.dir)
        .with_context(|| format!("cannot create the output directory {}", job.dir.display()))
        .map_err(LiveError::Failed)?;
    let file = nodes::run_file(job, robot)
        .map_err(|e| LiveError::Failed(anyhow!("the run's robot file: {e}")))?;
    std::fs::write(&file.path, file.to_toml_string())
        .with_context(|| format!("cannot write {}", file.path.display()))
        .map_err(LiveError::Failed)?;
    Ok(())
}

/// The run's ending as `run` returns it (the exit code's error), naming the logs in `dir`.
fn ending_result(ending: report::Ending, dir: &Path) -> Result<(), LiveError> {
    let logs = dir.display();
    match ending {
        report::Ending::Clean => Ok(()),
        report::Ending::Failed => Err(LiveError::Failed(anyhow!(
            "the live run did not end cleanly (see above; logs in {logs})"
        ))),
        report::Ending::Fault => Err(LiveError::Fault(anyhow!(
            "the live run ended on a fault of the model (see above; logs in {logs})"
        ))),
        report::Ending::OrbitLost => Err(LiveError::OrbitLost(anyhow!(
            "the live run lost the orbit (see the verdict above; logs in {logs})"
        ))),
    }
}

/// Checks the flags (usage errors) and resolves the law.
fn check(args: &LiveArgs) -> Result<Job<'_>, LiveError> {
    let usage = LiveError::Usage;
    check_seconds("--duration", args.duration, false)?;
    args.ros2.check(&args.robot, args.secure)?;
    let (lo, hi) = tilting_plant::node::PERIOD_RANGE;
    if !(args.rate.is_finite() && (1.0 / hi..=1.0 / lo).contains(&args.rate)) {
        return Err(usage(anyhow!(
            "invalid `--rate` = {}: allowed {} to {} Hz",
            args.rate,
            1.0 / hi,
            1.0 / lo
        )));
    }
    let impairment = args
        .network
        .impairment(args.max_age)
        .map_err(|e| usage(e.into()))?;
    if args.max_age > MAX_AGE {
        return Err(usage(anyhow!(
            "invalid `--max-age` = {}: allowed 0 to {MAX_AGE} periods",
            args.max_age
        )));
    }
    // A link whose round trip outlasts --max-age: refused when no torque can arrive in time,
    // a warning (printed at the start) when only its jitter makes most of them late.
    let link_warning = match &impairment {
        Some(imp) => imp
            .check_round_trip(1.0 / args.rate)
            .map_err(|e| usage(e.into()))?,
        None => None,
    };
    if let Some(tilting_sim::Predict::Given(d)) = args.predict.predict {
        // The controller predicts over `d`; the plant drops torques older than --max-age.
        tilting_sim::network::check_max_age(d, 1.0 / args.rate, args.max_age)
            .map_err(|e| usage(e.into()))?;
    }
    if let Some(p) = args.realtime {
        if !(1..=99).contains(&p) {
            return Err(usage(anyhow!(
                "invalid `--realtime` = {p}: allowed 1 to 99"
            )));
        }
        tilting_launch::check_fifo(p).map_err(|e| usage(e.context("--realtime")))?;
    }
    if args.plant_cmd.as_ref().is_some_and(|c| c.trim().is_empty()) {
        return Err(usage(anyhow!(
            "invalid `--plant-cmd` = \"\": give a command, e.g. \"python3 -m tilting_mujoco\""
        )));
    }
    if args.lockstep && args.plant_cmd.is_some() {
        return Err(usage(anyhow!(
            "`--lockstep` paces tilting-plant by its controller (`--clock lockstep`): not with \
             `--plant-cmd`, whose plant keeps its own clock"
        )));
    }
    if args.port == Some(0) {
        return Err(usage(anyhow!(
            "invalid `--port` = 0: allowed 1 to 65535 (omit it for a free port)"
        )));
    }
    let keys = Keys::new(&args.robot).map_err(|e| usage(anyhow!("--robot: {e}")))?;
    if let Some(c) = &args.certs {
        security::read_manifest(c, keys.robot())
            .map_err(|e| usage(e.context(format!("--certs {}", c.display()))))?;
    }
    for (flag, f) in [
        ("--params", &args.params),
        ("--plant-params", &args.plant_params),
    ] {
        if let Some(f) = f {
            tilting_plant::Params::from_toml_file(f)
                .map_err(|e| usage(anyhow!("invalid `{flag}` = {}: {e}", f.display())))?;
        }
    }
    let reference = args.law.resolve()?;
    args.foxglove.check()?;
    args.imperfect
        .imperfections(args.network.seed)
        .map_err(|e| usage(e.into()))?;
    let dir = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("runs").join(utc_timestamp()));
    Ok(Job {
        args,
        keys,
        reference,
        impairment,
        link_warning,
        dir,
        ids: tilting_record::Sources {
            plant: Some(tilting_net::random_source_id()),
            controller: Some(tilting_net::random_source_id()),
        },
    })
}

/// What `live` says before it starts.
fn announce(job: &Job) {
    let args = job.args;
    let robots = if args.robots.is_empty() {
        format!("robot {}", job.keys.robot())
    } else {
        format!("robots {}", args.robots.join(", "))
    };
    eprintln!(
        "live: {} s at {} Hz {}, {robots}; law: {}",
        args.duration,
        args.rate,
        if args.lockstep {
            "in lockstep"
        } else {
            "in real time"
        },
        job.reference
    );
    eprintln!("live: recording to {}", job.dir.display());
    if let (Some(p), Some(c)) = (job.ids.plant, job.ids.controller) {
        eprintln!(
            "live: zenoh ids: plant {p}, controller {c} (messages from other sessions are \
             refused; `tilting record --plant-id {p} --controller-id {c}` records this run)"
        );
    }
    if let Some(cmd) = &args.plant_cmd {
        eprintln!("live: the plant is `{cmd}` (given the flags of tilting-plant)");
    }
    if let Some(p) = args.realtime {
        eprintln!("live: the plant and the controller run under SCHED_FIFO {p} (every thread)");
    }
    if let Some(imp) = &job.impairment {
        eprintln!(
            "live: the plant emulates the link: states {}; torques {}; seed {}, --max-age {}",
            describe_link(&imp.state),
            describe_link(&imp.torque),
            imp.seed,
            args.max_age
        );
    }
    if let Some(w) = &job.link_warning {
        eprintln!("live: warning: {w}");
    }
}

/// Closes a robot's recording: the messages it dropped and its view (whatever happened to
/// the files, the view comes back: the report and the summary are written in any case); a
/// failed recording is added to `problems`.
fn close_recorder(recorder: Recorder, problems: &mut Vec<String>) -> (u64, record::RecordView) {
    let dropped = recorder.dropped();
    let (view, _) = recorder.close();
    if let Some(e) = &view.error {
        problems.push(format!("the recording failed: {e}"));
    }
    (dropped, view)
}

/// Runs the live job: spawn, record, monitor, shut down, summarise; how it ended (the
/// recording and the summary are written whatever happened).
async fn live(
    job: &Job<'_>,
    bins: &NodeBinaries,
    signals: Signals,
) -> anyhow::Result<report::Ending> {
    let force = signals.force();
    let mut topo = Topology::ports(job)?;
    let recorder = job.recorder()?;
    announce(job);
    let (scenario, check) = job.nominal().await?;

    // Spawn: the router (--secure), the plant, the planner's session (subscribers first, then
    // the reference), and once the plant's state 0 reaches us, the controller.
    if job.args.secure {
        topo.start_router(job, bins).await?;
    }
    let mut fox =
        foxglove::LiveServer::start(&job.args.foxglove, &job.keys, job.plant_params()).await;
    let mut plant = nodes::spawn_plant(job, &topo, bins)?;
    let (record, planner) = topo.front_door_sessions(job.keys.robot())?;
    let tap = Tap::open(
        &record,
        planner.as_ref(),
        &job.keys,
        &recorder,
        job.reference.to_wire(),
    )
    .await?;
    fox.attach(tap.session(), tap.planner_session(), &job.keys)
        .await?;
    let early_end = monitor::wait_for_first_state(&recorder, &mut plant, &signals).await;
    let mut controller = match early_end {
        None => Some(nodes::spawn_controller(job, &topo, bins)?),
        Some(_) => None,
    };

    // Monitor until the run ends.
    let end = match early_end {
        Some(end) => end,
        None => {
            let watch = Watch {
                recorder: &recorder,
                tap: &tap,
                check,
                impaired: job.impairment.is_some(),
                foxglove: &fox,
                robot: None,
            };
            let children = monitor::Children {
                plant: &mut plant,
                controller: controller.as_mut(),
                router: topo.router(),
            };
            monitor::monitor(&[watch], children, &signals, job.args.duration).await
        }
    };

    // Shut down: the children, then (once the last messages arrived) the planner's session, the
    // router and the recording.
    let mut problems = Vec::new();
    let stopped = shutdown::stop_children(
        &end,
        &mut plant,
        controller.as_mut(),
        &force,
        job.args.duration,
        &mut problems,
    );
    tokio::time::sleep(Duration::from_millis(150)).await;
    fox.close().await;
    let closed = tap.close().await;
    problems.extend(topo.stop_router(&force));
    let (dropped, view) = close_recorder(recorder, &mut problems);
    let last_status = view.last_status.clone();
    shutdown::show_failed_logs(&plant, controller.as_ref());
    problems.extend(shutdown::fallback_problems(
        &job.dir,
        &plant,
        controller.as_ref(),
    ));

    let outcome = report::Outcome {
        end,
        problems,
        stopped,
        plant: plant.summary(),
        controller: controller.as_ref().and_then(|c| c.summary()),
        view,
        dropped,
        invalid: closed.invalid,
        last_status,
        planner: closed.planner,
        endpoints: topo.endpoints(),
    };
    report::summarise(job, &scenario, check, outcome)
}

#[cfg(test)]
mod tests {
    use super::lands_as_modelled;
    use tilting_plant::{ImpactLaw, Params};

    #[test]
    fn an_external_plants_nominal_lands_by_the_models_law_with_its_own_geometry() {
        // MuJoCo's parameter file names its geometry and no landing law (the paper's by
        // default); the identified model lands by the physical law with a pass-through.
        let model = Params {
            impact: ImpactLaw::Physical,
            restitution: -0.11,
            m_f: 1.0700002,
            ..Params::default()
        };
        let plant = Params {
            m_f: 1.07,
            i_f: 0.04,
            ..Params::default()
        };
        let p = lands_as_modelled(&model, plant);
        assert_eq!(
            (p.impact, p.restitution, p.m_f, p.i_f),
            (ImpactLaw::Physical, -0.11, 1.07, 0.04)
        );
        p.validate().unwrap();
    }
}
