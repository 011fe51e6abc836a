//! The controller's state estimators against the truth (a benchmark, not a test).
//!
//! `cargo run --release -p tilting-sim --example estimator_bench [-- SECONDS [Q]]`
//!
//! (`Q`: the observer's acceleration noise density in rad^2/s^3, default the controller's.)
//!
//! The paper's loop (k = 500, 1 kHz zero-order hold, the plant's sampled stepper) with the angles
//! measured only (`--measure angles`), the controller running the hybrid observer or the
//! filtered finite difference (`tilting_controller::estimate`) on them, against the loop that
//! reads exact rates. Cases: exact angles and model; 1 mrad of angle noise and a 4,096-count
//! encoder; the same with the plant's arm 5 % heavier or lighter than the controller's model;
//! the same noise over a 50 ms round trip with `--predict 0.05` (estimate, then predict).
//!
//! Printed per case and estimator, over SECONDS simulated s (default 90):
//! - the rates' RMS error against the plant's true rates after the first second (rad/s);
//! - survival: completed tilts, the fault if any, and the mean |alpha| of the last 10 peaks
//!   against the nominal one (the exact loop's), in %;
//! - the estimator's cost per sample (µs): the observer's closed loop's inputs (times, modes,
//!   measured angles, torques sent) replayed through each estimator, `Estimator::update` and
//!   `Estimator::sent` (the observer's propagation by the hybrid simulator included), one
//!   timed block per replay, observer and finite difference alternating over [`ROUNDS`]
//!   rounds, the fastest round of each kept; and the observer's cost as a ratio to the finite
//!   difference's measured in the same rounds (the machine may be loaded: the ratio is the
//!   figure to compare between runs, the µs are this run's).

use std::collections::VecDeque;
use std::time::Instant;
use tilting_controller::estimate::{Estimator, Method, Tuning};
use tilting_controller::{ControlConfig, Controller, LawSpec, Predictor};
use tilting_plant::imperfect::{Imperfections, Measure};
use tilting_plant::{paper, Mode, Observer, Plant, SimConfig, State, TiltPeak};

/// One case: the robot and the round trip (s, a multiple of the period; 0 for none).
struct Case {
    name: &'static str,
    imp: Imperfections,
    delay: f64,
}

/// What one run gave.
struct Outcome {
    rms: [f64; 2],
    tilts: u64,
    fault: Option<String>,
    peak: f64,
    /// What the estimator was given, in order (empty for measured rates).
    inputs: Vec<Input>,
}

/// One call to the estimator: `update(t, mode, angles)`, then `sent(t_act, tau)`.
#[derive(Clone, Copy)]
struct Input {
    t: f64,
    mode: Mode,
    angles: [f64; 2],
    t_act: f64,
    tau: f64,
}

/// Replays (alternating observer and finite difference) per cost measurement.
const ROUNDS: usize = 5;

#[derive(Default)]
struct Peaks(Vec<f64>);

impl Observer for Peaks {
    fn tilt_peak(&mut self, p: &TiltPeak) {
        self.0.push(p.alpha.abs());
    }
}

const PERIOD: f64 = 1e-3;

/// The closed loop of `case` for `duration` s with `method` (`None`: the rates measured,
/// exactly).
fn run(case: &Case, method: Option<Method>, duration: f64, tuning: Tuning) -> Outcome {
    let model = SimConfig::default();
    let law = Controller::new(ControlConfig::new(model.params, LawSpec::default())).unwrap();
    let plant_cfg = SimConfig {
        params: case.imp.plant_params(&model.params),
        ..model
    };
    let x0 = State::from(paper::orbit_x0());
    let mut plant = Plant::new(plant_cfg, 0.0, paper::ORBIT_MODE, x0).unwrap();
    let imp = Imperfections {
        measure: if method.is_some() {
            Measure::Angles
        } else {
            Measure::Full
        },
        ..case.imp
    };
    let mut hw = imp.hardware();
    let mut est = method.map(|m| Estimator::with_tuning(m, model, tuning));
    let mut pred = (case.delay > 0.0).then(|| Predictor::new(model, PERIOD, case.delay));
    let lag = (case.delay / PERIOD).round() as usize;
    let mut in_flight: VecDeque<f64> = VecDeque::new();
    let (mut sq, mut count) = ([0.0; 2], 0u64);
    let mut inputs = Vec::new();
    let mut peaks = Peaks::default();
    let n = (duration / PERIOD).round() as u64;
    let mut fault = None;
    for k in 0..n {
        let t = k as f64 * PERIOD;
        let mode: Mode = plant.mode();
        let y = hw.measure(&plant);
        let x = match &mut est {
            Some(e) => e.update(t, mode, y.angles),
            None => y.state().unwrap(),
        };
        if t >= 1.0 {
            let truth = plant.state();
            for i in 0..2 {
                sq[i] += (x[i + 2] - truth[i + 2]).powi(2);
            }
            count += 1;
        }
        let (tau, t_act) = match &mut pred {
            Some(p) => (p.answer(&law, t, mode, &x, true), p.acts_at(t, true)),
            None => (law.torque(t, mode, &x), t),
        };
        if let Some(e) = &mut est {
            e.sent(t_act, tau);
            inputs.push(Input {
                t,
                mode,
                angles: y.angles,
                t_act,
                tau,
            });
        }
        // The answer to state k acts from sample k + lag on; zero before the first.
        in_flight.push_back(tau);
        let applied = if in_flight.len() > lag {
            in_flight.pop_front().unwrap()
        } else {
            0.0
        };
        if let Err(f) = hw.advance(&mut plant, applied, (k + 1) as f64 * PERIOD, &mut peaks) {
            fault = Some(f.to_string());
            break;
        }
    }
    let last: Vec<f64> = peaks.0.iter().rev().take(10).copied().collect();
    Outcome {
        rms: sq.map(|s| (s / count.max(1) as f64).sqrt()),
        tilts: plant.tilts(),
        fault,
        peak: last.iter().sum::<f64>() / last.len().max(1) as f64,
        inputs,
    }
}

