//! Fig. 8: the bifurcation diagram over the adaptation gain `k`, with `k*` and peak series.

use super::fig5::short_fault;
use super::*;
use tilting_planner::bifurcation::RowFault;

// ---------------------------------------------------------------------------------------------
// Fig. 8.

/// What Fig. 8 shows (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig8Summary {
    /// `E_av` of the orbit the sweep starts from (J).
    pub energy_avg: f64,
    /// The first `k` of the sweep whose peaks are not of period 1, if any.
    pub k_onset_observed: Option<f64>,
    /// The `k` where the orbit loses stability, if in range.
    pub k_star: Option<f64>,
    /// The three time series.
    pub series: Vec<bifurcation::Row>,
    /// One line of text.
    pub text: String,
}

pub(super) fn fig8(ctx: &Ctx, tick: &(dyn Fn() + Sync)) -> Result<Fig8Summary> {
    let pb = ctx.orbit_problem();
    let o = orbit::smallest(&pb)
        .ok_or_else(|| anyhow!("no periodic orbit for K_P = {KP}, K_D = {KD}"))?;
    tick();
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
    let rows = bifurcation::sweep(&sw, &ks, tick);
    let k_star = bifurcation::k_star(&sw, 500.0, FIG8_K.0, FIG8_K.1, 1e-3);
    tick();
    let series_sw = Sweep {
        tilts: set.series_tilts,
        keep: set.series_keep,
        ..sw
    };
    let series: Vec<bifurcation::Row> = FIG8_SERIES
        .par_iter()
        .map(|&k| {
            let r = bifurcation::run_one(&series_sw, k);
            tick();
            r
        })
        .collect();
    draw_fig8(&ctx.path("8"), &rows, k_star, &sw, &series, &series_sw)?;
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
    Ok(Fig8Summary {
        text,
        k_star,
        k_onset_observed: onset,
        energy_avg: o.energy_avg,
        series,
    })
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
    crate::plot::mesh(
        &mut chart,
        "adaptation gain k [1/(J s²)]",
        "tilt peak |α|max [rad]",
        (20, 16),
    )
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
    draw_fig8_marks(&mut chart, rows, k_star, (lo, hi))?;
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    draw_series_panels(&bottom, series, series_sw)?;
    root.present()?;
    Ok(())
}

/// The marks on Fig. 8's bifurcation diagram `chart` (tilt peaks `lo..hi`, rad): a red cross at
/// the bottom for each of the `rows` that stopped on a fault, `k*` (1/(J s^2)) dashed where the
/// orbit flips, and a grey tick at each `k` of [`FIG8_SERIES`].
fn draw_fig8_marks(
    chart: &mut Chart<'_>,
    rows: &[bifurcation::Row],
    k_star: Option<f64>,
    (lo, hi): (f64, f64),
) -> Result<()> {
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
    Ok(())
}

/// The bottom row of Fig. 8: the tilt peaks against the tilt number for each `k` of
/// [`FIG8_SERIES`], on one scale so that period 1 looks constant.
fn draw_series_panels(
    bottom: &DrawingArea<BitMapBackend<'_>, Shift>,
    series: &[bifurcation::Row],
    series_sw: &Sweep,
) -> Result<()> {
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
                (Some(RowFault::Plant(f)), _) => short_fault(f),
                (Some(f), _) => f.to_string(),
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
        crate::plot::mesh(&mut c, "tilt number n", "|α|max [rad]", (19, 15))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&tick3)
            .draw()?;
        c.draw_series(LineSeries::new(pts.clone(), BLUE.mix(0.5).stroke_width(1)))?;
        c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, BLUE.filled())))?;
    }
    Ok(())
}
