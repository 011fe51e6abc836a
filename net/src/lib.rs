//! Zenoh plumbing shared by the tilting nodes: command-line flags and session configuration,
//! typed publishing, decoding with drop counting and rate-limited logging, and peer presence
//! through liveliness tokens.
//!
//! The wire format itself lives in `tilting-proto`; this crate only moves its bytes.
//!
//! # Session defaults
//!
//! Without `--zenoh-config`, [`open_session`] builds a configuration that works on a machine
//! without multicast and never joins a stranger's zenoh network by accident:
//!
//! - `mode = "peer"`: no router is needed;
//! - multicast scouting off; gossip scouting on, so peers that each know only the plant's
//!   endpoint still find each other (each advertises its own listening endpoint);
//! - explicit endpoints, loopback by default: the plant listens on `tcp/127.0.0.1:7447`
//!   ([`DEFAULT_PLANT_ENDPOINT`]); the other nodes connect there and listen on an ephemeral
//!   loopback port (`tcp/127.0.0.1:0`) for the gossip mesh. `--listen` and `--connect` replace
//!   these defaults (repeat the flag for several endpoints);
//! - `scouting/delay` [`OPEN_WAIT_MS`]: `open` returns as soon as the configured peers are
//!   connected and their declarations received, and waits at most that long for them;
//! - connect retries start after 100 ms and back off to 1 s, so a node started before its
//!   peer connects within a second of the peer's start;
//! - timestamping off;
//! - the real-time queues hold [`REAL_TIME_QUEUE_BATCHES`] batches per link and a droppable
//!   message waits at most [`WAIT_BEFORE_DROP_US`] for room (see "Never blocking the loop").
//!
//! With `--zenoh-config FILE` the file is the whole configuration (zenoh's JSON5 format); only
//! explicit `--listen`/`--connect` flags are applied on top of it, and the two queue settings
//! above where the file leaves them at zenoh's defaults. The secure deployment works
//! this way: `tilting certs` writes one file per node that makes the session a TLS client (with
//! the node's own certificate) of a `tilting-router` that enforces the access control (see the
//! `tilting` crate's `security` module and docs/protocol.md).
//!
//! # Never blocking the loop
//!
//! A zenoh put pushes the message into the transmit queue of every link with a matching
//! subscriber. With `CongestionControl::Block` a link whose peer stops reading (a slow recorder,
//! a script that sleeps in its callback, a stalled or hostile subscriber) fills its queue and
//! the put waits, up to zenoh's `wait_before_close` (5 s), on the thread that made it: for the
//! plant that is the pacing thread, for the controller the state callback. Measured before this
//! rule: one Python subscriber that blocked in its callback for 75 s stalled the plant's pacing
//! thread 5.0 s once its link's buffers had filled (after about 30 s), and the orbit was lost.
//! So every message a node publishes from its loop ([`Qos::Control`], [`Qos::Telemetry`]) is
//! droppable: on a congested link it waits at most [`WAIT_BEFORE_DROP_US`], then is dropped on
//! that link only (zenoh marks the queue congested, and later messages for it are dropped at
//! once until it drains); the other links are not touched. The receivers see a drop as a gap
//! (the plant's lost torques, the recorder's missing states). Only messages sent off the loop
//! and rarely ([`Qos::Data`]: the planner's reference), and a tool's that must all arrive
//! ([`Qos::Lossless`]: `tilting replay`), block.

#![deny(missing_docs)]
#![forbid(unsafe_code)]

use std::path::PathBuf;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use tilting_proto::{codec, Keys, Message, SourceId};
use zenoh::bytes::ZBytes;
use zenoh::pubsub::Publisher;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Config, Session, Wait};

pub use tilting_proto;
pub use zenoh;

mod host;
pub use host::{check_hosted_config, hosted_keys, HostArgs, HostedSummary, MAX_HOSTED};

/// Where the plant listens, and the others connect, by default.
pub const DEFAULT_PLANT_ENDPOINT: &str = "tcp/127.0.0.1:7447";

/// Default listening endpoint of the nodes other than the plant: an ephemeral loopback port.
pub const DEFAULT_PEER_LISTEN: &str = "tcp/127.0.0.1:0";

/// Longest time (ms) `open` waits for the configured peers to connect (`scouting/delay`).
pub const OPEN_WAIT_MS: u64 = 1000;

/// Batches per link in the real-time priority queue (zenoh's default is 2, its maximum 16).
/// Each loop message is sent at once in its own batch (express), so this is how many messages
/// a link may have waiting before the next is dropped: 16 periods at 1 kHz, more than the
/// plant's default `--max-age` of 10, so no message that would still be used is dropped.
pub const REAL_TIME_QUEUE_BATCHES: usize = 16;

