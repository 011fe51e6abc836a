//! The deployed topology on one machine: plant, controller and planner each in its own
//! network namespace (a network stack of its own), joined by veth pairs to a fourth namespace
//! that runs the `tilting-router` with TLS and access control and routes between the others.
//! The nodes start with the flags `tilting live --secure` gives its own
//! (`tilting::security::session_flags`): the controller dials the plant's own TLS endpoint
//! across the namespaces (the direct loop, each end with its own access control), and both,
//! and the planner, are clients or peers of the router. A fifth namespace holds a rogue with
//! valid certificates of the wrong identities: a controller with the logger's certificate that
//! dials the plant's own endpoint, and a planner with a `rogue` certificate, a client of the
//! router.
//!
//! The test proves that the loop runs across the namespaces, and that the rogue's torques and
//! reference are not delivered: the plant received no more torques than the real controller
//! published, and the controller applied the real planner's law only.
//!
//! It needs root and iproute2's `ip`; otherwise it prints `SKIP` and passes. It creates its
//! namespaces (`tlt{pid}{r,p,c,n,x}`) and removes them, also when it fails.

use std::process::Command;
use std::time::Duration;
use tilting_proto::Keys;
use tilting_tests::*;

/// The namespaces of one test; deleted on drop.
struct Namespaces(Vec<String>);

impl Drop for Namespaces {
    fn drop(&mut self) {
        for ns in &self.0 {
            let _ = Command::new("ip").args(["netns", "del", ns]).status();
        }
    }
}

