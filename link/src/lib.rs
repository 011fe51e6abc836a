//! A network link that is not perfect, emulated deterministically: what happens to a message
//! sent at time `t` over it (arrives at `t + delay + jitter`, or is lost).
//!
//! - constant delay `D` (s);
//! - jitter added to it, from a distribution ([`Jitter`]): `uniform:MAX` (on `[0, MAX]`),
//!   `normal:SIGMA` (normal with mean 0 and deviation `SIGMA`, truncated at 0: only its
//!   non-negative half, so the delay never drops below `D`), `exp:MEAN` (exponential); a jittered
//!   link can reorder messages;
//! - Bernoulli loss `P` (each message lost with probability `P`);
//! - bursty loss (Gilbert-Elliott, `P,R`): the link is *good* or *bad*; before each message it
//!   goes good → bad with probability `P` and bad → good with probability `R`; a message sent in
//!   the bad state is lost, one sent in the good state is lost with the Bernoulli `P` above.
//!
//! The random stream is ChaCha8 seeded with `(seed, stream)`: one seed gives every direction of
//! every run the same impairments on any machine, and the two directions of a loop (`stream` 0
//! for states, 1 for torques) are independent.
//!
//! ```
//! use tilting_link::{Link, LinkSpec};
//!
//! let spec: LinkSpec = LinkSpec { delay: 0.002, ..LinkSpec::default() };
//! let mut link = Link::new(spec, 7, 0);
//! assert_eq!(link.send(1.0), Some(1.002));
//! ```

#![warn(missing_docs)]
#![forbid(unsafe_code)]

use rand::{Rng as _, SeedableRng as _};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution as _, Exp, Normal};
use std::str::FromStr;

/// Largest accepted constant delay or jitter parameter, s (a minute: anything longer is not a
/// control loop).
pub const MAX_SECONDS: f64 = 60.0;

/// Largest `--max-age` (periods) the plant allows: the oldest torque it may apply.
pub const MAX_AGE: u64 = 1000;

/// A jitter distribution, added to the constant delay.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "dist", rename_all = "lowercase")]
pub enum Jitter {
    /// Uniform on `[0, max]` (s).
    Uniform {
        /// Upper end, s.
        max: f64,
    },
    /// Normal with mean 0 and deviation `sigma` (s), truncated at 0.
    Normal {
        /// Standard deviation of the untruncated normal, s.
        sigma: f64,
    },
    /// Exponential with mean `mean` (s).
    Exp {
        /// Mean, s.
        mean: f64,
    },
}

/// A flag value that is not a valid impairment.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("invalid `{flag}` = {value}: {allowed}")]
pub struct LinkError {
    /// The flag (or scenario field).
    pub flag: String,
    /// The value given.
    pub value: String,
    /// What is allowed.
    pub allowed: String,
}

fn err(flag: &str, value: impl ToString, allowed: &str) -> LinkError {
    LinkError {
        flag: flag.to_owned(),
        value: value.to_string(),
        allowed: allowed.to_owned(),
    }
}

impl Jitter {
    /// The mean (s) of the delay this jitter adds: uniform `max / 2`, the normal truncated at 0
    /// `sigma sqrt(2 / pi)`, the exponential's `mean`.
    pub fn mean(&self) -> f64 {
        match *self {
            Jitter::Uniform { max } => 0.5 * max,
            Jitter::Normal { sigma } => sigma * (2.0 / std::f64::consts::PI).sqrt(),
            Jitter::Exp { mean } => mean,
        }
    }
}

impl FromStr for Jitter {
    type Err = LinkError;
    /// `uniform:MAX`, `normal:SIGMA` or `exp:MEAN`, seconds.
    fn from_str(s: &str) -> Result<Self, LinkError> {
        const ALLOWED: &str = "uniform:MAX, normal:SIGMA or exp:MEAN, with a parameter in \
                               seconds in (0, 60]";
        let (dist, param) = s
            .split_once(':')
            .ok_or_else(|| err("--jitter", s, ALLOWED))?;
        let v: f64 = param
            .trim()
            .parse()
            .map_err(|_| err("--jitter", s, ALLOWED))?;
        if !(v.is_finite() && v > 0.0 && v <= MAX_SECONDS) {
            return Err(err("--jitter", s, ALLOWED));
        }
        match dist.trim() {
            "uniform" => Ok(Jitter::Uniform { max: v }),
            "normal" => Ok(Jitter::Normal { sigma: v }),
            "exp" | "exponential" => Ok(Jitter::Exp { mean: v }),
            other => Err(err(
                "--jitter",
                s,
                &format!("unknown distribution `{other}`; {ALLOWED}"),
            )),
        }
    }
}

