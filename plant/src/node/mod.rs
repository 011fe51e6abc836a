//! The `tilting-plant` node: integrates the hybrid dynamics paced by the wall clock (or in
//! lockstep with the controller) and speaks the `tilting-proto` topics over zenoh.
//!
//! # The loop
//!
//! The plant publishes `PlantState` `seq = k` at plant time `t_k = k h` (`h` = 1/`--rate`), the
//! controller answers with `TorqueCommand` `seq = k`, and the plant integrates `[t_k, t_{k+1}]`
//! holding that torque (zero-order hold), then publishes `seq = k + 1`. Mode transitions are
//! published on `plant/event` as they happen, the health on `plant/status` at 10 Hz and at every
//! change of its `state`.
//!
//! - `--clock realtime` (default): a dedicated thread sleeps to absolute deadlines
//!   `start + (k + 1) h` (`clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)` with 1 ns timer
//!   slack, then a short spin), and at each deadline integrates the period that just ended
//!   with the torque that answered `seq = k`. If that answer has not arrived (a deadline
//!   miss), the newest torque received stands in for it as long as its age (periods since the
//!   state it answers) is at most `--max-age`; otherwise the torque in force is held. A
//!   real-time run whose answers all arrive in time is therefore the same computation as a
//!   lockstep run.
//! - `--clock realtime` with `--delay`, `--jitter`, `--loss` or `--loss-burst`: the states and
//!   the torques cross links emulated on the wall clock, with the draws of `tilting simulate`
//!   (module `emulation`): a lost message never arrives, a delayed one is published (a state)
//!   or put in the torque inbox (a torque) at its due time, where the `--max-age` rule applies.
//! - `--clock lockstep`: after publishing `seq = k` the plant waits for the torque answering
//!   `seq = k` (re-publishing the state every 100 ms), then integrates: the run is
//!   deterministic and reproduces `tilting simulate --control-period h` bit for bit.
//!
//! # A robot that is not the model
//!
//! With the imperfection flags (`--noise-*`, `--encoder-counts`, `--torque-saturation`,
//! `--torque-lag`, `--mass-error`; [`crate::imperfect`]) the published `PlantState` is the
//! measured state (measured once per `seq`), the torque acts through the actuator, and the arm
//! is off by the mass error, in both clocks. In lockstep this equals `tilting simulate` with the
//! same flags bit for bit. The `--record` CSV keeps the true state and the commanded torque.
//!
//! # Safe mode
//!
//! Without a valid torque at most `--max-age` periods old for `--watchdog` periods (real-time),
//! or for `--lockstep-timeout-ms` (lockstep), or when the controller is gone (its liveliness
//! token absent, and no torque arrived, for `max(--max-age, 2)` periods: 10 ms at 1 kHz; a token
//! that disappears and comes back within that bound is a renegotiated link, counted as
//! `token_losses` in the summary, and the loop goes on), the plant enters the safe mode (`Status.state = 2`): `--safe-mode zero` applies no
//! torque, `--safe-mode hold` (default) a holding computed-torque PD towards `beta = pi/2` with
//! `--safe-kp`/`--safe-kd`. A valid torque within `--max-age` ends it. In lockstep the plant then
//! waits at most 1 ms per period for an answer, so a run without its controller goes on at
//! about real-time speed instead of one period per timeout.
//!
//! The watchdog's count and the safe mode's torque are [`crate::safe`]'s, the rule `tilting
//! simulate` applies to its loop over links too.
//!
//! # Whose torques
//!
//! A torque must pass the plausibility rules (`tilting_proto::plausible`: `--max-torque`, a
//! state already published), and where its source is known (our publishers attach their
//! zenoh session's id: `tilting_proto::source`), come from the controller's session: the first
//! torque believed pins it, and torques from another session are refused, counted
//! (`torques_foreign`) and logged at a bounded rate while it keeps answering; after
//! `--watchdog` periods of silence the pin lapses (a restarted controller is a new session).
//!
//! # Host mode
//!
//! With `--robots A,B,...` (1 to 32 names, [`host`]) one process serves several robots over
//! one zenoh session: each robot has its own keys `tilting/{name}/...`, loop, faults, pins and
//! summary (one JSON line each, `{"robot": NAME, "summary": ...}`), and `--record FILE` writes
//! `FILE-{name}` per robot; the other flags apply to every robot. In real time the robots are
//! paced by a thread each (`--host-pacing each`, their grids shifted by `i/N` of a period) or by
//! one thread (`--host-pacing one`); `--spin-us` defaults to 0 there. A `tilting-controller
//! --robots` with the same names answers them all.
//!
//! # End of a run
//!
//! After `--duration` plant seconds (status `stopped`, exit code 0), at Ctrl-C/SIGTERM
//! (`stopped`, 0), or at a fault of the model (fall, contact loss, Zeno, non-finite torque:
//! the event and a `faulted` status with the reason are published, exit code
//! [`EXIT_FAULT`]). A JSON summary of the run is printed on stdout; if stdout fails (a full
//! disk, a closed pipe), it goes to `$TMPDIR/tilting-plant-{pid}-summary.json` instead, said on
//! stderr (`tilting_net::say_summary`).

