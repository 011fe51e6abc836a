//! Any law on the wire (protocol 3): [`LawReference`], a law by name with a bounded list of
//! positional parameters beside the trajectory, and [`AnyReference`], what a controller decodes
//! on the planner's reference key (either layout).
//!
//! The 57-byte [`Reference`] of protocol 2 is the paper law's parameter list: it stays what
//! every command sends for the paper's law, byte for byte. A law with other parameters travels
//! as a [`LawReference`] (107 bytes): its name (as in `--law`), the trajectory, and up to
//! [`LawReference::MAX_PARAMETERS`] `f64` in the order of the law's own list
//! (`tilting_controller::PlannableLaw::parameters`), each in the unit that law documents.
//! Byte 0 tells the layouts apart as well as the size does: a `Reference`'s `kind` (0..=2),
//! a `LawReference`'s marker 3. A protocol-2 peer refuses a `LawReference` by its size check
//! (`Reference: wrong payload size: expected 57 bytes, got 107`), never misreads it
//! (`docs/protocol.md`, *Versions*).
//!
//! ```
//! use tilting_proto::{codec, AnyReference, LawReference, Reference};
//! let toy = LawReference {
//!     trajectory: Reference::HOLD,
//!     amplitude: 0.0,
//!     omega: 0.0,
//!     law: "plain-pd".into(),
//!     parameters: vec![400.0, 56.56],
//! };
//! let bytes = codec::encode(&toy);
//! assert_eq!((bytes.len(), bytes[0]), (LawReference::SIZE, LawReference::MARKER));
//! // A controller decodes either layout from the reference key.
//! let any: AnyReference = codec::decode(&bytes).unwrap();
//! assert_eq!(any.law(), toy);
//! // The paper's law of a protocol-2 message, in the generic form.
//! let paper = Reference { kind: Reference::HOLD, amplitude: 0.0, omega: 0.0, kp: 100.0,
//!     kd: 14.14, k: 500.0, energy_avg: 20.0, torque_limit: 0.0 };
//! let any: AnyReference = codec::decode(&codec::encode(&paper)).unwrap();
//! assert_eq!(any.law().law, LawReference::PAPER_LAW);
//! assert_eq!(any.law().parameters, [100.0, 14.14, 500.0, 20.0, 0.0]);
//! // Too many parameters are refused naming the field and the bound.
//! let long = LawReference { parameters: vec![0.0; 9], ..toy };
//! assert!(long.validate().unwrap_err().to_string().contains("count"));
//! ```

use crate::msg::{
    at_most, deserialize_dual, finite, moving_omega, serialize_dual, Reference, ValidationError,
};
use serde::de::{Error as _, SeqAccess, Visitor};
use serde::{Deserialize, Serialize};

/// A law by name with its parameters, and the trajectory it tracks (protocol 3); 107 bytes.
///
/// Encoding panics on a name over [`LawReference::LAW_NAME_MAX`] bytes or a list over
/// [`LawReference::MAX_PARAMETERS`] (they have no wire form): check with
/// [`LawReference::validate`] first.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "schema", schemars(deny_unknown_fields))]
pub struct LawReference {
    /// 0 hold `beta_d = pi/2`, 1 sinusoid, 2 excitation, as [`Reference::kind`]
    /// ([`Reference::HOLD`], [`Reference::SINUSOID`], [`Reference::EXCITATION`]).
    pub trajectory: u8,
    /// Sinusoid amplitude (the excitation's bound), rad (ignored for hold).
    pub amplitude: f64,
    /// Sinusoid angular frequency (the excitation's base), rad/s; `> 0` for a sinusoid or an
    /// excitation.
    pub omega: f64,
    /// The law's name, as in `--law` and the controller's registry (`computed-torque`): 1 to
    /// [`LawReference::LAW_NAME_MAX`] bytes of `a-z`, `0-9` and `-`.
    pub law: String,
    /// The law's parameters in the order of its list, each in the unit the law documents
    /// (for the paper's law [`LawReference::PAPER_PARAMETERS`]); at most
    /// [`LawReference::MAX_PARAMETERS`], every one finite. The law checks their ranges.
    pub parameters: Vec<f64>,
}

