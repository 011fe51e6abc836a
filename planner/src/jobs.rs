//! The sweeps of `tilting plan` as jobs: their inputs checked (an error names the flag and its
//! range), run whole or one shard at a time ([`crate::shard`]), and merged back into the
//! report the whole run gives. The front door and the Python package both run them, so they
//! take the same inputs and give the same messages and results. The margins survey is
//! [`crate::margins::Survey`], which works the same way.
//!
//! - [`BifurcationJob`]: the sweep of the adaptation gain `k` (Fig. 8) and `k*`; its units
//!   are the values of `k`;
//! - [`orbits`] and [`sinusoid`]: the two approaches of Sec. III for one set of inputs;
//! - [`GainsJob`]: the orbits over a `(K_P, K_D)` grid (Fig. 6); its units are the rows of
//!   constant `K_P` (each row is a continuation in `K_D`);
//! - [`ContinuationJob`] and [`StabilityJob`]: the orbit continued in one parameter (flips,
//!   cascade, Lyapunov exponents) and its stability region in two, with [`Progress`].

mod continuation;
mod continuation_text;
mod orbit_text;

pub use continuation::{
    ContinuationJob, ContinuationReport, ContinuationTiming, Continued, Progress, StabilityJob,
    StabilityReport,
};

use crate::bifurcation::{self, Row, Sweep};
use crate::gains::{self, Cell};
use crate::orbit::{self, OrbitProblem, OrbitSolution};
use crate::peak::PeakSearch;
use crate::shard::{self, Shard, ShardError};
use crate::sinusoid::{self, SinusoidError, SinusoidSolution};
use serde::{Deserialize, Serialize};
use std::time::Instant;
use tilting_plant::paper::ORBIT_K;
use tilting_plant::{ImpactLaw, Params};

/// An invalid input of a sweep, or one that cannot run: the message names the flag of
/// `tilting plan` (the Python keyword without the dashes) and its allowed range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JobError {
    /// An input out of range.
    #[error("{0}")]
    Invalid(String),
    /// The computation failed (no solution where one was asked for).
    #[error("{0}")]
    Failed(String),
    /// No `k = 0` orbit to start the bifurcation sweep from.
    #[error("no periodic orbit for K_P = {kp}, K_D = {kd}")]
    NoOrbit {
        /// `K_P` (1/s^2).
        kp: f64,
        /// `K_D` (1/s).
        kd: f64,
    },
}

/// A wanted tilt peak (rad), checked.
fn check_peak(peak: f64) -> Result<f64, JobError> {
    check(
        "peak",
        peak,
        peak > 0.0 && peak < 1.5,
        "finite, > 0 and < 1.5 (rad)",
    )
}

/// `v` if finite and `ok`, otherwise the error naming `--{field}` and `allowed`.
fn check(field: &str, v: f64, ok: bool, allowed: &str) -> Result<f64, JobError> {
    if v.is_finite() && ok {
        Ok(v)
    } else {
        Err(JobError::Invalid(format!(
            "invalid `--{field}` = {v}: must be {allowed}"
        )))
    }
}

/// Most cells of a `gains` grid (each one is an orbit search of about 0.1 s: 100,000 cells are
/// hours on 2 cores).
pub const MAX_GAIN_CELLS: f64 = 100_000.0;
/// Most values of `k` in one `bifurcation` sweep (each keeps `keep` peaks in memory).
pub const MAX_SWEEP_VALUES: f64 = 100_000.0;
/// Most tilts simulated per `k`.
pub const MAX_TILTS: usize = 1_000_000;

