//! The scenario as command-line flags.

use super::*;

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
    /// Parameter file (TOML: m_f, m_l, l, f, g, and the hardware keys l_c, i_l, j_m, n_g, b_v,
    /// tau_c of docs/model.md); overrides the scenario's [params] table
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
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