impl std::fmt::Display for Jitter {
    /// The flag form [`Jitter::from_str`] parses: `uniform:MAX`, `normal:SIGMA`, `exp:MEAN` (s).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Jitter::Uniform { max } => write!(f, "uniform:{max}"),
            Jitter::Normal { sigma } => write!(f, "normal:{sigma}"),
            Jitter::Exp { mean } => write!(f, "exp:{mean}"),
        }
    }
}

/// Gilbert-Elliott bursty loss: `p` good → bad and `r` bad → good, per message.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Burst {
    /// Probability of going from good to bad before a message.
    pub p: f64,
    /// Probability of going from bad to good before a message.
    pub r: f64,
}

impl FromStr for Burst {
    type Err = LinkError;
    /// `P,R`, both in `[0, 1]`, `R > 0`.
    fn from_str(s: &str) -> Result<Self, LinkError> {
        const ALLOWED: &str = "P,R with P in [0, 1] (good to bad) and R in (0, 1] (bad to good)";
        let (p, r) = s
            .split_once(',')
            .ok_or_else(|| err("--loss-burst", s, ALLOWED))?;
        let (Ok(p), Ok(r)) = (p.trim().parse::<f64>(), r.trim().parse::<f64>()) else {
            return Err(err("--loss-burst", s, ALLOWED));
        };
        if !((0.0..=1.0).contains(&p) && r > 0.0 && r <= 1.0) {
            return Err(err("--loss-burst", s, ALLOWED));
        }
        Ok(Burst { p, r })
    }
}

impl std::fmt::Display for Burst {
    /// The flag form [`Burst::from_str`] parses: `P,R`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{}", self.p, self.r)
    }
}

/// What one direction of a link does to the messages on it. The default is a perfect link.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LinkSpec {
    /// Constant delay, s, in `[0, 60]`.
    pub delay: f64,
    /// Jitter added to the delay.
    pub jitter: Option<Jitter>,
    /// Bernoulli loss probability, in `[0, 1]`.
    pub loss: f64,
    /// Gilbert-Elliott bursty loss.
    pub burst: Option<Burst>,
}

impl LinkSpec {
    /// Checks the ranges; `prefix` names the direction in the error (`state-`, `torque-` or
    /// empty), as the flags do.
    pub fn validate(&self, prefix: &str) -> Result<(), LinkError> {
        if !(self.delay.is_finite() && (0.0..=MAX_SECONDS).contains(&self.delay)) {
            return Err(err(
                &format!("--{prefix}delay"),
                self.delay,
                "a delay in seconds in [0, 60]",
            ));
        }
        if !(self.loss.is_finite() && (0.0..=1.0).contains(&self.loss)) {
            return Err(err(
                &format!("--{prefix}loss"),
                self.loss,
                "a probability in [0, 1]",
            ));
        }
        let ok = |v: f64| v.is_finite() && v > 0.0 && v <= MAX_SECONDS;
        match self.jitter {
            Some(
                Jitter::Uniform { max: v } | Jitter::Normal { sigma: v } | Jitter::Exp { mean: v },
            ) if !ok(v) => {
                return Err(err(
                    &format!("--{prefix}jitter"),
                    v,
                    "a parameter in seconds in (0, 60]",
                ))
            }
            _ => {}
        }
        if let Some(b) = self.burst {
            if !((0.0..=1.0).contains(&b.p) && b.r > 0.0 && b.r <= 1.0) {
                return Err(err(
                    &format!("--{prefix}loss-burst"),
                    format!("{},{}", b.p, b.r),
                    "P in [0, 1] and R in (0, 1]",
                ));
            }
        }
        Ok(())
    }

