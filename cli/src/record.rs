//! Recording of a live run: the robot's five topics as received by a subscriber, streamed with
//! flat memory into `run.mcap` (see `tilting_record`: JSON channels with schemas that Foxglove
//! and PlotJuggler open, plant-time log times, wire bytes recoverable exactly), optionally also
//! into CSV files for spreadsheets (`--csv`), and the figure drawn from the recording at the end.
//!
//! CSV files (numbers in Rust's shortest round-trip form, modes as wire bytes: 0 flat, 1 left,
//! 2 right):
//!
//! - `state.csv`: `seq,t,mode,alpha,beta,alpha_dot,beta_dot`, one row per `PlantState`;
//! - `torque.csv`: `seq,tau`, one row per `TorqueCommand`;
//! - `events.csv`: `t,from,to,alpha_before,beta_before,alpha_dot_before,beta_dot_before,
//!   alpha_after,beta_after,alpha_dot_after,beta_dot_after`, one row per `ModeEvent`.
//!
//! Both grow by whole records only, at least every 100 ms (MCAP: one closed chunk;
//! CSV: [`tilting_plant::node::csv::RowWriter`]): a run killed with SIGKILL leaves everything
//! up to the last flush readable, and no torn row.
//!
//! Subscriber callbacks hand messages to a [`RecordSender`], which never blocks: a bounded
//! channel feeds one writer thread, and a message that finds the channel full is counted as
//! dropped (a slow disk must not slow the zenoh threads, and through them the plant). Repeated
//! samples (the plant re-publishes state 0 while it waits for a controller, and its controller
//! answers each copy) are written once.

use anyhow::{anyhow, Context as _, Result};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use tilting_plant::node::csv::RowWriter;
use tilting_proto::{encode, Keys, ModeEvent, PlantState, Reference, Status, Topic, TorqueCommand};
use tilting_record::trace::{
    EVENTS_CSV, EVENTS_HEADER, RUN_MCAP, STATE_CSV, STATE_HEADER, TORQUE_CSV, TORQUE_HEADER,
};
use tilting_record::Recorder as McapRecorder;
use tilting_sim::Scenario;
use tilting_viz::plot::plot_trace;

/// The figure of a live run, beside the recording.
pub const RUN_PNG: &str = "run.png";

/// Capacity of the channel to the writer thread (messages): about 20 s of a 1 kHz loop.
const CHANNEL: usize = 1 << 15;
/// Tilt peaks kept for the status line and the summary.
const PEAKS: usize = 16;
/// Longest time the view lags behind the files when messages are few.
const VIEW_INTERVAL: std::time::Duration = std::time::Duration::from_millis(20);

/// A message to record.
#[derive(Debug, Clone)]
pub enum Record {
    /// A plant state.
    State(PlantState),
    /// A torque answer.
    Torque(TorqueCommand),
    /// A mode transition.
    Event(ModeEvent),
    /// A plant status.
    Status(Status),
    /// A reference of the planner.
    Reference(Reference),
}

enum Msg {
    Rec(Record),
    Stop,
}

/// What the recording has seen so far (for the status line and the summary).
#[derive(Debug, Clone, Default)]
pub struct RecordView {
    /// The latest state written.
    pub last_state: Option<PlantState>,
    /// States recorded.
    pub states: u64,
    /// Torques recorded.
    pub torques: u64,
    /// Events recorded.
    pub events: u64,
    /// Status messages recorded.
    pub statuses: u64,
    /// References recorded.
    pub references: u64,
    /// Flat → tilted events.
    pub tilts: u64,
    /// States skipped because their `seq` was not above the last one (re-publications).
    pub repeated_states: u64,
    /// Torques skipped likewise.
    pub repeated_torques: u64,
    /// States missing between two consecutive rows (gaps in `seq`).
    pub missing_states: u64,
    /// The last tilt peaks `(t, alpha)` seen in the sampled states (extreme `alpha` of each
    /// completed tilt, and, once the recording ends, of a tilt in progress whose `|alpha|` has
    /// already turned back), oldest first.
    pub peaks: VecDeque<(f64, f64)>,
}

