//! The front door's command-line tests, one test binary (issue 30: each binary links the
//! workspace, so one per crate keeps `cargo test` cheap). Each module was a test file of its
//! own; they share `common` and no state (each run works in its own scratch directory).

mod common;

mod continuation_cli;
mod figures_cli;
mod headline_cli;
mod identify_cli;
mod margins_cli;
mod network_flags_cli;
mod robot_file_cli;
mod shard_cli;
mod simulate_cli;
