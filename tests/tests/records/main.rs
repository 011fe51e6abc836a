//! The recording tests (recordings, their sources, animations of them, the imperfect sensors
//! recorded), an area of the one process test binary (`tests/process.rs`, issue 30). Each
//! module was a test file of its own. They run side by
//! side on threads of one process: robot names carry the tag of their test (`robot(tag)`, tags
//! distinct across modules) and ports are reserved per run (`free_port`), so no two clash.

mod animate;
mod imperfect;
mod record_sources;
mod recordings;
