//! The closed loop of the hybrid plant and the computed-torque controller: the two couplings,
//! and [`simulate`], which runs one [`Scenario`] and reports the mode transitions, the tilt
//! peaks, the final state and any fault.
//!
//! Two couplings:
//! - continuous (`control_period = 0`): the torque law is evaluated inside the right-hand side
//!   ([`Plant::advance_continuous`]), the paper's setting;
//! - sampled (`control_period = T > 0`): the controller runs at `t_k = k T` on the state at that
//!   instant and its torque is held until `t_{k+1}` ([`Plant::advance_held`]), as over a network.

use crate::network::{run_sampled_over, Impairment, LoopOptions, NetStats, Predict};
use crate::scenario::{Scenario, ScenarioError};
use serde::{Deserialize, Serialize};
use std::time::Instant;
use tilting_plant::imperfect::{Actuator, Imperfections};
use tilting_plant::sampled::{self, Grid, Transport};
use tilting_plant::{Fault, Mode, Observer, Plant, State, TiltPeak, TorqueLaw, Transition};
/// The trajectory types are the recordings' ([`tilting_record::trace`]): a simulated run and a
/// recorded one are drawn alike.
pub use tilting_record::{EventRecord, Sample, Trace};

/// The plant's default `--max-age` (periods), used for a loop with prediction or sampling on
/// events over a perfect network.
pub const DEFAULT_MAX_AGE: u64 = 10;

/// Options of [`simulate`]: how it reports, and the network and loop options.
#[derive(Debug, Clone, Copy, Default)]
pub struct SimOptions {
    /// Record the trajectory (decimated) for plotting.
    pub record_samples: bool,
    /// Run the sampled loop over these impaired links ([`crate::network`]); needs a control
    /// period.
    pub network: Option<Impairment>,
    /// Prediction and sampling on events ([`crate::network`]); need a control period.
    pub loop_options: LoopOptions,
    /// The robot's imperfections ([`tilting_plant::imperfect`]): sensor noise, encoder,
    /// actuator saturation and lag (these need a control period) and the arm-mass error of the
    /// plant against the controller's model.
    pub imperfect: Option<Imperfections>,
    /// Keep what the sensors gave the controller at each sample
    /// ([`SimulationReport::measured`]; a run with hardware imperfections only).
    pub log_measurements: bool,
}

/// The extreme tilt angle of one tilt: every completed tilt, and the last tilt of the run if
/// it reached its peak before the end.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeakRecord {
    /// Time of the extreme (s).
    pub t: f64,
    /// The tilt (`left` or `right`).
    pub mode: Mode,
    /// The extreme `alpha` (rad).
    pub alpha: f64,
}

/// The hybrid state at the end of the run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FinalRecord {
    /// Time (s): the duration, or the time of the fault.
    pub t: f64,
    /// Mode.
    pub mode: Mode,
    /// State `(alpha, beta, alpha_dot, beta_dot)`.
    pub x: [f64; 4],
}

/// How the controller is coupled to the plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Coupling {
    /// The torque law inside the right-hand side (`control_period = 0`).
    Continuous,
    /// A zero-order hold every `control_period`.
    Sampled,
}

/// Work counters and settings of the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunStats {
    /// `continuous` or `sampled`.
    pub coupling: Coupling,
    /// Zero-order-hold period (s); 0 for continuous.
    pub control_period: f64,
    /// Requested simulated time (s).
    pub duration: f64,
    /// Right-hand-side evaluations counted by the integrator.
    pub rhs_evals: u64,
    /// Accepted steps.
    pub steps: u64,
    /// Rejected step attempts.
    pub rejected_steps: u64,
    /// Dense outputs built (one per step that contains an event).
    pub dense_outputs: u64,
    /// Mode transitions.
    pub transitions: u64,
    /// Completed tilts (landings).
    pub tilts: u64,
    /// Controller evaluations of the sampled coupling (0 for continuous).
    pub controller_samples: u64,
    /// Wall-clock time of the simulation (s), without output and plotting.
    pub wall_time_s: f64,
}

