//! Wall-clock pacing. On Linux: `CLOCK_MONOTONIC` nanoseconds, absolute-deadline sleeps with
//! `clock_nanosleep(TIMER_ABSTIME)` followed by a short spin, and best-effort thread tuning
//! (timer slack, real-time priority). Elsewhere a portable fallback with the same API
//! (`std::thread::sleep` and a spin; no timer slack, no real-time priority): it runs, but a
//! 1 kHz loop jitters more there.

#[cfg(target_os = "linux")]
pub use linux::*;
#[cfg(not(target_os = "linux"))]
pub use portable::*;

/// Busy-waits until `now()` reaches `deadline_ns` (the last microseconds before a deadline,
/// which a kernel sleep overshoots); returns the time it saw last.
fn spin_until(deadline_ns: u64, now: fn() -> u64) -> u64 {
    loop {
        let t = now();
        if t >= deadline_ns {
            return t;
        }
        std::hint::spin_loop();
    }
}

#[cfg(target_os = "linux")]
mod linux {
    /// Nanoseconds of `CLOCK_MONOTONIC` (the clock `std::time::Instant` uses on Linux).
    pub fn now_ns() -> u64 {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
        unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
        ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
    }

    /// Sleeps until `CLOCK_MONOTONIC` reaches `deadline_ns`: a kernel sleep to `spin_ns` before the
    /// deadline, then a busy wait. Returns the wake-up time (>= `deadline_ns`).
    pub fn sleep_until(deadline_ns: u64, spin_ns: u64) -> u64 {
        let wake_at = deadline_ns.saturating_sub(spin_ns);
        if now_ns() < wake_at {
            let ts = libc::timespec {
                tv_sec: (wake_at / 1_000_000_000) as libc::time_t,
                tv_nsec: (wake_at % 1_000_000_000) as libc::c_long,
            };
            loop {
                // SAFETY: `ts` is a valid timespec; a null `rem` is allowed with TIMER_ABSTIME.
                let rc = unsafe {
                    libc::clock_nanosleep(
                        libc::CLOCK_MONOTONIC,
                        libc::TIMER_ABSTIME,
                        &ts,
                        std::ptr::null_mut(),
                    )
                };
                if rc != libc::EINTR {
                    break;
                }
            }
        }
        super::spin_until(deadline_ns, now_ns)
    }

    /// Sets this thread's timer slack to 1 ns (the default 50 µs delays every timed wake-up).
    pub fn set_min_timer_slack() -> bool {
        // SAFETY: PR_SET_TIMERSLACK takes an unsigned long value and no pointers.
        unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0) == 0 }
    }

    /// Tries to run this thread under `SCHED_FIFO` at `priority` (1..=99); needs CAP_SYS_NICE or
    /// an rtprio limit. Returns the OS error on failure.
    pub fn set_fifo_priority(priority: i32) -> Result<(), std::io::Error> {
        let param = libc::sched_param {
            sched_priority: priority,
        };
        // SAFETY: `param` is a valid sched_param; pid 0 is the calling thread.
        let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
        if rc == 0 {
            Ok(())
        } else {
            Err(std::io::Error::last_os_error())
        }
    }
}

#[cfg(not(target_os = "linux"))]
mod portable {
    use std::sync::OnceLock;
    use std::time::{Duration, Instant};

    fn epoch() -> Instant {
        static EPOCH: OnceLock<Instant> = OnceLock::new();
        *EPOCH.get_or_init(Instant::now)
    }

    /// Nanoseconds of a monotonic clock (since the first call in this process).
    pub fn now_ns() -> u64 {
        epoch().elapsed().as_nanos() as u64
    }

    /// Sleeps until [`now_ns`] reaches `deadline_ns`: a thread sleep to `spin_ns` before the
    /// deadline, then a busy wait. Returns the wake-up time (>= `deadline_ns`).
    pub fn sleep_until(deadline_ns: u64, spin_ns: u64) -> u64 {
        let wake_at = deadline_ns.saturating_sub(spin_ns);
        let now = now_ns();
        if now < wake_at {
            std::thread::sleep(Duration::from_nanos(wake_at - now));
        }
        super::spin_until(deadline_ns, now_ns)
    }

    /// Timer slack is a Linux setting: nothing to do here.
    pub fn set_min_timer_slack() -> bool {
        false
    }

    /// Real-time priority is only implemented on Linux.
    pub fn set_fifo_priority(_priority: i32) -> Result<(), std::io::Error> {
        Err(std::io::Error::new(
            std::io::ErrorKind::Unsupported,
            "SCHED_FIFO is only available on Linux",
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sleeps_to_the_deadline() {
        set_min_timer_slack();
        let start = now_ns();
        let deadline = start + 2_000_000;
        let woke = sleep_until(deadline, 50_000);
        assert!(woke >= deadline);
        assert!(
            woke - deadline < 5_000_000,
            "woke {} ns late",
            woke - deadline
        );
        // A past deadline returns at once.
        let w2 = sleep_until(start, 50_000);
        assert!(w2 >= woke);
    }
}
