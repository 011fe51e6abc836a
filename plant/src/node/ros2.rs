//! `--ros2 [zenoh|dds|both]`: the plant as a ROS 2 node (`tilting_ros2`): the mirror of its
//! topics, fed by the loop through a queue it never waits on (one thread publishing on each
//! route chosen), and `/<robot>/effort_command` on each route, whose valid commands enter the
//! same torque inbox as the controller's, as answers to the state their source timestamp
//! follows.

use super::*;
use tilting_ros2::mirror::{EffortCounts, MirrorTx, Sink};
use tilting_ros2::node::{EffortInput, Mirror, RosNode};
use tilting_ros2::robot::{answered_seq, EffortCommand, EffortLimits, FloodGate};
use tilting_ros2::Route;

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
    route: Route,
    domain: u32,
    effort: Option<EffortInput>,
    #[cfg(feature = "dds")]
    dds: Option<dds::Dds>,
    _node: Option<RosNode>,
}

/// What `--ros2` did, in the plant's summary.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Ros2Summary {
    /// The route: zenoh, dds or both (absent in summaries from before there was a choice).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub route: String,
    /// ROS 2 domain id.
    pub domain: u32,
    /// Inputs (states, events, statuses) handed to the mirror.
    pub mirror_sent: u64,
    /// Inputs dropped because the mirror's queue was full.
    pub mirror_dropped: u64,
    /// `/<robot>/effort_command` over zenoh, by outcome (zeros when the route is dds).
    pub effort: EffortCounts,
    /// `/<robot>/effort_command` over DDS, by outcome (absent unless the route is dds or both).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effort_dds: Option<EffortCounts>,
}

/// The bounds and the flood gate of `effort_command` from the plant's flags: `--max-torque`,
/// and an age of at most `max(--max-age, 1)` periods (lockstep: `--lockstep-timeout-ms`) either
/// way of the wall clock.
fn effort_rules(args: &PlantArgs) -> (EffortLimits, FloodGate) {
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
    let rate = match args.clock {
        ClockMode::Realtime => FLOOD_RATE,
        ClockMode::Lockstep => FLOOD_RATE_LOCKSTEP,
    };
    (limits, FloodGate::new(rate, FLOOD_BURST))
}

/// What a valid command does: it enters the torque inbox as the answer to the newest state
/// published at or before its source timestamp.
fn on_command(shared: Arc<Shared>, period_ns: i64) -> impl Fn(EffortCommand) + Send + Sync {
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
    }
}

impl Ros2 {
    /// Declares the node `/<robot>/tilting_plant` on each route of `--ros2`, starts the mirror
    /// and subscribes to `effort_command` with the plant's bounds ([`effort_rules`]).
    pub(super) async fn start(
        session: &zenoh::Session,
        args: &PlantArgs,
        shared: Arc<Shared>,
    ) -> anyhow::Result<Ros2> {
        let route = args.ros2.unwrap_or_default();
        let domain = args.ros_domain()?;
        let robot = args.zenoh.robot.as_str();
        let period_ns = (args.period() * 1e9).round() as i64;
        let mut sinks: Vec<Box<dyn Sink>> = Vec::new();
        let (mut node, mut effort) = (None, None);
        if route.zenoh() {
            let n =
                RosNode::declare(session, domain, &format!("/{robot}"), "tilting_plant").await?;
            sinks.push(Box::new(Mirror::declare(&n, robot).await?));
            let (limits, gate) = effort_rules(args);
            effort = Some(
                EffortInput::subscribe(
                    &n,
                    robot,
                    limits,
                    gate,
                    on_command(shared.clone(), period_ns),
                )
                .await?,
            );
            node = Some(n);
        }
        #[cfg(feature = "dds")]
        let dds = match route.dds() {
            true => Some(dds::Dds::start(
                args,
                domain,
                &mut sinks,
                on_command(shared, period_ns),
            )?),
            false => None,
        };
        let mirror = tilting_ros2::mirror::spawn(sinks, MIRROR_QUEUE)
            .context("cannot start the ROS 2 mirror thread")?;
        Ok(Ros2 {
            mirror,
            route,
            domain,
            effort,
            #[cfg(feature = "dds")]
            dds,
            _node: node,
        })
    }

    pub(super) fn summary(&self) -> Ros2Summary {
        let c = self.mirror.counts();
        #[cfg(feature = "dds")]
        let effort_dds = self.dds.as_ref().map(|d| d.effort.counts());
        #[cfg(not(feature = "dds"))]
        let effort_dds = None;
        Ros2Summary {
            route: self.route.to_string(),
            domain: self.domain,
            mirror_sent: c.sent.load(Ordering::Relaxed),
            mirror_dropped: c.dropped.load(Ordering::Relaxed),
            effort: self.effort.as_ref().map(|e| e.counts()).unwrap_or_default(),
            effort_dds,
        }
    }
}

/// The URDF's geometry of a robot with parameters `p` (lengths in m, masses in kg, inertia in
/// kg m^2, `l_c` resolved) and the arm joint's effort limit `max_torque` (N m).
pub fn urdf_geometry(p: &crate::Params, max_torque: f64) -> tilting_ros2::urdf::Geometry {
    tilting_ros2::urdf::Geometry {
        f: p.f,
        l: p.l,
        l_c: p.lc(),
        m_f: p.m_f,
        m_l: p.m_l,
        i_l: p.i_l,
        max_torque,
    }
}

/// The DDS route (feature `dds`).
#[cfg(feature = "dds")]
mod dds {
    use super::*;
    use tilting_ros2::dds::{DdsEffortInput, DdsMirror, DdsNode, DiscoveryRange};

    /// The DDS node and its `effort_command` (the mirror is one of the mirror thread's sinks).
    pub(super) struct Dds {
        pub(super) effort: DdsEffortInput,
        _node: DdsNode,
    }

    impl Dds {
        /// Joins the domain within `ROS_AUTOMATIC_DISCOVERY_RANGE`, adds the DDS mirror (with
        /// the robot's URDF as `robot_description`) to `sinks` and subscribes to
        /// `effort_command`.
        pub(super) fn start(
            args: &PlantArgs,
            domain: u32,
            sinks: &mut Vec<Box<dyn Sink>>,
            on_command: impl Fn(EffortCommand) + Send + 'static,
        ) -> anyhow::Result<Dds> {
            let robot = args.zenoh.robot.as_str();
            let range = DiscoveryRange::from_env().map_err(anyhow::Error::msg)?;
            let mut node =
                DdsNode::new(domain as u16, range, &format!("/{robot}"), "tilting_plant")?;
            let p = args.sim_config()?.params;
            let geometry = super::urdf_geometry(&p, args.max_torque());
            let urdf = tilting_ros2::urdf::urdf(robot, &geometry);
            sinks.push(Box::new(DdsMirror::declare(&mut node, robot, &urdf)?));
            let (limits, gate) = effort_rules(args);
            let effort = DdsEffortInput::subscribe(&mut node, robot, limits, gate, on_command)?;
            tracing::info!("ROS 2 over DDS: domain {domain}, discovery {range:?}");
            Ok(Dds {
                effort,
                _node: node,
            })
        }
    }
}
