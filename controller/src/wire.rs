//! The law on the wire: the one conversion between the planner's message
//! [`tilting_proto::Reference`] and the law [`LawSpec`].
//!
//! The message carries everything of the law but the model parameters (each node keeps its own
//! `--params`); a torque limit of 0 on the wire means none. Its `kind` byte names the
//! trajectory ([`Reference::HOLD`], [`Reference::SINUSOID`], [`Reference::EXCITATION`]); the
//! message is the paper's law's ([`LawKind::ComputedTorque`]). Any other law travels as a
//! `tilting_proto::LawReference` and is built by [`crate::registry`].

use crate::law::LawKind;
use crate::{ControlConfig, LawSpec, Trajectory};
use tilting_plant::{ConfigError, Params};
use tilting_proto::Reference;

impl From<&Reference> for Trajectory {
    /// The trajectory of a message: `kind` gives the sinusoid ([`Reference::SINUSOID`]) or
    /// the excitation ([`Reference::EXCITATION`]), else the arm holds upright.
    fn from(r: &Reference) -> Self {
        trajectory_of(r.kind, r.amplitude, r.omega)
    }
}

/// The trajectory of a message's trajectory byte (`Reference.kind`,
/// `LawReference.trajectory`), amplitude (rad) and frequency (rad/s): hold for any byte but
/// [`Reference::SINUSOID`] and [`Reference::EXCITATION`] (the messages' `validate` refuses
/// them).
pub fn trajectory_of(kind: u8, amplitude: f64, omega: f64) -> Trajectory {
    match kind {
        Reference::SINUSOID => Trajectory::Sinusoid { amplitude, omega },
        Reference::EXCITATION => Trajectory::Excitation { amplitude, omega },
        _ => Trajectory::Hold,
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

/// Checks a law against [`bounds`] (after [`LawSpec::validate`]), naming the field and its
/// range.
pub fn check_bounds(law: &LawSpec) -> Result<(), ConfigError> {
    use bounds::*;
    let out = |field: &'static str, value: f64, allowed: &'static str| {
        Err(ConfigError::OutOfRange {
            field,
            value: value.to_string(),
            allowed,
        })
    };
    if law.kp > KP_MAX {
        return out("kp", law.kp, "in [0, 1e4] 1/s^2");
    }
    if law.kd > KD_MAX {
        return out("kd", law.kd, "in [0, 1e3] 1/s");
    }
    if law.k > K_MAX {
        return out("k", law.k, "in [0, 1e4] 1/(J s^2)");
    }
    if law.energy_avg.abs() > ENERGY_AVG_MAX {
        return out("energy_avg", law.energy_avg, "in [-1e3, 1e3] J");
    }
    if let Trajectory::Sinusoid { amplitude, omega } | Trajectory::Excitation { amplitude, omega } =
        law.reference
    {
        if amplitude.abs() > AMPLITUDE_MAX {
            return out("amplitude", amplitude, "in [-1.5, 1.5] rad");
        }
        if omega > OMEGA_MAX {
            return out("omega", omega, "in (0, 30] rad/s");
        }
    }
    if let Some(l) = law.torque_limit {
        if l > TORQUE_LIMIT_MAX {
            return out("torque_limit", l, "in (0, 1e3] N m, or 0 for none");
        }
    }
    Ok(())
}

impl From<&Reference> for LawSpec {
    /// The law a message carries, as it is (not checked: see [`LawSpec::from_wire`]).
    fn from(r: &Reference) -> Self {
        LawSpec {
            law: LawKind::ComputedTorque,
            kp: r.kp,
            kd: r.kd,
            k: r.k,
            energy_avg: r.energy_avg,
            reference: Trajectory::from(r),
            torque_limit: (r.torque_limit > 0.0).then_some(r.torque_limit),
            // Not on the wire: the controller keeps its own (`Node::on_reference`).
            orbit_peak: None,
            orbit_start: None,
            orbit_steepness: None,
        }
    }
}

impl LawSpec {
    /// The law of a planner's message, checked by [`LawSpec::validate`] and [`check_bounds`]
    /// (the error names the field and its range).
    pub fn from_wire(r: &Reference) -> Result<Self, ConfigError> {
        if r.kind > Reference::EXCITATION {
            return Err(ConfigError::OutOfRange {
                field: "kind",
                value: r.kind.to_string(),
                allowed: "0..=2, the trajectory (another law travels as a LawReference)",
            });
        }
        let law = LawSpec::from(r);
        law.validate()?;
        check_bounds(&law)?;
        Ok(law)
    }

    /// The message that carries this law (the paper's: [`LawKind`] has no other).
    pub fn to_wire(&self) -> Reference {
        let LawKind::ComputedTorque = self.law;
        let kind = match self.reference {
            Trajectory::Hold => Reference::HOLD,
            Trajectory::Sinusoid { .. } => Reference::SINUSOID,
            Trajectory::Excitation { .. } => Reference::EXCITATION,
        };
        let (amplitude, omega) = self.reference.sinusoid();
        Reference {
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

impl ControlConfig {
    /// The law of a planner's message with the model `params` ([`LawSpec::from_wire`]).
    pub fn from_wire(params: Params, r: &Reference) -> Result<Self, ConfigError> {
        let cfg = ControlConfig::new(params, LawSpec::from_wire(r)?);
        params.validate()?;
        Ok(cfg)
    }

    /// The message that carries this law (the model parameters stay behind).
    pub fn to_wire(&self) -> Reference {
        self.law.to_wire()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_law_survives_the_round_trip_through_the_message() {
        for reference in [
            Trajectory::Hold,
            Trajectory::Sinusoid {
                amplitude: 0.33,
                omega: 1.8,
            },
            Trajectory::Excitation {
                amplitude: 0.4,
                omega: 1.2,
            },
        ] {
            for torque_limit in [None, Some(40.0)] {
                let cfg = ControlConfig {
                    law: LawSpec {
                        k: 500.0,
                        energy_avg: 19.9,
                        reference,
                        torque_limit,
                        ..LawSpec::without_adaptation()
                    },
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
            law: LawSpec {
                k: 500.0,
                energy_avg: 19.9,
                reference: Trajectory::Sinusoid {
                    amplitude: 0.33,
                    omega: 1.8,
                },
                ..LawSpec::without_adaptation()
            },
            ..ControlConfig::default()
        }
        .to_wire();
        assert!(ControlConfig::from_wire(Params::default(), &ok).is_ok());
        for (bad, field) in [
            (Reference { k: 1e12, ..ok }, "`k`"),
            (Reference { kp: 1e5, ..ok }, "`kp`"),
            (Reference { kd: 2e3, ..ok }, "`kd`"),
            (
                Reference {
                    energy_avg: 1e6,
                    ..ok
                },
                "`energy_avg`",
            ),
            (
                Reference {
                    amplitude: 2.0,
                    ..ok
                },
                "`amplitude`",
            ),
            (Reference { omega: 1e3, ..ok }, "`omega`"),
            (
                Reference {
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
            law: LawSpec {
                k: 500.0,
                energy_avg: 19.9,
                ..LawSpec::without_adaptation()
            },
            ..ControlConfig::default()
        }
        .to_wire();
        let bad = Reference {
            energy_avg: 0.0,
            ..wire
        };
        let err = ControlConfig::from_wire(Params::default(), &bad).unwrap_err();
        assert!(err.to_string().contains("energy_avg"), "{err}");
    }
}
