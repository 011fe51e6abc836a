//! `figures`: the paper's Figs. 4 to 8 as PNG files, computed from scratch with the planning
//! modules and drawn with plotters.
//!
//! - Fig. 4 ([`sinusoid`]): the partition of the `(A, w)` plane: the pairs whose ideal arm
//!   motion never tilts the plate, and the curves `t_l = T/2 + s t_t` for `s = -1, 0, 1`;
//! - Fig. 5: the closed loop (PD, `K_P = 100`, `K_D = 14.14`, impacts) tracking the sinusoid of
//!   four planned `(A, w)` pairs, the simulated tilt against the planned one;
//! - Fig. 6 ([`gains`]): the maximal tilt of the periodic orbits of approach 2 over `(K_P, K_D)`;
//! - Fig. 7: the unstable orbit left alone (perturbed up and down) and stabilised by the energy
//!   adaptation `k = 500`;
//! - Fig. 8 ([`bifurcation`]): the tilt peaks over the adaptation gain `k`, with `k*`, and three
//!   peak series.

use crate::bifurcation::{self, Sweep};
use crate::commands::{self, ModelArgs};
use crate::orbit::{self, OrbitProblem, OrbitSolution};
use crate::plot::register_fonts;
use crate::sinusoid::{self, Search};
use crate::{gains, CommandError};
use anyhow::{anyhow, Context, Result};
use clap::Args;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use rayon::prelude::*;
use serde_json::{json, Value};
use std::f64::consts::{FRAC_PI_2, PI};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tilting_controller::{ComputedTorque, ControlConfig, Reference};
use tilting_plant::{ImpactLaw, Mode, Observer, Params, Plant, SimConfig, State, TiltPeak};

/// `figures`: the PNGs of the paper's Figs. 4 to 8.
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
    #[command(flatten)]
    pub model: ModelArgs,
}

fn parse_figure(s: &str) -> Result<u8, String> {
    match s.trim().parse::<u8>() {
        Ok(n) if (4..=8).contains(&n) => Ok(n),
        _ => Err(format!(
            "no figure `{s}`: the figures are numbered 4 to 8 (e.g. --only 4,7)"
        )),
    }
}

/// Grid sizes and run lengths; [`Settings::quick`] for previews and tests.
#[derive(Debug, Clone, Copy)]
struct Settings {
    /// Fig. 4: amplitude step of the curves (rad).
    a_step: f64,
    /// Fig. 4: amplitude step of the no-tilt grid (rad).
    grid_a_step: f64,
    /// Fig. 4: frequency step of the no-tilt grid (rad/s).
    grid_w_step: f64,
    /// Fig. 4: scan points above the no-tilt boundary.
    scan: usize,
    /// Fig. 5: periods simulated.
    periods: f64,
    /// Fig. 6: steps of K_P and K_D.
    kp_step: f64,
    kd_step: f64,
    /// Fig. 7: duration of each run (s).
    fig7_duration: f64,
    /// Fig. 8: step of k, tilts per k, tilts kept.
    k_step: f64,
    tilts: usize,
    keep: usize,
    /// Fig. 8: tilts per time series, and how many of the last are shown.
    series_tilts: usize,
    series_keep: usize,
}

impl Settings {
    fn full() -> Self {
        Self {
            a_step: 0.01,
            grid_a_step: 0.02,
            grid_w_step: 0.25,
            scan: 90,
            periods: 3.0,
            kp_step: 10.0,
            kd_step: 0.5,
            fig7_duration: 15.0,
            k_step: 5.0,
            tilts: 600,
            keep: 150,
            series_tilts: 600,
            series_keep: 60,
        }
    }

    fn quick() -> Self {
        Self {
            a_step: 0.05,
            grid_a_step: 0.05,
            grid_w_step: 1.0,
            scan: 40,
            periods: 2.0,
            kp_step: 40.0,
            kd_step: 3.0,
            fig7_duration: 6.0,
            k_step: 100.0,
            tilts: 150,
            keep: 40,
            series_tilts: 150,
            series_keep: 30,
        }
    }
}

/// Amplitude range of Fig. 4 (rad) and the frequency range of its no-tilt grid (rad/s).
const FIG4_A: (f64, f64) = (0.02, 0.6);
const FIG4_W: (f64, f64) = (0.5, 16.0);
/// Fig. 5: amplitude and landing offsets (the paper's).
const FIG5_A: f64 = 0.33;
const FIG5_S: [(f64, &str); 4] = [
    (-0.5, "1/2"),
    (-0.25, "1/4"),
    (-1.0 / 6.0, "1/6"),
    (-0.125, "1/8"),
];
/// The paper's gains.
const KP: f64 = 100.0;
const KD: f64 = 14.14;
/// Fig. 7: adaptation gain and the perturbation of `beta_dot0` (rad/s).
const FIG7_K: f64 = 500.0;
const FIG7_PERTURBATION: f64 = 1e-3;
/// Fig. 8: range of k and the three gains of the time series.
const FIG8_K: (f64, f64) = (1500.0, 2500.0);
const FIG8_SERIES: [f64; 3] = [1900.0, 2210.0, 2300.0];

const BLUE: RGBColor = RGBColor(31, 119, 180);
const GREEN: RGBColor = RGBColor(30, 150, 60);
const RED: RGBColor = RGBColor(200, 40, 40);
const GREY: RGBColor = RGBColor(120, 120, 120);
const PALETTE: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(100, 100, 100),
    RGBColor(23, 190, 207),
];

const FONT: &str = "sans-serif";

