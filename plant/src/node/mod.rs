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
//!   with the torque that answered `seq = k`. If that torque has not arrived the previous one
//!   is held (a deadline miss). A real-time run whose answers all arrive in time is therefore
//!   the same computation as a lockstep run.
//! - `--clock lockstep`: after publishing `seq = k` the plant waits for the torque answering
//!   `seq = k` (re-publishing the state every 100 ms), then integrates: the run is
//!   deterministic and reproduces `tilting-planner simulate --control-period h` bit for bit.
//!
//! # Safe mode
//!
//! Without a valid torque for `--watchdog` periods (real-time), or for `--lockstep-timeout-ms`
//! (lockstep), or at once when the controller's liveliness token disappears, the plant enters
//! the safe mode (`Status.state = 2`): `--safe-mode zero` applies no torque, `--safe-mode hold`
//! (default) a holding computed-torque PD towards `beta = pi/2` with `--safe-kp`/`--safe-kd`. A
//! valid torque answering the current state ends it.
//!
//! # End of a run
//!
//! After `--duration` plant seconds (status `stopped`, exit code 0), at Ctrl-C/SIGTERM
//! (`stopped`, 0), or at a fault of the model (fall, contact loss, Zeno, non-finite torque:
//! the event and a `faulted` status with the reason are published, exit code
//! [`EXIT_FAULT`]). A JSON summary of the run is printed on stdout.

pub mod clock;
pub mod stats;
pub mod summary;

use std::collections::VecDeque;
use std::f64::consts::FRAC_PI_2;
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use tilting_net::{DropCounter, Qos, Role, TypedPublisher, ZenohArgs};
use tilting_proto::{Keys, ModeEvent, PlantState, Status, TorqueCommand};

use crate::{
    paper, Fault, ImpactLaw, Mode, Observer, Params, Plant, SimConfig, State, TiltPeak, Tolerance,
    Transition,
};
use stats::Ring;
pub use summary::{PlantSummary, RunResult, Window};

/// The columns of a state row in every CSV the project writes (the plant's `--record`, the
/// `state.csv` of `tilting live`): sample number, plant time (s), mode byte (0 flat, 1 left,
/// 2 right), then `alpha, beta` (rad) and their rates (rad/s).
pub const STATE_COLUMNS: &str = "seq,t,mode,alpha,beta,alpha_dot,beta_dot";

/// Exit code of a run that ended with a fault of the model.
pub const EXIT_FAULT: u8 = 3;

/// How plant time advances.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ClockMode {
    /// Paced by the wall clock, one period per `1/rate` s.
    Realtime,
    /// One period per torque answer: deterministic.
    Lockstep,
}

/// The torque applied in safe mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SafeMode {
    /// No torque.
    Zero,
    /// A holding computed-torque PD towards `beta = pi/2`.
    Hold,
}

