//! The plant's `--record` CSV and the offline closed loop it must reproduce.

use tilting_controller::{ComputedTorque, ControlConfig, LawSpec};
use tilting_plant::{paper, Observer, Plant, SimConfig, Tolerance, Transition};

/// One CSV row of `--record`: seq, t, mode, alpha, beta, alpha_dot, beta_dot, tau (empty on the
/// last row).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Plant time (s).
    pub t: f64,
    /// Mode index.
    pub mode: u8,
    /// State.
    pub x: [f64; 4],
    /// Torque applied over the next period (N m); none on the last row.
    pub tau: Option<f64>,
    /// Sample number.
    pub seq: u64,
}

/// Parses a `--record` CSV file.
pub fn parse_csv(text: &str) -> Vec<Row> {
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau")
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 8, "{l}");
            let p = |s: &str| s.parse::<f64>().unwrap_or_else(|e| panic!("{s}: {e}"));
            Row {
                seq: f[0].parse().unwrap(),
                t: p(f[1]),
                mode: f[2].parse().unwrap(),
                x: [p(f[3]), p(f[4]), p(f[5]), p(f[6])],
                tau: (!f[7].is_empty()).then(|| p(f[7])),
            }
        })
        .collect()
}

/// The offline closed loop: `tau_k = c(t_k, q_k, x_k)` held over `[t_k, t_{k+1}]`, with the
/// plant's settings (`atol = rtol / 100`, as `simulate` and `tilting-plant` use).
pub fn offline(duration: f64, period: f64) -> Vec<Row> {
    offline_with_events(duration, period).0
}

/// Collects the mode transitions of a run.
#[derive(Default)]
struct Transitions(Vec<Transition>);

impl Observer for Transitions {
    fn transition(&mut self, ev: &Transition) {
        self.0.push(*ev);
    }
}

/// [`offline`], and the mode transitions of that run in time order.
pub fn offline_with_events(duration: f64, period: f64) -> (Vec<Row>, Vec<Transition>) {
    let rtol = Tolerance::default().rtol;
    let cfg = SimConfig {
        tol: Tolerance {
            rtol,
            atol: rtol * 1e-2,
        },
        ..SimConfig::default()
    };
    let mut plant = Plant::new(cfg, 0.0, paper::ORBIT_MODE, paper::orbit_state()).unwrap();
    let c = ComputedTorque::new(ControlConfig {
        law: LawSpec {
            k: paper::ORBIT_K,
            energy_avg: paper::ORBIT_ENERGY_AVG,
            ..LawSpec::without_adaptation()
        },
        ..ControlConfig::default()
    })
    .unwrap();
    let n = (duration / period).round() as u64;
    let mut rows = Vec::new();
    let mut events = Transitions::default();
    for k in 0..=n {
        let x = plant.state();
        let row = |tau| Row {
            t: plant.time(),
            mode: plant.mode().as_u8(),
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
            .advance_held(tau, (k + 1) as f64 * period, &mut events)
            .unwrap();
    }
    (rows, events.0)
}

/// The largest differences of a recorded run `got` from the offline loop `want`, sample by
/// sample: `(state, torque)`, the largest `|x_i - x_i'|` (rad, rad/s) and `|tau - tau'|`
/// (N m). Asserts what must agree exactly: the number of samples, and each sample's `seq`, mode,
/// time (`k h`, the plant's own product in both) and whether it carries a torque (all but the
/// last).
pub fn largest_differences(got: &[Row], want: &[Row]) -> (f64, f64) {
    assert_eq!(got.len(), want.len(), "number of samples");
    let (mut worst_x, mut worst_tau) = (0.0f64, 0.0f64);
    for (g, w) in got.iter().zip(want) {
        assert_eq!((g.seq, g.mode), (w.seq, w.mode), "seq/mode at {w:?}");
        assert_eq!(g.t, w.t, "sample time of seq {}", w.seq);
        for i in 0..4 {
            worst_x = worst_x.max((g.x[i] - w.x[i]).abs());
        }
        match (g.tau, w.tau) {
            (Some(a), Some(b)) => worst_tau = worst_tau.max((a - b).abs()),
            (None, None) => {}
            other => panic!("tau presence differs at seq {}: {other:?}", w.seq),
        }
    }
    (worst_x, worst_tau)
}
