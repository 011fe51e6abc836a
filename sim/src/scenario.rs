//! A simulation scenario: the model, the initial hybrid state, the controller, the coupling and
//! the run length, with the paper's stabilised tilting orbit as the default.
//!
//! Values come in layers, later ones winning: the built-in defaults, a TOML scenario file
//! (`--scenario`), a TOML parameter file (`--params`, only the `[params]` table), then the
//! command-line flags. [`Scenario::validate`] checks the result and names the offending field
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
//! torque_limit = 200            # N m, omit for none
//! rtol = 3e-11                  # the absolute tolerance is rtol / 100
//!
//! [params]                      # missing entries keep the paper's values
//! m_f = 1.0
//! l = 2.0
//! ```

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::path::{Path, PathBuf};
use tilting_controller::{ComputedTorque, ControlConfig, Reference};
use tilting_plant::dynamics::accelerations;
use tilting_plant::paper::{orbit_x0, ORBIT_ENERGY_AVG, ORBIT_K, ORBIT_KD, ORBIT_KP, ORBIT_MODE};
use tilting_plant::{ConfigError, ImpactLaw, Mode, Params, SimConfig, State, Tolerance};

/// Default run length (s).
pub const DEFAULT_DURATION: f64 = 10.0;
/// Allowed relative tolerances of the integrator.
pub const RTOL_RANGE: (f64, f64) = (1e-13, 1e-3);
/// Most zero-order-hold periods in one run (a guard against a period typed in the wrong unit).
pub const MAX_PERIODS: f64 = 1e8;

/// A scenario file error or an invalid value. The message names the field (as spelled in the
/// scenario file, with the command-line flag) and its allowed range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// A value is outside its allowed range.
    #[error("invalid `{field}` ({flag}) = {value}: must be {allowed}")]
    OutOfRange {
        /// The scenario-file key.
        field: String,
        /// The flag that sets it.
        flag: String,
        /// The offending value.
        value: String,
        /// The allowed range in words.
        allowed: String,
    },
    /// A required value is missing.
    #[error("missing `{field}` ({flag}): {why}")]
    Missing {
        /// The scenario-file key.
        field: String,
        /// The flag that sets it.
        flag: String,
        /// Why it is needed.
        why: String,
    },
    /// A file could not be read or parsed, or its contents are invalid.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong (the TOML parser names the line and the field).
        message: String,
    },
}

fn out_of_range(field: &str, flag: &str, value: impl ToString, allowed: &str) -> ScenarioError {
    ScenarioError::OutOfRange {
        field: field.to_string(),
        flag: flag.to_string(),
        value: value.to_string(),
        allowed: allowed.to_string(),
    }
}

/// Maps a parameter error of the plant or controller crate onto the scenario's naming.
fn from_config(e: ConfigError, prefix: &str, flag: &str) -> ScenarioError {
    match e {
        ConfigError::OutOfRange {
            field,
            value,
            allowed,
        } => out_of_range(&format!("{prefix}{field}"), flag, value, allowed),
        other => ScenarioError::File {
            path: PathBuf::from(flag),
            message: other.to_string(),
        },
    }
}

/// One layer of scenario values: the contents of a scenario file, or the command-line flags.
/// Every key is optional; a missing key keeps the value of the layer below.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Physical parameters (a `[params]` table; missing entries keep the paper's values).
    pub params: Option<Params>,
    /// Initial state `[alpha, beta, alpha_dot, beta_dot]` (rad, rad, rad/s, rad/s).
    pub x0: Option<[f64; 4]>,
    /// Initial mode: `"flat"`, `"left"` or `"right"`.
    pub mode: Option<Mode>,
    /// Base stiffness gain `K_P0` (1/s^2).
    pub kp: Option<f64>,
    /// Damping gain `K_D` (1/s).
    pub kd: Option<f64>,
    /// Energy adaptation gain `k` (1/(J s^2)).
    pub k: Option<f64>,
    /// Average orbit energy `E_av` (J) for the adaptation.
    pub energy_avg: Option<f64>,
    /// Desired arm trajectory: `"hold"` or `"sinusoid:A,w"`.
    #[serde(default, with = "reference_text")]
    pub reference: Option<Reference>,
    /// Landing impact law: `"paper"` or `"striking-edge"`.
    pub impact: Option<ImpactLaw>,
    /// Simulated time (s).
    pub duration: Option<f64>,
    /// Zero-order-hold period of the controller (s); 0 for continuous coupling.
    pub control_period: Option<f64>,
    /// Torque limit (N m).
    pub torque_limit: Option<f64>,
    /// Relative tolerance of the integrator.
    pub rtol: Option<f64>,
}

