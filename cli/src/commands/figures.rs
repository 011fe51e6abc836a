//! `tilting figures`: the paper's Figs. 4 to 8 and issue 19's Figs. 8b and 8c as PNG files,
//! drawn by `tilting_viz::figures`, with a progress bar and a summary of what each shows.

use super::{emit, ModelArgs};
use crate::CommandError;
use anyhow::anyhow;
use clap::Args;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tilting_viz::figures::{figure_id, Figures, FiguresProgress, Settings, ALL};
pub use tilting_viz::figures::{FigureReport, FiguresReport};

/// Flags of `tilting figures`.
#[derive(Debug, Clone, Args)]
pub struct FiguresArgs {
    /// Directory for fig4.png ... fig8.png, fig8b.png, fig8c.png (created if missing)
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Draw only these figures (comma-separated: 4, 5, 6, 7, 8, 8b, 8c)
    #[arg(long, value_name = "ID,...", value_delimiter = ',', value_parser = parse_figure)]
    pub only: Vec<&'static str>,
    /// Coarse grids and short runs: a fast preview (used by the tests)
    #[arg(long)]
    pub quick: bool,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
}

fn parse_figure(s: &str) -> Result<&'static str, String> {
    figure_id(s)
}

/// `tilting figures`: the PNGs of the paper's Figs. 4 to 8 and of Figs. 8b and 8c.
pub fn figures(args: &FiguresArgs) -> Result<(), CommandError> {
    let start = Instant::now();
    let params = args.model.params()?;
    let out = prepare_out(&args.out)?;
    // In the order of ALL, each once.
    let which: Vec<&str> = ALL
        .into_iter()
        .filter(|n| args.only.is_empty() || args.only.contains(n))
        .collect();
    let set = if args.quick {
        Settings::quick()
    } else {
        Settings::full()
    };
    let ctx = Figures {
        params,
        impact: params.impact,
        set,
        out,
    };
    let units: u64 = which.iter().map(|n| ctx.units(n)).sum();
    let bar = progress(units, args.model.json);
    let mut report = ctx.draw_all(&which, args.quick, &Bar(bar.clone()));
    bar.finish_and_clear();
    // The whole command's wall time, as before the drawing moved into the library.
    report.seconds = start.elapsed().as_secs_f64();
    emit(args.model.json, &report, || human(&report))?;
    if report.failed.is_empty() {
        Ok(())
    } else {
        Err(CommandError::Failed(anyhow!(
            "{} of {} figures failed: {}",
            report.failed.len(),
            which.len(),
            report.failed.join("; ")
        )))
    }
}

/// Checks `--out`: an existing directory, or a path that can be created as one.
fn prepare_out(out: &Path) -> Result<PathBuf, CommandError> {
    if out.exists() && !out.is_dir() {
        return Err(CommandError::Usage(anyhow!(
            "invalid `--out` = {}: it exists and is not a directory",
            out.display()
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| {
        CommandError::Usage(anyhow!(
            "invalid `--out` = {}: cannot create the directory: {e}",
            out.display()
        ))
    })?;
    Ok(out.to_path_buf())
}

/// The figures' progress as one bar with the figure's id for its message.
struct Bar(indicatif::ProgressBar);

impl FiguresProgress for Bar {
    fn figure(&self, id: &str) {
        self.0.set_message(format!("fig{id}"));
    }
    fn tick(&self) {
        self.0.inc(1);
    }
    fn reached(&self, units: u64) {
        self.0.set_position(units);
    }
}

fn progress(len: u64, json: bool) -> indicatif::ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new(len);
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "figures {msg:6} [{bar:40}] {pos}/{len} {elapsed_precise} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    b
}

fn human(report: &FiguresReport) -> String {
    let mut s = format!(
        "figures written to {} in {:.1} s{}\n",
        report.out.display(),
        report.seconds,
        if report.quick { " (quick preview)" } else { "" }
    );
    for f in &report.figures {
        s += &format!(
            "  {} ({:.1} s): {}\n",
            f.path.display(),
            f.seconds,
            f.summary.text()
        );
    }
    s
}
