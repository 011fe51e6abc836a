//! The pacing loop of the plant node and everything it owns: per period it takes the torque
//! (or the safe-mode torque), integrates the period with the hybrid simulator, publishes the
//! events and the next state, and keeps the statistics of the status and the summary.

use super::*;
use crate::imperfect::Actuator;
use crate::sampled::{self, End, Grid, Transport};
use transport::{Lockstep, Realtime};

mod transport;

/// Collects what the simulator reports during one period.
#[derive(Default)]
pub(super) struct Obs {
    pub(super) transitions: Vec<Transition>,
    pub(super) tilts: u64,
    pub(super) peaks: VecDeque<TiltPeak>,
}

pub(super) const MAX_PEAKS: usize = 256;

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
pub(super) enum Outcome {
    Completed,
    Stopped,
    Faulted(Fault),
}

pub(super) struct Publishers {
    pub(super) state: TypedPublisher<PlantState>,
    pub(super) event: TypedPublisher<ModeEvent>,
    pub(super) status: TypedPublisher<Status>,
    /// `--ros2`: the mirror's queue (never waited on).
    pub(super) ros2: Option<tilting_ros2::node::MirrorTx>,
}

/// The pacing loop and everything it owns.
pub(super) struct Loop {
    pub(super) args: PlantArgs,
    pub(super) h: f64,
    pub(super) plant: Plant,
    /// The safe mode's torque.
    pub(super) safe: crate::safe::SafeSettings,
    /// The watchdog's count and the safe mode (`crate::safe`, the rule `simulate` applies too).
    pub(super) watchdog: crate::safe::Watchdog,
    pub(super) shared: Arc<Shared>,
    pub(super) pubs: Arc<Publishers>,
    pub(super) obs: Obs,
    pub(super) record: Option<Recording>,
    /// Torque commands taken into force.
    pub(super) torques_applied: u64,
    /// Lockstep over emulated links (`--delay` ...): the hold that picks the torque.
    pub(super) hold: Option<tilting_link::ImpairedHold>,
    /// The robot's sensors and actuator (`crate::imperfect`; perfect by default).
    pub(super) hw: crate::imperfect::Hardware,
    /// What was measured for `seq` (measured once: a re-publication sends the same numbers).
    /// (`seq`, plant time s, measurement).
    pub(super) measured: Option<(u64, f64, crate::imperfect::Measurement)>,
    /// The angles measured before (plant time s, `[alpha, beta]` rad): the safe mode's rates
    /// by a backward difference when the rates are not measured (`--measure angles`).
    pub(super) previous_angles: Option<(f64, [f64; 2])>,
    /// Real time over emulated links (`--delay` ...): states leave through it.
    pub(super) link: Option<Arc<super::emulation::Emulator>>,
    /// `seq` of the last published state (= periods done).
    pub(super) seq: u64,
    /// Extra states published at mode transitions (`--sample-on-event`).
    pub(super) extra_states: u64,
    /// Answers to extra states taken into force.
    pub(super) extra_answers: u64,
    /// When it was published (ns).
    pub(super) t_pub: u64,
    pub(super) status_state: u8,
    pub(super) fault: String,
    pub(super) tau: f64,
    /// `seq` of the state the torque in force answered.
    pub(super) applied_seq: Option<u64>,
    /// Torques applied after their own period (age > 0).
    pub(super) torques_late: u64,
    /// States whose answer was never applied (skipped between two applied torques).
    pub(super) torques_lost: u64,
    /// Age of each applied torque (periods).
    pub(super) age: Ring,
    pub(super) deadline_misses: u64,
    /// When the newest torque taken into force arrived (ns), for the token verdict.
    pub(super) last_answer: Option<u64>,
    /// The safe-mode entries (the first [`SAFE_MODES_KEPT`]).
    pub(super) safe_modes: Vec<super::SafeModeEntry>,
    pub(super) overruns: u64,
    pub(super) step_overrun_max: f64,
    pub(super) jitter: Ring,
    pub(super) latency: Ring,
    pub(super) step_cost: Ring,
    pub(super) next_status: Instant,
    pub(super) status_interval: Duration,
    pub(super) next_timing_log: Instant,
    /// The share of missed deadlines over the last second, and whether the log said the loop
    /// is late (said once when it becomes late, once when it recovers).
    pub(super) lateness: (super::stats::Lateness, bool),
    /// When the period being integrated started (ns), for its cost.
    pub(super) period_t0: u64,
    /// `--sample-on-event`: the answer to the last extra state, until it takes effect.
    pub(super) event_answer: Option<f64>,
    /// Host mode with a pacing thread per robot, robot `i` of `N`: `i / N`, the share of a
    /// period its real-time grid is shifted by from the clock's multiples of the period, so
    /// the robots' states spread over the period ([`Loop::run_all_realtime`] shifts them so).
    pub(super) stagger: Option<f64>,
}

