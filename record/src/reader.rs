//! Reading a recording back: [`read`] checks the file and counts what it holds;
//! [`Recording::messages`] streams the wire payloads in file order.
//!
//! A damaged file (flipped bits, a torn write) is read up to the damage, then reading stops
//! with an error that gives the byte offset where it stopped. No record's stated length can
//! make the reader allocate more than the file holds ([`RECORD_LIMIT`]), and a chunk whose
//! CRC does not match yields none of its messages.

use crate::{schema, JSON_ENCODING};
use mcap::sans_io::{LinearReaderOptions, MessageReadEvent, MessageReader};
use std::path::{Path, PathBuf};
use tilting_proto::bounded;
use tilting_proto::{codec, ModeEvent, Status, Topic};

/// Why a file cannot be read as a recording.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file cannot be opened or read.
    #[error("cannot read {path}: {cause}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: std::io::Error,
    },
    /// It does not start with the MCAP magic bytes.
    #[error("{path} is not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap {
        /// The file.
        path: PathBuf,
    },
    /// It is MCAP, but holds none of the channels this project writes.
    #[error(
        "{path} is an MCAP file but has no tilting channels (JSON with schemas `tilting.PlantState`, \
         `tilting.TorqueCommand`, ...): it was not recorded by tilting"
    )]
    Foreign {
        /// The file.
        path: PathBuf,
    },
    /// It ends (torn) before its first message of ours.
    #[error("{path} ends before its first message ({why}): nothing to read")]
    Empty {
        /// The file.
        path: PathBuf,
        /// Where reading stopped.
        why: String,
    },
    /// It is MCAP, but broken before its first message.
    #[error("{path}: {cause}")]
    Broken {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: mcap::McapError,
    },
}

/// One recorded message: its topic, its log time (plant time, ns) and its wire payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    /// The topic.
    pub topic: Topic,
    /// Log time: plant time, ns.
    pub log_time: u64,
    /// The payload exactly as it crossed the wire (recovered from the JSON; decode with
    /// `tilting_proto::codec`).
    pub wire: Vec<u8>,
}

impl Entry {
    /// Log time in plant seconds.
    pub fn time(&self) -> f64 {
        self.log_time as f64 / 1e9
    }
}

/// A recording opened by [`read`]: the file's bytes (compressed: a 20 s run at 1 kHz is a few
/// hundred kB) and what a first pass counted.
pub struct Recording {
    path: PathBuf,
    bytes: Vec<u8>,
    robot: Option<String>,
    counts: [u64; 5],
    first: Option<u64>,
    last: Option<u64>,
    complete: bool,
    truncation: Option<String>,
    tilts: u64,
    faults: Vec<String>,
    invalid: u64,
    first_invalid: Option<String>,
}

/// Opens `path`, checks it is a tilting recording and counts its messages per topic, its tilts
/// and the faults its status messages report. A file whose writer was killed (no summary
/// section, a torn last chunk) opens: [`Recording::complete`] is then false and
/// [`Recording::truncation`] says where reading stopped.
pub fn read(path: &Path) -> Result<Recording, ReadError> {
    let io = |cause| ReadError::Io {
        path: path.to_owned(),
        cause,
    };
    // The magic first: a file that is not MCAP (`/dev/zero`) is not read further.
    let mut magic = [0u8; 8];
    let n = std::fs::File::open(path)
        .and_then(|f| std::io::Read::read(&mut std::io::Read::take(f, 8), &mut magic))
        .map_err(io)?;
    if !magic[..n].starts_with(mcap::MAGIC) {
        return Err(ReadError::NotMcap {
            path: path.to_owned(),
        });
    }
    let bytes = bounded::read(path, bounded::RECORDING_LIMIT, "a recording").map_err(io)?;
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(ReadError::NotMcap {
            path: path.to_owned(),
        });
    }
    let complete = bytes.ends_with(mcap::MAGIC)
        && bytes.len() > 2 * mcap::MAGIC.len()
        && mcap::read::footer(&bytes).is_ok();
    let mut rec = Recording {
        path: path.to_owned(),
        bytes: Vec::new(),
        robot: None,
        counts: [0; 5],
        first: None,
        last: None,
        complete,
        truncation: None,
        tilts: 0,
        faults: Vec::new(),
        invalid: 0,
        first_invalid: None,
    };
    let mut wire_channels = 0usize;
    let mut it = stream(&bytes);
    while let Some(m) = it.next_message() {
        let Some(topic) = topic_of(&m.channel) else {
            continue;
        };
        wire_channels += 1;
        if rec.robot.is_none() {
            rec.robot = m.channel.topic.split('/').nth(2).map(str::to_owned);
        }
        let data = match schema::from_json(topic, &m.data) {
            Ok(d) => d,
            Err(e) => {
                // One bad message (another version's, or edited) does not hide the rest.
                if rec.invalid == 0 {
                    rec.first_invalid = Some(format!(
                        "a {topic} message at log time {} ns: {e}",
                        m.log_time
                    ));
                }
                rec.invalid += 1;
                continue;
            }
        };
        rec.tally(topic, &data, m.log_time);
    }
    rec.truncation = it.error.take();
    drop(it);
    rec.bytes = bytes;
    if wire_channels == 0 {
        return Err(match rec.truncation {
            None => ReadError::Foreign {
                path: path.to_owned(),
            },
            Some(why) => ReadError::Empty {
                path: path.to_owned(),
                why,
            },
        });
    }
    if rec.complete && rec.truncation.is_some() {
        rec.complete = false;
    }
    if !rec.complete && rec.truncation.is_none() {
        rec.truncation = Some("the file has no summary section (its writer did not finish)".into());
    }
    Ok(rec)
}

