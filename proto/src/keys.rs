//! Zenoh key expressions, as plain strings.
//!
//! Every key lives under `tilting/{robot}/`, where `{robot}` names one plant/controller/planner
//! group (default [`DEFAULT_ROBOT`]). The robot name must be non-empty and use only ASCII letters,
//! digits, `_` and `-`, so it can never inject `/`, `*`, `$` or `?` into a key expression.

use thiserror::Error;

/// First chunk of every key expression.
pub const PREFIX: &str = "tilting";

/// Robot name used when none is configured.
pub const DEFAULT_ROBOT: &str = "demo";

/// Characters allowed in a robot name, for error messages and help texts.
pub const ROBOT_NAME_CHARS: &str = "ASCII letters, digits, '_' and '-' ([A-Za-z0-9_-])";

/// An invalid robot name.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum KeyError {
    /// The robot name is empty.
    #[error("robot name is empty; allowed: one or more {ROBOT_NAME_CHARS}")]
    Empty,
    /// The robot name contains a character outside `[A-Za-z0-9_-]`.
    #[error(
        "robot name {name:?} has invalid character {ch:?} at byte {index}; allowed: {ROBOT_NAME_CHARS}"
    )]
    InvalidChar {
        /// The rejected name.
        name: String,
        /// The first offending character.
        ch: char,
        /// Its byte offset in `name`.
        index: usize,
    },
}

/// Checks that `robot` is non-empty and uses only `[A-Za-z0-9_-]`.
pub fn validate_robot_name(robot: &str) -> Result<(), KeyError> {
    if robot.is_empty() {
        return Err(KeyError::Empty);
    }
    match robot
        .char_indices()
        .find(|&(_, c)| !(c.is_ascii_alphanumeric() || c == '_' || c == '-'))
    {
        Some((index, ch)) => Err(KeyError::InvalidChar {
            name: robot.to_owned(),
            ch,
            index,
        }),
        None => Ok(()),
    }
}

/// All key expressions of one robot, built once.
///
/// | accessor             | key                                   | publisher  | payload                      |
/// |----------------------|---------------------------------------|------------|------------------------------|
/// | `plant_state`        | `tilting/{robot}/plant/state`         | plant      | [`PlantState`]               |
/// | `controller_torque`  | `tilting/{robot}/controller/torque`   | controller | [`TorqueCommand`]            |
/// | `plant_event`        | `tilting/{robot}/plant/event`         | plant      | [`ModeEvent`]                |
/// | `plant_status`       | `tilting/{robot}/plant/status`        | plant      | [`Status`]                   |
/// | `planner_reference`  | `tilting/{robot}/planner/reference`   | planner    | [`Reference`]                |
/// | `alive_plant`        | `tilting/{robot}/alive/plant`         | plant      | liveliness token (no payload) |
/// | `alive_controller`   | `tilting/{robot}/alive/controller`    | controller | liveliness token (no payload) |
/// | `alive_planner`      | `tilting/{robot}/alive/planner`       | planner    | liveliness token (no payload) |
///
/// [`PlantState`]: crate::msg::PlantState
/// [`TorqueCommand`]: crate::msg::TorqueCommand
/// [`ModeEvent`]: crate::msg::ModeEvent
/// [`Status`]: crate::msg::Status
/// [`Reference`]: crate::msg::Reference
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Keys {
    robot: String,
    plant_state: String,
    controller_torque: String,
    plant_event: String,
    plant_status: String,
    planner_reference: String,
    alive_plant: String,
    alive_controller: String,
    alive_planner: String,
}

impl Keys {
    /// Builds every key for `robot`, after [`validate_robot_name`].
    pub fn new(robot: &str) -> Result<Self, KeyError> {
        validate_robot_name(robot)?;
        let k = |suffix: &str| format!("{PREFIX}/{robot}/{suffix}");
        Ok(Self {
            robot: robot.to_owned(),
            plant_state: k("plant/state"),
            controller_torque: k("controller/torque"),
            plant_event: k("plant/event"),
            plant_status: k("plant/status"),
            planner_reference: k("planner/reference"),
            alive_plant: k("alive/plant"),
            alive_controller: k("alive/controller"),
            alive_planner: k("alive/planner"),
        })
    }

    /// The validated robot name.
    pub fn robot(&self) -> &str {
        &self.robot
    }

