//! A recording for [`super::identify`]: the trace (the project's one loader) and the torque
//! answered to each state.
//!
//! The torque of the state `seq = k` (`TorqueCommand.seq`) is taken as held over that state's
//! interval `[t_k, t_{k+1}]`, as the sampled loop and the lockstep plant apply it. A state with
//! no torque answered leaves its interval out.

use super::IdentifyError;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use tilting_proto::{PlantState, TorqueCommand};
use tilting_record::trace::RUN_MCAP;
use tilting_record::{Topic, Trace, Window};

/// A recording ready for [`super::identify`].
#[derive(Debug, Clone)]
pub struct Recorded {
    /// The run's states and events, every state kept.
    pub trace: Trace,
    /// The torque (N m) held over each sample's interval, `None` where none was answered.
    pub tau: Vec<Option<f64>>,
    /// The robot name in the channels.
    pub robot: Option<String>,
    /// The MCAP file read.
    pub source: PathBuf,
}

/// The pause (s) put between two recordings joined by [`Recorded::append`]: longer than any
/// sample gap, so no equation spans the join.
pub const JOIN_GAP: f64 = 1.0;

impl Recorded {
    /// Appends `other` after this recording, its times shifted to start [`JOIN_GAP`] after
    /// this one's end: the rows of both enter one fit (several experiments on one robot, e.g.
    /// an excitation run and an orbit run, as MATLAB's `merge` of data sets).
    pub fn append(&mut self, other: Recorded) {
        let start = other.trace.samples.first().map_or(0.0, |s| s.t);
        let end = self
            .trace
            .samples
            .last()
            .map_or(0.0, |s| s.t)
            .max(self.trace.end);
        let shift = end + JOIN_GAP - start;
        self.trace
            .samples
            .extend(other.trace.samples.into_iter().map(|mut s| {
                s.t += shift;
                s
            }));
        self.trace
            .events
            .extend(other.trace.events.into_iter().map(|mut e| {
                e.t += shift;
                e
            }));
        self.trace.end = other.trace.end + shift;
        self.trace.stopped_early |= other.trace.stopped_early;
        self.tau.extend(other.tau);
    }
}

/// Loads an MCAP recording (or a live run's directory holding [`RUN_MCAP`]); with `robot`,
/// refuses a file of another robot, naming the one it holds.
pub fn load(path: &Path, robot: Option<&str>) -> Result<Recorded, IdentifyError> {
    let file = if path.is_dir() {
        path.join(RUN_MCAP)
    } else {
        path.to_path_buf()
    };
    let run = tilting_record::read(&file)?;
    let found = run.robot().map(str::to_owned);
    if let Some(asked) = robot {
        if found.as_deref() != Some(asked) {
            return Err(IdentifyError::Robot {
                path: file.display().to_string(),
                asked: asked.into(),
                found: found.map_or("no robot name".into(), |f| format!("{f:?}")),
            });
        }
    }
    let trace = tilting_record::load(&file, Window::default(), None)?.trace;
    let mut seqs = Vec::with_capacity(trace.samples.len());
    let mut torque = HashMap::new();
    for e in run.messages() {
        match e.topic {
            Topic::State => {
                if let Ok(s) = tilting_proto::decode::<PlantState>(&e.wire) {
                    seqs.push(s.seq);
                }
            }
            Topic::Torque => {
                if let Ok(c) = tilting_proto::decode::<TorqueCommand>(&e.wire) {
                    torque.entry(c.seq).or_insert(c.tau);
                }
            }
            _ => {}
        }
    }
    let tau = if seqs.len() == trace.samples.len() {
        seqs.iter().map(|s| torque.get(s).copied()).collect()
    } else {
        vec![None; trace.samples.len()]
    };
    Ok(Recorded {
        trace,
        tau,
        robot: found,
        source: file,
    })
}
