//! The thin zenoh part: a ROS 2 node on a zenoh session (its liveliness tokens), publishers that
//! put CDR payloads with rmw_zenoh's attachment, the mirror of a robot's topics on a thread of
//! its own, and the `effort_command` subscription with its checks and counters.

use crate::attachment::Attachment;
use crate::mirror::{EffortJudge, Sink};
use crate::msgs;
use crate::names::{topic_key, Entity, EntityKind, Qos, RosType, TopicInfo};
use crate::robot::{self, EffortCommand, EffortLimits, FloodGate, Topics};
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::{Session, Wait};

pub use crate::mirror::{
    lower_priority, wall_ns, EffortCounts, Input, MirrorCounts, MirrorTx, MIRROR_NICE,
};

fn zerr(what: &str, e: impl std::fmt::Display) -> anyhow::Error {
    anyhow::anyhow!("{what}: {e}")
}

/// A ROS 2 node on a zenoh session: its `NN` token, and the ids of its entities.
pub struct RosNode {
    session: Session,
    domain: u32,
    zid: String,
    namespace: String,
    name: String,
    next_eid: AtomicU64,
    _token: LivelinessToken,
}

impl RosNode {
    /// Declares node `name` in `namespace` (e.g. `/demo`) of ROS domain `domain`.
    pub async fn declare(
        session: &Session,
        domain: u32,
        namespace: &str,
        name: &str,
    ) -> Result<RosNode, anyhow::Error> {
        let zid = session.zid().to_string();
        let entity = Entity {
            domain,
            zid: zid.clone(),
            nid: 0,
            eid: 0,
            kind: EntityKind::Node,
            enclave: "/".into(),
            namespace: namespace.to_owned(),
            node: name.to_owned(),
            topic: None,
        };
        let token = session
            .liveliness()
            .declare_token(entity.token())
            .await
            .map_err(|e| zerr("cannot declare the ROS 2 node token", e))?;
        Ok(RosNode {
            session: session.clone(),
            domain,
            zid,
            namespace: namespace.to_owned(),
            name: name.to_owned(),
            next_eid: AtomicU64::new(1),
            _token: token,
        })
    }

    /// The entity of a new publisher or subscription on `topic`.
    fn entity(&self, kind: EntityKind, topic: &str, ty: &RosType, qos: Qos) -> Entity {
        Entity {
            domain: self.domain,
            zid: self.zid.clone(),
            nid: 0,
            eid: self.next_eid.fetch_add(1, Ordering::Relaxed),
            kind,
            enclave: "/".into(),
            namespace: self.namespace.clone(),
            node: self.name.clone(),
            topic: Some(TopicInfo {
                name: topic.to_owned(),
                dds_type: ty.dds_name(),
                hash: ty.hash.to_owned(),
                qos,
            }),
        }
    }

    async fn token(&self, e: &Entity) -> Result<LivelinessToken, anyhow::Error> {
        self.session
            .liveliness()
            .declare_token(e.token())
            .await
            .map_err(|err| zerr(&format!("cannot declare {}", e.token()), err))
    }

    /// Declares a publisher of `ty` on `topic` (its `MP` token and zenoh publisher). Reliable:
    /// under congestion it waits (so the sequence numbers on the wire have no gaps); the
    /// mirror's queue in front of it is what drops, never the loop.
    pub async fn publisher(
        &self,
        topic: &str,
        ty: &RosType,
        qos: Qos,
    ) -> Result<RosPublisher, anyhow::Error> {
        let e = self.entity(EntityKind::Publisher, topic, ty, qos);
        let key = topic_key(self.domain, topic, ty);
        let publisher = self
            .session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Block)
            .priority(Priority::DataHigh)
            .express(true)
            .await
            .map_err(|err| zerr(&format!("cannot declare a publisher on {key}"), err))?;
        Ok(RosPublisher {
            _token: self.token(&e).await?,
            gid: e.gid(),
            publisher,
            seq: 0,
        })
    }

    /// Declares a subscription of `ty` on `topic` (its `MS` token and zenoh subscriber); every
    /// sample goes to `on_sample(payload, attachment)` on a zenoh thread.
    pub async fn subscription<F>(
        &self,
        topic: &str,
        ty: &RosType,
        qos: Qos,
        on_sample: F,
    ) -> Result<RosSubscription, anyhow::Error>
    where
        F: Fn(&[u8], Option<&[u8]>) + Send + Sync + 'static,
    {
        let e = self.entity(EntityKind::Subscription, topic, ty, qos);
        let key = topic_key(self.domain, topic, ty);
        let subscriber = self
            .session
            .declare_subscriber(key.clone())
            .callback(move |s| {
                let att = s.attachment().map(|a| a.to_bytes());
                on_sample(&s.payload().to_bytes(), att.as_deref());
            })
            .await
            .map_err(|err| zerr(&format!("cannot subscribe to {key}"), err))?;
        Ok(RosSubscription {
            _token: self.token(&e).await?,
            _subscriber: subscriber,
        })
    }
}

