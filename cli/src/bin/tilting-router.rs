//! `tilting-router`: a zenoh router for a secure deployment, opened from a configuration file
//! (`router.json5` of `tilting certs`: TLS with mutual authentication and the robot's access
//! control). A thin shell over [`tilting::security::router`].

use clap::Parser as _;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = tilting::security::RouterArgs::parse();
    match tilting::security::router(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}
