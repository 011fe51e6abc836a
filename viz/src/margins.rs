//! The maps of `tilting plan margins`: survival over delay × loss as a heat map with the
//! survival boundary drawn, survival over the control rate, and survival against the robot's
//! imperfections (sensor noise, arm-mass error).

use anyhow::Result;
use plotters::prelude::*;
use std::path::Path;
use tilting_planner::margins::{Criteria, ImperfectPoint, Imperfection, Point};

const FONT: &str = "sans-serif";

/// The maps of one `plan margins` run.
#[derive(Debug, Clone, Copy)]
pub struct Maps<'a> {
    /// Delay × loss, plain controller.
    pub delay_loss: &'a [Point],
    /// Delay × loss, predicting controller.
    pub delay_loss_predict: &'a [Point],
    /// Control rate, periodic sampling only.
    pub rates: &'a [Point],
    /// Control rate, with an extra sample at each mode transition.
    pub rates_events: &'a [Point],
}

/// Draws the maps into `path` (PNG): the two delay × loss heat maps (delays in s, losses per
/// direction) and the rate maps. A cell's colour is the deviation of its last peaks from
/// `nominal` (rad): green when it survives, red when it does not; the black line is the survival
/// boundary (the largest surviving delay of each loss).
pub fn plot(path: &Path, maps: &Maps, nominal: f64, c: &Criteria) -> Result<()> {
    crate::plot::register_fonts()?;
    let root = BitMapBackend::new(path, (1400, 1250)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "What the k = 500 orbit survives ({} tilts, peaks within {:.0} % of {:.4} rad, no fault, no {}-period gap)",
            c.tilts,
            100.0 * c.tolerance,
            nominal,
            c.watchdog
        ),
        (FONT, 22),
    )?;
    let (top, bottom) = root.split_vertically(600);
    let (tl, tr) = top.split_horizontally(700);
    let (bl, br) = bottom.split_horizontally(700);
    heat(
        &tl,
        maps.delay_loss,
        "delay × loss, plain controller (labels at cell corners)",
        nominal,
        c,
    )?;
    heat(
        &tr,
        maps.delay_loss_predict,
        "delay × loss, --predict auto (delay estimated from the ages)",
        nominal,
        c,
    )?;
    rate_bars(
        &bl,
        maps.rates,
        "control rate, periodic samples",
        nominal,
        c,
    )?;
    rate_bars(
        &br,
        maps.rates_events,
        "control rate, --sample-on-event",
        nominal,
        c,
    )?;
    root.present()?;
    Ok(())
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>;

fn heat(left: &Area, map: &[Point], title: &str, nominal: f64, c: &Criteria) -> Result<()> {
    let mut delays: Vec<f64> = map.iter().map(|p| p.delay).collect();
    delays.sort_by(f64::total_cmp);
    delays.dedup();
    let mut losses: Vec<f64> = map.iter().map(|p| p.loss).collect();
    losses.sort_by(f64::total_cmp);
    losses.dedup();
    let (nl, nd) = (losses.len().max(1), delays.len().max(1));
    let mut chart = ChartBuilder::on(left)
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .caption(title, (FONT, 20))
        .build_cartesian_2d(0f64..nl as f64, 0f64..nd as f64)?;
    let ls = losses.clone();
    let ds = delays.clone();
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(nl + 1)
        .y_labels(nd + 1)
        .x_label_formatter(&move |x| {
            ls.get(x.floor() as usize)
                .map_or(String::new(), |l| format!("{l}"))
        })
        .y_label_formatter(&move |y| {
            ds.get(y.floor() as usize)
                .map_or(String::new(), |d| format!("{:.1}", d * 1e3))
        })
        .x_desc("loss probability of each direction")
        .y_desc("total constant delay (ms)")
        .axis_desc_style((FONT, 18))
        .label_style((FONT, 15))
        .draw()?;
    let idx = |v: &[f64], x: f64| v.iter().position(|&y| y == x).unwrap_or(0) as f64;
    chart.draw_series(map.iter().map(|p| {
        let (x, y) = (idx(&losses, p.loss), idx(&delays, p.delay));
        let dev = if p.last_peak > 0.0 {
            ((p.last_peak / nominal - 1.0).abs() / c.tolerance).min(1.0)
        } else {
            1.0
        };
        let color = if p.survived {
            RGBColor(40 + (150.0 * dev) as u8, 170, 60)
        } else {
            RGBColor(200, 60 + (80.0 * (1.0 - dev)) as u8, 60)
        };
        Rectangle::new([(x, y), (x + 1.0, y + 1.0)], color.filled())
    }))?;
    // The boundary: above the largest surviving delay of each loss column.
    let mut line = Vec::new();
    for (i, l) in losses.iter().enumerate() {
        let top = map
            .iter()
            .filter(|p| p.loss == *l && p.survived)
            .map(|p| idx(&delays, p.delay) + 1.0)
            .fold(0.0, f64::max);
        line.push((i as f64, top));
        line.push((i as f64 + 1.0, top));
    }
    chart.draw_series(LineSeries::new(line, BLACK.stroke_width(4)))?;

    Ok(())
}

