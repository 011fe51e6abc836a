//! `tilting certs`: the flags are [`tilting_launch::CertsArgs`], the work
//! [`tilting_launch::certs`]; this prints what was written and how to start the router and a
//! node with it.

use crate::CommandError;
use tilting_launch::{common_name, CertsArgs};

/// `tilting certs`.
pub fn run(args: &CertsArgs) -> Result<(), CommandError> {
    let w = tilting_launch::certs(args)?;
    let (m, dir) = (&w.manifest, args.out.display());
    println!(
        "certificates for robot {} in {dir}: {}",
        m.robot,
        m.nodes
            .iter()
            .map(|n| common_name(&m.robot, n))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!("start the router:  tilting-router --config {dir}/router.json5");
    println!(
        "start a node:      tilting-plant --robot {} --zenoh-config {dir}/plant.json5",
        m.robot
    );
    for h in &w.hosts {
        println!("{}'s certificate names {}", h.node, h.name);
    }
    Ok(())
}
