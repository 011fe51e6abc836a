//! Colours, fonts and drawing helpers shared by the figures.

use super::*;

pub(super) const BLUE: RGBColor = RGBColor(31, 119, 180);
pub(super) const GREEN: RGBColor = RGBColor(30, 150, 60);
pub(super) const RED: RGBColor = RGBColor(200, 40, 40);
pub(super) const GREY: RGBColor = RGBColor(120, 120, 120);
pub(super) const PALETTE: [RGBColor; 9] = [
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

pub(super) const FONT: &str = "sans-serif";

// ---------------------------------------------------------------------------------------------
// Drawing helpers.

pub(super) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// A chart of `f64` over `f64` on a bitmap.
pub(super) type Chart<'a> = ChartContext<
    'a,
    BitMapBackend<'a>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

pub(super) fn style_mesh<'a, X, Y>(
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
    crate::plot::mesh(chart, x_desc, y_desc, (22, 17)).draw()?;
    Ok(())
}

pub(super) fn legend<'a, X, Y>(
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
pub(super) fn tick3(v: &f64) -> String {
    let v = if v.abs() < 5e-4 { 0.0 } else { *v };
    format!("{v:.3}")
}

/// A five-pointed star of outer radius `r` pixels (polygon offsets from its centre).
pub(super) fn star_points(r: f64) -> Vec<(i32, i32)> {
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
pub(super) fn clip(
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
pub(super) fn symmetric(v: impl Iterator<Item = f64>, pad: f64) -> (f64, f64) {
    let m = v
        .filter(|x| x.is_finite())
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(1e-6);
    (-(1.0 + pad) * m, (1.0 + pad) * m)
}
