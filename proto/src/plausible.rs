//! Plausibility: what a well-formed message must also satisfy to be believed.
//!
//! Validation ([`crate::Message::validate`]) makes a message well-formed: finite numbers, mode
//! bytes in range. A peer can still send a well-formed lie: a state with `seq = 2^63` and
//! `time = 1e300`, a torque of 1e6 N m. These rules are the plant's own, stated once: the plant
//! node applies [`torque`] to every command it receives, and the recorder and the status line of
//! `tilting live` apply all of them to what they receive, so a message the plant would not
//! believe changes neither a recording nor a verdict.
//!
//! - **Physical bounds.** A torque is at most the plant's `--max-torque` (N m) in magnitude; a
//!   state's plate angle is below the fall angle (`|alpha| < fall_angle`, rad: the plant faults
//!   there and publishes no further state).
//! - **Sequence window.** A torque answers a state already published (`seq <= newest`).
//! - **Time window.** The plant samples state `seq` at `t = seq T` (`T`: the control period, s)
//!   and an extra state at a transition inside that period, so a state's, an event's or a
//!   status's `time` lies in `[seq T, (seq + 1) T]` ([`on_grid`]). A real-time plant does not
//!   run ahead of the wall clock: between two messages, `seq` grows by at most the elapsed
//!   wall-clock time over the period, and `time` by at most that time, each plus a slack
//!   ([`within_clock`]).
//! - **Source.** Where the source is known (our publishers attach their session's identity:
//!   [`crate::source`]), a stream is pinned to its first believed source, and a message from
//!   another session is refused while that one keeps talking ([`foreign`]). This catches a
//!   second publisher that does not lie about itself, not a forger (see [`crate::source`]).

use crate::source::{self, SourceId};
use crate::{PlantState, TorqueCommand};

/// Relative tolerance of [`on_grid`] on the period's ends (the plant's times are sums of
/// floating-point steps).
pub const GRID_TOLERANCE: f64 = 1e-9;

/// The shortest control period (s) a plant may run at: 0.1 ms (10 kHz). The plant refuses a
/// shorter `--period`; a receiver that does not know the period bounds jumps with this one.
pub const MIN_PERIOD: f64 = 1e-4;

/// Why a well-formed message is not believed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Implausible {
    /// A torque beyond the plant's bound.
    #[error("TorqueCommand.tau = {tau} N m (seq {seq}) is beyond --max-torque {max} N m")]
    TorqueBeyond {
        /// The command's `seq`.
        seq: u64,
        /// Its torque, N m.
        tau: f64,
        /// The bound, N m.
        max: f64,
    },
    /// A message about a state that was never published.
    #[error("{message}.seq = {seq} is ahead of the newest state, seq {newest}")]
    Ahead {
        /// The message type.
        message: &'static str,
        /// Its `seq`.
        seq: u64,
        /// The newest state's `seq`.
        newest: u64,
    },
    /// A time off the sample grid of its `seq`.
    #[error(
        "{message}.time = {time} s is outside the period of seq {seq}: allowed {lo} to {hi} s"
    )]
    OffGrid {
        /// The message type.
        message: &'static str,
        /// Its `seq`.
        seq: u64,
        /// Its time, s.
        time: f64,
        /// Start of the period, s.
        lo: f64,
        /// End of the period, s.
        hi: f64,
    },
    /// A jump ahead that the wall clock does not allow.
    #[error(
        "{message}.{field} = {value} jumps {jump} past the last believed one after {elapsed:.3} s \
         of wall-clock time (allowed {allowed})"
    )]
    AheadOfClock {
        /// The message type.
        message: &'static str,
        /// `seq` or `time`.
        field: &'static str,
        /// Its value.
        value: f64,
        /// The jump (periods or s).
        jump: f64,
        /// The wall-clock time since the last believed message, s.
        elapsed: f64,
        /// The largest jump allowed (periods or s).
        allowed: f64,
    },
    /// A plate angle at or beyond the fall angle.
    #[error("PlantState.alpha = {alpha} rad is at or beyond the fall angle {limit} rad")]
    BeyondFall {
        /// The angle, rad.
        alpha: f64,
        /// The fall angle, rad.
        limit: f64,
    },
    /// A message from a foreign source: another session than the one the stream is pinned to
    /// ([`crate::source::SourcePin`]).
    #[error(
        "{message} from a foreign source: {}, while the {who} is session {pinned}",
        source::describe(*got)
    )]
    ForeignSource {
        /// The message type.
        message: &'static str,
        /// Whose stream it claims to be: `plant` or `controller`.
        who: &'static str,
        /// The source it names, if any.
        got: Option<SourceId>,
        /// The pinned source.
        pinned: SourceId,
    },
}

