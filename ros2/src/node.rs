//! The thin zenoh part: a ROS 2 node on a zenoh session (its liveliness tokens), publishers that
//! put CDR payloads with rmw_zenoh's attachment, the mirror of a robot's topics on a thread of
//! its own, and the `effort_command` subscription with its checks and counters.

use crate::attachment::Attachment;
use crate::msgs;
use crate::names::{topic_key, Entity, EntityKind, Qos, RosType, TopicInfo};
use crate::robot::{self, EffortCommand, EffortLimits, FloodGate, Refusal, Topics};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use tilting_proto::{ModeEvent, PlantState, Status};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::{Session, Wait};

/// Wall-clock time, ns since the Unix epoch (the attachments' source timestamps).
pub fn wall_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

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

/// What the mirror publishes.
#[derive(Debug, Clone)]
pub enum Input {
    /// A state, with the torque in force (N m) if known.
    State(PlantState, Option<f64>),
    /// A mode transition.
    Event(ModeEvent),
    /// A status.
    Status(Status),
}

/// The counters of a mirror.
#[derive(Debug, Default)]
pub struct MirrorCounts {
    /// Inputs handed to the mirror.
    pub sent: AtomicU64,
    /// Inputs dropped because the mirror's queue was full (the loop never waits for it).
    pub dropped: AtomicU64,
    /// Samples published.
    pub published: AtomicU64,
}

/// The loop's end of a mirror: [`MirrorTx::send`] never blocks.
#[derive(Clone)]
pub struct MirrorTx {
    tx: SyncSender<Input>,
    counts: Arc<MirrorCounts>,
}

impl MirrorTx {
    /// Hands `input` to the mirror's thread, or drops it (counted) when its queue is full.
    pub fn send(&self, input: Input) {
        self.counts.sent.fetch_add(1, Ordering::Relaxed);
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = self.tx.try_send(input)
        {
            self.counts.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// The counters.
    pub fn counts(&self) -> &MirrorCounts {
        &self.counts
    }
}

/// A robot's topics as ROS 2 topics: `joint_states`, `contact_mode` and `/rosout`.
pub struct Mirror {
    robot: String,
    joint_states: RosPublisher,
    contact_mode: RosPublisher,
    rosout: RosPublisher,
    run_state: Option<u8>,
    counts: Arc<MirrorCounts>,
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
            counts: Arc::default(),
        })
    }

    /// Publishes what `input` becomes in ROS 2.
    pub fn publish(&mut self, input: &Input) {
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
                    None => return,
                }
            }
        };
        match r {
            Ok(()) => {
                self.counts.published.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => tracing::debug!("ROS 2 mirror: {e}"),
        }
    }

    /// Runs the mirror on a thread of its own fed by a queue of `capacity` inputs; the thread
    /// ends when every [`MirrorTx`] is dropped.
    pub fn spawn(mut self, capacity: usize) -> std::io::Result<MirrorTx> {
        let (tx, rx): (SyncSender<Input>, Receiver<Input>) = sync_channel(capacity);
        let counts = self.counts.clone();
        std::thread::Builder::new()
            .name("ros2-mirror".into())
            .spawn(move || {
                lower_priority();
                while let Ok(i) = rx.recv() {
                    self.publish(&i);
                }
            })?;
        Ok(MirrorTx { tx, counts })
    }
}

/// Nice value of the mirror's thread: under CPU contention the plant's pacing thread (nice 0)
/// runs first, and the mirror catches up from its queue.
pub const MIRROR_NICE: i32 = 10;

/// Lowers the calling thread's scheduling priority to [`MIRROR_NICE`] (Linux: a thread is a
/// task with its own nice value); best effort, elsewhere nothing.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: plain system calls on the calling thread's own id; no memory is passed.
    unsafe {
        let tid = libc::gettid();
        if libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, MIRROR_NICE) != 0 {
            tracing::debug!("ROS 2 mirror: cannot lower the thread's priority");
        }
    }
}

/// Counts of the `effort_command` subscription, by outcome (the plant's summary `ros2`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct EffortCounts {
    /// Samples received.
    pub received: u64,
    /// Commands passed on to the loop.
    pub accepted: u64,
    /// Refused: no or a malformed attachment.
    pub no_attachment: u64,
    /// Refused: not a `Float64MultiArray` or not exactly one value.
    pub malformed: u64,
    /// Refused: NaN, infinite or beyond `--max-torque`.
    pub out_of_bounds: u64,
    /// Refused: source timestamp older than `--max-age` periods.
    pub stale: u64,
    /// Refused: source timestamp in the future.
    pub future: u64,
    /// Refused: beyond the flood gate's rate.
    pub flood: u64,
}

/// The `effort_command` subscription of the plant.
pub struct EffortInput {
    counts: Arc<Mutex<EffortCounts>>,
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
        let counts = Arc::new(Mutex::new(EffortCounts::default()));
        let c = counts.clone();
        let gate = Mutex::new(gate);
        let last_log = Mutex::new(None::<std::time::Instant>);
        let sub = node
            .subscription(
                &t.effort_command,
                &msgs::FLOAT64_MULTI_ARRAY,
                robot::EFFORT_QOS,
                move |payload, att| {
                    let now = wall_ns();
                    let admitted = gate.lock().unwrap_or_else(|e| e.into_inner()).admit(now);
                    let verdict =
                        admitted.and_then(|()| robot::check_effort(payload, att, now, &limits));
                    let mut k = c.lock().unwrap_or_else(|e| e.into_inner());
                    k.received += 1;
                    match verdict {
                        Ok(cmd) => {
                            k.accepted += 1;
                            drop(k);
                            on_command(cmd);
                        }
                        Err(r) => {
                            count(&mut k, &r);
                            drop(k);
                            let mut l = last_log.lock().unwrap_or_else(|e| e.into_inner());
                            if l.is_none_or(|t| t.elapsed().as_secs() >= 1) {
                                tracing::warn!("refused: {r}");
                                *l = Some(std::time::Instant::now());
                            }
                        }
                    }
                },
            )
            .await?;
        Ok(EffortInput { counts, _sub: sub })
    }

    /// The counts so far.
    pub fn counts(&self) -> EffortCounts {
        self.counts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

fn count(k: &mut EffortCounts, r: &Refusal) {
    match r {
        Refusal::Attachment(_) => k.no_attachment += 1,
        Refusal::Cdr(_) | Refusal::Length(_) => k.malformed += 1,
        Refusal::NotFinite(_) | Refusal::Beyond { .. } => k.out_of_bounds += 1,
        Refusal::Stale { .. } => k.stale += 1,
        Refusal::Future { .. } => k.future += 1,
        Refusal::Flood(..) => k.flood += 1,
    }
}
