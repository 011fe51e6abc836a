//! The robot's imperfections in the plant node (`tilting_plant::imperfect`): in lockstep the
//! plant with sensor noise, an encoder, a saturating and lagging actuator, a heavier arm and an
//! impaired network equals `tilting simulate` with the same flags bit for bit; in real time it
//! publishes the measured state (the true state plus noise of the given deviation) while it
//! integrates the true one.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tilting_proto::PlantState;
use tilting_tests::recording::parse_csv;
use tilting_tests::*;

const IMPERFECT: [&str; 18] = [
    "--noise-alpha",
    "0.0002",
    "--noise-beta",
    "0.0005",
    "--noise-alpha-dot",
    "0.002",
    "--noise-beta-dot",
    "0.005",
    "--encoder-counts",
    "16384",
    "--torque-saturation",
    "11",
    "--torque-lag",
    "0.002",
    "--mass-error",
    "0.05",
    "--seed",
    "13",
];

fn simulate_final(extra: &[&str]) -> SimulationReport {
    let mut args = vec!["--control-period", "0.001", "--duration", "2"];
    args.extend(extra);
    simulate_json(&args)
}

/// Lockstep plant with every imperfection and a lossy, delayed link against `simulate` with the
/// same flags: the same final state bit for bit and the same network counters (one sensor, one
/// actuator, one hold: the same code in both). The imperfections act: the perfect run ends
/// elsewhere.
#[test]
fn lockstep_with_imperfections_equals_simulate_with_the_same_flags() {
    let mut flags: Vec<&str> = IMPERFECT.to_vec();
    flags.extend(["--torque-delay", "0.001", "--loss", "0.02"]);
    let dir = Scratch::new("lockstep-imperfect");
    let mut extra = vec!["--clock", "lockstep", "--duration", "2"];
    extra.extend(&flags);
    let (summary, _) = run_loop(dir.path(), &robot("lockimp"), free_port(), &extra, &[]);
    assert_eq!(summary.result, RunResult::Completed, "{summary:?}");
    assert_eq!(summary.time, 2.0);

    let want = simulate_final(&flags);
    assert!(want.imperfections.is_some(), "{want:?}");
    let want_x = want.final_state.x;
    for (i, (g, w)) in summary.x.iter().zip(&want_x).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "component {i}: {g} vs {w}");
    }
    assert!(want.network.is_some());
    assert_eq!(summary.network, want.network);

    let perfect_x = simulate_final(&["--torque-delay", "0.001", "--loss", "0.02"])
        .final_state
        .x;
    let d = perfect_x
        .iter()
        .zip(&want_x)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        d > 1e-4,
        "the imperfections changed the final state by {d} only"
    );
}

/// `--measure angles` (the angles only, the controller estimating the rates with its hybrid
/// observer) with noise, an encoder, a heavier arm and a delayed link: the lockstep plant
/// and its controller node equal `simulate --measure angles` with the same flags bit for bit
/// (the same estimator code runs in both). The controller reports that it estimated every
/// state, and the run differs from the one with measured rates.
#[test]
fn lockstep_measuring_angles_equals_simulate_with_the_same_flags() {
    let mut flags = MEASURED_AS_HARDWARE.to_vec();
    flags.extend([
        "--mass-error",
        "0.05",
        "--seed",
        "5",
        "--torque-delay",
        "0.001",
    ]);
    // No loss: in lockstep the controller still sees (and estimates from) a state the
    // emulated link loses, which `simulate`'s controller never sees.
    let dir = Scratch::new("lockstep-angles");
    let mut extra = vec!["--clock", "lockstep", "--duration", "2"];
    extra.extend(&flags);
    let (summary, ctl) = run_loop(dir.path(), &robot("lockang"), free_port(), &extra, &[]);
    assert_eq!(summary.result, RunResult::Completed, "{summary:?}");
    let want = simulate_final(&flags);
    assert_eq!(want.fault, None);
    for (i, (g, w)) in summary.x.iter().zip(&want.final_state.x).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "component {i}: {g} vs {w}");
    }
    assert_eq!(summary.network, want.network);
    let est = ctl.estimation.expect("the controller estimated");
    assert_eq!(est.method, tilting_controller::estimate::Method::Observer);
    assert!(est.estimates >= 1900, "{est:?}");
    let full = simulate_final(&flags[2..]).final_state.x;
    assert_ne!(full, want.final_state.x);
}

