//! The front door: the workspace's layout and the docs' facts, the secure deployment (mutual
//! TLS and access control, `tilting live --secure`) and the front door under attack and
//! accident (forged and foreign messages, hostile files). An area of the one process test
//! binary (`tests/process.rs`, issue 30); each module was a test file of its own.
//!
//! They run side by side on threads of one process. Robot names carry their test's tag
//! (`robot(tag)`, distinct across the modules), ports are reserved per run (`free_port`), and
//! no module changes the environment or the working directory. Every test that runs a loop
//! takes `realtime_turn()` first, so no two run at once.

mod front_door;
mod layout;
mod live_secure;
mod secure;
