//! `tilting-controller`: the computed-torque controller as a zenoh node. See
//! [`tilting_controller::node`].

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = tilting_controller::node::ControllerArgs::parse();
    tilting_net::init_tracing("warn,tilting_controller=info,tilting_net=info");
    match tilting_controller::node::run(args) {
        Ok(code) => code,
        Err(e) => {
            tilting_net::say_err(&format!("tilting-controller: error: {e:#}"));
            ExitCode::FAILURE
        }
    }
}
