//! A simulation scenario: the model, the initial hybrid state, the controller, the coupling and
//! the run length, with the paper's stabilised tilting orbit as the default.
//!
//! Values come in layers, later ones winning: the built-in defaults, a TOML scenario file
//! (`--scenario`), a TOML parameter file (`--params`, only the `[params]` table), then the
//! command-line flags. The plant may be given other parameters than the controller (model
//! mismatch): a `[plant_params]` table or `--plant-params FILE.toml`; without them the plant has
//! the controller's `params`. [`Scenario::validate`] checks the result and names the offending field
//! and its allowed range.
//!
//! A scenario file holds any subset of the keys, for example
//!
//! ```toml
//! mode = "left"
//! x0 = [0.0, 1.5705814493798966, 0.0, 0.498257789692]
//! kp = 100
//! kd = 14.14
//! k = 500
//! energy_avg = 19.963439703027
//! reference = "hold"            # or "sinusoid:A,w"
//! impact = "paper"              # or "striking-edge"
//! duration = 10                 # s
//! control_period = 0            # s, 0 = continuous coupling
//! torque_limit = 200            # N m, 0 or omit for none
//! rtol = 3e-11                  # the absolute tolerance is rtol / 100
//!
//! [params]                      # missing entries keep the paper's values
//! m_f = 1.0
//! l = 2.0
//! ```

#[cfg(feature = "clap")]
mod args;
mod file;
mod validate;

#[cfg(feature = "clap")]
pub use args::ScenarioArgs;
pub use file::ScenarioFile;
use validate::from_config;
pub use validate::ScenarioError;

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tilting_controller::{ControlConfig, Controller, LawArgs, LawSpec};
use tilting_plant::dynamics::accelerations;
use tilting_plant::paper::{orbit_x0, ORBIT_ENERGY_AVG, ORBIT_K, ORBIT_KD, ORBIT_KP, ORBIT_MODE};
use tilting_plant::{ConfigError, ImpactLaw, Mode, Params, SimConfig, State, Tolerance};

/// Default run length (s).
pub const DEFAULT_DURATION: f64 = 10.0;
/// Allowed relative tolerances of the integrator.
pub const RTOL_RANGE: (f64, f64) = (1e-13, 1e-3);
/// Most zero-order-hold periods in one run (a guard against a period typed in the wrong unit).
pub const MAX_PERIODS: f64 = 1e8;
/// Longest run (s), about 28 hours of plant time: the report keeps every transition and tilt
/// peak in memory, about 0.5 kB per simulated second on the orbit (a tilt every 0.435 s), so a
/// run of this length holds about 50 MB and its JSON about 100 MB.
pub const MAX_DURATION: f64 = 1e5;

/// A complete simulation scenario. [`Default`] is the paper's stabilised orbit: start of a left
/// tilt on the orbit, the law [`LawSpec::default`] (`K_P0 = 100`, `K_D = 14.14`, `k = 500`),
/// 10 s, continuous coupling.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Scenario {
    /// Physical parameters: the controller's model, and the plant's unless `plant_params` is
    /// given.
    pub params: Params,
    /// The plant's own parameters when they differ from the controller's model (model
    /// mismatch); `None`: the plant is the model.
    pub plant_params: Option<Params>,
    /// Initial state `[alpha, beta, alpha_dot, beta_dot]` (rad, rad, rad/s, rad/s).
    pub x0: [f64; 4],
    /// Initial mode.
    pub mode: Mode,
    /// The control law (its model is `params`). With `k != 0` its `energy_avg` is required:
    /// 0 stands for none given (see [`Scenario::resolve`]).
    #[serde(flatten)]
    pub law: LawSpec,
    /// Landing impact law: the `impact` of a layer, else the plant's parameter file's.
    pub impact: ImpactLaw,
    /// Simulated time (s), from `t = 0`.
    pub duration: f64,
    /// Zero-order-hold period of the controller (s); 0 for continuous coupling (the torque law
    /// evaluated inside the integrator).
    pub control_period: f64,
    /// Relative tolerance of the integrator (the absolute one is `rtol / 100`).
    pub rtol: f64,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            params: Params::default(),
            plant_params: None,
            x0: orbit_x0(),
            mode: ORBIT_MODE,
            law: LawSpec::default(),
            impact: ImpactLaw::Paper,
            duration: DEFAULT_DURATION,
            control_period: 0.0,
            rtol: Tolerance::default().rtol,
        }
    }
}