fn ip(args: &[&str]) {
    let out = Command::new("ip").args(args).output().expect("run ip");
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Waits until something in namespace `ns` listens on TCP `port` (iproute2's `ss`), at most
/// `timeout`. A zenoh client exits at once when its endpoint refuses the connection, so the
/// rogue controller (a client that dials the plant's own endpoint) starts only after this.
fn wait_listening(ns: &str, port: u16, timeout: Duration) -> bool {
    let end = std::time::Instant::now() + timeout;
    while std::time::Instant::now() < end {
        let out = Command::new("ip")
            .args(["netns", "exec", ns, "ss", "-Hltn"])
            .arg(format!("sport = :{port}"))
            .output();
        if matches!(&out, Ok(o) if o.status.success() && !o.stdout.trim_ascii().is_empty()) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

fn skip_reason() -> Option<String> {
    // SAFETY: geteuid(2) has no preconditions.
    if unsafe { libc::geteuid() } != 0 {
        return Some("not root".into());
    }
    for tool in ["ip", "ss"] {
        match Command::new(tool).arg("-V").output() {
            Ok(o) if o.status.success() => {}
            _ => return Some(format!("iproute2's `{tool}` is missing")),
        }
    }
    None
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_namespaces_through_a_secure_router() {
    let _turn = realtime_turn();
    if let Some(why) = skip_reason() {
        skip(
            "three_namespaces_through_a_secure_router",
            Missing::Right,
            &why,
        );
        return;
    }
    let (plant_bin, ctl_bin, planner_bin) = (
        bin("tilting-plant"),
        bin("tilting-controller"),
        bin("tilting-planner"),
    );
    let dir = Scratch::new("netns");
    let robot = robot("netns");
    let keys = Keys::new(&robot).unwrap();
    let pid = std::process::id();
    let name = |s: &str| format!("tlt{pid}{s}");
    let router_ns = name("r");
    let nodes = ["p", "c", "n", "x"]; // plant, controller, planner, rogue
    let all: Vec<String> = std::iter::once(router_ns.clone())
        .chain(nodes.iter().map(|s| name(s)))
        .collect();
    let _guard = Namespaces(all.clone());
    for ns in &all {
        ip(&["netns", "add", ns]);
        ip(&["-n", ns, "link", "set", "lo", "up"]);
    }
    // Link i: 10.77.i.1 in the node's namespace, 10.77.i.2 on the router's side; the router's
    // namespace forwards between the links (the controller reaches the plant through it).
    let mut router_ips = Vec::new();
    for (i, n) in nodes.iter().enumerate() {
        let i = i + 1;
        let (r_if, n_if, ns) = (format!("r{i}"), format!("n{i}"), name(n));
        ip(&[
            "-n", &router_ns, "link", "add", &r_if, "type", "veth", "peer", "name", &n_if, "netns",
            &ns,
        ]);
        ip(&[
            "-n",
            &router_ns,
            "addr",
            "add",
            &format!("10.77.{i}.2/24"),
            "dev",
            &r_if,
        ]);
        ip(&["-n", &router_ns, "link", "set", &r_if, "up"]);
        ip(&[
            "-n",
            &ns,
            "addr",
            "add",
            &format!("10.77.{i}.1/24"),
            "dev",
            &n_if,
        ]);
        ip(&["-n", &ns, "link", "set", &n_if, "up"]);
        ip(&[
            "-n",
            &ns,
            "route",
            "add",
            "default",
            "via",
            &format!("10.77.{i}.2"),
        ]);
        router_ips.push(format!("10.77.{i}.2"));
    }
    ip(&[
        "netns",
        "exec",
        &router_ns,
        "sysctl",
        "-qw",
        "net.ipv4.ip_forward=1",
    ]);
    // The plant's own endpoint (the direct loop), in its namespace: its certificate names it.
    let plant_ep = "tls/10.77.1.1:7448";
    let mut hosts = router_ips.clone();
    hosts.push("10.77.1.1".into());
    let certs = dir.path().join("certs");
    let hosts: Vec<_> = hosts
        .iter()
        .flat_map(|h| tilting::security::Host::router_host(h))
        .collect();
    tilting::security::generate(
        &keys,
        &certs,
        &hosts,
        "tls/10.77.1.2:7447",
        &["rogue".into()],
    )
    .expect("certificates");
    let ep = |i: usize| format!("tls/10.77.{i}.2:7447");
    // The flags of `live --secure`, with this topology's endpoints.
    let flags = |node: &str, router: &str| {
        tilting::security::session_flags(&certs, node, plant_ep, router, None)
    };
    let mut router = start_router_with(
        dir.path(),
        &certs,
        "tls/0.0.0.0:7447",
        &["ip", "netns", "exec", &router_ns],
    );
    let exec = |tag: &str, ns: &str, bin: &std::path::Path, args: &[String]| {
        let mut v: Vec<String> = vec!["netns".into(), "exec".into(), ns.into()];
        v.push(bin.display().to_string());
        v.extend(["--robot".into(), robot.clone()]);
        v.extend(args.iter().cloned());
        Proc::spawn(tag, std::path::Path::new("ip"), &v, dir.path())
    };
    let with = |mut v: Vec<String>, extra: &[&str]| {
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let mut plant = exec(
        "plant",
        &name("p"),
        &plant_bin,
        &with(flags("plant", &ep(1)), &["--duration", "3"]),
    );
    let mut planner = exec(
        "planner",
        &name("n"),
        &planner_bin,
        &with(flags("planner", &ep(3)), &["--torque-limit", "60"]),
    );
    let mut ctl = exec(
        "controller",
        &name("c"),
        &ctl_bin,
        &flags("controller", &ep(2)),
    );
    // The rogue: a controller with the logger's certificate dialling the plant's own endpoint
    // (it may listen, so it answers every state it sees), and a planner with a `rogue`
    // certificate and another law, a client of the router.
    let logger = certs.join("logger.json5").display().to_string();
    assert!(
        wait_listening(&name("p"), 7448, Duration::from_secs(20)),
        "the plant did not listen on {plant_ep}\n{}",
        plant.logs()
    );
    let mut rogue_ctl = exec(
        "rogue-controller",
        &name("x"),
        &ctl_bin,
        &with(
            vec![],
            &[
                "--zenoh-config",
                &logger,
                "--connect",
                plant_ep,
                "--torque-limit",
                "1",
            ],
        ),
    );
    let mut rogue_planner = exec(
        "rogue-planner",
        &name("x"),
        &planner_bin,
        &with(flags("rogue", &ep(4)), &["--torque-limit", "2"]),
    );

    let s = plant.expect_exit(Duration::from_secs(30));
    assert!(
        s.success(),
        "plant: {s}\n{}\n{}",
        plant.logs(),
        router.logs()
    );
    for p in [&mut ctl, &mut rogue_ctl, &mut planner, &mut rogue_planner] {
        let s = p.interrupt(Duration::from_secs(10));
        assert!(s.success(), "{s}\n{}", p.logs());
    }
    let p = plant.plant_summary();
    let c = ctl.controller_summary();
    let r = rogue_ctl.controller_summary();
    eprintln!("plant: {p:?}\ncontroller: {c:?}\nrogue controller: {r:?}");
    // The loop ran across the namespaces, under the real planner's law.
    assert!(p.steps >= 2900 && p.torques_received > 1000, "{p:?}");
    assert!(p.fault.is_none(), "{p:?}");
    assert!(c.references_applied >= 1, "{c:?}");
    assert_eq!(
        c.law.torque_limit,
        Some(60.0),
        "the real planner's law: {c:?}"
    );
    // The rogue controller was connected and active (the logger's identity may listen)...
    assert!(r.states_received > 1000, "{r:?}");
    assert!(r.torques_published > 1000, "{r:?}");
    // ...but none of its torques reached the plant, and the rogue planner's law never reached
    // the controller.
    assert!(
        p.torques_received <= c.torques_published,
        "plant received {} torques, the real controller published {}",
        p.torques_received,
        c.torques_published
    );
    assert_eq!(c.references_rejected, 0, "{c:?}");
    router.signal(libc::SIGINT);
    assert!(
        router.expect_exit(Duration::from_secs(10)).success(),
        "{}",
        router.logs()
    );
}
