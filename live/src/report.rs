//! Summarising a live run: the figure and the moving clip, the orbit verdict, `summary.json`
//! and the report on stdout.

use super::monitor::End;
use super::orbit::OrbitCheck;
use super::shutdown::Stopped;
use super::summary::{
    Endpoints, LawRecord, LiveResult, LiveSummary, OrbitVerdict, PlannerCounts, RecordCounts,
};
use super::Job;
use crate::record::{self, RecordView};
use anyhow::{anyhow, Context as _};
use std::path::Path;
use tilting_controller::node::ControllerSummary;
use tilting_plant::node::PlantSummary;
use tilting_proto::Status;
use tilting_sim::Scenario;

/// Everything a finished run left: how it ended, the children's summaries, the recording.
pub(super) struct Outcome {
    /// Why the monitoring ended.
    pub(super) end: End,
    /// What went wrong so far, one sentence each.
    pub(super) problems: Vec<String>,
    /// The children's exit statuses.
    pub(super) stopped: Stopped,
    /// The plant's own summary.
    pub(super) plant: Option<PlantSummary>,
    /// The controller's own summary.
    pub(super) controller: Option<ControllerSummary>,
    /// The closed recording.
    pub(super) view: RecordView,
    /// Messages the recorder dropped.
    pub(super) dropped: u64,
    /// Undecodable messages.
    pub(super) invalid: u64,
    /// The plant's last status.
    pub(super) last_status: Option<Status>,
    /// The planner's counters.
    pub(super) planner: PlannerCounts,
    /// The sessions' endpoints.
    pub(super) endpoints: Endpoints,
}

/// Draws `run.png` (and `run.gif`, the last seconds moving) from the recording in `dir`;
/// whether the figure was drawn. A failure is a problem of the run.
fn draw(
    dir: &Path,
    scenario: &Scenario,
    view: &RecordView,
    early: bool,
    problems: &mut Vec<String>,
) -> bool {
    let png = dir.join(record::RUN_PNG);
    let plot = if view.states > 0 {
        record::plot_recording(dir, &png, scenario, early)
    } else {
        Err(anyhow!("no state was recorded"))
    };
    if let Err(e) = &plot {
        problems.push(format!("cannot draw {}: {e:#}", png.display()));
    }
    if view.states > 0 {
        let gif = dir.join("run.gif");
        if let Err(e) = record::live_clip(dir, &gif, &scenario.params) {
            problems.push(format!("cannot animate {}: {e:#}", gif.display()));
        }
    }
    plot.is_ok()
}

/// The orbit verdict from the plant's own peaks (every tilt, not the sampled states), or the
/// recording's without a plant summary.
fn verdict(check: OrbitCheck, o: &Outcome, fault: Option<&str>) -> OrbitVerdict {
    match &o.plant {
        Some(p) => {
            let peaks: Vec<(f64, f64)> = p.tilt_peaks.iter().map(|x| (x[0], x[1])).collect();
            check.judge(&peaks, p.time, fault)
        }
        None => {
            let peaks: Vec<(f64, f64)> = o.view.peaks.iter().copied().collect();
            let now = o.view.last_state.map_or(0.0, |s| s.time);
            check.judge(&peaks, now, fault)
        }
    }
}

/// What the recording holds.
fn record_counts(o: &Outcome, csv: bool) -> RecordCounts {
    let v = &o.view;
    RecordCounts {
        states: v.states,
        torques: v.torques,
        events: v.events,
        statuses: v.statuses,
        references: v.references,
        csv,
        tilts: v.tilts,
        dropped: o.dropped,
        missing_states: v.missing_states,
        repeated_states: v.repeated_states,
        repeated_torques: v.repeated_torques,
        invalid: o.invalid,
        refused: v.refused,
        foreign: v.foreign,
        first_refusal: v.first_refusal.clone(),
        peaks: v.peaks.iter().map(|p| [p.0, p.1]).collect(),
    }
}

/// How a live run ended, for its exit code (README, "Faults").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Ending {
    /// Every node ended cleanly and the orbit holds (or the law has none): exit code 0.
    Clean,
    /// A node failed or had to be killed, the recording failed, or `summary.json` could not
    /// be written to the run's directory: exit code 1.
    Failed,
    /// The plant faulted (fall, contact loss, Zeno, non-finite torque): exit code 3.
    Fault,
    /// The run ended cleanly but its orbit was lost: exit code 4.
    OrbitLost,
}

