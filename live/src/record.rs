//! The recording of a live run: the one [`Recorder`] of `tilting_record` (the robot's five
//! topics as received, streamed with flat memory into `run.mcap` and optionally the CSV files
//! of `--csv`; see [`tilting_record::recorder`]), and the figure drawn from the recording at
//! the end, and its short animation.

use anyhow::Result;
use std::path::Path;
use tilting_plant::Params;
use tilting_record::trace::RUN_MCAP;
use tilting_record::Window;
pub use tilting_record::{Record, RecordSender, RecordView, Recorder};
use tilting_sim::Scenario;
use tilting_viz::animate::{animate, Options, Output, Rendered};
use tilting_viz::plot::plot_trace;

/// The figure of a live run, beside the recording.
pub const RUN_PNG: &str = "run.png";

/// Points kept for the figure, about.
const PLOT_POINTS: u64 = 20_000;

/// Draws `alpha(t)` and `beta(t)` of the recording `run.mcap` in `dir` into `png` (via
/// [`plot_trace`]), decimated to about 20 000 points (mode changes are always kept).
/// `scenario` gives the gains and the control period for the title; `stopped_early` marks an
/// early end.
pub fn plot_recording(
    dir: &Path,
    png: &Path,
    scenario: &Scenario,
    stopped_early: bool,
) -> Result<()> {
    let run = tilting_record::load(
        &dir.join(RUN_MCAP),
        tilting_record::Window::default(),
        Some(PLOT_POINTS),
    )?;
    let sc = Scenario {
        duration: run.trace.end.max(1e-3),
        ..scenario.clone()
    };
    let trace = tilting_record::Trace {
        stopped_early: stopped_early || run.truncated,
        ..run.trace
    };
    plot_trace(png, &sc, &trace)
}

/// Seconds of the end of a live run in its animation (`run.gif`).
pub const LIVE_CLIP: f64 = 8.0;

/// The short animation of a live run beside `run.png`: the last [`LIVE_CLIP`] s of the
/// recording in `dir`, real time at 20 fps, 480 x 360 px, into `gif`.
pub fn live_clip(dir: &Path, gif: &Path, params: &Params) -> Result<Rendered> {
    let w = Window {
        tail: Some(LIVE_CLIP),
        ..Window::default()
    };
    let trace = tilting_record::load(dir, w, None)?.trace;
    let opts = Options {
        fps: 20.0,
        size: (480, 360),
        ..Options::default()
    };
    animate(Output::Gif(gif), params, &trace, &opts, &|_, _| {})
}

#[cfg(test)]
mod tests {
    use super::*;
    use tilting_proto::{Keys, PlantState};
    use tilting_record::Sources;

    #[test]
    fn plots_a_recording() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let rec = Recorder::create(
            dir,
            &Keys::new("t").unwrap(),
            false,
            None,
            Sources::default(),
        )
        .unwrap();
        let tx = rec.sender();
        for k in 0..100u64 {
            tx.send(Record::State(PlantState {
                seq: k,
                time: k as f64 * 1e-3,
                alpha: 0.01 * (k as f64 * 0.06).sin(),
                beta: 1.5,
                alpha_dot: Some(0.0),
                beta_dot: Some(0.0),
                mode: 1,
            }));
        }
        rec.finish().unwrap();
        let png = dir.join(RUN_PNG);
        plot_recording(dir, &png, &Scenario::default(), false).unwrap();
        assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
    }
}