/// The bifurcation sweep: everything its rows depend on (its JSON identifies the grid of a
/// shard).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BifurcationJob {
    /// The model.
    pub params: Params,
    /// The landing impact law.
    pub impact: ImpactLaw,
    /// The values of `k` (1/(J s^2)), in sweep order.
    pub ks: Vec<f64>,
    /// Tilts simulated for each `k`.
    pub tilts: usize,
    /// Tilts kept (the last ones) for each `k`.
    pub keep: usize,
    /// `K_P0` (1/s^2).
    pub kp: f64,
    /// `K_D` (1/s).
    pub kd: f64,
    /// Peaks closer than this (rad) count as equal when classifying the period.
    pub period_tol: f64,
    /// The sweep's `E_av` and start from the orbit of the paper's `k = 500` loop with this
    /// peak (rad, [`crate::peak`]) instead of the `k = 0` orbit, which a landing law that
    /// loses energy does not have ([`BifurcationJob::with_peak`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak: Option<f64>,
}

/// The flags of a bifurcation sweep, before they are checked ([`BifurcationJob::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BifurcationRange {
    /// First `k` (1/(J s^2)).
    pub k_from: f64,
    /// Last `k`.
    pub k_to: f64,
    /// Step of `k`.
    pub k_step: f64,
    /// Tilts simulated for each `k`.
    pub tilts: usize,
    /// Tilts kept (the last ones) for each `k`.
    pub keep: usize,
    /// `K_P0` (1/s^2).
    pub kp: f64,
    /// `K_D` (1/s).
    pub kd: f64,
    /// Peak equality tolerance (rad).
    pub period_tol: f64,
}

/// The report of a bifurcation sweep (the JSON of `tilting plan bifurcation`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BifurcationReport {
    /// E_av of the k = 0 orbit (J).
    pub energy_avg: f64,
    /// Where a multiplier of the adapted orbit crosses -1 (null if not in the range).
    pub k_star: Option<f64>,
    /// The first k of the sweep whose peaks are not period 1 (null if none).
    pub k_onset_observed: Option<f64>,
    /// One row per k.
    pub rows: Vec<Row>,
    /// Where the wall time went.
    pub timing: BifurcationTiming,
}

/// Wall times of one bifurcation sweep (s): a fixed set-up, the sweep (which grows with the
/// number of values of k and of tilts) and `k*`. Merged from shards: the sums of the shards'
/// set-ups and sweeps (the work done), and shard 0's `k*`.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct BifurcationTiming {
    /// Finding the `k = 0` base orbit the sweep starts from (s).
    pub setup_s: f64,
    /// The sweep over k on all cores (s).
    pub sweep_s: f64,
    /// Locating `k*` (s).
    pub k_star_s: f64,
}

/// One shard of a bifurcation sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BifurcationShard {
    /// Which shard.
    pub shard: Shard,
    /// E_av of the k = 0 orbit (J), which every shard finds.
    pub energy_avg: f64,
    /// Whether this shard located `k*` (shard 0 does).
    pub k_star_located: bool,
    /// `k*` if this shard located it and it is in the range.
    pub k_star: Option<f64>,
    /// The shard's wall times (s).
    pub timing: BifurcationTiming,
    /// Its rows: the number of the value of `k`, and the row.
    pub rows: Vec<(usize, Row)>,
}

impl BifurcationJob {
    /// The sweep the flags describe, checked.
    pub fn new(params: Params, impact: ImpactLaw, r: &BifurcationRange) -> Result<Self, JobError> {
        check("k-from", r.k_from, r.k_from >= 0.0, "finite and >= 0")?;
        check("k-to", r.k_to, r.k_to >= r.k_from, "finite and >= --k-from")?;
        check("k-step", r.k_step, r.k_step > 0.0, "finite and > 0")?;
        check("kp", r.kp, r.kp > 0.0, "finite and > 0")?;
        check("kd", r.kd, r.kd > 0.0, "finite and > 0")?;
        let tol = r.period_tol;
        check("period-tol", tol, tol > 0.0, "finite and > 0 (rad)")?;
        if r.keep == 0 || r.keep > r.tilts {
            return Err(JobError::Invalid(format!(
                "invalid `--keep` = {}: must be in 1..=--tilts ({})",
                r.keep, r.tilts
            )));
        }
        let n = gains::range_len(r.k_from, r.k_to, r.k_step);
        if n > MAX_SWEEP_VALUES {
            return Err(JobError::Invalid(format!(
                "invalid `--k-step` = {}: the sweep from --k-from {} to --k-to {} has {n:.0} \
                 values of k; allowed: at most {MAX_SWEEP_VALUES}",
                r.k_step, r.k_from, r.k_to
            )));
        }
        if r.tilts > MAX_TILTS {
            return Err(JobError::Invalid(format!(
                "invalid `--tilts` = {}: allowed 1..={MAX_TILTS}",
                r.tilts
            )));
        }
        Ok(BifurcationJob {
            params,
            impact,
            ks: gains::range(r.k_from, r.k_to, r.k_step),
            tilts: r.tilts,
            keep: r.keep,
            kp: r.kp,
            kd: r.kd,
            period_tol: r.period_tol,
            peak: None,
        })
    }

