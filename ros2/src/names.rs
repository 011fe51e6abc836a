//! Names in rmw_zenoh's conventions: a topic's zenoh key, the liveliness token that announces an
//! entity (node, publisher, subscription) to the ROS 2 graph, the QoS field of that token and the
//! entity's GID.
//!
//! Written from rmw_zenoh's `liveliness_utils.cpp` and `qos.cpp` (docs/ros2.md cites them):
//! - topic key `<domain>/<topic without its leading and trailing '/'>/<DDS type>/<type hash>`;
//! - token `@ros2_lv/<domain>/<zid>/<nid>/<eid>/<kind>/<enclave>/<namespace>/<node>` and, for a
//!   publisher or subscription, `/<topic>/<DDS type>/<type hash>/<qos>`; every `/` inside a part
//!   is written `%` (so the root namespace `/` is `%`);
//! - GID: the XXH3-128 of the whole token, low 64 bits then high 64 bits, each little endian.

use thiserror::Error;

/// A ROS 2 message type: its name and its RIHS01 type hash (the SHA-256 of its type description,
/// `RIHS01_` + 64 lowercase hex digits, as `ros2 interface` and rosbags' `hash_rihs01` give it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RosType {
    /// `package/msg/Name`, e.g. `sensor_msgs/msg/JointState`.
    pub name: &'static str,
    /// `RIHS01_<sha256 hex>`.
    pub hash: &'static str,
}

impl RosType {
    /// The DDS type name rmw_zenoh puts in keys and tokens: `package::msg::dds_::Name_`.
    pub fn dds_name(&self) -> String {
        let mut parts = self.name.rsplitn(2, '/');
        let short = parts.next().unwrap_or_default();
        let pkg = parts.next().unwrap_or_default().replace('/', "::");
        format!("{pkg}::dds_::{short}_")
    }
}

/// The zenoh key of topic `topic` (a fully qualified ROS name such as `/demo/joint_states`) of
/// type `ty` in ROS domain `domain`.
pub fn topic_key(domain: u32, topic: &str, ty: &RosType) -> String {
    format!(
        "{domain}/{}/{}/{}",
        topic.trim_matches('/'),
        ty.dds_name(),
        ty.hash
    )
}

/// Writes every `/` of a name part as `%` (rmw_zenoh's `mangle_name`).
pub fn mangle(part: &str) -> String {
    part.replace('/', "%")
}

/// The admin space of every liveliness token.
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// What a liveliness token announces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EntityKind {
    /// `NN`: a node.
    Node,
    /// `MP`: a message publisher.
    Publisher,
    /// `MS`: a message subscription.
    Subscription,
    /// `SS`: a service server.
    Service,
    /// `SC`: a service client.
    Client,
}

impl EntityKind {
    /// The two letters of the token.
    pub fn tag(self) -> &'static str {
        match self {
            Self::Node => "NN",
            Self::Publisher => "MP",
            Self::Subscription => "MS",
            Self::Service => "SS",
            Self::Client => "SC",
        }
    }

    fn from_tag(tag: &str) -> Option<Self> {
        [
            Self::Node,
            Self::Publisher,
            Self::Subscription,
            Self::Service,
            Self::Client,
        ]
        .into_iter()
        .find(|k| k.tag() == tag)
    }
}

/// A duration in a QoS profile, s and ns (`rmw_time_t`).
pub type Duration = (u64, u64);

/// `RMW_DURATION_INFINITE`: rmw_zenoh's default deadline, lifespan and lease.
pub const INFINITE: Duration = (9_223_372_036, 854_775_807);

/// A QoS profile (`rmw_qos_profile_t`); the enumerations are rmw's numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Qos {
    /// 1 reliable, 2 best effort.
    pub reliability: u8,
    /// 1 transient local, 2 volatile.
    pub durability: u8,
    /// 1 keep last, 2 keep all.
    pub history: u8,
    /// History depth (samples).
    pub depth: u64,
    /// Deadline.
    pub deadline: Duration,
    /// Lifespan.
    pub lifespan: Duration,
    /// 1 automatic, 3 manual by topic.
    pub liveliness: u8,
    /// Liveliness lease.
    pub lease: Duration,
}

impl Qos {
    /// rmw_zenoh's default profile (`qos.cpp`): reliable, volatile, keep last 42, every duration
    /// infinite, automatic liveliness. The token writes only what differs from it.
    pub const RMW_ZENOH_DEFAULT: Qos = Qos {
        reliability: 1,
        durability: 2,
        history: 1,
        depth: 42,
        deadline: INFINITE,
        lifespan: INFINITE,
        liveliness: 1,
        lease: INFINITE,
    };

    /// Reliable, volatile, keep last `depth` (rclcpp's default profile with a depth).
    pub const fn reliable(depth: u64) -> Qos {
        Qos {
            depth,
            ..Self::RMW_ZENOH_DEFAULT
        }
    }

