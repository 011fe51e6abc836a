//! Foxglove in a live run: the flags (`--foxglove [ADDR]`, `--foxglove-any`,
//! `--tilt-exaggeration`, also those of `tilting replay`), the subscription that feeds a
//! [`Server`] from a robot on the network (as `tilting record` subscribes; `tilting view` uses
//! it too), and the piece of `tilting live` that serves its robot. The server itself is
//! `tilting_foxglove`'s.

use crate::LiveError;
use anyhow::anyhow;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tilting_foxglove::{Feed, Options, Server, StartError, DEFAULT_ADDR};
use tilting_proto::{Keys, Topic};
use zenoh::pubsub::Subscriber;
use zenoh::Session;

/// The Foxglove flags of `live` and `replay`.
#[derive(Debug, Clone, clap::Args)]
pub struct FoxgloveArgs {
    /// Serve the robot over the Foxglove WebSocket protocol (open Foxglove, "Open connection",
    /// Foxglove WebSocket, ws://ADDR) [default ADDR: 127.0.0.1:8765]
    #[arg(
        long,
        value_name = "ADDR",
        num_args = 0..=1,
        default_missing_value = DEFAULT_ADDR,
        value_parser = parse_addr
    )]
    pub foxglove: Option<SocketAddr>,
    /// Allow --foxglove on an address that is not loopback (serves the robot to the network)
    #[arg(long)]
    pub foxglove_any: bool,
    /// The tilt drawn this many times larger in the 3D scene (display only; stated in the
    /// scene's title; 1 is to scale)
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "K",
        allow_negative_numbers = true
    )]
    pub tilt_exaggeration: f64,
}

/// `HOST:PORT` with a numeric host (`127.0.0.1:8765`, `[::1]:8765`), or `localhost:PORT`.
pub fn parse_addr(s: &str) -> Result<SocketAddr, String> {
    let s2 = s.replace("localhost:", "127.0.0.1:");
    s2.parse().map_err(|_| {
        format!(
            "`{s}` is not an address: expected IP:PORT, e.g. {DEFAULT_ADDR} (port 0: a free one)"
        )
    })
}

impl FoxgloveArgs {
    /// Checks the flags without binding: usage errors naming the flag.
    pub fn check(&self) -> Result<(), LiveError> {
        let usage = |e: String| LiveError::Usage(anyhow!(e));
        tilting_foxglove::scene::check_exaggeration(self.tilt_exaggeration).map_err(usage)?;
        match self.foxglove {
            Some(addr) => tilting_foxglove::check_addr(addr, self.foxglove_any)
                .map_err(|e| usage(e.to_string())),
            None if self.foxglove_any => Err(usage("--foxglove-any needs --foxglove".into())),
            None => Ok(()),
        }
    }

    /// The server's options for robot `keys` with geometry `params`, if --foxglove.
    pub fn options(&self, keys: &Keys, params: tilting_plant::Params) -> Option<Options> {
        Some(Options {
            addr: self.foxglove?,
            any: self.foxglove_any,
            keys: keys.clone(),
            params,
            exaggeration: self.tilt_exaggeration,
        })
    }
}

/// Starts the server and says where it serves.
pub async fn start(opts: &Options, who: &str) -> Result<Server, StartError> {
    let server = Server::start(opts).await?;
    eprintln!(
        "{who}: Foxglove serves robot {} at ws://{} (Foxglove: Open connection, Foxglove \
         WebSocket; layout: docs/foxglove-layout.json)",
        opts.keys.robot(),
        server.addr()
    );
    Ok(server)
}

/// Subscribes to the four loop topics of `keys` on `session` and to the reference on
/// `reference` (the same session, except in `live --secure`, where the recording session links
/// only to the plant and the controller and the reference comes through the router), and hands
/// every payload to `feed` (never blocking: the feed drops its oldest message when full),
/// counting them in `received`.
pub async fn subscribe(
    session: &Session,
    reference: &Session,
    keys: &Keys,
    feed: &Feed,
    received: &Arc<AtomicU64>,
) -> anyhow::Result<Vec<Subscriber<()>>> {
    let mut subs = Vec::new();
    for topic in Topic::ALL {
        let feed = feed.clone();
        let n = received.clone();
        let on = if topic == Topic::Reference {
            reference
        } else {
            session
        };
        subs.push(
            tilting_net::subscribe_bytes(on, topic.key(keys), move |bytes| {
                n.fetch_add(1, Ordering::Relaxed);
                feed.send_wire(topic, bytes.to_vec())
            })
            .await?,
        );
    }
    Ok(subs)
}

/// Prints what a server did, once closed.
pub fn report(who: &str, c: &tilting_foxglove::Counts) {
    eprintln!(
        "{who}: Foxglove: {} messages published, {} scene updates, {} log entries, {} invalid, \
         {} dropped (publisher behind), {} clients",
        c.published, c.scenes, c.logs, c.invalid, c.dropped, c.clients
    );
}

/// The Foxglove server of a `tilting live` run (if `--foxglove`).
pub struct LiveServer {
    server: Option<Server>,
    subscribers: Vec<Subscriber<()>>,
}

