//! The three contact modes of the hybrid system.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// Discrete contact mode `q`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// `q = 0`: the plate lies flat, `alpha = alpha_dot = 0`.
    Flat,
    /// `q = 1`: tilted over the left edge `(0, 0)`, `alpha > 0`.
    Left,
    /// `q = 2`: tilted over the right edge `(2 f, 0)`, `alpha < 0`.
    Right,
}

impl Mode {
    /// The paper's index `q` (0 flat, 1 left, 2 right), also the wire value.
    pub fn index(self) -> u8 {
        match self {
            Mode::Flat => 0,
            Mode::Left => 1,
            Mode::Right => 2,
        }
    }

    /// Inverse of [`Mode::index`].
    pub fn from_index(q: u8) -> Option<Mode> {
        match q {
            0 => Some(Mode::Flat),
            1 => Some(Mode::Left),
            2 => Some(Mode::Right),
            _ => None,
        }
    }

    /// `"flat"`, `"left"` or `"right"`.
    pub fn as_str(self) -> &'static str {
        match self {
            Mode::Flat => "flat",
            Mode::Left => "left",
            Mode::Right => "right",
        }
    }

    /// The mode under the mirror symmetry (left and right swap).
    pub fn mirrored(self) -> Mode {
        match self {
            Mode::Flat => Mode::Flat,
            Mode::Left => Mode::Right,
            Mode::Right => Mode::Left,
        }
    }

    /// Signed half plate length as seen from the pivot: `+f` for the left pivot, `-f` for the
    /// right one (the right-tilt equations are the left ones with `f -> -f`). Flat uses `+f`
    /// (the world origin is the left edge).
    pub fn signed_f(self, f: f64) -> f64 {
        match self {
            Mode::Right => -f,
            _ => f,
        }
    }

    /// Is the plate tilted?
    pub fn is_tilted(self) -> bool {
        self != Mode::Flat
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Mode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "flat" => Ok(Mode::Flat),
            "left" => Ok(Mode::Left),
            "right" => Ok(Mode::Right),
            other => Err(format!(
                "invalid mode `{other}`: must be flat, left or right"
            )),
        }
    }
}