/// Runs `figures`.
pub fn figures(args: &FiguresArgs) -> Result<(), CommandError> {
    let start = Instant::now();
    let params = match &args.model.params {
        Some(p) => Params::from_toml_file(p).map_err(|e| CommandError::Usage(e.into()))?,
        None => Params::default(),
    };
    let out = prepare_out(&args.out)?;
    let mut which: Vec<u8> = if args.only.is_empty() {
        (4..=8).collect()
    } else {
        args.only.clone()
    };
    which.sort_unstable();
    which.dedup();
    register_fonts().map_err(CommandError::Failed)?;
    let set = if args.quick {
        Settings::quick()
    } else {
        Settings::full()
    };
    let ctx = Ctx {
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
        let r = match n {
            4 => fig4(&ctx, &bar),
            5 => fig5(&ctx, &bar),
            6 => fig6(&ctx, &bar),
            7 => fig7(&ctx, &bar),
            8 => fig8(&ctx, &bar),
            _ => unreachable!("validated by the parser"),
        };
        match r {
            Ok(summary) => done.push(json!({
                "figure": n,
                "path": ctx.path(n).display().to_string(),
                "seconds": t0.elapsed().as_secs_f64(),
                "summary": summary,
            })),
            Err(e) => failed.push(format!("fig{n}: {e:#}")),
        }
    }
    bar.finish_and_clear();
    let seconds = start.elapsed().as_secs_f64();
    let report = json!({
        "out": ctx.out.display().to_string(),
        "quick": args.quick,
        "impact": ctx.impact.as_str(),
        "seconds": seconds,
        "figures": done,
        "failed": failed,
    });
    let text = if args.model.json {
        format!("{report}\n")
    } else {
        human(&report)
    };
    let mut stdout = std::io::stdout().lock();
    if let Err(e) = stdout.write_all(text.as_bytes()) {
        if e.kind() != std::io::ErrorKind::BrokenPipe {
            return Err(CommandError::Failed(anyhow!("cannot write to stdout: {e}")));
        }
    }
    if failed.is_empty() {
        Ok(())
    } else {
        Err(CommandError::Failed(anyhow!(
            "{} of {} figures failed: {}",
            failed.len(),
            which.len(),
            failed.join("; ")
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

fn human(report: &Value) -> String {
    let mut s = format!(
        "figures written to {} in {:.1} s{}\n",
        report["out"].as_str().unwrap_or(""),
        report["seconds"].as_f64().unwrap_or(0.0),
        if report["quick"].as_bool() == Some(true) {
            " (quick preview)"
        } else {
            ""
        }
    );
    for f in report["figures"].as_array().into_iter().flatten() {
        s += &format!(
            "  {} ({:.1} s): {}\n",
            f["path"].as_str().unwrap_or(""),
            f["seconds"].as_f64().unwrap_or(0.0),
            f["summary"]["text"].as_str().unwrap_or("")
        );
    }
    s
}

/// What every figure needs.
struct Ctx {
    params: Params,
    impact: ImpactLaw,
    set: Settings,
    out: PathBuf,
}

impl Ctx {
    fn path(&self, n: u8) -> PathBuf {
        self.out.join(format!("fig{n}.png"))
    }

    fn amplitudes(&self) -> Vec<f64> {
        gains::range(FIG4_A.0, FIG4_A.1, self.set.a_step)
    }

    fn kps(&self) -> Vec<f64> {
        gains::range(60.0, 140.0, self.set.kp_step)
    }

    fn kds(&self) -> Vec<f64> {
        gains::range(8.0, 20.0, self.set.kd_step)
    }

    fn ks(&self) -> Vec<f64> {
        gains::range(FIG8_K.0, FIG8_K.1, self.set.k_step)
    }

    /// Progress units of figure `n`.
    fn units(&self, n: u8) -> u64 {
        (match n {
            4 => self.amplitudes().len() + 1,
            5 => FIG5_S.len(),
            6 => self.kps().len() + 1,
            7 => 4,
            8 => self.ks().len() + FIG8_SERIES.len() + 2,
            _ => 0,
        }) as u64
    }

    fn sim_config(&self) -> SimConfig {
        SimConfig {
            params: self.params,
            impact: self.impact,
            // Small steps: the samples are drawn as a polyline.
            h_max: 2e-3,
            ..SimConfig::default()
        }
    }

    fn orbit_problem(&self) -> OrbitProblem {
        OrbitProblem::new(self.params, self.impact, KP, KD)
    }
}

// ---------------------------------------------------------------------------------------------
// Drawing helpers.

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

fn style_mesh<'a, X, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<X, Y>>,
    x_desc: &str,
    y_desc: &str,
) -> Result<()>
where
    X: plotters::coord::ranged1d::Ranged<ValueType = f64>
        + plotters::coord::ranged1d::ValueFormatter<f64>,
    Y: plotters::coord::ranged1d::Ranged<ValueType = f64>
        + plotters::coord::ranged1d::ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .axis_desc_style((FONT, 22))
        .label_style((FONT, 17))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08))
        .draw()?;
    Ok(())
}

fn legend<'a, X, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<X, Y>>,
    pos: SeriesLabelPosition,
) -> Result<()>
where
    X: plotters::coord::ranged1d::Ranged<ValueType = f64>,
    Y: plotters::coord::ranged1d::Ranged<ValueType = f64>,
{
    chart
        .configure_series_labels()
        .position(pos)
        .label_font((FONT, 17))
        .background_style(WHITE.mix(0.92))
        .border_style(BLACK.mix(0.4))
        .margin(10)
        .draw()?;
    Ok(())
}

/// An axis label with three decimals, without a spurious "-0.000".
fn tick3(v: &f64) -> String {
    let v = if v.abs() < 5e-4 { 0.0 } else { *v };
    format!("{v:.3}")
}

/// A five-pointed star of outer radius `r` pixels (polygon offsets from its centre).
fn star_points(r: f64) -> Vec<(i32, i32)> {
    (0..10)
        .map(|i| {
            let rr = if i % 2 == 0 { r } else { 0.42 * r };
            let phi = -FRAC_PI_2 + PI * i as f64 / 5.0;
            (
                (rr * phi.cos()).round() as i32,
                (rr * phi.sin()).round() as i32,
            )
        })
        .collect()
}

/// Cuts a polyline to the box `x0..x1` by `y0..y1` (Liang-Barsky on each segment): the parts
/// inside, each as its own polyline. plotters does not clip to the plotting area.
fn clip(
    pts: impl IntoIterator<Item = (f64, f64)>,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut prev: Option<(f64, f64)> = None;
    let mut open = false;
    for q in pts {
        let Some(p) = prev.replace(q) else {
            if (x0..=x1).contains(&q.0) && (y0..=y1).contains(&q.1) {
                out.push(vec![q]);
                open = true;
            }
            continue;
        };
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        let (mut u0, mut u1) = (0.0f64, 1.0f64);
        let mut visible = true;
        for (pk, qk) in [
            (-dx, p.0 - x0),
            (dx, x1 - p.0),
            (-dy, p.1 - y0),
            (dy, y1 - p.1),
        ] {
            if pk == 0.0 {
                if qk < 0.0 {
                    visible = false;
                }
            } else {
                let r = qk / pk;
                if pk < 0.0 {
                    u0 = u0.max(r);
                } else {
                    u1 = u1.min(r);
                }
            }
        }
        if !visible || u0 > u1 {
            open = false;
            continue;
        }
        let a = (p.0 + u0 * dx, p.1 + u0 * dy);
        let b = (p.0 + u1 * dx, p.1 + u1 * dy);
        if !(open && u0 == 0.0) {
            out.push(vec![a]);
        }
        out.last_mut().expect("a part was started").push(b);
        open = u1 == 1.0;
    }
    out
}

