//! Control laws for the tilting system: computed torque so that `beta_ddot = v` in every
//! contact mode, a PD law on the arm angle, and the energy-based adaptation of the stiffness
//! gain `K_P = K_P0 + k (E_av - E)` that stabilises the paper's tilting orbit.
//!
//! ```
//! use tilting_controller::{ComputedTorque, ControlConfig};
//! use tilting_plant::{Mode, State};
//! let c = ComputedTorque::new(ControlConfig::default()).unwrap();
//! let tau = c.torque(0.0, Mode::Flat, &State::new(0.0, 1.2, 0.0, 0.0));
//! assert!(tau > 0.0); // pushes the arm back towards upright
//! ```

#![warn(missing_docs)]

pub mod estimate;
pub mod excite;
pub mod law;
#[cfg(feature = "node")]
pub mod node;
pub mod plannable;
pub mod predict;
pub mod registry;
pub mod robust;
pub mod trajectory;
pub mod wire;

pub use estimate::{Estimation, EstimatorArgs, EstimatorChoice};
pub use law::{Controller, LawArgs, LawKind, LawSpec};
pub use plannable::PlannableLaw;
pub use predict::Predictor;
pub use registry::{LawRegistry, RegisteredLaw};
pub use trajectory::Trajectory;

use serde::{Deserialize, Serialize};
use tilting_plant::dynamics::{energy_t, torque_for_beta_ddot_t, Terms};
use tilting_plant::{ConfigError, Mode, Params, State, TorqueLaw};

/// A law with the model it computes with: the settings of the computed-torque PD controller
/// with energy adaptation. Its JSON is the law's, with the model as `params`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ControlConfig {
    /// Model parameters used for the inverse dynamics and the energy.
    pub params: Params,
    /// The law.
    #[serde(flatten)]
    pub law: LawSpec,
}

impl Default for ControlConfig {
    /// The paper's model and gains `K_P = 100`, `K_D = 14.14` ([`tilting_plant::paper`]), no
    /// adaptation, hold upright, no limit ([`LawSpec::without_adaptation`]).
    fn default() -> Self {
        Self::new(Params::default(), LawSpec::without_adaptation())
    }
}

impl ControlConfig {
    /// The law `law` computed with the model `params`.
    pub fn new(params: Params, law: LawSpec) -> Self {
        Self { params, law }
    }

    /// Checks every field, naming the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.params.validate()?;
        self.law.validate()
    }
}

/// Share of the torque that lifts the plate which the excitation may use
/// ([`excitation_torque_limit`]).
pub const EXCITATION_TORQUE_SHARE: f64 = 0.7;

/// The excitation's torque limit (N m): [`EXCITATION_TORQUE_SHARE`] of `f (m_f + m_l) g`, the
/// torque that moves the zero moment point of the model at rest to the plate's edge (docs/
/// model.md, flat: `r_z = f + tau / F_y`). Below it a plate at rest stays flat however far
/// the model is off by up to 30 % in its masses; an arm whose gravity torque passes it cannot
/// be held and falls, unloading the plate, which the amplitude governor
/// ([`crate::excite`]) prevents.
pub fn excitation_torque_limit(p: &tilting_plant::Params) -> f64 {
    EXCITATION_TORQUE_SHARE * p.f * (p.m_f + p.m_l) * p.g
}

/// The computed-torque PD law with energy adaptation. A pure function of `(t, q, x)`, so it
/// serves both inside the integrator (continuous coupling) and once per sample (zero-order
/// hold over the network).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComputedTorque {
    cfg: ControlConfig,
}

