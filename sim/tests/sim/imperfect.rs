//! The robot's imperfections in the offline loop (`tilting_plant::imperfect`): zero settings are
//! the perfect loop bit for bit, the mass error is the same plant as a parameter file with the
//! heavier arm, the noise does not change the network's draws, and the imperfections act.

use tilting_link::LinkSpec;
use tilting_plant::imperfect::Imperfections;
use tilting_plant::{Params, Plant};
use tilting_sim::closed_loop::run_sampled;
use tilting_sim::{run_sampled_over, simulate, Impairment, Scenario, SimOptions};

const H: f64 = 0.001;
const T: f64 = 3.0;

fn sampled() -> Scenario {
    Scenario {
        control_period: H,
        duration: T,
        ..Scenario::default()
    }
}

fn bits(x: [f64; 4]) -> [u64; 4] {
    x.map(f64::to_bits)
}

/// Every setting zero (but a seed): the sensor hands over the true state and the actuator holds
/// the command, so the loop through the hardware is `run_sampled` bit for bit.
#[test]
fn zero_settings_reproduce_the_perfect_loop_bit_for_bit() {
    let sc = sampled();
    let law = sc.controller().unwrap();
    let new = || Plant::new(sc.sim_config(), 0.0, sc.mode, sc.initial_state()).unwrap();
    let mut a = new();
    run_sampled(&mut a, &law, H, T, &mut (), &mut |_| {})
        .0
        .unwrap();
    let zero = Imperfections {
        seed: 5,
        ..Imperfections::default()
    };
    let mut b = new();
    let (r, _, _) = run_sampled_over(
        &mut b,
        &law,
        H,
        T,
        &Impairment::default(),
        &Default::default(),
        &mut zero.hardware(),
        &mut (),
        &mut |_| {},
    );
    r.unwrap();
    assert_eq!(a.time(), b.time());
    assert_eq!(bits(a.state().into()), bits(b.state().into()));
    assert_eq!(a.transitions(), b.transitions());
    assert!(a.tilts() >= 6);
}

/// `mass_error = 0.05` makes the plant's arm 1.05 kg: the same run, bit for bit, as a plant
/// given that arm mass in its own parameters while the controller keeps the paper's; and not
/// the perfect run.
#[test]
fn the_mass_error_is_a_plant_with_a_heavier_arm() {
    let opts = |e: f64| SimOptions {
        imperfect: Some(Imperfections {
            mass_error: e,
            ..Imperfections::default()
        }),
        ..SimOptions::default()
    };
    let by_error = simulate(&sampled(), opts(0.05)).unwrap();
    let by_file = simulate(
        &Scenario {
            plant_params: Some(Params {
                m_l: 1.05,
                ..Params::default()
            }),
            ..sampled()
        },
        SimOptions::default(),
    )
    .unwrap();
    let perfect = simulate(&sampled(), SimOptions::default()).unwrap();
    assert_eq!(
        bits(by_error.final_state.x),
        bits(by_file.final_state.x),
        "{:?} vs {:?}",
        by_error.final_state,
        by_file.final_state
    );
    assert_eq!(by_error.events, by_file.events);
    let d = (0..4)
        .map(|i| (by_error.final_state.x[i] - perfect.final_state.x[i]).abs())
        .fold(0.0, f64::max);
    assert!(d > 1e-3, "a 5 % heavier arm changed the state by only {d}");
    assert!(by_error.imperfections.is_some() && by_file.imperfections.is_none());
    // The continuous coupling takes a mass error (it needs no sampling).
    let cont = simulate(
        &Scenario {
            duration: 1.0,
            ..Scenario::default()
        },
        opts(0.05),
    );
    assert!(cont.is_ok(), "{cont:?}");
}

/// The sensor noise has its own random stream (2 of the seed): the links (streams 0 and 1)
/// lose the same states and torques with and without it, although the trajectories differ.
#[test]
fn noise_does_not_change_the_network_draws() {
    let net = Impairment {
        state: LinkSpec {
            loss: 0.05,
            ..LinkSpec::default()
        },
        torque: LinkSpec {
            delay: 0.001,
            loss: 0.05,
            ..LinkSpec::default()
        },
        seed: 21,
        max_age: 10,
    };
    let run = |noise: [f64; 4]| {
        simulate(
            &sampled(),
            SimOptions {
                network: Some(net),
                imperfect: Some(Imperfections {
                    noise,
                    seed: 21,
                    ..Imperfections::default()
                }),
                ..SimOptions::default()
            },
        )
        .unwrap()
    };
    let quiet = run([0.0; 4]);
    let noisy = run([1e-3, 1e-3, 1e-2, 1e-2]);
    let (q, n) = (quiet.network.unwrap(), noisy.network.unwrap());
    assert!(q.states_lost > 0 && q.torques_lost_on_link > 0, "{q:?}");
    assert_eq!(q.states_lost, n.states_lost);
    assert_eq!(q.torques_lost_on_link, n.torques_lost_on_link);
    assert_eq!(q.age_histogram, n.age_histogram);
    assert_ne!(quiet.final_state.x, noisy.final_state.x);
}

/// Sensors and actuators need a sampled loop; bad settings are refused naming the flag.
#[test]
fn continuous_coupling_refuses_sensors_and_bad_values_name_the_flag() {
    let cont = Scenario {
        duration: 1.0,
        ..Scenario::default()
    };
    let e = simulate(
        &cont,
        SimOptions {
            imperfect: Some(Imperfections {
                torque_lag: 0.01,
                ..Imperfections::default()
            }),
            ..SimOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("--control-period") && e.contains("--torque-lag"),
        "{e}"
    );
    let e = simulate(
        &sampled(),
        SimOptions {
            imperfect: Some(Imperfections {
                encoder_counts: Some(0),
                ..Imperfections::default()
            }),
            ..SimOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("--encoder-counts") && e.contains("[2, 4294967296]"),
        "{e}"
    );
}
