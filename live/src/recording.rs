//! `tilting record`, `tilting replay` and `tilting info`: MCAP recordings of a robot's topics
//! (the format is `tilting_record`'s), made from any robot on the network, played back into
//! nodes under test, and summarised.

use crate::out::print_stdout;
use crate::topics::{check_seconds, parse_topic, session_args};
use crate::LiveError;
use anyhow::anyhow;
use clap::Args;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tilting_net::{Qos, RawPublisher, Role, ZenohArgs};
use tilting_proto::{Keys, Topic};
use tilting_record::{recorder, Info, Record, Recorder, Recording};

/// Flags of `tilting record`.
#[derive(Debug, Clone, Args)]
pub struct RecordArgs {
    /// The MCAP file to write
    #[arg(long, value_name = "FILE.mcap")]
    pub out: PathBuf,
    /// Robot name and zenoh endpoints (default: connect to tcp/127.0.0.1:7447).
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Stop after this many seconds [default: until Ctrl-C]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// Fail if no message arrives within this many seconds
    #[arg(
        long,
        default_value_t = 10.0,
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub wait: f64,
    /// The plant's zenoh id (its `--zenoh-id`; `tilting live` prints the ids of its nodes): its
    /// states, events and statuses are recorded only from that session
    /// [default: pin the session of the first state, event or status]
    #[arg(long, value_name = "HEX", value_parser = tilting_net::parse_source_id)]
    pub plant_id: Option<tilting_proto::SourceId>,
    /// The controller's zenoh id: its torques are recorded only from that session [default:
    /// pin the session of the first torque]
    #[arg(long, value_name = "HEX", value_parser = tilting_net::parse_source_id)]
    pub controller_id: Option<tilting_proto::SourceId>,
    /// Record every message whatever session sent it (a recording of the network, a second
    /// plant or a forger included), as `record` did before it checked sources
    #[arg(long, conflicts_with_all = ["plant_id", "controller_id"])]
    pub any_source: bool,
}

/// `tilting record`: subscribes to the five topics of a robot and writes every message that
/// decodes and validates into an MCAP file, until Ctrl-C or `--seconds`. The plant's topics are
/// recorded only from the plant's session and the torques only from the controller's
/// (`--plant-id`, `--controller-id`, or each pinned by its first message, as `tilting live`'s
/// recorder does); messages from any other session are counted as foreign, reported, and not
/// recorded (`--any-source` records them).
pub fn record(args: &RecordArgs) -> Result<(), LiveError> {
    tilting_net::init_tracing("warn");
    check_seconds("--seconds", args.seconds)?;
    check_seconds("--wait", Some(args.wait))?;
    let keys = session_args(&args.zenoh)?;
    // Every message as received (re-publications too): the recording replays what was sent.
    let opts = recorder::Options {
        mcap: args.out.clone(),
        csv_dir: None,
        skip_repeats: false,
        // Every message as received (no plausibility rules: `record` does not know the robot's
        // period or bounds), but only from the plant's and the controller's sessions.
        rules: None,
        sources: (!args.any_source).then_some(tilting_record::Sources {
            plant: args.plant_id,
            controller: args.controller_id,
        }),
    };
    let rec = Recorder::with_options(&opts, &keys)
        .map_err(|e| LiveError::Failed(anyhow!("--out {e}")))?;
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    rt.block_on(async {
        let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
        let received = Arc::new(AtomicU64::new(0));
        let mut subs = Vec::new();
        for topic in Topic::ALL {
            let tx = rec.sender();
            let n = received.clone();
            let key = topic.key(&keys).to_owned();
            subs.push(
                tilting_net::subscribe_sourced(&session, &key, move |bytes, from| {
                    n.fetch_add(1, Ordering::Relaxed);
                    tx.send_from(Record::Wire(topic, bytes.to_vec()), from);
                })
                .await?,
            );
        }
        eprintln!(
            "record: tilting/{}/** into {} (Ctrl-C stops)",
            keys.robot(),
            args.out.display()
        );
        let start = Instant::now();
        let end = args.seconds.map(|s| start + Duration::from_secs_f64(s));
        let wait = Duration::from_secs_f64(args.wait);
        let mut stop = std::pin::pin!(tilting_net::shutdown_signal());
        let mut last_report = Instant::now();
        while end.is_none_or(|e| Instant::now() < e) {
            let total = received.load(Ordering::Relaxed);
            if total == 0 && start.elapsed() >= wait {
                drop(subs);
                let _ = session.close().await;
                let _ = rec.finish();
                let _ = std::fs::remove_file(&args.out);
                return Err(anyhow!(
                    "no message from robot `{}` within {} s (is it running, and reachable at {}?); \
                     nothing recorded",
                    keys.robot(),
                    args.wait,
                    endpoints(&args.zenoh)
                ));
            }
            if last_report.elapsed() >= Duration::from_secs(1) {
                last_report = Instant::now();
                eprint!(
                    "\rrecord: {total} messages, {:.0} s",
                    start.elapsed().as_secs_f64()
                );
            }
            tokio::select! {
                _ = &mut stop => break,
                _ = tokio::time::sleep(Duration::from_millis(20)) => {}
            }
        }
        // What was queued before the subscribers went away is written by `finish`.
        drop(subs);
        let _ = session.close().await;
        let dropped = rec.dropped();
        let view = rec.finish()?;
        let counts: Vec<String> = Topic::ALL
            .iter()
            .map(|&t| format!("{} {}", view.count(t), t))
            .collect();
        eprintln!();
        print_stdout(&format!(
            "recorded {} into {}: {}; invalid {}, dropped {dropped}, foreign {}\n{}",
            keys.robot(),
            args.out.display(),
            counts.join(", "),
            view.invalid,
            view.foreign,
            foreign_line(&view),
        ))
        .map_err(|e| anyhow!("{e}"))?;
        anyhow::Ok(())
    })
    .map_err(LiveError::Failed)
}

