//! The planner node (`tilting-planner`): the planner as a zenoh node. It publishes the controller's law (gains,
//! energy target, reference trajectory, torque limit) as a `tilting_proto::Reference` on
//! `tilting/{robot}/planner/reference`, following the late-joiner convention of
//! `docs/protocol.md`:
//!
//! 1. a queryable on that key answers every query with the current reference;
//! 2. the reference is put on the key when it changes, and repeated at a low rate (`--repeat`,
//!    1 s by default);
//! 3. the liveliness token `tilting/{robot}/alive/planner` is declared after the queryable, so
//!    a controller that sees the token can query at once.
//!
//! For now the "plan" is the law given by the flags; `--from-orbit` computes the energy target
//! `E_av` of the adaptation from the smallest periodic tilting orbit of the loop without
//! adaptation ([`crate::orbit::find_all`]). [`ReferencePublisher`] is also used in-process by
//! `live`.

use crate::orbit::{find_all, OrbitProblem};
use anyhow::{anyhow, Context as _};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tilting_controller::law::LawRecord;
use tilting_controller::{LawArgs, LawSpec};
use tilting_net::{Qos, Role, TypedPublisher, ZenohArgs};
use tilting_plant::{ImpactLaw, Params};
use tilting_proto::{codec, Keys, Reference};
use zenoh::{Session, Wait as _};

/// Why the planner node (or the law of its flags) cannot be used. The front doors map these
/// to exit codes (`tilting-planner` and `tilting`: 2 for [`NodeError::Invalid`], 1 otherwise).
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// A flag, or the law the flags describe, is invalid (names the flag and what is allowed).
    #[error("{0:#}")]
    Invalid(anyhow::Error),
    /// `--from-orbit` found no periodic tilting orbit for the gains.
    #[error("--from-orbit: no periodic tilting orbit found for K_P = {kp}, K_D = {kd}")]
    NoOrbit {
        /// `K_P` (1/s^2).
        kp: f64,
        /// `K_D` (1/s).
        kd: f64,
    },
    /// The runtime or the zenoh session failed.
    #[error("{0:#}")]
    Run(anyhow::Error),
}

/// The law the planner publishes, as flags (shared by `publish` and `live`): the law's own
/// flags ([`LawArgs`], over the paper's orbit [`LawSpec::default`]) and `--from-orbit`.
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
pub struct PlannerLawArgs {
    /// The law.
    #[command(flatten)]
    pub law: LawArgs,
    /// Take E_av from the smallest periodic tilting orbit of the loop without adaptation with
    /// --kp and --kd (paper model and impact law), computed by shooting (as `orbit`)
    #[arg(long, conflicts_with = "energy_avg")]
    pub from_orbit: bool,
    /// Take the law from a plan (`tilting plan orbit [--peak P] --json > plan.json`): its
    /// K_P0, K_D, k and E_av, and the start of its first stable orbit (where the plant starts
    /// and where --orbit-peak's re-entry hands over); a flag given as well overrides the
    /// plan's value. Give the plant the robot file the plan was made for (--params)
    #[arg(long, value_name = "PLAN.json", conflicts_with = "from_orbit")]
    pub plan: Option<std::path::PathBuf>,
}

impl PlannerLawArgs {
    /// The law the flags describe, checked as the controller checks a reference (the message,
    /// [`LawSpec::validate`], the bounds) and, by the same [`LawSpec::validate`], in what the
    /// wire does not carry (the robust option, the orbit's start and steepness). With
    /// `--from-orbit` this runs the orbit search (a few seconds) and reports it on stderr.
    pub fn resolve(&self) -> Result<LawSpec, NodeError> {
        let base = match &self.plan {
            Some(p) => crate::jobs::law_of_plan(p).map_err(NodeError::Invalid)?,
            None => LawSpec::default(),
        };
        let mut law = self.law.over(base);
        if self.from_orbit {
            law.energy_avg = orbit_energy_avg(law.kp, law.kd)?;
        }
        // Each check once: the message's (finite values, signs), the law's own
        // ([`LawSpec::validate`]: the wire's fields and what the wire does not carry, the robust
        // option and the orbit's start and steepness, so that `live` refuses them before any
        // node starts), and the controller's bounds.
        let invalid = |e: &dyn std::fmt::Display| NodeError::Invalid(anyhow!("{e}"));
        law.to_wire().validate().map_err(|e| invalid(&e))?;
        law.validate().map_err(|e| invalid(&e))?;
        tilting_controller::wire::check_bounds(&law).map_err(|e| invalid(&e))?;
        Ok(law)
    }
}

