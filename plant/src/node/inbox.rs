//! The torque inbox: shared by the zenoh callbacks, which put the answers in, and the pacing
//! thread, which takes them out at each deadline.

use super::*;
use tilting_proto::{SourceId, SourcePin};

/// State shared by the zenoh callbacks and the pacing thread.
pub(super) struct Shared {
    /// The newest valid torque received (the highest `seq`, never above the current state's),
    /// with its arrival time (ns). Real time peeks at it at each deadline; lockstep takes it.
    pub(super) inbox: Mutex<Option<(TorqueCommand, u64)>>,
    /// Valid torques that arrived after a newer one (dropped).
    pub(super) reordered: AtomicU64,
    pub(super) cv: Condvar,
    /// `seq` of the last published state.
    pub(super) current_seq: AtomicU64,
    /// When it was published, wall clock (ns since the Unix epoch): `--ros2` commands carry a
    /// wall-clock source timestamp.
    pub(super) published_wall_ns: std::sync::atomic::AtomicI64,
    pub(super) torques: DropCounter,
    pub(super) stale: AtomicU64,
    pub(super) controller_alive: AtomicBool,
    /// When the controller's token disappeared (`clock::now_ns`), 0 while one is alive (or
    /// before any was seen). Whether that is a controller gone or a link renegotiated is the
    /// pacing thread's verdict ([`token_verdict`]).
    pub(super) controller_lost_at: AtomicU64,
    /// Times the controller's token disappeared, renegotiated links included.
    pub(super) token_losses: AtomicU64,
    pub(super) stop: AtomicBool,
    /// Torques beyond this magnitude (N m) are refused (`--max-torque`).
    pub(super) max_torque: f64,
    /// The controller's session, pinned by the first torque believed; it lapses after
    /// `--watchdog` periods of silence (a restarted controller is a new session).
    pub(super) controller: Mutex<SourcePin>,
    /// Plausible torques refused because another session than the controller's sent them.
    pub(super) foreign: AtomicU64,
}

/// Where a torque came in.
#[derive(Debug, Clone, Copy)]
pub(super) enum Ingress {
    /// Over zenoh, from the source the sample names (`None`: it names none).
    Zenoh(Option<SourceId>),
    /// `--ros2`'s `effort_command` (its own checks; no pin).
    Ros2,
}

impl Shared {
    pub(super) fn on_torque(&self, bytes: &[u8], source: Option<SourceId>) {
        let Some(cmd) = self.torques.decode::<TorqueCommand>(bytes) else {
            return;
        };
        self.on_torque_command(cmd, Ingress::Zenoh(source));
    }

    /// A decoded torque (the controller's, or a ROS 2 `effort_command`'s): the plausibility
    /// rules, the source's pin, then the inbox.
    pub(super) fn on_torque_command(&self, cmd: TorqueCommand, ingress: Ingress) {
        // A torque that decodes can still be a lie: the plausibility rules of
        // `tilting_proto::plausible`, which the recorder of `tilting live` applies too. Beyond
        // the bound it is refused, counted with the malformed ones and logged at a bounded rate;
        // an answer to a state never published is counted as stale.
        let newest = self.current_seq.load(Ordering::Acquire);
        match tilting_proto::plausible::torque(&cmd, newest, self.max_torque) {
            Ok(()) => {}
            Err(e @ tilting_proto::Implausible::TorqueBeyond { .. }) => {
                self.torques.record_drop(&e);
                return;
            }
            Err(_) => {
                self.stale.fetch_add(1, Ordering::Relaxed);
                return;
            }
        }
        // Then its source: the controller's session, where known (`tilting_proto::source`).
        if let Ingress::Zenoh(source) = ingress {
            let at = Instant::now();
            let mut pin = self.controller.lock().unwrap_or_else(|e| e.into_inner());
            let who = "controller";
            if let Err(e) =
                tilting_proto::plausible::foreign(&pin, "TorqueCommand", who, source, at)
            {
                drop(pin);
                let n = self.foreign.fetch_add(1, Ordering::Relaxed) + 1;
                if n.is_power_of_two() {
                    tracing::warn!("torque refused ({n} so far): {e}");
                }
                return;
            }
            pin.believe(source, at);
        }
        let now = clock::now_ns();
        let mut inbox = self.inbox.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((c, _)) = *inbox {
            if cmd.seq == c.seq {
                // A second answer to the same state: keep the first.
                self.stale.fetch_add(1, Ordering::Relaxed);
                return;
            }
            if cmd.seq < c.seq {
                // Overtaken by a newer answer on the way: too old to use.
                self.reordered.fetch_add(1, Ordering::Relaxed);
                return;
            }
        }
        *inbox = Some((cmd, now));
        drop(inbox);
        self.cv.notify_all();
    }

