//! Benchmark (not a test) of issue 19's diagram: the period-1 orbit continued in `k` from 500
//! to 2400, branch switching at each flip up to the period-16 orbit (whose own flip is located
//! too), and the Lyapunov curve over `k = 1500..2400` step 5 (200 tilts discarded, 400
//! averaged), on all cores. Prints the flips, the ratios against Feigenbaum's constant, the
//! accumulation point, the step count and the cost per step, and the whole diagram's time.
//!
//! Run: `cargo run --release -p tilting-planner --example continuation_bench`

use std::time::Instant;
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::continuation::{self, Param, Settings, FEIGENBAUM_DELTA};
use tilting_planner::lyapunov;
use tilting_planner::orbit::{self, OrbitProblem};
use tilting_plant::{paper, ImpactLaw, Params};

fn main() {
    let all = Instant::now();
    let pb = OrbitProblem::new(
        Params::default(),
        ImpactLaw::Paper,
        paper::ORBIT_KP,
        paper::ORBIT_KD,
    );
    let o = orbit::smallest(&pb).expect("the paper's orbit");
    let sw = Sweep {
        problem: pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: o.energy_avg,
        tilts: 0,
        keep: 1,
        period_tol: 1e-5,
    };
    let base = pb.with_adaptation(paper::ORBIT_K, o.energy_avg);
    let guess = bifurcation::attracting_orbit_guess(&sw, paper::ORBIT_K, 200).expect("start");
    let set = Settings {
        p_min: 0.0,
        p_max: 2400.0,
        ds: 9.5,
        ds_min: 1e-3,
        ds_max: 38.0,
        max_steps: 2000,
        locate_tol: 1e-7,
        max_period: 16,
        stop_at_first_event: false,
    };
    let t = Instant::now();
    let d = continuation::diagram(&base, Param::K, paper::ORBIT_K, guess, &set, &|_, _| {})
        .expect("continuation");
    let cont_s = t.elapsed().as_secs_f64();
    print_diagram(&d);
    let steps = d.steps();
    println!(
        "continuation: {cont_s:.3} s, {steps} steps, {:.2} ms per step",
        1e3 * cont_s / steps as f64
    );
    let ks: Vec<f64> = (0..=180).map(|i| 1500.0 + 5.0 * i as f64).collect();
    let t = Instant::now();
    let ly = lyapunov::curve(
        &ks,
        &|k| Param::K.set(&base, k),
        [o.beta0, o.beta_dot0],
        200,
        400,
        &|| {},
    );
    let ly_s = t.elapsed().as_secs_f64();
    let first_pos = ly.iter().find(|e| e.lambda.is_some_and(|l| l > 0.0));
    let faults = ly.iter().filter(|e| e.lambda.is_none()).count();
    println!(
        "Lyapunov: {} values in {ly_s:.3} s ({:.1} ms each on {} threads), first positive at k = {:?}, {faults} undefined",
        ks.len(),
        1e3 * ly_s / ks.len() as f64,
        rayon::current_num_threads(),
        first_pos.map(|e| e.p)
    );
    for e in ly.iter().step_by(10) {
        println!(
            "  k = {:.0}: lambda = {:?} 1/s {}",
            e.p,
            e.lambda,
            e.fault.clone().unwrap_or_default()
        );
    }
    println!(
        "whole diagram with its Lyapunov curve: {:.3} s",
        all.elapsed().as_secs_f64()
    );
}

/// Prints each branch of `d` (points, range of k, steps, Newton iterations, worst residual and
/// re-simulated mismatch, end, its bifurcations), the flips, their ratios against Feigenbaum's
/// constant and the accumulation point.
fn print_diagram(d: &continuation::Diagram) {
    for br in &d.branches {
        let worst = br.points.iter().map(|p| p.residual).fold(0.0, f64::max);
        let mism = br
            .points
            .iter()
            .map(|p| p.resimulated_mismatch)
            .fold(0.0, f64::max);
        println!(
            "period {:>2}: {:>4} points, k in [{:.3}, {:.3}], {:>4} steps, {:>5} Newton iterations, residual <= {worst:.1e}, re-simulated <= {mism:.1e}, end {:?}",
            br.tilts,
            br.points.len(),
            br.points.first().map_or(f64::NAN, |p| p.p),
            br.points.last().map_or(f64::NAN, |p| p.p),
            br.steps,
            br.newton_iterations,
            br.end
        );
        for e in &br.events {
            println!(
                "    {:?} at k = {:.7} (test {:.1e}), multipliers {:?}",
                e.kind, e.p, e.test, e.point.multipliers
            );
        }
    }
    for (i, k) in d.flips.iter().enumerate() {
        println!("k_{} = {k:.7}", i + 1);
    }
    for (i, r) in d.ratios.iter().enumerate() {
        println!(
            "delta_{} = {r:.4} (Feigenbaum {FEIGENBAUM_DELTA:.4})",
            i + 1
        );
    }
    println!(
        "k_inf = {:?} (own ratio), {:?} (Feigenbaum's)",
        d.p_inf, d.p_inf_feigenbaum
    );
}
