//! A run's trajectory ([`Trace`]) and its one loader ([`load`]): from an MCAP recording, from
//! a live run's directory (its `run.mcap`, else its CSV files), for plots and animations.
//!
//! The offline simulation fills the same types (`tilting_sim` re-exports [`Sample`] and
//! [`EventRecord`] and builds a [`Trace`] from its report), so a figure or an animation draws
//! a simulated run and a recorded one alike.
//!
//! The CSV files of a live run's directory (written by `tilting live --csv`; numbers in Rust's
//! shortest round-trip form, modes as wire bytes: 0 flat, 1 left, 2 right):
//!
//! - [`STATE_CSV`]: [`STATE_HEADER`], one row per `PlantState`;
//! - [`TORQUE_CSV`]: [`TORQUE_HEADER`], one row per `TorqueCommand`;
//! - [`EVENTS_CSV`]: [`EVENTS_HEADER`], one row per `ModeEvent`.

use crate::{ReadError, Topic};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufRead, BufReader, Read as _};
use std::path::{Path, PathBuf};
use tilting_proto::{bounded, DecodeError, Mode, ModeError, ModeEvent, PlantState};

/// The MCAP recording of a live run's directory.
pub const RUN_MCAP: &str = "run.mcap";
/// The states of a live run's directory (with `--csv`).
pub const STATE_CSV: &str = "state.csv";
/// The torques of a live run's directory (with `--csv`).
pub const TORQUE_CSV: &str = "torque.csv";
/// The events of a live run's directory (with `--csv`).
pub const EVENTS_CSV: &str = "events.csv";
/// The state columns of every CSV file of the project (the plant's `--record FILE.csv` adds
/// `tau`): sample number, plant time (s), mode byte, then rad and rad/s.
pub const STATE_HEADER: &str = "seq,t,mode,alpha,beta,alpha_dot,beta_dot";
/// Header of [`TORQUE_CSV`]: the `seq` answered and the torque (N m).
pub const TORQUE_HEADER: &str = "seq,tau";
/// Header of [`EVENTS_CSV`]: plant time (s), the mode bytes, the state just before and just
/// after (rad, rad/s).
pub const EVENTS_HEADER: &str = "t,from,to,alpha_before,beta_before,alpha_dot_before,\
beta_dot_before,alpha_after,beta_after,alpha_dot_after,beta_dot_after";

/// One point of a trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Plant time (s).
    pub t: f64,
    /// Contact mode.
    pub mode: Mode,
    /// State `[alpha, beta, alpha_dot, beta_dot]` (rad, rad/s). A rate the plant did not
    /// measure (`--measure angles`) is NaN here, never zero: plots leave it out.
    pub x: [f64; 4],
}

/// A mode transition.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EventRecord {
    /// Plant time (s).
    pub t: f64,
    /// Mode before.
    pub from: Mode,
    /// Mode after.
    pub to: Mode,
    /// State just before `[alpha, beta, alpha_dot, beta_dot]` (rad, rad/s).
    pub x_before: [f64; 4],
    /// State just after (the impact map applied for a landing).
    pub x_after: [f64; 4],
}

/// A run's trajectory: an offline run's or a recording's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// The trajectory, in time order (decimated as the producer likes; mode changes kept).
    pub samples: Vec<Sample>,
    /// The mode transitions, in time order.
    pub events: Vec<EventRecord>,
    /// Plant time at the end of the run (s).
    pub end: f64,
    /// The run ended before its planned duration (a fault, or a node that failed).
    pub stopped_early: bool,
}

/// The part of a run to load (plant time, s); the default is all of it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Window {
    /// First time kept.
    pub start: Option<f64>,
    /// Last time kept.
    pub end: Option<f64>,
    /// Keep only this many seconds before the end of the run.
    pub tail: Option<f64>,
}

/// A run read by [`load`].
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    /// The trajectory in the window (`stopped_early` is false: a recording does not say).
    pub trace: Trace,
    /// The file read: the MCAP recording, or the directory of CSV files.
    pub source: PathBuf,
    /// The MCAP file was not closed normally (see [`crate::Recording::truncation`]); always
    /// false for CSV files.
    pub truncated: bool,
}

