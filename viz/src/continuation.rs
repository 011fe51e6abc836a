//! The drawings of issue 19: Fig. 8b (the sweep's tilt peaks overlaid with the continued
//! branches, stable solid and unstable dashed, flips marked, and the largest Lyapunov exponent
//! below on the same `k` axis) and Fig. 8c (the stability region of the period-1 orbit in
//! `(k, p2)` between its fold and flip curves).

use anyhow::Result;
use plotters::prelude::*;
use std::path::Path;
use tilting_planner::bifurcation::{self, Row, Sweep};
use tilting_planner::continuation::twopar::Region;
use tilting_planner::continuation::{Branch, Diagram, EventKind};
use tilting_planner::lyapunov::sampled::SampledExponent;
use tilting_planner::lyapunov::Exponent;

const FONT: &str = "sans-serif";

/// A colour per period 1, 2, 4, 8, 16, 32.
const PERIOD_COLOURS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(140, 86, 75),
];

fn colour(tilts: usize) -> RGBColor {
    PERIOD_COLOURS[(tilts.trailing_zeros() as usize).min(PERIOD_COLOURS.len() - 1)]
}

/// The sweep of the loop drawn under Fig. 8b's branches: `k` from the curve's start (at least
/// 1500) to its end in steps of `k_step`, `tilts` tilts per `k`, the last `keep` drawn.
#[derive(Debug, Clone, Copy)]
pub struct CascadeSweep {
    /// Step of `k` (1/(J s^2)).
    pub k_step: f64,
    /// Tilts simulated per `k`.
    pub tilts: usize,
    /// Tilts drawn (the last ones).
    pub keep: usize,
    /// The sweep starts at `k` no lower than this (1/(J s^2)): the paper's figure shows its
    /// cascade from 1500; a loop whose cascade lies elsewhere starts where its curve does.
    pub k_min: f64,
}

impl CascadeSweep {
    /// The published figure's: step 5, 600 tilts, 150 drawn.
    pub const FULL: Self = Self {
        k_step: 5.0,
        tilts: 600,
        keep: 150,
        k_min: 1500.0,
    };

    /// The values of `k` it runs over `[max(k_lo, k_min), k_hi]`.
    pub fn ks(&self, (k_lo, k_hi): (f64, f64)) -> Vec<f64> {
        let k_lo = k_lo.max(self.k_min).min(k_hi);
        (0..)
            .map(|i| k_lo + self.k_step * i as f64)
            .take_while(|&k| k <= k_hi)
            .collect()
    }
}

