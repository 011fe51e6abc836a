//! [`Recorder`]: the one recorder of a robot's topics as a subscriber receives them, for
//! `tilting live` and `tilting record`. Streams with flat memory into an MCAP file
//! ([`McapWriter`]) and optionally into the CSV files of a live run's directory
//! ([`crate::trace`]: `state.csv`, `torque.csv`, `events.csv`, by [`RowWriter`]).
//!
//! Both files grow by whole records only, at least every 100 ms (MCAP: one closed chunk; CSV:
//! whole rows): a run killed with SIGKILL leaves everything up to the last flush readable, and
//! no torn row.
//!
//! Subscriber callbacks hand messages to a [`RecordSender`], which never blocks: one writer
//! thread drains a bounded queue ([`Sink`]), and a message that finds the queue full is counted
//! as dropped. With [`Options::skip_repeats`], repeated samples (the plant re-publishes state 0
//! while it waits for a controller, and its controller answers each copy) are written once.
//! A [`RecordView`] of what was written is kept for a status line and a summary.
//!
//! With [`Options::rules`], every message first passes the plant's own plausibility rules
//! ([`crate::guard`]): a refused one is counted ([`RecordView::refused`]) and never written, so
//! it changes neither the files nor the view. A write error (a full disk) stops the files where
//! it happened; it is in the view at once ([`RecordView::error`], naming ENOSPC and the file),
//! and the view goes on counting what arrives.

use crate::csv::RowWriter;
use crate::guard::{Guard, Rules, Sources};
use crate::sink::{Drain, Panicked, Sink, SinkSender};
use crate::trace::{
    EVENTS_CSV, EVENTS_HEADER, RUN_MCAP, STATE_CSV, STATE_HEADER, TORQUE_CSV, TORQUE_HEADER,
};
use crate::writer::{McapWriter, WriteError};
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tilting_proto::{
    codec, encode, Keys, ModeEvent, PlantState, Reference, SourceId, Status, Topic, TorqueCommand,
};

/// Capacity of the queue to the writer thread (messages): about 30 s of a 1 kHz loop.
const QUEUE: usize = 1 << 15;
/// Tilt peaks kept for the status line and the summary.
const PEAKS: usize = 16;
/// Longest time the view lags behind the files when messages are few.
const VIEW_INTERVAL: Duration = Duration::from_millis(20);

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
    /// A payload as received on `topic`'s key, decoded (and counted as invalid if it does not
    /// decode and validate) by the writer thread.
    Wire(Topic, Vec<u8>),
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
    /// Wire payloads that did not decode or validate (not written).
    pub invalid: u64,
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
    /// Messages refused by the plausibility rules (not written), per topic
    /// ([`Topic::index`]).
    pub refused: [u64; 5],
    /// Of those, the messages refused because they came from a foreign source (another
    /// session than the plant's or the controller's: [`tilting_proto::source`]).
    pub foreign: u64,
    /// The foreign-source refusals per topic ([`Topic::index`]): the states', events' and
    /// statuses' are the plant's pin's, the torques' the controller's.
    pub foreign_per_topic: [u64; 5],
    /// The first refusal, in words.
    pub first_refusal: Option<String>,
    /// The newest status believed (written).
    pub last_status: Option<Status>,
    /// When the newest state was believed (wall clock).
    pub last_state_at: Option<Instant>,
    /// The first write error, in words (naming ENOSPC for a full disk, and the file): the
    /// files stopped growing there.
    pub error: Option<String>,
}

impl RecordView {
    /// Messages recorded on `topic`.
    pub fn count(&self, topic: Topic) -> u64 {
        match topic {
            Topic::State => self.states,
            Topic::Torque => self.torques,
            Topic::Event => self.events,
            Topic::Status => self.statuses,
            Topic::Reference => self.references,
        }
    }

    /// Messages refused by the plausibility rules, all topics.
    pub fn refused_total(&self) -> u64 {
        self.refused.iter().sum()
    }
}