/// A symmetric range `[-m, m]` around zero covering the values, with a margin.
fn symmetric(v: impl Iterator<Item = f64>, pad: f64) -> (f64, f64) {
    let m = v
        .filter(|x| x.is_finite())
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(1e-6);
    (-(1.0 + pad) * m, (1.0 + pad) * m)
}

// ---------------------------------------------------------------------------------------------
// Fig. 4.

/// `s` with a typographic minus sign.
fn signed(s: f64) -> String {
    if s < 0.0 {
        format!("−{}", -s)
    } else {
        format!("{s}")
    }
}

/// A landing-offset curve of Fig. 4.
struct Curve {
    /// The target `s`.
    s: f64,
    /// The `s` actually drawn (the target or the fallback `±0.98`).
    drawn: f64,
    /// `(A, w)` of each amplitude, `None` where there is no solution.
    points: Vec<Option<(f64, f64)>>,
}

/// Tilt start and landing of the ideal motion, if it tilts and lands.
fn tilt_and_landing(p: &Params, a: f64, w: f64) -> Option<(f64, f64)> {
    let tol = Search::default().tol;
    let t = sinusoid::ideal_tilt(p, a, w, tol).ok()?;
    Some((t.tilt_time, t.landing_time?))
}

/// The lowest frequency (rad/s) in `[lo, hi]` at which the ideal motion of amplitude `a`
/// makes the plate tilt; `Some(lo)` if it tilts at `lo` already, `None` if never.
fn no_tilt_boundary(p: &Params, a: f64, lo: f64, hi: f64) -> Option<f64> {
    let no_tilt = |w: f64| sinusoid::tilt_start(p, a, w).is_none();
    if !no_tilt(lo) {
        return Some(lo);
    }
    let n = 200;
    let mut w0 = lo;
    for i in 1..=n {
        let w1 = lo * (hi / lo).powf(i as f64 / n as f64);
        if !no_tilt(w1) {
            let (mut a0, mut a1) = (w0, w1);
            while a1 - a0 > 1e-12 * a1 {
                let m = 0.5 * (a0 + a1);
                if no_tilt(m) {
                    a0 = m;
                } else {
                    a1 = m;
                }
            }
            return Some(a1);
        }
        w0 = w1;
    }
    None
}

/// For one amplitude: the first `w` above the no-tilt boundary solving `t_l = T/2 + s t_t`
/// for each of `ss`. The scan is geometric in the distance to the boundary, where the
/// solutions for `s` near -1 crowd.
fn solve_curves(p: &Params, a: f64, ss: &[f64], scan: usize) -> Vec<Option<f64>> {
    let (lo, hi) = (0.05, 60.0);
    let Some(w_nt) = no_tilt_boundary(p, a, lo, hi) else {
        return vec![None; ss.len()];
    };
    let ws: Vec<f64> = if w_nt > lo {
        // Distances from 1e-9 to 1.5 times the boundary frequency.
        (0..scan)
            .map(|i| w_nt * (1.0 + 1e-9 * (1.5e9f64).powf(i as f64 / (scan - 1) as f64)))
            .collect()
    } else {
        (0..scan)
            .map(|i| lo * (hi / lo).powf(i as f64 / (scan - 1) as f64))
            .collect()
    };
    let tl: Vec<Option<(f64, f64)>> = ws.iter().map(|&w| tilt_and_landing(p, a, w)).collect();
    let residual = |s: f64, w: f64, tt: (f64, f64)| tt.1 - (PI / w + s * tt.0);
    ss.iter()
        .map(|&s| {
            for i in 1..ws.len() {
                let (Some(t0), Some(t1)) = (tl[i - 1], tl[i]) else {
                    continue;
                };
                let (r0, r1) = (residual(s, ws[i - 1], t0), residual(s, ws[i], t1));
                if (r0 > 0.0) == (r1 > 0.0) {
                    continue;
                }
                let (mut w0, mut w1) = (ws[i - 1], ws[i]);
                let pos0 = r0 > 0.0;
                let mut ok = true;
                while w1 - w0 > 1e-11 * w1 {
                    let m = 0.5 * (w0 + w1);
                    let Some(tm) = tilt_and_landing(p, a, m) else {
                        ok = false;
                        break;
                    };
                    if (residual(s, m, tm) > 0.0) == pos0 {
                        w0 = m;
                    } else {
                        w1 = m;
                    }
                }
                if ok {
                    return Some(0.5 * (w0 + w1));
                }
            }
            None
        })
        .collect()
}

