//! Prediction over the network delay (`--predict`): the controller answers a state sampled at
//! `t_s` with the torque for the state the plant will be in when that torque takes effect, not
//! for the state it was sent.
//!
//! The controller keeps the schedule of the torques it has sent and when each will take effect
//! at the plant (`t_s + delay`, on the plant's sample grid for periodic states). To answer a
//! state it runs the plant crate's own hybrid simulator ([`Plant`], impacts and mode changes
//! included) from that state under the scheduled torques up to the instant its answer will act,
//! and evaluates the control law there.
//!
//! With a zero delay the answer is the law evaluated on the state itself, bit for bit, so a
//! predicting controller over a perfect link is the plain one. A prediction that cannot be made
//! (a state the model refuses, or a fault inside the horizon) falls back to the plain answer
//! and is counted.

use std::collections::VecDeque;
use tilting_plant::{Mode, Plant, SimConfig, State, TorqueLaw};

/// Fraction of a period below which a time counts as on the sample grid (rounding of `t + D`).
const GRID_TOL: f64 = 1e-9;

/// Most answers kept (older ones can no longer be in force).
const MAX_SENT: usize = 65_536;

/// Where a predicting controller gets the delay from (`--predict auto|SECONDS`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Predict {
    /// A given round-trip delay (s).
    Given(f64),
    /// Estimated online: the median age of the applied torques (as the plant reports it)
    /// times the period.
    Estimated,
}

/// Parses `--predict`'s value: `auto` or a round-trip delay in seconds in [0, 60].
pub fn parse_predict(s: &str) -> Result<Predict, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(Predict::Estimated);
    }
    match s.parse::<f64>() {
        Ok(d) if (0.0..=60.0).contains(&d) => Ok(Predict::Given(d)),
        _ => Err(format!(
            "`{s}`: allowed are `auto` (estimate the delay from the ages the plant reports) \
             or a round-trip delay in seconds in [0, 60]"
        )),
    }
}

impl std::fmt::Display for Predict {
    /// `--predict`'s value that [`parse_predict`] reads back: `auto` or the delay in seconds.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Predict::Given(d) => write!(f, "{d}"),
            Predict::Estimated => f.write_str("auto"),
        }
    }
}

/// The `--predict` flag, declared once for the controller node, `simulate` and `live`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct PredictArgs {
    /// The controller predicts the plant's state over the round-trip delay with the hybrid
    /// model (impacts and mode changes included) and answers for the predicted state: `auto`
    /// (the default value) estimates the delay from the ages of the applied torques, as the
    /// plant reports them, or give the delay in seconds, in [0, 60]
    #[cfg_attr(
        feature = "clap",
        arg(long, value_name = "auto|SECONDS", num_args = 0..=1, default_missing_value = "auto",
            value_parser = parse_predict, allow_negative_numbers = true)
    )]
    pub predict: Option<Predict>,
}

/// The predictor of one controller: the model of the plant, the loop's period and delay, and
/// the answers sent.
#[derive(Debug, Clone)]
pub struct Predictor {
    model: SimConfig,
    period: f64,
    delay: f64,
    /// The answers sent, in the order of the states they answer: `(t_s, on_grid, tau)`, the
    /// state's sample time (s), whether it was a periodic sample, the torque (N m). When each
    /// acts follows from the current delay ([`Predictor::acts_at`]), so a new estimate of the
    /// delay re-times the answers still in flight.
    sent: VecDeque<(f64, bool, f64)>,
    /// Scratch: the effective schedule `(t_act, tau)` of one prediction.
    scratch: Vec<(f64, f64)>,
    predictions: u64,
    fallbacks: u64,
}

impl Predictor {
    /// A predictor with the plant model `model`, a loop sampled every `period` (s) and a
    /// round-trip `delay` (s, state and torque links together; 0 for none).
    pub fn new(model: SimConfig, period: f64, delay: f64) -> Self {
        Self {
            model,
            period,
            delay: delay.max(0.0),
            sent: VecDeque::new(),
            scratch: Vec::new(),
            predictions: 0,
            fallbacks: 0,
        }
    }

    /// The round-trip delay predicted over (s).
    pub fn delay(&self) -> f64 {
        self.delay
    }

    /// Sets the round-trip delay (s), e.g. from the ages the plant reports: an age of `a`
    /// periods means a delay of `a * period`.
    pub fn set_delay(&mut self, delay: f64) {
        if delay.is_finite() {
            self.delay = delay.max(0.0);
        }
    }

    /// The loop's sample period (s).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Sets the loop's sample period (s) (a controller learns it from the states' times).
    pub fn set_period(&mut self, period: f64) {
        if period.is_finite() && period > 0.0 {
            self.period = period;
        }
    }

    /// Predictions made, and those that fell back to the plain answer.
    pub fn counts(&self) -> (u64, u64) {
        (self.predictions, self.fallbacks)
    }

    /// When the answer to a state sampled at `t` (s) takes effect: for a periodic sample, the
    /// first sample instant at or after `t + delay` (the plant switches torques there); for an
    /// extra state sampled at a mode transition (`on_grid = false`), `t + delay` itself.
    pub fn acts_at(&self, t: f64, on_grid: bool) -> f64 {
        if self.delay == 0.0 {
            return t;
        }
        if on_grid {
            let n = ((t + self.delay) / self.period - GRID_TOL).ceil();
            (n * self.period).max(t)
        } else {
            t + self.delay
        }
    }