    /// No delay, no jitter, no loss.
    pub fn is_perfect(&self) -> bool {
        *self == LinkSpec::default()
    }
}

/// One direction of an emulated link: a [`LinkSpec`] and its random stream.
#[derive(Debug, Clone)]
pub struct Link {
    spec: LinkSpec,
    rng: ChaCha8Rng,
    bad: bool,
}

impl Link {
    /// A link with `spec`, its random stream seeded with `(seed, stream)`.
    pub fn new(spec: LinkSpec, seed: u64, stream: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        Self {
            spec,
            rng,
            bad: false,
        }
    }

    /// The arrival time of a message sent at `t` (s), or `None` if it is lost. Draws from the
    /// random stream in a fixed order (burst state, loss, jitter), whatever the outcome, so the
    /// impairment of message `n` does not depend on what happened to earlier ones.
    pub fn send(&mut self, t: f64) -> Option<f64> {
        let s = self.spec;
        if let Some(b) = s.burst {
            let u: f64 = self.rng.random();
            self.bad = if self.bad { u >= b.r } else { u < b.p };
        }
        let u: f64 = self.rng.random();
        let lost = self.bad || u < s.loss;
        let jitter = match s.jitter {
            None => 0.0,
            Some(Jitter::Uniform { max }) => self.rng.random::<f64>() * max,
            Some(Jitter::Normal { sigma }) => loop {
                // Normal::new fails only for a non-finite sigma, which validate refuses.
                let v = Normal::new(0.0, sigma).map_or(0.0, |d| d.sample(&mut self.rng));
                if v >= 0.0 {
                    break v;
                }
            },
            Some(Jitter::Exp { mean }) => {
                Exp::new(1.0 / mean).map_or(0.0, |d| d.sample(&mut self.rng))
            }
        };
        (!lost).then_some(t + s.delay + jitter)
    }

    /// The specification.
    pub fn spec(&self) -> &LinkSpec {
        &self.spec
    }
}

/// What the plant's watchdog did in a loop that models it (`tilting_plant::safe`).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SafeModeStats {
    /// Times the safe mode was entered.
    pub trips: u64,
    /// Periods run in safe mode.
    pub periods: u64,
    /// When it was first entered (s).
    pub entered: Option<f64>,
    /// In safe mode at the end of the run, since this time (s).
    pub since: Option<f64>,
}

/// What an impaired loop did (see [`ImpairedHold`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NetStats {
    /// States the state link lost.
    pub states_lost: u64,
    /// Torques the torque link lost.
    pub torques_lost_on_link: u64,
    /// Torques taken into force.
    pub torques_applied: u64,
    /// Torques applied after their own period (age > 0).
    pub torques_late: u64,
    /// Torques that arrived after a newer one had been applied (dropped).
    pub torques_reordered: u64,
    /// Torques overtaken at the instant they would act by a newer one that arrived by then.
    pub torques_superseded: u64,
    /// Torques that arrived too old (age > `max_age`) and were dropped.
    pub torques_too_old: u64,
    /// Periods integrated with zero torque before the first torque arrived.
    pub periods_before_first_torque: u64,
    /// Histogram of the age of the applied torques: `age_histogram[a]` torques of age `a`
    /// periods.
    pub age_histogram: Vec<u64>,
    /// Longest run of periods without a new torque taken into force (the plant's watchdog
    /// trips when this reaches `--watchdog`).
    #[serde(default)]
    pub longest_gap: u64,
    /// The plant's watchdog and safe mode, where the loop models them (`tilting simulate`
    /// over links).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub safe_mode: Option<SafeModeStats>,
}

impl NetStats {
    /// The median age of the applied torques (periods), `None` before the first.
    pub fn age_median(&self) -> Option<u64> {
        self.age_quantile(0.5)
    }

    /// The smallest age (periods) at or below which a fraction `q` in (0, 1] of the applied
    /// torques lie, `None` before the first.
    pub fn age_quantile(&self, q: f64) -> Option<u64> {
        let n: u64 = self.age_histogram.iter().sum();
        let mut seen = 0;
        for (age, &c) in self.age_histogram.iter().enumerate() {
            seen += c;
            if c > 0 && seen as f64 >= q * n as f64 {
                return Some(age as u64);
            }
        }
        None
    }
}