/// The writer thread's end of a recording.
pub struct Recorder {
    tx: SyncSender<Msg>,
    dropped: Arc<AtomicU64>,
    view: Arc<Mutex<RecordView>>,
    thread: Option<JoinHandle<Result<()>>>,
    dir: PathBuf,
}

/// A cheap, cloneable handle for subscriber callbacks.
#[derive(Clone)]
pub struct RecordSender {
    tx: SyncSender<Msg>,
    dropped: Arc<AtomicU64>,
}

impl RecordSender {
    /// Queues `r` for writing; never blocks (a full queue drops and counts it).
    pub fn send(&self, r: Record) {
        match self.tx.try_send(Msg::Rec(r)) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
            Err(TrySendError::Disconnected(_)) => {}
        }
    }
}

impl Recorder {
    /// Creates `run.mcap` for `keys`' robot in `dir`, and with `csv` the three CSV files (with
    /// their headers), and starts the writer thread.
    pub fn create(dir: &Path, keys: &Keys, csv: bool) -> Result<Self> {
        let open = |name: &str, header: &str| -> Result<RowWriter> {
            let path = dir.join(name);
            RowWriter::create(&path, header, RowWriter::INTERVAL)
                .with_context(|| format!("cannot create {}", path.display()))
        };
        let csv = if csv {
            Some(CsvFiles {
                state: open(STATE_CSV, STATE_HEADER)?,
                torque: open(TORQUE_CSV, TORQUE_HEADER)?,
                events: open(EVENTS_CSV, EVENTS_HEADER)?,
            })
        } else {
            None
        };
        let files = Files {
            mcap: McapRecorder::create(&dir.join(RUN_MCAP), keys)
                .context("cannot create the recording")?,
            csv,
        };
        let (tx, rx) = sync_channel(CHANNEL);
        let view = Arc::new(Mutex::new(RecordView::default()));
        let v = view.clone();
        let thread = std::thread::Builder::new()
            .name("live-record".into())
            .spawn(move || writer(rx, files, v))
            .context("cannot start the recording thread")?;
        Ok(Self {
            tx,
            dropped: Arc::new(AtomicU64::new(0)),
            view,
            thread: Some(thread),
            dir: dir.to_path_buf(),
        })
    }

    /// A handle for callbacks.
    pub fn sender(&self) -> RecordSender {
        RecordSender {
            tx: self.tx.clone(),
            dropped: self.dropped.clone(),
        }
    }

    /// A snapshot of what was written so far.
    pub fn view(&self) -> RecordView {
        self.view.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Messages dropped because the writer fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// The output directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Writes what is queued, flushes and closes the files; returns the final view. Messages
    /// sent afterwards are ignored.
    pub fn finish(mut self) -> Result<RecordView> {
        // A blocking send: the writer drains the queue before it sees the stop.
        let _ = self.tx.send(Msg::Stop);
        if let Some(t) = self.thread.take() {
            t.join()
                .map_err(|_| anyhow!("the recording thread panicked"))?
                .context("cannot write the recording")?;
        }
        Ok(self.view())
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            let _ = self.tx.send(Msg::Stop);
            let _ = t.join();
        }
    }
}

struct CsvFiles {
    state: RowWriter,
    torque: RowWriter,
    events: RowWriter,
}

struct Files {
    mcap: McapRecorder,
    csv: Option<CsvFiles>,
}

impl Files {
    fn flush_if_due(&mut self) -> Result<()> {
        self.mcap.flush_if_due()?;
        if let Some(c) = &mut self.csv {
            c.state.flush_if_due()?;
            c.torque.flush_if_due()?;
            c.events.flush_if_due()?;
        }
        Ok(())
    }

