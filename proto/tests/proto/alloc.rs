//! A forged `Status.fault` length prefix must not make the decoder allocate it.
//!
//! This test binary installs a global allocator that records the largest single allocation
//! requested by the current thread, so the check is independent of other tests' threads.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use tilting_proto::{codec, DecodeError, Status};

struct Tracking;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note(size: usize) {
    let _ = LARGEST.try_with(|m| m.set(m.get().max(size)));
}

unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Tracking = Tracking;

/// Largest single allocation made by `f` on this thread.
fn largest_allocation<R>(f: impl FnOnce() -> R) -> (R, usize) {
    LARGEST.with(|m| m.set(0));
    let r = f();
    (r, LARGEST.with(|m| m.get()))
}

fn status_bytes_with_declared_len(len: u64) -> Vec<u8> {
    let s = Status {
        seq: 1,
        time: 0.5,
        state: Status::RUNNING,
        steps: 10,
        torques_received: 10,
        jitter_p50_us: 1.0,
        jitter_p99_us: 2.0,
        max_overrun_us: 3.0,
        latency_p50_us: 4.0,
        latency_p99_us: 5.0,
        ..Status::default()
    };
    let mut b = codec::encode(&s);
    assert_eq!(b.len(), Status::MIN_SIZE);
    b[Status::MIN_SIZE - 8..].copy_from_slice(&len.to_le_bytes());
    b.extend_from_slice(b"tail");
    b
}

#[test]
fn huge_declared_fault_length_is_rejected_without_allocating_it() {
    for len in [u64::MAX, u64::MAX / 2, 1 << 40, 1 << 31, 1 << 20] {
        let bytes = status_bytes_with_declared_len(len);
        let (res, largest) = largest_allocation(|| codec::decode::<Status>(&bytes));
        assert!(
            matches!(
                res,
                Err(DecodeError::Malformed {
                    message: "Status",
                    ..
                })
            ),
            "{len}: {res:?}"
        );
        // Only the error text is allocated, never anything near the declared length.
        assert!(largest < 4096, "declared {len}: allocated {largest} bytes");
    }
}

#[test]
fn the_tracker_does_see_string_allocations() {
    // Control: a genuine 1000-byte fault is allocated, so the bound above is meaningful.
    let mut bytes = status_bytes_with_declared_len(1000);
    bytes.truncate(Status::MIN_SIZE);
    bytes.extend(std::iter::repeat_n(b'f', 1000));
    let (res, largest) = largest_allocation(|| codec::decode::<Status>(&bytes));
    assert_eq!(res.unwrap().fault.len(), 1000);
    assert!(largest >= 1000, "{largest}");
}
