//! What every ROS 2 route shares, whatever carries it (zenoh in rmw_zenoh's conventions, or
//! DDS): the loop's non-blocking queue to a mirror thread of its own at a lower priority, the
//! sinks that thread publishes to, and the judging and counting of `effort_command`s.

use crate::attachment::Attachment;
use crate::robot::{EffortCommand, FloodGate, Refusal};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use tilting_proto::{ModeEvent, PlantState, Status};

/// Wall-clock time, ns since the Unix epoch (the source timestamps of commands).
pub fn wall_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// What the mirror publishes.
#[derive(Debug, Clone)]
pub enum Input {
    /// A state, with the torque in force (N m) if known.
    State(PlantState, Option<f64>),
    /// A mode transition.
    Event(ModeEvent),
    /// A status.
    Status(Status),
}

/// The counters of a mirror.
#[derive(Debug, Default)]
pub struct MirrorCounts {
    /// Inputs handed to the mirror.
    pub sent: AtomicU64,
    /// Inputs dropped because the mirror's queue was full (the loop never waits for it).
    pub dropped: AtomicU64,
    /// Samples published.
    pub published: AtomicU64,
}

/// The loop's end of a mirror: [`MirrorTx::send`] never blocks.
#[derive(Clone)]
pub struct MirrorTx {
    tx: SyncSender<Input>,
    counts: Arc<MirrorCounts>,
}

