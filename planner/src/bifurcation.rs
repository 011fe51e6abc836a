//! The bifurcation sweep of the paper's Fig. 8: the energy-adapted loop `K_P = K_P0 + k (E_av -
//! E)` simulated from the periodic orbit for each `k`, the maximal `|alpha|` of each tilt after
//! the transient, and the period of that sequence; plus `k*`, where a Floquet multiplier of the
//! adapted orbit crosses -1 (the first period doubling), by bisection.

use crate::orbit::{self, OrbitProblem, OrbitSolution};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use tilting_controller::{ComputedTorque, PlannableLaw};
use tilting_plant::{Mode, Observer, Plant, SimConfig, TiltPeak};

/// What to sweep.
#[derive(Debug, Clone, Copy)]
pub struct Sweep {
    /// The orbit problem (model, impact law, `K_P0`, `K_D`).
    pub problem: OrbitProblem,
    /// The orbit to start from and whose average energy is `E_av`.
    pub start_beta0: f64,
    /// Start `beta_dot0` (rad/s).
    pub start_beta_dot0: f64,
    /// `E_av` (J).
    pub energy_avg: f64,
    /// Tilts simulated per `k`.
    pub tilts: usize,
    /// Tilts kept (the last ones).
    pub keep: usize,
    /// Two peaks closer than this (rad) count as equal when classifying the period.
    pub period_tol: f64,
}

/// One `k` of the sweep.
#[derive(Debug, Clone)]
pub struct Row {
    /// Adaptation gain `k`.
    pub k: f64,
    /// Maximal `|alpha|` (rad) of each of the last `keep` tilts, in order.
    pub peaks: Vec<f64>,
    /// Period of the peak sequence (1, 2, 4, ...), or `None` when irregular or faulted. In JSON:
    /// the number, `"irregular"`, or `null` after a fault.
    pub period: Option<usize>,
    /// What ended the run early, if anything (its message text in JSON).
    pub fault: Option<RowFault>,
}

/// Why the run of one `k` ended early.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RowFault {
    /// The law or the start is invalid for this `k`.
    #[error("{0}")]
    Config(#[from] tilting_plant::ConfigError),
    /// The plant faulted (contact loss, fall, Zeno guard, integrator).
    #[error("{0}")]
    Plant(#[from] tilting_plant::Fault),
    /// No tilt for 10 s: the loop has left the orbit and come to rest.
    #[error("no tilt between t = {from} s and {to} s")]
    NoTilt {
        /// Start of the window (s).
        from: f64,
        /// End of the window (s).
        to: f64,
    },
    /// A fault read back from a report's JSON, which carries its message text only.
    #[error("{0}")]
    Reported(String),
}

impl Serialize for Row {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut st = s.serialize_struct("Row", 4)?;
        st.serialize_field("k", &self.k)?;
        st.serialize_field("peaks", &self.peaks)?;
        match (self.period, &self.fault) {
            (Some(p), _) => st.serialize_field("period", &p)?,
            (None, None) => st.serialize_field("period", "irregular")?,
            (None, Some(_)) => st.serialize_field("period", &None::<usize>)?,
        }
        st.serialize_field("fault", &self.fault.as_ref().map(RowFault::to_string))?;
        st.end()
    }
}

/// Reads the JSON [`Row`] serialises to (a fault as [`RowFault::Reported`]).
impl<'de> Deserialize<'de> for Row {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        /// `period` in JSON: a number, `"irregular"` or `null`.
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Period {
            Of(usize),
            Irregular(String),
        }
        #[derive(Deserialize)]
        struct Json {
            k: f64,
            peaks: Vec<f64>,
            period: Option<Period>,
            fault: Option<String>,
        }
        let j = Json::deserialize(d)?;
        let period = match j.period {
            Some(Period::Of(p)) => Some(p),
            Some(Period::Irregular(s)) if s == "irregular" => None,
            Some(Period::Irregular(s)) => {
                return Err(serde::de::Error::custom(format!(
                    "period {s:?}: expected a number, \"irregular\" or null"
                )))
            }
            None => None,
        };
        Ok(Row {
            k: j.k,
            peaks: j.peaks,
            period,
            fault: j.fault.map(RowFault::Reported),
        })
    }
}

/// Keeps the last `keep` tilt peaks and counts them all (bounded memory).
struct Peaks {
    keep: usize,
    last: VecDeque<f64>,
    count: usize,
}

impl Observer for Peaks {
    fn tilt_peak(&mut self, p: &TiltPeak) {
        self.count += 1;
        if self.last.len() == self.keep {
            self.last.pop_front();
        }
        self.last.push_back(p.alpha.abs());
    }
}