fn fig4(ctx: &Ctx, bar: &indicatif::ProgressBar) -> Result<Value> {
    let p = ctx.params;
    // The no-tilt grid.
    let ga = gains::range(FIG4_A.0, FIG4_A.1, ctx.set.grid_a_step);
    let gw = gains::range(FIG4_W.0, FIG4_W.1, ctx.set.grid_w_step);
    let cells: Vec<(f64, f64, u8)> = ga
        .par_iter()
        .flat_map_iter(|&a| {
            gw.iter().map(move |&w| {
                let kind = u8::from(sinusoid::tilt_start(&p, a, w).is_some());
                (a, w, kind)
            })
        })
        .collect();
    bar.inc(1);
    // The curves: exact s = -1, 0, 1 and the fallbacks -0.98, 0.98.
    let ss = [-1.0, 0.0, 1.0, -0.98, 0.98];
    let amps = ctx.amplitudes();
    let roots: Vec<Vec<Option<f64>>> = amps
        .par_iter()
        .map(|&a| {
            let r = solve_curves(&p, a, &ss, ctx.set.scan);
            bar.inc(1);
            r
        })
        .collect();
    let column = |j: usize| -> Vec<Option<(f64, f64)>> {
        amps.iter()
            .zip(&roots)
            .map(|(&a, r)| r[j].map(|w| (a, w)))
            .collect()
    };
    let count = |v: &[Option<(f64, f64)>]| v.iter().filter(|x| x.is_some()).count();
    let mut curves = Vec::new();
    for (j, fallback) in [(0, 3), (1, 1), (2, 4)] {
        let exact = column(j);
        let alt = column(fallback);
        // Fall back when the exact limit has clearly fewer solutions than its neighbour.
        let curve = if j != fallback && count(&exact) * 2 < count(&alt) {
            Curve {
                s: ss[j],
                drawn: ss[fallback],
                points: alt,
            }
        } else {
            Curve {
                s: ss[j],
                drawn: ss[j],
                points: exact,
            }
        };
        curves.push(curve);
    }
    draw_fig4(&ctx.path(4), &cells, &curves)?;
    let no_tilt = cells.iter().filter(|c| c.2 == 0).count();
    let band_033 = curves
        .iter()
        .map(|c| {
            c.points
                .iter()
                .flatten()
                .find(|(a, _)| (a - 0.33).abs() < 1e-9)
                .map(|&(_, w)| w)
        })
        .collect::<Vec<_>>();
    let text = format!(
        "(A, w) partition: {no_tilt} of {} grid pairs do not tilt; curves s = {} ({} amplitudes){}",
        cells.len(),
        curves
            .iter()
            .map(|c| format!("{}", c.drawn))
            .collect::<Vec<_>>()
            .join(", "),
        amps.len(),
        match (band_033[0], band_033[2]) {
            (Some(w0), Some(w1)) =>
                format!("; at A = 0.33 the band is w in [{w0:.4}, {w1:.4}] rad/s"),
            _ => String::new(),
        }
    );
    Ok(json!({
        "text": text,
        "grid_pairs": cells.len(),
        "no_tilt_pairs": no_tilt,
        "curves": curves.iter().map(|c| json!({
            "s": c.s,
            "s_drawn": c.drawn,
            "points": c.points.iter().flatten().map(|&(a, w)| [a, w]).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
    }))
}

fn draw_fig4(path: &Path, cells: &[(f64, f64, u8)], curves: &[Curve]) -> Result<()> {
    let root = BitMapBackend::new(path, (1400, 1000)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        "Fig. 4: partition of the (A, ω) plane for β_d = A sin(ωt) + π/2 (ideal tracking, no impact)",
        (FONT, 26),
    )?;
    let w_top = curves
        .iter()
        .flat_map(|c| c.points.iter().flatten().map(|p| p.1))
        .fold(FIG4_W.1, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .margin(20)
        .margin_right(40)
        .x_label_area_size(60)
        .y_label_area_size(80)
        .build_cartesian_2d(0.0..FIG4_A.1 + 0.02, 0.0..w_top * 1.03)?;
    style_mesh(&mut chart, "amplitude A [rad]", "frequency ω [rad/s]")?;
    let star = star_points(7.0);
    chart
        .draw_series(cells.iter().filter(|c| c.2 == 0).map(|&(a, w, _)| {
            EmptyElement::at((a, w)) + Polygon::new(star.clone(), GREY.mix(0.85).filled())
        }))?
        .label("no tilt: the ZMP stays inside the support for all t")
        .legend(|(x, y)| {
            EmptyElement::at((x + 10, y)) + Polygon::new(star_points(7.0), GREY.filled())
        });
    let colors = [BLUE, GREEN, RED];
    for (c, color) in curves.iter().zip(colors) {
        let name = match c.s {
            s if s < 0.0 => "t_l = T/2 − t_t",
            s if s > 0.0 => "t_l = T/2 + t_t",
            _ => "t_l = T/2",
        };
        let label = if c.drawn != c.s {
            format!(
                "{name}: no tilting solution at s = {}, drawn with s = {}",
                signed(c.s),
                signed(c.drawn)
            )
        } else {
            format!("{name} (s = {})", signed(c.s))
        };
        // Consecutive solved amplitudes are joined; a gap breaks the line.
        for seg in c.points.split(|p| p.is_none()) {
            chart.draw_series(LineSeries::new(
                seg.iter().flatten().copied(),
                color.stroke_width(3),
            ))?;
        }
        chart
            .draw_series(
                c.points
                    .iter()
                    .flatten()
                    .map(|&p| Circle::new(p, 3, color.filled())),
            )?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
            });
    }
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present()?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Fig. 5.

/// Records `(t, alpha)` and the transitions of a run.
#[derive(Default)]
struct Trace {
    t: Vec<f64>,
    alpha: Vec<f64>,
    alpha_dot: Vec<f64>,
    peaks: Vec<TiltPeak>,
}

impl Observer for Trace {
    fn sample(&mut self, t: f64, _mode: Mode, x: &State) {
        self.t.push(t);
        self.alpha.push(x[0]);
        self.alpha_dot.push(x[2]);
    }
    fn tilt_peak(&mut self, p: &TiltPeak) {
        self.peaks.push(*p);
    }
}

/// Simulates `law` from `(mode, x0)` for `duration` seconds; the trace and the fault, if any.
fn simulate(
    ctx: &Ctx,
    law: &ComputedTorque,
    mode: Mode,
    x0: State,
    duration: f64,
) -> Result<(Trace, Option<String>)> {
    let mut plant = Plant::new(ctx.sim_config(), 0.0, mode, x0)?;
    let mut tr = Trace::default();
    tr.sample(0.0, mode, &x0);
    let fault = plant
        .advance_continuous(law, duration, &mut tr)
        .err()
        .map(|e| e.to_string());
    Ok((tr, fault))
}

/// A short form of a fault for a panel title.
fn short_fault(f: &str) -> String {
    let head = f.split(':').next().unwrap_or(f);
    let kind = head.split(" at t = ").next().unwrap_or(head);
    let t = f
        .split("t = ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse::<f64>().ok());
    match t {
        Some(t) => format!("{kind} at t = {t:.2} s"),
        None => kind.to_string(),
    }
}

struct Fig5Panel {
    label: String,
    omega: f64,
    period: f64,
    max_tilt: f64,
    desired: Vec<(f64, f64)>,
    simulated: Vec<(f64, f64)>,
    fault: Option<String>,
    sim_max: f64,
}

fn fig5(ctx: &Ctx, bar: &indicatif::ProgressBar) -> Result<Value> {
    let p = ctx.params;
    let panels: Vec<Result<Fig5Panel>> = FIG5_S
        .par_iter()
        .enumerate()
        .map(|(i, &(s, frac))| {
            let r = (|| {
                let sol = sinusoid::solve(&p, FIG5_A, s, &Search::default())
                    .with_context(|| format!("A = {FIG5_A}, s = -{frac}"))?;
                let w = sol.omega;
                let law = ComputedTorque::new(ControlConfig {
                    params: p,
                    kp: KP,
                    kd: KD,
                    reference: Reference::Sinusoid {
                        amplitude: FIG5_A,
                        omega: w,
                    },
                    ..ControlConfig::default()
                })?;
                let x0 = State::new(0.0, FRAC_PI_2, 0.0, FIG5_A * w);
                let duration = ctx.set.periods * sol.period;
                let (tr, fault) = simulate(ctx, &law, Mode::Flat, x0, duration)?;
                let ideal = sinusoid::sample_ideal_tilt(&p, FIG5_A, w, 400);
                let n = 3000;
                let desired = (0..=n)
                    .map(|j| {
                        let t = duration * j as f64 / n as f64;
                        (t, sinusoid::desired_alpha(&ideal, sol.period, t))
                    })
                    .collect();
                let sim_max = tr.alpha.iter().fold(0.0f64, |m, a| m.max(a.abs()));
                Ok(Fig5Panel {
                    label: format!(
                        "{}) t_l = T/2 − t_t/{}",
                        (b'a' + i as u8) as char,
                        &frac[2..]
                    ),
                    omega: w,
                    period: sol.period,
                    max_tilt: sol.max_tilt,
                    desired,
                    simulated: tr.t.iter().copied().zip(tr.alpha.iter().copied()).collect(),
                    fault,
                    sim_max,
                })
            })();
            bar.inc(1);
            r
        })
        .collect();
    let panels = panels.into_iter().collect::<Result<Vec<_>>>()?;
    draw_fig5(&ctx.path(5), &panels)?;
    let text = panels
        .iter()
        .map(|q| {
            format!(
                "{} w = {:.4} rad/s (planned max tilt {:.4} rad, simulated {:.4} rad{})",
                &q.label[..2],
                q.omega,
                q.max_tilt,
                q.sim_max,
                q.fault
                    .as_ref()
                    .map_or(String::new(), |f| format!(", {}", short_fault(f)))
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    Ok(json!({
        "text": text,
        "panels": panels.iter().map(|q| json!({
            "label": q.label,
            "omega": q.omega,
            "period": q.period,
            "planned_max_tilt": q.max_tilt,
            "simulated_max_tilt": q.sim_max,
            "fault": q.fault,
        })).collect::<Vec<_>>(),
    }))
}

fn draw_fig5(path: &Path, panels: &[Fig5Panel]) -> Result<()> {
    let root = BitMapBackend::new(path, (1600, 1100)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "Fig. 5: planned (dashed) vs simulated (solid) tilt, A = {FIG5_A} rad, PD K_P = {KP}, K_D = {KD}, with impacts"
        ),
        (FONT, 26),
    )?;
    for (area, q) in root.split_evenly((2, 2)).iter().zip(panels) {
        draw_fig5_panel(area, q)?;
    }
    root.present()?;
    Ok(())
}

fn draw_fig5_panel(area: &Area, q: &Fig5Panel) -> Result<()> {
    let t_end = q.desired.last().map_or(1.0, |d| d.0);
    // Scaled to the plan: a run that falls leaves the frame (the fall is in the caption).
    let planned = q.desired.iter().fold(0.0f64, |m, d| m.max(d.1.abs()));
    let (lo, hi) = symmetric(
        q.desired.iter().map(|d| d.1).chain(
            q.simulated
                .iter()
                .map(|s| s.1.clamp(-3.0 * planned, 3.0 * planned)),
        ),
        0.1,
    );
    // Headroom for the legend.
    let (data_hi, hi) = (hi, hi + 0.35 * (hi - lo));
    let caption = format!(
        "{}: ω = {:.4} rad/s{}",
        q.label,
        q.omega,
        q.fault
            .as_ref()
            .map_or(String::new(), |f| format!(" ({})", short_fault(f)))
    );
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 22))
        .margin(14)
        .margin_right(30)
        .x_label_area_size(55)
        .y_label_area_size(95)
        .build_cartesian_2d(0.0..t_end, lo..hi)?;
    chart
        .configure_mesh()
        .x_desc("time t [s]")
        .y_desc("tilt angle α [rad]")
        .axis_desc_style((FONT, 20))
        .label_style((FONT, 16))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08))
        .y_label_formatter(&tick3)
        .draw()?;
    chart
        .draw_series(DashedLineSeries::new(
            q.desired.iter().copied(),
            10,
            6,
            BLACK.stroke_width(2),
        ))?
        .label(format!(
            "planned α_d (ideal tracking, max {:.4} rad)",
            q.max_tilt
        ))
        .legend(|(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(vec![(0, 0), (10, 0)], BLACK.stroke_width(2))
                + PathElement::new(vec![(16, 0), (26, 0)], BLACK.stroke_width(2))
        });
    let parts = clip(q.simulated.iter().copied(), (0.0, t_end), (lo, data_hi));
    for part in parts.iter().skip(1) {
        chart.draw_series(LineSeries::new(part.iter().copied(), BLUE.stroke_width(2)))?;
    }
    chart
        .draw_series(LineSeries::new(
            parts.first().into_iter().flatten().copied(),
            BLUE.stroke_width(2),
        ))?
        .label(format!("simulated α (max |α| {:.4} rad)", q.sim_max))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 26, y)], BLUE.stroke_width(2)));
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Fig. 6.

