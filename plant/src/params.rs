//! Physical parameters of the tilting system.

use crate::{ImpactLaw, Mode};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Error for a parameter or configuration value outside its allowed range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// A value is outside its allowed range.
    #[error("invalid `{field}` = {value}: must be {allowed}")]
    OutOfRange {
        /// The field, as spelled in the TOML file.
        field: &'static str,
        /// The offending value, formatted.
        value: String,
        /// The allowed range, in words.
        allowed: &'static str,
    },
    /// The TOML text could not be parsed.
    #[error("cannot parse {what}: {message}")]
    Parse {
        /// What was being parsed (a file name or "parameters").
        what: String,
        /// The parser's message (it names the line and the field).
        message: String,
    },
    /// The file could not be read.
    #[error("cannot read {path}: {message}")]
    Io {
        /// The path.
        path: String,
        /// The operating system's message.
        message: String,
    },
}

/// Masses, lengths, gravity, the arm's and motor's inertias and the joint's friction (SI units).
///
/// A foot plate of length `2 f` with a point mass `m_f` at its centre, and an arm of length `l`
/// mounted at the plate centre with its mass `m_l` at the distance `l_c` from the joint (the tip
/// unless given) and the rotational inertia `i_l` about that centre of mass; a motor on the
/// plate whose rotor (inertia `j_m`) turns `n_g` times per turn of the joint; viscous (`b_v`)
/// and Coulomb (`tau_c`) friction at the joint. The defaults are the paper's: point masses, no
/// motor, no friction. The hardware terms are left out of the TOML and JSON forms while they
/// keep their defaults, so the paper's parameters serialize as before. `docs/model.md` gives
/// the equations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Foot plate mass `m_f` (kg).
    pub m_f: f64,
    /// Arm mass `m_l` (kg).
    pub m_l: f64,
    /// Arm length `l` (m): the joint to the tip.
    pub l: f64,
    /// Half the foot plate length `f` (m); the support is `[0, 2 f]`.
    pub f: f64,
    /// Gravitational acceleration `g` (m/s^2).
    pub g: f64,
    /// Distance `l_c` (m) from the joint to the arm's centre of mass, along the arm; `None`
    /// (the default) for the tip, `l` ([`Params::lc`] gives the value).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub l_c: Option<f64>,
    /// The arm's rotational inertia `i_l` (kg m^2) about its centre of mass; 0 (the default)
    /// for a point mass.
    #[serde(skip_serializing_if = "is_zero")]
    pub i_l: f64,
    /// The motor rotor's rotational inertia `j_m` (kg m^2) about its axis; 0 (the default) for
    /// no motor inertia. The stator is fixed to the plate at the joint.
    #[serde(skip_serializing_if = "is_zero")]
    pub j_m: f64,
    /// Gear ratio `n_g` (1): rotor turns relative to the plate per turn of `beta`; default 1
    /// (direct drive). Only `j_m` feels it.
    #[serde(skip_serializing_if = "is_one")]
    pub n_g: f64,
    /// Viscous friction coefficient `b_v` (N m s/rad) at the joint: a torque `-b_v beta_dot`
    /// on the arm; default 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub b_v: f64,
    /// Coulomb friction torque `tau_c` (N m) at the joint: `-tau_c sign(beta_dot)` on the arm
    /// while it slides, and up to `tau_c` either way while it sticks; default 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub tau_c: f64,
    /// The plate's rotational inertia `i_f` (kg m^2) about its centre of mass (the plate turns
    /// with `alpha_dot`); 0 (the default) for the paper's point mass. A uniform plate of mass
    /// `m_f` and length `2 f` has `m_f (2 f)^2 / 12`.
    #[serde(skip_serializing_if = "is_zero")]
    pub i_f: f64,
    /// The landing law: `paper` (the default), `striking-edge` or `physical`
    /// ([`ImpactLaw`]). A `--impact` flag, where a command takes one, overrides it.
    #[serde(skip_serializing_if = "is_paper")]
    pub impact: ImpactLaw,
    /// The plate's signed coefficient of restitution `e` (1) at a landing, in `(-1, 1)`:
    /// `e > 0`, the striking edge leaves the ground again with `e` times the rate it struck
    /// with (a rebound over the same edge); `e < 0`, the plate carries `|e|` of its rate on
    /// over the striking edge into the other tilt (a pass-through, as a compliant contact's
    /// landings do). Only the `physical` law uses it; 0 (the default) is a plastic landing.
    #[serde(skip_serializing_if = "is_zero")]
    pub restitution: f64,
    /// How long (s) the robot's contact sensing may report the plate flat at a pass-through
    /// landing (`restitution < 0`), in `[0, 0.05]`: a compliant contact takes a few
    /// milliseconds to carry the plate from one edge to the other (MuJoCo's stiff contact
    /// about 2 ms), with both edges loaded, where the rigid model passes through at once. A
    /// controller takes a flat report within this long of the first flat report after a
    /// tilt as the tilt the plate passes into ([`Params::sensed_mode`]). 0 (the default):
    /// every flat report is flat.
    #[serde(skip_serializing_if = "is_zero")]
    pub contact_dwell: f64,
}