impl MirrorTx {
    /// Hands `input` to the mirror's thread, or drops it (counted) when its queue is full.
    pub fn send(&self, input: Input) {
        self.counts.sent.fetch_add(1, Ordering::Relaxed);
        if let Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) = self.tx.try_send(input)
        {
            self.counts.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// The counters.
    pub fn counts(&self) -> &MirrorCounts {
        &self.counts
    }
}

/// A route the mirror thread publishes on (the zenoh mirror, the DDS mirror).
pub trait Sink: Send {
    /// Publishes what `input` becomes in ROS 2; false if nothing was published.
    fn publish(&mut self, input: &Input) -> bool;
}

/// Runs `sinks` on one thread of their own at [`MIRROR_NICE`], fed by a queue of `capacity`
/// inputs; every input goes to every sink in order. The thread ends when every [`MirrorTx`] is
/// dropped.
pub fn spawn(mut sinks: Vec<Box<dyn Sink>>, capacity: usize) -> std::io::Result<MirrorTx> {
    let (tx, rx): (SyncSender<Input>, Receiver<Input>) = sync_channel(capacity);
    let counts = Arc::new(MirrorCounts::default());
    let c = counts.clone();
    std::thread::Builder::new()
        .name("ros2-mirror".into())
        .spawn(move || {
            lower_priority();
            while let Ok(i) = rx.recv() {
                for s in sinks.iter_mut() {
                    if s.publish(&i) {
                        c.published.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        })?;
    Ok(MirrorTx { tx, counts })
}

/// Nice value of the mirror's thread: under CPU contention the plant's pacing thread (nice 0)
/// runs first, and the mirror catches up from its queue.
pub const MIRROR_NICE: i32 = 10;

/// Lowers the calling thread's scheduling priority to [`MIRROR_NICE`] (Linux: a thread is a
/// task with its own nice value); best effort, elsewhere nothing.
pub fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: plain system calls on the calling thread's own id; no memory is passed.
    unsafe {
        let tid = libc::gettid();
        if libc::setpriority(libc::PRIO_PROCESS, tid as libc::id_t, MIRROR_NICE) != 0 {
            tracing::debug!("ROS 2 mirror: cannot lower the thread's priority");
        }
    }
}

/// Counts of an `effort_command` subscription, by outcome (the plant's summary `ros2`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct EffortCounts {
    /// Samples received.
    pub received: u64,
    /// Commands passed on to the loop.
    pub accepted: u64,
    /// Refused: no or a malformed attachment (zenoh), no source timestamp (DDS).
    pub no_attachment: u64,
    /// Refused: not a `Float64MultiArray` or not exactly one value.
    pub malformed: u64,
    /// Refused: NaN, infinite or beyond `--max-torque`.
    pub out_of_bounds: u64,
    /// Refused: source timestamp older than `--max-age` periods.
    pub stale: u64,
    /// Refused: source timestamp in the future.
    pub future: u64,
    /// Refused: beyond the flood gate's rate.
    pub flood: u64,
}

impl EffortCounts {
    fn count(&mut self, r: &Refusal) {
        match r {
            Refusal::Attachment(_) | Refusal::NoTimestamp => self.no_attachment += 1,
            Refusal::Cdr(_) | Refusal::Length(_) => self.malformed += 1,
            Refusal::NotFinite(_) | Refusal::Beyond { .. } => self.out_of_bounds += 1,
            Refusal::Stale { .. } => self.stale += 1,
            Refusal::Future { .. } => self.future += 1,
            Refusal::Flood(..) => self.flood += 1,
        }
    }
}

/// The judge of one `effort_command` subscription: the flood gate first, then the checks the
/// caller runs, every outcome counted, refusals logged at most once a second.
pub struct EffortJudge {
    counts: Arc<Mutex<EffortCounts>>,
    gate: Mutex<FloodGate>,
    last_log: Mutex<Option<std::time::Instant>>,
}

impl EffortJudge {
    /// A judge with `gate`.
    pub fn new(gate: FloodGate) -> Self {
        Self {
            counts: Arc::default(),
            gate: Mutex::new(gate),
            last_log: Mutex::new(None),
        }
    }

    /// Judges one sample received at `now_ns` (wall clock): the flood gate, then `check`.
    pub fn judge(
        &self,
        now_ns: i64,
        check: impl FnOnce() -> Result<EffortCommand, Refusal>,
    ) -> Option<EffortCommand> {
        let admitted = self
            .gate
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .admit(now_ns);
        let verdict = admitted.and_then(|()| check());
        let mut k = self.counts.lock().unwrap_or_else(|e| e.into_inner());
        k.received += 1;
        match verdict {
            Ok(cmd) => {
                k.accepted += 1;
                Some(cmd)
            }
            Err(r) => {
                k.count(&r);
                drop(k);
                let mut l = self.last_log.lock().unwrap_or_else(|e| e.into_inner());
                if l.is_none_or(|t| t.elapsed().as_secs() >= 1) {
                    tracing::warn!("refused: {r}");
                    *l = Some(std::time::Instant::now());
                }
                None
            }
        }
    }

    /// The counts so far.
    pub fn counts(&self) -> EffortCounts {
        self.counts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// An attachment as DDS delivers its parts (sample info): the writer's sequence number, the
/// source timestamp (none when the writer sent none) and the writer's GUID.
pub fn dds_attachment(
    seq: i64,
    source_timestamp_ns: Option<i64>,
    gid: [u8; 16],
) -> Option<Attachment> {
    source_timestamp_ns.map(|ts| Attachment {
        seq,
        source_timestamp_ns: ts,
        gid,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::{check_effort, EffortLimits};

    #[test]
    fn the_judge_counts_every_outcome_once() {
        let j = EffortJudge::new(FloodGate::new(1000, 2));
        let limits = EffortLimits {
            max_torque: 1.0,
            max_age_ns: 1_000_000,
            max_lead_ns: 1_000_000,
        };
        let ok = j.judge(0, || {
            check_effort(
                &crate::msgs::encode(&crate::msgs::Float64MultiArray {
                    layout: Default::default(),
                    data: vec![0.5],
                }),
                Some(&dds_attachment(1, Some(0), [1; 16]).unwrap().encode()),
                0,
                &limits,
            )
        });
        assert_eq!(ok.map(|c| c.tau), Some(0.5));
        assert!(j.judge(0, || Err(Refusal::Length(2))).is_none());
        // The gate's burst of 2 is spent: the check is not even run.
        assert!(j
            .judge(0, || panic!("the flood gate refuses before the checks"))
            .is_none());
        let c = j.counts();
        assert_eq!(
            (c.received, c.accepted, c.malformed, c.flood),
            (3, 1, 1, 1),
            "{c:?}"
        );
        assert_eq!(dds_attachment(1, None, [0; 16]), None);
    }
}
