//! ROS 2 over zenoh in the conventions of rmw_zenoh (the ROS 2 middleware on zenoh), so that a
//! tilting robot is a ROS 2 node: `ros2 topic list/echo/hz`, rviz2, rosbag2 and ros2_control see
//! and drive it.
//!
//! Target: rmw_zenoh's attachment layout of **0.2.4 and later** (ROS 2 Jazzy from rmw_zenoh
//! 0.2.4, Kilted, Rolling): 33 bytes, no key strings. Older Jazzy releases (attachment with
//! key strings) are not supported. Everything is in `docs/ros2.md`.
//!
//! - [`names`]: topic keys, liveliness tokens (with the QoS field and name mangling) and GIDs;
//! - [`attachment`]: the 33-byte attachment of every sample;
//! - [`msgs`]: the ROS 2 message types we speak, in CDR (XCDR1, little endian) with their
//!   RIHS01 type hashes;
//! - [`robot`]: our messages as ROS 2 messages (joint names, contact mode, log lines) and the
//!   checks on a torque command arriving over ROS 2;
//! - [`urdf`]: the robot's URDF from the model's parameters;
//! - `node` (feature `node`): the thin zenoh part, declaring entities and publishing.
//!
//! Nothing here but `node` knows of zenoh sessions.

pub mod attachment;
pub mod msgs;
pub mod names;
pub mod robot;
pub mod urdf;

#[cfg(feature = "node")]
pub mod node;

pub use attachment::{Attachment, AttachmentError};
pub use names::{Entity, EntityKind, Qos, RosType, Token, TokenError};
