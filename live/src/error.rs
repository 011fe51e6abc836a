//! The error of a live run (or of a tool that watches a robot), sorted by how it ended; the
//! front door maps each to its exit code.

use tilting_planner::node::NodeError;
use tilting_record::ReadError;

/// The error of [`crate::run`], sorted by exit code (`tilting` maps them: 2, 1, 3, 4).
#[derive(Debug)]
pub enum LiveError {
    /// A flag, the robot file or a parameter file out of range: the message names it.
    Usage(anyhow::Error),
    /// The run failed (a child died, I/O, the recording): it did not end cleanly.
    Failed(anyhow::Error),
    /// The run ended on a fault of the model (the plant's own fault).
    Fault(anyhow::Error),
    /// The run ended without holding its orbit (the orbit verdict of the report).
    OrbitLost(anyhow::Error),
}

impl LiveError {
    /// The underlying error.
    pub fn error(&self) -> &anyhow::Error {
        match self {
            LiveError::Usage(e)
            | LiveError::Failed(e)
            | LiveError::Fault(e)
            | LiveError::OrbitLost(e) => e,
        }
    }
}

impl std::fmt::Display for LiveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#}", self.error())
    }
}

impl std::error::Error for LiveError {}

impl From<NodeError> for LiveError {
    /// An invalid flag or law is a usage error; a missing orbit or a failed session is not.
    fn from(e: NodeError) -> Self {
        match e {
            NodeError::Invalid(_) => LiveError::Usage(e.into()),
            NodeError::NoOrbit { .. } | NodeError::Run(_) => LiveError::Failed(e.into()),
        }
    }
}

impl From<ReadError> for LiveError {
    /// A recording that cannot be read: a failure.
    fn from(e: ReadError) -> Self {
        LiveError::Failed(e.into())
    }
}
