//! Helpers shared by the command-line tests of `tilting`.

#![allow(dead_code)] // each test file uses a part

/// The front door, built by cargo for these tests.
pub const BIN: &str = env!("CARGO_BIN_EXE_tilting");

/// The project's one temporary-directory helper (see the file).
#[path = "../../../../tests/src/scratch.rs"]
mod scratch;

#[allow(unused_imports)] // not every test file uses it
pub use scratch::Scratch;

/// The headline's sensors (issue 17) as flags, beside `Imperfections::measured_as_hardware`.
#[allow(unused_imports)] // not every test file uses it
pub use tilting_plant::imperfect::MEASURED_AS_HARDWARE;
