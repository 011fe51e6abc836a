//! Secure deployment: a development certificate authority, one certificate per node, and the
//! zenoh configuration files that turn on mutual TLS and access control (`tilting certs`,
//! `tilting live --secure`, `tilting-router`).
//!
//! Everything here is zenoh's own machinery, configured: the `tls` link with `enable_mtls`
//! authenticates both ends of every link with a certificate signed by the robot's CA, and the
//! router's `access_control` block (default deny) matches each link's certificate common name
//! against the identities below and lets each identity publish only its own keys:
//!
//! | identity (CN `{robot}-{node}`) | may put | may declare a liveliness token |
//! |---|---|---|
//! | `plant` | `plant/state`, `plant/event`, `plant/status` | `alive/plant` |
//! | `controller` | `controller/torque` | `alive/controller` |
//! | `planner` | `planner/reference` (and reply to queries on it) | `alive/planner` |
//! | `logger` | nothing | nothing |
//!
//! All four may subscribe to, query and watch the liveliness of `tilting/{robot}/**`; a
//! certificate with any other common name (signed by the same CA or not) may do nothing.
//!
//! Zenoh applies ACL in the session that holds the configuration, on the messages crossing
//! its own links. Peers that find each other by gossip talk directly and never cross the
//! ACL of a third peer, so no session scouts, and every session that accepts links holds
//! rules: the router's for its **clients** (the planner, loggers, outside peers), and in the
//! direct topology of `live --secure` each **peer**'s own ([`node_acl`]): the plant's, the
//! controller's and the recorder's ([`RECORDER`]), which take the loop's messages from each
//! other on links of their own, so that the router relays none of them.

use crate::CommandError;
use anyhow::{anyhow, Context as _};
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use tilting_proto::Keys;

/// The identities `tilting certs` always creates, in this order.
pub const NODES: [&str; 5] = ["plant", "controller", "planner", "logger", "router"];

/// The file listing what a certificate directory holds (robot, identities).
pub const MANIFEST: &str = "certs.json";

/// Default endpoint of the router, in the generated configuration files.
pub const DEFAULT_ROUTER_ENDPOINT: &str = "tls/127.0.0.1:7447";

/// Flags of `tilting certs`.
#[derive(Debug, Clone, clap::Args)]
pub struct CertsArgs {
    /// Robot name: the identities are `{robot}-plant`, `{robot}-controller`, ...
    #[arg(long, default_value = tilting_proto::keys::DEFAULT_ROBOT, value_name = "NAME")]
    pub robot: String,
    /// Directory to write the CA, the certificates, the keys and the zenoh configuration files
    /// into (created; existing files of the same names are replaced)
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Host name or IP address the nodes use to reach the router (repeatable; localhost and
    /// 127.0.0.1 are always there): the router's certificate and the plant's (which runs on
    /// the router's host) are valid for these names too
    #[arg(long = "router-host", value_name = "HOST")]
    pub router_hosts: Vec<String>,
    /// The router's endpoint written into the nodes' configuration files (and the router's
    /// listen endpoint in router.json5)
    #[arg(long, default_value = DEFAULT_ROUTER_ENDPOINT, value_name = "ENDPOINT")]
    pub router_endpoint: String,
    /// Another host name or IP address of an identity (repeatable), e.g. `--host
    /// logger=10.0.0.4`: NODE's certificate is valid for HOST too (subjectAltName), for
    /// the nodes that dial it and check the name. The plant's first host (its first `--host
    /// plant=`, else the first `--router-host`) and the logger's first also name their
    /// endpoints of the direct loop in the `{node}-direct.json5` files (`tls/HOST:7448`,
    /// `tls/HOST:7449`). NODE: plant, controller, planner, logger, router or an `--extra` name
    #[arg(long = "host", value_name = "NODE=HOST")]
    pub hosts: Vec<String>,
    /// Another identity to certify, with no rights beyond a logger's if named `logger*`, none
    /// otherwise (repeatable; only [A-Za-z0-9_-])
    #[arg(long = "extra", value_name = "NODE")]
    pub extra: Vec<String>,
}

/// What a certificate directory holds.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    /// The robot these certificates and rules are for.
    pub robot: String,
    /// The node names with a certificate (`{node}.pem`, `{node}.key`, `{node}.json5`).
    pub nodes: Vec<String>,
}

/// The common name of `node`'s certificate for `robot`: the identity the ACL matches.
pub fn common_name(robot: &str, node: &str) -> String {
    format!("{robot}-{node}")
}

fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 64
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// `tilting certs`.
pub fn certs(args: &CertsArgs) -> Result<(), CommandError> {
    let keys = Keys::new(&args.robot).map_err(|e| CommandError::Usage(anyhow!("--robot: {e}")))?;
    for e in &args.extra {
        if !valid_name(e) || NODES.contains(&e.as_str()) {
            return Err(CommandError::Usage(anyhow!(
                "invalid `--extra` = {e:?}: 1 to 64 of [A-Za-z0-9_-], not one of {NODES:?}"
            )));
        }
    }
    // `--host` first: the plant's and the logger's first name their endpoints.
    let mut hosts = Vec::new();
    for h in &args.hosts {
        hosts.push(Host::parse(h, &args.extra).map_err(CommandError::Usage)?);
    }
    for h in &args.router_hosts {
        if !valid_host(h) {
            return Err(CommandError::Usage(anyhow!(
                "invalid `--router-host` = {h:?}: {HOST_RULE}"
            )));
        }
        hosts.extend(Host::router_host(h));
    }
    if !args.router_endpoint.starts_with("tls/") {
        return Err(CommandError::Usage(anyhow!(
            "invalid `--router-endpoint` = {:?}: must be a tls/HOST:PORT endpoint",
            args.router_endpoint
        )));
    }
    let m = generate(&keys, &args.out, &hosts, &args.router_endpoint, &args.extra)
        .map_err(CommandError::Failed)?;
    let dir = args.out.display();
    println!(
        "certificates for robot {} in {dir}: {}",
        m.robot,
        m.nodes
            .iter()
            .map(|n| common_name(&m.robot, n))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!("start the router:  tilting-router --config {dir}/router.json5");
    println!(
        "start a node:      tilting-plant --robot {} --zenoh-config {dir}/plant.json5",
        m.robot
    );
    for h in &hosts {
        println!("{}'s certificate names {}", h.node, h.name);
    }
    Ok(())
}

/// What `--host` and `--router-host` allow as a host, in words.
pub const HOST_RULE: &str = "a DNS name (labels of 1 to 63 letters, digits and '-', not \
    starting or ending with '-', joined by '.', at most 253 characters) or an IP address \
    (IPv4 or IPv6, without brackets)";

/// Whether `h` is a DNS name or an IP address a certificate may name ([`HOST_RULE`]).
pub fn valid_host(h: &str) -> bool {
    if h.parse::<std::net::IpAddr>().is_ok() {
        return true;
    }
    !h.is_empty()
        && h.len() <= 253
        && h.split('.').all(|l| {
            (1..=63).contains(&l.len())
                && !l.starts_with('-')
                && !l.ends_with('-')
                && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
        })
}

/// Port of the plant's TLS endpoint of the direct loop in the generated files (`tls/HOST:7448`
/// with the plant's first `--host`).
pub const DIRECT_PLANT_PORT: u16 = 7448;

/// Port of the recorder's (the logger's) TLS endpoint of the direct loop in the generated
/// files (`tls/HOST:7449` with the logger's first `--host`).
pub const DIRECT_RECORDER_PORT: u16 = 7449;

/// One more name of an identity's certificate (`tilting certs --host NODE=HOST`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Host {
    /// The identity: one of [`NODES`] or an `--extra` name.
    pub node: String,
    /// A DNS name or an IP address ([`valid_host`]).
    pub name: String,
}

impl Host {
    /// `NODE=HOST` of `--host`, NODE one of [`NODES`] or `extra`; a usage error naming the flag
    /// and what it allows otherwise.
    pub fn parse(s: &str, extra: &[String]) -> anyhow::Result<Self> {
        let Some((node, name)) = s.split_once('=') else {
            anyhow::bail!("invalid `--host` = {s:?}: NODE=HOST, e.g. logger=10.0.0.4");
        };
        if !(NODES.contains(&node) || extra.iter().any(|e| e == node)) {
            let mut known: Vec<&str> = NODES.to_vec();
            known.extend(extra.iter().map(String::as_str));
            anyhow::bail!(
                "invalid `--host` = {s:?}: NODE must be one of {}",
                known.join(", ")
            );
        }
        if !valid_host(name) {
            anyhow::bail!("invalid `--host` = {s:?}: HOST must be {HOST_RULE}");
        }
        Ok(Self {
            node: node.to_owned(),
            name: name.to_owned(),
        })
    }

    /// What `--router-host HOST` means: the router's certificate and the plant's name HOST
    /// (the plant runs on the router's host, and the controller dials both).
    pub fn router_host(name: &str) -> [Self; 2] {
        ["router", "plant"].map(|node| Self {
            node: node.to_owned(),
            name: name.to_owned(),
        })
    }

    /// A TLS endpoint on this host: `tls/HOST:PORT` (`tls/[HOST]:PORT` for IPv6).
    pub fn endpoint(&self, port: u16) -> String {
        match self.name.parse::<std::net::Ipv6Addr>() {
            Ok(_) => format!("tls/[{}]:{port}", self.name),
            Err(_) => format!("tls/{}:{port}", self.name),
        }
    }
}

