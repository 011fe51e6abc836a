//! `tilting live` hands its children the run's robot file (`OUT/robot.toml`), not its settings
//! spelled out again as flags: the controller reads its law and model from it, and a
//! `--plant-cmd` plant is given the file's link and sensor keys as the flags `tilting-plant`
//! takes. A run from the file is the run of the flags.

use std::process::Command;
use tilting_tests::*;

/// `tilting live` in lockstep (its plant `tilting-plant --clock lockstep` as a `--plant-cmd`,
/// given the run file's `[network]` and `[sensors]` keys as flags; the controller reading the
/// run file) over an emulated link with noisy, quantised sensors and other gains ends in the
/// state of `tilting simulate` with the same flags, bit for bit, with the same network
/// counters: the file carried every setting to the nodes unchanged. The run file holds the
/// link's keys as given, and the controller was given no law flags.
#[test]
fn live_in_lockstep_from_the_run_file_equals_simulate() {
    let _turn = realtime_turn();
    let dir = Scratch::new("runfile");
    let out = dir.path().join("out");
    let flags = [
        "--kd",
        "14",
        "--energy-avg",
        "19.963439703027",
        "--state-delay",
        "0.0005",
        "--torque-delay",
        "0.001",
        "--jitter",
        "exp:0.0007",
        "--loss",
        "0.03",
        "--seed",
        "11",
        "--noise-alpha",
        "0.0001",
        "--encoder-counts",
        "4096",
    ];
    let plant_cmd = format!("{} --clock lockstep", bin("tilting-plant").display());
    let o = Command::new(bin("tilting"))
        .args(["live", "--duration", "2", "--robot", &robot("runfile")])
        .args(["--plant-cmd", &plant_cmd, "--out"])
        .arg(&out)
        .args(flags)
        .current_dir(dir.path())
        .output()
        .expect("run tilting live");
    let logs = || {
        let mut s = format!(
            "--- stdout ---\n{}\n--- stderr ---\n{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        for f in ["plant.log", "controller.log", "robot.toml"] {
            let t = std::fs::read_to_string(out.join(f)).unwrap_or_default();
            s.push_str(&format!("\n--- {f} ---\n{t}"));
        }
        s
    };
    assert!(o.status.success(), "live: {}\n{}", o.status, logs());
    let run_file = std::fs::read_to_string(out.join("robot.toml")).unwrap();
    for line in ["torque_delay = 0.001", "encoder_counts = 4096", "kd = 14"] {
        assert!(
            run_file.lines().any(|l| l.starts_with(line)),
            "{line}:\n{run_file}"
        );
    }
    let plant_json = std::fs::read_to_string(out.join("plant.json")).unwrap();
    let plant: PlantSummary = plant_json
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .unwrap_or_else(|| panic!("no plant summary\n{}", logs()));

    let mut args = vec!["--control-period", "0.001", "--duration", "2"];
    args.extend(flags);
    let want = simulate_json(&args);
    assert_eq!(plant.time, 2.0);
    for (i, (g, w)) in plant.x.iter().zip(&want.final_state.x).enumerate() {
        assert_eq!(g.to_bits(), w.to_bits(), "component {i}: {g} vs {w}");
    }
    let got_net = plant.network.expect("the plant's network counters");
    assert!(
        got_net.states_lost > 0 && got_net.torques_late > 0,
        "{got_net:?}"
    );
    assert_eq!(Some(got_net), want.network);
}
