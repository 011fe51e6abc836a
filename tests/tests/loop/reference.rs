//! A controller started after the planner published its reference still gets it (from the
//! planner's queryable on the reference key), and a reference published later replaces it.
//! The test plays the planner and the plant.

use std::f64::consts::FRAC_PI_2;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tilting_controller::{ComputedTorque, ControlConfig, LawSpec};
use tilting_plant::{Mode, State};
use tilting_proto::{codec, PlantState, Reference, TorqueCommand};
use tilting_tests::*;

/// The law the controller must use for the planner's reference `r`.
fn law(r: &Reference) -> ComputedTorque {
    ComputedTorque::new(ControlConfig {
        law: LawSpec {
            law: tilting_controller::LawKind::ComputedTorque,
            kp: r.kp,
            kd: r.kd,
            k: r.k,
            energy_avg: r.energy_avg,
            reference: if r.kind == Reference::SINUSOID {
                tilting_controller::Trajectory::Sinusoid {
                    amplitude: r.amplitude,
                    omega: r.omega,
                }
            } else {
                tilting_controller::Trajectory::Hold
            },
            torque_limit: (r.torque_limit > 0.0).then_some(r.torque_limit),
            orbit_peak: None,
            orbit_start: None,
            orbit_steepness: None,
        },
        ..ControlConfig::default()
    })
    .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn controller_started_after_the_planner_receives_the_reference() {
    let _turn = realtime_turn();
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("reference");
    let port = free_port();
    let robot = robot("reference");

    // The planner: publishes its reference (nobody listens yet), answers queries on the same key
    // with the latest one, and declares its liveliness token.
    let planner = Client::open(&robot, Some(port), None).await;
    let first = Reference {
        kind: Reference::SINUSOID,
        amplitude: 0.2,
        omega: 4.0,
        kp: 60.0,
        kd: 12.0,
        k: 0.0,
        energy_avg: 0.0,
        torque_limit: 0.0,
    };
    let latest = Arc::new(Mutex::new(first));
    let key = planner.keys.planner_reference().to_owned();
    planner
        .session
        .put(key.clone(), codec::encode(&first))
        .await
        .unwrap();
    let l = latest.clone();
    let _queryable = planner
        .session
        .declare_queryable(key.clone())
        .callback(move |q| {
            let r = *l.lock().unwrap();
            let _ = zenoh::Wait::wait(q.reply(q.key_expr().clone(), codec::encode(&r)));
        })
        .await
        .unwrap();
    let _token = planner
        .session
        .liveliness()
        .declare_token(planner.keys.alive_planner().to_owned())
        .await
        .unwrap();

    // The controller starts afterwards, connecting to the planner.
    let mut ctl = Proc::spawn(
        "controller",
        &ctl_bin,
        &peer_args(&robot, port, &[]),
        dir.path(),
    );

    // The test plays the plant: sends a state until the answer comes.
    let answers: Arc<Mutex<Vec<TorqueCommand>>> = Arc::default();
    let a = answers.clone();
    let _torques = planner
        .session
        .declare_subscriber(planner.keys.controller_torque().to_owned())
        .callback(move |s| {
            if let Ok(t) = tilting_proto::decode::<TorqueCommand>(&s.payload().to_bytes()) {
                a.lock().unwrap().push(t);
            }
        })
        .await
        .unwrap();
    let state_pub = planner
        .session
        .declare_publisher(planner.keys.plant_state().to_owned())
        .await
        .unwrap();
    let x = State::new(0.0, FRAC_PI_2 + 0.1, 0.0, -0.3);
    let ask = |seq: u64| {
        let s = PlantState {
            seq,
            time: 0.3,
            alpha: x[0],
            beta: x[1],
            alpha_dot: Some(x[2]),
            beta_dot: Some(x[3]),
            mode: 0,
        };
        codec::encode(&s)
    };
    let answer = |seq: u64| {
        answers
            .lock()
            .unwrap()
            .iter()
            .find(|t| t.seq == seq)
            .copied()
    };
    let flags_law = ComputedTorque::new(ControlConfig {
        law: LawSpec {
            k: 500.0,
            energy_avg: 19.963439703027,
            ..LawSpec::without_adaptation()
        },
        ..ControlConfig::default()
    })
    .unwrap();
    let want_first = law(&first).torque(0.3, Mode::Flat, &x);
    assert_ne!(want_first, flags_law.torque(0.3, Mode::Flat, &x));

    // Ask until the controller answers with the planner's law (it may answer with the law of
    // its flags before its query returns).
    let mut seq = 0;
    let got = loop {
        seq += 1;
        assert!(
            seq < 200,
            "no answer with the planner's law\n{}",
            ctl.logs()
        );
        state_pub.put(ask(seq)).await.unwrap();
        tokio::time::sleep(Duration::from_millis(50)).await;
        if let Some(t) = answer(seq) {
            if t.tau == want_first {
                break t;
            }
        }
    };
    eprintln!(
        "late controller answered with the planner's law at seq {}",
        got.seq
    );

    // A newer reference published on the topic replaces it.
    let second = Reference {
        kind: Reference::HOLD,
        kp: 30.0,
        kd: 9.0,
        torque_limit: 5.0,
        ..first
    };
    *latest.lock().unwrap() = second;
    planner
        .session
        .put(key.clone(), codec::encode(&second))
        .await
        .unwrap();
    let want_second = law(&second).torque(0.3, Mode::Flat, &x);
    assert_ne!(want_second, want_first);
    let got = loop {
        seq += 1;
        assert!(
            seq < 400,
            "the new reference was not applied\n{}",
            ctl.logs()
        );
        state_pub.put(ask(seq)).await.unwrap();
        tokio::time::sleep(Duration::from_millis(50)).await;
        if let Some(t) = answer(seq) {
            if t.tau == want_second {
                break t;
            }
        }
    };
    assert!(got.tau.abs() <= 5.0);

    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );
    let c = ctl.controller_summary();
    eprintln!("controller summary: {c:?}");
    assert!(c.references_applied >= 2);
    assert_eq!(c.references_dropped, 0);
    assert_eq!(c.law.kp, 30.0);
    assert_eq!(c.law.torque_limit, Some(5.0));
    assert_eq!(c.law.reference, tilting_controller::Trajectory::Hold);
}

