//! [`LaunchError`]: what starting a deployment reports, sorted the way a front door maps it to
//! an exit code.

/// The error of [`crate::certs`] and [`crate::router`].
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// A bad flag or configuration file; the message names it and what it allows (a usage
    /// error: exit code 2 at the front door).
    #[error("{0:#}")]
    Invalid(anyhow::Error),
    /// Failed while running: I/O, certificate signing, the zenoh session (exit code 1).
    #[error("{0:#}")]
    Failed(anyhow::Error),
}
