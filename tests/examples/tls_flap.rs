//! The TLS link flap of issue 22, reproduced with bare zenoh sessions (no tilting node, no
//! tilting wire format, no access control):
//!
//! ```sh
//! cargo run --release -p tilting-tests --features bench --example tls_flap -- --seconds 30 --runs 3
//! RUST_LOG=zenoh_transport=debug cargo run --release -p tilting-tests --features bench --example tls_flap
//! ```
//!
//! One process opens a zenoh **router** listening on `tls/127.0.0.1:PORT` with mutual TLS, and
//! two or three **clients** of it (`--clients 2|3`), each with its own certificate (made with
//! `tilting certs`' generator; any CA and certificates do):
//!
//! - `a` (the plant's pattern) publishes a 49-byte sample on `repro/state` every `1/--rate` s
//!   (real-time priority, express, blocking congestion control) and a 10 Hz status on
//!   `repro/status`;
//! - `b` (the controller's) answers each state from its subscriber callback with a 16-byte
//!   sample on `repro/torque`;
//! - `c` (the recorder's, with `--clients 3`) subscribes to `repro/**`.
//!
//! `a` and `b` each hold a liveliness token and watch the other's. A **flap** is a token that
//! disappears: the transport of that client was closed and reopened. With the zenoh 1.10.2
//! TLS link (`zenoh-link-tls`), a link's RX and TX tasks use one `tokio_rustls::TlsStream` at
//! the same time through an `UnsafeCell` (eclipse-zenoh/zenoh#2557): rustls' `Connection` is
//! not meant for that. The RX task's `process_new_packets` parks the connection state as
//! `Err(HandshakeNotComplete)` while it decrypts a record; a TX task's `write` that checks
//! the state in that window fails with `handshake not complete` ("TX task failed" in the
//! `zenoh_transport` debug log), the link is closed, the client reconnects within a few ms, and
//! its liveliness token flaps. `--tcp` runs the same sessions over plain TCP for comparison.
//!
//! `--direct` makes `a` and `b` peers with a TLS link of their own (`b` dials `a`), both also
//! connected to the router (the direct loop of `tilting live --secure`): the answers then take
//! one hop instead of two, none arrives twice, and `c` still hears everything via the router.
//!
//! It prints, per run: flaps, samples sent and answered, and the round-trip time (state put →
//! torque received at `a`) p50/p99/max in µs.

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::json;
use tilting_proto::Keys;
use tilting_tests::{free_port, Scratch};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::SampleKind;
use zenoh::{Config, Session, Wait};

/// The run's settings (command line).
struct Opts {
    seconds: f64,
    rate: f64,
    clients: usize,
    tcp: bool,
    runs: usize,
    direct: bool,
}

fn parse() -> Opts {
    let mut o = Opts {
        seconds: 30.0,
        rate: 1000.0,
        clients: 3,
        tcp: false,
        runs: 1,
        direct: false,
    };
    let mut args = std::env::args().skip(1);
    let num = |v: Option<String>, name: &str, lo: f64, hi: f64| -> f64 {
        v.and_then(|s| s.parse::<f64>().ok())
            .filter(|x| (lo..=hi).contains(x))
            .unwrap_or_else(|| panic!("{name}: a number from {lo} to {hi}"))
    };
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seconds" => o.seconds = num(args.next(), "--seconds", 1.0, 3600.0),
            "--rate" => o.rate = num(args.next(), "--rate", 1.0, 20_000.0),
            "--clients" => o.clients = num(args.next(), "--clients", 2.0, 3.0) as usize,
            "--runs" => o.runs = num(args.next(), "--runs", 1.0, 100.0) as usize,
            "--tcp" => o.tcp = true,
            "--direct" => o.direct = true,
            other => panic!(
                "unknown flag {other}; usage: tls_flap [--seconds S] [--rate HZ] \
                 [--clients 2|3] [--runs N] [--tcp]"
            ),
        }
    }
    o
}

