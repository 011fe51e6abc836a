//! How long `tilting identify` takes on a 60 s recording at 1 kHz (60,000 states): a robot
//! changed from the paper's (a geared motor, friction) recorded on the orbit's controller by
//! the code behind `simulate --record`, identified from its angles (the weak form, the
//! default) and from its recorded velocities, with the fit check. Prints the median of 5 runs.
//!
//! Then the noisy case: robots measured as hardware measures them (angles only, 1 mrad
//! of noise, a 4,096-count encoder) on the excitation (`--reference excitation`, 300 s) and
//! the robust orbit (30 s), identified from both recordings: each physical parameter's error
//! for four noise seeds, `b_v` by the least squares alone and with the output-error
//! refinement (the default, `identify::refine`), and both times. Robots: the heavy arm of
//! the excitation tests (`m_f` 0.8, `m_l` 1.2, with friction), the paper's with friction,
//! and the README's, the last also on `excitation:0.3,0.8` (docs/identify.md).
//!
//! `cargo build --release -p tilting-planner -p tilting --example identify_bench &&
//! ./target/release/examples/identify_bench` (the front door beside it resolves the
//! planner's node features).

use std::time::Instant;
use tilting_controller::trajectory::{Trajectory, EXCITATION_DEFAULT};
use tilting_controller::{LawArgs, LawSpec};
use tilting_planner::identify::{identify, Options, Recorded, Velocities};
use tilting_plant::imperfect::Imperfections;
use tilting_plant::Params;
use tilting_sim::recording::{run_logged, simulate_logged};
use tilting_sim::{Scenario, ScenarioFile, SimOptions};

fn main() {
    let robot = Params {
        m_f: 0.85,
        m_l: 1.1,
        l_c: Some(1.8),
        i_l: 0.08,
        j_m: 0.02,
        n_g: 0.8,
        b_v: 0.03,
        tau_c: 0.05,
        ..Params::default()
    };
    let run = run_logged(&Scenario {
        params: robot,
        control_period: 1e-3,
        duration: 60.0,
        ..Scenario::default()
    })
    .expect("the scenario runs");
    let tau: Vec<Option<f64>> = run.tau.iter().map(|t| Some(*t)).collect();
    let n = run.trace.samples.len();
    println!(
        "recording: {n} states, {} transitions",
        run.trace.events.len()
    );
    let prior = Params {
        m_l: robot.m_l,
        ..Params::default()
    };
    for v in [Velocities::Angles, Velocities::Recorded] {
        let opts = Options {
            base: prior,
            velocities: v,
            ..Options::default()
        };
        let mut times = Vec::new();
        let mut fits = Vec::new();
        let mut id = None;
        for _ in 0..5 {
            let t = Instant::now();
            let mut r = identify(&run.trace, &tau, &opts).expect("identifiable");
            times.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            r.check_fit(&run.trace, &tau, &prior, 0.25);
            fits.push(t.elapsed().as_secs_f64());
            id = Some(r);
        }
        times.sort_by(f64::total_cmp);
        fits.sort_by(f64::total_cmp);
        let id = id.expect("ran");
        let worst = id
            .base
            .iter()
            .take(7)
            .zip(base_of(&robot))
            .map(|(e, w)| ((e.value.unwrap_or(f64::NAN) - w) / w).abs())
            .fold(0.0, f64::max);
        println!(
            "{v:?}: identify {:.1} ms ({} equations, condition {:.1}), fit check {:.1} ms \
             (two re-simulations); worst base parameter error {:.2e} (relative)",
            1e3 * times[2],
            id.rows.equations,
            id.condition_number,
            1e3 * fits[2],
            worst
        );
    }
    noisy(&robot);
}

