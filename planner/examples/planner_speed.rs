//! Benchmark (not a test) of the planner: wall time of `sinusoid` for the four Fig. 5 cases and
//! of the full bifurcation sweep `k = 1500..2500` step 10, 500 tilts, 200 kept.
//!
//! Baseline: the sweep on one thread, measured in the same run (the ratio is the parallel
//! speed-up; the rows must be bit-identical).
//!
//! Run: `cargo run --release -p tilting-planner --example planner_speed`

use std::time::Instant;
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::gains::range;
use tilting_planner::orbit::{self, OrbitProblem};
use tilting_planner::sinusoid::{self, Search};
use tilting_plant::{paper, ImpactLaw, Params};

fn rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

fn main() {
    println!("VmRSS at start: {} kB", rss_kib());
    let p = Params::default();
    println!("sinusoid (A = 0.33), median of 21 solves each:");
    for (name, s) in [("a", -0.5), ("b", -0.25), ("c", -1.0 / 6.0), ("d", -0.125)] {
        let mut times = Vec::new();
        let mut w = 0.0;
        for _ in 0..21 {
            let t = Instant::now();
            w = sinusoid::solve(&p, 0.33, s, &Search::default())
                .unwrap()
                .omega;
            times.push(t.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        let med = times[times.len() / 2];
        println!(
            "  Fig. 5{name}: s = {s:+.4}  w = {w:.9} rad/s  {:.2} ms",
            med * 1e3,
        );
    }

    let pb = OrbitProblem::new(p, ImpactLaw::Paper, paper::ORBIT_KP, paper::ORBIT_KD);
    let o = orbit::find_all(&pb).remove(0);
    let sw = Sweep {
        problem: pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: o.energy_avg,
        tilts: 500,
        keep: 200,
        period_tol: 1e-5,
    };
    let ks = range(1500.0, 2500.0, 10.0);
    let t = Instant::now();
    let rows = bifurcation::sweep(&sw, &ks, &|| {});
    let all = t.elapsed().as_secs_f64();
    let one_pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let t = Instant::now();
    let rows1 = one_pool.install(|| bifurcation::sweep(&sw, &ks, &|| {}));
    let one = t.elapsed().as_secs_f64();
    assert_eq!(rows.len(), rows1.len());
    let same = rows.iter().zip(&rows1).all(|(a, b)| a.peaks == b.peaks);
    let t = Instant::now();
    let ks_star = bifurcation::k_star(&sw, paper::ORBIT_K, 1500.0, 2500.0, 1e-3);
    let kst = t.elapsed().as_secs_f64();
    println!(
        "bifurcation sweep: {} values of k, 500 tilts, 200 kept, {} threads: {:.3} s \
         (one thread: {:.3} s, speed-up {:.2}x; bit-identical rows: {same})",
        ks.len(),
        rayon::current_num_threads(),
        all,
        one,
        one / all,
    );
    println!(
        "k* = {:?} ({:.3} s); first k not period 1: {:?}",
        ks_star,
        kst,
        rows.iter().find(|r| r.period != Some(1)).map(|r| r.k)
    );
    println!("VmRSS at end: {} kB", rss_kib());
}
