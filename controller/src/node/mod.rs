//! The `tilting-controller` node: answers every `PlantState` with the computed-torque law.
//!
//! For each valid state received on `tilting/{robot}/plant/state` it computes
//! `tau = Controller::torque(state.time, mode, x)` (the law of the flags or of the planner's
//! reference) and publishes
//! `TorqueCommand { seq: state.seq, tau }` on `tilting/{robot}/controller/torque` at once, from
//! the subscriber's callback (no queue, no extra thread hop).
//!
//! The law starts from the flags ([`LawArgs`]: `--kp`, `--kd`, `--k`, `--energy-avg`,
//! `--reference`, `--torque-limit`; the model from `--params`). A valid `Reference` on `tilting/{robot}/planner/reference`
//! replaces its gains and reference (the model parameters stay those of `--params`), unless
//! `--ignore-planner`. A controller started after the planner still gets the reference: it
//! queries the planner's queryable on the same key at start-up and each time a planner's
//! liveliness token (`tilting/{robot}/alive/planner`) appears. Invalid payloads are dropped,
//! counted and logged at a bounded rate; a non-finite torque is never published. A state
//! must pass the plant's plausibility window, and where its source is known, come from the
//! plant's session: the first believed state pins it, and states (and `--predict`'s statuses)
//! from another session are refused while it keeps talking (`tilting_proto::source`), counted
//! as `states_foreign`.
//!
//! With `--robots A,B,...` (host mode, 1 to 32 names) one process answers several robots over
//! one zenoh session, each with its own keys, law, estimator, predictor, pins and counters, and
//! prints one summary line per robot (`{"robot": NAME, "summary": ...}`).
//!
//! At Ctrl-C or SIGTERM the node prints a JSON summary of its counters on stdout; if stdout
//! fails (a full disk, a closed pipe), it goes to
//! `$TMPDIR/tilting-controller-{pid}-summary.json` instead, said on stderr.

use anyhow::Context as _;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tilting_net::{DropCounter, Qos, Role, TypedPublisher, ZenohArgs};
use tilting_plant::imperfect::Measurement;
use tilting_plant::ParamsArgs;
use tilting_proto::plausible::{self, StateWindow, MIN_PERIOD};
use tilting_proto::{Keys, PlantState, SourceId, SourcePin, Status, TorqueCommand};

use crate::estimate::{EstimatorArgs, Method};
use crate::predict::{Predict, PredictArgs, Predictor};
use crate::{ControlConfig, Controller, Estimation, LawArgs, LawSpec};

/// Flags of `tilting-controller`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "tilting-controller",
    allow_negative_numbers = true,
    version,
    about = "Computed-torque PD controller with energy adaptation: answers every plant state with a torque over zenoh",
    after_help = "At Ctrl-C/SIGTERM a JSON summary of the counters is printed on stdout."
)]
pub struct ControllerArgs {
    /// Zenoh and naming flags.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Host mode: several robots from this one process, one zenoh session.
    #[command(flatten)]
    pub host: tilting_net::HostArgs,
    /// The law, until a planner's reference replaces it (its model stays `--params`).
    #[command(flatten)]
    pub law: LawArgs,
    /// The model of the inverse dynamics and the energy.
    #[command(flatten)]
    pub params: ParamsArgs,
    /// Keep the law of the flags: ignore references published by a planner
    #[arg(long)]
    pub ignore_planner: bool,
    /// Prediction over the round-trip delay.
    #[command(flatten)]
    pub predict: PredictArgs,
    /// The state estimator (for states without rates).
    #[command(flatten)]
    pub estimator: EstimatorArgs,
    /// The plant's zenoh id (its `--zenoh-id`), if known before it starts: states and statuses
    /// are believed only from that session, from the first one on, and the pin never lapses
    /// [default: pin the session of the first believed state]
    #[arg(long, value_name = "HEX", value_parser = tilting_net::parse_source_id)]
    pub plant_id: Option<SourceId>,
    /// A robot file (TOML): its keys are the defaults of the flags of the same names (its
    /// [robot] the model, [law] the law, [network] predict, [sensors] estimator; a flag given
    /// as well overrides its key). `tilting live` hands the controller its run's robot.toml
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot_file: Option<std::path::PathBuf>,
}