impl Recording {
    /// Counts one valid message of `topic` (wire bytes `data`, logged at `log_time` ns): its
    /// topic's count, the span, a tilt's start (an event from flat) and a new fault (a status).
    fn tally(&mut self, topic: Topic, data: &[u8], log_time: u64) {
        self.counts[topic.index()] += 1;
        self.first = Some(self.first.map_or(log_time, |f| f.min(log_time)));
        self.last = Some(self.last.map_or(log_time, |l| l.max(log_time)));
        match topic {
            Topic::Event => {
                if let Ok(e) = codec::decode::<ModeEvent>(data) {
                    self.tilts += u64::from(e.from == 0 && e.to != 0);
                }
            }
            Topic::Status => {
                if let Ok(s) = codec::decode::<Status>(data) {
                    if !s.fault.is_empty() && !self.faults.contains(&s.fault) {
                        self.faults.push(s.fault);
                    }
                }
            }
            _ => {}
        }
    }
}

/// The topic of a channel of ours (JSON with a `tilting.*` schema), `None` for any other.
fn topic_of(c: &mcap::Channel<'_>) -> Option<Topic> {
    if c.message_encoding != JSON_ENCODING {
        return None;
    }
    schema::topic_of_schema(&c.schema.as_ref()?.name)
}

/// Longest record the reader accepts, inside a chunk or not (bytes): the file's size, or 64 MiB
/// for a small file whose chunks decompress to more (this project's chunks hold at most about
/// 1 MiB). A stated length beyond it is damage, not an allocation.
pub const RECORD_LIMIT: usize = 64 << 20;

/// The messages of a recording in file order (log time order for one writer).
pub struct Messages<'a> {
    bytes: &'a [u8],
    /// Bytes handed to the reader so far.
    offset: usize,
    reader: MessageReader,
    error: Option<String>,
}

impl Messages<'_> {
    /// The next message of the file, or `None` at its end or at the first damage (then
    /// [`Messages::error`] says what and where).
    fn next_message(&mut self) -> Option<mcap::Message<'static>> {
        if self.error.is_some() {
            return None;
        }
        loop {
            match self.reader.next_event()? {
                Ok(MessageReadEvent::Message(m)) => return Some(m),
                Ok(MessageReadEvent::ReadRequest(n)) => {
                    let n = n.min(self.bytes.len() - self.offset);
                    let buf = self.reader.insert(n);
                    buf.copy_from_slice(&self.bytes[self.offset..self.offset + n]);
                    self.reader.notify_read(n);
                    self.offset += n;
                }
                Err(e) => {
                    self.error = Some(format!(
                        "{e} (reading stopped at byte {} of {})",
                        self.offset,
                        self.bytes.len()
                    ));
                    return None;
                }
            }
        }
    }

    /// Why the stream ended early (a torn or damaged chunk, with the byte offset where reading
    /// stopped), if it did.
    pub fn error(&self) -> Option<&str> {
        self.error.as_deref()
    }
}

impl Iterator for Messages<'_> {
    type Item = Entry;
    fn next(&mut self) -> Option<Entry> {
        loop {
            let m = self.next_message()?;
            if let Some(topic) = topic_of(&m.channel) {
                // Messages that do not decode are skipped (counted by `read`).
                if let Ok(wire) = schema::from_json(topic, &m.data) {
                    return Some(Entry {
                        topic,
                        log_time: m.log_time,
                        wire,
                    });
                }
            }
        }
    }
}