/// Longest wait (µs) of a droppable message for room in a full queue before it is dropped
/// (zenoh's default is 1,000 µs, a whole period of the 1 kHz loop).
pub const WAIT_BEFORE_DROP_US: i64 = 50;

/// The queue settings of "Never blocking the loop": (key, our value, zenoh's default).
const QUEUE_SETTINGS: [(&str, i64, i64); 2] = [
    (
        "transport/link/tx/queue/size/real_time",
        REAL_TIME_QUEUE_BATCHES as i64,
        2,
    ),
    (
        "transport/link/tx/queue/congestion_control/drop/wait_before_drop",
        WAIT_BEFORE_DROP_US,
        1000,
    ),
];

/// Which node opens the session: selects the default endpoints.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Listens on [`DEFAULT_PLANT_ENDPOINT`], connects nowhere.
    Plant,
    /// Connects to [`DEFAULT_PLANT_ENDPOINT`], listens on [`DEFAULT_PEER_LISTEN`].
    Peer,
}

/// Zenoh and naming flags shared by every tilting binary (flatten into a clap parser).
#[derive(Debug, Clone, Default, PartialEq, Eq, clap::Args)]
pub struct ZenohArgs {
    /// Robot name: keys are `tilting/{robot}/...`; only [A-Za-z0-9_-].
    #[arg(long, default_value = tilting_proto::keys::DEFAULT_ROBOT, value_name = "NAME")]
    pub robot: String,
    /// Zenoh endpoint to listen on, e.g. tcp/127.0.0.1:7447 (repeatable; replaces the default:
    /// tcp/127.0.0.1:7447 for the plant, tcp/127.0.0.1:0 for the other nodes).
    #[arg(long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Zenoh endpoint to connect to (repeatable; replaces the default: none for the plant,
    /// tcp/127.0.0.1:7447 for the other nodes).
    #[arg(long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Zenoh configuration file (JSON5) used instead of the built-in defaults; --listen and
    /// --connect still apply on top of it.
    #[arg(long = "zenoh-config", value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// This session's zenoh id (1 to 32 hexadecimal digits, not all zero; replaces the
    /// configuration's `id`) [default: a random one]. Its publishers attach it to every message,
    /// and a peer told it (`--plant-id`, `--controller-id`) believes only messages naming it.
    #[arg(long = "zenoh-id", value_name = "HEX", value_parser = parse_source_id)]
    pub zenoh_id: Option<SourceId>,
}

/// A `--zenoh-id`, `--plant-id` or `--controller-id` value: a zenoh id as zenoh prints it
/// ([`SourceId`]'s `FromStr`).
pub fn parse_source_id(s: &str) -> Result<SourceId, String> {
    s.parse()
}

/// A zenoh id drawn at random (as zenoh draws a session's own), for a node whose id is chosen
/// before it starts (`tilting live` names its plant's and controller's ids to the other nodes).
pub fn random_source_id() -> SourceId {
    SourceId(zenoh::session::ZenohId::default().to_le_bytes())
}

/// Reads a zenoh configuration file (JSON5 or YAML, by its extension) of at most
/// [`tilting_proto::bounded::CONFIG_LIMIT`] bytes; the error is in words.
pub fn config_from_file(path: &std::path::Path) -> Result<Config, String> {
    use tilting_proto::bounded;
    // The size first: zenoh reads a file whole, however long (`/dev/zero`).
    bounded::read(path, bounded::CONFIG_LIMIT, "a zenoh configuration")
        .map_err(|e| e.to_string())?;
    let config = Config::from_file(path).map_err(|e| zenoh_error(&e))?;
    check_tls_files(&config)?;
    Ok(config)
}

/// The TLS files a configuration names (`transport/link/tls/*`), each checked to be a readable
/// file of at most [`tilting_proto::bounded::CONFIG_LIMIT`] bytes before zenoh reads it whole
/// (a certificate path pointing at `/dev/zero` would otherwise fill the memory).
fn check_tls_files(config: &Config) -> Result<(), String> {
    use tilting_proto::bounded;
    for field in [
        "root_ca_certificate",
        "listen_certificate",
        "listen_private_key",
        "connect_certificate",
        "connect_private_key",
    ] {
        let key = format!("transport/link/tls/{field}");
        let Ok(json) = config.get_json(&key) else {
            continue;
        };
        let Ok(Some(file)) = serde_json::from_str::<Option<String>>(&json) else {
            continue;
        };
        let what = format!("the TLS file of {key}");
        bounded::read(std::path::Path::new(&file), bounded::CONFIG_LIMIT, &what).map_err(|e| {
            if e.kind() == std::io::ErrorKind::InvalidData {
                e.to_string()
            } else {
                format!("{key} = {file}: {e}")
            }
        })?;
    }
    Ok(())
}

