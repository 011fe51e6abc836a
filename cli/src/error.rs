//! The error of a `tilting` command and its exit code: the front door's mapping of what the
//! libraries report (their own typed errors) to the process's exit status.

use tilting_launch::LaunchError;
use tilting_live::LiveError;
use tilting_planner::jobs::JobError;
use tilting_planner::margins::{InvalidSurvey, SurveyError};
use tilting_planner::node::NodeError;
use tilting_planner::shard::ShardError;
use tilting_plant::ConfigError;
use tilting_record::ReadError;
use tilting_sim::ScenarioError;

/// The error of a command, sorted by exit code.
#[derive(Debug)]
pub enum CommandError {
    /// Bad flags, an invalid scenario or parameter file (exit code 2).
    Usage(anyhow::Error),
    /// The command failed while running (I/O, drawing) (exit code 1).
    Failed(anyhow::Error),
    /// A live run that ended on a fault of the model (exit code 3, the plant's own).
    Fault(anyhow::Error),
    /// A live run whose orbit was lost (exit code 4).
    OrbitLost(anyhow::Error),
}

impl CommandError {
    /// The process exit code: 2 for usage and configuration errors, 3 for a fault of the
    /// model, 4 for a lost orbit, 1 otherwise.
    pub fn exit_code(&self) -> u8 {
        match self {
            CommandError::Usage(_) => 2,
            CommandError::Failed(_) => 1,
            CommandError::Fault(_) => 3,
            CommandError::OrbitLost(_) => 4,
        }
    }

    /// The underlying error.
    pub fn error(&self) -> &anyhow::Error {
        match self {
            CommandError::Usage(e)
            | CommandError::Failed(e)
            | CommandError::Fault(e)
            | CommandError::OrbitLost(e) => e,
        }
    }
}

impl std::fmt::Display for CommandError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#}", self.error())
    }
}

impl std::error::Error for CommandError {}

impl From<NodeError> for CommandError {
    /// An invalid flag or law is a usage error; a missing orbit or a failed session is not.
    fn from(e: NodeError) -> Self {
        LiveError::from(e).into()
    }
}

impl From<LiveError> for CommandError {
    /// The live run's ending, one variant each: usage, failure, fault, lost orbit.
    fn from(e: LiveError) -> Self {
        match e {
            LiveError::Usage(e) => CommandError::Usage(e),
            LiveError::Failed(e) => CommandError::Failed(e),
            LiveError::Fault(e) => CommandError::Fault(e),
            LiveError::OrbitLost(e) => CommandError::OrbitLost(e),
        }
    }
}

impl From<JobError> for CommandError {
    /// An input out of range is a usage error; a failed computation or a missing orbit is not.
    fn from(e: JobError) -> Self {
        match e {
            JobError::Invalid(_) => CommandError::Usage(e.into()),
            JobError::Failed(_) | JobError::NoOrbit { .. } => CommandError::Failed(e.into()),
        }
    }
}

impl From<InvalidSurvey> for CommandError {
    /// A margins survey's flag out of range: a usage error.
    fn from(e: InvalidSurvey) -> Self {
        CommandError::Usage(e.into())
    }
}

impl From<SurveyError> for CommandError {
    /// A survey that could not run (no nominal orbit): a failure.
    fn from(e: SurveyError) -> Self {
        CommandError::Failed(e.into())
    }
}

impl From<ConfigError> for CommandError {
    /// A parameter file that cannot be read or is out of range: a usage error.
    fn from(e: ConfigError) -> Self {
        CommandError::Usage(e.into())
    }
}

impl From<ScenarioError> for CommandError {
    /// An invalid scenario (its file, a flag or a parameter out of range): a usage error.
    fn from(e: ScenarioError) -> Self {
        CommandError::Usage(e.into())
    }
}

impl From<ReadError> for CommandError {
    /// A recording that cannot be read: a failure.
    fn from(e: ReadError) -> Self {
        CommandError::Failed(e.into())
    }
}

impl From<ShardError> for CommandError {
    /// A shard that cannot be, or shard files that do not make one sweep: a usage error.
    fn from(e: ShardError) -> Self {
        CommandError::Usage(e.into())
    }
}

impl From<LaunchError> for CommandError {
    /// A bad flag or configuration file is a usage error; the rest is a failure. The message is
    /// the library's, unchanged.
    fn from(e: LaunchError) -> Self {
        match e {
            LaunchError::Invalid(e) => CommandError::Usage(e),
            LaunchError::Failed(e) => CommandError::Failed(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The planner's errors keep their exit codes in the front door: an invalid law is a usage
    /// error (2), a missing orbit or a failed session is a failure (1); the message is the
    /// library's.
    #[test]
    fn library_errors_map_to_exit_codes() {
        let invalid = CommandError::from(NodeError::Invalid(anyhow::anyhow!("bad `--kp`")));
        assert_eq!(
            (invalid.exit_code(), invalid.to_string().as_str()),
            (2, "bad `--kp`")
        );
        let orbit = CommandError::from(NodeError::NoOrbit { kp: 1.0, kd: 2.0 });
        assert_eq!(orbit.exit_code(), 1);
        assert!(orbit.to_string().contains("K_P = 1, K_D = 2"), "{orbit}");
        let run = CommandError::from(NodeError::Run(anyhow::anyhow!("no session")));
        assert_eq!(run.exit_code(), 1);
        // The jobs', the shards' and the launcher's the same way.
        let job = CommandError::from(JobError::Invalid("invalid `--peak` = 2".into()));
        assert_eq!(
            (job.exit_code(), job.to_string().as_str()),
            (2, "invalid `--peak` = 2")
        );
        assert_eq!(
            CommandError::from(JobError::Failed("x".into())).exit_code(),
            1
        );
        assert_eq!(
            CommandError::from(JobError::NoOrbit { kp: 1.0, kd: 2.0 }).exit_code(),
            1
        );
        let survey = CommandError::from(InvalidSurvey("invalid `--rate`".into()));
        assert_eq!(
            (survey.exit_code(), survey.to_string().as_str()),
            (2, "invalid `--rate`")
        );
        assert_eq!(
            CommandError::from(SurveyError::NoNominalOrbit(3)).exit_code(),
            1
        );
        let shard = CommandError::from(ShardError::Syntax("1".into()));
        assert_eq!(shard.exit_code(), 2);
        assert!(shard.to_string().contains("`--shard` = \"1\""), "{shard}");
        let bad = CommandError::from(LaunchError::Invalid(anyhow::anyhow!("--robot: x")));
        assert_eq!(
            (bad.exit_code(), bad.to_string().as_str()),
            (2, "--robot: x")
        );
        let failed = CommandError::from(LaunchError::Failed(anyhow::anyhow!("disk")));
        assert_eq!(failed.exit_code(), 1);
    }
}
