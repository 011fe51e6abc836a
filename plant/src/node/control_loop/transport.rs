//! The two ways the plant node's loop meets its controller, as [`Transport`]s of the sampled
//! driver ([`crate::sampled::run`]): lockstep (one period per answer) and real time (one period
//! per deadline).

use super::*;

/// The lockstep transport: the state goes out on zenoh and the plant waits for its answer
/// (or, over emulated links, hands it to the hold that picks the torque in force, as
/// `simulate` does with the same flags).
pub(super) struct Lockstep<'a>(pub(super) &'a mut Loop);

impl Transport for Lockstep<'_> {
    type Observer = Obs;

    fn parts(&mut self) -> (&mut Plant, &mut Actuator, &mut Obs) {
        let lp = &mut *self.0;
        (&mut lp.plant, &mut lp.hw.actuator, &mut lp.obs)
    }

    fn sample(&mut self, _k: u64) -> Option<f64> {
        let lp = &mut *self.0;
        if lp.shared.stop.load(Ordering::Acquire) {
            return None;
        }
        let timeout = Duration::from_millis(lp.args.lockstep_timeout_ms);
        let wait = if lp.status_state == Status::SAFE_MODE {
            SAFE_MODE_POLL.min(timeout)
        } else {
            timeout
        };
        let fresh = lp.wait_fresh(wait);
        if lp.shared.stop.load(Ordering::Acquire) {
            return None;
        }
        let fresh_tau = fresh.map(|(c, _)| c.tau);
        let mut tau = lp.choose_torque(fresh, true);
        if let (Some(answer), Some(hold)) = (fresh_tau, lp.hold.as_mut()) {
            // The answer crosses the emulated links; the hold picks the torque in force,
            // as `simulate` does with the same flags.
            tau = hold.step(lp.seq, lp.plant.time(), || answer);
            if lp.args.torque_limit > 0.0 {
                tau = tau.clamp(-lp.args.torque_limit, lp.args.torque_limit);
            }
        }
        Some(lp.begin_period(tau))
    }

    fn samples_events(&self) -> bool {
        self.0.args.sample_on_event
    }

    fn extra(&mut self, _k: u64) {
        self.0.extra_state();
    }

    fn torque_at(&mut self, _k: u64, _t: f64) -> Option<f64> {
        self.0.event_answer.take()
    }

    fn period_end(&mut self, _k: u64, last: bool, result: &Result<(), Fault>) {
        self.0.end_period(result);
        if result.is_ok() && !last {
            self.0.maybe_status();
        }
    }
}

/// The real-time transport: the plant sleeps to the period's deadline on the wall clock, then
/// takes the answer to the state of the period that just ended, or the newest valid torque.
pub(super) struct Realtime<'a> {
    pub(super) lp: &'a mut Loop,
    /// The period (ns).
    pub(super) h_ns: f64,
    /// The spin before each deadline (ns).
    pub(super) spin: u64,
    /// Wall-clock start (ns).
    pub(super) start: u64,
    /// Whether [`Transport::sample`] sleeps to the deadline (else the caller has: host mode's
    /// one pacing thread, [`Loop::run_all_realtime`]).
    pub(super) paced: bool,
}

impl Transport for Realtime<'_> {
    type Observer = Obs;

    fn parts(&mut self) -> (&mut Plant, &mut Actuator, &mut Obs) {
        let lp = &mut *self.lp;
        (&mut lp.plant, &mut lp.hw.actuator, &mut lp.obs)
    }

    fn sample(&mut self, k: u64) -> Option<f64> {
        if self.lp.shared.stop.load(Ordering::Acquire) {
            return None;
        }
        let deadline = self.start + ((k + 1) as f64 * self.h_ns).round() as u64;
        let woke = if self.paced {
            clock::sleep_until(deadline, self.spin)
        } else {
            clock::now_ns()
        };
        self.lp.jitter.push((woke - deadline) as f64 * 1e-3);
        let newest = self.lp.take_newest();
        let tau = self.lp.choose_torque(newest, false);
        Some(self.lp.begin_period(tau))
    }

    fn samples_events(&self) -> bool {
        self.lp.args.sample_on_event
    }

    fn extra(&mut self, _k: u64) {
        self.lp.extra_state();
    }

    fn torque_at(&mut self, _k: u64, _t: f64) -> Option<f64> {
        self.lp.event_answer.take()
    }

    fn period_end(&mut self, k: u64, last: bool, result: &Result<(), Fault>) {
        self.lp.end_period(result);
        if result.is_err() || last {
            return;
        }
        let done = clock::now_ns();
        let next_deadline = self.start + ((k + 2) as f64 * self.h_ns).round() as u64;
        if done > next_deadline {
            self.lp.overruns += 1;
            let o = (done - next_deadline) as f64 * 1e-3;
            if o > self.lp.step_overrun_max {
                self.lp.step_overrun_max = o;
            }
        }
        self.lp.maybe_status();
    }
}