/// A zenoh configuration: `mode`, explicit endpoints, no scouting; TLS with mutual
/// authentication and `node`'s certificate unless `tcp`.
fn config(
    certs: &Path,
    node: &str,
    mode: &str,
    listen: &[String],
    connect: &[String],
    tcp: bool,
) -> Config {
    let f = |name: String| certs.join(name).display().to_string();
    let mut v = json!({
        "mode": mode,
        "listen": { "endpoints": listen },
        "connect": { "endpoints": connect,
                     "retry": { "period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2 } },
        "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false } },
        "timestamping": { "enabled": false },
    });
    if !tcp {
        v["transport"] = json!({ "link": { "protocols": ["tls"], "tls": {
            "root_ca_certificate": f("ca.pem".into()),
            "listen_certificate": f(format!("{node}.pem")),
            "listen_private_key": f(format!("{node}.key")),
            "connect_certificate": f(format!("{node}.pem")),
            "connect_private_key": f(format!("{node}.key")),
            "enable_mtls": true,
            // The nodes' certificates name no host (only the router's does): a peer dialling
            // another peer checks the chain and the identity, not the address.
            "verify_name_on_connect": mode == "router" || mode == "client",
        }}});
    }
    Config::from_json5(&v.to_string()).expect("a valid zenoh configuration")
}

/// Counts the deletions of the liveliness tokens on `key` seen by `s`.
async fn watch(s: &Session, key: &str, gone: Arc<AtomicU64>) -> zenoh::pubsub::Subscriber<()> {
    s.liveliness()
        .declare_subscriber(key)
        .callback(move |sample| {
            if sample.kind() == SampleKind::Delete {
                gone.fetch_add(1, Ordering::Relaxed);
            }
        })
        .await
        .expect("liveliness subscriber")
}

/// Nearest-rank percentile of sorted `v`.
fn pct(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1]
}

/// One run; returns the number of flaps.
// long: one linear script (sessions, traffic, counting) reads best in one piece
async fn run(o: &Opts, i: usize) -> u64 {
    let dir = Scratch::new(&format!("tls-flap-{i}"));
    let certs = dir.path().join("certs");
    let keys = Keys::new("repro").unwrap();
    tilting::security::generate(&keys, &certs, &[], "tls/127.0.0.1:7447", &["c".into()])
        .expect("certificates");
    let proto = if o.tcp { "tcp" } else { "tls" };
    let ep = format!("{proto}/127.0.0.1:{}", free_port());
    let router = zenoh::open(config(
        &certs,
        "router",
        "router",
        std::slice::from_ref(&ep),
        &[],
        o.tcp,
    ))
    .await
    .expect("router");
    // The generated certificates name the nodes plant, controller, logger, ...: a, b, c here.
    let client = |node: &str| {
        zenoh::open(config(
            &certs,
            node,
            "client",
            &[],
            std::slice::from_ref(&ep),
            o.tcp,
        ))
    };
    // --direct: a and b are peers with a link of their own (b connects to a's listener), each
    // also connected to the router; c stays a client of the router.
    let a_ep = format!("{proto}/127.0.0.1:{}", free_port());
    let (a, b) = if o.direct {
        let peer = |node: &str, listen: &[String], connect: &[String]| {
            zenoh::open(config(&certs, node, "peer", listen, connect, o.tcp))
        };
        let a = peer(
            "plant",
            std::slice::from_ref(&a_ep),
            std::slice::from_ref(&ep),
        );
        let a = a.await.expect("peer a");
        let b = peer("controller", &[], &[a_ep.clone(), ep.clone()]);
        (a, b.await.expect("peer b"))
    } else {
        let a = client("plant").await.expect("client a");
        (a, client("controller").await.expect("client b"))
    };
    let c = if o.clients == 3 {
        Some(client("logger").await.expect("client c"))
    } else {
        None
    };

    let a_saw_b_gone = Arc::new(AtomicU64::new(0));
    let b_saw_a_gone = Arc::new(AtomicU64::new(0));
    let _wa = watch(&a, "repro/alive/b", a_saw_b_gone.clone()).await;
    let _wb = watch(&b, "repro/alive/a", b_saw_a_gone.clone()).await;
    let _ta = a.liveliness().declare_token("repro/alive/a").await.unwrap();
    let _tb = b.liveliness().declare_token("repro/alive/b").await.unwrap();

    let control = |s: &Session, key: &'static str| {
        s.declare_publisher(key)
            .congestion_control(CongestionControl::Block)
            .priority(Priority::RealTime)
            .express(true)
            .wait()
            .expect("publisher")
    };
    // b answers every state with a torque carrying the state's sequence number.
    let torque = Arc::new(control(&b, "repro/torque"));
    let t = torque.clone();
    let _sb = b
        .declare_subscriber("repro/state")
        .callback(move |s| {
            let mut answer = [0u8; 16];
            answer[..8].copy_from_slice(&s.payload().to_bytes()[..8]);
            let _ = t.put(answer.to_vec()).wait();
        })
        .await
        .unwrap();
    // a stamps each state's departure and each torque's arrival.
    let n = (o.seconds * o.rate) as usize + 16;
    let sent_at: Arc<Vec<AtomicU64>> = Arc::new((0..n).map(|_| AtomicU64::new(0)).collect());
    let rtt: Arc<Mutex<Vec<f64>>> = Arc::new(Mutex::new(Vec::with_capacity(n)));
    let t0 = Instant::now();
    let duplicates = Arc::new(AtomicU64::new(0));
    let (s2, r2, d2) = (sent_at.clone(), rtt.clone(), duplicates.clone());
    let _sa = a
        .declare_subscriber("repro/torque")
        .callback(move |s| {
            let now = t0.elapsed().as_nanos() as u64;
            let seq = u64::from_le_bytes(s.payload().to_bytes()[..8].try_into().unwrap()) as usize;
            if let Some(at) = s2.get(seq).map(|x| x.swap(0, Ordering::Relaxed)) {
                if at == 0 {
                    d2.fetch_add(1, Ordering::Relaxed); // a second answer to the same state
                } else {
                    r2.lock().unwrap().push((now - at) as f64 * 1e-3);
                }
            }
        })
        .await
        .unwrap();
    let heard = Arc::new(AtomicU64::new(0));
    let h = heard.clone();
    let _sc = match &c {
        Some(c) => Some(
            c.declare_subscriber("repro/**")
                .callback(move |_| {
                    h.fetch_add(1, Ordering::Relaxed);
                })
                .await
                .unwrap(),
        ),
        None => None,
    };
    tokio::time::sleep(Duration::from_millis(500)).await;

    let state = control(&a, "repro/state");
    let status = a
        .declare_publisher("repro/status")
        .congestion_control(CongestionControl::Block)
        .wait()
        .unwrap();
    let period = Duration::from_secs_f64(1.0 / o.rate);
    let (seconds, rate) = (o.seconds, o.rate);
    let sent = tokio::task::spawn_blocking(move || {
        let start = Instant::now();
        let mut k = 0usize;
        while start.elapsed().as_secs_f64() < seconds && k + 1 < n {
            k += 1;
            let due = start + period * k as u32;
            if let Some(d) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(d);
            }
            let mut msg = [0u8; 49];
            msg[..8].copy_from_slice(&(k as u64).to_le_bytes());
            sent_at[k].store(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
            let _ = state.put(msg.to_vec()).wait();
            if k.is_multiple_of((rate / 10.0).max(1.0) as usize) {
                let _ = status.put(vec![0u8; 64]).wait();
            }
        }
        k
    })
    .await
    .unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;

    let flaps = a_saw_b_gone.load(Ordering::Relaxed) + b_saw_a_gone.load(Ordering::Relaxed);
    let mut v = rtt.lock().unwrap().clone();
    v.sort_unstable_by(f64::total_cmp);
    println!(
        "run {i} ({proto}, {}, {} sessions besides the router, {seconds} s at {rate} Hz): flaps \
         {flaps} (a saw b gone {}, b saw a gone {}); states {sent}, answered {}, twice {}; rtt \
         p50 {:.0} p99 {:.0} max {:.0} us; c heard {}",
        if o.direct {
            "a-b direct"
        } else {
            "all via the router"
        },
        o.clients,
        a_saw_b_gone.load(Ordering::Relaxed),
        b_saw_a_gone.load(Ordering::Relaxed),
        v.len(),
        duplicates.load(Ordering::Relaxed),
        pct(&v, 0.5),
        pct(&v, 0.99),
        v.last().copied().unwrap_or(f64::NAN),
        heard.load(Ordering::Relaxed),
    );
    for s in [Some(a), Some(b), c, Some(router)].into_iter().flatten() {
        let _ = s.close().await;
    }
    flaps
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let o = parse();
    tilting_net::init_tracing("warn");
    let mut total = 0;
    let mut flapped = 0;
    for i in 0..o.runs {
        let f = run(&o, i).await;
        total += f;
        flapped += usize::from(f > 0);
    }
    println!(
        "{} of {} runs flapped, {total} flaps in all",
        flapped, o.runs
    );
}