/// Why a run cannot be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The MCAP file cannot be read as a recording.
    #[error(transparent)]
    Read(#[from] ReadError),
    /// A recorded message does not decode.
    #[error("{path}: {cause}")]
    Decode {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: DecodeError,
    },
    /// A recorded message has a mode byte out of range.
    #[error("{path}: {cause}")]
    Mode {
        /// The file.
        path: PathBuf,
        /// The cause.
        cause: ModeError,
    },
    /// Nothing to draw: no state at all, or none in the window.
    #[error("{path} holds no plant state{}: nothing to draw", if *.windowed { " in the window asked for" } else { "" })]
    NoStates {
        /// The file.
        path: PathBuf,
        /// A window was asked for.
        windowed: bool,
    },
    /// A CSV file is missing, unreadable or malformed (the message names the file and line).
    #[error("{0}")]
    Csv(String),
}

/// Loads a run: an MCAP file, a live run's directory holding [`RUN_MCAP`], or a live run's
/// directory of CSV files ([`STATE_CSV`] and [`EVENTS_CSV`]). Keeps the states in `window`
/// (memory bounded by the window) and, with `max_points`, about that many of them (mode changes
/// and the last state always kept); every event.
///
/// Errors name the file (and for CSV the line): a file that is not a recording, a missing
/// file, a foreign header, a row that is not numbers, a mode out of 0..=2, a time that goes
/// back, or no states at all.
pub fn load(path: &Path, window: Window, max_points: Option<u64>) -> Result<Loaded, LoadError> {
    let mcap = if path.is_dir() {
        let m = path.join(RUN_MCAP);
        m.is_file().then_some(m)
    } else {
        Some(path.to_path_buf())
    };
    match mcap {
        Some(m) => load_mcap(&m, window, max_points),
        None => {
            let mut trace = load_csv(path, window)?;
            if let Some(m) = max_points {
                trace.samples = decimate(&trace.samples, m);
            }
            Ok(Loaded {
                trace,
                source: path.to_path_buf(),
                truncated: false,
            })
        }
    }
}

/// Keeps every `ceil(len / max_points)`-th sample, every mode change and the last sample.
fn decimate(samples: &[Sample], max_points: u64) -> Vec<Sample> {
    let stride = (samples.len() as u64).div_ceil(max_points.max(1)).max(1);
    let mut out = Vec::new();
    let mut skip = 0u64;
    let mut last_mode = None;
    for s in samples {
        if skip == 0 || last_mode != Some(s.mode) {
            out.push(*s);
        }
        skip = if skip == 0 { stride - 1 } else { skip - 1 };
        last_mode = Some(s.mode);
    }
    if let (Some(l), Some(p)) = (samples.last(), out.last()) {
        if p.t < l.t {
            out.push(*l);
        }
    }
    out
}

fn load_mcap(path: &Path, w: Window, max_points: Option<u64>) -> Result<Loaded, LoadError> {
    let run = crate::read(path)?;
    let states = run.count(Topic::State);
    let no_states = |windowed| LoadError::NoStates {
        path: path.to_owned(),
        windowed,
    };
    if states == 0 {
        return Err(no_states(false));
    }
    let last = run.span().map_or(0.0, |s| s.1);
    let t0 = match (w.start, w.tail) {
        (Some(a), Some(t)) => a.max(last - t),
        (Some(a), None) => a,
        (None, Some(t)) => last - t,
        (None, None) => f64::NEG_INFINITY,
    };
    let t1 = w.end.unwrap_or(f64::INFINITY);
    let stride = max_points.map_or(1, |m| states.div_ceil(m.max(1)).max(1));
    let mut trace = Trace {
        samples: Vec::with_capacity((states / stride + 1024).min(1 << 22) as usize),
        ..Trace::default()
    };
    let decode = |cause| LoadError::Decode {
        path: path.to_owned(),
        cause,
    };
    let mode = |cause| LoadError::Mode {
        path: path.to_owned(),
        cause,
    };
    let mut last_mode = None;
    let mut last: Option<Sample> = None;
    // States to skip before the next kept one.
    let mut skip = 0u64;
    for e in run.messages() {
        match e.topic {
            Topic::State => {
                let s: PlantState = tilting_proto::decode(&e.wire).map_err(decode)?;
                if s.time < t0 || s.time > t1 {
                    continue;
                }
                let sample = Sample {
                    t: s.time,
                    mode: s.mode().map_err(mode)?,
                    x: [
                        s.alpha,
                        s.beta,
                        s.alpha_dot.unwrap_or(f64::NAN),
                        s.beta_dot.unwrap_or(f64::NAN),
                    ],
                };
                if skip == 0 || last_mode != Some(sample.mode) {
                    trace.samples.push(sample);
                }
                skip = if skip == 0 { stride - 1 } else { skip - 1 };
                last_mode = Some(sample.mode);
                last = Some(sample);
            }
            Topic::Event => {
                let ev: ModeEvent = tilting_proto::decode(&e.wire).map_err(decode)?;
                let (from, to) = ev.modes().map_err(mode)?;
                trace.events.push(EventRecord {
                    t: ev.time,
                    from,
                    to,
                    x_before: ev.x_before,
                    x_after: ev.x_after,
                });
            }
            _ => {}
        }
    }
    if let (Some(l), Some(p)) = (last, trace.samples.last()) {
        if p.t < l.t {
            trace.samples.push(l);
        }
    }
    trace.end = last.map_or(0.0, |l| l.t);
    if trace.samples.is_empty() {
        return Err(no_states(true));
    }
    Ok(Loaded {
        trace,
        source: path.to_owned(),
        truncated: !run.complete(),
    })
}

