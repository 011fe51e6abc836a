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

use tilting_plant::imperfect::Hardware;
use tilting_plant::{Fault, Observer, Plant, TorqueLaw};

pub use tilting_link::Impairment;
pub use tilting_link::NetStats;

/// [`crate::closed_loop::run_sampled`] over the links of `imp`: the zero-order hold with the
/// controller `law` at `period` (s) up to `t_end` (s), torques chosen by
/// [`tilting_link::ImpairedHold`], the controller seeing the state measured by `hw` and the
/// torque applied through its actuator ([`Hardware::default`]: the perfect robot). Returns the
/// run's result, the number of samples, and what the network did.
#[allow(clippy::too_many_arguments)]
pub fn run_sampled_over<L: TorqueLaw, O: Observer>(
    plant: &mut Plant,
    law: &L,
    period: f64,
    t_end: f64,
    imp: &Impairment,
    hw: &mut Hardware,
    obs: &mut O,
    progress: &mut dyn FnMut(f64),
) -> (Result<(), Fault>, u64, NetStats) {
    let mut hold = imp.hold(period);
    let every = ((t_end / period) / 1000.0).ceil().max(1.0) as u64;
    let mut next_update = every;
    let mut samples = 0u64;
    let mut k: u64 = 0;
    loop {
        let t_k = k as f64 * period;
        let y = hw.measure(plant);
        let tau = hold.step(k, t_k, || law.torque(t_k, plant.mode(), &y));
        samples += 1;
        let next = (k + 1) as f64 * period;
        let t_next = if next >= t_end - 1e-9 * period {
            t_end
        } else {
            next
        };
        if let Err(f) = hw.advance(plant, tau, t_next, obs) {
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

pub use tilting_link::NetworkArgs;
