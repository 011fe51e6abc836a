//! The `tilting-planner` binary's exit codes: 2 for flags it refuses (clap's convention), before
//! any session is opened.

use std::process::Command;

#[test]
fn refused_flags_exit_with_code_2_and_name_the_flag() {
    for (args, flag) in [
        (&["--kp=-1"][..], "kp"),
        (&["--repeat=-1"][..], "--repeat"),
        (&["--duration", "0"][..], "--duration"),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_tilting-planner"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
    }
}
