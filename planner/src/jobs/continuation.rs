//! `plan continuation` and `plan stability` as jobs: the period-1 orbit continued in one
//! parameter with its flips, the period-doubling cascade and the largest Lyapunov exponent
//! ([`ContinuationJob`]), and its stability region in two ([`StabilityJob`]). Their inputs are
//! checked here (an error names the flag and its range); the caller shows progress
//! ([`Progress`]) and draws the figures.

use super::{check, JobError};
use crate::bifurcation::Sweep;
use crate::continuation::twopar::{self, Region};
use crate::continuation::{self, Diagram, Param, Settings};
use crate::lyapunov::sampled::{self, SampledExponent};
use crate::lyapunov::{self, Exponent};
use crate::orbit::OrbitProblem;
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;
use tilting_plant::paper::ORBIT_K;
use tilting_plant::Params;

/// Where a long job is: each stage begins with its length in steps, moves on, and ends.
/// Called from worker threads (hence `Sync`).
pub trait Progress: Sync {
    /// Stage `name` begins, `len` steps long.
    fn begin(&self, name: &str, len: u64);
    /// The stage is at step `pos` (never lower than before).
    fn at(&self, pos: u64);
    /// One more step of the stage is done.
    fn step(&self);
    /// The stage is over.
    fn end(&self);
}

/// No progress shown.
impl Progress for () {
    fn begin(&self, _: &str, _: u64) {}
    fn at(&self, _: u64) {}
    fn step(&self) {}
    fn end(&self) {}
}

/// The inputs of `plan continuation` (the flags' names in the errors).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContinuationJob {
    /// The parameter continued in.
    pub param: Param,
    /// Where to continue to (the parameter's units); `None`: 2400 for `k`, required otherwise.
    pub to: Option<f64>,
    /// The adaptation gain k (1/(J s^2)), >= 0: the loop's when the parameter is another, the
    /// start of a continuation in `k`.
    pub k: f64,
    /// `K_P0` (1/s^2), > 0.
    pub kp: f64,
    /// `K_D` (1/s), > 0.
    pub kd: f64,
    /// First step (parameter units), > 0; `None`: 1/200 of the range.
    pub step: Option<f64>,
    /// Largest step (parameter units); `None`: 1/50 of the range (never below the first).
    pub max_step: Option<f64>,
    /// Branch switching until this period (tilts): a power of two in 1..=64.
    pub max_period: usize,
    /// Spacing of the Lyapunov curve (parameter units), >= 0 (0: no curve); `None`: 1/200 of
    /// the range.
    pub lyapunov_step: Option<f64>,
    /// Lyapunov: tilts discarded before averaging, 0..=100000.
    pub transient: usize,
    /// Lyapunov: tilts averaged, 1..=100000.
    pub tilts: usize,
    /// The sampled loop's exponents too, at this control period (s), in (0, 0.05].
    pub control_period: Option<f64>,
    /// Start from the adapted loop's orbit with this peak |alpha| (rad) and its E_av.
    pub peak: Option<f64>,
}

/// The report of [`ContinuationJob::run`] (`plan continuation --json`).
#[derive(Debug, Serialize)]
pub struct ContinuationReport {
    /// E_av of the k = 0 orbit (J), the adaptation's target.
    pub energy_avg: f64,
    /// Where the continuation started.
    pub p_start: f64,
    /// The branches, flips, ratios and accumulation point.
    pub diagram: Diagram,
    /// The largest Lyapunov exponent against the parameter.
    pub lyapunov: Vec<Exponent>,
    /// With a control period: the sampled loop's two largest exponents on the same values.
    pub lyapunov_sampled: Vec<SampledExponent>,
    /// Continuation steps over all branches.
    pub steps: usize,
    /// Wall times (s).
    pub timing: ContinuationTiming,
}

/// Wall times of one continuation (s).
#[derive(Debug, Serialize)]
pub struct ContinuationTiming {
    /// The base orbit and the attracting start (s).
    pub setup_s: f64,
    /// All branches with their events and switches (s).
    pub continuation_s: f64,
    /// The Lyapunov curve on all cores (s).
    pub lyapunov_s: f64,
    /// The sampled loop's curve on all cores (s), 0 without a control period.
    pub lyapunov_sampled_s: f64,
    /// `continuation_s` per step (ms).
    pub per_step_ms: f64,
}

