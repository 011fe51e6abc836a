//! The scenario as command-line flags.

use super::*;
use tilting_plant::ParamsArgs;

/// The scenario flags shared by the commands that run a simulation. Every flag is optional; an
/// unset flag keeps the scenario file's value, or the default.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct ScenarioArgs {
    /// Initial state alpha,beta,alpha_dot,beta_dot (rad, rad, rad/s, rad/s) [default: start of
    /// the paper's orbit, 0,1.5705814493798966,0,0.498257789692]
    #[arg(long, value_name = "A,B,AD,BD", value_parser = tilting_plant::parse_x0, allow_hyphen_values = true)]
    pub x0: Option<[f64; 4]>,
    /// Initial mode: flat, left or right [default: left]
    #[arg(long, value_name = "MODE")]
    pub mode: Option<Mode>,
    /// The law (`simulate` keeps the built-in E_av only with the built-in model, gains and
    /// reference).
    #[command(flatten)]
    pub law: LawArgs,
    /// Landing impact law: paper, striking-edge or physical [default: the params file's
    /// `impact`, else paper]
    #[arg(long, value_name = "LAW")]
    pub impact: Option<ImpactLaw>,
    /// Simulated time (s) [default: 10]
    #[arg(long, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Zero-order-hold period of the controller (s); 0 for continuous coupling [default: 0]
    #[arg(long, allow_negative_numbers = true)]
    pub control_period: Option<f64>,
    /// Relative tolerance of the integrator; the absolute one is rtol/100 [default: the
    /// plant's default, tilting_plant::Tolerance::default().rtol]
    #[arg(long, allow_negative_numbers = true)]
    pub rtol: Option<f64>,
    /// Scenario file (TOML); flags override its values (--params its [params] table)
    #[arg(long, value_name = "FILE.toml")]
    pub scenario: Option<PathBuf>,
    /// The model's parameter file; overrides the scenario's [params] table.
    #[command(flatten)]
    pub params: ParamsArgs,
    /// The plant's own parameter file (model mismatch: the controller keeps --params); overrides
    /// the scenario's [plant_params] table [default: the plant is the controller's model]
    #[arg(long, value_name = "FILE.toml")]
    pub plant_params: Option<PathBuf>,
}

impl ScenarioArgs {
    /// The flags as a scenario layer.
    pub fn to_layer(&self) -> ScenarioFile {
        ScenarioFile {
            params: None,
            plant_params: None,
            x0: self.x0,
            mode: self.mode,
            law: self.law,
            impact: self.impact,
            duration: self.duration,
            control_period: self.control_period,
            rtol: self.rtol,
        }
    }

    /// Loads the files, stacks defaults, scenario file, parameter file and flags, and validates.
    pub fn load(&self) -> Result<Scenario, ScenarioError> {
        let file = match &self.scenario {
            Some(p) => ScenarioFile::from_toml_file(p)?,
            None => ScenarioFile::default(),
        };
        let read = |p: &PathBuf, flag: &str| {
            Params::from_toml_file(p).map_err(|e| {
                let detail = match e {
                    ConfigError::Parse { message, .. } => message.trim_end().to_string(),
                    other => other.to_string(),
                };
                ScenarioError::File {
                    path: p.clone(),
                    message: format!("invalid parameter file ({flag}): {detail}"),
                }
            })
        };
        let params = ScenarioFile {
            params: self
                .params
                .params
                .as_ref()
                .map(|p| read(p, "--params"))
                .transpose()?,
            plant_params: self
                .plant_params
                .as_ref()
                .map(|p| read(p, "--plant-params"))
                .transpose()?,
            ..ScenarioFile::default()
        };
        let s = Scenario::resolve(&[&file, &params, &self.to_layer()]);
        s.validate()?;
        Ok(s)
    }
}
