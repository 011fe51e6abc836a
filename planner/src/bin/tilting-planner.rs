//! `tilting-planner`: the planner node, which publishes the controller's law over zenoh. See
//! [`tilting_planner::node`].
//!
//! The offline commands that used to be its subcommands now live in the front door, `tilting`.
//! For one release their old names still work here: they say where the command went and run
//! it from the `tilting` binary next to this one.

use clap::Parser;
use std::process::ExitCode;
use tilting_planner::node::{self, NodeError, PublishArgs};

/// Old `tilting-planner` subcommands and their place in `tilting`.
const MOVED: &[(&str, &[&str])] = &[
    ("live", &["live"]),
    ("simulate", &["simulate"]),
    ("figures", &["figures"]),
    ("orbit", &["plan", "orbit"]),
    ("sinusoid", &["plan", "sinusoid"]),
    ("bifurcation", &["plan", "bifurcation"]),
    ("gains", &["plan", "gains"]),
];

fn main() -> ExitCode {
    let mut argv: Vec<String> = std::env::args().collect();
    if let Some((old, new)) = argv
        .get(1)
        .and_then(|a| MOVED.iter().find(|(old, _)| a == old))
    {
        let rest = argv.split_off(2);
        return run_moved(old, new, rest);
    }
    // `tilting-planner publish ...` is the node itself: the subcommand name is optional.
    if argv.get(1).is_some_and(|a| a == "publish") {
        argv.remove(1);
    }
    let args = PublishArgs::parse_from(argv);
    match node::run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            // 2 for bad flags (clap's convention), 1 when the node failed.
            ExitCode::from(match e {
                NodeError::Invalid(_) => 2,
                NodeError::NoOrbit { .. } | NodeError::Run(_) => 1,
            })
        }
    }
}

/// Runs `tilting NEW... REST...` from the directory of this executable.
fn run_moved(old: &str, new: &[&str], rest: Vec<String>) -> ExitCode {
    eprintln!(
        "note: `tilting-planner {old}` is now `tilting {}`; the old name goes away in the next \
         release",
        new.join(" ")
    );
    let exe = std::env::current_exe().ok().and_then(|p| {
        Some(
            p.parent()?
                .join(format!("tilting{}", std::env::consts::EXE_SUFFIX)),
        )
    });
    let Some(front) = exe.filter(|p| p.is_file()) else {
        eprintln!(
            "error: cannot find the `tilting` binary next to tilting-planner: build the workspace \
             with `cargo build --release --workspace`"
        );
        return ExitCode::FAILURE;
    };
    let mut cmd = std::process::Command::new(&front);
    cmd.args(new).args(rest);
    // On Unix the alias becomes the command (same pid, so Ctrl-C and exit codes behave as if
    // `tilting` had been typed); elsewhere it waits for it.
    #[cfg(unix)]
    let err = std::os::unix::process::CommandExt::exec(&mut cmd);
    #[cfg(not(unix))]
    let err = match cmd.status() {
        Ok(s) => return ExitCode::from(s.code().map_or(1, |c| u8::try_from(c).unwrap_or(1))),
        Err(e) => e,
    };
    eprintln!("error: cannot run {}: {err}", front.display());
    ExitCode::FAILURE
}
