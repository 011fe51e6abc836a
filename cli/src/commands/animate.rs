//! `tilting animate`: the plate and the arm, moving, as an animated GIF (or PNG frames for a
//! video), from a `simulate` scenario (the same flags) or from a recording (`--from
//! FILE.mcap`, or a live run's directory: its `run.mcap`, else its `state.csv` and
//! `events.csv`). The drawing is [`tilting_viz::animate`], the reading [`tilting_record::load`];
//! this module checks the flags.

use super::{bar, emit, usage};
use crate::CommandError;
use anyhow::{Context as _, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tilting_record::{Trace, Window};
use tilting_sim::{ScenarioArgs, SimOptions};
use tilting_viz::animate::{animate, Options, Output};

/// Flags of `tilting animate`.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct AnimateArgs {
    /// The scenario to simulate (ignored with `--from`, except `--params` for the geometry).
    #[command(flatten)]
    pub scenario: ScenarioArgs,
    /// Animate a recording instead of a simulation: an MCAP file, or a live run's directory
    /// (its run.mcap, else its state.csv and events.csv)
    #[arg(long, value_name = "FILE.mcap|DIR")]
    pub from: Option<PathBuf>,
    /// The animated GIF to write [default: robot.gif]
    #[arg(long, value_name = "FILE.gif")]
    pub out: Option<PathBuf>,
    /// Write PNG frames frame_000000.png, ... into this directory instead of a GIF (created if
    /// missing, refused if it already holds frames); for a video:
    /// ffmpeg -framerate FPS -i DIR/frame_%06d.png robot.mp4
    #[arg(long, value_name = "DIR", conflicts_with = "out")]
    pub frames: Option<PathBuf>,
    /// Frames per second of playback, at most 50 (GIF delays are whole 1/100 s: 25 and 50 are
    /// exact, 30 plays at 100/3)
    #[arg(long, default_value_t = 25.0, value_name = "FPS")]
    pub fps: f64,
    /// Playback speed: plant seconds per second of playback (0.25 is slow motion)
    #[arg(long, default_value_t = 1.0, value_name = "FACTOR")]
    pub speed: f64,
    /// Frame size in pixels
    #[arg(long, default_value = "640x480", value_name = "WxH", value_parser = parse_size)]
    pub size: (u32, u32),
    /// First plant time shown (s) [default: the start of the run]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub start: Option<f64>,
    /// Last plant time shown (s) [default: the end of the run]
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pub end: Option<f64>,
    /// The tilt drawn this many times larger (display only, stated in each frame; 1 is to
    /// scale, as in the Foxglove scene's default)
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "K",
        allow_negative_numbers = true
    )]
    pub tilt_exaggeration: f64,
    /// Print one JSON object (out, frames, fps, window, landings flashed, seconds) instead of a
    /// line of text
    #[arg(long)]
    pub json: bool,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("invalid size {s:?}: expected WIDTHxHEIGHT in pixels, e.g. 640x480");
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    Ok((
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    ))
}

/// What `animate --json` prints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AnimateReport {
    /// The GIF file or the frame directory.
    pub out: PathBuf,
    /// What was written.
    pub format: AnimationFormat,
    /// Frames drawn.
    pub frames: usize,
    /// Frames per second of playback.
    pub fps: f64,
    /// Playback speed: plant seconds per second of playback.
    pub speed: f64,
    /// First plant time shown (s).
    pub t0: f64,
    /// Last plant time shown (s).
    pub t1: f64,
    /// Frames with a landing flashed.
    pub flashed: usize,
    /// Wall-clock time of the rendering (s).
    pub seconds: f64,
}

/// The output of `tilting animate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AnimationFormat {
    /// An animated GIF (`--out`).
    #[serde(rename = "gif")]
    Gif,
    /// PNG frames in a directory (`--frames`).
    #[serde(rename = "png-frames")]
    PngFrames,
}

