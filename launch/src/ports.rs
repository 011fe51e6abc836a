//! Free loopback ports for the sessions of a run, reserved across processes.
//!
//! The OS hands out a free port to a socket bound to port 0, but the port is free again once
//! that socket closes, and the child that is to listen on it binds it only later: several runs
//! started together (`bench/robots_bench.py` starts 8) could be given the same port in between.
//! A [`PortLease`] closes that gap among the processes that take their ports here: the port is
//! also locked (`flock`) through a file `tilting-ports/PORT.lock` in the temporary directory,
//! held until the lease is dropped, and a port another lease holds is passed over. Processes
//! that do not take their ports here can still take it before the child binds it; the child
//! then fails at start naming the address in use.

use anyhow::Context as _;
use std::fs::File;
use std::net::TcpListener;
use std::os::fd::AsRawFd;
use std::path::PathBuf;

/// Ports tried before [`reserve_port`] gives up (each one locked by another lease).
const TRIES: usize = 64;

/// A loopback TCP port reserved for this process until dropped: no other [`reserve_port`], in
/// this process or another of the same machine, returns it meanwhile. Hold it until the session
/// that listens on the port has bound it (for a run, its whole length).
#[derive(Debug)]
pub struct PortLease {
    port: u16,
    /// The locked file (`None` if the lock directory could not be used: a port as free as
    /// [`free_port`]'s).
    _lock: Option<File>,
}

impl PortLease {
    /// The port (1 to 65535).
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Keeps the reservation until the process exits (for short-lived processes, tests).
    pub fn keep(self) -> u16 {
        let port = self.port;
        std::mem::forget(self);
        port
    }
}

/// The directory of the port locks: `tilting-ports/` in the temporary directory, writable by
/// every user (sticky), so runs of several users share it.
fn lock_dir() -> PathBuf {
    std::env::temp_dir().join("tilting-ports")
}

/// Locks `port`'s file without waiting: `Ok(Some(file))` when this lease holds it, `Ok(None)`
/// when another does, `Err` when the lock file cannot be opened.
fn lock(port: u16) -> std::io::Result<Option<File>> {
    let dir = lock_dir();
    if !dir.is_dir() {
        std::fs::create_dir_all(&dir)?;
        use std::os::unix::fs::PermissionsExt as _;
        // Best effort: another user's runs may share the directory.
        let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o1777));
    }
    let file = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(dir.join(format!("{port}.lock")))?;
    // SAFETY: flock on a descriptor this function owns; no memory is shared.
    let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if r == 0 {
        return Ok(Some(file));
    }
    let e = std::io::Error::last_os_error();
    if e.kind() == std::io::ErrorKind::WouldBlock {
        Ok(None)
    } else {
        Err(e)
    }
}

/// A free loopback TCP port, reserved until the lease is dropped (see the module's doc). The
/// OS chooses it (a socket bound to 127.0.0.1:0); one another lease holds is passed over while
/// the sockets of the ports passed over stay bound, so the OS offers a new one each try. If the
/// lock directory cannot be used the port is returned unlocked.
pub fn reserve_port() -> anyhow::Result<PortLease> {
    let mut passed_over = Vec::new();
    for _ in 0..TRIES {
        let listener = TcpListener::bind("127.0.0.1:0").context("cannot bind 127.0.0.1:0")?;
        let port = listener.local_addr()?.port();
        match lock(port) {
            Ok(Some(file)) => {
                return Ok(PortLease {
                    port,
                    _lock: Some(file),
                })
            }
            Ok(None) => passed_over.push(listener),
            Err(e) => {
                tracing::debug!("port {port} not locked ({e}): {}", lock_dir().display());
                return Ok(PortLease { port, _lock: None });
            }
        }
    }
    anyhow::bail!(
        "no free loopback port within {TRIES} tries: each was reserved by another run (locks in {})",
        lock_dir().display()
    )
}

/// A free TCP port on 127.0.0.1, kept reserved for the rest of this process
/// ([`PortLease::keep`]): for tests and short-lived tools. A long-running process that starts
/// many runs should hold a [`reserve_port`] lease per run instead.
pub fn free_port() -> anyhow::Result<u16> {
    Ok(reserve_port()?.keep())
}

/// `tcp/127.0.0.1:{port}`, the zenoh endpoint of a loopback port.
pub fn endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    #[test]
    fn endpoint_is_tcp_on_loopback() {
        assert_eq!(endpoint(7447), "tcp/127.0.0.1:7447");
    }

    /// 64 reservations taken at once from 16 threads (each lock a file description of its own,
    /// as another process's would be) are 64 distinct ports, each bindable while reserved.
    #[test]
    fn concurrent_reservations_are_distinct() {
        let leases: Vec<PortLease> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..16)
                .map(|_| s.spawn(|| (0..4).map(|_| reserve_port().unwrap()).collect::<Vec<_>>()))
                .collect();
            handles
                .into_iter()
                .flat_map(|h| h.join().unwrap())
                .collect()
        });
        let ports: BTreeSet<u16> = leases.iter().map(PortLease::port).collect();
        assert_eq!(ports.len(), leases.len(), "a port was handed out twice");
        for p in &ports {
            TcpListener::bind(("127.0.0.1", *p)).expect("a reserved port is free to bind");
        }
    }

    /// A port another lease holds is passed over: its lock cannot be taken again, and once the
    /// lease is dropped it can.
    #[test]
    fn a_held_port_is_locked_until_its_lease_drops() {
        let lease = reserve_port().unwrap();
        if lease._lock.is_none() {
            return; // no lock directory here: nothing to check
        }
        assert!(lock(lease.port()).unwrap().is_none(), "locked twice");
        let port = lease.port();
        drop(lease);
        assert!(lock(port).unwrap().is_some(), "still locked after the drop");
    }
}
