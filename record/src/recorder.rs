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
use crate::peaks::PeakTracker;
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
    codec, encode, AnyReference, Keys, ModeEvent, PlantState, SourceId, Status, Topic,
    TorqueCommand,
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
    /// A reference of the planner, either layout (the paper's `Reference` or any law's
    /// `LawReference`, protocol 3): recorded as sent.
    Reference(AnyReference),
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
            tilt: PeakTracker::default(),
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
    tilt: PeakTracker,
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

/// Feeds the state `s` to the tilt tracker; a tilt it ends goes into `peaks` as `(t, alpha)`.
fn track_peak(tilt: &mut PeakTracker, s: &PlantState, peaks: &mut VecDeque<(f64, f64)>) {
    if let Some(p) = tilt.push(s.mode, s.time, s.alpha) {
        push_peak(peaks, (p.t, p.alpha));
    }
}

/// At the end of a recording: the tilt still in progress has reached its peak if `|alpha|` has
/// come back down since its largest sample; that peak belongs to the run although the tilt has
/// not landed (a tilt whose `|alpha|` is still growing at the last sample has no peak yet:
/// [`PeakTracker::settled_peak`]).
fn finish_peak(tilt: &PeakTracker, peaks: &mut VecDeque<(f64, f64)>) {
    if let Some(p) = tilt.settled_peak() {
        push_peak(peaks, (p.t, p.alpha));
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
mod tests;
