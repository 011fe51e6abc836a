//! The torque inbox: shared by the zenoh callbacks, which put the answers in, and the pacing
//! thread, which takes them out at each deadline.

use super::*;

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
    pub(super) torques: DropCounter,
    pub(super) stale: AtomicU64,
    pub(super) controller_alive: AtomicBool,
    /// Set when the controller's token disappears; consumed by the pacing thread.
    pub(super) controller_gone: AtomicBool,
    pub(super) stop: AtomicBool,
    /// Torques beyond this magnitude (N m) are refused (`--max-torque`).
    pub(super) max_torque: f64,
}

impl Shared {
    pub(super) fn on_torque(&self, bytes: &[u8]) {
        let Some(cmd) = self.torques.decode::<TorqueCommand>(bytes) else {
            return;
        };
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

    pub(super) fn wake(&self) {
        let _guard = self.inbox.lock().unwrap_or_else(|e| e.into_inner());
        self.cv.notify_all();
    }
}
