//! `tilting ros2 bridge` and `tilting ros2 urdf`: any robot on the network as a ROS 2 node in
//! rmw_zenoh's conventions (`tilting_ros2`, docs/ros2.md), and the robot's URDF from the
//! model's parameters.

use crate::out::print_stdout;
use crate::topics::{check_seconds, session_args};
use crate::LiveError;
use anyhow::{anyhow, Context as _};
use clap::{Args, Subcommand};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tilting_net::{DropCounter, Role, ZenohArgs};
use tilting_plant::ParamsArgs;
use tilting_proto::{ModeEvent, PlantState, Status, TorqueCommand};
use tilting_ros2::node::{Input, Mirror, RosNode};

/// `tilting ros2 ...`.
#[derive(Debug, Subcommand)]
pub enum Ros2Command {
    /// Mirror a robot already on the network as ROS 2 topics (/<robot>/joint_states,
    /// /<robot>/contact_mode, /rosout), like `record` does into a file, until Ctrl-C
    Bridge(BridgeArgs),
    /// The robot's URDF from the model's parameters (robot_state_publisher, rviz2, Foxglove)
    Urdf(UrdfArgs),
}

/// Flags of `tilting ros2 bridge`.
#[derive(Debug, Clone, Args)]
pub struct BridgeArgs {
    /// Robot name and zenoh endpoints (default: connect to tcp/127.0.0.1:7447).
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// ROS 2 domain id, 0 to 232 [default: ROS_DOMAIN_ID, else 0]
    #[arg(long, value_name = "0-232")]
    pub ros_domain: Option<u32>,
    /// Stop after this many seconds [default: until Ctrl-C]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub seconds: Option<f64>,
}

/// What `tilting ros2 bridge` printed at its end (one JSON object on stdout).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BridgeSummary {
    /// Messages received from the robot (state, event, status, torque) that decoded.
    pub received: u64,
    /// Inputs handed to the mirror.
    pub mirrored: u64,
    /// Inputs dropped because the mirror's queue was full.
    pub dropped: u64,
}

/// The bridge's subscriptions to robot `keys`: its states (sent to the mirror `tx` with the
/// controller's newest torque, N m, for the efforts), events and status (sent as they come),
/// and the torques (kept for the states); each message that decodes counts in `received`.
async fn subscribe_robot(
    session: &zenoh::Session,
    keys: &tilting_proto::Keys,
    tx: &tilting_ros2::node::MirrorTx,
    received: &Arc<AtomicU64>,
) -> anyhow::Result<Vec<zenoh::pubsub::Subscriber<()>>> {
    // The newest torque of the controller, for the efforts of joint_states.
    let tau = Arc::new(Mutex::new(None::<f64>));
    let mut subs = Vec::new();
    let (t, n) = (tx.clone(), received.clone());
    let tau2 = tau.clone();
    subs.push(
        tilting_net::subscribe_decoded(
            session,
            Arc::new(DropCounter::new(keys.plant_state())),
            move |s: PlantState| {
                n.fetch_add(1, Ordering::Relaxed);
                let tau = *tau2.lock().unwrap_or_else(|e| e.into_inner());
                t.send(Input::State(s, tau));
            },
        )
        .await?,
    );
    let (t, n) = (tx.clone(), received.clone());
    subs.push(
        tilting_net::subscribe_decoded(
            session,
            Arc::new(DropCounter::new(keys.plant_event())),
            move |e: ModeEvent| {
                n.fetch_add(1, Ordering::Relaxed);
                t.send(Input::Event(e));
            },
        )
        .await?,
    );
    let (t, n) = (tx.clone(), received.clone());
    subs.push(
        tilting_net::subscribe_decoded(
            session,
            Arc::new(DropCounter::new(keys.plant_status())),
            move |s: Status| {
                n.fetch_add(1, Ordering::Relaxed);
                t.send(Input::Status(s));
            },
        )
        .await?,
    );
    let n = received.clone();
    subs.push(
        tilting_net::subscribe_decoded(
            session,
            Arc::new(DropCounter::new(keys.controller_torque())),
            move |c: TorqueCommand| {
                n.fetch_add(1, Ordering::Relaxed);
                *tau.lock().unwrap_or_else(|e| e.into_inner()) = Some(c.tau);
            },
        )
        .await?,
    );
    Ok(subs)
}

