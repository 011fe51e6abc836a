//! The terminal of the commands that run or watch a robot: stdout that tolerates a closed pipe,
//! and a progress bar on stderr.

use crate::LiveError;
use std::io::{IsTerminal as _, Write as _};

/// Writes `text` to stdout; a closed pipe (`| head`) is not an error.
pub fn print_stdout(text: &str) -> Result<(), LiveError> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(LiveError::Failed(
            anyhow::Error::new(e).context("cannot write to stdout"),
        )),
        _ => Ok(()),
    }
}

/// A progress bar on stderr over `len` steps labelled `what` (hidden with `json` or when
/// stderr is not a terminal).
pub fn bar(len: u64, what: &str, json: bool) -> indicatif::ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new(len);
    b.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "{what} [{{bar:40}}] {{pos}}/{{len}} {{elapsed_precise}} (eta {{eta}})"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    );
    b
}