impl ControllerArgs {
    /// The controller settings the flags describe.
    pub fn control_config(&self) -> anyhow::Result<ControlConfig> {
        let cfg = ControlConfig::new(self.params.params()?, self.law.over(LawSpec::default()));
        cfg.validate()?;
        crate::wire::check_bounds(&cfg.law)?;
        Ok(cfg)
    }
}

struct Node {
    params: tilting_plant::Params,
    /// The robust option of the flags (not on the wire: kept across references).
    orbit_peak: Option<f64>,
    /// The orbit start of the flags (not on the wire either).
    orbit_start: Option<[f64; 2]>,
    /// The orbit's steepness (the trim's gain), the controller's own (not on the wire).
    orbit_steepness: Option<f64>,
    law: Mutex<Controller>,
    states: DropCounter,
    /// The plausibility window of the states (`tilting_proto::plausible`): a forged state
    /// moves neither the law nor the estimator nor the predictor's period.
    window: Mutex<StateWindow>,
    /// Well-formed states the window refused (not answered).
    states_refused: AtomicU64,
    /// The plant's session, pinned by the first believed state ([`PLANT_PIN_LAPSE`]).
    plant: Mutex<SourcePin>,
    /// States and statuses refused as from a foreign source (not answered, not used).
    states_foreign: AtomicU64,
    references: DropCounter,
    torques_published: AtomicU64,
    torques_not_finite: AtomicU64,
    publish_errors: AtomicU64,
    references_applied: AtomicU64,
    references_rejected: AtomicU64,
    /// The planner's liveliness token, as watched: references count only while one is alive.
    planner: Arc<tilting_net::Presence>,
    /// A reference arrived on the topic itself (newer than any query answer).
    live_reference: AtomicBool,
    ignore_planner: bool,
    torque: TypedPublisher<TorqueCommand>,
    /// `--predict`: the predictor, once the loop's period is known from the states' times.
    predict: Option<Mutex<Prediction>>,
    /// `--estimator`: the rates of states that lack them (`--measure angles`).
    estimation: Mutex<Estimation>,
}

/// The predictor of the node and what it has learnt.
struct Prediction {
    p: Predictor,
    /// The period is known (from a state with `seq > 0`: `t = seq * T` on the grid).
    period_known: bool,
    /// ... from state 1, `t = T` exactly.
    period_exact: bool,
    /// Estimate the delay from the plant's status.
    estimate: bool,
    /// Status messages that set the delay.
    estimates: u64,
}

/// How long the plant's pinned session may be silent before another may take its place (s):
/// a plant restarted under a running controller is a new session.
pub const PLANT_PIN_LAPSE: f64 = 0.5;

