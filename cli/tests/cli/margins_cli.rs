//! Runs the built `tilting plan margins` on a small grid: the JSON states its criteria, the
//! maps bracket what `simulate` shows (no delay survives, 10 ms does not unless the controller
//! predicts; 1 kHz survives, 75 Hz only with samples on events, 50 Hz not at all), the PNG is
//! drawn, and bad lists are refused naming the flag and the range.

use std::process::Command;
use tilting_planner::margins::{Imperfection, MarginsReport, Point};

use crate::common;
use common::{Scratch, BIN};

#[test]
fn a_small_map_with_its_criteria_and_plot() {
    let dir = Scratch::new("margins");
    let png = dir.path().join("m.png");
    let o = Command::new(BIN)
        .args([
            "plan",
            "margins",
            "--tilts",
            "20",
            "--delays",
            "0,0.01,0.02",
            "--losses",
            "0",
        ])
        .args(["--rates", "1000,75,50", "--json", "--plot"])
        .arg(&png)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: MarginsReport = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        v.survives_means.contains("20 tilts"),
        "{}",
        v.survives_means
    );
    let survived = |map: &[Point]| -> Vec<bool> { map.iter().map(|p| p.survived).collect() };
    // Plain: 10 ms is past the 9 ms at which the orbit falls (see `simulate`).
    assert_eq!(survived(&v.delay_loss), [true, false, false]);
    // Predicting over the delay it measures, the controller keeps the orbit at 10 ms.
    let predict = survived(&v.delay_loss_predict);
    assert!(predict[0] && predict[1], "{predict:?}");
    assert_eq!(v.largest_delay, Some(0.0));
    assert!(v.largest_delay_predict.is_some_and(|d| d >= 0.01), "{v:?}");
    // 75 Hz leaves the landed plate waiting up to 13 ms for its next sample and falls; an
    // extra sample at each landing keeps it.
    assert_eq!(survived(&v.rates), [true, false, false]);
    assert_eq!(survived(&v.rates_events), [true, true, false]);
    assert_eq!(v.lowest_rate, Some(1000.0));
    assert_eq!(v.lowest_rate_events, Some(75.0));
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000);
}

#[test]
fn bad_lists_name_the_flag_and_the_range() {
    for (args, want) in [
        (
            vec!["--losses", "0,1.5"],
            "`--losses` value 1.5: allowed 0 to 1",
        ),
        (
            vec!["--delays", "-0.001"],
            "`--delays` value -0.001: allowed 0 to 60",
        ),
        (
            vec!["--rates", "0"],
            "`--rates` value 0: allowed 1 to 10000",
        ),
        (vec!["--tilts", "5"], "`--tilts` = 5: allowed 10 to 100000"),
    ] {
        let o = Command::new(BIN)
            .args(["plan", "margins"])
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

/// The robot maps: the perfect robot survives, angle noise of 0.2 rad and an arm twice as heavy
/// as modelled do not (20 tilts); the JSON carries the maps and their ranges, the second PNG is
/// drawn beside the first, and bad lists are refused naming the flag and the range.
#[test]
fn robot_maps_with_their_ranges_and_plot() {
    let dir = Scratch::new("margins-robot");
    let png = dir.path().join("m.png");
    let o = Command::new(BIN)
        .args([
            "plan", "margins", "--tilts", "20", "--delays", "0", "--losses", "0", "--rates", "1000",
        ])
        .args(["--angle-noises", "0,0.2", "--rate-noises", "0"])
        .args(["--mass-errors=-0.001,0,1", "--json", "--plot"])
        .arg(&png)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: MarginsReport = serde_json::from_slice(&o.stdout).unwrap();
    let r = &v.robot;
    let angle = &r.angle_noise;
    assert_eq!(angle.len(), 2);
    assert!(angle[0].survived, "{:?}", angle[0]);
    assert!(!angle[1].survived, "{:?}", angle[1]);
    assert_eq!(angle[1].imperfection, Imperfection::AngleNoise);
    assert_eq!(r.largest_angle_noise, Some(0.0));
    assert_eq!(r.largest_rate_noise, Some(0.0));
    assert_eq!(r.mass_error_range, Some((-0.001, 0.0)));
    let bytes = std::fs::read(dir.path().join("m-robot.png")).unwrap();
    assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000);

    for (args, want) in [
        (
            vec!["--angle-noises", "0,-0.1"],
            "`--angle-noises` value -0.1: allowed 0 to 10",
        ),
        (
            vec!["--rate-noises", "nan"],
            "`--rate-noises` value NaN: allowed 0 to 10",
        ),
        (
            vec!["--mass-errors=-1"],
            "`--mass-errors` value -1: allowed (-1, 10]",
        ),
    ] {
        let o = Command::new(BIN)
            .args(["plan", "margins"])
            .args(&args)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{args:?}: {err}");
    }
}