/// The result of [`simulate`]; serialises to the JSON of `simulate --json`, and reads back
/// from it (the fault then as [`Fault::Reported`], without the trajectory).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SimulationReport {
    /// Mode transitions in time order.
    pub events: Vec<EventRecord>,
    /// Extreme angle of each tilt, in time order: every completed tilt, then the tilt in
    /// progress at the end if its peak was reached before the end.
    pub tilt_peaks: Vec<PeakRecord>,
    /// Hybrid state at the end.
    #[serde(rename = "final")]
    pub final_state: FinalRecord,
    /// The fault that ended the run early, if any (its message text in JSON).
    pub fault: Option<Fault>,
    /// Work counters.
    pub stats: RunStats,
    /// What the network did, for a run over impaired links (or with prediction or sampling on
    /// events).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub network: Option<NetStats>,
    /// Prediction and sampling on events, if asked for.
    #[serde(default, skip_serializing_if = "LoopOptions::is_plain")]
    pub loop_options: LoopOptions,
    /// The robot's imperfections, for a run with any.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imperfections: Option<Imperfections>,
    /// What the excitation's amplitude governor found (`tilting_controller::excite`), for a
    /// run on the excitation: the amplitude's scale and the arm's estimated gravity torque.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub excitation: Option<tilting_controller::excite::GovernorStatus>,
    /// The trajectory, if recorded (not serialised).
    #[serde(skip)]
    pub samples: Vec<Sample>,
    /// What the sensors gave the controller at each sample, if kept
    /// ([`SimOptions::log_measurements`]; absent rates as NaN; not serialised).
    #[serde(skip)]
    pub measured: Vec<Sample>,
}

impl SimulationReport {
    /// The run's trajectory (a copy of the samples and the events), for plots and animations.
    pub fn trace(&self) -> Trace {
        Trace {
            samples: self.samples.clone(),
            events: self.events.clone(),
            end: self.final_state.t,
            // A loop that ended in safe mode ran to its end.
            stopped_early: self
                .fault
                .as_ref()
                .is_some_and(|f| !matches!(f, Fault::SafeMode { .. })),
        }
    }
}

/// Collects events, peaks and (optionally) a decimated trajectory.
struct Collector {
    events: Vec<EventRecord>,
    peaks: Vec<PeakRecord>,
    samples: Option<Vec<Sample>>,
    /// What the sensors measured at each sample, if kept (absent rates as NaN).
    measured: Option<Vec<Sample>>,
    /// Smallest spacing of recorded samples between events (s).
    min_dt: f64,
}

impl Collector {
    fn push(&mut self, t: f64, mode: Mode, x: &State, force: bool) {
        if let Some(s) = &mut self.samples {
            if force || s.last().is_none_or(|l| t - l.t >= self.min_dt) {
                s.push(Sample {
                    t,
                    mode,
                    x: (*x).into(),
                });
            }
        }
    }
}

impl Observer for Collector {
    fn measured(&mut self, t: f64, mode: Mode, y: &tilting_plant::imperfect::Measurement) {
        if let Some(m) = &mut self.measured {
            let [ad, bd] = y.rates.unwrap_or([f64::NAN; 2]);
            m.push(Sample {
                t,
                mode,
                x: [y.angles[0], y.angles[1], ad, bd],
            });
        }
    }

    fn transition(&mut self, ev: &Transition) {
        self.events.push(EventRecord {
            t: ev.t,
            from: ev.from,
            to: ev.to,
            x_before: ev.x_before.into(),
            x_after: ev.x_after.into(),
        });
        self.push(ev.t, ev.from, &ev.x_before, true);
        self.push(ev.t, ev.to, &ev.x_after, true);
    }

    fn tilt_peak(&mut self, p: &TiltPeak) {
        self.peaks.push(PeakRecord {
            t: p.t,
            mode: p.mode,
            alpha: p.alpha,
        });
    }

    fn sample(&mut self, t: f64, mode: Mode, x: &State) {
        self.push(t, mode, x, false);
    }
}

/// The continuous run is cut into at most this many pieces (for the progress reports)...
const MAX_CHUNKS: f64 = 100.0;
/// ...of at least this length (s): each cut ends an integrator step early, so the pieces are
/// kept long. The cuts depend on the duration only, so the result does not depend on whether a
/// bar is shown.
const MIN_CHUNK: f64 = 1.0;

/// Samples recorded for a plot, about.
const PLOT_SAMPLES: f64 = 20_000.0;

