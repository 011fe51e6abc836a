//! A real robot is not the model: the imperfections of the hardware, seeded and off by default,
//! shared by the offline sampled loop (`tilting simulate`) and the plant node (`tilting-plant`,
//! lockstep and real time), so the two compute the same numbers bit for bit.
//!
//! Per control period `[t_k, t_{k+1}]` of a sampled loop:
//!
//! - **Sensors** ([`Sensor::measure`]): the controller sees the *measured* state, the plant
//!   integrates the *true* one. For the angles `alpha`, `beta` (rad):
//!   `y = round((x + sigma n) / q) q` with `n` standard normal and `q = 2 pi / counts` the
//!   encoder's resolution (no rounding without `--encoder-counts`); for the rates `alpha_dot`,
//!   `beta_dot` (rad/s): `y = x + sigma n`. The rates are **not** derived from the quantised
//!   angles: they model a separate rate measurement (a gyro, or the drive's own velocity
//!   estimate) with its own noise, so the encoder quantises the angles only. Angles are in the
//!   model's frames (`docs/model.md`: `alpha` the plate's tilt, `beta` the arm relative to the
//!   plate); the encoder's zero is the frame's zero. Four normals are drawn per sample, in the
//!   order `alpha, beta, alpha_dot, beta_dot`, whenever any deviation is positive (none
//!   otherwise), from a ChaCha8 stream seeded with `(seed, SENSOR_STREAM)`: the network links
//!   use streams 0 and 1 of the same seed, so noise does not change the network's draws. The
//!   contact mode is measured exactly (contact switches).
//! - **What is measured** ([`Measure`], `--measure full|angles`): `full` (the default) sends the
//!   four measured quantities; `angles` sends the two angles only, as a robot with encoders and
//!   no velocity sensor would ([`Measurement::rates`] is `None`, and the published `PlantState`
//!   marks the rates absent). The four normals are drawn either way, so the angles of `angles`
//!   are those of `full` with the same seed, bit for bit.
//! - **Actuator** ([`Actuator::advance`]): the commanded torque `c_k` (N m, about the arm
//!   joint) is first clipped to `[-S, S]` (`--torque-saturation`), `s_k = clamp(c_k)`, then the
//!   applied torque lags it with the first-order law `T dtau/dt = s_k - tau`, integrated exactly
//!   inside the right-hand side: `tau(t) = s_k + (tau(t_k) - s_k) exp(-(t - t_k) / T)` for `t`
//!   in the period ([`FirstOrderLag`], given to
//!   [`Plant::advance_continuous`](crate::Plant::advance_continuous)). The applied torque starts
//!   at `tau(0) = 0` and is continuous across periods. It is a convex combination of clipped
//!   values, so it never exceeds `S` either. With `T = 0` the clipped command is held
//!   ([`Plant::advance_held`](crate::Plant::advance_held)): the zero-order hold.
//! - **Model mismatch**: the plant's arm mass is `(1 + e) m_l` of the parameters it was given
//!   (`--mass-error e`, [`Imperfections::plant_params`]); the controller keeps its own
//!   parameters (its `--params`). Other mismatches: give the plant its own parameter file.
//!
//! With every setting zero ([`Imperfections::default`]) the sensor returns the true state and
//! the actuator holds the command: the perfect loop, bit for bit.

use crate::hybrid::{Fault, Observer, Plant, TorqueLaw};
use crate::{Mode, Params, State};
use rand::SeedableRng as _;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution as _, StandardNormal};

/// The random stream of the sensor noise within the seed shared with the network links (which
/// use streams 0 and 1).
pub const SENSOR_STREAM: u64 = 2;

/// Largest accepted noise deviation (rad for angles, rad/s for rates).
pub const MAX_SIGMA: f64 = 10.0;
/// Accepted encoder resolutions (counts per revolution).
pub const COUNTS_RANGE: (u64, u64) = (2, 1 << 32);
/// Largest accepted torque saturation (N m).
pub const MAX_SATURATION: f64 = 1e6;
/// Largest accepted torque lag time constant (s).
pub const MAX_LAG: f64 = 10.0;
/// Accepted relative arm-mass errors: `(-1, 10]` (the plant's arm mass stays positive).
pub const MASS_ERROR_RANGE: (f64, f64) = (-1.0, 10.0);

/// What the sensors measure (`--measure`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Measure {
    /// Both angles and both rates (the model's full state).
    #[default]
    Full,
    /// The two angles only (encoders, no velocity sensor): the rates are absent.
    Angles,
}

impl Measure {
    /// The default, `full`.
    pub fn is_full(&self) -> bool {
        *self == Measure::Full
    }

    /// The flag's value: `full` or `angles`.
    pub fn name(self) -> &'static str {
        match self {
            Measure::Full => "full",
            Measure::Angles => "angles",
        }
    }
}

