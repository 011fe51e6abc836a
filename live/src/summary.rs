//! The summary of a live run: `summary.json` in the run's directory, and the human report
//! printed at the end. One type for the command that writes it and the tests that read it.

use crate::record::RecordView;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use tilting_controller::node::ControllerSummary;
use tilting_plant::node::PlantSummary;
use tilting_proto::Status;

/// How a live run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LiveResult {
    /// Ran for `--duration` and every node ended cleanly.
    Completed,
    /// Stopped by Ctrl-C or SIGTERM, cleanly.
    Interrupted,
    /// A node failed, faulted or had to be killed (see `problems`).
    Failed,
}

/// Whether a run holds the orbit (the criterion of `tilting plan margins`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OrbitState {
    /// Alternating tilts, still coming, no fault, and the last peaks within the tolerance of
    /// the nominal orbit's (safe-mode stays are reported beside the verdict, not in it).
    Holds,
    /// One of these failed (see `why`).
    Lost,
    /// Fewer than two tilts so far.
    Pending,
}

/// The orbit verdict of a live run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OrbitVerdict {
    /// Holds, lost or pending.
    pub state: OrbitState,
    /// Why it is lost (or pending); empty when it holds.
    pub why: String,
    /// Mean |peak| of the last tilts (at most 10), rad.
    pub last_peak: f64,
    /// The nominal orbit's (the same law at 1 kHz over a perfect network), rad.
    pub nominal_peak: f64,
    /// Largest relative deviation of `last_peak` from `nominal_peak` that holds.
    pub tolerance: f64,
}

impl OrbitVerdict {
    /// One phrase: `holds (last peaks ...)`, `LOST: why` or `pending`.
    pub fn describe(&self) -> String {
        match self.state {
            OrbitState::Holds => format!(
                "holds (last peaks {:.4} rad, {:+.0} % from the nominal {:.4} rad)",
                self.last_peak,
                100.0 * (self.last_peak / self.nominal_peak - 1.0),
                self.nominal_peak
            ),
            OrbitState::Lost => format!("LOST: {}", self.why),
            OrbitState::Pending => "pending".into(),
        }
    }
}

/// The plant's safe-mode stays in words: how many, how long in all, and the first three with
/// their start, duration and cause.
pub fn describe_safe_modes(p: &PlantSummary) -> String {
    if p.watchdog_trips == 0 {
        return "never entered".into();
    }
    let dur = |e: &tilting_plant::node::SafeModeEntry| e.end.unwrap_or(p.time) - e.start;
    let total: f64 = p.safe_modes.iter().map(dur).sum();
    let mut text = format!(
        "{} entr{}, {total:.3} s in all ({} periods)",
        p.watchdog_trips,
        if p.watchdog_trips == 1 { "y" } else { "ies" },
        p.safe_periods
    );
    for e in p.safe_modes.iter().take(3) {
        text.push_str(&format!(
            "; at {:.3} s for {:.3} s{}: {}",
            e.start,
            dur(e),
            if e.end.is_none() { " (to the end)" } else { "" },
            e.cause
        ));
    }
    text
}

/// The law that was published, in the layout of the `Reference` message.
pub use tilting_controller::law::LawRecord;

/// The zenoh endpoints of the three sessions.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Endpoints {
    /// Where the plant listens.
    pub plant: String,
    /// Where the controller listens.
    pub controller: String,
    /// Where the in-process planner listens (`--secure`: where the front door's recorder
    /// listens, with the logger's identity, for the controller to dial; empty with
    /// certificates made before the direct recorder).
    pub planner: String,
    /// `--secure`: the router (the plant listens on its TLS endpoint of the direct loop, the
    /// controller nowhere: its field above is empty).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub router: Option<String>,
}

/// What the recording holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordCounts {
    /// States recorded (`run.mcap`, and rows of `state.csv`).
    pub states: u64,
    /// Torques recorded (and rows of `torque.csv`).
    pub torques: u64,
    /// Events recorded (and rows of `events.csv`).
    pub events: u64,
    /// Status messages recorded.
    #[serde(default)]
    pub statuses: u64,
    /// References recorded.
    #[serde(default)]
    pub references: u64,
    /// The CSV files were written too (`--csv`).
    #[serde(default)]
    pub csv: bool,
    /// Tilts seen in the events.
    pub tilts: u64,
    /// Messages the recorder had to drop (its queue was full).
    pub dropped: u64,
    /// Gaps in the state `seq`.
    pub missing_states: u64,
    /// Re-published states skipped.
    pub repeated_states: u64,
    /// Repeated torques skipped.
    pub repeated_torques: u64,
    /// Payloads that did not decode or validate, on any topic.
    pub invalid: u64,
    /// Well-formed messages refused by the plant's plausibility rules (not recorded, not
    /// judged), per topic: states, torques, events, status, references.
    #[serde(default)]
    pub refused: [u64; 5],
    /// Of those, the messages from a foreign source: another zenoh session than the plant's
    /// (states, events, statuses) or the controller's (torques), each pinned to the first
    /// believed message's source.
    #[serde(default)]
    pub foreign: u64,
    /// The first refusal, in words.
    #[serde(default)]
    pub first_refusal: Option<String>,
    /// `(t, alpha)` of the last tilt peaks (s, rad).
    pub peaks: Vec<[f64; 2]>,
}