impl ZenohArgs {
    /// Arguments for `robot` with explicit endpoints (for tests and tools).
    pub fn new(robot: &str, listen: &[&str], connect: &[&str]) -> Self {
        Self {
            robot: robot.to_owned(),
            listen: listen.iter().map(|s| s.to_string()).collect(),
            connect: connect.iter().map(|s| s.to_string()).collect(),
            zenoh_config: None,
            zenoh_id: None,
        }
    }

    /// The validated key expressions of `--robot`.
    pub fn keys(&self) -> anyhow::Result<Keys> {
        Keys::new(&self.robot).map_err(|e| anyhow::anyhow!("--robot: {e}"))
    }

    /// The zenoh configuration these flags describe (see the crate documentation).
    pub fn config(&self, role: Role) -> anyhow::Result<Config> {
        let json = |v: &[String]| serde_json::to_string(v).expect("strings serialize");
        let mut cfg = match &self.zenoh_config {
            Some(path) => config_from_file(path)
                .map_err(|e| anyhow::anyhow!("--zenoh-config {}: {e}", path.display()))?,
            None => {
                let (listen, connect): (Vec<String>, Vec<String>) = match role {
                    Role::Plant => (vec![DEFAULT_PLANT_ENDPOINT.into()], vec![]),
                    Role::Peer => (
                        vec![DEFAULT_PEER_LISTEN.into()],
                        vec![DEFAULT_PLANT_ENDPOINT.into()],
                    ),
                };
                let mut cfg = Config::default();
                let settings = [
                    ("mode", "\"peer\"".to_owned()),
                    ("scouting/multicast/enabled", "false".to_owned()),
                    ("scouting/gossip/enabled", "true".to_owned()),
                    ("scouting/delay", OPEN_WAIT_MS.to_string()),
                    ("timestamping/enabled", "false".to_owned()),
                    (
                        "connect/retry",
                        "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}"
                            .to_owned(),
                    ),
                    ("listen/endpoints", json(&listen)),
                    ("connect/endpoints", json(&connect)),
                ];
                for (key, value) in settings {
                    cfg.insert_json5(key, &value).map_err(|e| {
                        anyhow::anyhow!("zenoh config {key} = {value}: {}", zenoh_error(&e))
                    })?;
                }
                cfg
            }
        };
        if !self.listen.is_empty() {
            cfg.insert_json5("listen/endpoints", &json(&self.listen))
                .map_err(|e| anyhow::anyhow!("--listen {:?}: {}", self.listen, zenoh_error(&e)))?;
        }
        if !self.connect.is_empty() {
            cfg.insert_json5("connect/endpoints", &json(&self.connect))
                .map_err(|e| {
                    anyhow::anyhow!("--connect {:?}: {}", self.connect, zenoh_error(&e))
                })?;
        }
        for (key, ours, zenoh_default) in QUEUE_SETTINGS {
            // A file's own choice stands; zenoh's default (or no file) gets ours.
            let current = cfg.get_json(key).unwrap_or_default();
            if current.trim() == zenoh_default.to_string() {
                cfg.insert_json5(key, &ours.to_string()).map_err(|e| {
                    anyhow::anyhow!("zenoh config {key} = {ours}: {}", zenoh_error(&e))
                })?;
            }
        }
        if let Some(id) = self.zenoh_id {
            // As zenoh writes ids: lowercase, no leading zero (it refuses anything else).
            cfg.insert_json5("id", &format!("\"{id}\""))
                .map_err(|e| anyhow::anyhow!("--zenoh-id {id}: {}", zenoh_error(&e)))?;
        }
        Ok(cfg)
    }
}

/// The message of a zenoh error without the source locations zenoh appends to it (`... at
/// /root/.cargo/registry/src/.../unicast.rs:338.`): they say where in zenoh's code the error
/// was made, which means nothing to a user and leaks the build machine's paths.
pub fn zenoh_error(e: &dyn std::fmt::Display) -> String {
    let text = e.to_string();
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(i) = rest.find(" at /") {
        out.push_str(&rest[..i]);
        let tail = &rest[i + 4..];
        // The location runs to the first ".rs:<digits>", optionally followed by a '.'.
        match tail.find(".rs:") {
            Some(j) => {
                let after = &tail[j + 4..];
                let digits =
                    after.len() - after.trim_start_matches(|c: char| c.is_ascii_digit()).len();
                let mut end = j + 4 + digits;
                if tail[end..].starts_with('.') {
                    end += 1;
                }
                rest = &tail[end..];
            }
            None => {
                out.push_str(&rest[i..]);
                rest = "";
            }
        }
    }
    out.push_str(rest);
    out
}

