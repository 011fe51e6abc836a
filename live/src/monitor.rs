//! Monitoring a live run: waiting for the plant's first state, then the status line, the
//! children's health, the reference repetition and the signals, until the run ends.

use super::orbit::OrbitCheck;
use super::status::status_line;
use super::tap::Tap;
use crate::record::Recorder;
use std::io::{IsTerminal as _, Write as _};
use std::process::ExitStatus;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tilting_launch::Child;
use tilting_plant::node::stats::{Lateness, LATE_SHARE};
use tilting_proto::Status;

/// Longest wait for the plant's first state (s).
pub(super) const START_TIMEOUT_S: u64 = 15;
/// Wall-clock time allowed beyond `--duration` before the run counts as hung (s).
pub(super) const GRACE_S: f64 = 30.0;

/// Ctrl-C/SIGTERM count, updated by a task that starts with the runtime.
#[derive(Clone, Default)]
pub(super) struct Signals(Arc<AtomicU32>);

impl Signals {
    /// Starts counting the signals on `rt`.
    pub(super) fn start(rt: &tokio::runtime::Runtime) -> Self {
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

    /// Signals received so far.
    pub(super) fn count(&self) -> u32 {
        self.0.load(Ordering::Acquire)
    }

    /// A second signal: stop the children at once (kill instead of waiting).
    pub(super) fn force(&self) -> impl Fn() -> bool {
        let s = self.clone();
        move || s.count() >= 2
    }
}

/// Why the monitoring ended.
#[derive(Debug, Clone)]
pub(super) enum End {
    /// The plant ended by itself (its `--duration`, or a fault).
    PlantExited(ExitStatus),
    /// The controller exited while the plant was running.
    ControllerExited(ExitStatus),
    /// Ctrl-C or SIGTERM.
    Interrupted,
    /// The plant's first state did not arrive within [`START_TIMEOUT_S`].
    StartTimeout,
    /// The plant did not finish in time.
    Timeout,
}

/// Waits until the plant's state 0 reaches the recording (our subscription is in place);
/// `Some(end)` if the run ended before that.
pub(super) async fn wait_for_first_state(
    recorder: &Recorder,
    plant: &mut Child,
    signals: &Signals,
) -> Option<End> {
    let t0 = Instant::now();
    while recorder.view().states == 0 {
        if let Some(s) = plant.try_wait() {
            return Some(End::PlantExited(s));
        }
        if signals.count() > 0 {
            return Some(End::Interrupted);
        }
        if t0.elapsed() > Duration::from_secs(START_TIMEOUT_S) {
            return Some(End::StartTimeout);
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    None
}

/// What the status line shows and judges.
pub(super) struct Watch<'a> {
    /// The recording (its counts and peaks).
    pub(super) recorder: &'a Recorder,
    /// The planner's session (the plant's latest status; the reference it repeats).
    pub(super) tap: &'a Tap,
    /// The nominal orbit, if the law has one.
    pub(super) check: Option<OrbitCheck>,
    /// The plant emulates an impaired link.
    pub(super) impaired: bool,
    /// The Foxglove server (its clients, for the viewer warning).
    pub(super) foxglove: &'a crate::foxglove::LiveServer,
    /// The robot's name in host mode (`--robots`), where each line and alarm names it.
    pub(super) robot: Option<&'a str>,
}

/// The children a live run watches.
pub(super) struct Children<'a> {
    /// The plant.
    pub(super) plant: &'a mut Child,
    /// The controller, once started.
    pub(super) controller: Option<&'a mut Child>,
    /// The router of `--secure`.
    pub(super) router: Option<&'a mut Child>,
}

/// How long without a new state before the status line says so (s): 500 periods at 1 kHz, and
/// half the 1 s within which a failure is to be said.
pub(super) const STATE_SILENCE_S: f64 = 0.5;

/// Watches the running loop five times a second until the plant or the controller exits, a
/// signal arrives or `duration` + [`GRACE_S`] s pass: checks the children, repeats the
/// reference once a second and refreshes the status line (each tick on a terminal, once a
/// second otherwise, and at once when an alarm appears: within 200 ms of its cause being
/// seen). Host mode watches several robots (`watches`): a line each, named, once a second.
pub(super) async fn monitor(
    watches: &[Watch<'_>],
    children: Children<'_>,
    signals: &Signals,
    duration: f64,
) -> End {
    let Children {
        plant,
        mut controller,
        mut router,
    } = children;
    // The kinds of alarm last announced (a new kind is announced on its own line at once).
    let mut alarm_kinds: Vec<String> = Vec::new();
    // Several robots' lines are printed one under the other, never rewritten in place.
    let tty = std::io::stderr().is_terminal() && watches.len() == 1;
    let give_up = Instant::now() + Duration::from_secs_f64(duration + GRACE_S);
    let mut ticks: u64 = 0;
    let mut printed = String::new();
    // Five samples a second, one per tick, per robot.
    let mut lateness: Vec<Lateness> = watches.iter().map(|_| Lateness::new(5)).collect();
    let mut viewers: Vec<crate::foxglove::ViewerWatch> =
        watches.iter().map(|_| Default::default()).collect();
    let end = loop {
        tokio::time::sleep(Duration::from_millis(200)).await;
        // Five ticks a second: `second` marks one of them.
        ticks = (ticks + 1) % 5;
        let second = ticks == 0;
        let end = if let Some(s) = plant.try_wait() {
            Some(End::PlantExited(s))
        } else if let Some(s) = controller.as_deref_mut().and_then(Child::try_wait) {
            Some(End::ControllerExited(s))
        } else if signals.count() > 0 {
            Some(End::Interrupted)
        } else if Instant::now() >= give_up {
            Some(End::Timeout)
        } else {
            None
        };
        if second {
            watches.iter().for_each(|w| w.tap.repeat());
        }
        let router_exit = router.as_deref_mut().and_then(Child::try_wait);
        let (kinds, texts) = alarms_now(
            watches,
            end.is_some(),
            router_exit,
            &mut lateness,
            &mut viewers,
        );
        let new_alarm = kinds.iter().any(|k| !alarm_kinds.contains(k));
        let text = watches
            .iter()
            .zip(&texts)
            .filter(|(_, t)| !t.is_empty())
            .map(|(w, t)| format!("{}{t}", w.prefix()))
            .collect::<Vec<_>>()
            .join("; ");
        if new_alarm {
            let mut err = std::io::stderr().lock();
            let _ = writeln!(
                err,
                "{}live: ALARM: {text}",
                if tty { "\r\x1b[K" } else { "" }
            );
            let _ = err.flush();
        }
        alarm_kinds = kinds;
        if tty || second || end.is_some() || new_alarm {
            let line = watches
                .iter()
                .zip(&texts)
                .map(|(w, t)| format!("{}{}", w.prefix(), w.line(t)))
                .collect::<Vec<_>>()
                .join("\n");
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
        if let Some(e) = end {
            break e;
        }
    };
    if tty && !printed.is_empty() {
        eprintln!();
    }
    end
}

/// Each robot's alarms now (none once the run ended, `ended`): their kinds, named by robot
/// in host mode, and each robot's alarm text (empty without one).
fn alarms_now(
    watches: &[Watch<'_>],
    ended: bool,
    router_exit: Option<ExitStatus>,
    lateness: &mut [Lateness],
    viewers: &mut [crate::foxglove::ViewerWatch],
) -> (Vec<String>, Vec<String>) {
    let mut kinds = Vec::new();
    let mut texts = Vec::new();
    for ((w, late), viewer) in watches.iter().zip(lateness).zip(viewers) {
        let alarms = if ended {
            Vec::new()
        } else {
            w.alarms(router_exit, late, viewer)
        };
        kinds.extend(alarms.iter().map(|a| format!("{}{}", w.prefix(), a.0)));
        let text: Vec<&str> = alarms.iter().map(|a| a.1.as_str()).collect();
        texts.push(text.join("; "));
    }
    (kinds, texts)
}

impl Watch<'_> {
    /// What each line and alarm of this robot starts with: `robot NAME: ` in host mode.
    fn prefix(&self) -> String {
        self.robot
            .map_or_else(String::new, |r| format!("robot {r}: "))
    }

    /// What is wrong now that the user must hear of at once, each as its kind and its text:
    /// the recording failing, the router exited, a node's liveliness token gone, no state for
    /// [`STATE_SILENCE_S`], over an unimpaired link more than [`LATE_SHARE`] of the last
    /// second's periods missed (`lateness`, sampled here from the plant's status), and the
    /// loop missing deadlines since a Foxglove viewer connected (`viewer`).
    fn alarms(
        &self,
        router_exit: Option<ExitStatus>,
        lateness: &mut Lateness,
        viewer: &mut crate::foxglove::ViewerWatch,
    ) -> Vec<(&'static str, String)> {
        let view = self.recorder.view();
        let late = view
            .last_status
            .as_ref()
            .and_then(|st| lateness.update(st.steps, st.deadline_misses));
        let mut v = Vec::new();
        if let Some(st) = view.last_status.as_ref().filter(|_| !self.impaired) {
            let clients = self.foxglove.clients();
            if let Some(text) = viewer.update(clients, st.steps, st.deadline_misses, late) {
                v.push(("viewer", text));
            }
        }
        if let Some(e) = &view.error {
            v.push(("recording", format!("RECORDING FAILED: {e}")));
        }
        if let Some(s) = router_exit {
            v.push((
                "router",
                format!("ROUTER EXITED ({s}): no messages can cross"),
            ));
        }
        // A plant that said it stopped (its duration) or faulted has ended its loop: its token
        // and its states go away as they should.
        let ended = view
            .last_status
            .as_ref()
            .is_some_and(|s| s.state == Status::STOPPED || s.state == Status::FAULTED);
        if ended {
            return v;
        }
        for (i, who) in ["plant", "controller"].into_iter().enumerate() {
            if let Some(t) = self.tap.gone_since(i) {
                let text = format!(
                    "{who} link LOST {:.1} s ago (its liveliness token is gone)",
                    t.elapsed().as_secs_f64()
                );
                v.push((who, text));
            }
        }
        if let Some(share) = late.filter(|&l| l > LATE_SHARE && !self.impaired) {
            v.push((
                "late",
                format!(
                    "LOOP LATE: {:.0} % of the last second's periods missed their torque (the \
                     plant or the controller is short of CPU, or the link is slow; \
                     `--realtime` runs them under SCHED_FIFO)",
                    share * 100.0
                ),
            ));
        }
        // A plant that is starting publishes its state 0 and waits for the controller: its
        // silence then is the controller's start-up (over 0.5 s on a loaded machine).
        let starting = view
            .last_status
            .as_ref()
            .is_some_and(|s| s.state == Status::STARTING);
        if let Some(t) = view.last_state_at.filter(|_| !starting) {
            let quiet = t.elapsed().as_secs_f64();
            if quiet > STATE_SILENCE_S {
                v.push((
                    "silence",
                    format!("no state from the plant for {quiet:.1} s"),
                ));
            }
        }
        v
    }

    /// The status line now, with the orbit verdict so far and the `alarms`.
    fn line(&self, alarms: &str) -> String {
        let view = self.recorder.view();
        let st = view.last_status.clone();
        let verdict = self.check.zip(st.as_ref()).map(|(c, st)| {
            let fault = (!st.fault.is_empty()).then_some(st.fault.as_str());
            let peaks: Vec<(f64, f64)> = view.peaks.iter().copied().collect();
            c.judge(&peaks, st.time, fault)
        });
        let mut line = status_line(
            st.as_ref(),
            &view,
            self.recorder.dropped(),
            self.impaired,
            verdict.as_ref(),
        );
        if !alarms.is_empty() {
            line.push_str(" | ");
            line.push_str(alarms);
        }
        line
    }
}
