//! The law specification: one home for the control law's settings (gains, energy target,
//! desired trajectory, torque limit), in every form they take.
//!
//! - [`LawSpec`]: a complete law, as the controller runs it, the planner publishes it and a
//!   scenario simulates it; its JSON is the `law` of the controller's summary;
//! - [`LawArgs`]: the same settings as flags (`--kp`, `--kd`, `--k`, `--energy-avg`,
//!   `--reference`, `--torque-limit`) and as scenario-file keys (`kp`, `kd`, `k`, `energy_avg`,
//!   `reference`, `torque_limit`), every one optional: a layer over a lower one
//!   ([`LawArgs::over`]). It is flattened into each command and node that takes a law, and
//!   its serde form is a robot file's `[law]` (`tilting live` hands its children the file,
//!   with the law it resolved, not flags);
//! - [`LawRecord`]: the law in the flat layout of the wire message, for the planner's summary
//!   and `live`'s `summary.json`;
//! - the wire message itself ([`tilting_proto::Reference`]) is converted in one place,
//!   [`crate::wire`].
//!
//! A torque limit of 0 means none, in the flags, the files and on the wire.
//!
//! **Adding a law.** A new law is a [`crate::PlannableLaw`] in its own module, registered in
//! [`crate::registry`] (two non-test files): the planner plans it (orbits, continuation,
//! Lyapunov exponents, figures) through the trait, it crosses the wire as a
//! `tilting_proto::LawReference` by its name and parameters, and the controller node builds
//! it by name and runs it as [`Controller::Registered`]. [`LawKind`] and the other variants of
//! [`Controller`] are the paper's law, which the flags (`--law`), the scenario key (`law`) and
//! the protocol-2 `Reference` name; a law that needs those too (`simulate` from a scenario
//! file, the summaries' [`LawSpec`]) becomes a variant of each as well.

use crate::excite::{GovernedExcitation, GovernorStatus};
use crate::robust::{RobustLaw, RobustStatus};
use crate::{ComputedTorque, ControlConfig, Trajectory};
use serde::{Deserialize, Serialize};
use tilting_plant::dynamics::Terms;
use tilting_plant::paper;
use tilting_plant::params::{finite, non_negative};
use tilting_plant::{ConfigError, Mode, Params, State, TorqueLaw};

/// The control laws a spec can name (`--law`, the scenario key `law`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum LawKind {
    /// The paper's computed-torque PD with energy adaptation ([`ComputedTorque`]).
    #[default]
    ComputedTorque,
}

impl LawKind {
    /// Every law.
    pub const ALL: [LawKind; 1] = [LawKind::ComputedTorque];

    /// The law's name in the flags, the files and the JSON (`computed-torque`).
    pub fn name(self) -> &'static str {
        match self {
            LawKind::ComputedTorque => "computed-torque",
        }
    }

    fn is_default(&self) -> bool {
        *self == Self::default()
    }
}

/// The law a spec names, ready to run: a [`TorqueLaw`] for the loops (`simulate`, the
/// controller node, `live`'s nominal run).
#[derive(Debug, Clone, PartialEq)]
pub enum Controller {
    /// [`LawKind::ComputedTorque`].
    ComputedTorque(ComputedTorque),
    /// [`LawKind::ComputedTorque`] with the robust option ([`LawSpec::orbit_peak`]), or
    /// launched from rest onto its orbit ([`LawSpec::orbit_start`], [`RobustLaw::launcher`]):
    /// it keeps a memory of the states it answered, so it must be called once per sample, in
    /// time order ([`crate::robust`]).
    Robust(RobustLaw),
    /// [`LawKind::ComputedTorque`] on the excitation: its amplitude follows the arm's holding
    /// torque ([`crate::excite`]); it keeps a memory of the states it answered, so it must be
    /// called once per sample, in time order.
    Excitation(Box<GovernedExcitation>),
    /// Any other law, built by name from a planner's message through the controller's
    /// [`crate::LawRegistry`] (a [`crate::PlannableLaw`]: no memory).
    Registered(crate::RegisteredLaw),
}