/// `tilting ros2 bridge`.
pub fn bridge(args: &BridgeArgs) -> Result<(), LiveError> {
    tilting_net::init_tracing("warn");
    check_seconds("--seconds", args.seconds)?;
    let keys = session_args(&args.zenoh)?;
    // One rule with the plant's `--ros2`: the flag, else ROS_DOMAIN_ID, else 0 (0 to 232).
    let env = std::env::var("ROS_DOMAIN_ID").ok();
    let domain = tilting_ros2::domain_id(args.ros_domain, env.as_deref())
        .map_err(|e| LiveError::Usage(anyhow!(e)))?;
    tilting_ros2::robot::Topics::new(keys.robot()).map_err(|e| LiveError::Usage(anyhow!(e)))?;
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    let summary = rt
        .block_on(async {
            let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
            let robot = keys.robot();
            let node =
                RosNode::declare(&session, domain, &format!("/{robot}"), "tilting_bridge").await?;
            let tx = Mirror::declare(&node, robot).await?.spawn(256)?;
            let received = Arc::new(AtomicU64::new(0));
            let subs = subscribe_robot(&session, &keys, &tx, &received).await?;
            eprintln!(
                "ros2 bridge: tilting/{robot}/** as /{robot}/joint_states, /{robot}/contact_mode \
                 and /rosout in ROS domain {} (Ctrl-C stops)",
                domain
            );
            let end = args
                .seconds
                .map(|s| Instant::now() + Duration::from_secs_f64(s));
            let mut stop = std::pin::pin!(tilting_net::shutdown_signal());
            while end.is_none_or(|e| Instant::now() < e) {
                tokio::select! {
                    _ = &mut stop => break,
                    _ = tokio::time::sleep(Duration::from_millis(100)) => {}
                }
            }
            drop(subs);
            let c = tx.counts();
            let summary = BridgeSummary {
                received: received.load(Ordering::Relaxed),
                mirrored: c.sent.load(Ordering::Relaxed),
                dropped: c.dropped.load(Ordering::Relaxed),
            };
            drop(tx);
            drop(node);
            let _ = session.close().await;
            anyhow::Ok(summary)
        })
        .map_err(LiveError::Failed)?;
    print_stdout(
        &(serde_json::to_string(&summary).map_err(|e| LiveError::Failed(anyhow!(e)))? + "\n"),
    )
}

/// Flags of `tilting ros2 urdf`.
#[derive(Debug, Clone, Args)]
pub struct UrdfArgs {
    /// The model's parameter file.
    #[command(flatten)]
    pub params: ParamsArgs,
    /// The robot's name in the URDF
    #[arg(long, default_value = tilting_proto::keys::DEFAULT_ROBOT)]
    pub name: String,
    /// The arm joint's effort limit (N m) [default: the plant's --max-torque default]
    #[arg(long, value_name = "NM")]
    pub max_torque: Option<f64>,
    /// Write the URDF here [default: stdout]
    #[arg(long, value_name = "FILE.urdf")]
    pub out: Option<PathBuf>,
}

/// The URDF's geometry from the model's parameters (`l_c` resolved, the plant's torque bound):
/// the plant's `--ros2` and `tilting ros2 urdf` describe one robot alike.
pub use tilting_plant::node::urdf_geometry as geometry;

/// `tilting ros2 urdf`.
pub fn urdf(args: &UrdfArgs) -> Result<(), LiveError> {
    let p = args
        .params
        .params()
        .map_err(|e| LiveError::Usage(e.into()))?;
    let tau = args
        .max_torque
        .unwrap_or(tilting_plant::node::DEFAULT_MAX_TORQUE);
    if !(tau.is_finite() && tau > 0.0) {
        return Err(LiveError::Usage(anyhow!(
            "invalid `--max-torque` = {tau}: must be a positive number of N m"
        )));
    }
    tilting_ros2::names::validate_ros_name(&args.name)
        .map_err(|e| LiveError::Usage(anyhow!("--name: {e}")))?;
    let text = tilting_ros2::urdf::urdf(&args.name, &geometry(&p, tau));
    match &args.out {
        Some(path) => std::fs::write(path, text)
            .with_context(|| format!("cannot write --out {}", path.display()))
            .map_err(LiveError::Failed),
        None => print_stdout(&text),
    }
}