/// The smallest period `p` in 1, 2, 4, ..., 64 with `|x[i] - x[i + p]| < tol` for all `i`, or
/// `None`.
pub fn classify(peaks: &[f64], tol: f64) -> Option<usize> {
    let mut p = 1;
    while p <= 64 && p * 2 <= peaks.len() {
        if peaks.windows(p + 1).all(|w| (w[0] - w[p]).abs() < tol) {
            return Some(p);
        }
        p *= 2;
    }
    None
}

/// Simulates the adapted loop for one `k` and returns its row.
pub fn run_one(sw: &Sweep, k: f64) -> Row {
    let control = sw.problem.with_adaptation(k, sw.energy_avg).control;
    match ComputedTorque::new(control) {
        Ok(law) => run_with(sw, &law, k),
        Err(e) => Row {
            k,
            peaks: Vec::new(),
            period: None,
            fault: Some(e.into()),
        },
    }
}

/// The row of the loop closed by `law` (any [`PlannableLaw`]; `sw`'s model, impact law,
/// start and counts), labelled with the parameter value `k`.
pub fn run_with(sw: &Sweep, law: &impl PlannableLaw, k: f64) -> Row {
    let pb = &sw.problem;
    let mut row = Row {
        k,
        peaks: Vec::new(),
        period: None,
        fault: None,
    };
    let cfg = SimConfig {
        params: pb.params,
        impact: pb.impact,
        ..SimConfig::default()
    };
    let x0 = OrbitProblem::start(sw.start_beta0, sw.start_beta_dot0);
    let mut plant = match Plant::new(cfg, 0.0, Mode::Left, x0) {
        Ok(p) => p,
        Err(e) => {
            row.fault = Some(e.into());
            return row;
        }
    };
    let mut obs = Peaks {
        keep: sw.keep,
        last: VecDeque::with_capacity(sw.keep),
        count: 0,
    };
    let mut t = 0.0;
    while obs.count < sw.tilts {
        // Advance in slices so the run stops soon after the last tilt; a run without tilts
        // for 10 s has left the orbit (it came to rest).
        let before = obs.count;
        t += 10.0;
        if let Err(e) = plant.advance_continuous(law, t, &mut obs) {
            row.fault = Some(e.into());
            break;
        }
        if obs.count == before {
            row.fault = Some(RowFault::NoTilt {
                from: t - 10.0,
                to: t,
            });
            break;
        }
    }
    row.peaks = obs.last.into_iter().collect();
    if row.fault.is_none() {
        row.period = classify(&row.peaks, sw.period_tol);
    }
    row
}

/// Runs the sweep over `ks` on all cores, calling `tick` after each `k`; rows in the order of
/// `ks`.
pub fn sweep(sw: &Sweep, ks: &[f64], tick: &(dyn Fn() + Sync)) -> Vec<Row> {
    ks.par_iter()
        .map(|&k| {
            let r = run_one(sw, k);
            tick();
            r
        })
        .collect()
}

/// The most negative real part among the multipliers (a real multiplier crossing -1 marks the
/// period doubling of the half-period map).
fn lowest_multiplier(s: &OrbitSolution) -> f64 {
    s.multipliers
        .iter()
        .map(|m| m[0])
        .fold(f64::INFINITY, f64::min)
}

/// Records the last left tilt: its start state and its landing time.
#[derive(Default)]
struct LastLeftTilt {
    start: Option<(f64, tilting_plant::State)>,
    complete: Option<(f64, tilting_plant::State, f64)>,
}

impl Observer for LastLeftTilt {
    fn transition(&mut self, ev: &tilting_plant::Transition) {
        if ev.to == Mode::Left {
            self.start = Some((ev.t, ev.x_after));
        } else if ev.from == Mode::Left {
            if let Some((t0, x0)) = self.start.take() {
                self.complete = Some((t0, x0, ev.t - t0));
            }
        }
    }
}

/// A Newton guess `(beta0, beta_dot0, t_end)` for the orbit that attracts the adapted loop at
/// gain `k`: the last left tilt of a simulation of `tilts` tilts from the orbit start.
pub fn attracting_orbit_guess(sw: &Sweep, k: f64, tilts: usize) -> Option<[f64; 3]> {
    let control = sw.problem.with_adaptation(k, sw.energy_avg).control;
    attracting_orbit_guess_with(sw, &ComputedTorque::new(control).ok()?, tilts)
}

/// [`attracting_orbit_guess`] for the loop closed by `law` (any [`PlannableLaw`]).
pub fn attracting_orbit_guess_with(
    sw: &Sweep,
    law: &impl PlannableLaw,
    tilts: usize,
) -> Option<[f64; 3]> {
    let pb = &sw.problem;
    let cfg = SimConfig {
        params: pb.params,
        impact: pb.impact,
        ..SimConfig::default()
    };
    let x0 = OrbitProblem::start(sw.start_beta0, sw.start_beta_dot0);
    let mut plant = Plant::new(cfg, 0.0, Mode::Left, x0).ok()?;
    let mut obs = LastLeftTilt::default();
    let mut t = 0.0;
    while (plant.tilts() as usize) < tilts {
        let before = plant.tilts();
        t += 10.0;
        plant.advance_continuous(law, t, &mut obs).ok()?;
        if plant.tilts() == before {
            return None;
        }
    }
    let (_, x, te) = obs.complete?;
    Some([x[1] - std::f64::consts::FRAC_PI_2, x[3], te])
}

