//! `tilting plan orbit --peak P --calibrate RUN_DIR`, end to end: a plan, a `tilting live` run of
//! it in lockstep on our own plant (the robot *is* the model here), and the plan calibrated from
//! that run's directory (its robot.toml's `[law]`, its run.mcap's tilts).

use std::process::Command;
use tilting_tests::*;

/// `tilting plan orbit --params robot.toml --peak 0.018 --control-period 0.001 --json ARGS` in
/// `dir`.
fn plan_orbit(args: &[&str], dir: &std::path::Path) -> std::process::Output {
    Command::new(bin("tilting"))
        .args(["plan", "orbit", "--params", "robot.toml", "--peak", "0.018"])
        .args(["--control-period", "0.001", "--json"])
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run tilting plan orbit")
}

/// [`plan_orbit`]'s JSON, which must succeed.
fn plan_json(args: &[&str], dir: &std::path::Path) -> serde_json::Value {
    let o = plan_orbit(args, dir);
    assert!(
        o.status.success(),
        "plan orbit {args:?}: {}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("plan orbit --json")
}

/// Where the robot is the model, the calibration finds no bias beyond the sampled loop's
/// scatter of its means (the run averages about 90 tilts, the model's loop 200 from another
/// tilt on: 1.5 % of the peak allows that), and the calibrated `E_av` stays within what such a
/// bias moves it (5 mJ: 0.01 J moves this orbit's peak by about 5 %). A trimmed run is refused
/// naming the key.
#[test]
fn a_run_of_the_model_itself_calibrates_to_no_bias() {
    let _turn = realtime_turn();
    let dir = Scratch::new("calibrate");
    std::fs::write(dir.path().join("robot.toml"), "impact = \"physical\"\n").unwrap();
    let plan = plan_json(&[], dir.path());
    std::fs::write(dir.path().join("plan.json"), plan.to_string()).unwrap();
    let e0 = plan["energy_avg_adaptation"].as_f64().unwrap();
    let out = dir.path().join("run");
    let plant_cmd = format!("{} --clock lockstep", bin("tilting-plant").display());
    let o = Command::new(bin("tilting"))
        .args(["live", "--duration", "30", "--robot", &robot("calibrate")])
        .args(["--plant-cmd", &plant_cmd, "--start", "orbit"])
        .args(["--params", "robot.toml", "--plan", "plan.json", "--out"])
        .arg(&out)
        .current_dir(dir.path())
        .output()
        .expect("run tilting live");
    assert!(
        o.status.success(),
        "live: {}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stderr)
    );
    let cal = plan_json(&["--calibrate", "run"], dir.path());
    let c = &cal["calibration"];
    let run = &c["runs"][0];
    let tilts = run["tilts"].as_u64().unwrap();
    let bias = run["bias"].as_f64().unwrap();
    assert!(tilts >= 80, "{c}");
    assert!(bias.abs() < 0.015 * 0.018, "{c}");
    assert_eq!(run["energy_avg"].as_f64(), Some(e0), "{c}");
    let e1 = cal["energy_avg_adaptation"].as_f64().unwrap();
    assert!((e1 - e0).abs() < 5e-3, "{e0} -> {e1}: {c}");
    assert!(c["period"].as_f64().unwrap() > 0.5, "{c}");

    // The same run said to be trimmed: refused, naming the key (exit 2, usage).
    let file = out.join("robot.toml");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(
        &file,
        text.replace("[law]\n", "[law]\norbit_peak = 0.018\n"),
    )
    .unwrap();
    let o = plan_orbit(&["--calibrate", "run"], dir.path());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("law.orbit_peak"), "{err}");
}
