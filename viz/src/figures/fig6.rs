//! Fig. 6: the maximal tilt of the periodic orbits over `(K_P, K_D)`.

use super::*;

// ---------------------------------------------------------------------------------------------
// Fig. 6.

/// What Fig. 6 shows (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig6Summary {
    /// The `(K_P, K_D)` grid with the orbits of each cell.
    pub cells: Vec<gains::Cell>,
    /// One line of text.
    pub text: String,
}

pub(super) fn fig6(ctx: &Ctx, tick: &(dyn Fn() + Sync)) -> Result<Fig6Summary> {
    let (kps, kds) = (ctx.kps(), ctx.kds());
    let cells = gains::grid(ctx.params, ctx.impact, &kps, &kds, tick);
    let paper = orbit::find_all(&ctx.orbit_problem());
    tick();
    if cells.iter().all(|c| c.max_tilt.is_empty()) {
        return Err(anyhow!(
            "no periodic orbit anywhere on the grid (impact law {})",
            ctx.impact.as_str()
        ));
    }
    draw_fig6(&ctx.path("6"), &kps, &cells, &paper)?;
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
    Ok(Fig6Summary { text, cells })
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
    crate::plot::mesh(
        &mut chart,
        "damping gain K_D [1/s]",
        "maximal tilt angle α_max [rad]",
        (22, 17),
    )
    .y_label_formatter(&|v| format!("{v:.2}"))
    .draw()?;
    for (i, &kp) in kps.iter().enumerate() {
        draw_fig6_row(&mut chart, kp, PALETTE[i % PALETTE.len()], cells)?;
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

/// One `K_P` (1/s^2) of Fig. 6 in `color`: the cells of `cells` at `kp` as the maximal tilt
/// (rad) over `K_D` (1/s), the smallest-tilt branch joined where it exists, the middle and
/// upper branches as one fold, each orbit a dot (filled: stable), labelled at its right end.
fn draw_fig6_row(
    chart: &mut Chart<'_>,
    kp: f64,
    color: RGBColor,
    cells: &[gains::Cell],
) -> Result<()> {
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
    Ok(())
}
