//! The three contact modes of the hybrid system.
//!
//! [`Mode`] is defined once, in `tilting-proto`, and shared by the wire format, the model and
//! every report: there is no second enum to convert to or from.

pub use tilting_proto::{Mode, ModeError};
