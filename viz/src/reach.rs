//! The reach map of `tilting plan reach`: which gains `(K_D, k)` give the adapted loop an orbit
//! with a wanted tilt peak, and how stable it is.

use anyhow::Result;
use plotters::prelude::*;
use std::path::Path;
use tilting_planner::peak::{Reach, ReachCell};

const FONT: &str = "sans-serif";

/// Draws the cells into a PNG at `path`: a filled circle per reached cell (green stable, the
/// darker the smaller its largest multiplier; red unstable), a grey cross where the family
/// turns back below the peak (with the largest peak it reaches, in mrad), a grey ring where
/// it stays above, nothing where no orbit was found.
pub fn draw_reach(path: &Path, cells: &[ReachCell], peak: f64, law: &str) -> Result<()> {
    crate::plot::register_fonts()?;
    let root = BitMapBackend::new(path, (1300, 950)).into_drawing_area();
    root.fill(&WHITE)?;
    let (x0, x1) = crate::plot::padded_range(cells.iter().map(|c| c.kd), 0.06);
    let (y0, y1) = crate::plot::padded_range(cells.iter().map(|c| c.k), 0.06);
    // Room above the grid for the legend.
    let y1 = y1 + 0.22 * (y1 - y0);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("which gains reach a tilt peak of {peak} rad ({law} landing law)"),
            (FONT, 24),
        )
        .margin(18)
        .margin_right(40)
        .x_label_area_size(55)
        .y_label_area_size(90)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc("damping gain K_D [1/s]")
        .y_desc("adaptation gain k [1/(J s²)]")
        .axis_desc_style((FONT, 20))
        .label_style((FONT, 16))
        .draw()?;
    let stable = |rho: f64| {
        let s = (rho.clamp(0.0, 1.0) * 160.0) as u8;
        RGBColor(s / 2, 100 + s / 2, s / 2)
    };
    let mut legend = [false; 4];
    for c in cells {
        let at = (c.kd, c.k);
        match c.reach {
            Reach::Reached {
                stable: true, rho, ..
            } => {
                let s = chart.draw_series([Circle::new(at, 9, stable(rho).filled())])?;
                if !legend[0] {
                    legend[0] = true;
                    s.label("stable (darker: smaller largest |multiplier|)")
                        .legend(move |(x, y)| Circle::new((x, y), 6, stable(0.3).filled()));
                }
            }
            Reach::Reached { stable: false, .. } => {
                let s = chart.draw_series([Circle::new(at, 9, RED.filled())])?;
                if !legend[1] {
                    legend[1] = true;
                    s.label("reached, unstable")
                        .legend(|(x, y)| Circle::new((x, y), 6, RED.filled()));
                }
            }
            Reach::Below { largest } => {
                chart.draw_series([Text::new(
                    format!("{:.0}", largest * 1e3),
                    (c.kd, c.k),
                    (FONT, 13).into_font().color(&BLACK.mix(0.6)),
                )])?;
                let s = chart.draw_series([Cross::new(at, 7, BLACK.mix(0.5).stroke_width(2))])?;
                if !legend[2] {
                    legend[2] = true;
                    s.label("not reached: the largest peak it reaches [mrad]")
                        .legend(|(x, y)| Cross::new((x, y), 6, BLACK.mix(0.5)));
                }
            }
            Reach::Above { .. } => {
                let s = chart.draw_series([Circle::new(at, 7, BLACK.mix(0.5))])?;
                if !legend[3] {
                    legend[3] = true;
                    s.label("not reached: every orbit tilts more")
                        .legend(|(x, y)| Circle::new((x, y), 6, BLACK.mix(0.5)));
                }
            }
            Reach::None => {}
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font((FONT, 16))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}
