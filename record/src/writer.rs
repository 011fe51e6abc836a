//! [`McapWriter`]: writes a robot's messages into an MCAP file as they arrive.

use crate::{json_topic, schema, JSON_ENCODING};
use mcap::records::{MessageHeader, Metadata};
use mcap::{Compression, WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use tilting_proto::{
    codec, DecodeError, Keys, ModeEvent, PlantState, Status, Topic, TorqueCommand,
};

/// Longest time between two chunk closes while messages arrive: what a SIGKILL can lose.
pub const FLUSH_INTERVAL: Duration = Duration::from_millis(100);

/// Uncompressed size at which a chunk is closed even before [`FLUSH_INTERVAL`] (bytes).
const CHUNK_SIZE: u64 = 1 << 20;

/// Recent `seq -> plant time` pairs kept to time-stamp torques (a torque answers a state at
/// most a few periods old; 1,024 periods is a second at 1 kHz).
const SEQ_TIMES: usize = 1024;

/// Why a recording failed.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The file could not be created or written.
    #[error("{path}: {cause}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: std::io::Error,
    },
    /// The MCAP writer refused (an I/O error underneath, usually).
    #[error("{path}: {cause}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: mcap::McapError,
    },
}

/// Writes the five topics of one robot into an MCAP file (see the crate documentation for the
/// channels). Not thread-safe: one writer thread owns it.
pub struct McapWriter {
    writer: Writer<BufWriter<File>>,
    path: PathBuf,
    json: [u16; 5],
    sequence: [u32; 5],
    counts: [u64; 5],
    invalid: u64,
    /// `(seq, time)` of recent states, indexed by `seq % SEQ_TIMES`.
    seq_times: Vec<(u64, u64)>,
    /// Latest plant time seen, ns.
    now: u64,
    last_flush: Instant,
    dirty: bool,
}

