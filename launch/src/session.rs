//! Who dials whom in the secure topology: the endpoints of the direct loop and the session
//! flags of each node ([`session_flags`], the one place they are made).

use crate::certs::Host;
use std::path::Path;

/// Port of the plant's TLS endpoint of the direct loop in the generated files (`tls/HOST:7448`
/// with the plant's first `--host`).
pub const DIRECT_PLANT_PORT: u16 = 7448;

/// Port of the recorder's (the logger's) TLS endpoint of the direct loop in the generated
/// files (`tls/HOST:7449` with the logger's first `--host`).
pub const DIRECT_RECORDER_PORT: u16 = 7449;

/// The endpoints written into the `{node}-direct.json5` files (a node's `--listen` and
/// `--connect` replace them, as `tilting live --secure` does).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DirectEndpoints {
    /// The plant's TLS endpoint, `tls/HOST:7448` on the plant's first `--host`, if any.
    pub plant: Option<String>,
    /// The recorder's, `tls/HOST:7449` on the logger's first `--host`, if any.
    pub recorder: Option<String>,
    /// The router's.
    pub router: String,
}

impl DirectEndpoints {
    /// The plant's and the recorder's endpoints on the first host `hosts` gives each (none
    /// without: the flags must say them), and the router's.
    pub fn from_hosts(hosts: &[Host], router_endpoint: &str) -> Self {
        let first = |node: &str, port| {
            hosts
                .iter()
                .find(|h| h.node == node)
                .map(|h| h.endpoint(port))
        };
        Self {
            plant: first("plant", DIRECT_PLANT_PORT),
            recorder: first(RECORDER, DIRECT_RECORDER_PORT),
            router: router_endpoint.to_owned(),
        }
    }

    /// Where `node` (one of [`DIRECT`]) listens and what it dials, as [`session_flags`] would
    /// say with these endpoints: the plant listens on its endpoint and dials the router; the
    /// controller dials the plant, the router and the recorder; the recorder listens on its
    /// endpoint and dials the plant. Unknown endpoints are left out.
    pub fn of(&self, node: &str) -> (Vec<String>, Vec<String>) {
        let (p, r) = (self.plant.clone(), self.recorder.clone());
        let router = Some(self.router.clone());
        let (listen, connect) = match node {
            "plant" => (vec![p], vec![router]),
            "controller" => (vec![], vec![p, router, r]),
            _ => (vec![r], vec![p]),
        };
        let known = |v: Vec<Option<String>>| v.into_iter().flatten().collect();
        (known(listen), known(connect))
    }
}

/// The nodes of the direct loop: the plant listens, the controller dials it, and the front
/// door's recorder ([`RECORDER`]) listens and dials the plant; the controller dials it.
pub const DIRECT: [&str; 3] = ["plant", "controller", RECORDER];

/// The identity of `tilting live --secure`'s recorder (and status line) when it takes the loop's
/// messages straight from the plant and the controller (`logger-direct.json5`), so that the
/// router relays none of them: a logger, which may only listen.
pub const RECORDER: &str = "logger";

/// The session flags of `node` in the deployed secure topology, from the certificate directory
/// `certs`: the plant and the controller run the direct loop with their own access control
/// (`{node}-direct.json5`: the plant `--listen`s on `plant_endpoint`, the controller
/// `--connect`s to it), and both `--connect` to the router at `router_endpoint`; every other
/// node is a client of the router (`{node}.json5`). With `recorder_endpoint` (`tilting live
/// --secure`'s recorder, identity [`RECORDER`]), the recorder `--listen`s there and
/// `--connect`s to the plant only, and the controller `--connect`s to it too: the loop's
/// messages reach the recorder on links of their own and the router relays none of them.
/// Certificates without the `{node}-direct.json5` files (made before the direct loop, or
/// before the direct recorder) run that part through the router. The one place these flags
/// are made: `tilting live --secure`, the flood benchmark and the network-namespace test all
/// start their nodes with them.
pub fn session_flags(
    certs: &Path,
    node: &str,
    plant_endpoint: &str,
    router_endpoint: &str,
    recorder_endpoint: Option<&str>,
) -> Vec<String> {
    let direct = certs.join(format!("{node}-direct.json5"));
    if !DIRECT.contains(&node)
        || !direct.is_file()
        || (node == RECORDER && recorder_endpoint.is_none())
    {
        let client = certs.join(format!("{node}.json5"));
        return vec![
            "--zenoh-config".into(),
            client.display().to_string(),
            "--connect".into(),
            router_endpoint.into(),
        ];
    }
    let mut v = vec!["--zenoh-config".into(), direct.display().to_string()];
    if let (RECORDER, Some(rec)) = (node, recorder_endpoint) {
        v.extend(["--listen".into(), rec.into()]);
        v.extend(["--connect".into(), plant_endpoint.into()]);
        return v;
    }
    let to_plant = if node == "plant" {
        "--listen"
    } else {
        "--connect"
    };
    v.extend([to_plant.into(), plant_endpoint.into()]);
    v.extend(["--connect".into(), router_endpoint.into()]);
    if let Some(rec) = recorder_endpoint.filter(|_| node == "controller" && direct_recorder(certs))
    {
        v.extend(["--connect".into(), rec.into()]);
    }
    v
}

