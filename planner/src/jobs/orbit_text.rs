//! The words of `plan orbit`: an [`OrbitReport`] as lines for a reader.

use super::OrbitReport;
use std::fmt::Write;

impl OrbitReport {
    /// The report in words (one line per fact, each ending in a newline): the gains and the
    /// number of orbits, the adaptation's `E_av` (J) and how to run it, the settled and
    /// calibrated `E_av` if any, each orbit (angles in rad, times in s, energies in J, its
    /// Floquet multipliers) and the peak's steepness in the arm mass. `peak` is the wanted
    /// peak (rad) of `plan orbit --peak`, `None` without it.
    pub fn human(&self, peak: Option<f64>) -> String {
        let mut s = format!(
            "periodic orbits for K_P = {}, K_D = {}, k = {} ({} found)\n",
            self.kp,
            self.kd,
            self.k,
            self.solutions.len()
        );
        if let Some(e) = self.energy_avg_adaptation {
            // The orbit's own E_av below is its mean energy; the adaptation's is the k = 0
            // orbit's, the one `simulate`/`live --energy-avg` need to run this orbit.
            let whose = match peak {
                Some(p) => format!("for the peak {p} rad"),
                None => "the k = 0 orbit's".into(),
            };
            let _ = writeln!(
                s,
                "  adaptation E_av = {e:.9} J ({whose}): run it with --k {} --energy-avg {e:.9}",
                self.k
            );
        }
        self.settled_lines(&mut s, peak.unwrap_or(0.0));
        for o in &self.solutions {
            let mult: Vec<String> = o
                .multipliers
                .iter()
                .map(|m| {
                    if m[1] == 0.0 {
                        format!("{:.6}", m[0])
                    } else {
                        format!("{:.6}{:+.6}i", m[0], m[1])
                    }
                })
                .collect();
            let _ = writeln!(
                s,
                "  beta0 = {:+.9} rad, beta_dot0 = {:.9} rad/s, t_end = {:.9} s, period = {:.6} s, \
                 max tilt = {:.6} rad, E_av = {:.9} J, multipliers [{}] ({})",
                o.beta0,
                o.beta_dot0,
                o.t_end,
                o.period,
                o.max_tilt,
                o.energy_avg,
                mult.join(", "),
                if o.stable { "stable" } else { "unstable" }
            );
        }
        if let Some(d) = self.peak_per_arm_mass {
            let _ = writeln!(
                s,
                "  peak per arm mass d ln(peak)/d ln(m_l) = {d:.2}: to first order, an arm 1 % \
                 off the model moves the peak by {:.0} % (steeper orbits hold worse on a real \
                 robot)",
                d.abs()
            );
        }
        s
    }

    /// Appends the lines of the settled loop and of the calibration, if any, to `s`; `want` is
    /// the wanted peak (rad), the base of the biases' percentages.
    fn settled_lines(&self, s: &mut String, want: f64) {
        if let Some(st) = &self.settled {
            let _ = writeln!(
                s,
                "  simulated (control period {} s, restitution {}): E_av {:.9} J settles at a \
                 mean peak of {:.6} rad (tilts {:.6} to {:.6}), period {:.6} s ({} runs); the \
                 orbit below is the continuous loop's with plastic landings",
                st.control_period,
                st.restitution,
                st.energy_avg,
                st.peak_mean,
                st.peak_min,
                st.peak_max,
                st.period,
                st.runs
            );
        }
        if let Some(c) = &self.calibration {
            for r in &c.runs {
                let _ = writeln!(
                    s,
                    "  calibration: {} at E_av {:.9} J: the robot's mean peak {:.6} rad ({} \
                     tilts), the model's {:.6} rad, bias {:+.2} %",
                    r.recorded.source.display(),
                    r.recorded.energy_avg,
                    r.recorded.peak_mean,
                    r.recorded.tilts,
                    r.model_peak_mean,
                    100.0 * r.bias / want
                );
            }
            let _ = writeln!(
                s,
                "  calibrated: the model's loop settled at {:.6} rad for the robot's {} rad, \
                 whose period is {:.6} s (the model's loop at that peak)",
                c.model_peak, want, c.period
            );
        }
    }
}
