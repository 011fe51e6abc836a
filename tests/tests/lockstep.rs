//! A lockstep run over zenoh (plant and controller as separate processes) is the offline
//! sampled-loop simulation: the same samples, torques and final state, bit for bit.

use std::f64::consts::FRAC_PI_2;
use std::time::Duration;
use tilting_controller::{ComputedTorque, ControlConfig};
use tilting_plant::{Mode, Plant, SimConfig, State, Tolerance};
use tilting_tests::*;

const PERIOD: f64 = 0.001;
const DURATION: f64 = 2.0;

/// One CSV row of `--record`: t, mode, alpha, beta, alpha_dot, beta_dot, tau (empty on the last
/// row), seq.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Row {
    t: f64,
    mode: u8,
    x: [f64; 4],
    tau: Option<f64>,
    seq: u64,
}

fn parse_csv(text: &str) -> Vec<Row> {
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("t,mode,alpha,beta,alpha_dot,beta_dot,tau,seq")
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 8, "{l}");
            let p = |s: &str| s.parse::<f64>().unwrap_or_else(|e| panic!("{s}: {e}"));
            Row {
                t: p(f[0]),
                mode: f[1].parse().unwrap(),
                x: [p(f[2]), p(f[3]), p(f[4]), p(f[5])],
                tau: (!f[6].is_empty()).then(|| p(f[6])),
                seq: f[7].parse().unwrap(),
            }
        })
        .collect()
}

/// The offline closed loop: `tau_k = c(t_k, q_k, x_k)` held over `[t_k, t_{k+1}]`, with the
/// plant's settings (`atol = rtol / 100`, as `simulate` and `tilting-plant` use).
fn offline() -> Vec<Row> {
    let rtol = Tolerance::default().rtol;
    let cfg = SimConfig {
        tol: Tolerance {
            rtol,
            atol: rtol * 1e-2,
        },
        ..SimConfig::default()
    };
    let x0 = State::new(0.0, FRAC_PI_2 - 0.000214877415, 0.0, 0.498257789692);
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).unwrap();
    let c = ComputedTorque::new(ControlConfig {
        k: 500.0,
        energy_avg: 19.963439703027,
        ..ControlConfig::default()
    })
    .unwrap();
    let n = (DURATION / PERIOD).round() as u64;
    let mut rows = Vec::new();
    for k in 0..=n {
        let x = plant.state();
        let row = |tau| Row {
            t: plant.time(),
            mode: plant.mode().index(),
            x: [x[0], x[1], x[2], x[3]],
            tau,
            seq: k,
        };
        if k == n {
            rows.push(row(None));
            break;
        }
        let tau = c.torque(plant.time(), plant.mode(), &x);
        rows.push(row(Some(tau)));
        plant
            .advance_held(tau, (k + 1) as f64 * PERIOD, &mut ())
            .unwrap();
    }
    rows
}

#[test]
fn lockstep_run_equals_offline_simulation() {
    let plant_bin = bin("tilting-plant");
    let ctl_bin = bin("tilting-controller");
    let dir = Scratch::new("lockstep");
    let port = free_port();
    let robot = robot("lockstep");
    let csv = dir.path().join("plant.csv");
    let mut plant = Proc::spawn(
        "plant",
        &plant_bin,
        &plant_args(
            &robot,
            port,
            &[
                "--clock",
                "lockstep",
                "--duration",
                "2",
                "--record",
                csv.to_str().unwrap(),
            ],
        ),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &ctl_bin,
        &peer_args(&robot, port, &[]),
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "plant: {status}\n{}", plant.logs());
    let summary = plant.summary();
    eprintln!("plant summary: {summary}");
    assert_eq!(summary["result"], "completed");
    assert_eq!(summary["deadline_misses"], 0, "{summary}");
    assert_eq!(summary["torques_dropped"], 0);
    let c_status = ctl.interrupt(Duration::from_secs(10));
    assert!(c_status.success(), "{}", ctl.logs());

    let got = parse_csv(&std::fs::read_to_string(&csv).unwrap());
    let want = offline();
    assert_eq!(got.len(), want.len(), "number of samples");
    let mut worst = 0.0f64;
    for (g, w) in got.iter().zip(&want) {
        assert_eq!((g.seq, g.mode), (w.seq, w.mode), "seq/mode at {w:?}");
        assert_eq!(g.t, w.t, "sample time of seq {}", w.seq);
        for i in 0..4 {
            worst = worst.max((g.x[i] - w.x[i]).abs());
        }
        match (g.tau, w.tau) {
            (Some(a), Some(b)) => worst = worst.max((a - b).abs()),
            (None, None) => {}
            other => panic!("tau presence differs at seq {}: {other:?}", w.seq),
        }
    }
    eprintln!(
        "lockstep vs offline: {} samples, largest difference {worst:e}",
        got.len()
    );
    assert!(worst <= 1e-12, "largest difference {worst:e}");
    // The state is transmitted as raw f64 bits and the code path is the same: bit-identical.
    assert_eq!(worst, 0.0, "expected a bit-identical reproduction");
    let last = want.last().unwrap();
    let x: Vec<f64> = summary["x"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(x, last.x.to_vec());
    assert_eq!(summary["time"].as_f64().unwrap(), DURATION);
}