/// Checks a reference as the controller will: valid message and a valid control law.
pub fn check_reference(r: &Reference) -> anyhow::Result<()> {
    r.validate().map_err(|e| anyhow!("{e}"))?;
    LawSpec::from_wire(r).map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// `E_av` of the smallest periodic tilting orbit of the loop `K_P = kp`, `K_D = kd` without
/// adaptation (paper model, paper impact law).
pub fn orbit_energy_avg(kp: f64, kd: f64) -> Result<f64, NodeError> {
    if !(kp.is_finite() && kp > 0.0 && kd.is_finite() && kd >= 0.0) {
        return Err(NodeError::Invalid(anyhow!(
            "--from-orbit needs --kp > 0 and --kd >= 0, got {kp} and {kd}"
        )));
    }
    let t0 = Instant::now();
    let pb = OrbitProblem::new(Params::default(), ImpactLaw::Paper, kp, kd);
    let all = find_all(&pb);
    let Some(best) = all.first() else {
        return Err(NodeError::NoOrbit { kp, kd });
    };
    eprintln!(
        "--from-orbit: {} orbit(s) for K_P = {kp}, K_D = {kd} in {:.1} s; the smallest (max tilt \
         {:.6} rad, period {:.6} s, {}) has E_av = {} J",
        all.len(),
        t0.elapsed().as_secs_f64(),
        best.max_tilt,
        best.period,
        if best.stable { "stable" } else { "unstable" },
        best.energy_avg
    );
    Ok(best.energy_avg)
}

/// The planner's side of the reference convention: a queryable answering the latest reference,
/// puts on change (and on [`ReferencePublisher::repeat`]), and the planner's liveliness token.
/// Dropping it undeclares all three.
pub struct ReferencePublisher {
    latest: Arc<Mutex<Reference>>,
    publisher: TypedPublisher<Reference>,
    puts: AtomicU64,
    queries: Arc<AtomicU64>,
    _queryable: zenoh::query::Queryable<()>,
    _token: zenoh::liveliness::LivelinessToken,
}

impl ReferencePublisher {
    /// Declares the queryable, puts `reference`, then declares the token (in that order).
    pub async fn start(
        session: &Session,
        keys: &Keys,
        reference: Reference,
    ) -> anyhow::Result<Self> {
        check_reference(&reference).context("invalid reference")?;
        let key = keys.planner_reference().to_owned();
        let latest = Arc::new(Mutex::new(reference));
        let queries = Arc::new(AtomicU64::new(0));
        let (l, q, reply_key) = (latest.clone(), queries.clone(), key.clone());
        let queryable = session
            .declare_queryable(key.clone())
            .callback(move |query| {
                let r = *l.lock().unwrap_or_else(|e| e.into_inner());
                match query.reply(reply_key.clone(), codec::encode(&r)).wait() {
                    Ok(()) => {
                        q.fetch_add(1, Ordering::Relaxed);
                    }
                    Err(e) => tracing::warn!("cannot answer a reference query: {e}"),
                }
            })
            .await
            .map_err(|e| anyhow!("cannot declare the queryable on {key}: {e}"))?;
        let publisher = TypedPublisher::declare(session, &key, Qos::Data).await?;
        let me = Self {
            latest,
            publisher,
            puts: AtomicU64::new(0),
            queries,
            _queryable: queryable,
            _token: tilting_net::declare_token(session, keys.alive_planner()).await?,
        };
        // Put before the token exists would also do; after it, a controller that queried on
        // the token's appearance and one that only listens both get it.
        me.repeat()?;
        Ok(me)
    }

    /// Replaces the reference; puts it at once if it changed.
    pub fn set(&self, reference: Reference) -> anyhow::Result<()> {
        check_reference(&reference).context("invalid reference")?;
        let changed = {
            let mut l = self.latest.lock().unwrap_or_else(|e| e.into_inner());
            let changed = *l != reference;
            *l = reference;
            changed
        };
        if changed {
            self.repeat()?;
        }
        Ok(())
    }

    /// Puts the current reference again.
    pub fn repeat(&self) -> anyhow::Result<()> {
        let r = self.reference();
        self.publisher.put(&r)?;
        self.puts.fetch_add(1, Ordering::Relaxed);
        Ok(())
    }

    /// The current reference.
    pub fn reference(&self) -> Reference {
        *self.latest.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Puts so far.
    pub fn puts(&self) -> u64 {
        self.puts.load(Ordering::Relaxed)
    }

    /// Queries answered so far.
    pub fn queries_answered(&self) -> u64 {
        self.queries.load(Ordering::Relaxed)
    }
}

/// Flags of the planner node, `tilting-planner`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "tilting-planner",
    allow_negative_numbers = true,
    version,
    about = "The planner node: publishes the controller's law (gains, E_av, reference trajectory) \
             over zenoh, answers late joiners and holds the planner's liveliness token",
    after_help = "The offline tools that used to live here are now subcommands of `tilting` \
                  (`tilting live`, `tilting simulate`, `tilting plan ...`, `tilting figures`); \
                  their old names still work for one release and say where they went."
)]
pub struct PublishArgs {
    /// Zenoh and naming flags.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// The law to publish.
    #[command(flatten)]
    pub law: PlannerLawArgs,
    /// Repeat the reference on its key every this many seconds; 0 = only when it changes (the
    /// queryable answers late joiners either way)
    #[arg(long, default_value_t = 1.0, value_name = "SECONDS")]
    pub repeat: f64,
    /// Stop after this many seconds [default: run until Ctrl-C]
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
}

