//! Velocities and accelerations from sampled angles: a zero-phase Savitzky–Golay
//! differentiator (a local least-squares polynomial of degree [`DEGREE`] over `2m + 1`
//! samples), with the matching filter for a held torque.
//!
//! Written by hand: no maintained Rust crate provides Savitzky–Golay derivatives with shifted
//! windows at the ends of a segment, nor the torque weights below.
//!
//! **Why the torque is filtered too.** The second-derivative estimate at sample `p` is a linear
//! combination `L[q] = sum_j c_j q_j` that is exact for polynomials up to [`DEGREE`]; by
//! Peano's theorem `L[q] = integral K(s) q''(t_p + s) ds` with the kernel `K(s) = sum_{j > p}
//! c_j (t_j - t_p - s)_+` for `s > 0` (mirrored for `s < 0`), piecewise linear between the
//! samples, of unit integral, and (degree 4) with vanishing first and second moments. So the
//! estimate is the acceleration filtered by `K`, and the equation it enters holds when the
//! torque is filtered by the same `K`: a torque held over `[t_i, t_{i+1}]` weighs
//! `w_i = integral_{t_i}^{t_{i+1}} K` (the trapezoid rule, exact for the linear `K`). With the
//! vanishing moments, the other terms of the equation (gravity, friction, the velocity
//! products) evaluated at `t_p` agree with their filtered values to `O(W^4)` for a window
//! `W`, and so does an acceleration's state-dependent coefficient.

use nalgebra::DMatrix;
#[cfg(test)]
use nalgebra::DVector;

/// Degree of the local polynomial.
pub const DEGREE: usize = 4;

/// The filters of one window length: for each position `p` of the evaluation sample in the
/// window (`0..=2m`), the weights of the value, first and second derivatives (per sample, in
/// units of the sample spacing) and of the held torques (per interval).
#[derive(Debug, Clone)]
pub struct Savgol {
    m: usize,
    /// `[p][j]`: value weights.
    c0: Vec<Vec<f64>>,
    /// `[p][j]`: first-derivative weights times `h`.
    c1: Vec<Vec<f64>>,
    /// `[p][j]`: second-derivative weights times `h^2`.
    c2: Vec<Vec<f64>>,
    /// `[p][i]`: weights of the torque held over interval `i` (`0..2m`), summing to 1.
    w: Vec<Vec<f64>>,
}

/// One sample's smoothed value and derivatives (per second), and its filtered torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Smoothed {
    /// Value.
    pub q: f64,
    /// First derivative (per s).
    pub dq: f64,
    /// Second derivative (per s^2).
    pub ddq: f64,
}

impl Savgol {
    /// The filters of half width `m` samples (window `2m + 1`); `m >= DEGREE / 2 + 1`.
    pub fn new(m: usize) -> Self {
        let m = m.max(DEGREE / 2 + 1);
        let n = 2 * m + 1;
        let (mut c0, mut c1, mut c2, mut w) = (vec![], vec![], vec![], vec![]);
        for p in 0..n {
            // Abscissae scaled by m for conditioning: x_j = (j - p) / m.
            let v = DMatrix::from_fn(n, DEGREE + 1, |j, k| {
                ((j as f64 - p as f64) / m as f64).powi(k as i32)
            });
            let pinv = (v.transpose() * &v)
                .try_inverse()
                .expect("a Vandermonde matrix of distinct abscissae has full rank")
                * v.transpose();
            let row = |k: usize, f: f64| -> Vec<f64> { (0..n).map(|j| pinv[(k, j)] * f).collect() };
            let mf = m as f64;
            let d2 = row(2, 2.0 / (mf * mf));
            w.push(torque_weights(&d2, p));
            c0.push(row(0, 1.0));
            c1.push(row(1, 1.0 / mf));
            c2.push(d2);
        }
        Self { m, c0, c1, c2, w }
    }

    /// Half width (samples).
    pub fn half_width(&self) -> usize {
        self.m
    }

    /// Window length (samples).
    pub fn len(&self) -> usize {
        2 * self.m + 1
    }

    /// Never empty.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The window of sample `i` in a segment of `n >= len()` samples: its first sample and the
    /// position of `i` in it (centred where the segment allows, shifted at its ends).
    pub fn window(&self, i: usize, n: usize) -> (usize, usize) {
        let lo = i.saturating_sub(self.m).min(n - self.len());
        (lo, i - lo)
    }

    /// Value and derivatives at position `p` of the window `q` (`len()` samples spaced `h` s).
    pub fn at(&self, q: &[f64], p: usize, h: f64) -> Smoothed {
        let dot = |c: &[f64]| c.iter().zip(q).map(|(a, b)| a * b).sum::<f64>();
        Smoothed {
            q: dot(&self.c0[p]),
            dq: dot(&self.c1[p]) / h,
            ddq: dot(&self.c2[p]) / (h * h),
        }
    }

