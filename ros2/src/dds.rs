//! The robot's ROS 2 topics over DDS, so a stock ROS 2 (rmw_fastrtps, rmw_cyclonedds, with no
//! RMW change) sees and drives it: the same topics, types, QoS and checks as the zenoh mirror
//! ([`crate::node`]), plus `robot_description`, on RustDDS through Atostek's `ros2-client`
//! (its node appears in `ros2 node list`: it publishes `ros_discovery_info`).
//!
//! Build cost, measured 2026-11-28 on the shared 2-core VM (load average about 3.5), cold release
//! builds in an empty target directory: `tilting-ros2` alone 62 s wall (86 s CPU); then with
//! `--features dds` 84 s wall (81 s CPU) more, for 39 crates more (`rustdds`, `ros2-client`,
//! `speedy`, `netdev`, `netlink-*`, `nix`, `chrono`, ...). `ros2-client` alone, cold, with its 101
//! crates: 153 s wall (134 s CPU).
//!
//! Why `ros2-client` and not its zenoh backend in place of [`crate::node`]: its zenoh feature
//! pulls `zenoh` and `zenoh-ext` as `zenoh = "1"` with the `unstable` feature, which would
//! unify with (and so change) the workspace's zenoh build, and it opens its own session
//! (`zenoh::ContextOptions`): the plant's mirror would no longer share the plant's session, its
//! ACL (`--secure`) and its endpoints. What we hand-wrote (keys, tokens, the 33-byte attachment,
//! GIDs) is ~700 lines that tests hold to rmw_zenoh's rules; it stays.

use crate::mirror::{dds_attachment, wall_ns, EffortCounts, EffortJudge, Input, Sink};
use crate::msgs::{Float64MultiArray, JointState, Log, UInt8};
use crate::robot::{self, check_command, EffortCommand, EffortLimits, FloodGate, Refusal, Topics};
use futures::StreamExt;
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::dds::{Context, Node, Publisher, Subscription};
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{MessageTypeName, Name, NodeName, NodeOptions, QosProfile};
use std::net::{IpAddr, Ipv4Addr};
use std::sync::Arc;
use std::time::Duration;

/// How far discovery reaches: ROS 2's `ROS_AUTOMATIC_DISCOVERY_RANGE` (Jazzy and later).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiscoveryRange {
    /// Other hosts on the subnet too (multicast on every interface): ROS 2's default.
    Subnet,
    /// This host only: discovery and data over the loopback interface (127.0.0.1).
    Localhost,
}

/// The environment variable of [`DiscoveryRange`].
pub const RANGE_ENV: &str = "ROS_AUTOMATIC_DISCOVERY_RANGE";

impl DiscoveryRange {
    /// The range `ROS_AUTOMATIC_DISCOVERY_RANGE` = `value` names (unset, empty and
    /// `SYSTEM_DEFAULT` are the default, `SUBNET`); with it unset, `ROS_LOCALHOST_ONLY=1`
    /// (before Jazzy) is `LOCALHOST`. `OFF` is refused: it would hide the robot from every
    /// other process.
    pub fn parse(value: Option<&str>, localhost_only: Option<&str>) -> Result<Self, String> {
        match value.map(str::trim) {
            None | Some("") if localhost_only.map(str::trim) == Some("1") => Ok(Self::Localhost),
            None | Some("") | Some("SYSTEM_DEFAULT") | Some("SUBNET") => Ok(Self::Subnet),
            Some("LOCALHOST") => Ok(Self::Localhost),
            Some("OFF") => Err(format!(
                "{RANGE_ENV}=OFF would let no other process discover the robot; allowed with \
                 --ros2 dds: SUBNET, LOCALHOST, SYSTEM_DEFAULT or unset"
            )),
            Some(other) => Err(format!(
                "invalid {RANGE_ENV} = {other:?}: allowed SUBNET, LOCALHOST, OFF, \
                 SYSTEM_DEFAULT or unset"
            )),
        }
    }

    /// The range the environment names.
    pub fn from_env() -> Result<Self, String> {
        let var = |k: &str| std::env::var(k).ok();
        Self::parse(
            var(RANGE_ENV).as_deref(),
            var("ROS_LOCALHOST_ONLY").as_deref(),
        )
    }
}

/// QoS of `joint_states` and `contact_mode`: reliable, volatile, keep last 10.
pub const STATE_QOS: QosProfile = QosProfile::publisher_default()
    .reliability(Reliability::Reliable {
        when_full: WhenFull::Wait(Duration::from_millis(10)),
    })
    .history(History::KeepLast { depth: 10 });
/// QoS of `/rosout`: rcl's (reliable, transient local, keep last 1000, lifespan 10 s).
pub const ROSOUT_QOS: QosProfile = QosProfile::publisher_default()
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 1000 })
    .lifespan(Some(Duration::from_secs(10)));
/// QoS of `robot_description`: robot_state_publisher's (reliable, transient local, keep last 1),
/// so rviz2 or a late `ros2 topic echo --qos-durability transient_local` gets the URDF.
pub const DESCRIPTION_QOS: QosProfile = QosProfile::publisher_default()
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 1 });
/// QoS of the `effort_command` subscription: best effort, keep last 1 (matches any writer).
pub const EFFORT_QOS: QosProfile = QosProfile::subscription_default();

