//! The impairment and loop flags of the built `tilting simulate`: bad values are refused with
//! exit code 2 and a message naming the flag and what is allowed.

use std::process::Command;

use crate::common;
use common::BIN;

#[test]
fn bad_network_and_loop_flags_name_the_flag() {
    for (args, want) in [
        (vec!["--delay", "-1"], vec!["--delay", "[0, 60]"]),
        (vec!["--torque-loss", "2"], vec!["--torque-loss", "[0, 1]"]),
        (
            vec!["--jitter", "gamma:0.001"],
            vec!["--jitter", "unknown distribution"],
        ),
        (
            vec!["--predict", "-1"],
            vec!["--predict", "auto", "[0, 60]"],
        ),
        (vec!["--predict", "soon"], vec!["--predict", "auto"]),
        // Both act on samples: the continuous loop has none.
        (vec!["--sample-on-event"], vec!["--control-period", "> 0"]),
    ] {
        let mut cmd = Command::new(BIN);
        cmd.args(["simulate", "--duration", "0.1"]).args(&args);
        if args[0] != "--sample-on-event" {
            cmd.args(["--control-period", "0.001"]);
        }
        let o = cmd.output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        for w in want {
            assert!(err.contains(w), "{args:?}: `{w}` not in {err}");
        }
    }
}