impl McapWriter {
    /// Creates `path` and writes the header, the schemas, the five channels and a `tilting`
    /// metadata record naming the robot.
    pub fn create(path: &Path, keys: &Keys) -> Result<Self, WriteError> {
        let io = |cause| WriteError::Io {
            path: path.to_owned(),
            cause,
        };
        let file = File::create(path).map_err(io)?;
        let mc = |cause| WriteError::Mcap {
            path: path.to_owned(),
            cause,
        };
        let mut writer = WriteOptions::new()
            .compression(Some(Compression::Zstd))
            // Measured on a 20 s run cut in 100 ms chunks: level 1 gave 1.36 MB in 48 us per
            // chunk, the default level 3 1.40 MB in 62 us; levels up to 12 were no smaller, 19
            // saved 12 % for 70 times the time (the full-precision floats set the floor).
            .compression_level(1)
            .chunk_size(Some(CHUNK_SIZE))
            .library(concat!("tilting ", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(mc)?;
        // The metadata first: a record outside chunks closes the open chunk, so written after
        // the schemas and channels it left a first chunk with no message (no message index,
        // times 0-0), which Foxglove Studio 1.48's MCAP reader refuses to open.
        writer
            .write_metadata(&Metadata {
                name: "tilting".into(),
                metadata: BTreeMap::from([
                    ("robot".to_owned(), keys.robot().to_owned()),
                    ("log_time".to_owned(), "plant time, ns".to_owned()),
                ]),
            })
            .map_err(mc)?;
        let mut json = [0; 5];
        for t in Topic::ALL {
            let key = t.key(keys);
            let schema = serde_json::to_vec(&schema::json_schema(t)).unwrap_or_default();
            let sid = writer
                .add_schema(&schema::schema_name(t), "jsonschema", &schema)
                .map_err(mc)?;
            json[t.index()] = writer
                .add_channel(sid, &json_topic(key), JSON_ENCODING, &BTreeMap::new())
                .map_err(mc)?;
        }
        Ok(Self {
            writer,
            path: path.to_owned(),
            json,
            sequence: [0; 5],
            counts: [0; 5],
            invalid: 0,
            seq_times: vec![(u64::MAX, 0); SEQ_TIMES],
            now: 0,
            last_flush: Instant::now(),
            dirty: false,
        })
    }

    /// Records one wire payload of `topic` as its JSON object, at the plant time it carries
    /// (see the crate documentation). A payload that does not decode and validate is counted
    /// ([`McapWriter::invalid`]) and not written. Closes the current chunk when
    /// [`FLUSH_INTERVAL`] has passed.
    pub fn record(&mut self, topic: Topic, wire: &[u8]) -> Result<(), WriteError> {
        let Ok((json, time)) = self.decode(topic, wire) else {
            self.invalid += 1;
            return Ok(());
        };
        let time = match time {
            Some(t) => {
                self.now = self.now.max(t);
                t
            }
            None => self.now,
        };
        let i = topic.index();
        self.writer
            .write_to_known_channel(
                &MessageHeader {
                    channel_id: self.json[i],
                    sequence: self.sequence[i],
                    log_time: time,
                    publish_time: time,
                },
                &json,
            )
            .map_err(|cause| WriteError::Mcap {
                path: self.path.clone(),
                cause,
            })?;
        self.sequence[i] = self.sequence[i].wrapping_add(1);
        self.counts[i] += 1;
        self.dirty = true;
        self.flush_if_due()
    }

    /// The JSON object of a payload and the plant time it carries, ns (a torque: the time of
    /// the state it answers, if that state was recorded recently).
    fn decode(&mut self, topic: Topic, wire: &[u8]) -> Result<(Vec<u8>, Option<u64>), DecodeError> {
        // The JSON of the schema module (absent rates left out, enumeration names added): the
        // same bytes the Foxglove server sends.
        let json = schema::to_json(topic, wire)?;
        Ok(match topic {
            Topic::State => {
                let s: PlantState = codec::decode(wire)?;
                let t = ns(s.time);
                self.seq_times[(s.seq % SEQ_TIMES as u64) as usize] = (s.seq, t);
                (json, Some(t))
            }
            Topic::Torque => {
                let c: TorqueCommand = codec::decode(wire)?;
                let (seq, t) = self.seq_times[(c.seq % SEQ_TIMES as u64) as usize];
                (json, (seq == c.seq).then_some(t))
            }
            Topic::Event => {
                let e: ModeEvent = codec::decode(wire)?;
                (json, Some(ns(e.time)))
            }
            Topic::Status => {
                let s: Status = codec::decode(wire)?;
                (json, Some(ns(s.time)))
            }
            Topic::Reference => (json, None),
        })
    }

    /// Closes the current chunk if [`FLUSH_INTERVAL`] has passed since the last close (call it
    /// also when no message has come for a while).
    pub fn flush_if_due(&mut self) -> Result<(), WriteError> {
        if self.dirty && self.last_flush.elapsed() >= FLUSH_INTERVAL {
            self.flush()?;
        }
        Ok(())
    }

    /// Closes the current chunk and hands it to the operating system: a process killed after
    /// this leaves a file readable up to here.
    pub fn flush(&mut self) -> Result<(), WriteError> {
        self.writer.flush().map_err(|cause| WriteError::Mcap {
            path: self.path.clone(),
            cause,
        })?;
        self.last_flush = Instant::now();
        self.dirty = false;
        Ok(())
    }

    /// Messages recorded on `topic`.
    pub fn count(&self, topic: Topic) -> u64 {
        self.counts[topic.index()]
    }

    /// Payloads refused because they did not decode or validate.
    pub fn invalid(&self) -> u64 {
        self.invalid
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes the last chunk and the summary section, and flushes the file (writing after
    /// this is an error).
    pub fn finish(&mut self) -> Result<(), WriteError> {
        self.writer.finish().map_err(|cause| WriteError::Mcap {
            path: self.path.clone(),
            cause,
        })?;
        Ok(())
    }
}

/// Plant seconds to ns (times are validated finite; negative ones clamp to 0).
fn ns(t: f64) -> u64 {
    (t * 1e9).round().max(0.0) as u64
}