    /// `tilting/{robot}/plant/state`: [`PlantState`](crate::msg::PlantState), plant to controller.
    pub fn plant_state(&self) -> &str {
        &self.plant_state
    }

    /// `tilting/{robot}/controller/torque`: [`TorqueCommand`](crate::msg::TorqueCommand),
    /// controller to plant.
    pub fn controller_torque(&self) -> &str {
        &self.controller_torque
    }

    /// `tilting/{robot}/plant/event`: [`ModeEvent`](crate::msg::ModeEvent), plant to anyone.
    pub fn plant_event(&self) -> &str {
        &self.plant_event
    }

    /// `tilting/{robot}/plant/status`: [`Status`](crate::msg::Status), plant to anyone.
    pub fn plant_status(&self) -> &str {
        &self.plant_status
    }

    /// `tilting/{robot}/planner/reference`: [`Reference`](crate::msg::Reference), planner to
    /// controller.
    pub fn planner_reference(&self) -> &str {
        &self.planner_reference
    }

    /// `tilting/{robot}/alive/plant`: liveliness token declared by the plant.
    pub fn alive_plant(&self) -> &str {
        &self.alive_plant
    }

    /// `tilting/{robot}/alive/controller`: liveliness token declared by the controller.
    pub fn alive_controller(&self) -> &str {
        &self.alive_controller
    }

    /// `tilting/{robot}/alive/planner`: liveliness token declared by the planner.
    pub fn alive_planner(&self) -> &str {
        &self.alive_planner
    }
}

impl Default for Keys {
    /// The keys of [`DEFAULT_ROBOT`].
    fn default() -> Self {
        Self::new(DEFAULT_ROBOT).expect("the default robot name is valid")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_keys_are_exact() {
        let k = Keys::default();
        assert_eq!(k.robot(), "demo");
        assert_eq!(k.plant_state(), "tilting/demo/plant/state");
        assert_eq!(k.controller_torque(), "tilting/demo/controller/torque");
        assert_eq!(k.plant_event(), "tilting/demo/plant/event");
        assert_eq!(k.plant_status(), "tilting/demo/plant/status");
        assert_eq!(k.planner_reference(), "tilting/demo/planner/reference");
        assert_eq!(k.alive_plant(), "tilting/demo/alive/plant");
        assert_eq!(k.alive_controller(), "tilting/demo/alive/controller");
        assert_eq!(k.alive_planner(), "tilting/demo/alive/planner");
    }

    #[test]
    fn custom_robot_name_is_used_everywhere() {
        let k = Keys::new("Rig_2-b").unwrap();
        let all = [
            k.plant_state(),
            k.controller_torque(),
            k.plant_event(),
            k.plant_status(),
            k.planner_reference(),
            k.alive_plant(),
            k.alive_controller(),
            k.alive_planner(),
        ];
        for key in all {
            assert!(key.starts_with("tilting/Rig_2-b/"), "{key}");
            assert!(!key.contains("demo"), "{key}");
        }
        // All distinct.
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    #[test]
    fn robot_name_validation() {
        for ok in ["demo", "a", "Z", "0", "robot_1", "r-2", "ABC_def-123"] {
            assert_eq!(validate_robot_name(ok), Ok(()), "{ok}");
        }
        assert_eq!(validate_robot_name(""), Err(KeyError::Empty));
        assert!(Keys::new("").is_err());
        for (bad, ch, index) in [
            ("a/b", '/', 1),
            ("*", '*', 0),
            ("**", '*', 0),
            ("de mo", ' ', 2),
            ("robot$", '$', 5),
            ("q?", '?', 1),
            ("é", 'é', 0),
            ("a.b", '.', 1),
        ] {
            let err = validate_robot_name(bad).unwrap_err();
            assert_eq!(
                err,
                KeyError::InvalidChar {
                    name: bad.to_owned(),
                    ch,
                    index
                }
            );
            let text = err.to_string();
            assert!(text.contains("robot name"), "{text}");
            assert!(text.contains("[A-Za-z0-9_-]"), "{text}");
            assert!(Keys::new(bad).is_err());
        }
        let text = KeyError::Empty.to_string();
        assert!(
            text.contains("robot name") && text.contains("[A-Za-z0-9_-]"),
            "{text}"
        );
    }
}
