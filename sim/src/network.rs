//! The sampled loop over an impaired network: states go to the controller and torques come back
//! over two emulated links ([`tilting_link::Link`]), with the plant's rule for torques that
//! arrive late.
//!
//! Semantics (the same the plant node applies in real time, here on exact sample instants):
//!
//! - the state sampled at `t_k` is sent at `t_k`; if the state link delivers it (at `a`), the
//!   controller answers at once with the torque for that state, sent back at `a`; if the torque
//!   link delivers it, it arrives at `r_k`;
//! - at each sample instant `t_j` the plant takes, among the torques arrived by then
//!   (`r_k <= t_j`, with a tolerance of `1e-9` periods for the rounding of `t_k + D`), the one
//!   answering the newest state, if that state is newer than the one of the torque in force and
//!   at most `max_age` periods old; it holds it until a newer one takes over. An older torque
//!   arriving after a newer one is dropped and counted as reordered;
//! - before the first torque arrives the plant applies zero torque.
//!
//! So with a constant delay `D` (both directions together) and no loss, the torque computed
//! from the state at `t_k` acts from the first sample instant at or after `t_k + D`.
//!
//! The robot's hardware ([`tilting_plant::imperfect`]) sits at both ends: the state is measured
//! once per sample (`hw.measure`, before the link, so a lost state still draws its noise) and the
//! torque in force is applied through the actuator (`hw.advance`).

//!
//! Two options change the controller and the plant ([`LoopOptions`]):
//!
//! - **prediction** (`--predict`): the controller answers each state with the torque for the
//!   state predicted at the instant its answer will act ([`tilting_controller::Predictor`]);
//!   the round-trip delay is given, or estimated from the ages of the applied torques as the
//!   plant reports them (their median, when the first torque is applied and then every
//!   [`ESTIMATE_EVERY`] periods);
//! - **sampling on events** (`--sample-on-event`): at each mode transition inside a period the
//!   plant sends an extra state; its answer crosses the same links and takes effect the moment
//!   it arrives (between sample instants), unless a torque answering a newer periodic state is
//!   already in force.
//!
//! With neither option the loop is the plain one above, bit for bit.

use serde::{Deserialize, Serialize};
use tilting_controller::estimate::EstimatorChoice;
use tilting_controller::{Estimation, Predictor};
use tilting_link::ImpairedHold;
use tilting_plant::imperfect::{Actuator, Hardware, Measurement};
use tilting_plant::safe::{SafeSettings, Watchdog};
use tilting_plant::sampled::{self, Grid, Transport};
use tilting_plant::{Fault, Mode, Observer, Plant, State, TorqueLaw};

pub use tilting_link::Impairment;
pub use tilting_link::{NetStats, SafeModeStats};

/// How often an estimating predictor reads the ages (periods): the plant's status goes out at
/// 10 Hz, every 100 periods at 1 kHz.
pub const ESTIMATE_EVERY: u64 = 100;

pub use tilting_controller::predict::Predict;

/// Options of the sampled loop that change what it does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LoopOptions {
    /// Predict over the delay (`--predict`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub predict: Option<Predict>,
    /// The plant sends an extra state at each mode transition (`--sample-on-event`).
    pub sample_on_event: bool,
    /// The controller's state estimator (`--estimator`; `auto` is left out of the JSON).
    #[serde(default, skip_serializing_if = "EstimatorChoice::is_auto")]
    pub estimator: EstimatorChoice,
    /// The controller's model of the plant, which the predictor runs (`None`: the plant's own
    /// configuration, no model mismatch).
    #[serde(skip)]
    pub model: Option<tilting_plant::SimConfig>,
    /// The plant's watchdog and safe mode ([`tilting_plant::safe`]; `tilting simulate` sets
    /// the plant's defaults): after `watchdog` periods without a new valid torque the plant
    /// applies the safe mode's torque until one comes. `None`: the last torque is held.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub safe: Option<SafeSettings>,
}

impl LoopOptions {
    /// No option: the plain loop.
    pub fn is_plain(&self) -> bool {
        self.predict.is_none() && !self.sample_on_event && self.estimator.is_auto()
    }
}

/// Event answers in flight: `(period of the event, arrival time (s), torque (N m))`.
type InFlight = Vec<(u64, f64, f64)>;

/// The controller's answer to the measurement `y` in `mode` sampled at `t` (s), as the
/// controller node computes it: the state is the measured one or `est`'s estimate; the answer
/// is the law at the state `predictor` forecasts for the answer's arrival, or at that state
/// itself without prediction. `periodic`: a sample on the period grid (else an extra state at
/// an event).
fn answer<L: TorqueLaw>(
    predictor: &mut Option<Predictor>,
    est: &mut Estimation,
    law: &L,
    t: f64,
    mode: Mode,
    y: &Measurement,
    periodic: bool,
) -> f64 {
    let (mode, x): (Mode, State) = est.observe(t, mode, y);
    let (tau, t_act) = match predictor {
        Some(p) => (p.answer(law, t, mode, &x, periodic), p.acts_at(t, periodic)),
        None => (law.torque(t, mode, &x), t),
    };
    est.sent(t_act, tau);
    tau
}

