//! The hybrid simulator: continuous flow in each contact mode, event location on the dense
//! output, the landing impact, immediate re-tilt, a Zeno guard and faults.
//!
//! [`Plant`] owns the hybrid state `(t, q, x)` and the integrator's step-size memory, and
//! advances either with a torque held over an interval (the zero-order hold of a sampled or
//! networked controller: [`Plant::advance_held`]) or with a torque law evaluated inside the
//! right-hand side ([`Plant::advance_continuous`], the paper's setting).

use crate::dynamics::{joint_accelerations, Joint, Terms, Trig};
use crate::ode::{Dop853, Dopri5, OdeError, OdeStats, Tolerance};
use crate::{ConfigError, ImpactLaw, Landing, Mode, Params, State};

mod events;

pub use events::locate;
use events::{fires_in, Ev};

/// A torque law `tau(t, q, x)` (N m) evaluated inside the right-hand side. It must be a pure
/// function of its arguments (the integrator evaluates it at trial states).
pub trait TorqueLaw {
    /// Joint torque (N m) at time `t` (s) in mode `mode` at state `x`.
    fn torque(&self, t: f64, mode: Mode, x: &State) -> f64;

    /// The same with the shared terms of `x` (sines, cosines, mass matrix, bias) already
    /// computed; override to save recomputing them.
    #[inline]
    /// `params` are the plant's, with which `terms` were computed.
    fn torque_t(&self, t: f64, mode: Mode, x: &State, _params: &Params, _terms: &Terms) -> f64 {
        self.torque(t, mode, x)
    }
}

impl<F: Fn(f64, Mode, &State) -> f64> TorqueLaw for F {
    fn torque(&self, t: f64, mode: Mode, x: &State) -> f64 {
        self(t, mode, x)
    }
}

/// A mode transition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Time of the event (s).
    pub t: f64,
    /// Mode before.
    pub from: Mode,
    /// Mode after.
    pub to: Mode,
    /// State just before.
    pub x_before: State,
    /// State just after (the impact map applied for a landing).
    pub x_after: State,
}

/// A change of the joint's Coulomb-friction phase ([`Joint`]): the arm sticks to the plate or
/// starts to slide. Not a mode transition: the plate's contact does not change.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointEvent {
    /// Time of the event (s).
    pub t: f64,
    /// The plate's mode at the time.
    pub mode: Mode,
    /// Phase before.
    pub from: Joint,
    /// Phase after.
    pub to: Joint,
    /// The state (`beta_dot = 0` exactly when the arm sticks or starts from rest).
    pub x: State,
}

/// The extreme tilt angle of one tilt: the largest `|alpha|` among the extremes of `alpha`
/// (zeros of `alpha_dot`, located on the dense output) of that tilt. A completed tilt reports it
/// at its landing ([`Observer::tilt_peak`]); a tilt still in progress when a run ends has one as
/// soon as `alpha` has turned back ([`Plant::peak_in_progress`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TiltPeak {
    /// Time of the extreme (s).
    pub t: f64,
    /// The tilt it belongs to ([`Mode::Left`] or [`Mode::Right`]).
    pub mode: Mode,
    /// The extreme `alpha` (rad): positive for a left tilt, negative for a right one.
    pub alpha: f64,
}

/// Why a simulation stopped early. The model does not cover flight or a fall.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Fault {
    /// The vertical contact force reached zero: the plate would leave the ground.
    #[error("contact loss at t = {t:.9} s in mode {mode}: vertical contact force F_y = {force:.3e} N <= 0")]
    ContactLoss {
        /// Time (s).
        t: f64,
        /// Mode at the time.
        mode: Mode,
        /// The force (N).
        force: f64,
    },
    /// The plate tipped past the fall angle.
    #[error("fall at t = {t:.9} s: |alpha| reached {alpha:.4} rad (limit {limit:.4} rad)")]
    Fall {
        /// Time (s).
        t: f64,
        /// The tilt angle (rad).
        alpha: f64,
        /// The configured limit (rad).
        limit: f64,
    },
    /// Too many mode transitions in too short a time.
    #[error("Zeno guard at t = {t:.9} s: {events} transitions within {window:e} s")]
    Zeno {
        /// Time (s).
        t: f64,
        /// Transitions counted.
        events: usize,
        /// The window (s).
        window: f64,
    },
    /// The torque was not a finite number.
    #[error("non-finite torque {tau} at t = {t:.9} s")]
    NonFiniteTorque {
        /// Time (s).
        t: f64,
        /// The torque.
        tau: f64,
    },
    /// The integrator failed.
    #[error("integrator: {0}")]
    Integrator(#[from] OdeError),
    /// A sampled loop's plant was in safe mode at the end of the run: its watchdog saw no valid
    /// torque for `watchdog` periods from `t` on and it held the arm ([`crate::safe`]). Not a
    /// fault of the model: the run went on to its end, as the plant node's does.
    #[error(
        "safe mode from t = {t:.3} s to the end: the plant's watchdog saw no valid torque for \
         {watchdog} periods (none arrived, or all older than --max-age) and held the arm"
    )]
    SafeMode {
        /// When the safe mode was entered, the last time (s).
        t: f64,
        /// The watchdog's limit (periods).
        watchdog: u64,
    },
    /// A fault read back from a report: reports carry a fault as its message text
    /// ([`Fault`]'s serde form), so reading one gives this variant with the message.
    #[error("{0}")]
    Reported(String),
}

