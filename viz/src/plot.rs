//! PNG figures with plotters. The font is embedded (`assets/DejaVuSans.ttf`, registered as
//! `sans-serif`), so drawing needs no system font.

use anyhow::{anyhow, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::Path;
use std::sync::OnceLock;
use tilting_plant::Mode;
use tilting_sim::Scenario;
use tilting_sim::SimulationReport;

/// The trajectory a figure draws: an offline run's or a recording's (one type, the
/// recordings').
pub use tilting_sim::closed_loop::Trace;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// A chart's grid and axes in the figures' style: the axis descriptions `x_desc` and `y_desc`,
/// `sizes` the descriptions' and the tick labels' font sizes (px), no minor grid lines, faint
/// major ones. Returned for the caller's tick formatters and `draw()`.
pub(crate) fn mesh<'a, 'b, DB, X, Y>(
    chart: &'b mut ChartContext<'a, DB, Cartesian2d<X, Y>>,
    x_desc: &str,
    y_desc: &str,
    (desc, label): (u32, u32),
) -> plotters::chart::MeshStyle<'a, 'b, X, Y, DB>
where
    DB: DrawingBackend,
    X: plotters::coord::ranged1d::Ranged<ValueType = f64>
        + plotters::coord::ranged1d::ValueFormatter<f64>,
    Y: plotters::coord::ranged1d::Ranged<ValueType = f64>
        + plotters::coord::ranged1d::ValueFormatter<f64>,
{
    let mut m = chart.configure_mesh();
    m.x_desc(x_desc)
        .y_desc(y_desc)
        .axis_desc_style(("sans-serif", desc))
        .label_style(("sans-serif", label))
        .light_line_style(WHITE.mix(0.0))
        .bold_line_style(BLACK.mix(0.08));
    m
}

/// Registers the embedded DejaVu Sans as the `sans-serif` family (once per process).
pub fn register_fonts() -> Result<()> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(anyhow!("the embedded font DejaVuSans.ttf is invalid"))
    }
}

/// Figure size (px).
const SIZE: (u32, u32) = (1400, 900);

/// Colour of the markers of tilt starts (flat to left/right).
const TILT_START: RGBColor = RGBColor(230, 120, 40);
/// Colour of the markers of landings (left/right to flat).
const LANDING: RGBColor = RGBColor(60, 140, 220);

/// `[lo, hi]` of the finite values of `v` widened by `pad` times their spread on each side; a
/// flat signal gets a band of 5 % of its value (at least 1e-3) around it.
pub fn padded_range(v: impl Iterator<Item = f64>, pad: f64) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let w = hi - lo;
    if w > 1e-9 * hi.abs().max(1e-3) {
        (lo - pad * w, hi + pad * w)
    } else {
        let d = 0.05 * hi.abs().max(0.02);
        (lo - d, hi + d)
    }
}

/// Draws the legend of `chart`'s labelled series in its upper right corner, on a white box.
fn legend_upper_right<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 18))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK.mix(0.4))
        .draw()?;
    Ok(())
}

/// One angle-against-time panel of a run or fit-check figure: its caption, the time axis
/// `t` (s) and the angle axis `y` (rad, labelled `ylabel`), with the light mesh both figures
/// share; the caller draws the curves.
fn angle_panel<'a, DB: DrawingBackend>(
    panel: &'a DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    ylabel: &str,
    t: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
) -> Result<
    ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
>
where
    DB::ErrorType: 'static,
{
    let mut chart = ChartBuilder::on(panel)
        .caption(caption, ("sans-serif", 24))
        .margin(12)
        .margin_right(40)
        .x_label_area_size(55)
        .y_label_area_size(95)
        .build_cartesian_2d(t, y)?;
    crate::plot::mesh(&mut chart, "time t [s]", ylabel, (22, 18))
        .y_label_formatter(&|v| format!("{v:.3}"))
        .draw()?;
    Ok(chart)
}

/// Draws `alpha(t)` and `beta(t)` of an offline run (`simulate --plot`) in two stacked panels,
/// with the transition times marked: vertical lines at tilt starts and at landings.
pub fn plot_run(path: &Path, sc: &Scenario, r: &SimulationReport) -> Result<()> {
    plot_trace(path, sc, &r.trace())
}

