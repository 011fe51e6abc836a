//! A subscriber that stops reading must not hold up a loop publisher ("Never blocking the
//! loop" in the crate docs).
//!
//! Session B subscribes to a key with a callback that blocks zenoh's receive task (as a script
//! sleeping in its callback does), so B's end of the link stops reading. Session A then puts
//! 1,500 payloads of 32 kB (48 MB, more than the kernel's socket buffers can hold: at most
//! 32 MB received + 4 MB sent by default on Linux) with [`Qos::Control`] and times each put.
//! With a blocking publisher the put that finds the link's queue full waits zenoh's
//! `wait_before_close` (5 s) and the link is closed; a droppable one waits at most
//! [`WAIT_BEFORE_DROP_US`] (50 µs), then drops at once while the queue stays full. The
//! assertion, the slowest put under 2.5 s, separates the two outcomes by five orders of
//! magnitude, so a loaded machine cannot flip it. Then B reads again and A's next message
//! still arrives over the same link.
//!
//! Moved here from `net/tests/` (issue 30: its own test binary linked zenoh for one test). It
//! takes a real-time turn: 48 MB over loopback would load the machine under another test's loop.

use std::sync::mpsc;
use std::time::{Duration, Instant};
use tilting_net::{open_session, Qos, RawPublisher, Role, ZenohArgs};
use tilting_tests::realtime_turn;

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_stalled_subscriber_does_not_block_a_control_publisher() {
    let _turn = realtime_turn();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let a = open_session(&ZenohArgs::new("slow", &[&endpoint], &[]), Role::Plant)
        .await
        .unwrap();
    let b = open_session(
        &ZenohArgs::new("slow", &["tcp/127.0.0.1:0"], &[&endpoint]),
        Role::Peer,
    )
    .await
    .unwrap();
    let key = "tilting/slow/plant/state";
    let (release_tx, release_rx) = mpsc::channel::<()>();
    let release_rx = std::sync::Mutex::new(release_rx);
    let (seen_tx, seen_rx) = mpsc::channel::<usize>();
    let stalled = std::sync::atomic::AtomicBool::new(false);
    let _sub = b
        .declare_subscriber(key)
        .callback(move |sample| {
            let n = sample.payload().len();
            if n > 100 && !stalled.swap(true, std::sync::atomic::Ordering::Relaxed) {
                // The first big payload: stop reading until released (at most 60 s).
                let _ = release_rx
                    .lock()
                    .unwrap()
                    .recv_timeout(Duration::from_secs(60));
            }
            let _ = seen_tx.send(n);
        })
        .await
        .unwrap();
    let publisher = RawPublisher::declare(&a, key, Qos::Control).await.unwrap();
    let deadline = Instant::now() + Duration::from_secs(10);
    while !publisher.has_subscribers().await {
        assert!(Instant::now() < deadline, "the subscriber never matched");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let big = vec![7u8; 32 * 1024];
    let mut slowest = Duration::ZERO;
    for _ in 0..1500 {
        let t = Instant::now();
        publisher.put_raw(&big).unwrap();
        slowest = slowest.max(t.elapsed());
    }
    println!("slowest of 1,500 puts of 32 kB to a stalled subscriber: {slowest:?}");
    assert!(
        slowest < Duration::from_millis(2500),
        "a put waited {slowest:?} for a subscriber that stopped reading"
    );
    // Reading again: the link is still up, and a small message put now arrives.
    release_tx.send(()).unwrap();
    let deadline = Instant::now() + Duration::from_secs(20);
    let (mut big_seen, mut got_small) = (0, false);
    while Instant::now() < deadline && !got_small {
        publisher.put_raw(&[1, 2, 3]).unwrap();
        while let Ok(n) = seen_rx.recv_timeout(Duration::from_millis(50)) {
            got_small |= n == 3;
            big_seen += usize::from(n > 100);
        }
    }
    println!("after the stall: {big_seen} of the 1,500 big payloads arrived (the rest dropped)");
    assert!(got_small, "nothing arrived once the subscriber read again");
    assert!(
        big_seen < 1500,
        "no payload was dropped: the link never congested"
    );
    drop(_sub);
    let _ = b.close().await;
    let _ = a.close().await;
}
