//! The zenoh configuration files of a secure deployment, from one builder ([`Session`]): every
//! session is TLS only with mutual authentication and the robot's CA, never scouts, and keeps
//! timestamps off; what differs is its mode, whether it dials (then with retries, the open
//! delay, its certificate as a client and the dialled name checked), whether it accepts links
//! (then with its certificate as a server), and its access control.

use crate::acl::{acl, node_acl};
use serde_json::{json, Value};
use std::path::Path;
use tilting_proto::Keys;

/// One zenoh session of the deployment, before it is written out ([`Session::build`]).
struct Session<'a> {
    /// `"client"`, `"peer"` or `"router"`.
    mode: &'a str,
    /// The certificate directory (absolute: the paths in the file are).
    dir: &'a Path,
    /// Whose certificate and key the session presents (`{node}.pem`, `{node}.key`).
    node: &'a str,
    /// Endpoints it listens on; with any role that accepts links, its server certificate.
    listen: Vec<String>,
    /// Endpoints it dials.
    connect: Vec<String>,
    /// Whether it dials: connect retries (100 ms doubling to 1 s), the open delay
    /// ([`tilting_net::OPEN_WAIT_MS`]), its client certificate and the name check.
    dials: bool,
    /// Whether it accepts links (its server certificate).
    accepts: bool,
    /// Its `access_control` block, if it enforces one.
    acl: Option<Value>,
}

impl Session<'_> {
    /// The configuration as zenoh reads it (JSON5; this is JSON).
    fn build(self) -> Value {
        let file = |name: &str| self.dir.join(name).display().to_string();
        let (cert, key) = (
            file(&format!("{}.pem", self.node)),
            file(&format!("{}.key", self.node)),
        );
        let mut tls = json!({ "root_ca_certificate": file("ca.pem"), "enable_mtls": true });
        let mut connect = json!({ "endpoints": self.connect });
        let mut scouting = json!({
            "multicast": { "enabled": false },
            "gossip": { "enabled": false },
        });
        if self.accepts {
            tls["listen_certificate"] = json!(cert);
            tls["listen_private_key"] = json!(key);
        }
        if self.dials {
            tls["connect_certificate"] = json!(cert);
            tls["connect_private_key"] = json!(key);
            tls["verify_name_on_connect"] = json!(true);
            connect["retry"] = json!({ "period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2 });
            scouting["delay"] = json!(tilting_net::OPEN_WAIT_MS);
        }
        let mut v = json!({
            "mode": self.mode,
            "connect": connect,
            "listen": { "endpoints": self.listen },
            "scouting": scouting,
            "timestamping": { "enabled": false },
            "transport": { "link": { "protocols": ["tls"], "tls": tls } },
        });
        if let Some(acl) = self.acl {
            v["access_control"] = acl;
        }
        v
    }
}

/// The zenoh configuration of a node: a client of the router at `router_endpoint`, TLS only,
/// with `node`'s certificate, no scouting, no listener.
pub fn client_config(dir: &Path, node: &str, router_endpoint: &str) -> Value {
    Session {
        mode: "client",
        dir,
        node,
        listen: vec![],
        connect: vec![router_endpoint.to_owned()],
        dials: true,
        accepts: false,
        acl: None,
    }
    .build()
}

/// The zenoh configuration of `node` (one of [`crate::DIRECT`]) in the direct loop
/// (`{node}-direct.json5`, what `tilting live --secure` runs): a **peer** with the TLS link of
/// [`client_config`] (its own certificate, mutual authentication, names checked), its
/// certificate also as a server, no scouting, and its own access control ([`node_acl`]). No
/// endpoint here: [`crate::generate`] writes those of [`crate::DirectEndpoints`] into the file,
/// and the flags replace them ([`crate::session_flags`]: the plant `--listen`s on its endpoint
/// and `--connect`s to the router; the controller `--connect`s to the plant, the router and the
/// recorder; the recorder `--listen`s on its own and `--connect`s to the plant).
pub fn direct_config(keys: &Keys, dir: &Path, node: &str, nodes: &[String]) -> Value {
    Session {
        mode: "peer",
        dir,
        node,
        listen: vec![],
        connect: vec![],
        dials: true,
        accepts: true,
        acl: Some(node_acl(keys, node, nodes)),
    }
    .build()
}

/// The zenoh configuration of the router: listens on `endpoint` (the one the nodes dial;
/// replace it with `tilting-router --listen`), TLS only with mutual authentication, scouting
/// off, dials nothing, and the access control of [`acl`] for the identities in `nodes`.
pub fn router_config(keys: &Keys, dir: &Path, nodes: &[String], endpoint: &str) -> Value {
    Session {
        mode: "router",
        dir,
        node: "router",
        listen: vec![endpoint.to_owned()],
        connect: vec![],
        dials: false,
        accepts: true,
        acl: Some(acl(keys, nodes)),
    }
    .build()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// Each role presents exactly the certificates its links need, and only a session that
    /// dials retries, waits to open and checks the dialled name: the keys of each file's `tls`,
    /// `connect` and `scouting` blocks against the table written out here.
    #[test]
    fn each_role_has_the_tls_keys_of_its_links() {
        let keys = Keys::new("unit").unwrap();
        let dir = Path::new("/certs");
        let nodes: Vec<String> = crate::NODES.iter().map(|s| s.to_string()).collect();
        let base = ["root_ca_certificate", "enable_mtls"];
        let server = ["listen_certificate", "listen_private_key"];
        let client = [
            "connect_certificate",
            "connect_private_key",
            "verify_name_on_connect",
        ];
        let set = |parts: &[&[&str]]| -> BTreeSet<String> {
            parts.concat().iter().map(|s| s.to_string()).collect()
        };
        let names = |v: &Value, block: &str| -> BTreeSet<String> {
            v.pointer(block)
                .and_then(Value::as_object)
                .unwrap_or_else(|| panic!("{block} in {v}"))
                .keys()
                .cloned()
                .collect()
        };
        let cases = [
            (
                "client",
                client_config(dir, "planner", "tls/r:1"),
                set(&[&base, &client]),
                true,
            ),
            (
                "peer",
                direct_config(&keys, dir, "plant", &nodes),
                set(&[&base, &server, &client]),
                true,
            ),
            (
                "router",
                router_config(&keys, dir, &nodes, "tls/r:1"),
                set(&[&base, &server]),
                false,
            ),
        ];
        for (mode, cfg, tls, dials) in cases {
            assert_eq!(cfg["mode"], mode);
            assert_eq!(names(&cfg, "/transport/link/tls"), tls, "{mode}");
            assert_eq!(cfg["connect"].get("retry").is_some(), dials, "{mode}");
            assert_eq!(cfg["scouting"].get("delay").is_some(), dials, "{mode}");
            assert_eq!(cfg["scouting"]["multicast"]["enabled"], false, "{mode}");
            assert_eq!(cfg["scouting"]["gossip"]["enabled"], false, "{mode}");
            assert_eq!(
                cfg.get("access_control").is_some(),
                mode != "client",
                "{mode}"
            );
        }
        let router = router_config(&keys, dir, &nodes, "tls/r:1");
        assert_eq!(
            router["transport"]["link"]["tls"]["listen_certificate"],
            "/certs/router.pem"
        );
        assert_eq!(router["listen"]["endpoints"], json!(["tls/r:1"]));
        let planner = client_config(dir, "planner", "tls/r:1");
        assert_eq!(planner["connect"]["endpoints"], json!(["tls/r:1"]));
        assert_eq!(
            planner["transport"]["link"]["tls"]["connect_private_key"],
            "/certs/planner.key"
        );
    }
}