/// Creates `out` and writes into it: `ca.pem` (the CA certificate; its key is not kept),
/// `{node}.pem` and `{node}.key` for each of [`NODES`] and `extra`, a client configuration
/// `{node}.json5` for each node (mode client, scouting off, TLS with its certificate, connect to
/// `router_endpoint`), `router.json5` (mode router, listening on `router_endpoint`, TLS with
/// mTLS, the ACL of the module documentation), `{node}-direct.json5` for each of [`DIRECT`]
/// (the plant, the controller and the recorder of `live --secure`, [`direct_config`], with
/// the endpoints of [`DirectEndpoints::from_hosts`]) and [`MANIFEST`]. File paths inside the
/// configurations are absolute.
///
/// The certificates of the router, the plant and the logger name `localhost` and `127.0.0.1`
/// (in their subjectAltName: the nodes dial the router, the controller and the recorder dial
/// the plant, the controller dials the recorder, and each checks the name); every `hosts`
/// entry adds its name to its identity's certificate.
pub fn generate(
    keys: &Keys,
    out: &Path,
    hosts: &[Host],
    router_endpoint: &str,
    extra: &[String],
) -> anyhow::Result<Manifest> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("cannot create the directory {}", out.display()))?;
    let out = out
        .canonicalize()
        .with_context(|| format!("cannot resolve {}", out.display()))?;
    let robot = keys.robot();
    let year: i32 = crate::supervise::utc_timestamp()[..4]
        .parse()
        .unwrap_or(2026);
    let validity = |p: &mut CertificateParams| {
        p.not_before = rcgen::date_time_ymd(year - 1, 1, 1);
        p.not_after = rcgen::date_time_ymd(year + 2, 1, 1);
    };

    let ca_key = KeyPair::generate().context("cannot generate the CA key")?;
    let mut ca = CertificateParams::new(Vec::<String>::new())?;
    ca.distinguished_name.push(
        DnType::CommonName,
        format!("tilting {robot} development CA"),
    );
    ca.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    ca.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
    validity(&mut ca);
    let ca_cert = ca.self_signed(&ca_key).context("cannot sign the CA")?;
    write(&out.join("ca.pem"), &ca_cert.pem(), false)?;
    let issuer = Issuer::new(ca, ca_key);

    let mut nodes: Vec<String> = NODES.iter().map(|s| s.to_string()).collect();
    nodes.extend(extra.iter().cloned());
    let endpoints = DirectEndpoints::from_hosts(hosts, router_endpoint);
    for node in &nodes {
        let mut sans: Vec<String> = Vec::new();
        // The certificates of the sessions that are dialled name their host: the nodes dial
        // the router, the controller and the recorder dial the plant (the direct loop), the
        // controller dials the recorder ([`RECORDER`]), and each checks the name. On one host
        // that is the loopback host; `--host` adds the others ("Three hosts" in the README).
        if node == "router" || node == "plant" || node == RECORDER {
            sans.extend(["localhost".to_owned(), "127.0.0.1".to_owned()]);
        }
        for h in hosts.iter().filter(|h| &h.node == node) {
            if !sans.contains(&h.name) {
                sans.push(h.name.clone());
            }
        }
        let mut p = CertificateParams::new(sans)?;
        p.distinguished_name
            .push(DnType::CommonName, common_name(robot, node));
        p.key_usages = vec![
            KeyUsagePurpose::DigitalSignature,
            KeyUsagePurpose::KeyEncipherment,
        ];
        p.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ClientAuth,
            ExtendedKeyUsagePurpose::ServerAuth,
        ];
        validity(&mut p);
        let key = KeyPair::generate().with_context(|| format!("cannot generate {node}'s key"))?;
        let cert = p
            .signed_by(&key, &issuer)
            .with_context(|| format!("cannot sign {node}'s certificate"))?;
        write(&out.join(format!("{node}.pem")), &cert.pem(), false)?;
        write(&out.join(format!("{node}.key")), &key.serialize_pem(), true)?;
        let cfg = if node == "router" {
            router_config(keys, &out, &nodes, router_endpoint)
        } else {
            client_config(&out, node, router_endpoint)
        };
        write(
            &out.join(format!("{node}.json5")),
            &serde_json::to_string_pretty(&cfg)?,
            false,
        )?;
        if DIRECT.contains(&node.as_str()) {
            let mut cfg = direct_config(keys, &out, node, &nodes);
            let (listen, connect) = endpoints.of(node);
            cfg["listen"]["endpoints"] = json!(listen);
            cfg["connect"]["endpoints"] = json!(connect);
            write(
                &out.join(format!("{node}-direct.json5")),
                &serde_json::to_string_pretty(&cfg)?,
                false,
            )?;
        }
    }
    let manifest = Manifest {
        robot: robot.to_owned(),
        nodes,
    };
    write(
        &out.join(MANIFEST),
        &serde_json::to_string_pretty(&manifest)?,
        false,
    )?;
    Ok(manifest)
}

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

/// Reads the [`MANIFEST`] of a certificate directory and checks that it is for `robot`.
pub fn read_manifest(dir: &Path, robot: &str) -> anyhow::Result<Manifest> {
    let path = dir.join(MANIFEST);
    use tilting_proto::bounded;
    let text = bounded::read_to_string(&path, bounded::CONFIG_LIMIT, "a certificate manifest")
        .with_context(|| {
            format!(
            "cannot read {} (create the directory with `tilting certs --robot {robot} --out {}`)",
            path.display(),
            dir.display()
        )
        })?;
    let m: Manifest =
        serde_json::from_str(&text).with_context(|| format!("{} is invalid", path.display()))?;
    if m.robot != robot {
        anyhow::bail!(
            "the certificates in {} are for robot {:?}, not {robot:?}",
            dir.display(),
            m.robot
        );
    }
    Ok(m)
}