/// `tilting animate`.
pub fn run(args: &AnimateArgs) -> Result<(), CommandError> {
    let opts = Options {
        fps: args.fps,
        speed: args.speed,
        size: args.size,
        start: args.start,
        end: args.end,
        tilt_exaggeration: args.tilt_exaggeration,
    };
    opts.validate().map_err(CommandError::Usage)?;
    let (out, gif) = output(args)?;
    let sc = args.scenario.load()?;
    // The trajectory: a live run's files, or a simulation.
    let trace = match &args.from {
        Some(from) => {
            let w = Window {
                start: args.start,
                end: args.end,
                tail: None,
            };
            load_run(from, w).map_err(CommandError::Usage)?
        }
        None => {
            let r = super::simulate_with_bar(
                &sc,
                SimOptions {
                    record_samples: true,
                    network: None,
                    loop_options: Default::default(),
                    imperfect: None,
                    log_measurements: false,
                },
                args.json,
            )?;
            if let Some(f) = &r.fault {
                eprintln!("warning: the simulation stopped early: {f}");
            }
            r.trace()
        }
    };
    let started = Instant::now();
    let pb = bar(0, "animate", args.json);
    let target = if gif {
        Output::Gif(&out)
    } else {
        Output::Frames(&out)
    };
    let progress = |done, frames| {
        pb.set_length(frames as u64);
        pb.set_position(done as u64);
    };
    let r = animate(target, &sc.params, &trace, &opts, &progress);
    pb.finish_and_clear();
    let r = r
        .with_context(|| format!("cannot animate into {}", out.display()))
        .map_err(CommandError::Failed)?;
    let seconds = started.elapsed().as_secs_f64();
    let report = AnimateReport {
        out: out.clone(),
        format: if gif {
            AnimationFormat::Gif
        } else {
            AnimationFormat::PngFrames
        },
        frames: r.timeline.frames,
        fps: r.timeline.fps(),
        speed: args.speed,
        t0: r.timeline.t0,
        t1: r.timeline.t1,
        flashed: r.flashed,
        seconds,
    };
    emit(args.json, &report, || {
        let mut s = format!(
            "animation: {} ({} frames at {} fps, t = {:.3} to {:.3} s at speed {}, {} frames flashed for landings; {:.1} s)\n",
            out.display(),
            report.frames,
            report.fps,
            report.t0,
            report.t1,
            args.speed,
            report.flashed,
            seconds
        );
        if !gif {
            s.push_str(&format!(
                "video: ffmpeg -framerate {} -i {}/frame_%06d.png -pix_fmt yuv420p robot.mp4\n",
                report.fps,
                out.display()
            ));
        }
        s
    })
}

/// Where `animate` writes, checked: `(the frame directory, false)` for `--frames` (created,
/// refused if it already holds frames), else `(the GIF file, true)`.
fn output(args: &AnimateArgs) -> Result<(PathBuf, bool), CommandError> {
    Ok(match (&args.frames, &args.out) {
        (Some(d), _) => {
            // Frames of an earlier, longer render would join this one in a video.
            let old = std::fs::read_dir(d).ok().and_then(|mut it| {
                it.find_map(|e| {
                    let name = e.ok()?.file_name().into_string().ok()?;
                    (name.starts_with("frame_") && name.ends_with(".png")).then_some(name)
                })
            });
            if let Some(name) = old {
                return Err(usage(format!(
                    "invalid `--frames` = {}: the directory already holds frames ({name}); \
                     remove them or choose another directory",
                    d.display()
                )));
            }
            std::fs::create_dir_all(d)
                .with_context(|| format!("cannot create the frame directory {}", d.display()))
                .map_err(CommandError::Failed)?;
            (d.clone(), false)
        }
        (None, o) => {
            let o = o.clone().unwrap_or_else(|| PathBuf::from("robot.gif"));
            if !o.extension().is_some_and(|e| e.eq_ignore_ascii_case("gif")) {
                return Err(usage(format!(
                    "invalid `--out` = {}: must be a file name ending in .gif (or use --frames DIR)",
                    o.display()
                )));
            }
            if let Some(dir) = o.parent().filter(|d| !d.as_os_str().is_empty()) {
                if !dir.is_dir() {
                    return Err(usage(format!(
                        "invalid `--out` = {}: the directory {} does not exist",
                        o.display(),
                        dir.display()
                    )));
                }
            }
            (o, true)
        }
    })
}

/// The trajectory of a recording in `w` ([`tilting_record::load`]: an MCAP file, or a live
/// run's directory), with a note on stderr when the file was not closed normally.
fn load_run(from: &Path, w: Window) -> Result<Trace> {
    let run = tilting_record::load(from, w, None)?;
    if run.truncated {
        eprintln!(
            "note: {} was not closed normally; animating what it holds",
            run.source.display()
        );
    }
    Ok(run.trace)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert!(parse_size("640").is_err() && parse_size("ax3").is_err());
    }
}