/// Opens a zenoh session configured by `args` for `role`.
pub async fn open_session(args: &ZenohArgs, role: Role) -> anyhow::Result<Session> {
    let cfg = args.config(role)?;
    let t0 = Instant::now();
    let session = zenoh::open(cfg)
        .await
        .map_err(|e| anyhow::anyhow!("cannot open the zenoh session: {}", zenoh_error(&e)))?;
    tracing::debug!(
        zid = %session.zid(),
        elapsed_ms = t0.elapsed().as_millis() as u64,
        "zenoh session open"
    );
    Ok(session)
}

/// Writes `text` and a line end to standard output and flushes it. A failure (a closed pipe:
/// EPIPE; a file on a full disk: ENOSPC) does not stop the node, unlike `println!`, which
/// panics: it is said once on stderr, and the error returned for a caller that cares.
pub fn say_out(text: &str) -> std::io::Result<()> {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    let r = writeln!(out, "{text}").and_then(|()| out.flush());
    if let Err(e) = &r {
        say_err(&format!("cannot write to stdout: {e}"));
    }
    r
}

/// Where node `node` (its binary's name, e.g. `tilting-plant`) of process `pid` puts its
/// summary when its standard output fails ([`say_summary`]): the system's temporary
/// directory, `{node}-{pid}-summary.json`.
pub fn summary_fallback(node: &str, pid: u32) -> PathBuf {
    std::env::temp_dir().join(format!("{node}-{pid}-summary.json"))
}

/// Prints a node's JSON summary on standard output ([`say_out`]); if that fails (a full disk
/// under a redirected stdout: ENOSPC; a closed pipe), writes it to [`summary_fallback`] of
/// this process instead and says so on stderr, or as a last resort puts the summary itself on
/// stderr. Returns the fallback file if the summary went there.
pub fn say_summary(node: &str, json: &str) -> Option<PathBuf> {
    let Err(e) = say_out(json) else {
        return None;
    };
    let path = summary_fallback(node, std::process::id());
    match std::fs::write(&path, format!("{json}\n")) {
        Ok(()) => {
            say_err(&format!(
                "{node}: cannot print the summary on stdout ({e}); it is in {}",
                path.display()
            ));
            Some(path)
        }
        Err(e2) => {
            say_err(&format!(
                "{node}: cannot print the summary on stdout ({e}) nor write {} ({e2}): {json}",
                path.display()
            ));
            None
        }
    }
}

/// Writes `text` and a line end to standard error, ignoring a failure (`eprintln!` panics on
/// a broken or full stderr; a node must not).
pub fn say_err(text: &str) {
    use std::io::Write as _;
    let mut err = std::io::stderr().lock();
    let _ = writeln!(err, "{text}").and_then(|()| err.flush());
}

/// The nodes' default sizing of zenoh's runtimes (zenoh-runtime's `ZENOH_RUNTIME`, a RON map
/// of runtime -> `worker_threads`, `max_blocking_threads`, `handover`): the acceptor, tx, rx and
/// net runtimes hand their tasks over to the application runtime, which has one worker and at
/// most 4 blocking threads. A node then has 4-6 threads instead of zenoh's default 10-12 (app 1,
/// acc 1, tx 1, rx 2, net 1 workers, each runtime its own pool). Measured with
/// `bench/robots_bench.py` on 2 cores under load (docs/guide/performance.md): 8 robots at 1 kHz
/// missed 7-22 % of their periods instead of 49-81 %, 4 robots 1.1-3.1 % instead of 2.7-11 %.
pub const NODE_ZENOH_RUNTIME: &str = "(app: (worker_threads: 1, max_blocking_threads: 4), \
     acc: (handover: app), tx: (handover: app), rx: (handover: app), net: (handover: app))";

/// The `ZENOH_RUNTIME` a node should set given the one it was started with: `None` (keep it)
/// when the environment already names one (the user's override; `()` gives zenoh's own
/// sizing), else [`NODE_ZENOH_RUNTIME`].
pub fn zenoh_runtime_default(current: Option<&std::ffi::OsStr>) -> Option<&'static str> {
    match current {
        Some(_) => None,
        None => Some(NODE_ZENOH_RUNTIME),
    }
}

/// Sizes zenoh's runtimes for a node ([`NODE_ZENOH_RUNTIME`]) unless `ZENOH_RUNTIME` is set.
/// Call first thing in `main`, before any thread starts and before zenoh reads the variable
/// (at its runtimes' first use): setting the environment is not thread-safe.
pub fn size_zenoh_runtime() {
    if let Some(v) = zenoh_runtime_default(std::env::var_os("ZENOH_RUNTIME").as_deref()) {
        std::env::set_var("ZENOH_RUNTIME", v);
    }
}

/// Builds the tracing subscriber of a binary: logs to stderr, filter from `RUST_LOG` or
/// `default_filter` (e.g. `"warn,tilting_plant=info,tilting_net=info"`).
pub fn init_tracing(default_filter: &str) {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default_filter));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .try_init();
}