    /// The same sweep about the orbit of the `k = 500` loop with the peak `peak` (rad): its
    /// `E_av` and its start, as `plan orbit --peak` finds them.
    pub fn with_peak(mut self, peak: f64) -> Result<Self, JobError> {
        check_peak(peak)?;
        self.peak = Some(peak);
        Ok(self)
    }

    /// The sweep from the `k = 0` base orbit (the one with the smallest tilt), and the time its
    /// search took (s).
    pub fn sweep(&self) -> Result<(Sweep, f64), JobError> {
        let pb = OrbitProblem::new(self.params, self.impact, self.kp, self.kd);
        let start = Instant::now();
        let (o, energy_avg) = match self.peak {
            Some(p) => {
                let adapted = pb.with_adaptation(ORBIT_K, 0.0);
                let f = crate::peak::energy_for_peak(&adapted, &PeakSearch::new(p), &|_| {})
                    .map_err(|e| JobError::Failed(e.to_string()))?;
                (f.orbit, f.energy_avg_adaptation)
            }
            None => {
                let o = orbit::smallest(&pb).ok_or(JobError::NoOrbit {
                    kp: self.kp,
                    kd: self.kd,
                })?;
                let e = o.energy_avg;
                (o, e)
            }
        };
        let sw = Sweep {
            problem: pb,
            start_beta0: o.beta0,
            start_beta_dot0: o.beta_dot0,
            energy_avg,
            tilts: self.tilts,
            keep: self.keep,
            period_tol: self.period_tol,
        };
        Ok((sw, start.elapsed().as_secs_f64()))
    }

    /// `k*` over the range of the sweep, and the time it took (s). The attracting adapted
    /// orbit is found by simulation at k = 500 (the paper's stabilised case), or at the first
    /// k if that is lower, and continued from there.
    fn k_star(&self, sw: &Sweep) -> (Option<f64>, f64) {
        let start = Instant::now();
        let (lo, hi) = (self.ks[0], self.ks[self.ks.len() - 1]);
        let k = bifurcation::k_star(sw, ORBIT_K, lo, hi, 1e-3);
        (k, start.elapsed().as_secs_f64())
    }

    /// The whole sweep on all cores, `tick` called after each `k`, then `k*`.
    pub fn run(&self, tick: &(dyn Fn() + Sync)) -> Result<BifurcationReport, JobError> {
        let (sw, setup_s) = self.sweep()?;
        let start = Instant::now();
        let rows = bifurcation::sweep(&sw, &self.ks, tick);
        let sweep_s = start.elapsed().as_secs_f64();
        let (k_star, k_star_s) = self.k_star(&sw);
        let timing = BifurcationTiming {
            setup_s,
            sweep_s,
            k_star_s,
        };
        Ok(report(sw.energy_avg, k_star, rows, timing))
    }

    /// The values of `k` of one shard, on all cores; shard 0 also locates `k*`.
    pub fn run_shard(&self, shard: Shard) -> Result<BifurcationShard, JobError> {
        let (sw, setup_s) = self.sweep()?;
        let start = Instant::now();
        let rows = shard::run(shard, self.ks.len(), |j| {
            bifurcation::run_one(&sw, self.ks[j])
        });
        let sweep_s = start.elapsed().as_secs_f64();
        let (k_star, k_star_s) = if shard.index == 0 {
            self.k_star(&sw)
        } else {
            (None, 0.0)
        };
        Ok(BifurcationShard {
            shard,
            energy_avg: sw.energy_avg,
            k_star_located: shard.index == 0,
            k_star,
            timing: BifurcationTiming {
                setup_s,
                sweep_s,
                k_star_s,
            },
            rows,
        })
    }

