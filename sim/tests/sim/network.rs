//! The sampled loop over an emulated network against independent implementations of its
//! semantics (`tilting_sim::network`): a perfect network changes nothing, a constant delay `D`
//! makes the torque computed from the state at `t_k` act from the first sample instant at or
//! after `t_k + D` (zero torque before), a link that loses everything leaves the plant without
//! torque, and the counters add up.

use tilting_link::{Jitter, LinkSpec};
use tilting_plant::Plant;
use tilting_sim::closed_loop::run_sampled;
use tilting_sim::{run_sampled_over, Impairment, LoopOptions, Scenario};

const H: f64 = 0.001;
const T: f64 = 2.0;

fn plant(sc: &Scenario) -> Plant {
    Plant::new(sc.sim_config(), 0.0, sc.mode, sc.initial_state()).unwrap()
}

fn over(imp: Impairment) -> (Plant, tilting_sim::NetStats) {
    let sc = Scenario::default();
    let law = sc.controller().unwrap();
    let mut p = plant(&sc);
    let (r, n, st) = run_sampled_over(
        &mut p,
        &law,
        H,
        T,
        &imp,
        &LoopOptions::default(),
        &mut Default::default(),
        &mut (),
        &mut |_| {},
    );
    r.unwrap();
    assert_eq!(n, 2000);
    (p, st)
}

/// The zero-order hold written out: torque `j` is the law at the state sampled `lag` periods
/// earlier, zero for the first `lag` periods.
fn delayed_by(lag: usize) -> Plant {
    let sc = Scenario::default();
    let law = sc.controller().unwrap();
    let mut p = plant(&sc);
    let mut computed: Vec<f64> = Vec::new();
    for j in 0..2000usize {
        let t = j as f64 * H;
        computed.push(tilting_plant::TorqueLaw::torque(
            &law,
            t,
            p.mode(),
            &p.state(),
        ));
        let tau = if j >= lag { computed[j - lag] } else { 0.0 };
        let next = if j == 1999 { T } else { (j + 1) as f64 * H };
        p.advance_held(tau, next, &mut ()).unwrap();
    }
    p
}

fn same(a: &Plant, b: &Plant) {
    assert_eq!(a.time(), b.time());
    assert_eq!(a.mode(), b.mode());
    let (x, y) = (a.state(), b.state());
    for i in 0..4 {
        assert_eq!(
            x[i].to_bits(),
            y[i].to_bits(),
            "component {i}: {} vs {}",
            x[i],
            y[i]
        );
    }
}

#[test]
fn a_perfect_network_is_the_plain_sampled_loop() {
    let sc = Scenario::default();
    let law = sc.controller().unwrap();
    let mut p = plant(&sc);
    run_sampled(&mut p, &law, H, T, &mut (), &mut |_| {})
        .0
        .unwrap();
    let (q, st) = over(Impairment {
        max_age: 10,
        ..Impairment::default()
    });
    same(&p, &q);
    assert_eq!(st.torques_applied, 2000);
    assert_eq!(st.torques_late, 0);
    assert_eq!(st.age_histogram, vec![2000]);
}

/// D = 3 periods split over the two directions, and D = 2.5 periods (which acts at the same
/// instants: the first at or after t_k + D), against the hold written out with a lag of 3.
#[test]
fn a_constant_delay_acts_from_the_first_sample_instant_at_or_after_t_plus_d() {
    let want = delayed_by(3);
    for (up, down) in [(0.001, 0.002), (0.0, 0.003), (0.0015, 0.001)] {
        let (got, st) = over(Impairment {
            state: LinkSpec {
                delay: up,
                ..LinkSpec::default()
            },
            torque: LinkSpec {
                delay: down,
                ..LinkSpec::default()
            },
            seed: 1,
            max_age: 10,
        });
        same(&got, &want);
        assert_eq!(st.periods_before_first_torque, 3, "D = {up} + {down}");
        assert_eq!(st.torques_late, st.torques_applied);
        assert_eq!(st.age_histogram.iter().sum::<u64>(), st.torques_applied);
        assert_eq!(st.age_histogram.len() - 1, 3);
    }
    // And a lag the plant refuses: max_age 2 never applies a 3-period-old torque.
    let (_, st) = over(Impairment {
        torque: LinkSpec {
            delay: 0.003,
            ..LinkSpec::default()
        },
        max_age: 2,
        ..Impairment::default()
    });
    assert_eq!(st.torques_applied, 0);
    assert_eq!(st.periods_before_first_torque, 2000);
}

#[test]
fn a_link_that_loses_everything_leaves_zero_torque() {
    let (got, st) = over(Impairment {
        torque: LinkSpec {
            loss: 1.0,
            ..LinkSpec::default()
        },
        max_age: 10,
        ..Impairment::default()
    });
    // Zero torque for the whole run: a lag longer than the run.
    same(&got, &delayed_by(usize::MAX));
    assert_eq!(st.torques_lost_on_link, 2000);
    assert_eq!(st.torques_applied, 0);
}

/// Every answer that came back is accounted for exactly once (applied, superseded, reordered,
/// too old, or still in flight at the end: at most a handful with this jitter), and the same
/// seed gives the same run.
#[test]
fn with_jitter_and_loss_every_answer_is_counted_once_and_a_seed_repeats() {
    let imp = Impairment {
        state: LinkSpec {
            delay: 0.0005,
            jitter: Some(Jitter::Exp { mean: 0.001 }),
            loss: 0.05,
            burst: None,
        },
        torque: LinkSpec {
            delay: 0.0005,
            jitter: Some(Jitter::Uniform { max: 0.002 }),
            loss: 0.05,
            burst: None,
        },
        seed: 9,
        max_age: 10,
    };
    let (a, st) = over(imp);
    let (b, st2) = over(imp);
    same(&a, &b);
    assert_eq!(st, st2);
    let back = 2000 - st.states_lost - st.torques_lost_on_link;
    let counted =
        st.torques_applied + st.torques_superseded + st.torques_reordered + st.torques_too_old;
    assert!(counted <= back && back - counted <= 20, "{st:?}");
    assert!(
        st.torques_reordered + st.torques_superseded > 0,
        "jitter reorders: {st:?}"
    );
    // Loss rates near 5 % (binomial standard deviation about 0.5 %).
    assert!(
        (st.states_lost as f64 / 2000.0 - 0.05).abs() < 0.02,
        "{st:?}"
    );
}