/// Draws the figures, writes `summary.json` and prints the report (and the problems, on
/// stderr); how the run ended.
pub(super) fn summarise(
    job: &Job,
    scenario: &Scenario,
    check: Option<OrbitCheck>,
    mut o: Outcome,
) -> anyhow::Result<Ending> {
    let fault = o.plant.as_ref().and_then(|s| s.fault.clone()).or_else(|| {
        o.last_status
            .as_ref()
            .filter(|s| !s.fault.is_empty())
            .map(|s| s.fault.clone())
    });
    let early = fault.is_some() || !o.problems.is_empty();
    let png = draw(&job.dir, scenario, &o.view, early, &mut o.problems);
    let orbit = check.map(|c| verdict(c, &o, fault.as_deref()));
    let ok = o.problems.is_empty();
    let result = match (&o.end, ok) {
        (End::Interrupted, true) => LiveResult::Interrupted,
        (_, true) => LiveResult::Completed,
        (_, false) => LiveResult::Failed,
    };
    let args = job.args;
    let summary = LiveSummary {
        result,
        problems: o.problems.clone(),
        duration: args.duration,
        rate: args.rate,
        robot: job.keys.robot().to_owned(),
        out: job.dir.clone(),
        reference: LawRecord::from(&job.reference),
        endpoints: o.endpoints.clone(),
        zenoh_ids: Some(super::summary::Sessions::new(
            &job.ids,
            o.view.foreign_per_topic,
        )),
        realtime: args.realtime,
        record: record_counts(&o, args.csv),
        planner: o.planner,
        png,
        plant_exit: o.stopped.plant.to_string(),
        plant_cmd: args.plant_cmd.clone(),
        controller_exit: o.stopped.controller.map(|s| s.to_string()),
        plant: o.plant.take(),
        controller: o.controller.take(),
        orbit,
    };
    let text = serde_json::to_string_pretty(&summary).context("cannot serialise the summary")?;
    // The report first (stdout), then the summary: whatever the disk does, the user hears.
    let report = summary.report(&o.view, o.last_status.as_ref(), fault.as_deref());
    let _ = tilting_net::say_out(report.trim_end());
    let saved = save_summary(&job.dir, &text);
    for p in &o.problems {
        tilting_net::say_err(&format!("live: error: {p}"));
    }
    let lost = summary
        .orbit
        .as_ref()
        .is_some_and(|v| v.state == super::summary::OrbitState::Lost);
    Ok(if fault.is_some() {
        Ending::Fault
    } else if !(ok && saved) {
        Ending::Failed
    } else if lost {
        Ending::OrbitLost
    } else {
        Ending::Clean
    })
}

/// Writes `summary.json` into `dir`; if that fails (a full disk), into the fallback
/// [`fallback_summary`], and if that fails too, onto stdout. Says where it went unless it went
/// where expected; whether it reached `dir`.
fn save_summary(dir: &Path, text: &str) -> bool {
    let path = dir.join("summary.json");
    let Err(e) = std::fs::write(&path, format!("{text}\n")) else {
        return true;
    };
    let _ = std::fs::remove_file(&path);
    let first = crate::describe_io(&e);
    let fallback = fallback_summary(dir);
    match std::fs::write(&fallback, format!("{text}\n")) {
        Ok(()) => tilting_net::say_err(&format!(
            "live: error: cannot write {}: {first}; the summary is in {}",
            path.display(),
            fallback.display()
        )),
        Err(e2) => {
            tilting_net::say_err(&format!(
                "live: error: cannot write {} ({first}) nor {} ({}); the summary follows on stdout",
                path.display(),
                fallback.display(),
                crate::describe_io(&e2)
            ));
            let _ = tilting_net::say_out(text);
        }
    }
    false
}

/// Where the summary goes when the run's directory cannot take it: the system's temporary
/// directory, named after the run's directory.
pub(super) fn fallback_summary(dir: &Path) -> std::path::PathBuf {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "run".into());
    std::env::temp_dir().join(format!("tilting-live-{name}-summary.json"))
}