impl Controller {
    /// The law of `cfg.law.law` with validated settings.
    pub fn new(cfg: ControlConfig) -> Result<Self, ConfigError> {
        Ok(match (cfg.law.law, cfg.law.orbit_peak) {
            (LawKind::ComputedTorque, None) => {
                let law = ComputedTorque::new(cfg)?;
                if matches!(cfg.law.reference, Trajectory::Excitation { .. }) {
                    Controller::Excitation(Box::new(GovernedExcitation::new(law)))
                } else if cfg.law.orbit_start.is_some() && cfg.law.reference.adapts() {
                    // A planned orbit: the plain law, launched from rest by the re-entry.
                    Controller::Robust(RobustLaw::launcher(law))
                } else {
                    Controller::ComputedTorque(law)
                }
            }
            (LawKind::ComputedTorque, Some(p)) => {
                Controller::Robust(RobustLaw::new(ComputedTorque::new(cfg)?, p))
            }
        })
    }

    /// The settings.
    pub fn config(&self) -> &ControlConfig {
        match self {
            Controller::ComputedTorque(c) => c.config(),
            Controller::Robust(c) => c.law().config(),
            Controller::Excitation(c) => c.law().config(),
            Controller::Registered(c) => c.config(),
        }
    }

    /// The registered law, if this is one (its name and parameters).
    pub fn registered(&self) -> Option<&crate::RegisteredLaw> {
        match self {
            Controller::Registered(c) => Some(c),
            _ => None,
        }
    }

    /// Whether `other` runs the same law with the same settings (its memory aside: a node
    /// keeps the law it has when a message repeats it).
    pub fn same_law(&self, other: &Controller) -> bool {
        match (self.registered(), other.registered()) {
            (None, None) => self.config() == other.config(),
            (a, b) => a == b,
        }
    }

    /// What the excitation's amplitude governor has found so far (`None` on another
    /// reference).
    pub fn excitation_status(&self) -> Option<GovernorStatus> {
        match self {
            Controller::Excitation(c) => Some(c.status()),
            _ => None,
        }
    }

    /// What the robust option has done so far (`None` without it).
    pub fn robust_status(&self) -> Option<RobustStatus> {
        match self {
            Controller::ComputedTorque(_)
            | Controller::Excitation(_)
            | Controller::Registered(_) => None,
            Controller::Robust(c) => Some(c.status()),
        }
    }

    /// The joint torque (N m) at time `t` (s) in `mode` at the state `x`.
    #[inline(always)]
    pub fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        TorqueLaw::torque(self, t, mode, x)
    }
}

impl TorqueLaw for Controller {
    #[inline(always)]
    fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        match self {
            Controller::ComputedTorque(c) => c.torque(t, mode, x),
            Controller::Robust(c) => c.torque(t, mode, x),
            Controller::Excitation(c) => c.torque(t, mode, x),
            Controller::Registered(c) => c.torque(t, mode, x),
        }
    }

    #[inline(always)]
    fn torque_t(&self, t: f64, mode: Mode, x: &State, params: &Params, terms: &Terms) -> f64 {
        match self {
            Controller::ComputedTorque(c) => TorqueLaw::torque_t(c, t, mode, x, params, terms),
            Controller::Robust(c) => TorqueLaw::torque_t(c, t, mode, x, params, terms),
            Controller::Excitation(c) => c.torque(t, mode, x),
            Controller::Registered(c) => TorqueLaw::torque_t(c, t, mode, x, params, terms),
        }
    }
}

