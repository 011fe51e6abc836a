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
