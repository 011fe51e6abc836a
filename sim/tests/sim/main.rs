//! The simulator's integration tests, one test binary (issue 30 item 6: each
//! binary links the workspace, so one per crate keeps `cargo test` cheap).
//! Each module was a test file of its own; the modules share no state.

mod excitation;
mod imperfect;
mod last_peak;
mod network;
mod predict_events;
mod robust;
mod safe_mode;
