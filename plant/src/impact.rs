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
    /// with `alpha_dot+ = -e alpha_dot-` and `c = (1 + e) M12 / M22` (`e > 0`), or passes on
    /// over the striking edge into the other tilt (`e < 0`, [`Landing::PassThrough`])
    /// ([`ImpactLaw::land`]). It never gains kinetic energy: a plastic landing loses
    /// `S alpha_dot-^2 / 2` (`S = M11 - M12^2 / M22` of the mode landed from), a rebound or a
    /// pass-through `(1 - e^2)` times that.
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
    /// The plate passes on over the edge it struck, into the other tilt (the mode landed from,
    /// mirrored): the state just after the impact, `alpha = 0`, `alpha_dot` pointing into the
    /// new tilt. A compliant contact does this: its springs at both edges hand the plate's
    /// rotation on to the striking edge (MuJoCo's landings of the orbit carry 8-14 % of the
    /// landing rate on; docs/mujoco.md).
    PassThrough(State),
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

    /// The landing from `from` with the pre-impact state `x` (`alpha` taken as 0). For the
    /// physical law with `restitution = e != 0`, when the striking edge moves at
    /// [`REBOUND_MIN_SPEED`] or faster after it (`2 f |e alpha_dot-|`): `e > 0`, a rebound
    /// over the same edge, `alpha_dot+ = -e alpha_dot-`; `e < 0`, a pass-through into the
    /// other tilt, `alpha_dot+ = -e sqrt(S_from / S_to) alpha_dot-` (`S = M11 - M12^2 / M22` of
    /// each mode; the factor is 1 without a rotor, and makes the kinetic energy lost exactly
    /// `(1 - e^2) S_from alpha_dot-^2 / 2` with one); `p_beta` kept in both, each side with its
    /// own mode's `M12`. Otherwise [`ImpactLaw::apply`].
    pub fn land(self, p: &Params, from: Mode, x: &State) -> Landing {
        let e = p.restitution;
        if self != ImpactLaw::Physical
            || e == 0.0
            || 2.0 * p.f * (e * x[2]).abs() < REBOUND_MIN_SPEED
        {
            return Landing::Plastic(self.apply(p, from, x));
        }
        if e > 0.0 {
            let c = self.coefficient(p, from, x[1]);
            return Landing::Rebound(State::new(
                0.0,
                x[1],
                -e * x[2],
                x[3] + (1.0 + e) * c * x[2],
            ));
        }
        let to = from.mirrored();
        let (f11, f12, f22) = mass_matrix(p, from, x[1]);
        let (t11, t12, t22) = mass_matrix(p, to, x[1]);
        let (s_from, s_to) = (f11 - f12 * f12 / f22, t11 - t12 * t12 / t22);
        let alpha_dot = -e * (s_from / s_to).sqrt() * x[2];
        let p_beta = f12 * x[2] + f22 * x[3];
        Landing::PassThrough(State::new(
            0.0,
            x[1],
            alpha_dot,
            (p_beta - t12 * alpha_dot) / t22,
        ))
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
