//! The plant node's run summary: one JSON object printed on stdout at the end of a run.
//!
//! One type for the node that writes it, `tilting live` that embeds it in its own summary, and
//! the tests that read it: a renamed field fails to compile instead of reading as `null`.

use serde::{Deserialize, Serialize};

use super::ClockMode;

/// One stay in the safe mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SafeModeEntry {
    /// Plant time of the entry (s).
    pub start: f64,
    /// Plant time of the exit (s), `None` if the run ended in it.
    pub end: Option<f64>,
    /// Why: the watchdog (no valid torque for `--watchdog` periods), the controller's
    /// liveliness token gone, or the lockstep timeout.
    pub cause: String,
}
use crate::Mode;

/// How a plant run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunResult {
    /// Ran for `--duration`.
    Completed,
    /// Stopped early by Ctrl-C or SIGTERM (or a lockstep controller that went away).
    Stopped,
    /// The model faulted (fall, contact loss, Zeno guard, non-finite torque).
    Faulted,
}

/// Percentiles of a window of samples, in µs (zeros for an empty window).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Window {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile (absent for the step cost).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p999: Option<f64>,
    /// Largest sample of the whole run.
    pub max: f64,
    /// Samples of the whole run (for the latency).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub count: Option<u64>,
    /// Size of the window the percentiles are taken over.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<u64>,
}

/// The links a real-time plant emulated on the wall clock (`--delay`, `--jitter`, `--loss`,
/// `--loss-burst` with `--clock realtime`): their settings and what they did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkEmulation {
    /// The state link (plant to controller).
    pub state: tilting_link::LinkSpec,
    /// The torque link (controller to plant).
    pub torque: tilting_link::LinkSpec,
    /// Seed of the random streams (0: states, 1: torques).
    pub seed: u64,
    /// States published into the state link (re-publications of state 0 included).
    pub states_sent: u64,
    /// States the state link lost.
    pub states_lost: u64,
    /// Torque messages that reached the plant's end of the torque link.
    pub torques_sent: u64,
    /// Torque messages the torque link lost.
    pub torques_lost: u64,
    /// Delayed messages still on their way when the summary was taken (discarded at the end).
    pub in_flight: u64,
    /// How late a delayed message was handed on after its due time (µs): the wake-up latency
    /// of the emulation thread.
    pub delivery_late_us: Window,
}

/// The summary of one plant run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlantSummary {
    /// How the run ended.
    pub result: RunResult,
    /// The fault's message, when `result` is `faulted`.
    pub fault: Option<String>,
    /// `realtime` or `lockstep`.
    pub clock: ClockMode,
    /// Control period (s).
    pub period: f64,
    /// `seq` of the last published state.
    pub seq: u64,
    /// Plant time at the end (s).
    pub time: f64,
    /// Contact mode at the end.
    pub mode: Mode,
    /// State at the end `(alpha, beta, alpha_dot, beta_dot)` (rad, rad/s).
    pub x: [f64; 4],
    /// Control periods run.
    pub steps: u64,
    /// Tilts started.
    pub tilts: u64,
    /// Mode transitions.
    pub transitions: u64,
    /// `--ros2`: the mirror's and `effort_command`'s counts (absent without `--ros2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ros2: Option<super::Ros2Summary>,
    /// Torque messages received, valid or not.
    pub torques_received: u64,
    /// Torque messages dropped as malformed or invalid.
    pub torques_dropped: u64,
    /// Valid torques that did not answer the latest state.
    pub torques_stale: u64,
    /// Plausible torques refused because another zenoh session than the controller's sent
    /// them (the first torque believed pins the controller's session; see
    /// `tilting_proto::source`).
    #[serde(default)]
    pub torques_foreign: u64,
    /// Valid torques that arrived after a newer one and were dropped.
    #[serde(default)]
    pub torques_reordered: u64,
    /// Torques applied after their own period (their age was 1 to `--max-age` periods).
    #[serde(default)]
    pub torques_late: u64,
    /// States whose answer was never applied (between two applied torques).
    #[serde(default)]
    pub torques_lost: u64,
    /// Torque commands taken into force (the torque channel of an MCAP `--record`).
    #[serde(default)]
    pub torques_applied: u64,
    /// Extra states published at mode transitions (`--sample-on-event`).
    #[serde(default)]
    pub extra_states: u64,
    /// Answers to extra states taken into force (in real time, those that came within half a
    /// period).
    #[serde(default)]
    pub extra_answers: u64,
    /// What the emulated links did, in lockstep with `--delay` ...
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub network: Option<tilting_link::NetStats>,
    /// What the links emulated on the wall clock did, in real time with `--delay` ...
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link: Option<LinkEmulation>,
    /// Age of the applied torques (periods between the state a torque answers and the state
    /// it was applied at): percentiles over the last 4096 applied torques.
    #[serde(default)]
    pub age_periods: Option<Window>,
    /// Periods whose torque did not arrive in time.
    pub deadline_misses: u64,
    /// Times the watchdog put the plant in safe mode.
    pub watchdog_trips: u64,
    /// Times the controller's liveliness token disappeared: a controller gone, or its zenoh
    /// transport closed and reopened (a renegotiated link, which does not trip the watchdog
    /// when the token is back, or torques still arrive, within `max(--max-age, 2)` periods).
    #[serde(default)]
    pub token_losses: u64,
    /// Periods run in safe mode.
    pub safe_periods: u64,
    /// Each entry into the safe mode: when, why and for how long (at most the first 100).
    #[serde(default)]
    pub safe_modes: Vec<SafeModeEntry>,
    /// Periods whose integration overran the deadline.
    pub overruns: u64,
    /// Largest overrun (µs).
    pub max_overrun_us: f64,
    /// Wake-up jitter of the pacing thread (µs).
    pub jitter_us: Window,
    /// Loop latency, state published to its torque received (µs).
    pub latency_us: Window,
    /// Cost of integrating one period (µs).
    pub step_us: Window,
    /// `(t, alpha)` of the last tilt peaks (s, rad).
    pub tilt_peaks: Vec<[f64; 2]>,
}

impl PlantSummary {
    /// The last line of `stdout` that parses as a summary (a node prints logs on stderr only,
    /// but a caller may hand over a whole captured stream).
    pub fn from_stdout(stdout: &str) -> Option<Self> {
        stdout
            .lines()
            .rev()
            .find_map(|l| serde_json::from_str(l).ok())
    }
}
