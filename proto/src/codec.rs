//! The wire format: the only place that touches bincode.
//!
//! Encoding is bincode 2 through serde with
//! `standard().with_little_endian().with_fixed_int_encoding()`: fields in declaration order, no
//! padding, integers little-endian at their full width, `f64` as its IEEE-754 bits little-endian,
//! `[f64; 4]` as four `f64` (no length), `String` as a `u64` byte length then UTF-8 bytes.
//! Decoding adds a 2048-byte limit, so a forged length prefix cannot make the receiver allocate
//! more than that.
//!
//! [`decode`] accepts a payload only if it has the right size, no trailing bytes, decodes, and
//! passes the message's `validate()`. Receivers should drop anything else (see
//! `docs/protocol.md`).

use crate::law::{AnyReference, LawReference};
use crate::msg::{ModeEvent, PlantState, Reference, Status, TorqueCommand, ValidationError};
use bincode::config::{Configuration, Fixint, Limit, LittleEndian};
use serde::de::DeserializeOwned;
use serde::Serialize;
use thiserror::Error;

/// Largest number of bytes a decode may claim; above every message's `MAX_WIRE_SIZE`.
pub const DECODE_LIMIT: usize = 2048;

const ENCODE_CONFIG: Configuration<LittleEndian, Fixint> = bincode::config::standard()
    .with_little_endian()
    .with_fixed_int_encoding();

const DECODE_CONFIG: Configuration<LittleEndian, Fixint, Limit<DECODE_LIMIT>> =
    ENCODE_CONFIG.with_limit::<DECODE_LIMIT>();

mod sealed {
    pub trait Sealed {}
}

/// A message of this crate that has a wire format.
///
/// Sealed: implemented for [`PlantState`], [`TorqueCommand`], [`ModeEvent`], [`Status`],
/// [`Reference`], [`LawReference`] and [`AnyReference`] (either of the last two layouts) only.
pub trait Message: Serialize + DeserializeOwned + sealed::Sealed {
    /// Type name used in error messages, e.g. `"PlantState"`.
    const NAME: &'static str;
    /// Exact wire size in bytes for fixed-size messages, `None` for [`Status`] and
    /// [`AnyReference`].
    const WIRE_SIZE: Option<usize>;
    /// Largest wire size of a valid message, bytes (a receive buffer of this size suffices).
    const MAX_WIRE_SIZE: usize;
    /// The wire size of an older protocol's layout of this message, if it had one, with what
    /// changed: a payload of that size is refused as [`DecodeError::OldVersion`].
    const OLD_LAYOUT: Option<(usize, &'static str)> = None;
    /// Range checks of the message (finite floats, enumerations in range, ...).
    fn validate(&self) -> Result<(), ValidationError>;
}

macro_rules! message {
    ($t:ty, $name:literal, $wire:expr, $max:expr) => {
        message!($t, $name, $wire, $max, None);
    };
    ($t:ty, $name:literal, $wire:expr, $max:expr, $old:expr) => {
        impl sealed::Sealed for $t {}
        impl Message for $t {
            const NAME: &'static str = $name;
            const WIRE_SIZE: Option<usize> = $wire;
            const MAX_WIRE_SIZE: usize = $max;
            const OLD_LAYOUT: Option<(usize, &'static str)> = $old;
            fn validate(&self) -> Result<(), ValidationError> {
                <$t>::validate(self)
            }
        }
    };
}

message!(
    PlantState,
    "PlantState",
    Some(PlantState::SIZE),
    PlantState::SIZE,
    Some((
        PlantState::SIZE_V1,
        "the protocol-1 layout, without the `measured` byte at offset 49 that says which \
         fields are measured"
    ))
);
message!(
    TorqueCommand,
    "TorqueCommand",
    Some(TorqueCommand::SIZE),
    TorqueCommand::SIZE
);
message!(
    ModeEvent,
    "ModeEvent",
    Some(ModeEvent::SIZE),
    ModeEvent::SIZE
);
message!(Status, "Status", None, Status::MAX_SIZE);
message!(
    Reference,
    "Reference",
    Some(Reference::SIZE),
    Reference::SIZE
);
message!(
    LawReference,
    "LawReference",
    Some(LawReference::SIZE),
    LawReference::SIZE
);
// Either layout, told apart by byte 0: a payload of another size is refused as trailing bytes
// or as ending early.
message!(AnyReference, "Reference", None, LawReference::SIZE);

/// Why a payload was rejected. Every variant names the message type.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DecodeError {
    /// A fixed-size message arrived with another length.
    #[error("{message}: wrong payload size: expected {expected} bytes, got {got}")]
    WrongSize {
        /// Message type name.
        message: &'static str,
        /// The message's wire size.
        expected: usize,
        /// The payload length.
        got: usize,
    },
    /// A payload of an older protocol's layout of the message: the sender speaks an older
    /// protocol (see `docs/protocol.md`, *Versions*).
    #[error(
        "{message}: a {got}-byte payload is {what}; this peer speaks protocol {protocol} \
         ({expected} bytes): update the sender (docs/protocol.md, Versions)"
    )]
    OldVersion {
        /// Message type name.
        message: &'static str,
        /// The payload length.
        got: usize,
        /// The message's wire size in this protocol.
        expected: usize,
        /// What the old layout lacks.
        what: &'static str,
        /// This crate's protocol version ([`crate::PROTOCOL_VERSION`]).
        protocol: u32,
    },
    /// A variable-size message is longer than its largest valid size.
    #[error("{message}: payload too large: at most {max} bytes, got {got}")]
    TooLarge {
        /// Message type name.
        message: &'static str,
        /// The message's largest valid size.
        max: usize,
        /// The payload length.
        got: usize,
    },
    /// The payload decoded but did not use every byte.
    #[error("{message}: {trailing} trailing bytes after the {used}-byte message")]
    TrailingBytes {
        /// Message type name.
        message: &'static str,
        /// Bytes used by the message.
        used: usize,
        /// Bytes left over.
        trailing: usize,
    },
    /// The bytes are not a message of this type (ends early, length prefix over the limit,
    /// invalid UTF-8, ...).
    #[error("{message}: malformed payload: {reason}")]
    Malformed {
        /// Message type name.
        message: &'static str,
        /// What the decoder found.
        reason: String,
    },
    /// The payload decoded but a field is out of range.
    #[error("invalid {0}")]
    Invalid(#[from] ValidationError),
}