    fn finish(self) -> Result<()> {
        self.mcap.finish()?;
        if let Some(mut c) = self.csv {
            c.state.flush()?;
            c.torque.flush()?;
            c.events.flush()?;
        }
        Ok(())
    }
}

/// The current tilt, for peak tracking: its mode and extreme alpha so far.
struct Tilt {
    mode: u8,
    /// Time and `alpha` of the sample of largest `|alpha|` so far.
    t: f64,
    alpha: f64,
    /// `alpha` of the latest sample of the tilt.
    last: f64,
}

fn writer(rx: Receiver<Msg>, mut f: Files, view: Arc<Mutex<RecordView>>) -> Result<()> {
    let mut last_state: Option<u64> = None;
    let mut last_torque: Option<u64> = None;
    let mut tilt: Option<Tilt> = None;
    // Counters are published to `view` every 64 messages, or when the queue has been idle for
    // VIEW_INTERVAL, so the lock is cheap and the view is never stale for long.
    let mut local = RecordView::default();
    let mut pending = 0u32;
    let mut result = Ok(());
    loop {
        let rec = match rx.recv_timeout(VIEW_INTERVAL) {
            Ok(Msg::Rec(r)) => r,
            Ok(Msg::Stop) | Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => {
                if result.is_ok() {
                    result = f.flush_if_due();
                }
                if pending > 0 {
                    pending = 0;
                    *view.lock().unwrap_or_else(|e| e.into_inner()) = local.clone();
                }
                continue;
            }
        };
        if result.is_err() {
            continue; // keep draining so senders never see a full queue forever
        }
        let r: Result<()> = (|| {
            match rec {
                Record::State(s) => {
                    if last_state.is_some_and(|l| s.seq <= l) {
                        local.repeated_states += 1;
                        return Ok(());
                    }
                    if let Some(l) = last_state {
                        local.missing_states += s.seq - l - 1;
                    }
                    last_state = Some(s.seq);
                    local.states += 1;
                    local.last_state = Some(s);
                    track_peak(&mut tilt, &s, &mut local.peaks);
                    f.mcap.record(Topic::State, &encode(&s))?;
                    if let Some(c) = &mut f.csv {
                        c.state.row(format_args!(
                            "{},{},{},{},{},{},{}",
                            s.seq, s.time, s.mode, s.alpha, s.beta, s.alpha_dot, s.beta_dot
                        ))?;
                    }
                }
                Record::Torque(t) => {
                    if last_torque.is_some_and(|l| t.seq <= l) {
                        local.repeated_torques += 1;
                        return Ok(());
                    }
                    last_torque = Some(t.seq);
                    local.torques += 1;
                    f.mcap.record(Topic::Torque, &encode(&t))?;
                    if let Some(c) = &mut f.csv {
                        c.torque.row(format_args!("{},{}", t.seq, t.tau))?;
                    }
                }
                Record::Event(e) => {
                    local.events += 1;
                    if e.from == 0 && e.to != 0 {
                        local.tilts += 1;
                    }
                    f.mcap.record(Topic::Event, &encode(&e))?;
                    if let Some(c) = &mut f.csv {
                        let (b, a) = (e.x_before, e.x_after);
                        c.events.row(format_args!(
                            "{},{},{},{},{},{},{},{},{},{},{}",
                            e.time, e.from, e.to, b[0], b[1], b[2], b[3], a[0], a[1], a[2], a[3]
                        ))?;
                    }
                }
                Record::Status(st) => {
                    local.statuses += 1;
                    f.mcap.record(Topic::Status, &encode(&st))?;
                }
                Record::Reference(r) => {
                    local.references += 1;
                    f.mcap.record(Topic::Reference, &encode(&r))?;
                }
            }
            Ok(())
        })();
        if let Err(e) = r {
            result = Err(e);
        }
        pending += 1;
        if pending >= 64 {
            pending = 0;
            *view.lock().unwrap_or_else(|e| e.into_inner()) = local.clone();
        }
    }
    finish_peak(&tilt, &mut local.peaks);
    *view.lock().unwrap_or_else(|e| e.into_inner()) = local;
    result?;
    f.finish()
}