/// Reads [`STATE_CSV`] and [`EVENTS_CSV`] of a live run's directory, keeping the states in the
/// window.
fn load_csv(dir: &Path, w: Window) -> Result<Trace, LoadError> {
    let mut samples = VecDeque::new();
    let mut last_t = f64::NEG_INFINITY;
    let path = dir.join(STATE_CSV);
    // The rates' cells are empty when not measured: NaN in the trace.
    for_rows::<7>(
        &path,
        STATE_HEADER,
        &[5, 6],
        |line, [_, t, q, a, b, ad, bd]| {
            let mode = mode_of(q).ok_or_else(|| row_error(&path, line, "the mode", q))?;
            if t < last_t {
                return Err(LoadError::Csv(format!(
                    "{} line {line}: the time t = {t} s goes back (the row before has {last_t} s)",
                    path.display()
                )));
            }
            last_t = t;
            if w.start.is_some_and(|s| t < s) || w.end.is_some_and(|e| t > e) {
                return Ok(());
            }
            samples.push_back(Sample {
                t,
                mode,
                x: [a, b, ad, bd],
            });
            if let Some(tail) = w.tail {
                while samples.front().is_some_and(|f: &Sample| f.t < t - tail) {
                    samples.pop_front();
                }
            }
            Ok(())
        },
    )?;
    if samples.is_empty() {
        return Err(LoadError::Csv(format!(
            "{} has no states{}: nothing to draw",
            path.display(),
            if w.start.is_some() || w.end.is_some() {
                " in the window asked for"
            } else {
                ""
            }
        )));
    }
    let mut events = Vec::new();
    let path = dir.join(EVENTS_CSV);
    for_rows::<11>(&path, EVENTS_HEADER, &[], |line, v| {
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
    // As for a recording: the run ends, for this window, at its last state.
    let end = samples.back().map_or(last_t, |s: &Sample| s.t);
    Ok(Trace {
        samples: samples.into(),
        events,
        end,
        stopped_early: false,
    })
}

fn mode_of(q: f64) -> Option<Mode> {
    (q.fract() == 0.0 && (0.0..=2.0).contains(&q))
        .then(|| Mode::try_from(q as u8).ok())
        .flatten()
}

fn row_error(path: &Path, line: usize, what: &str, v: f64) -> LoadError {
    LoadError::Csv(format!(
        "{} line {line}: {what} is {v}, not one of 0 (flat), 1 (left), 2 (right)",
        path.display()
    ))
}

/// Longest line of a CSV recording (bytes); ours are under 200.
const MAX_LINE: u64 = 4096;

/// The lines of a CSV file, none longer than [`MAX_LINE`] (a longer one is an error: a file
/// without line ends, such as `/dev/zero`, is not read to its end), at most
/// [`bounded::RECORDING_LIMIT`] bytes in all.
fn bounded_lines(r: impl BufRead) -> impl Iterator<Item = std::io::Result<String>> {
    let mut r = r.take(bounded::RECORDING_LIMIT);
    std::iter::from_fn(move || {
        let mut buf = Vec::new();
        match (&mut r).take(MAX_LINE + 1).read_until(b'\n', &mut buf) {
            Ok(0) => None,
            Ok(_) if buf.len() as u64 > MAX_LINE => Some(Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("a line longer than {MAX_LINE} bytes (not a CSV recording?)"),
            ))),
            Ok(_) => {
                if buf.last() == Some(&b'\n') {
                    buf.pop();
                    if buf.last() == Some(&b'\r') {
                        buf.pop();
                    }
                }
                Some(String::from_utf8(buf).map_err(|e| {
                    std::io::Error::new(std::io::ErrorKind::InvalidData, e.to_string())
                }))
            }
            Err(e) => Some(Err(e)),
        }
    })
}

