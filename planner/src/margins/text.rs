//! The survey's report in words: the tables `tilting plan margins` prints.

use super::{Edge, Knob, MarginsReport, RobotMargins};
use std::fmt;
use tilting_controller::EstimatorChoice;

impl MarginsReport {
    /// The report as tables, as `tilting plan margins` prints it: the delay × loss maps over
    /// the grid `delays` (total delay, s) × `losses` (loss of each direction, in [0, 1)), the
    /// rate maps, the boundaries, then the robot ([`RobotMargins`]'s `Display`). A grid cell
    /// the report lacks prints `?`. Ends with a newline.
    pub fn summary(&self, delays: &[f64], losses: &[f64]) -> String {
        summary(self, delays, losses)
    }
}

fn summary(report: &MarginsReport, delays: &[f64], losses: &[f64]) -> String {
    let mut s = format!("survives = {}\n", report.survives_means);
    for (name, map) in [
        ("plain controller", &report.delay_loss),
        ("--predict auto", &report.delay_loss_predict),
    ] {
        s += &format!(
            "\ndelay × loss at {} Hz, {name} (rows: total delay, columns: loss of each direction)\n{:>12}",
            report.rate, "delay \\ loss"
        );
        for l in losses {
            s += &format!("{l:>8}");
        }
        s += "\n";
        for d in delays {
            s += &format!("{:>10.4} s ", d);
            for l in losses {
                let p = map.iter().find(|p| p.delay == *d && p.loss == *l);
                s += &format!(
                    "{:>8}",
                    p.map_or("?", |p| if p.survived { "yes" } else { "no" })
                );
            }
            s += "\n";
        }
    }
    for (name, rates) in [
        ("periodic samples", &report.rates),
        ("--sample-on-event", &report.rates_events),
    ] {
        s += &format!("\ncontrol rate (perfect network), {name}\n");
        for p in rates.iter() {
            s += &format!(
                "  {:>7.1} Hz: {}{}\n",
                p.rate,
                if p.survived { "survives" } else { "fails" },
                if p.why.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", p.why)
                }
            );
        }
    }
    let f =
        |v: Option<f64>, unit: &str| v.map_or("none of the grid".into(), |v| format!("{v} {unit}"));
    s += &format!(
        "\n{:<38}{:>18}{:>22}\n{:<38}{:>18}{:>22}\n{:<38}{:>18}{:>22}\n",
        "",
        "plain",
        "--predict auto",
        "largest delay survived (no loss)",
        f(report.largest_delay, "s"),
        f(report.largest_delay_predict, "s"),
        "largest loss survived (no delay)",
        f(report.largest_loss, ""),
        f(report.largest_loss_predict, ""),
    );
    s += &format!(
        "{:<38}{:>18}{:>22}\n{:<38}{:>18}{:>22}\n",
        "",
        "periodic",
        "--sample-on-event",
        "lowest rate survived",
        f(report.lowest_rate, "Hz"),
        f(report.lowest_rate_events, "Hz"),
    );
    s += &robot_text(&report.robot);
    s
}

impl fmt::Display for RobotMargins {
    /// The imperfection maps as text, one line per grid value, then the largest imperfections
    /// survived and the bisection tables of [`RobotMargins::edges`] (the lines `tilting plan
    /// margins` prints; angles in rad, rates in rad/s, parameter bands in %).
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        out.write_str(&robot_text(self))
    }
}

/// The imperfection maps as text.
fn robot_text(r: &RobotMargins) -> String {
    let mut s = format!(
        "\nthe robot is not the model, at {} Hz over a perfect network (one imperfection at a \
             time)\n",
        r.rate
    );
    for map in [&r.angle_noise, &r.rate_noise, &r.mass_error] {
        let Some(first) = map.first() else { continue };
        s += &format!("  {}\n", first.imperfection.describe());
        for p in map {
            s += &format!(
                "  {:>10}: {}{}\n",
                p.value,
                if p.survived { "survives" } else { "fails" },
                if p.why.is_empty() {
                    format!(" (last peaks {:.4} rad)", p.last_peak)
                } else {
                    format!(" ({})", p.why)
                }
            );
        }
    }
    let f =
        |v: Option<f64>, unit: &str| v.map_or("none of the grid".into(), |v| format!("{v} {unit}"));
    s += &format!(
        "largest angle noise survived: {}\nlargest rate noise survived: {}\narm-mass errors \
             survived: {}\n",
        f(r.largest_angle_noise, "rad"),
        f(r.largest_rate_noise, "rad/s"),
        r.mass_error_range
            .map_or("none of the grid".into(), |(a, b)| format!("{a} to {b}")),
    );
    s += &edges_text(&r.edges);
    s
}

