//! Shutting a live run down: the children in order, the plant first (its final status and
//! summary), then the controller; what went wrong, one sentence each.

use super::monitor::{End, GRACE_S, START_TIMEOUT_S};
use std::process::ExitStatus;
use tilting_launch::Child;

/// How the children ended.
pub(super) struct Stopped {
    /// The plant's exit status.
    pub(super) plant: ExitStatus,
    /// The controller's, if it was started.
    pub(super) controller: Option<ExitStatus>,
}

/// The problem the end of the monitoring is, if any (`None` for a clean end or an interrupt,
/// which is announced here).
fn problem(end: &End, plant: &Child, duration: f64) -> Option<String> {
    match end {
        End::PlantExited(s) if s.success() => None,
        End::PlantExited(s) => Some(format!(
            "the plant exited during the run with {s}{}",
            if s.code() == Some(3) {
                " (a fault of the model)"
            } else {
                ""
            }
        )),
        End::ControllerExited(s) => Some(format!("the controller exited during the run with {s}")),
        End::Interrupted => {
            eprintln!("live: interrupted, stopping the nodes");
            None
        }
        End::StartTimeout => Some(format!(
            "no state of the plant arrived within {START_TIMEOUT_S} s (see {})",
            plant.stderr_path().display()
        )),
        End::Timeout => Some(format!(
            "the plant did not finish within {} s of wall-clock time",
            duration + GRACE_S
        )),
    }
}

/// Stops the plant, then the controller (`force()`: kill at once), and adds to `problems` why
/// the run ended early and which child failed or had to be killed.
pub(super) fn stop_children(
    end: &End,
    plant: &mut Child,
    controller: Option<&mut Child>,
    force: &dyn Fn() -> bool,
    duration: f64,
    problems: &mut Vec<String>,
) -> Stopped {
    problems.extend(problem(end, plant, duration));
    let (plant_status, plant_killed) = tokio::task::block_in_place(|| plant.stop(force));
    let ctl = controller.map(|c| tokio::task::block_in_place(|| c.stop(force)));
    if plant_killed {
        problems.push(format!("the plant had to be killed ({plant_status})"));
    } else if !plant_status.success() && !matches!(end, End::PlantExited(_)) {
        problems.push(format!("the plant exited with {plant_status}"));
    }
    match ctl {
        Some((s, true)) => problems.push(format!("the controller had to be killed ({s})")),
        Some((s, false)) if !s.success() && !matches!(end, End::ControllerExited(_)) => {
            problems.push(format!("the controller exited with {s}"))
        }
        _ => {}
    }
    Stopped {
        plant: plant_status,
        controller: ctl.map(|c| c.0),
    }
}

/// The last lines of each child that failed, on stderr.
pub(super) fn show_failed_logs(plant: &Child, controller: Option<&Child>) {
    for child in std::iter::once(plant).chain(controller) {
        if child.status().is_some_and(|s| !s.success()) {
            eprintln!(
                "--- last lines of {} ({}) ---\n{}",
                child.name(),
                child.stderr_path().display(),
                child.log_tail(15)
            );
        }
    }
}

/// A node whose stdout failed (a full disk) put its summary in a fallback file: where, one
/// problem each (`dir`, the run's directory, where `{name}.json` was to be).
pub(super) fn fallback_problems(
    dir: &std::path::Path,
    plant: &Child,
    controller: Option<&Child>,
) -> Vec<String> {
    std::iter::once(plant)
        .chain(controller)
        .filter_map(|child| {
            let f = child.fallback_summary()?;
            Some(format!(
                "the {} could not print its summary into {} (see its log); it is in {}",
                child.name(),
                dir.join(format!("{}.json", child.name())).display(),
                f.display()
            ))
        })
        .collect()
}