/// The planner node's summary, one JSON object on stdout at the end.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PublishSummary {
    /// The key the reference was published on.
    pub key: String,
    /// The published law.
    pub reference: LawRecord,
    /// Puts of the reference.
    pub puts: u64,
    /// Queries answered.
    pub queries_answered: u64,
    /// How long the node ran (s).
    pub seconds: f64,
}

/// Checks a duration flag: positive and finite.
pub fn check_seconds(flag: &str, v: f64, allow_zero: bool) -> Result<(), NodeError> {
    let ok = v.is_finite() && (v > 0.0 || (allow_zero && v == 0.0)) && v < 1e9;
    if ok {
        Ok(())
    } else {
        Err(NodeError::Invalid(anyhow!(
            "invalid `{flag}` = {v}: must be a {} number of seconds",
            if allow_zero {
                "non-negative"
            } else {
                "positive"
            }
        )))
    }
}

/// Runs the planner node (`tilting-planner`, also `tilting-planner publish`).
pub fn run(args: &PublishArgs) -> Result<(), NodeError> {
    tilting_net::init_tracing("warn,tilting_planner=info,tilting_net=info");
    check_seconds("--repeat", args.repeat, true)?;
    if let Some(d) = args.duration {
        check_seconds("--duration", d, false)?;
    }
    let keys = args.zenoh.keys().map_err(NodeError::Invalid)?;
    args.zenoh.config(Role::Peer).map_err(NodeError::Invalid)?;
    let law = args.law.resolve()?;
    let rt = tilting_net::runtime().map_err(NodeError::Run)?;
    rt.block_on(serve(args, keys, law)).map_err(NodeError::Run)
}

