//! The default excitation on robots up to 20 % off the paper's (issue 17 §4), a measurement:
//! does the plate stay flat, how far does the arm go, how well does it follow, and what
//! amplitude does the governor (`tilting_controller::excite`) leave.
//!
//! `cargo run --release -p tilting-sim --example excitation_safety [-- SECONDS [REFERENCE]]`
//!
//! The controller keeps the paper's model; the plant is each robot of the grid, at 1 kHz,
//! noise-free and with 1 mrad of angle noise on a 4,096-count encoder, angles only (two noise
//! seeds). Prints per robot: mode transitions (0 = the plate stayed flat) and the first one's
//! time, the largest `|beta - pi/2|` read (rad), the largest tracking error over the last
//! quarter of the run (against the reference at the governor's final scale, rad), the governor's final and smallest amplitude
//! scale and its estimate of `m_l l_c g` against the truth (N m).

use tilting_controller::trajectory::EXCITATION_DEFAULT;
use tilting_controller::{LawArgs, Trajectory};
use tilting_plant::imperfect::Imperfections;
use tilting_plant::Params;
use tilting_sim::recording::simulate_logged;
use tilting_sim::{Scenario, ScenarioFile, SimOptions};

fn robots() -> Vec<(&'static str, Params)> {
    let p = Params::default();
    let with = |f: &dyn Fn(&mut Params)| {
        let mut q = p;
        f(&mut q);
        q
    };
    vec![
        ("paper", p),
        ("m_f 0.8", with(&|q| q.m_f = 0.8)),
        ("m_f 1.2", with(&|q| q.m_f = 1.2)),
        ("m_l 0.8", with(&|q| q.m_l = 0.8)),
        ("m_l 1.1", with(&|q| q.m_l = 1.1)),
        ("m_l 1.2", with(&|q| q.m_l = 1.2)),
        ("m_f 0.8 m_l 1.2", with(&|q| (q.m_f, q.m_l) = (0.8, 1.2))),
        ("m_f 1.2 m_l 0.8", with(&|q| (q.m_f, q.m_l) = (1.2, 0.8))),
        ("m_f 0.8 m_l 0.8", with(&|q| (q.m_f, q.m_l) = (0.8, 0.8))),
        ("m_f 1.2 m_l 1.2", with(&|q| (q.m_f, q.m_l) = (1.2, 1.2))),
        ("m_f 0.8 m_l 1.1", with(&|q| (q.m_f, q.m_l) = (0.8, 1.1))),
        ("l_c 1.6", with(&|q| q.l_c = Some(1.6))),
        (
            "m_l 1.2 l_c 1.6",
            with(&|q| (q.m_l, q.l_c) = (1.2, Some(1.6))),
        ),
        (
            "m_f 0.8 m_l 1.2 i_l 0.08",
            with(&|q| (q.m_f, q.m_l, q.i_l) = (0.8, 1.2, 0.08)),
        ),
        (
            "m_f 0.8 m_l 1.2 b_v 0.06 tau_c 0.1",
            with(&|q| (q.m_f, q.m_l, q.b_v, q.tau_c) = (0.8, 1.2, 0.06, 0.1)),
        ),
        (
            "m_f 1.2 m_l 0.8 b_v 0.06 tau_c 0.1",
            with(&|q| (q.m_f, q.m_l, q.b_v, q.tau_c) = (1.2, 0.8, 0.06, 0.1)),
        ),
        (
            "m_f 0.8 m_l 1.2 j_m 0.03 n_g 1.2",
            with(&|q| (q.m_f, q.m_l, q.j_m, q.n_g) = (0.8, 1.2, 0.03, 1.2)),
        ),
        (
            "README robot",
            with(&|q| {
                (q.m_f, q.m_l, q.l_c, q.i_l, q.j_m, q.n_g, q.b_v, q.tau_c) =
                    (0.85, 1.1, Some(1.8), 0.08, 0.02, 0.8, 0.03, 0.05)
            }),
        ),
        (
            "tests' robot",
            with(&|q| {
                (q.m_f, q.m_l, q.l_c, q.i_l, q.j_m, q.n_g, q.b_v, q.tau_c) =
                    (1.15, 0.85, Some(1.7), 0.06, 0.03, 1.2, 0.05, 0.08)
            }),
        ),
    ]
}

fn main() {
    let mut args = std::env::args().skip(1);
    let secs: f64 = args.next().map_or(120.0, |s| s.parse().expect("SECONDS"));
    let reference: Trajectory = args
        .next()
        .map_or(EXCITATION_DEFAULT, |s| s.parse().expect("REFERENCE"));
    let filter = args.next().unwrap_or_default();
    let seeds: Vec<Option<u64>> = if std::env::var("NOISE").is_ok() {
        vec![None, Some(1), Some(2)]
    } else {
        vec![None]
    };
    println!("{reference} for {secs} s at 1 kHz, the controller on the paper's model");
    println!(
        "{:<36} {:>6} | {:>5} {:>7} {:>7} {:>7} {:>6} {:>6} {:>7} {:>7}",
        "robot", "noise", "trans", "first", "max th", "track", "scale", "min", "G est", "G true"
    );
    let (mut unsafe_runs, mut runs) = (0, 0);
    for (name, plant) in robots().into_iter().filter(|(n, _)| n.contains(&filter)) {
        for &noise in &seeds {
            let sc = Scenario {
                plant_params: Some(plant),
                control_period: 1e-3,
                duration: secs,
                ..Scenario::resolve(&[&ScenarioFile {
                    law: LawArgs {
                        reference: Some(reference),
                        ..LawArgs::default()
                    },
                    ..ScenarioFile::default()
                }])
            };
            let opts = SimOptions {
                imperfect: noise.map(Imperfections::measured_as_hardware),
                ..SimOptions::default()
            };
            let (r, logged) = simulate_logged(&sc, opts, &mut |_| {}).expect("valid scenario");
            let reach = logged.trace.samples.iter().fold(0.0f64, |m, s| {
                m.max((s.x[1] - std::f64::consts::FRAC_PI_2).abs())
            });
            let e = r.excitation.expect("the excitation's governor");
            let track = logged
                .trace
                .samples
                .iter()
                .filter(|s| s.t >= 0.75 * secs)
                .fold(0.0f64, |m, s| {
                    m.max((s.x[1] - reference.at_scaled(s.t, (e.scale, 0.0, 0.0)).0).abs())
                });
            let first = r
                .events
                .first()
                .map_or("-".to_string(), |e| format!("{:.1}", e.t));
            runs += 1;
            if r.stats.transitions > 0 || r.fault.is_some() {
                unsafe_runs += 1;
            }
            println!(
                "{:<36} {:>6} | {:>5} {:>7} {:>7.3} {:>7.4} {:>6.3} {:>6.3} {:>7.3} {:>7.3}{}",
                name,
                noise.map_or("none".to_string(), |s| format!("seed {s}")),
                r.stats.transitions,
                first,
                reach,
                track,
                e.scale,
                e.min_scale,
                e.gravity,
                plant.m_l * plant.lc() * plant.g,
                r.fault.map_or(String::new(), |f| format!("  fault: {f}"))
            );
        }
    }
    println!("{unsafe_runs} of {runs} runs left the flat plate");
}
