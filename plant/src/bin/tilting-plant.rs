//! `tilting-plant`: the simulated tilting system as a zenoh node. See [`tilting_plant::node`].

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = tilting_plant::node::PlantArgs::parse();
    tilting_net::init_tracing("warn,tilting_plant=info,tilting_net=info");
    match tilting_plant::node::run(args) {
        Ok(code) => code,
        Err(e) => {
            tilting_net::say_err(&format!("tilting-plant: error: {e:#}"));
            ExitCode::FAILURE
        }
    }
}