fn push_peak(peaks: &mut VecDeque<(f64, f64)>, peak: (f64, f64)) {
    if peaks.len() == PEAKS {
        peaks.pop_front();
    }
    peaks.push_back(peak);
}

fn track_peak(tilt: &mut Option<Tilt>, s: &PlantState, peaks: &mut VecDeque<(f64, f64)>) {
    let same = tilt.as_ref().is_some_and(|c| c.mode == s.mode);
    if !same {
        if let Some(done) = tilt.take() {
            push_peak(peaks, (done.t, done.alpha));
        }
        if s.mode != 0 {
            *tilt = Some(Tilt {
                mode: s.mode,
                t: s.time,
                alpha: s.alpha,
                last: s.alpha,
            });
        }
    } else if let Some(c) = tilt {
        c.last = s.alpha;
        if s.alpha.abs() > c.alpha.abs() {
            c.alpha = s.alpha;
            c.t = s.time;
        }
    }
}

/// At the end of a recording: the tilt still in progress has reached its peak if `|alpha|` has
/// come back down since its largest sample; that peak belongs to the run although the tilt has
/// not landed. (A tilt whose `|alpha|` is still growing at the last sample has no peak yet.)
fn finish_peak(tilt: &Option<Tilt>, peaks: &mut VecDeque<(f64, f64)>) {
    if let Some(c) = tilt {
        if c.last.abs() < c.alpha.abs() {
            push_peak(peaks, (c.t, c.alpha));
        }
    }
}

/// Points kept for the figure, about.
const PLOT_POINTS: u64 = 20_000;

