//! Key expressions, messages and the byte-exact wire format of the tilting control loop.
//!
//! Three processes talk over zenoh: the **plant** (simulated hybrid system), the **controller**
//! (computed-torque PD with energy adaptation) and the **planner** (reference and gains). This
//! crate knows nothing of zenoh: it only builds key expression strings ([`keys`]), defines the
//! messages ([`msg`]) and turns them into bytes and back ([`codec`]).
//!
//! Conventions used by every message (see `docs/protocol.md` for byte tables):
//! - angles in rad, rates in rad/s, torques in N·m, times in plant seconds;
//! - `alpha`: plate tilt angle, counter-clockwise positive (`> 0` tilted over the left edge);
//! - `beta`: arm angle relative to the plate, `pi/2` upright, counter-clockwise positive;
//! - continuous state order `(alpha, beta, alpha_dot, beta_dot)`;
//! - wire format: little-endian, fixed-width integers, IEEE-754 `f64`, no padding.
//!
//! ```
//! use tilting_proto::{codec, Keys, PlantState, TorqueCommand};
//!
//! let keys = Keys::new("demo").unwrap();
//! assert_eq!(keys.plant_state(), "tilting/demo/plant/state");
//!
//! let cmd = TorqueCommand { seq: 7, tau: 0.5 };
//! let mut buf = [0u8; 16];
//! let n = codec::encode_into(&cmd, &mut buf);
//! assert_eq!(n, 16);
//! assert_eq!(codec::decode::<TorqueCommand>(&buf).unwrap(), cmd);
//! assert!(codec::decode::<PlantState>(&buf).is_err()); // wrong size
//! ```

#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod bounded;
pub mod codec;
pub mod keys;
pub mod law;
pub mod mode;
pub mod msg;
pub mod plausible;
pub mod source;
pub mod topic;

/// The protocol version this crate speaks. Protocol 2 added the `measured` byte to
/// [`PlantState`] (50 bytes; the rates may be absent); protocol 1's 49-byte states are refused
/// with [`DecodeError::OldVersion`]. Protocol 3 added [`LawReference`] (107 bytes, byte 0 the
/// marker 3): any law by name with its parameters, beside the paper law's 57-byte
/// [`Reference`], which is unchanged; a protocol-2 peer refuses it by its size. The layouts'
/// sizes tell the versions apart (`docs/protocol.md`, *Versions*).
pub const PROTOCOL_VERSION: u32 = 3;

pub use codec::{decode, encode, encode_into, DecodeError, Message};
pub use keys::{KeyError, Keys};
pub use law::{AnyReference, LawReference};
pub use mode::{Mode, ModeError};
pub use msg::{ModeEvent, PlantState, Reference, Status, TorqueCommand, ValidationError};
pub use plausible::Implausible;
pub use source::{SourceId, SourcePin};
pub use topic::{Topic, UnknownTopic};