/// Flags of `tilting-plant`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "tilting-plant",
    version,
    about = "Simulated tilting plant: integrates the hybrid dynamics in real time (or in lockstep) \
             and publishes its state over zenoh",
    after_help = "Exit codes: 0 run completed or stopped, 1 error, 3 the model faulted (fall, contact loss). \
                  A JSON summary is printed on stdout at the end."
)]
pub struct PlantArgs {
    /// Zenoh and naming flags.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Pace plant time by the wall clock (realtime) or by the controller's answers (lockstep)
    #[arg(long, value_enum, default_value_t = ClockMode::Realtime)]
    pub clock: ClockMode,
    /// Control rate (Hz): one PlantState per period 1/rate
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    pub rate: f64,
    /// Control period (s), instead of --rate (to match `simulate --control-period` exactly)
    #[arg(long, value_name = "SECONDS", conflicts_with = "rate")]
    pub period: Option<f64>,
    /// Safe mode after this many periods without a valid torque (realtime clock)
    #[arg(long, default_value_t = 50, value_name = "PERIODS")]
    pub watchdog: u64,
    /// Torque in safe mode
    #[arg(long, value_enum, default_value_t = SafeMode::Hold)]
    pub safe_mode: SafeMode,
    /// Stiffness (1/s^2) of the holding PD of --safe-mode hold
    #[arg(long, default_value_t = 25.0, value_name = "1/S2")]
    pub safe_kp: f64,
    /// Damping (1/s) of the holding PD of --safe-mode hold
    #[arg(long, default_value_t = 10.0, value_name = "1/S")]
    pub safe_kd: f64,
    /// Lockstep clock: wait this long for a torque, then apply the safe mode for that period
    #[arg(long, default_value_t = 1000, value_name = "MS")]
    pub lockstep_timeout_ms: u64,
    /// Stop after this much plant time (s); default: run until Ctrl-C
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// Initial contact mode: flat, left or right
    #[arg(long, default_value_t = paper::ORBIT_MODE)]
    pub mode: Mode,
    /// Initial state alpha,beta,alpha_dot,beta_dot (rad, rad/s) [default: the start of the
    /// paper's tilting orbit, `tilting_plant::paper::orbit_x0`]
    #[arg(long, value_name = "A,B,AD,BD", value_parser = parse_x0, allow_hyphen_values = true)]
    pub x0: Option<[f64; 4]>,
    /// Landing impact law: paper or striking-edge
    #[arg(long, default_value = "paper")]
    pub impact: ImpactLaw,
    /// Physical parameters (TOML: m_f, m_l, l, f, g); default: the paper's
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    /// Relative tolerance of the integrator (the absolute one is rtol/100, as in `simulate`)
    #[arg(long, default_value_t = Tolerance::default().rtol)]
    pub rtol: f64,
    /// Hard torque limit (N m) applied by the plant; 0 = none
    #[arg(long, default_value_t = 0.0, value_name = "NM")]
    pub torque_limit: f64,
    /// Write every sample to this CSV file: seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau (the
    /// state columns in the order of `tilting live`'s state.csv, then the torque applied)
    #[arg(long, value_name = "FILE.csv")]
    pub record: Option<PathBuf>,
    /// Start at once instead of waiting for a controller (its liveliness token or an answer)
    #[arg(long)]
    pub no_wait: bool,
    /// Realtime clock: busy-wait this long before each deadline (µs)
    #[arg(long, default_value_t = 50, value_name = "US")]
    pub spin_us: u64,
    /// Realtime clock: try SCHED_FIFO at this priority for the pacing thread (needs privileges)
    #[arg(long, value_name = "1-99")]
    pub rt_priority: Option<i32>,
}

fn parse_x0(s: &str) -> Result<[f64; 4], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("`{s}`: {e}; expected alpha,beta,alpha_dot,beta_dot"))?;
    match v.as_slice() {
        [a, b, c, d] if v.iter().all(|x| x.is_finite()) => Ok([*a, *b, *c, *d]),
        _ => Err(format!(
            "`{s}`: expected four finite numbers alpha,beta,alpha_dot,beta_dot"
        )),
    }
}

impl PlantArgs {
    /// The control period (s).
    pub fn period(&self) -> f64 {
        self.period.unwrap_or(1.0 / self.rate)
    }

    fn validate(&self) -> anyhow::Result<()> {
        let h = self.period();
        anyhow::ensure!(
            h.is_finite() && h > 0.0 && h <= 10.0,
            "--rate/--period: the period must be in (0, 10] s, got {h}"
        );
        if let Some(d) = self.duration {
            anyhow::ensure!(
                d.is_finite() && d > 0.0,
                "--duration must be a positive number of seconds, got {d}"
            );
            anyhow::ensure!(d / h <= 1e9, "--duration/period exceeds 1e9 periods");
        }
        anyhow::ensure!(self.watchdog >= 1, "--watchdog must be at least 1 period");
        anyhow::ensure!(
            self.safe_kp.is_finite() && self.safe_kp >= 0.0,
            "--safe-kp must be >= 0"
        );
        anyhow::ensure!(
            self.safe_kd.is_finite() && self.safe_kd >= 0.0,
            "--safe-kd must be >= 0"
        );
        anyhow::ensure!(
            self.torque_limit.is_finite() && self.torque_limit >= 0.0,
            "--torque-limit must be >= 0 (0 = none)"
        );
        anyhow::ensure!(
            self.rtol.is_finite() && (1e-13..=1e-3).contains(&self.rtol),
            "--rtol must be in [1e-13, 1e-3]"
        );
        anyhow::ensure!(self.lockstep_timeout_ms >= 1, "--lockstep-timeout-ms >= 1");
        Ok(())
    }

