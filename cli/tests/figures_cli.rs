//! Runs the built `tilting figures` binary: the quick preview writes the five PNGs,
//! `--only` and `--json` select and report, and a bad `--out` or figure number fails clearly.

use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

mod common;
use common::{TempDir, BIN};

const PNG_MAGIC: &[u8] = b"\x89PNG\r\n\x1a\n";

fn figures(args: &[&str]) -> Output {
    Command::new(BIN)
        .arg("figures")
        .args(args)
        .output()
        .expect("cannot run tilting")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Checks that `path` is a PNG of a plausible size (a drawn figure, not an empty canvas).
fn assert_png(path: &Path) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(
        bytes.starts_with(PNG_MAGIC),
        "{} is not a PNG",
        path.display()
    );
    assert!(
        bytes.len() > 20_000,
        "{} is suspiciously small: {} bytes",
        path.display(),
        bytes.len()
    );
}

#[test]
fn quick_run_writes_all_five_figures() {
    let dir = TempDir::new("all");
    // A directory that does not exist yet is created.
    let out = dir.path().join("nested").join("figs");
    let o = figures(&["--quick", "--out", &out.to_string_lossy()]);
    assert!(o.status.success(), "{}", stderr(&o));
    for n in 4..=8 {
        assert_png(&out.join(format!("fig{n}.png")));
    }
    let text = String::from_utf8_lossy(&o.stdout);
    for n in 4..=8 {
        assert!(text.contains(&format!("fig{n}.png")), "{text}");
    }
}

#[test]
fn only_and_json_select_and_report() {
    let dir = TempDir::new("only");
    let o = figures(&["--quick", "--json", "--only", "8,5", "--out", &dir.arg()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).expect("stdout is one JSON object");
    let figs = v["figures"].as_array().expect("a figures array");
    let numbers: Vec<u64> = figs.iter().filter_map(|f| f["figure"].as_u64()).collect();
    assert_eq!(numbers, vec![5, 8], "{v}");
    assert!(v["failed"].as_array().is_some_and(|f| f.is_empty()), "{v}");
    // Fig. 5: four panels with the solved frequencies, in the tilting band at A = 0.33.
    let panels = figs[0]["summary"]["panels"].as_array().expect("panels");
    assert_eq!(panels.len(), 4);
    let omegas: Vec<f64> = panels.iter().filter_map(|p| p["omega"].as_f64()).collect();
    assert!(omegas.windows(2).all(|w| w[0] < w[1]), "{omegas:?}");
    assert!(omegas.iter().all(|w| (1.7..2.2).contains(w)), "{omegas:?}");
    // Fig. 8: the period doubling near the paper's k = 1925.
    let k_star = figs[1]["summary"]["k_star"].as_f64().expect("k* found");
    assert!((k_star - 1925.0).abs() < 10.0, "k* = {k_star}");
    assert_png(&dir.path().join("fig5.png"));
    assert_png(&dir.path().join("fig8.png"));
    for n in [4, 6, 7] {
        assert!(!dir.path().join(format!("fig{n}.png")).exists());
    }
}

#[test]
fn out_that_is_a_file_is_rejected() {
    let dir = TempDir::new("file");
    let file = dir.path().join("not-a-dir.png");
    std::fs::write(&file, b"x").expect("cannot write a temp file");
    let o = figures(&["--quick", "--out", &file.to_string_lossy()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("--out") && err.contains("not a directory"),
        "{err}"
    );
    // Nothing was drawn next to it.
    assert!(!dir.path().join("fig4.png").exists());
}

#[test]
fn unknown_figure_is_rejected() {
    let dir = TempDir::new("nine");
    for bad in ["9", "4,9", "x"] {
        let o = figures(&["--quick", "--only", bad, "--out", &dir.arg()]);
        assert_eq!(o.status.code(), Some(2), "--only {bad}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains("--only") && err.contains("4 to 8"), "{err}");
    }
    assert!(
        std::fs::read_dir(dir.path())
            .expect("temp dir")
            .next()
            .is_none(),
        "no figure may be written"
    );
}

#[test]
fn missing_out_is_a_usage_error() {
    let o = figures(&["--quick"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--out"), "{}", stderr(&o));
}
