//! `tilting figures`: the paper's Figs. 4 to 8 and issue 19's Figs. 8b and 8c as PNG files,
//! drawn by `tilting_viz::figures`, with a progress bar and a summary of what each shows.

use super::ModelArgs;
use crate::CommandError;
use anyhow::anyhow;
use clap::Args;
use serde::{Deserialize, Serialize};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tilting_viz::figures::{figure_id, Figures, Settings, Summary, ALL};

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

/// What `tilting figures --json` prints (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FiguresReport {
    /// The figures that failed: `figN: why`.
    pub failed: Vec<String>,
    /// The figures drawn, in the order of `tilting_viz::figures::ALL`.
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
    /// Its id: "4" to "8", "8b", "8c".
    pub figure: String,
    /// The PNG file.
    pub path: PathBuf,
    /// Wall-clock time of its computation and drawing (s).
    pub seconds: f64,
    /// What it shows.
    pub summary: Summary,
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
    let mut done = Vec::new();
    let mut failed = Vec::new();
    let mut reached = 0;
    for &n in &which {
        bar.set_message(format!("fig{n}"));
        let t0 = Instant::now();
        let r = ctx.draw(n, &|| bar.inc(1));
        // 8b and 8c give an upper bound of their ticks: each figure ends at its share.
        reached += ctx.units(n);
        bar.set_position(reached);
        match r {
            Ok(summary) => done.push(FigureReport {
                figure: n.to_owned(),
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
