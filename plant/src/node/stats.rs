//! Timing statistics with flat memory: a fixed ring of the latest samples and percentiles
//! computed on a preallocated copy.

/// The last [`Ring::CAPACITY`] samples of one quantity (µs), with the running maximum and count
/// over the whole run.
#[derive(Debug, Clone)]
pub struct Ring {
    buf: Box<[f64]>,
    scratch: Vec<f64>,
    next: usize,
    len: usize,
    count: u64,
    max: f64,
}

/// Percentiles of a [`Ring`]'s window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
}

impl Default for Ring {
    fn default() -> Self {
        Self::new()
    }
}

impl Ring {
    /// Samples kept.
    pub const CAPACITY: usize = 4096;

    /// An empty ring.
    pub fn new() -> Self {
        Self {
            buf: vec![0.0; Self::CAPACITY].into_boxed_slice(),
            scratch: Vec::with_capacity(Self::CAPACITY),
            next: 0,
            len: 0,
            count: 0,
            max: 0.0,
        }
    }

    /// Adds a sample (non-finite samples are ignored).
    pub fn push(&mut self, v: f64) {
        if !v.is_finite() {
            return;
        }
        self.buf[self.next] = v;
        self.next = (self.next + 1) % Self::CAPACITY;
        self.len = (self.len + 1).min(Self::CAPACITY);
        self.count += 1;
        if v > self.max {
            self.max = v;
        }
    }

    /// Samples pushed over the whole run.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Largest sample over the whole run (0 if none).
    pub fn max(&self) -> f64 {
        self.max
    }

    /// Percentiles of the samples in the window (nearest rank; zeros if empty). Does not
    /// allocate. Three selections instead of a sort (about 15 us instead of 40 to 80 us for a
    /// full window): the plant computes these at 10 Hz on its pacing thread, while a round
    /// trip is in flight.
    pub fn percentiles(&mut self) -> Percentiles {
        if self.len == 0 {
            return Percentiles::default();
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(&self.buf[..self.len]);
        let n = self.scratch.len();
        let rank = |q: f64| ((q * n as f64).ceil() as usize).clamp(1, n) - 1;
        let (i50, i99, i999) = (rank(0.5), rank(0.99), rank(0.999));
        // Each selection leaves the smaller values before the chosen index, so the next,
        // smaller rank is selected within that prefix.
        let (_, &mut p999, _) = self.scratch.select_nth_unstable_by(i999, f64::total_cmp);
        let (_, &mut p99, _) = self.scratch[..=i999].select_nth_unstable_by(i99, f64::total_cmp);
        let (_, &mut p50, _) = self.scratch[..=i99].select_nth_unstable_by(i50, f64::total_cmp);
        Percentiles { p50, p99, p999 }
    }
}

/// Share of a second's control periods whose torque missed its deadline above which the loop
/// is late (the plant's log warns, `tilting live`'s status line raises `LOOP LATE`). A quiet
/// run misses under 1 %; with the plant and the controller starved of CPU (6 busy loops beside
/// them on 2 cores) 77-79 % were missed and the robot fell within 20 s (README, Faults). At
/// 20 % the loop can still hold the orbit, so this is said before the robot falls.
pub const LATE_SHARE: f64 = 0.2;

/// The share of missed deadlines over about the last second, from the counters (control
/// periods, deadline misses) sampled at a steady rate, flat memory.
#[derive(Debug, Clone)]
pub struct Lateness {
    samples: std::collections::VecDeque<(u64, u64)>,
    per_second: usize,
}

impl Lateness {
    /// For counters sampled `per_second` times a second (at least 1).
    pub fn new(per_second: usize) -> Self {
        let per_second = per_second.max(1);
        Self {
            samples: std::collections::VecDeque::with_capacity(per_second + 1),
            per_second,
        }
    }

    /// Adds a sample of the run's counters (periods so far, deadline misses so far); returns
    /// the share of the periods since the oldest sample kept (a second ago, once a second has
    /// passed) that missed, if at least 100 periods lie between them.
    pub fn update(&mut self, periods: u64, misses: u64) -> Option<f64> {
        if self.samples.len() > self.per_second {
            self.samples.pop_front();
        }
        self.samples.push_back((periods, misses));
        let (&(p0, m0), &(p1, m1)) = (self.samples.front()?, self.samples.back()?);
        let periods = p1.checked_sub(p0)?;
        (periods >= 100).then(|| m1.saturating_sub(m0) as f64 / periods as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lateness_is_the_share_missed_over_the_last_second() {
        // Five samples a second, 200 periods apart.
        let mut l = Lateness::new(5);
        assert_eq!(l.update(0, 0), None, "one sample");
        // 10 % missed in each of the first five intervals.
        let mut out = None;
        for k in 1..=5u64 {
            out = l.update(200 * k, 20 * k);
        }
        assert!((out.unwrap() - 0.1).abs() < 1e-12, "{out:?}");
        // Then every period of one interval missed: the window (the last 5 intervals, 1,000
        // periods) holds 4 at 10 % and one at 100 %.
        let out = l.update(1200, 100 + 200);
        assert!(
            (out.unwrap() - (80.0 + 200.0) / 1000.0).abs() < 1e-12,
            "{out:?}"
        );
        // A window of fewer than 100 periods (a stalled plant) says nothing.
        let mut l = Lateness::new(5);
        l.update(10, 10);
        assert_eq!(l.update(50, 50), None);
    }

    #[test]
    fn percentiles_of_a_known_window() {
        let mut r = Ring::new();
        assert_eq!(r.percentiles(), Percentiles::default());
        for i in 1..=1000 {
            r.push(i as f64);
        }
        let p = r.percentiles();
        assert_eq!(p.p50, 500.0);
        assert_eq!(p.p99, 990.0);
        assert_eq!(p.p999, 999.0);
        assert_eq!(r.max(), 1000.0);
        // The window keeps only the last CAPACITY samples; memory stays flat.
        for _ in 0..10 * Ring::CAPACITY {
            r.push(1.0);
        }
        assert_eq!(r.percentiles().p999, 1.0);
        assert_eq!(r.max(), 1000.0);
        assert_eq!(r.count(), 1000 + 10 * Ring::CAPACITY as u64);
        r.push(f64::NAN);
        assert_eq!(r.count(), 1000 + 10 * Ring::CAPACITY as u64);
    }

    #[test]
    fn selection_matches_a_sort() {
        let mut x: u64 = 12345;
        for len in [1usize, 2, 3, 99, 1000, 4095, 4096, 10_000] {
            let mut r = Ring::new();
            let mut all = Vec::new();
            for _ in 0..len {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let v = ((x >> 33) % 5000) as f64 * 0.25;
                r.push(v);
                all.push(v);
            }
            let mut w = all[all.len().saturating_sub(Ring::CAPACITY)..].to_vec();
            w.sort_unstable_by(f64::total_cmp);
            let at = |q: f64| w[((q * w.len() as f64).ceil() as usize).clamp(1, w.len()) - 1];
            let p = r.percentiles();
            assert_eq!(
                (p.p50, p.p99, p.p999),
                (at(0.5), at(0.99), at(0.999)),
                "{len}"
            );
        }
    }
}
