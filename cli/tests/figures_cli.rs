//! Runs the built `tilting figures` binary: the quick preview writes the five PNGs,
//! `--only` and `--json` select and report, and a bad `--out` or figure number fails clearly.

use std::path::Path;
use std::process::{Command, Output};
use tilting::commands::figures::FiguresReport;
use tilting_viz::figures::Summary;

mod common;
use common::{Scratch, BIN};

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
    let dir = Scratch::new("all");
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
    let dir = Scratch::new("only");
    let o = figures(&["--quick", "--json", "--only", "8,5", "--out", &dir.arg()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: FiguresReport = serde_json::from_slice(&o.stdout).expect("stdout is the report");
    let numbers: Vec<u8> = v.figures.iter().map(|f| f.figure).collect();
    assert_eq!(numbers, vec![5, 8], "{v:?}");
    assert!(v.failed.is_empty(), "{v:?}");
    assert_eq!(v.out, dir.path());
    // Fig. 5: four panels with the solved frequencies, in the tilting band at A = 0.33.
    let Summary::Fig5(fig5) = &v.figures[0].summary else {
        panic!("not Fig. 5's summary: {:?}", v.figures[0].summary)
    };
    assert_eq!(fig5.panels.len(), 4);
    let omegas: Vec<f64> = fig5.panels.iter().map(|p| p.omega).collect();
    assert!(omegas.windows(2).all(|w| w[0] < w[1]), "{omegas:?}");
    assert!(omegas.iter().all(|w| (1.7..2.2).contains(w)), "{omegas:?}");
    // Fig. 8: the period doubling near the paper's k = 1925.
    let Summary::Fig8(fig8) = &v.figures[1].summary else {
        panic!("not Fig. 8's summary: {:?}", v.figures[1].summary)
    };
    let k_star = fig8.k_star.expect("k* found");
    assert!((k_star - 1925.0).abs() < 10.0, "k* = {k_star}");
    assert_png(&dir.path().join("fig5.png"));
    assert_png(&dir.path().join("fig8.png"));
    for n in [4, 6, 7] {
        assert!(!dir.path().join(format!("fig{n}.png")).exists());
    }
}

#[test]
fn out_that_is_a_file_is_rejected() {
    let dir = Scratch::new("file");
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
    let dir = Scratch::new("nine");
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
