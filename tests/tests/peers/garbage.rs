//! Garbage on every topic: random bytes, payloads one byte short or long, NaN in a float
//! field, an out-of-range enumeration, valid torques answering no current state. Everything is
//! dropped and counted, logged at a bounded rate, and nothing crashes or moves the plant.

use std::time::Duration;
use tilting_proto::{codec, PlantState, Reference, Status, TorqueCommand};
use tilting_tests::*;

/// A small deterministic generator (xorshift64*), so a failure reproduces.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.next() as u8).collect()
    }
}

/// Invalid payloads for a fixed-size message of `size` bytes whose valid encoding is `valid`,
/// with a float at `float_at`: random lengths, size ± 1, NaN/inf in the float.
fn garbage(rng: &mut Rng, size: usize, valid: &[u8], float_at: usize) -> Vec<Vec<u8>> {
    let mut v = Vec::new();
    for _ in 0..40 {
        let mut n = (rng.next() % 200) as usize;
        if n == size {
            n += 1;
        }
        v.push(rng.bytes(n));
    }
    v.push(Vec::new());
    v.push(rng.bytes(size - 1));
    v.push(rng.bytes(size + 1));
    let mut short = valid.to_vec();
    short.pop();
    v.push(short);
    let mut long = valid.to_vec();
    long.push(0);
    v.push(long);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut b = valid.to_vec();
        b[float_at..float_at + 8].copy_from_slice(&bad.to_le_bytes());
        v.push(b);
    }
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn invalid_payloads_are_dropped_and_counted_and_nothing_crashes() {
    let _turn = realtime_turn();
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("garbage");
    let port = free_port();
    let robot = robot("garbage");
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(&robot, port, &[]),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let status = StatusWatch::new(&client).await;
    let mut ctl = Proc::spawn(
        "controller",
        &ctl_bin,
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    status
        .wait_for(Duration::from_secs(15), |s| {
            s.state == Status::RUNNING && s.steps > 300
        })
        .await
        .unwrap_or_else(|| panic!("never running\n{}\n{}", plant.logs(), ctl.logs()));

    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let torque = codec::encode(&TorqueCommand { seq: 1, tau: 0.5 });
    let state = codec::encode(&PlantState {
        seq: 1,
        time: 0.1,
        alpha: 0.0,
        beta: 1.5,
        alpha_dot: Some(0.0),
        beta_dot: Some(0.0),
        mode: 0,
    });
    let reference = codec::encode(&Reference {
        kind: Reference::HOLD,
        amplitude: 0.0,
        omega: 1.0,
        kp: 100.0,
        kd: 14.14,
        k: 0.0,
        energy_avg: 0.0,
        torque_limit: 0.0,
    });
    let mut bad_torque = garbage(&mut rng, TorqueCommand::SIZE, &torque, 8);
    let mut bad_state = garbage(&mut rng, PlantState::SIZE, &state, 16);
    // PlantState: mode 3.
    let mut m3 = state.clone();
    m3[48] = 3;
    bad_state.push(m3);
    // Valid encodings of physically absurd torques: beyond the plant's --max-torque bound
    // (default 10 x the largest torque of the paper's orbit, 116.5 N m).
    for tau in [1e9, -1e9, 117.0] {
        bad_torque.push(codec::encode(&TorqueCommand { seq: 1, tau }));
    }
    let mut bad_reference = garbage(&mut rng, Reference::SIZE, &reference, 17);
    // Reference: the first kind past the known ones (hold, sinusoid, excitation).
    let mut k2 = reference.clone();
    k2[0] = Reference::EXCITATION + 1;
    bad_reference.push(k2);
    // Repeat the lot to make a flood (all invalid).
    for v in [&mut bad_torque, &mut bad_state, &mut bad_reference] {
        let copy = v.clone();
        for _ in 0..4 {
            v.extend(copy.iter().cloned());
        }
    }
    // Valid, plausible torques answering no current state (a far future seq): stale. (A huge
    // torque is refused before its seq is looked at: see the absurd ones above.)
    let stale: Vec<Vec<u8>> = (0..100)
        .map(|i| {
            codec::encode(&TorqueCommand {
                seq: 1 << 40 | i,
                tau: 1.0,
            })
        })
        .collect();

    let put = |key: &str, payloads: &[Vec<u8>]| {
        let key = key.to_owned();
        let payloads = payloads.to_vec();
        let session = client.session.clone();
        async move {
            let publisher = session.declare_publisher(key).await.unwrap();
            for p in &payloads {
                publisher.put(p.clone()).await.unwrap();
            }
        }
    };
    let before = status.latest().unwrap();
    put(client.keys.controller_torque(), &bad_torque).await;
    put(client.keys.controller_torque(), &stale).await;
    put(client.keys.plant_state(), &bad_state).await;
    put(client.keys.planner_reference(), &bad_reference).await;
    // Nobody of ours subscribes to these, but any peer may: garbage there must not matter.
    let junk: Vec<Vec<u8>> = (0..50).map(|i| rng.bytes(i * 7)).collect();
    put(client.keys.plant_event(), &junk).await;
    put(client.keys.plant_status(), &junk).await;

    // The counters show every invalid torque, and the stale ones.
    let want = before.torques_dropped + bad_torque.len() as u64;
    let (_, s) = status
        .wait_for(Duration::from_secs(5), |s| s.torques_dropped >= want)
        .await
        .unwrap_or_else(|| {
            panic!(
                "torques_dropped never reached {want}: {:?}",
                status.latest()
            )
        });
    assert_eq!(s.torques_dropped, want, "exactly the invalid ones");
    assert!(s.torques_stale >= before.torques_stale + stale.len() as u64);
    assert_eq!(s.fault, "");

    // Both nodes are alive and the loop still runs (no safe mode: the real answers still win).
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert!(plant.try_wait().is_none(), "{}", plant.logs());
    assert!(ctl.try_wait().is_none(), "{}", ctl.logs());
    let s = status.latest().unwrap();
    assert_eq!(s.state, Status::RUNNING, "{s:?}");
    assert_eq!(s.watchdog_trips, 0, "{s:?}");

    // The controller counted its share.
    assert!(
        ctl.interrupt(Duration::from_secs(10)).success(),
        "{}",
        ctl.logs()
    );
    let c = ctl.controller_summary();
    eprintln!("controller summary: {c:?}");
    assert_eq!(c.states_dropped, bad_state.len() as u64);
    assert_eq!(c.references_dropped, bad_reference.len() as u64);
    assert_eq!(c.references_applied, 0);
    assert_eq!(c.torques_not_finite, 0);
    // Logged at a bounded rate: a flood of hundreds gives a handful of lines.
    let lines = ctl
        .stderr()
        .lines()
        .filter(|l| l.contains("dropped"))
        .count();
    assert!(
        (1..=6).contains(&lines),
        "{lines} drop log lines\n{}",
        ctl.stderr()
    );

    let exit = plant.interrupt(Duration::from_secs(10));
    assert!(exit.success(), "{}", plant.logs());
    let p = plant.plant_summary();
    eprintln!("plant summary: {p:?}");
    assert_eq!(p.torques_dropped, want);
    let lines = plant
        .stderr()
        .lines()
        .filter(|l| l.contains("dropped"))
        .count();
    assert!(
        (1..=6).contains(&lines),
        "{lines} drop log lines\n{}",
        plant.stderr()
    );
}