/// The zero-order hold of a sampled loop whose states and torques cross two emulated links,
/// with the plant's rule for late torques (the semantics are in `tilting_sim::network`).
/// Used by the offline `simulate` and by the plant node in lockstep, so the two agree bit for
/// bit.
#[derive(Debug, Clone)]
pub struct ImpairedHold {
    up: Link,
    down: Link,
    max_age: u64,
    tol: f64,
    flight: Vec<(u64, f64, f64)>,
    applied: Option<u64>,
    tau: f64,
    gap: u64,
    stats: NetStats,
}

impl ImpairedHold {
    /// The hold for states on `state`, torques on `torque` (random streams 0 and 1 of `seed`),
    /// sampling `period` (s), applying torques at most `max_age` periods old.
    pub fn new(state: LinkSpec, torque: LinkSpec, seed: u64, period: f64, max_age: u64) -> Self {
        Self {
            up: Link::new(state, seed, 0),
            down: Link::new(torque, seed, 1),
            max_age,
            tol: 1e-9 * period,
            flight: Vec::new(),
            applied: None,
            tau: 0.0,
            gap: 0,
            stats: NetStats::default(),
        }
    }

    /// Sample `k` at `t_k` (s): the state leaves; if it arrives, `answer` computes the
    /// controller's torque for it, which goes back over the torque link. Then returns the
    /// torque to hold over `[t_k, t_{k+1})`. `answer` is called only for a state that arrives
    /// (a controller never sees a lost one).
    pub fn step(&mut self, k: u64, t_k: f64, answer: impl FnOnce() -> f64) -> f64 {
        match self.up.send(t_k) {
            None => self.stats.states_lost += 1,
            Some(a) => {
                let tau = answer();
                match self.down.send(a) {
                    None => self.stats.torques_lost_on_link += 1,
                    Some(r) => self.flight.push((k, r, tau)),
                }
            }
        }
        let mut best: Option<(u64, f64, f64)> = None;
        let (tol, max_age, applied) = (self.tol, self.max_age, self.applied);
        let stats = &mut self.stats;
        self.flight.retain(|&f| {
            if f.1 > t_k + tol {
                return true;
            }
            if applied.is_some_and(|a| f.0 <= a) {
                stats.torques_reordered += 1;
            } else if k - f.0 > max_age {
                stats.torques_too_old += 1;
            } else if let Some(b) = best {
                if f.0 > b.0 {
                    best = Some(f);
                }
                stats.torques_superseded += 1;
            } else {
                best = Some(f);
            }
            false
        });
        if let Some(b) = best {
            let age = (k - b.0) as usize;
            if self.stats.age_histogram.len() <= age {
                self.stats.age_histogram.resize(age + 1, 0);
            }
            self.stats.age_histogram[age] += 1;
            self.stats.torques_applied += 1;
            self.stats.torques_late += u64::from(age > 0);
            self.applied = Some(b.0);
            self.tau = b.2;
            self.gap = 0;
        } else {
            self.gap += 1;
            self.stats.longest_gap = self.stats.longest_gap.max(self.gap);
            if self.applied.is_none() {
                self.stats.periods_before_first_torque += 1;
            }
        }
        self.tau
    }

    /// An extra state sampled at `t` (s) between two sample instants (at a mode transition,
    /// `--sample-on-event`): it crosses the state link; if it arrives, `answer` computes the
    /// torque for it, which crosses the torque link. Returns when that torque arrives (s) and
    /// the torque, or `None` if either message is lost. The draws come from the same random
    /// streams as the periodic messages.
    pub fn send_extra(&mut self, t: f64, answer: impl FnOnce() -> f64) -> Option<(f64, f64)> {
        let Some(a) = self.up.send(t) else {
            self.stats.states_lost += 1;
            return None;
        };
        let tau = answer();
        match self.down.send(a) {
            None => {
                self.stats.torques_lost_on_link += 1;
                None
            }
            Some(r) => Some((r, tau)),
        }
    }