fn fig6(ctx: &Ctx, bar: &indicatif::ProgressBar) -> Result<Value> {
    let (kps, kds) = (ctx.kps(), ctx.kds());
    let cells = gains::grid(ctx.params, ctx.impact, &kps, &kds, &|| bar.inc(1));
    let paper = orbit::find_all(&ctx.orbit_problem());
    bar.inc(1);
    if cells.iter().all(|c| c.max_tilt.is_empty()) {
        return Err(anyhow!(
            "no periodic orbit anywhere on the grid (impact law {})",
            ctx.impact.as_str()
        ));
    }
    draw_fig6(&ctx.path(6), &kps, &cells, &paper)?;
    let orbits: usize = cells.iter().map(|c| c.max_tilt.len()).sum();
    let stable: usize = cells
        .iter()
        .map(|c| c.stable.iter().filter(|s| **s).count())
        .sum();
    let empty = cells.iter().filter(|c| c.max_tilt.is_empty()).count();
    let text = format!(
        "{} cells (K_P {}..{}, K_D {}..{}), {orbits} orbits ({stable} stable), {empty} cells without orbit; at K_P = {KP}, K_D = {KD}: max tilt {}",
        cells.len(),
        kps[0],
        kps[kps.len() - 1],
        kds[0],
        kds[kds.len() - 1],
        paper
            .first()
            .map_or("none".into(), |o| format!("{:.6} rad", o.max_tilt))
    );
    Ok(json!({ "text": text, "cells": cells }))
}

