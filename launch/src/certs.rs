//! The certificate directory of a secure deployment: a development CA, one certificate per
//! identity (with the host names the nodes dial it by), the zenoh configuration files of
//! [`crate::client_config`], [`crate::router_config`] and [`crate::direct_config`], and the
//! [`MANIFEST`] (`tilting certs`).

use crate::config::{client_config, direct_config, router_config};
use crate::session::{DirectEndpoints, DIRECT, RECORDER};
use crate::LaunchError;
use anyhow::{anyhow, Context as _};
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use serde_json::json;
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

/// What [`certs`] wrote: the manifest and the extra host names, in the order of the flags.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Written {
    /// The robot and its identities ([`MANIFEST`]).
    pub manifest: Manifest,
    /// The `--host` names, then the `--router-host` names (each as the router's and the plant's).
    pub hosts: Vec<Host>,
}

/// `tilting certs`: checks the flags (an [`LaunchError::Invalid`] naming the flag and what it
/// allows) and [`generate`]s the directory `args.out`.
pub fn certs(args: &CertsArgs) -> Result<Written, LaunchError> {
    let keys = Keys::new(&args.robot).map_err(|e| LaunchError::Invalid(anyhow!("--robot: {e}")))?;
    for e in &args.extra {
        if !valid_name(e) || NODES.contains(&e.as_str()) {
            return Err(LaunchError::Invalid(anyhow!(
                "invalid `--extra` = {e:?}: 1 to 64 of [A-Za-z0-9_-], not one of {NODES:?}"
            )));
        }
    }
    // `--host` first: the plant's and the logger's first name their endpoints.
    let mut hosts = Vec::new();
    for h in &args.hosts {
        hosts.push(Host::parse(h, &args.extra).map_err(LaunchError::Invalid)?);
    }
    for h in &args.router_hosts {
        if !valid_host(h) {
            return Err(LaunchError::Invalid(anyhow!(
                "invalid `--router-host` = {h:?}: {HOST_RULE}"
            )));
        }
        hosts.extend(Host::router_host(h));
    }
    if !args.router_endpoint.starts_with("tls/") {
        return Err(LaunchError::Invalid(anyhow!(
            "invalid `--router-endpoint` = {:?}: must be a tls/HOST:PORT endpoint",
            args.router_endpoint
        )));
    }
    let manifest = generate(&keys, &args.out, &hosts, &args.router_endpoint, &args.extra)
        .map_err(LaunchError::Failed)?;
    Ok(Written { manifest, hosts })
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

/// The certificate parameters of `node` of `robot` (its common name, a TLS client and server
/// key), validity left to the caller. Its subjectAltName: the sessions that are dialled name
/// their host, `localhost` and `127.0.0.1` for the router, the plant and the recorder, and each
/// of `hosts` for its node.
fn node_params(robot: &str, node: &str, hosts: &[Host]) -> anyhow::Result<CertificateParams> {
    let mut sans: Vec<String> = Vec::new();
    // The certificates of the sessions that are dialled name their host: the nodes dial
    // the router, the controller and the recorder dial the plant (the direct loop), the
    // controller dials the recorder ([`RECORDER`]), and each checks the name. On one host
    // that is the loopback host; `--host` adds the others ("Three hosts" in the README).
    if node == "router" || node == "plant" || node == RECORDER {
        sans.extend(["localhost".to_owned(), "127.0.0.1".to_owned()]);
    }
    for h in hosts.iter().filter(|h| h.node == node) {
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
    Ok(p)
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
        let mut p = node_params(robot, node, hosts)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::DIRECT;
    use std::path::Path;

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
}
