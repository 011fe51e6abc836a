//! `tilting-router`: the zenoh router of a secure deployment, opened from the `router.json5`
//! of [`crate::certs`], at a lowered priority on request.

use crate::LaunchError;
use anyhow::anyhow;
use serde_json::json;
use std::path::PathBuf;

/// Flags of `tilting-router`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    name = "tilting-router",
    version,
    about = "A zenoh router for a secure tilting deployment: TLS with mutual authentication and \
             the robot's access control, from a configuration written by `tilting certs`"
)]
pub struct RouterArgs {
    /// The router's zenoh configuration (JSON5), e.g. router.json5 of `tilting certs`
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// Endpoint to listen on instead of the configuration's (repeatable), e.g.
    /// tls/0.0.0.0:7447
    #[arg(long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Nice value (0-19) the router lowers itself to before it opens its session, so that on a
    /// host it shares with the plant or the controller the loop's processes run first (0: keep
    /// the priority it was started with; see the README's "Cost" for when a higher value hurts)
    #[arg(long, default_value_t = ROUTER_NICE, value_name = "0-19",
          value_parser = clap::value_parser!(i32).range(0..=19))]
    pub nice: i32,
}

/// Default nice value of `tilting-router` (`--nice`): 0, the priority it was started with.
///
/// The router carries no message of the control loop (the plant and the controller talk over
/// their direct link, and `live --secure`'s recorder takes them on links of its own), but with
/// an outside client subscribed to the loop's topics (a logger, `tilting echo`) it decrypts,
/// routes and re-encrypts every state and torque at the very moment the controller wakes up
/// for that state, and on a host it shares with the loop it competes with the controller for
/// the CPU (README, "Cost"). `--nice 19` removes that cost (when the recorder of `live` was
/// such a client: loop latency p99 0.6-0.9x the open loop's instead of 1.0-1.5x, at load 9-11
/// on 2 cores), but it is not the default: on a saturated host (load 11-12 on 2 cores) 3 of 3
/// such runs with the router at nice 19 had 6 to 11 safe-mode entries, against 0 of 4 at nice
/// 0. The loop's publishers use blocking congestion control, so a router starved of CPU that
/// has subscribers of the loop's topics back-pressures the plant and the controller. With
/// none (`live --secure` today) the router has nothing to do for the loop, at any priority.
pub const ROUTER_NICE: i32 = 0;

/// Lowers the calling thread's priority to nice `nice` if it is higher than the current one
/// (threads made afterwards, zenoh's among them, inherit it on Linux, where a thread is a task
/// with its own nice value; raising the priority would need privileges, so a lower `nice`
/// leaves it as it is). Returns the nice value in force. Linux only; elsewhere nothing.
pub fn lower_priority(nice: i32) -> std::io::Result<i32> {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: getpriority(2)/setpriority(2) on the calling thread (who = 0); no memory is
        // passed. (getpriority returns the nice value, -20..19; it cannot fail for who = 0.)
        unsafe {
            let now = libc::getpriority(libc::PRIO_PROCESS, 0);
            if nice <= now {
                return Ok(now);
            }
            if libc::setpriority(libc::PRIO_PROCESS, 0, nice) != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
        Ok(nice)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = nice;
        Ok(0)
    }
}

/// `tilting-router`: opens a zenoh router session from `--config` (which must say `mode:
/// "router"`), prints `ready` with its zenoh id on stdout, and runs until Ctrl-C or SIGTERM.
pub fn router(args: &RouterArgs) -> Result<(), LaunchError> {
    tilting_net::init_tracing("warn");
    // Before any other thread exists: the tokio and zenoh threads inherit the nice value.
    let nice = match lower_priority(args.nice) {
        Ok(n) => n,
        Err(e) => {
            tracing::warn!(
                "cannot lower the router's priority to nice {}: {e}",
                args.nice
            );
            0
        }
    };
    let mut cfg = tilting_net::config_from_file(&args.config)
        .map_err(|e| LaunchError::Invalid(anyhow!("--config {}: {e}", args.config.display())))?;
    let mode = cfg.get_json("mode").unwrap_or_default();
    if mode != "\"router\"" {
        return Err(LaunchError::Invalid(anyhow!(
            "--config {}: mode is {mode}, must be \"router\"",
            args.config.display()
        )));
    }
    if !args.listen.is_empty() {
        let json = serde_json::to_string(&args.listen).expect("strings serialize");
        cfg.insert_json5("listen/endpoints", &json).map_err(|e| {
            LaunchError::Invalid(anyhow!(
                "--listen {:?}: {}",
                args.listen,
                tilting_net::zenoh_error(&e)
            ))
        })?;
    }
    let rt = tilting_net::runtime().map_err(LaunchError::Failed)?;
    rt.block_on(async {
        let session = zenoh::open(cfg).await.map_err(|e| {
            anyhow!(
                "cannot open the router session: {}",
                tilting_net::zenoh_error(&e)
            )
        })?;
        let ready = json!({ "ready": true, "zid": session.zid().to_string(), "nice": nice });
        let _ = tilting_net::say_out(&ready.to_string());
        tilting_net::shutdown_signal().await;
        let _ = session.close().await;
        let _ = tilting_net::say_out(&json!({ "stopped": true }).to_string());
        Ok::<_, anyhow::Error>(())
    })
    .map_err(LaunchError::Failed)
}