impl Node {
    fn on_state(&self, bytes: &[u8], source: Option<SourceId>) {
        let Some(s) = self.states.decode::<PlantState>(bytes) else {
            return;
        };
        let Ok(mode) = s.mode() else {
            return; // unreachable: decode validated the mode
        };
        let now = std::time::Instant::now();
        let believed = {
            let w = self.window.lock().unwrap_or_else(|e| e.into_inner());
            w.test(&s, now).map(|()| w)
        };
        let mut window = match believed {
            Ok(w) => w,
            Err(e) => {
                let n = self.states_refused.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_power_of_two() {
                    tracing::warn!("state refused, not answered ({n} so far): {e}");
                }
                return;
            }
        };
        if !self.is_from_plant("PlantState", source, now) {
            return;
        }
        window.believe(&s, now);
        drop(window);
        let y = Measurement {
            angles: s.angles(),
            rates: s.rates(),
        };
        let tau = {
            let law = self.law.lock().unwrap_or_else(|e| e.into_inner());
            let mut est = self.estimation.lock().unwrap_or_else(|e| e.into_inner());
            let (mode, x) = est.observe(s.time, mode, &y);
            match &self.predict {
                None => {
                    let tau = law.torque(s.time, mode, &x);
                    est.sent(s.time, tau);
                    tau
                }
                Some(m) => {
                    let mut pr = m.lock().unwrap_or_else(|e| e.into_inner());
                    if s.seq > 0 && !pr.period_exact {
                        // Periodic states lie on the grid, `t = seq * T`; an extra state
                        // (sampled at a mode transition) comes later in its period, so the
                        // smallest `t / seq` is the period; state 1 is at exactly `T`.
                        let per = s.time / s.seq as f64;
                        if !pr.period_known || per < pr.p.period() || s.seq == 1 {
                            pr.p.set_period(per);
                            pr.period_known = true;
                            pr.period_exact = s.seq == 1;
                        }
                    }
                    let on_grid =
                        pr.period_known && (s.time / pr.p.period() - s.seq as f64).abs() < 1e-6;
                    let tau = pr.p.answer(&*law, s.time, mode, &x, on_grid);
                    est.sent(pr.p.acts_at(s.time, on_grid), tau);
                    tau
                }
            }
        };
        if !tau.is_finite() {
            let n = self.torques_not_finite.fetch_add(1, Ordering::Relaxed) + 1;
            if n.is_power_of_two() {
                tracing::warn!(
                    seq = s.seq,
                    "torque is not finite ({tau}); not published ({n} so far)"
                );
            }
            return;
        }
        match self.torque.put(&TorqueCommand { seq: s.seq, tau }) {
            Ok(()) => {
                self.torques_published.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => {
                let n = self.publish_errors.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_power_of_two() {
                    tracing::warn!("cannot publish a torque ({n} failures so far): {e}");
                }
            }
        }
    }

    /// A reference from the topic (`live`) or from a query answer: the paper law's
    /// `Reference` or any law's `LawReference`, built through the registry ([`REGISTRY`]).
    fn on_reference(&self, bytes: &[u8], live: bool) {
        let Some(any) = self.references.decode::<tilting_proto::AnyReference>(bytes) else {
            return;
        };
        let r = any.law();
        if self.ignore_planner {
            tracing::debug!("--ignore-planner: reference ignored");
            return;
        }
        if !live && self.live_reference.load(Ordering::Acquire) {
            return; // a query answer older than what the topic already gave
        }
        if !self.planner.alive() {
            // A reference needs a planner: some peer must hold the planner's liveliness token.
            // (Which peer sent it is not known here; binding identities to keys is the job of
            // access control at the transport.)
            let n = self.references_rejected.fetch_add(1, Ordering::Relaxed) + 1;
            if n.is_power_of_two() {
                tracing::warn!(
                    rejected = n,
                    "reference ignored: no peer holds the planner's liveliness token"
                );
            }
            return;
        }
        // The controller's own settings, not on the wire (the paper's law reads them).
        let local = LawSpec {
            orbit_peak: self.orbit_peak,
            orbit_start: self.orbit_start,
            orbit_steepness: self.orbit_steepness,
            ..LawSpec::default()
        };
        match REGISTRY.build(&self.params, &local, &r) {
            Ok(c) => {
                if live {
                    self.live_reference.store(true, Ordering::Release);
                }
                let mut law = self.law.lock().unwrap_or_else(|e| e.into_inner());
                if !law.same_law(&c) {
                    tracing::info!(
                        law = r.law,
                        trajectory = r.trajectory,
                        amplitude = r.amplitude,
                        omega = r.omega,
                        parameters = ?r.parameters,
                        source = if live { "topic" } else { "query" },
                        "planner reference applied"
                    );
                    // The same law again keeps its memory (the robust option's trim).
                    *law = c;
                }
                self.references_applied.fetch_add(1, Ordering::Relaxed);
            }
            Err(e) => {
                self.references_rejected.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("planner reference rejected: {e}");
            }
        }
    }

    /// The plant's status: with `--predict auto`, its median torque age sets the delay.
    /// Whether a `message` from `source`, received at `now`, comes from the plant's pinned
    /// session (which it then keeps alive, or pins); a refusal is counted and logged at a
    /// bounded rate.
    fn is_from_plant(
        &self,
        message: &'static str,
        source: Option<SourceId>,
        now: std::time::Instant,
    ) -> bool {
        let mut pin = self.plant.lock().unwrap_or_else(|e| e.into_inner());
        match plausible::foreign(&pin, message, "plant", source, now) {
            Ok(()) => {
                pin.believe(source, now);
                true
            }
            Err(e) => {
                let n = self.states_foreign.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_power_of_two() {
                    tracing::warn!("refused, not answered ({n} so far): {e}");
                }
                false
            }
        }
    }

    fn on_status(&self, bytes: &[u8], source: Option<SourceId>) {
        let Some(m) = &self.predict else { return };
        let Ok(st) = tilting_proto::codec::decode::<Status>(bytes) else {
            return; // the status is advisory here; malformed ones are the logger's business
        };
        if !self.is_from_plant("Status", source, std::time::Instant::now()) {
            return;
        }
        let mut pr = m.lock().unwrap_or_else(|e| e.into_inner());
        if pr.estimate && pr.period_known && st.age_p50.is_finite() && st.age_p50 >= 0.0 {
            let d = st.age_p50.round() * pr.p.period();
            if d != pr.p.delay() {
                tracing::info!(delay = d, age = st.age_p50, "predicting over the delay");
            }
            pr.p.set_delay(d);
            pr.estimates += 1;
        }
    }

    fn summary(&self) -> ControllerSummary {
        let (law, robust, registered) = {
            let l = self.law.lock().unwrap_or_else(|e| e.into_inner());
            let registered = l.registered().map(crate::RegisteredLaw::summary);
            (l.config().law, l.robust_status(), registered)
        };
        let prediction = self.predict.as_ref().map(|m| {
            let pr = m.lock().unwrap_or_else(|e| e.into_inner());
            let (made, fallbacks) = pr.p.counts();
            PredictionSummary {
                delay: pr.p.delay(),
                estimated: pr.estimate,
                estimates: pr.estimates,
                predictions: made,
                fallbacks,
            }
        });
        let estimation = {
            let est = self.estimation.lock().unwrap_or_else(|e| e.into_inner());
            est.estimator().map(|e| {
                let (estimates, fallbacks) = e.counts();
                EstimationSummary {
                    method: e.method(),
                    estimates,
                    fallbacks,
                }
            })
        };
        ControllerSummary {
            prediction,
            estimation,
            states_received: self.states.received(),
            states_dropped: self.states.dropped(),
            states_refused: self.states_refused.load(Ordering::Relaxed),
            states_foreign: self.states_foreign.load(Ordering::Relaxed),
            torques_published: self.torques_published.load(Ordering::Relaxed),
            torques_not_finite: self.torques_not_finite.load(Ordering::Relaxed),
            publish_errors: self.publish_errors.load(Ordering::Relaxed),
            references_received: self.references.received(),
            references_dropped: self.references.dropped(),
            references_rejected: self.references_rejected.load(Ordering::Relaxed),
            references_applied: self.references_applied.load(Ordering::Relaxed),
            law,
            registered,
            robust,
        }
    }
}

/// The laws a controller builds from the planner's messages ([`crate::registry`]).
static REGISTRY: std::sync::LazyLock<crate::LawRegistry> =
    std::sync::LazyLock::new(crate::LawRegistry::builtin);

/// The controller node's summary, one JSON object on stdout at Ctrl-C or SIGTERM; shared by
/// the node, `tilting live` and the tests.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ControllerSummary {
    /// State messages received, valid or not.
    pub states_received: u64,
    /// State messages dropped as malformed or invalid.
    pub states_dropped: u64,
    /// Well-formed states refused as implausible (`tilting_proto::plausible::StateWindow`:
    /// ahead of the wall clock, off the time grid, beyond the fall angle) and not answered.
    #[serde(default)]
    pub states_refused: u64,
    /// Well-formed states (and `--predict`'s statuses) refused because they came from another
    /// zenoh session than the plant's (pinned by the first believed state; see
    /// `tilting_proto::source`), not answered.
    #[serde(default)]
    pub states_foreign: u64,
    /// Torques published.
    pub torques_published: u64,
    /// States whose torque came out NaN or infinite (not published).
    pub torques_not_finite: u64,
    /// Publications that failed.
    pub publish_errors: u64,
    /// Reference messages received, valid or not.
    pub references_received: u64,
    /// Reference messages dropped as malformed or invalid.
    pub references_dropped: u64,
    /// Valid references whose law was refused.
    pub references_rejected: u64,
    /// References applied.
    pub references_applied: u64,
    /// The law in force at the end (for a registered law other than the paper's, its
    /// trajectory and zero gains: see `registered`).
    pub law: LawSpec,
    /// A law of the registry other than the paper's, if one is in force at the end: its name
    /// and parameters (left out of the JSON for the paper's law).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub registered: Option<crate::registry::RegisteredSummary>,
    /// With `--orbit-peak`: what the robust option did (the energy target in force, tilts,
    /// re-entries).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robust: Option<crate::robust::RobustStatus>,
    /// With `--predict`: the delay predicted over at the end and the counts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub prediction: Option<PredictionSummary>,
    /// The estimator, if one ran (states without rates, or `--estimator observer|fd`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub estimation: Option<EstimationSummary>,
}