/// The sampled closed loop over a perfect link, the code that a lockstep plant node reproduces
/// bit for bit: at `t_k = k T` the controller reads the plant's state, and its torque is held
/// over `[t_k, t_{k+1}]` ([`Plant::advance_held`]); the period grid and the cut of the last
/// period are [`tilting_plant::sampled`]'s. The plant must stand at `t = 0`. `progress` gets
/// the plant time about a thousand times per run.
///
/// Returns how the run ended and the number of controller evaluations.
pub fn run_sampled<L: TorqueLaw, O: Observer>(
    plant: &mut Plant,
    law: &L,
    period: f64,
    t_end: f64,
    obs: &mut O,
    progress: &mut dyn FnMut(f64),
) -> (Result<(), Fault>, u64) {
    let mut direct = Direct {
        plant,
        actuator: Actuator::new(&Imperfections::default()),
        obs,
        law,
    };
    let (r, n) = sampled::run(&mut direct, Grid { period, t_end }, progress);
    (r.map(|_| ()), n)
}

/// The perfect link: the law reads the plant's true state at the sample instant and its torque
/// acts at once, held by the perfect actuator.
struct Direct<'a, L, O> {
    plant: &'a mut Plant,
    actuator: Actuator,
    obs: &'a mut O,
    law: &'a L,
}

impl<L: TorqueLaw, O: Observer> Transport for Direct<'_, L, O> {
    type Observer = O;

    #[inline]
    fn parts(&mut self) -> (&mut Plant, &mut Actuator, &mut O) {
        (self.plant, &mut self.actuator, self.obs)
    }

    #[inline]
    fn sample(&mut self, _k: u64) -> Option<f64> {
        // law.torque(t_k, plant.mode(), &plant.state()), reusing the plant's terms.
        Some(self.plant.torque_now(self.law))
    }
}

/// The continuous closed loop, the paper's setting: `law` inside the right-hand side
/// ([`Plant::advance_continuous`]) up to `t_end` (s), in `pieces` equal calls (each cut ends an
/// integrator step early, so the result depends on `pieces`; `progress` gets the plant time
/// after each).
pub fn run_continuous<L: TorqueLaw, O: Observer>(
    plant: &mut Plant,
    law: &L,
    t_end: f64,
    pieces: u64,
    obs: &mut O,
    progress: &mut dyn FnMut(f64),
) -> Result<(), Fault> {
    let pieces = pieces.max(1);
    for j in 1..=pieces {
        let t_j = if j == pieces {
            t_end
        } else {
            t_end * j as f64 / pieces as f64
        };
        plant.advance_continuous(law, t_j, obs)?;
        progress(t_j);
    }
    Ok(())
}

/// The plant of the scenario: the controller's model, or the imperfect robot's
/// (`imperfect`: validated, its mass error applied).
fn plant_for(sc: &Scenario, imperfect: Option<&Imperfections>) -> Result<Plant, ScenarioError> {
    let mut cfg = sc.sim_config();
    if let Some(i) = imperfect {
        i.validate().map_err(|e| ScenarioError::OutOfRange {
            field: e.flag.trim_start_matches("--").replace('-', "_"),
            flag: e.flag.into(),
            value: e.value,
            allowed: e.allowed.into(),
        })?;
        cfg.params = i.plant_params(&cfg.params);
    }
    Plant::new(cfg, 0.0, sc.mode, sc.initial_state()).map_err(|e| ScenarioError::File {
        path: "initial state".into(),
        message: e.to_string(),
    })
}

/// Runs the scenario. Fails only on an invalid scenario; a fault of the plant (contact loss,
/// fall, Zeno, integrator failure) ends the run and is reported in the result.
pub fn simulate(sc: &Scenario, opts: SimOptions) -> Result<SimulationReport, ScenarioError> {
    simulate_with_progress(sc, opts, &mut |_| {})
}

/// [`simulate`], reporting progress: `progress` gets the simulated time reached (s, up to the
/// scenario's duration) about a thousand times per sampled run, and after each of the at most
/// 100 pieces of a continuous one. The library draws nothing: a front door draws a bar from it.
pub fn simulate_with_progress(
    sc: &Scenario,
    opts: SimOptions,
    progress: &mut dyn FnMut(f64),
) -> Result<SimulationReport, ScenarioError> {
    sc.validate()?;
    let ctrl = sc.controller()?;
    let mut report = simulate_law(sc, opts, &ctrl, progress)?;
    report.excitation = ctrl.excitation_status();
    Ok(report)
}

