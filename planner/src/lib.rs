//! Planning for the tilting system (the paper's Sec. III), and the planner node.
//!
//! - [`sinusoid`]: approach 1, the frequency of a sinusoidal arm motion whose ideal-tracking
//!   tilt lands at a chosen instant, and the `(A, w)` partition of Fig. 4;
//! - [`orbit`]: approach 2, periodic tilting orbits of the closed loop by Newton shooting, with
//!   their Floquet multipliers;
//! - [`peak`]: the adaptation's energy target `E_av` for a wanted tilt peak;
//! - [`gains`]: orbits over a `(K_P, K_D)` grid (Fig. 6);
//! - [`bifurcation`]: the sweep over the adaptation gain `k` (Fig. 8) and `k*`;
//! - [`continuation`]: pseudo-arclength continuation of the orbits, flips, folds and
//!   Neimark–Sacker points, branch switching up the period-doubling cascade;
//! - [`lyapunov`]: the largest Lyapunov exponent of the tilting loop (variational equations
//!   through the landings);
//! - [`margins`]: what the stabilised orbit survives: delay × loss, control rate;
//! - [`jobs`]: the bifurcation sweep and the gains grid as jobs: checked, whole or sharded;
//! - [`shard`]: splitting a sweep into shards (`--shard I/N`) and merging them back;
//! - [`node`] (feature `node`): the planner node that publishes the controller's reference over
//!   zenoh (the `tilting-planner` binary).
//!
//! Closed-loop runs come from `tilting-sim`, the model and simulator from `tilting-plant`.

#![warn(missing_docs)]

pub mod bifurcation;
pub mod calibrate;
pub mod continuation;
pub mod gains;
pub mod identify;
pub mod jobs;
pub mod lyapunov;
pub mod margins;
#[cfg(feature = "node")]
pub mod node;
pub mod orbit;
pub mod peak;
pub mod shard;
pub mod sinusoid;