    /// The report of the whole sweep from all its shards (in any order); refused unless every
    /// shard of one split is there once with its own rows, all from the same base orbit.
    pub fn merge(&self, shards: Vec<BifurcationShard>) -> Result<BifurcationReport, ShardError> {
        let energy_avg = shards.first().map_or(0.0, |s| s.energy_avg);
        let mut k_star = None;
        let mut timing = BifurcationTiming::default();
        let mut parts = Vec::with_capacity(shards.len());
        for s in shards {
            if s.energy_avg.to_bits() != energy_avg.to_bits() {
                return Err(ShardError::Corrupt {
                    shard: s.shard,
                    why: "its base orbit (E_av) is not the other shards' (another build?)".into(),
                });
            }
            if s.shard.index == 0 && s.k_star_located {
                k_star = Some(s.k_star);
                timing.k_star_s = s.timing.k_star_s;
            }
            timing.setup_s += s.timing.setup_s;
            timing.sweep_s += s.timing.sweep_s;
            parts.push((s.shard, s.rows));
        }
        let count = parts.first().map_or(1, |p| p.0.count);
        let rows = shard::gather(self.ks.len(), parts)?;
        let k_star = k_star.ok_or(ShardError::Corrupt {
            shard: Shard { index: 0, count },
            why: "it carries no k*".into(),
        })?;
        Ok(report(energy_avg, k_star, rows, timing))
    }
}

/// The report of the rows and `k*`.
fn report(
    energy_avg: f64,
    k_star: Option<f64>,
    rows: Vec<Row>,
    timing: BifurcationTiming,
) -> BifurcationReport {
    BifurcationReport {
        energy_avg,
        k_star,
        k_onset_observed: rows.iter().find(|r| r.period != Some(1)).map(|r| r.k),
        rows,
        timing,
    }
}

/// The gains grid: everything its cells depend on (its JSON identifies the grid of a shard).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GainsJob {
    /// The model.
    pub params: Params,
    /// The landing impact law.
    pub impact: ImpactLaw,
    /// The values of `K_P` (1/s^2): the rows.
    pub kps: Vec<f64>,
    /// The values of `K_D` (1/s) along each row.
    pub kds: Vec<f64>,
}

/// The report of a gains grid (the JSON of `tilting plan gains`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GainsReport {
    /// One entry per (K_P, K_D), rows of constant K_P in order.
    pub cells: Vec<Cell>,
}

/// One shard of a gains grid: the number of each of its rows, and the row.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct GainsShard {
    /// Which shard.
    pub shard: Shard,
    /// Its rows.
    pub rows: Vec<(usize, Vec<Cell>)>,
}

impl GainsJob {
    /// The grid `kp_from..=kp_to` step `kp_step` × `kd_from..=kd_to` step `kd_step`, checked
    /// (`[from, to, step]` each).
    pub fn new(
        params: Params,
        impact: ImpactLaw,
        kp: [f64; 3],
        kd: [f64; 3],
    ) -> Result<Self, JobError> {
        let [kp_from, kp_to, kp_step] = kp;
        let [kd_from, kd_to, kd_step] = kd;
        check("kp-from", kp_from, kp_from > 0.0, "finite and > 0")?;
        check("kp-to", kp_to, kp_to >= kp_from, "finite and >= --kp-from")?;
        check("kp-step", kp_step, kp_step > 0.0, "finite and > 0")?;
        check("kd-from", kd_from, kd_from > 0.0, "finite and > 0")?;
        check("kd-to", kd_to, kd_to >= kd_from, "finite and >= --kd-from")?;
        check("kd-step", kd_step, kd_step > 0.0, "finite and > 0")?;
        // The grid is counted before it is allocated: a tiny step must be an error, not an
        // abort.
        let cells =
            gains::range_len(kp_from, kp_to, kp_step) * gains::range_len(kd_from, kd_to, kd_step);
        if cells > MAX_GAIN_CELLS {
            return Err(JobError::Invalid(format!(
                "the (--kp-from..--kp-to step --kp-step) x (--kd-from..--kd-to step --kd-step) \
                 grid has {cells:.0} cells; allowed: at most {MAX_GAIN_CELLS} (make a step \
                 larger)"
            )));
        }
        Ok(GainsJob {
            params,
            impact,
            kps: gains::range(kp_from, kp_to, kp_step),
            kds: gains::range(kd_from, kd_to, kd_step),
        })
    }