/// [`crate::closed_loop::run_sampled`] over the links of `imp`: the zero-order hold with the
/// controller `law` at `period` (s) up to `t_end` (s), torques chosen by
/// [`tilting_link::ImpairedHold`], with the options `opts`. The controller sees the state
/// measured by `hw` and the torque acts through its actuator ([`Hardware::default`]: the
/// perfect robot; with sampling on events the torque is held as commanded). Returns the run's
/// result, the number of states the controller answered, and what the network did.
#[allow(clippy::too_many_arguments)]
pub fn run_sampled_over<L: TorqueLaw, O: Observer>(
    plant: &mut Plant,
    law: &L,
    period: f64,
    t_end: f64,
    imp: &Impairment,
    opts: &LoopOptions,
    hw: &mut Hardware,
    obs: &mut O,
    progress: &mut dyn FnMut(f64),
) -> (Result<(), Fault>, u64, NetStats) {
    let predictor = opts.predict.map(|p| {
        let d = match p {
            Predict::Given(d) => d,
            Predict::Estimated => 0.0,
        };
        Predictor::new(opts.model.unwrap_or(*plant.config()), period, d)
    });
    let estimation = Estimation::new(opts.estimator, opts.model.unwrap_or(*plant.config()));
    let mut links = OverLinks {
        estimation,
        plant,
        hw,
        obs,
        law,
        hold: imp.hold(period),
        period,
        tol: 1e-9 * period,
        predictor,
        estimate: opts.predict == Some(Predict::Estimated),
        estimated: false,
        events: opts.sample_on_event,
        pending: Vec::new(),
        safe: opts.safe.map(|s| SafeState {
            settings: s,
            watchdog: Watchdog::new(s.watchdog),
            entered: None,
            previous: None,
        }),
    };
    let (r, n) = sampled::run(&mut links, Grid { period, t_end }, progress);
    let mut stats = links.hold.stats().clone();
    // Only when it acted, so that a run the watchdog never saw reports what the plant node
    // reports (its summary's `network`).
    if let Some(s) = links.safe.as_ref().filter(|s| s.watchdog.trips() > 0) {
        stats.safe_mode = Some(SafeModeStats {
            trips: s.watchdog.trips(),
            periods: s.watchdog.safe_periods(),
            entered: s.entered.map(|(first, _)| first),
            since: s
                .watchdog
                .is_safe()
                .then(|| s.entered.map(|(_, last)| last))
                .flatten(),
        });
    }
    (r.map(|_| ()), n, stats)
}

/// The plant's watchdog in a sampled loop over links.
struct SafeState {
    settings: SafeSettings,
    watchdog: Watchdog,
    /// When the safe mode was first and last entered (s).
    entered: Option<(f64, f64)>,
    /// The previous sample's time (s) and measured angles (rad), for the safe mode's rates
    /// when they are not measured.
    previous: Option<(f64, [f64; 2])>,
}

/// The transport of [`run_sampled_over`]: the state measured by the hardware crosses the state
/// link, the controller answers it in place (predicting, if asked), the answer crosses the
/// torque link, and the plant's rule for late torques picks the torque in force.
struct OverLinks<'a, L, O> {
    plant: &'a mut Plant,
    hw: &'a mut Hardware,
    obs: &'a mut O,
    law: &'a L,
    hold: ImpairedHold,
    /// Sample period (s).
    period: f64,
    /// Arrivals within this time (s) of an instant count as arrived by then.
    tol: f64,
    predictor: Option<Predictor>,
    /// The controller's state estimation.
    estimation: Estimation,
    /// The predictor reads the delay from the ages of the applied torques.
    estimate: bool,
    /// The first estimate was made.
    estimated: bool,
    /// Sampling on events.
    events: bool,
    /// Answers to extra states in flight.
    pending: InFlight,
    /// The plant's watchdog and safe mode, if modelled.
    safe: Option<SafeState>,
}

impl<L: TorqueLaw, O: Observer> OverLinks<'_, L, O> {
    /// Applies the event answers that have arrived by `t` (within the tolerance), in arrival
    /// order, during period `now`.
    fn take_arrived(&mut self, t: f64, now: u64) {
        while let Some(i) = self
            .pending
            .iter()
            .enumerate()
            .filter(|(_, p)| p.1 <= t + self.tol)
            .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
            .map(|(i, _)| i)
        {
            let (k, _, tau) = self.pending.swap_remove(i);
            self.hold.take_extra(k, tau, now);
        }
    }
}

