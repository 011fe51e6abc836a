//! `tilting animate`: the plate and the arm, moving, as an animated GIF (or PNG frames for a
//! video), from a `simulate` scenario (the same flags) or from a recording (`--from
//! FILE.mcap`, or a live run's directory: its `run.mcap`, else its `state.csv` and
//! `events.csv`). The drawing is [`tilting_viz::animate`];
//! this module reads the inputs into a [`Trace`] and checks the flags.

use super::{bar, check, emit, usage};
use crate::record::{EVENTS_CSV, EVENTS_HEADER, STATE_CSV, STATE_HEADER};
use anyhow::{anyhow, bail, Context as _, Result};
use serde::Serialize;
use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufRead as _, BufReader, IsTerminal as _};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tilting_planner::CommandError;
use tilting_plant::{Mode, Params};
use tilting_sim::closed_loop::{EventRecord, Sample};
use tilting_sim::{ScenarioArgs, SimOptions};
use tilting_viz::animate::{animate, Options, Output, Rendered, MAX_FPS};
use tilting_viz::plot::Trace;

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
#[derive(Debug, Serialize)]
struct AnimateReport {
    /// The GIF file or the frame directory.
    out: PathBuf,
    /// `"gif"` or `"png-frames"`.
    format: &'static str,
    frames: usize,
    /// Frames per second of playback.
    fps: f64,
    speed: f64,
    /// Plant time window shown (s).
    t0: f64,
    t1: f64,
    /// Frames with a landing flashed.
    flashed: usize,
    /// Wall-clock time of the rendering (s).
    seconds: f64,
}