    /// The answer `tau` (N m) to an extra state sampled during period `k` has arrived during
    /// period `now` (`now >= k`): it takes effect at once, unless a torque answering a newer
    /// state (a periodic state after `k`) is already in force, in which case it is dropped and
    /// counted as reordered. Returns the torque now in force.
    pub fn take_extra(&mut self, k: u64, tau: f64, now: u64) -> f64 {
        if self.applied.is_some_and(|a| a > k) {
            self.stats.torques_reordered += 1;
            return self.tau;
        }
        let age = now.saturating_sub(k) as usize;
        if self.stats.age_histogram.len() <= age {
            self.stats.age_histogram.resize(age + 1, 0);
        }
        self.stats.age_histogram[age] += 1;
        self.stats.torques_applied += 1;
        self.stats.torques_late += u64::from(age > 0);
        self.applied = Some(k);
        self.tau = tau;
        self.gap = 0;
        self.tau
    }

    /// The torque in force (N m).
    pub fn torque(&self) -> f64 {
        self.tau
    }

    /// The period of the newest state whose answer is or was in force.
    pub fn applied(&self) -> Option<u64> {
        self.applied
    }

    /// What the links and the rule did so far.
    pub fn stats(&self) -> &NetStats {
        &self.stats
    }
}

/// The impairments of a loop: one link per direction, the seed of their random streams and the
/// plant's age rule.
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

    /// Whether the torques come back in time for a loop sampled every `period` (s): the round
    /// trip of the constant delays (the states' plus the torques', s) must be at most
    /// [`Impairment::max_age`] periods, else every torque is older than the plant applies and
    /// the loop has no control: refused, naming the delay flag, `--max-age` and the delays that
    /// fit. `Ok(Some(warning))` when only the jitter's mean ([`Jitter::mean`]) makes the round
    /// trip longer than that (the plant then drops most torques as too old), naming both.
    pub fn check_round_trip(&self, period: f64) -> Result<Option<String>, LinkError> {
        let (s, t) = (self.state.delay, self.torque.delay);
        let reach = self.max_age as f64 * period;
        let need = |rt: f64| (rt / period - 1e-9).ceil().max(0.0) as u64;
        // The --max-age that would do, when the plant allows it.
        let longer = |n: u64| {
            if n <= MAX_AGE {
                format!(", or --max-age {n} or more")
            } else {
                String::new()
            }
        };
        let (flag, value) = if s == t {
            ("--delay".to_owned(), format!("{s} s each way"))
        } else {
            (
                "--state-delay + --torque-delay".to_owned(),
                format!("{s} + {t} s"),
            )
        };
        if need(s + t) > self.max_age {
            return Err(LinkError {
                flag,
                value,
                allowed: format!(
                    "a round trip of at most --max-age {} periods ({reach} s at {period} s a \
                     period): with {} s no torque arrives young enough to be applied; give a \
                     delay in [0, {}] s each way{}",
                    self.max_age,
                    s + t,
                    0.5 * reach,
                    longer(need(s + t))
                ),
            });
        }
        let jitter = |l: &LinkSpec| l.jitter.map_or(0.0, |j| j.mean());
        let mean = s + t + jitter(&self.state) + jitter(&self.torque);
        Ok((need(mean) > self.max_age).then(|| {
            format!(
                "the link's mean round trip ({mean} s: {flag} {value} plus the jitter's mean) is \
                 longer than --max-age {} periods ({reach} s): the plant will drop most torques as \
                 too old; give less delay or jitter{}",
                self.max_age,
                longer(need(mean))
            )
        }))
    }

    /// The hold of a loop sampled every `period` (s) over these links.
    pub fn hold(&self, period: f64) -> ImpairedHold {
        ImpairedHold::new(self.state, self.torque, self.seed, period, self.max_age)
    }
}

#[cfg(feature = "clap")]
/// The impairment flags of `simulate` (and of the nodes that emulate a link): each has a form
/// for both directions and one per direction (`--state-...`: plant to controller,
/// `--torque-...`: controller to plant); a direction's own flag wins.
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
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
}

#[cfg(feature = "clap")]
fn parse_jitter(s: &str) -> Result<Jitter, String> {
    s.parse().map_err(|e: LinkError| e.allowed)
}