/// What `record` refused, in words, if anything: per topic, and the first refusal (which names
/// the foreign session and the pinned one).
fn foreign_line(view: &tilting_record::RecordView) -> String {
    if view.refused_total() == 0 {
        return String::new();
    }
    let per: Vec<String> = Topic::ALL
        .iter()
        .filter(|t| view.refused[t.index()] > 0)
        .map(|&t| format!("{} {t}", view.refused[t.index()]))
        .collect();
    format!(
        "not recorded, from a foreign source: {} ({}); first: {}\n",
        view.foreign,
        per.join(", "),
        view.first_refusal.as_deref().unwrap_or("?")
    )
}

fn endpoints(z: &ZenohArgs) -> String {
    if z.connect.is_empty() {
        "tcp/127.0.0.1:7447".into()
    } else {
        z.connect.join(", ")
    }
}

/// Flags of `tilting replay`.
#[derive(Debug, Clone, Args)]
pub struct ReplayArgs {
    /// The MCAP file (written by `live`, `record` or the plant's `--record`)
    #[arg(value_name = "FILE.mcap")]
    pub file: PathBuf,
    /// Robot name (the keys published) and zenoh endpoints (default: connect to
    /// tcp/127.0.0.1:7447).
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Only these topics [default: all recorded]
    #[arg(long, value_parser = parse_topic, value_delimiter = ',', value_name = "TOPIC,...")]
    pub topics: Vec<Topic>,
    /// Playback speed: 1 is the original pace, 10 ten times faster
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "FACTOR",
        allow_negative_numbers = true
    )]
    pub speed: f64,
    /// As fast as possible (ignores --speed)
    #[arg(long)]
    pub fast: bool,
    /// Play into a Foxglove server (with the 3D scene) instead of zenoh.
    #[command(flatten)]
    pub fox: crate::foxglove::FoxgloveArgs,
    /// With --foxglove: the robot's geometry for the scene (TOML, the keys of docs/model.md)
    /// [default: the paper's]
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    /// Seconds to wait for a subscriber on every replayed topic (with --foxglove: for a first
    /// client) before starting
    #[arg(
        long,
        default_value_t = 10.0,
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub wait: f64,
}