/// Interval of the timing line in the log.
/// Lockstep in safe mode: the longest wait per period for a controller's answer.
pub(super) const SAFE_MODE_POLL: Duration = Duration::from_millis(1);

pub(super) const TIMING_LOG_INTERVAL: Duration = Duration::from_secs(10);

/// Safe-mode entries kept for the summary.
pub(super) const SAFE_MODES_KEPT: usize = 100;

impl Loop {
    /// What the sensors measured at the current `seq` (measured at its first use).
    pub(super) fn measured(&mut self) -> crate::imperfect::Measurement {
        match self.measured {
            Some((seq, _, y)) if seq == self.seq => y,
            other => {
                if let Some((_, t, y)) = other {
                    self.previous_angles = Some((t, y.angles));
                }
                let y = self.hw.measure(&self.plant);
                self.measured = Some((self.seq, self.plant.time(), y));
                y
            }
        }
    }

    /// The measured state of the safe mode's PD: with the rates not measured, they are the
    /// backward difference of the measured angles over the last sample interval (zero at the
    /// first sample, the plant's own fallback; the controller estimates them properly).
    fn measured_for_safe_mode(&mut self) -> State {
        let y = self.measured();
        crate::safe::measured_state(&y, self.plant.time(), self.previous_angles)
    }

    pub(super) fn publish_state(&mut self) {
        let y = self.measured();
        let msg = PlantState {
            seq: self.seq,
            time: self.plant.time(),
            alpha: y.angles[0],
            beta: y.angles[1],
            alpha_dot: y.rates.map(|r| r[0]),
            beta_dot: y.rates.map(|r| r[1]),
            mode: self.plant.mode().as_u8(),
        };
        let previous = self.shared.current_seq.swap(self.seq, Ordering::AcqRel);
        self.t_pub = clock::now_ns();
        if let Some(m) = &self.pubs.ros2 {
            // When `seq` was first published (a lockstep re-publication keeps it).
            let first = &self.shared.published_wall_ns;
            if previous != self.seq || first.load(Ordering::Acquire) == 0 {
                first.store(tilting_ros2::node::wall_ns(), Ordering::Release);
            }
            m.send(tilting_ros2::node::Input::State(msg, Some(self.tau)));
        }
        if let Some(link) = &self.link {
            link.send_state(msg);
        } else if let Err(e) = self.pubs.state.put(&msg) {
            tracing::warn!("cannot publish the state: {e}");
        }
        self.rec(|r| r.state(&msg));
    }

    /// Runs `f` on the `--record` file; a write error is logged once and stops the recording.
    pub(super) fn rec(&mut self, f: impl FnOnce(&mut Recording) -> anyhow::Result<()>) {
        if let Some(r) = &mut self.record {
            if let Err(e) = f(r) {
                tracing::warn!("--record: write failed, recording stops: {e:#}");
                self.record = None;
            }
        }
    }