fn draw_fig6(
    path: &Path,
    kps: &[f64],
    cells: &[gains::Cell],
    paper: &[OrbitSolution],
) -> Result<()> {
    let root = BitMapBackend::new(path, (1400, 950)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        "Fig. 6: maximal tilt angle of the periodic orbits (approach 2, hold β_d = π/2), one line per K_P [1/s²]",
        (FONT, 26),
    )?;
    let kd_lo = cells.iter().map(|c| c.kd).fold(f64::INFINITY, f64::min);
    let kd_hi = cells.iter().map(|c| c.kd).fold(f64::NEG_INFINITY, f64::max);
    let y_hi = cells
        .iter()
        .flat_map(|c| c.max_tilt.iter().copied())
        .fold(0.0f64, f64::max)
        * 1.08;
    let mut chart = ChartBuilder::on(&root)
        .margin(20)
        .margin_right(40)
        .x_label_area_size(60)
        .y_label_area_size(90)
        .build_cartesian_2d((kd_lo - 0.3)..(kd_hi + 1.6), 0.0..y_hi)?;
    chart
        .configure_mesh()
        .x_desc("damping gain K_D [1/s]")
        .y_desc("maximal tilt angle α_max [rad]")
        .axis_desc_style((FONT, 22))
        .label_style((FONT, 17))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08))
        .y_label_formatter(&|v| format!("{v:.2}"))
        .draw()?;
    for (i, &kp) in kps.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let row: Vec<&gains::Cell> = cells.iter().filter(|c| c.kp == kp).collect();
        // The smallest-tilt branch over the whole row, joined where it exists.
        let lower: Vec<Option<(f64, f64)>> = row
            .iter()
            .map(|c| c.max_tilt.first().map(|&m| (c.kd, m)))
            .collect();
        for seg in lower.split(|p| p.is_none()) {
            chart.draw_series(LineSeries::new(
                seg.iter().flatten().copied(),
                color.stroke_width(2),
            ))?;
        }
        // Where three orbits coexist, the middle and upper ones meet in a fold: draw them as
        // one curve, the middle branch forward and the upper one back.
        let three: Vec<&&gains::Cell> = row.iter().filter(|c| c.max_tilt.len() == 3).collect();
        if three.len() >= 2 {
            let fold: Vec<(f64, f64)> = three
                .iter()
                .map(|c| (c.kd, c.max_tilt[1]))
                .chain(three.iter().rev().map(|c| (c.kd, c.max_tilt[2])))
                .collect();
            chart.draw_series(LineSeries::new(fold, color.mix(0.6).stroke_width(2)))?;
        }
        for c in &row {
            for (&m, &st) in c.max_tilt.iter().zip(&c.stable) {
                let style = if st {
                    color.filled()
                } else {
                    color.stroke_width(2)
                };
                chart.draw_series(std::iter::once(Circle::new((c.kd, m), 5, style)))?;
            }
        }
        // Each line is labelled at its right end.
        if let Some(&(kd, m)) = lower.iter().flatten().last() {
            chart.draw_series(std::iter::once(Text::new(
                format!("K_P = {kp}"),
                (kd + 0.2, m),
                TextStyle::from((FONT, 17))
                    .color(&color)
                    .pos(Pos::new(HPos::Left, VPos::Center)),
            )))?;
        }
    }
    chart
        .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
        .label("unstable orbit (smallest tilt: the paper's orbits)")
        .legend(|(x, y)| Circle::new((x + 12, y), 5, BLACK.stroke_width(2)));
    chart
        .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
        .label("stable orbit (a second pair at small K_D, joined with the upper unstable one)")
        .legend(|(x, y)| Circle::new((x + 12, y), 5, BLACK.filled()));
    if let Some(o) = paper.first() {
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((KD, o.max_tilt))
                    + Polygon::new(star_points(13.0), BLACK.filled()),
            ))?
            .label(format!(
                "paper's gains K_P = {KP}, K_D = {KD}: {:.4} rad (Fig. 7 orbit)",
                o.max_tilt
            ))
            .legend(|(x, y)| {
                EmptyElement::at((x + 12, y)) + Polygon::new(star_points(9.0), BLACK.filled())
            });
    }
    legend(&mut chart, SeriesLabelPosition::UpperMiddle)?;
    root.present()?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Fig. 7.

struct Fig7Run {
    name: &'static str,
    color: RGBColor,
    trace: Trace,
    fault: Option<String>,
}

