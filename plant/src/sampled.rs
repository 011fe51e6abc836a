//! The sampled loop, written once: a controller samples the plant every period `T`, and its
//! torque is held (through the actuator) until the next sample. Every sampled loop of the
//! project runs on this stepper ([`run`]): `tilting simulate` over a perfect link and over
//! impaired links (`tilting-sim`), and the plant node in lockstep and in real time (`node`).
//! What differs between them, how a state leaves and a torque comes back, is a [`Transport`].
//! The stepper owns the rest:
//!
//! - **the period grid**: sample `k` at `t_k = k T` (a product, not a running sum, which would
//!   drift); the torque the transport returns for it is held over `[t_k, t_{k+1}]`. The last
//!   period is cut at `t_end`; a remainder below a billionth of a period is merged into it (a
//!   zero-length hold would underflow the integrator's step). `t_end` may be infinite (a node
//!   without `--duration`);
//! - **a period**: without sampling on events, one call of
//!   [`Actuator::advance`](crate::imperfect::Actuator::advance) (clipped, lagged or held);
//! - **sampling on events** ([`Transport::samples_events`]): the period is integrated in
//!   segments with the torque held as commanded
//!   ([`Plant::advance_held_to_event`](crate::Plant::advance_held_to_event)). A segment ends at
//!   the period's end, at the first mode transition (the transport sends an extra state:
//!   [`Transport::extra`]) or when an answer in flight arrives ([`Transport::next_arrival`]);
//!   after each segment the transport names the torque now in force
//!   ([`Transport::torque_at`]);
//! - **the end**: at `t_end`, at a fault of the plant, or when the transport stops the loop
//!   (the node at Ctrl-C).
//!
//! Because one stepper serves them all, a lockstep plant node over zenoh computes what
//! `tilting simulate --control-period T` computes, bit for bit, given the same torques.

use crate::hybrid::{Fault, Observer, Plant};
use crate::imperfect::Actuator;

/// How a sampled loop ended without a fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// It reached `t_end`.
    Completed,
    /// The transport stopped it ([`Transport::sample`] returned `None`).
    Stopped,
}

/// How states leave the plant and torques come back, and what happens around each period: the
/// part of a sampled loop that differs between `simulate` (a law called in place, or emulated
/// links) and the plant node (zenoh, lockstep or paced by the wall clock). The transport owns
/// the plant, its actuator and the observer of its transitions and lends them to the stepper
/// ([`Transport::parts`]).
pub trait Transport {
    /// Receives the plant's transitions, peaks and samples.
    type Observer: Observer;

    /// The plant, the actuator the torque acts through, and the observer.
    fn parts(&mut self) -> (&mut Plant, &mut Actuator, &mut Self::Observer);

    /// Sample `k`: the plant stands at `t_k`; its state leaves, and the transport returns the
    /// torque (N m) to hold from `t_k` on, or `None` to stop the loop before this period.
    fn sample(&mut self, k: u64) -> Option<f64>;

    /// Whether the plant sends an extra state at each mode transition (`--sample-on-event`).
    fn samples_events(&self) -> bool {
        false
    }

    /// An extra state at a mode transition inside period `k`: the plant stands right after the
    /// transition (the reset applied). Called only when [`Transport::samples_events`].
    fn extra(&mut self, _k: u64) {}

    /// The earliest instant (s) after `t` at which an answer still in flight arrives, or
    /// infinity for none (a segment ends there).
    fn next_arrival(&self, _t: f64) -> f64 {
        f64::INFINITY
    }

    /// After a segment of period `k` ending at `t` (s) with sampling on events: the torque
    /// (N m) now in force, or `None` to keep the one held.
    fn torque_at(&mut self, _k: u64, _t: f64) -> Option<f64> {
        None
    }

    /// Period `k` ended: the plant stands at its end (`result` is `Ok`) or at a fault. `last`:
    /// it was the last period of the run.
    fn period_end(&mut self, _k: u64, _last: bool, _result: &Result<(), Fault>) {}
}

/// The period grid of a sampled loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Sample period `T` (s), positive.
    pub period: f64,
    /// End of the run (s); infinite for none.
    pub t_end: f64,
}

impl Grid {
    /// The end of period `k` (s), `t_{k+1} = (k + 1) T` or `t_end`, and whether it is the last
    /// period (a remainder below `1e-9 T` is merged into it).
    #[inline]
    pub fn end_of(&self, k: u64) -> (f64, bool) {
        let next = (k + 1) as f64 * self.period;
        if next >= self.t_end - 1e-9 * self.period {
            (self.t_end, true)
        } else {
            (next, false)
        }
    }
}

/// Runs the sampled loop over `transport` on `grid` from sample 0 (the plant must stand at
/// `t = 0`). `progress` gets the plant time about a thousand times per run of finite length.
///
/// Returns how the run ended and the number of states sent (periodic and extra).
pub fn run<T: Transport + ?Sized>(
    transport: &mut T,
    grid: Grid,
    progress: &mut dyn FnMut(f64),
) -> (Result<End, Fault>, u64) {
    let every = ((grid.t_end / grid.period) / 1000.0).ceil().max(1.0) as u64;
    let mut next_update = every;
    let mut sent = 0u64;
    let mut k: u64 = 0;
    loop {
        debug_assert_eq!(k as f64 * grid.period, transport.parts().0.time());
        let Some(tau) = transport.sample(k) else {
            return (Ok(End::Stopped), sent);
        };
        sent += 1;
        match period(transport, grid, k, tau, &mut sent) {
            Err(f) => return (Err(f), sent),
            Ok(true) => return (Ok(End::Completed), sent),
            Ok(false) => {}
        }
        let (t_next, _) = grid.end_of(k);
        k += 1;
        if k >= next_update {
            next_update += every;
            progress(t_next);
        }
    }
}

/// Period `k` of [`run`] once its sample returned `tau` (N m): integrates it (in segments
/// when the transport samples on events, counting the extra states in `sent`) and reports its
/// end ([`Transport::period_end`]). `Ok(true)`: it was the last period of `grid`. For a
/// driver that paces several plants itself (the plant node's host mode, one thread for all).
pub fn period<T: Transport + ?Sized>(
    transport: &mut T,
    grid: Grid,
    k: u64,
    tau: f64,
    sent: &mut u64,
) -> Result<bool, Fault> {
    let (t_next, last) = grid.end_of(k);
    let result = if transport.samples_events() {
        segments(transport, k, tau, t_next, sent)
    } else {
        let (plant, actuator, obs) = transport.parts();
        actuator.advance(plant, tau, t_next, obs)
    };
    transport.period_end(k, last, &result);
    result.map(|()| last)
}

/// Period `k` sampled on events: segments up to `t_next` (s) starting with `tau` (N m).
fn segments<T: Transport + ?Sized>(
    transport: &mut T,
    k: u64,
    mut tau: f64,
    t_next: f64,
    sent: &mut u64,
) -> Result<(), Fault> {
    loop {
        let t = transport.parts().0.time();
        if t >= t_next {
            return Ok(());
        }
        let t_seg = transport.next_arrival(t).min(t_next);
        let (plant, _, obs) = transport.parts();
        if plant.advance_held_to_event(tau, t_seg, obs)? {
            transport.extra(k);
            *sent += 1;
        }
        let t = transport.parts().0.time();
        if let Some(v) = transport.torque_at(k, t) {
            tau = v;
        }
    }
}