    /// Best effort, volatile, keep last `depth` (rclcpp's `SensorDataQoS` with depth 5).
    pub const fn best_effort(depth: u64) -> Qos {
        Qos {
            reliability: 2,
            depth,
            ..Self::RMW_ZENOH_DEFAULT
        }
    }

    /// The QoS part of a token (rmw_zenoh's `qos_to_keyexpr`):
    /// `reliability:durability:history,depth:deadline_s,deadline_ns:lifespan_s,lifespan_ns:liveliness,lease_s,lease_ns`,
    /// each field empty when it equals [`Qos::RMW_ZENOH_DEFAULT`]'s.
    pub fn to_keyexpr(&self) -> String {
        let d = Self::RMW_ZENOH_DEFAULT;
        fn f<T: PartialEq + ToString>(v: T, default: T) -> String {
            if v == default {
                String::new()
            } else {
                v.to_string()
            }
        }
        format!(
            "{}:{}:{},{}:{},{}:{},{}:{},{},{}",
            f(self.reliability, d.reliability),
            f(self.durability, d.durability),
            f(self.history, d.history),
            f(self.depth, d.depth),
            f(self.deadline.0, d.deadline.0),
            f(self.deadline.1, d.deadline.1),
            f(self.lifespan.0, d.lifespan.0),
            f(self.lifespan.1, d.lifespan.1),
            f(self.liveliness, d.liveliness),
            f(self.lease.0, d.lease.0),
            f(self.lease.1, d.lease.1),
        )
    }

    /// Reads the QoS part of a token under rmw_zenoh's rules (`keyexpr_to_qos`): six `:` parts,
    /// the history, deadline and lifespan parts two `,` fields each, liveliness three; an empty
    /// field is the default; the enumerations in rmw's ranges.
    pub fn from_keyexpr(s: &str) -> Result<Qos, TokenError> {
        let bad = |why: &str| TokenError::Qos(format!("{s:?}: {why}"));
        let parts: Vec<&str> = s.split(':').collect();
        if parts.len() < 6 {
            return Err(bad("fewer than 6 ':' parts"));
        }
        let fields = |i: usize, n: usize| -> Result<Vec<&str>, TokenError> {
            let v: Vec<&str> = parts[i].split(',').collect();
            if v.len() < n {
                return Err(bad(&format!("part {i} has fewer than {n} ',' fields")));
            }
            Ok(v)
        };
        let (h, dl, ls, lv) = (fields(2, 2)?, fields(3, 2)?, fields(4, 2)?, fields(5, 3)?);
        let d = Self::RMW_ZENOH_DEFAULT;
        let num = |v: &str, default: u64| -> Result<u64, TokenError> {
            if v.is_empty() {
                Ok(default)
            } else {
                v.parse()
                    .map_err(|_| bad(&format!("{v:?} is not a number")))
            }
        };
        let en = |v: &str, default: u8, allowed: &[u8]| -> Result<u8, TokenError> {
            let x = num(v, u64::from(default))?;
            u8::try_from(x)
                .ok()
                .filter(|x| allowed.contains(x))
                .ok_or_else(|| bad(&format!("{v:?} is not one of {allowed:?}")))
        };
        Ok(Qos {
            reliability: en(parts[0], d.reliability, &[0, 1, 2, 3])?,
            durability: en(parts[1], d.durability, &[0, 1, 2, 3])?,
            history: en(h[0], d.history, &[0, 1, 2, 3])?,
            depth: num(h[1], d.depth)?,
            deadline: (num(dl[0], d.deadline.0)?, num(dl[1], d.deadline.1)?),
            lifespan: (num(ls[0], d.lifespan.0)?, num(ls[1], d.lifespan.1)?),
            liveliness: en(lv[0], d.liveliness, &[0, 1, 3, 4, 5])?,
            lease: (num(lv[1], d.lease.0)?, num(lv[2], d.lease.1)?),
        })
    }
}

/// A topic as a token names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    /// Fully qualified ROS name, e.g. `/demo/joint_states`.
    pub name: String,
    /// DDS type name, e.g. `sensor_msgs::msg::dds_::JointState_`.
    pub dds_type: String,
    /// `RIHS01_...`.
    pub hash: String,
    /// QoS profile.
    pub qos: Qos,
}

/// An entity of the ROS 2 graph, as its liveliness token describes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entity {
    /// ROS domain id.
    pub domain: u32,
    /// The zenoh session id, as zenoh prints it.
    pub zid: String,
    /// Node id within the session.
    pub nid: u64,
    /// Entity id within the session (the node's own for a node).
    pub eid: u64,
    /// What it is.
    pub kind: EntityKind,
    /// Security enclave, `/` when none.
    pub enclave: String,
    /// Node namespace, e.g. `/demo` (`/` for the root).
    pub namespace: String,
    /// Node name.
    pub node: String,
    /// The topic, for a publisher or a subscription.
    pub topic: Option<TopicInfo>,
}