/// A publisher: CDR payloads with the attachment (sequence number from 1, wall-clock source
/// timestamp, GID of its token).
pub struct RosPublisher {
    publisher: Publisher<'static>,
    _token: LivelinessToken,
    gid: [u8; 16],
    seq: i64,
}

impl RosPublisher {
    /// Publishes `msg` (synchronously).
    pub fn put<T: Serialize>(&mut self, msg: &T) -> Result<(), anyhow::Error> {
        self.seq += 1;
        let att = Attachment {
            seq: self.seq,
            source_timestamp_ns: wall_ns(),
            gid: self.gid,
        };
        self.publisher
            .put(msgs::encode(msg))
            .attachment(att.encode().to_vec())
            .wait()
            .map_err(|e| zerr("put", e))
    }

    /// This publisher's GID.
    pub fn gid(&self) -> [u8; 16] {
        self.gid
    }
}

/// A subscription (keep it alive).
pub struct RosSubscription {
    _token: LivelinessToken,
    _subscriber: Subscriber<()>,
}

/// A robot's topics as ROS 2 topics: `joint_states`, `contact_mode` and `/rosout`.
pub struct Mirror {
    robot: String,
    joint_states: RosPublisher,
    contact_mode: RosPublisher,
    rosout: RosPublisher,
    run_state: Option<u8>,
}

impl Mirror {
    /// Declares the mirror's publishers on `node` for `robot`.
    pub async fn declare(node: &RosNode, robot: &str) -> Result<Mirror, anyhow::Error> {
        let t = Topics::new(robot).map_err(anyhow::Error::msg)?;
        Ok(Mirror {
            robot: robot.to_owned(),
            joint_states: node
                .publisher(&t.joint_states, &msgs::JOINT_STATE, robot::JOINT_STATES_QOS)
                .await?,
            contact_mode: node
                .publisher(&t.contact_mode, &msgs::UINT8, robot::CONTACT_MODE_QOS)
                .await?,
            rosout: node
                .publisher(&t.rosout, &msgs::LOG, robot::ROSOUT_QOS)
                .await?,
            run_state: None,
        })
    }

    /// Runs the mirror on a thread of its own fed by a queue of `capacity` inputs; the thread
    /// ends when every [`MirrorTx`] is dropped.
    pub fn spawn(self, capacity: usize) -> std::io::Result<MirrorTx> {
        crate::mirror::spawn(vec![Box::new(self)], capacity)
    }
}

impl Sink for Mirror {
    /// Publishes what `input` becomes in ROS 2.
    fn publish(&mut self, input: &Input) -> bool {
        let r = match input {
            Input::State(s, tau) => self
                .joint_states
                .put(&robot::joint_state(s, *tau))
                .and_then(|()| self.contact_mode.put(&msgs::UInt8 { data: s.mode })),
            Input::Event(e) => self
                .rosout
                .put(&robot::event_log(&self.robot, e, wall_ns())),
            Input::Status(s) => {
                let line = robot::status_log(&self.robot, self.run_state, s, wall_ns());
                self.run_state = Some(s.state);
                match line {
                    Some(l) => self.rosout.put(&l),
                    None => return false,
                }
            }
        };
        match r {
            Ok(()) => true,
            Err(e) => {
                tracing::debug!("ROS 2 mirror: {e}");
                false
            }
        }
    }
}

/// The `effort_command` subscription of the plant.
pub struct EffortInput {
    judge: std::sync::Arc<EffortJudge>,
    _sub: RosSubscription,
}

impl EffortInput {
    /// Subscribes to `/<robot>/effort_command`; every valid command goes to `on_command` (on a
    /// zenoh thread), every refused one is counted and logged at a bounded rate.
    pub async fn subscribe<F>(
        node: &RosNode,
        robot: &str,
        limits: EffortLimits,
        gate: FloodGate,
        on_command: F,
    ) -> Result<EffortInput, anyhow::Error>
    where
        F: Fn(EffortCommand) + Send + Sync + 'static,
    {
        let t = Topics::new(robot).map_err(anyhow::Error::msg)?;
        let judge = std::sync::Arc::new(EffortJudge::new(gate));
        let j = judge.clone();
        let sub = node
            .subscription(
                &t.effort_command,
                &msgs::FLOAT64_MULTI_ARRAY,
                robot::EFFORT_QOS,
                move |payload, att| {
                    let now = wall_ns();
                    if let Some(cmd) =
                        j.judge(now, || robot::check_effort(payload, att, now, &limits))
                    {
                        on_command(cmd);
                    }
                },
            )
            .await?;
        Ok(EffortInput { judge, _sub: sub })
    }

    /// The counts so far.
    pub fn counts(&self) -> EffortCounts {
        self.judge.counts()
    }
}
