//! The subcommands of `tilting`, grouped by what a person wants to do: [`simulate`] (run),
//! [`plan`] (plan), [`figures`], [`animate`] (look); `live`, `echo`, `hz`, `record`, `replay`,
//! `info`, `view` and `ros2` are [`tilting_live`]'s. Each is a thin shell: flags, validation that names the field and its range, a progress bar, and output (a human summary,
//! or one JSON object with `--json`); the computations live in the library crates.

pub mod animate;
pub mod certs;
pub mod continuation;
pub mod figures;
pub mod identify;
pub mod margins;
pub mod plan;
pub mod shard;
pub mod simulate;

use crate::CommandError;
use anyhow::anyhow;
use clap::Args;
use serde::Serialize;
use std::io::{IsTerminal, Write};
use tilting_plant::{ImpactLaw, Params, ParamsArgs};

/// Model flags shared by the planning commands.
#[derive(Debug, Clone, Args)]
pub struct ModelArgs {
    /// The model's parameter file.
    #[command(flatten)]
    pub params: ParamsArgs,
    /// Landing impact law: paper, striking-edge or physical [default: the params file's
    /// `impact`, else paper]
    #[arg(long, value_name = "LAW", value_parser = parse_impact)]
    pub impact: Option<ImpactLaw>,
    /// Print one JSON object instead of a human summary
    #[arg(long)]
    pub json: bool,
}

pub(crate) fn parse_impact(s: &str) -> Result<ImpactLaw, String> {
    s.parse()
}

impl ModelArgs {
    /// The parameters of `--params`, or the paper's, with the landing law of `--impact` when
    /// given (it overrides the file's `impact`).
    pub fn params(&self) -> Result<Params, CommandError> {
        let p = self.params.params()?;
        Ok(p.with_impact(p.impact_or(self.impact)))
    }
}

/// A usage error (exit code 2).
pub fn usage(msg: String) -> CommandError {
    CommandError::Usage(anyhow!(msg))
}

/// `v` if it is finite and `ok`; otherwise a usage error naming `--{field}` and `allowed`.
pub fn check(field: &str, v: f64, ok: bool, allowed: &str) -> Result<f64, CommandError> {
    if v.is_finite() && ok {
        Ok(v)
    } else {
        Err(usage(format!(
            "invalid `--{field}` = {v}: must be {allowed}"
        )))
    }
}

/// Prints `value` as one JSON line, or `human()`; a closed pipe is not an error.
pub fn emit<T: Serialize>(
    json: bool,
    value: &T,
    human: impl FnOnce() -> String,
) -> Result<(), CommandError> {
    let text = if json {
        let mut s = serde_json::to_string(value).map_err(|e| CommandError::Failed(e.into()))?;
        s.push('\n');
        s
    } else {
        human()
    };
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(CommandError::Failed(anyhow!("cannot write to stdout: {e}")))
        }
        _ => Ok(()),
    }
}

pub use tilting_live::out::bar;

/// The progress of a planner job ([`tilting_planner::jobs::Progress`]) as one progress bar a
/// stage on stderr ([`bar`]: hidden with `--json` or when stderr is not a terminal).
pub struct Bars {
    json: bool,
    bar: std::sync::Mutex<indicatif::ProgressBar>,
}

impl Bars {
    /// Bars for a command with (`json`) or without `--json`.
    pub fn new(json: bool) -> Self {
        Self {
            json,
            bar: std::sync::Mutex::new(indicatif::ProgressBar::hidden()),
        }
    }

    fn current(&self) -> indicatif::ProgressBar {
        self.bar.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}

impl tilting_planner::jobs::Progress for Bars {
    fn begin(&self, name: &str, len: u64) {
        *self.bar.lock().unwrap_or_else(|e| e.into_inner()) = bar(len, name, self.json);
    }
    fn at(&self, pos: u64) {
        self.current().set_position(pos);
    }
    fn step(&self) {
        self.current().inc(1);
    }
    fn end(&self) {
        self.current().finish_and_clear();
    }
}

/// Runs `tilting_sim::simulate` with a progress bar on stderr over the scenario's simulated
/// time (hidden with `--json` or when stderr is not a terminal), cleared at the end.
pub fn simulate_with_bar(
    sc: &tilting_sim::Scenario,
    opts: tilting_sim::SimOptions,
    json: bool,
) -> Result<tilting_sim::SimulationReport, tilting_sim::ScenarioError> {
    let duration = sc.duration;
    let b = if json || !std::io::stderr().is_terminal() {
        indicatif::ProgressBar::hidden()
    } else {
        let b = indicatif::ProgressBar::new(1000);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "simulate [{bar:40}] {msg} {elapsed_precise} (eta {eta})",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        b.set_message(format!("t = 0 / {duration} s"));
        b
    };
    let r = tilting_sim::simulate_with_progress(sc, opts, &mut |t| {
        b.set_position((1000.0 * t / duration).round() as u64);
        b.set_message(format!("t = {t:.2} / {duration} s"));
    });
    b.finish_and_clear();
    r
}

/// Writes `text` to stdout; a closed pipe (`| head`) is not an error
/// ([`tilting_live::out::print_stdout`]).
pub fn print_stdout(text: &str) -> Result<(), CommandError> {
    Ok(tilting_live::out::print_stdout(text)?)
}