/// Encodes `msg`. Does not validate: call `msg.validate()` first if the values may be bad
/// (receivers reject invalid messages).
pub fn encode<T: Message>(msg: &T) -> Vec<u8> {
    bincode::serde::encode_to_vec(msg, ENCODE_CONFIG)
        .unwrap_or_else(|e| panic!("{}: encoding into a Vec cannot fail: {e}", T::NAME))
}

/// Encodes `msg` into the front of `buf` without allocating and returns the number of bytes
/// written. Does not validate.
///
/// # Panics
/// If `buf` is shorter than the encoded message (a buffer of `T::MAX_WIRE_SIZE` bytes always
/// suffices for a valid message).
pub fn encode_into<T: Message>(msg: &T, buf: &mut [u8]) -> usize {
    bincode::serde::encode_into_slice(msg, buf, ENCODE_CONFIG).unwrap_or_else(|e| {
        panic!(
            "{}: encode_into buffer of {} bytes is too small: {e}",
            T::NAME,
            buf.len()
        )
    })
}

/// Decodes and validates one message: rejects a wrong size (fixed-size messages), a payload over
/// `T::MAX_WIRE_SIZE`, malformed bytes, trailing bytes and out-of-range fields.
pub fn decode<T: Message>(bytes: &[u8]) -> Result<T, DecodeError> {
    let got = bytes.len();
    match (T::WIRE_SIZE, T::OLD_LAYOUT) {
        (Some(expected), Some((old, what))) if got == old && got != expected => {
            return Err(DecodeError::OldVersion {
                message: T::NAME,
                got,
                expected,
                what,
                protocol: crate::PROTOCOL_VERSION,
            })
        }
        (Some(expected), _) if got != expected => {
            return Err(DecodeError::WrongSize {
                message: T::NAME,
                expected,
                got,
            })
        }
        (None, _) if got > T::MAX_WIRE_SIZE => {
            return Err(DecodeError::TooLarge {
                message: T::NAME,
                max: T::MAX_WIRE_SIZE,
                got,
            })
        }
        _ => {}
    }
    let (msg, used): (T, usize) =
        bincode::serde::decode_from_slice(bytes, DECODE_CONFIG).map_err(|e| {
            DecodeError::Malformed {
                message: T::NAME,
                reason: reason(&e),
            }
        })?;
    if used != got {
        return Err(DecodeError::TrailingBytes {
            message: T::NAME,
            used,
            trailing: got - used,
        });
    }
    msg.validate()?;
    Ok(msg)
}

fn reason(e: &bincode::error::DecodeError) -> String {
    use bincode::error::DecodeError as E;
    match e {
        E::UnexpectedEnd { additional } => format!(
            "payload ends early (at least {additional} more bytes needed; a string length prefix may exceed the payload)"
        ),
        E::LimitExceeded => format!(
            "a declared string length exceeds the {DECODE_LIMIT}-byte decode limit"
        ),
        E::Utf8 { inner } => format!("string is not valid UTF-8: {inner}"),
        // A message's own check inside its decoding (`PlantState`'s `measured` byte).
        E::OtherString(s) => s.clone(),
        other => other.to_string(),
    }
}
