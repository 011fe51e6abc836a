//! Calibrating a plan's `E_av` on the robot (`tilting plan orbit --peak P --calibrate RUN`).
//!
//! **Why.** On a small orbit the peak is steep in the energy: at the 0.018 rad orbit of the
//! paper's gains, 0.1 % of `E_av` moves the peak by 3-6 %. The model's rigid landing is an
//! instant; a real contact takes milliseconds, ringing (MuJoCo's stiff contact: the plate's and
//! the arm's rates oscillate for about 5 ms after each landing, the arm's rate overshooting its
//! settled value by a third), and the controller answers those samples. What that costs the
//! orbit is a small, steady share of its energy balance, which no parameter of the rigid model
//! holds (the landing's restitution barely moves the model's mean peak: its effect is taken up
//! by the adaptation), so a plan from identified parameters alone runs 4-6 % high on MuJoCo.
//!
//! **What.** A run of the *plain* adapted law on the robot (a `tilting live` run directory:
//! its `robot.toml` says the law it ran, its `run.mcap` the tilts) gives the robot's mean peak
//! at that run's `E_av`. The model's loop, simulated with that `E_av` as the plan simulates it
//! ([`crate::peak::settle_energy_for_peak`]), gives the model's. Their difference, the
//! **bias**, is taken as the robot's at nearby energies too, and the plan settles the model's
//! loop at the wanted peak minus the bias. With runs at two energies or more the bias is a
//! least-squares line in `E_av` (two runs: the robot's own secant), which takes up the model's
//! slope being steeper or shallower than the robot's; the model is then settled again at the
//! bias where the last settling ended, until the target stays. A run's own scatter (the mean of
//! about 100 tilts of a 1-2 % scatter) limits it to about 1-2 % on MuJoCo.

use crate::orbit::OrbitProblem;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use tilting_controller::{LawSpec, Trajectory};
use tilting_record::{trace::RUN_MCAP, Window};

/// Tilts of a recorded run left out before its peaks are averaged (the start's transient).
pub const SKIP_TILTS: usize = 10;
/// The fewest tilts a recorded run must average after [`SKIP_TILTS`].
pub const MIN_TILTS: usize = 20;
/// The largest bias taken, as a share of the wanted peak: beyond it the robot runs too far
/// from the model for a correction measured at one energy to hold at another.
pub const MAX_BIAS: f64 = 0.5;
/// Tilts of the model's loop averaged at a run's `E_av` (after
/// [`crate::peak::SETTLE_TILTS`]): the sampled loop's peaks scatter, and its mean of 40 moves
/// by 0.3-0.5 % between neighbouring energies; 200 bring that to about 0.1-0.2 %.
pub const MODEL_TILTS: usize = 200;

/// What a run of the plain adapted law on the robot says: its law and its tilts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedOrbit {
    /// The run directory read.
    pub source: PathBuf,
    /// `E_av` of the run's law (J).
    pub energy_avg: f64,
    /// `K_P0` (1/s^2), `K_D` (1/s) and `k` (1/(J s^2)) of the run's law.
    pub gains: [f64; 3],
    /// Tilts averaged (after [`SKIP_TILTS`]).
    pub tilts: usize,
    /// Mean |peak| of those tilts (rad).
    pub peak_mean: f64,
}

/// One run's share of a [`Calibration`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationRun {
    /// The robot's run.
    #[serde(flatten)]
    pub recorded: RecordedOrbit,
    /// The model's loop at the run's `E_av`: mean |peak| (rad) of [`MODEL_TILTS`] tilts.
    pub model_peak_mean: f64,
    /// `peak_mean - model_peak_mean` (rad).
    pub bias: f64,
}

/// The calibration of a plan on recorded runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Each run.
    pub runs: Vec<CalibrationRun>,
    /// The mean of the runs' biases (rad).
    pub bias: f64,
    /// The mean of the runs' `E_av` (J).
    pub energy_avg: f64,
    /// With runs at two or more energies: the bias's slope in `E_av` (rad/J), a least-squares
    /// line through the runs' biases (with two runs, the robot's own secant); `None` (left out
    /// of the JSON) with one energy, or where the line would make the robot's peak fall as
    /// `E_av` grows (runs too close for their scatter): the bias is then taken as constant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slope: Option<f64>,
    /// The peak the model's loop is settled at (rad): the wanted one minus the bias at the
    /// settled `E_av` ([`Self::bias_at`]).
    pub model_peak: f64,
    /// The period (s) of the model's loop settled at the wanted peak itself, without the bias:
    /// the period the robot should show on the calibrated plan (the report's `settled` is the
    /// model's loop at [`Self::model_peak`], a smaller orbit with a shorter period).
    pub period: f64,
}

