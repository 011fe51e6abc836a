//! The plant's deadline misses under a flood of spoofed messages, before and after access
//! control (a benchmark, not a test):
//!
//! ```sh
//! cargo run --release -p tilting-tests --features bench --example flood_bench -- --seconds 5
//! ```
//!
//! Five real-time runs at 1 kHz of `tilting-plant` and `tilting-controller` as processes, each
//! `--seconds` long:
//!
//! 1. **open, quiet**: the default topology (loopback peers, no authentication);
//! 2. **open, flood**: the same, with a flooder peer that publishes, as fast as zenoh takes
//!    them, spoofed plausible states, torques answering future states, absurd torques (1e9 N m)
//!    and undecodable payloads on the state and torque keys: all of it reaches the plant and
//!    the controller, which refuse it by their rules;
//! 3. **secure, quiet**: the deployed topology of `live --secure`, with the flags
//!    `tilting::security::session_flags` gives `live` (the direct TLS loop between the plant
//!    and the controller, each with its own access control, beside a `tilting-router` with
//!    mutual TLS and access control);
//! 4. **secure, flood via router**: the same flooder, holding a valid certificate of the wrong
//!    identity (the logger's), a client of the router: the router drops its puts at ingress;
//! 5. **secure, flood at plant**: the same flooder dialling the plant's own TLS endpoint: the
//!    plant's own access control drops its puts.
//!
//! For each run it prints the deadline-miss rate of the plant (misses / periods), what the
//! plant and the controller received, and how many messages the flooder sent.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use tilting_proto::{codec, Keys, PlantState, TorqueCommand};
use tilting_tests::*;

struct Outcome {
    steps: u64,
    misses: u64,
    plant_torques: u64,
    plant_dropped: u64,
    plant_stale: u64,
    plant_foreign: u64,
    ctl_states: u64,
    flood_sent: u64,
}

/// Publishes spoofed and invalid states and torques until `stop`; returns the count.
async fn flood(c: Client, stop: Arc<AtomicBool>, sent: Arc<AtomicU64>) {
    let k = c.keys.clone();
    let state_pub = c
        .session
        .declare_publisher(k.plant_state().to_owned())
        .await
        .unwrap();
    let torque_pub = c
        .session
        .declare_publisher(k.controller_torque().to_owned())
        .await
        .unwrap();
    let mut i: u64 = 0;
    while !stop.load(Ordering::Relaxed) {
        i += 1;
        let state = codec::encode(&PlantState {
            seq: i % 5000,
            time: 0.1,
            alpha: 0.0,
            beta: 1.5,
            alpha_dot: Some(0.0),
            beta_dot: Some(0.3),
            mode: 0,
        });
        let future = codec::encode(&TorqueCommand {
            seq: 1_000_000 + i,
            tau: 12.345,
        });
        let absurd = codec::encode(&TorqueCommand {
            seq: i % 5000,
            tau: 1e9,
        });
        let _ = state_pub.put(state).await;
        let _ = torque_pub.put(future).await;
        let _ = torque_pub.put(absurd).await;
        let _ = torque_pub.put(vec![1u8, 2, 3]).await;
        let _ = state_pub.put(vec![4u8; 7]).await;
        sent.fetch_add(5, Ordering::Relaxed);
        if i.is_multiple_of(64) {
            tokio::task::yield_now().await;
        }
    }
    let _ = c.session.close().await;
}

/// Where the flooder is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Flood {
    None,
    /// A client of the router (secure) or a peer of the plant (open).
    Router,
    /// Dialling the plant's own endpoint (secure).
    Plant,
}

