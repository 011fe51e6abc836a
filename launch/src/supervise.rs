//! Child processes of a run: where the node binaries are, free loopback ports, and children
//! that never outlive the process that started them.
//!
//! `tilting live` starts the plant and the controller through this module, and so does the
//! process-level test harness (`tilting-tests`) and its loop benchmark: one supervisor, one set
//! of rules.
//!
//! - A [`Child`] writes stdout and stderr to files in a directory of the caller's choice
//!   (`{name}.json`, `{name}.log`), runs in its own process group (a Ctrl-C in the terminal
//!   reaches the supervisor, which then stops the children in order), is told to stop when the
//!   supervisor dies (Linux: `PR_SET_PDEATHSIG`), and is killed if dropped while running.
//! - [`Child::stop`] asks politely (SIGINT, then SIGTERM) and kills after a grace period.
//! - A node prints its summary as the last JSON line of stdout; [`Child::summary`] reads it
//!   into the node's summary type (`PlantSummary`, `ControllerSummary`), or from the node's
//!   fallback file when its stdout failed (a full disk: `tilting_net::say_summary`).

use anyhow::{anyhow, Context as _};
use serde::de::DeserializeOwned;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// File name of the plant node binary.
pub const PLANT_BIN: &str = "tilting-plant";
/// File name of the controller node binary.
pub const CONTROLLER_BIN: &str = "tilting-controller";
/// File name of the zenoh router of a secure deployment.
pub const ROUTER_BIN: &str = "tilting-router";

/// The paths of the node binaries.
#[derive(Debug, Clone)]
pub struct NodeBinaries {
    /// `tilting-plant`.
    pub plant: PathBuf,
    /// `tilting-controller`.
    pub controller: PathBuf,
    /// `tilting-router` (the zenoh router of `live --secure`).
    pub router: PathBuf,
}

impl NodeBinaries {
    /// `tilting-plant`, `tilting-controller` and `tilting-router` in `dir`, which must hold
    /// all three.
    pub fn in_dir(dir: &Path) -> anyhow::Result<Self> {
        let find = |name: &str| {
            let p = dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
            if p.is_file() {
                Ok(p)
            } else {
                Err(anyhow!(
                    "cannot find `{name}` in {} (looked for {}): build the workspace first with \
                     `cargo build --release --workspace`",
                    dir.display(),
                    p.display()
                ))
            }
        };
        Ok(Self {
            plant: find(PLANT_BIN)?,
            controller: find(CONTROLLER_BIN)?,
            router: find(ROUTER_BIN)?,
        })
    }

    /// The node binaries next to the current executable (the cargo profile directory, also
    /// from a test or example binary in its `deps/` or `examples/` subdirectory).
    pub fn next_to_current_exe() -> anyhow::Result<Self> {
        Self::in_dir(&profile_dir()?)
    }
}

/// The directory of the current executable, or its parent when that is cargo's `deps/` or
/// `examples/` (so tests and examples find the binaries of the same profile).
pub fn profile_dir() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("cannot locate the current executable")?;
    let mut dir = exe
        .parent()
        .ok_or_else(|| anyhow!("the executable {} has no directory", exe.display()))?
        .to_path_buf();
    if dir
        .file_name()
        .is_some_and(|n| n == "deps" || n == "examples")
    {
        dir.pop();
    }
    Ok(dir)
}

/// Whether this process may run threads under `SCHED_FIFO` at `priority` (1 to 99): tried on a
/// short-lived thread of its own, so nothing else changes. The error says what to do.
pub fn check_fifo(priority: i32) -> anyhow::Result<()> {
    let tried = std::thread::spawn(move || tilting_plant::node::clock::set_fifo_priority(priority))
        .join()
        .map_err(|_| anyhow::anyhow!("the SCHED_FIFO probe thread panicked"))?;
    tried.map_err(|e| {
        anyhow::anyhow!(
            "SCHED_FIFO at priority {priority} is not permitted here ({e}): run as root, give \
             the node binaries CAP_SYS_NICE (`setcap cap_sys_nice+ep`), or raise the \
             real-time priority limit (`ulimit -r {priority}`, or `rtprio` in \
             /etc/security/limits.conf)"
        )
    })
}

