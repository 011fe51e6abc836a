//! `tilting._core`: the Rust side of the Python package `tilting` (see `python/tilting/` for
//! the public API, its types and its docs). Thin bindings over the library crates: the inputs
//! are parsed and checked by the same code as the front door's (`simulate`'s flags by its clap
//! struct, the sweeps by `tilting_planner::jobs` and `margins::Survey`), so the options and the
//! messages are the CLI's. Reports cross as the CLI's JSON text (parsed on the Python side),
//! trajectories as numpy arrays. Every call that computes releases the GIL.

use clap::Parser;
use numpy::{IntoPyArray, PyArray2};
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use tilting_planner::jobs::{self, BifurcationJob, BifurcationRange, GainsJob, JobError};
use tilting_planner::margins::{self, Bands, Criteria, Sample, Survey, SurveyShard};
use tilting_planner::shard::Shard;
use tilting_plant::{ImpactLaw, Params, ParamsArgs};

create_exception!(
    tilting._core,
    UsageError,
    PyValueError,
    "Invalid input: the message names the option (as the CLI's flag) and its allowed range."
);
create_exception!(
    tilting._core,
    RunError,
    PyRuntimeError,
    "A computation that could not be done (no orbit, a failed run)."
);

fn usage(e: impl ToString) -> PyErr {
    UsageError::new_err(e.to_string())
}

fn failed(e: impl ToString) -> PyErr {
    RunError::new_err(e.to_string())
}

fn job_err(e: JobError) -> PyErr {
    match e {
        JobError::Invalid(_) => usage(e),
        JobError::Failed(_) | JobError::NoOrbit { .. } => failed(e),
    }
}

fn to_json<T: serde::Serialize>(v: &T) -> PyResult<String> {
    serde_json::to_string(v).map_err(failed)
}

fn from_json<T: serde::de::DeserializeOwned>(what: &str, s: &str) -> PyResult<T> {
    serde_json::from_str(s).map_err(|e| usage(format!("not a {what}: {e}")))
}

/// The model of `params` (a TOML file, as `--params`; `None`: the paper's) and `impact`.
fn model(params: Option<PathBuf>, impact: &str) -> PyResult<(Params, ImpactLaw)> {
    let p = ParamsArgs { params }.params().map_err(usage)?;
    let i: ImpactLaw = impact
        .parse()
        .map_err(|e: String| usage(format!("invalid `--impact` = {impact:?}: {e}")))?;
    // The run's law is the one given: the parameters carry it too (the controller's model).
    Ok((p.with_impact(i), i))
}

/// The flags of `tilting simulate` that say what to run.
#[derive(Debug, Parser)]
#[command(
    name = "simulate",
    disable_help_flag = true,
    disable_version_flag = true
)]
struct SimulateCli {
    #[command(flatten)]
    run: tilting_sim::flags::SimulateArgs,
}

/// The first line of a clap error, without its `error: ` prefix.
fn clap_message(e: &clap::Error) -> String {
    let text = e.to_string();
    let text = text.strip_prefix("error: ").unwrap_or(&text);
    text.split("\n\n").next().unwrap_or(text).trim().to_string()
}

/// Runs `tilting simulate` with the flags `argv` (`--name=value`). Returns a dict: `json` (the
/// report `--json` prints), `t` (s), `x` (n x 4: alpha, beta in rad, their rates in rad/s),
/// `mode` (0 flat, 1 left, 2 right) and `torque` (N m) of the recorded trajectory.
#[pyfunction]
fn simulate<'py>(py: Python<'py>, argv: Vec<String>) -> PyResult<Bound<'py, PyDict>> {
    let argv = std::iter::once("simulate".to_string()).chain(argv);
    let cli = SimulateCli::try_parse_from(argv).map_err(|e| usage(clap_message(&e)))?;
    let (sc, opts) = cli.run.prepare(true).map_err(usage)?;
    let (report, tau) = py
        .detach(|| {
            let law = sc.controller()?;
            let r = tilting_sim::simulate(&sc, opts)?;
            let tau: Vec<f64> = r
                .samples
                .iter()
                .map(|s| law.torque(s.t, s.mode, &s.x.into()))
                .collect();
            Ok::<_, tilting_sim::ScenarioError>((r, tau))
        })
        .map_err(usage)?;
    let d = PyDict::new(py);
    d.set_item("json", to_json(&report)?)?;
    let s = &report.samples;
    d.set_item(
        "t",
        s.iter().map(|s| s.t).collect::<Vec<_>>().into_pyarray(py),
    )?;
    let x: Vec<Vec<f64>> = s.iter().map(|s| s.x.to_vec()).collect();
    d.set_item("x", PyArray2::from_vec2(py, &x).map_err(failed)?)?;
    let mode: Vec<u8> = s.iter().map(|s| s.mode as u8).collect();
    d.set_item("mode", mode.into_pyarray(py))?;
    d.set_item("torque", tau.into_pyarray(py))?;
    Ok(d)
}