async fn run(secure: bool, flooding: Flood, seconds: f64, tag: &str) -> Outcome {
    let dir = Scratch::new(tag);
    let robot = robot(tag);
    let keys = Keys::new(&robot).unwrap();
    let (plant_bin, ctl_bin) = (bin("tilting-plant"), bin("tilting-controller"));
    let duration = seconds.to_string();
    let certs = dir.path().join("certs");
    let mut router = None;
    let robot_flags = ["--robot".to_owned(), robot.clone()];
    // (plant's flags, controller's flags, router's endpoint, plant's endpoint)
    let (plant_flags, ctl_flags, router_ep, plant_ep) = if secure {
        tilting::security::generate(&keys, &certs, &[], "tls/127.0.0.1:7447", &[]).unwrap();
        let ep = format!("tls/127.0.0.1:{}", free_port());
        let plant_ep = format!("tls/127.0.0.1:{}", free_port());
        router = Some(start_router(dir.path(), &certs, &ep));
        let flags = |node: &str| -> Vec<String> {
            let mut v = robot_flags.to_vec();
            // No front door here: the loop's two nodes and the router.
            v.extend(tilting::security::session_flags(
                &certs, node, &plant_ep, &ep, None,
            ));
            v
        };
        (
            flags("plant"),
            flags("controller"),
            ep.clone(),
            plant_ep.clone(),
        )
    } else {
        let port = free_port();
        (
            plant_args(&robot, port, &[]),
            peer_args(&robot, port, &[]),
            endpoint(port),
            endpoint(port),
        )
    };
    let mut plant_flags = plant_flags;
    plant_flags.extend(["--duration".into(), duration]);
    let mut plant = Proc::spawn("plant", &plant_bin, &plant_flags, dir.path());
    let mut ctl = Proc::spawn("controller", &ctl_bin, &ctl_flags, dir.path());
    let stop = Arc::new(AtomicBool::new(false));
    let sent = Arc::new(AtomicU64::new(0));
    let flooder = if flooding != Flood::None {
        // Once the plant listens (the secure plant's own endpoint refuses a client before).
        let t0 = std::time::Instant::now();
        while !plant.stderr().contains("plant running") && t0.elapsed().as_secs() < 30 {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let c = if secure {
            let to = if flooding == Flood::Plant {
                &plant_ep
            } else {
                &router_ep
            };
            Client::open_config(&robot, &certs.join("logger.json5"), to).await
        } else {
            let port: u16 = plant_ep.rsplit(':').next().unwrap().parse().unwrap();
            Client::open(&robot, None, Some(port)).await
        };
        Some(tokio::spawn(flood(c, stop.clone(), sent.clone())))
    } else {
        None
    };
    let status =
        tokio::task::block_in_place(|| plant.expect_exit(Duration::from_secs_f64(seconds + 60.0)));
    stop.store(true, Ordering::Relaxed);
    if let Some(f) = flooder {
        let _ = f.await;
    }
    let _ = tokio::task::block_in_place(|| ctl.interrupt(Duration::from_secs(10)));
    if let Some(r) = router.as_mut() {
        r.signal(libc::SIGINT);
        let _ = tokio::task::block_in_place(|| r.wait_timeout(Duration::from_secs(10)));
    }
    assert!(
        status.success() || status.code() == Some(3),
        "{}",
        plant.logs()
    );
    let p = plant.plant_summary();
    let c = ctl.controller_summary();
    Outcome {
        steps: p.steps,
        misses: p.deadline_misses,
        plant_torques: p.torques_received,
        plant_dropped: p.torques_dropped,
        plant_stale: p.torques_stale,
        plant_foreign: p.torques_foreign,
        ctl_states: c.states_received,
        flood_sent: sent.load(Ordering::Relaxed),
    }
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let mut seconds = 5.0;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seconds" => {
                seconds = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .filter(|s: &f64| (1.0..=600.0).contains(s))
                    .expect("--seconds: 1 to 600")
            }
            other => panic!("unknown flag {other}; usage: flood_bench [--seconds S]"),
        }
    }
    println!(
        "{:<26} {:>8} {:>8} {:>8} {:>12} {:>10} {:>10} {:>10} {:>12} {:>12}",
        "run",
        "periods",
        "misses",
        "miss %",
        "plant torq",
        "dropped",
        "stale",
        "foreign",
        "ctl states",
        "flood sent"
    );
    for (i, (secure, flooding, name)) in [
        (false, Flood::None, "open, quiet"),
        (false, Flood::Router, "open, flood"),
        (true, Flood::None, "secure, quiet"),
        (true, Flood::Router, "secure, flood via router"),
        (true, Flood::Plant, "secure, flood at plant"),
    ]
    .into_iter()
    .enumerate()
    {
        let o = run(secure, flooding, seconds, &format!("flood{i}")).await;
        println!(
            "{:<26} {:>8} {:>8} {:>8.2} {:>12} {:>10} {:>10} {:>10} {:>12} {:>12}",
            name,
            o.steps,
            o.misses,
            100.0 * o.misses as f64 / o.steps.max(1) as f64,
            o.plant_torques,
            o.plant_dropped,
            o.plant_stale,
            o.plant_foreign,
            o.ctl_states,
            o.flood_sent
        );
    }
}
