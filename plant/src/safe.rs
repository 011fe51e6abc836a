//! The plant's watchdog and safe mode, one rule for the plant node and `tilting simulate`.
//!
//! A plant counts the periods in which no new valid torque is taken into force (none arrived,
//! or only ones older than `--max-age`). After `--watchdog` such periods in a row it enters the
//! safe mode ([`Watchdog::miss`]); the node also enters it at once when the controller's
//! liveliness token disappears or, in lockstep, when no answer comes within the timeout
//! ([`Watchdog::trip`]). In safe mode the torque is [`SafeSettings::torque`]: none
//! (`--safe-mode zero`) or a holding computed-torque PD towards `beta = pi/2` (`--safe-mode
//! hold`, `--safe-kp`, `--safe-kd`) on the measured state, computed with the plant's own
//! parameters. The next valid torque ends it ([`Watchdog::take`]).

use crate::dynamics::torque_for_beta_ddot;
use crate::imperfect::Measurement;
use crate::{Mode, Params, State};
use std::f64::consts::FRAC_PI_2;

/// The torque applied in safe mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum SafeMode {
    /// No torque: the arm falls freely.
    Zero,
    /// A holding PD towards `beta = pi/2` (computed torque with `--safe-kp`, `--safe-kd`).
    #[default]
    Hold,
}

/// The watchdog and the safe mode's torque: the plant's `--watchdog`, `--safe-mode`,
/// `--safe-kp` and `--safe-kd`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SafeSettings {
    /// Periods without a new valid torque before the safe mode.
    pub watchdog: u64,
    /// The torque in safe mode.
    pub mode: SafeMode,
    /// Stiffness of the holding PD (1/s^2).
    pub kp: f64,
    /// Damping of the holding PD (1/s).
    pub kd: f64,
}

impl Default for SafeSettings {
    /// The plant's defaults: 50 periods, hold with `K_P = 25 1/s^2`, `K_D = 10 1/s`.
    fn default() -> Self {
        Self {
            watchdog: 50,
            mode: SafeMode::Hold,
            kp: 25.0,
            kd: 10.0,
        }
    }
}

impl SafeSettings {
    /// The safe mode's torque (N m) at the measured state `x` in `mode`, with the plant's
    /// parameters `params`.
    pub fn torque(&self, params: &Params, mode: Mode, x: &State) -> f64 {
        match self.mode {
            SafeMode::Zero => 0.0,
            SafeMode::Hold => {
                let v = self.kd * (0.0 - x[3]) + self.kp * (FRAC_PI_2 - x[1]);
                torque_for_beta_ddot(params, mode, x, v)
            }
        }
    }
}

impl SafeSettings {
    /// Checks every setting, naming the flag and its range.
    pub fn validate(&self) -> Result<(), crate::imperfect::ImperfectError> {
        let out = |flag, value: String, allowed| {
            Err(crate::imperfect::ImperfectError {
                flag,
                value,
                allowed,
            })
        };
        if !(1..=1_000_000).contains(&self.watchdog) {
            return out(
                "--watchdog",
                self.watchdog.to_string(),
                "1 to 1000000 periods",
            );
        }
        if !(self.kp.is_finite() && (0.0..=1e6).contains(&self.kp)) {
            return out("--safe-kp", self.kp.to_string(), "0 to 1e6 1/s^2");
        }
        if !(self.kd.is_finite() && (0.0..=1e4).contains(&self.kd)) {
            return out("--safe-kd", self.kd.to_string(), "0 to 1e4 1/s");
        }
        Ok(())
    }
}

/// The flags of the watchdog and the safe mode, shared by `tilting-plant` and `tilting
/// simulate` ([`SafeSettings`]).
#[cfg(feature = "clap")]
#[derive(Debug, Clone, Copy, PartialEq, clap::Args)]
pub struct SafeArgs {
    /// Safe mode after this many periods without a valid torque (realtime clock; `simulate`:
    /// over emulated links)
    #[arg(long, default_value_t = 50, value_name = "PERIODS")]
    pub watchdog: u64,
    /// Torque in safe mode
    #[arg(long, value_enum, default_value_t = SafeMode::Hold)]
    pub safe_mode: SafeMode,
    /// Stiffness (1/s^2) of the holding PD of --safe-mode hold
    #[arg(long, default_value_t = 25.0, value_name = "1/S2")]
    pub safe_kp: f64,
    /// Damping (1/s) of the holding PD of --safe-mode hold
    #[arg(long, default_value_t = 10.0, value_name = "1/S")]
    pub safe_kd: f64,
}

#[cfg(feature = "clap")]
impl Default for SafeArgs {
    /// The defaults of the flags ([`SafeSettings::default`]).
    fn default() -> Self {
        let s = SafeSettings::default();
        Self {
            watchdog: s.watchdog,
            safe_mode: s.mode,
            safe_kp: s.kp,
            safe_kd: s.kd,
        }
    }
}