/// Reads an MCAP recording (or a live run's directory): a dict with `t` (s), `x` (n x 4),
/// `mode`, `torque` (N m, NaN where no torque was answered), `events` (JSON text), `robot`.
#[pyfunction]
fn read_mcap<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let rec = py
        .detach(|| tilting_planner::identify::load::load(&path, None))
        .map_err(usage)?;
    let s = &rec.trace.samples;
    let d = PyDict::new(py);
    d.set_item(
        "t",
        s.iter().map(|s| s.t).collect::<Vec<_>>().into_pyarray(py),
    )?;
    let x: Vec<Vec<f64>> = s.iter().map(|s| s.x.to_vec()).collect();
    d.set_item("x", PyArray2::from_vec2(py, &x).map_err(failed)?)?;
    let mode: Vec<u8> = s.iter().map(|s| s.mode as u8).collect();
    d.set_item("mode", mode.into_pyarray(py))?;
    let tau: Vec<f64> = rec.tau.iter().map(|t| t.unwrap_or(f64::NAN)).collect();
    d.set_item("torque", tau.into_pyarray(py))?;
    d.set_item("events", to_json(&rec.trace.events)?)?;
    d.set_item("end", rec.trace.end)?;
    d.set_item("stopped_early", rec.trace.stopped_early)?;
    d.set_item("robot", rec.robot)?;
    d.set_item("source", rec.source)?;
    Ok(d)
}

/// `tilting plan orbit`: the report's JSON.
#[pyfunction]
#[pyo3(signature = (kp, kd, k, energy_avg, impact, params))]
fn orbit(
    py: Python<'_>,
    kp: f64,
    kd: f64,
    k: f64,
    energy_avg: Option<f64>,
    impact: &str,
    params: Option<PathBuf>,
) -> PyResult<String> {
    let (p, i) = model(params, impact)?;
    let r = py.detach(|| jobs::orbits(p, i, kp, kd, k, energy_avg));
    to_json(&r.map_err(job_err)?)
}

/// `tilting plan sinusoid`: the solution's JSON.
#[pyfunction]
#[pyo3(signature = (amplitude, landing_offset, omega_min, omega_max, impact, params))]
fn sinusoid(
    py: Python<'_>,
    amplitude: f64,
    landing_offset: f64,
    omega_min: f64,
    omega_max: f64,
    impact: &str,
    params: Option<PathBuf>,
) -> PyResult<String> {
    let (p, _) = model(params, impact)?;
    let r = py.detach(|| jobs::sinusoid(&p, amplitude, landing_offset, omega_min, omega_max));
    to_json(&r.map_err(job_err)?)
}

/// The checked job of `tilting plan bifurcation` (its JSON: the grid of its shards).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (k_from, k_to, k_step, tilts, keep, kp, kd, period_tol, impact, params))]
fn bifurcation_job(
    k_from: f64,
    k_to: f64,
    k_step: f64,
    tilts: usize,
    keep: usize,
    kp: f64,
    kd: f64,
    period_tol: f64,
    impact: &str,
    params: Option<PathBuf>,
) -> PyResult<String> {
    let (p, i) = model(params, impact)?;
    let r = BifurcationRange {
        k_from,
        k_to,
        k_step,
        tilts,
        keep,
        kp,
        kd,
        period_tol,
    };
    to_json(&BifurcationJob::new(p, i, &r).map_err(job_err)?)
}

/// Runs one shard `index/count` of a sweep (`kind`: `bifurcation`, `gains` or `margins`)
/// described by `job` (JSON): the shard's JSON. `count = 1` is the whole sweep's shard.
#[pyfunction]
fn run_shard(
    py: Python<'_>,
    kind: &str,
    job: &str,
    index: usize,
    count: usize,
) -> PyResult<String> {
    let shard = Shard::new(index, count).map_err(usage)?;
    let part = match kind {
        "bifurcation" => {
            let j: BifurcationJob = from_json("bifurcation job", job)?;
            to_value(&py.detach(|| j.run_shard(shard)).map_err(job_err)?)
        }
        "gains" => {
            let j: GainsJob = from_json("gains job", job)?;
            to_value(&py.detach(|| j.run_shard(shard)))
        }
        "margins" => {
            let j: Survey = from_json("margins survey", job)?;
            to_value(&py.detach(|| j.run_shard(shard, &|| {})).map_err(failed)?)
        }
        other => Err(usage(format!("no sweep {other:?}"))),
    }?;
    let grid: serde_json::Value = from_json("job", job)?;
    to_json(&serde_json::json!({ "grid": grid, "part": part }))
}

