//! Monitoring a live run: waiting for the plant's first state, then the status line, the
//! children's health, the reference repetition and the signals, until the run ends.

use super::orbit::OrbitCheck;
use super::status::status_line;
use super::tap::Tap;
use crate::record::Recorder;
use crate::supervise::Child;
use std::io::{IsTerminal as _, Write as _};
use std::process::ExitStatus;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

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
#[derive(Debug)]
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
}

/// Watches the running loop five times a second until the plant or the controller exits, a
/// signal arrives or `duration` + [`GRACE_S`] s pass: checks the children, repeats the
/// reference once a second and refreshes the status line (each tick on a terminal, once a
/// second otherwise).
pub(super) async fn monitor(
    w: &Watch<'_>,
    plant: &mut Child,
    mut controller: Option<&mut Child>,
    signals: &Signals,
    duration: f64,
) -> End {
    let tty = std::io::stderr().is_terminal();
    let give_up = Instant::now() + Duration::from_secs_f64(duration + GRACE_S);
    let mut ticks: u64 = 0;
    let mut printed = String::new();
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
            w.tap.repeat();
        }
        if tty || second || end.is_some() {
            let line = w.line();
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

impl Watch<'_> {
    /// The status line now, with the orbit verdict so far.
    fn line(&self) -> String {
        let st = self.tap.status();
        let view = self.recorder.view();
        let verdict = self.check.zip(st.as_ref()).map(|(c, st)| {
            let fault = (!st.fault.is_empty()).then_some(st.fault.as_str());
            let peaks: Vec<(f64, f64)> = view.peaks.iter().copied().collect();
            c.judge(&peaks, st.time, st.watchdog_trips, fault)
        });
        status_line(
            st.as_ref(),
            &view,
            self.recorder.dropped(),
            self.impaired,
            verdict.as_ref(),
        )
    }
}