#[cfg(feature = "clap")]
impl SafeArgs {
    /// The settings of the flags, validated.
    pub fn settings(&self) -> Result<SafeSettings, crate::imperfect::ImperfectError> {
        let s = SafeSettings {
            watchdog: self.watchdog,
            mode: self.safe_mode,
            kp: self.safe_kp,
            kd: self.safe_kd,
        };
        s.validate().map(|_| s)
    }
}

/// The state the safe mode's PD acts on, from the measurement `y` at `t` (s): the measured
/// state, or, with the rates not measured (`--measure angles`), the backward difference of the
/// measured angles since the previous sample `previous` (its time and angles; zero rates
/// without one). The plant's own fallback, not an estimator: the controller estimates.
pub fn measured_state(y: &Measurement, t: f64, previous: Option<(f64, [f64; 2])>) -> State {
    if let Some(x) = y.state() {
        return x;
    }
    let [a, b] = y.angles;
    match previous {
        Some((t0, [a0, b0])) if t > t0 => {
            State::new(a, b, (a - a0) / (t - t0), (b - b0) / (t - t0))
        }
        _ => State::new(a, b, 0.0, 0.0),
    }
}

/// The watchdog's count and the safe mode's state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Watchdog {
    /// Periods without a new valid torque before the safe mode.
    limit: u64,
    /// Periods in a row without a new valid torque.
    missed: u64,
    safe: bool,
    trips: u64,
    safe_periods: u64,
}

impl Watchdog {
    /// A watchdog that trips after `limit` periods without a new valid torque.
    pub fn new(limit: u64) -> Self {
        Self {
            limit,
            ..Self::default()
        }
    }

    /// A new valid torque was taken into force: the count restarts. Returns true if this ends
    /// the safe mode.
    pub fn take(&mut self) -> bool {
        self.missed = 0;
        std::mem::replace(&mut self.safe, false)
    }

    /// A period without a new valid torque. Returns true if the count has reached the limit:
    /// the plant must be in safe mode ([`Watchdog::trip`]).
    pub fn miss(&mut self) -> bool {
        self.missed += 1;
        self.missed >= self.limit
    }

    /// Enters the safe mode at once (the controller is gone). Returns true if it was not in
    /// safe mode.
    pub fn trip(&mut self) -> bool {
        if self.safe {
            return false;
        }
        self.safe = true;
        self.trips += 1;
        true
    }

    /// Counts a period run in safe mode, if it is in safe mode; returns whether it is.
    pub fn count_period(&mut self) -> bool {
        self.safe_periods += u64::from(self.safe);
        self.safe
    }

    /// In safe mode.
    pub fn is_safe(&self) -> bool {
        self.safe
    }

    /// Periods in a row without a new valid torque.
    pub fn missed(&self) -> u64 {
        self.missed
    }

    /// Times the safe mode was entered.
    pub fn trips(&self) -> u64 {
        self.trips
    }

    /// Periods run in safe mode.
    pub fn safe_periods(&self) -> u64 {
        self.safe_periods
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trips_after_the_limit_and_a_torque_ends_it() {
        let mut w = Watchdog::new(3);
        assert!(!w.miss() && !w.miss());
        assert!(!w.is_safe() && !w.count_period());
        assert!(w.miss(), "the third miss reaches the limit");
        assert!(w.trip(), "and enters the safe mode");
        assert!(w.miss() && !w.trip(), "already in safe mode");
        assert!(w.count_period());
        assert_eq!((w.trips(), w.safe_periods(), w.missed()), (1, 1, 4));
        assert!(w.take());
        assert!(!w.is_safe() && !w.count_period());
        assert!(!w.take(), "not in safe mode");
        // A miss streak starts again from zero.
        assert!(!w.miss() && !w.miss());
        assert!(w.trip() && !w.trip());
        assert_eq!(w.trips(), 2);
    }

    #[test]
    fn the_hold_is_a_pd_towards_upright() {
        let p = Params::default();
        let s = SafeSettings::default();
        // Upright at rest: nothing to correct but gravity's zero moment.
        let up = State::new(0.0, FRAC_PI_2, 0.0, 0.0);
        assert!(s.torque(&p, Mode::Flat, &up).abs() < 1e-12);
        // Flat, the arm alone: tau = m_l l (l v + g cos beta) with v = K_P (pi/2 - beta).
        let x = State::new(0.0, 1.2, 0.0, 0.3);
        let v = 25.0 * (FRAC_PI_2 - 1.2) - 10.0 * 0.3;
        let want = 1.0 * 2.0 * (2.0 * v + 9.81 * 1.2f64.cos());
        assert!((s.torque(&p, Mode::Flat, &x) - want).abs() < 1e-12);
        let zero = SafeSettings {
            mode: SafeMode::Zero,
            ..s
        };
        assert_eq!(zero.torque(&p, Mode::Left, &x), 0.0);
    }
}
