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
use tilting_controller::Predictor;
use tilting_plant::imperfect::Hardware;
use tilting_plant::{Fault, Mode, Observer, Plant, State, TorqueLaw};

pub use tilting_link::Impairment;
pub use tilting_link::NetStats;

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
    /// The controller's model of the plant, which the predictor runs (`None`: the plant's own
    /// configuration, no model mismatch).
    #[serde(skip)]
    pub model: Option<tilting_plant::SimConfig>,
}

impl LoopOptions {
    /// Neither option: the plain loop.
    pub fn is_plain(&self) -> bool {
        self.predict.is_none() && !self.sample_on_event
    }
}

/// Event answers in flight: `(period of the event, arrival time (s), torque (N m))`.
type InFlight = Vec<(u64, f64, f64)>;

/// Applies the event answers that have arrived by `t` (within `tol`), in arrival order.
fn take_arrived(
    pending: &mut InFlight,
    hold: &mut tilting_link::ImpairedHold,
    t: f64,
    tol: f64,
    now: u64,
) {
    while let Some(i) = pending
        .iter()
        .enumerate()
        .filter(|(_, p)| p.1 <= t + tol)
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
        .map(|(i, _)| i)
    {
        let (k, _, tau) = pending.swap_remove(i);
        hold.take_extra(k, tau, now);
    }
}

/// The controller's answer to the state `x` in `mode` sampled at `t` (s): the law at the state
/// `predictor` forecasts for the answer's arrival, or at `x` itself without prediction.
/// `periodic`: a sample on the period grid (else an extra state at an event).
fn answer<L: TorqueLaw>(
    predictor: &mut Option<Predictor>,
    law: &L,
    t: f64,
    mode: Mode,
    x: &State,
    periodic: bool,
) -> f64 {
    match predictor {
        Some(p) => p.answer(law, t, mode, x, periodic),
        None => law.torque(t, mode, x),
    }
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
    let mut hold = imp.hold(period);
    let tol = 1e-9 * period;
    let mut predictor = opts.predict.map(|p| {
        let d = match p {
            Predict::Given(d) => d,
            Predict::Estimated => 0.0,
        };
        Predictor::new(opts.model.unwrap_or(*plant.config()), period, d)
    });
    let estimate = opts.predict == Some(Predict::Estimated);
    let mut estimated = false;
    let mut pending: InFlight = Vec::new();
    let every = ((t_end / period) / 1000.0).ceil().max(1.0) as u64;
    let mut next_update = every;
    let mut samples = 0u64;
    let mut k: u64 = 0;
    let result = loop {
        let t_k = k as f64 * period;
        // The plant reports the ages in its status, every ESTIMATE_EVERY periods and when the
        // first torque is applied.
        if estimate && (k.is_multiple_of(ESTIMATE_EVERY) || !estimated) {
            if let (Some(p), Some(a)) = (&mut predictor, hold.stats().age_median()) {
                p.set_delay(a as f64 * period);
                estimated = true;
            }
        }
        let (mode, x) = (plant.mode(), hw.measure(plant));
        let mut tau = hold.step(k, t_k, || answer(&mut predictor, law, t_k, mode, &x, true));
        samples += 1;
        let next = (k + 1) as f64 * period;
        let t_next = if next >= t_end - 1e-9 * period {
            t_end
        } else {
            next
        };
        if opts.sample_on_event || !pending.is_empty() {
            take_arrived(&mut pending, &mut hold, t_k, tol, k);
            tau = hold.torque();
        }
        if !opts.sample_on_event {
            if let Err(f) = hw.advance(plant, tau, t_next, obs) {
                break Err(f);
            }
        } else {
            // Segments end at the period's end, at an event answer's arrival, or at an event.
            let mut fault = None;
            while plant.time() < t_next {
                let t_seg = pending
                    .iter()
                    .map(|p| p.1)
                    .filter(|&r| r > plant.time() + tol)
                    .fold(t_next, f64::min);
                match plant.advance_held_to_event(tau, t_seg, obs) {
                    Err(f) => {
                        fault = Some(f);
                        break;
                    }
                    Ok(true) => {
                        let (t_e, m, xe) = (plant.time(), plant.mode(), hw.measure(plant));
                        let sent = hold
                            .send_extra(t_e, || answer(&mut predictor, law, t_e, m, &xe, false));
                        samples += 1;
                        if let Some((r, tau_e)) = sent {
                            pending.push((k, r, tau_e));
                        }
                    }
                    Ok(false) => {}
                }
                take_arrived(&mut pending, &mut hold, plant.time(), tol, k);
                tau = hold.torque();
            }
            if let Some(f) = fault {
                break Err(f);
            }
        }
        if t_next >= t_end {
            break Ok(());
        }
        k += 1;
        if k >= next_update {
            next_update += every;
            progress(t_next);
        }
    };
    (result, samples, hold.stats().clone())
}

pub use tilting_link::NetworkArgs;

/// The flags that change the loop ([`LoopOptions`]), shared by `simulate` and the nodes.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct LoopArgs {
    /// Prediction over the round-trip delay (`--predict`).
    #[command(flatten)]
    pub predict: tilting_controller::predict::PredictArgs,
    /// The plant sends an extra state at each mode transition; its answer takes effect as
    /// soon as it arrives
    #[arg(long)]
    pub sample_on_event: bool,
}

impl LoopArgs {
    /// The options these flags ask for.
    pub fn options(&self) -> LoopOptions {
        LoopOptions {
            predict: self.predict.predict,
            sample_on_event: self.sample_on_event,
            model: None,
        }
    }
}