impl Calibration {
    /// The robot's bias (rad) at `energy_avg` (J): the mean, moved along [`Self::slope`].
    pub fn bias_at(&self, energy_avg: f64) -> f64 {
        self.bias + self.slope.unwrap_or(0.0) * (energy_avg - self.energy_avg)
    }
}

/// Why a run cannot calibrate a plan.
#[derive(Debug, thiserror::Error)]
pub enum CalibrateError {
    /// The run directory lacks a file, or a file cannot be read.
    #[error("{path}: {why}")]
    Read {
        /// The file.
        path: String,
        /// What went wrong.
        why: String,
    },
    /// The run's law is not the plain adapted law, or not the plan's.
    #[error("{path}: the run's law cannot calibrate this plan: {why}")]
    Law {
        /// The run's robot file.
        path: String,
        /// Which key, and what it must be.
        why: String,
    },
    /// Too few tilts.
    #[error(
        "{path}: {tilts} tilts, at least {need} needed (the first {SKIP_TILTS} are left out): \
         a run of the plain law that keeps tilting, e.g. 40 s"
    )]
    TooFewTilts {
        /// The recording.
        path: String,
        /// Tilts found.
        tilts: usize,
        /// Tilts needed.
        need: usize,
    },
    /// The bias is too large to correct.
    #[error(
        "the robot's mean peak is {robot:.6} rad where the model's is {model:.6} rad at the \
         same E_av: a bias of {share:+.1} % of the wanted peak, allowed at most {max:.0} %; \
         identify the robot again (from a recording at this orbit), or calibrate from a run \
         nearer the wanted peak"
    )]
    TooFar {
        /// The robot's mean peak (rad).
        robot: f64,
        /// The model's (rad).
        model: f64,
        /// The bias in % of the wanted peak.
        share: f64,
        /// [`MAX_BIAS`] in %.
        max: f64,
    },
    /// The model's loop failed.
    #[error("simulating the model's loop at the run's E_av: {0}")]
    Model(String),
}

/// The run of a `tilting live` run directory (`run.mcap`) whose law was `law` (the `[law]` of
/// the `robot.toml` the run wrote): the plain adapted law holding `beta_d = pi/2` with `k > 0`
/// and without `orbit_peak` (a trimmed run holds the peak whatever the plan, so says nothing of
/// the bias).
pub fn recorded_orbit(run: &Path, law: &LawSpec) -> Result<RecordedOrbit, CalibrateError> {
    check_plain(law).map_err(|why| CalibrateError::Law {
        path: run.join("robot.toml").display().to_string(),
        why,
    })?;
    let mcap = run.join(RUN_MCAP);
    let trace = tilting_record::load(&mcap, Window::default(), None)
        .map_err(|e| CalibrateError::Read {
            path: mcap.display().to_string(),
            why: e.to_string(),
        })?
        .trace;
    let peaks = counted(tilt_peaks(&trace.samples));
    if peaks.len() < SKIP_TILTS + MIN_TILTS {
        return Err(CalibrateError::TooFewTilts {
            path: mcap.display().to_string(),
            tilts: peaks.len(),
            need: SKIP_TILTS + MIN_TILTS,
        });
    }
    let used = &peaks[SKIP_TILTS..];
    Ok(RecordedOrbit {
        source: run.to_path_buf(),
        energy_avg: law.energy_avg,
        gains: [law.kp, law.kd, law.k],
        tilts: used.len(),
        peak_mean: used.iter().sum::<f64>() / used.len() as f64,
    })
}

/// `Ok` for the plain adapted law holding upright; else which key is not.
fn check_plain(law: &LawSpec) -> Result<(), String> {
    if law.orbit_peak.is_some() {
        return Err(
            "law.orbit_peak is set: a run of the plain law (no --orbit-peak) is needed, \
             the trim holds the peak whatever E_av"
                .into(),
        );
    }
    if !matches!(law.reference, Trajectory::Hold) {
        return Err(format!(
            "law.reference is {:?}: the hold reference is needed",
            law.reference
        ));
    }
    if law.k.is_nan() || law.k <= 0.0 {
        return Err(format!(
            "law.k = {}: the adapted law (k > 0) is needed",
            law.k
        ));
    }
    Ok(())
}

/// The share of the median peak below which a tilt is not counted: a compliant contact's
/// rebound over the edge the plate came from (MuJoCo's: about 2e-4 rad, against 0.018).
pub const REBOUND_SHARE: f64 = 0.2;

/// `peaks` without the rebounds ([`REBOUND_SHARE`] of their median).
fn counted(peaks: Vec<f64>) -> Vec<f64> {
    let mut sorted = peaks.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    peaks
        .into_iter()
        .filter(|&p| p >= REBOUND_SHARE * median)
        .collect()
}