    /// The simulator settings (the same convention as `simulate`: `atol = rtol / 100`).
    pub fn sim_config(&self) -> anyhow::Result<SimConfig> {
        let params = match &self.params {
            Some(p) => Params::from_toml_file(p)?,
            None => Params::default(),
        };
        Ok(SimConfig {
            params,
            impact: self.impact,
            tol: Tolerance {
                rtol: self.rtol,
                atol: self.rtol * 1e-2,
            },
            ..SimConfig::default()
        })
    }
}

/// State shared by the zenoh callbacks and the pacing thread.
struct Shared {
    /// The latest valid torque answering the current state, with its arrival time (ns).
    inbox: Mutex<Option<(TorqueCommand, u64)>>,
    cv: Condvar,
    /// `seq` of the last published state.
    current_seq: AtomicU64,
    torques: DropCounter,
    stale: AtomicU64,
    controller_alive: AtomicBool,
    /// Set when the controller's token disappears; consumed by the pacing thread.
    controller_gone: AtomicBool,
    stop: AtomicBool,
}

impl Shared {
    fn on_torque(&self, bytes: &[u8]) {
        let Some(cmd) = self.torques.decode::<TorqueCommand>(bytes) else {
            return;
        };
        let now = clock::now_ns();
        if cmd.seq != self.current_seq.load(Ordering::Acquire) {
            self.stale.fetch_add(1, Ordering::Relaxed);
            return;
        }
        let mut inbox = self.inbox.lock().unwrap_or_else(|e| e.into_inner());
        if inbox.is_some_and(|(c, _)| c.seq == cmd.seq) {
            // A second answer to the same state: keep the first.
            self.stale.fetch_add(1, Ordering::Relaxed);
            return;
        }
        *inbox = Some((cmd, now));
        drop(inbox);
        self.cv.notify_all();
    }

    fn wake(&self) {
        let _guard = self.inbox.lock().unwrap_or_else(|e| e.into_inner());
        self.cv.notify_all();
    }
}

/// Collects what the simulator reports during one period.
#[derive(Default)]
struct Obs {
    transitions: Vec<Transition>,
    tilts: u64,
    peaks: VecDeque<TiltPeak>,
}

const MAX_PEAKS: usize = 256;

impl Observer for Obs {
    fn transition(&mut self, ev: &Transition) {
        if ev.from == Mode::Flat && ev.to != Mode::Flat {
            self.tilts += 1;
        }
        self.transitions.push(*ev);
    }
    fn tilt_peak(&mut self, peak: &TiltPeak) {
        if self.peaks.len() == MAX_PEAKS {
            self.peaks.pop_front();
        }
        self.peaks.push_back(*peak);
    }
}

/// How the run ended.
#[derive(Debug, Clone, PartialEq)]
enum Outcome {
    Completed,
    Stopped,
    Faulted(Fault),
}

struct Publishers {
    state: TypedPublisher<PlantState>,
    event: TypedPublisher<ModeEvent>,
    status: TypedPublisher<Status>,
}

/// The pacing loop and everything it owns.
struct Loop {
    args: PlantArgs,
    h: f64,
    plant: Plant,
    safe_pd: (f64, f64),
    shared: Arc<Shared>,
    pubs: Arc<Publishers>,
    obs: Obs,
    record: Option<std::io::BufWriter<std::fs::File>>,
    /// `seq` of the last published state (= periods done).
    seq: u64,
    /// When it was published (ns).
    t_pub: u64,
    status_state: u8,
    fault: String,
    tau: f64,
    missed: u64,
    deadline_misses: u64,
    watchdog_trips: u64,
    safe_periods: u64,
    overruns: u64,
    step_overrun_max: f64,
    jitter: Ring,
    latency: Ring,
    step_cost: Ring,
    next_status: Instant,
    status_interval: Duration,
    next_timing_log: Instant,
}

/// Interval of the timing line in the log.
const TIMING_LOG_INTERVAL: Duration = Duration::from_secs(10);

impl Loop {
    fn publish_state(&mut self) {
        let x = self.plant.state();
        let msg = PlantState {
            seq: self.seq,
            time: self.plant.time(),
            alpha: x[0],
            beta: x[1],
            alpha_dot: x[2],
            beta_dot: x[3],
            mode: self.plant.mode().as_u8(),
        };
        self.shared.current_seq.store(self.seq, Ordering::Release);
        self.t_pub = clock::now_ns();
        if let Err(e) = self.pubs.state.put(&msg) {
            tracing::warn!("cannot publish the state: {e}");
        }
    }