    /// The controller's token changed (`alive`): keeps the time of a loss and wakes the pacing
    /// thread.
    pub(super) fn on_controller_token(&self, alive: bool) {
        self.controller_alive.store(alive, Ordering::Release);
        if alive {
            self.controller_lost_at.store(0, Ordering::Release);
        } else {
            self.token_losses.fetch_add(1, Ordering::Relaxed);
            self.controller_lost_at
                .store(clock::now_ns().max(1), Ordering::Release);
        }
        self.wake();
    }

    /// When the controller's token disappeared (ns), if it is gone now.
    pub(super) fn controller_lost_at(&self) -> Option<u64> {
        Some(self.controller_lost_at.load(Ordering::Acquire)).filter(|&t| t != 0)
    }

    pub(super) fn wake(&self) {
        let _guard = self.inbox.lock().unwrap_or_else(|e| e.into_inner());
        self.cv.notify_all();
    }
}

/// "Peer gone" or "link renegotiated": is the controller gone, `now` (ns), given when its
/// liveliness token disappeared (`lost_at`, `None` while it is alive), when the newest torque
/// taken into force arrived (`last_answer`, `None` if none yet) and the bound `grace` (ns)?
///
/// A token disappears when the controller's process ends, and also when its zenoh transport
/// closes and reopens (a link renegotiated: the token is deleted and declared again within a
/// few ms). Only the first is a controller gone. So the controller counts as gone once its
/// token has been absent for `grace` **and** no torque has arrived for `grace`; a token back
/// within `grace`, or torques still arriving, are a renegotiated link, and the loop goes on
/// (the `--max-age` rule and the `--watchdog` count still apply to the torques themselves).
pub(super) fn token_verdict(
    lost_at: Option<u64>,
    last_answer: Option<u64>,
    now: u64,
    grace: u64,
) -> bool {
    let Some(lost) = lost_at else {
        return false;
    };
    let quiet = last_answer.is_none_or(|t| now.saturating_sub(t) >= grace);
    now.saturating_sub(lost) >= grace && quiet
}

#[cfg(test)]
mod tests {
    use super::token_verdict;

    const MS: u64 = 1_000_000;

    #[test]
    fn a_token_back_within_the_bound_is_a_renegotiated_link() {
        let grace = 10 * MS;
        // Present: never gone, whatever the torques do.
        assert!(!token_verdict(None, None, 100 * MS, grace));
        assert!(!token_verdict(None, Some(0), 100 * MS, grace));
        // Lost 4 ms ago (a reconnect in progress), torques stopped 4 ms ago: not yet.
        assert!(!token_verdict(
            Some(96 * MS),
            Some(96 * MS),
            100 * MS,
            grace
        ));
        // Lost 50 ms ago but torques still arrive (1 ms ago): the controller is there.
        assert!(!token_verdict(
            Some(50 * MS),
            Some(99 * MS),
            100 * MS,
            grace
        ));
        // Lost exactly `grace` ago and no torque since: gone.
        assert!(token_verdict(Some(90 * MS), Some(90 * MS), 100 * MS, grace));
        // Lost long ago, never answered: gone.
        assert!(token_verdict(Some(10 * MS), None, 100 * MS, grace));
        // One nanosecond short of the bound on either clock: not gone.
        assert!(!token_verdict(Some(90 * MS + 1), Some(0), 100 * MS, grace));
        assert!(!token_verdict(Some(1), Some(90 * MS + 1), 100 * MS, grace));
    }
}