/// Whether `certs` has the direct recorder's configuration (`{RECORDER}-direct.json5`).
pub fn direct_recorder(certs: &Path) -> bool {
    certs.join(format!("{RECORDER}-direct.json5")).is_file()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::certs::{generate, Host, DEFAULT_ROUTER_ENDPOINT};
    use std::time::Duration;
    use tilting_proto::Keys;

    /// A TLS handshake with the name checked (`verify_name_on_connect`), between two zenoh
    /// peers of the direct loop on 127.0.0.1: the controller dials the plant with the default
    /// certificates and the link comes up; the plant dials the controller (whose default
    /// certificate names no host) and it never does, until `--host controller=127.0.0.1` puts
    /// the address in the controller's certificate. The truth: whether each session sees the
    /// other as a peer.
    #[test]
    fn a_name_checked_handshake_needs_the_dialled_name_in_the_certificate() {
        let keys = Keys::new("unit").unwrap();
        let rt = tilting_net::runtime().unwrap();
        // Whether `dialler` (its `-direct.json5`) links to `listener` on 127.0.0.1 within
        // `wait`.
        let link = |dir: &Path, listener: &str, dialler: &str, wait: Duration| {
            let port = crate::ports::free_port().unwrap();
            let ep = format!("[\"tls/127.0.0.1:{port}\"]");
            let cfg = |node: &str, listen: &str, connect: &str| {
                let mut c =
                    zenoh::Config::from_file(dir.join(format!("{node}-direct.json5"))).unwrap();
                c.insert_json5("listen/endpoints", listen).unwrap();
                c.insert_json5("connect/endpoints", connect).unwrap();
                c
            };
            rt.block_on(async {
                let l = zenoh::open(cfg(listener, &ep, "[]")).await.unwrap();
                let opened = tokio::time::timeout(wait, zenoh::open(cfg(dialler, "[]", &ep))).await;
                let Ok(Ok(d)) = opened else {
                    let _ = l.close().await;
                    return false;
                };
                let t0 = std::time::Instant::now();
                let mut linked = false;
                while !linked && t0.elapsed() < wait {
                    linked = d.info().peers_zid().await.any(|z| z == l.zid());
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
                let _ = d.close().await;
                let _ = l.close().await;
                linked
            })
        };
        let plain = tempfile::tempdir().unwrap();
        generate(&keys, plain.path(), &[], DEFAULT_ROUTER_ENDPOINT, &[]).unwrap();
        // Generous: a loaded machine may take seconds to open two sessions.
        let long = Duration::from_secs(30);
        assert!(link(plain.path(), "plant", "controller", long), "default");
        // A refused name never links, however long: 3 s show the retries failing.
        let short = Duration::from_secs(3);
        assert!(!link(plain.path(), "controller", "plant", short), "no name");
        let named = tempfile::tempdir().unwrap();
        let host = [Host::parse("controller=127.0.0.1", &[]).unwrap()];
        generate(&keys, named.path(), &host, DEFAULT_ROUTER_ENDPOINT, &[]).unwrap();
        assert!(link(named.path(), "controller", "plant", long), "--host");
    }

    /// The flags of the direct topology: the recorder listens on its endpoint and dials the
    /// plant only (no link to the router), the controller dials the plant, the router and the
    /// recorder; without `logger-direct.json5` (older certificates) the recorder is a client
    /// of the router and the controller does not dial it.
    #[test]
    fn the_recorder_dials_the_plant_and_the_controller_dials_the_recorder() {
        let dir = tempfile::tempdir().unwrap();
        let keys = Keys::new("unit").unwrap();
        generate(&keys, dir.path(), &[], DEFAULT_ROUTER_ENDPOINT, &[]).unwrap();
        let (plant, router, rec) = ("tls/p:1", "tls/r:2", "tls/l:3");
        let flags = |node| session_flags(dir.path(), node, plant, router, Some(rec));
        let pairs = |v: Vec<String>| -> Vec<(String, String)> {
            v.chunks(2)
                .filter(|c| c[0] != "--zenoh-config")
                .map(|c| (c[0].clone(), c[1].clone()))
                .collect()
        };
        let p = |a: &str, b: &str| (a.to_owned(), b.to_owned());
        assert_eq!(
            pairs(flags(RECORDER)),
            [p("--listen", rec), p("--connect", plant)]
        );
        assert_eq!(
            pairs(flags("controller")),
            [
                p("--connect", plant),
                p("--connect", router),
                p("--connect", rec)
            ]
        );
        assert_eq!(
            pairs(flags("plant")),
            [p("--listen", plant), p("--connect", router)]
        );
        std::fs::remove_file(dir.path().join("logger-direct.json5")).unwrap();
        assert_eq!(pairs(flags(RECORDER)), [p("--connect", router)]);
        assert_eq!(
            pairs(flags("controller")),
            [p("--connect", plant), p("--connect", router)]
        );
    }
}