fn write(path: &Path, text: &str, secret: bool) -> anyhow::Result<()> {
    #[cfg(unix)]
    if secret {
        use std::io::Write as _;
        use std::os::unix::fs::OpenOptionsExt as _;
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .mode(0o600)
            .open(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
        return f
            .write_all(text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()));
    }
    let _ = secret;
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn file(dir: &Path, name: &str) -> String {
    dir.join(name).display().to_string()
}

/// The zenoh configuration of a node: a client of the router at `router_endpoint`, TLS only,
/// with `node`'s certificate, no scouting, no listener.
pub fn client_config(dir: &Path, node: &str, router_endpoint: &str) -> Value {
    json!({
        "mode": "client",
        "connect": {
            "endpoints": [router_endpoint],
            "retry": { "period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2 },
        },
        "listen": { "endpoints": [] },
        "scouting": {
            "multicast": { "enabled": false },
            "gossip": { "enabled": false },
            "delay": tilting_net::OPEN_WAIT_MS,
        },
        "timestamping": { "enabled": false },
        "transport": { "link": {
            "protocols": ["tls"],
            "tls": {
                "root_ca_certificate": file(dir, "ca.pem"),
                "connect_certificate": file(dir, &format!("{node}.pem")),
                "connect_private_key": file(dir, &format!("{node}.key")),
                "enable_mtls": true,
                "verify_name_on_connect": true,
            },
        }},
    })
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

/// The zenoh configuration of `node` (one of [`DIRECT`]) in the direct loop (`{node}-direct.json5`,
/// what `tilting live --secure` runs): a **peer** with the TLS link of [`client_config`] (its own
/// certificate, mutual authentication, names checked), no scouting, and its own access control
/// ([`node_acl`]). No endpoint here: [`generate`] writes those of [`DirectEndpoints`] into
/// the file, and the flags replace them ([`session_flags`]: the plant `--listen`s on its
/// endpoint and `--connect`s to the router; the controller `--connect`s to the plant, the
/// router and the recorder; the recorder `--listen`s on its own and `--connect`s to the plant).
pub fn direct_config(keys: &Keys, dir: &Path, node: &str, nodes: &[String]) -> Value {
    json!({
        "mode": "peer",
        "connect": {
            "endpoints": [],
            "retry": { "period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2 },
        },
        "listen": { "endpoints": [] },
        "scouting": {
            "multicast": { "enabled": false },
            "gossip": { "enabled": false },
            "delay": tilting_net::OPEN_WAIT_MS,
        },
        "timestamping": { "enabled": false },
        "transport": { "link": {
            "protocols": ["tls"],
            "tls": {
                "root_ca_certificate": file(dir, "ca.pem"),
                "listen_certificate": file(dir, &format!("{node}.pem")),
                "listen_private_key": file(dir, &format!("{node}.key")),
                "connect_certificate": file(dir, &format!("{node}.pem")),
                "connect_private_key": file(dir, &format!("{node}.key")),
                "enable_mtls": true,
                "verify_name_on_connect": true,
            },
        }},
        "access_control": node_acl(keys, node, nodes),
    })
}

/// One allow rule of a zenoh ACL: `id`, the flows (`ingress`/`egress`), the message kinds and
/// the key expressions it covers.
fn acl_rule(id: &str, flows: &[&str], messages: &[&str], key_exprs: Vec<&str>) -> Value {
    json!({ "id": id, "permission": "allow", "flows": flows, "messages": messages,
            "key_exprs": key_exprs })
}

/// A subject of a zenoh ACL: the certificates' common names it matches.
fn acl_subject(id: &str, cns: Vec<String>) -> Value {
    json!({ "id": id, "cert_common_names": cns })
}

/// A policy of a zenoh ACL: which rules apply to which subjects.
fn acl_policy(id: &str, rules: &[&str], subjects: &[&str]) -> Value {
    json!({ "id": id, "rules": rules, "subjects": subjects })
}

/// The rules every authenticated identity of the robot gets, in the router's ACL and in each
/// node's own: "listen" (subscribe, query, watch tokens: ingress) and "receive" (get what it
/// listens to: egress), both on `all` (`tilting/<robot>/**`).
fn listen_rules(all: &str) -> [Value; 2] {
    [
        acl_rule(
            "listen",
            &["ingress"],
            &[
                "declare_subscriber",
                "query",
                "liveliness_query",
                "declare_liveliness_subscriber",
            ],
            vec![all],
        ),
        acl_rule(
            "receive",
            &["egress"],
            &[
                "put",
                "delete",
                "declare_subscriber",
                "query",
                "reply",
                "declare_queryable",
                "liveliness_token",
                "liveliness_query",
                "declare_liveliness_subscriber",
            ],
            vec![all],
        ),
    ]
}

/// The ingress rules `node` (one of [`DIRECT`]) enforces on its own links in the direct loop
/// (zenoh applies ACL only in the session that holds it: eclipse-zenoh/zenoh#2137). Every
/// identity of the robot (the router's included) may subscribe, query and watch tokens, and
/// receive what it subscribed to; beyond that, default deny:
///
/// - the plant accepts torques and the controller's token **only from the controller's
///   identity**, so only on the direct link (the router's copies are refused);
/// - the controller accepts states, events, statuses and the plant's token only from the
///   plant's identity, and the reference (puts, replies, queryable, the planner's token) only
///   from the router's, which let only the planner's identity publish it;
/// - the recorder ([`RECORDER`]) accepts states, events, statuses and the plant's token only
///   from the plant's identity, torques and the controller's token only from the controller's,
///   and nothing else (it takes the reference from its own planner session).
pub fn node_acl(keys: &Keys, node: &str, nodes: &[String]) -> Value {
    let robot = keys.robot();
    let all = format!("tilting/{robot}/**");
    let rule = acl_rule;
    let subject = acl_subject;
    let policy = acl_policy;
    let mut listeners: Vec<String> = nodes
        .iter()
        .filter(|n| NODES.contains(&n.as_str()) || n.starts_with("logger"))
        .map(|n| common_name(robot, n))
        .collect();
    listeners.sort();
    let mut rules = listen_rules(&all).to_vec();
    let mut subjects = vec![subject("robot", listeners)];
    let mut policies = vec![policy(
        "everyone listens",
        &["listen", "receive"],
        &["robot"],
    )];
    let states = rule(
        "states",
        &["ingress"],
        &["put", "liveliness_token"],
        vec![
            keys.plant_state(),
            keys.plant_event(),
            keys.plant_status(),
            keys.alive_plant(),
        ],
    );
    if node == RECORDER {
        rules.push(states);
        rules.push(rule(
            "torques",
            &["ingress"],
            &["put", "liveliness_token"],
            vec![keys.controller_torque(), keys.alive_controller()],
        ));
        subjects.push(subject("plant", vec![common_name(robot, "plant")]));
        subjects.push(subject(
            "controller",
            vec![common_name(robot, "controller")],
        ));
        policies.push(policy("plant", &["states"], &["plant"]));
        policies.push(policy("controller", &["torques"], &["controller"]));
    } else if node == "plant" {
        rules.push(rule(
            "torques",
            &["ingress"],
            &["put", "liveliness_token"],
            vec![keys.controller_torque(), keys.alive_controller()],
        ));
        subjects.push(subject(
            "controller",
            vec![common_name(robot, "controller")],
        ));
        policies.push(policy("controller", &["torques"], &["controller"]));
    } else {
        rules.push(states);
        rules.push(rule(
            "reference",
            &["ingress"],
            &["put", "reply", "declare_queryable", "liveliness_token"],
            vec![keys.planner_reference(), keys.alive_planner()],
        ));
        subjects.push(subject("plant", vec![common_name(robot, "plant")]));
        subjects.push(subject("router", vec![common_name(robot, "router")]));
        policies.push(policy("plant", &["states"], &["plant"]));
        policies.push(policy("router", &["reference"], &["router"]));
    }
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

/// The zenoh configuration of the router: listens on `endpoint` (the one the nodes dial;
/// replace it with `tilting-router --listen`), TLS only with mutual authentication, scouting
/// off, and the access control of the module documentation for the identities in `nodes`.
pub fn router_config(keys: &Keys, dir: &Path, nodes: &[String], endpoint: &str) -> Value {
    json!({
        "mode": "router",
        "listen": { "endpoints": [endpoint] },
        "connect": { "endpoints": [] },
        "scouting": {
            "multicast": { "enabled": false },
            "gossip": { "enabled": false },
        },
        "timestamping": { "enabled": false },
        "transport": { "link": {
            "protocols": ["tls"],
            "tls": {
                "root_ca_certificate": file(dir, "ca.pem"),
                "listen_certificate": file(dir, "router.pem"),
                "listen_private_key": file(dir, "router.key"),
                "enable_mtls": true,
            },
        }},
        "access_control": acl(keys, nodes),
    })
}

/// The `access_control` block for `keys`' robot (see the module documentation).
pub fn acl(keys: &Keys, nodes: &[String]) -> Value {
    let robot = keys.robot();
    let all = format!("tilting/{robot}/**");
    let rule = acl_rule;
    let [listen, receive] = listen_rules(&all);
    let rules = vec![
        listen,
        receive,
        rule(
            "plant publishes",
            &["ingress"],
            &["put"],
            vec![keys.plant_state(), keys.plant_event(), keys.plant_status()],
        ),
        rule(
            "plant token",
            &["ingress"],
            &["liveliness_token"],
            vec![keys.alive_plant()],
        ),
        rule(
            "controller publishes",
            &["ingress"],
            &["put"],
            vec![keys.controller_torque()],
        ),
        rule(
            "controller token",
            &["ingress"],
            &["liveliness_token"],
            vec![keys.alive_controller()],
        ),
        rule(
            "planner publishes",
            &["ingress"],
            &["put", "declare_queryable", "reply"],
            vec![keys.planner_reference()],
        ),
        rule(
            "planner token",
            &["ingress"],
            &["liveliness_token"],
            vec![keys.alive_planner()],
        ),
    ];
    let listeners: Vec<String> = nodes
        .iter()
        .filter(|n| {
            n.as_str() != "router" && (NODES.contains(&n.as_str()) || n.starts_with("logger"))
        })
        .map(|n| common_name(robot, n))
        .collect();
    let subject = acl_subject;
    let subjects = vec![
        subject("nodes", listeners),
        subject("plant", vec![common_name(robot, "plant")]),
        subject("controller", vec![common_name(robot, "controller")]),
        subject("planner", vec![common_name(robot, "planner")]),
    ];
    let policy = acl_policy;
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": [
            policy("everyone listens", &["listen", "receive"], &["nodes"]),
            policy("plant", &["plant publishes", "plant token"], &["plant"]),
            policy("controller", &["controller publishes", "controller token"], &["controller"]),
            policy("planner", &["planner publishes", "planner token"], &["planner"]),
        ],
    })
}

/// Flags of `tilting-router`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "tilting-router",
    version,
    about = "A zenoh router for a secure tilting deployment: TLS with mutual authentication and \
             the robot's access control, from a configuration written by `tilting certs`"
)]
pub struct RouterArgs {
    /// The router's zenoh configuration (JSON5), e.g. router.json5 of `tilting certs`
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// Endpoint to listen on instead of the configuration's (repeatable), e.g.
    /// tls/0.0.0.0:7447
    #[arg(long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Nice value (0-19) the router lowers itself to before it opens its session, so that on a
    /// host it shares with the plant or the controller the loop's processes run first (0: keep
    /// the priority it was started with; see the README's "Cost" for when a higher value hurts)
    #[arg(long, default_value_t = ROUTER_NICE, value_name = "0-19",
          value_parser = clap::value_parser!(i32).range(0..=19))]
    pub nice: i32,
}

