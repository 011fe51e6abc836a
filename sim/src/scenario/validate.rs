//! Validation of a scenario: every value checked, the first bad one named with its field (as
//! spelled in the scenario file, with the command-line flag) and its allowed range.

use super::*;

/// Largest `|beta|` of an initial state (rad): ten turns.
pub const MAX_ANGLE: f64 = 20.0 * std::f64::consts::PI;
/// Largest initial rate `|alpha_dot|`, `|beta_dot|` (rad/s): about 16 turns per second.
pub const MAX_RATE: f64 = 100.0;

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

pub(super) fn out_of_range(
    field: &str,
    flag: &str,
    value: impl ToString,
    allowed: &str,
) -> ScenarioError {
    ScenarioError::OutOfRange {
        field: field.to_string(),
        flag: flag.to_string(),
        value: value.to_string(),
        allowed: allowed.to_string(),
    }
}

/// Maps a parameter error of the plant or controller crate onto the scenario's naming.
pub(super) fn from_config(e: ConfigError, prefix: &str, flag: &str) -> ScenarioError {
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

/// Maps an error of the law onto the scenario's naming: the key and its flag (the sinusoid's
/// amplitude and frequency are set by `--reference`).
fn law_error(e: ConfigError) -> ScenarioError {
    match e {
        ConfigError::OutOfRange {
            field,
            value,
            allowed,
        } => {
            let flag = match field {
                "amplitude" | "omega" => "--reference".to_owned(),
                f => format!("--{}", f.replace('_', "-")),
            };
            out_of_range(field, &flag, value, allowed)
        }
        other => from_config(other, "", "law"),
    }
}

impl Scenario {
    /// Checks every value, naming the first bad one and its allowed range.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        self.params
            .validate()
            .map_err(|e| from_config(e, "params.", "[params] table or --params file"))?;
        if let Some(p) = &self.plant_params {
            p.validate().map_err(|e| {
                from_config(
                    e,
                    "plant_params.",
                    "[plant_params] table or --plant-params file",
                )
            })?;
        }
        match self.law.validate() {
            // No E_av given (0) while the adaptation is on: say what differs from the built-in
            // scenario, whose E_av would do.
            Err(ConfigError::OutOfRange {
                field: "energy_avg",
                ..
            }) if self.law.energy_avg == 0.0 => return Err(self.missing_energy()),
            r => r.map_err(law_error)?,
        }
        if !(self.duration.is_finite() && self.duration > 0.0 && self.duration <= MAX_DURATION) {
            return Err(out_of_range(
                "duration",
                "--duration",
                self.duration,
                &format!(
                    "finite, > 0 and at most {MAX_DURATION:e} (s): the report keeps every \
                     transition and tilt peak in memory"
                ),
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
        if let (Some(p), 0.0) = (self.law.orbit_peak, cp) {
            return Err(out_of_range(
                "orbit_peak",
                "--orbit-peak",
                p,
                "0 (off) with continuous coupling: the robust option learns from the samples \
                 of a sampled loop; give --control-period T > 0",
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

    /// The error for an adaptation (`k != 0`) without `E_av`.
    fn missing_energy(&self) -> ScenarioError {
        let differs = self.builtin_differences();
        ScenarioError::Missing {
            field: "energy_avg".into(),
            flag: "--energy-avg".into(),
            why: format!(
                "required when k != 0 (k = {}): the built-in E_av = {ORBIT_ENERGY_AVG} J is the \
                 average energy of the paper's orbit and goes only with the built-in k = \
                 {ORBIT_K}, the paper's params, kp = {ORBIT_KP}, kd = {ORBIT_KD}, impact law and \
                 hold reference; here {}; give --energy-avg E (J) or --k 0",
                self.law.k,
                if differs.is_empty() {
                    "energy_avg is 0".to_owned()
                } else {
                    differs.join(", ")
                }
            ),
        }
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
        // Physical bounds: an arm angle beyond a few turns or a rate beyond MAX_RATE is a typo
        // (or a unit mix-up), not a state of this machine; the integrator would only report a
        // non-finite derivative.
        let limits = [
            (1, MAX_ANGLE, "rad"),
            (2, MAX_RATE, "rad/s"),
            (3, MAX_RATE, "rad/s"),
        ];
        for (i, limit, unit) in limits {
            if self.x0[i].abs() > limit {
                return Err(out_of_range(
                    &format!("x0[{i}]"),
                    &flag(i),
                    format!("{:e}", self.x0[i]),
                    &format!("in [-{limit:.0}, {limit:.0}] {unit}"),
                ));
            }
        }
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
            let (alpha_ddot, _) = accelerations(&self.plant_params(), self.mode, &x, tau);
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