    fn status(&mut self) -> Status {
        let p = self.jitter.percentiles();
        let l = self.latency.percentiles();
        let mut s = Status {
            seq: self.seq,
            time: self.plant.time(),
            state: self.status_state,
            mode: self.plant.mode().as_u8(),
            tilts: self.obs.tilts,
            steps: self.seq,
            torques_received: self.shared.torques.received(),
            torques_dropped: self.shared.torques.dropped(),
            torques_stale: self.shared.stale.load(Ordering::Relaxed),
            deadline_misses: self.deadline_misses,
            watchdog_trips: self.watchdog_trips,
            jitter_p50_us: p.p50,
            jitter_p99_us: p.p99,
            max_overrun_us: self.max_overrun_us(),
            latency_p50_us: l.p50,
            latency_p99_us: l.p99,
            fault: String::new(),
        };
        s.set_fault(&self.fault);
        s
    }

    fn max_overrun_us(&self) -> f64 {
        self.step_overrun_max
    }

    fn publish_status(&mut self) {
        let s = self.status();
        if let Err(e) = self.pubs.status.put(&s) {
            tracing::warn!("cannot publish the status: {e}");
        }
        self.next_status = Instant::now() + self.status_interval;
    }

    fn maybe_status(&mut self) {
        let now = Instant::now();
        if now >= self.next_status {
            self.publish_status();
        }
        if now >= self.next_timing_log {
            self.next_timing_log = now + TIMING_LOG_INTERVAL;
            let j = self.jitter.percentiles();
            let l = self.latency.percentiles();
            tracing::info!(
                seq = self.seq,
                tilts = self.obs.tilts,
                deadline_misses = self.deadline_misses,
                overruns = self.overruns,
                "timing over the last {} periods: jitter p50 {:.1} us p99 {:.1} us; \
                 loop latency p50 {:.1} us p99 {:.1} us p99.9 {:.1} us",
                Ring::CAPACITY,
                j.p50,
                j.p99,
                l.p50,
                l.p99,
                l.p999
            );
        }
    }

    fn set_state(&mut self, state: u8) {
        if state != self.status_state {
            self.status_state = state;
            self.publish_status();
        }
    }

    fn safe_torque(&self) -> f64 {
        match self.args.safe_mode {
            SafeMode::Zero => 0.0,
            SafeMode::Hold => {
                let x = self.plant.state();
                let (kp, kd) = self.safe_pd;
                let v = kd * (0.0 - x[3]) + kp * (FRAC_PI_2 - x[1]);
                crate::dynamics::torque_for_beta_ddot(
                    &self.plant.config().params,
                    self.plant.mode(),
                    &x,
                    v,
                )
            }
        }
    }

    fn enter_safe(&mut self, why: &str) {
        if self.status_state != Status::SAFE_MODE {
            self.watchdog_trips += 1;
            tracing::warn!(seq = self.seq, t = self.plant.time(), "safe mode: {why}");
            self.set_state(Status::SAFE_MODE);
        }
    }

    /// Applies the outcome of waiting for the answer to `seq`: picks the torque of the period.
    fn choose_torque(&mut self, fresh: Option<(TorqueCommand, u64)>, lockstep: bool) -> f64 {
        let gone = self.shared.controller_gone.swap(false, Ordering::AcqRel);
        match fresh {
            Some((cmd, arrived)) => {
                self.latency
                    .push(arrived.saturating_sub(self.t_pub) as f64 * 1e-3);
                self.missed = 0;
                self.tau = cmd.tau;
                if self.status_state != Status::RUNNING {
                    if self.status_state == Status::SAFE_MODE {
                        tracing::info!(seq = self.seq, "torque is back: leaving safe mode");
                    }
                    self.set_state(Status::RUNNING);
                }
            }
            None => {
                self.deadline_misses += 1;
                self.missed += 1;
                if lockstep {
                    self.enter_safe("lockstep timeout: no torque answered the state");
                } else if self.missed >= self.args.watchdog {
                    let why = format!("no valid torque for {} periods", self.missed);
                    self.enter_safe(&why);
                } else if gone {
                    self.enter_safe("the controller's liveliness token disappeared");
                }
            }
        }
        let tau = if self.status_state == Status::SAFE_MODE {
            self.safe_periods += 1;
            self.safe_torque()
        } else {
            self.tau
        };
        if self.args.torque_limit > 0.0 {
            tau.clamp(-self.args.torque_limit, self.args.torque_limit)
        } else {
            tau
        }
    }

