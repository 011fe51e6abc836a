//! `--secure`: mutual TLS and the router's access control. The plant and the controller run as
//! clients of a `tilting-router` (certificates and configurations of `tilting certs`), and
//! peers with a valid certificate but the wrong identity try to move the robot: the logger's
//! identity (may only listen) and a `rogue` identity signed by the same CA (may do nothing).
//! Their torques, states and references must not be delivered, which the plant's and the
//! controller's counters show; the same payloads sent with the right identity (a stolen key)
//! are delivered, so the counters could show it.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tilting_proto::{codec, Keys, Reference, TorqueCommand};
use tilting_tests::*;
use zenoh::qos::CongestionControl;

/// Payloads that never decode: a delivered one is counted as dropped by its receiver.
const GARBAGE: &[u8] = &[1, 2, 3];

async fn counting_subscriber(
    c: &Client,
    key: &str,
) -> (Arc<AtomicU64>, zenoh::pubsub::Subscriber<()>) {
    let n = Arc::new(AtomicU64::new(0));
    let m = n.clone();
    let sub = c
        .session
        .declare_subscriber(key.to_owned())
        .callback(move |_| {
            m.fetch_add(1, Ordering::Relaxed);
        })
        .await
        .unwrap();
    (n, sub)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wrong_identity_cannot_move_the_robot() {
    let _turn = realtime_turn();
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("secure");
    let robot = robot("secure");
    let keys = Keys::new(&robot).unwrap();
    let certs = dir.path().join("certs");
    tilting::security::generate(&keys, &certs, &[], "tls/127.0.0.1:7447", &["rogue".into()])
        .expect("certificates");
    let ep = format!("tls/127.0.0.1:{}", free_port());
    let mut router = start_router(dir.path(), &certs, &ep);
    let cfg = |node: &str| certs.join(format!("{node}.json5")).display().to_string();

    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &[
            "--robot",
            &robot,
            "--zenoh-config",
            &cfg("plant"),
            "--connect",
            &ep,
            "--duration",
            "3",
        ]
        .map(String::from),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &ctl_bin,
        &[
            "--robot",
            &robot,
            "--zenoh-config",
            &cfg("controller"),
            "--connect",
            &ep,
        ]
        .map(String::from),
        dir.path(),
    );

    // The logger's identity may listen (it receives states) but not publish; `rogue` may do
    // neither.
    let logger = Client::open_config(&robot, &certs.join("logger.json5"), &ep).await;
    let rogue = Client::open_config(&robot, &certs.join("rogue.json5"), &ep).await;
    let (logger_states, _s1) = counting_subscriber(&logger, keys.plant_state()).await;
    let (rogue_states, _s2) = counting_subscriber(&rogue, keys.plant_state()).await;

    // Wait for the loop to run (the logger sees states).
    let running = poll_until(Duration::from_secs(10), || {
        (logger_states.load(Ordering::Relaxed) > 100).then_some(())
    })
    .await;
    assert!(
        running.is_some(),
        "the loop did not start\n{}\n{}\n{}",
        router.logs(),
        plant.logs(),
        ctl.logs()
    );

    // Counted before the puts below: a session gets its own puts too.
    let rogue_heard = rogue_states.load(Ordering::Relaxed);

    for c in [&logger, &rogue] {
        attack(c).await;
    }

    // The same garbage with the right identity (a stolen key) is delivered: 5 torques, 7 states
    // (blocking, so that none is dropped on a congested queue).
    let stolen_ctl = Client::open_config(&robot, &certs.join("controller.json5"), &ep).await;
    let stolen_plant = Client::open_config(&robot, &certs.join("plant.json5"), &ep).await;
    for _ in 0..5 {
        stolen_ctl
            .session
            .put(keys.controller_torque().to_owned(), GARBAGE.to_vec())
            .congestion_control(CongestionControl::Block)
            .await
            .unwrap();
    }
    for _ in 0..7 {
        stolen_plant
            .session
            .put(keys.plant_state().to_owned(), GARBAGE.to_vec())
            .congestion_control(CongestionControl::Block)
            .await
            .unwrap();
    }

    let s = plant.expect_exit(Duration::from_secs(20));
    assert!(s.success(), "plant: {s}\n{}", plant.logs());
    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );
    let p = plant.plant_summary();
    let c = ctl.controller_summary();
    eprintln!("plant: {p:?}\ncontroller: {c:?}");
    eprintln!(
        "logger received {} states, rogue {rogue_heard} (before its own puts)",
        logger_states.load(Ordering::Relaxed),
    );
    // The loop ran over TLS through the router.
    assert!(p.steps >= 2900, "{p:?}");
    assert!(p.torques_received > 1000, "{p:?}");
    assert!(p.fault.is_none(), "{p:?}");
    // Exactly the stolen key's garbage arrived; none of the 600 rogue torques, 200 states, 200
    // references.
    assert_eq!(p.torques_dropped, 5, "{p:?}");
    assert_eq!(c.states_dropped, 7, "{c:?}");
    assert_eq!(c.references_received, 0, "{c:?}");
    assert_eq!(c.references_applied, 0, "{c:?}");
    // Listening needs an identity of the robot's nodes.
    assert!(logger_states.load(Ordering::Relaxed) > 1000);
    assert_eq!(rogue_heard, 0);
    router.signal(libc::SIGINT);
    assert!(
        router.expect_exit(Duration::from_secs(10)).success(),
        "{}",
        router.logs()
    );
}

