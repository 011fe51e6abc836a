//! A real transport delay, not an emulated one: plant and controller run unchanged (no
//! impairment flags) in real time, with the controller's zenoh TCP link passing through a
//! delaying proxy (`tilting_tests::proxy`, 1 ms each way: a 2 ms round trip at 1 kHz). The
//! ages of the applied torques and the orbit must agree with the emulator set to the same delay
//! (`tilting simulate --delay 0.001`, where every torque is exactly 2 periods old).
//!
//! Tolerances: the real round trip adds the controller's computation and the zenoh stack to the
//! 2 ms (measured 0.1-0.4 ms on loopback), so a real age is 2 or 3 periods where the emulator
//! says 2: the median age must be within one period. The orbit must keep tilting, alternating,
//! with as many tilts as the emulated run (within one) and its last peaks within 15 % of the
//! emulated ones (the shift of a third of a period in the real delay moves them by a few %).

use std::time::Duration;
use tilting_tests::proxy::DelayProxy;
use tilting_tests::*;

#[test]
fn over_a_delaying_proxy_the_loop_matches_the_emulator() {
    let _turn = realtime_turn();
    let dir = Scratch::new("proxy");
    let port = free_port();
    let robot = robot("proxy");
    let proxy = DelayProxy::start(
        format!("127.0.0.1:{port}").parse().unwrap(),
        Duration::from_millis(1),
        Duration::ZERO,
    );
    let mut plant = Proc::spawn(
        "plant",
        &bin("tilting-plant"),
        &plant_args(&robot, port, &["--duration", "5"]),
        dir.path(),
    );
    let mut ctl = Proc::spawn(
        "controller",
        &bin("tilting-controller"),
        &peer_args(&robot, proxy.port, &[]),
        dir.path(),
    );
    let status = plant.expect_exit(Duration::from_secs(60));
    assert!(status.success(), "plant: {status}\n{}", plant.logs());
    ctl.interrupt(Duration::from_secs(10));
    let real = plant.plant_summary();
    let through = proxy.bytes.load(std::sync::atomic::Ordering::Relaxed);
    drop(proxy);
    eprintln!("real: {real:?}\nproxy forwarded {through} bytes");
    assert!(
        through > 5000 * 16,
        "the torques did not cross the proxy: {through} bytes"
    );

    let v = simulate_json(&[
        "--control-period",
        "0.001",
        "--duration",
        "5",
        "--delay",
        "0.001",
    ]);
    let hist = v
        .network
        .as_ref()
        .expect("network counters")
        .age_histogram
        .clone();
    let emulated_age = hist
        .iter()
        .enumerate()
        .max_by_key(|(_, n)| **n)
        .map(|(a, _)| a as f64)
        .unwrap();
    assert_eq!(emulated_age, 2.0, "{hist:?}");
    let age = real.age_periods.expect("ages");
    assert!(
        (age.p50 - emulated_age).abs() <= 1.0,
        "real median age {} periods, emulated {emulated_age}",
        age.p50
    );
    assert_eq!(real.watchdog_trips, 0, "{real:?}");

    let peaks: Vec<f64> = v.tilt_peaks.iter().map(|p| p.alpha).collect();
    let emulated_tilts = v
        .events
        .iter()
        .filter(|e| e.from == tilting_proto::Mode::Flat)
        .count() as u64;
    assert!(
        real.tilts.abs_diff(emulated_tilts) <= 1,
        "real {} tilts, emulated {emulated_tilts}",
        real.tilts
    );
    let real_peaks: Vec<f64> = real.tilt_peaks.iter().map(|p| p[1]).collect();
    for w in real_peaks.windows(2) {
        assert!(w[0] * w[1] < 0.0, "tilts alternate: {real_peaks:?}");
    }
    let mean_abs = |v: &[f64]| v.iter().map(|x| x.abs()).sum::<f64>() / v.len() as f64;
    let (r, e) = (
        mean_abs(&real_peaks[real_peaks.len().saturating_sub(4)..]),
        mean_abs(&peaks[peaks.len().saturating_sub(4)..]),
    );
    assert!(
        (r / e - 1.0).abs() < 0.15,
        "last peaks: real {r:.4} rad, emulated {e:.4} rad"
    );
}