/// A publisher of raw payloads on one key (tools that forward bytes: `replay`, tests that
/// send garbage). Nodes use [`TypedPublisher`]. Every put carries the session's identity as
/// its attachment ([`source_id`], [`tilting_proto::source`]).
#[derive(Debug)]
pub struct RawPublisher {
    publisher: Publisher<'static>,
    /// The attachment of every put: the session's [`SourceId`].
    source: ZBytes,
}

/// The identity of `session` as its publishers attach it: its `ZenohId`.
pub fn source_id(session: &Session) -> SourceId {
    SourceId(session.zid().to_le_bytes())
}

/// The source a sample names in its attachment ([`tilting_proto::source`]), if any.
pub fn source_of(sample: &Sample) -> Option<SourceId> {
    let a = sample.attachment()?;
    if a.len() != tilting_proto::source::ATTACHMENT_SIZE {
        return None;
    }
    SourceId::from_attachment(&a.to_bytes())
}

/// Quality of service of a publisher (see "Never blocking the loop" in the crate docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Qos {
    /// The control loop (state, torque): real-time priority, sent at once (express, no
    /// batching), dropped on a congested link rather than waited for.
    Control,
    /// What a node publishes from its loop besides the loop itself (the plant's events and
    /// status): data priority, dropped on a congested link rather than waited for.
    Telemetry,
    /// Rare messages sent off the loop (the planner's reference): data priority, blocking
    /// rather than dropping when the link is congested.
    Data,
    /// A tool that must deliver every message and has no loop to stall (`tilting replay`):
    /// real-time priority, express, blocking rather than dropping when the link is congested.
    Lossless,
}

impl RawPublisher {
    /// Declares a publisher on `key` with the given quality of service.
    pub async fn declare(session: &Session, key: &str, qos: Qos) -> anyhow::Result<Self> {
        let (priority, express, congestion) = match qos {
            Qos::Control => (Priority::RealTime, true, CongestionControl::Drop),
            Qos::Telemetry => (Priority::Data, false, CongestionControl::Drop),
            Qos::Data => (Priority::Data, false, CongestionControl::Block),
            Qos::Lossless => (Priority::RealTime, true, CongestionControl::Block),
        };
        let publisher = session
            .declare_publisher(key.to_owned())
            .congestion_control(congestion)
            .priority(priority)
            .express(express)
            .await
            .map_err(|e| {
                anyhow::anyhow!("cannot declare a publisher on {key}: {}", zenoh_error(&e))
            })?;
        let source = ZBytes::from(source_id(session).attachment());
        Ok(Self { publisher, source })
    }

    /// Publishes `bytes` as they are (synchronously), with the session's identity attached.
    pub fn put_raw(&self, bytes: &[u8]) -> anyhow::Result<()> {
        let put = self.publisher.put(bytes).attachment(self.source.clone());
        put.wait().map_err(|e| {
            anyhow::anyhow!("put on {}: {}", self.publisher.key_expr(), zenoh_error(&e))
        })
    }

    /// Does a subscriber match this publisher's key now? (A put before one exists is lost.)
    pub async fn has_subscribers(&self) -> bool {
        self.publisher
            .matching_status()
            .await
            .is_ok_and(|m| m.matching())
    }

    /// The key expression.
    pub fn key(&self) -> &str {
        self.publisher.key_expr().as_str()
    }
}

/// A publisher of one message type on one key.
#[derive(Debug)]
pub struct TypedPublisher<T: Message> {
    raw: RawPublisher,
    _t: std::marker::PhantomData<fn(&T)>,
}

impl<T: Message> TypedPublisher<T> {
    /// Declares a publisher on `key` with the given quality of service.
    pub async fn declare(session: &Session, key: &str, qos: Qos) -> anyhow::Result<Self> {
        Ok(Self {
            raw: RawPublisher::declare(session, key, qos).await?,
            _t: std::marker::PhantomData,
        })
    }

    /// Encodes and publishes `msg` (synchronously: usable from any thread, including zenoh
    /// callbacks and the plant's pacing thread). Does not validate.
    pub fn put(&self, msg: &T) -> anyhow::Result<()> {
        let mut buf = [0u8; 1280];
        let n = codec::encode_into(msg, &mut buf[..T::MAX_WIRE_SIZE]);
        self.raw.put_raw(&buf[..n])
    }

    /// Publishes raw bytes on this publisher's key (tests use it to send garbage).
    pub fn put_raw(&self, bytes: &[u8]) -> anyhow::Result<()> {
        self.raw.put_raw(bytes)
    }

    /// The key expression.
    pub fn key(&self) -> &str {
        self.raw.key()
    }
}

