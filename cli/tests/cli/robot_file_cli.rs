//! The robot file at the front door (issue 30): `tilting config` prints a file that reads back
//! the same; an unknown key and a bad value are refused naming the key; a flag overrides a key;
//! a run from the file equals the same run from flags, bit for bit; `identify --out` writes into
//! a robot file.

use crate::common;

use common::{Scratch, BIN};
use std::path::Path;
use std::process::{Command, Output};
use tilting_plant::robot_file::read_doc;

fn tilting(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().expect("run tilting")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

const ROBOT: &str = "\
[robot]
m_f = 0.85
impact = \"physical\"
restitution = 0.1
i_f = 0.02

[law]
kd = 13.5
k = 400
energy_avg = 19.9
reference = \"hold\"

[run]
duration = 3
control_period = 0.001

[network]
delay = 0.002
jitter = \"exp:0.0005\"
loss = 0.05
seed = 7

[sensors]
noise_alpha = 0.001
encoder_counts = 4096

[deploy]
name = \"r1\"
rate = 500
";

#[test]
fn config_round_trips_and_flags_override_keys() {
    let s = Scratch::new("robot-config");
    let f = s.file("robot.toml", ROBOT);
    let once = tilting(&["config", &f]);
    assert!(once.status.success(), "{}", stderr(&once));
    let printed = stdout(&once);
    let again_path = s.file("again.toml", &printed);
    let twice = tilting(&["config", &again_path]);
    assert!(twice.status.success(), "{}", stderr(&twice));
    assert_eq!(stdout(&twice), printed, "config of config's output differs");
    for want in [
        "kd = 13.5",
        "m_f = 0.85",
        "jitter = \"exp:0.0005\"",
        "rate = 500",
    ] {
        assert!(printed.contains(want), "{want} missing:\n{printed}");
    }
    // A flag replaces its key, and only it.
    let over = tilting(&[
        "config",
        &f,
        "--kd",
        "12.25",
        "--robot",
        "r2",
        "--max-age",
        "20",
    ]);
    assert!(over.status.success(), "{}", stderr(&over));
    let text = stdout(&over);
    let out = s.file("over.toml", &text);
    let doc = read_doc(Path::new(&out)).unwrap();
    assert_eq!(doc["law"]["kd"].as_float(), Some(12.25), "{text}");
    assert_eq!(doc["law"]["k"].as_integer(), Some(400), "{text}");
    assert_eq!(doc["deploy"]["name"].as_str(), Some("r2"), "{text}");
    assert_eq!(doc["network"]["max_age"].as_integer(), Some(20), "{text}");
    assert_eq!(doc["network"]["delay"].as_float(), Some(0.002), "{text}");
    // `--write` writes the file (nothing on stdout); `--out` stays the run directory's key.
    let written = s.path().join("written.toml");
    let w = written.display().to_string();
    let o = tilting(&[
        "config",
        &f,
        "--kd",
        "12.25",
        "--robot",
        "r2",
        "--max-age",
        "20",
        "--write",
        &w,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));
    assert_eq!(std::fs::read_to_string(&written).unwrap(), text);
    let o = tilting(&["config", &f, "--out", "runs/r"]);
    let printed = s.file("with-out.toml", &stdout(&o));
    let doc = read_doc(Path::new(&printed)).unwrap();
    let out_key = doc["deploy"]["out"].as_str().unwrap_or_default();
    assert!(out_key.ends_with("runs/r"), "{}", stdout(&o));
}

#[test]
fn unknown_keys_and_bad_values_are_refused_naming_the_key() {
    let s = Scratch::new("robot-bad");
    for (text, want) in [
        ("[law]\nkdd = 3\n", "unknown key `law.kdd`"),
        ("[lw]\nkd = 3\n", "unknown section `[lw]`"),
        ("[law]\nkd = -3\n", "`law.kd`"),
        ("[robot]\nm_f = -1\n", "`robot.m_f` = -1"),
        ("[network]\nloss = 1.5\n", "`network.loss`"),
        ("[sensors]\nmeasure = \"all\"\n", "`sensors.measure`"),
        ("[deploy]\nrealtime = 120\n", "`deploy.realtime`"),
    ] {
        let f = s.file("bad.toml", text);
        for cmd in ["config", "simulate", "live"] {
            let o = tilting(&[cmd, &f]);
            assert_eq!(o.status.code(), Some(2), "{cmd} {text}: {}", stderr(&o));
            assert!(stderr(&o).contains(want), "{cmd} {text}: {}", stderr(&o));
        }
    }
    // The range is named too.
    let f = s.file("bad.toml", "[network]\nloss = 1.5\n");
    let e = stderr(&tilting(&["config", &f]));
    assert!(e.contains("1.5") && e.contains("[0, 1]"), "{e}");
}

/// The JSON report without its wall-clock time.
fn report(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", stderr(o));
    let mut v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    v["stats"]["wall_time_s"] = serde_json::Value::Null;
    v
}

#[test]
fn a_run_from_the_file_is_the_run_from_flags_bit_for_bit() {
    let s = Scratch::new("robot-run");
    let p = s.file(
        "p.toml",
        "m_f = 0.85\nimpact = \"physical\"\nrestitution = 0.1\ni_f = 0.02\n",
    );
    let f = s.file("robot.toml", ROBOT);
    let from_file = report(&tilting(&["simulate", &f, "--json"]));
    let from_flags = report(&tilting(&[
        "simulate",
        "--params",
        &p,
        "--kd",
        "13.5",
        "--k",
        "400",
        "--energy-avg",
        "19.9",
        "--reference",
        "hold",
        "--duration",
        "3",
        "--control-period",
        "0.001",
        "--delay",
        "0.002",
        "--jitter",
        "exp:0.0005",
        "--loss",
        "0.05",
        "--seed",
        "7",
        "--noise-alpha",
        "0.001",
        "--encoder-counts",
        "4096",
        "--json",
    ]));
    assert_eq!(from_file, from_flags);
    // A flag over the file changes the run (and is the run of the same flags).
    let over = report(&tilting(&["simulate", &f, "--json", "--seed", "8"]));
    assert_ne!(over, from_file);
}

#[test]
fn identify_writes_into_a_robot_file_from_its_prior() {
    let s = Scratch::new("robot-identify");
    let f = s.file(
        "robot.toml",
        "[plant]\nm_f = 0.85\nm_l = 1.1\nl_c = 1.8\ni_l = 0.08\n\n[prior]\nm_l = 1.1\n\n\
         [run]\nduration = 10\ncontrol_period = 0.001\n",
    );
    let rec = s.path().join("rec.mcap").display().to_string();
    let o = tilting(&["simulate", &f, "--record", &rec]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = tilting(&["identify", &rec, "--out", &f]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc = read_doc(Path::new(&f)).unwrap();
    let robot = &doc["robot"];
    let m_f = robot["m_f"].as_float().unwrap();
    assert!((m_f - 0.85).abs() < 1e-3, "{m_f}");
    // The prior's m_l, and the other tables kept.
    assert_eq!(robot["m_l"].as_float(), Some(1.1));
    assert_eq!(doc["run"]["duration"].as_integer(), Some(10));
    assert_eq!(doc["plant"]["l_c"].as_float(), Some(1.8));
}
