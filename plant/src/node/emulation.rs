//! Emulated links on the wall clock: the real-time plant with `--delay`, `--jitter`, `--loss`
//! or `--loss-burst`.
//!
//! The draws are those of the offline emulator (`tilting_link::Link`, ChaCha8 seeded with
//! `(--seed, 0)` for the states and `(--seed, 1)` for the torques): each state the plant
//! publishes and each torque message it receives takes the next draw of its direction's stream,
//! which says whether it is lost and how long it is delayed. A delayed message waits in a
//! deadline queue (a binary heap) served by one thread that sleeps with the plant's own
//! absolute-deadline sleep (`clock::sleep_until`: a kernel wait to `--spin-us` before the
//! deadline, then a spin), and is then published (a state) or handed to the torque inbox (a
//! torque, where the age rule of `--max-age` applies to it as to any late answer). A message
//! without delay is passed on at once, on the caller's thread.
//!
//! What is exact: which messages are lost, and the delay each one is given, message by message
//! in the order they are sent. What is approximate: the instant a delayed message is handed on,
//! which is its due time plus the wake-up latency of the queue's thread (measured, reported as
//! `delivery_late_us`), and the order of the draws, which follows the wall-clock order of the
//! messages (re-publications of state 0 while the plant waits for its controller take draws too).

use super::*;
use std::cmp::{Ordering as CmpOrdering, Reverse};
use std::collections::BinaryHeap;
use std::thread::JoinHandle;
use tilting_link::{Impairment, Link};

use super::stats::Ring;
use super::summary::LinkEmulation;

/// A message on its way.
enum Item {
    State(PlantState),
    /// The payload and the source the sample named.
    Torque(Vec<u8>, Option<tilting_proto::SourceId>),
}

/// A message and when it is due (ns of [`clock::now_ns`]); `order` keeps messages due at the
/// same nanosecond in the order they were sent.
struct Pending {
    due: u64,
    order: u64,
    item: Item,
}

impl PartialEq for Pending {
    fn eq(&self, other: &Self) -> bool {
        (self.due, self.order) == (other.due, other.order)
    }
}
impl Eq for Pending {}
impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<CmpOrdering> {
        Some(self.cmp(other))
    }
}
impl Ord for Pending {
    fn cmp(&self, other: &Self) -> CmpOrdering {
        (self.due, self.order).cmp(&(other.due, other.order))
    }
}

#[derive(Default)]
struct Queue {
    heap: BinaryHeap<Reverse<Pending>>,
    sent: u64,
    stop: bool,
}

#[derive(Default)]
struct Counts {
    states_sent: AtomicU64,
    states_lost: AtomicU64,
    torques_sent: AtomicU64,
    torques_lost: AtomicU64,
}