/// Counts the payloads received on one key and the ones dropped, and logs drops at a bounded
/// rate: the first with its full error at once, then at most one line per
/// [`DropCounter::LOG_INTERVAL`] with the number dropped since the last line and the latest
/// error.
#[derive(Debug)]
pub struct DropCounter {
    key: String,
    received: AtomicU64,
    dropped: AtomicU64,
    log: Mutex<LogState>,
}

#[derive(Debug, Default)]
struct LogState {
    last: Option<Instant>,
    suppressed: u64,
}

impl DropCounter {
    /// Shortest interval between two log lines of one counter.
    pub const LOG_INTERVAL: Duration = Duration::from_secs(1);

    /// A counter for payloads on `key`.
    pub fn new(key: &str) -> Self {
        Self {
            key: key.to_owned(),
            received: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            log: Mutex::new(LogState::default()),
        }
    }

    /// The key expression this counter watches.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Payloads received, valid or not.
    pub fn received(&self) -> u64 {
        self.received.load(Ordering::Relaxed)
    }

    /// Payloads dropped because they did not decode or validate.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Decodes `bytes` as a `T`: counts the payload, and on failure counts the drop, logs at the
    /// bounded rate and returns `None`.
    pub fn decode<T: Message>(&self, bytes: &[u8]) -> Option<T> {
        self.received.fetch_add(1, Ordering::Relaxed);
        match codec::decode::<T>(bytes) {
            Ok(msg) => Some(msg),
            Err(err) => {
                self.record_drop(&err);
                None
            }
        }
    }

    /// Counts a drop for a reason found by the caller (e.g. a reply error) and logs it at the
    /// bounded rate.
    pub fn record_drop(&self, err: &dyn std::fmt::Display) {
        let total = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
        let mut log = self.log.lock().unwrap_or_else(|e| e.into_inner());
        let now = Instant::now();
        match log.last {
            Some(last) if now.duration_since(last) < Self::LOG_INTERVAL => log.suppressed += 1,
            None => {
                tracing::warn!(key = %self.key, total, "dropped an invalid payload: {err}");
                log.last = Some(now);
            }
            Some(_) => {
                let n = log.suppressed + 1;
                tracing::warn!(
                    key = %self.key,
                    total,
                    "dropped {n} invalid payloads since the last report; latest: {err}"
                );
                log.last = Some(now);
                log.suppressed = 0;
            }
        }
    }
}

