//! `tilting-plant`: the simulated tilting system as a zenoh node. See [`tilting_plant::node`].

use std::process::ExitCode;

fn main() -> ExitCode {
    // Before any thread: zenoh's runtimes sized small unless ZENOH_RUNTIME is set.
    tilting_net::size_zenoh_runtime();
    // With `--robot-file`, its plant keys are the defaults of the flags.
    let argv: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let args =
        tilting_plant::robot_file::exit_on_error(tilting_plant::node::PlantArgs::from_argv(&argv));
    // RustDDS (--ros2 dds) warns per packet it cannot route (e.g. to its own loopback
    // announcements): errors only.
    tilting_net::init_tracing(
        "warn,tilting_plant=info,tilting_net=info,rustdds=error,ros2_client=error",
    );
    match tilting_plant::node::run(args) {
        Ok(code) => code,
        Err(e) => {
            tilting_net::say_err(&format!("tilting-plant: error: {e:#}"));
            ExitCode::FAILURE
        }
    }
}
