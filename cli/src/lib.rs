//! The front door of the tilting system: the `tilting` binary and what it runs.
//!
//! - [`error`]: [`CommandError`], the exit codes (the libraries return their own errors);
//! - [`commands`]: the subcommands, grouped by what a person wants (run: `live`, `simulate`;
//!   plan: `plan orbit|sinusoid|bifurcation|gains`; look: `figures`, `animate`);
//! - [`robot`]: the robot file at the front door (its keys as the flags' defaults) and
//!   `tilting config`;
//!
//! `tilting live`, the main job (the nodes live on localhost with a status line, a recording and
//! a report), is [`tilting_live`]'s; this crate parses its flags and maps its ending to an exit
//! code.
//!
//! Child processes and the secure deployment's certificates, zenoh configurations and router
//! are `tilting_launch`'s; `security` and `supervise` here are that crate under the names
//! `live` and older callers use.
//!
//! The three node binaries of the design stay separate: `tilting-plant`, `tilting-controller`
//! and `tilting-planner` (the planner node that publishes references). `tilting live` starts the
//! first two as children and runs the planner's publisher in-process.

#![warn(missing_docs)]

pub mod commands;
pub mod error;
pub mod robot;

pub use error::CommandError;

/// `tilting_launch` (certificates, zenoh configurations, the router), by its former path.
pub use tilting_launch as security;
/// `tilting_launch` (child processes, ports), by its former path.
pub use tilting_launch as supervise;