    /// The whole grid, rows in parallel; `tick` is called after each row.
    pub fn run(&self, tick: &(dyn Fn() + Sync)) -> GainsReport {
        GainsReport {
            cells: gains::grid(self.params, self.impact, &self.kps, &self.kds, tick),
        }
    }

    /// The rows of one shard, in parallel.
    pub fn run_shard(&self, shard: Shard) -> GainsShard {
        let rows = shard::run(shard, self.kps.len(), |j| {
            gains::row(self.params, self.impact, self.kps[j], &self.kds)
        });
        GainsShard { shard, rows }
    }

    /// The whole grid from all its shards (in any order).
    pub fn merge(&self, shards: Vec<GainsShard>) -> Result<GainsReport, ShardError> {
        let parts = shards.into_iter().map(|s| (s.shard, s.rows)).collect();
        let rows = shard::gather(self.kps.len(), parts)?;
        Ok(GainsReport {
            cells: rows.into_iter().flatten().collect(),
        })
    }
}

/// The orbits of approach 2 for one gain pair (the JSON of `tilting plan orbit`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OrbitReport {
    /// K_P (1/s^2).
    pub kp: f64,
    /// K_D (1/s).
    pub kd: f64,
    /// k.
    pub k: f64,
    /// E_av used by the adaptation (J), if any.
    pub energy_avg_adaptation: Option<f64>,
    /// The orbits found, by increasing maximal tilt.
    pub solutions: Vec<OrbitSolution>,
    /// With `--peak`: how steep the orbit's peak is in the robot's arm mass,
    /// `d ln(peak) / d ln(m_l)` with the controller's model kept
    /// ([`crate::peak::arm_mass_sensitivity`]); `None` (left out of the JSON) otherwise, or
    /// where a neighbouring orbit was not found. -28 means a 1 % heavier arm than the model
    /// lowers the peak by about 28 %.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_per_arm_mass: Option<f64>,
    /// With `--peak` and a control period (`--control-period`) or a robot whose landings are
    /// not plastic (`restitution != 0`): the loop as the hybrid simulator runs it, sampled and
    /// with those landings, and the `E_av` at which its mean peak is the wanted one (that `E_av`
    /// is then `energy_avg_adaptation`; the orbit in `solutions` stays the shooting's, of the
    /// continuous loop with plastic landings). `None` (left out of the JSON) otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settled: Option<crate::peak::SettledPeak>,
    /// With `--calibrate`: the robot's runs, the model's loop at their `E_av`, and the bias by
    /// which `settled` aims below (or above) the wanted peak ([`crate::calibrate`]). `None`
    /// (left out of the JSON) otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<crate::calibrate::Calibration>,
}

