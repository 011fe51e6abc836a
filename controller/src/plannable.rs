//! A law the planner can plan: [`PlannableLaw`], the one trait through which the planner's
//! orbit search, its period-`n` cycles, the Lyapunov exponents and the figures take a control
//! law, instead of building the paper's [`ComputedTorque`] themselves.
//!
//! A law is a pure function of `(t, mode, x)` (a [`TorqueLaw`] without memory: the shooting
//! calls it inside the integrator, in any order) with a list of named numbers that set it and
//! the model it computes with. The paper's law is the implementation every command uses; a
//! new law implements this trait in its own module and is planned with the planner's `*_with`
//! entry points (`tilting_planner::orbit::find_all_with`, `solve_with`,
//! `tilting_planner::lyapunov::largest_with`).
//!
//! ```
//! use tilting_controller::{ComputedTorque, ControlConfig, PlannableLaw};
//! let law = ComputedTorque::new(ControlConfig::default()).unwrap();
//! assert_eq!(law.parameter("kd"), Some(14.14));
//! let softer = law.with_parameter("kp", 60.0).unwrap();
//! assert_eq!(softer.parameter("kp"), Some(60.0));
//! // A bad value is refused naming the field.
//! assert!(law.with_parameter("kd", -1.0).unwrap_err().to_string().contains("kd"));
//! ```

use crate::{ComputedTorque, ControlConfig, Trajectory};
use tilting_plant::{ConfigError, Mode, Params, State, TorqueLaw};

/// A control law the planner can plan: its torque for a state and a time ([`TorqueLaw`], a
/// pure function: no memory of earlier calls), its parameters as a named list of numbers and
/// a constructor from them, and the model it computes with.
///
/// Contract: `self.with_parameters(self.model(), &values)` with the values of
/// [`PlannableLaw::parameters`] is `self`, torque for torque; the torque is finite for every
/// finite state.
pub trait PlannableLaw: TorqueLaw + Clone + Send + Sync {
    /// The law's name, as in `--law` (`computed-torque`).
    fn name(&self) -> &'static str;

    /// The parameters, `(name, value)` in a fixed order, each in its unit (the implementation
    /// documents them).
    fn parameters(&self) -> Vec<(&'static str, f64)>;

    /// The same law with the parameter values `values` (in the order of
    /// [`PlannableLaw::parameters`]), computing with the model `model`: checked, naming the
    /// first bad value and its range; a list of the wrong length is refused as `parameters`.
    fn with_parameters(&self, model: &Params, values: &[f64]) -> Result<Self, ConfigError>;

    /// The model the law computes with (inverse dynamics, energy).
    fn model(&self) -> &Params;

    /// The same law tracking `trajectory` (a message's `trajectory`, the controller's
    /// registry). The default is a law that tracks only upright: it takes the hold and refuses
    /// the others naming `trajectory`.
    fn with_trajectory(&self, trajectory: Trajectory) -> Result<Self, ConfigError> {
        match trajectory {
            Trajectory::Hold => Ok(self.clone()),
            other => Err(ConfigError::OutOfRange {
                field: "trajectory",
                value: format!("{other} (law {})", self.name()),
                allowed: "hold: this law tracks upright only",
            }),
        }
    }

    /// The adapted stiffness (1/s^2) at `x` in `mode`, for a law that adapts one (the
    /// figures draw it); `None` for a law without.
    fn stiffness(&self, _mode: Mode, _x: &State) -> Option<f64> {
        None
    }

    /// The value of the parameter `name`, if the law has it.
    fn parameter(&self, name: &str) -> Option<f64> {
        self.parameters()
            .into_iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| v)
    }

    /// The same law with the one parameter `name` set to `value` (the continuation's and the
    /// sweeps' step), checked; an unknown name is refused as `parameters`.
    fn with_parameter(&self, name: &str, value: f64) -> Result<Self, ConfigError> {
        let mut values = self.parameters();
        let slot =
            values
                .iter_mut()
                .find(|(n, _)| *n == name)
                .ok_or_else(|| ConfigError::OutOfRange {
                    field: "parameters",
                    value: name.to_owned(),
                    allowed: "one of the law's parameter names (PlannableLaw::parameters)",
                })?;
        slot.1 = value;
        let values: Vec<f64> = values.into_iter().map(|(_, v)| v).collect();
        self.with_parameters(self.model(), &values)
    }
}