/// A liveliness token's key expression.
pub type Token = String;

/// A token that rmw_zenoh would reject, and why.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum TokenError {
    /// Fewer parts than the kind needs.
    #[error("token has {got} '/' parts; allowed: {min} or more")]
    Parts {
        /// Parts found.
        got: usize,
        /// Parts needed.
        min: usize,
    },
    /// A part is empty (`//` or a trailing `/`).
    #[error("token part {0} is empty; allowed: non-empty parts (an empty name is written '%')")]
    EmptyPart(usize),
    /// Not under `@ros2_lv`.
    #[error("token admin space {0:?}; allowed: \"@ros2_lv\"")]
    AdminSpace(String),
    /// Unknown entity kind.
    #[error("token entity kind {0:?}; allowed: NN, MP, MS, SS, SC")]
    Kind(String),
    /// A number part does not parse.
    #[error("token {field} {value:?} is not a number; allowed: decimal digits")]
    Number {
        /// Which part.
        field: &'static str,
        /// The text.
        value: String,
    },
    /// The QoS part does not parse.
    #[error("token QoS {0}")]
    Qos(String),
}

impl Entity {
    /// The liveliness token of this entity (rmw_zenoh's `Entity` constructor).
    pub fn token(&self) -> Token {
        let mut t = format!(
            "{ADMIN_SPACE}/{}/{}/{}/{}/{}/{}/{}/{}",
            self.domain,
            self.zid,
            self.nid,
            self.eid,
            self.kind.tag(),
            mangle(&self.enclave),
            mangle(&self.namespace),
            mangle(&self.node)
        );
        if let Some(topic) = &self.topic {
            t.push_str(&format!(
                "/{}/{}/{}/{}",
                mangle(&topic.name),
                mangle(&topic.dds_type),
                mangle(&topic.hash),
                topic.qos.to_keyexpr()
            ));
        }
        t
    }

    /// The entity's GID: XXH3-128 of its token, low then high 64 bits, little endian.
    pub fn gid(&self) -> [u8; 16] {
        gid(&self.token())
    }

    /// Parses a token under rmw_zenoh's rules (`Entity::make(keyexpr)`): at least 9 parts, none
    /// empty, the admin space, a known kind, a numeric domain; a publisher, subscription, service
    /// or client needs all 13 parts and a QoS part that parses.
    pub fn parse(token: &str) -> Result<Entity, TokenError> {
        let parts: Vec<&str> = token.split('/').collect();
        if parts.len() < 9 {
            return Err(TokenError::Parts {
                got: parts.len(),
                min: 9,
            });
        }
        if let Some(i) = parts.iter().position(|p| p.is_empty()) {
            return Err(TokenError::EmptyPart(i));
        }
        if parts[0] != ADMIN_SPACE {
            return Err(TokenError::AdminSpace(parts[0].to_owned()));
        }
        let kind = EntityKind::from_tag(parts[5]).ok_or(TokenError::Kind(parts[5].to_owned()))?;
        let number = |field: &'static str, v: &str| -> Result<u64, TokenError> {
            v.parse().map_err(|_| TokenError::Number {
                field,
                value: v.to_owned(),
            })
        };
        let demangle = |p: &str| p.replace('%', "/");
        let topic = if kind == EntityKind::Node {
            None
        } else {
            if parts.len() < 13 {
                return Err(TokenError::Parts {
                    got: parts.len(),
                    min: 13,
                });
            }
            Some(TopicInfo {
                name: demangle(parts[9]),
                dds_type: demangle(parts[10]),
                hash: demangle(parts[11]),
                qos: Qos::from_keyexpr(parts[12])?,
            })
        };
        Ok(Entity {
            domain: u32::try_from(number("domain", parts[1])?).map_err(|_| TokenError::Number {
                field: "domain",
                value: parts[1].to_owned(),
            })?,
            zid: parts[2].to_owned(),
            nid: number("node id", parts[3])?,
            eid: number("entity id", parts[4])?,
            kind,
            enclave: demangle(parts[6]),
            namespace: demangle(parts[7]),
            node: demangle(parts[8]),
            topic,
        })
    }
}

/// The GID rmw_zenoh derives from a token: XXH3-128 of its bytes, the low 64 bits then the high
/// 64 bits, each little endian (`memcpy` of `low64`, `high64` on a little-endian host).
pub fn gid(token: &str) -> [u8; 16] {
    xxhash_rust::xxh3::xxh3_128(token.as_bytes()).to_le_bytes()
}