/// A stream over the file's bytes: the end magic is not required (a killed writer's file), no
/// record may state a length beyond [`RECORD_LIMIT`] or the file's size, whichever is larger,
/// and each chunk's CRC is checked before any of its messages is yielded.
fn stream(bytes: &[u8]) -> Messages<'_> {
    let options = LinearReaderOptions::default()
        .with_skip_end_magic(true)
        .with_prevalidate_chunk_crcs(true)
        .with_record_length_limit(bytes.len().max(RECORD_LIMIT));
    Messages {
        bytes,
        offset: 0,
        reader: MessageReader::new_with_options(options),
        error: None,
    }
}

impl Recording {
    /// Streams the wire messages, decompressing one chunk at a time.
    pub fn messages(&self) -> Messages<'_> {
        stream(&self.bytes)
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Size of the file, bytes.
    pub fn size(&self) -> u64 {
        self.bytes.len() as u64
    }

    /// The robot name in the channel topics.
    pub fn robot(&self) -> Option<&str> {
        self.robot.as_deref()
    }

    /// Messages on `topic`.
    pub fn count(&self, topic: Topic) -> u64 {
        self.counts[topic.index()]
    }

    /// Log time of the first and of the last message (plant time, s).
    pub fn span(&self) -> Option<(f64, f64)> {
        Some((self.first? as f64 / 1e9, self.last? as f64 / 1e9))
    }

    /// The file was closed normally (summary section and footer present, every chunk read).
    pub fn complete(&self) -> bool {
        self.complete
    }

    /// Why reading stopped before a footer, for a file that is not complete.
    pub fn truncation(&self) -> Option<&str> {
        self.truncation.as_deref()
    }

    /// Tilts (flat to left or right events).
    pub fn tilts(&self) -> u64 {
        self.tilts
    }

    /// Messages of our channels that did not decode or validate (skipped), and the first one.
    pub fn invalid(&self) -> (u64, Option<&str>) {
        (self.invalid, self.first_invalid.as_deref())
    }

    /// Distinct faults reported by status messages, in order of first appearance.
    pub fn faults(&self) -> &[String] {
        &self.faults
    }

    /// What the recording holds, in one value (`tilting info`).
    pub fn info(&self) -> Info {
        let span = self.span();
        Info {
            file: self.path.clone(),
            bytes: self.size(),
            robot: self.robot().map(str::to_owned),
            complete: self.complete(),
            truncation: self.truncation().map(str::to_owned),
            start: span.map(|s| s.0),
            end: span.map(|s| s.1),
            counts: Topic::ALL
                .iter()
                .map(|&t| (t.name().to_owned(), self.count(t)))
                .collect(),
            tilts: self.tilts(),
            faults: self.faults().to_vec(),
            invalid: self.invalid().0,
        }
    }
}