/// A zenoh session a live run pinned streams to: the plant's (its states, events and
/// statuses) or the controller's (its torques).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PinnedSession {
    /// Its zenoh id, in hexadecimal as zenoh prints it and as `--zenoh-id`, `--plant-id` and
    /// `--controller-id` take it (`tilting record --plant-id ID`).
    pub id: String,
    /// Well-formed messages the recorder refused on this pin's streams because they named
    /// another session, or none (part of `record.foreign`).
    pub foreign: u64,
}

/// The zenoh sessions of the plant and the controller: `tilting live` draws both ids before it
/// starts either node (`--zenoh-id`), tells each node the other's, and pins its recorder and
/// status line to them.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sessions {
    /// The plant's session.
    pub plant: Option<PinnedSession>,
    /// The controller's session.
    pub controller: Option<PinnedSession>,
}

impl Sessions {
    /// The sessions of `ids`, with the recorder's foreign-source refusals per topic
    /// (`foreign_per_topic`, [`tilting_proto::Topic::index`] order) charged to their pins.
    pub fn new(ids: &tilting_record::Sources, foreign_per_topic: [u64; 5]) -> Self {
        let [states, torques, events, statuses, _] = foreign_per_topic;
        let pin = |id: Option<tilting_proto::SourceId>, foreign| {
            id.map(|id| PinnedSession {
                id: id.to_string(),
                foreign,
            })
        };
        Self {
            plant: pin(ids.plant, states + events + statuses),
            controller: pin(ids.controller, torques),
        }
    }

    /// One line: `plant ID (N foreign refused), controller ID (M foreign refused)`.
    pub fn describe(&self) -> String {
        let one = |who: &str, p: &Option<PinnedSession>| match p {
            Some(p) => format!("{who} {} ({} foreign refused)", p.id, p.foreign),
            None => format!("{who} not pinned in advance"),
        };
        format!(
            "{}, {}",
            one("plant", &self.plant),
            one("controller", &self.controller)
        )
    }
}

/// The planner's counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlannerCounts {
    /// References put on the key.
    pub puts: u64,
    /// Queries answered.
    pub queries_answered: u64,
}

/// `summary.json` of a live run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LiveSummary {
    /// How the run ended.
    pub result: LiveResult,
    /// What went wrong, one sentence each.
    pub problems: Vec<String>,
    /// Planned run length (s).
    pub duration: f64,
    /// Control rate (Hz).
    pub rate: f64,
    /// Robot name.
    pub robot: String,
    /// The run's directory.
    pub out: PathBuf,
    /// The published law.
    pub reference: LawRecord,
    /// The sessions' endpoints.
    pub endpoints: Endpoints,
    /// The plant's and the controller's zenoh ids, as the run chose them and pinned its
    /// recorder to them (absent in summaries written before they were recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zenoh_ids: Option<Sessions>,
    /// The SCHED_FIFO priority the plant and the controller ran at (`--realtime`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub realtime: Option<i32>,
    /// The recording.
    pub record: RecordCounts,
    /// The planner's counters.
    pub planner: PlannerCounts,
    /// `run.png` was drawn.
    pub png: bool,
    /// The plant's exit status.
    pub plant_exit: String,
    /// `--plant-cmd`: the command that ran as the plant instead of `tilting-plant`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plant_cmd: Option<String>,
    /// The controller's exit status (`null` if it never started).
    pub controller_exit: Option<String>,
    /// The plant's own summary.
    pub plant: Option<PlantSummary>,
    /// The controller's own summary.
    pub controller: Option<ControllerSummary>,
    /// Whether the run held the orbit, judged at its end from the plant's tilt peaks.
    #[serde(default)]
    pub orbit: Option<OrbitVerdict>,
}