impl ComputedTorque {
    /// A controller with validated settings.
    pub fn new(cfg: ControlConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self { cfg })
    }

    /// The settings.
    pub fn config(&self) -> &ControlConfig {
        &self.cfg
    }

    /// The adapted stiffness `K_P = K_P0 + k (E_av - E(x))` (1/s^2).
    #[inline(always)]
    pub fn stiffness(&self, mode: Mode, x: &State) -> f64 {
        self.stiffness_t(mode, x, &Terms::new(&self.cfg.params, mode, x))
    }

    #[inline(always)]
    fn stiffness_t(&self, mode: Mode, x: &State, tr: &Terms) -> f64 {
        if self.cfg.law.k == 0.0 || !self.cfg.law.reference.adapts() {
            self.cfg.law.kp
        } else {
            self.cfg.law.kp
                + self.cfg.law.k
                    * (self.cfg.law.energy_avg - energy_t(&self.cfg.params, mode, x, tr))
        }
    }

    /// The commanded arm acceleration `v = beta_d_ddot + K_D (beta_d_dot - beta_dot) +
    /// K_P (beta_d - beta)` (rad/s^2).
    #[inline(always)]
    pub fn acceleration(&self, t: f64, mode: Mode, x: &State) -> f64 {
        self.acceleration_t(t, mode, x, &Terms::new(&self.cfg.params, mode, x))
    }

    #[inline(always)]
    fn acceleration_t(&self, t: f64, mode: Mode, x: &State, tr: &Terms) -> f64 {
        let (bd, bd_dot, bd_ddot) = self.cfg.law.reference.at(t);
        bd_ddot + self.cfg.law.kd * (bd_dot - x[3]) + self.stiffness_t(mode, x, tr) * (bd - x[1])
    }

    /// The joint torque (N m): the inverse dynamics of `mode` applied to `v`, clipped to the
    /// torque limit if one is set.
    #[inline(always)]
    pub fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        self.torque_t(t, mode, x, &Terms::new(&self.cfg.params, mode, x))
    }

    /// The torque (N m) before the torque limit (the robust option clips after its scale).
    pub(crate) fn unclipped(&self, t: f64, mode: Mode, x: &State) -> f64 {
        self.unclipped_t(t, mode, x, &Terms::new(&self.cfg.params, mode, x))
    }

    #[inline(always)]
    pub(crate) fn unclipped_t(&self, t: f64, mode: Mode, x: &State, tr: &Terms) -> f64 {
        let v = self.acceleration_t(t, mode, x, tr);
        torque_for_beta_ddot_t(&self.cfg.params, mode, x, tr, v)
    }

    /// The clipped torque (N m) for the reference `(beta_d, beta_d_dot, beta_d_ddot)` given
    /// instead of the law's own (the excitation's amplitude governor scales it): the same PD
    /// (without the energy adaptation), inverse dynamics and clips as [`ComputedTorque::torque`].
    pub(crate) fn torque_for_reference(&self, mode: Mode, x: &State, r: (f64, f64, f64)) -> f64 {
        let tr = Terms::new(&self.cfg.params, mode, x);
        let law = &self.cfg.law;
        let v = r.2 + law.kd * (r.1 - x[3]) + law.kp * (r.0 - x[1]);
        let tau = torque_for_beta_ddot_t(&self.cfg.params, mode, x, &tr, v);
        self.clip(tau)
    }

    #[inline(always)]
    fn torque_t(&self, t: f64, mode: Mode, x: &State, tr: &Terms) -> f64 {
        self.clip(self.unclipped_t(t, mode, x, tr))
    }

    /// The torque limit, then (for the excitation) the excitation's clip.
    #[inline(always)]
    fn clip(&self, tau: f64) -> f64 {
        let tau = match self.cfg.law.torque_limit {
            Some(l) => tau.clamp(-l, l),
            None => tau,
        };
        if self.cfg.law.reference.adapts() {
            tau
        } else {
            let l = excitation_torque_limit(&self.cfg.params);
            tau.clamp(-l, l)
        }
    }
}