#[cfg(feature = "clap")]
fn parse_burst(s: &str) -> Result<Burst, String> {
    s.parse().map_err(|e: LinkError| e.allowed)
}

#[cfg(feature = "clap")]
impl NetworkArgs {
    /// The impairment, validated (an error names the flag and the allowed range), with the
    /// plant's age rule `max_age` (periods); `None` when no flag impairs the link.
    pub fn impairment(&self, max_age: u64) -> Result<Option<Impairment>, LinkError> {
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
            max_age,
        };
        Ok((!imp.is_perfect()).then_some(imp))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats(spec: LinkSpec, n: usize) -> (f64, f64, usize) {
        let mut l = Link::new(spec, 42, 0);
        let d: Vec<f64> = (0..n).filter_map(|_| l.send(0.0)).collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let min = d.iter().cloned().fold(f64::INFINITY, f64::min);
        (mean, min, n - d.len())
    }

    /// Sample means against the distributions' closed forms: uniform max/2, half-normal
    /// sigma sqrt(2/pi), exponential mean. With 200,000 samples the standard error of the mean
    /// is below 0.3 % of it; the tolerance is 1.5 %.
    /// Jitter::mean against the sample mean of the link's own draws (200,000 each: the standard
    /// error is below 0.3 % of the mean; tolerance 1.5 %).
    #[test]
    fn the_jitters_mean_is_the_sample_means() {
        for j in [
            Jitter::Uniform { max: 0.004 },
            Jitter::Normal { sigma: 0.002 },
            Jitter::Exp { mean: 0.003 },
        ] {
            let spec = LinkSpec {
                jitter: Some(j),
                ..LinkSpec::default()
            };
            let (sampled, _, _) = stats(spec, 200_000);
            assert!(
                (sampled / j.mean() - 1.0).abs() < 0.015,
                "{j:?}: {sampled} vs {}",
                j.mean()
            );
        }
    }

    /// A round trip of constant delays longer than --max-age periods is refused naming the
    /// flags and the delays that fit; one exactly at it passes; a jitter whose mean makes it
    /// longer is a warning naming both values.
    #[test]
    fn a_round_trip_longer_than_the_age_rule_is_refused_or_warned_about() {
        let imp = |delay: f64, jitter: Option<Jitter>, max_age: u64| {
            let spec = LinkSpec {
                delay,
                jitter,
                ..LinkSpec::default()
            };
            Impairment {
                state: spec,
                torque: spec,
                seed: 0,
                max_age,
            }
        };
        let e = imp(25.0, None, 10).check_round_trip(1e-3).unwrap_err();
        let m = e.to_string();
        assert_eq!(e.flag, "--delay");
        // 50,000 periods would do, more than the plant allows: not offered.
        assert!(
            m.contains("--max-age 10") && m.contains("[0, 0.005] s") && !m.contains("50000"),
            "{m}"
        );
        // 2 x 6 ms needs 12 periods.
        let m = imp(0.006, None, 10).check_round_trip(1e-3).unwrap_err();
        assert!(m.to_string().contains("--max-age 12 or more"), "{m}");
        // 2 x 5 ms = 10 periods of 1 ms: every torque is exactly --max-age old.
        assert_eq!(imp(0.005, None, 10).check_round_trip(1e-3), Ok(None));
        // Uneven directions name both flags.
        let mut uneven = imp(0.004, None, 10);
        uneven.torque.delay = 0.007;
        let e = uneven.check_round_trip(1e-3).unwrap_err();
        assert_eq!(e.flag, "--state-delay + --torque-delay");
        // 2 x 4 ms plus 2 x 1.5 ms of mean jitter = 11 ms > 10 periods: a warning.
        let w = imp(0.004, Some(Jitter::Uniform { max: 0.003 }), 10)
            .check_round_trip(1e-3)
            .unwrap()
            .unwrap();
        assert!(w.contains("--max-age 10") && w.contains("0.011"), "{w}");
    }

