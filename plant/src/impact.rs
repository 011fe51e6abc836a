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
    /// The physical law: the joint carries no impulsive torque, so the landing impulse (at the
    /// striking edge, with the pivot's) leaves the momentum conjugate to `beta`,
    /// `p_beta = M12 alpha_dot + M22 beta_dot`, unchanged; the plate lands plastically
    /// (`c = M12 / M22`) or, with the restitution `e` of [`Params::restitution`], rebounds
    /// with `alpha_dot+ = -e alpha_dot-` and `c = (1 + e) M12 / M22` ([`ImpactLaw::land`]).
    /// It never gains kinetic energy: a plastic landing loses
    /// `(M11 - M12^2 / M22) alpha_dot-^2 / 2`, a rebound `(1 - e^2)` times that.
    Physical,
}

/// A rebound whose striking edge leaves the ground slower than this (m/s) is a plastic
/// landing: it would only add bounces shorter than a millisecond (a geometric series that the
/// Zeno guard would stop), which real contacts and MuJoCo's damp out.
pub const REBOUND_MIN_SPEED: f64 = 0.01;

/// What a landing does: the plate stays down, or it leaves the ground again.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Landing {
    /// The plate rests: the flat-mode state just after the impact.
    Plastic(State),
    /// The plate rebounds into the tilt it landed from: the state just after the impact
    /// (`alpha = 0`, `alpha_dot` pointing away from the ground).
    Rebound(State),
}

impl ImpactLaw {
    /// `"paper"` or `"striking-edge"`.
    pub fn as_str(self) -> &'static str {
        match self {
            ImpactLaw::Paper => "paper",
            ImpactLaw::StrikingEdge => "striking-edge",
            ImpactLaw::Physical => "physical",
        }
    }

    /// The coefficient `c(beta)` of a plastic landing from the tilted mode `from`:
    /// `beta_dot+ = beta_dot- + c alpha_dot-`.
    pub fn coefficient(self, p: &Params, from: Mode, beta: f64) -> f64 {
        let sf = from.signed_f(p.f);
        match self {
            ImpactLaw::Physical => {
                let (_, m12, m22) = mass_matrix(p, from, beta);
                m12 / m22
            }
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

    /// The impact map `h` of a plastic landing: the flat-mode state just after a landing from
    /// `from` with the pre-impact state `x`.
    pub fn apply(self, p: &Params, from: Mode, x: &State) -> State {
        let c = self.coefficient(p, from, x[1]);
        State::new(0.0, x[1], 0.0, x[3] + c * x[2])
    }

    /// The landing from `from` with the pre-impact state `x` (`alpha` taken as 0): a rebound
    /// for the physical law with `restitution = e > 0` when the striking edge leaves at
    /// [`REBOUND_MIN_SPEED`] or faster (`2 f e |alpha_dot-|`), otherwise [`ImpactLaw::apply`].
    pub fn land(self, p: &Params, from: Mode, x: &State) -> Landing {
        let e = p.restitution;
        if self == ImpactLaw::Physical && e > 0.0 && 2.0 * p.f * e * x[2].abs() >= REBOUND_MIN_SPEED
        {
            let c = self.coefficient(p, from, x[1]);
            Landing::Rebound(State::new(
                0.0,
                x[1],
                -e * x[2],
                x[3] + (1.0 + e) * c * x[2],
            ))
        } else {
            Landing::Plastic(self.apply(p, from, x))
        }
    }
}

impl FromStr for ImpactLaw {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "paper" => Ok(ImpactLaw::Paper),
            "striking-edge" => Ok(ImpactLaw::StrikingEdge),
            "physical" => Ok(ImpactLaw::Physical),
            other => Err(format!(
                "invalid impact law `{other}`: must be paper, striking-edge or physical"
            )),
        }
    }
}
