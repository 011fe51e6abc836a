//! A sampled offline run kept whole, as a recording holds a live one: every state the
//! controller read, the torque it answered, every mode transition ([`run_logged`]); written
//! as an MCAP recording with the channels `live` writes for them ([`write_mcap`]), so an
//! offline run can be identified (`tilting identify`) or drawn like a real one.

use crate::{Scenario, ScenarioError, SimOptions, SimulationReport};
use std::cell::RefCell;
use std::path::Path;
use tilting_plant::dynamics::Terms;
use tilting_plant::{Fault, Mode, Params, State, TorqueLaw};
use tilting_proto::{encode, Keys, ModeEvent, PlantState, TorqueCommand};
use tilting_record::{EventRecord, McapWriter, Sample, Topic, Trace};

/// A sampled run kept whole.
#[derive(Debug, Clone)]
pub struct Logged {
    /// Every state the controller read (`samples[k]` at `t_k = k T`), and every transition.
    pub trace: Trace,
    /// The torque (N m) answered to `samples[k]`, held over `[t_k, t_{k+1}]`.
    pub tau: Vec<f64>,
    /// How the run ended.
    pub fault: Option<Fault>,
}

/// Logs every sample the loop takes and the torque it answers.
struct Logging<'a, L> {
    law: &'a L,
    log: RefCell<(Vec<Sample>, Vec<f64>)>,
}

impl<L: TorqueLaw> TorqueLaw for Logging<'_, L> {
    fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        let tau = self.law.torque(t, mode, x);
        self.push(t, mode, x, tau)
    }
    fn torque_t(&self, t: f64, mode: Mode, x: &State, p: &Params, tm: &Terms) -> f64 {
        let tau = self.law.torque_t(t, mode, x, p, tm);
        self.push(t, mode, x, tau)
    }
}

impl<L> Logging<'_, L> {
    fn push(&self, t: f64, mode: Mode, x: &State, tau: f64) -> f64 {
        let mut l = self.log.borrow_mut();
        l.0.push(Sample {
            t,
            mode,
            x: (*x).into(),
        });
        l.1.push(tau);
        tau
    }
}

/// Runs the scenario as [`crate::simulate_with_progress`] does, keeping every state the
/// plant measured for the controller (with the robot's sensor noise and encoder, the rates
/// NaN with `--measure angles`, as a plant publishes it; not the estimate the law reads) and
/// every torque it answered: the report and the recording of one run.
///
/// Refused (naming the flag): a continuous scenario (`control_period` = 0: there are no
/// samples to keep), and a run over impaired links or with prediction or sampling on events
/// (a torque then answers another state than the one it is held after, or a predicted state:
/// record those runs with `live`).
pub fn simulate_logged(
    sc: &Scenario,
    opts: SimOptions,
    progress: &mut dyn FnMut(f64),
) -> Result<(SimulationReport, Logged), ScenarioError> {
    sc.validate()?;
    let refuse = |field: &str, flag: &str, value: String, allowed: &str| {
        Err(ScenarioError::OutOfRange {
            field: field.into(),
            flag: flag.into(),
            value,
            allowed: allowed.into(),
        })
    };
    if !sc.is_sampled() {
        return refuse(
            "control_period",
            "--control-period",
            sc.control_period.to_string(),
            "> 0 to record a run: a recording holds the controller's samples",
        );
    }
    if opts.network.is_some_and(|n| !n.is_perfect()) {
        return refuse(
            "network",
            "--delay/--jitter/--loss",
            "an impaired network".into(),
            "a perfect link to record a run offline (each torque held after the state it \
             answers); record a run over a network with `tilting live`",
        );
    }
    if !opts.loop_options.is_plain() {
        return refuse(
            "loop_options",
            "--predict/--sample-on-event",
            "given".into(),
            "neither, to record a run offline (the controller answers predicted or extra \
             states)",
        );
    }
    let ctrl = sc.controller()?;
    let law = Logging {
        law: &ctrl,
        log: RefCell::new((Vec::new(), Vec::new())),
    };
    let opts = SimOptions {
        log_measurements: true,
        ..opts
    };
    let mut report = crate::closed_loop::simulate_law(sc, opts, &law, progress)?;
    report.excitation = ctrl.excitation_status();
    let (read, tau) = law.log.into_inner();
    // The state a recording holds is the one the plant publishes: what its sensors measured
    // (noise, encoder, absent rates), not what the controller's estimator made of it (the
    // law reads the estimate). Without hardware the law reads the measured (exact) state.
    let measured = std::mem::take(&mut report.measured);
    let samples = if measured.is_empty() {
        read
    } else {
        assert_eq!(
            measured.len(),
            read.len(),
            "one measurement per answered sample"
        );
        measured
    };
    let logged = Logged {
        trace: Trace {
            samples,
            events: report.events.clone(),
            end: report.final_state.t,
            stopped_early: report.fault.is_some(),
        },
        tau,
        fault: report.fault.clone(),
    };
    Ok((report, logged))
}

/// Runs the scenario's sampled loop over a perfect link and a perfect robot, keeping every
/// sample and torque ([`simulate_logged`] with the default options).
pub fn run_logged(sc: &Scenario) -> Result<Logged, ScenarioError> {
    simulate_logged(sc, SimOptions::default(), &mut |_| {}).map(|(_, l)| l)
}

/// Writes `run` as an MCAP recording of the robot `robot`: a `PlantState` (seq `k`) and its
/// `TorqueCommand` per sample, a `ModeEvent` per transition, in time order.
pub fn write_mcap(path: &Path, robot: &str, run: &Logged) -> Result<(), String> {
    let keys = Keys::new(robot).map_err(|e| e.to_string())?;
    let mut rec = McapWriter::create(path, &keys).map_err(|e| e.to_string())?;
    let mut events = run.trace.events.iter().peekable();
    let mut seq_ev = 0u64;
    for (k, (s, &tau)) in run.trace.samples.iter().zip(&run.tau).enumerate() {
        while let Some(e) = events.next_if(|e| e.t <= s.t) {
            rec.record(Topic::Event, &encode(&event(seq_ev, e)))
                .map_err(|e| e.to_string())?;
            seq_ev += 1;
        }
        let [alpha, beta, alpha_dot, beta_dot] = s.x;
        let st = PlantState {
            seq: k as u64,
            time: s.t,
            alpha,
            beta,
            // A trace marks a rate that was not measured as NaN.
            alpha_dot: Some(alpha_dot).filter(|v| !v.is_nan()),
            beta_dot: Some(beta_dot).filter(|v| !v.is_nan()),
            mode: s.mode.as_u8(),
        };
        rec.record(Topic::State, &encode(&st))
            .map_err(|e| e.to_string())?;
        let cmd = TorqueCommand { seq: k as u64, tau };
        rec.record(Topic::Torque, &encode(&cmd))
            .map_err(|e| e.to_string())?;
    }
    for e in events {
        rec.record(Topic::Event, &encode(&event(seq_ev, e)))
            .map_err(|e| e.to_string())?;
        seq_ev += 1;
    }
    rec.finish().map_err(|e| e.to_string())
}

fn event(seq: u64, e: &EventRecord) -> ModeEvent {
    ModeEvent {
        seq,
        time: e.t,
        from: e.from.as_u8(),
        to: e.to.as_u8(),
        x_before: e.x_before,
        x_after: e.x_after,
    }
}
