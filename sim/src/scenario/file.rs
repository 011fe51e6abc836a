//! One layer of scenario values as a TOML file.

use super::*;

/// One layer of scenario values: the contents of a scenario file, or the command-line flags.
/// Every key is optional; a missing key keeps the value of the layer below.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Physical parameters (a `[params]` table; missing entries keep the paper's values).
    pub params: Option<Params>,
    /// The plant's own parameters (a `[plant_params]` table; missing entries keep the paper's
    /// values): a plant that differs from the controller's model.
    pub plant_params: Option<Params>,
    /// Initial state `[alpha, beta, alpha_dot, beta_dot]` (rad, rad, rad/s, rad/s).
    pub x0: Option<[f64; 4]>,
    /// Initial mode: `"flat"`, `"left"` or `"right"`.
    pub mode: Option<Mode>,
    /// The law's keys (`kp`, `kd`, `k`, `energy_avg`, `reference` as `"hold"` or
    /// `"sinusoid:A,w"`, `torque_limit`).
    #[serde(flatten)]
    pub law: LawArgs,
    /// Landing impact law: `"paper"` or `"striking-edge"`.
    pub impact: Option<ImpactLaw>,
    /// Simulated time (s).
    pub duration: Option<f64>,
    /// Zero-order-hold period of the controller (s); 0 for continuous coupling.
    pub control_period: Option<f64>,
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
        use tilting_proto::bounded;
        let text = bounded::read_to_string(path, bounded::CONFIG_LIMIT, "a scenario file")
            .map_err(|e| err(format!("cannot read: {e}")))?;
        Self::from_toml_str(&text).map_err(|m| err(format!("invalid scenario file: {m}")))
    }
}