/// A child node. Killed on drop if still running.
pub struct Child {
    name: String,
    /// The binary's file name (`tilting-plant`): names the node's fallback summary.
    bin: String,
    /// When it was started (a fallback summary older than that is another process's).
    started: std::time::SystemTime,
    child: std::process::Child,
    stdout: PathBuf,
    stderr: PathBuf,
    status: Option<ExitStatus>,
}

impl Child {
    /// Starts `bin args...` with stdout in `{dir}/{name}.json` and stderr in
    /// `{dir}/{name}.log`.
    pub fn spawn(name: &str, bin: &Path, args: &[String], dir: &Path) -> anyhow::Result<Self> {
        Self::spawn_with(name, bin, args, dir, None)
    }

    /// [`Child::spawn`], and with `fifo` = `Some(priority)` (1 to 99) the child runs under
    /// `SCHED_FIFO` at that priority from before its `exec`: its main thread and every thread
    /// it starts later (Linux threads inherit the policy), zenoh's included. Fails, naming the
    /// OS error, where that is not permitted (see [`check_fifo`]).
    pub fn spawn_with(
        name: &str,
        bin: &Path,
        args: &[String],
        dir: &Path,
        fifo: Option<i32>,
    ) -> anyhow::Result<Self> {
        let stdout = dir.join(format!("{name}.json"));
        let stderr = dir.join(format!("{name}.log"));
        let mut cmd = Command::new(bin);
        cmd.args(args)
            .stdin(Stdio::null())
            .stdout(
                std::fs::File::create(&stdout)
                    .with_context(|| format!("cannot create {}", stdout.display()))?,
            )
            .stderr(
                std::fs::File::create(&stderr)
                    .with_context(|| format!("cannot create {}", stderr.display()))?,
            )
            .env("NO_COLOR", "1");
        #[cfg(unix)]
        {
            use std::os::unix::process::CommandExt as _;
            cmd.process_group(0);
        }
        #[cfg(target_os = "linux")]
        {
            use std::os::unix::process::CommandExt as _;
            // SAFETY: the closure runs in the child between fork and exec and only calls
            // prctl(2) and sched_setscheduler(2) (`set_fifo_priority`), which are
            // async-signal-safe, and allocates nothing (its error reads errno).
            unsafe {
                cmd.pre_exec(move || {
                    libc::prctl(
                        libc::PR_SET_PDEATHSIG,
                        libc::SIGTERM as libc::c_ulong,
                        0,
                        0,
                        0,
                    );
                    match fifo {
                        Some(p) => tilting_plant::node::clock::set_fifo_priority(p),
                        None => Ok(()),
                    }
                });
            }
        }
        #[cfg(not(target_os = "linux"))]
        if let Some(p) = fifo {
            anyhow::bail!(
                "cannot start {} under SCHED_FIFO {p}: only on Linux",
                bin.display()
            );
        }
        let child = cmd.spawn().with_context(|| match fifo {
            Some(p) => format!("cannot start {} under SCHED_FIFO {p}", bin.display()),
            None => format!("cannot start {}", bin.display()),
        })?;
        Ok(Self {
            name: name.to_owned(),
            bin: bin
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            started: std::time::SystemTime::now(),
            child,
            stdout,
            stderr,
            status: None,
        })
    }

    /// The name given at [`Child::spawn`].
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Sends a signal (`libc::SIGINT`, `SIGTERM`, `SIGKILL`, `SIGSTOP`, `SIGCONT`, ...) unless
    /// the child has been reaped already.
    #[cfg(unix)]
    pub fn signal(&self, sig: i32) {
        if self.status.is_none() {
            // SAFETY: kill(2) on the pid of our own child, which has not been reaped yet.
            unsafe { libc::kill(self.child.id() as libc::pid_t, sig) };
        }
    }

