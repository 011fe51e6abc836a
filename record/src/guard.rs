//! [`Guard`]: the front door trusts nothing either. Before a [`crate::Recorder`] writes a
//! message, it applies the plant's own plausibility rules ([`tilting_proto::plausible`]) to it:
//! a state inside the wall-clock window and on its period's time grid, below the fall angle; a
//! torque within the torque bound, answering a state already seen; an event or a status about a
//! state already seen, on the grid; and where the source is known, from the plant's session
//! (states, events, statuses) or the controller's (torques), each pinned to the first believed
//! message's source ([`tilting_proto::source`]), or to the source known in advance
//! ([`Sources`]: `tilting live` chooses its nodes' zenoh ids). A refused message is counted and
//! never written, so it changes neither the recording nor anything judged from it (the status
//! line, the peaks). Without rules (`tilting record`, which does not know the robot's bounds)
//! only the sources are checked.

use crate::recorder::Record;
use std::time::{Duration, Instant};
use tilting_proto::plausible::{self, Implausible, StateWindow};
use tilting_proto::{SourceId, SourcePin};

/// Delivery slack of the wall-clock window (s): how far the plant's messages may run ahead of
/// the wall clock as the recorder sees them (a burst after a stall of the recorder's thread).
pub const SLACK: f64 = 1.0;

/// How long the plant's or the controller's pinned source may be silent before another
/// session may take its place (s): a controller restarted after a crash is a new session.
/// Half a second, the status line's silence alarm.
pub const PIN_LAPSE: f64 = 0.5;

/// The plausibility rules a recorder applies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rules {
    /// The control period (s), if known: then times must lie on its grid.
    pub period: Option<f64>,
    /// The shortest control period the plant allows (s), for the wall-clock window when the
    /// period is unknown.
    pub min_period: f64,
    /// The plant's torque bound (N m, its `--max-torque`).
    pub max_torque: f64,
    /// The plant's fall angle (rad).
    pub fall_angle: f64,
    /// The plant starts after the recorder: the first state too must be within the wall clock
    /// since the recorder started (otherwise the first state is believed as it comes, as for a
    /// recorder that joins a running robot).
    pub from_start: bool,
}

/// The plant's and the controller's zenoh sessions, where known before the first message
/// (their `--zenoh-id`): each stream is then pinned to its source from the start, and a message
/// from any other session, or naming none, is refused, however early it comes. An unknown one
/// is pinned by the first believed message ([`tilting_proto::SourcePin`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sources {
    /// The session of the plant's states, events and statuses.
    pub plant: Option<SourceId>,
    /// The session of the controller's torques.
    pub controller: Option<SourceId>,
}

/// The gate of one recording: the state window of the rules (if any), and the pinned sources
/// of the plant's and the controller's streams.
#[derive(Debug)]
pub(crate) struct Guard {
    rules: Option<Rules>,
    window: Option<StateWindow>,
    plant: SourcePin,
    controller: SourcePin,
}

impl Guard {
    pub(crate) fn new(rules: Option<Rules>, sources: Sources) -> Self {
        let lapse = Duration::from_secs_f64(PIN_LAPSE);
        Self {
            rules,
            window: rules.map(|r| {
                StateWindow::new(r.period, r.min_period, r.fall_angle, SLACK, r.from_start)
            }),
            plant: SourcePin::expect_or_new(sources.plant, lapse),
            controller: SourcePin::expect_or_new(sources.controller, lapse),
        }
    }

    /// Whether `rec` from `source` is believed: the rules of its message, then its source;
    /// a believed state becomes the newest, and a believed message's source holds the pin.
    pub(crate) fn check(
        &mut self,
        rec: &Record,
        source: Option<SourceId>,
    ) -> Result<(), Implausible> {
        let now = Instant::now();
        let plant =
            |pin: &SourcePin, message| plausible::foreign(pin, message, "plant", source, now);
        let Some((rules, window)) = self.rules.as_ref().zip(self.window.as_mut()) else {
            // Sources only.
            match rec {
                Record::State(_) => plant(&self.plant, "PlantState")?,
                Record::Event(_) => plant(&self.plant, "ModeEvent")?,
                Record::Status(_) => plant(&self.plant, "Status")?,
                Record::Torque(_) => {
                    plausible::foreign(
                        &self.controller,
                        "TorqueCommand",
                        "controller",
                        source,
                        now,
                    )?;
                    self.controller.believe(source, now);
                    return Ok(());
                }
                Record::Reference(_) | Record::Wire(..) => return Ok(()),
            }
            self.plant.believe(source, now);
            return Ok(());
        };
        let grid = |message, seq, time| match rules.period {
            Some(p) => plausible::on_grid(message, seq, time, p),
            None => Ok(()),
        };
        match rec {
            Record::State(s) => {
                window.test(s, now)?;
                plant(&self.plant, "PlantState")?;
                window.believe(s, now);
            }
            Record::Torque(c) => {
                plausible::torque(c, window.newest(now), rules.max_torque)?;
                plausible::foreign(&self.controller, "TorqueCommand", "controller", source, now)?;
                self.controller.believe(source, now);
                return Ok(());
            }
            Record::Event(e) => {
                plausible::ahead("ModeEvent", e.seq, window.newest(now))?;
                grid("ModeEvent", e.seq, e.time)?;
                plant(&self.plant, "ModeEvent")?;
            }
            Record::Status(st) => {
                plausible::ahead("Status", st.seq, window.newest(now))?;
                grid("Status", st.seq, st.time)?;
                plant(&self.plant, "Status")?;
            }
            Record::Reference(_) | Record::Wire(..) => return Ok(()),
        }
        self.plant.believe(source, now);
        Ok(())
    }
}
