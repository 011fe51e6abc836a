//! The discrete contact mode `q`: one type for the wire, the model and every report.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;
use thiserror::Error;

/// Discrete contact mode `q` of the hybrid system; a `u8` on the wire (0 flat, 1 left,
/// 2 right), `"flat"`, `"left"` or `"right"` in text, TOML and JSON.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[repr(u8)]
pub enum Mode {
    /// `q = 0`: the plate lies flat, `alpha = alpha_dot = 0`.
    Flat = 0,
    /// `q = 1`: tilted over the left edge `(0, 0)`, `alpha > 0`.
    Left = 1,
    /// `q = 2`: tilted over the right edge `(2 f, 0)`, `alpha < 0`.
    Right = 2,
}

/// A byte or name that is not a [`Mode`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ModeError {
    /// The wire byte is above 2.
    #[error("mode {0} is out of range; allowed: 0..=2 (0 flat, 1 left, 2 right)")]
    OutOfRange(u8),
    /// The name is not one of `flat`, `left`, `right`.
    #[error("unknown mode {0:?}; allowed: \"flat\", \"left\", \"right\"")]
    UnknownName(String),
}

impl Mode {
    /// The wire byte, which is also the paper's index `q`.
    pub const fn as_u8(self) -> u8 {
        self as u8
    }

    /// `"flat"`, `"left"` or `"right"`.
    pub const fn as_str(self) -> &'static str {
        match self {
            Mode::Flat => "flat",
            Mode::Left => "left",
            Mode::Right => "right",
        }
    }

    /// The mode under the mirror symmetry (left and right swap).
    pub const fn mirrored(self) -> Mode {
        match self {
            Mode::Flat => Mode::Flat,
            Mode::Left => Mode::Right,
            Mode::Right => Mode::Left,
        }
    }

    /// Signed half plate length as seen from the pivot: `+f` for the left pivot, `-f` for the
    /// right one (the right-tilt equations are the left ones with `f -> -f`). Flat uses `+f`
    /// (the world origin is the left edge). `f` in m.
    #[inline(always)]
    pub fn signed_f(self, f: f64) -> f64 {
        match self {
            Mode::Right => -f,
            _ => f,
        }
    }

    /// Is the plate tilted?
    pub const fn is_tilted(self) -> bool {
        !matches!(self, Mode::Flat)
    }
}

impl fmt::Display for Mode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Mode {
    type Err = ModeError;

    /// Parses exactly `"flat"`, `"left"` or `"right"`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "flat" => Ok(Mode::Flat),
            "left" => Ok(Mode::Left),
            "right" => Ok(Mode::Right),
            _ => Err(ModeError::UnknownName(s.to_owned())),
        }
    }
}

impl TryFrom<u8> for Mode {
    type Error = ModeError;

    fn try_from(q: u8) -> Result<Self, Self::Error> {
        match q {
            0 => Ok(Mode::Flat),
            1 => Ok(Mode::Left),
            2 => Ok(Mode::Right),
            _ => Err(ModeError::OutOfRange(q)),
        }
    }
}

impl From<Mode> for u8 {
    fn from(mode: Mode) -> u8 {
        mode.as_u8()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mode_conversions() {
        for (m, b, s) in [
            (Mode::Flat, 0u8, "flat"),
            (Mode::Left, 1, "left"),
            (Mode::Right, 2, "right"),
        ] {
            assert_eq!(m.as_u8(), b);
            assert_eq!(u8::from(m), b);
            assert_eq!(m.as_str(), s);
            assert_eq!(m.to_string(), s);
            assert_eq!(Mode::try_from(b), Ok(m));
            assert_eq!(s.parse::<Mode>(), Ok(m));
        }
        for b in 3..=255u8 {
            assert_eq!(Mode::try_from(b), Err(ModeError::OutOfRange(b)));
        }
        let text = Mode::try_from(3).unwrap_err().to_string();
        assert!(text.contains('3') && text.contains("0..=2"), "{text}");
        for bad in ["", "Flat", "LEFT", " right", "2", "up"] {
            let err = bad.parse::<Mode>().unwrap_err();
            assert_eq!(err, ModeError::UnknownName(bad.to_owned()));
            assert!(err.to_string().contains("\"flat\", \"left\", \"right\""));
        }
    }

    #[test]
    fn mirror_is_an_involution_that_swaps_the_edges() {
        for m in [Mode::Flat, Mode::Left, Mode::Right] {
            assert_eq!(m.mirrored().mirrored(), m);
            assert_eq!(m.mirrored().is_tilted(), m.is_tilted());
            assert_eq!(
                m.mirrored().signed_f(0.5),
                if m.is_tilted() { -m.signed_f(0.5) } else { 0.5 }
            );
        }
    }
}