/// A fault serialises as its message text (the JSON of every report).
impl serde::Serialize for Fault {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// A fault's message text reads back as [`Fault::Reported`], which displays as the same text.
impl<'de> serde::Deserialize<'de> for Fault {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        String::deserialize(d).map(Fault::Reported)
    }
}

impl Fault {
    /// A short name of the kind of fault: `contact loss`, `fall`, `Zeno guard`,
    /// `non-finite torque`, `integrator failure`, `safe mode` or `reported fault`.
    pub fn kind(&self) -> &'static str {
        match self {
            Fault::ContactLoss { .. } => "contact loss",
            Fault::Fall { .. } => "fall",
            Fault::Zeno { .. } => "Zeno guard",
            Fault::NonFiniteTorque { .. } => "non-finite torque",
            Fault::Integrator(_) => "integrator failure",
            Fault::SafeMode { .. } => "safe mode",
            Fault::Reported(_) => "reported fault",
        }
    }

    /// The simulated time of the fault (s), where the fault records one.
    pub fn time(&self) -> Option<f64> {
        match *self {
            Fault::ContactLoss { t, .. }
            | Fault::Fall { t, .. }
            | Fault::Zeno { t, .. }
            | Fault::NonFiniteTorque { t, .. }
            | Fault::SafeMode { t, .. } => Some(t),
            Fault::Integrator(_) | Fault::Reported(_) => None,
        }
    }
}

/// Receives what happens during a simulation. Every method has an empty default.
pub trait Observer {
    /// A mode transition happened.
    fn transition(&mut self, _ev: &Transition) {}
    /// The joint stuck or started to slide (Coulomb friction only).
    fn joint(&mut self, _ev: &JointEvent) {}
    /// A tilt ended (landing); this was its extreme angle. A run that ends inside a tilt gets
    /// that tilt's peak, if it was reached, from [`Plant::peak_in_progress`].
    fn tilt_peak(&mut self, _peak: &TiltPeak) {}
    /// The state at the end of an accepted step or at an event (before the reset). Not called
    /// for the state an `advance_*` call starts from: an observer that integrates over time
    /// (a time average, say) must take the starting state itself.
    fn sample(&mut self, _t: f64, _mode: Mode, _x: &State) {}
    /// What the sensors gave the controller at a sample `t` (s), in `mode`: noise, encoder and
    /// missing rates included (a sampled loop with [`crate::imperfect::Hardware`]; the plain
    /// loops' controller reads the exact state).
    fn measured(&mut self, _t: f64, _mode: Mode, _y: &crate::imperfect::Measurement) {}
}

impl Observer for () {}

/// Settings of the hybrid simulator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// Physical parameters.
    pub params: Params,
    /// Landing impact law.
    pub impact: ImpactLaw,
    /// Integrator tolerances.
    pub tol: Tolerance,
    /// `|alpha|` (rad) at which the plate counts as fallen; default `pi/2`.
    pub fall_angle: f64,
    /// Zeno guard: at most `zeno_events` transitions within `zeno_window` seconds.
    pub zeno_events: usize,
    /// Zeno guard window (s).
    pub zeno_window: f64,
    /// Largest integration step (s): bounds the spacing of [`Observer::sample`] calls.
    pub h_max: f64,
    /// Event times are located to this width (s).
    pub event_tol: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            params: Params::default(),
            impact: ImpactLaw::Paper,
            tol: Tolerance::default(),
            fall_angle: std::f64::consts::FRAC_PI_2,
            zeno_events: 16,
            zeno_window: 1e-3,
            h_max: f64::INFINITY,
            event_tol: 1e-13,
        }
    }
}