fn rate_bars(right: &Area, rates: &[Point], title: &str, nominal: f64, c: &Criteria) -> Result<()> {
    let mut rs: Vec<&Point> = rates.iter().collect();
    rs.sort_by(|a, b| a.rate.total_cmp(&b.rate));
    let n = rs.len().max(1);
    let y_hi = rs
        .iter()
        .map(|p| p.last_peak / nominal)
        .fold(1.0 + c.tolerance, f64::max)
        * 1.1;
    let labels: Vec<String> = rs.iter().map(|p| format!("{}", p.rate)).collect();
    // One segment per rate, labelled at its centre.
    let mut chart = ChartBuilder::on(right)
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .caption(title, (FONT, 20))
        .build_cartesian_2d((0..n as i32 - 1).into_segmented(), 0f64..y_hi)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n + 1)
        .x_label_formatter(&move |x| match x {
            SegmentValue::CenterOf(i) => labels.get(*i as usize).cloned().unwrap_or_default(),
            _ => String::new(),
        })
        .x_desc("control rate (Hz)")
        .y_desc("last peaks / nominal")
        .axis_desc_style((FONT, 18))
        .label_style((FONT, 15))
        .draw()?;
    chart.draw_series(rs.iter().enumerate().map(|(i, p)| {
        let color = if p.survived {
            RGBColor(40, 170, 60)
        } else {
            RGBColor(200, 60, 60)
        };
        let h = if p.last_peak > 0.0 {
            p.last_peak / nominal
        } else {
            0.02 * y_hi
        };
        let mut bar = Rectangle::new(
            [
                (SegmentValue::Exact(i as i32), 0.0),
                (SegmentValue::Exact(i as i32 + 1), h),
            ],
            color.filled(),
        );
        bar.set_margin(0, 0, 12, 12);
        bar
    }))?;
    for y in [1.0 - c.tolerance, 1.0 + c.tolerance] {
        chart.draw_series(LineSeries::new(
            vec![
                (SegmentValue::Exact(0), y),
                (SegmentValue::Exact(n as i32), y),
            ],
            BLACK.stroke_width(2),
        ))?;
    }
    Ok(())
}

/// Draws the imperfection maps of `plan margins` into `path` (PNG): one panel per map (angle
/// noise, rate noise, arm-mass error), a bar per value of height last peaks / `nominal`, green
/// when it survives and red when it does not, with the tolerance band of the criteria.
pub fn plot_imperfections(
    path: &Path,
    maps: &[&[ImperfectPoint]],
    nominal: f64,
    c: &Criteria,
) -> Result<()> {
    crate::plot::register_fonts()?;
    let panels = maps.iter().filter(|m| !m.is_empty()).count().max(1);
    let root = BitMapBackend::new(path, (480 * panels as u32, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!(
            "The robot is not the model: what the k = 500 orbit survives ({} tilts, peaks within {:.0} % of {:.4} rad, no fault)",
            c.tilts,
            100.0 * c.tolerance,
            nominal
        ),
        (FONT, 20),
    )?;
    let areas = root.split_evenly((1, panels));
    for (area, map) in areas.iter().zip(maps.iter().filter(|m| !m.is_empty())) {
        let mut ps: Vec<&ImperfectPoint> = map.iter().collect();
        ps.sort_by(|a, b| a.value.total_cmp(&b.value));
        let n = ps.len();
        let y_hi = ps
            .iter()
            .map(|p| p.last_peak / nominal)
            .fold(1.0 + c.tolerance, f64::max)
            * 1.1;
        let labels: Vec<String> = ps.iter().map(|p| format!("{}", p.value)).collect();
        let (caption, x_desc) = match ps[0].imperfection {
            Imperfection::AngleNoise => {
                ("sensor noise of the angles", "sigma of alpha, beta (rad)")
            }
            Imperfection::RateNoise => ("sensor noise of the rates", "sigma of the rates (rad/s)"),
            Imperfection::MassError => ("model mismatch", "arm-mass error (relative)"),
        };
        let mut chart = ChartBuilder::on(area)
            .margin(15)
            .x_label_area_size(50)
            .y_label_area_size(55)
            .caption(caption, (FONT, 18))
            .build_cartesian_2d(0f64..n as f64, 0f64..y_hi)?;
        chart
            .configure_mesh()
            .x_labels(n)
            .x_label_formatter(&move |x| {
                labels.get(x.floor() as usize).cloned().unwrap_or_default()
            })
            .x_desc(x_desc)
            .y_desc("last peaks / nominal")
            .axis_desc_style((FONT, 16))
            .label_style((FONT, 12))
            .draw()?;
        chart.draw_series(ps.iter().enumerate().map(|(i, p)| {
            let color = if p.survived {
                RGBColor(40, 170, 60)
            } else {
                RGBColor(200, 60, 60)
            };
            // A stub for a run without 10 tilts to compare.
            let h = (p.last_peak / nominal).max(0.02 * y_hi);
            Rectangle::new(
                [(i as f64 + 0.15, 0.0), (i as f64 + 0.85, h)],
                color.filled(),
            )
        }))?;
        for y in [1.0 - c.tolerance, 1.0 + c.tolerance] {
            chart.draw_series(LineSeries::new(
                vec![(0.0, y), (n as f64, y)],
                BLACK.stroke_width(2),
            ))?;
        }
    }
    root.present()?;
    Ok(())
}