mod args;
pub mod clock;
mod control_loop;
/// CSV files written by whole rows (the recordings' [`tilting_record::csv`]).
pub use tilting_record::csv;
mod emulation;
pub mod host;
mod inbox;
mod recording;
mod ros2;
pub mod stats;
pub mod summary;

use std::collections::VecDeque;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use tilting_net::{DropCounter, Qos, Role, TypedPublisher, ZenohArgs};
use tilting_proto::{Keys, ModeEvent, PlantState, Status, TorqueCommand};

use crate::{
    paper, Fault, ImpactLaw, Mode, Observer, Plant, SimConfig, State, TiltPeak, Tolerance,
    Transition,
};
pub use args::{
    ClockMode, HostPacing, PlantArgs, DEFAULT_MAX_AGE, DEFAULT_MAX_TORQUE, MAX_PERIODS,
    MAX_SPIN_US, PERIOD_RANGE,
};
use control_loop::{Loop, Obs, Outcome, Publishers, TIMING_LOG_INTERVAL};
use inbox::Shared;
use recording::Recording;
pub use ros2::{urdf_geometry, Ros2Summary};
use stats::Ring;
pub use summary::{LinkEmulation, PlantSummary, RunResult, SafeModeEntry, Window};

/// The columns of a state row in every CSV the project writes (the plant's `--record`, the
/// `state.csv` of `tilting live`): sample number, plant time (s), mode byte (0 flat, 1 left,
/// 2 right), then `alpha, beta` (rad) and their rates (rad/s). Defined with the recordings'
/// formats ([`tilting_record::trace::STATE_HEADER`]).
pub const STATE_COLUMNS: &str = tilting_record::trace::STATE_HEADER;

/// Exit code of a run that ended with a fault of the model.
pub const EXIT_FAULT: u8 = 3;

/// Runs the plant node until the end of the run; returns the process exit code. With
/// `--robots` (host mode, [`host`]) one process serves every robot named, one pacing thread
/// each, over one zenoh session; the exit code is [`EXIT_FAULT`] if any robot faulted.
pub fn run(args: PlantArgs) -> anyhow::Result<ExitCode> {
    args.validate()?;
    let hosted = args.host.hosting();
    let all_keys = if hosted {
        host::check(&args)?;
        args.host.keys()?
    } else {
        vec![args.zenoh.keys()?]
    };
    let cfg = args.sim_config()?;
    let x0 = State::from(args.x0.unwrap_or_else(paper::orbit_x0));
    let mut robots = Vec::with_capacity(all_keys.len());
    for keys in all_keys {
        let plant = Plant::new(cfg, 0.0, args.mode, x0).context("initial state")?;
        let record = match &args.record {
            Some(path) if hosted => Some(Recording::create(
                &host::record_path(path, keys.robot()),
                &keys,
            )?),
            Some(path) => Some(Recording::create(path, &keys)?),
            None => None,
        };
        robots.push((keys, plant, record));
    }
    let rt = tilting_net::runtime()?;
    rt.block_on(run_async(args, robots, hosted))
}

/// The state the pacing thread shares with the zenoh callbacks, empty at the start.
fn shared_state(args: &PlantArgs, keys: &Keys) -> Arc<Shared> {
    Arc::new(Shared {
        inbox: Mutex::new(None),
        cv: Condvar::new(),
        current_seq: AtomicU64::new(0),
        published_wall_ns: std::sync::atomic::AtomicI64::new(0),
        torques: DropCounter::new(keys.controller_torque()),
        stale: AtomicU64::new(0),
        controller_alive: AtomicBool::new(false),
        controller_lost_at: AtomicU64::new(0),
        token_losses: AtomicU64::new(0),
        stop: AtomicBool::new(false),
        max_torque: args.max_torque(),
        reordered: AtomicU64::new(0),
        controller: Mutex::new(tilting_proto::SourcePin::expect_or_new(
            args.controller_id,
            Duration::from_secs_f64(args.safe.watchdog as f64 * args.period()),
        )),
        foreign: AtomicU64::new(0),
    })
}

