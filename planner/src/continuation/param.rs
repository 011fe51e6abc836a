//! The continuation parameter: which number of the orbit problem moves along a branch.

use crate::orbit::OrbitProblem;
use serde::{Deserialize, Serialize};
use std::str::FromStr;

/// A parameter of [`OrbitProblem`] to continue in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Param {
    /// The energy adaptation gain `k` (1/(J s^2)), `>= 0`.
    K,
    /// The stiffness gain `K_P0` (1/s^2), `> 0`.
    Kp,
    /// The damping gain `K_D` (1/s), `> 0`.
    Kd,
    /// The arm mass `m_l` (kg), `> 0`, of the robot and of the controller's model together.
    Ml,
    /// The robot's arm mass `m_l` (kg), `> 0`, with the controller's model kept at its value: the
    /// arm-mass error of the model.
    MlPlant,
    /// The plate mass `m_f` (kg), `> 0`, of the robot and of the model together.
    Mf,
}

/// Every parameter, in the order of [`Param::NAMES`].
pub const ALL: [Param; 6] = [
    Param::K,
    Param::Kp,
    Param::Kd,
    Param::Ml,
    Param::MlPlant,
    Param::Mf,
];

impl Param {
    /// The flag spellings, in the order of [`ALL`].
    pub const NAMES: [&'static str; 6] = ["k", "kp", "kd", "m_l", "m_l_plant", "m_f"];

    /// The flag spelling.
    pub fn name(self) -> &'static str {
        Self::NAMES[ALL.iter().position(|&p| p == self).expect("listed")]
    }

    /// Its value in `pb`.
    pub fn get(self, pb: &OrbitProblem) -> f64 {
        match self {
            Param::K => pb.control.law.k,
            Param::Kp => pb.control.law.kp,
            Param::Kd => pb.control.law.kd,
            Param::Ml | Param::MlPlant => pb.params.m_l,
            Param::Mf => pb.params.m_f,
        }
    }

    /// Whether `v` is allowed, and the allowed range's text.
    pub fn allows(self, v: f64) -> (bool, &'static str) {
        match self {
            Param::K => (v.is_finite() && v >= 0.0, "finite and >= 0"),
            _ => (v.is_finite() && v > 0.0, "finite and > 0"),
        }
    }

    /// `pb` with this parameter set to `v`, or an error naming the parameter and its range.
    pub fn set(self, pb: &OrbitProblem, v: f64) -> Result<OrbitProblem, String> {
        let (ok, range) = self.allows(v);
        if !ok {
            return Err(format!("invalid `{}` = {v}: must be {range}", self.name()));
        }
        let mut q = *pb;
        match self {
            Param::K => q.control.law.k = v,
            Param::Kp => q.control.law.kp = v,
            Param::Kd => q.control.law.kd = v,
            Param::Ml => {
                q.params.m_l = v;
                q.control.params.m_l = v;
            }
            Param::MlPlant => q.params.m_l = v,
            Param::Mf => {
                q.params.m_f = v;
                q.control.params.m_f = v;
            }
        }
        Ok(q)
    }
}

impl FromStr for Param {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::NAMES
            .iter()
            .position(|&n| n == s)
            .map(|i| ALL[i])
            .ok_or_else(|| {
                format!(
                    "invalid parameter `{s}`: must be one of {}",
                    Self::NAMES.join(", ")
                )
            })
    }
}

impl std::fmt::Display for Param {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