fn is_paper(v: &ImpactLaw) -> bool {
    *v == ImpactLaw::Paper
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_one(v: &f64) -> bool {
    *v == 1.0
}

impl Default for Params {
    fn default() -> Self {
        Self {
            m_f: 1.0,
            m_l: 1.0,
            l: 2.0,
            f: 0.5,
            g: 9.81,
            l_c: None,
            i_l: 0.0,
            j_m: 0.0,
            n_g: 1.0,
            b_v: 0.0,
            tau_c: 0.0,
            i_f: 0.0,
            impact: ImpactLaw::Paper,
            restitution: 0.0,
            contact_dwell: 0.0,
        }
    }
}

/// The largest [`Params::contact_dwell`] (s): a landing's spring motion longer than this is
/// not a landing the rigid model describes.
pub const MAX_CONTACT_DWELL: f64 = 0.05;

impl Params {
    /// Checks every value, naming the first bad one: the masses, lengths and `g` finite and
    /// `> 0`; `l_c` in `(0, l]`; `n_g` finite and `> 0`; the inertias and friction coefficients
    /// finite and `>= 0`.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (field, v) in [
            ("m_f", self.m_f),
            ("m_l", self.m_l),
            ("l", self.l),
            ("f", self.f),
            ("g", self.g),
            ("n_g", self.n_g),
        ] {
            positive(field, v)?;
        }
        if let Some(lc) = self.l_c {
            if !(lc.is_finite() && lc > 0.0 && lc <= self.l) {
                return Err(ConfigError::OutOfRange {
                    field: "l_c",
                    value: format!("{lc}"),
                    allowed: "finite, > 0 and <= l (the centre of mass lies on the arm)",
                });
            }
        }
        for (field, v) in [
            ("i_l", self.i_l),
            ("j_m", self.j_m),
            ("b_v", self.b_v),
            ("tau_c", self.tau_c),
            ("i_f", self.i_f),
        ] {
            non_negative(field, v)?;
        }
        let e = self.restitution;
        if !(e.is_finite() && e > -1.0 && e < 1.0) {
            return Err(ConfigError::OutOfRange {
                field: "restitution",
                value: format!("{e}"),
                allowed: "finite, > -1 and < 1 (> 0 a rebound, < 0 a pass-through)",
            });
        }
        if e != 0.0 && self.impact != ImpactLaw::Physical {
            return Err(ConfigError::OutOfRange {
                field: "restitution",
                value: format!("{e} (with impact = {})", self.impact.as_str()),
                allowed: "0 unless impact = \"physical\" (only the physical law rebounds)",
            });
        }
        let d = self.contact_dwell;
        if !(d.is_finite() && (0.0..=MAX_CONTACT_DWELL).contains(&d)) {
            return Err(ConfigError::OutOfRange {
                field: "contact_dwell",
                value: format!("{d}"),
                allowed: "finite, >= 0 and <= 0.05 s",
            });
        }
        if d != 0.0 && e >= 0.0 {
            return Err(ConfigError::OutOfRange {
                field: "contact_dwell",
                value: format!("{d} (with restitution = {e})"),
                allowed: "0 unless the landings pass through (restitution < 0)",
            });
        }
        Ok(())
    }

    /// Parses TOML text such as `m_f = 1.0\nl = 2.0` (missing fields keep their defaults) and
    /// validates the result.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let p: Params = toml::from_str(text).map_err(|e| ConfigError::Parse {
            what: "parameters".into(),
            message: e.to_string(),
        })?;
        p.validate()?;
        Ok(p)
    }

    /// Reads and validates a TOML parameter file; a robot file's `[robot]` table, or
    /// `FILE.toml#table` for another table of it ([`crate::robot_file::params_from_file`]).
    pub fn from_toml_file(path: &Path) -> Result<Self, ConfigError> {
        crate::robot_file::params_from_file(path)
    }

    /// The TOML text of these parameters, as `--params` reads it (the hardware keys left out
    /// while at their defaults).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("parameters serialize as TOML")
    }

    /// Total mass `m_f + m_l` (kg).
    pub fn total_mass(&self) -> f64 {
        self.m_f + self.m_l
    }

    /// Distance `l_c` (m) from the joint to the arm's centre of mass: `l` unless set.
    #[inline(always)]
    pub fn lc(&self) -> f64 {
        match self.l_c {
            Some(v) => v,
            None => self.l,
        }
    }

    /// Does any rotational inertia (`i_l`, `j_m` or `i_f`) add to the point masses' mass
    /// matrix?
    #[inline(always)]
    pub fn has_inertia(&self) -> bool {
        self.i_l != 0.0 || self.j_m != 0.0 || self.i_f != 0.0
    }

    /// These parameters with the landing law `law` (and their restitution kept only if `law`
    /// is `physical`, the one law that rebounds).
    pub fn with_impact(mut self, law: ImpactLaw) -> Self {
        self.impact = law;
        if law != ImpactLaw::Physical {
            self.restitution = 0.0;
            self.contact_dwell = 0.0;
        }
        self
    }

    /// The mode a controller takes a sensed `reported` mode for, at `t` (s), in a flat spell
    /// that began at `spell = (t_flat, from)` (the first flat report after a tilt on `from`):
    /// with a pass-through landing (`restitution < 0`) and a [`Params::contact_dwell`], a flat
    /// report within `contact_dwell` of the spell's start is the pass-through in progress, so
    /// the tilt on the other side; otherwise `reported`. (1 ns of slack on the comparison:
    /// sample times on a grid are sums of the period.)
    pub fn sensed_mode(&self, t: f64, reported: Mode, spell: Option<(f64, Mode)>) -> Mode {
        match (reported, spell) {
            (Mode::Flat, Some((t_flat, from)))
                if self.contact_dwell > 0.0 && t - t_flat <= self.contact_dwell + 1e-9 =>
            {
                from.mirrored()
            }
            _ => reported,
        }
    }

    /// The same robot landing plastically: `restitution` and `contact_dwell` 0 (what the
    /// orbit planner's shooting plans).
    pub fn plastic(mut self) -> Self {
        self.restitution = 0.0;
        self.contact_dwell = 0.0;
        self
    }

    /// The landing law of a run: the `--impact` flag when given, else the file's `impact`.
    pub fn impact_or(&self, flag: Option<ImpactLaw>) -> ImpactLaw {
        flag.unwrap_or(self.impact)
    }

    /// The actuated joint's total inertia `J = m_l l_c^2 + i_l + n_g^2 j_m` (kg m^2) about the
    /// joint axis, with the plate held still: the arm's mass at `l_c`, the arm's own rotational
    /// inertia and the rotor reflected through the gear. It is the mass matrix entry `M22` (in
    /// every mode; flat, `tau_j = J beta_ddot + m_l g l_c cos(beta)`) and the curvature
    /// `d^2 T / d beta_dot^2` of the kinetic energy; the identification's arm inertia about the
    /// joint (`pi3 + pi5`).
    #[inline(always)]
    pub fn joint_inertia(&self) -> f64 {
        let lc = self.lc();
        self.m_l * lc * lc + self.inertia().2
    }

    /// The rotational inertias' share of the mass matrix `(I11, I12, I22)` (kg m^2): the arm's
    /// `i_l` turns with `alpha + beta`, the rotor's `j_m` with `alpha + n_g beta`, the plate's
    /// `i_f` with `alpha`, so `I11 = i_l + j_m + i_f`, `I12 = i_l + n_g j_m`,
    /// `I22 = i_l + n_g^2 j_m`.
    #[inline(always)]
    pub fn inertia(&self) -> (f64, f64, f64) {
        (
            self.i_l + self.j_m + self.i_f,
            self.i_l + self.n_g * self.j_m,
            self.i_l + self.n_g * self.n_g * self.j_m,
        )
    }
}

