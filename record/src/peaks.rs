//! Tilt peaks from a stream of samples `(mode, t, alpha)` in time order: one tracker for the
//! recorder's live view ([`crate::Recorder`]: its status line and summary) and for a recording
//! read back (`tilting_planner::calibrate::tilt_peaks`).
//!
//! A tilt is a run of samples in one tilted mode (1 left, 2 right); its peak is the sample of
//! largest `|alpha|` (the first of equals). A tilt ends at the first sample of another mode
//! (flat, or the other tilt straight away). A tilt cut by the end of the stream has a peak only
//! if `|alpha|` has come back down since its largest sample ([`PeakTracker::settled_peak`]); a
//! reader that wants whole tilts only leaves it out.

/// The extreme `alpha` of one tilt.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// The tilt's mode byte (1 left, 2 right).
    pub mode: u8,
    /// Time of the extreme sample (s).
    pub t: f64,
    /// `alpha` there (rad, signed).
    pub alpha: f64,
}

/// Follows the tilts of a stream of samples (module documentation).
#[derive(Debug, Clone, Copy, Default)]
pub struct PeakTracker {
    /// The tilt in progress: its peak so far and the latest sample's `alpha` (rad).
    tilt: Option<(Peak, f64)>,
}

impl PeakTracker {
    /// Takes the next sample: its mode byte `mode` (0 flat, 1 left, 2 right), time `t` (s) and
    /// tilt angle `alpha` (rad). Returns the peak of the tilt this sample ends (its mode is not
    /// the tilt's), if one was in progress. A NaN `alpha` never replaces a number as the peak;
    /// a number replaces a NaN.
    pub fn push(&mut self, mode: u8, t: f64, alpha: f64) -> Option<Peak> {
        if let Some((peak, last)) = &mut self.tilt {
            if peak.mode == mode {
                *last = alpha;
                if alpha.abs() > peak.alpha.abs() || (peak.alpha.is_nan() && !alpha.is_nan()) {
                    peak.t = t;
                    peak.alpha = alpha;
                }
                return None;
            }
        }
        let done = self.tilt.take().map(|(p, _)| p);
        if mode != 0 {
            self.tilt = Some((Peak { mode, t, alpha }, alpha));
        }
        done
    }

    /// The peak of the tilt in progress at the end of a stream, if `|alpha|` has come back down
    /// since its largest sample (the peak is reached although the tilt has not landed); `None`
    /// without a tilt in progress or while its `|alpha|` is still growing.
    pub fn settled_peak(&self) -> Option<Peak> {
        self.tilt
            .filter(|(p, last)| last.abs() < p.alpha.abs())
            .map(|(p, _)| p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples every `dt` s of tilts `alpha = a sin(pi (t - t0) / d)` (rad) of duration `d` (s),
    /// alternating left (`a > 0`) and right, with `flat` samples flat between them.
    fn tilts(amps: &[f64], d: f64, dt: f64, flat: usize) -> Vec<(u8, f64, f64)> {
        let mut out = Vec::new();
        let mut t = 0.0;
        for (i, &a) in amps.iter().enumerate() {
            let (mode, sign) = if i % 2 == 0 { (1, 1.0) } else { (2, -1.0) };
            let n = (d / dt).round() as usize;
            for k in 1..n {
                let u = k as f64 * dt;
                out.push((mode, t + u, sign * a * (std::f64::consts::PI * u / d).sin()));
            }
            t += d;
            for _ in 0..flat {
                out.push((0, t, 0.0));
                t += dt;
            }
        }
        out
    }

    fn run(samples: &[(u8, f64, f64)]) -> (Vec<Peak>, PeakTracker) {
        let mut tr = PeakTracker::default();
        let peaks = samples
            .iter()
            .filter_map(|&(m, t, a)| tr.push(m, t, a))
            .collect();
        (peaks, tr)
    }

    /// The peak of a half sine sampled with its middle on a sample is its amplitude at half
    /// its duration, with the tilt's sign; tilts end at a flat sample and at the other tilt.
    #[test]
    fn each_tilt_gives_its_half_sine_peak_at_mid_tilt() {
        let (d, dt) = (0.4, 1e-3);
        for flat in [0, 5] {
            let s = tilts(&[0.03, 0.05, 0.04], d, dt, flat);
            let (peaks, tr) = run(&s);
            // The last tilt ends only if flat samples follow it.
            let want = if flat > 0 { 3 } else { 2 };
            assert_eq!(peaks.len(), want, "flat {flat}");
            for (i, p) in peaks.iter().enumerate() {
                let a = [0.03, 0.05, 0.04][i];
                let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                assert_eq!(p.mode, if i % 2 == 0 { 1 } else { 2 });
                assert!((p.alpha - sign * a).abs() < 1e-12, "{p:?}");
                let t_mid = i as f64 * (d + flat as f64 * dt) + d / 2.0;
                assert!((p.t - t_mid).abs() < 1e-9, "{p:?} vs {t_mid}");
            }
            // The last tilt, ended by the stream after its whole half sine: come back down.
            if flat == 0 {
                let p = tr.settled_peak().expect("came back down");
                assert!((p.alpha - 0.04).abs() < 1e-12);
            } else {
                assert_eq!(tr.settled_peak(), None, "no tilt in progress");
            }
        }
    }

    /// A tilt cut before its peak has no settled peak; cut after it, it has, and that peak is
    /// the largest sample.
    #[test]
    fn a_cut_tilt_has_a_peak_only_once_alpha_came_back_down() {
        let (d, dt) = (0.4, 1e-3);
        let s = tilts(&[0.05], d, dt, 0);
        let half = s.len() / 2;
        let (peaks, tr) = run(&s[..half - 10]);
        assert!(peaks.is_empty());
        assert_eq!(tr.settled_peak(), None, "still rising");
        let (_, tr) = run(&s[..half + 10]);
        let p = tr.settled_peak().expect("past the peak");
        assert!((p.alpha - 0.05).abs() < 1e-12 && (p.t - d / 2.0).abs() < 1e-9);
    }

    /// Mirror symmetry: the stream with left and right swapped and alpha negated gives the same
    /// peaks, negated; NaN samples never become the peak.
    #[test]
    fn mirrored_streams_give_mirrored_peaks_and_nan_is_never_a_peak() {
        let mut s = tilts(&[0.03, 0.05], 0.3, 1e-3, 3);
        s.insert(5, (1, s[4].1 + 1e-4, f64::NAN));
        let mirror: Vec<_> = s
            .iter()
            .map(|&(m, t, a)| (if m == 0 { 0 } else { 3 - m }, t, -a))
            .collect();
        let (a, _) = run(&s);
        let (b, _) = run(&mirror);
        assert_eq!(a.len(), 2);
        for (p, q) in a.iter().zip(&b) {
            assert!(p.alpha.is_finite());
            assert_eq!((3 - p.mode, p.t, -p.alpha), (q.mode, q.t, q.alpha));
        }
    }
}