impl Implausible {
    /// Is this the refusal of a foreign source?
    pub fn is_foreign(&self) -> bool {
        matches!(self, Self::ForeignSource { .. })
    }
}

/// The pin of `who`'s stream (`plant` or `controller`) admits a `message` from `got`, received
/// at `now`: the [`Implausible::ForeignSource`] refusal of [`source::SourcePin::admits`].
pub fn foreign(
    pin: &source::SourcePin,
    message: &'static str,
    who: &'static str,
    got: Option<SourceId>,
    now: std::time::Instant,
) -> Result<(), Implausible> {
    pin.admits(got, now)
        .map_err(|pinned| Implausible::ForeignSource {
            message,
            who,
            got,
            pinned,
        })
}

/// The plant's rule for a torque command: `|tau| <= max_torque` (N m) and it answers a state
/// already published (`seq <= newest`, the newest state's `seq`).
pub fn torque(cmd: &TorqueCommand, newest: u64, max_torque: f64) -> Result<(), Implausible> {
    if cmd.tau.abs() > max_torque {
        return Err(Implausible::TorqueBeyond {
            seq: cmd.seq,
            tau: cmd.tau,
            max: max_torque,
        });
    }
    ahead("TorqueCommand", cmd.seq, newest)
}

/// A message (`message`: its type) about state `seq` when the newest state is `newest`: not
/// ahead of it.
pub fn ahead(message: &'static str, seq: u64, newest: u64) -> Result<(), Implausible> {
    if seq > newest {
        return Err(Implausible::Ahead {
            message,
            seq,
            newest,
        });
    }
    Ok(())
}

/// The time window of a message about state `seq` at plant time `time` (s) for control period
/// `period` (s): `seq period <= time <= (seq + 1) period`, within [`GRID_TOLERANCE`].
pub fn on_grid(message: &'static str, seq: u64, time: f64, period: f64) -> Result<(), Implausible> {
    let lo = seq as f64 * period;
    let hi = (seq as f64 + 1.0) * period;
    let tol = GRID_TOLERANCE * hi.max(1.0);
    if time < lo - tol || time > hi + tol {
        return Err(Implausible::OffGrid {
            message,
            seq,
            time,
            lo,
            hi,
        });
    }
    Ok(())
}

/// The wall-clock window: after `elapsed` s of wall-clock time since the last believed state
/// `(last_seq, last_time)` (s), a state `(seq, time)` is at most `elapsed / min_period + slack /
/// min_period` periods and `elapsed + slack` s ahead (`min_period`, s: the period, or the
/// shortest the plant allows if it is unknown; `slack`, s: delivery jitter).
pub fn within_clock(
    s: &PlantState,
    last: (u64, f64),
    elapsed: f64,
    min_period: f64,
    slack: f64,
) -> Result<(), Implausible> {
    let allowed_s = elapsed + slack;
    let jump = s.seq.saturating_sub(last.0) as f64;
    let allowed = allowed_s / min_period;
    let err = |field, value: f64, jump: f64, allowed: f64| Implausible::AheadOfClock {
        message: "PlantState",
        field,
        value,
        jump,
        elapsed,
        allowed,
    };
    if jump > allowed {
        return Err(err("seq", s.seq as f64, jump, allowed.floor()));
    }
    let dt = s.time - last.1;
    if dt > allowed_s {
        return Err(err("time", s.time, dt, allowed_s));
    }
    Ok(())
}

/// The physical bound on a state: `|alpha| < fall_angle` (rad).
pub fn state_bounds(s: &PlantState, fall_angle: f64) -> Result<(), Implausible> {
    if s.alpha.abs() >= fall_angle {
        return Err(Implausible::BeyondFall {
            alpha: s.alpha,
            limit: fall_angle,
        });
    }
    Ok(())
}

/// The rules on the stream of states one receiver believes: the wall-clock window
/// ([`within_clock`]) against the newest believed state, the period's time grid ([`on_grid`])
/// when the period is known, and the fall angle ([`state_bounds`]). The front door's recorder
/// and the controller node each keep one, so a forged state (`seq = 2^63`, `time = 1e300`)
/// moves neither a recording nor a controller's estimator.
///
/// Only jumps *ahead* are bounded: an old or repeated state is believed (it is late, not a lie)
/// and does not move the newest. A plant in lockstep runs ahead of the wall clock, but one
/// period per state, well inside `slack`.
#[derive(Debug, Clone)]
pub struct StateWindow {
    /// The control period (s), if known: then times must lie on its grid.
    pub period: Option<f64>,
    /// The shortest control period the plant allows (s), for the wall-clock window while the
    /// period is unknown.
    pub min_period: f64,
    /// The plant's fall angle (rad).
    pub fall_angle: f64,
    /// Delivery slack of the wall-clock window (s).
    pub slack: f64,
    /// The receiver started with the plant (seq 0 at `started`); otherwise the first state is
    /// believed as it comes, as by a receiver that joins a running robot.
    pub from_start: bool,
    started: std::time::Instant,
    /// `(seq, time, when)` of the newest believed state.
    last: Option<(u64, f64, std::time::Instant)>,
    /// `(seq, time, when)` of the origin: state 0 at the start ([`Self::from_start`]) or the
    /// first believed state.
    origin: Option<(u64, f64, std::time::Instant)>,
}