/// The wire layout of [`LawReference`] (bincode: fields in this order, no padding).
#[derive(Serialize, Deserialize)]
struct LawReferenceWire {
    marker: u8,
    trajectory: u8,
    amplitude: f64,
    omega: f64,
    law: [u8; LawReference::LAW_NAME_MAX],
    count: u8,
    parameters: [f64; LawReference::MAX_PARAMETERS],
}

/// The JSON form of [`LawReference`].
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct LawReferenceJson {
    trajectory: u8,
    amplitude: f64,
    omega: f64,
    law: String,
    parameters: Vec<f64>,
}

const M: &str = "LawReference";
const NAME_RANGE: &str = "1 to 24 bytes of a-z, 0-9 and '-' (the law's name, as in --law), \
                          NUL-padded to 24 bytes on the wire";
const COUNT_RANGE: &str = "0..=8 parameters (LawReference::MAX_PARAMETERS)";
const PARAMETER_FIELDS: [&str; LawReference::MAX_PARAMETERS] = [
    "parameters[0]",
    "parameters[1]",
    "parameters[2]",
    "parameters[3]",
    "parameters[4]",
    "parameters[5]",
    "parameters[6]",
    "parameters[7]",
];

impl LawReference {
    /// Byte 0 of the layout: the protocol that introduced it (a [`Reference`]'s `kind` there
    /// is `0..=2`).
    pub const MARKER: u8 = 3;
    /// Longest law name, bytes.
    pub const LAW_NAME_MAX: usize = 24;
    /// Most parameters a law may have on the wire.
    pub const MAX_PARAMETERS: usize = 8;
    /// Exact wire size in bytes.
    pub const SIZE: usize = 107;
    /// The paper's law's name (`--law computed-torque`): what a [`Reference`] carries.
    pub const PAPER_LAW: &'static str = "computed-torque";
    /// The paper's law's parameters, in the order of its generic form: the floats of a
    /// [`Reference`] after `amplitude` and `omega` (`kp` 1/s², `kd` 1/s, `k` 1/(J s²),
    /// `energy_avg` J, `torque_limit` N m with 0 for none).
    pub const PAPER_PARAMETERS: [&'static str; 5] = ["kp", "kd", "k", "energy_avg", "torque_limit"];

    /// Checks `trajectory` in `0..=2`, `amplitude` and `omega` finite, `omega > 0` for a
    /// sinusoid or an excitation, the name's alphabet and length, at most
    /// [`LawReference::MAX_PARAMETERS`] parameters and every one finite. The ranges of the
    /// parameters are the law's to check (the controller's registry).
    pub fn validate(&self) -> Result<(), ValidationError> {
        at_most(
            M,
            "trajectory",
            self.trajectory,
            Reference::EXCITATION,
            "0..=2 (0 hold, 1 sinusoid, 2 excitation)",
        )?;
        finite(M, "amplitude", self.amplitude)?;
        finite(M, "omega", self.omega)?;
        moving_omega(M, self.omega, self.trajectory != Reference::HOLD)?;
        self.fits_the_layout()?;
        let alphabet = |c: u8| c.is_ascii_lowercase() || c.is_ascii_digit() || c == b'-';
        if self.law.is_empty() || !self.law.bytes().all(alphabet) {
            return Err(ValidationError::BadName {
                message: M,
                field: "law",
                value: self.law.clone(),
                allowed: NAME_RANGE,
            });
        }
        for (field, &value) in PARAMETER_FIELDS.iter().zip(&self.parameters) {
            finite(M, field, value)?;
        }
        Ok(())
    }

    /// The protocol-2 [`Reference`] of this law, if it is the paper's with its five
    /// parameters (what a sender of the paper's law publishes, so that protocol-2 peers read
    /// it); `None` for any other law.
    pub fn to_paper(&self) -> Option<Reference> {
        if self.law != Self::PAPER_LAW {
            return None;
        }
        let [kp, kd, k, energy_avg, torque_limit] =
            <[f64; 5]>::try_from(&self.parameters[..]).ok()?;
        Some(Reference {
            kind: self.trajectory,
            amplitude: self.amplitude,
            omega: self.omega,
            kp,
            kd,
            k,
            energy_avg,
            torque_limit,
        })
    }

    /// Checks the name has at most [`LawReference::LAW_NAME_MAX`] bytes and the list at most
    /// [`LawReference::MAX_PARAMETERS`] values: what the layout has room for.
    fn fits_the_layout(&self) -> Result<(), ValidationError> {
        if self.law.len() > Self::LAW_NAME_MAX {
            return Err(ValidationError::TooLong {
                message: M,
                field: "law",
                len: self.law.len(),
                max: Self::LAW_NAME_MAX,
            });
        }
        if self.parameters.len() > Self::MAX_PARAMETERS {
            return Err(ValidationError::OutOfRange {
                message: M,
                field: "count",
                value: self.parameters.len() as f64,
                allowed: COUNT_RANGE,
            });
        }
        Ok(())
    }

    /// The wire layout; refused if the name or the list has no wire form.
    fn to_wire(&self) -> Result<LawReferenceWire, ValidationError> {
        self.fits_the_layout()?;
        let mut law = [0u8; Self::LAW_NAME_MAX];
        law[..self.law.len()].copy_from_slice(self.law.as_bytes());
        let mut parameters = [0.0; Self::MAX_PARAMETERS];
        parameters[..self.parameters.len()].copy_from_slice(&self.parameters);
        Ok(LawReferenceWire {
            marker: Self::MARKER,
            trajectory: self.trajectory,
            amplitude: self.amplitude,
            omega: self.omega,
            law,
            count: self.parameters.len() as u8,
            parameters,
        })
    }

    /// The message of the wire layout: marker 3, `count <= 8`, the name NUL-padded (no byte
    /// after the first NUL), the slots past `count` holding `+0.0`.
    fn from_wire(w: &LawReferenceWire) -> Result<Self, ValidationError> {
        if w.marker != Self::MARKER {
            return Err(ValidationError::OutOfRange {
                message: M,
                field: "marker",
                value: f64::from(w.marker),
                allowed: "3 (the protocol-3 LawReference layout)",
            });
        }
        let count = usize::from(w.count);
        if count > Self::MAX_PARAMETERS {
            return Err(ValidationError::OutOfRange {
                message: M,
                field: "count",
                value: f64::from(w.count),
                allowed: COUNT_RANGE,
            });
        }
        let len = w.law.iter().position(|&b| b == 0).unwrap_or(w.law.len());
        if w.law[len..].iter().any(|&b| b != 0) {
            return Err(ValidationError::BadName {
                message: M,
                field: "law",
                value: String::from_utf8_lossy(&w.law).into_owned(),
                allowed: NAME_RANGE,
            });
        }
        if let Some(&v) = w.parameters[count..].iter().find(|v| v.to_bits() != 0) {
            return Err(ValidationError::OutOfRange {
                message: M,
                field: "parameters",
                value: v,
                allowed: "+0.0 in the slots past `count`",
            });
        }
        Ok(Self {
            trajectory: w.trajectory,
            amplitude: w.amplitude,
            omega: w.omega,
            law: String::from_utf8_lossy(&w.law[..len]).into_owned(),
            parameters: w.parameters[..count].to_vec(),
        })
    }
}

impl From<&Reference> for LawReference {
    /// The paper's law of a protocol-2 message in the generic form: its name
    /// [`LawReference::PAPER_LAW`], its floats in the order of
    /// [`LawReference::PAPER_PARAMETERS`], its `kind` as the trajectory.
    fn from(r: &Reference) -> Self {
        Self {
            trajectory: r.kind,
            amplitude: r.amplitude,
            omega: r.omega,
            law: Self::PAPER_LAW.to_owned(),
            parameters: vec![r.kp, r.kd, r.k, r.energy_avg, r.torque_limit],
        }
    }
}

impl Serialize for LawReference {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        serialize_dual(
            s,
            || LawReferenceJson {
                trajectory: self.trajectory,
                amplitude: self.amplitude,
                omega: self.omega,
                law: self.law.clone(),
                parameters: self.parameters.clone(),
            },
            || self.to_wire(),
        )
    }
}