fn fig7(ctx: &Ctx, bar: &indicatif::ProgressBar) -> Result<Value> {
    let pb = ctx.orbit_problem();
    let o = commands::base_orbit(&pb).map_err(|e| anyhow!("{e}"))?;
    bar.inc(1);
    let law = |k: f64| {
        ComputedTorque::new(ControlConfig {
            k,
            energy_avg: o.energy_avg,
            ..pb.control
        })
    };
    let runs = [
        (0.0, -FIG7_PERTURBATION),
        (FIG7_K, FIG7_PERTURBATION),
        (0.0, FIG7_PERTURBATION),
    ];
    let traces: Vec<Result<(Trace, Option<String>)>> = runs
        .par_iter()
        .map(|&(k, d)| {
            let r = law(k).map_err(anyhow::Error::from).and_then(|l| {
                simulate(
                    ctx,
                    &l,
                    Mode::Left,
                    OrbitProblem::start(o.beta0, o.beta_dot0 + d),
                    ctx.set.fig7_duration,
                )
            });
            bar.inc(1);
            r
        })
        .collect();
    let mut traces = traces.into_iter().collect::<Result<Vec<_>>>()?;
    // Name the k = 0 runs by what they do: compare their last peaks.
    let last_peak = |tr: &Trace| tr.peaks.last().map_or(0.0, |p| p.alpha.abs());
    let (a, b) = (last_peak(&traces[0].0), last_peak(&traces[2].0));
    if a > b {
        traces.swap(0, 2);
    }
    let names = [
        ("k = 0, decreasing", BLUE),
        ("k = 500, controlled", GREEN),
        ("k = 0, increasing", RED),
    ];
    let runs: Vec<Fig7Run> = traces
        .into_iter()
        .zip(names)
        .map(|((trace, fault), (name, color))| Fig7Run {
            name,
            color,
            trace,
            fault,
        })
        .collect();
    // The unstable orbit itself, one period from its exact start.
    let (orbit_trace, _) = simulate(
        ctx,
        &law(0.0)?,
        Mode::Left,
        OrbitProblem::start(o.beta0, o.beta_dot0),
        o.period,
    )?;
    draw_fig7(&ctx.path(7), &o, &orbit_trace, &runs, ctx.set.fig7_duration)?;
    let text = runs
        .iter()
        .map(|r| {
            let peaks: Vec<f64> = r.trace.peaks.iter().map(|p| p.alpha.abs()).collect();
            format!(
                "{}: {} tilts, last peak {}{}",
                r.name,
                peaks.len(),
                peaks
                    .last()
                    .map_or("none".into(), |p| format!("{p:.4} rad")),
                r.fault
                    .as_ref()
                    .map_or(String::new(), |f| format!(" ({})", short_fault(f)))
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    Ok(json!({
        "text": format!("orbit max tilt {:.4} rad, E_av = {:.6} J; {text}", o.max_tilt, o.energy_avg),
        "orbit": o,
        "runs": runs.iter().map(|r| json!({
            "name": r.name,
            "peaks": r.trace.peaks.iter().map(|p| p.alpha).collect::<Vec<_>>(),
            "fault": r.fault,
        })).collect::<Vec<_>>(),
    }))
}

fn draw_fig7(
    path: &Path,
    o: &OrbitSolution,
    orbit_trace: &Trace,
    runs: &[Fig7Run],
    duration: f64,
) -> Result<()> {
    let root = BitMapBackend::new(path, (1600, 1250)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "Fig. 7: stabilisation of the unstable orbit by K_P = K_P0 + k (E_av − E), K_P0 = {KP}, K_D = {KD}, start: the orbit's dβ/dt(0) ± {FIG7_PERTURBATION} rad/s"
        ),
        (FONT, 24),
    )?;
    let (top, bottom) = root.split_vertically(680);
    // Phase portrait, scaled to the controlled orbit: the diverging run leaves the frame.
    let ctrl = &runs[1].trace;
    let (a_lo, a_hi) = symmetric(ctrl.alpha.iter().copied(), 0.0);
    let (v_lo, v_hi) = symmetric(ctrl.alpha_dot.iter().copied(), 0.0);
    let scale = 2.2;
    let mut chart = ChartBuilder::on(&top)
        .caption(
            format!(
                "phase portrait (α, dα/dt): the unstable orbit lies between the decaying and the growing run; k = {FIG7_K} holds the adapted loop on its own orbit (last peak {:.4} rad)",
                runs[1].trace.peaks.last().map_or(f64::NAN, |p| p.alpha.abs())
            ),
            (FONT, 21),
        )
        .margin(14)
        .margin_right(40)
        .x_label_area_size(55)
        .y_label_area_size(90)
        .build_cartesian_2d(scale * a_lo..scale * a_hi, scale * v_lo..scale * v_hi)?;
    chart
        .configure_mesh()
        .x_desc("tilt angle α [rad]")
        .y_desc("tilt rate dα/dt [rad/s]")
        .axis_desc_style((FONT, 20))
        .label_style((FONT, 16))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08))
        .x_label_formatter(&tick3)
        .draw()?;
    // Draw the k = 0 runs first and the controlled orbit on top.
    for i in [0, 2, 1] {
        let r = &runs[i];
        let parts = clip(
            r.trace
                .alpha
                .iter()
                .copied()
                .zip(r.trace.alpha_dot.iter().copied()),
            (scale * a_lo, scale * a_hi),
            (scale * v_lo, scale * v_hi),
        );
        let width = if i == 1 { 3 } else { 1 };
        for part in parts.iter().skip(1) {
            chart.draw_series(LineSeries::new(
                part.iter().copied(),
                r.color.mix(0.9).stroke_width(width),
            ))?;
        }
        chart
            .draw_series(LineSeries::new(
                parts.first().into_iter().flatten().copied(),
                r.color.mix(0.9).stroke_width(width),
            ))?
            .label(format!(
                "{}{}",
                r.name,
                r.fault
                    .as_ref()
                    .map_or(String::new(), |f| format!(" ({})", short_fault(f)))
            ))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], r.color.stroke_width(3))
            });
    }
    chart
        .draw_series(DashedLineSeries::new(
            orbit_trace
                .alpha
                .iter()
                .copied()
                .zip(orbit_trace.alpha_dot.iter().copied()),
            8,
            5,
            BLACK.stroke_width(2),
        ))?
        .label(format!(
            "unstable k = 0 orbit, one period (max tilt {:.4} rad)",
            o.max_tilt
        ))
        .legend(|(x, y)| {
            EmptyElement::at((x, y))
                + PathElement::new(vec![(0, 0), (10, 0)], BLACK.stroke_width(2))
                + PathElement::new(vec![(15, 0), (24, 0)], BLACK.stroke_width(2))
        });
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    // Bottom: alpha(t) side by side.
    for (area, r) in bottom.split_evenly((1, 3)).iter().zip(runs) {
        let (lo, hi) = symmetric(r.trace.alpha.iter().copied(), 0.08);
        let caption = format!(
            "{}{}",
            r.name,
            r.fault
                .as_ref()
                .map_or(String::new(), |f| format!(": {}", short_fault(f)))
        );
        let mut c = ChartBuilder::on(area)
            .caption(caption, (FONT, 20))
            .margin(12)
            .margin_right(24)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(0.0..duration, lo..hi)?;
        c.configure_mesh()
            .x_desc("time t [s]")
            .y_desc("α [rad]")
            .axis_desc_style((FONT, 19))
            .label_style((FONT, 15))
            .light_line_style(WHITE.mix(0.0))
            .bold_line_style(BLACK.mix(0.08))
            .y_label_formatter(&tick3)
            .draw()?;
        c.draw_series(LineSeries::new(
            r.trace.t.iter().copied().zip(r.trace.alpha.iter().copied()),
            r.color.stroke_width(2),
        ))?;
    }
    root.present()?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Fig. 8.

