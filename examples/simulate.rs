//! Simulate the closed loop from code: the paper's stabilised orbit, then the same loop under
//! a 1 ms zero-order hold (as over a network), and the mode transitions of the first second.
//!
//! ```sh
//! cargo run --release -p tilting-examples --example simulate -- --duration 5
//! ```

use clap::Parser;
use tilting_plant::paper;
use tilting_sim::{simulate, Scenario, SimOptions};

#[derive(Parser)]
struct Args {
    /// Simulated time (s)
    #[arg(long, default_value_t = 5.0)]
    duration: f64,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    // The default scenario is the paper's stabilised orbit: K_P0 = 100, K_D = 14.14, k = 500,
    // started at the beginning of a left tilt (tilting_plant::paper).
    let continuous = Scenario {
        duration: args.duration,
        ..Scenario::default()
    };
    let held = Scenario {
        control_period: 1e-3, // the controller samples every 1 ms and its torque is held
        ..continuous.clone()
    };
    for (name, sc) in [("continuous", &continuous), ("1 ms hold", &held)] {
        let r = simulate(sc, SimOptions::default())?;
        let peaks: Vec<String> = r
            .tilt_peaks
            .iter()
            .rev()
            .take(4)
            .map(|p| format!("{:+.5}", p.alpha))
            .collect();
        println!(
            "{name:>10}: {} tilts in {} s (a tilt every {:.3} s on the orbit), last peaks {} rad, \
             fault: {}",
            r.stats.tilts,
            r.final_state.t,
            paper::ORBIT_HALF_PERIOD,
            peaks.join(" "),
            r.fault.map_or_else(|| "none".to_owned(), |f| f.to_string()),
        );
        if name == "continuous" {
            for e in r.events.iter().take_while(|e| e.t < 1.0) {
                println!(
                    "{:>12.6} s  {:>5} -> {:<5}  alpha_dot {:+.5} -> {:+.5} rad/s",
                    e.t, e.from, e.to, e.x_before[2], e.x_after[2]
                );
            }
        }
    }
    Ok(())
}