/// One sample of the sensors: the angles `[alpha, beta]` (rad) always, the rates `[alpha_dot,
/// beta_dot]` (rad/s) only when measured ([`Measure::Full`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Measured `[alpha, beta]` (rad).
    pub angles: [f64; 2],
    /// Measured `[alpha_dot, beta_dot]` (rad/s), `None` when the rates are not measured.
    pub rates: Option<[f64; 2]>,
}

impl Measurement {
    /// Every quantity of the state `y`, measured.
    pub fn full(y: &State) -> Self {
        Self {
            angles: [y[0], y[1]],
            rates: Some([y[2], y[3]]),
        }
    }

    /// The full measured state, if the rates were measured (never with invented rates).
    pub fn state(&self) -> Option<State> {
        let [ad, bd] = self.rates?;
        Some(State::new(self.angles[0], self.angles[1], ad, bd))
    }
}

/// The flags of [`Imperfections::measured_as_hardware`], the issue 17 headline's sensors (the
/// angles only, 1 mrad of noise on each, a 4,096-count encoder), as `simulate`, `live` and
/// `tilting-plant` take them; `--seed` seeds the noise.
pub const MEASURED_AS_HARDWARE: [&str; 8] = [
    "--measure",
    "angles",
    "--noise-alpha",
    "0.001",
    "--noise-beta",
    "0.001",
    "--encoder-counts",
    "4096",
];

/// The hardware's imperfections. The default is the perfect robot (the model itself).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Imperfections {
    /// Standard deviations of the Gaussian sensor noise of `(alpha, beta, alpha_dot,
    /// beta_dot)`: rad, rad, rad/s, rad/s; each in `[0, 10]`.
    pub noise: [f64; 4],
    /// Encoder resolution of both angles, counts per revolution (`None`: exact angles).
    pub encoder_counts: Option<u64>,
    /// Largest torque the actuator applies, N m (`None`: no limit).
    pub torque_saturation: Option<f64>,
    /// Time constant of the first-order lag from the commanded to the applied torque, s
    /// (0: none).
    pub torque_lag: f64,
    /// Relative error of the plant's arm mass `m_l` against the model's: the plant has
    /// `(1 + mass_error) m_l`.
    pub mass_error: f64,
    /// Seed of the sensor noise (stream [`SENSOR_STREAM`]).
    pub seed: u64,
    /// What the sensors measure (`full`, the default, is left out of the JSON).
    #[serde(skip_serializing_if = "Measure::is_full")]
    pub measure: Measure,
}

/// A setting outside its allowed range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid `{flag}` = {value}: allowed {allowed}")]
pub struct ImperfectError {
    /// The flag.
    pub flag: &'static str,
    /// The value given.
    pub value: String,
    /// What is allowed.
    pub allowed: &'static str,
}

/// The flags of the four noise deviations, in state order.
pub const NOISE_FLAGS: [&str; 4] = [
    "--noise-alpha",
    "--noise-beta",
    "--noise-alpha-dot",
    "--noise-beta-dot",
];

impl Imperfections {
    /// Checks every range; the error names the flag and the allowed range.
    pub fn validate(&self) -> Result<(), ImperfectError> {
        for (i, &s) in self.noise.iter().enumerate() {
            if !(s.is_finite() && (0.0..=MAX_SIGMA).contains(&s)) {
                return Err(ImperfectError {
                    flag: NOISE_FLAGS[i],
                    value: s.to_string(),
                    allowed: if i < 2 {
                        "a standard deviation in rad in [0, 10]"
                    } else {
                        "a standard deviation in rad/s in [0, 10]"
                    },
                });
            }
        }
        if let Some(n) = self.encoder_counts {
            if !(COUNTS_RANGE.0..=COUNTS_RANGE.1).contains(&n) {
                return Err(ImperfectError {
                    flag: "--encoder-counts",
                    value: n.to_string(),
                    allowed: "counts per revolution in [2, 4294967296]",
                });
            }
        }
        if let Some(s) = self.torque_saturation {
            if !(s.is_finite() && s > 0.0 && s <= MAX_SATURATION) {
                return Err(ImperfectError {
                    flag: "--torque-saturation",
                    value: s.to_string(),
                    allowed: "a torque in N m in (0, 1e6]",
                });
            }
        }
        if !(self.torque_lag.is_finite() && (0.0..=MAX_LAG).contains(&self.torque_lag)) {
            return Err(ImperfectError {
                flag: "--torque-lag",
                value: self.torque_lag.to_string(),
                allowed: "a time constant in s in [0, 10] (0 = none)",
            });
        }
        let (lo, hi) = MASS_ERROR_RANGE;
        if !(self.mass_error.is_finite() && self.mass_error > lo && self.mass_error <= hi) {
            return Err(ImperfectError {
                flag: "--mass-error",
                value: self.mass_error.to_string(),
                allowed: "a relative error of the arm mass in (-1, 10]",
            });
        }
        Ok(())
    }

