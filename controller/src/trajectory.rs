//! Desired trajectories for the arm angle `beta`.
//!
//! A trajectory has one text form, `hold` or `sinusoid:A,w` ([`Display`](std::fmt::Display) and
//! [`FromStr`]), used by the flags and the scenario files, and one JSON form, an object tagged
//! by `kind` (`{"kind": "hold"}`, `{"kind": "sinusoid", "amplitude": A, "omega": w}`), used by
//! the summaries. Both take the names from [`Trajectory::name`].

use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;
use std::str::FromStr;

const HOLD: &str = "hold";
const SINUSOID: &str = "sinusoid";

/// The desired arm trajectory `beta_d(t)` (rad), with `t` in plant seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Trajectory {
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

impl Trajectory {
    /// `(beta_d, beta_d_dot, beta_d_ddot)` at time `t` (rad, rad/s, rad/s^2).
    #[inline(always)]
    pub fn at(&self, t: f64) -> (f64, f64, f64) {
        match *self {
            Trajectory::Hold => (FRAC_PI_2, 0.0, 0.0),
            Trajectory::Sinusoid { amplitude, omega } => {
                let (s, c) = (omega * t).sin_cos();
                (
                    amplitude * s + FRAC_PI_2,
                    amplitude * omega * c,
                    -amplitude * omega * omega * s,
                )
            }
        }
    }

    /// The kind's name: `hold` or `sinusoid` (as in the text and the JSON forms).
    pub fn name(&self) -> &'static str {
        match self {
            Trajectory::Hold => HOLD,
            Trajectory::Sinusoid { .. } => SINUSOID,
        }
    }

    /// The sinusoid's `(amplitude, omega)` (rad, rad/s); `(0, 0)` for hold.
    pub fn sinusoid(&self) -> (f64, f64) {
        match *self {
            Trajectory::Hold => (0.0, 0.0),
            Trajectory::Sinusoid { amplitude, omega } => (amplitude, omega),
        }
    }
}

impl std::fmt::Display for Trajectory {
    /// `hold` or `sinusoid:A,w`, the form [`FromStr`] parses (the numbers round-trip).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Trajectory::Hold => f.write_str(self.name()),
            Trajectory::Sinusoid { amplitude, omega } => {
                write!(f, "{}:{amplitude},{omega}", self.name())
            }
        }
    }
}

impl FromStr for Trajectory {
    type Err = String;
    /// Parses `hold` or `sinusoid:A,w`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!(
                "invalid reference `{s}`: must be hold or sinusoid:A,w (A in rad, w > 0 in rad/s)"
            )
        };
        if s == HOLD {
            return Ok(Trajectory::Hold);
        }
        let rest = s
            .strip_prefix(SINUSOID)
            .and_then(|r| r.strip_prefix(':'))
            .ok_or_else(bad)?;
        let mut it = rest.split(',').map(|v| v.trim().parse::<f64>());
        match (it.next(), it.next(), it.next()) {
            (Some(Ok(amplitude)), Some(Ok(omega)), None)
                if amplitude.is_finite() && omega.is_finite() && omega > 0.0 =>
            {
                Ok(Trajectory::Sinusoid { amplitude, omega })
            }
            _ => Err(bad()),
        }
    }
}

/// The text form in serde (`"hold"`, `"sinusoid:A,w"`) for an optional trajectory, as the
/// scenario files write it: `#[serde(default, with = "tilting_controller::trajectory::text")]`.
pub mod text {
    use super::Trajectory;
    use serde::{Deserialize, Deserializer, Serializer};

    /// Writes `Some(r)` as its text form.
    pub fn serialize<S: Serializer>(r: &Option<Trajectory>, s: S) -> Result<S::Ok, S::Error> {
        match r {
            Some(r) => s.collect_str(r),
            None => s.serialize_none(),
        }
    }

    /// Reads the text form.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Trajectory>, D::Error> {
        let s = Option::<String>::deserialize(d)?;
        s.map(|s| s.parse().map_err(serde::de::Error::custom))
            .transpose()
    }
}