/// What a [`Recorder`] writes.
#[derive(Debug, Clone)]
pub struct Options {
    /// The MCAP file.
    pub mcap: PathBuf,
    /// Also write the three CSV files into this directory.
    pub csv_dir: Option<PathBuf>,
    /// Write a state or a torque only if its `seq` is above the last one's.
    pub skip_repeats: bool,
    /// The plausibility rules a message must pass to be written (none: every message that
    /// validates is written, as far as `sources` goes).
    pub rules: Option<Rules>,
    /// Check the sources: the plant's messages are written only from the plant's session, the
    /// torques only from the controller's, each known in advance or pinned by its first
    /// believed message ([`Sources`]); always done with `rules`. `None` without rules: every
    /// source is written.
    pub sources: Option<Sources>,
}

/// Why a recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// A CSV file could not be created or written.
    #[error("{path}: {cause}")]
    Csv {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: std::io::Error,
    },
    /// The MCAP file could not be created or written.
    #[error(transparent)]
    Mcap(#[from] WriteError),
    /// The writer thread could not start, or panicked.
    #[error("the recording thread: {0}")]
    Thread(String),
}

/// The recorder: a writer thread and what it has written so far.
pub struct Recorder {
    sink: Sink<Received, Writer>,
    view: Arc<Mutex<RecordView>>,
}

/// A message and the source it names, if any ([`tilting_proto::source`]).
type Received = (Record, Option<SourceId>);

/// A cheap, cloneable handle for subscriber callbacks: [`RecordSender::send`] never blocks.
#[derive(Clone)]
pub struct RecordSender(SinkSender<Received>);

impl RecordSender {
    /// Queues `rec`, whose source is unknown.
    pub fn send(&self, rec: Record) {
        self.0.send((rec, None));
    }

    /// Queues `rec` from `source` (`None`: it named none): with plausibility rules, a message
    /// from another session than the stream's pinned one is refused as foreign.
    pub fn send_from(&self, rec: Record, source: Option<SourceId>) {
        self.0.send((rec, source));
    }
}

impl Recorder {
    /// The recording of a live run: [`RUN_MCAP`] for `keys`' robot in `dir`, with `csv` the
    /// three CSV files (with their headers), repeats skipped, the plausibility `rules` and the
    /// plant's and controller's `sources` where known.
    pub fn create(
        dir: &Path,
        keys: &Keys,
        csv: bool,
        rules: Option<Rules>,
        sources: Sources,
    ) -> Result<Self, RecordError> {
        let opts = Options {
            mcap: dir.join(RUN_MCAP),
            csv_dir: csv.then(|| dir.to_path_buf()),
            skip_repeats: true,
            rules,
            sources: Some(sources),
        };
        Self::with_options(&opts, keys)
    }

    /// Creates the files of `opts` and starts the writer thread.
    pub fn with_options(opts: &Options, keys: &Keys) -> Result<Self, RecordError> {
        let csv = match &opts.csv_dir {
            Some(dir) => {
                let open = |name: &str, header: &str| {
                    let path = dir.join(name);
                    RowWriter::create(&path, header, RowWriter::INTERVAL)
                        .map_err(|cause| RecordError::Csv { path, cause })
                };
                Some(CsvFiles {
                    state: open(STATE_CSV, STATE_HEADER)?,
                    torque: open(TORQUE_CSV, TORQUE_HEADER)?,
                    events: open(EVENTS_CSV, EVENTS_HEADER)?,
                    dir: dir.clone(),
                })
            }
            None => None,
        };
        let view = Arc::new(Mutex::new(RecordView::default()));
        let writer = Writer {
            mcap: McapWriter::create(&opts.mcap, keys)?,
            csv,
            skip_repeats: opts.skip_repeats,
            guard: (opts.rules.is_some() || opts.sources.is_some())
                .then(|| Guard::new(opts.rules, opts.sources.unwrap_or_default())),
            shared: view.clone(),
            local: RecordView::default(),
            pending: 0,
            last_state: None,
            last_torque: None,
            tilt: None,
            result: Ok(()),
        };
        let sink = Sink::spawn("record", QUEUE, VIEW_INTERVAL, writer)
            .map_err(|e| RecordError::Thread(e.to_string()))?;
        Ok(Self { sink, view })
    }

    /// A handle for callbacks.
    pub fn sender(&self) -> RecordSender {
        RecordSender(self.sink.sender())
    }