/// [`simulate`] with the law `law` in place of the scenario's (any [`TorqueLaw`] without
/// memory or, called once per sample in time order, with it; a planner's
/// `tilting_controller::PlannableLaw`): the same checks, couplings and report; the scenario's
/// `law` settings are not used. Fails only on an invalid scenario.
pub fn simulate_with<L: TorqueLaw>(
    sc: &Scenario,
    opts: SimOptions,
    law: &L,
) -> Result<SimulationReport, ScenarioError> {
    sc.validate()?;
    simulate_law(sc, opts, law, &mut |_| {})
}

/// [`simulate_with_progress`] with the scenario's controller `ctrl` given (wrapped by
/// [`crate::recording`] to keep every sample it reads and every torque it answers): the run's
/// refusals ([`couplings`]), its coupling ([`run_coupled`]) and the report ([`report`]).
pub(crate) fn simulate_law<L: TorqueLaw>(
    sc: &Scenario,
    opts: SimOptions,
    ctrl: &L,
    progress: &mut dyn FnMut(f64),
) -> Result<SimulationReport, ScenarioError> {
    let imperfect = opts.imperfect.filter(|i| !i.is_perfect());
    let mut plant = plant_for(sc, imperfect.as_ref())?;
    let mut rec = Collector {
        events: Vec::new(),
        peaks: Vec::new(),
        samples: opts.record_samples.then(Vec::new),
        measured: opts.log_measurements.then(Vec::new),
        min_dt: sc.duration / PLOT_SAMPLES,
    };
    rec.push(0.0, plant.mode(), &plant.state(), true);
    let start = Instant::now();
    let (network, hardware) = couplings(sc, &opts, imperfect)?;
    let run = run_coupled(
        &mut plant,
        ctrl,
        sc,
        &opts,
        Coupled {
            network,
            hardware,
            imperfect,
        },
        &mut rec,
        progress,
    );
    let wall = start.elapsed().as_secs_f64();
    Ok(report(sc, &opts, imperfect, &plant, rec, run, wall))
}

/// A control period (`> 0`) that a run needs, or the error saying why (`allowed`).
fn needs_period(sc: &Scenario, allowed: &str) -> Result<(), ScenarioError> {
    if sc.is_sampled() {
        return Ok(());
    }
    Err(ScenarioError::OutOfRange {
        field: "control_period".into(),
        flag: "--control-period".into(),
        value: sc.control_period.to_string(),
        allowed: allowed.into(),
    })
}

/// The network (`None`: the controller's torque reaches the plant at once) and the hardware
/// imperfections (`None`: perfect sensors and actuator) a run of `sc` couples through, after
/// the refusals: a loop option, an impaired network or hardware imperfections without a control
/// period, a prediction older than the plant's `max_age`, or sampling on events with an
/// actuator's saturation or lag. A loop option without a network runs over a perfect one that
/// drops samples older than [`DEFAULT_MAX_AGE`] periods.
fn couplings(
    sc: &Scenario,
    opts: &SimOptions,
    imperfect: Option<Imperfections>,
) -> Result<(Option<Impairment>, Option<Imperfections>), ScenarioError> {
    let network = opts.network.filter(|n| !n.is_perfect());
    let plain = opts.loop_options.is_plain();
    if !plain {
        needs_period(
            sc,
            "> 0 for --predict, --sample-on-event or --estimator: they act on a sampled loop",
        )?;
    }
    let network = match network {
        None if !plain => Some(opts.network.unwrap_or(Impairment {
            max_age: DEFAULT_MAX_AGE,
            ..Impairment::default()
        })),
        n => n,
    };
    if let (Some(n), Some(Predict::Given(d))) = (&network, opts.loop_options.predict) {
        crate::network::check_max_age(d, sc.control_period, n.max_age)?;
    }
    if network.is_some() {
        needs_period(
            sc,
            "> 0 for a run over an impaired network (--delay, --jitter, --loss, --loss-burst): \
             the network carries samples",
        )?;
    }
    let hardware = imperfect.filter(Imperfections::has_hardware);
    if hardware.is_some() {
        needs_period(
            sc,
            "> 0 for a robot with sensor noise, an encoder, angles only or an actuator's \
             saturation or lag (--noise-*, --encoder-counts, --measure angles, \
             --torque-saturation, --torque-lag): the controller samples the sensors",
        )?;
    }
    let actuator = hardware.is_some_and(|h| h.torque_saturation.is_some() || h.torque_lag > 0.0);
    if opts.loop_options.sample_on_event && actuator {
        return Err(ScenarioError::OutOfRange {
            field: "sample_on_event".into(),
            flag: "--sample-on-event".into(),
            value: "true".into(),
            allowed: "without --torque-saturation and --torque-lag (not combined yet)".into(),
        });
    }
    Ok((network, hardware))
}