fn err(what: &str, e: impl std::fmt::Debug) -> anyhow::Error {
    anyhow::anyhow!("ROS 2 over DDS: {what}: {e:?}")
}

/// A ROS 2 node on a DDS domain participant of its own.
pub struct DdsNode {
    context: Context,
    node: Node,
    domain: u16,
}

impl DdsNode {
    /// Joins DDS domain `domain` (0 to 232) within `range` as node `name` in `namespace`.
    pub fn new(
        domain: u16,
        range: DiscoveryRange,
        namespace: &str,
        name: &str,
    ) -> Result<DdsNode, anyhow::Error> {
        anyhow::ensure!(
            domain <= 232,
            "invalid ROS 2 domain = {domain}: allowed 0 to 232"
        );
        let mut b = DomainParticipantBuilder::new(domain);
        if range == DiscoveryRange::Localhost {
            b = b.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        // RustDDS starts its event loop and discovery threads inside `build`, and a Linux
        // thread inherits the nice value of the thread that creates it: built on a thread at
        // the mirror's lower priority, they yield the cores to the loop's threads (nice 0)
        // under contention, as the mirror thread does. Measured on a `live --ros2 dds` run
        // with an rclpy subscriber: the participant's event loop took about 3.5 % of a core
        // at 1 kHz, the mirror thread 2 %.
        let participant = std::thread::scope(|s| {
            s.spawn(|| {
                crate::mirror::lower_priority();
                b.build()
            })
            .join()
        })
        .map_err(|_| anyhow::anyhow!("cannot create the DDS participant: its thread panicked"))?
        .map_err(|e| err("cannot create the DDS participant", e))?;
        let context = Context::from_domain_participant(participant)
            .map_err(|e| err("cannot create the ROS 2 context", e))?;
        let node = context
            .new_node(
                NodeName::new(namespace, name).map_err(|e| err("node name", e))?,
                NodeOptions::new().enable_rosout(false),
            )
            .map_err(|e| err("cannot create the node", e))?;
        Ok(DdsNode {
            context,
            node,
            domain,
        })
    }

    /// The domain id.
    pub fn domain(&self) -> u16 {
        self.domain
    }

    fn topic(
        &mut self,
        topic: &str,
        ty: (&str, &str),
        qos: &QosProfile,
    ) -> Result<ros2_client::dds::rustdds::Topic, anyhow::Error> {
        if topic == "/rosout" {
            return Ok(self.context.get_rosout_topic());
        }
        let (ns, base) = topic.rsplit_once('/').unwrap_or(("/", topic));
        let ns = if ns.is_empty() { "/" } else { ns };
        let name = Name::new(ns, base).map_err(|e| err(&format!("topic {topic}"), e))?;
        self.node
            .create_topic(&name, MessageTypeName::new(ty.0, ty.1), qos)
            .map_err(|e| err(&format!("cannot create topic {topic}"), e))
    }

    /// A publisher of `T` (ROS type `ty` = (package, name)) on `topic`.
    pub fn publisher<T: serde::Serialize>(
        &mut self,
        topic: &str,
        ty: (&str, &str),
        qos: QosProfile,
    ) -> Result<Publisher<T>, anyhow::Error> {
        let t = self.topic(topic, ty, &qos)?;
        self.node
            .create_publisher(&t, Some(qos))
            .map_err(|e| err(&format!("cannot publish on {topic}"), e))
    }

    /// A subscription of `T` (ROS type `ty`) on `topic`.
    pub fn subscription<T: 'static>(
        &mut self,
        topic: &str,
        ty: (&str, &str),
        qos: QosProfile,
    ) -> Result<Subscription<T>, anyhow::Error> {
        let t = self.topic(topic, ty, &qos)?;
        self.node
            .create_subscription(&t, Some(qos))
            .map_err(|e| err(&format!("cannot subscribe to {topic}"), e))
    }
}

/// The robot's topics over DDS: `joint_states`, `contact_mode`, `/rosout`, and
/// `robot_description` (published once, kept for late joiners).
pub struct DdsMirror {
    robot: String,
    joint_states: Publisher<JointState>,
    contact_mode: Publisher<UInt8>,
    rosout: Publisher<Log>,
    _description: Publisher<String>,
    run_state: Option<u8>,
}

impl DdsMirror {
    /// Declares the publishers on `node` for `robot` and publishes `urdf` on
    /// `/<robot>/robot_description`.
    pub fn declare(node: &mut DdsNode, robot: &str, urdf: &str) -> Result<Self, anyhow::Error> {
        let t = Topics::new(robot).map_err(anyhow::Error::msg)?;
        let description: Publisher<String> = node.publisher(
            &format!("/{robot}/robot_description"),
            ("std_msgs", "String"),
            DESCRIPTION_QOS,
        )?;
        description
            .publish(urdf.to_owned())
            .map_err(|e| err("robot_description", e.to_string()))?;
        Ok(DdsMirror {
            robot: robot.to_owned(),
            joint_states: node.publisher(
                &t.joint_states,
                ("sensor_msgs", "JointState"),
                STATE_QOS,
            )?,
            contact_mode: node.publisher(&t.contact_mode, ("std_msgs", "UInt8"), STATE_QOS)?,
            rosout: node.publisher(&t.rosout, ("rcl_interfaces", "Log"), ROSOUT_QOS)?,
            _description: description,
            run_state: None,
        })
    }
}

