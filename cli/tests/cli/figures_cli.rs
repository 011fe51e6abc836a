//! Runs the built `tilting figures` binary: the quick preview writes the seven PNGs (Figs. 4 to
//! 8, 8b and 8c), `--only` and `--json` select and report, and a bad `--out` or figure id fails
//! clearly, naming the ids there are.

use std::path::Path;
use std::process::{Command, Output};
use tilting::commands::figures::FiguresReport;
use tilting_viz::figures::Summary;

use crate::common;
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

/// CRC-32 (ISO 3309, as PNG uses it), bit by bit.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Reads the PNG at `path` chunk by chunk (every chunk's CRC checked, IHDR first, IEND last,
/// image data present) and returns its size in pixels from IHDR.
fn decoded_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(
        bytes.starts_with(PNG_MAGIC),
        "{} is not a PNG",
        path.display()
    );
    let (mut at, mut names, mut size, mut data) = (PNG_MAGIC.len(), Vec::new(), (0, 0), 0);
    while at + 12 <= bytes.len() {
        let len = u32::from_be_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        let body = &bytes[at + 4..at + 8 + len];
        let crc = u32::from_be_bytes(bytes[at + 8 + len..at + 12 + len].try_into().unwrap());
        assert_eq!(
            crc32(body),
            crc,
            "{}: bad CRC in a {:?} chunk",
            path.display(),
            &body[..4]
        );
        let name = String::from_utf8_lossy(&body[..4]).into_owned();
        if name == "IHDR" {
            let be = |i: usize| u32::from_be_bytes(body[4 + i..8 + i].try_into().unwrap());
            size = (be(0), be(4));
        }
        if name == "IDAT" {
            data += len;
        }
        names.push(name);
        at += 12 + len;
    }
    assert_eq!(at, bytes.len(), "{}: trailing bytes", path.display());
    assert_eq!(names.first().map(String::as_str), Some("IHDR"), "{names:?}");
    assert_eq!(names.last().map(String::as_str), Some("IEND"), "{names:?}");
    assert!(
        data > 20_000,
        "{}: {data} bytes of image data",
        path.display()
    );
    size
}

#[test]
fn quick_run_writes_all_seven_figures() {
    let dir = Scratch::new("all");
    // A directory that does not exist yet is created.
    let out = dir.path().join("nested").join("figs");
    let o = figures(&["--quick", "--out", &out.to_string_lossy()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ids = ["4", "5", "6", "7", "8", "8b", "8c"];
    for n in ids {
        assert_png(&out.join(format!("fig{n}.png")));
    }
    let text = String::from_utf8_lossy(&o.stdout);
    for n in ids {
        assert!(text.contains(&format!("fig{n}.png")), "{text}");
    }
}

#[test]
fn figures_8b_and_8c_are_the_continuation_and_the_stability_region() {
    let dir = Scratch::new("8bc");
    let o = figures(&["--quick", "--json", "--only", "8c,8b", "--out", &dir.arg()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: FiguresReport = serde_json::from_slice(&o.stdout).expect("stdout is the report");
    let ids: Vec<&str> = v.figures.iter().map(|f| f.figure.as_str()).collect();
    assert_eq!(ids, vec!["8b", "8c"], "{v:?}");
    // The sizes `plan continuation --plot` and `plan stability --plot` draw.
    assert_eq!(decoded_size(&dir.path().join("fig8b.png")), (1600, 1250));
    assert_eq!(decoded_size(&dir.path().join("fig8c.png")), (1300, 950));
    let Summary::Fig8b(b) = &v.figures[0].summary else {
        panic!("not Fig. 8b's summary: {:?}", v.figures[0].summary)
    };
    // The quick preview continues to period 4: three branches, the first flip at the
    // project's k* = 1923.99 (the multipliers' bisection of `plan bifurcation`), then two more.
    assert_eq!(b.branch_periods, vec![1, 2, 4], "{b:?}");
    assert!((b.flips_k[0] - 1923.99).abs() < 0.01, "{b:?}");
    assert!(b.flips_k.windows(2).all(|w| w[1] > w[0]), "{b:?}");
    let Summary::Fig8c(c) = &v.figures[1].summary else {
        panic!("not Fig. 8c's summary: {:?}", v.figures[1].summary)
    };
    // The flip curve passes through (k*, 14.14), more damping tolerating more adaptation; the
    // fold lies below the paper's k = 500.
    let at = c
        .flip_curve
        .iter()
        .find(|p| p[1] == 14.14)
        .expect("the base point");
    assert!((at[0] - 1923.99).abs() < 0.01, "{at:?}");
    assert!(c.flip_curve.windows(2).all(|w| w[1][0] > w[0][0]), "{c:?}");
    assert!(
        c.fold_curve.iter().all(|p| p[0] > 0.0 && p[0] < 500.0),
        "{c:?}"
    );
    for n in ["4", "5", "6", "7", "8"] {
        assert!(!dir.path().join(format!("fig{n}.png")).exists());
    }
}

#[test]
fn only_and_json_select_and_report() {
    let dir = Scratch::new("only");
    let o = figures(&["--quick", "--json", "--only", "8,5", "--out", &dir.arg()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: FiguresReport = serde_json::from_slice(&o.stdout).expect("stdout is the report");
    let ids: Vec<&str> = v.figures.iter().map(|f| f.figure.as_str()).collect();
    assert_eq!(ids, vec!["5", "8"], "{v:?}");
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
    for bad in ["9", "4,9", "x", "8d", "8b,8B"] {
        let o = figures(&["--quick", "--only", bad, "--out", &dir.arg()]);
        assert_eq!(o.status.code(), Some(2), "--only {bad}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(
            err.contains("--only") && err.contains("4, 5, 6, 7, 8, 8b, 8c"),
            "{err}"
        );
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