/// The periodic orbits of the loop with gains `kp` (1/s^2), `kd` (1/s) and adaptation gain `k`
/// (1/(J s^2)); with `k > 0` each `k = 0` orbit is continued to `k` in steps of at most 100,
/// for the adapted loop with `E_av = energy_avg` (J), by default the `k = 0` orbit's.
pub fn orbits(
    params: Params,
    impact: ImpactLaw,
    kp: f64,
    kd: f64,
    k: f64,
    energy_avg: Option<f64>,
) -> Result<OrbitReport, JobError> {
    check("kp", kp, kp > 0.0, "finite and > 0")?;
    check("kd", kd, kd > 0.0, "finite and > 0")?;
    check("k", k, k >= 0.0, "finite and >= 0")?;
    let pb = OrbitProblem::new(params, impact, kp, kd);
    let base = orbit::find_all(&pb);
    let (solutions, e_av) = if k > 0.0 {
        let e_av = match energy_avg {
            Some(e) => check("energy-avg", e, e > 0.0, "finite and > 0 (J)")?,
            None => base.first().map(|s| s.energy_avg).ok_or_else(|| {
                JobError::Invalid("no k = 0 orbit to take E_av from: give --energy-avg".into())
            })?,
        };
        let mut sols: Vec<OrbitSolution> = base
            .iter()
            .filter_map(|s| {
                // Continue each branch from k = 0 in steps, the orbit moves with k.
                let mut g = [s.beta0, s.beta_dot0, s.t_end];
                let n = (k / 100.0).ceil().max(1.0) as usize;
                let mut last = None;
                for i in 1..=n {
                    let kk = k * i as f64 / n as f64;
                    let sol = orbit::solve(&pb.with_adaptation(kk, e_av), g).ok()?;
                    g = [sol.beta0, sol.beta_dot0, sol.t_end];
                    last = Some(sol);
                }
                last
            })
            .collect();
        sols.sort_by(|a, b| a.max_tilt.total_cmp(&b.max_tilt));
        (sols, Some(e_av))
    } else {
        (base, None)
    };
    Ok(OrbitReport {
        kp,
        kd,
        k,
        energy_avg_adaptation: e_av,
        solutions,
        peak_per_arm_mass: None,
        settled: None,
        calibration: None,
    })
}

/// The adapted loop's orbit with the wanted `peak` (rad): the `E_av` (J) for it, found by
/// [`crate::peak::energy_for_peak`] for the gains `kp` (1/s^2), `kd` (1/s) and `k > 0`
/// (1/(J s^2)). Reported as [`orbits`] reports, with the one orbit and its `E_av`; a peak the
/// family does not reach is refused naming the largest (or smallest) one it does.
///
/// The shooting plans the continuous loop with plastic landings. With `control_period` (s, 0
/// for continuous; the robot's sampling) or a robot whose `restitution` is not 0, `E_av` is
/// then refined by simulating the loop as the robot runs it
/// ([`crate::peak::settle_energy_for_peak`], in [`OrbitReport::settled`]); with `calibrate`
/// (runs of the plain law on the robot, [`crate::calibrate::recorded_orbit`]) at the wanted peak
/// less the robot's bias against the model ([`crate::calibrate::calibrate`]).
pub fn orbit_for_peak(
    params: Params,
    impact: ImpactLaw,
    [kp, kd, k]: [f64; 3],
    peak: f64,
    control_period: Option<f64>,
    calibrate: &[crate::calibrate::RecordedOrbit],
    tick: &dyn Fn(&str),
) -> Result<OrbitReport, JobError> {
    check("kp", kp, kp > 0.0, "finite and > 0")?;
    check("kd", kd, kd > 0.0, "finite and > 0")?;
    check(
        "k",
        k,
        k > 0.0,
        "finite and > 0 (the peak is set through E_av)",
    )?;
    check_peak(peak)?;
    if let Some(dt) = control_period {
        check(
            "control-period",
            dt,
            (0.0..=0.1).contains(&dt),
            "finite, >= 0 and <= 0.1 (s; 0 for a continuous law)",
        )?;
    }
    let plastic = params.plastic();
    let pb = OrbitProblem::new(plastic, impact, kp, kd).with_adaptation(k, 0.0);
    let found = crate::peak::energy_for_peak(&pb, &crate::peak::PeakSearch::new(peak), tick)
        .map_err(|e| match e {
            crate::peak::PeakError::NoOrbit { .. } => JobError::Failed(e.to_string()),
            _ => JobError::Invalid(e.to_string()),
        })?;
    let (settled, calibration) =
        if control_period.is_some() || params.restitution != 0.0 || !calibrate.is_empty() {
            let robot = OrbitProblem::new(params, impact, kp, kd).with_adaptation(k, 0.0);
            let dt = control_period.unwrap_or(0.0);
            let (s, c) = settle_on_robot(&robot, &found, peak, dt, calibrate, tick)?;
            (Some(s), c)
        } else {
            (None, None)
        };
    Ok(OrbitReport {
        kp,
        kd,
        k,
        energy_avg_adaptation: Some(
            settled
                .as_ref()
                .map_or(found.energy_avg_adaptation, |s| s.energy_avg),
        ),
        peak_per_arm_mass: crate::peak::arm_mass_sensitivity(
            &pb.with_adaptation(k, found.energy_avg_adaptation),
            &found.orbit,
        ),
        solutions: vec![found.orbit],
        settled,
        calibration,
    })
}