/// One robot being served: what its pacing thread shares and the zenoh
/// declarations that live as long as it runs.
struct Served {
    keys: Keys,
    shared: Arc<Shared>,
    link: Option<Arc<emulation::Emulator>>,
    ros2: Option<ros2::Ros2>,
    _token: zenoh::liveliness::LivelinessToken,
    _subscribers: [zenoh::pubsub::Subscriber<()>; 2],
    _presence: Arc<tilting_net::Presence>,
}

/// Declares robot `keys`' publishers, subscribers and token on `session`, and its pacing loop.
async fn serve(
    session: &zenoh::Session,
    args: &PlantArgs,
    (keys, plant, record): (Keys, Plant, Option<Recording>),
) -> anyhow::Result<(Served, Loop)> {
    let shared = shared_state(args, &keys);
    let ros2 = match args.ros2 {
        Some(_) => Some(ros2::Ros2::start(session, args, shared.clone()).await?),
        None => None,
    };
    let pubs = Arc::new(Publishers {
        state: TypedPublisher::declare(session, keys.plant_state(), Qos::Control).await?,
        event: TypedPublisher::declare(session, keys.plant_event(), Qos::Telemetry).await?,
        status: TypedPublisher::declare(session, keys.plant_status(), Qos::Telemetry).await?,
        ros2: ros2.as_ref().map(|r| r.mirror.clone()),
    });
    // Real time over emulated links: states and torques cross them on the wall clock.
    let impairment = args.network.impairment(args.max_age)?;
    let link = match (impairment, args.clock) {
        (Some(imp), ClockMode::Realtime) => Some(emulation::Emulator::start(
            imp,
            args.spin_ns(),
            args.rt_priority,
            pubs.clone(),
            shared.clone(),
        )?),
        _ => None,
    };
    let sh = shared.clone();
    let l = link.clone();
    let torque_sub = tilting_net::subscribe_sourced(
        session,
        keys.controller_torque(),
        move |b, from| match &l {
            Some(l) => l.send_torque(b, from),
            None => sh.on_torque(b, from),
        },
    )
    .await?;
    let sh = shared.clone();
    let (presence, presence_sub) =
        tilting_net::watch_presence(session, keys.alive_controller(), move |alive| {
            sh.on_controller_token(alive)
        })
        .await?;
    let token = tilting_net::declare_token(session, keys.alive_plant()).await?;

    let lp = new_loop(
        args,
        (plant, record),
        shared.clone(),
        pubs,
        link.clone(),
        impairment,
    )?;
    let served = Served {
        keys,
        shared,
        link,
        ros2,
        _token: token,
        _subscribers: [torque_sub, presence_sub],
        _presence: presence,
    };
    Ok((served, lp))
}

/// The pacing loop of one robot, at its start (no step taken, every counter at zero): the
/// plant `plant` (and its recording `record`) at the period, safe mode, hardware and clock of
/// `args`; `impairment` held in lockstep (a real-time run crosses `link`, the emulated links).
fn new_loop(
    args: &PlantArgs,
    (plant, record): (Plant, Option<Recording>),
    shared: Arc<Shared>,
    pubs: Arc<Publishers>,
    link: Option<Arc<emulation::Emulator>>,
    impairment: Option<tilting_link::Impairment>,
) -> anyhow::Result<Loop> {
    let args = args.clone();
    let h = args.period();
    let safe = args.safe.settings()?;
    let hold = impairment
        .filter(|_| args.clock == ClockMode::Lockstep)
        .map(|imp| imp.hold(args.period()));
    let hw = args.imperfections()?.hardware();
    Ok(Loop {
        args,
        h,
        plant,
        safe,
        watchdog: crate::safe::Watchdog::new(safe.watchdog),
        shared,
        pubs,
        obs: Obs::default(),
        record,
        seq: 0,
        extra_states: 0,
        extra_answers: 0,
        t_pub: 0,
        status_state: Status::STARTING,
        fault: String::new(),
        tau: 0.0,
        applied_seq: None,
        torques_late: 0,
        torques_lost: 0,
        torques_applied: 0,
        hold,
        hw,
        measured: None,
        previous_angles: None,
        link,
        age: Ring::new(),
        deadline_misses: 0,
        last_answer: None,
        safe_modes: Vec::new(),
        overruns: 0,
        step_overrun_max: 0.0,
        jitter: Ring::new(),
        latency: Ring::new(),
        step_cost: Ring::new(),
        next_status: Instant::now(),
        status_interval: Duration::from_millis(100),
        next_timing_log: Instant::now() + TIMING_LOG_INTERVAL,
        // One sample per periodic status (every 100 ms).
        lateness: (stats::Lateness::new(10), false),
        period_t0: 0,
        event_answer: None,
        stagger: None,
    })
}

