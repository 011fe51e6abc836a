//! Desired trajectories for the arm angle `beta`.
//!
//! A trajectory has one text form, `hold`, `sinusoid:A,w`, `excitation` or `excitation:A,w`
//! ([`Display`](std::fmt::Display) and [`FromStr`]), used by the flags and the scenario files,
//! and one JSON form, an object tagged by `kind` (`{"kind": "hold"}`, `{"kind": "sinusoid",
//! "amplitude": A, "omega": w}`, the same for `excitation`), used by the summaries. Both take
//! the names from [`Trajectory::name`].
//!
//! **The excitation** ([`Trajectory::Excitation`]) is the motion `tilting identify` wants
//! (Swevers et al.'s periodic excitation: a finite Fourier series): `beta_d = pi/2 + A e(t)
//! s(w t)`, `s(theta) = sum_k c_k sin(n_k theta + phi_k)` over the harmonics [`HARMONICS`]
//! with weights `c_k` summing to 1, so `|beta_d - pi/2| <= A` by the triangle inequality, its
//! rate `<= A w sum c_k n_k` and its acceleration `<= A w^2 sum c_k n_k^2` (plus the ramp's
//! share). `e(t)` ramps from 0 to 1 over the first period `2 pi / w` with zero rate and
//! acceleration at both ends (a quintic), so the motion starts from the arm at rest upright.
//! The law runs it without the energy adaptation ([`Trajectory::adapts`]), clips its torque
//! to 70 % of the torque that lifts the plate (`tilting_controller::excitation_torque_limit`),
//! and scales its amplitude down on an arm too heavy for it, measured on line
//! (`tilting_controller::excite`), so the plate stays flat: the excitation shows the arm's
//! equation (`m_l l_c`, the arm's inertia about the joint, friction); tilts (an orbit run)
//! show `m_f`.

use serde::{Deserialize, Serialize};
use std::f64::consts::FRAC_PI_2;
use std::str::FromStr;

const HOLD: &str = "hold";
const SINUSOID: &str = "sinusoid";
const EXCITATION: &str = "excitation";

/// The excitation's harmonics `(n_k, c_k, phi_k)`: multiple of the base frequency, weight
/// (the weights sum to 1), phase (rad, spread so that the peaks of the harmonics do not
/// line up). Four harmonics, as Swevers' series uses a handful: the accelerations vary over
/// a decade of frequencies, which separates inertia (acceleration), friction (rate) and
/// gravity (angle) in the regressor.
pub const HARMONICS: [(f64, f64, f64); 4] = [
    (1.0, 0.45, 0.0),
    (2.0, 0.25, 1.3),
    (3.0, 0.18, 2.6),
    (5.0, 0.12, 4.4),
];

