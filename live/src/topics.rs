//! `tilting echo` and `tilting hz`: a live look at a robot's topics, the way `ros2 topic echo`
//! and `ros2 topic hz` look at ROS topics. Both join the robot's zenoh session as a peer (by
//! default connecting to a plant on `tcp/127.0.0.1:7447`), decode every payload with the wire
//! codec, and never publish anything.

use crate::out::print_stdout;
use crate::LiveError;
use anyhow::anyhow;
use clap::Args;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tilting_net::{Role, ZenohArgs};
use tilting_proto::{
    codec, AnyReference, Keys, ModeEvent, PlantState, Status, Topic, TorqueCommand,
};
use tilting_record::sink::{Drain, Sink};

/// Parses a topic name for clap (`state`, `torque`, `event`, `status`, `reference`).
pub fn parse_topic(s: &str) -> Result<Topic, String> {
    s.parse::<Topic>().map_err(|e| e.to_string())
}

/// One payload decoded: a human line, or a JSON object (`--json`); `Err` with the codec's
/// message (naming the message type and the field) for a payload that does not decode.
pub fn describe(topic: Topic, bytes: &[u8], json: bool) -> Result<String, String> {
    fn out<T: serde::Serialize>(m: &T, json: bool, human: String) -> String {
        if json {
            serde_json::to_string(m).unwrap_or_default()
        } else {
            human
        }
    }
    let mode = |q: u8| tilting_proto::Mode::try_from(q).map_or("?", |m| m.as_str());
    Ok(match topic {
        Topic::State => {
            let s: PlantState = codec::decode(bytes).map_err(|e| e.to_string())?;
            // A rate the plant does not measure (`--measure angles`) prints as `-`, never 0.
            let rate = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:+.5}"));
            let h = format!(
                "seq {:>8}  t {:10.4} s  {:<5}  alpha {:+.6} rad  beta {:.6} rad  alpha_dot {} rad/s  beta_dot {} rad/s",
                s.seq,
                s.time,
                mode(s.mode),
                s.alpha,
                s.beta,
                rate(s.alpha_dot),
                rate(s.beta_dot)
            );
            out(&s, json, h)
        }
        Topic::Torque => {
            let c: TorqueCommand = codec::decode(bytes).map_err(|e| e.to_string())?;
            out(&c, json, format!("seq {:>8}  tau {:+.6} N m", c.seq, c.tau))
        }
        Topic::Event => {
            let e: ModeEvent = codec::decode(bytes).map_err(|e| e.to_string())?;
            let h = format!(
                "t {:.6} s  {} -> {}  alpha_dot {:+.5} -> {:+.5} rad/s  beta_dot {:+.5} -> {:+.5} rad/s",
                e.time,
                mode(e.from),
                mode(e.to),
                e.x_before[2],
                e.x_after[2],
                e.x_before[3],
                e.x_after[3]
            );
            out(&e, json, h)
        }
        Topic::Status => {
            let s: Status = codec::decode(bytes).map_err(|e| e.to_string())?;
            let h = format!(
                "t {:.3} s  {}  {}  tilts {}  misses {}  dropped {}  stale {}  latency p50 {:.0} us p99 {:.0} us  age p50 {} p99 {} max {} periods  late {}  lost {}  reordered {}{}",
                s.time,
                s.state_name(),
                mode(s.mode),
                s.tilts,
                s.deadline_misses,
                s.torques_dropped,
                s.torques_stale,
                s.latency_p50_us,
                s.latency_p99_us,
                s.age_p50,
                s.age_p99,
                s.age_max,
                s.torques_late,
                s.torques_lost,
                s.torques_reordered,
                if s.fault.is_empty() {
                    String::new()
                } else {
                    format!("  fault: {}", s.fault)
                }
            );
            out(&s, json, h)
        }
        Topic::Reference => {
            // Either layout (protocol 3): the paper's gains, or any law's name and parameters.
            let r: AnyReference = codec::decode(bytes).map_err(|e| e.to_string())?;
            let human = match &r {
                AnyReference::Paper(p) => tilting_controller::LawSpec::from(p).to_string(),
                AnyReference::Law(l) => describe_law(l),
            };
            out(&r, json, human)
        }
    })
}

