//! The words of `plan continuation` and `plan stability`: their reports as lines for a reader.

use super::{ContinuationReport, StabilityReport};
use crate::continuation::{Branch, EventKind, FEIGENBAUM_DELTA};

impl ContinuationReport {
    /// The report in words (lines ending in newlines): the start and its `E_av` (J), each
    /// branch (its range, steps, residual, end and bifurcations with their multipliers), the
    /// flips with their ratios against Feigenbaum's constant, the accumulation point, the
    /// Lyapunov curves (1/s) and the wall time (s).
    pub fn human(&self) -> String {
        let r = self;
        let d = &r.diagram;
        let name = d.param.name();
        let mut s = format!(
            "continuation in {name} from {} (E_av = {:.9} J): {} branches, {} steps\n",
            r.p_start,
            r.energy_avg,
            d.branches.len(),
            r.steps
        );
        for br in &d.branches {
            branch_lines(&mut s, br, name);
        }
        s += "flips (period 2^(n-1) -> 2^n):\n";
        for (i, k) in d.flips.iter().enumerate() {
            let ratio = (i >= 2).then(|| d.ratios[i - 2]);
            s += &format!(
                "  {name}_{} = {k:.7}{}\n",
                i + 1,
                ratio.map_or(String::new(), |q| format!(
                    "   ratio ({name}_{} - {name}_{}) / ({name}_{} - {name}_{}) = {q:.4} (Feigenbaum {:.4})",
                    i,
                    i - 1,
                    i + 1,
                    i,
                    FEIGENBAUM_DELTA
                ))
            );
        }
        if let Some(pi) = d.p_inf {
            s += &format!("accumulation point {name}_inf = {pi:.4} (own ratio)");
            if let Some(pf) = d.p_inf_feigenbaum {
                s += &format!(", {pf:.4} (Feigenbaum's)");
            }
            s += "\n";
        }
        lyapunov_lines(&mut s, r, name);
        let tm = &r.timing;
        s += &format!(
            "wall time: set-up {:.3} s, continuation {:.3} s ({:.2} ms per step), Lyapunov {:.3} s, sampled {:.3} s\n",
            tm.setup_s, tm.continuation_s, tm.per_step_ms, tm.lyapunov_s, tm.lyapunov_sampled_s
        );
        s
    }
}

/// Appends the lines of one branch `br` of a diagram in the parameter `name` to `s`: its points'
/// range, steps, Newton iterations, largest residual and end, and each bifurcation on it.
fn branch_lines(s: &mut String, br: &Branch, name: &str) {
    let (lo, hi) = br
        .points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.p), b.max(p.p))
        });
    let worst = br.points.iter().map(|p| p.residual).fold(0.0, f64::max);
    *s += &format!(
        "  period {:>2}: {} points in {name} [{lo:.4}, {hi:.4}], {} steps, {} Newton iterations, \
         largest residual {worst:.1e}, end: {:?}\n",
        br.tilts,
        br.points.len(),
        br.steps,
        br.newton_iterations,
        br.end
    );
    for ev in &br.events {
        let mu: Vec<String> = ev
            .point
            .multipliers
            .iter()
            .map(|m| format!("{:.6}{:+.6}i", m[0], m[1]))
            .collect();
        *s += &format!(
            "    {}: {name} = {:.7}, multipliers {}\n",
            match ev.kind {
                EventKind::Flip => "flip",
                EventKind::Fold => "fold",
                EventKind::NeimarkSacker => "Neimark-Sacker",
            },
            ev.p,
            mu.join(", ")
        );
    }
}

/// Appends the lines of the Lyapunov curves of `r` (continuous and sampled, if any) in the
/// parameter `name` to `s`: their counts and the first value above 0.01 1/s.
fn lyapunov_lines(s: &mut String, r: &ContinuationReport, name: &str) {
    if !r.lyapunov.is_empty() {
        let pos = r
            .lyapunov
            .iter()
            .find(|e| e.lambda.is_some_and(|l| l > 0.01));
        *s += &format!(
            "Lyapunov: {} values; first exponent above 0.01 1/s at {name} = {}\n",
            r.lyapunov.len(),
            pos.map_or("none".into(), |e| format!(
                "{} ({:.4} 1/s)",
                e.p,
                e.lambda.unwrap_or(0.0)
            ))
        );
    }
    if let Some(h) = r.lyapunov_sampled.first().map(|e| e.period) {
        let pos = r
            .lyapunov_sampled
            .iter()
            .find(|e| e.lambda.is_some_and(|l| l > 0.01));
        let faults = r
            .lyapunov_sampled
            .iter()
            .filter(|e| e.fault.is_some())
            .count();
        *s += &format!(
            "Lyapunov of the loop sampled every {} ms: {} values ({faults} faulted); first largest exponent above 0.01 1/s at {name} = {}\n",
            h * 1e3,
            r.lyapunov_sampled.len(),
            pos.map_or("none".into(), |e| format!(
                "{} ({:.4} 1/s)",
                e.p,
                e.lambda.unwrap_or(0.0)
            ))
        );
    }
}

impl StabilityReport {
    /// The report in words (lines ending in newlines): the region's base and time (s), each
    /// curve's points (about 12 of them, the second parameter and `k` in 1/(J s^2)), the notes.
    pub fn human(&self) -> String {
        let r = &self.region;
        let p2 = r.p2;
        let mut s = format!(
            "stability region of the period-1 orbit in (k, {p2}) ({:.2} s); base {p2} = {}\n",
            self.seconds, r.p2_base
        );
        for (name, c) in [("flip (upper k)", &r.flip), ("fold (lower k)", &r.fold)] {
            let Some(c) = c else { continue };
            s += &format!("  {name}: {} points, ends {:?}\n", c.points.len(), c.ends);
            let step = (c.points.len() / 12).max(1);
            for p in c.points.iter().step_by(step) {
                s += &format!("    {p2} = {:>9.4}  k = {:>10.3}\n", p[1], p[0]);
            }
        }
        for n in &r.notes {
            s += &format!("  note: {n}\n");
        }
        s
    }
}
