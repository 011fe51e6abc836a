//! Desired trajectories for the arm angle `beta`.

use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;
use std::str::FromStr;

/// The desired arm trajectory `beta_d(t)` (rad), with `t` in plant seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Reference {
    /// Hold the arm upright: `beta_d = pi/2`.
    Hold,
    /// `beta_d = A sin(w t) + pi/2`.
    Sinusoid {
        /// Amplitude `A` (rad).
        amplitude: f64,
        /// Angular frequency `w` (rad/s).
        omega: f64,
    },
}

impl Reference {
    /// `(beta_d, beta_d_dot, beta_d_ddot)` at time `t` (rad, rad/s, rad/s^2).
    #[inline(always)]
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        match *self {
            Reference::Hold => (FRAC_PI_2, 0.0, 0.0),
            Reference::Sinusoid { amplitude, omega } => {
                let (s, c) = (omega * t).sin_cos();
                (
                    amplitude * s + FRAC_PI_2,
                    amplitude * omega * c,
                    -amplitude * omega * omega * s,
                )
            }
        }
    }
}

impl std::fmt::Display for Reference {
    /// `hold` or `sinusoid:A,w`, the form [`FromStr`] parses (the numbers round-trip).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reference::Hold => f.write_str("hold"),
            Reference::Sinusoid { amplitude, omega } => write!(f, "sinusoid:{amplitude},{omega}"),
        }
    }
}

impl FromStr for Reference {
    type Err = String;
    /// Parses `hold` or `sinusoid:A,w`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!(
                "invalid reference `{s}`: must be hold or sinusoid:A,w (A in rad, w > 0 in rad/s)"
            )
        };
        if s == "hold" {
            return Ok(Reference::Hold);
        }
        let rest = s.strip_prefix("sinusoid:").ok_or_else(bad)?;
        let mut it = rest.split(',').map(|v| v.trim().parse::<f64>());
        match (it.next(), it.next(), it.next()) {
            (Some(Ok(amplitude)), Some(Ok(omega)), None)
                if amplitude.is_finite() && omega.is_finite() && omega > 0.0 =>
            {
                Ok(Reference::Sinusoid { amplitude, omega })
            }
            _ => Err(bad()),
        }
    }
}
