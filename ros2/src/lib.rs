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
//! - `mirror` (features `node` or `dds`): the mirror thread and its queue, the judging of
//!   effort commands, shared by both routes;
//! - `node` (feature `node`): the thin zenoh part, declaring entities and publishing;
//! - `dds` (feature `dds`): the same topics, types, QoS and checks over DDS (RustDDS through
//!   Atostek's `ros2-client`), so a stock ROS 2 (rmw_fastrtps, rmw_cyclonedds) sees the robot
//!   with no RMW change.
//!
//! Nothing here but `node` knows of zenoh sessions, and nothing but `dds` of DDS.

pub mod attachment;
pub mod msgs;
pub mod names;
pub mod robot;
pub mod urdf;

#[cfg(any(feature = "node", feature = "dds"))]
pub mod mirror;

#[cfg(feature = "node")]
pub mod node;

#[cfg(feature = "dds")]
pub mod dds;

pub use attachment::{Attachment, AttachmentError};
pub use names::{Entity, EntityKind, Qos, RosType, Token, TokenError};

/// Which route `--ros2` takes: rmw_zenoh's conventions on the robot's zenoh session, DDS for a
/// stock ROS 2, or both at once (one mirror thread publishing on both).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Route {
    /// rmw_zenoh's conventions (`node`): what a bare `--ros2` means.
    #[default]
    Zenoh,
    /// DDS (`dds`): `ros2 topic echo` on a stock ROS 2.
    Dds,
    /// Both.
    Both,
}

impl Route {
    /// The names `--ros2` takes.
    pub const NAMES: [&'static str; 3] = ["zenoh", "dds", "both"];

    /// Whether the zenoh route is on.
    pub fn zenoh(self) -> bool {
        matches!(self, Route::Zenoh | Route::Both)
    }

    /// Whether the DDS route is on.
    pub fn dds(self) -> bool {
        matches!(self, Route::Dds | Route::Both)
    }
}

impl std::str::FromStr for Route {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "zenoh" => Ok(Route::Zenoh),
            "dds" => Ok(Route::Dds),
            "both" => Ok(Route::Both),
            _ => Err(format!(
                "invalid --ros2 = {s:?}: allowed zenoh (rmw_zenoh, the default of a bare \
                 --ros2), dds (a stock ROS 2) or both (a bare --ros2 takes the next word as its \
                 value: write `--ros2 zenoh` before a robot file, or the file first)"
            )),
        }
    }
}

impl std::fmt::Display for Route {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Route::Zenoh => "zenoh",
            Route::Dds => "dds",
            Route::Both => "both",
        })
    }
}

/// The ROS 2 domain id: `flag` if given, else `ROS_DOMAIN_ID` = `env` if set and not empty,
/// else 0; each checked to be 0 to 232 (a DDS domain's ports stay below 65536).
pub fn domain_id(flag: Option<u32>, env: Option<&str>) -> Result<u32, String> {
    let (d, from) = match (flag, env.map(str::trim)) {
        (Some(d), _) => (d, "--ros-domain".to_owned()),
        (None, Some(v)) if !v.is_empty() => (
            v.parse::<u32>()
                .map_err(|_| format!("invalid ROS_DOMAIN_ID = {v:?}: allowed 0 to 232"))?,
            "ROS_DOMAIN_ID".to_owned(),
        ),
        _ => (0, String::new()),
    };
    if d > 232 {
        return Err(format!("invalid {from} = {d}: allowed 0 to 232"));
    }
    Ok(d)
}

#[cfg(test)]
mod route_tests {
    use super::*;

    #[test]
    fn routes_and_domains_parse_or_name_the_allowed_values() {
        assert_eq!("dds".parse(), Ok(Route::Dds));
        assert!(Route::Both.zenoh() && Route::Both.dds());
        assert!(!Route::Dds.zenoh() && !Route::Zenoh.dds());
        let e = "DDS".parse::<Route>().unwrap_err();
        assert!(e.contains("--ros2") && e.contains("both"), "{e}");
        for r in Route::NAMES {
            assert_eq!(r.parse::<Route>().unwrap().to_string(), r);
        }
        assert_eq!(domain_id(None, None), Ok(0));
        assert_eq!(domain_id(None, Some("")), Ok(0));
        assert_eq!(domain_id(None, Some("42")), Ok(42));
        assert_eq!(domain_id(Some(3), Some("42")), Ok(3));
        let e = domain_id(None, Some("233")).unwrap_err();
        assert!(
            e.contains("ROS_DOMAIN_ID = 233") && e.contains("0 to 232"),
            "{e}"
        );
        let e = domain_id(Some(999), None).unwrap_err();
        assert!(e.contains("--ros-domain = 999"), "{e}");
        assert!(domain_id(None, Some("x"))
            .unwrap_err()
            .contains("ROS_DOMAIN_ID"));
    }
}