/// Sends 100 rounds of garbage, 1e9 N m, plausible torques, garbage states and a lying
/// reference from `c`, and tries to declare the planner's token.
async fn attack(c: &Client) {
    let huge = codec::encode(&TorqueCommand { seq: 0, tau: 1e9 });
    let lie = codec::encode(&Reference {
        kind: Reference::HOLD,
        amplitude: 0.0,
        omega: 0.0,
        kp: 30.0,
        kd: 8.0,
        k: 0.0,
        energy_avg: 0.0,
        torque_limit: 0.0,
    });
    let k = &c.keys;
    for i in 0..100u64 {
        let t = codec::encode(&TorqueCommand {
            seq: 500 + i,
            tau: 12.345,
        });
        for (key, payload) in [
            (k.controller_torque(), GARBAGE),
            (k.controller_torque(), &huge[..]),
            (k.controller_torque(), &t[..]),
            (k.plant_state(), GARBAGE),
            (k.planner_reference(), &lie[..]),
        ] {
            c.session
                .put(key.to_owned(), payload.to_vec())
                .await
                .unwrap();
        }
    }
    let _ = c
        .session
        .liveliness()
        .declare_token(c.keys.alive_planner().to_owned())
        .await;
}

/// The direct loop of `tilting live --secure`: the plant (`plant-direct.json5`) listens on its
/// own TLS endpoint and the controller (`controller-direct.json5`) dials it, both also
/// connected to the router; each enforces its own ingress rules (`security::node_acl`). The
/// logger's and a `rogue` identity attack both ways in: directly at the plant's endpoint (where
/// only the plant's rules judge them) and through the router. Nothing of theirs reaches the
/// plant or the controller. A stolen controller key dialling the plant is delivered (5 garbage
/// torques, so the counter could show it); a stolen plant key can reach the controller only
/// through the router, whose copies of plant topics the controller refuses (0 delivered).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_wrong_identity_cannot_move_the_robot_over_the_direct_loop() {
    let _turn = realtime_turn();
    let dir = Scratch::new("secure-direct");
    let robot = robot("secure_direct");
    let keys = Keys::new(&robot).unwrap();
    let certs = dir.path().join("certs");
    tilting::security::generate(&keys, &certs, &[], "tls/127.0.0.1:7447", &["rogue".into()])
        .expect("certificates");
    let ep = format!("tls/127.0.0.1:{}", free_port());
    let plant_ep = format!("tls/127.0.0.1:{}", free_port());
    let mut router = start_router(dir.path(), &certs, &ep);
    let file = |name: &str| certs.join(name).display().to_string();
    let flags = |node: &str, extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = vec![
            "--robot".into(),
            robot.clone(),
            "--zenoh-config".into(),
            file(&format!("{node}-direct.json5")),
        ];
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &flags(
            "plant",
            &["--listen", &plant_ep, "--connect", &ep, "--duration", "3"],
        ),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &flags("controller", &["--connect", &plant_ep, "--connect", &ep]),
        dir.path(),
    );
    let logger = Client::open_config(&robot, &certs.join("logger.json5"), &ep).await;
    let (logger_states, _s1) = counting_subscriber(&logger, keys.plant_state()).await;
    let running = poll_until(Duration::from_secs(10), || {
        (logger_states.load(Ordering::Relaxed) > 100).then_some(())
    })
    .await;
    assert!(
        running.is_some(),
        "the loop did not start\n{}\n{}\n{}",
        router.logs(),
        plant.logs(),
        ctl.logs()
    );
    for node in ["logger", "rogue"] {
        for at in [&plant_ep, &ep] {
            let c = Client::open_config(&robot, &certs.join(format!("{node}.json5")), at).await;
            attack(&c).await;
        }
    }
    let stolen_ctl =
        Client::open_config(&robot, &certs.join("controller-direct.json5"), &plant_ep).await;
    let stolen_plant = Client::open_config(&robot, &certs.join("plant.json5"), &ep).await;
    for (c, key, n) in [
        (&stolen_ctl, keys.controller_torque(), 5),
        (&stolen_plant, keys.plant_state(), 7),
    ] {
        for _ in 0..n {
            c.session
                .put(key.to_owned(), GARBAGE.to_vec())
                .congestion_control(CongestionControl::Block)
                .await
                .unwrap();
        }
    }

    let s = plant.expect_exit(Duration::from_secs(20));
    assert!(s.success(), "plant: {s}\n{}", plant.logs());
    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );
    let p = plant.plant_summary();
    let c = ctl.controller_summary();
    eprintln!("plant: {p:?}\ncontroller: {c:?}");
    assert!(p.steps >= 2900, "{p:?}");
    assert!(p.torques_received > 1000, "{p:?}");
    assert!(p.fault.is_none(), "{p:?}");
    assert_eq!(p.watchdog_trips, 0, "{p:?}");
    assert_eq!(p.torques_dropped, 5, "{p:?}");
    assert_eq!(c.states_dropped, 0, "{c:?}");
    assert_eq!(c.references_received, 0, "{c:?}");
    router.signal(libc::SIGINT);
    assert!(
        router.expect_exit(Duration::from_secs(10)).success(),
        "{}",
        router.logs()
    );
}
