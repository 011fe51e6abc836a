//! `tilting-controller`: the computed-torque controller as a zenoh node. See
//! [`tilting_controller::node`].

use std::process::ExitCode;
use tilting_controller::node::ControllerArgs;

fn main() -> ExitCode {
    // Before any thread: zenoh's runtimes sized small unless ZENOH_RUNTIME is set.
    tilting_net::size_zenoh_runtime();
    // With `--robot-file`, its keys are the defaults of the flags.
    let args: ControllerArgs = tilting_plant::robot_file::parse_node_args();
    tilting_net::init_tracing("warn,tilting_controller=info,tilting_net=info");
    match tilting_controller::node::run(args) {
        Ok(code) => code,
        Err(e) => {
            tilting_net::say_err(&format!("tilting-controller: error: {e:#}"));
            ExitCode::FAILURE
        }
    }
}