    /// A snapshot of what was written so far (at most [`VIEW_INTERVAL`] old while messages
    /// are few, 64 messages behind while they stream).
    pub fn view(&self) -> RecordView {
        self.view.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Messages dropped because the writer fell behind.
    pub fn dropped(&self) -> u64 {
        self.sink.dropped()
    }

    /// Writes what is queued, flushes and closes the files; returns the final view. Messages
    /// sent afterwards are ignored.
    pub fn finish(self) -> Result<RecordView, RecordError> {
        let (view, result) = self.close();
        match result {
            Some(e) => Err(e),
            None => Ok(view),
        }
    }

    /// Like [`Recorder::finish`], but the view comes back whatever happened to the files: the
    /// view, and the first error if any (the files end where it happened).
    pub fn close(self) -> (RecordView, Option<RecordError>) {
        let last = self.view();
        match self.sink.finish() {
            Ok((view, result)) => (view, result.err()),
            Err(Panicked(p)) => (last, Some(RecordError::Thread(format!("{p} panicked")))),
        }
    }
}

/// A write error in words: the file, the system's error, and for a full disk `ENOSPC` by name.
pub fn describe(e: &RecordError) -> String {
    let io = match e {
        RecordError::Csv { cause, .. } => Some(cause),
        RecordError::Mcap(WriteError::Io { cause, .. }) => Some(cause),
        RecordError::Mcap(WriteError::Mcap {
            cause: mcap::McapError::Io(io),
            ..
        }) => Some(io),
        _ => None,
    };
    let mut text = e.to_string();
    if let Some(io) = io {
        if !text.contains(&io.to_string()) {
            text.push_str(&format!(": {io}"));
        }
        if io.kind() == std::io::ErrorKind::StorageFull {
            text.push_str(" (ENOSPC: the disk is full)");
        }
    }
    text
}

struct CsvFiles {
    state: RowWriter,
    torque: RowWriter,
    events: RowWriter,
    dir: PathBuf,
}

impl CsvFiles {
    /// Applies `write` (a flush) to the three files in turn; the first failure stops it, as
    /// [`RecordError::Csv`] naming that file's path.
    fn each(
        &mut self,
        write: impl Fn(&mut RowWriter) -> std::io::Result<()>,
    ) -> Result<(), RecordError> {
        for (w, name) in [
            (&mut self.state, STATE_CSV),
            (&mut self.torque, TORQUE_CSV),
            (&mut self.events, EVENTS_CSV),
        ] {
            write(w).map_err(|cause| RecordError::Csv {
                path: self.dir.join(name),
                cause,
            })?;
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

/// The writer thread's state.
struct Writer {
    mcap: McapWriter,
    csv: Option<CsvFiles>,
    skip_repeats: bool,
    guard: Option<Guard>,
    /// The view the recorder reads, published every 64 messages or when idle.
    shared: Arc<Mutex<RecordView>>,
    local: RecordView,
    pending: u32,
    last_state: Option<u64>,
    last_torque: Option<u64>,
    tilt: Option<Tilt>,
    /// The first error; the thread keeps draining after it so senders never block.
    result: Result<(), RecordError>,
}

impl Writer {
    fn publish(&mut self) {
        self.pending = 0;
        *self.shared.lock().unwrap_or_else(|e| e.into_inner()) = self.local.clone();
    }

    fn csv_error(&self, name: &str) -> impl FnOnce(std::io::Error) -> RecordError {
        let path = self
            .csv
            .as_ref()
            .map_or_else(PathBuf::new, |c| c.dir.join(name));
        move |cause| RecordError::Csv { path, cause }
    }

    /// A wire payload as the message it encodes, `None` (counted) if it does not decode.
    fn decode(&mut self, topic: Topic, wire: &[u8]) -> Option<Record> {
        let r = match topic {
            Topic::State => codec::decode(wire).map(Record::State),
            Topic::Torque => codec::decode(wire).map(Record::Torque),
            Topic::Event => codec::decode(wire).map(Record::Event),
            Topic::Status => codec::decode(wire).map(Record::Status),
            Topic::Reference => codec::decode(wire).map(Record::Reference),
        };
        if r.is_err() {
            self.local.invalid += 1;
        }
        r.ok()
    }

    /// Whether `rec` from `source` passes the plausibility rules; a refusal is counted.
    fn believed(&mut self, rec: &Record, source: Option<SourceId>) -> bool {
        let Some(g) = &mut self.guard else {
            return true;
        };
        let topic = match rec {
            Record::State(_) => Topic::State,
            Record::Torque(_) => Topic::Torque,
            Record::Event(_) => Topic::Event,
            Record::Status(_) => Topic::Status,
            Record::Reference(_) => Topic::Reference,
            Record::Wire(t, _) => *t,
        };
        match g.check(rec, source) {
            Ok(()) => true,
            Err(e) => {
                self.local.refused[topic.index()] += 1;
                self.local.foreign += u64::from(e.is_foreign());
                self.local.foreign_per_topic[topic.index()] += u64::from(e.is_foreign());
                if self.local.first_refusal.is_none() {
                    self.local.first_refusal = Some(e.to_string());
                    self.pending = 64;
                }
                false
            }
        }
    }

    fn write(&mut self, rec: Record, source: Option<SourceId>) -> Result<(), RecordError> {
        if !matches!(rec, Record::Wire(..)) && !self.believed(&rec, source) {
            return Ok(());
        }
        match rec {
            Record::Wire(topic, wire) => {
                if let Some(r) = self.decode(topic, &wire) {
                    self.write(r, source)?;
                }
            }
            Record::State(s) => {
                if self.skip_repeats && self.last_state.is_some_and(|l| s.seq <= l) {
                    self.local.repeated_states += 1;
                    return Ok(());
                }
                if let Some(last) = self.last_state.filter(|&last| s.seq > last) {
                    self.local.missing_states += s.seq - last - 1;
                }
                self.last_state = Some(s.seq);
                self.local.states += 1;
                self.local.last_state = Some(s);
                self.local.last_state_at = Some(Instant::now());
                track_peak(&mut self.tilt, &s, &mut self.local.peaks);
                self.mcap.record(Topic::State, &encode(&s))?;
                if self.csv.is_some() {
                    let e = self.csv_error(STATE_CSV);
                    if let Some(c) = &mut self.csv {
                        c.state
                            .row(format_args!(
                                "{},{},{},{},{},{},{}",
                                s.seq,
                                s.time,
                                s.mode,
                                s.alpha,
                                s.beta,
                                Cell(s.alpha_dot),
                                Cell(s.beta_dot)
                            ))
                            .map_err(e)?;
                    }
                }
            }
            Record::Torque(t) => {
                if self.skip_repeats && self.last_torque.is_some_and(|l| t.seq <= l) {
                    self.local.repeated_torques += 1;
                    return Ok(());
                }
                self.last_torque = Some(t.seq);
                self.local.torques += 1;
                self.mcap.record(Topic::Torque, &encode(&t))?;
                if self.csv.is_some() {
                    let e = self.csv_error(TORQUE_CSV);
                    if let Some(c) = &mut self.csv {
                        c.torque
                            .row(format_args!("{},{}", t.seq, t.tau))
                            .map_err(e)?;
                    }
                }
            }
            Record::Event(ev) => {
                self.local.events += 1;
                if ev.from == 0 && ev.to != 0 {
                    self.local.tilts += 1;
                }
                self.mcap.record(Topic::Event, &encode(&ev))?;
                if self.csv.is_some() {
                    let e = self.csv_error(EVENTS_CSV);
                    if let Some(c) = &mut self.csv {
                        let (b, a) = (ev.x_before, ev.x_after);
                        c.events
                            .row(format_args!(
                                "{},{},{},{},{},{},{},{},{},{},{}",
                                ev.time,
                                ev.from,
                                ev.to,
                                b[0],
                                b[1],
                                b[2],
                                b[3],
                                a[0],
                                a[1],
                                a[2],
                                a[3]
                            ))
                            .map_err(e)?;
                    }
                }
            }
            Record::Status(st) => {
                self.local.statuses += 1;
                self.mcap.record(Topic::Status, &encode(&st))?;
                self.local.last_status = Some(st);
            }
            Record::Reference(r) => {
                self.local.references += 1;
                self.mcap.record(Topic::Reference, &encode(&r))?;
            }
        }
        Ok(())
    }

    fn flush_if_due(&mut self) -> Result<(), RecordError> {
        self.mcap.flush_if_due()?;
        if let Some(c) = &mut self.csv {
            c.each(RowWriter::flush_if_due)?;
        }
        Ok(())
    }
}

impl Drain<Received> for Writer {
    type Output = (RecordView, Result<(), RecordError>);

    fn message(&mut self, (rec, source): Received) {
        if self.result.is_ok() {
            self.result = self.write(rec, source);
            self.note_error();
        } else {
            // The files stopped; the view goes on (the status line and the summary).
            self.count_only(rec, source);
        }
        self.pending += 1;
        if self.pending >= 64 {
            self.publish();
        }
    }

    fn idle(&mut self) {
        if self.result.is_ok() {
            self.result = self.flush_if_due();
            self.note_error();
        }
        if self.pending > 0 {
            self.publish();
        }
    }

    fn finish(mut self) -> (RecordView, Result<(), RecordError>) {
        finish_peak(&self.tilt, &mut self.local.peaks);
        self.publish();
        let result = std::mem::replace(&mut self.result, Ok(())).and_then(|()| self.close());
        if let Err(e) = &result {
            self.local.error.get_or_insert_with(|| describe(e));
        }
        (self.local, result)
    }
}

impl Writer {
    /// The first write error goes into the view at once.
    fn note_error(&mut self) {
        if let Err(e) = &self.result {
            if self.local.error.is_none() {
                self.local.error = Some(describe(e));
                self.publish();
            }
        }
    }

    /// After a write error: the view still follows what is believed (counts, status, peaks).
    fn count_only(&mut self, rec: Record, source: Option<SourceId>) {
        let rec = match rec {
            Record::Wire(topic, wire) => match self.decode(topic, &wire) {
                Some(r) => r,
                None => return,
            },
            r => r,
        };
        if !self.believed(&rec, source) {
            return;
        }
        match rec {
            Record::State(s) if self.last_state.is_none_or(|l| s.seq > l) => {
                self.last_state = Some(s.seq);
                self.local.last_state = Some(s);
                self.local.last_state_at = Some(Instant::now());
                track_peak(&mut self.tilt, &s, &mut self.local.peaks);
            }
            Record::Status(st) => self.local.last_status = Some(st),
            Record::Event(ev) if ev.from == 0 && ev.to != 0 => self.local.tilts += 1,
            _ => {}
        }
    }

    /// Writes the summary section and the last CSV rows.
    fn close(&mut self) -> Result<(), RecordError> {
        self.mcap.finish()?;
        if let Some(c) = &mut self.csv {
            c.each(RowWriter::flush)?;
        }
        Ok(())
    }
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

/// A rate in a CSV row: its value, or an empty cell when it was not measured (never 0).
struct Cell(Option<f64>);

impl std::fmt::Display for Cell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            Some(v) => write!(f, "{v}"),
            None => Ok(()),
        }
    }
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
            alpha_dot: Some(0.0),
            beta_dot: Some(0.0),
            mode,
        }
    }