/// Fig. 8b as `plan continuation --plot` and `figures` draw it: sweeps the loop of `sw` (its
/// `tilts` and `keep` replaced by `grid`'s) over [`CascadeSweep::ks`] of `(k_lo, k_hi)` on all
/// cores (`tick` after each `k`), then draws the diagram `d` and the exponents over it with
/// [`draw_cascade`] (`sampled`: the sampled loop's exponents, drawn when not empty). Returns the
/// sweep's rows.
#[allow(clippy::too_many_arguments)]
pub fn cascade_figure(
    path: &Path,
    sw: &Sweep,
    (k_lo, k_hi): (f64, f64),
    grid: CascadeSweep,
    d: &Diagram,
    lyap: &[Exponent],
    sampled: &[SampledExponent],
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<Row>> {
    let ks = grid.ks((k_lo, k_hi));
    let rows = bifurcation::sweep(
        &Sweep {
            tilts: grid.tilts,
            keep: grid.keep,
            ..*sw
        },
        &ks,
        tick,
    );
    let k_lo = ks.first().copied().unwrap_or(k_lo);
    draw_cascade(path, (k_lo, k_hi), &rows, d, lyap, sampled)?;
    Ok(rows)
}

/// Draws Fig. 8b into `path` (PNG) over `k` in `[k0, k1]`: the sweep's peaks (`rows`, grey
/// dots), each branch's tilt peaks (one curve per tilt of the cycle; solid where the orbit is
/// stable, dashed where not), the flips (black diamonds), and below the largest Lyapunov
/// exponent (1/s) with its zero line; with `sampled` not empty, the sampled loop's two largest
/// exponents too (orange: the largest solid, the second dashed).
pub fn draw_cascade(
    path: &Path,
    (k0, k1): (f64, f64),
    rows: &[Row],
    d: &Diagram,
    lyap: &[Exponent],
    sampled: &[SampledExponent],
) -> Result<()> {
    crate::plot::register_fonts()?;
    let root = BitMapBackend::new(path, (1600, 1250)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        "Fig. 8b: the continued orbits over the sweep, and the largest Lyapunov exponent",
        (FONT, 25),
    )?;
    let (top, bottom) = root.split_vertically(800);
    let inside = |k: f64| k >= k0 && k <= k1;
    let peaks = rows
        .iter()
        .filter(|r| inside(r.k))
        .flat_map(|r| r.peaks.iter().copied())
        .chain(d.branches.iter().flat_map(|b| {
            b.points
                .iter()
                .filter(|p| inside(p.p))
                .flat_map(|p| p.peaks.iter().copied())
        }));
    let (lo, hi) = crate::plot::padded_range(peaks, 0.05);
    let mut chart = k_chart(
        &top,
        "tilt peaks |α|max: sweep (grey), period-1/2/4/8/16 orbits as BVPs (solid stable, dashed unstable), flips ◆",
        [k0, k1, lo, hi],
        "tilt peak |α|max [rad]",
        50,
    )?;
    chart.draw_series(rows.iter().filter(|r| inside(r.k)).flat_map(|r| {
        r.peaks
            .iter()
            .map(move |&p| Circle::new((r.k, p), 1, BLACK.mix(0.35).filled()))
    }))?;
    for br in &d.branches {
        draw_branch(&mut chart, br, (k0, k1))?;
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    draw_lyapunov(&bottom, (k0, k1), d, lyap, sampled)?;
    root.present()?;
    Ok(())
}

/// A panel of Fig. 8b on `area`: `k` in `[k0, k1]` (1/(J s^2)) across, `lo..hi` up (in the
/// unit of `y_desc`, its axis label), captioned `caption`, its mesh drawn; `x_labels`: the
/// height (px) of the area under it for the `k` labels.
fn k_chart<'a, 'b: 'a>(
    area: &'a DrawingArea<BitMapBackend<'b>, plotters::coord::Shift>,
    caption: &str,
    [k0, k1, lo, hi]: [f64; 4],
    y_desc: &str,
    x_labels: u32,
) -> Result<Chart<'a, 'b>> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FONT, 20))
        .margin(14)
        .margin_right(40)
        .x_label_area_size(x_labels)
        .y_label_area_size(90)
        .build_cartesian_2d(k0..k1, lo..hi)?;
    crate::plot::mesh(&mut chart, "adaptation gain k [1/(J s²)]", y_desc, (20, 16)).draw()?;
    Ok(chart)
}

/// The legend of `chart` at `pos`, on a light box.
fn legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>, pos: SeriesLabelPosition) -> Result<()> {
    chart
        .configure_series_labels()
        .position(pos)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.3))
        .label_font((FONT, 17))
        .draw()?;
    Ok(())
}

/// A chart of `f64` over `f64` on a bitmap (`'a`: the drawing area's borrow, `'b`: the
/// bitmap's).
type Chart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// One branch of Fig. 8b over `k` in `[k0, k1]`: a curve per tilt of its cycle (solid where
/// the orbit is stable, dashed where not), its legend entry and its flips (black diamonds).
fn draw_branch<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    br: &Branch,
    (k0, k1): (f64, f64),
) -> Result<()> {
    let inside = |k: f64| k >= k0 && k <= k1;
    let c = colour(br.tilts);
    // One curve per tilt of the cycle, split where the stability changes.
    for i in 0..br.tilts {
        let mut run: Vec<(f64, f64)> = Vec::new();
        let mut stable = None;
        let flush = |run: &mut Vec<(f64, f64)>,
                     stable: Option<bool>,
                     chart: &mut ChartContext<_, _>|
         -> Result<()> {
            if run.len() >= 2 {
                if stable == Some(true) {
                    chart.draw_series(LineSeries::new(run.clone(), c.stroke_width(3)))?;
                } else {
                    chart.draw_series(DashedLineSeries::new(
                        run.clone(),
                        6,
                        5,
                        c.stroke_width(2),
                    ))?;
                }
            }
            run.clear();
            Ok(())
        };
        for p in br.points.iter().filter(|p| inside(p.p)) {
            if stable.is_some_and(|s| s != p.stable) {
                let last = run.last().copied();
                flush(&mut run, stable, chart)?;
                run.extend(last);
            }
            stable = Some(p.stable);
            run.push((p.p, p.peaks.get(i).copied().unwrap_or(f64::NAN)));
        }
        flush(&mut run, stable, chart)?;
    }
    let label = format!("period {}", br.tilts);
    chart
        .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], c.stroke_width(3)));
    for ev in br
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Flip && inside(e.p))
    {
        chart.draw_series(ev.point.peaks.iter().map(|&a| {
            Polygon::new(
                vec![
                    (ev.p - 3.0, a),
                    (ev.p, a * 1.004),
                    (ev.p + 3.0, a),
                    (ev.p, a * 0.996),
                ],
                BLACK.filled(),
            )
        }))?;
    }
    Ok(())
}

