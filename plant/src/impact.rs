//! The landing impact: the map `h` from the state just before the plate hits the ground to the
//! state just after.

use crate::dynamics::mass_matrix;
use crate::{Mode, Params, State};
use serde::{Deserialize, Serialize};
use std::str::FromStr;

/// Which angular momentum the landing conserves. After the impact the plate is at rest
/// (`alpha = alpha_dot = 0`) and `beta` is continuous; only `beta_dot` jumps:
/// `beta_dot+ = beta_dot- + c(beta) alpha_dot-`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ImpactLaw {
    /// The paper's law (the default): angular momentum about the pivot edge, i.e. the momentum
    /// conjugate to `alpha`, is kept: `c = M11 / M12`.
    #[default]
    Paper,
    /// The textbook rocking-block law: angular momentum about the edge that strikes the ground,
    /// `c = (m_l l_c^2 + I11 - (m_f + m_l) f^2) / (m_l l_c (l_c - f cos beta) + I12)` (with
    /// `f -> -f` from the right; `I11 = i_l + j_m`, `I12 = i_l + n_g j_m`, zero for the paper's
    /// point masses).
    StrikingEdge,
}

impl ImpactLaw {
    /// `"paper"` or `"striking-edge"`.
    pub fn as_str(self) -> &'static str {
        match self {
            ImpactLaw::Paper => "paper",
            ImpactLaw::StrikingEdge => "striking-edge",
        }
    }

    /// The coefficient `c(beta)` for a landing from the tilted mode `from`.
    pub fn coefficient(self, p: &Params, from: Mode, beta: f64) -> f64 {
        let sf = from.signed_f(p.f);
        match self {
            ImpactLaw::Paper => {
                let (m11, m12, _) = mass_matrix(p, from, beta);
                m11 / m12
            }
            ImpactLaw::StrikingEdge => {
                let l = p.lc();
                let (mut num, mut den) = (p.m_l * l * l, p.m_l * l * (l - sf * beta.cos()));
                // Skipped for point masses: the paper's numbers stay the same bits.
                if p.has_inertia() {
                    let (i11, i12, _) = p.inertia();
                    num += i11;
                    den += i12;
                }
                (num - p.total_mass() * p.f * p.f) / den
            }
        }
    }

    /// The impact map `h`: the flat-mode state just after a landing from `from` with the
    /// pre-impact state `x`.
    pub fn apply(self, p: &Params, from: Mode, x: &State) -> State {
        let c = self.coefficient(p, from, x[1]);
        State::new(0.0, x[1], 0.0, x[3] + c * x[2])
    }
}

impl FromStr for ImpactLaw {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "paper" => Ok(ImpactLaw::Paper),
            "striking-edge" => Ok(ImpactLaw::StrikingEdge),
            other => Err(format!(
                "invalid impact law `{other}`: must be paper or striking-edge"
            )),
        }
    }
}
