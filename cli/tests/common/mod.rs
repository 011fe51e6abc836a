//! Helpers shared by the command-line tests of `tilting`.

#![allow(dead_code)] // each test file uses a part

/// The front door, built by cargo for these tests.
pub const BIN: &str = env!("CARGO_BIN_EXE_tilting");

/// The project's one temporary-directory helper (see the file).
#[path = "../../../tests/src/scratch.rs"]
mod scratch;

#[allow(unused_imports)] // not every test file uses it
pub use scratch::Scratch;

/// The headline's sensors (issue 17): the angles only, 1 mrad of noise on each and a
/// 4,096-count encoder, as `simulate`/`live`/`tilting-plant` flags.
pub const MEASURED_AS_HARDWARE: [&str; 8] = [
    "--measure",
    "angles",
    "--noise-alpha",
    "0.001",
    "--noise-beta",
    "0.001",
    "--encoder-counts",
    "4096",
];
