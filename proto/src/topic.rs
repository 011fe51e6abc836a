//! The five data topics of a robot, by name: which key each uses and which message it carries.
//!
//! Tools that handle any topic (the recorder, `echo`, `hz`, `replay`) name topics with
//! [`Topic`]; nodes use the typed key accessors of [`Keys`] directly.

use crate::codec::{decode, DecodeError};
use crate::{Keys, ModeEvent, PlantState, Reference, Status, TorqueCommand};

/// A data topic of a robot (liveliness tokens are not topics).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Topic {
    /// `plant/state`: [`PlantState`], once per control period.
    State,
    /// `controller/torque`: [`TorqueCommand`], one per state.
    Torque,
    /// `plant/event`: [`ModeEvent`], at every mode transition.
    Event,
    /// `plant/status`: [`Status`], at 10 Hz.
    Status,
    /// `planner/reference`: [`Reference`], on change and repeated.
    Reference,
}

impl Topic {
    /// Every topic, in the order of the tables.
    pub const ALL: [Topic; 5] = [
        Topic::State,
        Topic::Torque,
        Topic::Event,
        Topic::Status,
        Topic::Reference,
    ];

    /// The lowercase name (`state`, `torque`, `event`, `status`, `reference`).
    pub fn name(self) -> &'static str {
        match self {
            Topic::State => "state",
            Topic::Torque => "torque",
            Topic::Event => "event",
            Topic::Status => "status",
            Topic::Reference => "reference",
        }
    }

    /// The name of the message type it carries (`PlantState`, ...).
    pub fn message_type(self) -> &'static str {
        match self {
            Topic::State => "PlantState",
            Topic::Torque => "TorqueCommand",
            Topic::Event => "ModeEvent",
            Topic::Status => "Status",
            Topic::Reference => "Reference",
        }
    }

    /// Position in [`Topic::ALL`] (for per-topic tables).
    pub fn index(self) -> usize {
        self as usize
    }

    /// The key expression of this topic for `keys`' robot.
    pub fn key(self, keys: &Keys) -> &str {
        match self {
            Topic::State => keys.plant_state(),
            Topic::Torque => keys.controller_torque(),
            Topic::Event => keys.plant_event(),
            Topic::Status => keys.plant_status(),
            Topic::Reference => keys.planner_reference(),
        }
    }

    /// Decodes and validates one payload of this topic, discarding the message.
    pub fn check(self, bytes: &[u8]) -> Result<(), DecodeError> {
        match self {
            Topic::State => decode::<PlantState>(bytes).map(drop),
            Topic::Torque => decode::<TorqueCommand>(bytes).map(drop),
            Topic::Event => decode::<ModeEvent>(bytes).map(drop),
            Topic::Status => decode::<Status>(bytes).map(drop),
            Topic::Reference => decode::<Reference>(bytes).map(drop),
        }
    }
}

impl std::fmt::Display for Topic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A topic name that is none of the five.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown topic `{0}` (expected one of: state, torque, event, status, reference)")]
pub struct UnknownTopic(pub String);

impl std::str::FromStr for Topic {
    type Err = UnknownTopic;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Topic::ALL
            .into_iter()
            .find(|t| t.name() == s)
            .ok_or_else(|| UnknownTopic(s.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_back_and_keys_are_distinct() {
        let keys = Keys::new("r").unwrap();
        let mut seen = std::collections::HashSet::new();
        for (i, t) in Topic::ALL.into_iter().enumerate() {
            assert_eq!(t.index(), i);
            assert_eq!(t.name().parse::<Topic>(), Ok(t));
            assert!(t.key(&keys).starts_with("tilting/r/"));
            assert!(seen.insert(t.key(&keys).to_owned()));
        }
        let e = "torques".parse::<Topic>().unwrap_err().to_string();
        assert!(e.contains("torques") && e.contains("reference"), "{e}");
    }

    #[test]
    fn check_rejects_a_payload_of_another_topic() {
        let bytes = crate::encode(&TorqueCommand { seq: 1, tau: 0.5 });
        assert!(Topic::Torque.check(&bytes).is_ok());
        assert!(Topic::State.check(&bytes).is_err());
    }
}
