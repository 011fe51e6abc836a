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

/// The ranges a law from the network (or from a node's flags) must lie in. They are wide for
/// this machine (the paper's law is `K_P0 = 100`, `K_D = 14.14`, `k = 500`, `E_av = 20 J`; the
/// sweeps go to `k = 2500`) but shut out a message that decodes and validates and still lies,
/// like `k = 1e12`.
pub mod bounds {
    /// Largest `K_P0` (1/s^2).
    pub const KP_MAX: f64 = 1e4;
    /// Largest `K_D` (1/s).
    pub const KD_MAX: f64 = 1e3;
    /// Largest `k` (1/(J s^2)).
    pub const K_MAX: f64 = 1e4;
    /// Largest `E_av` (J).
    pub const ENERGY_AVG_MAX: f64 = 1e3;
    /// Largest sinusoid amplitude `|A|` (rad): below pi/2, as `tilting plan sinusoid` requires.
    pub const AMPLITUDE_MAX: f64 = 1.5;
    /// Largest sinusoid frequency `w` (rad/s): the range `tilting plan sinusoid` searches.
    pub const OMEGA_MAX: f64 = 30.0;
    /// Largest torque limit (N m).
    pub const TORQUE_LIMIT_MAX: f64 = 1e3;
}

/// Checks a law against [`bounds`] (after [`ControlConfig::validate`]), naming the field and
/// its range.
pub fn check_bounds(cfg: &ControlConfig) -> Result<(), ConfigError> {
    use bounds::*;
    let out = |field: &'static str, value: f64, allowed: &'static str| {
        Err(ConfigError::OutOfRange {
            field,
            value: value.to_string(),
            allowed,
        })
    };
    if cfg.kp > KP_MAX {
        return out("kp", cfg.kp, "in [0, 1e4] 1/s^2");
    }
    if cfg.kd > KD_MAX {
        return out("kd", cfg.kd, "in [0, 1e3] 1/s");
    }
    if cfg.k > K_MAX {
        return out("k", cfg.k, "in [0, 1e4] 1/(J s^2)");
    }
    if cfg.energy_avg.abs() > ENERGY_AVG_MAX {
        return out("energy_avg", cfg.energy_avg, "in [-1e3, 1e3] J");
    }
    if let Reference::Sinusoid { amplitude, omega } = cfg.reference {
        if amplitude.abs() > AMPLITUDE_MAX {
            return out("amplitude", amplitude, "in [-1.5, 1.5] rad");
        }
        if omega > OMEGA_MAX {
            return out("omega", omega, "in (0, 30] rad/s");
        }
    }
    if let Some(l) = cfg.torque_limit {
        if l > TORQUE_LIMIT_MAX {
            return out("torque_limit", l, "in (0, 1e3] N m, or 0 for none");
        }
    }
    Ok(())
}

impl ControlConfig {
    /// The law of a planner's message with the model `params`, checked by
    /// [`ControlConfig::validate`] and [`check_bounds`] (the error names the field and its
    /// range).
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
        check_bounds(&cfg)?;
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
    fn laws_that_validate_but_lie_are_refused_by_the_bounds() {
        let ok = ControlConfig {
            k: 500.0,
            energy_avg: 19.9,
            reference: Reference::Sinusoid {
                amplitude: 0.33,
                omega: 1.8,
            },
            ..ControlConfig::default()
        }
        .to_wire();
        assert!(ControlConfig::from_wire(Params::default(), &ok).is_ok());
        for (bad, field) in [
            (WireReference { k: 1e12, ..ok }, "`k`"),
            (WireReference { kp: 1e5, ..ok }, "`kp`"),
            (WireReference { kd: 2e3, ..ok }, "`kd`"),
            (
                WireReference {
                    energy_avg: 1e6,
                    ..ok
                },
                "`energy_avg`",
            ),
            (
                WireReference {
                    amplitude: 2.0,
                    ..ok
                },
                "`amplitude`",
            ),
            (WireReference { omega: 1e3, ..ok }, "`omega`"),
            (
                WireReference {
                    torque_limit: 1e6,
                    ..ok
                },
                "`torque_limit`",
            ),
        ] {
            assert!(bad.validate().is_ok(), "{field}: a valid message");
            let err = ControlConfig::from_wire(Params::default(), &bad)
                .unwrap_err()
                .to_string();
            assert!(err.contains(field), "{field}: {err}");
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