/// What a recording holds ([`Recording::info`]; the JSON of `tilting info --json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Info {
    /// The file, as given to [`read`].
    pub file: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
    /// The robot of the channels.
    pub robot: Option<String>,
    /// Closed normally (summary section present).
    pub complete: bool,
    /// Why reading stopped early, for a file that is not complete.
    pub truncation: Option<String>,
    /// Plant time of the first and the last message, s.
    pub start: Option<f64>,
    /// See `start`.
    pub end: Option<f64>,
    /// Messages per topic, by topic name (every topic, 0 included).
    pub counts: std::collections::BTreeMap<String, u64>,
    /// Tilts (flat to left or right).
    pub tilts: u64,
    /// Distinct faults reported by the plant's status.
    pub faults: Vec<String>,
    /// Messages that did not decode or validate (skipped).
    pub invalid: u64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::McapWriter;
    use tilting_proto::{encode, Keys, PlantState, TorqueCommand};

    fn state(seq: u64) -> PlantState {
        PlantState {
            seq,
            time: seq as f64 * 1e-3,
            alpha: 0.0,
            beta: 1.5 + seq as f64 * 1e-6,
            alpha_dot: Some(0.0),
            beta_dot: Some(0.0),
            mode: 0,
        }
    }

    /// Writes `n` states and torques, flushing after `flushed` of them; returns the file and its
    /// length at that flush.
    fn write(dir: &Path, n: u64, flushed: u64) -> (PathBuf, usize) {
        let path = dir.join("run.mcap");
        let mut rec = McapWriter::create(&path, &Keys::new("bot").unwrap()).unwrap();
        let mut at_flush = 0;
        for k in 0..n {
            rec.record(Topic::State, &encode(&state(k))).unwrap();
            rec.record(
                Topic::Torque,
                &encode(&TorqueCommand {
                    seq: k,
                    tau: k as f64,
                }),
            )
            .unwrap();
            if k + 1 == flushed {
                rec.flush().unwrap();
                at_flush = std::fs::metadata(&path).unwrap().len() as usize;
            }
        }
        rec.finish().unwrap();
        (path, at_flush)
    }

    #[test]
    fn a_finished_file_reads_back_byte_exact_with_plant_times() {
        let dir = tempfile::tempdir().unwrap();
        let (path, _) = write(dir.path(), 500, 0);
        let run = read(&path).unwrap();
        assert!(run.complete() && run.truncation().is_none());
        assert_eq!(run.robot(), Some("bot"));
        assert_eq!(
            (run.count(Topic::State), run.count(Topic::Torque)),
            (500, 500)
        );
        assert_eq!(run.span(), Some((0.0, 0.499)));
        let mut k = 0;
        for e in run.messages().filter(|e| e.topic == Topic::Torque) {
            assert_eq!(
                e.wire,
                encode(&TorqueCommand {
                    seq: k,
                    tau: k as f64
                })
            );
            // A torque is logged at the plant time of the state it answers.
            assert_eq!(e.log_time, k * 1_000_000);
            k += 1;
        }
        assert_eq!(k, 500);
        // The summary of `tilting info`: what was written, every topic counted.
        let info = run.info();
        assert_eq!(
            (info.file, info.bytes),
            (path.clone(), std::fs::metadata(&path).unwrap().len())
        );
        assert_eq!(
            (info.robot.as_deref(), info.complete, info.truncation),
            (Some("bot"), true, None)
        );
        assert_eq!((info.start, info.end), (Some(0.0), Some(0.499)));
        let counts: Vec<(&str, u64)> = info.counts.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let mut want: Vec<(&str, u64)> = Topic::ALL.iter().map(|t| (t.name(), 0)).collect();
        want.sort();
        for w in &mut want {
            if w.0 == Topic::State.name() || w.0 == Topic::Torque.name() {
                w.1 = 500;
            }
        }
        assert_eq!(counts, want);
        assert_eq!((info.tilts, info.faults.len(), info.invalid), (0, 0, 0));
    }

    /// A writer killed after a flush and in the middle of the next chunk: everything up to the
    /// flush reads back, and the file says it is truncated.
    #[test]
    fn a_torn_file_reads_up_to_its_last_chunk() {
        let dir = tempfile::tempdir().unwrap();
        let (path, at_flush) = write(dir.path(), 400, 300);
        let full = std::fs::read(&path).unwrap();
        // Cut inside the next chunk: the flushed part plus some bytes of what followed.
        let torn = dir.path().join("torn.mcap");
        std::fs::write(&torn, &full[..at_flush + 37]).unwrap();
        let run = read(&torn).unwrap();
        assert!(!run.complete());
        assert!(run.truncation().is_some());
        assert_eq!(run.count(Topic::State), 300);
        assert_eq!(run.count(Topic::Torque), 300);
        // And cut exactly at the flush.
        std::fs::write(&torn, &full[..at_flush]).unwrap();
        let run = read(&torn).unwrap();
        assert!(!run.complete());
        assert_eq!(run.count(Topic::State), 300);
    }

    /// The offsets of the chunk records' bodies in an MCAP file.
    fn chunks(bytes: &[u8]) -> Vec<usize> {
        let mut at = mcap::MAGIC.len();
        let mut v = Vec::new();
        while at + 9 < bytes.len() && bytes[at] != 0x02 {
            let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
            if bytes[at] == 0x06 {
                v.push(at + 9);
            }
            at += 9 + len;
        }
        v
    }

    /// Every chunk carries messages: each chunk record is followed by its message index
    /// records (a chunk without messages has none, and Foxglove Studio 1.48's reader refuses
    /// the file: "Chunks without message indexes are not currently supported").
    #[test]
    fn every_chunk_has_a_message_index() {
        let dir = tempfile::tempdir().unwrap();
        let (path, _) = write(dir.path(), 3000, 1000);
        let bytes = std::fs::read(&path).unwrap();
        let mut at = mcap::MAGIC.len();
        let (mut chunks, mut after_chunk) = (0, None);
        while at + 9 < bytes.len() && bytes[at] != 0x02 {
            let (op, len) = (
                bytes[at],
                u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize,
            );
            if let Some(c) = after_chunk.take() {
                assert_eq!(op, 0x07, "chunk {c} is not followed by a message index");
            }
            if op == 0x06 {
                after_chunk = Some(chunks);
                chunks += 1;
            }
            at += 9 + len;
        }
        assert!(chunks >= 2, "{chunks} chunks");
    }

    /// Hostile files: a chunk stating 756,006,335,298 uncompressed bytes (the allocation that
    /// aborted `tilting info` in issue 22) and files with 50 flipped bits each. Every read
    /// returns (no abort, no allocation beyond the limit), yields at most the messages written,
    /// and a file read short says where reading stopped.
    #[test]
    fn damaged_files_read_to_the_damage_and_say_where() {
        let dir = tempfile::tempdir().unwrap();
        let (path, _) = write(dir.path(), 3000, 1000);
        let good = std::fs::read(&path).unwrap();
        let total = 2 * 3000;
        let bad = dir.path().join("bad.mcap");
        let at = chunks(&good);
        assert!(at.len() >= 2, "{at:?}");
        // The first chunk holds the channels (nothing to read before it); the last holds the
        // messages after the flush (the 1,000 states and torques before it read back).
        for (i, c) in [(0, at[0]), (1, at[at.len() - 1])] {
            let mut huge = good.clone();
            huge[c + 16..c + 24].copy_from_slice(&756_006_335_298u64.to_le_bytes());
            std::fs::write(&bad, &huge).unwrap();
            let why = match read(&bad) {
                Err(ReadError::Empty { why, .. }) if i == 0 => why,
                Ok(run) if i == 1 => {
                    assert_eq!(run.messages().count(), 2000);
                    run.truncation().unwrap().to_owned()
                }
                other => panic!("{:?}", other.map(|r| r.truncation().map(str::to_owned))),
            };
            assert!(why.contains("exceeds limit: `756006335298`"), "{why}");
            assert!(why.contains("reading stopped at byte"), "{why}");
        }
        // Flipped bits: 50 per file as in issue 22 (the first, largest chunk is nearly always
        // hit: nothing readable), then one per file (the damage anywhere). A chunk whose CRC
        // fails yields none of its messages.
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut short = [0; 2];
        for (flips, short) in [50, 1].into_iter().zip(&mut short) {
            for _ in 0..200 {
                let mut b = good.clone();
                for _ in 0..flips {
                    x ^= x << 13;
                    x ^= x >> 7;
                    x ^= x << 17;
                    let bit = (x % (8 * b.len() as u64)) as usize;
                    b[bit / 8] ^= 1 << (bit % 8);
                }
                std::fs::write(&bad, &b).unwrap();
                match read(&bad) {
                    Ok(run) => {
                        let n = run.messages().count();
                        assert!(n <= total, "{n}");
                        if let Some(why) = run.truncation() {
                            *short += 1;
                            let said = why.contains("reading stopped at byte")
                                || why.contains("summary section");
                            assert!(said, "{why}");
                        }
                    }
                    Err(e) => {
                        let e = e.to_string();
                        let said = e.contains("reading stopped at byte")
                            || e.contains("not an MCAP file")
                            || e.contains("no tilting channels");
                        assert!(said, "{e}");
                    }
                }
            }
        }
        // One flip in four lands in a later data chunk: read to the damage (49 of 200 seen; the
        // others hit the first chunk, which holds the channels, or the summary section).
        assert!(short[1] > 20, "{short:?}");
    }

    #[test]
    fn wrong_files_get_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let missing = read(&dir.path().join("nope.mcap"))
            .err()
            .unwrap()
            .to_string();
        assert!(missing.contains("nope.mcap"), "{missing}");
        let csv = dir.path().join("state.csv");
        std::fs::write(&csv, "seq,t\n0,0\n").unwrap();
        let e = read(&csv).err().unwrap().to_string();
        assert!(e.contains("not an MCAP file"), "{e}");
        // A valid MCAP file from another tool.
        let other = dir.path().join("other.mcap");
        let mut w = mcap::Writer::new(std::io::BufWriter::new(
            std::fs::File::create(&other).unwrap(),
        ))
        .unwrap();
        let ch = w
            .add_channel(0, "/imu", "json", &Default::default())
            .unwrap();
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: 0,
                log_time: 0,
                publish_time: 0,
            },
            b"{}",
        )
        .unwrap();
        w.finish().unwrap();
        drop(w);
        let e = read(&other).err().unwrap().to_string();
        assert!(e.contains("not recorded by tilting"), "{e}");
    }
}
