//! `--shard I/N` and `tilting plan merge`: the shards of a sweep, merged in any order, print
//! exactly the bytes the unsharded `--json` run prints (margins, gains; bifurcation but for its
//! wall times), whatever N, including an N larger than the number of points; a shard index out
//! of range, a missing or repeated shard, shards of two grids or two commands, and a torn file
//! are refused with a message naming what is wrong, and nothing is printed as if whole.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::common;
use common::{Scratch, BIN};

fn run(args: &[&str]) -> Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn ok(args: &[&str]) -> Vec<u8> {
    let o = run(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o.stdout
}

/// Runs shard I/N of `args` for every I into `dir`, and returns the files, last shard first.
fn shards(dir: &Path, tag: &str, args: &[&str], n: usize) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = (0..n)
        .map(|i| {
            let shard = format!("{i}/{n}");
            let mut a = args.to_vec();
            a.extend(["--shard", &shard]);
            let p = dir.join(format!("{tag}-{i}-of-{n}.json"));
            std::fs::write(&p, ok(&a)).unwrap();
            p
        })
        .collect();
    files.reverse();
    files
}

fn merge(files: &[PathBuf]) -> Output {
    Command::new(BIN)
        .args(["plan", "merge"])
        .args(files)
        .output()
        .unwrap()
}

/// A small survey of every map (20 tilts): points that survive and points that fail quickly
/// (a 20 ms delay, 50 Hz), lossy points whose random streams are seeded, noisy robots, and
/// the robot rows' bisections (the arm-mass band, Coulomb friction, the estimators' noise).
const MARGINS: &[&str] = &[
    "plan",
    "margins",
    "--tilts",
    "20",
    "--delays",
    "0,0.02",
    "--losses",
    "0,0.2",
    "--rates",
    "1000,50",
    "--angle-noises",
    "0,0.003",
    "--rate-noises",
    "0.02",
    "--mass-errors",
    "0,1",
    "--seed",
    "7",
    "--param-bands",
    "m_l",
    "--param-span",
    "0.1",
    "--viscous-span",
    "0",
    "--coulomb-span",
    "0.3",
    "--noise-span",
    "0.005",
    "--encoder-bits",
    "none",
    "--bisections",
    "2",
];

#[test]
fn margins_shards_merge_to_the_whole_run_bit_for_bit() {
    let dir = Scratch::new("shard-margins");
    let mut whole_args = MARGINS.to_vec();
    whole_args.push("--json");
    let whole = ok(&whole_args);
    // 25 units (17 points, 8 searches): 3 shards of 8 or 9, and 30 shards of which 5 are
    // empty.
    for n in [1, 3, 30] {
        let files = shards(dir.path(), "m", MARGINS, n);
        let o = merge(&files);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&whole),
            "N = {n}"
        );
    }
    // The survey really has lossy and noisy points, and both verdicts.
    let v: serde_json::Value = serde_json::from_slice(&whole).unwrap();
    let survived: Vec<bool> = v["delay_loss"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["survived"].as_bool().unwrap())
        .collect();
    assert!(
        survived.contains(&true) && survived.contains(&false),
        "{survived:?}"
    );
    assert_eq!(v["robot"]["edges"].as_array().unwrap().len(), 8);

    // Incomplete, repeated, mixed: refused, nothing on stdout.
    let files = shards(dir.path(), "m", MARGINS, 3);
    let refused = |files: &[PathBuf], want: &str| {
        let o = merge(files);
        assert_eq!(o.status.code(), Some(2), "{want}");
        assert!(o.stdout.is_empty(), "{want}: printed {:?}", o.stdout);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{want}: {err}");
    };
    refused(&files[..2], "shards missing: 0 of 3");
    refused(
        &[files[0].clone(), files[0].clone(), files[1].clone()],
        "is given twice",
    );
    let mut other = MARGINS.to_vec();
    other[5] = "0,0.01";
    let o = shards(dir.path(), "other", &other, 3);
    refused(
        &[files[0].clone(), files[1].clone(), o[2].clone()],
        "different grids (`delays[1]` differs: 0.02 and 0.01)",
    );
    let two = shards(dir.path(), "two", MARGINS, 2);
    refused(
        &[files[0].clone(), two[0].clone()],
        "split the sweep differently",
    );
    // A shard whose process died before the end leaves an empty or torn file.
    let torn = dir.path().join("torn.json");
    let text = std::fs::read(&files[0]).unwrap();
    std::fs::write(&torn, &text[..text.len() / 2]).unwrap();
    refused(
        &[torn, files[1].clone(), files[2].clone()],
        "is not a shard file",
    );
}

#[test]
fn bifurcation_and_gains_shards_merge_to_the_whole_run() {
    let dir = Scratch::new("shard-sweeps");
    let gains = [
        "plan",
        "gains",
        "--kp-from",
        "80",
        "--kp-to",
        "120",
        "--kp-step",
        "20",
        "--kd-from",
        "10",
        "--kd-to",
        "12",
        "--kd-step",
        "1",
    ];
    let mut whole = gains.to_vec();
    whole.push("--json");
    let whole = ok(&whole);
    let files = shards(dir.path(), "g", &gains, 2);
    let o = merge(&files);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(o.stdout, whole);

    let bif = [
        "plan",
        "bifurcation",
        "--k-from",
        "1500",
        "--k-to",
        "1540",
        "--k-step",
        "10",
        "--tilts",
        "60",
        "--keep",
        "20",
    ];
    let mut whole = bif.to_vec();
    whole.push("--json");
    let strip = |bytes: &[u8]| {
        let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
        // Wall times are the one thing that differs between two runs.
        v.as_object_mut().unwrap().remove("timing").unwrap();
        v.to_string()
    };
    let whole = strip(&ok(&whole));
    let files = shards(dir.path(), "b", &bif, 3);
    let o = merge(&files);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(strip(&o.stdout), whole);
    let v: serde_json::Value = serde_json::from_str(&whole).unwrap();
    assert_eq!(v["rows"].as_array().unwrap().len(), 5);

    // Shards of two commands do not merge.
    let g = shards(dir.path(), "g", &gains, 2);
    let o = merge(&[files[0].clone(), g[0].clone()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(o.stdout.is_empty());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("shards of different sweeps"), "{err}");
}

#[test]
fn shard_flags_out_of_range_are_refused() {
    for (shard, want) in [
        ("3/3", "the shard index I must be in 0..=2"),
        ("0/0", "N must be in 1..="),
        ("1", "expected I/N"),
        ("-1/2", "expected I/N"),
    ] {
        let o = run(&["plan", "gains", "--shard", shard]);
        assert_eq!(o.status.code(), Some(2), "{shard}");
        assert!(o.stdout.is_empty());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(want), "{shard}: {err}");
    }
    let o = run(&["plan", "margins", "--shard", "0/2", "--plot", "x.png"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("`--plot`"));
}