    /// Does the sensor or the actuator differ from the perfect one (anything but the mass
    /// error)? Such a loop must be sampled.
    pub fn has_hardware(&self) -> bool {
        self.measure != Measure::Full
            || self.noise.iter().any(|&s| s != 0.0)
            || self.encoder_counts.is_some()
            || self.torque_saturation.is_some()
            || self.torque_lag != 0.0
    }

    /// Nothing differs from the model.
    pub fn is_perfect(&self) -> bool {
        !self.has_hardware() && self.mass_error == 0.0
    }

    /// The plant's parameters from the model's `p`: the arm mass times `1 + mass_error`.
    pub fn plant_params(&self, p: &Params) -> Params {
        Params {
            m_l: p.m_l * (1.0 + self.mass_error),
            ..*p
        }
    }

    /// The robot measured as the hardware measures it: the two angles only (no rate sensor),
    /// each with Gaussian noise of 1 mrad standard deviation and quantised by a 4,096-count
    /// encoder, the noise drawn from `seed`; the actuator and the arm mass perfect. What the
    /// flags [`MEASURED_AS_HARDWARE`] with `--seed SEED` run with; the identification's and the
    /// excitation's noisy tests and benchmarks use it.
    pub fn measured_as_hardware(seed: u64) -> Self {
        Self {
            noise: [1e-3, 1e-3, 0.0, 0.0],
            encoder_counts: Some(4096),
            measure: Measure::Angles,
            seed,
            ..Self::default()
        }
    }

    /// The sensor and the actuator of a run, at its start.
    pub fn hardware(&self) -> Hardware {
        Hardware {
            sensor: Sensor::new(self),
            actuator: Actuator::new(self),
        }
    }
}

/// The sensors: noise and encoder quantisation (see the module's documentation).
#[derive(Debug, Clone)]
pub struct Sensor {
    sigma: [f64; 4],
    quantum: Option<f64>,
    measure: Measure,
    rng: ChaCha8Rng,
}

impl Sensor {
    /// The sensors of `imp`, their random stream at its start.
    pub fn new(imp: &Imperfections) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(imp.seed);
        rng.set_stream(SENSOR_STREAM);
        Self {
            sigma: imp.noise,
            quantum: imp.encoder_counts.map(|n| std::f64::consts::TAU / n as f64),
            measure: imp.measure,
            rng,
        }
    }

    /// What the sensors send for the true state `x`: [`Sensor::measure`], the rates left out
    /// with [`Measure::Angles`] (draws one sample of the noise either way).
    pub fn sample(&mut self, x: &State) -> Measurement {
        let y = self.measure(x);
        match self.measure {
            Measure::Full => Measurement::full(&y),
            Measure::Angles => Measurement {
                angles: [y[0], y[1]],
                rates: None,
            },
        }
    }

    /// The measured state of the true state `x`, all four quantities (draws one sample of the
    /// noise); what is sent is [`Sensor::sample`].
    pub fn measure(&mut self, x: &State) -> State {
        let mut y = *x;
        if self.sigma.iter().any(|&s| s > 0.0) {
            for (i, &s) in self.sigma.iter().enumerate() {
                let n: f64 = StandardNormal.sample(&mut self.rng);
                if s > 0.0 {
                    y[i] += s * n;
                }
            }
        }
        if let Some(q) = self.quantum {
            for i in 0..2 {
                y[i] = (y[i] / q).round() * q;
            }
        }
        y
    }

    /// The encoder's resolution (rad), if the angles are quantised.
    pub fn quantum(&self) -> Option<f64> {
        self.quantum
    }
}

/// The applied torque within one period of a lagging actuator: `tau(t) = cmd + (tau0 - cmd)
/// exp(-(t - t0) / time_constant)` (N m, `t` in s), the exact solution of `T dtau/dt = cmd -
/// tau` from `tau(t0) = tau0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstOrderLag {
    /// Start of the period (s).
    pub t0: f64,
    /// Applied torque at `t0` (N m).
    pub tau0: f64,
    /// Command (already clipped) held over the period (N m).
    pub cmd: f64,
    /// Time constant `T` (s), positive.
    pub time_constant: f64,
}

impl FirstOrderLag {
    /// The applied torque at `t` (N m).
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        self.cmd + (self.tau0 - self.cmd) * (-(t - self.t0) / self.time_constant).exp()
    }
}

impl TorqueLaw for FirstOrderLag {
    #[inline]
    fn torque(&self, t: f64, _mode: Mode, _x: &State) -> f64 {
        self.at(t)
    }
}

/// The actuator: saturation and first-order lag (see the module's documentation).
#[derive(Debug, Clone)]
pub struct Actuator {
    saturation: Option<f64>,
    lag: f64,
    tau: f64,
}