/// What a run couples the plant and the controller through (from [`couplings`]), and the
/// robot's imperfections (for the hardware at the loop's ends).
struct Coupled {
    network: Option<Impairment>,
    hardware: Option<Imperfections>,
    imperfect: Option<Imperfections>,
}

/// How a run went: its end (a fault, or safe mode), the controller's samples, and the network's
/// statistics (a run over a network, or one whose watchdog tripped).
struct Run {
    result: Result<(), Fault>,
    controller_samples: u64,
    net_stats: Option<NetStats>,
}

/// Runs `plant` under `ctrl` to the scenario's duration (s) through the coupling `c`: the
/// sampled loop over the network and hardware if there are any (a run that ends in safe mode
/// ends in [`Fault::SafeMode`], as the plant would say), else the plain sampled loop, else the
/// continuous coupling in at most [`MAX_CHUNKS`] pieces.
fn run_coupled<L: TorqueLaw>(
    plant: &mut Plant,
    ctrl: &L,
    sc: &Scenario,
    opts: &SimOptions,
    c: Coupled,
    rec: &mut Collector,
    progress: &mut dyn FnMut(f64),
) -> Run {
    let t_end = sc.duration;
    if c.network.is_some() || c.hardware.is_some() {
        // The perfect link (no --delay ...) hands each torque over at once: the plain sampled
        // loop, with the hardware at its ends.
        let perfect = Impairment::default();
        let (r, n, st) = run_sampled_over(
            plant,
            ctrl,
            sc.control_period,
            t_end,
            c.network.as_ref().unwrap_or(&perfect),
            &LoopOptions {
                model: Some(sc.sim_config()),
                ..opts.loop_options
            },
            &mut c.imperfect.unwrap_or_default().hardware(),
            rec,
            progress,
        );
        // The run ended in safe mode: say so, as the plant would (it holds the arm).
        let r = match (
            r,
            st.safe_mode.and_then(|s| s.since),
            opts.loop_options.safe,
        ) {
            (Ok(()), Some(t), Some(safe)) => Err(Fault::SafeMode {
                t,
                watchdog: safe.watchdog,
            }),
            (r, _, _) => r,
        };
        let net_stats =
            (c.network.is_some() || st.safe_mode.is_some_and(|s| s.trips > 0)).then_some(st);
        Run {
            result: r,
            controller_samples: n,
            net_stats,
        }
    } else if sc.is_sampled() {
        let (result, controller_samples) =
            run_sampled(plant, ctrl, sc.control_period, t_end, rec, progress);
        Run {
            result,
            controller_samples,
            net_stats: None,
        }
    } else {
        let pieces = (t_end / MIN_CHUNK).ceil().clamp(1.0, MAX_CHUNKS) as u64;
        Run {
            result: run_continuous(plant, ctrl, t_end, pieces, rec, progress),
            controller_samples: 0,
            net_stats: None,
        }
    }
}

/// The report of a run of `sc` that has ended (`wall`: its wall-clock time, s): what `rec`
/// collected, with the peak of a last tilt that has not landed (yet, or ever: the run ended in
/// it, at its duration or by a fault), which is a peak of the run too, and the final state.
fn report(
    sc: &Scenario,
    opts: &SimOptions,
    imperfect: Option<Imperfections>,
    plant: &Plant,
    mut rec: Collector,
    run: Run,
    wall: f64,
) -> SimulationReport {
    if let Some(p) = plant.peak_in_progress() {
        rec.tilt_peak(&p);
    }
    rec.push(plant.time(), plant.mode(), &plant.state(), true);
    let st = plant.stats();
    SimulationReport {
        measured: rec.measured.unwrap_or_default(),
        events: rec.events,
        tilt_peaks: rec.peaks,
        final_state: FinalRecord {
            t: plant.time(),
            mode: plant.mode(),
            x: plant.state().into(),
        },
        fault: run.result.err(),
        network: run.net_stats,
        loop_options: opts.loop_options,
        imperfections: imperfect,
        stats: RunStats {
            coupling: if sc.is_sampled() {
                Coupling::Sampled
            } else {
                Coupling::Continuous
            },
            control_period: sc.control_period,
            duration: sc.duration,
            rhs_evals: st.evals,
            steps: st.steps,
            rejected_steps: st.rejected,
            dense_outputs: st.dense,
            transitions: plant.transitions(),
            tilts: plant.tilts(),
            controller_samples: run.controller_samples,
            wall_time_s: wall,
        },
        excitation: None,
        samples: rec.samples.unwrap_or_default(),
    }
}