impl ScenarioFile {
    /// Parses scenario TOML text (unknown keys are errors).
    pub fn from_toml_str(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| e.to_string().trim_end().to_string())
    }

    /// Reads and parses a scenario file.
    pub fn from_toml_file(path: &Path) -> Result<Self, ScenarioError> {
        let err = |message: String| ScenarioError::File {
            path: path.to_path_buf(),
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
        Self::from_toml_str(&text).map_err(|m| err(format!("invalid scenario file: {m}")))
    }
}

/// The reference as text in TOML: `"hold"` or `"sinusoid:A,w"`.
mod reference_text {
    use super::*;

    pub fn serialize<S: Serializer>(r: &Option<Reference>, s: S) -> Result<S::Ok, S::Error> {
        match r {
            Some(r) => s.serialize_some(&r.to_string()),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Reference>, D::Error> {
        let s = Option::<String>::deserialize(d)?;
        s.map(|s| s.parse().map_err(serde::de::Error::custom))
            .transpose()
    }
}

/// A complete simulation scenario. [`Default`] is the paper's stabilised orbit: start of a left
/// tilt on the orbit, `K_P0 = 100`, `K_D = 14.14`, `k = 500`, 10 s, continuous coupling.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Scenario {
    /// Physical parameters.
    pub params: Params,
    /// Initial state `[alpha, beta, alpha_dot, beta_dot]` (rad, rad, rad/s, rad/s).
    pub x0: [f64; 4],
    /// Initial mode.
    pub mode: Mode,
    /// Base stiffness gain `K_P0` (1/s^2).
    pub kp: f64,
    /// Damping gain `K_D` (1/s).
    pub kd: f64,
    /// Energy adaptation gain `k` (1/(J s^2)); 0 disables the adaptation.
    pub k: f64,
    /// Average orbit energy `E_av` (J); required when `k != 0`.
    pub energy_avg: Option<f64>,
    /// Desired arm trajectory.
    #[serde(serialize_with = "serialize_reference")]
    pub reference: Reference,
    /// Landing impact law.
    pub impact: ImpactLaw,
    /// Simulated time (s), from `t = 0`.
    pub duration: f64,
    /// Zero-order-hold period of the controller (s); 0 for continuous coupling (the torque law
    /// evaluated inside the integrator).
    pub control_period: f64,
    /// Torque limit (N m); `None` for none.
    pub torque_limit: Option<f64>,
    /// Relative tolerance of the integrator (the absolute one is `rtol / 100`).
    pub rtol: f64,
}

fn serialize_reference<S: Serializer>(r: &Reference, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(r)
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            params: Params::default(),
            x0: orbit_x0(),
            mode: ORBIT_MODE,
            kp: ORBIT_KP,
            kd: ORBIT_KD,
            k: ORBIT_K,
            energy_avg: Some(ORBIT_ENERGY_AVG),
            reference: Reference::Hold,
            impact: ImpactLaw::Paper,
            duration: DEFAULT_DURATION,
            control_period: 0.0,
            torque_limit: None,
            rtol: Tolerance::default().rtol,
        }
    }
}

