//! Fig. 5: the closed loop tracking four planned sinusoids, simulated against planned tilt.

use super::*;

// ---------------------------------------------------------------------------------------------
// Fig. 5.

/// Records `(t, alpha)` and the transitions of a run.
#[derive(Default)]
pub(super) struct Trace {
    pub(super) t: Vec<f64>,
    pub(super) alpha: Vec<f64>,
    pub(super) alpha_dot: Vec<f64>,
    pub(super) peaks: Vec<TiltPeak>,
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

/// Simulates `law` (any [`PlannableLaw`]) from `(mode, x0)` for `duration` seconds with the closed loop of
/// `tilting-sim` (continuous coupling, one piece); the trace and the fault, if any.
pub(super) fn simulate(
    ctx: &Ctx,
    law: &impl PlannableLaw,
    mode: Mode,
    x0: State,
    duration: f64,
) -> Result<(Trace, Option<Fault>)> {
    let mut plant = Plant::new(ctx.sim_config(), 0.0, mode, x0)?;
    let mut tr = Trace::default();
    tr.sample(0.0, mode, &x0);
    let fault =
        tilting_sim::run_continuous(&mut plant, law, duration, 1, &mut tr, &mut |_| {}).err();
    // The peak of the last tilt, reached before the end but not landed, is a peak too.
    if let Some(p) = plant.peak_in_progress() {
        tr.tilt_peak(&p);
    }
    Ok((tr, fault))
}

/// A short form of a fault for a panel title: its kind and time.
pub(super) fn short_fault(f: &Fault) -> String {
    match f.time() {
        Some(t) => format!("{} at t = {t:.2} s", f.kind()),
        None => f.kind().to_string(),
    }
}

struct Panel {
    label: String,
    omega: f64,
    period: f64,
    max_tilt: f64,
    desired: Vec<(f64, f64)>,
    simulated: Vec<(f64, f64)>,
    fault: Option<Fault>,
    sim_max: f64,
}

/// What Fig. 5 shows (fields in the order of the JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig5Summary {
    /// The four panels.
    pub panels: Vec<Fig5Panel>,
    /// One line of text.
    pub text: String,
}

/// One panel of Fig. 5: a planned sinusoid and the closed loop tracking it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fig5Panel {
    /// What ended the simulation early, if anything (its message in JSON).
    pub fault: Option<Fault>,
    /// The panel's label.
    pub label: String,
    /// Solved frequency `w` (rad/s).
    pub omega: f64,
    /// Period `2 pi / w` (s).
    pub period: f64,
    /// Largest planned tilt (rad).
    pub planned_max_tilt: f64,
    /// Largest simulated tilt (rad).
    pub simulated_max_tilt: f64,
}

pub(super) fn fig5(ctx: &Ctx, tick: &(dyn Fn() + Sync)) -> Result<Fig5Summary> {
    let p = ctx.params;
    let panels: Vec<Result<Panel>> = FIG5_S
        .par_iter()
        .enumerate()
        .map(|(i, &(s, frac))| {
            let r = (|| {
                let sol = sinusoid::solve(&p, FIG5_A, s, &Search::default())
                    .with_context(|| format!("A = {FIG5_A}, s = -{frac}"))?;
                let w = sol.omega;
                let law = ComputedTorque::new(ControlConfig {
                    params: p,
                    law: LawSpec {
                        kp: KP,
                        kd: KD,
                        reference: Trajectory::Sinusoid {
                            amplitude: FIG5_A,
                            omega: w,
                        },
                        ..LawSpec::without_adaptation()
                    },
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
                Ok(Panel {
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
            tick();
            r
        })
        .collect();
    let panels = panels.into_iter().collect::<Result<Vec<_>>>()?;
    draw_fig5(&ctx.path("5"), &panels)?;
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
    Ok(Fig5Summary {
        text,
        panels: panels
            .iter()
            .map(|q| Fig5Panel {
                label: q.label.clone(),
                omega: q.omega,
                period: q.period,
                planned_max_tilt: q.max_tilt,
                simulated_max_tilt: q.sim_max,
                fault: q.fault.clone(),
            })
            .collect(),
    })
}

fn draw_fig5(path: &Path, panels: &[Panel]) -> Result<()> {
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

fn draw_fig5_panel(area: &Area, q: &Panel) -> Result<()> {
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
    crate::plot::mesh(&mut chart, "time t [s]", "tilt angle α [rad]", (20, 16))
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
