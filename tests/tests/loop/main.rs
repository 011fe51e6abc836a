//! The loop's process tests: `tilting live`, the plant, controller and planner nodes over
//! zenoh, on the wall clock and in lockstep, their faults, watchdog and links (real, emulated,
//! proxied, across network namespaces and hosts). An area of the one process test binary
//! (`tests/process.rs`, issue 30); each module was a test file of its own.
//!
//! They run side by side on threads of one process. Robot names carry their test's tag
//! (`robot(tag)`, distinct across the modules), ports are reserved per run (`free_port`), and
//! no module changes the environment or the working directory. Every test that runs a loop on
//! the wall clock or in lockstep takes `realtime_turn()` first, so no two of them run at once
//! (before the merge, such tests of different files never overlapped either).

mod calibrate;
mod emulated_link;
mod faults;
mod host_mode;
mod hosts;
mod late;
mod live;
mod lockstep;
mod netns;
mod proxy;
mod realtime;
mod reentry;
mod reference;
mod run_file;
mod sched_fifo;
mod watchdog;