impl StateWindow {
    /// A window that starts now (see the fields for the arguments).
    pub fn new(
        period: Option<f64>,
        min_period: f64,
        fall_angle: f64,
        slack: f64,
        from_start: bool,
    ) -> Self {
        Self {
            period,
            min_period,
            fall_angle,
            slack,
            from_start,
            started: std::time::Instant::now(),
            last: None,
            origin: None,
        }
    }

    fn step(&self) -> f64 {
        self.period.unwrap_or(self.min_period)
    }

    /// The newest `seq` a message may speak of at `now`: the newest believed state's, plus
    /// what the wall clock allows since it (with the slack); `u64::MAX` before any state when
    /// not [`Self::from_start`].
    pub fn newest(&self, now: std::time::Instant) -> u64 {
        let (seq, since) = match self.last {
            Some((seq, _, at)) => (seq, at),
            None if self.from_start => (0, self.started),
            None => return u64::MAX,
        };
        let periods = (now.duration_since(since).as_secs_f64() + self.slack) / self.step();
        seq.saturating_add(periods as u64)
    }

    /// Whether state `s`, received at `now`, is believed; a believed state newer than the
    /// newest becomes the newest ([`Self::test`], then [`Self::believe`]).
    pub fn check(&mut self, s: &PlantState, now: std::time::Instant) -> Result<(), Implausible> {
        self.test(s, now)?;
        self.believe(s, now);
        Ok(())
    }

    /// Whether state `s`, received at `now`, passes the window, without believing it (a
    /// receiver with further rules, such as the source's, believes it after them).
    pub fn test(&self, s: &PlantState, now: std::time::Instant) -> Result<(), Implausible> {
        let origin = match self.origin {
            Some(o) => Some(o),
            None if self.from_start => Some((0, 0.0, self.started)),
            None => None,
        };
        // Within the clock since the newest believed state (a lockstep plant runs ahead of the
        // wall clock one period per state), or since the origin (a real-time plant never
        // does): the second keeps a receiver that stalled, then believed a backlog of old
        // states late, from refusing every fresh state after it.
        let within = |anchor: Option<(u64, f64, std::time::Instant)>| match anchor {
            Some((seq, time, at)) => {
                let elapsed = now.saturating_duration_since(at).as_secs_f64();
                within_clock(s, (seq, time), elapsed, self.step(), self.slack)
            }
            None => Ok(()),
        };
        within(self.last.or(origin)).or_else(|e| within(origin).map_err(|_| e))?;
        if let Some(p) = self.period {
            on_grid("PlantState", s.seq, s.time, p)?;
        }
        state_bounds(s, self.fall_angle)
    }