    /// The torque (N m) answering the state `x` in `mode` sampled at `t` (s), periodic
    /// (`on_grid`) or extra: the law at the state predicted for [`Predictor::acts_at`]. Records
    /// the answer. States must come in time order.
    pub fn answer<L: TorqueLaw>(
        &mut self,
        law: &L,
        t: f64,
        mode: Mode,
        x: &State,
        on_grid: bool,
    ) -> f64 {
        let t_act = self.acts_at(t, on_grid);
        let tau = if t_act <= t {
            law.torque(t, mode, x)
        } else {
            self.predictions += 1;
            match self.predict(t, mode, x, t_act) {
                Some((m, xp)) => law.torque(t_act, m, &xp),
                None => {
                    self.fallbacks += 1;
                    law.torque(t, mode, x)
                }
            }
        };
        self.sent.push_back((t, on_grid, tau));
        self.forget_old(t);
        tau
    }

    /// The state (mode, x) at `t_act` predicted from `x` in `mode` at `t` under the answers
    /// sent; `None` if the model refuses the state or faults on the way.
    pub fn predict(&mut self, t: f64, mode: Mode, x: &State, t_act: f64) -> Option<(Mode, State)> {
        let mut x0 = *x;
        // A measured state need not satisfy the mode's constraints exactly (sensor noise):
        // project it onto them.
        match mode {
            Mode::Flat => {
                x0[0] = 0.0;
                x0[2] = 0.0;
            }
            Mode::Left => x0[0] = x0[0].max(0.0),
            Mode::Right => x0[0] = x0[0].min(0.0),
        }
        let mut plant = Plant::new(self.model, t, mode, x0).ok()?;
        self.effective_schedule(t);
        // The torque in force at `t`: the last one acting at or before it (zero before any).
        let first_after = self.scratch.partition_point(|&(ta, _)| ta <= t);
        let mut tau = first_after
            .checked_sub(1)
            .map_or(0.0, |i| self.scratch[i].1);
        for &(ta, next_tau) in &self.scratch[first_after..] {
            if ta >= t_act {
                break;
            }
            plant.advance_held(tau, ta, &mut ()).ok()?;
            tau = next_tau;
        }
        plant.advance_held(tau, t_act, &mut ()).ok()?;
        Some((plant.mode(), plant.state()))
    }

    /// Fills `scratch` with when the answers sent act, in time order, from the one in force at
    /// `t` (s) on. The plant applies the answer to the newest state: an answer that would act
    /// only after the answer to a newer state (a periodic answer rounded up to the grid,
    /// overtaken by an event's) never acts.
    fn effective_schedule(&mut self, t: f64) {
        self.scratch.clear();
        let mut earliest_newer = f64::INFINITY;
        for &(ts, on_grid, tau) in self.sent.iter().rev() {
            let ta = self.acts_at(ts, on_grid);
            if ta < earliest_newer {
                self.scratch.push((ta, tau));
                earliest_newer = ta;
                if ta <= t {
                    break; // in force at `t`: older answers no longer matter
                }
            }
        }
        self.scratch.reverse();
    }

    /// Forgets answers sent for states older than `t - 2 delay - 1 s` (s), keeping the
    /// newest of those (it may still be in force): room for a longer delay estimated later.
    fn forget_old(&mut self, t: f64) {
        let keep_from = t - 2.0 * self.delay - 1.0;
        while self.sent.len() > MAX_SENT || (self.sent.len() >= 2 && self.sent[1].0 < keep_from) {
            self.sent.pop_front();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Display` is the inverse of [`parse_predict`] on the values it accepts.
    #[test]
    fn predict_round_trips_through_its_flag_value() {
        for p in [
            Predict::Estimated,
            Predict::Given(0.0),
            Predict::Given(0.1 + 0.2),
            Predict::Given(1e-300),
            Predict::Given(60.0),
        ] {
            assert_eq!(parse_predict(&p.to_string()), Ok(p), "{p}");
        }
    }
}

#[cfg(all(test, feature = "clap"))]
mod flag_tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        p: PredictArgs,
    }

    #[test]
    fn flag_text_round_trips() {
        // A value's text reads back the same (a robot file's `predict` key is that text).
        for predict in [
            None,
            Some(Predict::Estimated),
            Some(Predict::Given(0.0)),
            Some(Predict::Given(0.1 + 0.2)),
            Some(Predict::Given(60.0)),
        ] {
            let x = PredictArgs { predict };
            let flag = predict.map(|p| format!("--predict={p}"));
            let argv = std::iter::once("x".to_owned()).chain(flag);
            assert_eq!(Cli::try_parse_from(argv).unwrap().p, x);
        }
        // The bare flag estimates; a delay out of range is refused.
        assert_eq!(
            Cli::try_parse_from(["x", "--predict"]).unwrap().p.predict,
            Some(Predict::Estimated)
        );
        assert!(Cli::try_parse_from(["x", "--predict", "-1"]).is_err());
    }
}
