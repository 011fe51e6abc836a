//! [`Sink`]: a bounded queue drained by one thread: the one subscribe-and-drain loop of the
//! project. Subscriber callbacks (zenoh threads) hand messages to a [`SinkSender`], which never
//! blocks: a message that finds the queue full is counted as dropped, so a slow disk or a slow
//! pipe never slows the network threads, and through them the plant. The thread hands each
//! message to a [`Drain`], and tells it when the queue has been idle for a tick (to flush).
//!
//! The [`crate::Recorder`] of `tilting live` and `tilting record` drains into files; `tilting
//! echo` drains into its standard output.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// What the thread of a [`Sink`] does with the messages.
pub trait Drain<T>: Send + 'static {
    /// What [`Sink::finish`] returns.
    type Output: Send + 'static;
    /// One message, in the order sent.
    fn message(&mut self, m: T);
    /// No message for a tick.
    fn idle(&mut self);
    /// The sink is finished and its queue drained.
    fn finish(self) -> Self::Output;
}

/// A message or the end.
enum Item<T> {
    Message(T),
    Stop,
}

/// A bounded queue and the thread that drains it into a [`Drain`].
pub struct Sink<T, D: Drain<T>> {
    tx: SyncSender<Item<T>>,
    dropped: Arc<AtomicU64>,
    thread: Option<JoinHandle<D::Output>>,
}

/// A cheap, cloneable handle for callbacks: [`SinkSender::send`] never blocks.
pub struct SinkSender<T> {
    tx: SyncSender<Item<T>>,
    dropped: Arc<AtomicU64>,
}

impl<T> Clone for SinkSender<T> {
    fn clone(&self) -> Self {
        Self {
            tx: self.tx.clone(),
            dropped: self.dropped.clone(),
        }
    }
}

impl<T> SinkSender<T> {
    /// Queues `m`; a full queue drops and counts it. After [`Sink::finish`], ignored.
    pub fn send(&self, m: T) {
        if let Err(TrySendError::Full(_)) = self.tx.try_send(Item::Message(m)) {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// The sink's thread panicked.
#[derive(Debug, thiserror::Error)]
#[error("the thread `{0}` panicked")]
pub struct Panicked(pub String);

impl<T: Send + 'static, D: Drain<T>> Sink<T, D> {
    /// Starts the thread `name`, which drains a queue of `capacity` messages into `drain` and
    /// calls [`Drain::idle`] after each `tick` without a message.
    pub fn spawn(name: &str, capacity: usize, tick: Duration, drain: D) -> std::io::Result<Self> {
        let (tx, rx) = sync_channel(capacity);
        let thread = std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(move || run(rx, tick, drain))?;
        Ok(Self {
            tx,
            dropped: Arc::new(AtomicU64::new(0)),
            thread: Some(thread),
        })
    }

    /// A handle for callbacks.
    pub fn sender(&self) -> SinkSender<T> {
        SinkSender {
            tx: self.tx.clone(),
            dropped: self.dropped.clone(),
        }
    }

    /// Messages dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Drains what is queued, stops the thread and returns what the drain made of it.
    pub fn finish(mut self) -> Result<D::Output, Panicked> {
        // A blocking send: the thread drains the queue before it sees the stop.
        let _ = self.tx.send(Item::Stop);
        let t = self.thread.take().expect("present until finish");
        let name = t.thread().name().unwrap_or("sink").to_owned();
        t.join().map_err(|_| Panicked(name))
    }
}

impl<T, D: Drain<T>> Drop for Sink<T, D> {
    fn drop(&mut self) {
        if let Some(t) = self.thread.take() {
            let _ = self.tx.send(Item::Stop);
            let _ = t.join();
        }
    }
}

fn run<T, D: Drain<T>>(rx: Receiver<Item<T>>, tick: Duration, mut drain: D) -> D::Output {
    loop {
        match rx.recv_timeout(tick) {
            Ok(Item::Message(m)) => drain.message(m),
            Ok(Item::Stop) | Err(RecvTimeoutError::Disconnected) => break,
            Err(RecvTimeoutError::Timeout) => drain.idle(),
        }
    }
    drain.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Collect(Vec<u32>, u32);

    impl Drain<u32> for Collect {
        type Output = (Vec<u32>, u32);
        fn message(&mut self, m: u32) {
            self.0.push(m);
        }
        fn idle(&mut self) {
            self.1 += 1;
        }
        fn finish(self) -> (Vec<u32>, u32) {
            (self.0, self.1)
        }
    }

    /// Every message sent before `finish` is drained, in order; a full queue drops without
    /// blocking and counts what it dropped; an idle queue ticks.
    #[test]
    fn drains_in_order_drops_when_full_and_ticks_when_idle() {
        let sink = Sink::spawn("t", 4, Duration::from_millis(5), Collect(vec![], 0)).unwrap();
        let tx = sink.sender();
        std::thread::sleep(Duration::from_millis(30));
        for k in 0..10_000 {
            tx.send(k);
        }
        let dropped = sink.dropped();
        let (got, ticks) = sink.finish().unwrap();
        assert!(ticks >= 2, "{ticks}");
        assert_eq!(got.len() as u64 + dropped, 10_000);
        assert!(got.windows(2).all(|w| w[0] < w[1]));
        // Sent after the end: ignored, not counted.
        tx.send(1);
    }
}