/// The default excitation `excitation` (`excitation:0.3,0.6`): at most 0.3 rad about
/// upright, base frequency 0.6 rad/s (period 10.5 s; rates up to about 0.4 rad/s,
/// accelerations up to about 1 rad/s^2). With the law's torque clipped below the torque that
/// lifts the plate (`tilting_controller::excitation_torque_limit`) the paper's robot follows
/// it flat (saturating at its turning points: the arm's gravity torque at its largest
/// excursion is 81 % of the clip); a heavier arm gets a smaller amplitude from the governor
/// (`tilting_controller::excite`: 0.25 rad for a 20 % heavier one), so every robot 20 % off
/// the paper's stays flat (docs/identify.md). See [`Trajectory::Excitation`].
pub const EXCITATION_DEFAULT: Trajectory = Trajectory::Excitation {
    amplitude: 0.3,
    omega: 0.6,
};

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
    /// The identification's excitation (module docs): `beta_d = pi/2 + A e(t) s(w t)`, a
    /// finite Fourier series ramped in over the first period, tracked without the energy
    /// adaptation. `|beta_d - pi/2| <= |A|`; the law may scale `A` down
    /// (`tilting_controller::excite`).
    Excitation {
        /// Amplitude bound `A` (rad).
        amplitude: f64,
        /// Base angular frequency `w` (rad/s).
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
            Trajectory::Excitation { amplitude, omega } => {
                let (s, ds, dds) = series(omega * t);
                let (e, de, dde) = ramp(omega * t / std::f64::consts::TAU);
                // d/dt: the series by omega, the ramp by omega / 2 pi.
                let (ds, dds) = (omega * ds, omega * omega * dds);
                let r = omega / std::f64::consts::TAU;
                let (de, dde) = (r * de, r * r * dde);
                (
                    FRAC_PI_2 + amplitude * e * s,
                    amplitude * (de * s + e * ds),
                    amplitude * (dde * s + 2.0 * de * ds + e * dds),
                )
            }
        }
    }

    /// The excitation with its amplitude scaled by a time-varying factor `r(t)` given with its
    /// first two time derivatives `(r, r_dot, r_ddot)` (1, 1/s, 1/s^2): `beta_d = pi/2 + A r(t)
    /// e(t) s(w t)` and its exact rate and acceleration (rad, rad/s, rad/s^2). With `r = (1, 0,
    /// 0)` it is [`Trajectory::at`]; any other trajectory ignores `r`. The amplitude governor
    /// of [`crate::excite`] scales the excitation this way.
    #[inline(always)]
    pub fn at_scaled(&self, t: f64, r: (f64, f64, f64)) -> (f64, f64, f64) {
        let Trajectory::Excitation { amplitude, omega } = *self else {
            return self.at(t);
        };
        let (s, ds, dds) = series(omega * t);
        let (e, de, dde) = ramp(omega * t / std::f64::consts::TAU);
        let (ds, dds) = (omega * ds, omega * omega * dds);
        let w = omega / std::f64::consts::TAU;
        let (de, dde) = (w * de, w * w * dde);
        // g = r e, the scaled ramp, and its derivatives.
        let g = r.0 * e;
        let dg = r.1 * e + r.0 * de;
        let ddg = r.2 * e + 2.0 * r.1 * de + r.0 * dde;
        (
            FRAC_PI_2 + amplitude * g * s,
            amplitude * (dg * s + g * ds),
            amplitude * (ddg * s + 2.0 * dg * ds + g * dds),
        )
    }

    /// Whether the law adapts its stiffness to the energy on this trajectory: not on the
    /// excitation, whose motion is the trajectory's own, not an orbit's (an energy target
    /// would fight it).
    #[inline(always)]
    pub fn adapts(&self) -> bool {
        !matches!(self, Trajectory::Excitation { .. })
    }

    /// The kind's name: `hold` or `sinusoid` (as in the text and the JSON forms).
    pub fn name(&self) -> &'static str {
        match self {
            Trajectory::Hold => HOLD,
            Trajectory::Sinusoid { .. } => SINUSOID,
            Trajectory::Excitation { .. } => EXCITATION,
        }
    }

    /// The sinusoid's or the excitation's `(amplitude, omega)` (rad, rad/s); `(0, 0)` for
    /// hold.
    pub fn sinusoid(&self) -> (f64, f64) {
        match *self {
            Trajectory::Hold => (0.0, 0.0),
            Trajectory::Sinusoid { amplitude, omega }
            | Trajectory::Excitation { amplitude, omega } => (amplitude, omega),
        }
    }
}

/// The excitation's series `s(theta)` and its first two derivatives in `theta`.
#[inline(always)]
pub(crate) fn series(theta: f64) -> (f64, f64, f64) {
    let mut out = (0.0, 0.0, 0.0);
    for (n, c, phi) in HARMONICS {
        let (s, co) = (n * theta + phi).sin_cos();
        out.0 += c * s;
        out.1 += c * n * co;
        out.2 -= c * n * n * s;
    }
    out
}

/// The ramp `e(u) = 10 u^3 - 15 u^4 + 6 u^5` on `u` in `[0, 1]` (0 before, 1 after) and its
/// first two derivatives in `u`: 0 and 1 with zero slope and curvature at the ends.
#[inline(always)]
pub(crate) fn ramp(u: f64) -> (f64, f64, f64) {
    if u <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    if u >= 1.0 {
        return (1.0, 0.0, 0.0);
    }
    let (u2, u3) = (u * u, u * u * u);
    (
        u3 * (10.0 - 15.0 * u + 6.0 * u2),
        30.0 * u2 * (1.0 - u) * (1.0 - u),
        60.0 * u * (1.0 - u) * (1.0 - 2.0 * u),
    )
}

impl std::fmt::Display for Trajectory {
    /// `hold` or `sinusoid:A,w`, the form [`FromStr`] parses (the numbers round-trip).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Trajectory::Hold => f.write_str(self.name()),
            Trajectory::Sinusoid { amplitude, omega }
            | Trajectory::Excitation { amplitude, omega } => {
                write!(f, "{}:{amplitude},{omega}", self.name())
            }
        }
    }
}

