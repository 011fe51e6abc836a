//! The plant's `--record` CSV and the offline closed loop it must reproduce.

use std::f64::consts::FRAC_PI_2;
use tilting_controller::{ComputedTorque, ControlConfig};
use tilting_plant::{Mode, Plant, SimConfig, State, Tolerance};

/// One CSV row of `--record`: t, mode, alpha, beta, alpha_dot, beta_dot, tau (empty on the last
/// row), seq.
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
pub fn offline(duration: f64, period: f64) -> Vec<Row> {
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
    let n = (duration / period).round() as u64;
    let mut rows = Vec::new();
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
            .advance_held(tau, (k + 1) as f64 * period, &mut ())
            .unwrap();
    }
    rows
}