/// A complete control law: the computed-torque PD
/// `v = beta_d_ddot + K_D (beta_d_dot - beta_dot) + K_P (beta_d - beta)` with the adapted
/// stiffness `K_P = K_P0 + k (E_av - E)`, tracking `reference`, the torque clipped to
/// `torque_limit`. [`Default`] is the paper's stabilised
/// orbit (`K_P0 = 100`, `K_D = 14.14`, `k = 500`, `E_av` of the orbit, hold, no limit), the
/// default of every command.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LawSpec {
    /// Which law ([`LawKind`]); left out of the JSON for the paper's.
    #[serde(default, skip_serializing_if = "LawKind::is_default")]
    pub law: LawKind,
    /// Base stiffness gain `K_P0` (1/s^2).
    pub kp: f64,
    /// Damping gain `K_D` (1/s).
    pub kd: f64,
    /// Energy adaptation gain `k` (1/(J s^2)); 0 disables the adaptation.
    pub k: f64,
    /// Average energy `E_av` (J) of the orbit to stabilise (unused when `k = 0`).
    pub energy_avg: f64,
    /// Torque limit (N m): the torque is clipped to `[-limit, limit]`; `None` (`null`) for no
    /// limit.
    pub torque_limit: Option<f64>,
    /// Desired arm trajectory.
    pub reference: Trajectory,
    /// The robust option ([`crate::robust`]): the tilt peak `|alpha|` (rad) to hold by trimming
    /// `E_av` once per tilt, with the re-entry motion from a plate at rest; `None` (left out
    /// of the JSON) for the paper's law. Needs `k > 0`, the hold reference and a sampled loop.
    /// Not carried by the planner's message: a controller keeps its own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit_peak: Option<f64>,
    /// The orbit's start, `[beta, beta_dot]` (rad, rad/s) at the lift-off of a left tilt
    /// (`alpha = 0`, `alpha_dot = 0`), a planned orbit's (`tilting plan orbit --json`): where
    /// a simulation starts, and where the re-entry from a plate at rest hands over to the
    /// orbit law, with the robust option or without it (the plain law is then launched from
    /// rest, [`crate::robust::RobustLaw::launcher`]); `None` (left out of the JSON) for the
    /// paper's orbit start ([`tilting_plant::paper::orbit_x0`]) and no launch. Not carried by
    /// the planner's message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit_start: Option<[f64; 2]>,
    /// How steep the orbit's peak is in the robot's arm mass, `d ln(peak) / d ln(m_l)` (1; a
    /// plan's `peak_per_arm_mass`): the robust trim's gain per tilt is
    /// [`crate::robust::TRIM_GAIN`] times `TRIM_STEEPNESS / |orbit_steepness|` where the
    /// orbit is steeper than the one that gain was tuned on
    /// ([`crate::robust::TRIM_STEEPNESS`]), so that the trim's loop gain per tilt stays that
    /// orbit's; `None` (left out of the JSON): the gain as tuned. Not carried by the planner's
    /// message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit_steepness: Option<f64>,
}

impl Default for LawSpec {
    /// The paper's stabilised orbit ([`tilting_plant::paper`]).
    fn default() -> Self {
        Self {
            law: LawKind::ComputedTorque,
            kp: paper::ORBIT_KP,
            kd: paper::ORBIT_KD,
            k: paper::ORBIT_K,
            energy_avg: paper::ORBIT_ENERGY_AVG,
            torque_limit: None,
            reference: Trajectory::Hold,
            orbit_peak: None,
            orbit_start: None,
            orbit_steepness: None,
        }
    }
}

impl LawSpec {
    /// The paper's gains without adaptation (`k = 0`, `E_av = 0`), holding upright, no limit.
    pub fn without_adaptation() -> Self {
        Self {
            k: 0.0,
            energy_avg: 0.0,
            ..Self::default()
        }
    }