impl Scenario {
    /// Stacks `layers` (later ones win) on the defaults, without validating.
    ///
    /// The built-in `E_av` belongs to the built-in `k` and to the model and gains the orbit was
    /// computed with: it is dropped (so that [`Scenario::validate`] asks for it when `k != 0`)
    /// unless some layer gives `energy_avg` explicitly, or no layer sets `k` and the params,
    /// `kp`, `kd`, impact law and reference are the paper's.
    pub fn resolve(layers: &[&ScenarioFile]) -> Self {
        let mut s = Self::default();
        let mut k_given = false;
        let mut e_given = false;
        for l in layers {
            if let Some(v) = l.params {
                s.params = v;
            }
            if let Some(v) = l.x0 {
                s.x0 = v;
            }
            if let Some(v) = l.mode {
                s.mode = v;
            }
            if let Some(v) = l.kp {
                s.kp = v;
            }
            if let Some(v) = l.kd {
                s.kd = v;
            }
            if let Some(v) = l.k {
                s.k = v;
                k_given = true;
            }
            if let Some(v) = l.energy_avg {
                s.energy_avg = Some(v);
                e_given = true;
            }
            if let Some(v) = l.reference {
                s.reference = v;
            }
            if let Some(v) = l.impact {
                s.impact = v;
            }
            if let Some(v) = l.duration {
                s.duration = v;
            }
            if let Some(v) = l.control_period {
                s.control_period = v;
            }
            if let Some(v) = l.torque_limit {
                s.torque_limit = Some(v);
            }
            if let Some(v) = l.rtol {
                s.rtol = v;
            }
        }
        if !e_given && (k_given || !s.is_paper_model()) {
            s.energy_avg = None;
        }
        s
    }

