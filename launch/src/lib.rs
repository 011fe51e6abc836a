//! Starting a tilting deployment: the processes of a run and the secure deployment's files.
//!
//! - **Child processes** ([`Child`], [`NodeBinaries`]): the node binaries of the same cargo
//!   profile, free loopback ports, children that write stdout and stderr to files, run in their
//!   own process group, die with their supervisor and stop in order (SIGINT, SIGTERM, then a
//!   kill after a grace period). `tilting live` and the process-level tests start their nodes
//!   through them.
//! - **Certificates** ([`certs`], [`generate`]): a development CA and one certificate per
//!   identity (`{robot}-{node}`), valid one year back and two ahead, with the host names the
//!   nodes dial them by, and the [`MANIFEST`] of the directory.
//! - **Zenoh configurations** ([`client_config`], [`direct_config`], [`router_config`]): TLS
//!   with mutual authentication and default-deny access control ([`acl`] at the router,
//!   [`node_acl`] in each session of the direct loop); [`session_flags`] says which file and
//!   endpoints each node runs with.
//! - **The router** ([`router`]): the `tilting-router` binary's session, at a lowered priority
//!   on request ([`RouterArgs::nice`], a nice value 0-19).
//!
//! Durations are in seconds or milliseconds as their names say (`*_ms`); ports are TCP ports.
//! Errors of the commands are [`LaunchError`]s: `Invalid` (a flag or file, named with what it
//! allows) or `Failed`; the rest return [`anyhow::Error`] with the path or node in the message.
//!
//! ```
//! use tilting_launch::{generate, session_flags, DEFAULT_ROUTER_ENDPOINT, NODES};
//!
//! let dir = std::env::temp_dir().join(format!("tilting-launch-doc-{}", std::process::id()));
//! let keys = tilting_proto::Keys::new("arm1").unwrap();
//! let m = generate(&keys, &dir, &[], DEFAULT_ROUTER_ENDPOINT, &[]).unwrap();
//! assert_eq!(m.nodes, NODES);
//! // The controller runs the direct loop: its own file, dialling the plant and the router.
//! let flags = session_flags(&dir, "controller", "tls/127.0.0.1:7448", DEFAULT_ROUTER_ENDPOINT, None);
//! assert_eq!(flags[0], "--zenoh-config");
//! assert!(flags[1].ends_with("controller-direct.json5"));
//! std::fs::remove_dir_all(&dir).unwrap();
//! ```

#![warn(missing_docs)]

mod acl;
mod certs;
mod config;
mod error;
mod ports;
mod router;
mod session;
mod supervise;

pub use acl::{acl, node_acl};
pub use certs::{
    certs, common_name, generate, read_manifest, valid_host, CertsArgs, Host, Manifest, Written,
    DEFAULT_ROUTER_ENDPOINT, HOST_RULE, MANIFEST, NODES,
};
pub use config::{client_config, direct_config, router_config};
pub use error::LaunchError;
pub use ports::{endpoint, free_port, reserve_port, PortLease};
pub use router::{lower_priority, router, RouterArgs, ROUTER_NICE};
pub use session::{
    direct_recorder, session_flags, DirectEndpoints, DIRECT, DIRECT_PLANT_PORT,
    DIRECT_RECORDER_PORT, RECORDER,
};
pub use supervise::{
    check_fifo, profile_dir, utc_timestamp, Child, NodeBinaries, CONTROLLER_BIN, PLANT_BIN,
    ROUTER_BIN,
};