    /// Checks every setting, naming the first bad one and its range (the model parameters are
    /// checked by [`crate::ControlConfig::validate`]).
    pub fn validate(&self) -> Result<(), ConfigError> {
        non_negative("kp", self.kp)?;
        non_negative("kd", self.kd)?;
        non_negative("k", self.k)?;
        finite("energy_avg", self.energy_avg)?;
        if self.k > 0.0 && self.energy_avg <= 0.0 && self.reference.adapts() {
            // The adaptation needs the orbit's average energy; 0 (the default) would make
            // K_P = K_P0 - k E, a large negative stiffness.
            return Err(ConfigError::OutOfRange {
                field: "energy_avg",
                value: self.energy_avg.to_string(),
                allowed: "> 0 (the orbit's average energy in J) when k > 0",
            });
        }
        if let Trajectory::Sinusoid { amplitude, omega }
        | Trajectory::Excitation { amplitude, omega } = self.reference
        {
            finite("amplitude", amplitude)?;
            tilting_plant::params::positive("omega", omega)?;
        }
        if let Some(l) = self.torque_limit {
            if !(l.is_finite() && l > 0.0) {
                return Err(ConfigError::OutOfRange {
                    field: "torque_limit",
                    value: l.to_string(),
                    allowed: "finite and > 0 (N m), or 0 for none",
                });
            }
        }
        if let Some(p) = self.orbit_peak {
            let out = |allowed| ConfigError::OutOfRange {
                field: "orbit_peak",
                value: p.to_string(),
                allowed,
            };
            if !(p.is_finite() && p > 0.0 && p <= ORBIT_PEAK_MAX) {
                return Err(out("in (0, 0.5] rad, or 0 for the paper's law"));
            }
            if self.k <= 0.0 || self.reference != Trajectory::Hold {
                return Err(out(
                    "0 (off) unless k > 0 and the reference is hold: the robust option trims \
                     the energy target of the hold orbit",
                ));
            }
        }
        if let Some(s) = self.orbit_start {
            check_orbit_start(s)?;
        }
        if let Some(s) = self.orbit_steepness {
            if !(s.is_finite() && (0.1..=1e4).contains(&s.abs())) {
                return Err(ConfigError::OutOfRange {
                    field: "orbit_steepness",
                    value: s.to_string(),
                    allowed: "finite, |value| in [0.1, 10000] (d ln peak / d ln m_l)",
                });
            }
        }
        Ok(())
    }
}

impl std::fmt::Display for LawSpec {
    /// One line: `hold, K_P0 = 100, K_D = 14.14, k = 500, E_av = ... J, torque limit none`;
    /// the excitation says it runs without the energy adaptation.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if !self.law.is_default() {
            write!(f, "{} law, ", self.law.name())?;
        }
        if self.reference.adapts() {
            write!(
                f,
                "{}, K_P0 = {}, K_D = {}, k = {}, E_av = {} J, torque limit ",
                self.reference, self.kp, self.kd, self.k, self.energy_avg
            )?;
        } else {
            // The excitation runs without the energy adaptation (k and E_av do not act), its
            // torque clipped below the one that lifts the plate.
            write!(
                f,
                "{}, K_P = {}, K_D = {}, no energy adaptation, amplitude governed by the \
                 arm's holding torque, torque clipped below the plate's lift-off, torque limit ",
                self.reference, self.kp, self.kd
            )?;
        }
        match self.torque_limit {
            Some(l) => write!(f, "{l} N m")?,
            None => f.write_str("none")?,
        }
        if let Some(p) = self.orbit_peak {
            write!(f, ", robust: orbit peak {p} rad")?;
        }
        match self.orbit_start {
            Some([b, bd]) => write!(f, ", orbit start beta = {b} rad, beta_dot = {bd} rad/s"),
            None => Ok(()),
        }
    }
}

/// Largest `|beta - pi/2|` (rad) of an orbit start: a lift-off with the arm further from
/// upright is no tilting orbit of this machine (the paper's starts 2e-4 rad from it).
pub const ORBIT_START_BETA_MAX: f64 = 0.5;
/// Largest `|beta_dot|` (rad/s) of an orbit start (the paper's is 0.498).
pub const ORBIT_START_RATE_MAX: f64 = 10.0;