/// What a continuation leaves besides its report, for a figure of it.
#[derive(Debug)]
pub struct Continued {
    /// The report.
    pub report: ContinuationReport,
    /// A sweep of the adapted loop from the start orbit (0 tilts: set `tilts` and `keep`).
    pub sweep: Sweep,
    /// The Lyapunov curve's range: its first value (the start without a curve) to `to`.
    pub range: (f64, f64),
}

impl ContinuationJob {
    /// The problem of `params` with these gains, and the checked `to`, first step, largest step
    /// and Lyapunov spacing; an [`JobError::Invalid`] naming the flag and its range otherwise.
    fn checked(&self, params: &Params) -> Result<(OrbitProblem, [f64; 5]), JobError> {
        check("kp", self.kp, self.kp > 0.0, "finite and > 0")?;
        check("kd", self.kd, self.kd > 0.0, "finite and > 0")?;
        check("k", self.k, self.k >= 0.0, "finite and >= 0")?;
        if !(1..=64).contains(&self.max_period) || !self.max_period.is_power_of_two() {
            return Err(JobError::Invalid(format!(
                "invalid `--max-period` = {}: must be a power of two in 1..=64",
                self.max_period
            )));
        }
        if self.tilts == 0 || self.tilts > 100_000 || self.transient > 100_000 {
            return Err(JobError::Invalid(format!(
                "invalid `--tilts` = {} / `--transient` = {}: allowed 1..=100000 and 0..=100000",
                self.tilts, self.transient
            )));
        }
        if let Some(h) = self.control_period {
            check("control-period", h, h > 0.0 && h <= 0.05, "in (0, 0.05] s")?;
        }
        let pb = OrbitProblem::new(*params, params.impact, self.kp, self.kd);
        // The parameter's start value (the adaptation's E_av does not enter any parameter).
        let p0 = self.param.get(&pb.with_adaptation(self.k, 0.0));
        let to = match (self.to, self.param) {
            (Some(v), _) => v,
            (None, Param::K) => 2400.0,
            (None, p) => {
                return Err(JobError::Invalid(format!(
                    "`--param {p}` needs `--to` (where to continue to)"
                )))
            }
        };
        let (ok, range) = self.param.allows(to);
        check(
            "to",
            to,
            ok && to != p0,
            &format!("{range} and not the start {p0}"),
        )?;
        let span = (to - p0).abs();
        let ds = check(
            "step",
            self.step.unwrap_or(span / 200.0),
            self.step.is_none_or(|s| s > 0.0),
            "finite and > 0",
        )?;
        let ds_max = self.max_step.unwrap_or(span / 50.0).max(ds);
        let lstep = self.lyapunov_step.unwrap_or(span / 200.0);
        check("lyapunov-step", lstep, lstep >= 0.0, "finite and >= 0")?;
        Ok((pb, [p0, to, ds, ds_max, lstep]))
    }

    /// Checks the inputs, then continues the orbit of `params` (stage `continuation`, 1000
    /// steps: the branch's share of the range in blocks per period), computes the Lyapunov
    /// curve (stage `lyapunov`, one step a value) and the sampled loop's (stage `sampled`, with
    /// a control period only).
    pub fn run(&self, params: &Params, progress: &dyn Progress) -> Result<Continued, JobError> {
        let (pb, [p0, to, ds, ds_max, lstep]) = self.checked(params)?;
        let start = Instant::now();
        let st = match self.peak {
            Some(p) => continuation::start_at_peak(&pb, self.k, p),
            None => continuation::start(&pb, self.k),
        }
        .map_err(JobError::Failed)?;
        let (o, base, guess) = (&st.orbit, st.base, st.guess);
        let setup_s = start.elapsed().as_secs_f64();
        let set = Settings {
            ds,
            ds_min: ds * 1e-4,
            ds_max,
            ..Settings::over(p0, to, self.max_period)
        };
        progress.begin("continuation", 1000);
        let at = AtomicU64::new(0);
        let start = Instant::now();
        let periods = self.max_period.trailing_zeros() as u64 + 1;
        let diagram = continuation::diagram(&base, self.param, p0, guess, &set, &|tilts, p| {
            // Position: the branch's share of the range, in blocks per period.
            let block = (tilts.trailing_zeros() as u64) * 1000 / periods;
            let frac = ((p - p0) / (to - p0)).clamp(0.0, 1.0);
            let pos = block + (frac * 1000.0 / periods as f64) as u64;
            at.fetch_max(pos, Ordering::Relaxed);
            progress.at(at.load(Ordering::Relaxed));
        })
        .map_err(|e| JobError::Failed(format!("continuation failed: {e}")))?;
        let continuation_s = start.elapsed().as_secs_f64();
        progress.end();
        let ps = continuation::grid(p0, to, lstep);
        progress.begin("lyapunov", ps.len() as u64);
        let start = Instant::now();
        let param = self.param;
        let at = |p| param.set(&base, p);
        let from = [o.beta0, o.beta_dot0];
        let tick = || progress.step();
        let lyap = lyapunov::curve(&ps, &at, from, self.transient, self.tilts, &tick);
        let lyapunov_s = start.elapsed().as_secs_f64();
        progress.end();
        let start = Instant::now();
        let lyap_sampled = match self.control_period {
            Some(h) => {
                progress.begin("sampled", ps.len() as u64);
                let c = sampled::curve(&ps, &at, h, from, self.transient, self.tilts, &tick);
                progress.end();
                c
            }
            None => Vec::new(),
        };
        let lyapunov_sampled_s = start.elapsed().as_secs_f64();
        let steps = diagram.steps();
        let report = ContinuationReport {
            energy_avg: st.energy_avg,
            p_start: p0,
            steps,
            timing: ContinuationTiming {
                setup_s,
                continuation_s,
                lyapunov_s,
                lyapunov_sampled_s,
                per_step_ms: 1e3 * continuation_s / steps.max(1) as f64,
            },
            diagram,
            lyapunov: lyap,
            lyapunov_sampled: lyap_sampled,
        };
        Ok(Continued {
            report,
            sweep: st.sweep,
            range: (ps.first().copied().unwrap_or(p0), to),
        })
    }
}

