//! The plant's integration tests, one test binary (issue 30: each binary links the workspace,
//! so one per crate keeps `cargo test` cheap). Each module was a test file of its own; the
//! modules share no state.

mod hardware;
mod physics;
