//! The process-level tests: real binaries as separate processes over loopback, in one test
//! binary (issue 30: each test binary compiles and links zenoh and the whole workspace again,
//! and `cargo test` runs binaries one after the other, so the four areas below were four links
//! and four queues of real-time runs; as modules of one binary they are one link, and what one
//! area's tests do off the wall clock overlaps another's real-time runs). Each area keeps its
//! directory, `tests/tests/<area>/`, and its module doc.
//!
//! They run side by side on threads of one process. Robot names carry their test's tag
//! (`robot(tag)`, distinct across all areas), ports are reserved per run (`free_port`), and no
//! module changes the environment or the working directory. Every test that runs a loop on the
//! wall clock or in lockstep, or asserts misses, latencies or deadlines, takes
//! `realtime_turn()` first (one lock for the whole binary), so no two of them run at once.
//!
//! Run one area or module with a filter: `cargo test --release -p tilting-tests --test process
//! peers::ros2::` (the loop's area is `r#loop`, spelled `loop::` in a filter).

#[path = "front/main.rs"]
mod front;
#[path = "loop/main.rs"]
mod r#loop;
#[path = "peers/main.rs"]
mod peers;
#[path = "records/main.rs"]
mod records;