impl<'de> Deserialize<'de> for LawReference {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        deserialize_dual(
            d,
            |j: LawReferenceJson| Self {
                trajectory: j.trajectory,
                amplitude: j.amplitude,
                omega: j.omega,
                law: j.law,
                parameters: j.parameters,
            },
            LawReference::from_wire,
        )
    }
}

/// The message on the planner's reference key, of either layout: a protocol-2 [`Reference`]
/// (the paper's law, 57 bytes) or a [`LawReference`] (any law, 107 bytes), told apart by
/// byte 0 (`kind` 0..=2, marker 3). Decoding it is how a controller reads the key.
#[derive(Debug, Clone, PartialEq)]
pub enum AnyReference {
    /// The paper's law in the protocol-2 layout.
    Paper(Reference),
    /// Any law by name (protocol 3).
    Law(LawReference),
}

impl AnyReference {
    /// The law in the generic form (a [`Reference`] as [`LawReference::from`] reads it).
    pub fn law(&self) -> LawReference {
        match self {
            AnyReference::Paper(r) => LawReference::from(r),
            AnyReference::Law(l) => l.clone(),
        }
    }

    /// The message's own checks ([`Reference::validate`] or [`LawReference::validate`]).
    pub fn validate(&self) -> Result<(), ValidationError> {
        match self {
            AnyReference::Paper(r) => r.validate(),
            AnyReference::Law(l) => l.validate(),
        }
    }
}

