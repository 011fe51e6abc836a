//! A delaying TCP proxy: real transport delay between two processes on one machine, where the
//! kernel has no `netem`. Every chunk read from one side is written to the other `delay` (plus
//! jitter) later, in order (a TCP stream cannot reorder), each direction on its own.
//!
//! Blocking threads, not tokio: tokio's timers round to the millisecond, which would add up to
//! a period to each direction of a 1 kHz loop; `std::thread::sleep` wakes within about 0.1 ms.
//! It lives in the test harness, not in the product: the nodes run unchanged over it.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A running proxy; stops accepting when dropped (open connections end with their peers).
pub struct DelayProxy {
    /// The port it listens on (127.0.0.1).
    pub port: u16,
    /// Bytes forwarded, both directions.
    pub bytes: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    /// The client side of every connection accepted so far, for [`DelayProxy::cut`].
    open: Arc<Mutex<Vec<TcpStream>>>,
}

impl Drop for DelayProxy {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Wake the accept loop.
        let _ = TcpStream::connect(("127.0.0.1", self.port));
    }
}

/// A uniform number on [0, 1) from a small xorshift stream (deterministic jitter).
fn next_u(state: &mut u64) -> f64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    (*state >> 11) as f64 / (1u64 << 53) as f64
}

impl DelayProxy {
    /// Listens on a free loopback port and forwards every connection to `target`, each chunk
    /// `delay` plus up to `jitter` (uniform) later, never before the chunk sent before it.
    pub fn start(target: SocketAddr, delay: Duration, jitter: Duration) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").expect("proxy bind");
        let port = listener.local_addr().unwrap().port();
        let bytes = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let open = Arc::new(Mutex::new(Vec::new()));
        let (b, s, o) = (bytes.clone(), stop.clone(), open.clone());
        std::thread::spawn(move || {
            let mut seed = 0x9E37_79B9_7F4A_7C15u64;
            for client in listener.incoming() {
                if s.load(Ordering::Relaxed) {
                    break;
                }
                let Ok(client) = client else { continue };
                let Ok(server) = TcpStream::connect(target) else {
                    continue;
                };
                let _ = client.set_nodelay(true);
                let _ = server.set_nodelay(true);
                if let Ok(c) = client.try_clone() {
                    o.lock().unwrap().push(c);
                }
                for (from, to) in [
                    (client.try_clone(), server.try_clone()),
                    (server.try_clone(), client.try_clone()),
                ] {
                    if let (Ok(from), Ok(to)) = (from, to) {
                        seed = seed.wrapping_add(0x2545_F491_4F6C_DD1D);
                        pump(from, to, delay, jitter, seed, b.clone());
                    }
                }
            }
        });
        Self {
            port,
            bytes,
            stop,
            open,
        }
    }

    /// Closes every connection accepted so far, both ways (the proxy keeps accepting new
    /// ones): the transport above sees its link die, as when a network path breaks. Returns
    /// how many were cut.
    pub fn cut(&self) -> usize {
        let mut open = self.open.lock().unwrap();
        for c in open.iter() {
            let _ = c.shutdown(std::net::Shutdown::Both);
        }
        let n = open.len();
        open.clear();
        n
    }
}

fn pump(
    mut from: TcpStream,
    mut to: TcpStream,
    delay: Duration,
    jitter: Duration,
    mut seed: u64,
    bytes: Arc<AtomicU64>,
) {
    let (tx, rx) = mpsc::channel::<(Instant, Vec<u8>)>();
    std::thread::spawn(move || {
        for (due, chunk) in rx {
            let now = Instant::now();
            if due > now {
                std::thread::sleep(due - now);
            }
            if to.write_all(&chunk).is_err() {
                break;
            }
        }
        let _ = to.shutdown(std::net::Shutdown::Write);
    });
    std::thread::spawn(move || {
        let mut buf = vec![0u8; 64 * 1024];
        let mut last_due = Instant::now();
        loop {
            let n = match from.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => n,
            };
            bytes.fetch_add(n as u64, Ordering::Relaxed);
            let due = (Instant::now() + delay + jitter.mul_f64(next_u(&mut seed))).max(last_due);
            last_due = due;
            if tx.send((due, buf[..n].to_vec())).is_err() {
                break;
            }
        }
    });
}