impl Scenario {
    /// Stacks `layers` (later ones win) on the defaults, without validating.
    ///
    /// The built-in `E_av` belongs to the built-in law and to the model it was computed with:
    /// it is dropped (set to 0, so that [`Scenario::validate`] asks for it when `k != 0`)
    /// unless some layer gives `energy_avg` explicitly, or the params, `kp`, `kd`, `k`, impact
    /// law and reference are the built-in ones ([`Scenario::builtin_differences`]), whether
    /// given or not.
    ///
    /// The excitation (`reference = "excitation"`) starts from the arm at rest upright on the
    /// flat plate (`x0 = [0, pi/2, 0, 0]`, `mode = "flat"`), where its ramp starts, unless a
    /// layer gives `x0` or `mode`. A law with an `orbit_start` (a planned orbit's lift-off)
    /// starts there, tilting left, unless a layer gives `x0` or `mode`.
    pub fn resolve(layers: &[&ScenarioFile]) -> Self {
        let mut s = Self::default();
        let mut e_given = false;
        let mut start_given = false;
        let mut impact_given = false;
        for l in layers {
            if let Some(v) = l.params {
                s.params = v;
            }
            if let Some(v) = l.plant_params {
                s.plant_params = Some(v);
            }
            if let Some(v) = l.x0 {
                s.x0 = v;
            }
            if let Some(v) = l.mode {
                s.mode = v;
            }
            start_given |= l.x0.is_some() || l.mode.is_some();
            s.law = l.law.over(s.law);
            e_given |= l.law.energy_avg.is_some();
            if let Some(v) = l.impact {
                s.impact = v;
                impact_given = true;
            }
            if let Some(v) = l.duration {
                s.duration = v;
            }
            if let Some(v) = l.control_period {
                s.control_period = v;
            }
            if let Some(v) = l.rtol {
                s.rtol = v;
            }
        }
        if !impact_given {
            // The robot's own law: the plant's parameter file's `impact` key.
            s.impact = s.plant_params().impact;
        }
        if !e_given && !s.builtin_differences().is_empty() {
            s.law.energy_avg = 0.0;
        }
        if !start_given && !s.law.reference.adapts() {
            s.x0 = [0.0, std::f64::consts::FRAC_PI_2, 0.0, 0.0];
            s.mode = Mode::Flat;
        }
        if let (false, true, Some([beta, beta_dot])) =
            (start_given, s.law.reference.adapts(), s.law.orbit_start)
        {
            // The law's own orbit (a planned one): the run starts at its lift-off.
            s.x0 = [0.0, beta, 0.0, beta_dot];
            s.mode = Mode::Left;
        }
        s
    }

    /// What differs from the built-in scenario among the settings its `E_av` was computed
    /// for (the params, `kp`, `kd`, `k`, impact law and reference), e.g. `["k = 300 (built-in
    /// 500)"]`; empty when none does.
    pub fn builtin_differences(&self) -> Vec<String> {
        let b = Self::default();
        let mut d = Vec::new();
        if self.params != b.params {
            d.push("params (built-in: the paper's)".to_owned());
        }
        for (name, v, bv) in [
            ("kp", self.law.kp, b.law.kp),
            ("kd", self.law.kd, b.law.kd),
            ("k", self.law.k, b.law.k),
        ] {
            if v != bv {
                d.push(format!("{name} = {v} (built-in {bv})"));
            }
        }
        if self.impact != b.impact {
            d.push(format!(
                "impact = {} (built-in {})",
                self.impact.as_str(),
                b.impact.as_str()
            ));
        }
        if self.law.reference != b.law.reference {
            d.push(format!(
                "reference = {} (built-in {})",
                self.law.reference, b.law.reference
            ));
        }
        d
    }