/// Draws `alpha(t)` and `beta(t)` of the recording `run.mcap` in `dir` into `png` (via
/// [`plot_trace`]), decimated to about 20 000 points (mode changes are always kept).
/// `scenario` gives the gains and the control period for the title; `stopped_early` marks an
/// early end.
pub fn plot_recording(
    dir: &Path,
    png: &Path,
    scenario: &Scenario,
    stopped_early: bool,
) -> Result<()> {
    let run = tilting_record::load(
        &dir.join(RUN_MCAP),
        tilting_record::Window::default(),
        Some(PLOT_POINTS),
    )?;
    let sc = Scenario {
        duration: run.trace.end.max(1e-3),
        ..scenario.clone()
    };
    let trace = tilting_record::Trace {
        stopped_early: stopped_early || run.truncated,
        ..run.trace
    };
    plot_trace(png, &sc, &trace)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(seq: u64, mode: u8, alpha: f64) -> PlantState {
        PlantState {
            seq,
            time: seq as f64 * 1e-3,
            alpha,
            beta: 1.5,
            alpha_dot: 0.0,
            beta_dot: 0.0,
            mode,
        }
    }

    #[test]
    fn a_peak_reached_in_the_unfinished_last_tilt_counts() {
        // The truth is the samples themselves: alpha rises to its largest sample, then falls
        // (a peak, though the tilt never lands) or only rises (no peak yet).
        for (turned_back, want) in [(true, 1), (false, 0)] {
            let tmp = tempfile::tempdir().unwrap();
            let rec = Recorder::create(tmp.path(), &Keys::new("t").unwrap(), false).unwrap();
            let tx = rec.sender();
            let n = if turned_back { 60 } else { 20 };
            for k in 0..n {
                tx.send(Record::State(state(k, 1, 0.03 * (k as f64 * 0.06).sin())));
            }
            let v = rec.finish().unwrap();
            assert_eq!(v.peaks.len(), want, "turned back: {turned_back}");
            if turned_back {
                let best = (0..n)
                    .max_by(|&a, &b| (a as f64 * 0.06).sin().total_cmp(&(b as f64 * 0.06).sin()));
                let k = best.unwrap();
                assert_eq!(
                    v.peaks[0],
                    (k as f64 * 1e-3, 0.03 * (k as f64 * 0.06).sin())
                );
            }
        }
    }

    #[test]
    fn writes_dedups_tracks_peaks_and_plots() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        let rec = Recorder::create(&dir, &Keys::new("t").unwrap(), true).unwrap();
        let tx = rec.sender();
        tx.send(Record::State(state(0, 1, 0.0)));
        tx.send(Record::State(state(0, 1, 0.0))); // re-published
        tx.send(Record::Torque(TorqueCommand { seq: 0, tau: 1.0 }));
        tx.send(Record::Torque(TorqueCommand { seq: 0, tau: 1.0 }));
        for k in 1..100u64 {
            let (mode, alpha) = if k < 50 {
                (1, 0.01 * (k as f64 * 0.06).sin())
            } else {
                (2, -0.02 * ((k - 50) as f64 * 0.06).sin())
            };
            tx.send(Record::State(state(k, mode, alpha)));
            tx.send(Record::Torque(TorqueCommand { seq: k, tau: 0.5 }));
        }
        tx.send(Record::State(state(105, 0, 0.0))); // a gap of 5
        tx.send(Record::Event(ModeEvent {
            seq: 49,
            time: 0.0495,
            from: 1,
            to: 0,
            x_before: [0.0, 1.0, -0.1, 0.2],
            x_after: [0.0, 1.0, 0.0, -0.2],
        }));
        tx.send(Record::Event(ModeEvent {
            seq: 49,
            time: 0.0495,
            from: 0,
            to: 2,
            x_before: [0.0, 1.0, 0.0, -0.2],
            x_after: [0.0, 1.0, 0.0, -0.2],
        }));
        let v = rec.finish().unwrap();
        assert_eq!((v.states, v.torques, v.events, v.tilts), (101, 100, 2, 1));
        assert_eq!((v.repeated_states, v.repeated_torques), (1, 1));
        assert_eq!(v.missing_states, 5);
        assert_eq!(v.peaks.len(), 2);
        let want = (1..50)
            .map(|k| 0.01 * (k as f64 * 0.06).sin())
            .fold(0.0, f64::max);
        assert_eq!(v.peaks[0].1, want);
        assert!(v.peaks[1].1 < -0.019);
        let text = std::fs::read_to_string(dir.join(STATE_CSV)).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some(STATE_HEADER));
        assert_eq!(lines.next(), Some("0,0,1,0,1.5,0,0"));
        assert_eq!(text.lines().count(), 102);
        let ev = std::fs::read_to_string(dir.join(EVENTS_CSV)).unwrap();
        assert_eq!(ev.lines().nth(2), Some("0.0495,0,2,0,1,0,-0.2,0,1,0,-0.2"));
        // The MCAP recording holds the same, deduplicated.
        let run = tilting_record::read(&dir.join(RUN_MCAP)).unwrap();
        assert!(run.complete());
        assert_eq!(
            (
                run.count(Topic::State),
                run.count(Topic::Torque),
                run.count(Topic::Event)
            ),
            (101, 100, 2)
        );
        let tr = tilting_record::load(&dir, Default::default(), None)
            .unwrap()
            .trace;
        assert_eq!((tr.samples.len(), tr.events.len()), (101, 2));
        assert_eq!(tr.end, 0.105);
        let png = dir.join(RUN_PNG);
        plot_recording(&dir, &png, &Scenario::default(), false).unwrap();
        assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_full_queue_drops_without_blocking() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        let rec = Recorder::create(&dir, &Keys::new("t").unwrap(), false).unwrap();
        let tx = rec.sender();
        for k in 0..(4 * CHANNEL as u64) {
            tx.send(Record::Torque(TorqueCommand { seq: k, tau: 0.0 }));
        }
        let dropped = rec.dropped();
        let v = rec.finish().unwrap();
        assert_eq!(v.torques + dropped, 4 * CHANNEL as u64);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