async fn serve(args: &PublishArgs, keys: Keys, law: LawSpec) -> anyhow::Result<()> {
    let session = tilting_net::open_session(&args.zenoh, Role::Peer).await?;
    let publisher = ReferencePublisher::start(&session, &keys, law.to_wire()).await?;
    tilting_net::say_err(&format!(
        "publishing on {}: {law}; {}",
        keys.planner_reference(),
        match args.duration {
            Some(d) => format!("for {d} s"),
            None => "until Ctrl-C".to_owned(),
        }
    ));
    let start = tokio::time::Instant::now();
    let end = args.duration.map(|d| start + Duration::from_secs_f64(d));
    let period = (args.repeat > 0.0).then(|| Duration::from_secs_f64(args.repeat));
    let mut next = period.map(|p| start + p);
    let stop = tilting_net::shutdown_signal();
    tokio::pin!(stop);
    loop {
        let wake = match (next, end) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        tokio::select! {
            _ = &mut stop => break,
            _ = async {
                match wake {
                    Some(w) => tokio::time::sleep_until(w).await,
                    None => std::future::pending().await,
                }
            } => {}
        }
        let now = tokio::time::Instant::now();
        if end.is_some_and(|e| now >= e) {
            break;
        }
        if let (Some(n), Some(p)) = (next, period) {
            if now >= n {
                if let Err(e) = publisher.repeat() {
                    tracing::warn!("{e}");
                }
                next = Some(n + p);
            }
        }
    }
    let summary = PublishSummary {
        key: keys.planner_reference().to_owned(),
        reference: LawRecord::from(&law),
        puts: publisher.puts(),
        queries_answered: publisher.queries_answered(),
        seconds: start.elapsed().as_secs_f64(),
    };
    drop(publisher);
    let _ = tilting_net::say_out(&serde_json::to_string(&summary)?);
    let _ = session.close().await;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use tilting_controller::Trajectory;
    use tilting_plant::paper::{ORBIT_ENERGY_AVG, ORBIT_K, ORBIT_KD, ORBIT_KP};

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: PublishArgs,
    }

    /// What the wire does not carry (the robust option, the orbit's steepness) is checked
    /// before any node starts: refused naming the field and its range.
    #[test]
    fn the_robust_options_are_refused_naming_the_field() {
        for (argv, field, range) in [
            (&["x", "--orbit-peak", "-1"][..], "orbit_peak", "(0, 0.5]"),
            (&["x", "--orbit-peak", "0.6"][..], "orbit_peak", "(0, 0.5]"),
            (
                &["x", "--orbit-peak", "0.02", "--k", "0"][..],
                "orbit_peak",
                "k > 0",
            ),
            (
                &["x", "--orbit-steepness", "0"][..],
                "orbit_steepness",
                "[0.1, 10000]",
            ),
        ] {
            let a = Cli::try_parse_from(argv).unwrap().args;
            let e = a.law.resolve().unwrap_err().to_string();
            assert!(e.contains(field) && e.contains(range), "{argv:?}: {e}");
        }
        let ok = Cli::try_parse_from(["x", "--orbit-peak", "0.02", "--orbit-steepness", "-24"]);
        let law = ok.unwrap().args.law.resolve().unwrap();
        assert_eq!(
            (law.orbit_peak, law.orbit_steepness),
            (Some(0.02), Some(-24.0))
        );
    }

    #[test]
    fn defaults_are_the_paper_orbit() {
        let a = Cli::try_parse_from(["x"]).unwrap().args;
        assert_eq!(a.law, PlannerLawArgs::default());
        let r = a.law.resolve().unwrap().to_wire();
        assert_eq!(r.kind, Reference::HOLD);
        assert_eq!((r.kp, r.kd, r.k), (ORBIT_KP, ORBIT_KD, ORBIT_K));
        assert_eq!(r.energy_avg, ORBIT_ENERGY_AVG);
        assert_eq!(r.torque_limit, 0.0);
        assert_eq!(a.duration, None);
        assert_eq!(a.repeat, 1.0);
    }

    #[test]
    fn flags_map_to_the_message_and_back() {
        let a = Cli::try_parse_from([
            "x",
            "--reference",
            "sinusoid:0.2,4",
            "--kp",
            "60",
            "--kd",
            "12",
            "--k",
            "0",
            "--torque-limit",
            "5",
            "--robot",
            "r1",
        ])
        .unwrap()
        .args;
        let law = a.law.resolve().unwrap();
        let r = law.to_wire();
        assert_eq!(
            (
                r.kind,
                r.amplitude,
                r.omega,
                r.kp,
                r.kd,
                r.k,
                r.torque_limit
            ),
            (Reference::SINUSOID, 0.2, 4.0, 60.0, 12.0, 0.0, 5.0)
        );
        // Its keys (a robot file's `[law]`, as `live` hands it to the controller) give the
        // same law back, the reference in the text of its flag.
        let keys = serde_json::to_value(tilting_controller::LawArgs::from(law)).unwrap();
        assert_eq!(keys["reference"], "sinusoid:0.2,4");
        let back: tilting_controller::LawArgs = serde_json::from_value(keys).unwrap();
        assert_eq!(back.over(LawSpec::default()), law);
        assert_eq!(
            law.reference,
            Trajectory::Sinusoid {
                amplitude: 0.2,
                omega: 4.0
            }
        );
        assert!(law.to_string().contains("sinusoid:0.2,4"));
        // Bad laws are usage errors.
        let bad = Cli::try_parse_from(["x", "--kp=-1"]).unwrap().args;
        assert!(matches!(bad.law.resolve(), Err(NodeError::Invalid(_))));
        assert!(Cli::try_parse_from(["x", "--reference", "sinusoid:1,0"]).is_err());
        assert!(
            Cli::try_parse_from(["x", "--from-orbit", "--energy-avg", "3"]).is_err(),
            "--from-orbit and --energy-avg conflict"
        );
    }

    #[test]
    fn the_summary_has_the_fields_of_the_message() {
        let law = LawSpec {
            torque_limit: Some(5.0),
            ..LawSpec::default()
        };
        let v = serde_json::to_value(PublishSummary {
            key: "k".into(),
            reference: LawRecord::from(&law),
            puts: 1,
            queries_answered: 2,
            seconds: 0.5,
        })
        .unwrap();
        let r = law.to_wire();
        let rv = &v["reference"];
        assert_eq!(rv["kind"], "hold");
        for (name, x) in [
            ("amplitude", r.amplitude),
            ("omega", r.omega),
            ("kp", r.kp),
            ("kd", r.kd),
            ("k", r.k),
            ("energy_avg", r.energy_avg),
            ("torque_limit", r.torque_limit),
        ] {
            assert_eq!(rv[name].as_f64(), Some(x), "{name}");
        }
        for name in ["key", "puts", "queries_answered", "seconds"] {
            assert!(v.get(name).is_some(), "{name}");
        }
    }

    #[test]
    fn from_orbit_finds_the_paper_orbit_energy() {
        let e = orbit_energy_avg(ORBIT_KP, ORBIT_KD).unwrap();
        assert!((e - ORBIT_ENERGY_AVG).abs() < 1e-8, "{e}");
    }
}