    pub(super) fn status(&mut self) -> Status {
        let p = self.jitter.percentiles();
        let l = self.latency.percentiles();
        let a = self.age.percentiles();
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
            watchdog_trips: self.watchdog.trips(),
            jitter_p50_us: p.p50,
            jitter_p99_us: p.p99,
            max_overrun_us: self.max_overrun_us(),
            latency_p50_us: l.p50,
            latency_p99_us: l.p99,
            torques_late: self.torques_late,
            torques_lost: self.torques_lost,
            torques_reordered: self.shared.reordered.load(Ordering::Relaxed),
            age_p50: a.p50,
            age_p99: a.p99,
            age_max: self.age.max(),
            fault: String::new(),
        };
        if let Some(h) = &self.hold {
            // Over emulated links the ages are the hold's (the answers themselves are fresh).
            let st = h.stats();
            let q = |q| st.age_quantile(q).unwrap_or(0) as f64;
            s.age_p50 = q(0.5);
            s.age_p99 = q(0.99);
            s.age_max = st.age_histogram.len().saturating_sub(1) as f64;
        }
        s.set_fault(&self.fault);
        s
    }

    pub(super) fn max_overrun_us(&self) -> f64 {
        self.step_overrun_max
    }

    pub(super) fn publish_status(&mut self) {
        let s = self.status();
        if let Err(e) = self.pubs.status.put(&s) {
            tracing::warn!("cannot publish the status: {e}");
        }
        if let Some(m) = &self.pubs.ros2 {
            m.send(tilting_ros2::node::Input::Status(s.clone()));
        }
        self.rec(|r| r.status(&s));
        self.next_status = Instant::now() + self.status_interval;
    }

    pub(super) fn maybe_status(&mut self) {
        self.rec(|r| r.flush_if_due());
        let now = Instant::now();
        if now >= self.next_status {
            self.publish_status();
            self.check_lateness();
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

    /// Says in the log when over [`super::stats::LATE_SHARE`] of the last second's periods
    /// missed their torque, and when the loop recovers (real time over a real link only: an
    /// emulated delay misses by design). A node started by hand has no status line to say it.
    fn check_lateness(&mut self) {
        if self.hold.is_some() || self.link.is_some() {
            return;
        }
        let Some(share) = self.lateness.0.update(self.seq, self.deadline_misses) else {
            return;
        };
        let late = share > super::stats::LATE_SHARE;
        if late && !self.lateness.1 {
            tracing::warn!(
                seq = self.seq,
                "the loop is late: {:.0} % of the last second's periods missed their torque \
                 (the plant or the controller is short of CPU, or the link is slow; run both \
                 under SCHED_FIFO: `chrt -f 20 ...`, or `tilting live --realtime`)",
                share * 100.0
            );
        } else if !late && self.lateness.1 {
            tracing::info!(
                seq = self.seq,
                "the loop is on time again: {:.0} % of the last second's periods missed",
                share * 100.0
            );
        }
        self.lateness.1 = late;
    }

    pub(super) fn set_state(&mut self, state: u8) {
        if state != self.status_state {
            self.status_state = state;
            self.publish_status();
        }
    }

    pub(super) fn safe_torque(&mut self) -> f64 {
        let x = self.measured_for_safe_mode();
        self.safe
            .torque(&self.plant.config().params, self.plant.mode(), &x)
    }

    /// The bound (ns of wall time) that tells a controller gone from a link renegotiated:
    /// `max(--max-age, 2)` periods ([`super::inbox::token_verdict`]). Within it the torque in
    /// force is still a valid one by the age rule, so waiting for the token costs nothing.
    pub(super) fn token_grace_ns(&self) -> u64 {
        (self.args.max_age.max(2) as f64 * self.h * 1e9) as u64
    }

    /// Is the controller gone now (token absent and no torque, both for the bound)?
    pub(super) fn controller_gone(&self) -> bool {
        super::inbox::token_verdict(
            self.shared.controller_lost_at(),
            self.last_answer,
            clock::now_ns(),
            self.token_grace_ns(),
        )
    }

    pub(super) fn enter_safe(&mut self, why: &str) {
        if self.watchdog.trip() {
            tracing::warn!(seq = self.seq, t = self.plant.time(), "safe mode: {why}");
            if self.safe_modes.len() < SAFE_MODES_KEPT {
                self.safe_modes.push(super::SafeModeEntry {
                    start: self.plant.time(),
                    end: None,
                    cause: why.to_owned(),
                });
            }
            self.set_state(Status::SAFE_MODE);
        }
    }

    /// Applies the torque chosen for the period (if any) and picks the torque to integrate
    /// with. `chosen` is the answer to the current state (lockstep, or real time on time), or in
    /// real time a newer torque than the one in force that is at most `--max-age` periods old.
    pub(super) fn choose_torque(
        &mut self,
        chosen: Option<(TorqueCommand, u64)>,
        lockstep: bool,
    ) -> f64 {
        match chosen {
            Some((cmd, arrived)) => {
                let age = self.seq - cmd.seq;
                if age == 0 {
                    self.latency
                        .push(arrived.saturating_sub(self.t_pub) as f64 * 1e-3);
                } else {
                    // The answer to this state is not in: a late one stands in for it.
                    self.deadline_misses += 1;
                    self.torques_late += 1;
                }
                if let Some(a) = self.applied_seq {
                    self.torques_lost += cmd.seq.saturating_sub(a + 1);
                }
                self.applied_seq = Some(cmd.seq);
                self.last_answer = Some(arrived);
                self.torques_applied += 1;
                self.rec(|r| r.torque(&cmd));
                self.age.push(age as f64);
                if self.torques_applied == 1 {
                    // The first age at once: a predicting controller learns the delay from it.
                    self.publish_status();
                }
                self.watchdog.take();
                self.tau = cmd.tau;
                if self.status_state != Status::RUNNING {
                    if self.status_state == Status::SAFE_MODE {
                        tracing::info!(seq = self.seq, age, "torque is back: leaving safe mode");
                        if let Some(e) = self.safe_modes.last_mut().filter(|e| e.end.is_none()) {
                            e.end = Some(self.plant.time());
                        }
                    }
                    self.set_state(Status::RUNNING);
                }
            }
            None => {
                self.deadline_misses += 1;
                let over = self.watchdog.miss();
                if self.controller_gone() {
                    let why = format!(
                        "the controller is gone: its liveliness token has been absent, and no \
                         torque has arrived, for at least {:.1} ms",
                        self.token_grace_ns() as f64 * 1e-6
                    );
                    self.enter_safe(&why);
                } else if lockstep {
                    self.enter_safe("lockstep timeout: no torque answered the state");
                } else if over {
                    let why = format!(
                        "no valid torque at most --max-age {} periods old for {} periods",
                        self.args.max_age,
                        self.watchdog.missed()
                    );
                    self.enter_safe(&why);
                }
            }
        }
        let tau = if self.watchdog.count_period() {
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

    /// Real time: the newest torque received, if it is newer than the one in force and its age
    /// (periods between the state it answers and the current one) is at most `--max-age`. The
    /// inbox keeps it (a later, older arrival is then recognised as reordered).
    pub(super) fn take_newest(&self) -> Option<(TorqueCommand, u64)> {
        let (cmd, t) = (*self.shared.inbox.lock().unwrap_or_else(|e| e.into_inner()))?;
        if self.applied_seq.is_some_and(|a| cmd.seq <= a) {
            return None; // already in force
        }
        (self.seq - cmd.seq <= self.args.max_age).then_some((cmd, t))
    }

    /// Lockstep: waits for the answer to the current state, re-publishing it every 100 ms.
    pub(super) fn wait_fresh(&mut self, timeout: Duration) -> Option<(TorqueCommand, u64)> {
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
                    if self.shared.stop.load(Ordering::Acquire) || self.controller_gone() {
                        // Stopping, or the controller is gone: no answer will come.
                        return None;
                    }
                    let now = Instant::now();
                    if now >= start + timeout {
                        return None;
                    }
                    if now >= next_repub || now >= self.next_status {
                        break;
                    }
                    let mut until = next_repub.min(start + timeout).min(self.next_status);
                    if let Some(lost) = self.shared.controller_lost_at() {
                        // Wake up when the token's absence reaches the bound.
                        let due = lost + self.token_grace_ns();
                        let wait = Duration::from_nanos(due.saturating_sub(clock::now_ns()));
                        until = until.min(now + wait.max(Duration::from_micros(100)));
                    }
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
    pub(super) fn wait_for_controller(&mut self) -> bool {
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

    pub(super) fn write_record(&mut self, tau: Option<f64>) {
        let (seq, t, mode) = (self.seq, self.plant.time(), self.plant.mode().as_u8());
        let x = self.plant.state();
        let x = [x[0], x[1], x[2], x[3]];
        self.rec(|r| r.row(seq, t, mode, x, tau));
    }

    /// The start of a period holding `tau` (N m): the record's row, and the clock of the
    /// period's cost.
    fn begin_period(&mut self, tau: f64) -> f64 {
        self.write_record(Some(tau));
        self.obs.transitions.clear();
        self.period_t0 = clock::now_ns();
        tau
    }

    /// The end of a period: its cost, its events on `plant/event`, and (unless it faulted)
    /// the next state.
    fn end_period(&mut self, result: &Result<(), Fault>) {
        self.step_cost
            .push(clock::now_ns().saturating_sub(self.period_t0) as f64 * 1e-3);
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
            if let Some(m) = &self.pubs.ros2 {
                m.send(tilting_ros2::node::Input::Event(msg));
            }
            if let Some(r) = &mut self.record {
                if let Err(e) = r.event(&msg) {
                    tracing::warn!("--record: write failed, recording stops: {e:#}");
                    self.record = None;
                }
            }
            tracing::debug!(t = ev.t, from = %ev.from, to = %ev.to, "transition");
        }
        if result.is_ok() {
            self.seq += 1;
            self.publish_state();
        }
    }

    /// `--sample-on-event` (perfect robot, no emulated links), at a mode transition inside the
    /// period: publishes the state there (the period's `seq`, the transition's time) and keeps
    /// its answer for [`Loop::event_answer`], as `simulate --sample-on-event` does over a
    /// perfect link. Without an answer within `--lockstep-timeout-ms` (lockstep) or half a
    /// period (real time) the torque in force stays.
    ///
    /// In real time the plant integrates each period when it ends, so the transition lies up to
    /// one period in the wall-clock past when its state leaves; the answer then acts from the
    /// transition's instant of plant time, as in lockstep, and the next periodic state leaves
    /// later by the round trip (at most half a period).
    fn extra_state(&mut self) {
        let timeout = match self.args.clock {
            ClockMode::Lockstep => Duration::from_millis(self.args.lockstep_timeout_ms),
            ClockMode::Realtime => Duration::from_secs_f64(0.5 * self.h),
        };
        if let Some((_, t, y)) = self.measured.take() {
            self.previous_angles = Some((t, y.angles));
        }
        {
            // An answer to this period's state may still sit in the inbox (in real time the
            // one in force, read without taking it; in lockstep a second answer to a
            // re-published state): the wait below must not take it for the answer to the
            // extra state, which carries the same `seq`.
            let mut inbox = self.shared.inbox.lock().unwrap_or_else(|e| e.into_inner());
            if inbox.is_some_and(|(c, _)| c.seq <= self.seq) {
                *inbox = None;
            }
        }
        let t = self.t_pub;
        self.publish_state();
        self.t_pub = t;
        self.extra_states += 1;
        if let Some((cmd, _)) = self.wait_fresh(timeout) {
            self.extra_answers += 1;
            self.rec(|r| r.torque(&cmd));
            let mut tau = cmd.tau;
            if self.args.torque_limit > 0.0 {
                tau = tau.clamp(-self.args.torque_limit, self.args.torque_limit);
            }
            self.event_answer = Some(tau);
        }
    }

    /// The grid of the run: the period, and `--duration` (or none).
    fn grid(&self) -> Grid {
        Grid {
            period: self.h,
            t_end: self.args.duration.unwrap_or(f64::INFINITY),
        }
    }

    /// Real time: at each deadline `start + (k + 1) h` the period that just ended is integrated
    /// with the answer to `seq = k`, or the newest valid torque ([`Realtime`]).
    pub(super) fn run_realtime(&mut self) -> Outcome {
        self.prepare_pacing_thread();
        let grid = self.grid();
        let mut rt = Realtime {
            h_ns: self.h * 1e9,
            spin: self.args.spin_ns(),
            start: self.realtime_start(),
            lp: self,
            paced: true,
        };
        outcome(sampled::run(&mut rt, grid, &mut |_| {}).0)
    }

    /// The calling thread as a pacing thread: the smallest timer slack, and `--rt-priority`'s
    /// SCHED_FIFO if it was asked for (said in the log either way).
    fn prepare_pacing_thread(&self) {
        clock::set_min_timer_slack();
        if let Some(p) = self.args.rt_priority {
            match clock::set_fifo_priority(p) {
                Ok(()) => tracing::info!("pacing thread runs SCHED_FIFO {p}"),
                Err(e) => tracing::warn!("--rt-priority {p}: {e}; staying SCHED_OTHER"),
            }
        }
    }

    /// The wall-clock start of a real-time run (ns): now, or in host mode
    /// ([`Loop::stagger`]) the next instant on robot `i`'s shifted grid.
    fn realtime_start(&self) -> u64 {
        let now = clock::now_ns();
        let Some(f) = self.stagger else {
            return now;
        };
        let h = self.h * 1e9;
        ((now as f64 / h).ceil() * h + f * h).round() as u64
    }

    /// Lockstep: one period per answer. Without a controller (its token gone, or no answer
    /// within `--lockstep-timeout-ms`) the plant is in safe mode and waits at most
    /// [`SAFE_MODE_POLL`] per period for an answer: the run goes on deterministically under the
    /// safe-mode torque at about real-time speed or faster (never one period per timeout), and
    /// a controller that comes back takes over at the period it answers.
    pub(super) fn run_lockstep(&mut self) -> Outcome {
        let grid = self.grid();
        outcome(sampled::run(&mut Lockstep(self), grid, &mut |_| {}).0)
    }

    pub(super) fn run(&mut self) -> Outcome {
        if !self.start() {
            return Outcome::Stopped;
        }
        let outcome = match self.args.clock {
            ClockMode::Realtime => self.run_realtime(),
            ClockMode::Lockstep => self.run_lockstep(),
        };
        self.finish(&outcome);
        outcome
    }

    /// The start of a run: state 0 out once the controller is there (or at once with
    /// `--no-wait`), status `running`. `false`: stopped before it started.
    fn start(&mut self) -> bool {
        if self.args.no_wait {
            self.publish_state();
        } else {
            if !self.wait_for_controller() {
                return false;
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
            robot = self.robot(),
            "plant running"
        );
        // Running until the first answer says otherwise; a missing one counts from now.
        self.set_state(Status::RUNNING);
        true
    }

    /// The robot's name (its keys `tilting/{robot}/...`).
    fn robot(&self) -> &str {
        self.pubs.state.key().split('/').nth(1).unwrap_or_default()
    }

    /// The end of a run: the fault or the last record row, the final status, the recording
    /// closed.
    fn finish(&mut self, outcome: &Outcome) {
        match outcome {
            Outcome::Faulted(f) => {
                let msg = f.to_string();
                self.fault = msg.clone();
                tracing::error!(robot = self.robot(), "fault: {msg}");
                self.set_state(Status::FAULTED);
            }
            _ => {
                self.write_record(None);
                self.set_state(Status::STOPPED);
            }
        }
        if let Some(r) = self.record.take() {
            if let Err(e) = r.finish() {
                tracing::warn!("--record: cannot finish the file: {e:#}");
            }
        }
    }

    /// Host mode with `--host-pacing one`: one thread paces every robot of `loops` (all in
    /// real time, one period `h`), robot `i` of `N` on its own grid shifted by `i h / N`: at
    /// its deadline `start + (k + 1) h + i h / N` the thread steps it as
    /// [`Loop::run_realtime`] steps one (the same torque rule, so a run whose answers all
    /// arrive in time is the same computation). The shift spreads the robots' states over the
    /// period, so the controller host answers them one at a time instead of in a burst. Each
    /// robot ends on its own (fault, Ctrl-C); returns the outcomes in the order of `loops`.
    pub(super) fn run_all_realtime(loops: &mut [Loop]) -> Vec<Outcome> {
        let mut outcomes: Vec<Option<Outcome>> = loops
            .iter_mut()
            .map(|lp| (!lp.start()).then_some(Outcome::Stopped))
            .collect();
        let Some(first) = loops.first() else {
            return Vec::new();
        };
        first.prepare_pacing_thread();
        let grid = first.grid();
        let (h_ns, spin) = (first.h * 1e9, first.args.spin_ns());
        let n = loops.len() as f64;
        let t0 = clock::now_ns();
        let mut k = 0u64;
        while outcomes.iter().any(Option::is_none) {
            for (i, (lp, outcome)) in loops.iter_mut().zip(&mut outcomes).enumerate() {
                if outcome.is_some() {
                    continue;
                }
                // Robot i's grid is shifted by i/N of a period.
                let start = t0 + (i as f64 / n * h_ns).round() as u64;
                let deadline = start + ((k + 1) as f64 * h_ns).round() as u64;
                clock::sleep_until(deadline, spin);
                let mut rt = Realtime {
                    h_ns,
                    spin,
                    start,
                    lp,
                    paced: false,
                };
                let Some(tau) = rt.sample(k) else {
                    *outcome = Some(Outcome::Stopped);
                    continue;
                };
                let mut sent = 0;
                match sampled::period(&mut rt, grid, k, tau, &mut sent) {
                    Err(f) => *outcome = Some(Outcome::Faulted(f)),
                    Ok(true) => *outcome = Some(Outcome::Completed),
                    Ok(false) => {}
                }
            }
            k += 1;
        }
        loops
            .iter_mut()
            .zip(outcomes)
            .map(|(lp, outcome)| {
                let outcome = outcome.unwrap_or(Outcome::Stopped);
                lp.finish(&outcome);
                outcome
            })
            .collect()
    }

    pub(super) fn summary(&mut self, outcome: &Outcome) -> PlantSummary {
        let j = self.jitter.percentiles();
        let l = self.latency.percentiles();
        let c = self.step_cost.percentiles();
        let a = self.age.percentiles();
        let (result, fault) = match outcome {
            Outcome::Completed => (RunResult::Completed, None),
            Outcome::Stopped => (RunResult::Stopped, None),
            Outcome::Faulted(f) => (RunResult::Faulted, Some(f.to_string())),
        };
        let window = Some(Ring::CAPACITY as u64);
        PlantSummary {
            ros2: None,
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
            torques_foreign: self.shared.foreign.load(Ordering::Relaxed),
            torques_reordered: self.shared.reordered.load(Ordering::Relaxed),
            torques_late: self.torques_late,
            torques_lost: self.torques_lost,
            torques_applied: self.torques_applied,
            extra_states: self.extra_states,
            extra_answers: self.extra_answers,
            network: self.hold.as_ref().map(|h| h.stats().clone()),
            link: self.link.as_ref().map(|l| l.stats()),
            age_periods: Some(Window {
                p50: a.p50,
                p99: a.p99,
                p999: None,
                max: self.age.max(),
                count: Some(self.age.count()),
                window,
            }),
            deadline_misses: self.deadline_misses,
            watchdog_trips: self.watchdog.trips(),
            token_losses: self.shared.token_losses.load(Ordering::Relaxed),
            safe_periods: self.watchdog.safe_periods(),
            safe_modes: self.safe_modes.clone(),
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
            // The completed tilts, then the peak of a tilt still in progress (reached before
            // the end of the run but not landed).
            tilt_peaks: {
                let mut peaks = self.obs.peaks.clone();
                if let Some(p) = self.plant.peak_in_progress() {
                    if peaks.len() == MAX_PEAKS {
                        peaks.pop_front();
                    }
                    peaks.push_back(p);
                }
                peaks.iter().map(|p| [p.t, p.alpha]).collect()
            },
        }
    }
}

/// The node's outcome of a sampled run.
fn outcome(r: Result<End, Fault>) -> Outcome {
    match r {
        Ok(End::Completed) => Outcome::Completed,
        Ok(End::Stopped) => Outcome::Stopped,
        Err(f) => Outcome::Faulted(f),
    }
}