/// What the estimator of `--estimator` did.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct EstimationSummary {
    /// `observer` or `fd`.
    pub method: Method,
    /// States estimated.
    pub estimates: u64,
    /// Propagations the model refused (a kinematic step was taken instead).
    pub fallbacks: u64,
}

/// What the predictor of `--predict` did.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PredictionSummary {
    /// The round-trip delay predicted over at the end (s).
    pub delay: f64,
    /// The delay was estimated from the plant's status (`--predict auto`).
    pub estimated: bool,
    /// Status messages that set the delay.
    pub estimates: u64,
    /// Answers computed for a predicted state.
    pub predictions: u64,
    /// Predictions the model could not make (answered for the state as received).
    pub fallbacks: u64,
}

impl ControllerSummary {
    /// The last line of `stdout` that parses as a summary.
    pub fn from_stdout(stdout: &str) -> Option<Self> {
        stdout
            .lines()
            .rev()
            .find_map(|l| serde_json::from_str(l).ok())
    }
}

/// Runs the controller node until Ctrl-C or SIGTERM. With `--robots` (host mode) one process
/// serves every robot named over one zenoh session, each with its own law, estimator,
/// predictor, pins and counters, and prints one summary line per robot
/// ([`tilting_net::HostedSummary`]).
pub fn run(args: ControllerArgs) -> anyhow::Result<ExitCode> {
    let cfg = args.control_config()?;
    let hosted = args.host.hosting();
    let all_keys = if hosted {
        tilting_net::check_hosted_config(&args.zenoh)?;
        args.host.keys()?
    } else {
        vec![args.zenoh.keys()?]
    };
    let robots = all_keys
        .into_iter()
        .map(|k| Ok((k, Controller::new(cfg)?)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let rt = tilting_net::runtime()?;
    rt.block_on(run_async(args, robots, hosted))
}

/// One robot being served: its node and the zenoh declarations that live as long as it runs.
struct Served {
    keys: Keys,
    node: Arc<Node>,
    querier: tokio::task::JoinHandle<()>,
    token: zenoh::liveliness::LivelinessToken,
    _subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
    _presence: [Arc<tilting_net::Presence>; 2],
}

/// The model the estimator and the predictor of a robot with parameters `params` run: it
/// lands by the robot's law (its parameter file's `impact`), applied at the landings they see
/// coming.
fn landing_model(params: tilting_plant::Params) -> tilting_plant::SimConfig {
    tilting_plant::SimConfig {
        params,
        impact: params.impact,
        ..tilting_plant::SimConfig::default()
    }
}

impl Node {
    /// The node of robot `keys` running `law` (its parameters, robust options and counters at
    /// zero), publishing its torques on `torque` and watching the robot's planner through
    /// `planner`; its estimator, predictor (`--predict`) and plant pin (`--plant-id`) from
    /// `args`.
    fn new(
        args: &ControllerArgs,
        keys: &Keys,
        law: Controller,
        planner: Arc<tilting_net::Presence>,
        torque: TypedPublisher<TorqueCommand>,
    ) -> Self {
        let params = law.config().params;
        let model = landing_model(params);
        Node {
            estimation: Mutex::new(Estimation::new(args.estimator.choice(), model)),
            params: law.config().params,
            orbit_peak: law.config().law.orbit_peak,
            orbit_start: law.config().law.orbit_start,
            orbit_steepness: law.config().law.orbit_steepness,
            law: Mutex::new(law),
            states: DropCounter::new(keys.plant_state()),
            // The period is learnt by the predictor only; the window bounds jumps by the
            // shortest one. The slack (1 s) is the recorder's: a burst after a stall of this
            // process.
            window: Mutex::new(StateWindow::new(
                None,
                MIN_PERIOD,
                tilting_plant::SimConfig::default().fall_angle,
                1.0,
                false,
            )),
            states_refused: AtomicU64::new(0),
            plant: Mutex::new(SourcePin::expect_or_new(
                args.plant_id,
                Duration::from_secs_f64(PLANT_PIN_LAPSE),
            )),
            states_foreign: AtomicU64::new(0),
            references: DropCounter::new(keys.planner_reference()),
            torques_published: AtomicU64::new(0),
            torques_not_finite: AtomicU64::new(0),
            publish_errors: AtomicU64::new(0),
            references_applied: AtomicU64::new(0),
            references_rejected: AtomicU64::new(0),
            live_reference: AtomicBool::new(false),
            ignore_planner: args.ignore_planner,
            planner,
            torque,
            predict: args.predict.predict.map(|p| {
                let (delay, estimate) = match p {
                    Predict::Given(d) => (d, false),
                    Predict::Estimated => (0.0, true),
                };
                Mutex::new(Prediction {
                    p: Predictor::new(landing_model(params), 1e-3, delay),
                    period_known: false,
                    period_exact: false,
                    estimate,
                    estimates: 0,
                })
            }),
        }
    }
}

/// Asks the planner's queryable on `key` for the current reference (timeout 2 s) each time
/// `query_rx` receives, unless the node ignores the planner; a reply goes to
/// [`Node::on_reference`], an error reply counts as a dropped reference. Ends when the channel
/// closes.
fn spawn_querier(
    session: zenoh::Session,
    node: Arc<Node>,
    key: String,
    mut query_rx: tokio::sync::mpsc::UnboundedReceiver<()>,
) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        while query_rx.recv().await.is_some() {
            if node.ignore_planner {
                continue;
            }
            let n = node.clone();
            let r = session
                .get(key.clone())
                .timeout(Duration::from_secs(2))
                .callback(move |reply| match reply.result() {
                    Ok(sample) => n.on_reference(&sample.payload().to_bytes(), false),
                    Err(e) => n.references.record_drop(&format!(
                        "error reply to the reference query: {}",
                        String::from_utf8_lossy(&e.payload().to_bytes())
                    )),
                })
                .await;
            if let Err(e) = r {
                tracing::warn!("reference query failed: {e}");
            }
        }
    })
}

