//! Does serving Foxglove slow the loop? (A benchmark, not a test.)
//!
//! ```sh
//! cargo run --release -p tilting-tests --features bench --example foxglove_bench -- --rounds 3 --seconds 10
//! ```
//!
//! Runs `tilting live --foxglove` for `--seconds` with no client, then the same with one client
//! subscribed to every channel (`tests/python/foxglove_client.py --all`, which decodes and
//! validates every message: a heavy client), alternating for `--rounds` rounds. Prints the
//! plant's loop latency p50/p99 (state published to its torque received, over its last 4096
//! periods) and its deadline misses for each run, the server's counts, and the ratio of the p99s
//! per round (with a client / without), with their median. On a shared machine the load
//! drifts, which is why the runs alternate and the ratio is taken per round.
//!
//! Needs python3 with `websockets`, `jsonschema` and `protobuf`.

use std::path::Path;
use std::process::{Command, Stdio};
use tilting_tests::{bin, free_port, Scratch};

struct Run {
    p50: f64,
    p99: f64,
    misses: u64,
    states: u64,
    received: usize,
}

fn live(seconds: f64, client: bool, dir: &Path, tag: &str) -> anyhow::Result<Run> {
    let port = free_port();
    let out = dir.join(tag);
    let robot = format!("foxbench_{}", std::process::id());
    let json = dir.join(format!("{tag}.json"));
    let mut py = None;
    if client {
        let mut c = Command::new("python3")
            .arg(tilting_tests::workspace_root().join("tests/python/foxglove_client.py"))
            .args([
                "--url",
                &format!("ws://127.0.0.1:{port}"),
                "--robot",
                &robot,
                "--all",
            ])
            .arg("--seconds")
            .arg((seconds + 60.0).to_string())
            .arg("--out")
            .arg(&json)
            .stdout(Stdio::piped())
            .spawn()?;
        let mut line = String::new();
        std::io::BufRead::read_line(
            &mut std::io::BufReader::new(c.stdout.take().expect("piped")),
            &mut line,
        )?;
        anyhow::ensure!(line.trim() == "ready", "the client did not start: {line}");
        py = Some(c);
    }
    let o = Command::new(bin("tilting"))
        .args(["live", "--robot", &robot, "--duration"])
        .arg(seconds.to_string())
        .args(["--foxglove", &format!("127.0.0.1:{port}"), "--out"])
        .arg(&out)
        .output()?;
    let stderr = String::from_utf8_lossy(&o.stderr);
    anyhow::ensure!(o.status.success(), "live failed: {stderr}");
    if let Some(line) = stderr.lines().find(|l| l.contains("Foxglove:")) {
        println!("    {tag}: {}", line.trim());
    }
    let mut received = 0;
    if let Some(mut c) = py {
        anyhow::ensure!(c.wait()?.success(), "the client failed");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json)?)?;
        received = v["states"].as_array().map_or(0, |a| a.len());
    }
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json"))?)?;
    let p = &s["plant"];
    Ok(Run {
        p50: p["latency_us"]["p50"].as_f64().unwrap_or(f64::NAN),
        p99: p["latency_us"]["p99"].as_f64().unwrap_or(f64::NAN),
        misses: p["deadline_misses"].as_u64().unwrap_or(0),
        states: s["record"]["states"].as_u64().unwrap_or(0),
        received,
    })
}

fn main() -> anyhow::Result<()> {
    let mut rounds = 3;
    let mut seconds = 10.0;
    let args: Vec<String> = std::env::args().skip(1).collect();
    for w in args.chunks(2) {
        match (w[0].as_str(), w.get(1)) {
            ("--rounds", Some(v)) => rounds = v.parse()?,
            ("--seconds", Some(v)) => seconds = v.parse()?,
            _ => anyhow::bail!("usage: foxglove_bench [--rounds N] [--seconds S]"),
        }
    }
    let dir = Scratch::new("foxglove-bench");
    let mut ratios = Vec::new();
    println!("live at 1 kHz for {seconds} s per run; loop latency of the plant (us)");
    for r in 0..rounds {
        let none = live(seconds, false, dir.path(), &format!("r{r}-none"))?;
        let one = live(seconds, true, dir.path(), &format!("r{r}-client"))?;
        for (what, x) in [("no client ", &none), ("one client", &one)] {
            println!(
                "round {r} {what}: p50 {:7.1}  p99 {:7.1}  misses {:4}  states {} (client got {})",
                x.p50, x.p99, x.misses, x.states, x.received
            );
        }
        let ratio = one.p99 / none.p99;
        println!("round {r}: p99 ratio (client / none) {ratio:.2}");
        ratios.push(ratio);
    }
    ratios.sort_by(f64::total_cmp);
    println!(
        "median p99 ratio over {rounds} rounds: {:.2} (all: {ratios:.2?})",
        ratios[ratios.len() / 2]
    );
    Ok(())
}