    #[test]
    fn jitter_means_match_their_closed_forms() {
        let n = 200_000;
        let d = 0.001;
        for (j, want) in [
            (Jitter::Uniform { max: 0.004 }, 0.002),
            (
                Jitter::Normal { sigma: 0.003 },
                0.003 * (2.0 / std::f64::consts::PI).sqrt(),
            ),
            (Jitter::Exp { mean: 0.0025 }, 0.0025),
        ] {
            let (mean, min, lost) = stats(
                LinkSpec {
                    delay: d,
                    jitter: Some(j),
                    ..LinkSpec::default()
                },
                n,
            );
            assert_eq!(lost, 0);
            assert!(min >= d, "{j:?}: a delay below the constant one: {min}");
            assert!(
                ((mean - d) / want - 1.0).abs() < 0.015,
                "{j:?}: mean jitter {} against {want}",
                mean - d
            );
        }
    }

    /// Bernoulli loss rate P; Gilbert-Elliott stationary loss p / (p + r) and mean burst length
    /// 1 / r (closed forms of the two-state chain).
    #[test]
    fn loss_rates_and_burst_lengths_match_their_closed_forms() {
        let n = 400_000;
        let (_, _, lost) = stats(
            LinkSpec {
                loss: 0.1,
                ..LinkSpec::default()
            },
            n,
        );
        assert!((lost as f64 / n as f64 - 0.1).abs() < 0.003, "{lost}");
        let b = Burst { p: 0.01, r: 0.25 };
        let mut l = Link::new(
            LinkSpec {
                burst: Some(b),
                ..LinkSpec::default()
            },
            3,
            1,
        );
        let outcomes: Vec<bool> = (0..n).map(|_| l.send(0.0).is_none()).collect();
        let rate = outcomes.iter().filter(|&&x| x).count() as f64 / n as f64;
        let want = b.p / (b.p + b.r);
        assert!(
            (rate / want - 1.0).abs() < 0.05,
            "loss {rate} against {want}"
        );
        let mut bursts = Vec::new();
        let mut run = 0;
        for &x in &outcomes {
            if x {
                run += 1;
            } else if run > 0 {
                bursts.push(run);
                run = 0;
            }
        }
        let mean = bursts.iter().sum::<usize>() as f64 / bursts.len() as f64;
        assert!(
            (mean * b.r - 1.0).abs() < 0.05,
            "mean burst {mean} against {}",
            1.0 / b.r
        );
    }

    #[test]
    fn a_seed_repeats_and_streams_differ() {
        let spec = LinkSpec {
            delay: 0.001,
            jitter: Some(Jitter::Exp { mean: 0.001 }),
            loss: 0.2,
            burst: None,
        };
        let run = |seed, stream| {
            let mut l = Link::new(spec, seed, stream);
            (0..1000).map(|k| l.send(k as f64)).collect::<Vec<_>>()
        };
        assert_eq!(run(5, 0), run(5, 0));
        assert_ne!(run(5, 0), run(5, 1));
        assert_ne!(run(5, 0), run(6, 0));
    }

    #[test]
    fn bad_values_name_the_flag_and_the_range() {
        let e = LinkSpec {
            delay: -0.001,
            ..LinkSpec::default()
        }
        .validate("")
        .unwrap_err()
        .to_string();
        assert!(e.contains("--delay") && e.contains("[0, 60]"), "{e}");
        let e = LinkSpec {
            loss: 1.5,
            ..LinkSpec::default()
        }
        .validate("torque-")
        .unwrap_err()
        .to_string();
        assert!(e.contains("--torque-loss") && e.contains("[0, 1]"), "{e}");
        let e = "gamma:0.001".parse::<Jitter>().unwrap_err().to_string();
        assert!(
            e.contains("--jitter") && e.contains("unknown distribution `gamma`"),
            "{e}"
        );
        assert!("uniform:-1".parse::<Jitter>().is_err());
        assert!("normal".parse::<Jitter>().is_err());
        assert_eq!(
            "exp:0.002".parse::<Jitter>(),
            Ok(Jitter::Exp { mean: 0.002 })
        );
        let e = "0.1".parse::<Burst>().unwrap_err().to_string();
        assert!(e.contains("--loss-burst"), "{e}");
        assert!("0.1,0".parse::<Burst>().is_err());
        assert_eq!("0.01,0.3".parse::<Burst>(), Ok(Burst { p: 0.01, r: 0.3 }));
    }
}
