//! Fig. 7: the unstable orbit left alone, and stabilised by the energy adaptation.

use super::fig5::{short_fault, simulate, Trace};
use super::*;

// ---------------------------------------------------------------------------------------------
// Fig. 7.

struct Run {
    name: &'static str,
    color: RGBColor,
    trace: Trace,
    fault: Option<Fault>,
}

/// What Fig. 7 shows (fields in the order of the JSON).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig7Summary {
    /// The unstable orbit.
    pub orbit: OrbitSolution,
    /// The runs: perturbed up, perturbed down, stabilised.
    pub runs: Vec<Fig7Run>,
    /// One line of text.
    pub text: String,
}

/// One run of Fig. 7.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig7Run {
    /// What ended the run early, if anything (its message in JSON).
    pub fault: Option<Fault>,
    /// The run's name.
    pub name: String,
    /// The extreme `alpha` of each tilt (rad).
    pub peaks: Vec<f64>,
}

pub(super) fn fig7(ctx: &Ctx, tick: &(dyn Fn() + Sync)) -> Result<Fig7Summary> {
    let pb = ctx.orbit_problem();
    let o = orbit::smallest(&pb)
        .ok_or_else(|| anyhow!("no periodic orbit for K_P = {KP}, K_D = {KD}"))?;
    tick();
    let law = |k: f64| {
        ComputedTorque::new(ControlConfig {
            law: LawSpec {
                k,
                energy_avg: o.energy_avg,
                ..pb.control.law
            },
            ..pb.control
        })
    };
    let runs = [
        (0.0, -FIG7_PERTURBATION),
        (FIG7_K, FIG7_PERTURBATION),
        (0.0, FIG7_PERTURBATION),
    ];
    let traces: Vec<Result<(Trace, Option<Fault>)>> = runs
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
            tick();
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
    let runs: Vec<Run> = traces
        .into_iter()
        .zip(names)
        .map(|((trace, fault), (name, color))| Run {
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
    draw_fig7(
        &ctx.path("7"),
        &o,
        &orbit_trace,
        &runs,
        ctx.set.fig7_duration,
    )?;
    Ok(fig7_summary(o, &runs))
}

/// What Fig. 7 shows in words and numbers: the unstable orbit `o` and each run's tilts, last
/// peak (rad) and fault.
fn fig7_summary(o: OrbitSolution, runs: &[Run]) -> Fig7Summary {
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
    Fig7Summary {
        text: format!(
            "orbit max tilt {:.4} rad, E_av = {:.6} J; {text}",
            o.max_tilt, o.energy_avg
        ),
        runs: runs
            .iter()
            .map(|r| Fig7Run {
                name: r.name.to_owned(),
                peaks: r.trace.peaks.iter().map(|p| p.alpha).collect(),
                fault: r.fault.clone(),
            })
            .collect(),
        orbit: o,
    }
}

fn draw_fig7(
    path: &Path,
    o: &OrbitSolution,
    orbit_trace: &Trace,
    runs: &[Run],
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
    draw_fig7_phase(&top, o, orbit_trace, runs)?;
    draw_fig7_alphas(&bottom, runs, duration)?;
    root.present()?;
    Ok(())
}

/// Fig. 7's phase portrait `(alpha, alpha_dot)` (rad, rad/s) on `top`: the three `runs`
/// (perturbed down, controlled, perturbed up), in a frame 2.2 times the controlled orbit's, and
/// the unstable orbit `o` (one period, `orbit_trace`) dashed.
fn draw_fig7_phase<'a>(
    top: &DrawingArea<BitMapBackend<'a>, Shift>,
    o: &OrbitSolution,
    orbit_trace: &Trace,
    runs: &'a [Run],
) -> Result<()> {
    // Phase portrait, scaled to the controlled orbit: the diverging run leaves the frame.
    let ctrl = &runs[1].trace;
    let (a_lo, a_hi) = symmetric(ctrl.alpha.iter().copied(), 0.0);
    let (v_lo, v_hi) = symmetric(ctrl.alpha_dot.iter().copied(), 0.0);
    let scale = 2.2;
    let mut chart = ChartBuilder::on(top)
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
    crate::plot::mesh(
        &mut chart,
        "tilt angle α [rad]",
        "tilt rate dα/dt [rad/s]",
        (20, 16),
    )
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
    Ok(())
}

/// Fig. 7's bottom row on `bottom`: `alpha(t)` (rad) of each of the `runs` over `duration` (s),
/// side by side, captioned with the run's fault if any.
fn draw_fig7_alphas(
    bottom: &DrawingArea<BitMapBackend<'_>, Shift>,
    runs: &[Run],
    duration: f64,
) -> Result<()> {
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
        crate::plot::mesh(&mut c, "time t [s]", "α [rad]", (19, 15))
            .y_label_formatter(&tick3)
            .draw()?;
        c.draw_series(LineSeries::new(
            r.trace.t.iter().copied().zip(r.trace.alpha.iter().copied()),
            r.color.stroke_width(2),
        ))?;
    }
    Ok(())
}