    fn take_fresh(&self) -> Option<(TorqueCommand, u64)> {
        let mut inbox = self.shared.inbox.lock().unwrap_or_else(|e| e.into_inner());
        match inbox.take() {
            Some((cmd, t)) if cmd.seq == self.seq => Some((cmd, t)),
            Some(_) => {
                self.shared.stale.fetch_add(1, Ordering::Relaxed);
                None
            }
            None => None,
        }
    }

    /// Lockstep: waits for the answer to the current state, re-publishing it every 100 ms.
    fn wait_fresh(&mut self, timeout: Duration) -> Option<(TorqueCommand, u64)> {
        let start = Instant::now();
        let mut next_repub = start + Duration::from_millis(100);
        loop {
            {
                let mut inbox = self.shared.inbox.lock().unwrap_or_else(|e| e.into_inner());
                loop {
                    match inbox.take() {
                        Some((cmd, t)) if cmd.seq == self.seq => return Some((cmd, t)),
                        Some(_) => {
                            self.shared.stale.fetch_add(1, Ordering::Relaxed);
                        }
                        None => {}
                    }
                    if self.shared.stop.load(Ordering::Acquire) {
                        return None;
                    }
                    let now = Instant::now();
                    if now >= start + timeout {
                        return None;
                    }
                    if now >= next_repub || now >= self.next_status {
                        break;
                    }
                    let until = next_repub.min(start + timeout).min(self.next_status);
                    inbox = self
                        .shared
                        .cv
                        .wait_timeout(inbox, until - now)
                        .unwrap_or_else(|e| e.into_inner())
                        .0;
                }
            }
            let now = Instant::now();
            if now >= next_repub {
                let t = self.t_pub;
                self.publish_state();
                self.t_pub = t; // latency counts from the first publication
                next_repub = now + Duration::from_millis(100);
            }
            self.maybe_status();
        }
    }

    /// Before the clock starts: publishes state 0 every 100 ms until a controller shows up
    /// (liveliness token or an answer to state 0). Returns false if stopped meanwhile.
    fn wait_for_controller(&mut self) -> bool {
        self.publish_state();
        self.publish_status();
        let mut announced = false;
        loop {
            if self.shared.stop.load(Ordering::Acquire) {
                return false;
            }
            let answered = self
                .shared
                .inbox
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .is_some_and(|(c, _)| c.seq == 0);
            if answered || self.shared.controller_alive.load(Ordering::Acquire) {
                return true;
            }
            if !announced {
                tracing::info!(
                    "waiting for a controller (liveliness token or an answer to state 0)"
                );
                announced = true;
            }
            let guard = self.shared.inbox.lock().unwrap_or_else(|e| e.into_inner());
            let _ = self
                .shared
                .cv
                .wait_timeout(guard, Duration::from_millis(100))
                .unwrap_or_else(|e| e.into_inner());
            self.maybe_status();
            if clock::now_ns().saturating_sub(self.t_pub) >= 100_000_000 {
                self.publish_state();
            }
        }
    }

    fn write_record(&mut self, tau: Option<f64>) {
        if let Some(w) = &mut self.record {
            let x = self.plant.state();
            let tau = tau.map(|t| t.to_string()).unwrap_or_default();
            let r = writeln!(
                w,
                "{},{},{},{},{},{},{},{}",
                self.seq,
                self.plant.time(),
                self.plant.mode().as_u8(),
                x[0],
                x[1],
                x[2],
                x[3],
                tau,
            );
            if let Err(e) = r {
                tracing::warn!("--record: write failed, recording stops: {e}");
                self.record = None;
            }
        }
    }