/// The bottom panel of Fig. 8b.
fn draw_lyapunov(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    (k0, k1): (f64, f64),
    d: &Diagram,
    lyap: &[Exponent],
    sampled: &[SampledExponent],
) -> Result<()> {
    let inside = |(k, _): &(f64, f64)| *k >= k0 && *k <= k1;
    let pts: Vec<(f64, f64)> = lyap
        .iter()
        .filter_map(|e| e.lambda.map(|l| (e.p, l)))
        .filter(inside)
        .collect();
    let s1: Vec<(f64, f64)> = sampled
        .iter()
        .filter_map(|e| e.lambda.map(|l| (e.p, l)))
        .filter(inside)
        .collect();
    let s2: Vec<(f64, f64)> = sampled
        .iter()
        .filter_map(|e| e.lambda2.map(|l| (e.p, l)))
        .filter(inside)
        .collect();
    let (lo, hi) = crate::plot::padded_range(
        pts.iter().chain(&s1).chain(&s2).map(|p| p.1).chain([0.0]),
        0.08,
    );
    let mut chart = k_chart(
        area,
        "largest Lyapunov exponent λ (variational equations through the landings)",
        [k0, k1, lo, hi],
        "λ [1/s]",
        55,
    )?;
    chart.draw_series(LineSeries::new(
        vec![(k0, 0.0), (k1, 0.0)],
        BLACK.stroke_width(1),
    ))?;
    let blue = RGBColor(31, 119, 180);
    chart
        .draw_series(LineSeries::new(pts.clone(), blue.stroke_width(2)))?
        .label("continuous loop (the paper's): largest λ of the tilt map")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], blue.stroke_width(2)));
    chart.draw_series(pts.iter().map(|&p| Circle::new(p, 2, blue.filled())))?;
    let orange = RGBColor(255, 127, 14);
    if let Some(h) = sampled.first().map(|e| e.period) {
        chart
            .draw_series(LineSeries::new(s1, orange.stroke_width(2)))?
            .label(format!(
                "sampled loop (hold {} ms): largest λ (positive below the hold's scale)",
                h * 1e3
            ))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], orange.stroke_width(2))
            });
        chart
            .draw_series(DashedLineSeries::new(s2, 5, 4, orange.stroke_width(2)))?
            .label("sampled loop: second λ")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], orange.stroke_width(1))
            });
    }
    draw_cascade_marks(&mut chart, d, (k0, k1), (lo, hi))?;
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    Ok(())
}

/// The flips of the cascade `d` in `[k0, k1]` (1/(J s^2)) as grey dashed lines over `lo..hi`
/// on `chart`, and its accumulation point `k_inf` as a red line with its legend entry.
fn draw_cascade_marks<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    d: &Diagram,
    (k0, k1): (f64, f64),
    (lo, hi): (f64, f64),
) -> Result<()> {
    for &k in d.flips.iter().filter(|&&k| k >= k0 && k <= k1) {
        chart.draw_series(DashedLineSeries::new(
            vec![(k, lo), (k, hi)],
            4,
            4,
            BLACK.mix(0.4).stroke_width(1),
        ))?;
    }
    if let Some(ki) = d.p_inf.filter(|&k| k >= k0 && k <= k1) {
        chart
            .draw_series(LineSeries::new(
                vec![(ki, lo), (ki, hi)],
                RGBColor(214, 39, 40).stroke_width(2),
            ))?
            .label(format!("accumulation point k∞ = {ki:.2}"))
            .legend(|(x, y)| {
                PathElement::new(
                    vec![(x, y), (x + 24, y)],
                    RGBColor(214, 39, 40).stroke_width(2),
                )
            });
    }
    Ok(())
}

/// `k` on the curve `c` (points `[k, p2]`) at `p2 = x`, linear between the first two
/// neighbouring points whose `p2` span `x`; `None` where none does.
fn interp(c: &[[f64; 2]], x: f64) -> Option<f64> {
    c.windows(2).find_map(|w| {
        let (a, b) = (w[0], w[1]);
        let (lo, hi) = (a[1].min(b[1]), a[1].max(b[1]));
        (x >= lo && x <= hi && hi > lo).then(|| a[0] + (b[0] - a[0]) * (x - a[1]) / (b[1] - a[1]))
    })
}