impl Sink for DdsMirror {
    fn publish(&mut self, input: &Input) -> bool {
        let r = match input {
            Input::State(s, tau) => self
                .joint_states
                .publish(robot::joint_state(s, *tau))
                .map_err(|e| e.to_string())
                .and_then(|()| {
                    self.contact_mode
                        .publish(UInt8 { data: s.mode })
                        .map_err(|e| e.to_string())
                }),
            Input::Event(e) => self
                .rosout
                .publish(robot::event_log(&self.robot, e, wall_ns()))
                .map_err(|e| e.to_string()),
            Input::Status(s) => {
                let line = robot::status_log(&self.robot, self.run_state, s, wall_ns());
                self.run_state = Some(s.state);
                match line {
                    Some(l) => self.rosout.publish(l).map_err(|e| e.to_string()),
                    None => return false,
                }
            }
        };
        match r {
            Ok(()) => true,
            Err(e) => {
                tracing::debug!("ROS 2 DDS mirror: {e}");
                false
            }
        }
    }
}

/// The `effort_command` subscription over DDS, read on a thread of its own: every sample is
/// judged as the zenoh route judges it (the flood gate, one finite value within the bound,
/// freshness of the writer's source timestamp), a sample that does not decode as a
/// `Float64MultiArray` counted `malformed`, one without a source timestamp `no_attachment`.
pub struct DdsEffortInput {
    judge: Arc<EffortJudge>,
    stop: Option<futures::channel::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl DdsEffortInput {
    /// Subscribes to `/<robot>/effort_command` on `node`; valid commands go to `on_command`.
    pub fn subscribe<F>(
        node: &mut DdsNode,
        robot: &str,
        limits: EffortLimits,
        gate: FloodGate,
        on_command: F,
    ) -> Result<Self, anyhow::Error>
    where
        F: Fn(EffortCommand) + Send + 'static,
    {
        let t = Topics::new(robot).map_err(anyhow::Error::msg)?;
        let sub: Subscription<Float64MultiArray> = node.subscription(
            &t.effort_command,
            ("std_msgs", "Float64MultiArray"),
            EFFORT_QOS,
        )?;
        let judge = Arc::new(EffortJudge::new(gate));
        let j = judge.clone();
        let (stop, stopped) = futures::channel::oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("ros2-dds-effort".into())
            .spawn(move || {
                let read = sub.async_stream().for_each(|r| {
                    let now = wall_ns();
                    let verdict = j.judge(now, || match r {
                        Ok((m, info)) => {
                            let att = dds_attachment(
                                info.sequence_number(),
                                info.source_timestamp().map(|t| t.to_nanos()),
                                info.publisher_gid().to_bytes16(),
                            )
                            .ok_or(Refusal::NoTimestamp)?;
                            check_command(&m, att, now, &limits)
                        }
                        Err(e) => Err(Refusal::Cdr(crate::msgs::CdrError::Body {
                            ty: "std_msgs/msg/Float64MultiArray",
                            why: format!("{e:?}"),
                        })),
                    });
                    if let Some(cmd) = verdict {
                        on_command(cmd);
                    }
                    futures::future::ready(())
                });
                futures::executor::block_on(futures::future::select(Box::pin(read), stopped));
            })?;
        Ok(DdsEffortInput {
            judge,
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// The counts so far.
    pub fn counts(&self) -> EffortCounts {
        self.judge.counts()
    }
}

impl Drop for DdsEffortInput {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_discovery_range_is_read_as_ros_2_reads_it() {
        use DiscoveryRange::*;
        assert_eq!(DiscoveryRange::parse(None, None), Ok(Subnet));
        assert_eq!(DiscoveryRange::parse(Some(""), Some("1")), Ok(Localhost));
        assert_eq!(
            DiscoveryRange::parse(Some("LOCALHOST"), None),
            Ok(Localhost)
        );
        assert_eq!(DiscoveryRange::parse(Some("SUBNET"), Some("1")), Ok(Subnet));
        assert_eq!(
            DiscoveryRange::parse(Some("SYSTEM_DEFAULT"), None),
            Ok(Subnet)
        );
        let off = DiscoveryRange::parse(Some("OFF"), None).unwrap_err();
        assert!(
            off.contains(RANGE_ENV) && off.contains("LOCALHOST"),
            "{off}"
        );
        let bad = DiscoveryRange::parse(Some("localhost"), None).unwrap_err();
        assert!(
            bad.contains("\"localhost\"") && bad.contains(RANGE_ENV),
            "{bad}"
        );
    }
}