impl TorqueLaw for ComputedTorque {
    #[inline(always)]
    fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        ComputedTorque::torque(self, t, mode, x)
    }

    #[inline(always)]
    fn torque_t(&self, t: f64, mode: Mode, x: &State, params: &Params, terms: &Terms) -> f64 {
        if *params == self.cfg.params {
            ComputedTorque::torque_t(self, t, mode, x, terms)
        } else {
            // The controller's model differs from the plant's: use its own terms.
            ComputedTorque::torque(self, t, mode, x)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;
    use tilting_plant::dynamics::accelerations;

    #[test]
    fn commanded_acceleration_is_achieved_in_every_mode() {
        let cfg = ControlConfig {
            law: LawSpec {
                k: 300.0,
                energy_avg: 20.0,
                reference: Trajectory::Sinusoid {
                    amplitude: 0.2,
                    omega: 3.0,
                },
                ..LawSpec::without_adaptation()
            },
            ..ControlConfig::default()
        };
        let c = ComputedTorque::new(cfg).unwrap();
        for (mode, x) in [
            (Mode::Flat, State::new(0.0, 1.3, 0.0, 0.4)),
            (Mode::Left, State::new(0.1, 1.7, -0.3, 0.2)),
            (Mode::Right, State::new(-0.2, 1.4, 0.5, -0.6)),
        ] {
            let t = 0.37;
            let tau = c.torque(t, mode, &x);
            let (_, bdd) = accelerations(&cfg.params, mode, &x, tau);
            // v written out from the PD law and the adapted stiffness.
            let (bd, bdd_d, bddd) = (
                0.2 * (3.0 * t).sin() + FRAC_PI_2,
                0.6 * (3.0 * t).cos(),
                -1.8 * (3.0 * t).sin(),
            );
            let kp = 100.0 + 300.0 * (20.0 - tilting_plant::energy(&cfg.params, mode, &x));
            let v = bddd + 14.14 * (bdd_d - x[3]) + kp * (bd - x[1]);
            assert!(
                (bdd - v).abs() < 1e-9 * (1.0 + v.abs()),
                "{mode}: {bdd} vs {v}"
            );
        }
    }

    #[test]
    fn torque_limit_clips() {
        let cfg = ControlConfig {
            law: LawSpec {
                torque_limit: Some(1.5),
                ..LawSpec::without_adaptation()
            },
            ..ControlConfig::default()
        };
        let c = ComputedTorque::new(cfg).unwrap();
        let tau = c.torque(0.0, Mode::Flat, &State::new(0.0, 0.3, 0.0, 0.0));
        assert_eq!(tau, 1.5);
        let tau = c.torque(0.0, Mode::Flat, &State::new(0.0, 2.8, 0.0, 0.0));
        assert_eq!(tau, -1.5);
    }

    #[test]
    fn invalid_settings_name_the_field() {
        for (cfg, field) in [
            (
                ControlConfig {
                    law: LawSpec {
                        kp: -1.0,
                        ..LawSpec::without_adaptation()
                    },
                    ..ControlConfig::default()
                },
                "kp",
            ),
            (
                ControlConfig {
                    law: LawSpec {
                        kd: f64::NAN,
                        ..LawSpec::without_adaptation()
                    },
                    ..ControlConfig::default()
                },
                "kd",
            ),
            (
                ControlConfig {
                    law: LawSpec {
                        k: 500.0,
                        ..LawSpec::without_adaptation()
                    },
                    ..ControlConfig::default()
                },
                "energy_avg",
            ),
            (
                ControlConfig {
                    law: LawSpec {
                        torque_limit: Some(0.0),
                        ..LawSpec::without_adaptation()
                    },
                    ..ControlConfig::default()
                },
                "torque_limit",
            ),
            (
                ControlConfig {
                    law: LawSpec {
                        reference: Trajectory::Sinusoid {
                            amplitude: 0.3,
                            omega: -1.0,
                        },
                        ..LawSpec::without_adaptation()
                    },
                    ..ControlConfig::default()
                },
                "omega",
            ),
        ] {
            let err = ComputedTorque::new(cfg).unwrap_err().to_string();
            assert!(err.contains(field), "{err}");
        }
        assert!("sinusoid:0.3".parse::<Trajectory>().is_err());
        assert!("sinusoid:0.3,0".parse::<Trajectory>().is_err());
        assert_eq!(
            "sinusoid:0.33,5".parse::<Trajectory>().unwrap(),
            Trajectory::Sinusoid {
                amplitude: 0.33,
                omega: 5.0
            }
        );
    }
}
