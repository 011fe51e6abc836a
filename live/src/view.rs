//! `tilting view` (any robot on the network, served to Foxglove) and `tilting replay
//! --foxglove`. The flags, the subscription and the live run's server are [`crate::foxglove`]'s;
//! the server itself is `tilting_foxglove`'s.

use crate::foxglove::{parse_addr, report, start, subscribe, FoxgloveArgs};
use crate::LiveError;
use anyhow::anyhow;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tilting_foxglove::{Feed, DEFAULT_ADDR};
use tilting_net::{Role, ZenohArgs};
use tilting_proto::{Keys, Topic};

/// The robot's geometry from `--params` (the paper's without it); the error names the flag.
pub fn scene_params(file: Option<&PathBuf>) -> Result<tilting_plant::Params, LiveError> {
    match file {
        None => Ok(tilting_plant::Params::default()),
        Some(f) => tilting_plant::Params::from_toml_file(f)
            .map_err(|e| LiveError::Usage(anyhow!("invalid `--params` = {}: {e}", f.display()))),
    }
}

/// Flags of `tilting view`.
#[derive(Debug, Clone, clap::Args)]
pub struct ViewArgs {
    /// Robot name and zenoh endpoints (default: connect to tcp/127.0.0.1:7447).
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// The address to serve Foxglove on
    #[arg(long = "foxglove", value_name = "ADDR", default_value = DEFAULT_ADDR, value_parser = parse_addr)]
    pub addr: SocketAddr,
    /// Allow --foxglove on an address that is not loopback (serves the robot to the network)
    #[arg(long)]
    pub foxglove_any: bool,
    /// The tilt drawn this many times larger in the 3D scene (display only; 1 is to scale)
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "K",
        allow_negative_numbers = true
    )]
    pub tilt_exaggeration: f64,
    /// The robot's geometry for the scene (TOML, the keys of docs/model.md) [default: the
    /// paper's]
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    /// Stop after this many seconds [default: until Ctrl-C]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// Say so if no message arrives within this many seconds (the server keeps serving)
    #[arg(
        long,
        default_value_t = 10.0,
        value_name = "SECONDS",
        allow_negative_numbers = true
    )]
    pub wait: f64,
}

/// `tilting view`: serves any robot on the network (ours, a Python plant, a real one) to
/// Foxglove, subscribing to its five topics as `tilting record` does, until Ctrl-C or
/// `--seconds`.
pub fn view(args: &ViewArgs) -> Result<(), LiveError> {
    tilting_net::init_tracing("warn");
    crate::topics::check_seconds("--seconds", args.seconds)?;
    crate::topics::check_seconds("--wait", Some(args.wait))?;
    let keys = crate::topics::session_args(&args.zenoh)?;
    let flags = FoxgloveArgs {
        foxglove: Some(args.addr),
        foxglove_any: args.foxglove_any,
        tilt_exaggeration: args.tilt_exaggeration,
    };
    flags.check()?;
    let params = scene_params(args.params.as_ref())?;
    let opts = flags.options(&keys, params).expect("--foxglove is set");
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    rt.block_on(async {
        let server = start(&opts, "view")
            .await
            .map_err(|e| LiveError::Failed(e.into()))?;
        let run = async {
            let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
            let received = Arc::default();
            let subs = subscribe(&session, &session, &keys, &server.feed(), &received).await?;
            watch(args, &keys, &received).await;
            drop(subs);
            let _ = session.close().await;
            anyhow::Ok(())
        };
        let result = run.await;
        report("view", &server.close().await);
        result.map_err(LiveError::Failed)
    })
}

/// Waits for Ctrl-C or `--seconds`, saying once if nothing arrived within `--wait`.
async fn watch(args: &ViewArgs, keys: &Keys, received: &AtomicU64) {
    let start = Instant::now();
    let end = args.seconds.map(|s| start + Duration::from_secs_f64(s));
    let mut stop = std::pin::pin!(tilting_net::shutdown_signal());
    let mut warned = false;
    while end.is_none_or(|e| Instant::now() < e) {
        if !warned
            && start.elapsed().as_secs_f64() >= args.wait
            && received.load(Ordering::Relaxed) == 0
        {
            warned = true;
            eprintln!(
                "view: no message from robot `{}` within {} s (is it running, and reachable at \
                 {}?); still serving",
                keys.robot(),
                args.wait,
                if args.zenoh.connect.is_empty() {
                    "tcp/127.0.0.1:7447".to_owned()
                } else {
                    args.zenoh.connect.join(", ")
                }
            );
        }
        tokio::select! {
            _ = &mut stop => break,
            _ = tokio::time::sleep(Duration::from_millis(50)) => {}
        }
    }
}

/// `tilting replay FILE --foxglove`: plays the recording's `topics` into a Foxglove server with
/// the scene, at the recording's pace times `--speed` (or, with `--fast`, as fast as the
/// publisher takes them, nothing dropped). It waits up to `--wait` s for a first client, then
/// plays, and stops serving at the end (or at Ctrl-C).
pub fn replay(
    args: &crate::recording::ReplayArgs,
    keys: &Keys,
    run: &tilting_record::Recording,
    topics: &[Topic],
) -> Result<(), LiveError> {
    args.fox.check()?;
    let params = scene_params(args.params.as_ref())?;
    let opts = args.fox.options(keys, params).expect("--foxglove is set");
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    rt.block_on(async {
        let server = start(&opts, "replay")
            .await
            .map_err(|e| LiveError::Failed(e.into()))?;
        let deadline = Instant::now() + Duration::from_secs_f64(args.wait);
        while server.clients() == 0 && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        if server.clients() == 0 {
            eprintln!(
                "replay: no Foxglove client within {} s: playing anyway",
                args.wait
            );
        } else {
            // Give the client a moment to subscribe to the channels it was offered.
            tokio::time::sleep(Duration::from_millis(500)).await;
        }
        let feed = server.feed();
        let sent = tokio::task::block_in_place(|| play(args, run, topics, &feed));
        // Let the publisher send what is queued before the server stops.
        while feed.queued() > 0 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
        let counts = server.close().await;
        report("replay", &counts);
        eprintln!(
            "replay: {sent} messages of {} played into Foxglove",
            run.path().display()
        );
        Ok(())
    })
}

/// Feeds the recording to `feed`, paced; the number of messages fed.
fn play(
    args: &crate::recording::ReplayArgs,
    run: &tilting_record::Recording,
    topics: &[Topic],
    feed: &Feed,
) -> u64 {
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let stop = stop.clone();
        tokio::spawn(async move {
            tilting_net::shutdown_signal().await;
            stop.store(true, Ordering::Relaxed);
        });
    }
    let started = Instant::now();
    let mut first = None;
    let mut sent = 0;
    for e in run.messages() {
        if !topics.contains(&e.topic) {
            continue;
        }
        if stop.load(Ordering::Relaxed) {
            break;
        }
        if args.fast {
            // As fast as the publisher takes them: never fill the drop-oldest queue.
            while feed.queued() > tilting_foxglove::server::QUEUE / 2 {
                std::thread::sleep(Duration::from_millis(1));
            }
        } else {
            let t0 = *first.get_or_insert(e.log_time);
            let due = started
                + Duration::from_secs_f64(e.log_time.saturating_sub(t0) as f64 / 1e9 / args.speed);
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
        }
        feed.send(tilting_foxglove::Item {
            topic: e.topic,
            wire: e.wire,
            log_time: Some(e.log_time),
        });
        sent += 1;
    }
    sent
}