/// `k*`: the adaptation gain in `[k_lo, k_hi]` where the lowest multiplier of the attracting
/// adapted orbit crosses -1, to within `tol`. The orbit is found by simulation at a gain
/// `k_start <= k_lo` where it attracts (the adapted loop converges onto it), refined by Newton,
/// continued to `k_lo`, scanned in 40 steps to `k_hi` and bisected at the crossing. `None` when
/// there is no crossing in the range or the orbit is lost.
pub fn k_star(sw: &Sweep, k_start: f64, k_lo: f64, k_hi: f64, tol: f64) -> Option<f64> {
    let pb = &sw.problem;
    let solve_at = |k: f64, g: [f64; 3]| {
        orbit::solve(&pb.with_adaptation(k, sw.energy_avg), g)
            .ok()
            .filter(|s| s.max_tilt > 0.0)
    };
    let as_guess = |s: &OrbitSolution| [s.beta0, s.beta_dot0, s.t_end];
    let k_start = k_start.min(k_lo);
    let mut prev = solve_at(k_start, attracting_orbit_guess(sw, k_start, 200)?)?;
    let mut k_prev = k_start;
    // Continue in small steps to k_lo (the orbit moves smoothly along its branch).
    while k_prev < k_lo {
        let k = (k_prev + 50.0).min(k_lo);
        prev = solve_at(k, as_guess(&prev))?;
        k_prev = k;
    }
    if lowest_multiplier(&prev) + 1.0 <= 0.0 {
        return None;
    }
    let dk = ((k_hi - k_lo) / 40.0).max(tol);
    while k_prev < k_hi {
        let k = (k_prev + dk).min(k_hi);
        let s = solve_at(k, as_guess(&prev))?;
        if lowest_multiplier(&s) + 1.0 <= 0.0 {
            let (mut lo, mut hi) = (k_prev, k);
            let mut guess = prev;
            while hi - lo > tol {
                let mid = 0.5 * (lo + hi);
                let sm = solve_at(mid, as_guess(&guess))?;
                if lowest_multiplier(&sm) + 1.0 > 0.0 {
                    lo = mid;
                    guess = sm;
                } else {
                    hi = mid;
                }
            }
            return Some(0.5 * (lo + hi));
        }
        prev = s;
        k_prev = k;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::classify;

    #[test]
    fn rows_serialise_the_period_as_number_irregular_or_null() {
        let row = |period, fault: Option<super::RowFault>| super::Row {
            k: 1.0,
            peaks: vec![0.1],
            period,
            fault,
        };
        let j = |r| serde_json::to_value(&r).unwrap();
        assert_eq!(j(row(Some(2), None))["period"], serde_json::json!(2));
        assert_eq!(j(row(None, None))["period"], serde_json::json!("irregular"));
        let no_tilt = super::RowFault::NoTilt {
            from: 10.0,
            to: 20.0,
        };
        let faulted = j(row(None, Some(no_tilt)));
        assert_eq!(faulted["period"], serde_json::Value::Null);
        // The fault travels as its message.
        assert_eq!(faulted["fault"], "no tilt between t = 10 s and 20 s");
        // And reads back: the same JSON, the fault as its message.
        for v in [j(row(Some(2), None)), j(row(None, None)), faulted.clone()] {
            let back: super::Row = serde_json::from_value(v.clone()).unwrap();
            assert_eq!(j(back), v);
        }
        let back: super::Row = serde_json::from_value(faulted).unwrap();
        assert_eq!(
            back.fault,
            Some(super::RowFault::Reported(
                "no tilt between t = 10 s and 20 s".into()
            ))
        );
        assert_eq!(back.period, None);
    }

    #[test]
    fn periods_are_classified() {
        assert_eq!(classify(&[0.1; 10], 1e-9), Some(1));
        let two: Vec<f64> = (0..10)
            .map(|i| if i % 2 == 0 { 0.1 } else { 0.2 })
            .collect();
        assert_eq!(classify(&two, 1e-9), Some(2));
        let four: Vec<f64> = (0..16).map(|i| [0.1, 0.2, 0.15, 0.3][i % 4]).collect();
        assert_eq!(classify(&four, 1e-9), Some(4));
        let irregular: Vec<f64> = (0..64).map(|i| ((i * i) % 17) as f64).collect();
        assert_eq!(classify(&irregular, 1e-9), None);
    }
}