/// Declares robot `keys`' subscribers, publisher, querier and token on `session`.
async fn serve(
    session: &zenoh::Session,
    args: &ControllerArgs,
    keys: Keys,
    law: Controller,
) -> anyhow::Result<Served> {
    // Ask the planner's queryable for the current reference now and whenever a planner appears.
    let (query_tx, query_rx) = tokio::sync::mpsc::unbounded_channel::<()>();
    let _ = query_tx.send(());
    let (planner, planner_sub) =
        tilting_net::watch_presence(session, keys.alive_planner(), move |alive| {
            if alive {
                let _ = query_tx.send(());
            }
        })
        .await?;
    let torque = TypedPublisher::declare(session, keys.controller_torque(), Qos::Control).await?;
    let node = Arc::new(Node::new(args, &keys, law, planner.clone(), torque));

    let n = node.clone();
    let state_sub = tilting_net::subscribe_sourced(session, keys.plant_state(), move |b, from| {
        n.on_state(b, from)
    })
    .await?;
    let n = node.clone();
    let status_sub = match node.predict {
        Some(_) => Some(
            tilting_net::subscribe_sourced(session, keys.plant_status(), move |b, from| {
                n.on_status(b, from)
            })
            .await?,
        ),
        None => None,
    };
    let n = node.clone();
    let reference_sub = tilting_net::subscribe_bytes(session, keys.planner_reference(), move |b| {
        n.on_reference(b, true)
    })
    .await?;

    let (plant, plant_sub) =
        tilting_net::watch_presence(session, keys.alive_plant(), |_| {}).await?;
    let querier = spawn_querier(
        session.clone(),
        node.clone(),
        keys.planner_reference().to_owned(),
        query_rx,
    );
    let token = tilting_net::declare_token(session, keys.alive_controller()).await?;
    tracing::info!(robot = keys.robot(), "controller ready");
    let mut subscribers = vec![state_sub, reference_sub, planner_sub, plant_sub];
    subscribers.extend(status_sub);
    Ok(Served {
        keys,
        node,
        querier,
        token,
        _subscribers: subscribers,
        _presence: [planner, plant],
    })
}