/// Default nice value of `tilting-router` (`--nice`): 0, the priority it was started with.
///
/// The router carries no message of the control loop (the plant and the controller talk over
/// their direct link, and `live --secure`'s recorder takes them on links of its own), but with
/// an outside client subscribed to the loop's topics (a logger, `tilting echo`) it decrypts,
/// routes and re-encrypts every state and torque at the very moment the controller wakes up
/// for that state, and on a host it shares with the loop it competes with the controller for
/// the CPU (README, "Cost"). `--nice 19` removes that cost (when the recorder of `live` was
/// such a client: loop latency p99 0.6-0.9x the open loop's instead of 1.0-1.5x, at load 9-11
/// on 2 cores), but it is not the default: on a saturated host (load 11-12 on 2 cores) 3 of 3
/// such runs with the router at nice 19 had 6 to 11 safe-mode entries, against 0 of 4 at nice
/// 0. The loop's publishers use blocking congestion control, so a router starved of CPU that
/// has subscribers of the loop's topics back-pressures the plant and the controller. With
/// none (`live --secure` today) the router has nothing to do for the loop, at any priority.
pub const ROUTER_NICE: i32 = 0;

/// Lowers the calling thread's priority to nice `nice` if it is higher than the current one
/// (threads made afterwards, zenoh's among them, inherit it on Linux, where a thread is a task
/// with its own nice value; raising the priority would need privileges, so a lower `nice`
/// leaves it as it is). Returns the nice value in force. Linux only; elsewhere nothing.
pub fn lower_priority(nice: i32) -> std::io::Result<i32> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: getpriority(2)/setpriority(2) on the calling thread (who = 0); no memory is
        // passed. (getpriority returns the nice value, -20..19; it cannot fail for who = 0.)
        unsafe {
            let now = libc::getpriority(libc::PRIO_PROCESS, 0);
            if nice <= now {
                return Ok(now);
            }
            if libc::setpriority(libc::PRIO_PROCESS, 0, nice) != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
        Ok(nice)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = nice;
        Ok(0)
    }
}

