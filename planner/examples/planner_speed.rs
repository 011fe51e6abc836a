//! Benchmark (not a test) of the planner: wall time of `sinusoid` for the four Fig. 5 cases and
//! of the full bifurcation sweep `k = 1500..2500` step 10, 500 tilts, 200 kept.
//!
//! Baseline: the sweep on one thread, measured in the same run (the ratio is the parallel
//! speed-up; the rows must be bit-identical).
//!
//! The sweep's throughput, one point at a time on one thread: a sweep point
//! (`bifurcation::run_one`, 500 tilts) against a plain continuous simulation of the same length
//! (one `Plant::advance_continuous` call, no observer) at the same `k`, interleaved, best of 5:
//! the ratio says what the sweep adds to the simulator. And the fixed set-up cost of a
//! `tilting plan bifurcation` command (finding the `k = 0` base orbit, `orbit::smallest`).
//!
//! Run: `cargo run --release -p tilting-planner --example planner_speed`

use std::time::Instant;
use tilting_controller::{ComputedTorque, ControlConfig, LawSpec};
use tilting_planner::bifurcation::{self, Sweep};
use tilting_planner::gains::range;
use tilting_planner::orbit::{self, OrbitProblem};
use tilting_planner::sinusoid::{self, Search};
use tilting_plant::{paper, ImpactLaw, Mode, Params, Plant, SimConfig};

/// Keeps the fastest wall time (s) of `run` into `best`.
fn time_into<T>(best: &mut f64, run: impl FnOnce() -> T) -> T {
    let start = Instant::now();
    let out = std::hint::black_box(run());
    *best = best.min(start.elapsed().as_secs_f64());
    out
}

/// One sweep point against a plain simulation of the same length at the same `k`.
fn point_throughput(sw: &Sweep, k: f64) {
    let pb = &sw.problem;
    let law = ComputedTorque::new(ControlConfig {
        law: LawSpec {
            k,
            energy_avg: sw.energy_avg,
            ..pb.control.law
        },
        ..pb.control
    })
    .expect("valid law");
    let cfg = SimConfig {
        params: pb.params,
        impact: pb.impact,
        ..SimConfig::default()
    };
    let x0 = OrbitProblem::start(sw.start_beta0, sw.start_beta_dot0);
    // The length of the sweep point: it advances in 10 s slices until `tilts` tilts.
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).expect("valid start");
    let mut t_end = 0.0;
    while (plant.tilts() as usize) < sw.tilts {
        t_end += 10.0;
        plant
            .advance_continuous(&law, t_end, &mut ())
            .expect("no fault");
    }
    let (mut w_point, mut w_plain) = (f64::INFINITY, f64::INFINITY);
    let mut evals = 0;
    for _ in 0..5 {
        let row = time_into(&mut w_point, || bifurcation::run_one(sw, k));
        assert!(row.fault.is_none(), "k = {k}: {:?}", row.fault);
        evals = time_into(&mut w_plain, || {
            let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).expect("valid start");
            plant
                .advance_continuous(&law, t_end, &mut ())
                .expect("no fault");
            plant.stats().evals
        });
    }
    println!(
        "  k = {k:>6}: {t_end} simulated s ({} tilts): sweep point {:>6.0} simulated s per wall s, \
         plain simulation {:>6.0} ({:.0} RHS evaluations per simulated s); ratio {:.2}",
        sw.tilts,
        t_end / w_point,
        t_end / w_plain,
        evals as f64 / t_end,
        w_plain / w_point,
    );
}

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
    let mut setup = f64::INFINITY;
    let mut o = None;
    for _ in 0..5 {
        o = time_into(&mut setup, || orbit::smallest(&pb));
    }
    let o = o.expect("the paper's orbit exists");
    println!(
        "bifurcation set-up (the k = 0 base orbit, orbit::smallest), best of 5: {:.1} ms",
        setup * 1e3
    );
    let sw = Sweep {
        problem: pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: o.energy_avg,
        tilts: 500,
        keep: 200,
        period_tol: 1e-5,
    };
    println!("sweep throughput, one point at a time on one thread (best of 5, interleaved):");
    for k in [1500.0, 2000.0, 2500.0] {
        point_throughput(&sw, k);
    }
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