/// The law that runs, in words, for the summaries of `simulate` and `live`: the gains, and the
/// energy adaptation (`k`, `E_av`) when the reference adapts; the excitation runs without it,
/// its torque clipped to `tilting_controller::excitation_torque_limit` of the model `params`.
pub fn law_line(law: &tilting_controller::LawSpec, params: &tilting_plant::Params) -> String {
    if law.reference.adapts() {
        format!(
            "K_P0 = {}, K_D = {}, k = {}{}",
            law.kp,
            law.kd,
            law.k,
            if law.k != 0.0 {
                format!(", E_av = {} J", law.energy_avg)
            } else {
                String::new()
            }
        )
    } else {
        format!(
            "{}, K_P = {}, K_D = {}, no energy adaptation, amplitude governed by the arm's \
             holding torque, torque clipped to {:.3} N m",
            law.reference,
            law.kp,
            law.kd,
            tilting_controller::excitation_torque_limit(params)
                .min(law.torque_limit.unwrap_or(f64::INFINITY))
        )
    }
}

/// The human-readable summary of a run.
pub fn summary(sc: &Scenario, r: &SimulationReport) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let coupling = if sc.is_sampled() {
        format!(
            "sampled coupling, zero-order hold every {} s",
            sc.control_period
        )
    } else {
        "continuous coupling".to_string()
    };
    let _ = writeln!(
        s,
        "simulated {} s of {} s ({coupling}; {}; {} impact law)",
        r.final_state.t,
        sc.duration,
        law_line(&sc.law, &sc.params),
        sc.impact.as_str(),
    );
    let _ = writeln!(
        s,
        "tilts: {} completed, {} mode transitions",
        r.stats.tilts, r.stats.transitions
    );
    if !r.tilt_peaks.is_empty() {
        let last: Vec<String> = r.tilt_peaks[r.tilt_peaks.len().saturating_sub(6)..]
            .iter()
            .map(|p| format!("{:+.6} ({}, t = {:.4} s)", p.alpha, p.mode, p.t))
            .collect();
        let _ = writeln!(s, "last tilt peaks alpha (rad): {}", last.join(", "));
    }
    let x = r.final_state.x;
    let _ = writeln!(
        s,
        "final: t = {} s, mode {}, alpha = {:.9} rad, beta = {:.9} rad, alpha_dot = {:.9} rad/s, \
         beta_dot = {:.9} rad/s",
        r.final_state.t, r.final_state.mode, x[0], x[1], x[2], x[3]
    );
    let _ = writeln!(
        s,
        "fault: {}",
        r.fault
            .as_ref()
            .map_or_else(|| "none (ran to the end)".to_owned(), Fault::to_string)
    );
    if let Some(e) = &r.excitation {
        let _ = writeln!(
            s,
            "excitation: amplitude scale {:.3} at the end (smallest {:.3}); the arm's gravity \
             torque estimated m_l l_c g = {:.3} N m, its inertia about the joint {:.3} kg m^2",
            e.scale, e.min_scale, e.gravity, e.inertia
        );
    }
    if let Some(n) = &r.network {
        network_lines(&mut s, n, sc.control_period);
    }
    if let Some(i) = &r.imperfections {
        robot_line(&mut s, i);
    }
    let _ = writeln!(
        s,
        "RHS evaluations: {} ({:.0} per simulated s), {} steps, {} rejected; wall time {:.3} s",
        r.stats.rhs_evals,
        r.stats.rhs_evals as f64 / r.final_state.t.max(f64::MIN_POSITIVE),
        r.stats.steps,
        r.stats.rejected_steps,
        r.stats.wall_time_s
    );
    s
}