/// One edge in words: the farthest surviving value, and the nearest failing one past it.
fn edge_text(e: &Edge) -> String {
    let v = |x: f64| match e.knob {
        Knob::Parameter(_) => format!("{:+.1} %", 100.0 * x),
        Knob::EncoderBits(_) => format!("{x}"),
        Knob::AngleNoise(_) => format!("{:.3} mrad", 1e3 * x),
        _ => format!("{x:.3}"),
    };
    match (e.edge, e.beyond) {
        (None, _) => format!("none ({} fails)", v(e.start)),
        (Some(x), None) => format!("{} (end)", v(x)),
        (Some(x), Some(b)) => format!("{} ({} fails)", v(x), v(b)),
    }
}

/// The robot rows searched by bisection, as tables.
fn edges_text(edges: &[Edge]) -> String {
    if edges.is_empty() {
        return String::new();
    }
    let find = |knob: Knob, robust: bool, up: bool| {
        edges
            .iter()
            .find(|e| e.knob == knob && e.robust == robust && (e.end > e.start) == up)
    };
    let mut s = String::from(
        "\nthe robot rows, by bisection (the edge survives, the value in brackets fails)\n",
    );
    let mut knobs: Vec<Knob> = Vec::new();
    for e in edges {
        if !knobs.contains(&e.knob) {
            knobs.push(e.knob);
        }
    }
    let params: Vec<Knob> = knobs
        .iter()
        .copied()
        .filter(|k| matches!(k, Knob::Parameter(_)))
        .collect();
    if !params.is_empty() {
        s += &format!(
            "  {:<6}{:<50}{}\n",
            "param", "band, plain law (plant = (1 + e) model)", "band, robust law (--orbit-peak)"
        );
        for k in params {
            let side = |robust: bool| {
                let down = find(k, robust, false).map_or("-".into(), edge_text);
                let up = find(k, robust, true).map_or("n/a".into(), edge_text);
                format!("{down} to {up}")
            };
            s += &format!("  {:<6}{:<50}{}\n", k.name(), side(false), side(true));
        }
    }
    for (k, label) in [
        (Knob::Viscous, "viscous friction b_v (N m s/rad)"),
        (Knob::Coulomb, "Coulomb friction tau_c (N m)"),
    ] {
        if knobs.contains(&k) {
            let f = |robust| find(k, robust, true).map_or("-".into(), edge_text);
            s += &format!("  {label}: plain {}, robust {}\n", f(false), f(true));
        }
    }
    for (knob, label) in [
        (
            Knob::AngleNoise as fn(_) -> Knob,
            "angle noise, --measure angles",
        ),
        (Knob::EncoderBits, "fewest encoder bits, --measure angles"),
    ] {
        let (obs, fd) = (knob(EstimatorChoice::Observer), knob(EstimatorChoice::Fd));
        if knobs.contains(&obs) || knobs.contains(&fd) {
            let f = |k| {
                edges
                    .iter()
                    .find(|e| e.knob == k)
                    .map_or("-".into(), edge_text)
            };
            s += &format!("  {label}: observer {}, fd {}\n", f(obs), f(fd));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilting_sim::robustness::Parameter;

    fn edge(knob: Knob, robust: bool, end: f64, edge: Option<f64>, beyond: Option<f64>) -> Edge {
        Edge {
            knob,
            robust,
            start: 0.0,
            end,
            edge,
            beyond,
            tried: Vec::new(),
        }
    }

    #[test]
    fn an_edge_prints_its_unit_and_the_failing_value_past_it() {
        let ml = Knob::Parameter(Parameter::ML);
        // A relative band is printed in per cent, one decimal: -0.05 is -5.0 %.
        assert_eq!(
            edge_text(&edge(ml, false, -0.2, Some(-0.05), Some(-0.0625))),
            "-5.0 % (-6.2 % fails)"
        );
        // The search's end survived: nothing fails past it.
        assert_eq!(
            edge_text(&edge(ml, false, 0.2, Some(0.2), None)),
            "+20.0 % (end)"
        );
        // Not even the start survived.
        assert_eq!(
            edge_text(&edge(Knob::Viscous, false, 0.1, None, None)),
            "none (0.000 fails)"
        );
        // Angle noise in mrad: 2e-4 rad is 0.200 mrad.
        let noise = Knob::AngleNoise(EstimatorChoice::Observer);
        assert_eq!(
            edge_text(&edge(noise, false, 1e-3, Some(2e-4), Some(4e-4))),
            "0.200 mrad (0.400 mrad fails)"
        );
    }

    #[test]
    fn the_tables_pair_each_parameter_rows_down_and_up_sides_by_law() {
        let ml = Knob::Parameter(Parameter::ML);
        let edges = [
            edge(ml, false, -0.5, Some(-0.1), Some(-0.2)),
            edge(ml, false, 0.5, Some(0.3), None),
            edge(ml, true, -0.5, None, None),
        ];
        let s = edges_text(&edges);
        let row = s
            .lines()
            .find(|l| l.trim_start().starts_with("m_l"))
            .unwrap();
        // Plain: down then up; robust: down failed at its start, up never searched.
        assert!(
            row.contains("-10.0 % (-20.0 % fails) to +30.0 % (end)"),
            "{row}"
        );
        assert!(row.contains("none (+0.0 % fails) to n/a"), "{row}");
        assert!(edges_text(&[]).is_empty());
    }
}
