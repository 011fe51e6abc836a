//! The words of `tilting identify`: an [`Identification`] as lines for a reader.

use super::{landing, refine, Identification};
use std::fmt::Write as _;

impl Identification {
    /// The identification in words (lines ending in newlines), for the recording(s) `source`:
    /// the equations and where they came from, the condition number and residual (N m), each
    /// base parameter's estimate and standard error (or why the data cannot fix it), the
    /// output-error refinement and the landings if any, the physical parameters (SI units),
    /// what motion cannot identify, the warnings and the fit check (rad).
    pub fn human(&self, source: &str) -> String {
        let mut s = String::new();
        let r = self.rows;
        let _ = writeln!(
            s,
            "{source}: {} equations ({} flat and {} tilted intervals; {} skipped at events or \
             without a torque)",
            r.equations, r.flat, r.tilted, r.skipped
        );
        let _ = writeln!(
            s,
            "condition number {:.3e} (columns scaled), residual RMS {:.3e} N m\n",
            self.condition_number, self.residual_rms
        );
        let _ = writeln!(
            s,
            "{:<8} {:<28} {:>14} {:>11}  unit",
            "base", "", "estimate", "std err"
        );
        for e in &self.base {
            match (e.value, e.std_error) {
                (Some(v), Some(se)) => {
                    let _ = writeln!(
                        s,
                        "{:<8} {:<28} {v:>14.6} {se:>11.2e}  {}",
                        e.name, e.combination, e.unit
                    );
                }
                _ => {
                    let why = e
                        .not_identifiable
                        .as_deref()
                        .unwrap_or("not fixed by the data");
                    let _ = writeln!(
                        s,
                        "{:<8} {:<28} not identifiable: {why}",
                        e.name, e.combination
                    );
                }
            }
        }
        if let Some(r) = &self.refinement {
            refinement_lines(&mut s, r);
        }
        if let Some(l) = &self.landing {
            landing_summary(&mut s, l);
        }
        let p = &self.params;
        let _ = writeln!(
            s,
            "\nparameters: m_f {:.6} kg, m_l {:.6} kg (prior), l_c {:.6} m, i_l {:.6} kg m^2, \
             j_m {:.6} kg m^2, n_g {:.6}, b_v {:.6} N m s/rad, tau_c {:.6} N m, i_f {:.6} kg m^2, \
             impact {}, restitution {:.4}",
            p.m_f,
            p.m_l,
            p.lc(),
            p.i_l,
            p.j_m,
            p.n_g,
            p.b_v,
            p.tau_c,
            p.i_f,
            p.impact.as_str(),
            p.restitution
        );
        let _ = writeln!(s, "not identifiable from motion:");
        for n in &self.not_identifiable {
            let _ = writeln!(s, "  - {n}");
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        if let Some(f) = &self.fit {
            let _ = writeln!(
                s,
                "fit check (re-simulated under the recorded torques, restarted every {} s, {} \
                 windows): RMS alpha {:.3e} rad, beta {:.3e} rad with the identified parameters; \
                 {:.3e} rad, {:.3e} rad with the prior",
                f.identified.window_s,
                f.identified.windows,
                f.identified.rms_alpha,
                f.identified.rms_beta,
                f.prior.rms_alpha,
                f.prior.rms_beta
            );
        }
        s
    }
}

/// The output-error refinement's line of the human summary: its windows, the angles' RMS
/// (rad) against the least squares', and `(J, m_l l_c g, b_v, tau_c)` with their errors.
fn refinement_lines(s: &mut String, r: &refine::Refinement) {
    let _ = writeln!(
        s,
        "\noutput-error refinement ({} flat windows of {} s joined, {} angles, {} \
         iterations{}): beta RMS {:.3e} rad (least squares {:.3e}); J {:.6} +- {:.1e} kg m^2, \
         m_l l_c g {:.6} +- {:.1e} N m, b_v {:.6} +- {:.1e} N m s/rad, tau_c {:.6} +- \
         {:.1e} N m (b_v and tau_c above are these where their standard errors are smaller)",
        r.windows,
        r.window_s,
        r.samples,
        r.iterations,
        if r.converged { "" } else { ", not converged" },
        r.rms,
        r.rms_start,
        r.value[0],
        r.std_error[0],
        r.value[1],
        r.std_error[1],
        r.value[2],
        r.std_error[2],
        r.value[3],
        r.std_error[3]
    );
}

/// The landings' lines of the human summary: the regressed `c`, the restitution, each law's
/// coefficient and residual, the best.
fn landing_summary(s: &mut String, l: &landing::LandingFit) {
    let _ = writeln!(
        s,
        "\nlandings: {} used ({} skipped: a side shorter than {} samples), {} rebounds; \
         beta_dot+ = beta_dot- + c alpha_dot-: c = {:.5} +- {:.1e}; physical law's restitution \
         e = {:.4} +- {:.1e}",
        l.landings.len(),
        l.skipped,
        landing::MIN_SIDE,
        l.rebounds,
        l.c,
        l.c_std_error,
        l.restitution,
        l.restitution_std_error
    );
    if let Some(t) = &l.by_tilts {
        let _ = writeln!(
            s,
            "  restitution by the tilts after the landings (the model's next peak as recorded): \
             e = {:.4} +- {:.1e} over {} landings{}",
            t.e,
            t.std_error,
            t.landings,
            if t.e < 0.0 {
                " (below 0: the plate passes on into the next tilt)"
            } else {
                ""
            }
        );
    }
    if let Some(d) = &l.contact_dwell {
        let _ = writeln!(
            s,
            "  the contact reports the plate flat for {:.2} ms on average (longest {:.2} ms) \
             at {} landings that pass on into the other tilt{}",
            d.mean * 1e3,
            d.longest * 1e3,
            d.spells,
            if d.outliers > 0 {
                format!(
                    " ({} longer than {} x the median left out: the plate at rest a moment)",
                    d.outliers,
                    landing::DWELL_OUTLIER
                )
            } else {
                String::new()
            }
        );
    }
    for f in &l.laws {
        let _ = writeln!(
            s,
            "  {:<14} c {:.5}  residual RMS {:.3e} rad/s{}",
            f.law.as_str(),
            f.c,
            f.residual_rms,
            if f.law == l.best {
                "  <- fits best"
            } else {
                ""
            }
        );
    }
}
