//! [`Feed`]: the bounded, drop-oldest queue between the network's callbacks and the thread
//! that publishes to Foxglove. [`Feed::send`] takes a lock for a push and never waits for the
//! WebSocket: when the publisher falls behind, the oldest queued message is dropped (and
//! counted), so a viewer always sees the newest robot and a slow client can never slow the
//! callbacks, the zenoh threads behind them, or the plant's 1 kHz loop.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;
use tilting_proto::Topic;

/// One message to publish: its topic, its wire payload, and its log time (plant time, ns) if
/// known (a recording's); `None` takes the message's own time, or the latest plant time seen.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    /// The topic.
    pub topic: Topic,
    /// The payload as it crossed the wire.
    pub wire: Vec<u8>,
    /// Log time (plant time, ns), if known.
    pub log_time: Option<u64>,
}

/// The queue's shared state.
struct Shared {
    items: Mutex<Inner>,
    ready: Condvar,
    capacity: usize,
    dropped: AtomicU64,
}

struct Inner {
    queue: VecDeque<Item>,
    closed: bool,
}

/// A cheap, cloneable sending handle: [`Feed::send`] never blocks on the consumer.
#[derive(Clone)]
pub struct Feed(Arc<Shared>);

/// The consuming end (one thread).
pub(crate) struct Drain(Arc<Shared>);

/// A queue holding at most `capacity` items (at least 1).
pub(crate) fn bounded(capacity: usize) -> (Feed, Drain) {
    let shared = Arc::new(Shared {
        items: Mutex::new(Inner {
            queue: VecDeque::with_capacity(capacity.max(1)),
            closed: false,
        }),
        ready: Condvar::new(),
        capacity: capacity.max(1),
        dropped: AtomicU64::new(0),
    });
    (Feed(shared.clone()), Drain(shared))
}

fn lock(s: &Shared) -> MutexGuard<'_, Inner> {
    s.items.lock().unwrap_or_else(|e| e.into_inner())
}

impl Feed {
    /// Queues `item`; a full queue drops its oldest item first (counted in
    /// [`Feed::dropped`]). After the server closed, ignored.
    pub fn send(&self, item: Item) {
        let mut inner = lock(&self.0);
        if inner.closed {
            return;
        }
        if inner.queue.len() >= self.0.capacity {
            inner.queue.pop_front();
            self.0.dropped.fetch_add(1, Ordering::Relaxed);
        }
        inner.queue.push_back(item);
        drop(inner);
        self.0.ready.notify_one();
    }

    /// Queues a wire payload of `topic` received from the network (log time: the message's
    /// own plant time, or the latest seen).
    pub fn send_wire(&self, topic: Topic, wire: Vec<u8>) {
        self.send(Item {
            topic,
            wire,
            log_time: None,
        });
    }

    /// Items queued now.
    pub fn queued(&self) -> usize {
        lock(&self.0).queue.len()
    }

    /// Items dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.0.dropped.load(Ordering::Relaxed)
    }
}

impl Drain {
    /// Moves every queued item into `out`, waiting up to `timeout` for the first one; `false`
    /// once closed and empty.
    pub(crate) fn take(&self, out: &mut Vec<Item>, timeout: Duration) -> bool {
        let mut inner = lock(&self.0);
        if inner.queue.is_empty() && !inner.closed {
            inner = self
                .0
                .ready
                .wait_timeout(inner, timeout)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        out.extend(inner.queue.drain(..));
        !(inner.closed && out.is_empty())
    }

    /// Refuses further items and wakes the consumer (which drains what is queued).
    pub(crate) fn close(&self) {
        lock(&self.0).closed = true;
        self.0.ready.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn item(k: u8) -> Item {
        Item {
            topic: Topic::Torque,
            wire: vec![k],
            log_time: None,
        }
    }

    /// A full queue keeps the newest `capacity` items in order and counts the others.
    #[test]
    fn drops_the_oldest() {
        let (feed, drain) = bounded(3);
        for k in 0..5 {
            feed.send(item(k));
        }
        assert_eq!(feed.dropped(), 2);
        let mut out = Vec::new();
        assert!(drain.take(&mut out, Duration::ZERO));
        let kept: Vec<u8> = out.iter().map(|i| i.wire[0]).collect();
        assert_eq!(kept, [2, 3, 4]);
        drain.close();
        feed.send(item(9));
        out.clear();
        assert!(!drain.take(&mut out, Duration::ZERO), "closed and empty");
    }
}