/// Checks that `v` is finite and strictly positive, naming `field` otherwise.
pub fn positive(field: &'static str, v: f64) -> Result<f64, ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::OutOfRange {
            field,
            value: format!("{v}"),
            allowed: "finite and > 0",
        })
    }
}

/// Checks that `v` is finite and not negative, naming `field` otherwise.
pub fn non_negative(field: &'static str, v: f64) -> Result<f64, ConfigError> {
    if v.is_finite() && v >= 0.0 {
        Ok(v)
    } else {
        Err(ConfigError::OutOfRange {
            field,
            value: format!("{v}"),
            allowed: "finite and >= 0",
        })
    }
}

/// Checks that `v` is finite, naming `field` otherwise.
pub fn finite(field: &'static str, v: f64) -> Result<f64, ConfigError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ConfigError::OutOfRange {
            field,
            value: format!("{v}"),
            allowed: "finite",
        })
    }
}

/// Reads a whole text file of at most [`tilting_proto::bounded::CONFIG_LIMIT`] bytes, mapping
/// failure to [`ConfigError::Io`].
pub fn read_text(path: &Path) -> Result<String, ConfigError> {
    use tilting_proto::bounded;
    bounded::read_to_string(path, bounded::CONFIG_LIMIT, "a parameter file").map_err(|e| {
        ConfigError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        }
    })
}