impl LiveSummary {
    /// The human-readable report printed at the end; `status` is the plant's last status,
    /// `fault` the fault that ended the run, if any.
    pub fn report(
        &self,
        view: &RecordView,
        status: Option<&Status>,
        fault: Option<&str>,
    ) -> String {
        use std::fmt::Write as _;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "live run {}: {} s planned at {} Hz, robot {}; plant {}, controller {}",
            serde_json::to_value(self.result)
                .ok()
                .and_then(|v| v.as_str().map(str::to_owned))
                .unwrap_or_default(),
            self.duration,
            self.rate,
            self.robot,
            self.plant_exit,
            self.controller_exit.as_deref().unwrap_or("not started"),
        );
        let p = self.plant.as_ref();
        if let Some(p) = p {
            let result = serde_json::to_value(p.result)
                .ok()
                .and_then(|v| v.as_str().map(str::to_owned))
                .unwrap_or_default();
            let _ = writeln!(
                out,
                "plant: {result} at t = {} s after {} periods, mode {}",
                p.time, p.steps, p.mode
            );
        }
        let tilts = p
            .map(|p| p.tilts)
            .or(status.map(|s| s.tilts))
            .unwrap_or(view.tilts);
        let peaks: Vec<f64> = match p {
            Some(p) if !p.tilt_peaks.is_empty() => p.tilt_peaks.iter().map(|x| x[1]).collect(),
            _ => view.peaks.iter().map(|x| x.1).collect(),
        };
        let last: Vec<String> = peaks[peaks.len().saturating_sub(6)..]
            .iter()
            .map(|a| format!("{:.5}", a.abs()))
            .collect();
        let _ = writeln!(
            out,
            "tilts: {tilts}; peak |alpha| of the last {} tilts (rad): {}",
            last.len(),
            if last.is_empty() {
                "-".to_owned()
            } else {
                last.join(" ")
            }
        );
        loop_lines(&mut out, p, status);
        if let Some(o) = &self.orbit {
            let _ = writeln!(out, "orbit: {}", o.describe());
        }
        if let Some(p) = p {
            let _ = writeln!(out, "safe mode: {}", describe_safe_modes(p));
        }
        let _ = writeln!(out, "faults: {}", fault.unwrap_or("none"));
        if let Some(ids) = &self.zenoh_ids {
            let _ = writeln!(out, "zenoh ids: {}", ids.describe());
        }
        self.record_lines(&mut out);
        out
    }

    /// Appends the recording's lines of [`LiveSummary::report`] to `out`: the messages refused
    /// (if any) and the files written with their counts.
    fn record_lines(&self, out: &mut String) {
        use std::fmt::Write as _;
        let r = &self.record;
        let refused: u64 = r.refused.iter().sum();
        if refused > 0 || r.invalid > 0 {
            let [s, t, e, st, rf] = r.refused;
            let _ = writeln!(
                out,
                "refused messages: {refused} implausible (states {s}, torques {t}, events {e}, status {st}, references {rf}; {} from a foreign source; first: {}), {} malformed; none recorded or judged",
                r.foreign,
                r.first_refusal.as_deref().unwrap_or("-"),
                r.invalid,
            );
        }
        let _ = writeln!(
            out,
            "recorded in {}: run.mcap ({} states, {} torques, {} events, {} status, {} references), {}{}summary.json (dropped {}, missing states {})",
            self.out.display(),
            r.states,
            r.torques,
            r.events,
            r.statuses,
            r.references,
            if r.csv { "state.csv, torque.csv, events.csv, " } else { "" },
            match (self.png, self.out.join("run.gif").is_file()) {
                (true, true) => "run.png, run.gif, ",
                (true, false) => "run.png, ",
                (false, true) => "run.gif, ",
                (false, false) => "",
            },
            r.dropped,
            r.missing_states,
        );
    }
}

/// Appends the loop's timing lines of [`LiveSummary::report`] to `out`: from the plant's summary
/// `p` (latency percentiles in us, deadline misses, watchdog trips, overruns, the emulated link
/// and the torques' age in periods), else from its last `status`.
fn loop_lines(out: &mut String, p: Option<&PlantSummary>, status: Option<&Status>) {
    use std::fmt::Write as _;
    if let Some(p) = p {
        let lat = &p.latency_us;
        let _ = writeln!(
            out,
            "loop latency (state out -> torque back, us, last {} periods): p50 {:.1}, p99 {:.1}, p99.9 {:.1}, max {:.1}",
            lat.count.unwrap_or(0).min(lat.window.unwrap_or(4096)),
            lat.p50,
            lat.p99,
            lat.p999.unwrap_or(f64::NAN),
            lat.max,
        );
        let _ = writeln!(
            out,
            "deadline misses: {}, watchdog trips: {}, overruns: {} (max {:.0} us), jitter p99 {:.1} us",
            p.deadline_misses, p.watchdog_trips, p.overruns, p.max_overrun_us, p.jitter_us.p99,
        );
    } else if let Some(st) = status {
        let _ = writeln!(
            out,
            "loop latency (us, from the last status): p50 {:.1}, p99 {:.1}; deadline misses {}, watchdog trips {}",
            st.latency_p50_us, st.latency_p99_us, st.deadline_misses, st.watchdog_trips
        );
    }
    if let Some(l) = p.and_then(|p| p.link.as_ref()) {
        let _ = writeln!(
            out,
            "emulated link: states lost {} of {}, torques lost {} of {}; hand-over late p99 {:.0} us",
            l.states_lost, l.states_sent, l.torques_lost, l.torques_sent, l.delivery_late_us.p99,
        );
    }
    if let Some((p, a)) = p.and_then(|p| p.age_periods.as_ref().map(|a| (p, a))) {
        if a.max > 0.0 {
            let _ = writeln!(
                out,
                "torque age (periods): p50 {:.0}, p99 {:.0}, max {:.0}; late {}, unanswered states {}, reordered {}",
                a.p50, a.p99, a.max, p.torques_late, p.torques_lost, p.torques_reordered
            );
        }
    }
}