/// Checks that `name` is a valid ROS 2 name token (`[A-Za-z_][A-Za-z0-9_]*`, no `__`), as a
/// namespace or node name needs; names the offending character.
pub fn validate_ros_name(name: &str) -> Result<(), String> {
    let allowed =
        "a letter or '_' first, then letters, digits and '_' ([A-Za-z_][A-Za-z0-9_]*, no '__')";
    let mut chars = name.char_indices();
    match chars.next() {
        None => return Err(format!("ROS 2 name is empty; allowed: {allowed}")),
        Some((_, c)) if !(c.is_ascii_alphabetic() || c == '_') => {
            return Err(format!(
                "ROS 2 name {name:?} starts with {c:?}; allowed: {allowed}"
            ))
        }
        _ => {}
    }
    if let Some((i, c)) = chars.find(|&(_, c)| !(c.is_ascii_alphanumeric() || c == '_')) {
        return Err(format!(
            "ROS 2 name {name:?} has {c:?} at byte {i}; allowed: {allowed}"
        ));
    }
    if name.contains("__") {
        return Err(format!(
            "ROS 2 name {name:?} contains '__'; allowed: {allowed}"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const JOINT_STATE: RosType = RosType {
        name: "sensor_msgs/msg/JointState",
        hash: "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    };

    #[test]
    fn the_key_of_the_design_doc_example() {
        // docs/design.md of rmw_zenoh: `0/chatter/std_msgs::msg::dds_::String_/RIHS01_...`.
        assert_eq!(
            topic_key(0, "/demo/joint_states", &JOINT_STATE),
            "0/demo/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
        );
    }

    #[test]
    fn default_qos_is_all_empty_fields_and_round_trips() {
        assert_eq!(Qos::RMW_ZENOH_DEFAULT.to_keyexpr(), "::,:,:,:,,");
        // rmw_zenoh's design doc example of a default reliable depth-10 profile: `::,10:,:,:,,`.
        assert_eq!(Qos::reliable(10).to_keyexpr(), "::,10:,:,:,,");
        assert_eq!(Qos::best_effort(5).to_keyexpr(), "2::,5:,:,:,,");
        for q in [
            Qos::RMW_ZENOH_DEFAULT,
            Qos::reliable(10),
            Qos::best_effort(5),
        ] {
            assert_eq!(Qos::from_keyexpr(&q.to_keyexpr()), Ok(q));
        }
        assert!(Qos::from_keyexpr("::,:,:,").is_err());
        assert!(Qos::from_keyexpr("7::,:,:,:,,").is_err());
        assert!(Qos::from_keyexpr("::,x:,:,:,,").is_err());
    }

    #[test]
    fn tokens_round_trip_and_empty_parts_are_refused() {
        let e = Entity {
            domain: 3,
            zid: "a1b2".into(),
            nid: 0,
            eid: 7,
            kind: EntityKind::Publisher,
            enclave: "/".into(),
            namespace: "/demo".into(),
            node: "tilting_plant".into(),
            topic: Some(TopicInfo {
                name: "/demo/joint_states".into(),
                dds_type: JOINT_STATE.dds_name(),
                hash: JOINT_STATE.hash.into(),
                qos: Qos::best_effort(5),
            }),
        };
        let t = e.token();
        assert_eq!(
            t,
            "@ros2_lv/3/a1b2/0/7/MP/%/%demo/tilting_plant/%demo%joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e/2::,5:,:,:,,"
        );
        assert_eq!(Entity::parse(&t), Ok(e.clone()));
        assert_eq!(
            Entity::parse("@ros2_lv/3/a1b2/0/7/MP//%demo/x"),
            Err(TokenError::EmptyPart(6))
        );
        let node = Entity {
            kind: EntityKind::Node,
            topic: None,
            ..e
        };
        assert_eq!(Entity::parse(&node.token()), Ok(node));
        assert!(matches!(
            Entity::parse("@ros2_lv/3/a1b2/0/7/MP/%/%demo/n"),
            Err(TokenError::Parts { min: 13, .. })
        ));
    }

    #[test]
    fn gid_is_the_low_then_high_half_of_xxh3_128() {
        // XXH3-128 of the empty input (the reference vector of xxHash's sanity test):
        // high 0x99aa06d3014798d8, low 0x6001c324468d497f.
        let g = gid("");
        assert_eq!(&g[..8], &0x6001c324468d497fu64.to_le_bytes());
        assert_eq!(&g[8..], &0x99aa06d3014798d8u64.to_le_bytes());
    }

    #[test]
    fn ros_names() {
        assert!(validate_ros_name("demo").is_ok());
        assert!(validate_ros_name("python_peer_123").is_ok());
        assert!(validate_ros_name("a-b").unwrap_err().contains("'-'"));
        assert!(validate_ros_name("1a").is_err());
        assert!(validate_ros_name("a__b").is_err());
    }
}