/// Wall time (s) of one replay of `inputs` through a fresh estimator of `method`.
fn replay(method: Method, inputs: &[Input], tuning: Tuning) -> f64 {
    let mut e = Estimator::with_tuning(method, SimConfig::default(), tuning);
    let start = Instant::now();
    for i in inputs {
        std::hint::black_box(e.update(i.t, i.mode, i.angles));
        e.sent(i.t_act, i.tau);
    }
    start.elapsed().as_secs_f64()
}

/// Cost per sample (µs) of the observer and the finite difference on the same `inputs`: the
/// fastest of [`ROUNDS`] alternating replays each.
fn costs(inputs: &[Input], tuning: Tuning) -> [f64; 2] {
    let mut best = [f64::INFINITY; 2];
    for _ in 0..ROUNDS {
        for (i, m) in [Method::Observer, Method::Fd].into_iter().enumerate() {
            best[i] = best[i].min(replay(m, inputs, tuning));
        }
    }
    best.map(|s| s / inputs.len().max(1) as f64 * 1e6)
}

fn main() {
    let duration: f64 = std::env::args()
        .nth(1)
        .map_or(90.0, |s| s.parse().expect("SECONDS"));
    let mut tuning = Tuning::default();
    if let Some(q) = std::env::args().nth(2) {
        tuning.accel_psd = q.parse().expect("Q");
    }
    // `run` sets what is measured (angles for an estimator, else the full state).
    let noisy = Imperfections::measured_as_hardware(1);
    let cases = [
        Case {
            name: "exact angles, exact model",
            imp: Imperfections::default(),
            delay: 0.0,
        },
        Case {
            name: "1 mrad noise + 4096 counts",
            imp: noisy,
            delay: 0.0,
        },
        Case {
            name: "1 mrad + 4096, arm mass +5 %",
            imp: Imperfections {
                mass_error: 0.05,
                ..noisy
            },
            delay: 0.0,
        },
        Case {
            name: "1 mrad + 4096, arm mass -5 %",
            imp: Imperfections {
                mass_error: -0.05,
                ..noisy
            },
            delay: 0.0,
        },
        Case {
            name: "1 mrad + 4096, 50 ms + --predict",
            imp: noisy,
            delay: 0.05,
        },
    ];
    let nominal = run(&cases[0], None, duration, tuning).peak;
    println!(
        "{duration} s at 1 kHz, k = 500; nominal peak {nominal:.5} rad (exact rates, exact \
         model); observer q = {} rad^2/s^3",
        tuning.accel_psd
    );
    println!(
        "{:<34} {:<9} {:>14} {:>13} {:>6} {:>10} {:>9} {:>6}  fault",
        "case", "rates", "RMS ad (rad/s)", "RMS bd (rad/s)", "tilts", "peak", "us/sample", "x fd"
    );
    let mut ratios = Vec::new();
    for case in &cases {
        let mut cost = [f64::NAN; 2];
        for (label, method) in [
            ("measured", None),
            ("observer", Some(Method::Observer)),
            ("fd", Some(Method::Fd)),
        ] {
            let o = run(case, method, duration, tuning);
            if method == Some(Method::Observer) {
                // Both estimators on the observer's loop: the same samples, events and torques.
                cost = costs(&o.inputs, tuning);
                ratios.push(cost[0] / cost[1]);
            }
            let (us, ratio) = match method {
                None => (String::new(), String::new()),
                Some(Method::Observer) => (
                    format!("{:.3}", cost[0]),
                    format!("{:.1}", cost[0] / cost[1]),
                ),
                Some(Method::Fd) => (format!("{:.3}", cost[1]), "1".to_owned()),
            };
            println!(
                "{:<34} {:<9} {:>14.2e} {:>13.2e} {:>6} {:>+9.1}% {:>9} {:>6}  {}",
                case.name,
                label,
                o.rms[0],
                o.rms[1],
                o.tilts,
                100.0 * (o.peak / nominal - 1.0),
                us,
                ratio,
                o.fault.as_deref().unwrap_or("none")
            );
        }
    }
    ratios.sort_by(f64::total_cmp);
    println!(
        "observer's cost per sample over the finite difference's (same inputs, {ROUNDS} \
         alternating replays, fastest of each): {:.1} to {:.1}",
        ratios[0],
        ratios[ratios.len() - 1]
    );
}