/// The noisy angles-only case (module docs).
fn noisy(readme: &Params) {
    let record = |sc: Scenario, seed: u64| -> Recorded {
        let opts = SimOptions {
            imperfect: Some(Imperfections::measured_as_hardware(seed)),
            ..SimOptions::default()
        };
        let (_, l) = simulate_logged(&sc, opts, &mut |_| {}).expect("the scenario runs");
        Recorded {
            trace: l.trace,
            tau: l.tau.into_iter().map(Some).collect(),
            robot: None,
            source: Default::default(),
        }
    };
    let excitation = |robot: &Params, reference: Trajectory| Scenario {
        plant_params: Some(*robot),
        control_period: 1e-3,
        duration: 300.0,
        ..Scenario::resolve(&[&ScenarioFile {
            law: LawArgs {
                reference: Some(reference),
                ..LawArgs::default()
            },
            ..ScenarioFile::default()
        }])
    };
    let orbit = |robot: &Params| Scenario {
        plant_params: Some(*robot),
        control_period: 1e-3,
        duration: 30.0,
        law: LawSpec {
            orbit_peak: Some(0.04),
            ..LawSpec::default()
        },
        ..Scenario::default()
    };
    let heavy = Params {
        m_f: 0.8,
        m_l: 1.2,
        i_l: 0.06,
        b_v: 0.05,
        tau_c: 0.08,
        ..Params::default()
    };
    let paper = Params {
        b_v: 0.05,
        tau_c: 0.08,
        ..Params::default()
    };
    let wide: Trajectory = "excitation:0.3,0.8".parse().expect("valid");
    for (name, robot, reference) in [
        (
            "heavy arm (m_f 0.8, m_l 1.2, i_l 0.06, b_v 0.05, tau_c 0.08)",
            heavy,
            EXCITATION_DEFAULT,
        ),
        (
            "paper's robot with friction (b_v 0.05, tau_c 0.08)",
            paper,
            EXCITATION_DEFAULT,
        ),
        ("README's robot", *readme, EXCITATION_DEFAULT),
        ("README's robot", *readme, wide),
    ] {
        println!(
            "noisy, {name} (angles only, 1 mrad, 4,096 counts; {reference} 300 s + robust \
             orbit 30 s, windows 2 s): relative errors (%); b_v by the least squares alone \
             (LS) and refined by the output error (OE, the default), with its standard error"
        );
        println!(
            "seed   m_f     l_c     joint inertia  tau_c   b_v LS   b_v OE (se)      \
             identify LS, OE (ms)  rotor"
        );
        for seed in [3, 13, 23, 33] {
            let mut rec = record(excitation(&robot, reference), seed);
            rec.append(record(orbit(&robot), seed + 1));
            noisy_row(&robot, &rec, seed);
        }
    }
}

/// One row of the noisy case: the recording `rec` of `robot` (seed `seed`) identified by the
/// least squares alone and refined by the output error, each estimate's relative error (%)
/// against `robot`, `b_v`'s standard error and the times (ms).
fn noisy_row(robot: &Params, rec: &Recorded, seed: u64) {
    let opts = Options {
        base: Params {
            m_l: robot.m_l,
            ..Params::default()
        },
        half_window: 0.05,
        window: 2.0,
        ..Options::default()
    };
    let t = Instant::now();
    let ls = identify(
        &rec.trace,
        &rec.tau,
        &Options {
            refine: None,
            ..opts
        },
    )
    .expect("identifiable");
    let ms_ls = 1e3 * t.elapsed().as_secs_f64();
    let t = Instant::now();
    let id = identify(&rec.trace, &rec.tau, &opts).expect("identifiable");
    let ms = 1e3 * t.elapsed().as_secs_f64();
    let p = id.params;
    let e = |g: f64, w: f64| 100.0 * (g - w) / w;
    let se = id.base[5].std_error.unwrap_or(f64::NAN);
    println!(
        "{seed:<6} {:+.2}  {:+.3}  {:+.3}         {:+.2}  {:+6.1}   {:+6.2} ({:.1})    \
         {ms_ls:.0}, {ms:.0}  {}",
        e(p.m_f, robot.m_f),
        e(p.lc(), robot.lc()),
        e(p.joint_inertia(), robot.joint_inertia()),
        e(p.tau_c, robot.tau_c),
        e(ls.params.b_v, robot.b_v),
        e(p.b_v, robot.b_v),
        100.0 * se / robot.b_v,
        if id.base[3].value.is_some() {
            "seen"
        } else {
            "below the noise (the sum pi3+pi5 reported)"
        }
    );
}

/// The base parameters of `p` by their definitions (docs/model.md).
fn base_of(p: &Params) -> [f64; 7] {
    let lc = p.lc();
    [
        p.m_f + p.m_l,
        p.m_l * lc,
        p.m_l * lc * lc + p.i_l + p.j_m,
        (p.n_g - 1.0) * p.j_m,
        (p.n_g * p.n_g - 1.0) * p.j_m,
        p.b_v,
        p.tau_c,
    ]
}