/// Draws a [`Trace`] as [`plot_run`] does; `sc` gives the gains, the coupling and the planned
/// duration for the title and the time axis.
pub fn plot_trace(path: &Path, sc: &Scenario, r: &Trace) -> Result<()> {
    register_fonts()?;
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let coupling = if sc.is_sampled() {
        format!("zero-order hold T = {} s", sc.control_period)
    } else {
        "continuous coupling".to_string()
    };
    let title = format!(
        "Tilting system: K_P0 = {}, K_D = {}, k = {}, {coupling}, {} impact law{}",
        sc.law.kp,
        sc.law.kd,
        sc.law.k,
        sc.impact.as_str(),
        if r.stopped_early {
            " (stopped by a fault)"
        } else {
            ""
        }
    );
    let root = root.titled(&title, ("sans-serif", 28))?;
    let panels = root.split_evenly((2, 1));
    let t_max = r.end.max(sc.duration * 1e-6).max(f64::MIN_POSITIVE);
    let t_max = if r.stopped_early { t_max } else { sc.duration };
    let specs: [(usize, &str, &str); 2] = [
        (0, "Plate tilt angle α(t)", "α [rad]"),
        (1, "Arm angle β(t) relative to the plate", "β [rad]"),
    ];
    for (panel, (i, caption, ylabel)) in panels.iter().zip(specs) {
        let (lo, hi) = padded_range(r.samples.iter().map(|s| s.x[i]), 0.08);
        // Headroom above the curve for the legend.
        let top = hi + 0.3 * (hi - lo);
        let mid = 0.5 * (lo + hi);
        let mut chart = angle_panel(panel, caption, ylabel, 0.0..t_max, lo..top)?;
        // A landing and the re-tilt it triggers share one instant: landings are marked in the
        // lower half of the panel, tilt starts in the upper half, so both stay visible.
        let mut labelled = [false; 2];
        for e in &r.events {
            let landing = e.to == Mode::Flat;
            let (color, y0, y1, label) = if landing {
                (LANDING, lo, mid, "landing (tilted → flat), lower half")
            } else {
                (
                    TILT_START,
                    mid,
                    hi,
                    "tilt start (flat → tilted), upper half",
                )
            };
            let s = chart.draw_series(std::iter::once(PathElement::new(
                vec![(e.t, y0), (e.t, y1)],
                color.mix(0.8).stroke_width(2),
            )))?;
            if i == 0 && !std::mem::replace(&mut labelled[landing as usize], true) {
                s.label(label).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
                });
            }
        }
        chart.draw_series(LineSeries::new(
            r.samples.iter().map(|s| (s.t, s.x[i])),
            BLACK.stroke_width(2),
        ))?;
        if i == 0 && !r.events.is_empty() {
            legend_upper_right(&mut chart)?;
        }
    }
    root.present()?;
    Ok(())
}

/// The fit check of `tilting identify --plot`: the recorded `alpha(t)` and `beta(t)` (black)
/// with the re-simulation's pieces (red, one per restart window,
/// [`tilting_planner::identify::fit`]) in two stacked panels; `title` names the figures.
pub fn plot_fit(
    path: &Path,
    recorded: &Trace,
    resim: &tilting_planner::identify::fit::Resimulation,
    title: &str,
) -> Result<()> {
    register_fonts()?;
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 26))?;
    let panels = root.split_evenly((2, 1));
    let s = &recorded.samples;
    let (t0, t1) = (
        s.first().map_or(0.0, |x| x.t),
        s.last()
            .map_or(1.0, |x| x.t)
            .max(s.first().map_or(0.0, |x| x.t) + 1e-6),
    );
    let red = RGBColor(220, 40, 40);
    for (panel, (i, caption, ylabel)) in panels.iter().zip([
        (0, "Plate tilt angle α(t)", "α [rad]"),
        (1, "Arm angle β(t) relative to the plate", "β [rad]"),
    ]) {
        let (lo, hi) = padded_range(s.iter().map(|x| x.x[i]), 0.08);
        let top = hi + 0.25 * (hi - lo);
        let mut chart = angle_panel(panel, caption, ylabel, t0..t1, lo..top)?;
        chart
            .draw_series(LineSeries::new(
                s.iter().map(|x| (x.t, x.x[i])),
                BLACK.stroke_width(3),
            ))?
            .label("recorded")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], BLACK.stroke_width(3)));
        let mut ends = resim.starts.clone();
        ends.push(resim.samples.len());
        for (j, w) in ends.windows(2).enumerate() {
            let piece = &resim.samples[w[0]..w[1]];
            let series = chart.draw_series(LineSeries::new(
                piece.iter().map(|x| (x.t, x.x[i])),
                red.stroke_width(2),
            ))?;
            if j == 0 {
                series
                    .label("re-simulated (identified parameters, restarted per window)")
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 24, y)], red.stroke_width(3))
                    });
            }
        }
        legend_upper_right(&mut chart)?;
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn font_registers() {
        super::register_fonts().unwrap();
        super::register_fonts().unwrap();
    }
}