/// `tilting replay`: publishes the recorded payloads, byte for byte, on the keys of `--robot`,
/// paced by their log times. While replaying a node's topics it holds that node's liveliness
/// token (the plant's for state/event/status, the controller's for torque, the planner's for
/// reference), as the node did.
pub fn replay(args: &ReplayArgs) -> Result<(), LiveError> {
    tilting_net::init_tracing("warn");
    if !(args.speed.is_finite() && args.speed > 0.0 && args.speed <= 1e6) {
        return Err(LiveError::Usage(anyhow!(
            "invalid `--speed` = {}: allowed a factor in (0, 1e6] (use --fast for no pacing)",
            args.speed
        )));
    }
    check_seconds("--wait", Some(args.wait))?;
    let keys = session_args(&args.zenoh)?;
    let run = tilting_record::read(&args.file)?;
    let topics: Vec<Topic> = if args.topics.is_empty() {
        Topic::ALL
            .into_iter()
            .filter(|&t| run.count(t) > 0)
            .collect()
    } else {
        args.topics.clone()
    };
    if topics.is_empty() {
        return Err(LiveError::Failed(anyhow!(
            "{} holds no message to replay",
            args.file.display()
        )));
    }
    for &t in &topics {
        if run.count(t) == 0 {
            return Err(LiveError::Usage(anyhow!(
                "`--topics`: {} holds no {t} message (it holds: {})",
                args.file.display(),
                held(&run)
            )));
        }
    }
    if let Some(r) = run.robot().filter(|&r| r != keys.robot()) {
        eprintln!(
            "replay: recorded from robot `{r}`, replaying as `{}`",
            keys.robot()
        );
    }
    if let Some(why) = run.truncation() {
        eprintln!(
            "replay: {} is truncated ({why}): replaying what it holds",
            args.file.display()
        );
    }
    if args.fox.foxglove.is_some() {
        return crate::view::replay(args, &keys, &run, &topics);
    }
    args.fox.check()?;
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    rt.block_on(replay_async(args, &keys, &run, &topics))
        .map_err(LiveError::Failed)
}