impl LiveServer {
    /// Starts the server before the run; a server that cannot start (a port in use) is
    /// reported, and the run goes on without it.
    pub async fn start(
        args: &FoxgloveArgs,
        keys: &Keys,
        params: tilting_plant::Params,
    ) -> LiveServer {
        let server = match args.options(keys, params) {
            None => None,
            Some(opts) => match start(&opts, "live").await {
                Ok(s) => Some(s),
                Err(e) => {
                    eprintln!("live: {e}; the run goes on without Foxglove");
                    None
                }
            },
        };
        LiveServer {
            server,
            subscribers: Vec::new(),
        }
    }

    /// Feeds the server from the run's sessions: the recording session's loop topics and the
    /// planner's reference (see [`subscribe`]).
    pub async fn attach(
        &mut self,
        session: &Session,
        reference: &Session,
        keys: &Keys,
    ) -> anyhow::Result<()> {
        if let Some(s) = &self.server {
            let n = Arc::default();
            self.subscribers = subscribe(session, reference, keys, &s.feed(), &n).await?;
        }
        Ok(())
    }

    /// Foxglove clients connected now (0 without a server).
    pub fn clients(&self) -> usize {
        self.server.as_ref().map_or(0, Server::clients)
    }

    /// Stops the server once the run is over.
    pub async fn close(self) {
        drop(self.subscribers);
        if let Some(s) = self.server {
            report("live", &s.close().await);
        }
    }
}

/// The share of a second's periods missed above which `live` blames a connected viewer: the
/// shared 2-core test machine, busy with builds, missed 1 to 2 % without a viewer, and a viewer
/// on the robot's own 2-core machine made it miss 12 to 18 % (issue 31).
pub const VIEWER_LATE_SHARE: f64 = 0.05;

/// Tells when the loop starts missing deadlines after a Foxglove viewer connected: the share of
/// the last second's periods missed while a client is connected, against the share missed over
/// the whole time no client was.
#[derive(Debug, Default)]
pub struct ViewerWatch {
    /// The last counters seen (periods, misses).
    last: Option<(u64, u64)>,
    /// Periods and misses while no client was connected.
    quiet: (u64, u64),
}

impl ViewerWatch {
    /// Takes the plant's counters (`periods` stepped, `misses` so far), the clients connected
    /// and the share missed over the last second (`late`, if known); the warning while a viewer
    /// is connected and the loop misses over [`VIEWER_LATE_SHARE`] of its periods and over
    /// twice its share without a viewer.
    pub fn update(
        &mut self,
        clients: usize,
        periods: u64,
        misses: u64,
        late: Option<f64>,
    ) -> Option<String> {
        if let Some((p0, m0)) = self.last.replace((periods, misses)) {
            if clients == 0 {
                self.quiet.0 += periods.saturating_sub(p0);
                self.quiet.1 += misses.saturating_sub(m0);
            }
        }
        let before = if self.quiet.0 == 0 {
            0.0
        } else {
            self.quiet.1 as f64 / self.quiet.0 as f64
        };
        let share = late.filter(|&l| clients > 0 && l > VIEWER_LATE_SHARE && l > 2.0 * before)?;
        let without = if self.quiet.0 == 0 {
            "connected since the start".to_owned()
        } else {
            format!("{:.1} % without", before * 100.0)
        };
        Some(format!(
            "LOOP LATE WITH A VIEWER: {:.0} % of the last second's periods missed with {clients} \
             Foxglove client(s) connected ({without}); a viewer on the robot's machine takes \
             its CPU: open it on another machine (--foxglove ADDR --foxglove-any) or run with \
             --realtime",
            share * 100.0,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A viewer is blamed only while connected, above 5 % missed and above twice the share
    /// missed without one.
    #[test]
    fn a_viewer_is_blamed_for_misses_that_came_with_it() {
        let mut w = ViewerWatch::default();
        // No viewer, 0.1 % missed: nothing to say.
        assert_eq!(w.update(0, 1000, 1, Some(0.001)), None);
        assert_eq!(w.update(0, 2000, 2, Some(0.001)), None);
        // A viewer and 4 % missed: under the threshold.
        assert_eq!(w.update(1, 2100, 6, Some(0.04)), None);
        // A viewer connects; the loop misses 15 %: warned, with both shares.
        let text = w.update(1, 3000, 152, Some(0.15)).expect("a warning");
        assert!(
            text.contains("15 %") && text.contains("0.1 %") && text.contains("--realtime"),
            "{text}"
        );
        // The same misses without a viewer: not the viewer's.
        assert_eq!(w.update(0, 4000, 302, Some(0.15)), None);
        // A loaded machine that missed 10 % without a viewer: 15 % with one is not twice that.
        let mut busy = ViewerWatch::default();
        busy.update(0, 0, 0, None);
        busy.update(0, 1000, 100, Some(0.1));
        assert_eq!(busy.update(1, 2000, 250, Some(0.15)), None);
        // A viewer connected before the loop started (no time without one): the threshold alone.
        let mut early = ViewerWatch::default();
        assert_eq!(early.update(1, 1000, 30, Some(0.03)), None);
        assert!(early.update(1, 2000, 150, Some(0.12)).is_some());
    }
}