impl Serialize for AnyReference {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            AnyReference::Paper(r) => r.serialize(s),
            AnyReference::Law(l) => l.serialize(s),
        }
    }
}

/// The JSON forms, told apart by their fields.
#[derive(Deserialize)]
#[serde(untagged)]
enum AnyReferenceJson {
    Paper(Reference),
    Law(LawReference),
}

/// Reads byte 0, then the rest of the layout it names.
struct AnyReferenceVisitor;

impl<'de> Visitor<'de> for AnyReferenceVisitor {
    type Value = AnyReference;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a Reference (57 bytes) or a LawReference (107 bytes)")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<AnyReference, A::Error> {
        fn next<'de, A: SeqAccess<'de>, T: Deserialize<'de>>(
            seq: &mut A,
            at: usize,
        ) -> Result<T, A::Error> {
            seq.next_element()?
                .ok_or_else(|| A::Error::invalid_length(at, &AnyReferenceVisitor))
        }
        let first: u8 = next(&mut seq, 0)?;
        if first <= Reference::EXCITATION {
            let mut f = [0.0f64; 7];
            for (i, slot) in f.iter_mut().enumerate() {
                *slot = next(&mut seq, i + 1)?;
            }
            let [amplitude, omega, kp, kd, k, energy_avg, torque_limit] = f;
            return Ok(AnyReference::Paper(Reference {
                kind: first,
                amplitude,
                omega,
                kp,
                kd,
                k,
                energy_avg,
                torque_limit,
            }));
        }
        if first != LawReference::MARKER {
            return Err(A::Error::custom(format!(
                "byte 0 = {first}: neither a protocol-2 Reference kind (0..=2) nor the \
                 protocol-3 LawReference marker (3)"
            )));
        }
        let w = LawReferenceWire {
            marker: first,
            trajectory: next(&mut seq, 1)?,
            amplitude: next(&mut seq, 2)?,
            omega: next(&mut seq, 3)?,
            law: next(&mut seq, 4)?,
            count: next(&mut seq, 5)?,
            parameters: next(&mut seq, 6)?,
        };
        LawReference::from_wire(&w)
            .map(AnyReference::Law)
            .map_err(A::Error::custom)
    }
}

impl<'de> Deserialize<'de> for AnyReference {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if d.is_human_readable() {
            Ok(match AnyReferenceJson::deserialize(d)? {
                AnyReferenceJson::Paper(r) => AnyReference::Paper(r),
                AnyReferenceJson::Law(l) => AnyReference::Law(l),
            })
        } else {
            // Eight elements at most: the paper's layout is byte 0 and seven floats.
            d.deserialize_tuple(8, AnyReferenceVisitor)
        }
    }
}