impl Actuator {
    /// The actuator of `imp`, applying no torque yet.
    pub fn new(imp: &Imperfections) -> Self {
        Self {
            saturation: imp.torque_saturation,
            lag: imp.torque_lag,
            tau: 0.0,
        }
    }

    /// The command clipped to the saturation (N m).
    pub fn clip(&self, cmd: f64) -> f64 {
        match self.saturation {
            Some(s) => cmd.clamp(-s, s),
            None => cmd,
        }
    }

    /// The torque applied at the plant's current time (N m): after [`Actuator::advance`], the
    /// torque at the end of the period.
    pub fn applied(&self) -> f64 {
        self.tau
    }

    /// Advances `plant` to `t_target` (s) with the command `cmd` (N m) issued at the plant's
    /// current time: clipped, then lagged (exactly) or, without a lag, held.
    #[inline(always)]
    pub fn advance<O: Observer>(
        &mut self,
        plant: &mut Plant,
        cmd: f64,
        t_target: f64,
        obs: &mut O,
    ) -> Result<(), Fault> {
        if self.saturation.is_none() && self.lag == 0.0 {
            // The perfect actuator (every sampled loop's hot path): the command is held;
            // `advance_held` refuses a non-finite one with the same fault.
            if cmd.is_finite() {
                self.tau = cmd;
            }
            return plant.advance_held(cmd, t_target, obs);
        }
        self.advance_imperfect(plant, cmd, t_target, obs)
    }

    /// [`Actuator::advance`] with a saturation or a lag.
    fn advance_imperfect<O: Observer>(
        &mut self,
        plant: &mut Plant,
        cmd: f64,
        t_target: f64,
        obs: &mut O,
    ) -> Result<(), Fault> {
        if !cmd.is_finite() {
            return Err(Fault::NonFiniteTorque {
                t: plant.time(),
                tau: cmd,
            });
        }
        let s = self.clip(cmd);
        if self.lag == 0.0 {
            self.tau = s;
            return plant.advance_held(s, t_target, obs);
        }
        let law = FirstOrderLag {
            t0: plant.time(),
            tau0: self.tau,
            cmd: s,
            time_constant: self.lag,
        };
        let r = plant.advance_continuous(&law, t_target, obs);
        self.tau = law.at(plant.time());
        r
    }
}

/// The sensors and the actuator of one run.
#[derive(Debug, Clone)]
pub struct Hardware {
    /// Noise and quantisation of the measured state.
    pub sensor: Sensor,
    /// Saturation and lag of the applied torque.
    pub actuator: Actuator,
}

impl Hardware {
    /// What the controller sees at the plant's current time (draws the noise once: call it
    /// once per sample).
    pub fn measure(&mut self, plant: &Plant) -> Measurement {
        self.sensor.sample(&plant.state())
    }

    /// Advances `plant` to `t_target` (s) under the command `cmd` (N m) ([`Actuator::advance`]).
    pub fn advance<O: Observer>(
        &mut self,
        plant: &mut Plant,
        cmd: f64,
        t_target: f64,
        obs: &mut O,
    ) -> Result<(), Fault> {
        self.actuator.advance(plant, cmd, t_target, obs)
    }
}

impl Default for Hardware {
    /// The perfect hardware.
    fn default() -> Self {
        Imperfections::default().hardware()
    }
}

#[cfg(feature = "clap")]
/// The imperfection flags of `tilting simulate` and `tilting-plant` (one struct for both). The
/// seed is the network's `--seed` (another random stream of it), passed to
/// [`ImperfectArgs::imperfections`].
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
pub struct ImperfectArgs {
    /// Sensor noise: standard deviation of the measured plate angle alpha (rad), in [0, 10]
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    pub noise_alpha: Option<f64>,
    /// Sensor noise: standard deviation of the measured arm angle beta (rad), in [0, 10]
    #[arg(long, value_name = "RAD", allow_negative_numbers = true)]
    pub noise_beta: Option<f64>,
    /// Sensor noise: standard deviation of the measured alpha_dot (rad/s), in [0, 10]
    #[arg(long, value_name = "RAD/S", allow_negative_numbers = true)]
    pub noise_alpha_dot: Option<f64>,
    /// Sensor noise: standard deviation of the measured beta_dot (rad/s), in [0, 10]
    #[arg(long, value_name = "RAD/S", allow_negative_numbers = true)]
    pub noise_beta_dot: Option<f64>,
    /// Encoder resolution of both angles (counts per revolution), in [2, 2^32]: the measured
    /// angles are rounded to 2 pi / N; the rates are not quantised
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub encoder_counts: Option<i64>,
    /// Actuator saturation (N m), in (0, 1e6]: the applied torque is clipped to [-S, S]
    #[arg(long, value_name = "NM", allow_negative_numbers = true)]
    pub torque_saturation: Option<f64>,
    /// Actuator lag (s), in [0, 10]: the applied torque follows the clipped command with this
    /// first-order time constant (0 = none)
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub torque_lag: Option<f64>,
    /// Model mismatch: the plant's arm mass is (1 + E) times the model's m_l, E in (-1, 10];
    /// the controller keeps the model's
    #[arg(long, value_name = "E", allow_negative_numbers = true)]
    pub mass_error: Option<f64>,
    /// What the sensors send: full (angles and rates) or angles (encoders only: the rates are
    /// absent and the controller estimates them) [default: full]
    #[arg(long, value_enum, value_name = "full|angles")]
    pub measure: Option<Measure>,
}