/// The `E_av` (J) at which the loop `robot` (the robot's landings, sampled every `dt` s, 0 for
/// continuous) settles at a mean peak of `peak` (rad), from the shooting's orbit `found`; with
/// `calibrate` (runs on the robot), at `peak` less the robot's bias against the model at the
/// `E_av` where the settling ends (settled again until that target moves by at most 1e-4 of
/// the peak, six rounds at most), with the [`crate::calibrate::Calibration`] that says so.
fn settle_on_robot(
    robot: &OrbitProblem,
    found: &crate::peak::PeakOrbit,
    peak: f64,
    dt: f64,
    calibrate: &[crate::calibrate::RecordedOrbit],
    tick: &dyn Fn(&str),
) -> Result<
    (
        crate::peak::SettledPeak,
        Option<crate::calibrate::Calibration>,
    ),
    JobError,
> {
    let x0 = OrbitProblem::start(found.orbit.beta0, found.orbit.beta_dot0);
    let mut calibration = None;
    let mut target = peak;
    if !calibrate.is_empty() {
        let c =
            crate::calibrate::calibrate(robot, &x0, calibrate, peak, dt, found.orbit.period, tick)
                .map_err(|e| match e {
                    crate::calibrate::CalibrateError::Model(m) => JobError::Failed(m),
                    e => JobError::Invalid(e.to_string()),
                })?;
        target = peak - c.bias_at(found.energy_avg_adaptation);
        calibration = Some(c);
    }
    let settle = |from: f64, target: f64| {
        crate::peak::settle_energy_for_peak(robot, &x0, from, target, dt, found.orbit.period, tick)
            .map_err(JobError::Failed)
    };
    if let Some(c) = calibration.as_mut() {
        c.period = settle(found.energy_avg_adaptation, peak)?.period;
    }
    let mut s = settle(found.energy_avg_adaptation, target)?;
    // A bias that moves with E_av: settle again at the bias where the last one ended, until
    // the target stays (a few rounds: the bias's slope is small against the model's).
    if let Some(c) = calibration.as_mut() {
        for _ in 0..6 {
            let next = peak - c.bias_at(s.energy_avg);
            if (next - target).abs() <= 1e-4 * peak {
                break;
            }
            target = next;
            s = settle(s.energy_avg, target)?;
        }
        c.model_peak = target;
    }
    Ok((s, calibration))
}

