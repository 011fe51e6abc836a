//! `tilting animate` as a person runs it: a GIF from a simulated scenario, PNG frames from a run
//! directory, and a garbled recording refused with the file and the line.

use std::process::Command;
use tilting::commands::animate::{AnimateReport, AnimationFormat};
use tilting_tests::bin;

#[test]
fn animate_simulates_writes_a_gif_and_refuses_a_garbled_recording() {
    let tmp = tempfile::tempdir().unwrap();
    let gif = tmp.path().join("robot.gif");
    let out = Command::new(bin("tilting"))
        .args([
            "animate",
            "--duration",
            "2",
            "--fps",
            "10",
            "--json",
            "--out",
        ])
        .arg(&gif)
        .output()
        .expect("run tilting animate");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let report: AnimateReport = serde_json::from_slice(&out.stdout).unwrap();
    // 2 s at 10 frames per second, both ends included; the orbit lands about every 0.44 s.
    assert_eq!(report.frames, 21, "{report:?}");
    assert_eq!(report.format, AnimationFormat::Gif);
    assert!(report.flashed >= 4, "{report:?}");
    let bytes = std::fs::read(&gif).unwrap();
    assert!(bytes.starts_with(b"GIF89a"));
    assert_eq!(&bytes[6..10], &[128, 2, 224, 1], "640 x 480 px");

    // A run directory: three flat states, PNG frames.
    let run = tmp.path().join("run");
    std::fs::create_dir(&run).unwrap();
    let state = "seq,t,mode,alpha,beta,alpha_dot,beta_dot\n";
    let events = "t,from,to,alpha_before,beta_before,alpha_dot_before,beta_dot_before,\
alpha_after,beta_after,alpha_dot_after,beta_dot_after\n";
    std::fs::write(
        run.join("state.csv"),
        format!("{state}0,0,0,0,1.5,0,0\n1,0.1,0,0,1.6,0,0\n2,0.2,0,0,1.7,0,0\n"),
    )
    .unwrap();
    std::fs::write(run.join("events.csv"), events).unwrap();
    let frames = tmp.path().join("frames");
    let out = Command::new(bin("tilting"))
        .args(["animate", "--fps", "10", "--from"])
        .arg(&run)
        .arg("--frames")
        .arg(&frames)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut names: Vec<_> = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["frame_000000.png", "frame_000001.png", "frame_000002.png"]
    );

    // Frames already there are not mixed with new ones.
    let out = Command::new(bin("tilting"))
        .args(["animate", "--from"])
        .arg(&run)
        .arg("--frames")
        .arg(&frames)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("already holds frames"), "{err}");

    // A garbled row: a usage error naming the file, the line and the column.
    std::fs::write(
        run.join("state.csv"),
        format!("{state}0,0,0,0,1.5,0,0\n1,0.1,0,0,oops,0,0\n"),
    )
    .unwrap();
    let out = Command::new(bin("tilting"))
        .args(["animate", "--from"])
        .arg(&run)
        .arg("--out")
        .arg(tmp.path().join("bad.gif"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("state.csv line 3, column 5") && err.contains("\"oops\""),
        "{err}"
    );
}
