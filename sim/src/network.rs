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

use tilting_link::{Burst, ImpairedHold, Jitter, LinkError, LinkSpec};
use tilting_plant::{Fault, Observer, Plant, TorqueLaw};

/// The impairments of the loop: one link per direction and the seed of their random streams.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Impairment {
    /// States, plant to controller.
    pub state: LinkSpec,
    /// Torques, controller to plant.
    pub torque: LinkSpec,
    /// Seed of both links' random streams (stream 0: states, 1: torques).
    pub seed: u64,
    /// Oldest torque the plant applies, periods between the state it answers and the current
    /// one (the plant's `--max-age`).
    pub max_age: u64,
}

impl Impairment {
    /// Both links perfect.
    pub fn is_perfect(&self) -> bool {
        self.state.is_perfect() && self.torque.is_perfect()
    }
}

pub use tilting_link::NetStats;

/// [`crate::closed_loop::run_sampled`] over the links of `imp`: the zero-order hold with the
/// controller `law` at `period` (s) up to `t_end` (s), torques chosen by
/// [`tilting_link::ImpairedHold`]. Returns the run's result, the number of samples, and what
/// the network did.
pub fn run_sampled_over<L: TorqueLaw, O: Observer>(
    plant: &mut Plant,
    law: &L,
    period: f64,
    t_end: f64,
    imp: &Impairment,
    obs: &mut O,
    progress: &mut dyn FnMut(f64),
) -> (Result<(), Fault>, u64, NetStats) {
    let mut hold = ImpairedHold::new(imp.state, imp.torque, imp.seed, period, imp.max_age);
    let every = ((t_end / period) / 1000.0).ceil().max(1.0) as u64;
    let mut next_update = every;
    let mut samples = 0u64;
    let mut k: u64 = 0;
    loop {
        let t_k = k as f64 * period;
        let tau = hold.step(k, t_k, || law.torque(t_k, plant.mode(), &plant.state()));
        samples += 1;
        let next = (k + 1) as f64 * period;
        let t_next = if next >= t_end - 1e-9 * period {
            t_end
        } else {
            next
        };
        if let Err(f) = plant.advance_held(tau, t_next, obs) {
            return (Err(f), samples, hold.stats().clone());
        }
        if t_next >= t_end {
            return (Ok(()), samples, hold.stats().clone());
        }
        k += 1;
        if k >= next_update {
            next_update += every;
            progress(t_next);
        }
    }
}

/// The impairment flags of `simulate` (and of the nodes that emulate a link): each has a form
/// for both directions and one per direction (`--state-...`: plant to controller,
/// `--torque-...`: controller to plant); a direction's own flag wins.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct NetworkArgs {
    /// Constant delay of each direction (s), in [0, 60]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub delay: Option<f64>,
    /// Constant delay of the states (s)
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub state_delay: Option<f64>,
    /// Constant delay of the torques (s)
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub torque_delay: Option<f64>,
    /// Jitter added to each direction's delay: uniform:MAX, normal:SIGMA (truncated at 0) or
    /// exp:MEAN, in s; a jittered link can reorder
    #[arg(long, value_name = "DIST:PARAM", value_parser = parse_jitter)]
    pub jitter: Option<Jitter>,
    /// Jitter of the states
    #[arg(long, value_name = "DIST:PARAM", value_parser = parse_jitter)]
    pub state_jitter: Option<Jitter>,
    /// Jitter of the torques
    #[arg(long, value_name = "DIST:PARAM", value_parser = parse_jitter)]
    pub torque_jitter: Option<Jitter>,
    /// Bernoulli loss probability of each direction, in [0, 1]
    #[arg(long, value_name = "P", allow_negative_numbers = true)]
    pub loss: Option<f64>,
    /// Loss probability of the states
    #[arg(long, value_name = "P", allow_negative_numbers = true)]
    pub state_loss: Option<f64>,
    /// Loss probability of the torques
    #[arg(long, value_name = "P", allow_negative_numbers = true)]
    pub torque_loss: Option<f64>,
    /// Bursty loss (Gilbert-Elliott) of each direction: P,R (good to bad, bad to good, per
    /// message)
    #[arg(long, value_name = "P,R", value_parser = parse_burst)]
    pub loss_burst: Option<Burst>,
    /// Bursty loss of the states
    #[arg(long, value_name = "P,R", value_parser = parse_burst)]
    pub state_loss_burst: Option<Burst>,
    /// Bursty loss of the torques
    #[arg(long, value_name = "P,R", value_parser = parse_burst)]
    pub torque_loss_burst: Option<Burst>,
    /// Seed of the links' random streams
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Oldest torque the plant applies (periods between the state it answers and the current
    /// one), as the plant's --max-age
    #[arg(long, default_value_t = 10, value_name = "PERIODS")]
    pub max_age: u64,
}

fn parse_jitter(s: &str) -> Result<Jitter, String> {
    s.parse().map_err(|e: LinkError| e.allowed)
}

fn parse_burst(s: &str) -> Result<Burst, String> {
    s.parse().map_err(|e: LinkError| e.allowed)
}

impl NetworkArgs {
    /// The impairment, validated (an error names the flag and the allowed range); `None` when
    /// no flag impairs the link.
    pub fn impairment(&self) -> Result<Option<Impairment>, LinkError> {
        let side = |delay: Option<f64>,
                    jitter: Option<Jitter>,
                    loss: Option<f64>,
                    burst: Option<Burst>,
                    prefix: &str| {
            let spec = LinkSpec {
                delay: delay.or(self.delay).unwrap_or(0.0),
                jitter: jitter.or(self.jitter),
                loss: loss.or(self.loss).unwrap_or(0.0),
                burst: burst.or(self.loss_burst),
            };
            // Name the flag the value came from.
            let own = |v: bool| if v { prefix } else { "" };
            spec.validate("").map_err(|mut e| {
                let which = e.flag.trim_start_matches("--").to_owned();
                let given = match which.as_str() {
                    "delay" => delay.is_some(),
                    "loss" => loss.is_some(),
                    _ => false,
                };
                e.flag = format!("--{}{which}", own(given));
                e
            })?;
            Ok::<_, LinkError>(spec)
        };
        let state = side(
            self.state_delay,
            self.state_jitter,
            self.state_loss,
            self.state_loss_burst,
            "state-",
        )?;
        let torque = side(
            self.torque_delay,
            self.torque_jitter,
            self.torque_loss,
            self.torque_loss_burst,
            "torque-",
        )?;
        let imp = Impairment {
            state,
            torque,
            seed: self.seed,
            max_age: self.max_age,
        };
        Ok((!imp.is_perfect()).then_some(imp))
    }
}