impl SimConfig {
    /// Checks every setting, naming the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        use crate::params::positive;
        self.params.validate()?;
        // Both impact laws divide by M12 (or its striking-edge analogue), whose least value
        // over beta is m_l l_c (l_c - f) + i_l + n_g j_m.
        let p = &self.params;
        let lc = p.lc();
        if p.m_l * lc * (lc - p.f) + p.inertia().1 <= 0.0 {
            return Err(ConfigError::OutOfRange {
                field: "l_c",
                value: format!("{lc} (with f = {}, i_l = {}, j_m = {})", p.f, p.i_l, p.j_m),
                allowed: "such that m_l l_c (l_c - f) + i_l + n_g j_m > 0 (the impact laws \
                          divide by it): l_c > f suffices",
            });
        }
        if p.restitution != 0.0 && self.impact != ImpactLaw::Physical {
            return Err(ConfigError::OutOfRange {
                field: "restitution",
                value: format!("{} (with impact = {})", p.restitution, self.impact.as_str()),
                allowed: "0 unless impact = \"physical\" (only the physical law rebounds)",
            });
        }
        positive("rtol", self.tol.rtol)?;
        positive("atol", self.tol.atol)?;
        positive("fall_angle", self.fall_angle)?;
        positive("zeno_window", self.zeno_window)?;
        positive("event_tol", self.event_tol)?;
        if self.h_max.is_nan() || self.h_max <= 0.0 {
            return Err(ConfigError::OutOfRange {
                field: "h_max",
                value: format!("{}", self.h_max),
                allowed: "> 0 (infinite for none)",
            });
        }
        if self.zeno_events < 2 {
            return Err(ConfigError::OutOfRange {
                field: "zeno_events",
                value: self.zeno_events.to_string(),
                allowed: ">= 2",
            });
        }
        Ok(())
    }
}

/// A torque held constant (zero-order hold).
struct Held(f64);

impl TorqueLaw for Held {
    #[inline]
    fn torque(&self, _t: f64, _mode: Mode, _x: &State) -> f64 {
        self.0
    }
}

/// Number of event functions per mode.
const NG: usize = 5;

/// The hybrid plant: state, mode, clock and integrator memory.
#[derive(Debug, Clone)]
pub struct Plant {
    cfg: SimConfig,
    t: f64,
    mode: Mode,
    x: State,
    stepper: Dop853,
    /// The cheaper stepper of short held-torque intervals (see [`Plant::advance_held`]).
    short: Dopri5,
    /// The shared terms of `(mode, x)` when they are known (from the last step's end): the
    /// next call's first evaluation (the torque changed, the state did not) then skips the
    /// sines and cosines. Keyed by the bits of the state, so a stale entry is never used.
    terms: Option<(Mode, [u64; 4], Terms)>,
    /// Extreme of the tilt in progress, `(t, alpha)`.
    extreme: Option<(f64, f64)>,
    /// Times of the most recent transitions (ring buffer for the Zeno guard).
    recent: Vec<f64>,
    recent_next: usize,
    transitions: u64,
    tilts: u64,
    /// Right-hand-side evaluations, all counted (steps, dense output, event location, checks).
    rhs_evals: u64,
    /// Return after the first transition inside an `advance_*` call.
    stop_at_event: bool,
    /// Held-torque intervals may use the 5th-order stepper ([`Plant::set_short_steps`]).
    short_steps: bool,
    /// The joint's Coulomb-friction phase.
    joint: Joint,
    /// Joint events (stick or slip) so far.
    joint_events: u64,
}

impl Plant {
    /// A plant at time `t0` (s) in `mode` with state `x0`. Flat mode forces `alpha = alpha_dot
    /// = 0`; a tilted mode requires `alpha` on its own side (or zero).
    pub fn new(cfg: SimConfig, t0: f64, mode: Mode, x0: State) -> Result<Self, ConfigError> {
        cfg.validate()?;
        for (field, v) in [
            ("t0", t0),
            ("alpha", x0[0]),
            ("beta", x0[1]),
            ("alpha_dot", x0[2]),
            ("beta_dot", x0[3]),
        ] {
            crate::params::finite(field, v)?;
        }
        let x = x0;
        match mode {
            Mode::Flat if x[0] != 0.0 || x[2] != 0.0 => {
                return Err(ConfigError::OutOfRange {
                    field: "alpha",
                    value: format!("{} (alpha_dot {})", x[0], x[2]),
                    allowed: "alpha = alpha_dot = 0 in mode flat",
                })
            }
            Mode::Left if x[0] < 0.0 => {
                return Err(ConfigError::OutOfRange {
                    field: "alpha",
                    value: x[0].to_string(),
                    allowed: ">= 0 in mode left",
                })
            }
            Mode::Right if x[0] > 0.0 => {
                return Err(ConfigError::OutOfRange {
                    field: "alpha",
                    value: x[0].to_string(),
                    allowed: "<= 0 in mode right",
                })
            }
            _ => {}
        }
        if x[0].abs() >= cfg.fall_angle {
            return Err(ConfigError::OutOfRange {
                field: "alpha",
                value: x[0].to_string(),
                allowed: "|alpha| below the fall angle",
            });
        }
        let mut stepper = Dop853::new(cfg.tol);
        stepper.h_max = cfg.h_max;
        let mut short = Dopri5::new(cfg.tol);
        short.h_max = cfg.h_max;
        Ok(Self {
            cfg,
            t: t0,
            mode,
            x,
            stepper,
            short,
            terms: None,
            extreme: None,
            recent: vec![f64::NEG_INFINITY; cfg.zeno_events],
            recent_next: 0,
            transitions: 0,
            tilts: 0,
            rhs_evals: 0,
            stop_at_event: false,
            short_steps: true,
            // Provisional at rest: the first advance decides it under its torque.
            joint: match (cfg.params.tau_c == 0.0, x[3]) {
                (true, _) => Joint::Free,
                (false, bd) if bd > 0.0 => Joint::Forward,
                (false, bd) if bd < 0.0 => Joint::Backward,
                _ => Joint::Stuck,
            },
            joint_events: 0,
        })
    }

