//! The robust option against model error (issue 17 §5), a measurement: each physical parameter
//! of the plant off by -10, -5, +5 and +10 % (the controller keeps the paper's model), the
//! plain law against the robust option (`--orbit-peak`), 200 tilts at 1 kHz.
//!
//! `cargo run --release -p tilting-sim --example robust_table [-- TILTS]`
//!
//! Prints, per parameter and error, for each law: tilts completed, whether they alternate, and
//! the mean |peak| of the last 10 tilts relative to the nominal orbit's (the plain law on the
//! exact model); `ok` when all of the goal holds (TILTS tilts, alternating, within 25 %).
//! Progress goes to stderr.

use std::io::Write as _;
use tilting_sim::closed_loop::{simulate, SimOptions};
use tilting_sim::robustness::{Goal, Parameter};
use tilting_sim::Scenario;

/// Plant time allowed per tilt (s), as `plan margins`: the orbit tilts every 0.435 s.
const SECONDS_PER_TILT: f64 = 0.6;
const ERRORS: [f64; 4] = [-0.10, -0.05, 0.05, 0.10];
const TOLERANCE: f64 = 0.25;

fn scenario(tilts: u64, peak: Option<f64>) -> Scenario {
    let mut sc = Scenario {
        control_period: 0.001,
        duration: tilts as f64 * SECONDS_PER_TILT,
        ..Scenario::default()
    };
    sc.law.orbit_peak = peak;
    sc
}

fn cell(g: &Goal) -> String {
    format!(
        "{:>4} {} {:>+7.1} % {}",
        g.tilts,
        if g.alternate { "alt" } else { "ALT!" },
        100.0 * g.deviation,
        if g.holds { "ok  " } else { "FAIL" }
    )
}

fn main() {
    let tilts: u64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("TILTS must be a whole number"))
        .unwrap_or(200);
    let nominal_run = simulate(&scenario(tilts, None), SimOptions::default()).expect("valid");
    let nominal = Goal::of(&nominal_run, tilts, 1.0, f64::INFINITY).last_peak;
    println!(
        "nominal orbit (plain law, exact model, 1 kHz): last peaks {nominal:.5} rad; robust \
         option --orbit-peak {nominal:.5}"
    );
    println!(
        "{:<5} {:>6} | {:<26} | {:<26}",
        "param", "error", "plain: tilts alt dev", "robust: tilts alt dev"
    );
    let total = Parameter::ALL.len() * ERRORS.len();
    let (mut plain_ok, mut robust_ok, mut valid) = (0, 0, 0);
    let start = std::time::Instant::now();
    for (i, p) in Parameter::ALL.iter().enumerate() {
        for (j, &e) in ERRORS.iter().enumerate() {
            eprint!(
                "\r[{}/{total}] {} {:+} % ({:.0} s)   ",
                i * ERRORS.len() + j + 1,
                p.key(),
                100.0 * e,
                start.elapsed().as_secs_f64()
            );
            let _ = std::io::stderr().flush();
            let base = Scenario::default().params;
            let Some(plant) = p.perturbed(&base, e) else {
                println!(
                    "{:<5} {:>+5.0}% | {:<26} | {:<26}",
                    p.key(),
                    100.0 * e,
                    "n/a (not a valid robot)",
                    ""
                );
                continue;
            };
            valid += 1;
            let run = |peak| {
                let mut sc = scenario(tilts, peak);
                sc.plant_params = Some(plant);
                let r = simulate(&sc, SimOptions::default()).expect("valid scenario");
                Goal::of(&r, tilts, nominal, TOLERANCE)
            };
            let (a, b) = (run(None), run(Some(nominal)));
            plain_ok += a.holds as usize;
            robust_ok += b.holds as usize;
            println!(
                "{:<5} {:>+5.0}% | {:<26} | {:<26}",
                p.key(),
                100.0 * e,
                cell(&a),
                cell(&b)
            );
        }
    }
    eprintln!();
    println!(
        "goal held: plain {plain_ok}/{valid}, robust {robust_ok}/{valid} ({:.0} s)",
        start.elapsed().as_secs_f64()
    );
}