fn to_value<T: serde::Serialize>(v: &T) -> PyResult<serde_json::Value> {
    serde_json::to_value(v).map_err(failed)
}

/// The parts of shards (`{"grid", "part"}`) of the sweep `job`, each checked to be of its
/// grid (the message names the first field that differs).
fn parts<T: serde::de::DeserializeOwned>(job: &str, shards: &[String]) -> PyResult<Vec<T>> {
    let grid: serde_json::Value = from_json("job", job)?;
    shards
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let v: serde_json::Value = from_json("shard", s)?;
            let g = v.get("grid").ok_or_else(|| usage("not a shard: no grid"))?;
            if let Some(field) = tilting_planner::shard::first_difference(&grid, g) {
                return Err(usage(format!(
                    "shard {i} of those given is of a different grid (`{field}` differs): \
                     merge only the shards of one sweep"
                )));
            }
            let part = v.get("part").cloned().unwrap_or_default();
            serde_json::from_value(part).map_err(|e| usage(format!("not a shard: {e}")))
        })
        .collect()
}

/// Runs a whole sweep (`kind` as [`run_shard`]) on all cores: the report's JSON, as the CLI's
/// `--json` prints it.
#[pyfunction]
fn run_whole(py: Python<'_>, kind: &str, job: &str) -> PyResult<String> {
    match kind {
        "bifurcation" => {
            let j: BifurcationJob = from_json("bifurcation job", job)?;
            to_json(&py.detach(|| j.run(&|| {})).map_err(job_err)?)
        }
        "gains" => {
            let j: GainsJob = from_json("gains job", job)?;
            to_json(&py.detach(|| j.run(&|| {})))
        }
        "margins" => {
            let j: Survey = from_json("margins survey", job)?;
            to_json(&py.detach(|| j.run(&|| {})).map_err(failed)?)
        }
        other => Err(usage(format!("no sweep {other:?}"))),
    }
}

/// Merges the shards (JSON, any order) of a sweep into its report's JSON; refused unless they
/// make the whole sweep.
#[pyfunction]
fn merge(kind: &str, job: &str, shards: Vec<String>) -> PyResult<String> {
    match kind {
        "bifurcation" => {
            let j: BifurcationJob = from_json("bifurcation job", job)?;
            to_json(&j.merge(parts(job, &shards)?).map_err(usage)?)
        }
        "gains" => {
            let j: GainsJob = from_json("gains job", job)?;
            to_json(&j.merge(parts(job, &shards)?).map_err(usage)?)
        }
        "margins" => {
            let j: Survey = from_json("margins survey", job)?;
            let p: Vec<SurveyShard> = parts(job, &shards)?;
            to_json(&j.merge(p).map_err(usage)?)
        }
        other => Err(usage(format!("no sweep {other:?}"))),
    }
}

/// The checked job of `tilting plan gains` (`[from, to, step]` of K_P and of K_D).
#[pyfunction]
fn gains_job(
    kp: [f64; 3],
    kd: [f64; 3],
    impact: &str,
    params: Option<PathBuf>,
) -> PyResult<String> {
    let (p, i) = model(params, impact)?;
    to_json(&GainsJob::new(p, i, kp, kd).map_err(job_err)?)
}

/// The checked survey of `tilting plan margins` (its JSON).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[pyo3(signature = (delays, losses, rate, rates, angle_noises, rate_noises, mass_errors, seed, tilts, watchdog, tolerance))]
fn margins_survey(
    delays: Vec<f64>,
    losses: Vec<f64>,
    rate: f64,
    rates: Vec<f64>,
    angle_noises: Vec<f64>,
    rate_noises: Vec<f64>,
    mass_errors: Vec<f64>,
    seed: u64,
    tilts: u64,
    watchdog: u64,
    tolerance: f64,
) -> PyResult<String> {
    let s = Survey {
        delays,
        losses,
        rate,
        rates,
        angle_noises,
        rate_noises,
        mass_errors,
        seed,
        criteria: Criteria {
            tilts,
            watchdog,
            tolerance,
        },
        // The robot rows (parameter bands, friction, estimators) are the CLI's only.
        bands: Bands::default(),
        // The paper's loop (another robot's is the CLI's `--params` and `--plan`).
        base: None,
    };
    s.check().map_err(usage)?;
    to_json(&s)
}