/// `tilting-router`: opens a zenoh router session from `--config` (which must say `mode:
/// "router"`), prints `ready` with its zenoh id on stdout, and runs until Ctrl-C or SIGTERM.
pub fn router(args: &RouterArgs) -> Result<(), CommandError> {
    tilting_net::init_tracing("warn");
    // Before any other thread exists: the tokio and zenoh threads inherit the nice value.
    let nice = match lower_priority(args.nice) {
        Ok(n) => n,
        Err(e) => {
            tracing::warn!(
                "cannot lower the router's priority to nice {}: {e}",
                args.nice
            );
            0
        }
    };
    let mut cfg = tilting_net::config_from_file(&args.config)
        .map_err(|e| CommandError::Usage(anyhow!("--config {}: {e}", args.config.display())))?;
    let mode = cfg.get_json("mode").unwrap_or_default();
    if mode != "\"router\"" {
        return Err(CommandError::Usage(anyhow!(
            "--config {}: mode is {mode}, must be \"router\"",
            args.config.display()
        )));
    }
    if !args.listen.is_empty() {
        let json = serde_json::to_string(&args.listen).expect("strings serialize");
        cfg.insert_json5("listen/endpoints", &json).map_err(|e| {
            CommandError::Usage(anyhow!(
                "--listen {:?}: {}",
                args.listen,
                tilting_net::zenoh_error(&e)
            ))
        })?;
    }
    let rt = tilting_net::runtime().map_err(CommandError::Failed)?;
    rt.block_on(async {
        let session = zenoh::open(cfg).await.map_err(|e| {
            anyhow!(
                "cannot open the router session: {}",
                tilting_net::zenoh_error(&e)
            )
        })?;
        let ready = json!({ "ready": true, "zid": session.zid().to_string(), "nice": nice });
        let _ = tilting_net::say_out(&ready.to_string());
        tilting_net::shutdown_signal().await;
        let _ = session.close().await;
        let _ = tilting_net::say_out(&json!({ "stopped": true }).to_string());
        Ok::<_, anyhow::Error>(())
    })
    .map_err(CommandError::Failed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn generates_certs_and_configs_zenoh_accepts() {
        let dir = tempfile::tempdir().unwrap();
        let keys = Keys::new("unit").unwrap();
        let m = generate(
            &keys,
            dir.path(),
            &Host::router_host("10.1.2.3"),
            DEFAULT_ROUTER_ENDPOINT,
            &["rogue".into()],
        )
        .unwrap();
        assert_eq!(m.nodes.len(), 6);
        for n in &m.nodes {
            let cfg = zenoh::Config::from_file(dir.path().join(format!("{n}.json5")))
                .unwrap_or_else(|e| panic!("{n}: {e}"));
            let want = if n == "router" {
                "\"router\""
            } else {
                "\"client\""
            };
            assert_eq!(cfg.get_json("mode").unwrap(), want);
        }
        let router = zenoh::Config::from_file(dir.path().join("router.json5")).unwrap();
        let acl = router.get_json("access_control").unwrap();
        assert!(
            acl.contains("unit-controller") && !acl.contains("unit-rogue"),
            "{acl}"
        );
        for n in DIRECT {
            let cfg = zenoh::Config::from_file(dir.path().join(format!("{n}-direct.json5")))
                .unwrap_or_else(|e| panic!("{n}-direct: {e}"));
            assert_eq!(cfg.get_json("mode").unwrap(), "\"peer\"");
            let acl = cfg.get_json("access_control").unwrap();
            // Each takes the loop's topics only from the other end of the loop.
            let other = if n == "plant" { "controller" } else { "plant" };
            assert!(acl.contains(&format!("unit-{other}")), "{acl}");
            assert!(!acl.contains("unit-rogue"), "{acl}");
        }
        assert!(read_manifest(dir.path(), "unit").is_ok());
        assert!(read_manifest(dir.path(), "other").is_err());
    }

    /// The names in the subjectAltName of the certificate `{node}.pem` in `dir`, read back
    /// with x509-parser (zenoh's TLS link parses certificates with it too): DNS names as
    /// written, IP addresses as `std::net::IpAddr` prints them.
    fn sans(dir: &Path, node: &str) -> std::collections::BTreeSet<String> {
        use x509_parser::extensions::GeneralName;
        let pem = std::fs::read(dir.join(format!("{node}.pem"))).unwrap();
        let (_, pem) = x509_parser::pem::parse_x509_pem(&pem).unwrap();
        let cert = pem.parse_x509().unwrap();
        let Some(san) = cert.subject_alternative_name().unwrap() else {
            return Default::default();
        };
        san.value
            .general_names
            .iter()
            .map(|n| match n {
                GeneralName::DNSName(d) => d.to_string(),
                GeneralName::IPAddress(b) => match b.len() {
                    4 => std::net::IpAddr::from(<[u8; 4]>::try_from(*b).unwrap()).to_string(),
                    16 => std::net::IpAddr::from(<[u8; 16]>::try_from(*b).unwrap()).to_string(),
                    _ => panic!("{node}: an IP address of {} bytes", b.len()),
                },
                other => panic!("{node}: unexpected name {other:?}"),
            })
            .collect()
    }

    fn set(names: &[&str]) -> std::collections::BTreeSet<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    /// `--host NODE=HOST` puts HOST in NODE's certificate (DNS names and IPv4 and IPv6
    /// addresses, as what they are), `--router-host` in the router's and the plant's, and the
    /// plant's and the logger's first host names their endpoints in the direct files; the
    /// defaults are unchanged. The truth: the certificates parsed back, against the names
    /// written out here.
    #[test]
    fn hosts_go_into_the_certificates_and_the_direct_endpoints() {
        let dir = tempfile::tempdir().unwrap();
        let keys = Keys::new("unit").unwrap();
        let extra = ["rogue".to_owned()];
        let mut hosts: Vec<Host> = [
            "plant=plant.arm1.example",
            "logger=10.0.0.4",
            "logger=rec.example",
            "controller=fd00::2",
            "rogue=10.9.9.9",
        ]
        .iter()
        .map(|h| Host::parse(h, &extra).unwrap())
        .collect();
        hosts.extend(Host::router_host("10.0.0.1"));
        generate(&keys, dir.path(), &hosts, "tls/10.0.0.1:7447", &extra).unwrap();
        let d = dir.path();
        let local = ["localhost", "127.0.0.1"];
        assert_eq!(
            sans(d, "plant"),
            set(&[&local[..], &["plant.arm1.example", "10.0.0.1"]].concat())
        );
        assert_eq!(
            sans(d, "router"),
            set(&[&local[..], &["10.0.0.1"]].concat())
        );
        assert_eq!(
            sans(d, "logger"),
            set(&[&local[..], &["10.0.0.4", "rec.example"]].concat())
        );
        assert_eq!(sans(d, "controller"), set(&["fd00::2"]));
        assert_eq!(sans(d, "rogue"), set(&["10.9.9.9"]));
        assert_eq!(sans(d, "planner"), set(&[]));
        // The endpoints: the plant's and the logger's first host, the router's endpoint.
        let endpoints = |d: &Path, node: &str, what: &str| {
            let cfg = zenoh::Config::from_file(d.join(format!("{node}-direct.json5"))).unwrap();
            let v: Vec<String> =
                serde_json::from_str(&cfg.get_json(&format!("{what}/endpoints")).unwrap()).unwrap();
            v
        };
        let (p, r, l) = (
            "tls/plant.arm1.example:7448",
            "tls/10.0.0.1:7447",
            "tls/10.0.0.4:7449",
        );
        assert_eq!(endpoints(d, "plant", "listen"), [p]);
        assert_eq!(endpoints(d, "plant", "connect"), [p, r][1..]);
        assert_eq!(endpoints(d, "controller", "listen"), Vec::<String>::new());
        assert_eq!(endpoints(d, "controller", "connect"), [p, r, l]);
        assert_eq!(endpoints(d, "logger", "listen"), [l]);
        assert_eq!(endpoints(d, "logger", "connect"), [p]);
        let router = zenoh::Config::from_file(d.join("router.json5")).unwrap();
        assert_eq!(
            router.get_json("listen/endpoints").unwrap(),
            "[\"tls/10.0.0.1:7447\"]"
        );
        // IPv6 endpoints take brackets.
        assert_eq!(
            Host::parse("plant=fd00::1", &[]).unwrap().endpoint(7448),
            "tls/[fd00::1]:7448"
        );
        // Without hosts: the loopback names only, and no endpoint but the router's.
        let dir = tempfile::tempdir().unwrap();
        generate(&keys, dir.path(), &[], DEFAULT_ROUTER_ENDPOINT, &[]).unwrap();
        let d = dir.path();
        for node in ["plant", "router", "logger"] {
            assert_eq!(sans(d, node), set(&local), "{node}");
        }
        assert_eq!(sans(d, "controller"), set(&[]));
        assert_eq!(endpoints(d, "plant", "listen"), Vec::<String>::new());
        assert_eq!(
            endpoints(d, "controller", "connect"),
            [DEFAULT_ROUTER_ENDPOINT]
        );
        assert_eq!(endpoints(d, "logger", "connect"), Vec::<String>::new());
    }

    /// Bad `--host` values get an error that names the flag and says what is allowed.
    #[test]
    fn bad_hosts_are_refused_with_the_rule() {
        let extra = ["rogue".to_owned()];
        for bad in [
            "logger",
            "=10.0.0.4",
            "nobody=10.0.0.4",
            "logger=",
            "logger=-rec.example",
            "logger=rec-.example",
            "logger=rec..example",
            "logger=rec_1.example",
            "logger=tls/10.0.0.4:7449",
            "logger=10.0.0.4:7449",
            "logger=[fd00::1]",
            "logger=rec example",
        ] {
            let e = Host::parse(bad, &extra).expect_err(bad).to_string();
            assert!(e.contains("`--host`") && e.contains(bad), "{bad}: {e}");
        }
        let long = format!("logger={}", vec!["a".repeat(63); 4].join("."));
        assert!(Host::parse(&long, &extra).is_err(), "255 characters");
        assert!(Host::parse(&format!("logger={}.b", "a".repeat(64)), &extra).is_err());
        for good in [
            "rogue=10.0.0.4",
            "logger=::1",
            "plant=Plant-1.arm1.example",
            "router=localhost",
        ] {
            assert!(Host::parse(good, &extra).is_ok(), "{good}");
        }
        let e = Host::parse("nobody=x", &extra).unwrap_err().to_string();
        assert!(e.contains("plant") && e.contains("rogue"), "{e}");
    }

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
            let port = crate::supervise::free_port().unwrap();
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

    /// Whether `acl` (an `access_control` block) lets the certificate `cn` send `message` on
    /// `key` in `flow`: an allow rule of a policy whose subject names `cn` covers it (our rules
    /// use exact keys and `prefix/**` only); default deny otherwise.
    fn allows(acl: &Value, cn: &str, flow: &str, message: &str, key: &str) -> bool {
        let has = |v: &Value, x: &str| v.as_array().unwrap().iter().any(|e| e == x);
        let covers = |v: &Value| {
            v.as_array().unwrap().iter().any(|k| {
                let k = k.as_str().unwrap();
                k == key || k.strip_suffix("**").is_some_and(|p| key.starts_with(p))
            })
        };
        let subjects: Vec<&str> = acl["subjects"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|s| has(&s["cert_common_names"], cn))
            .map(|s| s["id"].as_str().unwrap())
            .collect();
        acl["policies"].as_array().unwrap().iter().any(|p| {
            subjects.iter().any(|s| has(&p["subjects"], s))
                && acl["rules"].as_array().unwrap().iter().any(|r| {
                    has(&p["rules"], r["id"].as_str().unwrap())
                        && has(&r["flows"], flow)
                        && has(&r["messages"], message)
                        && covers(&r["key_exprs"])
                })
        })
    }

    /// Each session of the direct topology takes each of the loop's topics from exactly the
    /// identity the module's table says publishes it (and the recorder takes no reference, as
    /// it never dials the router), and every identity of the robot may subscribe at each.
    /// Checked by evaluating the generated rules, against the table written out here.
    #[test]
    fn each_direct_session_takes_each_topic_from_its_publisher_only() {
        let dir = tempfile::tempdir().unwrap();
        let keys = Keys::new("unit").unwrap();
        let m = generate(
            &keys,
            dir.path(),
            &[],
            DEFAULT_ROUTER_ENDPOINT,
            &["rogue".into()],
        )
        .unwrap();
        let topics = [
            (keys.plant_state(), "plant"),
            (keys.plant_event(), "plant"),
            (keys.plant_status(), "plant"),
            (keys.controller_torque(), "controller"),
            (keys.planner_reference(), "router"),
        ];
        // Which topics each session takes at all (the ones it subscribes to).
        let takes = |node: &str, key: &str| match node {
            "plant" => key == keys.controller_torque(),
            "controller" => key != keys.controller_torque(),
            _ => key != keys.planner_reference(),
        };
        for node in DIRECT {
            let acl = direct_config(&keys, dir.path(), node, &m.nodes)["access_control"].clone();
            for cn in &m.nodes {
                let id = common_name("unit", cn);
                for (key, from) in topics {
                    let want = takes(node, key) && cn == from;
                    assert_eq!(
                        allows(&acl, &id, "ingress", "put", key),
                        want,
                        "{node} taking a put on {key} from {id}"
                    );
                }
                let listens = cn != "rogue";
                assert_eq!(
                    allows(
                        &acl,
                        &id,
                        "ingress",
                        "declare_subscriber",
                        keys.plant_state()
                    ),
                    listens,
                    "{node}: {id} subscribing"
                );
            }
        }
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