#[cfg(feature = "clap")]
impl ImperfectArgs {
    /// The imperfections, validated (an error names the flag and the allowed range), with the
    /// sensor noise drawn from `seed`; `None` when no flag makes the robot imperfect.
    pub fn imperfections(&self, seed: u64) -> Result<Option<Imperfections>, ImperfectError> {
        let encoder_counts = match self.encoder_counts {
            None => None,
            Some(n) if n >= 0 => Some(n as u64),
            Some(n) => {
                return Err(ImperfectError {
                    flag: "--encoder-counts",
                    value: n.to_string(),
                    allowed: "counts per revolution in [2, 4294967296]",
                })
            }
        };
        let imp = Imperfections {
            noise: [
                self.noise_alpha.unwrap_or(0.0),
                self.noise_beta.unwrap_or(0.0),
                self.noise_alpha_dot.unwrap_or(0.0),
                self.noise_beta_dot.unwrap_or(0.0),
            ],
            encoder_counts,
            torque_saturation: self.torque_saturation,
            torque_lag: self.torque_lag.unwrap_or(0.0),
            mass_error: self.mass_error.unwrap_or(0.0),
            seed,
            measure: self.measure.unwrap_or_default(),
        };
        imp.validate()?;
        Ok((!imp.is_perfect()).then_some(imp))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Plant, SimConfig};
    use std::f64::consts::{FRAC_PI_2, TAU};

    fn mean_sd(v: &[f64]) -> (f64, f64) {
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
        (m, var.sqrt())
    }

    /// The noise of each quantity has mean 0 and the given deviation: over n = 200,000
    /// samples the sample mean is within 3 standard errors (sigma / sqrt(n)) of the true value
    /// and the sample deviation within 3 standard errors (sigma / sqrt(2 n), normal data) of
    /// sigma. The quantities are uncorrelated (|r| < 3 / sqrt(n)).
    #[test]
    fn noise_has_the_given_mean_and_deviation() {
        let sigma = [1e-3, 2e-3, 0.05, 0.3];
        let imp = Imperfections {
            noise: sigma,
            seed: 9,
            ..Imperfections::default()
        };
        let mut s = Sensor::new(&imp);
        let x = State::new(0.01, 1.5, -0.2, 0.7);
        let n = 200_000;
        let ys: Vec<State> = (0..n).map(|_| s.measure(&x)).collect();
        let nf = n as f64;
        let mut errs = Vec::new();
        for i in 0..4 {
            let e: Vec<f64> = ys.iter().map(|y| y[i] - x[i]).collect();
            let (m, sd) = mean_sd(&e);
            assert!(m.abs() < 3.0 * sigma[i] / nf.sqrt(), "{i}: mean {m}");
            assert!(
                (sd - sigma[i]).abs() < 3.0 * sigma[i] / (2.0 * nf).sqrt(),
                "{i}: sd {sd} against {}",
                sigma[i]
            );
            errs.push(e);
        }
        let r = errs[0]
            .iter()
            .zip(&errs[3])
            .map(|(a, b)| a * b)
            .sum::<f64>()
            / nf
            / (sigma[0] * sigma[3]);
        assert!(r.abs() < 3.0 / nf.sqrt(), "correlation {r}");
    }

    /// Only the quantities with a positive deviation are disturbed, and the draws of one
    /// quantity do not depend on which others are noisy (four normals per sample).
    #[test]
    fn a_zero_deviation_leaves_its_quantity_exact() {
        let x = State::new(0.0, 1.5, 0.0, 0.7);
        let mut a = Sensor::new(&Imperfections {
            noise: [0.0, 0.0, 0.0, 0.1],
            seed: 3,
            ..Imperfections::default()
        });
        let mut b = Sensor::new(&Imperfections {
            noise: [0.2, 0.0, 0.0, 0.1],
            seed: 3,
            ..Imperfections::default()
        });
        for _ in 0..100 {
            let (ya, yb) = (a.measure(&x), b.measure(&x));
            assert_eq!((ya[0], ya[1], ya[2]), (x[0], x[1], x[2]));
            assert_eq!(ya[3], yb[3]);
            assert_ne!(yb[0], x[0]);
        }
    }

