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
    /// Host name or IP address the nodes use to reach the router (repeatable; always adds
    /// localhost and 127.0.0.1): the router's certificate is valid for these names
    #[arg(long = "router-host", value_name = "HOST")]
    pub router_hosts: Vec<String>,
    /// The router's endpoint written into the nodes' configuration files
    #[arg(long, default_value = DEFAULT_ROUTER_ENDPOINT, value_name = "ENDPOINT")]
    pub router_endpoint: String,
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
    for h in &args.router_hosts {
        if h.is_empty() || (h.contains(['/', ' ', ':']) && h.parse::<std::net::IpAddr>().is_err()) {
            return Err(CommandError::Usage(anyhow!(
                "invalid `--router-host` = {h:?}: a host name or an IP address"
            )));
        }
    }
    if !args.router_endpoint.starts_with("tls/") {
        return Err(CommandError::Usage(anyhow!(
            "invalid `--router-endpoint` = {:?}: must be a tls/HOST:PORT endpoint",
            args.router_endpoint
        )));
    }
    let m = generate(
        &keys,
        &args.out,
        &args.router_hosts,
        &args.router_endpoint,
        &args.extra,
    )
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
    Ok(())
}

/// Creates `out` and writes into it: `ca.pem` (the CA certificate; its key is not kept),
/// `{node}.pem` and `{node}.key` for each of [`NODES`] and `extra`, a client configuration
/// `{node}.json5` for each node (mode client, scouting off, TLS with its certificate, connect to
/// `router_endpoint`), `router.json5` (mode router, TLS with mTLS, the ACL of the module
/// documentation), `{node}-direct.json5` for each of [`DIRECT`] (the plant, the controller and
/// the recorder of `live --secure`, [`direct_config`]) and [`MANIFEST`]. File paths inside the
/// configurations are absolute.
pub fn generate(
    keys: &Keys,
    out: &Path,
    router_hosts: &[String],
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
    for node in &nodes {
        let mut sans: Vec<String> = Vec::new();
        // The router's and the plant's certificates name their host: the nodes dial the router,
        // the controller and the recorder dial the plant (the direct loop), and each checks the
        // name. The plant runs on the router's host ("Three hosts" in the README). The
        // logger's names the loopback host: `live --secure`'s recorder listens with it and the
        // controller dials it ([`RECORDER`]).
        if node == "router" || node == "plant" {
            sans.extend(["localhost".to_owned(), "127.0.0.1".to_owned()]);
            for h in router_hosts {
                if !sans.contains(h) {
                    sans.push(h.clone());
                }
            }
        } else if node == RECORDER {
            sans.extend(["localhost".to_owned(), "127.0.0.1".to_owned()]);
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
            router_config(keys, &out, &nodes)
        } else {
            client_config(&out, node, router_endpoint)
        };
        write(
            &out.join(format!("{node}.json5")),
            &serde_json::to_string_pretty(&cfg)?,
            false,
        )?;
        if DIRECT.contains(&node.as_str()) {
            write(
                &out.join(format!("{node}-direct.json5")),
                &serde_json::to_string_pretty(&direct_config(keys, &out, node, &nodes))?,
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
/// ([`node_acl`]). The endpoints are left to the flags: the plant `--listen`s on its endpoint
/// and `--connect`s to the router; the controller `--connect`s to the plant and to the router.
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

/// The zenoh configuration of the router: listens on [`DEFAULT_ROUTER_ENDPOINT`] (replace it
/// with `tilting-router --listen`), TLS only with mutual authentication, scouting off, and the
/// access control of the module documentation for the identities in `nodes`.
pub fn router_config(keys: &Keys, dir: &Path, nodes: &[String]) -> Value {
    json!({
        "mode": "router",
        "listen": { "endpoints": [DEFAULT_ROUTER_ENDPOINT] },
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

    #[test]
    fn generates_certs_and_configs_zenoh_accepts() {
        let dir = tempfile::tempdir().unwrap();
        let keys = Keys::new("unit").unwrap();
        let m = generate(
            &keys,
            dir.path(),
            &["10.1.2.3".into()],
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