    /// Integrates one period with `tau` and publishes the events and the next state.
    fn step(&mut self, tau: f64) -> Result<bool, Fault> {
        self.write_record(Some(tau));
        let h = self.h;
        let next = (self.seq + 1) as f64 * h;
        let (t_next, last) = match self.args.duration {
            Some(d) if next >= d - 1e-9 * h => (d, true),
            _ => (next, false),
        };
        self.obs.transitions.clear();
        let t0 = clock::now_ns();
        let res = self.plant.advance_held(tau, t_next, &mut self.obs);
        self.step_cost
            .push(clock::now_ns().saturating_sub(t0) as f64 * 1e-3);
        for ev in &self.obs.transitions {
            let msg = ModeEvent {
                seq: self.seq,
                time: ev.t,
                from: ev.from.as_u8(),
                to: ev.to.as_u8(),
                x_before: [
                    ev.x_before[0],
                    ev.x_before[1],
                    ev.x_before[2],
                    ev.x_before[3],
                ],
                x_after: [ev.x_after[0], ev.x_after[1], ev.x_after[2], ev.x_after[3]],
            };
            if let Err(e) = self.pubs.event.put(&msg) {
                tracing::warn!("cannot publish an event: {e}");
            }
            tracing::debug!(t = ev.t, from = %ev.from, to = %ev.to, "transition");
        }
        res?;
        self.seq += 1;
        self.publish_state();
        Ok(last)
    }

    fn run_realtime(&mut self) -> Outcome {
        clock::set_min_timer_slack();
        if let Some(p) = self.args.rt_priority {
            match clock::set_fifo_priority(p) {
                Ok(()) => tracing::info!("pacing thread runs SCHED_FIFO {p}"),
                Err(e) => tracing::warn!("--rt-priority {p}: {e}; staying SCHED_OTHER"),
            }
        }
        let h_ns = self.h * 1e9;
        let spin = self.args.spin_us * 1000;
        let start = clock::now_ns();
        let mut k: u64 = 0;
        loop {
            if self.shared.stop.load(Ordering::Acquire) {
                return Outcome::Stopped;
            }
            let deadline = start + ((k + 1) as f64 * h_ns).round() as u64;
            let woke = clock::sleep_until(deadline, spin);
            self.jitter.push((woke - deadline) as f64 * 1e-3);
            let fresh = self.take_fresh();
            let tau = self.choose_torque(fresh, false);
            match self.step(tau) {
                Ok(true) => return Outcome::Completed,
                Ok(false) => {}
                Err(f) => return Outcome::Faulted(f),
            }
            let done = clock::now_ns();
            let next_deadline = start + ((k + 2) as f64 * h_ns).round() as u64;
            if done > next_deadline {
                self.overruns += 1;
                let o = (done - next_deadline) as f64 * 1e-3;
                if o > self.step_overrun_max {
                    self.step_overrun_max = o;
                }
            }
            self.maybe_status();
            k += 1;
        }
    }

    fn run_lockstep(&mut self) -> Outcome {
        let timeout = Duration::from_millis(self.args.lockstep_timeout_ms);
        loop {
            if self.shared.stop.load(Ordering::Acquire) {
                return Outcome::Stopped;
            }
            let fresh = self.wait_fresh(timeout);
            if self.shared.stop.load(Ordering::Acquire) {
                return Outcome::Stopped;
            }
            let tau = self.choose_torque(fresh, true);
            match self.step(tau) {
                Ok(true) => return Outcome::Completed,
                Ok(false) => {}
                Err(f) => return Outcome::Faulted(f),
            }
            self.maybe_status();
        }
    }

    fn run(&mut self) -> Outcome {
        if let Some(w) = &mut self.record {
            if let Err(e) = writeln!(w, "{STATE_COLUMNS},tau") {
                tracing::warn!("--record: {e}");
                self.record = None;
            }
        }
        if self.args.no_wait {
            self.publish_state();
        } else {
            if !self.wait_for_controller() {
                return Outcome::Stopped;
            }
            // The controller may have subscribed after the last publication of state 0.
            let answered = self
                .shared
                .inbox
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .is_some();
            if !answered {
                self.publish_state();
            }
        }
        tracing::info!(
            clock = ?self.args.clock,
            period = self.h,
            "plant running"
        );
        // Running until the first answer says otherwise; a missing one counts from now.
        self.set_state(Status::RUNNING);
        let outcome = match self.args.clock {
            ClockMode::Realtime => self.run_realtime(),
            ClockMode::Lockstep => self.run_lockstep(),
        };
        match &outcome {
            Outcome::Faulted(f) => {
                let msg = f.to_string();
                self.fault = msg.clone();
                tracing::error!("fault: {msg}");
                self.set_state(Status::FAULTED);
            }
            _ => {
                self.write_record(None);
                self.set_state(Status::STOPPED);
            }
        }
        if let Some(w) = &mut self.record {
            if let Err(e) = w.flush() {
                tracing::warn!("--record: flush failed: {e}");
            }
        }
        outcome
    }