/// One pacing thread per group of `groups` (all the robots in one when `one`), each running
/// its loops to their end (in one real-time schedule when `one`), saying so on `done_tx`, and
/// answering each loop's outcome and summary.
#[allow(clippy::type_complexity)]
fn spawn_pacing(
    groups: Vec<Vec<Loop>>,
    one: bool,
    done_tx: &tokio::sync::mpsc::UnboundedSender<()>,
) -> anyhow::Result<Vec<std::thread::JoinHandle<Vec<(Outcome, PlantSummary)>>>> {
    let mut pacing = Vec::with_capacity(groups.len());
    for mut group in groups {
        let done = done_tx.clone();
        pacing.push(
            std::thread::Builder::new()
                .name("plant-pacing".into())
                .spawn(move || {
                    let outcomes = if one {
                        Loop::run_all_realtime(&mut group)
                    } else {
                        group.iter_mut().map(Loop::run).collect()
                    };
                    let _ = done.send(());
                    group
                        .iter_mut()
                        .zip(outcomes)
                        .map(|(lp, o)| {
                            let summary = lp.summary(&o);
                            (o, summary)
                        })
                        .collect::<Vec<_>>()
                })
                .context("cannot start the pacing thread")?,
        );
    }
    Ok(pacing)
}

async fn run_async(
    args: PlantArgs,
    robots: Vec<(Keys, Plant, Option<Recording>)>,
    hosted: bool,
) -> anyhow::Result<ExitCode> {
    let session = tilting_net::open_session(&args.zenoh, Role::Plant).await?;
    let mut served = Vec::with_capacity(robots.len());
    let mut loops = Vec::with_capacity(robots.len());
    for robot in robots {
        let (s, lp) = serve(&session, &args, robot).await?;
        served.push(s);
        loops.push(lp);
    }
    // Each pacing thread says on `done` when its runs end; `None` once all have.
    let (done_tx, mut done_rx) = tokio::sync::mpsc::unbounded_channel();
    let one = hosted && args.host_pacing == HostPacing::One;
    let mut groups: Vec<Vec<Loop>> = if one {
        vec![loops]
    } else {
        loops.into_iter().map(|lp| vec![lp]).collect()
    };
    if hosted && !one {
        let n = groups.len() as f64;
        for (i, g) in groups.iter_mut().enumerate() {
            g[0].stagger = Some(i as f64 / n);
        }
    }
    let pacing = spawn_pacing(groups, one, &done_tx)?;
    drop(done_tx);
    let all_done = async { while done_rx.recv().await.is_some() {} };
    tokio::select! {
        _ = tilting_net::shutdown_signal() => {
            tracing::info!("stopping");
            for s in &served {
                s.shared.stop.store(true, Ordering::Release);
                s.shared.wake();
            }
        }
        _ = all_done => {}
    }
    let mut results = Vec::with_capacity(served.len());
    for thread in pacing {
        let r = tokio::task::spawn_blocking(move || thread.join())
            .await
            .context("pacing thread join")?
            .map_err(|_| anyhow::anyhow!("a pacing thread panicked"))?;
        results.extend(r);
    }
    let mut faulted = false;
    let mut lines = Vec::with_capacity(served.len());
    let mut sessions_kept = Vec::with_capacity(served.len());
    for (s, (outcome, mut summary)) in served.into_iter().zip(results) {
        let Served {
            keys,
            link,
            ros2,
            _token,
            ..
        } = s;
        summary.ros2 = ros2.as_ref().map(|r| r.summary());
        if let Some(l) = &link {
            l.stop();
        }
        faulted |= matches!(outcome, Outcome::Faulted(_));
        lines.push(
            if hosted {
                serde_json::to_string(&tilting_net::HostedSummary {
                    robot: keys.robot().to_owned(),
                    summary,
                })
            } else {
                serde_json::to_string(&summary)
            }
            .context("cannot serialise the summary")?,
        );
        sessions_kept.push((_token, ros2));
    }
    // On a full disk or a closed pipe, to a fallback file, said on stderr.
    let _ = tilting_net::say_summary("tilting-plant", &lines.join("\n"));
    // Let the last status and event leave before the session closes.
    tokio::time::sleep(Duration::from_millis(100)).await;
    drop(sessions_kept);
    let _ = session.close().await;
    Ok(if faulted {
        ExitCode::from(EXIT_FAULT)
    } else {
        ExitCode::SUCCESS
    })
}