/// Shades on `chart` (green, with its legend entry) the region of Fig. 8c between the flip
/// curve `flip` (above) and the fold curve `fold` (below), points `[k, p2]`, over `p2` in
/// `[x0, x1]` at 201 abscissae, where the flip lies above the fold.
fn shade_stable<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    flip: &[[f64; 2]],
    fold: &[[f64; 2]],
    (x0, x1): (f64, f64),
) -> Result<()> {
    let n = 200;
    let mut upper = Vec::new();
    let mut lower = Vec::new();
    for i in 0..=n {
        let x = x0 + (x1 - x0) * i as f64 / n as f64;
        if let (Some(u), Some(l)) = (interp(flip, x), interp(fold, x)) {
            if u > l {
                upper.push((x, u));
                lower.push((x, l));
            }
        }
    }
    if !upper.is_empty() {
        let poly: Vec<(f64, f64)> = upper
            .iter()
            .copied()
            .chain(lower.iter().rev().copied())
            .collect();
        chart
            .draw_series(std::iter::once(Polygon::new(
                poly,
                RGBColor(44, 160, 44).mix(0.25).filled(),
            )))?
            .label("period-1 orbit stable")
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 6), (x + 24, y + 6)],
                    RGBColor(44, 160, 44).mix(0.25).filled(),
                )
            });
    }
    Ok(())
}

/// Draws Fig. 8c into `path` (PNG): the stability region of the period-1 orbit in the plane
/// (second parameter, `k`), shaded between the fold curve (below) and the flip curve (above).
pub fn draw_stability(path: &Path, r: &Region) -> Result<()> {
    crate::plot::register_fonts()?;
    let root = BitMapBackend::new(path, (1300, 950)).into_drawing_area();
    root.fill(&WHITE)?;
    let curves: Vec<&tilting_planner::continuation::twopar::Curve> =
        r.flip.iter().chain(r.fold.iter()).collect();
    let xs = curves.iter().flat_map(|c| c.points.iter().map(|p| p[1]));
    let ys = curves
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p[0]))
        .chain([0.0]);
    let (x0, x1) = crate::plot::padded_range(xs, 0.03);
    let (_, y1) = crate::plot::padded_range(ys, 0.05);
    let name = r.p2.name();
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("Fig. 8c: where the adapted period-1 orbit is stable, in (k, {name})"),
            (FONT, 24),
        )
        .margin(18)
        .margin_right(40)
        .x_label_area_size(55)
        .y_label_area_size(90)
        .build_cartesian_2d(x0..x1, 0.0..y1)?;
    let xdesc = match r.p2.name() {
        "kd" => "damping gain K_D [1/s]".to_string(),
        "kp" => "stiffness gain K_P0 [1/s²]".to_string(),
        "m_l_plant" => "the robot's arm mass m_l [kg] (the model keeps 1 kg)".to_string(),
        other => other.to_string(),
    };
    crate::plot::mesh(&mut chart, &xdesc, "adaptation gain k [1/(J s²)]", (20, 16)).draw()?;
    // Shade between the curves where both are defined (linear interpolation in p2).
    if let (Some(fl), Some(fo)) = (&r.flip, &r.fold) {
        shade_stable(&mut chart, &fl.points, &fo.points, (x0, x1))?;
    }
    for (c, col, label) in [
        (
            &r.flip,
            RGBColor(214, 39, 40),
            "flip: a multiplier at −1 (period doubling above)",
        ),
        (
            &r.fold,
            RGBColor(31, 119, 180),
            "fold: a multiplier at +1 (the orbit ends below)",
        ),
    ] {
        if let Some(c) = c {
            let pts: Vec<(f64, f64)> = c.points.iter().map(|p| (p[1], p[0])).collect();
            chart
                .draw_series(LineSeries::new(pts, col.stroke_width(3)))?
                .label(label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], col.stroke_width(3))
                });
        }
    }
    chart
        .draw_series(std::iter::once(Cross::new(
            (r.p2_base, 500.0),
            8,
            BLACK.stroke_width(2),
        )))?
        .label("the paper's loop (k = 500)")
        .legend(|(x, y)| Cross::new((x + 12, y), 6, BLACK.stroke_width(2)));
    legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present()?;
    Ok(())
}
