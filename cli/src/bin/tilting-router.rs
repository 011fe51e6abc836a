//! `tilting-router`: a zenoh router for a secure deployment, opened from a configuration file
//! (`router.json5` of `tilting certs`: TLS with mutual authentication and the robot's access
//! control). A thin shell over [`tilting_launch::router`].

use clap::Parser as _;
use std::process::ExitCode;
use tilting::CommandError;

fn main() -> ExitCode {
    let args = tilting_launch::RouterArgs::parse();
    match tilting_launch::router(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let e = CommandError::from(e);
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