/// Subscribes to `key` and hands every payload, as bytes, to `on_bytes` (on a zenoh thread:
/// keep it short and non-blocking). For tools that look at raw payloads; nodes use
/// [`subscribe_decoded`]. Keep the returned subscriber alive.
pub async fn subscribe_bytes<F>(
    session: &Session,
    key: &str,
    on_bytes: F,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>>
where
    F: Fn(&[u8]) + Send + Sync + 'static,
{
    subscribe_sourced(session, key, move |b, _| on_bytes(b)).await
}

/// Like [`subscribe_bytes`], with the source the sample names ([`source_of`]).
pub async fn subscribe_sourced<F>(
    session: &Session,
    key: &str,
    on_bytes: F,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>>
where
    F: Fn(&[u8], Option<SourceId>) + Send + Sync + 'static,
{
    session
        .declare_subscriber(key.to_owned())
        .callback(move |s| on_bytes(&s.payload().to_bytes(), source_of(&s)))
        .await
        .map_err(|e| anyhow::anyhow!("cannot subscribe to {key}: {}", zenoh_error(&e)))
}

/// Subscribes to the key of `counter` and hands every payload that decodes and validates as a
/// `T` to `on_msg` (on a zenoh thread: keep it short and non-blocking); malformed payloads are
/// counted and logged by `counter`. Keep the returned subscriber alive.
pub async fn subscribe_decoded<T, F>(
    session: &Session,
    counter: Arc<DropCounter>,
    on_msg: F,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>>
where
    T: Message + Send + 'static,
    F: Fn(T) + Send + Sync + 'static,
{
    subscribe_decoded_from(session, counter, move |m, _| on_msg(m)).await
}

/// Like [`subscribe_decoded`], with the source the sample names ([`source_of`]).
pub async fn subscribe_decoded_from<T, F>(
    session: &Session,
    counter: Arc<DropCounter>,
    on_msg: F,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>>
where
    T: Message + Send + 'static,
    F: Fn(T, Option<SourceId>) + Send + Sync + 'static,
{
    let key = counter.key().to_owned();
    subscribe_sourced(session, &key, move |bytes, source| {
        if let Some(m) = counter.decode::<T>(bytes) {
            on_msg(m, source);
        }
    })
    .await
}

/// How many liveliness tokens matching one key are alive, kept up to date by a liveliness
/// subscriber (with history, so tokens declared before the subscriber count too).
#[derive(Debug, Default)]
pub struct Presence {
    count: AtomicI64,
}

impl Presence {
    /// Is at least one token alive?
    pub fn alive(&self) -> bool {
        self.count.load(Ordering::Acquire) > 0
    }
}

/// Watches the liveliness tokens on `key`; `on_change(alive)` runs (on a zenoh thread) each
/// time the presence changes between none and some. Keep the returned subscriber alive.
pub async fn watch_presence<F>(
    session: &Session,
    key: &str,
    on_change: F,
) -> anyhow::Result<(Arc<Presence>, zenoh::pubsub::Subscriber<()>)>
where
    F: Fn(bool) + Send + Sync + 'static,
{
    let presence = Arc::new(Presence::default());
    let p = presence.clone();
    let key_owned = key.to_owned();
    let sub = session
        .liveliness()
        .declare_subscriber(key.to_owned())
        .history(true)
        .callback(move |sample: Sample| {
            let (before, after) = match sample.kind() {
                SampleKind::Put => {
                    let b = p.count.fetch_add(1, Ordering::AcqRel);
                    (b, b + 1)
                }
                SampleKind::Delete => {
                    let b = p.count.fetch_sub(1, Ordering::AcqRel);
                    if b <= 0 {
                        // A delete without a put (history raced the subscription): clamp.
                        p.count.fetch_add(1, Ordering::AcqRel);
                        (0, 0)
                    } else {
                        (b, b - 1)
                    }
                }
            };
            if (before > 0) != (after > 0) {
                tracing::info!(
                    key = %key_owned,
                    "peer {}",
                    if after > 0 { "alive" } else { "gone" }
                );
                on_change(after > 0);
            }
        })
        .await
        .map_err(|e| anyhow::anyhow!("cannot watch liveliness on {key}: {}", zenoh_error(&e)))?;
    Ok((presence, sub))
}

/// Declares this node's liveliness token on `key` (keep it alive for the node's lifetime).
pub async fn declare_token(
    session: &Session,
    key: &str,
) -> anyhow::Result<zenoh::liveliness::LivelinessToken> {
    session
        .liveliness()
        .declare_token(key.to_owned())
        .await
        .map_err(|e| {
            anyhow::anyhow!(
                "cannot declare the liveliness token {key}: {}",
                zenoh_error(&e)
            )
        })
}

/// A multi-threaded tokio runtime with 2 workers, the one every node uses (zenoh does not
/// support the current-thread flavour).
pub fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot build the tokio runtime")
}

/// Resolves at Ctrl-C (SIGINT) or SIGTERM.
pub async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        let mut term = match signal(SignalKind::terminate()) {
            Ok(s) => s,
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
                return;
            }
        };
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn zenoh_runtime_default_keeps_an_override_and_sizes_otherwise() {
        let given = std::ffi::OsString::from("(app: (worker_threads: 2))");
        assert_eq!(zenoh_runtime_default(Some(&given)), None);
        assert_eq!(zenoh_runtime_default(Some(std::ffi::OsStr::new(""))), None);
        let d = zenoh_runtime_default(None).unwrap();
        // Every runtime but app hands over to app, and app has one worker.
        for rt in ["acc", "tx", "rx", "net"] {
            assert!(d.contains(&format!("{rt}: (handover: app)")), "{rt} in {d}");
        }
        assert!(d.contains("app: (worker_threads: 1"), "{d}");
    }

    use super::*;

    #[test]
    fn zenoh_errors_lose_their_source_locations() {
        let raw = "Can not create a new TCP listener bound to tcp/127.0.0.1:17999: [127.0.0.1:17999: \
                   Address already in use (os error 98) at /root/.cargo/registry/src/index.crates.io-1/\
                   zenoh-link-commons-1.10.2/src/tcp.rs:61.] at /root/.cargo/registry/src/x/unicast.rs:338.";
        assert_eq!(
            zenoh_error(&raw),
            "Can not create a new TCP listener bound to tcp/127.0.0.1:17999: [127.0.0.1:17999: \
             Address already in use (os error 98)]"
        );
        assert_eq!(zenoh_error(&"no location here"), "no location here");
        assert_eq!(
            zenoh_error(&"a path at /tmp/x without a line"),
            "a path at /tmp/x without a line"
        );
    }
    use tilting_proto::TorqueCommand;

    #[test]
    fn tls_files_of_a_config_are_bounded_and_named() {
        let dir = std::env::temp_dir().join(format!("tilting-net-tls-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cfg = dir.join("c.json5");
        let write = |ca: &str| {
            let text = format!(
                r#"{{ mode: "peer", transport: {{ link: {{ tls: {{ root_ca_certificate: "{ca}" }} }} }} }}"#
            );
            std::fs::write(&cfg, text).unwrap();
        };
        // An endless "certificate" is refused at the limit, the key named.
        write("/dev/zero");
        let e = config_from_file(&cfg).unwrap_err();
        assert!(
            e.contains("limit") && e.contains("root_ca_certificate"),
            "{e}"
        );
        // A missing one is named with its key.
        let missing = dir.join("missing.pem");
        write(&missing.display().to_string());
        let e = config_from_file(&cfg).unwrap_err();
        assert!(
            e.contains("transport/link/tls/root_ca_certificate") && e.contains("missing.pem"),
            "{e}"
        );
        // A small file passes.
        let ca = dir.join("ca.pem");
        std::fs::write(&ca, "-----BEGIN CERTIFICATE-----\n").unwrap();
        write(&ca.display().to_string());
        assert!(config_from_file(&cfg).is_ok());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn default_config_is_loopback_peer_without_multicast() {
        let args = ZenohArgs::new("demo", &[], &[]);
        let cfg = args.config(Role::Plant).unwrap();
        assert_eq!(cfg.get_json("mode").unwrap(), "\"peer\"");
        assert_eq!(cfg.get_json("scouting/multicast/enabled").unwrap(), "false");
        assert!(cfg
            .get_json("listen/endpoints")
            .unwrap()
            .contains("tcp/127.0.0.1:7447"));
        let cfg = args.config(Role::Peer).unwrap();
        assert!(cfg
            .get_json("connect/endpoints")
            .unwrap()
            .contains("tcp/127.0.0.1:7447"));
        let args = ZenohArgs::new("demo", &["tcp/127.0.0.1:17001"], &["tcp/127.0.0.1:17002"]);
        let cfg = args.config(Role::Peer).unwrap();
        assert!(cfg.get_json("listen/endpoints").unwrap().contains("17001"));
        assert!(cfg.get_json("connect/endpoints").unwrap().contains("17002"));
        assert!(!cfg
            .get_json("connect/endpoints")
            .unwrap()
            .contains("7447\""));
    }

    #[test]
    fn queue_settings_apply_unless_a_file_chose_its_own() {
        let wait = "transport/link/tx/queue/congestion_control/drop/wait_before_drop";
        let size = "transport/link/tx/queue/size/real_time";
        // The built-in configuration gets ours (zenoh's defaults are 1000 us and 2 batches).
        let cfg = ZenohArgs::new("demo", &[], &[])
            .config(Role::Plant)
            .unwrap();
        assert_eq!(cfg.get_json(wait).unwrap(), WAIT_BEFORE_DROP_US.to_string());
        assert_eq!(
            cfg.get_json(size).unwrap(),
            REAL_TIME_QUEUE_BATCHES.to_string()
        );
        // A file that says nothing of them gets ours; a file's own values stand.
        let dir = std::env::temp_dir().join(format!("tilting-net-queue-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("c.json5");
        let with = |text: &str| {
            std::fs::write(&file, text).unwrap();
            let mut args = ZenohArgs::new("demo", &[], &[]);
            args.zenoh_config = Some(file.clone());
            args.config(Role::Peer).unwrap()
        };
        let cfg = with(r#"{ mode: "peer" }"#);
        assert_eq!(cfg.get_json(wait).unwrap(), "50");
        assert_eq!(cfg.get_json(size).unwrap(), "16");
        let cfg = with(
            r#"{ mode: "peer", transport: { link: { tx: { queue: {
                size: { real_time: 4 },
                congestion_control: { drop: { wait_before_drop: 300 } } } } } } }"#,
        );
        assert_eq!(cfg.get_json(wait).unwrap(), "300");
        assert_eq!(cfg.get_json(size).unwrap(), "4");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_robot_and_endpoint_are_errors() {
        assert!(ZenohArgs::new("a/b", &[], &[]).keys().is_err());
        assert!(ZenohArgs::new("demo", &["not an endpoint"], &[])
            .config(Role::Plant)
            .is_err());
    }

    #[test]
    fn drop_counter_counts() {
        let c = DropCounter::new("k");
        assert!(c.decode::<TorqueCommand>(&[1, 2, 3]).is_none());
        let mut bad = codec::encode(&TorqueCommand { seq: 1, tau: 0.0 });
        bad[8..16].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(c.decode::<TorqueCommand>(&bad).is_none());
        let good = codec::encode(&TorqueCommand { seq: 1, tau: 0.5 });
        assert_eq!(c.decode::<TorqueCommand>(&good).unwrap().tau, 0.5);
        for _ in 0..1000 {
            assert!(c.decode::<TorqueCommand>(&[0; 48]).is_none());
        }
        assert_eq!(c.received(), 1003);
        assert_eq!(c.dropped(), 1002);
    }
}