    fn keys() -> Keys {
        Keys::new("t").unwrap()
    }

    /// The rules of a 1 kHz plant with the default bounds, started with the recorder.
    fn rules() -> Rules {
        Rules {
            period: Some(1e-3),
            min_period: 1e-4,
            max_torque: 116.5,
            fall_angle: std::f64::consts::FRAC_PI_2,
            from_start: true,
        }
    }

    #[test]
    fn a_peak_reached_in_the_unfinished_last_tilt_counts() {
        // The truth is the samples themselves: alpha rises to its largest sample, then falls
        // (a peak, though the tilt never lands) or only rises (no peak yet).
        for (turned_back, want) in [(true, 1), (false, 0)] {
            let tmp = tempfile::tempdir().unwrap();
            let rec =
                Recorder::create(tmp.path(), &keys(), false, None, Sources::default()).unwrap();
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
    fn writes_dedups_and_tracks_peaks() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().to_path_buf();
        let rec = Recorder::create(&dir, &keys(), true, None, Sources::default()).unwrap();
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
        let run = crate::read(&dir.join(RUN_MCAP)).unwrap();
        assert!(run.complete());
        assert_eq!(
            (
                run.count(Topic::State),
                run.count(Topic::Torque),
                run.count(Topic::Event)
            ),
            (101, 100, 2)
        );
        let tr = crate::load(&dir, Default::default(), None).unwrap().trace;
        assert_eq!((tr.samples.len(), tr.events.len()), (101, 2));
        assert_eq!(tr.end, 0.105);
        // And so do the CSV files.
        std::fs::remove_file(dir.join(RUN_MCAP)).unwrap();
        let csv = crate::load(&dir, Default::default(), None).unwrap().trace;
        assert_eq!(csv, tr);
    }

    /// Wire payloads as received: every copy kept without `skip_repeats`, one that does not
    /// decode counted and not written.
    #[test]
    fn wire_payloads_are_decoded_and_kept_as_sent() {
        let tmp = tempfile::tempdir().unwrap();
        let opts = Options {
            mcap: tmp.path().join("r.mcap"),
            csv_dir: None,
            skip_repeats: false,
            rules: None,
            sources: None,
        };
        let rec = Recorder::with_options(&opts, &keys()).unwrap();
        let tx = rec.sender();
        for _ in 0..3 {
            tx.send(Record::Wire(Topic::State, encode(&state(0, 0, 0.0))));
        }
        tx.send(Record::Wire(Topic::Torque, vec![1, 2, 3]));
        let v = rec.finish().unwrap();
        assert_eq!((v.states, v.repeated_states, v.invalid), (3, 0, 1));
        assert_eq!((v.count(Topic::State), v.count(Topic::Torque)), (3, 0));
        let run = crate::read(&opts.mcap).unwrap();
        assert_eq!(run.count(Topic::State), 3);
    }

    /// The forged state of issue 22 (`seq = 2^63`, `time = 1e300`) and a forged torque amid a
    /// plausible stream: both refused and counted, and the recording is the stream without them
    /// (the truth: the same stream recorded without the forgeries).
    #[test]
    fn forged_messages_are_refused_and_change_nothing() {
        let rules = rules();
        let run = |forge: bool| {
            let tmp = tempfile::tempdir().unwrap();
            let rec = Recorder::create(tmp.path(), &keys(), false, Some(rules), Sources::default())
                .unwrap();
            let tx = rec.sender();
            for k in 0..200u64 {
                if forge && k == 50 {
                    let mut lie = state(1 << 63, 1, 0.01);
                    lie.time = 1e300;
                    tx.send(Record::State(lie));
                    tx.send(Record::Torque(TorqueCommand {
                        seq: 1 << 62,
                        tau: 1.0,
                    }));
                    tx.send(Record::Torque(TorqueCommand { seq: 49, tau: 1e6 }));
                    // On its grid, but 2^40 periods ahead of the wall clock.
                    tx.send(Record::State(state(1 << 40, 1, 0.01)));
                }
                tx.send(Record::State(state(k, 1, 0.03 * (k as f64 * 0.06).sin())));
                tx.send(Record::Torque(TorqueCommand { seq: k, tau: 0.5 }));
            }
            let v = rec.finish().unwrap();
            let file = crate::read(&tmp.path().join(RUN_MCAP)).unwrap();
            (v, file.count(Topic::State), file.span())
        };
        let (clean, n0, span0) = run(false);
        let (v, n, span) = run(true);
        assert_eq!(v.refused, [2, 2, 0, 0, 0]);
        assert!(
            v.first_refusal
                .as_deref()
                .unwrap()
                .contains("PlantState.seq"),
            "{v:?}"
        );
        assert_eq!((v.states, v.torques, v.missing_states), (200, 200, 0));
        assert_eq!((n, span), (n0, span0));
        assert_eq!(span, Some((0.0, 0.199)));
        assert_eq!(v.peaks, clean.peaks);
        assert_eq!(clean.refused, [0; 5]);
    }

    /// A second session publishing plausible states (one period ahead, on the grid) and
    /// torques amid the plant's and the controller's streams, naming no source or its own:
    /// every one refused as foreign, and the recording is the honest stream's (the truth: the
    /// same stream recorded alone). A forger that copies the plant's id passes: the identity
    /// is the publisher's claim ([`tilting_proto::source`]).
    #[test]
    fn messages_from_a_foreign_source_are_refused_and_change_nothing() {
        let rules = rules();
        let (plant, ctl, other) = (
            Some(SourceId([1; 16])),
            Some(SourceId([2; 16])),
            Some(SourceId([3; 16])),
        );
        let run = |forge: bool, copy_id: bool| {
            let tmp = tempfile::tempdir().unwrap();
            let rec = Recorder::create(tmp.path(), &keys(), false, Some(rules), Sources::default())
                .unwrap();
            let tx = rec.sender();
            for k in 0..200u64 {
                if forge && (50..60).contains(&k) {
                    let from = match (copy_id, k % 2) {
                        (true, _) => plant,
                        (false, 0) => other,
                        (false, _) => None,
                    };
                    tx.send_from(Record::State(state(k, 1, 0.3)), from);
                    let torque_from = if copy_id { ctl } else { from };
                    let t = TorqueCommand {
                        seq: k - 1,
                        tau: 3.25,
                    };
                    tx.send_from(Record::Torque(t), torque_from);
                }
                let s = state(k, 1, 0.03 * (k as f64 * 0.06).sin());
                tx.send_from(Record::State(s), plant);
                tx.send_from(Record::Torque(TorqueCommand { seq: k, tau: 0.5 }), ctl);
            }
            let v = rec.finish().unwrap();
            let file = crate::read(&tmp.path().join(RUN_MCAP)).unwrap();
            let states: Vec<Vec<u8>> = file
                .messages()
                .filter(|m| m.topic == Topic::State)
                .map(|m| m.wire)
                .collect();
            (v, states)
        };
        let (clean, truth) = run(false, false);
        let (v, states) = run(true, false);
        assert_eq!(v.refused, [10, 10, 0, 0, 0], "{v:?}");
        assert_eq!(v.foreign, 20);
        let first = v.first_refusal.as_deref().unwrap();
        assert!(
            first.contains("PlantState from a foreign source"),
            "{first}"
        );
        assert_eq!(states, truth);
        assert_eq!((v.states, v.torques, v.missing_states), (200, 200, 0));
        assert_eq!(v.peaks, clean.peaks);
        assert_eq!((clean.refused, clean.foreign), ([0; 5], 0));
        // The limit: the plant's own id, copied, is believed (the forged state of seq k takes
        // the place of the plant's, which then counts as a repeat).
        let (v, states) = run(true, true);
        assert_eq!((v.refused, v.foreign), ([0; 5], 0));
        assert_ne!(states, truth);
    }

    /// A rogue session that publishes plausible states and torques *before* the plant and the
    /// controller start (seq 0..10, alpha 0.3 rad). With the sources unknown, the rogue's first
    /// state takes the pin and the plant's whole stream is refused (the failure this guards
    /// against); with the plant's and the controller's ids known in advance ([`Sources`]), every
    /// rogue message is refused as foreign and the recording is the honest stream's, the same
    /// bytes as the honest stream recorded alone (the truth).
    #[test]
    fn a_rogue_that_talks_first_does_not_take_a_known_pin() {
        let (plant, ctl, rogue) = (SourceId([1; 16]), SourceId([2; 16]), SourceId([3; 16]));
        let known = Sources {
            plant: Some(plant),
            controller: Some(ctl),
        };
        let run = |sources: Sources, with_rogue: bool| {
            let tmp = tempfile::tempdir().unwrap();
            let rec = Recorder::create(tmp.path(), &keys(), false, Some(rules()), sources).unwrap();
            let tx = rec.sender();
            if with_rogue {
                for k in 0..10u64 {
                    tx.send_from(Record::State(state(k, 1, 0.3)), Some(rogue));
                    let t = TorqueCommand { seq: k, tau: 3.25 };
                    tx.send_from(Record::Torque(t), Some(rogue));
                }
            }
            for k in 0..100u64 {
                let s = state(k, 1, 0.03 * (k as f64 * 0.06).sin());
                tx.send_from(Record::State(s), Some(plant));
                tx.send_from(
                    Record::Torque(TorqueCommand { seq: k, tau: 0.5 }),
                    Some(ctl),
                );
            }
            let v = rec.finish().unwrap();
            let file = crate::read(&tmp.path().join(RUN_MCAP)).unwrap();
            let wire: Vec<(Topic, Vec<u8>)> = file.messages().map(|m| (m.topic, m.wire)).collect();
            (v, wire)
        };
        let (_, truth) = run(known, false);
        let (v, wire) = run(known, true);
        // Every rogue message refused: its states as foreign, its torques as foreign or as
        // answering no believed state (that rule comes first).
        assert_eq!(v.refused, [10, 10, 0, 0, 0], "{v:?}");
        assert!(v.foreign >= 10, "{v:?}");
        assert_eq!((v.states, v.torques), (100, 100));
        assert_eq!(wire, truth);
        // Unknown sources: the rogue's states pinned the plant's stream and are in the
        // recording, and honest states were refused.
        let (v, wire) = run(Sources::default(), true);
        assert!(v.refused[0] > 0 && v.foreign > 0, "{v:?}");
        assert_ne!(wire, truth);
    }

    /// Sources without rules (`tilting record`): a second session's messages are refused as
    /// foreign and kept out, whatever they say; the pinned sources' messages are all written,
    /// implausible ones too (no rules). The truth: the honest streams recorded alone.
    #[test]
    fn sources_alone_keep_a_foreign_publisher_out() {
        let (plant, ctl, other) = (SourceId([1; 16]), SourceId([2; 16]), SourceId([3; 16]));
        let run = |sources: Option<Sources>, foreign: bool| {
            let tmp = tempfile::tempdir().unwrap();
            let opts = Options {
                mcap: tmp.path().join("r.mcap"),
                csv_dir: None,
                skip_repeats: false,
                rules: None,
                sources,
            };
            let rec = Recorder::with_options(&opts, &keys()).unwrap();
            let tx = rec.sender();
            for k in 0..50u64 {
                // An implausible state (alpha beyond the fall angle) from the plant: no rules.
                let alpha = if k == 7 { 9.0 } else { 0.01 };
                let s = encode(&state(k, 1, alpha));
                tx.send_from(Record::Wire(Topic::State, s), Some(plant));
                let t = encode(&TorqueCommand { seq: k, tau: 0.5 });
                tx.send_from(Record::Wire(Topic::Torque, t), Some(ctl));
                if foreign && k % 5 == 0 {
                    let s = encode(&state(k + 1, 1, 0.2));
                    tx.send_from(Record::Wire(Topic::State, s), Some(other));
                    let t = encode(&TorqueCommand { seq: k, tau: 2.0 });
                    tx.send_from(Record::Wire(Topic::Torque, t), None);
                }
            }
            let v = rec.finish().unwrap();
            let file = crate::read(&opts.mcap).unwrap();
            let wire: Vec<(Topic, Vec<u8>)> = file.messages().map(|m| (m.topic, m.wire)).collect();
            (v, wire)
        };
        let (_, truth) = run(None, false);
        let (v, wire) = run(Some(Sources::default()), true);
        assert_eq!((v.refused, v.foreign), ([10, 10, 0, 0, 0], 20), "{v:?}");
        // Each refusal is charged to its stream's pin: the states' to the plant's, the
        // torques' to the controller's.
        assert_eq!(v.foreign_per_topic, [10, 10, 0, 0, 0], "{v:?}");
        assert_eq!((v.states, v.torques), (50, 50));
        assert_eq!(wire, truth);
        // Without sources, everything is the recording (the foreign messages too).
        let (v, wire) = run(None, true);
        assert_eq!(
            (v.refused, v.foreign, v.states, v.torques),
            ([0; 5], 0, 60, 60)
        );
        assert_ne!(wire, truth);
    }

    #[test]
    fn a_full_queue_drops_without_blocking() {
        let tmp = tempfile::tempdir().unwrap();
        let rec = Recorder::create(tmp.path(), &keys(), false, None, Sources::default()).unwrap();
        let tx = rec.sender();
        for k in 0..(4 * QUEUE as u64) {
            tx.send(Record::Torque(TorqueCommand { seq: k, tau: 0.0 }));
        }
        let dropped = rec.dropped();
        let v = rec.finish().unwrap();
        assert_eq!(v.torques + dropped, 4 * QUEUE as u64);
    }
}
