//! `tilting figures`: the paper's Figs. 4 to 8 as PNG files, drawn by `tilting_viz::figures`,
//! with a progress bar and a summary of what each figure shows.

use super::ModelArgs;
use crate::CommandError;
use anyhow::anyhow;
use clap::Args;
use serde::{Deserialize, Serialize};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tilting_viz::figures::{Figures, Settings, Summary, ALL};

/// Flags of `tilting figures`.
#[derive(Debug, Clone, Args)]
pub struct FiguresArgs {
    /// Directory for fig4.png ... fig8.png (created if missing)
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Draw only these figures (comma-separated numbers from 4 to 8)
    #[arg(long, value_name = "N,...", value_delimiter = ',', value_parser = parse_figure)]
    pub only: Vec<u8>,
    /// Coarse grids and short runs: a fast preview (used by the tests)
    #[arg(long)]
    pub quick: bool,
    /// The model, impact law and output format.
    #[command(flatten)]
    pub model: ModelArgs,
}

fn parse_figure(s: &str) -> Result<u8, String> {
    match s.trim().parse::<u8>() {
        Ok(n) if ALL.contains(&n) => Ok(n),
        _ => Err(format!(
            "no figure `{s}`: the figures are numbered 4 to 8 (e.g. --only 4,7)"
        )),
    }
}

/// What `tilting figures --json` prints (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FiguresReport {
    /// The figures that failed: `figN: why`.
    pub failed: Vec<String>,
    /// The figures drawn, in increasing number.
    pub figures: Vec<FigureReport>,
    /// The landing impact law.
    pub impact: String,
    /// The output directory.
    pub out: PathBuf,
    /// `--quick`: coarse grids and short runs.
    pub quick: bool,
    /// Wall-clock time of the whole command (s).
    pub seconds: f64,
}

/// One figure drawn.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FigureReport {
    /// Its number, 4 to 8.
    pub figure: u8,
    /// The PNG file.
    pub path: PathBuf,
    /// Wall-clock time of its computation and drawing (s).
    pub seconds: f64,
    /// What it shows.
    pub summary: Summary,
}

/// `tilting figures`: the PNGs of the paper's Figs. 4 to 8.
pub fn figures(args: &FiguresArgs) -> Result<(), CommandError> {
    let start = Instant::now();
    let params = args.model.params()?;
    let out = prepare_out(&args.out)?;
    let mut which: Vec<u8> = if args.only.is_empty() {
        ALL.collect()
    } else {
        args.only.clone()
    };
    which.sort_unstable();
    which.dedup();
    let set = if args.quick {
        Settings::quick()
    } else {
        Settings::full()
    };
    let ctx = Figures {
        params,
        impact: args.model.impact,
        set,
        out,
    };
    let units: u64 = which.iter().map(|&n| ctx.units(n)).sum();
    let bar = progress(units, args.model.json);
    let mut done = Vec::new();
    let mut failed = Vec::new();
    for &n in &which {
        bar.set_message(format!("fig{n}"));
        let t0 = Instant::now();
        let r = ctx.draw(n, &|| bar.inc(1));
        match r {
            Ok(summary) => done.push(FigureReport {
                figure: n,
                path: ctx.path(n),
                seconds: t0.elapsed().as_secs_f64(),
                summary,
            }),
            Err(e) => failed.push(format!("fig{n}: {e:#}")),
        }
    }
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let report = FiguresReport {
        out: ctx.out.clone(),
        quick: args.quick,
        impact: ctx.impact.as_str().to_owned(),
        seconds,
        figures: done,
        failed,
    };
    let text = if args.model.json {
        format!(
            "{}\n",
            serde_json::to_string(&report).map_err(|e| CommandError::Failed(e.into()))?
        )
    } else {
        human(&report)
    };
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = stdout.write_all(text.as_bytes()) {
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            return Err(CommandError::Failed(anyhow!("cannot write to stdout: {e}")));
        }
    }
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

fn progress(len: u64, json: bool) -> indicatif::ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new(len);
    b.set_style(
        indicatif::ProgressStyle::with_template(
            "figures {msg:5} [{bar:40}] {pos}/{len} {elapsed_precise} (eta {eta})",
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
