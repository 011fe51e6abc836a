//! Physical parameters of the tilting system.

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

/// Masses, lengths and gravity of the tilting system (SI units).
///
/// A foot plate of length `2 f` with a point mass `m_f` at its centre, and an arm of length `l`
/// mounted at the plate centre with a point mass `m_l` at its tip. The defaults are the paper's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Params {
    /// Foot plate mass `m_f` (kg).
    pub m_f: f64,
    /// Arm tip mass `m_l` (kg).
    pub m_l: f64,
    /// Arm length `l` (m).
    pub l: f64,
    /// Half the foot plate length `f` (m); the support is `[0, 2 f]`.
    pub f: f64,
    /// Gravitational acceleration `g` (m/s^2).
    pub g: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            m_f: 1.0,
            m_l: 1.0,
            l: 2.0,
            f: 0.5,
            g: 9.81,
        }
    }
}

impl Params {
    /// Checks that every value is finite and strictly positive.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (field, v) in [
            ("m_f", self.m_f),
            ("m_l", self.m_l),
            ("l", self.l),
            ("f", self.f),
            ("g", self.g),
        ] {
            positive(field, v)?;
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

    /// Reads and validates a TOML parameter file.
    pub fn from_toml_file(path: &Path) -> Result<Self, ConfigError> {
        let text = read_text(path)?;
        Self::from_toml_str(&text).map_err(|e| match e {
            ConfigError::Parse { message, .. } => ConfigError::Parse {
                what: path.display().to_string(),
                message,
            },
            other => other,
        })
    }

    /// Total mass `m_f + m_l` (kg).
    pub fn total_mass(&self) -> f64 {
        self.m_f + self.m_l
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

/// Reads a whole text file, mapping failure to [`ConfigError::Io`].
pub fn read_text(path: &Path) -> Result<String, ConfigError> {
    std::fs::read_to_string(path).map_err(|e| ConfigError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}