async fn run_async(
    args: ControllerArgs,
    robots: Vec<(Keys, Controller)>,
    hosted: bool,
) -> anyhow::Result<ExitCode> {
    let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
    let mut served = Vec::with_capacity(robots.len());
    for (keys, law) in robots {
        served.push(serve(&session, &args, keys, law).await?);
    }

    tilting_net::shutdown_signal().await;
    tracing::info!("stopping");
    let mut lines = Vec::with_capacity(served.len());
    for s in served {
        s.querier.abort();
        drop(s.token);
        let summary = s.node.summary();
        lines.push(
            if hosted {
                serde_json::to_string(&tilting_net::HostedSummary {
                    robot: s.keys.robot().to_owned(),
                    summary,
                })
            } else {
                serde_json::to_string(&summary)
            }
            .context("cannot serialise the summary")?,
        );
    }
    // On a full disk or a closed pipe, to a fallback file, said on stderr.
    let _ = tilting_net::say_summary("tilting-controller", &lines.join("\n"));
    let _ = session.close().await;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Trajectory;
    use clap::Parser;

    #[test]
    fn flags_parse_with_defaults() {
        let a = ControllerArgs::try_parse_from(["tilting-controller"]).unwrap();
        let c = a.control_config().unwrap().law;
        assert_eq!((c.kp, c.kd, c.k), (100.0, 14.14, 500.0));
        assert_eq!(c.energy_avg, 19.963439703027);
        assert_eq!(c.reference, Trajectory::Hold);
        assert_eq!(c.torque_limit, None);
        let a = ControllerArgs::try_parse_from([
            "tilting-controller",
            "--reference",
            "sinusoid:0.33,5",
            "--torque-limit",
            "40",
            "--k",
            "0",
        ])
        .unwrap();
        let c = a.control_config().unwrap().law;
        assert_eq!(
            c.reference,
            Trajectory::Sinusoid {
                amplitude: 0.33,
                omega: 5.0
            }
        );
        assert_eq!(c.torque_limit, Some(40.0));
        assert!(
            ControllerArgs::try_parse_from(["tilting-controller", "--reference", "x"]).is_err()
        );
        let a = ControllerArgs::try_parse_from(["tilting-controller", "--kp=-1"]).unwrap();
        assert!(a.control_config().is_err());
    }

    #[test]
    fn reference_message_maps_to_the_law() {
        let r = tilting_proto::Reference {
            kind: tilting_proto::Reference::SINUSOID,
            amplitude: 0.2,
            omega: 3.0,
            kp: 50.0,
            kd: 10.0,
            k: 0.0,
            energy_avg: 1.0,
            torque_limit: 0.0,
        };
        let c = LawSpec::from_wire(&r).unwrap();
        assert_eq!(
            c.reference,
            Trajectory::Sinusoid {
                amplitude: 0.2,
                omega: 3.0
            }
        );
        assert_eq!((c.kp, c.kd, c.torque_limit), (50.0, 10.0, None));
        let hold = tilting_proto::Reference {
            kind: tilting_proto::Reference::HOLD,
            torque_limit: 5.0,
            ..r
        };
        let c = LawSpec::from_wire(&hold).unwrap();
        assert_eq!((c.reference, c.torque_limit), (Trajectory::Hold, Some(5.0)));
    }
}