/// The inputs of `plan stability`: the flip and the fold of the period-1 orbit continued in
/// `(k, param2)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityJob {
    /// The second parameter (not `k`).
    pub param2: Param,
    /// Its lowest value; `None`: 8 for kd, 0.7 for m_l_plant, required otherwise.
    pub from2: Option<f64>,
    /// Its highest value, > `from2`; `None`: 18 for kd, 1.4 for m_l_plant, required otherwise.
    pub to2: Option<f64>,
    /// Highest k searched for the flip (1/(J s^2)), > the paper's k.
    pub k_max: f64,
    /// `K_P0` (1/s^2), > 0.
    pub kp: f64,
    /// `K_D` (1/s), > 0.
    pub kd: f64,
    /// Start from the adapted loop's orbit with this peak |alpha| (rad) and its E_av.
    pub peak: Option<f64>,
}

/// The report of [`StabilityJob::run`] (`plan stability --json`).
#[derive(Debug, Serialize)]
pub struct StabilityReport {
    /// The region: the flip and fold curves.
    pub region: Region,
    /// Wall time (s).
    pub seconds: f64,
}

impl StabilityJob {
    /// Checks the inputs (the range must contain the robot's own value of the second
    /// parameter), then traces the region of `params` (stage `stability`, 400 steps).
    pub fn run(
        &self,
        params: &Params,
        progress: &dyn Progress,
    ) -> Result<StabilityReport, JobError> {
        check("kp", self.kp, self.kp > 0.0, "finite and > 0")?;
        check("kd", self.kd, self.kd > 0.0, "finite and > 0")?;
        check(
            "k-max",
            self.k_max,
            self.k_max > ORBIT_K,
            &format!("finite and > {ORBIT_K}"),
        )?;
        let p2 = self.param2;
        if p2 == Param::K {
            return Err(JobError::Invalid("invalid `--param2` = k: the first parameter is k; choose kd, kp, m_l, m_l_plant or m_f".into()));
        }
        let (lo, hi) = match (self.from2, self.to2, p2) {
            (Some(a), Some(b), _) => (a, b),
            (a, b, Param::Kd) => (a.unwrap_or(8.0), b.unwrap_or(18.0)),
            (a, b, Param::MlPlant) => (a.unwrap_or(0.7), b.unwrap_or(1.4)),
            _ => {
                return Err(JobError::Invalid(format!(
                    "`--param2 {p2}` needs `--from2` and `--to2`"
                )))
            }
        };
        let (ok, range) = p2.allows(lo);
        check("from2", lo, ok, range)?;
        check("to2", hi, hi > lo, "finite and > --from2")?;
        let pb = OrbitProblem::new(*params, params.impact, self.kp, self.kd);
        let base_p2 = p2.get(&pb);
        if !(lo..=hi).contains(&base_p2) {
            return Err(JobError::Invalid(format!(
                "invalid range [--from2 {lo}, --to2 {hi}]: it must contain the base value {p2} = {base_p2}"
            )));
        }
        let start = Instant::now();
        progress.begin("stability", 400);
        let tick = || progress.step();
        let region = match self.peak {
            Some(p) => continuation::start_at_peak(&pb, ORBIT_K, p).and_then(|st| {
                twopar::region_from(&st, ORBIT_K, self.k_max, (p2, (lo, hi)), &tick)
            }),
            None => twopar::region(&pb, ORBIT_K, self.k_max, (p2, (lo, hi)), &tick),
        }
        .map_err(JobError::Failed)?;
        progress.end();
        Ok(StabilityReport {
            region,
            seconds: start.elapsed().as_secs_f64(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each input out of range is refused before any computation, naming its flag; the
    /// messages are the ones the front door printed before the move.
    #[test]
    fn bad_inputs_name_their_flag() {
        let ok = ContinuationJob {
            param: Param::K,
            to: None,
            k: ORBIT_K,
            kp: 100.0,
            kd: 10.0,
            step: None,
            max_step: None,
            max_period: 16,
            lyapunov_step: None,
            transient: 200,
            tilts: 400,
            control_period: None,
            peak: None,
        };
        let params = Params::default();
        let refused = |job: ContinuationJob, what: &str| {
            let Err(JobError::Invalid(e)) = job.checked(&params) else {
                panic!("{what}: accepted");
            };
            assert!(e.contains(what), "{what}: {e}");
        };
        refused(ContinuationJob { kp: 0.0, ..ok }, "`--kp` = 0");
        refused(ContinuationJob { kd: f64::NAN, ..ok }, "`--kd` = NaN");
        refused(ContinuationJob { k: -1.0, ..ok }, "`--k` = -1");
        refused(
            ContinuationJob {
                max_period: 12,
                ..ok
            },
            "`--max-period` = 12",
        );
        refused(ContinuationJob { tilts: 0, ..ok }, "`--tilts` = 0");
        refused(
            ContinuationJob {
                transient: 100_001,
                ..ok
            },
            "`--transient` = 100001",
        );
        refused(
            ContinuationJob {
                control_period: Some(0.1),
                ..ok
            },
            "`--control-period` = 0.1",
        );
        refused(
            ContinuationJob {
                to: Some(ORBIT_K),
                ..ok
            },
            "`--to`",
        );
        refused(
            ContinuationJob {
                param: Param::Kd,
                ..ok
            },
            "`--param kd` needs `--to`",
        );
        refused(
            ContinuationJob {
                step: Some(-1.0),
                ..ok
            },
            "`--step` = -1",
        );
        refused(
            ContinuationJob {
                lyapunov_step: Some(-1.0),
                ..ok
            },
            "`--lyapunov-step` = -1",
        );
        // The defaults: k from the paper's to 2400, steps 1/200 and 1/50 of the range.
        let (_, [p0, to, ds, ds_max, lstep]) = ok.checked(&params).unwrap();
        let span = 2400.0 - ORBIT_K;
        assert_eq!([p0, to], [ORBIT_K, 2400.0]);
        assert_eq!(
            [ds, ds_max, lstep],
            [span / 200.0, span / 50.0, span / 200.0]
        );
        // A largest step below the first is raised to it.
        let small = ContinuationJob {
            step: Some(10.0),
            max_step: Some(1.0),
            ..ok
        };
        assert_eq!(small.checked(&params).unwrap().1[3], 10.0);
        let stab = StabilityJob {
            param2: Param::Kd,
            from2: None,
            to2: None,
            k_max: 4000.0,
            kp: 100.0,
            kd: 10.0,
            peak: None,
        };
        for (job, what) in [
            (
                StabilityJob {
                    param2: Param::K,
                    ..stab
                },
                "`--param2` = k",
            ),
            (
                StabilityJob {
                    k_max: ORBIT_K,
                    ..stab
                },
                "`--k-max`",
            ),
            (
                StabilityJob {
                    param2: Param::Kp,
                    ..stab
                },
                "needs `--from2` and `--to2`",
            ),
            (
                StabilityJob {
                    from2: Some(12.0),
                    ..stab
                },
                "must contain the base value kd = 10",
            ),
            (
                StabilityJob {
                    from2: Some(9.0),
                    to2: Some(9.0),
                    ..stab
                },
                "`--to2` = 9",
            ),
        ] {
            let Err(JobError::Invalid(e)) = job.run(&params, &()) else {
                panic!("{what}: accepted");
            };
            assert!(e.contains(what), "{what}: {e}");
        }
    }
}