/// Checks that `values` has one number per name of `names`, naming `parameters` if not.
pub fn check_count(names: &[&str], values: &[f64]) -> Result<(), ConfigError> {
    if values.len() == names.len() {
        Ok(())
    } else {
        Err(ConfigError::OutOfRange {
            field: "parameters",
            value: format!(
                "{} values for {} names ({})",
                values.len(),
                names.len(),
                names.join(", ")
            ),
            allowed: "one value per parameter, in the order of PlannableLaw::parameters",
        })
    }
}

/// The paper's law's parameter names, in the order of its [`PlannableLaw::parameters`]:
/// `K_P0` (1/s^2), `K_D` (1/s), `k` (1/(J s^2)), `E_av` (J) and the torque limit (N m, 0 for
/// none). The reference trajectory is kept by [`PlannableLaw::with_parameters`].
/// They are the floats of the protocol-2 `Reference` (its generic form's parameters).
pub const COMPUTED_TORQUE_PARAMETERS: [&str; 5] = tilting_proto::LawReference::PAPER_PARAMETERS;

impl PlannableLaw for ComputedTorque {
    fn name(&self) -> &'static str {
        crate::LawKind::ComputedTorque.name()
    }

    fn parameters(&self) -> Vec<(&'static str, f64)> {
        let l = &self.config().law;
        let values = [l.kp, l.kd, l.k, l.energy_avg, l.torque_limit.unwrap_or(0.0)];
        COMPUTED_TORQUE_PARAMETERS.into_iter().zip(values).collect()
    }

    fn with_parameters(&self, model: &Params, values: &[f64]) -> Result<Self, ConfigError> {
        check_count(&COMPUTED_TORQUE_PARAMETERS, values)?;
        let mut cfg: ControlConfig = *self.config();
        cfg.params = *model;
        cfg.law.kp = values[0];
        cfg.law.kd = values[1];
        cfg.law.k = values[2];
        cfg.law.energy_avg = values[3];
        cfg.law.torque_limit = (values[4] != 0.0).then_some(values[4]);
        ComputedTorque::new(cfg)
    }

    fn model(&self) -> &Params {
        &self.config().params
    }

    fn with_trajectory(&self, trajectory: Trajectory) -> Result<Self, ConfigError> {
        let mut cfg: ControlConfig = *self.config();
        cfg.law.reference = trajectory;
        ComputedTorque::new(cfg)
    }

    fn stiffness(&self, mode: Mode, x: &State) -> Option<f64> {
        Some(ComputedTorque::stiffness(self, mode, x))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LawSpec;

    #[test]
    fn parameters_round_trip_and_bad_lists_are_refused_naming_the_field() {
        let law = ComputedTorque::new(ControlConfig {
            law: LawSpec {
                torque_limit: Some(3.5),
                ..LawSpec::default()
            },
            ..ControlConfig::default()
        })
        .unwrap();
        let values: Vec<f64> = law.parameters().into_iter().map(|(_, v)| v).collect();
        assert_eq!(law.with_parameters(law.model(), &values).unwrap(), law);
        let e = law.with_parameters(law.model(), &values[..4]).unwrap_err();
        assert!(e.to_string().contains("parameters"), "{e}");
        let e = law.with_parameter("gain", 1.0).unwrap_err();
        assert!(e.to_string().contains("parameters"), "{e}");
        // E_av must be positive with k > 0: the spec's own check, naming the field.
        let e = law.with_parameter("energy_avg", 0.0).unwrap_err();
        assert!(e.to_string().contains("energy_avg"), "{e}");
        // A torque limit of 0 is none.
        let free = law.with_parameter("torque_limit", 0.0).unwrap();
        assert_eq!(free.config().law.torque_limit, None);
        let x = State::new(0.01, 1.5, 0.1, 0.2);
        assert_eq!(
            PlannableLaw::stiffness(&law, Mode::Left, &x),
            Some(law.stiffness(Mode::Left, &x))
        );
    }
}