    /// Quantisation: the error is at most half a count (plus the rounding of the product,
    /// 1e-12 of a count), and uniform over the count: over 100,000 angles spread over many
    /// counts, each of 10 bins of the error holds n/10 within 5 binomial standard deviations,
    /// and the variance is q^2/12 within 5 %. The rates are not quantised.
    #[test]
    fn quantisation_error_is_uniform_within_half_a_count() {
        let counts = 4096;
        let q = TAU / counts as f64;
        let mut s = Sensor::new(&Imperfections {
            encoder_counts: Some(counts),
            ..Imperfections::default()
        });
        assert_eq!(s.quantum(), Some(q));
        let n = 100_000;
        let mut bins = [0usize; 10];
        let mut sq = 0.0;
        for j in 0..n {
            // A golden-ratio sequence over [-1, 2] rad: angles at no fixed phase to the grid.
            let a = -1.0 + 3.0 * ((j as f64 * 0.618_033_988_749_895) % 1.0);
            let x = State::new(a, a + 0.5, a, -a);
            let y = s.measure(&x);
            for i in 0..2 {
                let e = (y[i] - x[i]) / q;
                assert!(e.abs() <= 0.5 + 1e-9, "error {e} counts at {}", x[i]);
                // The measured angle lies on the grid.
                assert!(((y[i] / q) - (y[i] / q).round()).abs() < 1e-9);
            }
            assert_eq!((y[2], y[3]), (x[2], x[3]));
            let e = (y[0] - x[0]) / q;
            bins[((e + 0.5) * 10.0).floor().clamp(0.0, 9.0) as usize] += 1;
            sq += e * e;
        }
        let want = n as f64 / 10.0;
        let sd = (n as f64 * 0.1 * 0.9).sqrt();
        for b in bins {
            assert!((b as f64 - want).abs() < 5.0 * sd, "{bins:?}");
        }
        assert!(
            (sq / n as f64 * 12.0 - 1.0).abs() < 0.05,
            "{}",
            sq / n as f64
        );
    }

    /// The torque the flat plant really felt, from the arm's acceleration: in the flat mode the
    /// arm is a pendulum on a fixed base, `m_l l^2 beta_ddot + m_l g l cos(beta) = tau`, and
    /// `beta_ddot` is the central difference of `beta_dot` over the samples (error
    /// `h^2/6 beta''''`, below 1e-4 N m here).
    fn felt_torque(imp: &Imperfections, cmd: f64, h: f64, n: usize) -> Vec<(f64, f64)> {
        let p = Params::default();
        let x0 = State::new(0.0, FRAC_PI_2, 0.0, 0.0);
        let mut plant = Plant::new(SimConfig::default(), 0.0, Mode::Flat, x0).unwrap();
        let mut act = Actuator::new(imp);
        let mut xs = vec![(0.0, plant.state())];
        for k in 1..=n {
            act.advance(&mut plant, cmd, k as f64 * h, &mut ()).unwrap();
            assert_eq!(plant.mode(), Mode::Flat);
            xs.push((plant.time(), plant.state()));
        }
        xs.windows(3)
            .map(|w| {
                let bdd = (w[2].1[3] - w[0].1[3]) / (2.0 * h);
                let b = w[1].1[1];
                (w[1].0, p.m_l * p.l * (p.l * bdd + p.g * b.cos()))
            })
            .collect()
    }

    /// A torque step of 1 N m through a lag of T = 50 ms: the torque the arm feels is
    /// `1 - exp(-t/T)` (the closed form of the first-order lag) to 2e-4 N m (the finite
    /// difference's error in the torque is about `h^2/6 tau'' <= h^2 / (6 T^2)` = 6.7e-5 N m);
    /// without the lag it is 1 N m from the start.
    #[test]
    fn a_lagged_step_follows_one_minus_exp() {
        let t_lag = 0.05;
        let imp = Imperfections {
            torque_lag: t_lag,
            ..Imperfections::default()
        };
        let felt = felt_torque(&imp, 1.0, 1e-3, 200);
        let mut worst = 0.0f64;
        for &(t, tau) in &felt {
            worst = worst.max((tau - (1.0 - (-t / t_lag).exp())).abs());
        }
        assert!(worst < 2e-4, "largest deviation {worst} N m");
        // At t = T: 1 - 1/e.
        let at_t = felt.iter().find(|f| (f.0 - t_lag).abs() < 1e-9).unwrap().1;
        assert!((at_t - 0.632_120_558).abs() < 2e-4, "{at_t}");
        for &(_, tau) in &felt_torque(&Imperfections::default(), 1.0, 1e-3, 50) {
            assert!((tau - 1.0).abs() < 1e-6, "{tau}");
        }
    }

