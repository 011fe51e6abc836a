//! The ROS 2 messages we speak, as serde structs in CDR (XCDR1, little endian, after the 4-byte
//! encapsulation header `00 01 00 00`), and their RIHS01 type hashes.
//!
//! The hashes are the ones of ROS 2 Jazzy, Kilted and Rolling (the types have not changed
//! since Iron); `tests/tests/peers/ros2.rs` checks every one against rosbags' `hash_rihs01`.

use crate::names::RosType;
use serde::{de::DeserializeOwned, Deserialize, Serialize};
use thiserror::Error;

/// `sensor_msgs/msg/JointState`.
pub const JOINT_STATE: RosType = RosType {
    name: "sensor_msgs/msg/JointState",
    hash: "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
};
/// `std_msgs/msg/UInt8`.
pub const UINT8: RosType = RosType {
    name: "std_msgs/msg/UInt8",
    hash: "RIHS01_6138bd83d8c3569cb80a667db03cfc1629f529fee79d944c39c34e352e72f010",
};
/// `std_msgs/msg/Float64MultiArray`.
pub const FLOAT64_MULTI_ARRAY: RosType = RosType {
    name: "std_msgs/msg/Float64MultiArray",
    hash: "RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f",
};
/// `rcl_interfaces/msg/Log`.
pub const LOG: RosType = RosType {
    name: "rcl_interfaces/msg/Log",
    hash: "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac",
};

/// Every type this crate hard-codes a hash for (the test checks them all).
pub const ALL_TYPES: [RosType; 4] = [JOINT_STATE, UINT8, FLOAT64_MULTI_ARRAY, LOG];

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, `0..1e9`.
    pub nanosec: u32,
}

impl Time {
    /// A time from seconds (rounded to the nearest ns; negative times clamp to 0).
    pub fn from_secs(t: f64) -> Time {
        let ns = (t.max(0.0) * 1e9).round() as i64;
        Self::from_ns(ns)
    }

    /// A time from ns (negative times clamp to 0).
    pub fn from_ns(ns: i64) -> Time {
        let ns = ns.max(0);
        Time {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Header {
    /// When the data was taken.
    pub stamp: Time,
    /// Frame the data is in.
    pub frame_id: String,
}

/// `sensor_msgs/msg/JointState`: per joint a name and, when known, position (rad), velocity
/// (rad/s) and effort (N m); an array is empty when that quantity is not known.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct JointState {
    /// Stamp and frame.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions, rad.
    pub position: Vec<f64>,
    /// Velocities, rad/s.
    pub velocity: Vec<f64>,
    /// Efforts, N m.
    pub effort: Vec<f64>,
}

/// `std_msgs/msg/UInt8`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct UInt8 {
    /// The value.
    pub data: u8,
}

/// `std_msgs/msg/MultiArrayDimension`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    /// Label of the dimension.
    pub label: String,
    /// Size of the dimension.
    pub size: u32,
    /// Stride of the dimension.
    pub stride: u32,
}

/// `std_msgs/msg/MultiArrayLayout`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct MultiArrayLayout {
    /// Dimensions.
    pub dim: Vec<MultiArrayDimension>,
    /// Padding elements at the front of `data`.
    pub data_offset: u32,
}

/// `std_msgs/msg/Float64MultiArray`: ros2_control's forward command controllers' command.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Float64MultiArray {
    /// Layout (forward command controllers leave it empty).
    pub layout: MultiArrayLayout,
    /// The values.
    pub data: Vec<f64>,
}

/// `rcl_interfaces/msg/Log`: one line of `/rosout`.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Log {
    /// When it was logged.
    pub stamp: Time,
    /// [`Log::INFO`], [`Log::WARN`], [`Log::ERROR`], ...
    pub level: u8,
    /// Logger name.
    pub name: String,
    /// The message.
    pub msg: String,
    /// Source file.
    pub file: String,
    /// Function.
    pub function: String,
    /// Line.
    pub line: u32,
}

impl Log {
    /// Debug level.
    pub const DEBUG: u8 = 10;
    /// Info level.
    pub const INFO: u8 = 20;
    /// Warning level.
    pub const WARN: u8 = 30;
    /// Error level.
    pub const ERROR: u8 = 40;
    /// Fatal level.
    pub const FATAL: u8 = 50;
}

/// The encapsulation header of little-endian plain CDR (`CDR_LE`).
pub const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// A payload that is not a CDR message of the expected type.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdrError {
    /// Shorter than the encapsulation header.
    #[error("payload is {0} bytes; allowed: 4 or more (the CDR encapsulation header first)")]
    Short(usize),
    /// Not little-endian plain CDR.
    #[error("CDR encapsulation {0:02x?}; allowed: 00 01 (little-endian CDR)")]
    Encapsulation([u8; 2]),
    /// The body does not decode.
    #[error("CDR body does not decode as {ty}: {why}")]
    Body {
        /// The type expected.
        ty: &'static str,
        /// cdr-encoding's error.
        why: String,
    },
}

/// The payload of `msg`: the header, then its CDR body.
pub fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    let body = cdr_encoding::to_vec::<T, byteorder::LittleEndian>(msg)
        .expect("CDR encoding of an in-memory message cannot fail");
    let mut out = Vec::with_capacity(4 + body.len());
    out.extend_from_slice(&CDR_LE);
    out.extend_from_slice(&body);
    out
}

/// Decodes a payload of type `ty` (checks the encapsulation header).
pub fn decode<T: DeserializeOwned>(bytes: &[u8], ty: &RosType) -> Result<T, CdrError> {
    if bytes.len() < 4 {
        return Err(CdrError::Short(bytes.len()));
    }
    if bytes[..2] != CDR_LE[..2] {
        return Err(CdrError::Encapsulation([bytes[0], bytes[1]]));
    }
    cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(&bytes[4..])
        .map(|(m, _)| m)
        .map_err(|e| CdrError::Body {
            ty: ty.name,
            why: e.to_string(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uint8_and_a_multi_array_by_hand() {
        assert_eq!(encode(&UInt8 { data: 2 }), [0, 1, 0, 0, 2]);
        let m = Float64MultiArray {
            layout: MultiArrayLayout::default(),
            data: vec![1.5],
        };
        let b = encode(&m);
        // header; dim: count 0 (u32); data_offset 0 (u32); data: count 1 (u32), 4 bytes of
        // padding to the 8-byte alignment (offset 12 of the body), then 1.5.
        let mut want = vec![0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0];
        want.extend_from_slice(&1.5f64.to_le_bytes());
        assert_eq!(b, want);
        assert_eq!(decode::<Float64MultiArray>(&b, &FLOAT64_MULTI_ARRAY), Ok(m));
        assert!(matches!(
            decode::<Float64MultiArray>(&[0, 0, 0, 0, 1], &FLOAT64_MULTI_ARRAY),
            Err(CdrError::Encapsulation(_))
        ));
        assert!(decode::<Float64MultiArray>(&b[..10], &FLOAT64_MULTI_ARRAY).is_err());
    }

    #[test]
    fn times() {
        assert_eq!(
            Time::from_secs(1.25),
            Time {
                sec: 1,
                nanosec: 250_000_000
            }
        );
        assert_eq!(Time::from_ns(-5), Time::default());
    }
}