/// Checks an orbit start `[beta, beta_dot]` against [`ORBIT_START_BETA_MAX`] and
/// [`ORBIT_START_RATE_MAX`], naming the bad component.
pub fn check_orbit_start([b, bd]: [f64; 2]) -> Result<(), ConfigError> {
    let out = |value: f64, allowed| ConfigError::OutOfRange {
        field: "orbit_start",
        value: value.to_string(),
        allowed,
    };
    if !(b.is_finite() && (b - std::f64::consts::FRAC_PI_2).abs() <= ORBIT_START_BETA_MAX) {
        return Err(out(
            b,
            "beta within 0.5 rad of pi/2 (the arm near upright at lift-off)",
        ));
    }
    if !(bd.is_finite() && bd.abs() <= ORBIT_START_RATE_MAX) {
        return Err(out(bd, "beta_dot in [-10, 10] rad/s"));
    }
    Ok(())
}

/// Parses `BETA,BETA_DOT` (rad, rad/s) for `--orbit-start`.
#[cfg(feature = "clap")]
fn parse_orbit_start(s: &str) -> Result<[f64; 2], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    let [b, bd] = v[..] else {
        return Err(format!("expected BETA,BETA_DOT (two numbers), got {s:?}"));
    };
    check_orbit_start([b, bd]).map_err(|e| e.to_string())?;
    Ok([b, bd])
}

/// Largest `--orbit-peak` (rad): far above any orbit of this machine (the paper's tilts reach
/// 0.041 rad), below the fall.
pub const ORBIT_PEAK_MAX: f64 = 0.5;

/// The law's settings as flags and scenario-file keys, each optional: an unset one keeps the
/// value of the layer below ([`LawArgs::over`]). Flatten it with `#[command(flatten)]` into a
/// command's flags and with `#[serde(flatten)]` into a file's keys.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct LawArgs {
    /// The control law [default: computed-torque]
    #[cfg_attr(feature = "clap", arg(long, value_enum))]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub law: Option<LawKind>,
    /// Base stiffness gain K_P0 (1/s^2) [default: 100]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "1/S2", allow_negative_numbers = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kp: Option<f64>,
    /// Damping gain K_D (1/s) [default: 14.14]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "1/S", allow_negative_numbers = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kd: Option<f64>,
    /// Energy adaptation gain k (1/(J s^2)); 0 = off [default: 500]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "1/(J S2)", allow_negative_numbers = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k: Option<f64>,
    /// Target average energy E_av (J) of the adaptation [default: 19.963439703027, the paper's
    /// stabilised orbit; `simulate` keeps it only with the built-in model, gains and reference]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "J", allow_negative_numbers = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy_avg: Option<f64>,
    /// Desired arm trajectory: hold (beta_d = pi/2), sinusoid:A,w (beta_d = A sin(w t) + pi/2,
    /// A in rad, w in rad/s), or excitation[:A,w] (the identification's flat Fourier motion,
    /// at most A rad from upright, base frequency w rad/s) [default: hold]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "hold|sinusoid:A,w|excitation[:A,w]")
    )]
    #[serde(
        default,
        with = "crate::trajectory::text",
        skip_serializing_if = "Option::is_none"
    )]
    pub reference: Option<Trajectory>,
    /// Symmetric torque saturation (N m); 0 = none [default: none]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "NM", allow_negative_numbers = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_limit: Option<f64>,
    /// Robust option: hold tilt peaks |alpha| of this size (rad) by trimming a scale of the
    /// torque once per tilt, and re-enter the orbit when the plate has come to rest; 0 = off
    /// (the paper's law). The paper's orbit at 1 kHz peaks at 0.0413 [default: 0]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "RAD", allow_negative_numbers = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit_peak: Option<f64>,
    /// The orbit's start BETA,BETA_DOT (rad, rad/s) at a left tilt's lift-off: where `live`
    /// starts the plant and where --orbit-peak's re-entry hands over (from `tilting plan
    /// orbit --json`: pi/2 + beta0, beta_dot0) [default: the paper's orbit start]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "BETA,BETA_DOT", value_parser = parse_orbit_start, allow_hyphen_values = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit_start: Option<[f64; 2]>,
    /// How steep the orbit's peak is in the arm's mass, d ln(peak) / d ln(m_l) (a plan's
    /// `peak_per_arm_mass`): --orbit-peak's trim steps more gently on a steeper orbit than the
    /// paper's (-10.9) [default: from --plan, else the paper's orbit's]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "SLOPE", allow_negative_numbers = true)
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit_steepness: Option<f64>,
}