    /// Saturation clips the command: 100 N m commanded against a 3 N m saturation is felt as
    /// 3 N m (to 1e-5 N m: the finite difference's error, `m_l l^2 h^2 / 6` times the fourth
    /// derivative of beta, is a few 1e-6 N m as gravity's share changes with the swinging arm); with a lag it approaches
    /// 3 (1 - exp(-t/T)) and never exceeds 3.
    #[test]
    fn saturation_clips_the_applied_torque() {
        let imp = Imperfections {
            torque_saturation: Some(3.0),
            ..Imperfections::default()
        };
        for &(_, tau) in &felt_torque(&imp, 100.0, 1e-3, 20) {
            assert!((tau - 3.0).abs() < 1e-5, "{tau}");
        }
        for &(_, tau) in &felt_torque(&imp, -100.0, 1e-3, 20) {
            assert!((tau + 3.0).abs() < 1e-5, "{tau}");
        }
        let imp = Imperfections {
            torque_lag: 0.02,
            ..imp
        };
        // h = 0.25 ms: the difference's error in the torque is about h^2/6 tau'' <= h^2/6 3/T^2
        // = 7.8e-5 N m.
        for &(t, tau) in &felt_torque(&imp, 100.0, 2.5e-4, 240) {
            assert!(
                (tau - 3.0 * (1.0 - (-t / 0.02).exp())).abs() < 2e-4,
                "{t}: {tau}"
            );
        }
        let mut a = Actuator::new(&imp);
        assert_eq!(a.clip(-7.0), -3.0);
        assert_eq!(a.clip(2.0), 2.0);
        let x0 = State::new(0.0, FRAC_PI_2, 0.0, 0.0);
        let mut plant = Plant::new(SimConfig::default(), 0.0, Mode::Flat, x0).unwrap();
        a.advance(&mut plant, 100.0, 1.0, &mut ()).unwrap();
        assert!(a.applied() <= 3.0 && a.applied() > 2.99, "{}", a.applied());
    }

    /// The lagged actuator in 1 ms pieces against one call of `advance_continuous` with the
    /// lag written out by hand (`tau(t) = 1 - exp(-t/T)` from rest): the same trajectory to the
    /// integrators' tolerance (the pieces cut the steps differently).
    #[test]
    fn the_lag_in_pieces_equals_the_hand_written_law() {
        let t_lag = 0.03;
        let x0 = State::new(0.0, FRAC_PI_2, 0.0, 0.0);
        let mut a = Plant::new(SimConfig::default(), 0.0, Mode::Flat, x0).unwrap();
        let mut b = a.clone();
        let mut act = Actuator::new(&Imperfections {
            torque_lag: t_lag,
            ..Imperfections::default()
        });
        for k in 1..=300 {
            act.advance(&mut a, 2.0, k as f64 * 1e-3, &mut ()).unwrap();
        }
        let law = move |t: f64, _m: Mode, _x: &State| 2.0 * (1.0 - (-t / t_lag).exp());
        b.advance_continuous(&law, 0.3, &mut ()).unwrap();
        assert_eq!(a.time(), b.time());
        let d = (a.state() - b.state()).amax();
        assert!(d < 1e-9, "{d}");
        assert!((act.applied() - 2.0 * (1.0 - (-10.0f64).exp())).abs() < 1e-12);
    }

    #[test]
    fn zero_settings_are_the_perfect_hardware() {
        let x = State::new(0.01, 1.5, -0.2, 0.7);
        let mut hw = Imperfections::default().hardware();
        assert_eq!(hw.sensor.measure(&x), x);
        assert_eq!(hw.sensor.sample(&x), Measurement::full(&x));
        assert!(Imperfections::default().is_perfect());
        let p = Params::default();
        assert_eq!(Imperfections::default().plant_params(&p), p);
        let m = Imperfections {
            mass_error: 0.1,
            ..Imperfections::default()
        };
        assert!(!m.is_perfect() && !m.has_hardware());
        assert_eq!(m.plant_params(&p).m_l, 1.1 * p.m_l);
        assert_eq!(m.plant_params(&p).m_f, p.m_f);
    }

    #[test]
    fn bad_values_name_the_flag_and_the_range() {
        for (imp, want) in [
            (
                Imperfections {
                    noise: [0.0, -0.1, 0.0, 0.0],
                    ..Imperfections::default()
                },
                "invalid `--noise-beta` = -0.1: allowed a standard deviation in rad in [0, 10]",
            ),
            (
                Imperfections {
                    noise: [0.0, 0.0, f64::NAN, 0.0],
                    ..Imperfections::default()
                },
                "invalid `--noise-alpha-dot` = NaN: allowed a standard deviation in rad/s",
            ),
            (
                Imperfections {
                    encoder_counts: Some(0),
                    ..Imperfections::default()
                },
                "invalid `--encoder-counts` = 0: allowed counts per revolution in [2, 4294967296]",
            ),
            (
                Imperfections {
                    torque_lag: -0.01,
                    ..Imperfections::default()
                },
                "invalid `--torque-lag` = -0.01: allowed a time constant in s in [0, 10]",
            ),
            (
                Imperfections {
                    torque_saturation: Some(0.0),
                    ..Imperfections::default()
                },
                "invalid `--torque-saturation` = 0: allowed a torque in N m in (0, 1e6]",
            ),
            (
                Imperfections {
                    mass_error: -1.0,
                    ..Imperfections::default()
                },
                "invalid `--mass-error` = -1: allowed a relative error of the arm mass in (-1, 10]",
            ),
        ] {
            let e = imp.validate().unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        }
    }

