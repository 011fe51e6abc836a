//! `--ros2`: the plant as a ROS 2 node (`tilting_ros2`): the mirror of its topics, fed by the
//! loop through a queue it never waits on, and `/<robot>/effort_command`, whose valid commands
//! enter the same torque inbox as the controller's, as answers to the state their source
//! timestamp follows.

use super::*;
use tilting_ros2::node::{EffortCounts, EffortInput, Mirror, MirrorTx, RosNode};
use tilting_ros2::robot::{answered_seq, EffortLimits, FloodGate};

/// Inputs the mirror's queue holds (about 0.25 s of states at 1 kHz with their events).
const MIRROR_QUEUE: usize = 256;

/// The flood gate in real time: commands per second on average (four per period at 1 kHz).
pub(super) const FLOOD_RATE: u32 = 4000;
/// The flood gate in lockstep, where a fast controller runs the loop faster than real time
/// (about 4,500 periods per second here over ROS 2): only a bound on the callback's work.
pub(super) const FLOOD_RATE_LOCKSTEP: u32 = 100_000;
/// Burst of the flood gate.
pub(super) const FLOOD_BURST: u32 = 16;

/// The ROS 2 side of a plant.
pub(super) struct Ros2 {
    pub(super) mirror: MirrorTx,
    effort: EffortInput,
    _node: RosNode,
}

/// What `--ros2` did, in the plant's summary.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Ros2Summary {
    /// ROS 2 domain id.
    pub domain: u32,
    /// Inputs (states, events, statuses) handed to the mirror.
    pub mirror_sent: u64,
    /// Inputs dropped because the mirror's queue was full.
    pub mirror_dropped: u64,
    /// `/<robot>/effort_command`, by outcome.
    pub effort: EffortCounts,
}

impl Ros2 {
    /// Declares the node `/<robot>/tilting_plant`, starts the mirror and subscribes to
    /// `effort_command` with the plant's bounds: `--max-torque`, and an age of at most
    /// `max(--max-age, 1)` periods (lockstep: `--lockstep-timeout-ms`) either way of the wall
    /// clock.
    pub(super) async fn start(
        session: &zenoh::Session,
        args: &PlantArgs,
        shared: Arc<Shared>,
    ) -> anyhow::Result<Ros2> {
        let robot = args.zenoh.robot.as_str();
        let node = RosNode::declare(
            session,
            args.ros_domain,
            &format!("/{robot}"),
            "tilting_plant",
        )
        .await?;
        let mirror = Mirror::declare(&node, robot)
            .await?
            .spawn(MIRROR_QUEUE)
            .context("cannot start the ROS 2 mirror thread")?;
        let period_ns = (args.period() * 1e9).round() as i64;
        // Real time: the age rule's `--max-age` periods; lockstep: the wait for an answer.
        let window = match args.clock {
            ClockMode::Realtime => period_ns.saturating_mul(args.max_age.max(1) as i64),
            ClockMode::Lockstep => (args.lockstep_timeout_ms as i64).saturating_mul(1_000_000),
        };
        let limits = EffortLimits {
            max_torque: args.max_torque(),
            max_age_ns: window,
            max_lead_ns: window,
        };
        let effort = EffortInput::subscribe(
            &node,
            robot,
            limits,
            FloodGate::new(
                match args.clock {
                    ClockMode::Realtime => FLOOD_RATE,
                    ClockMode::Lockstep => FLOOD_RATE_LOCKSTEP,
                },
                FLOOD_BURST,
            ),
            move |cmd| {
                let seq = answered_seq(
                    cmd.attachment.source_timestamp_ns,
                    shared.current_seq.load(Ordering::Acquire),
                    shared.published_wall_ns.load(Ordering::Acquire),
                    period_ns,
                );
                shared.on_torque_command(
                    TorqueCommand { seq, tau: cmd.tau },
                    super::inbox::Ingress::Ros2,
                );
            },
        )
        .await?;
        Ok(Ros2 {
            mirror,
            effort,
            _node: node,
        })
    }

    pub(super) fn summary(&self, domain: u32) -> Ros2Summary {
        let c = self.mirror.counts();
        Ros2Summary {
            domain,
            mirror_sent: c.sent.load(Ordering::Relaxed),
            mirror_dropped: c.dropped.load(Ordering::Relaxed),
            effort: self.effort.counts(),
        }
    }
}
