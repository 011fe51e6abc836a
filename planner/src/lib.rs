//! Offline tools for the tilting system: closed-loop simulation now; boundary value problems,
//! sweeps and figures to come. The `tilting-planner` binary is a thin command-line shell over
//! these modules.
//!
//! - [`scenario`]: a simulation scenario (model, start, controller, coupling), its TOML file and
//!   command-line flags, and validation that names the offending field;
//! - [`simulate`]: the closed loop (continuous or zero-order-hold coupling) and its report;
//! - [`plot`]: PNG figures with an embedded font.

pub mod plot;
pub mod scenario;
pub mod simulate;

/// The error of a command, sorted by exit code.
#[derive(Debug)]
pub enum CommandError {
    /// Bad flags, an invalid scenario or parameter file (exit code 2).
    Usage(anyhow::Error),
    /// The command failed while running (I/O, drawing) (exit code 1).
    Failed(anyhow::Error),
}

impl CommandError {
    /// The process exit code: 2 for usage and configuration errors, 1 otherwise.
    pub fn exit_code(&self) -> u8 {
        match self {
            CommandError::Usage(_) => 2,
            CommandError::Failed(_) => 1,
        }
    }

    /// The underlying error.
    pub fn error(&self) -> &anyhow::Error {
        match self {
            CommandError::Usage(e) | CommandError::Failed(e) => e,
        }
    }
}

impl std::fmt::Display for CommandError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:#}", self.error())
    }
}

impl std::error::Error for CommandError {}
pub mod bifurcation;
pub mod commands;
pub mod figures;
pub mod gains;
pub mod live;
pub mod orbit;
pub mod publish;
pub mod record;
pub mod sinusoid;
