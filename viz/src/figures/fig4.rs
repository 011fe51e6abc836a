//! Fig. 4: the partition of the `(A, w)` plane by the ideal arm motion (no tilt, and the
//! landing curves `t_l = T/2 + s t_t`).

use super::*;

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

/// What Fig. 4 shows (fields in the order of the JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig4Summary {
    /// The landing-offset curves.
    pub curves: Vec<Fig4Curve>,
    /// Pairs `(A, w)` of the no-tilt grid.
    pub grid_pairs: usize,
    /// Pairs of the grid whose ideal arm motion never tilts the plate.
    pub no_tilt_pairs: usize,
    /// One line of text.
    pub text: String,
}

/// One landing-offset curve `t_l = T/2 + s t_t` of Fig. 4.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig4Curve {
    /// `[A (rad), w (rad/s)]` of each amplitude with a solution.
    pub points: Vec<[f64; 2]>,
    /// The target `s`.
    pub s: f64,
    /// The `s` actually drawn (the target or the fallback `±0.98`).
    pub s_drawn: f64,
}

pub(super) fn fig4(ctx: &Ctx, tick: &(dyn Fn() + Sync)) -> Result<Fig4Summary> {
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
    tick();
    // The curves: exact s = -1, 0, 1 and the fallbacks -0.98, 0.98.
    let ss = [-1.0, 0.0, 1.0, -0.98, 0.98];
    let amps = ctx.amplitudes();
    let roots: Vec<Vec<Option<f64>>> = amps
        .par_iter()
        .map(|&a| {
            let r = sinusoid::landing_curves(&p, a, &ss, ctx.set.scan);
            tick();
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
    draw_fig4(&ctx.path("4"), &cells, &curves)?;
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
    Ok(Fig4Summary {
        text,
        grid_pairs: cells.len(),
        no_tilt_pairs: no_tilt,
        curves: curves
            .iter()
            .map(|c| Fig4Curve {
                s: c.s,
                s_drawn: c.drawn,
                points: c.points.iter().flatten().map(|&(a, w)| [a, w]).collect(),
            })
            .collect(),
    })
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
