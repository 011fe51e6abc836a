//! How fast a tiny perturbation of the start grows on the k = 500 orbit, with and without an
//! extra sample at each mode transition (a measurement, not a test).
//!
//! `cargo run --release -p tilting-sim --example perturbation [-- RATE_HZ]`
//!
//! Two runs of 20 simulated seconds whose initial `beta_dot` differ by 1e-12 rad/s, under a
//! zero-order hold at RATE_HZ (default 1000); prints the largest difference of their
//! transition times (s) up to 5, 10 and 20 s, for periodic samples only and for
//! `--sample-on-event`, and the same for continuous control as the reference.

use tilting_sim::closed_loop::{simulate, SimOptions, SimulationReport};
use tilting_sim::{LoopOptions, Scenario};

const DURATION: f64 = 20.0;
const DELTA: f64 = 1e-12;

fn run(period: f64, on_event: bool, delta: f64) -> SimulationReport {
    let mut sc = Scenario {
        control_period: period,
        duration: DURATION,
        ..Scenario::default()
    };
    sc.x0[3] += delta;
    let opts = SimOptions {
        loop_options: LoopOptions {
            sample_on_event: on_event,
            ..LoopOptions::default()
        },
        ..SimOptions::default()
    };
    simulate(&sc, opts).expect("the default scenario is valid")
}

/// Largest difference of the transition times up to `until` (s); infinite if the two runs
/// do not have the same transitions by then.
fn spread(a: &SimulationReport, b: &SimulationReport, until: f64) -> f64 {
    let (ea, eb): (Vec<_>, Vec<_>) = (
        a.events.iter().filter(|e| e.t <= until).collect(),
        b.events.iter().filter(|e| e.t <= until).collect(),
    );
    if ea.len().abs_diff(eb.len()) > 1 {
        return f64::INFINITY;
    }
    ea.iter()
        .zip(&eb)
        .map(|(x, y)| {
            if x.to == y.to {
                (x.t - y.t).abs()
            } else {
                f64::INFINITY
            }
        })
        .fold(0.0, f64::max)
}

fn main() {
    let rate: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("RATE_HZ must be a number"))
        .unwrap_or(1000.0);
    println!(
        "transition-time spread (s) after a change of {DELTA:e} rad/s in the initial beta_dot"
    );
    println!(
        "{:<34}{:>12}{:>12}{:>12}{:>8}",
        "", "by 5 s", "by 10 s", "by 20 s", "tilts"
    );
    let rows: [(&str, f64, bool); 3] = [
        ("continuous control", 0.0, false),
        ("hold, periodic samples", 1.0 / rate, false),
        ("hold, --sample-on-event", 1.0 / rate, true),
    ];
    for (name, period, on_event) in rows {
        let a = run(period, on_event, 0.0);
        let b = run(period, on_event, DELTA);
        let label = if period > 0.0 {
            format!("{name} ({rate} Hz)")
        } else {
            name.to_string()
        };
        println!(
            "{label:<34}{:>12.2e}{:>12.2e}{:>12.2e}{:>8}",
            spread(&a, &b, 5.0),
            spread(&a, &b, 10.0),
            spread(&a, &b, 20.0),
            a.stats.tilts
        );
    }
}
