//! The status line of a live run: one line on stderr, refreshed while the loop runs.

use super::summary::OrbitVerdict;
use crate::record::RecordView;
use tilting_proto::{Mode, Status};

/// The run state as shown: the alarming ones in capitals.
fn state_name(st: &Status) -> &'static str {
    match st.state {
        Status::SAFE_MODE => "SAFE MODE",
        Status::FAULTED => "FAULTED",
        _ => st.state_name(),
    }
}

fn mode_name(q: u8) -> &'static str {
    Mode::try_from(q).map_or("?", Mode::as_str)
}

/// The status line: plant time, run state, mode, alpha, tilts and last peaks, loop latency,
/// deadline misses, and the torque ages (late, lost, reordered; always over an `impaired`
/// link), the watchdog and recording counters when they are not zero, and whether the orbit
/// holds.
pub(super) fn status_line(
    st: Option<&Status>,
    v: &RecordView,
    dropped: u64,
    impaired: bool,
    orbit: Option<&OrbitVerdict>,
) -> String {
    let Some(st) = st else {
        return format!(
            "waiting for the plant's status | recorded {} states",
            v.states
        );
    };
    let (alpha, mode) = v.last_state.map_or((0.0, st.mode), |s| (s.alpha, s.mode));
    let peaks: Vec<String> = v
        .peaks
        .iter()
        .rev()
        .take(2)
        .rev()
        .map(|p| format!("{:+.4}", p.1))
        .collect();
    let mut line = format!(
        "t {:7.2} s | {} | {:<5} alpha {:+.4} rad | tilts {:3} (last peaks {}) | latency p50 {:.0} us p99 {:.0} us | misses {}",
        st.time,
        state_name(st),
        mode_name(mode),
        alpha,
        st.tilts,
        if peaks.is_empty() { "-".to_owned() } else { peaks.join(" ") },
        st.latency_p50_us,
        st.latency_p99_us,
        st.deadline_misses,
    );
    if impaired || st.age_max > 0.0 || st.torques_lost > 0 || st.torques_reordered > 0 {
        line.push_str(&format!(
            " | age p99 {:.0} max {:.0} periods, late {}, lost {}, reordered {}",
            st.age_p99, st.age_max, st.torques_late, st.torques_lost, st.torques_reordered
        ));
    }
    if st.watchdog_trips > 0 {
        line.push_str(&format!(" | watchdog trips {}", st.watchdog_trips));
    }
    if v.refused_total() > 0 {
        line.push_str(&format!(" | refused {}", v.refused_total()));
        if v.foreign > 0 {
            line.push_str(&format!(" ({} foreign source)", v.foreign));
        }
    }
    if dropped > 0 || v.missing_states > 0 {
        line.push_str(&format!(
            " | recording dropped {dropped}, missing {}",
            v.missing_states
        ));
    }
    if let Some(o) = orbit {
        line.push_str(" | orbit ");
        line.push_str(match o.state {
            super::summary::OrbitState::Holds => "holds",
            super::summary::OrbitState::Lost => "LOST",
            super::summary::OrbitState::Pending => "?",
        });
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_line_shows_the_essentials() {
        let st = Status {
            seq: 1000,
            time: 1.0,
            state: Status::RUNNING,
            mode: 1,
            tilts: 3,
            steps: 1000,
            torques_received: 1000,
            deadline_misses: 2,
            jitter_p50_us: 1.0,
            jitter_p99_us: 2.0,
            latency_p50_us: 40.0,
            latency_p99_us: 90.0,
            ..Status::default()
        };
        let v = RecordView {
            peaks: [(0.2, 0.04), (0.6, -0.041)].into_iter().collect(),
            ..RecordView::default()
        };
        let l = status_line(Some(&st), &v, 0, false, None);
        for needle in [
            "running",
            "left",
            "tilts   3",
            "p50 40 us",
            "p99 90 us",
            "misses 2",
            "-0.0410",
        ] {
            assert!(l.contains(needle), "{needle:?} not in {l:?}");
        }
        assert!(status_line(None, &v, 0, false, None).contains("waiting"));
        assert!(!l.contains("age p99") && !l.contains("orbit"), "{l}");
        // Over an impaired link: the ages and losses always, and the orbit's verdict.
        let o = OrbitVerdict {
            state: super::super::summary::OrbitState::Holds,
            why: String::new(),
            last_peak: 0.041,
            nominal_peak: 0.0413,
            tolerance: 0.25,
        };
        let l = status_line(Some(&st), &v, 0, true, Some(&o));
        assert!(l.contains("age p99 0") && l.contains("lost 0"), "{l}");
        assert!(l.ends_with("orbit holds"), "{l}");
    }
}