impl LawArgs {
    /// The law of these settings over `base`: each setting given here replaces `base`'s (a
    /// torque limit of 0 meaning none). Not validated.
    pub fn over(&self, base: LawSpec) -> LawSpec {
        LawSpec {
            law: self.law.unwrap_or(base.law),
            kp: self.kp.unwrap_or(base.kp),
            kd: self.kd.unwrap_or(base.kd),
            k: self.k.unwrap_or(base.k),
            energy_avg: self.energy_avg.unwrap_or(base.energy_avg),
            torque_limit: match self.torque_limit {
                Some(0.0) => None,
                Some(l) => Some(l),
                None => base.torque_limit,
            },
            reference: self.reference.unwrap_or(base.reference),
            orbit_peak: match self.orbit_peak {
                Some(0.0) => None,
                Some(p) => Some(p),
                None => base.orbit_peak,
            },
            orbit_start: self.orbit_start.or(base.orbit_start),
            orbit_steepness: self.orbit_steepness.or(base.orbit_steepness),
        }
    }
}

impl From<LawSpec> for LawArgs {
    /// Every setting given (no torque limit as 0); the law only if not the paper's, so that
    /// a child of an older release reads the flags of the paper's law.
    fn from(l: LawSpec) -> Self {
        Self {
            law: (!l.law.is_default()).then_some(l.law),
            kp: Some(l.kp),
            kd: Some(l.kd),
            k: Some(l.k),
            energy_avg: Some(l.energy_avg),
            reference: Some(l.reference),
            torque_limit: Some(l.torque_limit.unwrap_or(0.0)),
            // Only when on, so that a child of an older release reads the flags of the
            // paper's law.
            orbit_peak: l.orbit_peak,
            orbit_start: l.orbit_start,
            orbit_steepness: l.orbit_steepness,
        }
    }
}

/// The law in the flat layout of the wire message ([`tilting_proto::Reference`]) with the
/// trajectory's kind by name: the `reference` of the planner's summary and of `live`'s
/// `summary.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LawRecord {
    /// The law; left out for the paper's.
    #[serde(default, skip_serializing_if = "LawKind::is_default")]
    pub law: LawKind,
    /// `hold` or `sinusoid` ([`Trajectory::name`]).
    pub kind: String,
    /// Sinusoid amplitude (rad); 0 for hold.
    pub amplitude: f64,
    /// Sinusoid frequency (rad/s); 0 for hold.
    pub omega: f64,
    /// `K_P0` (1/s^2).
    pub kp: f64,
    /// `K_D` (1/s).
    pub kd: f64,
    /// `k` (1/(J s^2)).
    pub k: f64,
    /// `E_av` (J).
    pub energy_avg: f64,
    /// Torque limit (N m), 0 for none.
    pub torque_limit: f64,
    /// The robust option's tilt peak (rad); left out when off.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit_peak: Option<f64>,
}

impl From<&LawSpec> for LawRecord {
    fn from(l: &LawSpec) -> Self {
        let (amplitude, omega) = l.reference.sinusoid();
        Self {
            law: l.law,
            kind: l.reference.name().to_owned(),
            amplitude,
            omega,
            kp: l.kp,
            kd: l.kd,
            k: l.k,
            energy_avg: l.energy_avg,
            torque_limit: l.torque_limit.unwrap_or(0.0),
            orbit_peak: l.orbit_peak,
        }
    }
}

