//! The in-process planner's session of a live run: it subscribes to the five topics for the
//! recording (and keeps the plant's latest status for the status line), then publishes the
//! reference.

use super::status::LatestStatus;
use super::summary::PlannerCounts;
use crate::record::{Record, Recorder};
use std::sync::Arc;
use tilting_net::{subscribe_decoded, DropCounter, Role, ZenohArgs};
use tilting_planner::node::ReferencePublisher;
use tilting_proto::{Keys, ModeEvent, PlantState, Reference, Status, TorqueCommand};
use zenoh::pubsub::Subscriber;
use zenoh::Session;

/// The planner's session: the recorder's subscribers, the reference publisher and the plant's
/// latest status.
pub(super) struct Tap {
    session: Session,
    subscribers: Vec<Subscriber<()>>,
    publisher: ReferencePublisher,
    /// Undecodable messages per topic.
    counters: [Arc<DropCounter>; 5],
    /// The plant's latest status.
    latest: LatestStatus,
}

/// What the planner's session saw, once closed.
pub(super) struct Closed {
    /// The publisher's counts.
    pub(super) planner: PlannerCounts,
    /// Undecodable messages on the five topics.
    pub(super) invalid: u64,
    /// The plant's last status.
    pub(super) last_status: Option<Status>,
}

impl Tap {
    /// Opens the session, subscribes the recorder to the five topics (subscribers first), then
    /// starts publishing `reference`.
    pub(super) async fn open(
        zargs: &ZenohArgs,
        keys: &Keys,
        recorder: &Recorder,
        reference: Reference,
    ) -> anyhow::Result<Self> {
        let session = tilting_net::open_session(zargs, Role::Peer).await?;
        let latest: LatestStatus = Arc::default();
        let counters = [
            keys.plant_state(),
            keys.controller_torque(),
            keys.plant_event(),
            keys.plant_status(),
            keys.planner_reference(),
        ]
        .map(|k| Arc::new(DropCounter::new(k)));
        let [state, torque, event, status, refs] = counters.clone();
        let tx = recorder.sender();
        let mut subscribers = vec![
            subscribe_decoded(&session, state, move |m: PlantState| {
                tx.send(Record::State(m))
            })
            .await?,
        ];
        let tx = recorder.sender();
        subscribers.push(
            subscribe_decoded(&session, torque, move |m: TorqueCommand| {
                tx.send(Record::Torque(m))
            })
            .await?,
        );
        let tx = recorder.sender();
        subscribers.push(
            subscribe_decoded(&session, event, move |m: ModeEvent| {
                tx.send(Record::Event(m))
            })
            .await?,
        );
        let (l, tx) = (latest.clone(), recorder.sender());
        subscribers.push(
            subscribe_decoded(&session, status, move |m: Status| {
                tx.send(Record::Status(m.clone()));
                *l.lock().unwrap_or_else(|e| e.into_inner()) = Some(m)
            })
            .await?,
        );
        let tx = recorder.sender();
        subscribers.push(
            subscribe_decoded(&session, refs, move |m: Reference| {
                tx.send(Record::Reference(m))
            })
            .await?,
        );
        let publisher = ReferencePublisher::start(&session, keys, reference).await?;
        Ok(Self {
            session,
            subscribers,
            publisher,
            counters,
            latest,
        })
    }

    /// Puts the reference again (once a second while the run goes).
    pub(super) fn repeat(&self) {
        if let Err(e) = self.publisher.repeat() {
            tracing::warn!("{e}");
        }
    }

    /// The plant's latest status.
    pub(super) fn status(&self) -> Option<Status> {
        self.latest
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Undeclares everything and closes the session.
    pub(super) async fn close(self) -> Closed {
        let planner = PlannerCounts {
            puts: self.publisher.puts(),
            queries_answered: self.publisher.queries_answered(),
        };
        drop((self.subscribers, self.publisher));
        let _ = self.session.close().await;
        Closed {
            planner,
            invalid: self.counters.iter().map(|c| c.dropped()).sum(),
            last_status: self
                .latest
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .clone(),
        }
    }
}