    /// Allows (`true`, the default) or forbids the cheaper 5th-order stepper on held-torque
    /// intervals ([`Plant::advance_held`]). With it forbidden every step is a DOP853 step, as
    /// in [`Plant::advance_continuous`]: slower under a 1 kHz hold, useful as a reference.
    pub fn set_short_steps(&mut self, allowed: bool) {
        self.short_steps = allowed;
    }

    /// The torque (N m) `law` gives at the plant's current time, mode and state: the value of
    /// `law.torque(t, mode, &x)`, computed by [`TorqueLaw::torque_t`] with the shared terms the
    /// plant has at hand from its last step (which are those of `x`, computed the same way, so
    /// the value is the same to the bit). For a sampled controller at each sample instant.
    pub fn torque_now<L: TorqueLaw + ?Sized>(&mut self, law: &L) -> f64 {
        let tm = self.terms_here();
        law.torque_t(self.t, self.mode, &self.x, &self.cfg.params, &tm)
    }

    /// Current time (s).
    pub fn time(&self) -> f64 {
        self.t
    }
    /// Current mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }
    /// Current state `(alpha, beta, alpha_dot, beta_dot)`.
    pub fn state(&self) -> State {
        self.x
    }
    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.cfg
    }
    /// Integrator work counters.
    pub fn stats(&self) -> OdeStats {
        let (a, b) = (self.stepper.stats, self.short.stats);
        OdeStats {
            evals: self.rhs_evals,
            steps: a.steps + b.steps,
            rejected: a.rejected + b.rejected,
            dense: a.dense,
        }
    }
    /// Mode transitions so far.
    pub fn transitions(&self) -> u64 {
        self.transitions
    }
    /// Completed tilts (landings) so far.
    pub fn tilts(&self) -> u64 {
        self.tilts
    }
    /// The joint's Coulomb-friction phase ([`Joint::Free`] without Coulomb friction).
    pub fn joint(&self) -> Joint {
        self.joint
    }
    /// Joint events (the arm stuck or started to slide) so far.
    pub fn joint_events(&self) -> u64 {
        self.joint_events
    }

    /// The peak of the tilt in progress, if `alpha` has already passed an extreme in it: a peak
    /// reached but not yet reported, because [`Observer::tilt_peak`] fires at the landing. A run
    /// that ends (at its duration or by a fault) inside a tilt reports this one as its last
    /// peak. `None` when flat, or while `|alpha|` has only grown since the tilt started.
    pub fn peak_in_progress(&self) -> Option<TiltPeak> {
        if self.mode == Mode::Flat {
            return None;
        }
        self.extreme.map(|(t, alpha)| TiltPeak {
            t,
            mode: self.mode,
            alpha,
        })
    }

    /// Advances to `t_target` (s) with the torque `tau` (N m) held constant (zero-order hold).
    /// In the flat mode the support is checked at once, so a torque step that moves the ZMP
    /// outside the plate tilts it at the current instant.
    pub fn advance_held<O: Observer>(
        &mut self,
        tau: f64,
        t_target: f64,
        obs: &mut O,
    ) -> Result<(), Fault> {
        if !tau.is_finite() {
            return Err(Fault::NonFiniteTorque { t: self.t, tau });
        }
        self.integrate(&Held(tau), t_target, obs, true)
    }

    /// Like [`Plant::advance_held`], but stops right after the first mode transition inside
    /// `(t, t_target)` (the reset applied, the new mode entered, a landing's settling done).
    /// Returns `true` if it stopped there, `false` if it reached `t_target`. A transition at
    /// the starting instant itself (a torque step that tilts the flat plate at once) does not
    /// stop it. Used to sample the state at each mode transition (`--sample-on-event`).
    pub fn advance_held_to_event<O: Observer>(
        &mut self,
        tau: f64,
        t_target: f64,
        obs: &mut O,
    ) -> Result<bool, Fault> {
        if !tau.is_finite() {
            return Err(Fault::NonFiniteTorque { t: self.t, tau });
        }
        self.stop_at_event = true;
        let r = self.integrate(&Held(tau), t_target, obs, true);
        self.stop_at_event = false;
        r.map(|()| self.t < t_target)
    }

    /// Advances to `t_target` (s) with the torque law evaluated inside the right-hand side.
    pub fn advance_continuous<L: TorqueLaw, O: Observer>(
        &mut self,
        law: &L,
        t_target: f64,
        obs: &mut O,
    ) -> Result<(), Fault> {
        self.integrate(law, t_target, obs, false)
    }

    /// The shared terms of the current `(mode, x)`: from the cache when they were computed at
    /// this very state (the end of the last step), else computed now and cached.
    #[inline(always)]
    fn terms_here(&mut self) -> Terms {
        let key = [
            self.x[0].to_bits(),
            self.x[1].to_bits(),
            self.x[2].to_bits(),
            self.x[3].to_bits(),
        ];
        if let Some((m, k, tm)) = &self.terms {
            // Compared word by word: an array comparison is compiled to 16-byte loads of the
            // key just written by 8-byte stores, a store-forwarding stall that cost about 6 %
            // of the held path (perf annotate).
            if *m == self.mode
                && k[0] == key[0]
                && k[1] == key[1]
                && k[2] == key[2]
                && k[3] == key[3]
            {
                return *tm;
            }
        }
        let tm = Terms::new(&self.cfg.params, self.mode, &self.x);
        self.terms = Some((self.mode, key, tm));
        tm
    }

    fn record_transition<O: Observer>(
        &mut self,
        to: Mode,
        x_after: State,
        obs: &mut O,
    ) -> Result<(), Fault> {
        let ev = Transition {
            t: self.t,
            from: self.mode,
            to,
            x_before: self.x,
            x_after,
        };
        obs.transition(&ev);
        self.mode = to;
        self.x = x_after;
        self.transitions += 1;
        self.count_for_zeno()
    }

    /// Counts a transition or joint event at the current time for the Zeno guard.
    fn count_for_zeno(&mut self) -> Result<(), Fault> {
        let n = self.recent.len();
        let oldest = self.recent[self.recent_next];
        self.recent[self.recent_next] = self.t;
        self.recent_next = (self.recent_next + 1) % n;
        if self.t - oldest < self.cfg.zeno_window {
            return Err(Fault::Zeno {
                t: self.t,
                events: n,
                window: self.cfg.zeno_window,
            });
        }
        Ok(())
    }

    /// In the flat mode: checks the contact force and the ZMP for the current torque and tilts
    /// at once if the ZMP lies outside the support.
    fn settle<T: TorqueLaw + ?Sized, O: Observer>(
        &mut self,
        tau_of: &T,
        obs: &mut O,
    ) -> Result<(), Fault> {
        // Each pass either leaves the plate flat, starts a consistent tilt, or records a tilt
        // that is undone at once; the Zeno guard ends a torque law that keeps doing the last.
        self.settle_joint(tau_of, obs)?;
        while self.mode == Mode::Flat {
            let tau = tau_of.torque(self.t, self.mode, &self.x);
            if !tau.is_finite() {
                return Err(Fault::NonFiniteTorque { t: self.t, tau });
            }
            // The right-hand side at the current state (its terms are usually cached).
            let tm = self.terms_here();
            let (add, bdd) =
                joint_accelerations(&self.cfg.params, self.mode, self.joint, &self.x, &tm, tau);
            let xd = State::new(self.x[2], self.x[3], add, bdd);
            self.rhs_evals += 1;
            let g = self.events_t(&self.x, &xd, &tm.trig, || tau);
            if g[2] <= 0.0 {
                return Err(Fault::ContactLoss {
                    t: self.t,
                    mode: self.mode,
                    force: g[2],
                });
            }
            if g[0] < 0.0 {
                self.start_tilt_checked(Mode::Left, tau_of, obs)?;
            } else if g[1] < 0.0 {
                self.start_tilt_checked(Mode::Right, tau_of, obs)?;
            } else {
                break;
            }
            self.settle_joint(tau_of, obs)?;
        }
        Ok(())
    }

    /// With Coulomb friction: decides the joint's phase at the current state under the current
    /// torque ([`Joint::of`]) and records a change. Called wherever the torque or the state
    /// jumps: at each advance's start, after every transition and joint event.
    fn settle_joint<T: TorqueLaw + ?Sized, O: Observer>(
        &mut self,
        tau_of: &T,
        obs: &mut O,
    ) -> Result<(), Fault> {
        if self.cfg.params.tau_c == 0.0 {
            return Ok(());
        }
        let tau = tau_of.torque(self.t, self.mode, &self.x);
        if !tau.is_finite() {
            return Err(Fault::NonFiniteTorque { t: self.t, tau });
        }
        let tm = Terms::new(&self.cfg.params, self.mode, &self.x);
        let to = Joint::of(&self.cfg.params, self.mode, &self.x, &tm, tau);
        if to == self.joint {
            return Ok(());
        }
        let ev = JointEvent {
            t: self.t,
            mode: self.mode,
            from: self.joint,
            to,
            x: self.x,
        };
        obs.joint(&ev);
        self.joint = to;
        self.joint_events += 1;
        self.count_for_zeno()
    }

    /// The state's derivative in the current mode and joint phase under the torque `tau`.
    fn rhs_here(&mut self, tau: f64) -> State {
        let p = &self.cfg.params;
        let tm = Terms::new(p, self.mode, &self.x);
        let (add, bdd) = joint_accelerations(p, self.mode, self.joint, &self.x, &tm, tau);
        self.rhs_evals += 1;
        State::new(self.x[2], self.x[3], add, bdd)
    }

    /// Starts a tilt and checks that the torque law, evaluated in the tilted mode, really lifts
    /// the plate. A law that differs between modes (say, one clipped in one mode only) can put
    /// the flat ZMP outside the support while the tilted dynamics push the plate into the
    /// ground; such a tilt lands again at once (the plate never left the ground) instead of
    /// running through the ground unnoticed.
    fn start_tilt_checked<T: TorqueLaw + ?Sized, O: Observer>(
        &mut self,
        to: Mode,
        tau_of: &T,
        obs: &mut O,
    ) -> Result<(), Fault> {
        self.start_tilt(to, obs)?;
        self.settle_joint(tau_of, obs)?;
        let tau = tau_of.torque(self.t, self.mode, &self.x);
        let xd = self.rhs_here(tau);
        let s = if to == Mode::Left { 1.0 } else { -1.0 };
        // Below this the sign is round-off at a located switch (rad/s^2).
        if s * xd[2] < -1e-9 {
            self.land(obs)?;
        }
        Ok(())
    }

    fn start_tilt<O: Observer>(&mut self, to: Mode, obs: &mut O) -> Result<(), Fault> {
        let mut x = self.x;
        x[0] = 0.0;
        x[2] = 0.0;
        self.extreme = None;
        self.record_transition(to, x, obs)
    }

    fn land<O: Observer>(&mut self, obs: &mut O) -> Result<(), Fault> {
        let from = self.mode;
        if let Some((t, alpha)) = self.extreme.take() {
            obs.tilt_peak(&TiltPeak {
                t,
                mode: from,
                alpha,
            });
        }
        self.tilts += 1;
        let mut xm = self.x;
        xm[0] = 0.0; // located to round-off; the impact happens on the ground
        match self.cfg.impact.land(&self.cfg.params, from, &xm) {
            Landing::Plastic(x_after) => self.record_transition(Mode::Flat, x_after, obs),
            Landing::Rebound(x_after) => {
                // The plate touches (a landing at the rebound's arm rate) and leaves again at
                // once over the same edge: a new tilt, as the orbit's land-and-tilt is.
                let touch = State::new(0.0, x_after[1], 0.0, x_after[3]);
                self.record_transition(Mode::Flat, touch, obs)?;
                self.extreme = None;
                self.record_transition(from, x_after, obs)
            }
            Landing::PassThrough(x_after) => {
                // The touch, then the other tilt at the same instant, already turning.
                let touch = State::new(0.0, x_after[1], 0.0, x_after[3]);
                self.record_transition(Mode::Flat, touch, obs)?;
                self.extreme = None;
                self.record_transition(from.mirrored(), x_after, obs)
            }
        }
    }

    /// `held`: the torque is constant over the call, so intervals that one 5th-order step
    /// covers within the tolerance are taken by the cheaper [`Dopri5`] (events still located on
    /// [`Dop853`]'s dense output).
    fn integrate<T: TorqueLaw + ?Sized, O: Observer>(
        &mut self,
        tau_of: &T,
        t_target: f64,
        obs: &mut O,
        held: bool,
    ) -> Result<(), Fault> {
        self.settle(tau_of, obs)?;
        self.check_tilt_direction(tau_of, obs)?;
        let p = self.cfg.params;
        let evals = std::cell::Cell::new(0u64);
        let result = self.integrate_inner(tau_of, t_target, obs, &p, &evals, held);
        self.rhs_evals += evals.get();
        result
    }

    /// A tilted state at `alpha = 0` whose motion points into the ground (a start given that
    /// way, or a torque step at the very start of a tilt) lands at once instead of running
    /// through the ground unnoticed.
    fn check_tilt_direction<T: TorqueLaw + ?Sized, O: Observer>(
        &mut self,
        tau_of: &T,
        obs: &mut O,
    ) -> Result<(), Fault> {
        let s = match self.mode {
            Mode::Flat => return Ok(()),
            Mode::Left => 1.0,
            Mode::Right => -1.0,
        };
        if s * self.x[0] > 0.0 {
            return Ok(());
        }
        let into_ground = if self.x[2] != 0.0 {
            s * self.x[2] < 0.0
        } else {
            let tau = tau_of.torque(self.t, self.mode, &self.x);
            s * self.rhs_here(tau)[2] < 0.0
        };
        if into_ground {
            self.land(obs)?;
            self.settle(tau_of, obs)?;
        }
        Ok(())
    }

    fn integrate_inner<T: TorqueLaw + ?Sized, O: Observer>(
        &mut self,
        tau_of: &T,
        t_target: f64,
        obs: &mut O,
        p: &Params,
        evals: &std::cell::Cell<u64>,
        held: bool,
    ) -> Result<(), Fault> {
        let p = *p;
        while self.t < t_target {
            let (mode, joint) = (self.mode, self.joint);
            // The start of the current step and its sines and cosines: the 5th-order stepper's
            // inner stages take theirs from these by the angle-sum formulas.
            let tm0 = self.terms_here();
            let base = std::cell::Cell::new((self.x, tm0.trig));
            // Inlined into the stepper's six call sites: as a called function its results went
            // through memory, and each stage waits on the one before (measured: +17 % on the
            // held path).
            let mut f5 = same(
                #[inline(always)]
                |t: f64, x: &State, end: bool| {
                    evals.set(evals.get() + 1);
                    let tm = if end {
                        Terms::new(&p, mode, x)
                    } else {
                        let (x0, tr0) = base.get();
                        Terms::from_trig(&p, mode, x, Trig::near(x, &x0, &tr0))
                    };
                    let tau = tau_of.torque_t(t, mode, x, &p, &tm);
                    let (add, bdd) = joint_accelerations(&p, mode, joint, x, &tm, tau);
                    (State::new(x[2], x[3], add, bdd), tm)
                },
            );
            // DOP853's right-hand side (its steps, dense output and event location): the
            // library's sines and cosines everywhere.
            let mut f = |t: f64, x: &State| {
                evals.set(evals.get() + 1);
                let tm = Terms::new(&p, mode, x);
                let tau = tau_of.torque_t(t, mode, x, &p, &tm);
                let (add, bdd) = joint_accelerations(&p, mode, joint, x, &tm, tau);
                State::new(x[2], x[3], add, bdd)
            };
            evals.set(evals.get() + 1);
            let tau0 = tau_of.torque_t(self.t, mode, &self.x, &p, &tm0);
            let (add, bdd) = joint_accelerations(&p, mode, joint, &self.x, &tm0, tau0);
            let mut f0 = State::new(self.x[2], self.x[3], add, bdd);
            let mut g0 = self.events_t(&self.x, &f0, &tm0.trig, || tau0);
            // The sines and cosines at the current state, when known.
            let mut trig_here = Some(tm0.trig);
            let mut terminal = None;
            while self.t < t_target {
                // A sliver of time left by rounding (a few ulp): finish it with one Euler step
                // rather than asking the stepper for a step below its resolution.
                let rest = t_target - self.t;
                if rest <= 64.0 * f64::EPSILON * self.t.abs().max(1.0) {
                    self.x += f0 * rest;
                    self.t = t_target;
                    break;
                }
                // Under a held torque an interval that one 5th-order step covers (the
                // stepper's memory says so, or it has none yet) is tried with Dopri5 first; a
                // step without a sign change of any event function is kept, one with a sign
                // change is taken again below by Dop853 over the same interval, for its dense
                // output.
                let mut step_end = t_target;
                if held
                    && self.short_steps
                    && (self.short.h_next == 0.0 || rest <= self.short.h_next)
                {
                    let tr = *trig_here.get_or_insert_with(|| Trig::new(&self.x));
                    base.set((self.x, tr));
                    let here = (&mut trig_here, &mut f0, &mut g0);
                    match self.short_step(&mut f5, tau_of, obs, &p, t_target, here)? {
                        None => continue,
                        Some(t1) => step_end = t1,
                    }
                }
                let here = (&mut trig_here, &mut f0, &mut g0);
                if let Some(e) = self.long_step(&mut f, tau_of, obs, step_end, here)? {
                    terminal = Some(e);
                    break;
                }
            }
            let Some(e) = terminal else {
                continue;
            };
            let transitions = self.transitions;
            self.on_event(e, tau_of, obs)?;
            // Stop at a mode transition (a joint event alone does not count).
            if self.stop_at_event && self.transitions != transitions {
                return Ok(());
            }
        }
        Ok(())
    }

    /// Under a held torque, one [`Dopri5`] step from the current state to at most `t_target`
    /// (`f5` the 5th-order stepper's right-hand side, with `p` the plant's parameters): kept
    /// when no event function changes sign in it (the state, `here`'s sines and cosines,
    /// derivative and event values move to its end; `None`), else its end time, for
    /// [`Plant::long_step`] to take the same interval again.
    #[inline(always)]
    fn short_step<F5, T, O>(
        &mut self,
        f5: &mut F5,
        tau_of: &T,
        obs: &mut O,
        p: &Params,
        t_target: f64,
        (trig_here, f0, g0): Here<'_>,
    ) -> Result<Option<f64>, Fault>
    where
        F5: FnMut(f64, &State, bool) -> (State, Terms),
        T: TorqueLaw + ?Sized,
        O: Observer,
    {
        let mode = self.mode;
        let s = self.short.step(f5, self.t, &self.x, f0, t_target)?;
        let g1 = self.events_t(&s.y1, &s.f1, &s.aux1.trig, || {
            tau_of.torque_t(s.t1, mode, &s.y1, p, &s.aux1)
        });
        if (0..NG).any(|i| fires_in(mode != Mode::Flat, i, g0, &g1)) {
            return Ok(Some(s.t1));
        }
        self.t = s.t1;
        self.x = s.y1;
        self.terms = Some((mode, s.y1.map(f64::to_bits).into(), s.aux1));
        *trig_here = Some(s.aux1.trig);
        *f0 = s.f1;
        *g0 = g1;
        obs.sample(self.t, mode, &self.x);
        Ok(None)
    }

    /// One [`Dop853`] step from the current state to at most `step_end` (`f` its right-hand
    /// side): the state moves to the first terminal event inside it (returned, located on the
    /// step's dense output), or else to its end (`here`'s sines and cosines, derivative and
    /// event values with it; `None`).
    #[inline(always)]
    fn long_step<F, T, O>(
        &mut self,
        f: &mut F,
        tau_of: &T,
        obs: &mut O,
        step_end: f64,
        (trig_here, f0, g0): Here<'_>,
    ) -> Result<Option<Ev>, Fault>
    where
        F: Fn(f64, &State) -> State,
        T: TorqueLaw + ?Sized,
        O: Observer,
    {
        let mode = self.mode;
        let step = self.stepper.step(f, self.t, &self.x, f0, step_end)?;
        let tr1 = Trig::new(&step.y1);
        let g1 = self.events_t(&step.y1, step.f1(), &tr1, || {
            tau_of.torque(step.t1, mode, &step.y1)
        });
        let first = if (0..NG).any(|i| fires_in(mode != Mode::Flat, i, g0, &g1)) {
            let dense = self.stepper.dense(f, &step);
            let first = self.first_event(&*f, tau_of, &dense, (step.t0, g0), (step.t1, &g1));
            first.map(|(tr, e)| (tr, e, dense.eval(tr)))
        } else {
            None
        };
        if let Some((tr, e, x)) = first {
            self.t = tr;
            self.x = x;
            obs.sample(self.t, mode, &self.x);
            return Ok(Some(e));
        }
        self.t = step.t1;
        self.x = step.y1;
        *trig_here = Some(tr1);
        *f0 = *step.f1();
        *g0 = g1;
        obs.sample(self.t, mode, &self.x);
        Ok(None)
    }
}

/// The flow's state at the current time besides `(t, x)`, as [`Plant::integrate_inner`] keeps
/// it between steps: the sines and cosines when known, the derivative and the event values.
type Here<'a> = (&'a mut Option<Trig>, &'a mut State, &'a mut [f64; NG]);

/// `f` itself: lets a closure carry `#[inline(always)]` (an attribute on a closure in a `let` is
/// not stable Rust, one on a call argument is).
#[inline(always)]
fn same<F>(f: F) -> F {
    f
}