/// The reach map of `plan reach`: which `(K_D, k)` of the grids `[from, to, step]` reach the
/// peak `peak` (rad), and how stably ([`crate::peak::reach_map`]); `kp` is `K_P0` (1/s^2).
pub fn reach(
    params: Params,
    impact: ImpactLaw,
    kp: f64,
    [kd_from, kd_to, kd_step]: [f64; 3],
    [k_from, k_to, k_step]: [f64; 3],
    peak: f64,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<crate::peak::ReachCell>, JobError> {
    check("kp", kp, kp > 0.0, "finite and > 0")?;
    check_peak(peak)?;
    check("kd-from", kd_from, kd_from > 0.0, "finite and > 0")?;
    check("kd-to", kd_to, kd_to >= kd_from, "finite and >= --kd-from")?;
    check("kd-step", kd_step, kd_step > 0.0, "finite and > 0")?;
    check("k-from", k_from, k_from > 0.0, "finite and > 0")?;
    check("k-to", k_to, k_to >= k_from, "finite and >= --k-from")?;
    check("k-step", k_step, k_step > 0.0, "finite and > 0")?;
    let (kds, ks) = (
        gains::range(kd_from, kd_to, kd_step),
        gains::range(k_from, k_to, k_step),
    );
    if kds.len() * ks.len() > 10_000 {
        return Err(JobError::Invalid(format!(
            "invalid grid: {} x {} cells; allowed: at most 10,000",
            kds.len(),
            ks.len()
        )));
    }
    // The map is the shooting's, of plastic landings: a robot's own (a pass-through, a
    // rebound) moves each cell's E_av by a little, which `plan orbit --peak P
    // --control-period S` then refines for the gains chosen.
    let pb = OrbitProblem::new(params.plastic(), impact, kp, kds[0]);
    Ok(crate::peak::reach_map(&pb, &kds, &ks, peak, tick))
}

/// Approach 1: the frequency of `beta_d = A sin(w t) + pi/2` (`amplitude` A in rad) whose
/// ideal-tracking tilt lands at `t_l = T/2 + s t_t` (`landing_offset` s), searched in
/// `[omega_min, omega_max]` (rad/s).
pub fn sinusoid(
    params: &Params,
    amplitude: f64,
    landing_offset: f64,
    omega_min: f64,
    omega_max: f64,
) -> Result<SinusoidSolution, JobError> {
    let search = sinusoid::Search {
        omega_min,
        omega_max,
        ..sinusoid::Search::default()
    };
    check(
        "omega-min",
        omega_min,
        omega_min > 0.0,
        "finite and > 0 (rad/s)",
    )?;
    let allowed = "finite and > --omega-min (rad/s)";
    check("omega-max", omega_max, omega_max > omega_min, allowed)?;
    sinusoid::solve(params, amplitude, landing_offset, &search).map_err(|e| match e {
        SinusoidError::Invalid { .. } => JobError::Invalid(e.to_string()),
        other => JobError::Failed(other.to_string()),
    })
}

/// A plan file (`tilting plan orbit --json`, given as `--plan FILE`), read; an unreadable file
/// or other JSON is an error naming the file.
pub fn read_plan(path: &std::path::Path) -> anyhow::Result<OrbitReport> {
    use anyhow::Context as _;
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("--plan {}: cannot read it", path.display()))?;
    serde_json::from_str(&text).with_context(|| {
        format!(
            "--plan {}: not the JSON of `tilting plan orbit --json`",
            path.display()
        )
    })
}

/// The law of a plan (`tilting plan orbit --json`, a [`crate::jobs::OrbitReport`]): its
/// gains, the adaptation's `E_av` (J), the start of its first stable orbit and (a `--peak`
/// plan's) how steep its peak is in the arm's mass.
pub fn law_of_plan(path: &std::path::Path) -> anyhow::Result<tilting_controller::LawSpec> {
    use anyhow::Context as _;
    let r = read_plan(path)?;
    let Some(o) = r.solutions.iter().find(|o| o.stable) else {
        anyhow::bail!(
            "--plan {}: no stable orbit among its {} solutions (a loop cannot hold an \
             unstable one)",
            path.display(),
            r.solutions.len()
        );
    };
    let law = tilting_controller::LawSpec {
        kp: r.kp,
        kd: r.kd,
        k: r.k,
        energy_avg: r.energy_avg_adaptation.unwrap_or(o.energy_avg),
        orbit_start: Some([std::f64::consts::FRAC_PI_2 + o.beta0, o.beta_dot0]),
        orbit_steepness: r.peak_per_arm_mass,
        ..tilting_controller::LawSpec::default()
    };
    law.validate()
        .with_context(|| format!("--plan {}", path.display()))?;
    Ok(law)
}
