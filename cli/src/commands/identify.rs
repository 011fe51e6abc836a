//! `tilting identify`: the physical parameters of a robot from a recording
//! ([`tilting_planner::identify`]): the estimates with their standard errors, the regressor's
//! condition number, what the data cannot fix; `--out` writes the `--params` TOML.

use super::{print_stdout, usage};
use crate::CommandError;
use clap::Args;
use std::path::PathBuf;
use tilting_planner::identify::{self, Identification, IdentifyError, Options};
use tilting_plant::Params;

/// Flags of `tilting identify`.
#[derive(Debug, Clone, Args)]
pub struct IdentifyArgs {
    /// The recording: an MCAP file (`tilting record`, `live`, `simulate --record`) or a live
    /// run's directory holding run.mcap
    #[arg(value_name = "FILE.mcap|RUN_DIR")]
    pub file: PathBuf,
    /// The robot to identify; refused if the file holds another
    #[arg(long, value_name = "NAME")]
    pub robot: Option<String>,
    /// The prior: TOML with the measured geometry (l, f, g) and the weighed arm mass m_l,
    /// which the motion cannot tell from l_c and i_l; default the paper's
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    /// Write the identified robot's parameters here, as `--params` reads them
    #[arg(long, value_name = "params.toml")]
    pub out: Option<PathBuf>,
    /// Print one JSON object instead of a human summary
    #[arg(long)]
    pub json: bool,
}

/// Runs `tilting identify`.
pub fn run(args: &IdentifyArgs) -> Result<(), CommandError> {
    let base = match &args.params {
        Some(p) => Params::from_toml_file(p).map_err(|e| CommandError::Usage(e.into()))?,
        None => Params::default(),
    };
    let rec = identify::load(&args.file, args.robot.as_deref()).map_err(refused)?;
    let id = identify::identify(
        &rec.trace,
        &rec.tau,
        &Options {
            base,
            ..Options::default()
        },
    )
    .map_err(refused)?;
    if let Some(out) = &args.out {
        std::fs::write(out, id.params.to_toml_string()).map_err(|e| {
            CommandError::Failed(anyhow::anyhow!("cannot write {}: {e}", out.display()))
        })?;
    }
    let text = if args.json {
        serde_json::to_string_pretty(&id).map_err(|e| CommandError::Failed(e.into()))? + "\n"
    } else {
        human(&id, &rec.source.display().to_string(), args.out.as_ref())
    };
    print_stdout(&text)
}

/// A recording that cannot be read is a failure; one that cannot be identified, bad input.
fn refused(e: IdentifyError) -> CommandError {
    match e {
        IdentifyError::Load(_) | IdentifyError::Read(_) => CommandError::Failed(e.into()),
        e => usage(e.to_string()),
    }
}

fn human(id: &Identification, source: &str, out: Option<&PathBuf>) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let r = id.rows;
    let _ = writeln!(
        s,
        "{source}: {} equations ({} flat and {} tilted intervals; {} skipped at events or \
         without a torque)",
        r.equations, r.flat, r.tilted, r.skipped
    );
    let _ = writeln!(
        s,
        "condition number {:.3e} (columns scaled), residual RMS {:.3e} N m\n",
        id.condition_number, id.residual_rms
    );
    let _ = writeln!(
        s,
        "{:<8} {:<28} {:>14} {:>11}  unit",
        "base", "", "estimate", "std err"
    );
    for e in &id.base {
        match (e.value, e.std_error) {
            (Some(v), Some(se)) => {
                let _ = writeln!(
                    s,
                    "{:<8} {:<28} {v:>14.6} {se:>11.2e}  {}",
                    e.name, e.combination, e.unit
                );
            }
            _ => {
                let why = e
                    .not_identifiable
                    .as_deref()
                    .unwrap_or("not fixed by the data");
                let _ = writeln!(
                    s,
                    "{:<8} {:<28} not identifiable: {why}",
                    e.name, e.combination
                );
            }
        }
    }
    let p = &id.params;
    let _ = writeln!(
        s,
        "\nparameters: m_f {:.6} kg, m_l {:.6} kg (prior), l_c {:.6} m, i_l {:.6} kg m^2, \
         j_m {:.6} kg m^2, n_g {:.6}, b_v {:.6} N m s/rad, tau_c {:.6} N m",
        p.m_f,
        p.m_l,
        p.lc(),
        p.i_l,
        p.j_m,
        p.n_g,
        p.b_v,
        p.tau_c
    );
    let _ = writeln!(s, "not identifiable from motion:");
    for n in &id.not_identifiable {
        let _ = writeln!(s, "  - {n}");
    }
    for w in &id.warnings {
        let _ = writeln!(s, "warning: {w}");
    }
    if let Some(o) = out {
        let _ = writeln!(s, "wrote {} (use it with --params)", o.display());
    }
    s
}