/// A reference from a peer while no planner holds the planner's liveliness token is not
/// applied, even when it is a valid message with a plausible law; a law that decodes but lies
/// (`k = 1e12`) is refused by the bounds even with a planner present.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn references_need_a_planner_and_plausible_gains() {
    let _turn = realtime_turn();
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("rogue-reference");
    let port = free_port();
    let robot = robot("rogue_reference");
    let rogue = Client::open(&robot, Some(port), None).await;
    let mut ctl = Proc::spawn(
        "controller",
        &ctl_bin,
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    let key = rogue.keys.planner_reference().to_owned();
    let plausible = Reference {
        kind: Reference::HOLD,
        amplitude: 0.0,
        omega: 0.0,
        kp: 30.0,
        kd: 8.0,
        k: 0.0,
        energy_avg: 0.0,
        torque_limit: 0.0,
    };
    // No planner token: 20 puts over 2 s (the controller connects within the first second).
    for _ in 0..20 {
        rogue
            .session
            .put(key.clone(), codec::encode(&plausible))
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    // With a token, a lying law is refused by the bounds; a plausible one is applied.
    let _token = rogue
        .session
        .liveliness()
        .declare_token(rogue.keys.alive_planner().to_owned())
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let lie = Reference {
        k: 1e12,
        energy_avg: 20.0,
        ..plausible
    };
    for r in [
        lie,
        Reference {
            kp: 40.0,
            ..plausible
        },
    ] {
        rogue
            .session
            .put(key.clone(), codec::encode(&r))
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );
    let c = ctl.controller_summary();
    eprintln!("controller summary: {c:?}");
    assert!(c.references_received >= 11, "{c:?}");
    // Ignored while no token (at least the 10 puts of the second second) plus the lie.
    assert!(c.references_rejected >= 11, "{c:?}");
    assert_eq!(
        c.references_applied, 1,
        "only the plausible law under a planner: {c:?}"
    );
    assert_eq!(c.law.kp, 40.0, "{c:?}");
    assert_eq!(c.law.k, 0.0, "the reference carries k too: {c:?}");
}