#[cfg(all(test, feature = "clap"))]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        law: LawArgs,
    }

    fn parse(args: &[String]) -> LawArgs {
        let argv = std::iter::once("x".to_owned()).chain(args.iter().cloned());
        Cli::try_parse_from(argv).unwrap().law
    }

    #[test]
    fn an_orbit_start_off_the_machine_is_refused_naming_it() {
        let up = std::f64::consts::FRAC_PI_2;
        for bad in [
            [up + 0.6, 0.3],
            [up - 0.6, 0.3],
            [f64::NAN, 0.3],
            [up, 11.0],
            [up, f64::INFINITY],
        ] {
            let l = LawSpec {
                orbit_start: Some(bad),
                ..LawSpec::default()
            };
            let e = l.validate().unwrap_err().to_string();
            assert!(e.contains("orbit_start"), "{e}");
            let flag = format!("--orbit-start={},{}", bad[0], bad[1]);
            assert!(Cli::try_parse_from(["x", flag.as_str()]).is_err(), "{flag}");
        }
        assert!(Cli::try_parse_from(["x", "--orbit-start=1.57"]).is_err());
        let ok = parse(&["--orbit-start=1.5736,-0.3".into()]);
        assert_eq!(ok.orbit_start, Some([1.5736, -0.3]));
    }

    #[test]
    fn unset_flags_keep_the_base_and_zero_limit_is_none() {
        let base = LawSpec {
            torque_limit: Some(3.0),
            ..LawSpec::default()
        };
        assert_eq!(LawArgs::default().over(base), base);
        let l = parse(&[
            "--kd".into(),
            "2".into(),
            "--torque-limit".into(),
            "0".into(),
        ]);
        assert_eq!(
            l.over(base),
            LawSpec {
                kd: 2.0,
                torque_limit: None,
                ..base
            }
        );
    }

    #[test]
    fn the_help_states_the_defaults_of_the_spec() {
        use clap::CommandFactory;
        let help = Cli::command().render_long_help().to_string();
        let d = LawSpec::default();
        for v in [d.kp, d.kd, d.k, d.energy_avg] {
            assert!(help.contains(&format!("[default: {v}")), "{v}: {help}");
        }
        assert!(help.contains(&format!("[default: {}]", d.reference)));
    }

    #[test]
    fn law_names_agree_in_every_form() {
        for l in LawKind::ALL {
            assert_eq!(serde_json::to_value(l).unwrap(), l.name());
            let argv = ["x".to_owned(), format!("--law={}", l.name())];
            assert_eq!(Cli::try_parse_from(argv).unwrap().law.law, Some(l));
        }
        // The name the wire's generic form gives the paper's law (protocol 3).
        assert_eq!(
            LawKind::ComputedTorque.name(),
            tilting_proto::LawReference::PAPER_LAW
        );
    }

    #[test]
    fn json_forms() {
        let l = LawSpec {
            reference: Trajectory::Sinusoid {
                amplitude: 0.2,
                omega: 3.0,
            },
            ..LawSpec::default()
        };
        let v = serde_json::to_value(l).unwrap();
        assert_eq!(v["reference"]["kind"], l.reference.name());
        assert_eq!(v["torque_limit"], serde_json::Value::Null);
        assert_eq!(serde_json::from_value::<LawSpec>(v).unwrap(), l);
        let r = serde_json::to_value(LawRecord::from(&l)).unwrap();
        assert_eq!(r["kind"], "sinusoid");
        assert_eq!(
            (r["omega"].as_f64(), r["torque_limit"].as_f64()),
            (Some(3.0), Some(0.0))
        );
        // The scenario files' text form.
        let a: LawArgs =
            serde_json::from_str(r#"{"reference": "sinusoid:0.2,3", "k": 0}"#).unwrap();
        assert_eq!((a.reference, a.k), (Some(l.reference), Some(0.0)));
    }
}