    /// Parses and validates scenario TOML text (missing keys keep the defaults).
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        let file = ScenarioFile::from_toml_str(text).map_err(|message| ScenarioError::File {
            path: PathBuf::from("<scenario>"),
            message,
        })?;
        let s = Self::resolve(&[&file]);
        s.validate()?;
        Ok(s)
    }

    /// Reads and validates a scenario file.
    pub fn from_toml_file(path: &Path) -> Result<Self, ScenarioError> {
        let file = ScenarioFile::from_toml_file(path)?;
        let s = Self::resolve(&[&file]);
        s.validate()?;
        Ok(s)
    }

    /// Is the controller sampled (zero-order hold) rather than continuous?
    pub fn is_sampled(&self) -> bool {
        self.control_period > 0.0
    }

    /// The initial state as a plant state.
    pub fn initial_state(&self) -> State {
        State::from(self.x0)
    }

    /// The plant's parameters: `plant_params`, or the controller's `params`.
    pub fn plant_params(&self) -> Params {
        self.plant_params.unwrap_or(self.params)
    }

    /// The simulator settings: the defaults with this scenario's plant parameters, impact law
    /// and tolerances.
    pub fn sim_config(&self) -> SimConfig {
        SimConfig {
            params: self.plant_params().with_impact(self.impact),
            impact: self.impact,
            tol: Tolerance {
                rtol: self.rtol,
                atol: self.rtol * 1e-2,
            },
            ..SimConfig::default()
        }
    }

    /// The controller settings (its model is `params`, whatever the plant's).
    pub fn control_config(&self) -> ControlConfig {
        ControlConfig::new(self.params, self.law)
    }

    /// The controller: the law the spec names ([`Controller`]).
    pub fn controller(&self) -> Result<Controller, ScenarioError> {
        Controller::new(self.control_config()).map_err(|e| from_config(e, "", "controller"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;
    use tilting_controller::Trajectory;

    #[test]
    fn default_is_valid_and_the_orbit() {
        let s = Scenario::default();
        s.validate().unwrap();
        assert_eq!(s.mode, Mode::Left);
        assert_eq!(s.law.energy_avg, ORBIT_ENERGY_AVG);
        assert_eq!(Scenario::resolve(&[]), s);
    }

    fn law(law: LawArgs) -> ScenarioFile {
        ScenarioFile {
            law,
            ..Default::default()
        }
    }

    #[test]
    fn another_k_needs_explicit_energy() {
        let l = law(LawArgs {
            k: Some(300.0),
            ..Default::default()
        });
        let s = Scenario::resolve(&[&l]);
        assert_eq!(s.law.energy_avg, 0.0);
        let e = s.validate().unwrap_err().to_string();
        // The error says what differs from the built-in scenario.
        assert!(
            e.contains("`energy_avg`") && e.contains("k = 300 (built-in 500)"),
            "{e}"
        );
        let l2 = law(LawArgs {
            energy_avg: Some(20.0),
            ..Default::default()
        });
        // The energy from a lower layer survives a k from a higher one.
        let s = Scenario::resolve(&[&l2, &l]);
        assert_eq!(s.law.energy_avg, 20.0);
        s.validate().unwrap();
        // k = 0 needs no energy.
        let l0 = law(LawArgs {
            k: Some(0.0),
            ..Default::default()
        });
        Scenario::resolve(&[&l0]).validate().unwrap();
    }

    #[test]
    fn the_builtin_k_given_explicitly_keeps_the_builtin_energy() {
        // `--k 500` is the default: the scenario is the built-in one, with or without it.
        let l = law(LawArgs {
            k: Some(ORBIT_K),
            ..Default::default()
        });
        let flat = ScenarioFile {
            mode: Some(Mode::Flat),
            x0: Some([0.0, FRAC_PI_2, 0.0, 0.0]),
            ..Default::default()
        };
        for layers in [vec![&l], vec![&flat, &l]] {
            let s = Scenario::resolve(&layers);
            s.validate().unwrap();
            assert_eq!(s, Scenario::resolve(&layers[..layers.len() - 1]));
            assert_eq!(s.law.energy_avg, ORBIT_ENERGY_AVG);
        }
    }

    #[test]
    fn other_gains_drop_the_builtin_energy_and_say_so() {
        for (l, what) in [
            (
                law(LawArgs {
                    kp: Some(120.0),
                    ..Default::default()
                }),
                "kp = 120 (built-in 100)",
            ),
            (
                law(LawArgs {
                    reference: Some(Trajectory::Sinusoid {
                        amplitude: 0.1,
                        omega: 2.0,
                    }),
                    ..Default::default()
                }),
                "reference = sinusoid:0.1,2 (built-in hold)",
            ),
            (
                ScenarioFile {
                    impact: Some(ImpactLaw::StrikingEdge),
                    ..Default::default()
                },
                "impact = striking-edge (built-in paper)",
            ),
        ] {
            let s = Scenario::resolve(&[&l]);
            assert_eq!(s.law.energy_avg, 0.0);
            let e = s.validate().unwrap_err().to_string();
            assert!(
                e.contains("missing `energy_avg`") && e.contains(what),
                "{e}"
            );
        }
    }

    #[test]
    fn toml_round_trip_and_unknown_field() {
        let s = Scenario::from_toml_str(
            "mode = \"flat\"\nx0 = [0, 1.5, 0, 0]\nk = 0\nreference = \"sinusoid:0.3,5\"\n\
             impact = \"striking-edge\"\nduration = 2\n[params]\nl = 1.5\n",
        )
        .unwrap();
        assert_eq!(s.mode, Mode::Flat);
        assert_eq!(s.params.l, 1.5);
        assert_eq!(s.params.m_f, 1.0);
        assert_eq!(
            s.law.reference,
            Trajectory::Sinusoid {
                amplitude: 0.3,
                omega: 5.0
            }
        );
        assert_eq!(s.impact, ImpactLaw::StrikingEdge);
        let e = Scenario::from_toml_str("durration = 2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("durration"), "{e}");
        let e = Scenario::from_toml_str("[params]\nm_f = -1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("m_f"), "{e}");
    }

    #[test]
    fn a_duration_whose_report_cannot_fit_is_refused() {
        let d = |v: f64| {
            Scenario::resolve(&[&ScenarioFile {
                duration: Some(v),
                ..Default::default()
            }])
            .validate()
        };
        // `tilting simulate --duration 1e12` used to run silently while its report grew without
        // bound; now it fails at once, naming the field, the flag and the range.
        let e = d(1e12).unwrap_err().to_string();
        assert!(e.contains("`duration` (--duration) = 1000000000000"), "{e}");
        assert!(e.contains("at most 1e5 (s)"), "{e}");
        d(MAX_DURATION).unwrap();
        assert!(d(MAX_DURATION * (1.0 + f64::EPSILON)).is_err());
    }

    #[test]
    fn ranges_name_the_field() {
        for (l, field) in [
            (
                ScenarioFile {
                    duration: Some(f64::NAN),
                    ..Default::default()
                },
                "duration",
            ),
            (
                ScenarioFile {
                    control_period: Some(10.0),
                    ..Default::default()
                },
                "control_period",
            ),
            (
                ScenarioFile {
                    control_period: Some(1e-12),
                    ..Default::default()
                },
                "control_period",
            ),
            (
                law(LawArgs {
                    kd: Some(-1.0),
                    ..Default::default()
                }),
                "kd",
            ),
            (
                ScenarioFile {
                    rtol: Some(0.5),
                    ..Default::default()
                },
                "rtol",
            ),
            (
                law(LawArgs {
                    torque_limit: Some(-1.0),
                    ..Default::default()
                }),
                "torque_limit",
            ),
            (
                ScenarioFile {
                    x0: Some([0.0, f64::INFINITY, 0.0, 0.0]),
                    ..Default::default()
                },
                "x0[1]",
            ),
            (
                ScenarioFile {
                    mode: Some(Mode::Right),
                    x0: Some([0.1, 1.5, 0.0, 0.0]),
                    ..Default::default()
                },
                "x0[0]",
            ),
            (
                ScenarioFile {
                    mode: Some(Mode::Flat),
                    x0: Some([0.0, 1.5, 0.3, 0.0]),
                    ..Default::default()
                },
                "x0[2]",
            ),
            (
                ScenarioFile {
                    mode: Some(Mode::Flat),
                    x0: Some([0.0, 1.5, 0.0, 1e300]),
                    ..Default::default()
                },
                "x0[3]",
            ),
        ] {
            let e = Scenario::resolve(&[&l]).validate().unwrap_err().to_string();
            assert!(e.contains(&format!("`{field}`")), "{field}: {e}");
        }
    }

    #[test]
    fn a_tilt_start_into_the_ground_is_rejected() {
        // Upright arm at rest at the start of a left tilt: gravity on the plate centre, which
        // lies right of the left pivot, pushes the plate into the ground.
        let l = ScenarioFile {
            x0: Some([0.0, FRAC_PI_2, 0.0, 0.0]),
            ..Default::default()
        };
        let e = Scenario::resolve(&[&l]).validate().unwrap_err().to_string();
        assert!(e.contains("`x0`"), "{e}");
    }

    #[test]
    fn the_documented_example_file_is_valid() {
        let src = include_str!("mod.rs");
        let start = src.find("//! ```toml\n").unwrap() + "//! ```toml\n".len();
        let end = start + src[start..].find("//! ```").unwrap();
        let text: String = src[start..end]
            .lines()
            .map(|l| l.strip_prefix("//!").unwrap().trim_start().to_string() + "\n")
            .collect();
        let s = Scenario::from_toml_str(&text).unwrap();
        assert_eq!(s.law.torque_limit, Some(200.0));
        assert_eq!(s.law.energy_avg, ORBIT_ENERGY_AVG);
    }
}