impl<L: TorqueLaw, O: Observer> Transport for OverLinks<'_, L, O> {
    type Observer = O;

    fn parts(&mut self) -> (&mut Plant, &mut Actuator, &mut O) {
        (self.plant, &mut self.hw.actuator, self.obs)
    }

    fn sample(&mut self, k: u64) -> Option<f64> {
        let t_k = k as f64 * self.period;
        // The plant reports the ages in its status, every ESTIMATE_EVERY periods and when the
        // first torque is applied.
        if self.estimate && (k.is_multiple_of(ESTIMATE_EVERY) || !self.estimated) {
            if let (Some(p), Some(a)) = (&mut self.predictor, self.hold.stats().age_median()) {
                p.set_delay(a as f64 * self.period);
                self.estimated = true;
            }
        }
        let (mode, y) = (self.plant.mode(), self.hw.measure(self.plant));
        self.obs.measured(t_k, mode, &y);
        let (predictor, est, law) = (&mut self.predictor, &mut self.estimation, self.law);
        let taken = self.hold.stats().torques_applied;
        let tau = self
            .hold
            .step(k, t_k, || answer(predictor, est, law, t_k, mode, &y, true));
        let tau = if self.pending.is_empty() {
            tau
        } else {
            self.take_arrived(t_k, k);
            self.hold.torque()
        };
        let Some(s) = &mut self.safe else {
            return Some(tau);
        };
        // The plant's rule (`tilting_plant::safe`), as the plant node applies it.
        if self.hold.stats().torques_applied > taken {
            s.watchdog.take();
        } else if s.watchdog.miss() && s.watchdog.trip() {
            s.entered = Some((s.entered.map_or(t_k, |e| e.0), t_k));
        }
        let previous = s.previous.replace((t_k, y.angles));
        if s.watchdog.count_period() {
            let x = tilting_plant::safe::measured_state(&y, t_k, previous);
            return Some(s.settings.torque(&self.plant.config().params, mode, &x));
        }
        Some(tau)
    }

    fn samples_events(&self) -> bool {
        self.events
    }

    fn extra(&mut self, k: u64) {
        let (t_e, m, xe) = (
            self.plant.time(),
            self.plant.mode(),
            self.hw.measure(self.plant),
        );
        let (predictor, est, law) = (&mut self.predictor, &mut self.estimation, self.law);
        let sent = self
            .hold
            .send_extra(t_e, || answer(predictor, est, law, t_e, m, &xe, false));
        if let Some((r, tau_e)) = sent {
            self.pending.push((k, r, tau_e));
        }
    }

    fn next_arrival(&self, t: f64) -> f64 {
        self.pending
            .iter()
            .map(|p| p.1)
            .filter(|&r| r > t + self.tol)
            .fold(f64::INFINITY, f64::min)
    }

    fn torque_at(&mut self, k: u64, t: f64) -> Option<f64> {
        self.take_arrived(t, k);
        if self.safe.as_ref().is_some_and(|s| s.watchdog.is_safe()) {
            return None; // the safe mode's torque holds until the next sample
        }
        Some(self.hold.torque())
    }
}

/// `--predict D` against the plant's `--max-age`: a torque predicted over `D` (s) acts at the
/// first sample at or after its state's time plus `D`, i.e. `ceil(D / period)` periods after
/// it, and the plant drops torques older than `max_age` periods. A delay longer than the age
/// limit would drop every predicted torque, so the combination is refused, naming both flags
/// and the allowed range (`tilting simulate` and `tilting live` alike).
pub fn check_max_age(delay: f64, period: f64, max_age: u64) -> Result<(), crate::ScenarioError> {
    let need = (delay / period - 1e-9).ceil().max(0.0) as u64;
    if need <= max_age {
        return Ok(());
    }
    Err(crate::ScenarioError::OutOfRange {
        field: "max_age".into(),
        flag: "--max-age".into(),
        value: max_age.to_string(),
        allowed: format!(
            ">= {need} periods with --predict {delay} (s) at a period of {period} s: the \
             predicted torques act {need} periods after the state they answer and the plant \
             drops older ones; give --max-age {need} or more (at most 1000), or a shorter \
             --predict (at most {} s with this --max-age)",
            max_age as f64 * period
        ),
    })
}

#[cfg(feature = "clap")]
pub use tilting_link::NetworkArgs;

/// The flags that change the loop ([`LoopOptions`]), shared by `simulate` and the nodes.
#[cfg(feature = "clap")]
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct LoopArgs {
    /// Prediction over the round-trip delay (`--predict`).
    #[command(flatten)]
    pub predict: tilting_controller::predict::PredictArgs,
    /// The plant sends an extra state at each mode transition; its answer takes effect as
    /// soon as it arrives
    #[arg(long)]
    pub sample_on_event: bool,
    /// The controller's state estimator (`--estimator`).
    #[command(flatten)]
    pub estimator: tilting_controller::EstimatorArgs,
}

#[cfg(feature = "clap")]
impl LoopArgs {
    /// The options these flags ask for.
    pub fn options(&self) -> LoopOptions {
        LoopOptions {
            predict: self.predict.predict,
            sample_on_event: self.sample_on_event,
            estimator: self.estimator.choice(),
            model: None,
            safe: None,
        }
    }
}