    /// The torque filtered as the acceleration at position `p` is: `tau[i]` (N m) held over
    /// the window's interval `i` (`len() - 1` of them).
    pub fn torque(&self, tau: &[f64], p: usize) -> f64 {
        self.w[p].iter().zip(tau).map(|(a, b)| a * b).sum()
    }
}

/// The Peano-kernel weights of the held torques for the second-derivative weights `c`
/// (times `h^2`) evaluated at position `p`: `w_i = (K(i) + K(i + 1)) / 2` in sample units.
fn torque_weights(c: &[f64], p: usize) -> Vec<f64> {
    let n = c.len();
    // K at the sample u (in samples from the window start).
    let k = |u: usize| -> f64 {
        if u >= p {
            (p + 1..n)
                .map(|j| c[j] * (j as f64 - u as f64).max(0.0))
                .sum()
        } else {
            (0..p).map(|j| c[j] * (u as f64 - j as f64).max(0.0)).sum()
        }
    };
    (0..n - 1).map(|i| 0.5 * (k(i) + k(i + 1))).collect()
}

/// Least-squares check used by the tests: the polynomial fit of `q` at `p` directly.
#[cfg(test)]
fn direct(q: &[f64], p: usize, m: usize) -> [f64; 3] {
    let n = q.len();
    let v = DMatrix::from_fn(n, DEGREE + 1, |j, k| {
        ((j as f64 - p as f64) / m as f64).powi(k as i32)
    });
    let a = v
        .svd(true, true)
        .solve(&DVector::from_column_slice(q), 0.0)
        .unwrap();
    let mf = m as f64;
    [a[0], a[1] / mf, 2.0 * a[2] / (mf * mf)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_for_polynomials_and_equal_to_a_direct_fit() {
        let s = Savgol::new(6);
        let h = 1e-3;
        // A quartic in t: the derivatives are exact at every position.
        let f = |t: f64| 0.3 - 2.0 * t + 40.0 * t * t + 700.0 * t.powi(3) - 9e4 * t.powi(4);
        let df = |t: f64| -2.0 + 80.0 * t + 2100.0 * t * t - 3.6e5 * t.powi(3);
        let ddf = |t: f64| 80.0 + 4200.0 * t - 1.08e6 * t * t;
        let q: Vec<f64> = (0..s.len()).map(|j| f(j as f64 * h)).collect();
        for p in 0..s.len() {
            let t = p as f64 * h;
            let r = s.at(&q, p, h);
            assert!((r.q - f(t)).abs() < 1e-10, "{p}: {} vs {}", r.q, f(t));
            assert!((r.dq - df(t)).abs() < 1e-7 * df(t).abs().max(1.0), "{p}");
            assert!((r.ddq - ddf(t)).abs() < 1e-6 * ddf(t).abs().max(1.0), "{p}");
            // The same as a least-squares fit done directly, on noise.
            let noise: Vec<f64> = (0..s.len())
                .map(|j| ((j * 7919 + p * 104_729) % 1000) as f64 * 1e-3)
                .collect();
            let d = direct(&noise, p, s.half_width());
            let r = s.at(&noise, p, 1.0);
            assert!((r.q - d[0]).abs() < 1e-9 && (r.dq - d[1]).abs() < 1e-9);
            assert!((r.ddq - d[2]).abs() < 1e-9);
        }
    }

    #[test]
    fn the_torque_filter_is_the_acceleration_filter() {
        // q'' = tau piecewise constant over intervals (a double integrator under a held
        // torque): the second derivative estimate equals the filtered torque exactly.
        let s = Savgol::new(8);
        let h = 2e-3;
        let tau: Vec<f64> = (0..s.len() - 1)
            .map(|i| (i as f64 * 0.7).sin() * 3.0 + 1.0)
            .collect();
        let (mut q, mut v) = (vec![0.1], 0.5);
        for &a in &tau {
            let last = *q.last().unwrap();
            q.push(last + v * h + 0.5 * a * h * h);
            v += a * h;
        }
        for p in 0..s.len() {
            let sum: f64 = s.w[p].iter().sum();
            assert!((sum - 1.0).abs() < 1e-9, "weights sum {sum}");
            let acc = s.at(&q, p, h).ddq;
            let filt = s.torque(&tau, p);
            assert!(
                (acc - filt).abs() < 1e-7 * filt.abs().max(1.0),
                "{p}: {acc} vs {filt}"
            );
        }
    }
}
