//! MCAP recordings of a robot's topics.
//!
//! One file per run, written by the plant's `--record FILE.mcap`, by `tilting live` and by the
//! stand-alone `tilting record`; read back by `tilting info`, `tilting replay`, `tilting
//! animate` and the figure of a live run.
//!
//! Each of the five topics ([`Topic`]) has one channel, named `/` + its zenoh key (for example
//! `/tilting/demo/plant/state`): the message as a JSON object with a JSON Schema named
//! `tilting.<MessageType>` (`message_encoding = "json"`, schema encoding `jsonschema`), the
//! encoding Foxglove plots without plugins and PlotJuggler's MCAP loader parses (see
//! `docs/recordings.md`). The exact wire payloads are recovered from the JSON
//! ([`schema::from_json`]): numbers are written in shortest round-trip form and the wire
//! encoding of a message is unique, so a replay is byte-exact without storing every message
//! twice (which doubled the file).
//!
//! Log times are **plant time** in ns (a torque is logged at the time of the state it answers,
//! a reference at the latest plant time seen); publish times are equal to log times.
//! Chunks are zstd-compressed and closed at least every [`FLUSH_INTERVAL`]: a writer killed
//! with SIGKILL leaves a file readable up to its last chunk ([`read`] reports it as
//! truncated). A file closed normally has the summary section (chunk index and statistics).
//!
//! A run's trajectory ([`Trace`]) is loaded from a recording, or from a live run's CSV files,
//! by [`load`] ([`trace`]).
//!
//! ```
//! use tilting_proto::{encode, Keys, TorqueCommand, PlantState, Topic};
//! use tilting_record::{read, McapWriter};
//!
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("run.mcap");
//! let keys = Keys::new("demo").unwrap();
//! let mut rec = McapWriter::create(&path, &keys).unwrap();
//! let s = PlantState { seq: 0, time: 0.0, alpha: 0.0, beta: 1.5, alpha_dot: Some(0.0), beta_dot: Some(0.0), mode: 0 };
//! rec.record(Topic::State, &encode(&s)).unwrap();
//! rec.record(Topic::Torque, &encode(&TorqueCommand { seq: 0, tau: 0.25 })).unwrap();
//! rec.finish().unwrap();
//!
//! let run = read(&path).unwrap();
//! assert_eq!(run.count(Topic::State), 1);
//! assert!(run.complete());
//! ```

#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod csv;
pub mod guard;
pub mod peaks;
pub mod reader;
pub mod recorder;
pub mod schema;
pub mod sink;
pub mod trace;
pub mod writer;

pub use guard::{Rules, Sources};
pub use reader::{read, Entry, Info, ReadError, Recording};
pub use recorder::{Record, RecordError, RecordSender, RecordView, Recorder};
pub use tilting_proto::Topic;
pub use trace::{load, EventRecord, LoadError, Loaded, Sample, Trace, Window};
pub use writer::{McapWriter, FLUSH_INTERVAL};

/// `message_encoding` of the channels.
pub const JSON_ENCODING: &str = "json";

/// The channel's topic for a zenoh key: `/` + key.
pub fn json_topic(key: &str) -> String {
    format!("/{key}")
}