/// The largest |alpha| (rad) of each tilt (a run of samples in a tilted mode,
/// [`tilting_record::peaks::PeakTracker`]; a tilt cut by the end of the recording is left out,
/// unlike the recorder's summary, which keeps it once |alpha| has come back down), in time order.
pub fn tilt_peaks(samples: &[tilting_record::Sample]) -> Vec<f64> {
    let mut tracker = tilting_record::peaks::PeakTracker::default();
    samples
        .iter()
        .filter_map(|s| tracker.push(s.mode.as_u8(), s.t, s.x[0]))
        .map(|p| p.alpha.abs())
        .collect()
}

/// The calibration of the model `pb` (the plan's gains) on `runs` for the wanted `peak` (rad):
/// each run's bias against the model's loop at its `E_av` (started at `x0`, sampled every `dt`
/// s, [`MODEL_TILTS`] tilts), their mean and, with two energies or more, its line. A run with
/// other gains than `pb`'s is refused naming the gain; a mean bias over [`MAX_BIAS`] of the
/// peak too (before the line's model runs). `model_peak` is `peak` less the mean bias and
/// `period` NaN until the plan settles both ([`crate::jobs::orbit_for_peak`]).
pub fn calibrate(
    pb: &OrbitProblem,
    x0: &tilting_plant::State,
    runs: &[RecordedOrbit],
    peak: f64,
    dt: f64,
    orbit_period: f64,
    tick: &dyn Fn(&str),
) -> Result<Calibration, CalibrateError> {
    let want = [pb.control.law.kp, pb.control.law.kd, pb.control.law.k];
    let mut out = Vec::with_capacity(runs.len());
    for r in runs {
        for ((name, got), w) in ["kp", "kd", "k"].iter().zip(r.gains).zip(want) {
            if (got - w).abs() > 1e-12 * w.abs().max(1.0) {
                return Err(CalibrateError::Law {
                    path: r.source.join("robot.toml").display().to_string(),
                    why: format!("law.{name} = {got}, the plan's is {w}: runs of the plan's gains"),
                });
            }
        }
        tick(&format!(
            "simulating the model's loop at the run's E_av = {:.6} J ({})",
            r.energy_avg,
            r.source.display()
        ));
        let model = crate::peak::settled_mean(pb, x0, r.energy_avg, dt, orbit_period, MODEL_TILTS)
            .map_err(CalibrateError::Model)?;
        out.push(CalibrationRun {
            recorded: r.clone(),
            model_peak_mean: model,
            bias: r.peak_mean - model,
        });
    }
    let n = out.len().max(1) as f64;
    let bias = out.iter().map(|r| r.bias).sum::<f64>() / n;
    let energy_avg = out.iter().map(|r| r.recorded.energy_avg).sum::<f64>() / n;
    if bias.is_nan() || bias.abs() > MAX_BIAS * peak {
        let worst = out
            .iter()
            .max_by(|a, b| a.bias.abs().total_cmp(&b.bias.abs()))
            .expect("at least one run");
        return Err(CalibrateError::TooFar {
            robot: worst.recorded.peak_mean,
            model: worst.model_peak_mean,
            share: 100.0 * bias / peak,
            max: 100.0 * MAX_BIAS,
        });
    }
    let slope = bias_slope(&out, energy_avg, bias, pb, x0, dt, orbit_period)?;
    Ok(Calibration {
        runs: out,
        bias,
        energy_avg,
        slope,
        model_peak: peak - bias,
        period: f64::NAN,
    })
}

/// The least-squares slope (rad/J) of the runs' biases in their `E_av` (means `e_mean`,
/// `b_mean`), or `None` with fewer than two energies, or where the robot's peak would then fall
/// with `E_av` (the model's slope, from its loop 1 mJ either side of `e_mean`, plus the bias's
/// not above 0).
fn bias_slope(
    runs: &[CalibrationRun],
    e_mean: f64,
    b_mean: f64,
    pb: &OrbitProblem,
    x0: &tilting_plant::State,
    dt: f64,
    orbit_period: f64,
) -> Result<Option<f64>, CalibrateError> {
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for r in runs {
        let dx = r.recorded.energy_avg - e_mean;
        sxx += dx * dx;
        sxy += dx * (r.bias - b_mean);
    }
    // Energies closer than 0.1 mJ are one energy (the sampled loop's scatter alone moves the
    // mean peak by more than such a step).
    if runs.len() < 2 || sxx < 1e-8 {
        return Ok(None);
    }
    let slope = sxy / sxx;
    let model = |e: f64| {
        crate::peak::settled_mean(pb, x0, e, dt, orbit_period, MODEL_TILTS)
            .map_err(CalibrateError::Model)
    };
    let step = 1e-3;
    let model_slope = (model(e_mean + step)? - model(e_mean - step)?) / (2.0 * step);
    Ok((model_slope + slope > 0.0).then_some(slope))
}