    /// State `s`, received at `now`, is believed: if newer than the newest, it becomes the
    /// newest.
    pub fn believe(&mut self, s: &PlantState, now: std::time::Instant) {
        if self.origin.is_none() && !self.from_start {
            self.origin = Some((s.seq, s.time, now));
        }
        if self.last.is_none_or(|l| s.seq > l.0) {
            self.last = Some((s.seq, s.time, now));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(seq: u64, time: f64) -> PlantState {
        PlantState {
            seq,
            time,
            alpha: 0.01,
            beta: 1.5,
            alpha_dot: Some(0.0),
            beta_dot: Some(0.0),
            mode: 1,
        }
    }

    #[test]
    fn the_forged_state_of_issue_22_breaks_every_window() {
        let forged = state(1 << 63, 1e300);
        let e = on_grid("PlantState", forged.seq, forged.time, 1e-3).unwrap_err();
        assert!(e.to_string().contains("outside the period"), "{e}");
        // On the grid but ahead of the clock: 2^63 periods after 5 s.
        let on = state(1 << 63, (1u64 << 63) as f64 * 1e-3);
        assert!(on_grid("PlantState", on.seq, on.time, 1e-3).is_ok());
        let e = within_clock(&on, (5000, 5.0), 0.1, 1e-3, 1.0).unwrap_err();
        assert!(e.to_string().contains("seq"), "{e}");
    }

    #[test]
    fn the_plants_own_samples_pass() {
        let t = 1e-3;
        for k in [0u64, 1, 999, 1_000_000] {
            // Periodic samples, summed as the plant sums them, and an extra one mid-period.
            let summed =
                (0..k.min(2000)).fold(0.0, |a, _| a + t) + (k.saturating_sub(2000)) as f64 * t;
            assert!(on_grid("PlantState", k, summed, t).is_ok(), "{k}");
            assert!(on_grid("PlantState", k, (k as f64 + 0.5) * t, t).is_ok());
            assert!(on_grid("PlantState", k, (k as f64 + 1.01) * t, t).is_err());
            assert!(on_grid("PlantState", k + 1, k as f64 * t, t).is_err());
        }
        // The clock: 1,000 periods after 1 s with 0.1 s slack, not 1,200.
        assert!(within_clock(&state(1000, 1.0), (0, 0.0), 1.0, t, 0.1).is_ok());
        assert!(within_clock(&state(1200, 1.2), (0, 0.0), 1.0, t, 0.1).is_err());
        // A time jump with a plausible seq (an unknown period): refused by the time rule.
        assert!(within_clock(&state(10, 50.0), (0, 0.0), 1.0, 1e-4, 0.1).is_err());
        // Torques: the bound and the sequence window.
        let c = |seq, tau| TorqueCommand { seq, tau };
        assert!(torque(&c(5, 116.5), 5, 116.5).is_ok());
        assert!(matches!(
            torque(&c(5, -116.6), 5, 116.5),
            Err(Implausible::TorqueBeyond { .. })
        ));
        assert!(matches!(
            torque(&c(6, 1.0), 5, 116.5),
            Err(Implausible::Ahead { .. })
        ));
        assert!(state_bounds(&state(1, 1e-3), std::f64::consts::FRAC_PI_2).is_ok());
        let mut fallen = state(1, 1e-3);
        fallen.alpha = -1.6;
        assert!(state_bounds(&fallen, std::f64::consts::FRAC_PI_2).is_err());
    }

    #[test]
    fn a_window_believes_a_fast_lockstep_plant_and_not_the_forgery() {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let now = std::time::Instant::now();
        // Joins a running robot: the first state is believed as it comes.
        let mut w = StateWindow::new(None, 1e-4, half_pi, 1.0, false);
        assert_eq!(w.newest(now), u64::MAX);
        assert!(w.check(&state(5000, 5.0), now).is_ok());
        // A lockstep plant: 10,000 states in no wall-clock time at all, one period apart.
        for k in 5001..15_000u64 {
            assert!(w.check(&state(k, k as f64 * 1e-3), now).is_ok(), "{k}");
        }
        // The forged state, then one on the grid but far ahead: refused, and the newest stays.
        assert!(w.check(&state(1 << 63, 1e300), now).is_err());
        let ahead = 14_999 + 20_000; // 2 s of 1 kHz states after no wall-clock time (1 s slack)
        assert!(w.check(&state(ahead, ahead as f64 * 1e-3), now).is_err());
        assert!(w.check(&state(15_000, 15.0), now).is_ok());
        // An old state is late, not a lie.
        assert!(w.check(&state(10, 0.01), now).is_ok());
        // A receiver that stalled: it believed states to t = 2 s, then, 10 s later, a backlog
        // of old states (t = 2.1 s) late; fresh states (t = 12 s) are within the clock since
        // the origin, though 10 s past the newest believed one after no wall-clock time.
        let t0 = now;
        let mut r = StateWindow::new(Some(1e-3), 1e-4, half_pi, 1.0, true);
        let at = |s: f64| t0 + std::time::Duration::from_secs_f64(s);
        assert!(r.check(&state(2000, 2.0), at(2.0)).is_ok());
        assert!(r.check(&state(2100, 2.1), at(12.0)).is_ok());
        assert!(r.check(&state(12_000, 12.0), at(12.004)).is_ok());
        // ... and the forged state is still refused by both anchors.
        assert!(r
            .check(&state(1 << 63, (1u64 << 63) as f64 * 1e-3), at(12.005))
            .is_err());
        assert!(r.check(&state(40_000, 40.0), at(12.005)).is_err());
        // The period known: off the grid is refused.
        let mut g = StateWindow::new(Some(1e-3), 1e-4, half_pi, 1.0, false);
        assert!(g.check(&state(10, 0.0105), now).is_ok());
        assert!(g.check(&state(11, 0.0125), now).is_err());
    }
}