fn held(run: &Recording) -> String {
    Topic::ALL
        .iter()
        .filter(|&&t| run.count(t) > 0)
        .map(|t| t.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The liveliness tokens of the nodes whose topics a replay of `topics` publishes as robot
/// `keys` (the plant for states, events and status, the controller for torques, the planner for
/// references): the nodes under test see their peers alive.
async fn declare_roles(
    session: &zenoh::Session,
    keys: &Keys,
    topics: &[Topic],
) -> anyhow::Result<Vec<zenoh::liveliness::LivelinessToken>> {
    let mut tokens = Vec::new();
    let roles = [
        (
            [Topic::State, Topic::Event, Topic::Status].as_slice(),
            keys.alive_plant(),
        ),
        ([Topic::Torque].as_slice(), keys.alive_controller()),
        ([Topic::Reference].as_slice(), keys.alive_planner()),
    ];
    for (ts, key) in roles {
        if ts.iter().any(|t| topics.contains(t)) {
            tokens.push(
                session
                    .liveliness()
                    .declare_token(key.to_owned())
                    .await
                    .map_err(|e| {
                        anyhow!("cannot declare {key}: {}", tilting_net::zenoh_error(&e))
                    })?,
            );
        }
    }
    Ok(tokens)
}

/// Waits until every publisher of `pubs` has a subscriber (a put before a subscriber's route
/// exists is lost), at most `wait` s in all; then the error names the first key without one
/// and robot `keys`.
async fn wait_for_subscribers(
    pubs: &[Option<RawPublisher>],
    wait: f64,
    keys: &Keys,
) -> anyhow::Result<()> {
    // A put before a subscriber's route exists is lost: wait for one on every topic.
    let deadline = Instant::now() + Duration::from_secs_f64(wait);
    for p in pubs.iter().flatten() {
        while !p.has_subscribers().await {
            if Instant::now() >= deadline {
                return Err(anyhow!(
                    "nobody subscribes to {} after {} s: start the node under test first (with \
                     --robot {}), or pass --wait",
                    p.key(),
                    wait,
                    keys.robot()
                ));
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
    Ok(())
}

async fn replay_async(
    args: &ReplayArgs,
    keys: &Keys,
    run: &Recording,
    topics: &[Topic],
) -> anyhow::Result<()> {
    let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
    let mut pubs: Vec<Option<RawPublisher>> = (0..5).map(|_| None).collect();
    for &t in topics {
        let qos = match t {
            // A replay must deliver every message it was asked to (and `--fast` outruns any
            // queue): it waits on a full link, at the loop's priority.
            Topic::State | Topic::Torque | Topic::Event | Topic::Status => Qos::Lossless,
            _ => Qos::Data,
        };
        pubs[t.index()] = Some(RawPublisher::declare(&session, t.key(keys), qos).await?);
    }
    let tokens = declare_roles(&session, keys, topics).await?;
    wait_for_subscribers(&pubs, args.wait, keys).await?;
    // Routes exist; give the remote subscriber's declaration a moment to settle.
    tokio::time::sleep(Duration::from_millis(100)).await;
    let total: u64 = topics.iter().map(|&t| run.count(t)).sum();
    let bar = crate::out::bar(total, "messages", false);
    let started = Instant::now();
    let mut first: Option<u64> = None;
    let mut sent = [0u64; 5];
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let stop = stop.clone();
        tokio::spawn(async move {
            tilting_net::shutdown_signal().await;
            stop.store(true, Ordering::Relaxed);
        });
    }
    let speed = args.speed;
    let fast = args.fast;
    tokio::task::block_in_place(|| -> anyhow::Result<()> {
        for e in run.messages() {
            let Some(p) = &pubs[e.topic.index()] else {
                continue;
            };
            if stop.load(Ordering::Relaxed) {
                break;
            }
            if !fast {
                let t0 = *first.get_or_insert(e.log_time);
                let due = started
                    + Duration::from_secs_f64((e.log_time.saturating_sub(t0)) as f64 / 1e9 / speed);
                let now = Instant::now();
                if due > now {
                    std::thread::sleep(due - now);
                }
            }
            p.put_raw(&e.wire)?;
            sent[e.topic.index()] += 1;
            bar.inc(1);
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    // Let the last puts leave before the session closes.
    tokio::time::sleep(Duration::from_millis(200)).await;
    drop(tokens);
    let _ = session.close().await;
    let counts: Vec<String> = topics
        .iter()
        .map(|&t| format!("{} {}", sent[t.index()], t))
        .collect();
    print_stdout(&format!(
        "replayed {} as robot {}: {} in {:.2} s\n",
        run.path().display(),
        keys.robot(),
        counts.join(", "),
        started.elapsed().as_secs_f64()
    ))
    .map_err(|e| anyhow!("{e}"))
}

/// Flags of `tilting info`.
#[derive(Debug, Clone, Args)]
pub struct InfoArgs {
    /// The MCAP file
    #[arg(value_name = "FILE.mcap")]
    pub file: PathBuf,
    /// One JSON object instead of text
    #[arg(long)]
    pub json: bool,
}

/// `tilting info`.
pub fn info(args: &InfoArgs) -> Result<(), LiveError> {
    let run = tilting_record::read(&args.file)?;
    let info = run.info();
    let text = if args.json {
        serde_json::to_string_pretty(&info).map_err(|e| LiveError::Failed(e.into()))? + "\n"
    } else {
        info_text(&info, &run)
    };
    print_stdout(&text)
}

fn info_text(info: &Info, run: &Recording) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let robot = info.robot.as_deref().unwrap_or("?");
    let _ = writeln!(
        s,
        "file:       {} ({:.1} kB)\nrobot:      {robot}",
        info.file.display(),
        info.bytes as f64 / 1e3
    );
    let _ = match &info.truncation {
        None => writeln!(s, "closed:     yes (summary section present)"),
        Some(w) => writeln!(s, "closed:     NO, read up to the last whole chunk ({w})"),
    };
    let span = run.span();
    if let Some((a, b)) = span {
        let _ = writeln!(s, "plant time: {a:.3} s to {b:.3} s ({:.3} s)", b - a);
    }
    let _ = writeln!(s, "channels:");
    for t in Topic::ALL {
        let n = run.count(t);
        let rate = span
            .filter(|(a, b)| b > a)
            .map(|(a, b)| format!("  {:.1} Hz", n as f64 / (b - a)))
            .unwrap_or_default();
        let topic = format!(
            "/tilting/{robot}/{}",
            t.key(&Keys::new("r").expect("a valid name"))
                .trim_start_matches("tilting/r/")
        );
        let _ = writeln!(s, "  {topic:<36} {:<14} {n:>9}{rate}", t.message_type());
    }
    if let (n @ 1.., Some(first)) = run.invalid() {
        let _ = writeln!(s, "invalid:    {n} messages skipped (first: {first})");
    }
    let _ = writeln!(
        s,
        "tilts:      {}\nfaults:     {}",
        info.tilts,
        if info.faults.is_empty() {
            "none".to_owned()
        } else {
            info.faults.join("; ")
        }
    );
    s
}