    /// The exit status, if it has exited (does not block).
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            self.status = self.child.try_wait().ok().flatten();
        }
        self.status
    }

    /// The exit status once known (after [`Child::try_wait`] saw it).
    pub fn status(&self) -> Option<ExitStatus> {
        self.status
    }

    /// Waits at most `timeout` for the exit; gives up early when `give_up()` says so (a second
    /// Ctrl-C, say).
    pub fn wait_timeout(
        &mut self,
        timeout: Duration,
        give_up: &dyn Fn() -> bool,
    ) -> Option<ExitStatus> {
        let end = Instant::now() + timeout;
        loop {
            if let Some(s) = self.try_wait() {
                return Some(s);
            }
            if Instant::now() >= end || give_up() {
                return None;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Stops the child: SIGINT and up to 5 s, SIGTERM and up to 2 s, then SIGKILL (a
    /// `give_up()` skips the waiting). Returns the exit status and whether it had to be killed.
    pub fn stop(&mut self, give_up: &dyn Fn() -> bool) -> (ExitStatus, bool) {
        if let Some(s) = self.try_wait() {
            return (s, false);
        }
        #[cfg(unix)]
        for (sig, secs) in [(libc::SIGINT, 5), (libc::SIGTERM, 2)] {
            self.signal(sig);
            if let Some(s) = self.wait_timeout(Duration::from_secs(secs), give_up) {
                return (s, false);
            }
        }
        let _ = self.child.kill();
        let s = match self.child.wait() {
            Ok(s) => s,
            Err(_) => {
                #[cfg(unix)]
                {
                    use std::os::unix::process::ExitStatusExt as _;
                    ExitStatus::from_raw(9)
                }
                #[cfg(not(unix))]
                {
                    use std::os::windows::process::ExitStatusExt as _;
                    ExitStatus::from_raw(1)
                }
            }
        };
        self.status = Some(s);
        (s, true)
    }

    /// The file that holds stderr.
    pub fn stderr_path(&self) -> &Path {
        &self.stderr
    }

    /// Everything written to stdout so far.
    pub fn stdout(&self) -> String {
        std::fs::read_to_string(&self.stdout).unwrap_or_default()
    }

    /// Everything written to stderr so far.
    pub fn stderr(&self) -> String {
        std::fs::read_to_string(&self.stderr).unwrap_or_default()
    }

    /// The last `n` lines of stderr.
    pub fn log_tail(&self, n: usize) -> String {
        let log = self.stderr();
        let lines: Vec<&str> = log.lines().collect();
        lines[lines.len().saturating_sub(n)..].join("\n")
    }

    /// stdout and stderr, labelled, for failure messages.
    pub fn logs(&self) -> String {
        format!(
            "--- {} stdout ---\n{}\n--- {} stderr ---\n{}",
            self.name,
            self.stdout(),
            self.name,
            self.stderr()
        )
    }

    /// The node's summary: the last line of stdout that parses as a `T` (a node's summary type,
    /// or `serde_json::Value` for any JSON object), or if there is none, the node's
    /// [`Child::fallback_summary`].
    pub fn summary<T: DeserializeOwned>(&self) -> Option<T> {
        let last_object = |text: String| {
            text.lines().rev().find_map(|l| {
                let v: serde_json::Value = serde_json::from_str(l).ok()?;
                if !v.is_object() {
                    return None;
                }
                serde_json::from_value(v).ok()
            })
        };
        last_object(self.stdout()).or_else(|| {
            let fallback = self.fallback_summary()?;
            last_object(std::fs::read_to_string(fallback).ok()?)
        })
    }

    /// The file where the node put its summary because its stdout failed
    /// (`tilting_net::summary_fallback`), if this process wrote it (not one of an earlier
    /// process with the same pid).
    pub fn fallback_summary(&self) -> Option<PathBuf> {
        let path = tilting_net::summary_fallback(&self.bin, self.pid());
        let written = std::fs::metadata(&path).and_then(|m| m.modified()).ok()?;
        (written >= self.started).then_some(path)
    }
}

impl Drop for Child {
    fn drop(&mut self) {
        if self.try_wait().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// `YYYY-MM-DDTHH-MM-SSZ` of the current UTC time (no colons, so it is a valid file name
/// everywhere).
pub fn utc_timestamp() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm): a few lines instead of
    // a date crate for one file name.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}-{:02}-{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamp_is_a_file_name() {
        let t = utc_timestamp();
        assert_eq!(t.len(), 20, "{t}");
        assert!(t.ends_with('Z') && !t.contains(':'), "{t}");
    }
}
