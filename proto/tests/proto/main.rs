//! The wire format's integration tests, one test binary (issue 30: each binary links the
//! workspace, so one per crate keeps `cargo test` cheap). Each module was a test file of its
//! own. `alloc` installs the binary's global allocator, which records the largest allocation
//! per thread, so the other module's tests on other threads do not disturb its measurements.

mod alloc;
mod law;
mod wire;