fn fig8(ctx: &Ctx, bar: &indicatif::ProgressBar) -> Result<Value> {
    let pb = ctx.orbit_problem();
    let o = commands::base_orbit(&pb).map_err(|e| anyhow!("{e}"))?;
    bar.inc(1);
    let set = ctx.set;
    let sw = Sweep {
        problem: pb,
        start_beta0: o.beta0,
        start_beta_dot0: o.beta_dot0,
        energy_avg: o.energy_avg,
        tilts: set.tilts,
        keep: set.keep,
        period_tol: 1e-5,
    };
    let ks = ctx.ks();
    let rows = bifurcation::sweep(&sw, &ks, &|| bar.inc(1));
    let k_star = bifurcation::k_star(&sw, 500.0, FIG8_K.0, FIG8_K.1, 1e-3);
    bar.inc(1);
    let series_sw = Sweep {
        tilts: set.series_tilts,
        keep: set.series_keep,
        ..sw
    };
    let series: Vec<bifurcation::Row> = FIG8_SERIES
        .par_iter()
        .map(|&k| {
            let r = bifurcation::run_one(&series_sw, k);
            bar.inc(1);
            r
        })
        .collect();
    draw_fig8(&ctx.path(8), &rows, k_star, &sw, &series, &series_sw)?;
    let onset = rows.iter().find(|r| r.period != Some(1)).map(|r| r.k);
    let faults = rows.iter().filter(|r| r.fault.is_some()).count();
    let text = format!(
        "{} values of k in [{}, {}], {} tilts each (last {} drawn); k* = {}; first k not period 1: {}{}; series periods {}",
        ks.len(),
        FIG8_K.0,
        FIG8_K.1,
        set.tilts,
        set.keep,
        k_star.map_or("none in range".into(), |k| format!("{k:.2}")),
        onset.map_or("none".into(), |k| format!("{k}")),
        if faults > 0 {
            format!(", {faults} runs faulted")
        } else {
            String::new()
        },
        series
            .iter()
            .map(|r| format!(
                "k = {}: {}",
                r.k,
                r.period.map_or("irregular".into(), |p| p.to_string())
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(json!({
        "text": text,
        "k_star": k_star,
        "k_onset_observed": onset,
        "energy_avg": o.energy_avg,
        "series": series,
    }))
}

fn draw_fig8(
    path: &Path,
    rows: &[bifurcation::Row],
    k_star: Option<f64>,
    sw: &Sweep,
    series: &[bifurcation::Row],
    series_sw: &Sweep,
) -> Result<()> {
    let root = BitMapBackend::new(path, (1600, 1250)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "Fig. 8: energy-adapted loop K_P = K_P0 + k (E_av − E), K_P0 = {KP}, K_D = {KD}: maximal |α| of each tilt"
        ),
        (FONT, 25),
    )?;
    let (top, bottom) = root.split_vertically(700);
    let all = rows
        .iter()
        .flat_map(|r| r.peaks.iter().copied())
        .chain(series.iter().flat_map(|r| r.peaks.iter().copied()));
    let (lo, hi) = crate::plot::padded_range(all, 0.05);
    let hi = hi + 0.12 * (hi - lo);
    let (k0, k1) = (
        rows.first().map_or(FIG8_K.0, |r| r.k),
        rows.last().map_or(FIG8_K.1, |r| r.k),
    );
    let pad = 0.01 * (k1 - k0).max(1.0);
    let mut chart = ChartBuilder::on(&top)
        .caption(
            format!(
                "bifurcation diagram: the last {} of {} tilt peaks for each k",
                sw.keep
                    .min(rows.iter().map(|r| r.peaks.len()).max().unwrap_or(0)),
                sw.tilts,
            ),
            (FONT, 21),
        )
        .margin(14)
        .margin_right(40)
        .x_label_area_size(55)
        .y_label_area_size(90)
        .build_cartesian_2d((k0 - pad)..(k1 + pad), lo..hi)?;
    chart
        .configure_mesh()
        .x_desc("adaptation gain k [1/(J s²)]")
        .y_desc("tilt peak |α|max [rad]")
        .axis_desc_style((FONT, 20))
        .label_style((FONT, 16))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08))
        .y_label_formatter(&tick3)
        .draw()?;
    chart
        .draw_series(rows.iter().flat_map(|r| {
            r.peaks
                .iter()
                .map(move |&p| Circle::new((r.k, p), 1, BLACK.filled()))
        }))?
        .label("tilt peaks after the transient")
        .legend(|(x, y)| Circle::new((x + 12, y), 3, BLACK.filled()));
    let faulted: Vec<f64> = rows
        .iter()
        .filter(|r| r.fault.is_some())
        .map(|r| r.k)
        .collect();
    if !faulted.is_empty() {
        chart
            .draw_series(
                faulted
                    .iter()
                    .map(|&k| Cross::new((k, lo + 0.03 * (hi - lo)), 5, RED.stroke_width(2))),
            )?
            .label("run stopped early (fault)")
            .legend(|(x, y)| Cross::new((x + 12, y), 5, RED.stroke_width(2)));
    }
    if let Some(ks) = k_star {
        chart
            .draw_series(DashedLineSeries::new(
                vec![(ks, lo), (ks, hi)],
                8,
                5,
                RED.stroke_width(2),
            ))?
            .label(format!(
                "k* = {ks:.2}: a Floquet multiplier of the adapted orbit crosses −1 (paper: 1925)"
            ))
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], RED.stroke_width(2)));
    }
    for (i, &k) in FIG8_SERIES.iter().enumerate() {
        let s = chart.draw_series(std::iter::once(PathElement::new(
            vec![(k, lo), (k, lo + 0.06 * (hi - lo))],
            GREY.stroke_width(3),
        )))?;
        if i == 0 {
            s.label("k of the three time series below")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x + 12, y - 8), (x + 12, y + 8)], GREY.stroke_width(3))
                });
        }
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    // One scale for the three series, so that period 1 looks constant.
    let (plo, phi) =
        crate::plot::padded_range(series.iter().flat_map(|r| r.peaks.iter().copied()), 0.08);
    for (area, r) in bottom.split_evenly((1, 3)).iter().zip(series) {
        // The peaks kept are the last ones of the run (fewer if it stopped early).
        let n0 = series_sw.tilts.saturating_sub(r.peaks.len()) + 1;
        let pts: Vec<(f64, f64)> = r
            .peaks
            .iter()
            .enumerate()
            .map(|(i, &p)| ((n0 + i) as f64, p))
            .collect();
        let caption = format!(
            "k = {}: {}",
            r.k,
            match (&r.fault, r.period) {
                (Some(f), _) => short_fault(f),
                (None, Some(1)) => "period 1".to_string(),
                (None, Some(p)) => format!("period {p}"),
                (None, None) => "irregular".to_string(),
            }
        );
        let (x0, x1) = (
            pts.first().map_or(0.0, |p| p.0) - 1.0,
            pts.last().map_or(1.0, |p| p.0) + 1.0,
        );
        let mut c = ChartBuilder::on(area)
            .caption(caption, (FONT, 20))
            .margin(12)
            .margin_right(24)
            .x_label_area_size(50)
            .y_label_area_size(85)
            .build_cartesian_2d(x0..x1, plo..phi)?;
        c.configure_mesh()
            .x_desc("tilt number n")
            .y_desc("|α|max [rad]")
            .axis_desc_style((FONT, 19))
            .label_style((FONT, 15))
            .light_line_style(WHITE.mix(0.0))
            .bold_line_style(BLACK.mix(0.08))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&tick3)
            .draw()?;
        c.draw_series(LineSeries::new(pts.clone(), BLUE.mix(0.5).stroke_width(1)))?;
        c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, BLUE.filled())))?;
    }
    root.present()?;
    Ok(())
}