    /// Are the params, gains, impact law and reference those the built-in orbit (and its
    /// `E_av`) was computed with?
    pub fn is_paper_model(&self) -> bool {
        self.params == Params::default()
            && self.kp == ORBIT_KP
            && self.kd == ORBIT_KD
            && self.impact == ImpactLaw::Paper
            && self.reference == Reference::Hold
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

    /// The simulator settings: the defaults with this scenario's params, impact law and
    /// tolerances.
    pub fn sim_config(&self) -> SimConfig {
        SimConfig {
            params: self.params,
            impact: self.impact,
            tol: Tolerance {
                rtol: self.rtol,
                atol: self.rtol * 1e-2,
            },
            ..SimConfig::default()
        }
    }

    /// The controller settings (the controller's model is the plant's: no model mismatch).
    pub fn control_config(&self) -> ControlConfig {
        ControlConfig {
            params: self.params,
            kp: self.kp,
            kd: self.kd,
            k: self.k,
            energy_avg: self.energy_avg.unwrap_or(0.0),
            reference: self.reference,
            torque_limit: self.torque_limit,
        }
    }

    /// The controller.
    pub fn controller(&self) -> Result<ComputedTorque, ScenarioError> {
        ComputedTorque::new(self.control_config()).map_err(|e| from_config(e, "", "controller"))
    }

    /// Checks every value, naming the first bad one and its allowed range.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.params
            .validate()
            .map_err(|e| from_config(e, "params.", "[params] table or --params file"))?;
        let gain = |field: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(out_of_range(
                    field,
                    &format!("--{field}"),
                    v,
                    "finite and >= 0",
                ))
            }
        };
        gain("kp", self.kp)?;
        gain("kd", self.kd)?;
        gain("k", self.k)?;
        match self.energy_avg {
            Some(e) if !e.is_finite() => {
                return Err(out_of_range("energy_avg", "--energy-avg", e, "finite (J)"))
            }
            None if self.k != 0.0 => {
                return Err(ScenarioError::Missing {
                    field: "energy_avg".into(),
                    flag: "--energy-avg".into(),
                    why: format!(
                        "required when k != 0 (k = {}): the built-in E_av = {ORBIT_ENERGY_AVG} J \
                         is the average energy of the paper's orbit and goes only with the \
                         built-in k and the paper's params, kp = {ORBIT_KP}, kd = {ORBIT_KD}, \
                         impact law and hold reference; give --energy-avg E (J) or --k 0",
                        self.k
                    ),
                });
            }
            _ => {}
        }
        if let Reference::Sinusoid { amplitude, omega } = self.reference {
            if !(amplitude.is_finite() && omega.is_finite() && omega > 0.0) {
                return Err(out_of_range(
                    "reference",
                    "--reference",
                    self.reference,
                    "hold or sinusoid:A,w with A finite (rad) and w finite and > 0 (rad/s)",
                ));
            }
        }
        if !(self.duration.is_finite() && self.duration > 0.0) {
            return Err(out_of_range(
                "duration",
                "--duration",
                self.duration,
                "finite and > 0 (s)",
            ));
        }
        let cp = self.control_period;
        if !(cp.is_finite() && cp >= 0.0 && cp < self.duration) {
            return Err(out_of_range(
                "control_period",
                "--control-period",
                cp,
                &format!(
                    "finite, >= 0 and < duration = {} (s); 0 for continuous coupling",
                    self.duration
                ),
            ));
        }
        if cp > 0.0 && self.duration / cp > MAX_PERIODS {
            return Err(out_of_range(
                "control_period",
                "--control-period",
                cp,
                &format!(
                    "0 or >= duration / {MAX_PERIODS:e} = {:e} s (at most {MAX_PERIODS:e} \
                     controller periods per run)",
                    self.duration / MAX_PERIODS
                ),
            ));
        }
        if let Some(l) = self.torque_limit {
            if !(l.is_finite() && l > 0.0) {
                return Err(out_of_range(
                    "torque_limit",
                    "--torque-limit",
                    l,
                    "finite and > 0 (N m); omit it for no limit",
                ));
            }
        }
        if !(self.rtol.is_finite() && self.rtol >= RTOL_RANGE.0 && self.rtol <= RTOL_RANGE.1) {
            return Err(out_of_range(
                "rtol",
                "--rtol",
                self.rtol,
                &format!("in [{:e}, {:e}]", RTOL_RANGE.0, RTOL_RANGE.1),
            ));
        }
        self.validate_initial_state()?;
        // The controller and plant check again; they must agree with the checks above.
        self.controller()?;
        Ok(())
    }

    fn validate_initial_state(&self) -> Result<(), ScenarioError> {
        const NAMES: [&str; 4] = ["alpha", "beta", "alpha_dot", "beta_dot"];
        for (i, (&v, name)) in self.x0.iter().zip(NAMES).enumerate() {
            if !v.is_finite() {
                return Err(out_of_range(
                    &format!("x0[{i}]"),
                    &format!("{name} in --x0"),
                    v,
                    "finite",
                ));
            }
        }
        let [alpha, _, alpha_dot, _] = self.x0;
        let flag = |i: usize| format!("{} in --x0", NAMES[i]);
        let fall = SimConfig::default().fall_angle;
        match self.mode {
            Mode::Flat => {
                for i in [0, 2] {
                    if self.x0[i] != 0.0 {
                        return Err(out_of_range(
                            &format!("x0[{i}]"),
                            &flag(i),
                            self.x0[i],
                            "0 in mode flat (the plate lies on the ground)",
                        ));
                    }
                }
            }
            Mode::Left if !(0.0..fall).contains(&alpha) => {
                return Err(out_of_range(
                    "x0[0]",
                    &flag(0),
                    alpha,
                    &format!("in [0, {fall}) in mode left"),
                ));
            }
            Mode::Right if !(alpha > -fall && alpha <= 0.0) => {
                return Err(out_of_range(
                    "x0[0]",
                    &flag(0),
                    alpha,
                    &format!("in (-{fall}, 0] in mode right"),
                ));
            }
            _ => {}
        }
        if self.mode.is_tilted() && alpha == 0.0 {
            // At the start of a tilt the plate must rise off the ground. The simulator watches
            // for a landing only once `alpha` has left 0, so a start that drives the plate into
            // the ground would go undetected.
            let s = if self.mode == Mode::Left { 1.0 } else { -1.0 };
            let ctrl = self.controller()?;
            let x = self.initial_state();
            let tau = ctrl.torque(0.0, self.mode, &x);
            let (alpha_ddot, _) = accelerations(&self.params, self.mode, &x, tau);
            if s * alpha_dot < 0.0 || (alpha_dot == 0.0 && s * alpha_ddot < 0.0) {
                return Err(out_of_range(
                    "x0",
                    "--x0 with --mode",
                    format!(
                        "{:?} in mode {} (alpha_ddot = {alpha_ddot:.4} rad/s^2)",
                        self.x0, self.mode
                    ),
                    &format!(
                        "a state that lifts the plate off the ground at alpha = 0: sign(alpha_dot), \
                         or sign(alpha_ddot) under the initial torque if alpha_dot = 0, must be \
                         {} in mode {}; start in mode flat instead",
                        if s > 0.0 { "positive" } else { "negative" },
                        self.mode
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// The scenario flags shared by the commands that run a simulation. Every flag is optional; an
/// unset flag keeps the scenario file's value, or the default.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ScenarioArgs {
    /// Initial state alpha,beta,alpha_dot,beta_dot (rad, rad, rad/s, rad/s) [default: start of
    /// the paper's orbit, 0,1.5705814493798966,0,0.498257789692]
    #[arg(long, value_name = "A,B,AD,BD", value_parser = parse_x0, allow_hyphen_values = true)]
    pub x0: Option<[f64; 4]>,
    /// Initial mode: flat, left or right [default: left]
    #[arg(long, value_name = "MODE")]
    pub mode: Option<Mode>,
    /// Base stiffness gain K_P0 (1/s^2) [default: 100]
    #[arg(long, allow_negative_numbers = true)]
    pub kp: Option<f64>,
    /// Damping gain K_D (1/s) [default: 14.14]
    #[arg(long, allow_negative_numbers = true)]
    pub kd: Option<f64>,
    /// Energy adaptation gain k (1/(J s^2)), 0 to disable [default: 500]
    #[arg(long, allow_negative_numbers = true)]
    pub k: Option<f64>,
    /// Average orbit energy E_av (J) for the adaptation; required when k != 0 unless k and the
    /// model are the defaults [default: 19.963439703027 with the default k]
    #[arg(long, allow_negative_numbers = true)]
    pub energy_avg: Option<f64>,
    /// Desired arm trajectory: hold (beta_d = pi/2) or sinusoid:A,w (beta_d = A sin(w t) + pi/2,
    /// A in rad, w in rad/s) [default: hold]
    #[arg(long, value_name = "hold|sinusoid:A,w")]
    pub reference: Option<Reference>,
    /// Landing impact law: paper or striking-edge [default: paper]
    #[arg(long, value_name = "LAW")]
    pub impact: Option<ImpactLaw>,
    /// Simulated time (s) [default: 10]
    #[arg(long, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Zero-order-hold period of the controller (s); 0 for continuous coupling [default: 0]
    #[arg(long, allow_negative_numbers = true)]
    pub control_period: Option<f64>,
    /// Torque limit (N m) [default: none]
    #[arg(long, allow_negative_numbers = true)]
    pub torque_limit: Option<f64>,
    /// Relative tolerance of the integrator; the absolute one is rtol/100 [default: the
    /// plant's default, tilting_plant::Tolerance::default().rtol]
    #[arg(long, allow_negative_numbers = true)]
    pub rtol: Option<f64>,
    /// Scenario file (TOML); flags override its values
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: Option<PathBuf>,
    /// Parameter file (TOML: m_f, m_l, l, f, g); overrides the scenario's [params] table
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
}

impl ScenarioArgs {
    /// The flags as a scenario layer.
    pub fn to_layer(&self) -> ScenarioFile {
        ScenarioFile {
            params: None,
            x0: self.x0,
            mode: self.mode,
            kp: self.kp,
            kd: self.kd,
            k: self.k,
            energy_avg: self.energy_avg,
            reference: self.reference,
            impact: self.impact,
            duration: self.duration,
            control_period: self.control_period,
            torque_limit: self.torque_limit,
            rtol: self.rtol,
        }
    }

    /// Loads the files, stacks defaults, scenario file, parameter file and flags, and validates.
    pub fn load(&self) -> Result<Scenario, ScenarioError> {
        let file = match &self.scenario {
            Some(p) => ScenarioFile::from_toml_file(p)?,
            None => ScenarioFile::default(),
        };
        let params = match &self.params {
            Some(p) => ScenarioFile {
                params: Some(Params::from_toml_file(p).map_err(|e| {
                    let detail = match e {
                        ConfigError::Parse { message, .. } => message.trim_end().to_string(),
                        other => other.to_string(),
                    };
                    ScenarioError::File {
                        path: p.clone(),
                        message: format!("invalid parameter file (--params): {detail}"),
                    }
                })?),
                ..ScenarioFile::default()
            },
            None => ScenarioFile::default(),
        };
        let s = Scenario::resolve(&[&file, &params, &self.to_layer()]);
        s.validate()?;
        Ok(s)
    }
}

/// Parses `alpha,beta,alpha_dot,beta_dot`.
pub fn parse_x0(s: &str) -> Result<[f64; 4], String> {
    let bad = || {
        format!(
            "invalid x0 `{s}`: must be four comma-separated numbers alpha,beta,alpha_dot,beta_dot \
             (rad, rad, rad/s, rad/s)"
        )
    };
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    v.try_into().map_err(|_| bad())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn default_is_valid_and_the_orbit() {
        let s = Scenario::default();
        s.validate().unwrap();
        assert_eq!(s.mode, Mode::Left);
        assert_eq!(s.energy_avg, Some(ORBIT_ENERGY_AVG));
        assert_eq!(Scenario::resolve(&[]), s);
    }

    #[test]
    fn explicit_k_needs_explicit_energy() {
        let l = ScenarioFile {
            k: Some(300.0),
            ..Default::default()
        };
        let s = Scenario::resolve(&[&l]);
        assert_eq!(s.energy_avg, None);
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("energy_avg"), "{e}");
        let l2 = ScenarioFile {
            energy_avg: Some(20.0),
            ..Default::default()
        };
        // The energy from a lower layer survives a k from a higher one.
        let s = Scenario::resolve(&[&l2, &l]);
        assert_eq!(s.energy_avg, Some(20.0));
        s.validate().unwrap();
        // k = 0 needs no energy.
        let l0 = ScenarioFile {
            k: Some(0.0),
            ..Default::default()
        };
        Scenario::resolve(&[&l0]).validate().unwrap();
    }

    #[test]
    fn other_gains_drop_the_builtin_energy() {
        let l = ScenarioFile {
            kp: Some(120.0),
            ..Default::default()
        };
        assert_eq!(Scenario::resolve(&[&l]).energy_avg, None);
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
            s.reference,
            Reference::Sinusoid {
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
                ScenarioFile {
                    kd: Some(-1.0),
                    ..Default::default()
                },
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
                ScenarioFile {
                    torque_limit: Some(0.0),
                    ..Default::default()
                },
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
        let src = include_str!("scenario.rs");
        let start = src.find("//! ```toml\n").unwrap() + "//! ```toml\n".len();
        let end = start + src[start..].find("//! ```").unwrap();
        let text: String = src[start..end]
            .lines()
            .map(|l| l.strip_prefix("//!").unwrap().trim_start().to_string() + "\n")
            .collect();
        let s = Scenario::from_toml_str(&text).unwrap();
        assert_eq!(s.torque_limit, Some(200.0));
        assert_eq!(s.energy_avg, Some(ORBIT_ENERGY_AVG));
    }

    #[test]
    fn x0_parser() {
        assert_eq!(parse_x0("0, 1.5,-2,3e-1").unwrap(), [0.0, 1.5, -2.0, 0.3]);
        assert!(parse_x0("0,1,2").is_err());
        assert!(parse_x0("0,1,2,x").is_err());
    }
}