    fn summary(&mut self, outcome: &Outcome) -> PlantSummary {
        let j = self.jitter.percentiles();
        let l = self.latency.percentiles();
        let c = self.step_cost.percentiles();
        let (result, fault) = match outcome {
            Outcome::Completed => (RunResult::Completed, None),
            Outcome::Stopped => (RunResult::Stopped, None),
            Outcome::Faulted(f) => (RunResult::Faulted, Some(f.to_string())),
        };
        let window = Some(Ring::CAPACITY as u64);
        PlantSummary {
            result,
            fault,
            clock: self.args.clock,
            period: self.h,
            seq: self.seq,
            time: self.plant.time(),
            mode: self.plant.mode(),
            x: self.plant.state().into(),
            steps: self.seq,
            tilts: self.obs.tilts,
            transitions: self.plant.transitions(),
            torques_received: self.shared.torques.received(),
            torques_dropped: self.shared.torques.dropped(),
            torques_stale: self.shared.stale.load(Ordering::Relaxed),
            deadline_misses: self.deadline_misses,
            watchdog_trips: self.watchdog_trips,
            safe_periods: self.safe_periods,
            overruns: self.overruns,
            max_overrun_us: self.step_overrun_max,
            jitter_us: Window {
                p50: j.p50,
                p99: j.p99,
                p999: Some(j.p999),
                max: self.jitter.max(),
                count: None,
                window,
            },
            latency_us: Window {
                p50: l.p50,
                p99: l.p99,
                p999: Some(l.p999),
                max: self.latency.max(),
                count: Some(self.latency.count()),
                window,
            },
            step_us: Window {
                p50: c.p50,
                p99: c.p99,
                p999: None,
                max: self.step_cost.max(),
                count: None,
                window: None,
            },
            tilt_peaks: self.obs.peaks.iter().map(|p| [p.t, p.alpha]).collect(),
        }
    }
}

/// Runs the plant node until the end of the run; returns the process exit code.
pub fn run(args: PlantArgs) -> anyhow::Result<ExitCode> {
    args.validate()?;
    let keys = args.zenoh.keys()?;
    let cfg = args.sim_config()?;
    let x0 = State::from(args.x0.unwrap_or_else(paper::orbit_x0));
    let plant = Plant::new(cfg, 0.0, args.mode, x0).context("initial state")?;
    let record = match &args.record {
        Some(path) => Some(std::io::BufWriter::with_capacity(
            1 << 16,
            std::fs::File::create(path).with_context(|| format!("--record {}", path.display()))?,
        )),
        None => None,
    };
    let rt = tilting_net::runtime()?;
    rt.block_on(run_async(args, keys, plant, record))
}