/// Real time, noise on `beta` (sigma 2 mrad) and `alpha_dot` (sigma 20 mrad/s) only: the
/// published state minus the true one (the plant's `--record` CSV, same `seq`) has mean 0 and
/// deviation sigma within 3 standard errors (sigma / sqrt(n) and sigma / sqrt(2 n)), and the
/// quantities without noise are published exactly.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn realtime_plant_publishes_the_measured_state() {
    let sigma_b = 0.002;
    let sigma_ad = 0.02;
    let dir = Scratch::new("realtime-imperfect");
    let port = free_port();
    let robot = robot("rtimp");
    let csv = dir.path().join("plant.csv");
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(
            &robot,
            port,
            &[
                "--duration",
                "3",
                "--noise-beta",
                &sigma_b.to_string(),
                "--noise-alpha-dot",
                &sigma_ad.to_string(),
                "--seed",
                "4",
                "--record",
                csv.to_str().unwrap(),
            ],
        ),
        dir.path(),
    );
    let client = Client::open(&robot, None, Some(port)).await;
    let seen: Arc<Mutex<HashMap<u64, PlantState>>> = Arc::default();
    let s2 = seen.clone();
    let _sub = client
        .session
        .declare_subscriber(client.keys.plant_state().to_owned())
        .callback(move |s| {
            if let Ok(m) = tilting_proto::decode::<PlantState>(&s.payload().to_bytes()) {
                let mut map = s2.lock().unwrap();
                if let Some(old) = map.get(&m.seq) {
                    // A re-publication of the same sample carries the same measurement.
                    assert_eq!(old.beta.to_bits(), m.beta.to_bits());
                }
                map.insert(m.seq, m);
            }
        })
        .await
        .unwrap();
    // Let the subscription reach the plant before a controller starts the clock.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    let (exit, plant) = tokio::task::spawn_blocking(move || {
        let s = plant.expect_exit(Duration::from_secs(40));
        (s, plant)
    })
    .await
    .unwrap();
    assert!(exit.success(), "plant: {exit}\n{}", plant.logs());
    assert!(ctl.interrupt(Duration::from_secs(10)).success());
    tokio::time::sleep(Duration::from_millis(200)).await;

    let rows = parse_csv(&std::fs::read_to_string(&csv).unwrap());
    let seen = seen.lock().unwrap();
    let mut db = Vec::new();
    let mut dad = Vec::new();
    for r in &rows {
        let Some(m) = seen.get(&r.seq) else { continue };
        assert_eq!(m.time, r.t);
        assert_eq!(
            m.alpha.to_bits(),
            r.x[0].to_bits(),
            "alpha at seq {}",
            r.seq
        );
        assert_eq!(
            m.beta_dot.expect("a full state").to_bits(),
            r.x[3].to_bits(),
            "beta_dot at {}",
            r.seq
        );
        db.push(m.beta - r.x[1]);
        dad.push(m.alpha_dot.expect("a full state") - r.x[2]);
    }
    let n = db.len() as f64;
    assert!(n > 2000.0, "{n} states matched of {} rows", rows.len());
    for (d, sigma, what) in [(&db, sigma_b, "beta"), (&dad, sigma_ad, "alpha_dot")] {
        let mean = d.iter().sum::<f64>() / n;
        let sd = (d.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        eprintln!("{what}: {n} samples, mean {mean:e}, sd {sd:e} (sigma {sigma:e})");
        assert!(mean.abs() < 3.0 * sigma / n.sqrt(), "{what}: mean {mean}");
        assert!(
            (sd - sigma).abs() < 3.0 * sigma / (2.0 * n).sqrt(),
            "{what}: sd {sd} against {sigma}"
        );
    }
}
