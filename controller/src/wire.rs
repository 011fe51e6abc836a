//! The law on the wire: conversions between the planner's message
//! [`tilting_proto::Reference`] and the domain types [`ControlConfig`] and [`Reference`].
//!
//! The message carries everything of the law but the model parameters (each node keeps its own
//! `--params`); a torque limit of 0 on the wire means none.

use crate::{ControlConfig, Reference};
use tilting_plant::{ConfigError, Params};
use tilting_proto::Reference as WireReference;

impl From<&WireReference> for Reference {
    /// The trajectory of a message: [`WireReference::SINUSOID`] gives the sinusoid, any other
    /// kind (validated messages only carry 0 or 1) holds the arm upright.
    fn from(r: &WireReference) -> Self {
        if r.kind == WireReference::SINUSOID {
            Reference::Sinusoid {
                amplitude: r.amplitude,
                omega: r.omega,
            }
        } else {
            Reference::Hold
        }
    }
}

impl ControlConfig {
    /// The law of a planner's message with the model `params`, checked by
    /// [`ControlConfig::validate`] (the error names the field and its range).
    pub fn from_wire(params: Params, r: &WireReference) -> Result<Self, ConfigError> {
        let cfg = ControlConfig {
            params,
            kp: r.kp,
            kd: r.kd,
            k: r.k,
            energy_avg: r.energy_avg,
            reference: Reference::from(r),
            torque_limit: (r.torque_limit > 0.0).then_some(r.torque_limit),
        };
        cfg.validate()?;
        Ok(cfg)
    }

    /// The message that carries this law (the model parameters stay behind).
    pub fn to_wire(&self) -> WireReference {
        let (kind, amplitude, omega) = match self.reference {
            Reference::Hold => (WireReference::HOLD, 0.0, 0.0),
            Reference::Sinusoid { amplitude, omega } => (WireReference::SINUSOID, amplitude, omega),
        };
        WireReference {
            kind,
            amplitude,
            omega,
            kp: self.kp,
            kd: self.kd,
            k: self.k,
            energy_avg: self.energy_avg,
            torque_limit: self.torque_limit.unwrap_or(0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_law_survives_the_round_trip_through_the_message() {
        for reference in [
            Reference::Hold,
            Reference::Sinusoid {
                amplitude: 0.33,
                omega: 1.8,
            },
        ] {
            for torque_limit in [None, Some(40.0)] {
                let cfg = ControlConfig {
                    k: 500.0,
                    energy_avg: 19.9,
                    reference,
                    torque_limit,
                    ..ControlConfig::default()
                };
                let wire = cfg.to_wire();
                assert!(wire.validate().is_ok());
                assert_eq!(ControlConfig::from_wire(cfg.params, &wire).unwrap(), cfg);
            }
        }
    }

    #[test]
    fn an_invalid_law_is_refused_with_its_field() {
        let wire = ControlConfig {
            k: 500.0,
            energy_avg: 19.9,
            ..ControlConfig::default()
        }
        .to_wire();
        let bad = WireReference {
            energy_avg: 0.0,
            ..wire
        };
        let err = ControlConfig::from_wire(Params::default(), &bad).unwrap_err();
        assert!(err.to_string().contains("energy_avg"), "{err}");
    }
}
