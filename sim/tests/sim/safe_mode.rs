//! `simulate` models the plant's watchdog and safe mode (`tilting_plant::safe`), and refuses a
//! prediction longer than the plant's age limit.

use std::f64::consts::FRAC_PI_2;
use tilting_link::LinkSpec;
use tilting_plant::safe::SafeSettings;
use tilting_plant::Fault;
use tilting_sim::closed_loop::{simulate, SimOptions};
use tilting_sim::network::check_max_age;
use tilting_sim::{Impairment, LoopOptions, Predict, Scenario};

const T: f64 = 0.001;

fn delayed(
    delay: f64,
    max_age: u64,
    safe: Option<SafeSettings>,
    predict: Option<Predict>,
) -> SimOptions {
    SimOptions {
        network: Some(Impairment {
            torque: LinkSpec {
                delay,
                ..LinkSpec::default()
            },
            max_age,
            ..Impairment::default()
        }),
        loop_options: LoopOptions {
            safe,
            predict,
            ..LoopOptions::default()
        },
        ..SimOptions::default()
    }
}

fn scenario(duration: f64) -> Scenario {
    Scenario {
        control_period: T,
        duration,
        ..Scenario::default()
    }
}

/// Every torque arrives 50 periods old, past the default age limit of 10: none is applied.
/// The plant's watchdog trips after its 50th period without one (sample 49, t = 0.049 s) and
/// the safe hold brings the arm upright and the plate down, where the run ends, saying so.
#[test]
fn a_run_without_torques_ends_in_safe_mode_and_says_so() {
    let safe = SafeSettings::default();
    let r = simulate(&scenario(10.0), delayed(0.05, 10, Some(safe), None)).unwrap();
    let Some(Fault::SafeMode { t, watchdog }) = r.fault else {
        panic!("{:?}", r.fault);
    };
    assert_eq!(watchdog, 50);
    assert!((t - 49.0 * T).abs() < 1e-12, "{t}");
    let net = r.network.as_ref().unwrap();
    assert_eq!(net.torques_applied, 0);
    let m = net.safe_mode.unwrap();
    assert_eq!((m.trips, m.since), (1, Some(t)));
    // Samples 49 to 9,999 in safe mode.
    assert_eq!(m.periods, 10_000 - 49);
    // The run went on to its end, as the plant's does, and the hold did its job.
    assert_eq!(r.final_state.t, 10.0);
    let x = r.final_state.x;
    assert_eq!(r.final_state.mode, tilting_plant::Mode::Flat);
    assert!(
        (x[1] - FRAC_PI_2).abs() < 1e-6 && x[3].abs() < 1e-6,
        "{x:?}"
    );
    assert!(!r.trace().stopped_early);
    // Without the watchdog (the library's default) the last torque, none, is held: the arm
    // falls and the plate with it.
    let r = simulate(&scenario(10.0), delayed(0.05, 10, None, None)).unwrap();
    assert!(
        !matches!(r.fault, Some(Fault::SafeMode { .. })),
        "{:?}",
        r.fault
    );
}

/// A watchdog trip the loop recovers from is counted, and is not a fault at the end.
#[test]
fn a_late_first_torque_trips_once_and_the_loop_recovers() {
    let safe = SafeSettings {
        watchdog: 20,
        ..SafeSettings::default()
    };
    // Torques 30 periods late (predicted over, to keep the orbit): the watchdog trips at
    // sample 19; the first torque comes at sample 30.
    let opts = delayed(0.03, 40, Some(safe), Some(Predict::Given(0.03)));
    let r = simulate(&scenario(5.0), opts).unwrap();
    assert!(r.fault.is_none(), "{:?}", r.fault);
    let m = r.network.as_ref().unwrap().safe_mode.unwrap();
    assert_eq!((m.trips, m.periods, m.since), (1, 30 - 19, None));
    assert!((m.entered.unwrap() - 19.0 * T).abs() < 1e-12);
}

#[test]
fn a_prediction_longer_than_the_age_limit_is_refused() {
    // 50 ms at 1 kHz: the answers act 50 periods after their state.
    assert!(check_max_age(0.05, T, 50).is_ok());
    let e = check_max_age(0.05, T, 49).unwrap_err().to_string();
    assert!(
        e.contains("--max-age") && e.contains("--predict") && e.contains(">= 50"),
        "{e}"
    );
    assert!(check_max_age(0.0505, T, 50).is_err());
    assert!(check_max_age(0.0, T, 0).is_ok());
    // And in a run: refused before it starts.
    let opts = delayed(0.05, 10, None, Some(Predict::Given(0.05)));
    let e = simulate(&scenario(1.0), opts).unwrap_err().to_string();
    assert!(e.contains("max_age") && e.contains("--predict"), "{e}");
    let opts = delayed(0.05, 60, None, Some(Predict::Given(0.05)));
    let r = simulate(&scenario(10.0), opts).unwrap();
    assert!(r.fault.is_none() && r.stats.tilts > 15, "{:?}", r.fault);
}
