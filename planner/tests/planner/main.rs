//! The planner's integration tests, one test binary (issue 30: each binary links the workspace,
//! so one per crate keeps `cargo test` cheap). Each module was a test file of its own; the
//! modules share no state.

mod calibrate;
mod continuation;
#[cfg(feature = "node")] // runs the `tilting-planner` binary, built with the node only
mod exit_codes;
mod identify;
mod planning;
mod robust_goal;
mod sampled_lyapunov;
mod toy_law;