/// Both directions of the plant's link, emulated on the wall clock, and the thread that hands
/// delayed messages on.
pub(super) struct Emulator {
    imp: Impairment,
    state_link: Mutex<Link>,
    torque_link: Mutex<Link>,
    queue: Mutex<Queue>,
    cv: Condvar,
    counts: Counts,
    late: Mutex<Ring>,
    spin_ns: u64,
    pubs: Arc<Publishers>,
    shared: Arc<Shared>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl Emulator {
    /// Starts the queue's thread; `spin_ns` is the busy wait before each due time (the plant's
    /// `--spin-us`), `rt_priority` the plant's `--rt-priority` (tried for this thread too).
    pub(super) fn start(
        imp: Impairment,
        spin_ns: u64,
        rt_priority: Option<i32>,
        pubs: Arc<Publishers>,
        shared: Arc<Shared>,
    ) -> anyhow::Result<Arc<Self>> {
        let emu = Arc::new(Self {
            imp,
            state_link: Mutex::new(Link::new(imp.state, imp.seed, 0)),
            torque_link: Mutex::new(Link::new(imp.torque, imp.seed, 1)),
            queue: Mutex::new(Queue::default()),
            cv: Condvar::new(),
            counts: Counts::default(),
            late: Mutex::new(Ring::new()),
            spin_ns,
            pubs,
            shared,
            thread: Mutex::new(None),
        });
        let e = emu.clone();
        let handle = std::thread::Builder::new()
            .name("plant-link".into())
            .spawn(move || {
                if let Some(p) = rt_priority {
                    if let Err(err) = clock::set_fifo_priority(p) {
                        tracing::warn!("--rt-priority {p} for the link thread: {err}");
                    }
                }
                e.serve()
            })
            .context("cannot start the link emulation thread")?;
        *lock(&emu.thread) = Some(handle);
        Ok(emu)
    }

    /// A state leaves the plant over the state link.
    pub(super) fn send_state(&self, msg: PlantState) {
        let drawn = {
            // Counted under the link's lock: the counts always match the draws taken.
            let mut link = lock(&self.state_link);
            self.counts.states_sent.fetch_add(1, Ordering::Relaxed);
            let d = link.send(0.0);
            if d.is_none() {
                self.counts.states_lost.fetch_add(1, Ordering::Relaxed);
            }
            d
        };
        match drawn {
            None => {}
            Some(d) if d <= 0.0 => self.deliver(Item::State(msg)),
            Some(d) => self.enqueue(d, Item::State(msg)),
        }
    }

    /// A torque message reaches the plant's end of the torque link.
    pub(super) fn send_torque(&self, bytes: &[u8], source: Option<tilting_proto::SourceId>) {
        let drawn = {
            let mut link = lock(&self.torque_link);
            self.counts.torques_sent.fetch_add(1, Ordering::Relaxed);
            let d = link.send(0.0);
            if d.is_none() {
                self.counts.torques_lost.fetch_add(1, Ordering::Relaxed);
            }
            d
        };
        match drawn {
            None => {}
            Some(d) if d <= 0.0 => self.deliver(Item::Torque(bytes.to_vec(), source)),
            Some(d) => self.enqueue(d, Item::Torque(bytes.to_vec(), source)),
        }
    }

    fn enqueue(&self, delay: f64, item: Item) {
        let due = clock::now_ns() + (delay * 1e9).round() as u64;
        let mut q = lock(&self.queue);
        let order = q.sent;
        q.sent += 1;
        q.heap.push(Reverse(Pending { due, order, item }));
        drop(q);
        self.cv.notify_one();
    }

    fn deliver(&self, item: Item) {
        match item {
            Item::State(msg) => {
                if let Err(e) = self.pubs.state.put(&msg) {
                    tracing::warn!("cannot publish the state: {e}");
                }
            }
            Item::Torque(bytes, source) => self.shared.on_torque(&bytes, source),
        }
    }

    /// The queue's thread: waits (condition variable) until `spin` before the earliest due
    /// time, sleeps and spins to it, hands the message on, and records how late that was.
    fn serve(&self) {
        clock::set_min_timer_slack();
        let spin = self.spin_ns;
        let mut q = lock(&self.queue);
        loop {
            if q.stop {
                return;
            }
            let now = clock::now_ns();
            let Some(due) = q.heap.peek().map(|p| p.0.due) else {
                q = self.cv.wait(q).unwrap_or_else(|e| e.into_inner());
                continue;
            };
            if due <= now {
                let Some(Reverse(p)) = q.heap.pop() else {
                    continue;
                };
                drop(q);
                self.deliver(p.item);
                lock(&self.late).push(now.saturating_sub(p.due) as f64 * 1e-3);
                q = lock(&self.queue);
            } else if due - now > spin {
                // A new message may be due earlier: it notifies.
                q = self
                    .cv
                    .wait_timeout(q, Duration::from_nanos(due - now - spin))
                    .unwrap_or_else(|e| e.into_inner())
                    .0;
            } else {
                drop(q);
                clock::sleep_until(due, spin);
                q = lock(&self.queue);
            }
        }
    }

    /// Stops the queue's thread; messages still in flight are discarded.
    pub(super) fn stop(&self) {
        lock(&self.queue).stop = true;
        self.cv.notify_all();
        if let Some(h) = lock(&self.thread).take() {
            let _ = h.join();
        }
    }

    /// What the links did so far.
    pub(super) fn stats(&self) -> LinkEmulation {
        let c = &self.counts;
        let (states_sent, states_lost) = {
            let _link = lock(&self.state_link);
            (
                c.states_sent.load(Ordering::Relaxed),
                c.states_lost.load(Ordering::Relaxed),
            )
        };
        let (torques_sent, torques_lost) = {
            let _link = lock(&self.torque_link);
            (
                c.torques_sent.load(Ordering::Relaxed),
                c.torques_lost.load(Ordering::Relaxed),
            )
        };
        let mut late = lock(&self.late);
        let p = late.percentiles();
        LinkEmulation {
            state: self.imp.state,
            torque: self.imp.torque,
            seed: self.imp.seed,
            states_sent,
            states_lost,
            torques_sent,
            torques_lost,
            in_flight: lock(&self.queue).heap.len() as u64,
            delivery_late_us: Window {
                p50: p.p50,
                p99: p.p99,
                p999: Some(p.p999),
                max: late.max(),
                count: Some(late.count()),
                window: Some(Ring::CAPACITY as u64),
            },
        }
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}
