//! A controller node of your own: answer every `PlantState` with a `TorqueCommand` of the same
//! `seq`. This one holds the arm upright with a computed-torque PD (no tilting: compare with
//! `tilting-controller`, whose energy adaptation keeps the plate tilting). Replace `law` with
//! yours.
//!
//! ```sh
//! ./target/release/tilting-plant --duration 5 &          # listens on tcp/127.0.0.1:7447
//! cargo run --release -p tilting-examples --example custom_controller
//! ```
//!
//! The plant starts its clock when this node's liveliness token appears (or when its first
//! state is answered), so declare the token once the subscriber is in place.

use clap::Parser;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tilting_controller::{ComputedTorque, ControlConfig, LawSpec};
use tilting_net::{subscribe_decoded, DropCounter, Qos, Role, TypedPublisher, ZenohArgs};
use tilting_plant::State;
use tilting_proto::{PlantState, TorqueCommand};

#[derive(Parser)]
struct Args {
    /// Robot name, endpoints (default: connect to a plant on tcp/127.0.0.1:7447).
    #[command(flatten)]
    zenoh: ZenohArgs,
    /// Stiffness of the holding PD (1/s^2)
    #[arg(long, default_value_t = 25.0)]
    kp: f64,
    /// Damping of the holding PD (1/s)
    #[arg(long, default_value_t = 10.0)]
    kd: f64,
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let keys = args.zenoh.keys()?;
    // The law: beta_ddot = kd (0 - beta_dot) + kp (pi/2 - beta), made exact in every contact
    // mode by the inverse dynamics of the model.
    let law = ComputedTorque::new(ControlConfig {
        law: LawSpec {
            kp: args.kp,
            kd: args.kd,
            ..LawSpec::without_adaptation()
        },
        ..ControlConfig::default()
    })?;

    let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
    let torque = Arc::new(
        TypedPublisher::<TorqueCommand>::declare(&session, keys.controller_torque(), Qos::Control)
            .await?,
    );
    let answered = Arc::new(AtomicU64::new(0));
    let (t, n) = (torque.clone(), answered.clone());
    let _sub = subscribe_decoded(
        &session,
        Arc::new(DropCounter::new(keys.plant_state())),
        move |s: PlantState| {
            // Decoded and validated: the mode byte is in range, every float finite.
            let Ok(mode) = s.mode() else { return };
            // A state without rates (`--measure angles`) needs an estimator
            // (`tilting_controller::Estimation`); this example answers full states only.
            let Some(x) = s.x() else { return };
            let tau = law.torque(s.time, mode, &State::from(x));
            if tau.is_finite() && t.put(&TorqueCommand { seq: s.seq, tau }).is_ok() {
                n.fetch_add(1, Ordering::Relaxed);
            }
        },
    )
    .await?;
    let _token = tilting_net::declare_token(&session, keys.alive_controller()).await?;
    println!("answering {} (Ctrl-C stops)", keys.plant_state());
    tilting_net::shutdown_signal().await;
    println!("answered {} states", answered.load(Ordering::Relaxed));
    Ok(())
}
