//! Subscribe to a robot's state over zenoh and print one line per second: the plant's (or a
//! real robot's) `PlantState`, decoded and validated by the wire codec.
//!
//! Start a plant (or `tilting live`), then:
//!
//! ```sh
//! cargo run --release -p tilting-examples --example state_subscriber -- --connect tcp/127.0.0.1:7447
//! ```

use clap::Parser;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tilting_net::{subscribe_decoded, DropCounter, Role, ZenohArgs};
use tilting_proto::PlantState;

#[derive(Parser)]
struct Args {
    /// Robot name, endpoints (default: connect to a plant on tcp/127.0.0.1:7447).
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// Stop after this many seconds
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let keys = args.zenoh.keys()?;
    let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
    // The counter counts every payload on the key and the ones that do not decode or validate.
    let counter = Arc::new(DropCounter::new(keys.plant_state()));
    let latest: Arc<Mutex<Option<PlantState>>> = Arc::default();
    let l = latest.clone();
    let _sub = subscribe_decoded(&session, counter.clone(), move |s: PlantState| {
        *l.lock().unwrap() = Some(s); // runs on a zenoh thread: keep it short
    })
    .await?;
    println!("listening on {}", keys.plant_state());
    let mut left = args.seconds;
    while left > 0.0 {
        tokio::time::sleep(Duration::from_secs(1)).await;
        left -= 1.0;
        match *latest.lock().unwrap() {
            Some(s) => println!(
                "seq {:>7}  t {:8.3} s  {:<5}  alpha {:+.5} rad  beta {:.5} rad  ({} received, {} invalid)",
                s.seq,
                s.time,
                s.mode().map_or("?", |m| m.as_str()),
                s.alpha,
                s.beta,
                counter.received(),
                counter.dropped()
            ),
            None => println!("no state yet"),
        }
    }
    session.close().await.map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