/// The nominal peak of the criteria (rad), computed once per process and criteria.
fn nominal(c: &Criteria) -> PyResult<f64> {
    use std::sync::Mutex;
    static CACHE: Mutex<Vec<(Criteria, f64)>> = Mutex::new(Vec::new());
    if let Some(&(_, n)) = CACHE.lock().unwrap().iter().find(|(k, _)| k == c) {
        return Ok(n);
    }
    let n = margins::nominal_peak(&tilting_sim::Scenario::default(), c);
    if n <= 0.0 {
        return Err(failed(margins::SurveyError::NoNominalOrbit(c.tilts)));
    }
    CACHE.lock().unwrap().push((*c, n));
    Ok(n)
}

/// Monte-Carlo points (the columns of equal length: delay s, loss, angle noise rad, rate
/// noise rad/s, mass error, rate Hz, predict, seed) on `threads` cores (0: all): the columns
/// survived, tilts, last_peak (rad), why.
#[pyfunction]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
#[pyo3(signature = (delay, loss, angle_noise, rate_noise, mass_error, rate, predict, seed, tilts, watchdog, tolerance, threads))]
fn margins_points(
    py: Python<'_>,
    delay: Vec<f64>,
    loss: Vec<f64>,
    angle_noise: Vec<f64>,
    rate_noise: Vec<f64>,
    mass_error: Vec<f64>,
    rate: Vec<f64>,
    predict: Vec<bool>,
    seed: Vec<u64>,
    tilts: u64,
    watchdog: u64,
    tolerance: f64,
    threads: usize,
) -> PyResult<(Vec<bool>, Vec<u64>, Vec<f64>, Vec<String>)> {
    use rayon::prelude::*;
    let n = delay.len();
    let cols = [
        loss.len(),
        angle_noise.len(),
        rate_noise.len(),
        mass_error.len(),
        rate.len(),
        predict.len(),
        seed.len(),
    ];
    if cols.iter().any(|&l| l != n) {
        return Err(usage(format!(
            "the point columns differ in length: {n} delays and {cols:?}"
        )));
    }
    let c = Criteria {
        tilts,
        watchdog,
        tolerance,
    };
    let probe = Survey {
        delays: vec![0.0],
        losses: vec![0.0],
        rate: 1000.0,
        rates: vec![1000.0],
        angle_noises: vec![0.0],
        rate_noises: vec![0.0],
        mass_errors: vec![0.0],
        seed: 0,
        criteria: c,
        bands: Bands::default(),
        base: None,
    };
    probe.check().map_err(usage)?;
    let samples: Vec<Sample> = (0..n)
        .map(|i| Sample {
            delay: delay[i],
            loss: loss[i],
            angle_noise: angle_noise[i],
            rate_noise: rate_noise[i],
            mass_error: mass_error[i],
            rate: rate[i],
            predict: predict[i],
            seed: seed[i],
        })
        .collect();
    if let Some(e) = samples.iter().find_map(|s| s.check().err()) {
        return Err(usage(e));
    }
    let nominal = py.detach(|| nominal(&c))?;
    let results = py.detach(|| {
        let sc = tilting_sim::Scenario::default();
        let work = || -> Vec<_> {
            samples
                .par_iter()
                .map(|s| s.run(&sc, &c, nominal))
                .collect()
        };
        if threads == 0 {
            Ok(work())
        } else {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map(|p| p.install(work))
        }
    });
    let results = results.map_err(failed)?;
    let mut out = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for r in results {
        out.0.push(r.survived);
        out.1.push(r.tilts);
        out.2.push(r.last_peak);
        out.3.push(r.why);
    }
    Ok(out)
}

/// The Rust core of the `tilting` package.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("UsageError", m.py().get_type::<UsageError>())?;
    m.add("RunError", m.py().get_type::<RunError>())?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(read_mcap, m)?)?;
    m.add_function(wrap_pyfunction!(orbit, m)?)?;
    m.add_function(wrap_pyfunction!(sinusoid, m)?)?;
    m.add_function(wrap_pyfunction!(bifurcation_job, m)?)?;
    m.add_function(wrap_pyfunction!(gains_job, m)?)?;
    m.add_function(wrap_pyfunction!(margins_survey, m)?)?;
    m.add_function(wrap_pyfunction!(margins_points, m)?)?;
    m.add_function(wrap_pyfunction!(run_shard, m)?)?;
    m.add_function(wrap_pyfunction!(run_whole, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    Ok(())
}
