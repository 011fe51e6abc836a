//! Prediction over the delay and sampling on events (`tilting_sim::network`), checked against
//! what the plant actually does: the predicted state is the state the plant reaches, a zero
//! delay predicts nothing, an extra sample at a landing lets the plate tilt again at the
//! landing instant instead of at the next sample, and a controller that estimates the delay
//! from the ages keeps an orbit that the plain one loses.

use std::collections::VecDeque;
use tilting_controller::Predictor;
use tilting_link::{Impairment, LinkSpec};
use tilting_plant::{Mode, Observer, Plant, State, Transition};
use tilting_sim::{simulate, LoopOptions, Predict, Scenario, SimOptions};

const H: f64 = 0.001;

#[derive(Default)]
struct Log(Vec<Transition>);
impl Observer for Log {
    fn transition(&mut self, ev: &Transition) {
        self.0.push(*ev);
    }
}

fn torque_delay(d: f64) -> Impairment {
    Impairment {
        torque: LinkSpec {
            delay: d,
            ..LinkSpec::default()
        },
        max_age: 1000,
        ..Impairment::default()
    }
}

/// The loop over a link that delays torques by 5 periods, written out with the hold and the
/// predictor: before each answer the predictor's forecast of the state at the instant the
/// answer will act is kept, and when the plant gets there the forecast is compared with it.
/// Both integrate the same held torques over the same periods from the same state, so they
/// agree to the integrator's accuracy (rtol 1e-10 on states of order 1: 1e-9), across the
/// landings and lift-offs that fall inside the 5 ms horizons.
#[test]
fn the_predicted_state_is_the_state_the_plant_reaches() {
    let sc = Scenario::default();
    let law = sc.controller().unwrap();
    let mut plant = Plant::new(sc.sim_config(), 0.0, sc.mode, sc.initial_state()).unwrap();
    let d = 5.0 * H;
    let mut hold = torque_delay(d).hold(H);
    let mut pred = Predictor::new(sc.sim_config(), H, d);
    let mut forecasts: VecDeque<(u64, Mode, State)> = VecDeque::new();
    let mut log = Log::default();
    let (mut compared, mut worst, mut across_transitions) = (0, 0.0f64, 0);
    let mut transitions_seen = 0;
    for k in 0..3000u64 {
        let t_k = k as f64 * H;
        if forecasts.front().is_some_and(|f| f.0 == k) {
            let (_, m, x) = forecasts.pop_front().unwrap();
            assert_eq!(m, plant.mode(), "mode at period {k}");
            worst = worst.max((x - plant.state()).abs().max());
            compared += 1;
            if log.0.len() > transitions_seen {
                across_transitions += 1;
            }
        }
        transitions_seen = log.0.iter().filter(|e| e.t < t_k - d).count();
        let (m, x) = (plant.mode(), plant.state());
        let tau = hold.step(k, t_k, || {
            let t_act = pred.acts_at(t_k, true);
            assert!((t_act - (k + 5) as f64 * H).abs() < 1e-12);
            let (pm, px) = pred.predict(t_k, m, &x, t_act).unwrap();
            forecasts.push_back((k + 5, pm, px));
            pred.answer(&law, t_k, m, &x, true)
        });
        plant
            .advance_held(tau, (k + 1) as f64 * H, &mut log)
            .unwrap();
    }
    assert!(compared > 2900, "{compared}");
    assert!(
        across_transitions >= 5,
        "{across_transitions} horizons held a transition"
    );
    assert!(worst < 1e-9, "worst forecast error {worst:e}");
    assert_eq!(pred.counts().1, 0, "no prediction fell back");
}

fn run(
    sc: &Scenario,
    network: Option<Impairment>,
    opts: LoopOptions,
) -> tilting_sim::SimulationReport {
    simulate(
        sc,
        SimOptions {
            network,
            loop_options: opts,
            ..SimOptions::default()
        },
    )
    .unwrap()
}

#[test]
fn a_zero_delay_predicts_nothing() {
    let sc = Scenario {
        control_period: H,
        duration: 3.0,
        ..Scenario::default()
    };
    let plain = run(&sc, None, LoopOptions::default());
    let zero = run(
        &sc,
        None,
        LoopOptions {
            predict: Some(Predict::Given(0.0)),
            ..LoopOptions::default()
        },
    );
    assert_eq!(plain.events, zero.events);
    assert_eq!(plain.final_state, zero.final_state);
}

/// At 100 Hz a landed plate waits for the next sample (up to 10 ms) before the controller
/// tilts it the other way. With an extra sample at the landing, the answer acts at once and the
/// plate tilts again at the landing instant, as under continuous control.
#[test]
fn a_sample_at_the_landing_tilts_the_plate_again_at_once() {
    let sc = Scenario {
        control_period: 0.01,
        duration: 5.0,
        ..Scenario::default()
    };
    let waits = |r: &tilting_sim::SimulationReport| -> Vec<f64> {
        r.events
            .windows(2)
            .filter(|w| w[0].to == Mode::Flat)
            .map(|w| w[1].t - w[0].t)
            .collect()
    };
    let periodic = run(&sc, None, LoopOptions::default());
    let w = waits(&periodic);
    assert!(w.len() >= 8, "{w:?}");
    for wait in &w {
        // The lift-off comes at the next sample instant, after the landing.
        assert!(*wait > 0.0 && *wait <= 0.01 + 1e-12, "{wait}");
    }
    let lift_offs = periodic.events.iter().filter(|e| e.from == Mode::Flat);
    for e in lift_offs.skip(1) {
        let k = e.t / 0.01;
        assert!((k - k.round()).abs() < 1e-9, "lift-off at {} s", e.t);
    }
    let on_event = run(
        &sc,
        None,
        LoopOptions {
            sample_on_event: true,
            ..LoopOptions::default()
        },
    );
    let w = waits(&on_event);
    assert!(w.len() >= 8, "{w:?}");
    assert!(w.iter().all(|&x| x == 0.0), "waits {w:?}");
    // The controller answered the 500 periodic states and one extra state per landing.
    let extra = on_event.stats.controller_samples - 500;
    let landings = on_event
        .events
        .iter()
        .filter(|e| e.to == Mode::Flat)
        .count() as u64;
    assert!(
        extra >= landings,
        "{extra} extra samples, {landings} landings"
    );
}

/// 10 ms of round trip, past the 9 ms at which the plain loop falls: predicting over the delay
/// it estimates from the ages, the controller keeps the orbit (peaks within 10 % of the
/// nominal 0.0413 rad after 20 s), and the estimate is the true age.
#[test]
fn estimating_the_delay_from_the_ages_keeps_an_orbit_the_plain_loop_loses() {
    let sc = Scenario {
        control_period: H,
        duration: 20.0,
        ..Scenario::default()
    };
    let plain = run(&sc, Some(torque_delay(0.010)), LoopOptions::default());
    assert!(plain.fault.is_some(), "the plain loop survived 10 ms");
    let predicted = run(
        &sc,
        Some(torque_delay(0.010)),
        LoopOptions {
            predict: Some(Predict::Estimated),
            ..LoopOptions::default()
        },
    );
    assert!(predicted.fault.is_none(), "{:?}", predicted.fault);
    assert!(predicted.stats.tilts >= 40, "{}", predicted.stats.tilts);
    let last = predicted.tilt_peaks.last().unwrap().alpha.abs();
    assert!((last / 0.0413 - 1.0).abs() < 0.10, "last peak {last}");
    assert_eq!(predicted.network.unwrap().age_median(), Some(10));
}