/// A `LawReference` in words: the law's name, its parameters (the paper law's by name, any
/// other's by position, `p0`, `p1`, ...: their names are the law's own), and the trajectory.
fn describe_law(l: &tilting_proto::LawReference) -> String {
    let trajectory = match l.trajectory {
        tilting_proto::Reference::HOLD => "hold".to_owned(),
        t => format!(
            "{} amplitude {} rad, omega {} rad/s",
            if t == tilting_proto::Reference::SINUSOID {
                "sinusoid"
            } else {
                "excitation"
            },
            l.amplitude,
            l.omega
        ),
    };
    let params: Vec<String> = l
        .parameters
        .iter()
        .enumerate()
        .map(
            |(i, v)| match tilting_proto::LawReference::PAPER_PARAMETERS.get(i) {
                Some(name) if l.law == tilting_proto::LawReference::PAPER_LAW => {
                    format!("{name} {v}")
                }
                _ => format!("p{i} {v}"),
            },
        )
        .collect();
    format!(
        "law {} [{}], {trajectory}",
        l.law,
        if params.is_empty() {
            "no parameters".to_owned()
        } else {
            params.join(", ")
        }
    )
}

/// The session flags of `echo` and `hz`.
pub fn session_args(z: &ZenohArgs) -> Result<Keys, LiveError> {
    let keys = z.keys().map_err(LiveError::Usage)?;
    z.config(Role::Peer).map_err(LiveError::Usage)?;
    Ok(keys)
}

/// `Ok` unless `v` (a flag's seconds) is given and is not a positive number up to 1e7; the
/// error names `flag`.
pub fn check_seconds(flag: &str, v: Option<f64>) -> Result<(), LiveError> {
    match v {
        Some(s) if !(s.is_finite() && s > 0.0 && s <= 1e7) => Err(LiveError::Usage(anyhow!(
            "invalid `{flag}` = {s}: allowed a positive number of seconds up to 1e7"
        ))),
        _ => Ok(()),
    }
}

/// Flags of `tilting echo`.
#[derive(Debug, Clone, Args)]
pub struct EchoArgs {
    /// The topic to print
    #[arg(value_parser = parse_topic, value_name = "state|torque|event|status|reference")]
    pub topic: Topic,
    /// Robot name and zenoh endpoints (default: connect to tcp/127.0.0.1:7447).
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// One JSON object per message (the message's fields) instead of a line of text
    #[arg(long)]
    pub json: bool,
    /// Stop after this many messages
    #[arg(long, value_name = "N")]
    pub count: Option<u64>,
    /// Stop after this many seconds [default: until Ctrl-C]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub seconds: Option<f64>,
}

/// `tilting echo`.
pub fn echo(args: &EchoArgs) -> Result<(), LiveError> {
    tilting_net::init_tracing("warn");
    check_seconds("--seconds", args.seconds)?;
    let keys = session_args(&args.zenoh)?;
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    rt.block_on(async {
        let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
        // The callback only queues: printing (maybe into a slow pipe) must not hold a zenoh
        // thread. A full queue skips messages and says how many.
        let printed = Arc::new(AtomicU64::new(0));
        let failed = Arc::new(AtomicBool::new(false));
        let printer = Printer {
            topic: args.topic,
            json: args.json,
            limit: args.count,
            printed: printed.clone(),
            failed: failed.clone(),
            error: None,
        };
        let sink = Sink::spawn("echo", 4096, Duration::from_millis(100), printer)?;
        let key = args.topic.key(&keys).to_owned();
        let tx = sink.sender();
        let sub =
            tilting_net::subscribe_bytes(&session, &key, move |bytes| tx.send(bytes.to_vec()))
                .await?;
        eprintln!("echo: {key} (Ctrl-C stops)");
        let end = args
            .seconds
            .map(|s| Instant::now() + Duration::from_secs_f64(s));
        let mut stop = std::pin::pin!(tilting_net::shutdown_signal());
        while !(args
            .count
            .is_some_and(|c| printed.load(Ordering::Relaxed) >= c)
            || end.is_some_and(|e| Instant::now() >= e)
            || failed.load(Ordering::Relaxed))
        {
            tokio::select! {
                _ = &mut stop => break,
                _ = tokio::time::sleep(Duration::from_millis(2)) => {}
            }
        }
        drop(sub);
        let skipped = sink.dropped();
        // Messages queued before the stop are printed (up to `--count`).
        let printed = sink.finish()?;
        if skipped > 0 {
            eprintln!("echo: skipped {skipped} messages (the output was too slow)");
        }
        let _ = session.close().await;
        printed.map_err(|e| anyhow!("{e}"))
    })
    .map_err(LiveError::Failed)
}

