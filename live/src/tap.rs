//! The front door's sessions of a live run: the recording session subscribes to the five
//! topics for the recording (with the source each message names: the recorder applies the
//! plant's plausibility rules and the pinned sources before it believes a message, and the
//! status line reads the plant's latest status from it) and watches the plant's and the
//! controller's liveliness tokens; the planner's publishes the reference. Open, they are one
//! session. With `--secure` they are two: the recorder's (the logger's identity, linked
//! directly to the plant and the controller, so that the router relays none of the loop's
//! messages) and the planner's (a client of the router), where the reference is recorded.

use super::summary::PlannerCounts;
use crate::record::{Record, Recorder};
use std::sync::Arc;
use std::time::Instant;
use tilting_net::{subscribe_decoded_from, watch_presence, DropCounter, Presence, Role, ZenohArgs};
use tilting_planner::node::ReferencePublisher;
use tilting_proto::{AnyReference, Keys, ModeEvent, PlantState, Reference, Status, TorqueCommand};
use zenoh::pubsub::Subscriber;
use zenoh::Session;

/// The planner's session: the recorder's subscribers, the reference publisher and the
/// presence of the plant and the controller.
pub(super) struct Tap {
    /// The recording session.
    session: Session,
    /// The planner's session, if it is not the recording session.
    planner: Option<Session>,
    subscribers: Vec<Subscriber<()>>,
    publisher: ReferencePublisher,
    /// Undecodable messages per topic.
    counters: [Arc<DropCounter>; 5],
    /// The plant's and the controller's liveliness tokens, and since when each is gone.
    presence: [(Arc<Presence>, GoneSince); 2],
}

/// When a liveliness token went away (set by its watcher, cleared when it returns).
type GoneSince = Arc<std::sync::Mutex<Option<Instant>>>;

/// What the planner's session saw, once closed.
pub(super) struct Closed {
    /// The publisher's counts.
    pub(super) planner: PlannerCounts,
    /// Undecodable messages on the five topics.
    pub(super) invalid: u64,
}

impl Tap {
    /// Opens the recording session (`zargs`) and the planner's (`planner`, or the same),
    /// subscribes the recorder to the five topics (subscribers first; the reference on the
    /// planner's session), then starts publishing `reference`.
    pub(super) async fn open(
        zargs: &ZenohArgs,
        planner: Option<&ZenohArgs>,
        keys: &Keys,
        recorder: &Recorder,
        reference: Reference,
    ) -> anyhow::Result<Self> {
        let session = tilting_net::open_session(zargs, Role::Peer).await?;
        let planner = match planner {
            Some(p) => Some(tilting_net::open_session(p, Role::Peer).await?),
            None => None,
        };
        let publishing = planner.as_ref().unwrap_or(&session);
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
            subscribe_decoded_from(&session, state, move |m: PlantState, from| {
                tx.send_from(Record::State(m), from)
            })
            .await?,
        ];
        let tx = recorder.sender();
        subscribers.push(
            subscribe_decoded_from(&session, torque, move |m: TorqueCommand, from| {
                tx.send_from(Record::Torque(m), from)
            })
            .await?,
        );
        let tx = recorder.sender();
        subscribers.push(
            subscribe_decoded_from(&session, event, move |m: ModeEvent, from| {
                tx.send_from(Record::Event(m), from)
            })
            .await?,
        );
        let tx = recorder.sender();
        subscribers.push(
            subscribe_decoded_from(&session, status, move |m: Status, from| {
                tx.send_from(Record::Status(m), from)
            })
            .await?,
        );
        let tx = recorder.sender();
        subscribers.push(
            subscribe_decoded_from(publishing, refs, move |m: AnyReference, from| {
                tx.send_from(Record::Reference(m), from)
            })
            .await?,
        );
        let mut presence = Vec::new();
        for key in [keys.alive_plant(), keys.alive_controller()] {
            let gone: GoneSince = Arc::default();
            let g = gone.clone();
            let (p, sub) = watch_presence(&session, key, move |alive| {
                *g.lock().unwrap_or_else(|e| e.into_inner()) = (!alive).then(Instant::now);
            })
            .await?;
            subscribers.push(sub);
            presence.push((p, gone));
        }
        let presence = presence
            .try_into()
            .map_err(|_| anyhow::anyhow!("two tokens"))?;
        let publisher = ReferencePublisher::start(publishing, keys, reference).await?;
        Ok(Self {
            session,
            planner,
            subscribers,
            publisher,
            counters,
            presence,
        })
    }

    /// The recording session (for the Foxglove server's subscribers).
    pub(super) fn session(&self) -> &Session {
        &self.session
    }

    /// The planner's session, where the reference is published (the recording session when
    /// the run is open).
    pub(super) fn planner_session(&self) -> &Session {
        self.planner.as_ref().unwrap_or(&self.session)
    }

    /// Puts the reference again (once a second while the run goes).
    pub(super) fn repeat(&self) {
        if let Err(e) = self.publisher.repeat() {
            tracing::warn!("{e}");
        }
    }

    /// Since when the plant's (`0`) or the controller's (`1`) liveliness token is gone, if it
    /// was seen and is gone now.
    pub(super) fn gone_since(&self, which: usize) -> Option<Instant> {
        let (p, since) = &self.presence[which];
        if p.alive() {
            return None;
        }
        *since.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Undeclares everything and closes the session.
    pub(super) async fn close(self) -> Closed {
        let planner = PlannerCounts {
            puts: self.publisher.puts(),
            queries_answered: self.publisher.queries_answered(),
        };
        drop((self.subscribers, self.publisher));
        let _ = self.session.close().await;
        if let Some(p) = self.planner {
            let _ = p.close().await;
        }
        Closed {
            planner,
            invalid: self.counters.iter().map(|c| c.dropped()).sum(),
        }
    }
}