/// The summary's lines on the emulated network `n` (the control period `period`, s): what the
/// links lost and the plant applied, and the plant's safe mode if it was entered.
fn network_lines(s: &mut String, n: &NetStats, period: f64) {
    use std::fmt::Write as _;
    let max_age = n.age_histogram.len().saturating_sub(1);
    let _ = writeln!(
        s,
        "network: {} states and {} torques lost on the links; {} torques applied ({} late, \
         oldest {max_age} periods), {} reordered, {} superseded, {} too old; zero torque for \
         the first {} periods",
        n.states_lost,
        n.torques_lost_on_link,
        n.torques_applied,
        n.torques_late,
        n.torques_reordered,
        n.torques_superseded,
        n.torques_too_old,
        n.periods_before_first_torque
    );
    if let Some(m) = n.safe_mode.filter(|m| m.trips > 0) {
        let _ = writeln!(
            s,
            "safe mode (the plant's watchdog): entered {} times, first at t = {:.3} s; {} \
             periods ({:.3} s) in safe mode{}",
            m.trips,
            m.entered.unwrap_or(f64::NAN),
            m.periods,
            m.periods as f64 * period,
            m.since.map_or(String::new(), |t| format!(
                "; in safe mode since t = {t:.3} s at the end"
            ))
        );
    }
}

/// The summary's line on the robot's imperfections `i` (sensor noise, encoder, torque
/// saturation and lag, arm mass error).
fn robot_line(s: &mut String, i: &Imperfections) {
    use std::fmt::Write as _;
    let _ = writeln!(
        s,
        "robot: sensor noise sigma alpha {} rad, beta {} rad, alpha_dot {} rad/s, beta_dot {} \
         rad/s (seed {}); encoder {}; torque saturation {}; torque lag {} s; arm mass {:+} % \
         of the controller's model",
        i.noise[0],
        i.noise[1],
        i.noise[2],
        i.noise[3],
        i.seed,
        i.encoder_counts
            .map_or("exact".into(), |n| format!("{n} counts/rev")),
        i.torque_saturation
            .map_or("none".into(), |v| format!("{v} N m")),
        i.torque_lag,
        100.0 * i.mass_error
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::ScenarioFile;

    fn run(l: ScenarioFile) -> SimulationReport {
        simulate(&Scenario::resolve(&[&l]), SimOptions::default()).unwrap()
    }

    #[test]
    fn orbit_lands_at_its_half_period() {
        // Without the adaptation (k = 0) the built-in start is on the K_P0 orbit.
        let r = run(ScenarioFile {
            duration: Some(1.0),
            law: tilting_controller::LawArgs {
                k: Some(0.0),
                ..Default::default()
            },
            ..Default::default()
        });
        assert!(r.fault.is_none());
        let land = r.events[0];
        assert_eq!((land.from, land.to), (Mode::Left, Mode::Flat));
        assert!(
            (land.t - tilting_plant::paper::ORBIT_HALF_PERIOD).abs() < 1e-7,
            "{}",
            land.t
        );
        // On the orbit the landing state is the mirror of the start.
        let x0 = tilting_plant::paper::orbit_x0();
        assert!((land.x_after[1] - (std::f64::consts::PI - x0[1])).abs() < 1e-7);
        assert!((land.x_after[3] + x0[3]).abs() < 1e-6);
        assert_eq!(r.final_state.t, 1.0);
    }

    #[test]
    fn default_run_settles_on_a_symmetric_period_one_orbit() {
        let r = run(ScenarioFile::default());
        assert!(r.fault.is_none());
        assert_eq!(r.final_state.t, 10.0);
        let n = r.tilt_peaks.len();
        assert!(n > 15, "{n}");
        let (a, b) = (r.tilt_peaks[n - 2], r.tilt_peaks[n - 1]);
        assert_ne!(a.mode, b.mode);
        assert!((a.alpha + b.alpha).abs() < 1e-6, "{a:?} {b:?}");
    }

    #[test]
    fn sampled_run_ends_on_time_with_an_uneven_last_period() {
        let r = run(ScenarioFile {
            duration: Some(0.2),
            control_period: Some(0.03),
            ..Default::default()
        });
        assert!(r.fault.is_none(), "{:?}", r.fault);
        assert_eq!(r.final_state.t, 0.2);
        assert_eq!(r.stats.controller_samples, 7);
    }
}