/// `echo`'s end of its queue: prints each payload as a line, up to `limit`.
struct Printer {
    topic: Topic,
    json: bool,
    limit: Option<u64>,
    printed: Arc<AtomicU64>,
    /// Set when stdout fails (the first error is kept in `error`).
    failed: Arc<AtomicBool>,
    error: Option<LiveError>,
}

impl Drain<Vec<u8>> for Printer {
    type Output = Result<(), LiveError>;

    fn message(&mut self, bytes: Vec<u8>) {
        let n = self.printed.load(Ordering::Relaxed);
        if self.error.is_some() || self.limit.is_some_and(|c| n >= c) {
            return;
        }
        let line = match describe(self.topic, &bytes, self.json) {
            Ok(l) => l,
            Err(invalid) if self.json => {
                serde_json::to_string(&InvalidPayload { invalid }).unwrap_or_default()
            }
            Err(e) => format!("invalid payload ({} bytes): {e}", bytes.len()),
        };
        match print_stdout(&format!("{line}\n")) {
            Ok(()) => {
                self.printed.store(n + 1, Ordering::Relaxed);
            }
            Err(e) => {
                self.error = Some(e);
                self.failed.store(true, Ordering::Relaxed);
            }
        }
    }

    fn idle(&mut self) {}

    fn finish(self) -> Result<(), LiveError> {
        self.error.map_or(Ok(()), Err)
    }
}

/// Flags of `tilting hz`.
#[derive(Debug, Clone, Args)]
pub struct HzArgs {
    /// Robot name and zenoh endpoints (default: connect to tcp/127.0.0.1:7447).
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Only these topics [default: all]
    #[arg(long, value_parser = parse_topic, value_delimiter = ',', value_name = "TOPIC,...")]
    pub topics: Vec<Topic>,
    /// Seconds between two reports
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub every: f64,
    /// Stop after this many seconds [default: until Ctrl-C]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// One JSON object per report instead of a table
    #[arg(long)]
    pub json: bool,
}

/// What `hz` counts on one topic.
#[derive(Debug, Default, Clone, serde::Serialize)]
pub struct TopicStats {
    /// Messages over the whole run.
    pub count: u64,
    /// Payloads that did not decode or validate.
    pub invalid: u64,
    /// Bytes over the whole run.
    pub bytes: u64,
    /// Messages in the current report interval.
    #[serde(skip)]
    window: u64,
    /// Largest gap between two messages in the current interval (s).
    #[serde(skip)]
    window_max_gap: f64,
    #[serde(skip)]
    last: Option<Instant>,
}