/// `tilting animate`.
pub fn run(args: &AnimateArgs) -> Result<(), CommandError> {
    check(
        "fps",
        args.fps,
        args.fps > 0.0 && args.fps <= MAX_FPS,
        "in (0, 50]",
    )?;
    check("speed", args.speed, args.speed > 0.0, "a positive number")?;
    for (name, v) in [("start", args.start), ("end", args.end)] {
        if let Some(v) = v {
            check(name, v, true, "a number of seconds")?;
        }
    }
    let (w, h) = args.size;
    if !((160..=4096).contains(&w) && (120..=4096).contains(&h)) {
        return Err(usage(format!(
            "invalid `--size` = {w}x{h}: must be from 160x120 to 4096x4096 px"
        )));
    }
    if let (Some(a), Some(b)) = (args.start, args.end) {
        if b <= a {
            return Err(usage(format!(
                "invalid `--end` = {b}: must be after `--start` = {a}"
            )));
        }
    }
    let (out, gif) = match (&args.frames, &args.out) {
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
    };
    let opts = Options {
        fps: args.fps,
        speed: args.speed,
        size: args.size,
        start: args.start,
        end: args.end,
    };
    let sc = args
        .scenario
        .load()
        .map_err(|e| CommandError::Usage(e.into()))?;
    // The trajectory: a live run's files, or a simulation.
    let (samples, events, end, early) = match &args.from {
        Some(from) => {
            let run =
                read_recording(from, args.start, args.end, None).map_err(CommandError::Usage)?;
            (run.samples, run.events, run.end, false)
        }
        None => {
            let r = tilting_sim::simulate(
                &sc,
                SimOptions {
                    record_samples: true,
                    progress: !args.json && std::io::stderr().is_terminal(),
                    network: None,
                    loop_options: Default::default(),
                    imperfect: None,
                },
            )
            .map_err(|e| CommandError::Usage(e.into()))?;
            if let Some(f) = &r.fault {
                eprintln!("warning: the simulation stopped early: {f}");
            }
            let end = r.final_state.t;
            (r.samples, r.events, end, r.fault.is_some())
        }
    };
    let trace = Trace {
        samples: &samples,
        events: &events,
        end,
        stopped_early: early,
    };
    let started = Instant::now();
    let pb = bar(0, "animate", args.json);
    let target = if gif {
        Output::Gif(&out)
    } else {
        Output::Frames(&out)
    };
    let r = animate(target, &sc.params, &trace, &opts, &pb)
        .with_context(|| format!("cannot animate into {}", out.display()))
        .map_err(CommandError::Failed)?;
    let seconds = started.elapsed().as_secs_f64();
    let report = AnimateReport {
        out: out.clone(),
        format: if gif { "gif" } else { "png-frames" },
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

/// Reads a recording: an MCAP file, a directory holding `run.mcap`, or a directory of CSV files
/// ([`read_run_dir`]); the window as in [`read_run_dir`].
pub fn read_recording(
    from: &Path,
    start: Option<f64>,
    end: Option<f64>,
    tail: Option<f64>,
) -> Result<RunTrace> {
    let mcap = if from.is_dir() {
        let m = from.join(crate::record::RUN_MCAP);
        m.is_file().then_some(m)
    } else {
        Some(from.to_path_buf())
    };
    match mcap {
        Some(m) => {
            let w = crate::record::Window { start, end, tail };
            let t = crate::record::load_window(&m, None, w)?;
            if t.truncated {
                eprintln!(
                    "note: {} was not closed normally; animating what it holds",
                    m.display()
                );
            }
            Ok(RunTrace {
                samples: t.samples,
                events: t.events,
                end: t.end,
            })
        }
        None => read_run_dir(from, start, end, tail),
    }
}

/// The trajectory of a live run's directory, as read by [`read_run_dir`].
#[derive(Debug, Clone, PartialEq)]
pub struct RunTrace {
    /// The states of `state.csv` in the window, in time order.
    pub samples: Vec<Sample>,
    /// The events of `events.csv`.
    pub events: Vec<EventRecord>,
    /// Plant time of the last row of `state.csv` (s).
    pub end: f64,
}

/// Reads `state.csv` and `events.csv` of a live run's directory (the formats of
/// [`crate::record`]), keeping the states with `start <= t <= end` (s) and, with `tail`, only
/// the last `tail` s of them (memory stays bounded by the window). Errors name the file and the
/// line: a missing file, a foreign header, a row that is not numbers, a mode out of 0..=2, a
/// time that goes back, or no states at all.
pub fn read_run_dir(
    dir: &Path,
    start: Option<f64>,
    end: Option<f64>,
    tail: Option<f64>,
) -> Result<RunTrace> {
    if !dir.is_dir() {
        bail!("the run directory {} does not exist", dir.display());
    }
    let mut samples = VecDeque::new();
    let mut last_t = f64::NEG_INFINITY;
    let path = dir.join(STATE_CSV);
    for_rows::<7>(&path, STATE_HEADER, |line, [_, t, q, a, b, ad, bd]| {
        let mode = mode_of(q).ok_or_else(|| row_error(&path, line, "the mode", q))?;
        if t < last_t {
            bail!(
                "{} line {line}: the time t = {t} s goes back (the row before has {last_t} s)",
                path.display()
            );
        }
        last_t = t;
        if start.is_some_and(|s| t < s) || end.is_some_and(|e| t > e) {
            return Ok(());
        }
        samples.push_back(Sample {
            t,
            mode,
            x: [a, b, ad, bd],
        });
        if let Some(w) = tail {
            while samples.front().is_some_and(|f: &Sample| f.t < t - w) {
                samples.pop_front();
            }
        }
        Ok(())
    })?;
    if samples.is_empty() {
        bail!(
            "{} has no states{}: nothing to animate",
            path.display(),
            if start.is_some() || end.is_some() {
                " in the window of --start/--end"
            } else {
                ""
            }
        );
    }
    let mut events = Vec::new();
    let path = dir.join(EVENTS_CSV);
    for_rows::<11>(&path, EVENTS_HEADER, |line, v| {
        let from = mode_of(v[1]).ok_or_else(|| row_error(&path, line, "the mode `from`", v[1]))?;
        let to = mode_of(v[2]).ok_or_else(|| row_error(&path, line, "the mode `to`", v[2]))?;
        events.push(EventRecord {
            t: v[0],
            from,
            to,
            x_before: [v[3], v[4], v[5], v[6]],
            x_after: [v[7], v[8], v[9], v[10]],
        });
        Ok(())
    })?;
    Ok(RunTrace {
        samples: samples.into(),
        events,
        end: last_t,
    })
}

fn mode_of(q: f64) -> Option<Mode> {
    (q.fract() == 0.0 && (0.0..=2.0).contains(&q))
        .then(|| Mode::try_from(q as u8).ok())
        .flatten()
}

fn row_error(path: &Path, line: usize, what: &str, v: f64) -> anyhow::Error {
    anyhow!(
        "{} line {line}: {what} is {v}, not one of 0 (flat), 1 (left), 2 (right)",
        path.display()
    )
}

/// Calls `row(line, numbers)` for every row of the CSV file `path` after its header (line 1,
/// which must be `header`); lines are numbered from 1 as an editor shows them.
fn for_rows<const N: usize>(
    path: &Path,
    header: &str,
    mut row: impl FnMut(usize, [f64; N]) -> Result<()>,
) -> Result<()> {
    let file = File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut lines = BufReader::new(file).lines();
    match lines.next() {
        Some(Ok(h)) if h.trim_end() == header => {}
        Some(Ok(h)) => bail!(
            "{} line 1: the header is {h:?}, expected {header:?}",
            path.display()
        ),
        Some(Err(e)) => bail!("cannot read {}: {e}", path.display()),
        None => bail!(
            "{} is empty: expected the header {header:?}",
            path.display()
        ),
    }
    for (i, line) in lines.enumerate() {
        let n = i + 2;
        let line = line.with_context(|| format!("cannot read {} line {n}", path.display()))?;
        if line.trim().is_empty() {
            continue;
        }
        let mut out = [0.0; N];
        let mut it = line.split(',');
        for (k, v) in out.iter_mut().enumerate() {
            let cell = it.next().ok_or_else(|| {
                anyhow!(
                    "{} line {n}: {k} values, expected {N}: {line:?}",
                    path.display()
                )
            })?;
            *v = cell
                .trim()
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| {
                    anyhow!(
                        "{} line {n}, column {}: {cell:?} is not a finite number",
                        path.display(),
                        k + 1
                    )
                })?;
        }
        if it.next().is_some() {
            bail!(
                "{} line {n}: more than {N} values: {line:?}",
                path.display()
            );
        }
        row(n, out)?;
    }
    Ok(())
}

/// Seconds of the end of a live run in its animation (`run.gif`).
pub const LIVE_CLIP: f64 = 8.0;

/// The short animation of a live run beside `run.png`: the last [`LIVE_CLIP`] s of the
/// recording in `dir`, real time at 20 fps, 480 x 360 px, into `gif`.
pub fn live_clip(dir: &Path, gif: &Path, params: &Params) -> Result<Rendered> {
    let run = read_recording(dir, None, None, Some(LIVE_CLIP))?;
    let trace = Trace {
        samples: &run.samples,
        events: &run.events,
        end: run.end,
        stopped_early: false,
    };
    let opts = Options {
        fps: 20.0,
        size: (480, 360),
        ..Options::default()
    };
    animate(
        Output::Gif(gif),
        params,
        &trace,
        &opts,
        &indicatif::ProgressBar::hidden(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, state: &str, events: &str) {
        std::fs::write(dir.join(STATE_CSV), state).unwrap();
        std::fs::write(dir.join(EVENTS_CSV), events).unwrap();
    }

    #[test]
    fn reads_a_run_dir_and_names_the_bad_line() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let ev = format!("{EVENTS_HEADER}\n0.002,1,0,0,1.5,-0.1,0,0,1.5,0,0.3\n");
        write(
            d,
            &format!(
                "{STATE_HEADER}\n0,0,1,0,1.5,0,0\n1,0.001,1,0.01,1.5,0,0\n2,0.002,0,0,1.5,0,0\n"
            ),
            &ev,
        );
        let r = read_run_dir(d, None, None, None).unwrap();
        assert_eq!(r.samples.len(), 3);
        assert_eq!(r.events.len(), 1);
        assert_eq!((r.events[0].from, r.events[0].to), (Mode::Left, Mode::Flat));
        assert_eq!(r.end, 0.002);
        // The tail keeps the last rows only.
        let r = read_run_dir(d, None, None, Some(0.0015)).unwrap();
        assert_eq!(r.samples.len(), 2);

        let err = |state: String| {
            write(d, &state, &ev);
            format!("{:#}", read_run_dir(d, None, None, None).unwrap_err())
        };
        let e = err(format!(
            "{STATE_HEADER}\n0,0,1,0,1.5,0,0\n1,0.001,1,x,1.5,0,0\n"
        ));
        assert!(
            e.contains("state.csv line 3, column 4") && e.contains("\"x\""),
            "{e}"
        );
        let e = err(format!("{STATE_HEADER}\n0,0,1,0,1.5,0\n"));
        assert!(e.contains("state.csv line 2: 6 values, expected 7"), "{e}");
        let e = err(format!("{STATE_HEADER}\n0,0,7,0,1.5,0,0\n"));
        assert!(e.contains("line 2: the mode is 7"), "{e}");
        let e = err(format!(
            "{STATE_HEADER}\n0,1,1,0,1.5,0,0\n1,0.5,1,0,1.5,0,0\n"
        ));
        assert!(e.contains("line 3: the time t = 0.5 s goes back"), "{e}");
        let e = err("seq,t\n".into());
        assert!(e.contains("state.csv line 1: the header"), "{e}");
        let e = err(format!("{STATE_HEADER}\n"));
        assert!(e.contains("has no states"), "{e}");
        std::fs::remove_file(d.join(EVENTS_CSV)).unwrap();
        std::fs::write(
            d.join(STATE_CSV),
            format!("{STATE_HEADER}\n0,0,1,0,1.5,0,0\n"),
        )
        .unwrap();
        let e = format!("{:#}", read_run_dir(d, None, None, None).unwrap_err());
        assert!(e.contains("cannot open") && e.contains("events.csv"), "{e}");
        let e = format!(
            "{:#}",
            read_run_dir(&d.join("nope"), None, None, None).unwrap_err()
        );
        assert!(e.contains("does not exist"), "{e}");
    }

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert!(parse_size("640").is_err() && parse_size("ax3").is_err());
    }
}