    #[cfg(feature = "clap")]
    #[test]
    fn flags_parse_and_refuse_bad_values() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            imp: ImperfectArgs,
        }
        let parse = |args: &[&str]| {
            let mut all = vec!["x"];
            all.extend_from_slice(args);
            Cli::try_parse_from(all).unwrap().imp.imperfections(4)
        };
        assert_eq!(parse(&[]).unwrap(), None);
        let imp = parse(&[
            "--noise-alpha",
            "0.001",
            "--noise-beta-dot",
            "0.01",
            "--encoder-counts",
            "4096",
            "--torque-saturation",
            "11",
            "--torque-lag",
            "0.002",
            "--mass-error",
            "-0.1",
        ])
        .unwrap()
        .unwrap();
        assert_eq!(imp.noise, [0.001, 0.0, 0.0, 0.01]);
        assert_eq!(imp.encoder_counts, Some(4096));
        assert_eq!(imp.torque_saturation, Some(11.0));
        assert_eq!((imp.torque_lag, imp.mass_error, imp.seed), (0.002, -0.1, 4));
        // Zero settings are the perfect robot.
        assert_eq!(
            parse(&["--noise-alpha", "0", "--torque-lag", "0"]).unwrap(),
            None
        );
        for (args, want) in [
            (["--noise-alpha", "-1"], "`--noise-alpha` = -1"),
            (["--encoder-counts", "0"], "`--encoder-counts` = 0"),
            (["--encoder-counts", "-5"], "`--encoder-counts` = -5"),
            (["--torque-lag", "-0.5"], "`--torque-lag` = -0.5"),
        ] {
            let e = parse(&args).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("allowed"), "{e}");
        }
    }

    /// `--measure angles` sends the angles of `--measure full` (same seed, same draws), bit
    /// for bit, and no rates: never a zero in their place.
    #[test]
    fn angles_only_are_the_angles_of_full_and_no_rates() {
        let base = Imperfections {
            noise: [1e-3, 2e-3, 0.1, 0.2],
            encoder_counts: Some(4096),
            seed: 3,
            ..Imperfections::default()
        };
        let angles = Imperfections {
            measure: Measure::Angles,
            ..base
        };
        assert!(angles.has_hardware() && !angles.is_perfect());
        assert!(Imperfections {
            measure: Measure::Angles,
            ..Imperfections::default()
        }
        .has_hardware());
        let (mut a, mut b) = (Sensor::new(&base), Sensor::new(&angles));
        let x = State::new(0.01, 1.5, -0.3, 0.4);
        for _ in 0..100 {
            let (ya, yb) = (a.sample(&x), b.sample(&x));
            assert_eq!(yb.rates, None);
            assert_eq!(yb.state(), None);
            assert_eq!(ya.angles.map(f64::to_bits), yb.angles.map(f64::to_bits));
            assert!(ya.rates.is_some());
        }
    }

    /// `measured_as_hardware(seed)` is what its flags give ([`MEASURED_AS_HARDWARE`]: `--measure
    /// angles --noise-alpha 0.001 --noise-beta 0.001 --encoder-counts 4096`, the noise from `seed`):
    /// its sensor sends no rates and angles on the 4,096-count grid, within 5 sigmas plus half
    /// a count of the truth (5 sigmas: a 6e-7 chance a draw, 400 draws).
    #[cfg(feature = "clap")]
    #[test]
    fn measured_as_hardware_is_what_its_flags_give() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            imp: ImperfectArgs,
        }
        let flags = std::iter::once("x").chain(MEASURED_AS_HARDWARE);
        for seed in [0, 7, u64::MAX] {
            let parsed = Cli::try_parse_from(flags.clone())
                .unwrap()
                .imp
                .imperfections(seed);
            let imp = Imperfections::measured_as_hardware(seed);
            assert_eq!(parsed, Ok(Some(imp)));
            let mut sensor = Sensor::new(&imp);
            let q = TAU / 4096.0;
            let x = State::new(0.0, 1.2, 0.0, 0.5);
            for _ in 0..200 {
                let y = sensor.sample(&x);
                assert_eq!(y.rates, None);
                for i in 0..2 {
                    let counts = y.angles[i] / q;
                    assert!((counts - counts.round()).abs() < 1e-9, "{counts}");
                    assert!((y.angles[i] - x[i]).abs() <= 5e-3 + q / 2.0, "{y:?}");
                }
            }
        }
    }
}