/// `tilting hz`.
pub fn hz(args: &HzArgs) -> Result<(), LiveError> {
    tilting_net::init_tracing("warn");
    check_seconds("--seconds", args.seconds)?;
    check_seconds("--every", Some(args.every))?;
    let keys = session_args(&args.zenoh)?;
    let topics: Vec<Topic> = if args.topics.is_empty() {
        Topic::ALL.to_vec()
    } else {
        args.topics.clone()
    };
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    rt.block_on(async {
        let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
        let stats: Arc<Mutex<Vec<TopicStats>>> =
            Arc::new(Mutex::new(vec![TopicStats::default(); topics.len()]));
        let mut subs = Vec::new();
        for (i, &topic) in topics.iter().enumerate() {
            let st = stats.clone();
            let key = topic.key(&keys).to_owned();
            let sub = tilting_net::subscribe_bytes(&session, &key, move |bytes| {
                let ok = topic.check(bytes).is_ok();
                let now = Instant::now();
                let mut v = st.lock().unwrap_or_else(|e| e.into_inner());
                let t = &mut v[i];
                t.count += 1;
                t.window += 1;
                t.bytes += bytes.len() as u64;
                t.invalid += u64::from(!ok);
                if let Some(l) = t.last {
                    t.window_max_gap = t.window_max_gap.max((now - l).as_secs_f64());
                }
                t.last = Some(now);
            })
            .await?;
            subs.push(sub);
        }
        eprintln!(
            "hz: {} topics of robot {} (Ctrl-C stops)",
            topics.len(),
            keys.robot()
        );
        let start = Instant::now();
        let end = args.seconds.map(|s| start + Duration::from_secs_f64(s));
        let mut stop = std::pin::pin!(tilting_net::shutdown_signal());
        let mut last = start;
        loop {
            let tick = tokio::time::sleep(Duration::from_secs_f64(args.every));
            tokio::select! {
                _ = &mut stop => break,
                _ = tick => {}
            }
            let now = Instant::now();
            let dt = (now - last).as_secs_f64();
            last = now;
            let snapshot: Vec<TopicStats> = {
                let mut v = stats.lock().unwrap_or_else(|e| e.into_inner());
                let s = v.clone();
                for t in v.iter_mut() {
                    t.window = 0;
                    t.window_max_gap = 0.0;
                }
                s
            };
            let text = report(
                &topics,
                &snapshot,
                dt,
                (now - start).as_secs_f64(),
                args.json,
            );
            print_stdout(&text).map_err(|e| anyhow!("{e}"))?;
            if end.is_some_and(|e| now >= e) {
                break;
            }
        }
        drop(subs);
        let _ = session.close().await;
        anyhow::Ok(())
    })
    .map_err(LiveError::Failed)
}

/// One report of `hz --json` (fields in the order of the JSON).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HzReport {
    /// Seconds since the start.
    pub t: f64,
    /// One entry per topic watched, in the order asked.
    pub topics: Vec<HzTopic>,
}

/// One topic in an [`HzReport`] (fields in the order of the JSON).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HzTopic {
    /// Mean payload size over the whole run (bytes), `None` before the first message.
    pub bytes_per_msg: Option<f64>,
    /// Messages over the whole run.
    pub count: u64,
    /// Payloads that did not decode or validate, over the whole run.
    pub invalid: u64,
    /// Largest gap between two messages in the last interval (s), `None` for fewer than two.
    pub max_gap_s: Option<f64>,
    /// Message rate over the last interval (Hz).
    pub rate_hz: f64,
    /// The topic's name (`state`, `torque`, ...).
    pub topic: String,
}

/// What `echo --json` prints for a payload that does not decode.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct InvalidPayload {
    /// The codec's message, naming the message type and the field.
    pub invalid: String,
}

/// One report: a table (or a JSON object) with the rate over the last interval, its largest
/// gap, the message size and the totals.
fn report(topics: &[Topic], stats: &[TopicStats], dt: f64, t: f64, json: bool) -> String {
    if json {
        let r = HzReport {
            t,
            topics: topics
                .iter()
                .zip(stats)
                .map(|(tp, s)| HzTopic {
                    topic: tp.name().to_owned(),
                    rate_hz: s.window as f64 / dt,
                    max_gap_s: (s.window > 1).then_some(s.window_max_gap),
                    bytes_per_msg: (s.count > 0).then(|| s.bytes as f64 / s.count as f64),
                    count: s.count,
                    invalid: s.invalid,
                })
                .collect(),
        };
        // Serialising numbers, options and strings cannot fail.
        return format!("{}\n", serde_json::to_string(&r).unwrap_or_default());
    }
    let mut out = format!(
        "t {t:8.1} s | {:<9} | {:>9} | {:>10} | {:>9} | {:>9} | {:>7}\n",
        "topic", "rate (Hz)", "max gap ms", "bytes/msg", "total", "invalid"
    );
    for (tp, s) in topics.iter().zip(stats) {
        let gap = if s.window > 1 {
            format!("{:.2}", s.window_max_gap * 1e3)
        } else {
            "-".to_owned()
        };
        let size = if s.count > 0 {
            format!("{:.0}", s.bytes as f64 / s.count as f64)
        } else {
            "-".to_owned()
        };
        out += &format!(
            "             | {:<9} | {:>9.1} | {:>10} | {:>9} | {:>9} | {:>7}\n",
            tp.name(),
            s.window as f64 / dt,
            gap,
            size,
            s.count,
            s.invalid
        );
    }
    out
}