/// Calls `row(line, numbers)` for every row of the CSV file `path` after its header (line 1,
/// which must be `header`); lines are numbered from 1 as an editor shows them.
fn for_rows<const N: usize>(
    path: &Path,
    header: &str,
    may_be_empty: &[usize],
    mut row: impl FnMut(usize, [f64; N]) -> Result<(), LoadError>,
) -> Result<(), LoadError> {
    let csv = |m: String| LoadError::Csv(m);
    let file = File::open(path).map_err(|e| csv(format!("cannot open {}: {e}", path.display())))?;
    let mut lines = bounded_lines(BufReader::new(file));
    match lines.next() {
        Some(Ok(h)) if h.trim_end() == header => {}
        Some(Ok(h)) => {
            return Err(csv(format!(
                "{} line 1: the header is {h:?}, expected {header:?}",
                path.display()
            )))
        }
        Some(Err(e)) => return Err(csv(format!("cannot read {}: {e}", path.display()))),
        None => {
            return Err(csv(format!(
                "{} is empty: expected the header {header:?}",
                path.display()
            )))
        }
    }
    for (i, line) in lines.enumerate() {
        let n = i + 2;
        let line =
            line.map_err(|e| csv(format!("cannot read {} line {n}: {e}", path.display())))?;
        if line.trim().is_empty() {
            continue;
        }
        let mut out = [0.0; N];
        let mut it = line.split(',');
        for (k, v) in out.iter_mut().enumerate() {
            let cell = it.next().ok_or_else(|| {
                csv(format!(
                    "{} line {n}: {k} values, expected {N}: {line:?}",
                    path.display()
                ))
            })?;
            if cell.trim().is_empty() && may_be_empty.contains(&k) {
                *v = f64::NAN;
                continue;
            }
            *v = cell
                .trim()
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| {
                    csv(format!(
                        "{} line {n}, column {}: {cell:?} is not a finite number",
                        path.display(),
                        k + 1
                    ))
                })?;
        }
        if it.next().is_some() {
            return Err(csv(format!(
                "{} line {n}: more than {N} values: {line:?}",
                path.display()
            )));
        }
        row(n, out)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::McapWriter;
    use tilting_proto::{encode, Keys};

    fn write(dir: &Path, state: &str, events: &str) {
        std::fs::write(dir.join(STATE_CSV), state).unwrap();
        std::fs::write(dir.join(EVENTS_CSV), events).unwrap();
    }

    fn csv(d: &Path) -> Result<Trace, LoadError> {
        load(d, Window::default(), None).map(|l| l.trace)
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
        let r = load(d, Window::default(), None).unwrap();
        assert_eq!((r.source.as_path(), r.truncated), (d, false));
        let r = r.trace;
        assert_eq!(r.samples.len(), 3);
        assert_eq!(r.samples[1].x, [0.01, 1.5, 0.0, 0.0]);
        assert_eq!(r.events.len(), 1);
        assert_eq!((r.events[0].from, r.events[0].to), (Mode::Left, Mode::Flat));
        assert_eq!(r.end, 0.002);
        // The tail keeps the last rows only.
        let w = Window {
            tail: Some(0.0015),
            ..Window::default()
        };
        assert_eq!(load(d, w, None).unwrap().trace.samples.len(), 2);

        let err = |state: String| {
            write(d, &state, &ev);
            csv(d).unwrap_err().to_string()
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
        let e = csv(d).unwrap_err().to_string();
        assert!(e.contains("cannot open") && e.contains("events.csv"), "{e}");
        // A path that is not a directory is read as an MCAP file.
        let e = csv(&d.join("nope")).unwrap_err().to_string();
        assert!(e.contains("cannot read") && e.contains("nope"), "{e}");
    }

    fn state(seq: u64, mode: u8) -> PlantState {
        PlantState {
            seq,
            time: seq as f64 * 1e-3,
            alpha: 0.0,
            beta: 1.5 + seq as f64 * 1e-6,
            alpha_dot: Some(0.0),
            beta_dot: Some(0.0),
            mode,
        }
    }

    /// An MCAP file and the same run as CSV files load to the same trace; the window, the
    /// decimation (mode changes and the last state kept) and a directory holding `run.mcap`
    /// all go through [`load`].
    #[test]
    fn mcap_and_csv_load_alike() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let mcap = d.join(RUN_MCAP);
        let mut rec = McapWriter::create(&mcap, &Keys::new("t").unwrap()).unwrap();
        let mut rows = format!("{STATE_HEADER}\n");
        for k in 0..1000u64 {
            let s = state(k, if k < 500 { 1 } else { 2 });
            rec.record(Topic::State, &encode(&s)).unwrap();
            rows += &format!(
                "{},{},{},{},{},{},{}\n",
                s.seq,
                s.time,
                s.mode,
                s.alpha,
                s.beta,
                s.alpha_dot.unwrap(),
                s.beta_dot.unwrap()
            );
        }
        let e = ModeEvent {
            seq: 499,
            time: 0.4995,
            from: 1,
            to: 2,
            x_before: [0.0, 1.5, -0.1, 0.2],
            x_after: [0.0, 1.5, 0.1, 0.2],
        };
        rec.record(Topic::Event, &encode(&e)).unwrap();
        rec.finish().unwrap();
        let csv_dir = d.join("csv");
        std::fs::create_dir(&csv_dir).unwrap();
        write(
            &csv_dir,
            &rows,
            &format!("{EVENTS_HEADER}\n0.4995,1,2,0,1.5,-0.1,0.2,0,1.5,0.1,0.2\n"),
        );
        let w = Window {
            start: Some(0.0995),
            end: Some(0.8995),
            tail: None,
        };
        let a = load(&mcap, w, None).unwrap();
        let b = load(&csv_dir, w, None).unwrap();
        assert!(!a.truncated);
        assert_eq!(a.trace, b.trace);
        let n = a.trace.samples.len();
        assert_eq!(n, 800);
        assert_eq!(a.trace.samples[0], b.trace.samples[0]);
        assert_eq!(a.trace.samples[0].t, state(100, 1).time);
        assert_eq!(a.trace.samples[n - 1].t, state(899, 2).time);
        assert_eq!(a.trace.end, state(899, 2).time);
        for path in [&mcap, &csv_dir] {
            let t = load(path, w, Some(100)).unwrap().trace;
            // About 100 points (the MCAP stride counts the whole file), the first state of
            // the right tilt and the last state kept.
            assert!((80..=103).contains(&t.samples.len()), "{}", t.samples.len());
            assert!(t.samples.iter().any(|s| s.t == state(500, 2).time));
            assert_eq!(t.samples.last(), a.trace.samples.last());
        }
        // A directory with run.mcap reads the recording.
        assert_eq!(load(d, w, None).unwrap().source, mcap);
        let e = load(
            &mcap,
            Window {
                start: Some(5.0),
                ..w
            },
            None,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("no plant state in the window"), "{e}");
    }

    /// States without rates (`--measure angles`) load with NaN rates from MCAP and from the
    /// CSV's empty cells: never as zeros.
    #[test]
    fn absent_rates_load_as_nan_not_zero() {
        let tmp = tempfile::tempdir().unwrap();
        let d = tmp.path();
        let mcap = d.join(RUN_MCAP);
        let mut rec = McapWriter::create(&mcap, &Keys::new("t").unwrap()).unwrap();
        let mut rows = format!("{STATE_HEADER}\n");
        for k in 0..10u64 {
            let s = PlantState {
                alpha_dot: None,
                beta_dot: None,
                ..state(k, 1)
            };
            rec.record(Topic::State, &encode(&s)).unwrap();
            rows += &format!("{},{},{},{},{},,\n", s.seq, s.time, s.mode, s.alpha, s.beta);
        }
        rec.finish().unwrap();
        let csv_dir = d.join("csv");
        std::fs::create_dir(&csv_dir).unwrap();
        write(&csv_dir, &rows, &format!("{EVENTS_HEADER}\n"));
        let all = Window {
            start: None,
            end: None,
            tail: None,
        };
        for dir in [mcap.as_path(), csv_dir.as_path()] {
            let t = load(dir, all, None).unwrap().trace;
            assert_eq!(t.samples.len(), 10);
            for s in &t.samples {
                assert!(s.x[2].is_nan() && s.x[3].is_nan(), "{:?}", s.x);
                assert!(s.x[1] >= 1.5);
            }
        }
        // An empty angle cell is still refused.
        std::fs::write(
            csv_dir.join(STATE_CSV),
            format!("{STATE_HEADER}\n0,0,1,,1.5,,\n"),
        )
        .unwrap();
        assert!(load(&csv_dir, all, None).is_err());
    }
}