async fn run_async(
    args: PlantArgs,
    keys: Keys,
    plant: Plant,
    record: Option<std::io::BufWriter<std::fs::File>>,
) -> anyhow::Result<ExitCode> {
    let session = tilting_net::open_session(&args.zenoh, Role::Plant).await?;
    let shared = Arc::new(Shared {
        inbox: Mutex::new(None),
        cv: Condvar::new(),
        current_seq: AtomicU64::new(0),
        torques: DropCounter::new(keys.controller_torque()),
        stale: AtomicU64::new(0),
        controller_alive: AtomicBool::new(false),
        controller_gone: AtomicBool::new(false),
        stop: AtomicBool::new(false),
    });
    let pubs = Arc::new(Publishers {
        state: TypedPublisher::declare(&session, keys.plant_state(), Qos::Control).await?,
        event: TypedPublisher::declare(&session, keys.plant_event(), Qos::Data).await?,
        status: TypedPublisher::declare(&session, keys.plant_status(), Qos::Data).await?,
    });
    let sh = shared.clone();
    let _torque_sub = session
        .declare_subscriber(keys.controller_torque().to_owned())
        .callback(move |sample| sh.on_torque(&sample.payload().to_bytes()))
        .await
        .map_err(|e| anyhow::anyhow!("cannot subscribe to {}: {e}", keys.controller_torque()))?;
    let sh = shared.clone();
    let (_presence, _presence_sub) =
        tilting_net::watch_presence(&session, keys.alive_controller(), move |alive| {
            sh.controller_alive.store(alive, Ordering::Release);
            if !alive {
                sh.controller_gone.store(true, Ordering::Release);
            }
            sh.wake();
        })
        .await?;
    let _token = tilting_net::declare_token(&session, keys.alive_plant()).await?;

    let h = args.period();
    let safe_pd = (args.safe_kp, args.safe_kd);
    let mut lp = Loop {
        args,
        h,
        plant,
        safe_pd,
        shared: shared.clone(),
        pubs,
        obs: Obs::default(),
        record,
        seq: 0,
        t_pub: 0,
        status_state: Status::STARTING,
        fault: String::new(),
        tau: 0.0,
        missed: 0,
        deadline_misses: 0,
        watchdog_trips: 0,
        safe_periods: 0,
        overruns: 0,
        step_overrun_max: 0.0,
        jitter: Ring::new(),
        latency: Ring::new(),
        step_cost: Ring::new(),
        next_status: Instant::now(),
        status_interval: Duration::from_millis(100),
        next_timing_log: Instant::now() + TIMING_LOG_INTERVAL,
    };
    let (done_tx, done_rx) = tokio::sync::oneshot::channel();
    let pacing = std::thread::Builder::new()
        .name("plant-pacing".into())
        .spawn(move || {
            let outcome = lp.run();
            let summary = lp.summary(&outcome);
            let _ = done_tx.send(());
            (outcome, summary)
        })
        .context("cannot start the pacing thread")?;

    tokio::select! {
        _ = tilting_net::shutdown_signal() => {
            tracing::info!("stopping");
            shared.stop.store(true, Ordering::Release);
            shared.wake();
        }
        _ = done_rx => {}
    }
    let (outcome, summary) = tokio::task::spawn_blocking(move || pacing.join())
        .await
        .context("pacing thread join")?
        .map_err(|_| anyhow::anyhow!("the pacing thread panicked"))?;
    println!(
        "{}",
        serde_json::to_string(&summary).context("cannot serialise the summary")?
    );
    // Let the last status and event leave before the session closes.
    tokio::time::sleep(Duration::from_millis(100)).await;
    drop(_token);
    let _ = session.close().await;
    Ok(match outcome {
        Outcome::Faulted(_) => ExitCode::from(EXIT_FAULT),
        _ => ExitCode::SUCCESS,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[test]
    fn flags_parse_with_defaults() {
        let a = PlantArgs::try_parse_from(["tilting-plant"]).unwrap();
        assert_eq!(a.clock, ClockMode::Realtime);
        assert_eq!(a.period(), 0.001);
        assert_eq!(a.watchdog, 50);
        assert_eq!(a.safe_mode, SafeMode::Hold);
        assert_eq!(a.mode, Mode::Left);
        assert_eq!(a.zenoh.robot, "demo");
        a.validate().unwrap();
        let a = PlantArgs::try_parse_from([
            "tilting-plant",
            "--clock",
            "lockstep",
            "--period",
            "0.002",
            "--x0",
            "-0.01,1.5,0,0",
            "--mode",
            "right",
            "--listen",
            "tcp/127.0.0.1:17999",
        ])
        .unwrap();
        assert_eq!(a.clock, ClockMode::Lockstep);
        assert_eq!(a.period(), 0.002);
        assert_eq!(a.x0, Some([-0.01, 1.5, 0.0, 0.0]));
        assert!(PlantArgs::try_parse_from(["tilting-plant", "--x0", "1,2,3"]).is_err());
        assert!(PlantArgs::try_parse_from(["tilting-plant", "--x0", "1,2,3,nan"]).is_err());
        assert!(
            PlantArgs::try_parse_from(["tilting-plant", "--rate", "1", "--period", "1"]).is_err()
        );
        let a = PlantArgs::try_parse_from(["tilting-plant", "--rate", "0"]).unwrap();
        assert!(a.validate().is_err());
    }

    #[test]
    fn default_start_is_the_orbit() {
        let a = PlantArgs::try_parse_from(["tilting-plant"]).unwrap();
        assert_eq!(a.mode, paper::ORBIT_MODE);
        assert_eq!(a.x0, None); // resolved to paper::orbit_x0() by `run`
    }
}