impl FromStr for Trajectory {
    type Err = String;
    /// Parses `hold`, `sinusoid:A,w`, `excitation` or `excitation:A,w`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!(
                "invalid reference `{s}`: must be hold, sinusoid:A,w, excitation or \
                 excitation:A,w (A in rad, w > 0 in rad/s)"
            )
        };
        match s {
            HOLD => return Ok(Trajectory::Hold),
            EXCITATION => return Ok(EXCITATION_DEFAULT),
            _ => {}
        }
        let (kind, rest) = s.split_once(':').ok_or_else(bad)?;
        let mut it = rest.split(',').map(|v| v.trim().parse::<f64>());
        match (kind, it.next(), it.next(), it.next()) {
            (k, Some(Ok(amplitude)), Some(Ok(omega)), None)
                if amplitude.is_finite() && omega.is_finite() && omega > 0.0 =>
            {
                match k {
                    SINUSOID => Ok(Trajectory::Sinusoid { amplitude, omega }),
                    EXCITATION => Ok(Trajectory::Excitation { amplitude, omega }),
                    _ => Err(bad()),
                }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The excitation's rate and acceleration are the derivatives of its angle (central
    /// differences, step 1e-4 s: truncation error about `h^2 |beta'''| / 6`, below 1e-6
    /// here), through the ramp and after it; it starts at rest upright and stays within
    /// its amplitude bound.
    #[test]
    fn excitation_is_consistent_bounded_and_starts_at_rest() {
        let (a, w) = (0.5, 1.5);
        let tr = Trajectory::Excitation {
            amplitude: a,
            omega: w,
        };
        assert_eq!(tr.at(0.0), (FRAC_PI_2, 0.0, 0.0));
        let h = 1e-4;
        let mut peak: f64 = 0.0;
        for i in 1..4000 {
            let t = i as f64 * 3e-3;
            let (q, dq, ddq) = tr.at(t);
            let (qp, dqp, _) = tr.at(t + h);
            let (qm, dqm, _) = tr.at(t - h);
            let fd = (qp - qm) / (2.0 * h);
            let fdd = (dqp - dqm) / (2.0 * h);
            assert!((fd - dq).abs() < 1e-6, "t = {t}: rate {dq} vs {fd}");
            assert!(
                (fdd - ddq).abs() < 1e-5,
                "t = {t}: acceleration {ddq} vs {fdd}"
            );
            peak = peak.max((q - FRAC_PI_2).abs());
        }
        // The bound holds, and the series uses most of it (it is not a loose bound).
        assert!(peak <= a && peak > 0.6 * a, "peak {peak}");
        let weights: f64 = HARMONICS.iter().map(|h| h.1).sum();
        assert!((weights - 1.0).abs() < 1e-12);
        assert!(!tr.adapts() && Trajectory::Hold.adapts());
    }

    /// The scaled excitation's rate and acceleration are the derivatives of its angle for a
    /// scale that moves (`r(t) = 0.8 + 0.2 cos(0.7 t)`, given with its exact derivatives;
    /// central differences as above), and with `r = (1, 0, 0)` it is the excitation itself,
    /// to the bit.
    #[test]
    fn scaled_excitation_is_consistent_and_unscaled_is_the_excitation() {
        let tr = Trajectory::Excitation {
            amplitude: 0.3,
            omega: 0.9,
        };
        let r = |t: f64| {
            let (s, c) = (0.7 * t).sin_cos();
            (0.8 + 0.2 * c, -0.14 * s, -0.098 * c)
        };
        let h = 1e-4;
        for i in 1..3000 {
            let t = i as f64 * 7e-3;
            assert_eq!(tr.at_scaled(t, (1.0, 0.0, 0.0)), tr.at(t));
            let (_, dq, ddq) = tr.at_scaled(t, r(t));
            let (qp, dqp, _) = tr.at_scaled(t + h, r(t + h));
            let (qm, dqm, _) = tr.at_scaled(t - h, r(t - h));
            let fd = (qp - qm) / (2.0 * h);
            let fdd = (dqp - dqm) / (2.0 * h);
            assert!((fd - dq).abs() < 1e-6, "t = {t}: rate {dq} vs {fd}");
            assert!((fdd - ddq).abs() < 1e-5, "t = {t}: {ddq} vs {fdd}");
        }
        assert_eq!(
            Trajectory::Hold.at_scaled(3.0, r(3.0)),
            Trajectory::Hold.at(3.0)
        );
    }

    #[test]
    fn text_forms_round_trip() {
        for s in ["hold", "sinusoid:0.2,3", "excitation:0.3,2"] {
            let t: Trajectory = s.parse().unwrap();
            assert_eq!(t.to_string().parse::<Trajectory>().unwrap(), t);
        }
        assert_eq!(
            "excitation".parse::<Trajectory>().unwrap(),
            EXCITATION_DEFAULT
        );
        for bad in [
            "excitation:0.3",
            "excitation:0.3,0",
            "wobble:1,2",
            "excitation:",
        ] {
            let e = bad.parse::<Trajectory>().unwrap_err();
            assert!(e.contains("excitation:A,w"), "{e}");
        }
    }
}
