//! Spawning the nodes of a live run: where each session listens and connects (loopback ports,
//! or the router of `--secure`), the router itself, and the plant and controller children with
//! their flags.
//!
//! The controller and the plant read the run's robot file (`--robot-file RUN/robot.toml`,
//! [`run_file`]): the law, the model, the link and the sensors. The controller is given only
//! the run's wiring as flags (session, zenoh ids); the plant besides what `live` resolved for
//! it (rate, duration, age rule, hard torque limit, start). An external plant (`--plant-cmd`,
//! the MuJoCo plant) takes flags, not the file: the file's keys of the link and the sensors
//! as their flags ([`PlantArgs::file_flags`]).

use super::summary::Endpoints;
use super::Job;
use anyhow::Context as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use tilting_launch as security;
use tilting_launch::{endpoint, reserve_port, Child, NodeBinaries, PortLease};
use tilting_net::ZenohArgs;
use tilting_plant::imperfect::ImperfectArgs;
use tilting_plant::node::PlantArgs;
use tilting_plant::robot_file::{self, PARAMS_SECTIONS};
use tilting_sim::robot::{value_of_text, RobotFile};

/// The router of a `--secure` run.
pub(super) struct Secure {
    /// The certificate directory (its `{node}.json5` files).
    certs: PathBuf,
    /// The router's endpoint, `tls/127.0.0.1:{port}`.
    endpoint: String,
    /// The `tilting-router` child.
    router: Child,
}

/// Where the three sessions meet. Without `--secure`: the plant listens on its port; the
/// in-process planner listens on its own and connects to the plant; the controller listens on a
/// third and connects to both. With it, every node is a client of the router.
pub(super) struct Topology {
    plant_port: u16,
    ctl_port: u16,
    my_port: u16,
    secure: Option<Secure>,
    /// The reservations of the ports chosen here, held for the run: another run started at the
    /// same time is not given them before the sessions bind them ([`reserve_port`]).
    leases: Vec<PortLease>,
}

impl Topology {
    /// Free loopback ports for the three sessions (the plant's is `--port` if given), each
    /// reserved until the run ends.
    pub(super) fn ports(job: &Job) -> anyhow::Result<Self> {
        let mut leases = Vec::new();
        let mut free = || -> anyhow::Result<u16> {
            let lease = reserve_port()?;
            let port = lease.port();
            leases.push(lease);
            Ok(port)
        };
        let plant_port = match job.args.port {
            Some(p) => p,
            None => free()?,
        };
        let (ctl_port, my_port) = (free()?, free()?);
        Ok(Self {
            plant_port,
            ctl_port,
            my_port,
            secure: None,
            leases,
        })
    }

    /// With `--secure`: finds or creates the certificates, starts `tilting-router` on a free
    /// loopback port and waits until it listens (the nodes, clients, give up at once when no
    /// router answers).
    pub(super) async fn start_router(
        &mut self,
        job: &Job<'_>,
        bins: &NodeBinaries,
    ) -> anyhow::Result<()> {
        let certs = match &job.args.certs {
            // Checked by `run` already.
            Some(c) => c
                .canonicalize()
                .with_context(|| format!("--certs {}", c.display()))?,
            None => {
                let c = job.dir.join("certs");
                security::generate(&job.keys, &c, &[], security::DEFAULT_ROUTER_ENDPOINT, &[])?;
                c.canonicalize()?
            }
        };
        let lease = reserve_port()?;
        let endpoint = format!("tls/127.0.0.1:{}", lease.port());
        self.leases.push(lease);
        let config = certs.join("router.json5").display().to_string();
        let args = [
            "--config".into(),
            config,
            "--listen".into(),
            endpoint.clone(),
        ];
        let mut router = Child::spawn("router", &bins.router, &args, &job.dir)?;
        let t0 = Instant::now();
        while !router.stdout().contains("\"ready\"") {
            if let Some(s) = router.try_wait() {
                anyhow::bail!(
                    "the router exited at start with {s}:\n{}",
                    router.log_tail(15)
                );
            }
            if t0.elapsed() > Duration::from_secs(10) {
                anyhow::bail!(
                    "the router did not start within 10 s (see {})",
                    router.stderr_path().display()
                );
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        eprintln!(
            "live: secure: router on {endpoint}, certificates in {}",
            certs.display()
        );
        self.secure = Some(Secure {
            certs,
            endpoint,
            router,
        });
        Ok(())
    }

    /// The plant's TLS endpoint of the direct loop (`--secure`).
    fn plant_tls(&self) -> String {
        format!("tls/127.0.0.1:{}", self.plant_port)
    }

    /// The front door's recorder's TLS endpoint (`--secure` with certificates that have
    /// `logger-direct.json5`): it listens there with the logger's identity and the controller
    /// dials it, so the loop's messages reach it without the router.
    fn recorder_tls(&self) -> Option<String> {
        let s = self.secure.as_ref()?;
        security::direct_recorder(&s.certs).then(|| format!("tls/127.0.0.1:{}", self.my_port))
    }

    /// The session flags of child `node`: its certificate, its own access control and the
    /// direct loop (the plant listens on its port, the controller dials it and the recorder)
    /// beside the router; or loopback peers. Certificates of a `tilting certs` without the
    /// `{node}-direct.json5` files run the loop through the router, as clients.
    fn session_flags(&self, node: &str, listen: u16, connect: &[u16]) -> Vec<String> {
        match &self.secure {
            Some(s) => security::session_flags(
                &s.certs,
                node,
                &self.plant_tls(),
                &s.endpoint,
                self.recorder_tls().as_deref(),
            ),
            None => {
                let mut v = vec!["--listen".into(), endpoint(listen)];
                for c in connect {
                    v.extend(["--connect".into(), endpoint(*c)]);
                }
                v
            }
        }
    }

    /// The front door's sessions: the recorder's (which also watches the nodes' tokens) and,
    /// if it is another one, the in-process planner's. Open: one session, a loopback peer.
    /// `--secure`: the recorder is a peer with the logger's identity that listens on its own
    /// TLS endpoint and dials the plant's ([`security::session_flags`]), and the planner a
    /// client of the router with the planner's identity; with certificates made before the
    /// direct recorder, one session, the planner's, records through the router.
    pub(super) fn front_door_sessions(
        &self,
        robot: &str,
    ) -> anyhow::Result<(ZenohArgs, Option<ZenohArgs>)> {
        let Some(s) = &self.secure else {
            let open = ZenohArgs::new(
                robot,
                &[&endpoint(self.my_port)],
                &[&endpoint(self.plant_port)],
            );
            return Ok((open, None));
        };
        let planner = ZenohArgs {
            zenoh_config: Some(s.certs.join("planner.json5")),
            ..ZenohArgs::new(robot, &[], &[&s.endpoint])
        };
        let Some(rec) = self.recorder_tls() else {
            return Ok((planner, None));
        };
        #[derive(clap::Parser)]
        struct Flags {
            #[command(flatten)]
            zenoh: ZenohArgs,
        }
        let flags = security::session_flags(
            &s.certs,
            security::RECORDER,
            &self.plant_tls(),
            &s.endpoint,
            Some(&rec),
        );
        let argv = ["recorder", "--robot", robot]
            .into_iter()
            .map(String::from)
            .chain(flags);
        let record = <Flags as clap::Parser>::try_parse_from(argv)
            .context("the recorder's session flags")?
            .zenoh;
        Ok((record, Some(planner)))
    }

    /// The endpoints as the summary records them.
    pub(super) fn endpoints(&self) -> Endpoints {
        match &self.secure {
            Some(s) => Endpoints {
                plant: self.plant_tls(),
                controller: String::new(),
                planner: self.recorder_tls().unwrap_or_default(),
                router: Some(s.endpoint.clone()),
            },
            None => Endpoints {
                plant: endpoint(self.plant_port),
                controller: endpoint(self.ctl_port),
                planner: endpoint(self.my_port),
                router: None,
            },
        }
    }

    /// The router child of `--secure`, if any.
    pub(super) fn router(&mut self) -> Option<&mut Child> {
        self.secure.as_mut().map(|s| &mut s.router)
    }

    /// Stops the router, if any (after the nodes); a problem if it failed or had to be killed.
    pub(super) fn stop_router(&mut self, force: &dyn Fn() -> bool) -> Option<String> {
        let s = self.secure.as_mut()?;
        let (status, killed) = tokio::task::block_in_place(|| s.router.stop(force));
        (killed || !status.success()).then(|| {
            format!(
                "the router exited with {status} (see {})",
                s.router.stderr_path().display()
            )
        })
    }
}

/// The plant's flags: session, rate, duration, the law's torque limit as its hard limit, the
/// age rule and the emulated link.
fn plant_args(job: &Job, topo: &Topology) -> anyhow::Result<Vec<String>> {
    let args = job.args;
    let mut v: Vec<String> = vec!["--robot".into(), job.keys.robot().into()];
    v.extend(topo.session_flags("plant", topo.plant_port, &[]));
    v.extend(id_flags(
        job.ids.plant,
        "--controller-id",
        job.ids.controller,
    ));
    v.extend([
        "--rate".into(),
        args.rate.to_string(),
        "--duration".into(),
        args.duration.to_string(),
    ]);
    if let Some(limit) = job.reference.torque_limit {
        // The controller saturates already; the plant's hard limit is the same.
        v.extend(["--torque-limit".into(), limit.to_string()]);
    }
    v.extend(["--max-age".into(), args.max_age.to_string()]);
    if args.lockstep {
        v.extend(["--clock".into(), "lockstep".into()]);
    }
    if !job.reference.reference.adapts() {
        // The excitation starts from the arm at rest upright on the flat plate, where its ramp
        // starts (as `simulate`'s scenario does), not on the orbit.
        v.extend([
            "--mode".into(),
            "flat".into(),
            format!("--x0=0,{},0,0", std::f64::consts::FRAC_PI_2),
        ]);
    } else if let Some([beta, beta_dot]) = job.reference.orbit_start {
        // A planned orbit (`--plan`, `--orbit-start`): the plant starts at its lift-off, or at
        // rest, from where the law launches it (a robot starts where it stands).
        let rest = match args.start.as_deref() {
            Some(s) => s == "rest",
            None => args.plant_cmd.is_some(),
        };
        v.extend(if rest {
            let up = std::f64::consts::FRAC_PI_2;
            ["--mode".into(), "flat".into(), format!("--x0=0,{up},0,0")]
        } else {
            [
                "--mode".into(),
                "left".into(),
                format!("--x0=0,{beta},0,{beta_dot}"),
            ]
        });
    }
    if let Some(p) = args.params_files().0 {
        v.extend(["--params".into(), p.display().to_string()]);
    }
    if args.plant_cmd.is_none() {
        // The link, the seed and the sensors: the run's robot file ([network], [sensors]).
        v.extend([
            format!("--{}", robot_file::NODE_FILE_FLAG),
            run_file_path(job).display().to_string(),
        ]);
    } else {
        // An external plant (docs/mujoco.md) takes them as flags, as it always has: the
        // run file's keys of the plant's, when the run has a link or imperfections.
        if job.impairment.is_some() || args.imperfect != ImperfectArgs::default() {
            v.extend(external_plant_flags(&run_file_path(job))?);
        }
    }
    v.extend(args.ros2.plant_args());
    Ok(v)
}

/// The flags an external plant (`--plant-cmd`) is given for the emulated link, its seed and
/// the sensors: the keys of the run file `path` that `tilting-plant` would read from it
/// ([`PlantArgs::file_flags`]), each as `--flag=text` (the text the flag's parser reads, so
/// negative numbers pass).
fn external_plant_flags(path: &std::path::Path) -> anyhow::Result<Vec<String>> {
    let doc = robot_file::read_doc(path).map_err(anyhow::Error::msg)?;
    let longs = PlantArgs::file_flags();
    let defaults = robot_file::flag_defaults(&doc, path, &["network", "sensors"])
        .map_err(anyhow::Error::msg)?;
    Ok(defaults
        .into_iter()
        .filter(|d| longs.contains(&d.flag))
        .map(|d| format!("--{}={}", d.flag, d.text))
        .collect())
}

/// The run's robot file (`robot.toml` in the run directory), which the controller reads
/// (`--robot-file`): `merged` (the file `live` was given with its flags over it; `None`, an
/// empty one) made to stand alone in the run directory, with what `live` resolved:
///
/// - `[robot]`: the controller's model, inline; `[plant]` and `[prior]` inline too (a
///   `params = "x.toml"` is relative to the file given, not to the run directory);
/// - path keys (`law.plan`, `deploy.certs`, `deploy.out`) absolute;
/// - `[law]`: the law `live` resolved, every key given (a `--plan`'s gains and orbit start, a
///   `--from-orbit`'s E_av, which replaces the `from_orbit` key), so the controller need not
///   read the plan nor search the orbit, and a run from this file runs the same law.
pub(super) fn run_file(job: &Job, merged: Option<&RobotFile>) -> Result<RobotFile, String> {
    let mut f = merged
        .cloned()
        .unwrap_or_else(|| RobotFile::empty(&job.dir.join("robot.toml")));
    for section in PARAMS_SECTIONS {
        let Some(table) = f.doc.get(section).and_then(|v| v.as_table()) else {
            continue;
        };
        let p = robot_file::params_of_table(table, section, &f.path).map_err(|e| e.to_string())?;
        f.set_params(section, &p);
    }
    f.set_params("robot", &job.params().0);
    let dir = match f.path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => std::path::Path::new("."),
    };
    let dir = std::path::absolute(dir).map_err(|e| e.to_string())?;
    for (section, key) in robot_file::PATH_KEYS {
        let Some(text) = f
            .doc
            .get(section)
            .and_then(|t| t.get(key))
            .and_then(|v| v.as_str())
        else {
            continue;
        };
        let abs = dir.join(text).display().to_string();
        f.set(section, key, value_of_text(key, &abs));
    }
    f.set_law(&job.reference)?;
    f.path = run_file_path(job);
    Ok(f)
}

/// Where the run's robot file is written (absolute: the children are told it).
fn run_file_path(job: &Job) -> PathBuf {
    let p = job.dir.join("robot.toml");
    std::path::absolute(&p).unwrap_or(p)
}

/// The controller's flags: the run's robot file (its model, law, `--predict` and
/// `--estimator`), and what only this run has: its session and the zenoh ids.
fn controller_args(job: &Job, topo: &Topology) -> Vec<String> {
    let mut v: Vec<String> = vec!["--robot".into(), job.keys.robot().into()];
    let peers = [topo.plant_port, topo.my_port];
    v.extend(topo.session_flags("controller", topo.ctl_port, &peers));
    v.extend(id_flags(job.ids.controller, "--plant-id", job.ids.plant));
    v.extend([
        format!("--{}", robot_file::NODE_FILE_FLAG),
        run_file_path(job).display().to_string(),
    ]);
    v
}

/// A node's own zenoh id (`--zenoh-id`) and its peer's (`peer_flag`), chosen by `live` before
/// either starts, so that each believes the other's messages only from the first on.
fn id_flags(
    own: Option<tilting_proto::SourceId>,
    peer_flag: &str,
    peer: Option<tilting_proto::SourceId>,
) -> Vec<String> {
    let mut v = Vec::new();
    if let Some(id) = own {
        v.extend(["--zenoh-id".into(), id.to_string()]);
    }
    if let Some(id) = peer {
        v.extend([peer_flag.into(), id.to_string()]);
    }
    v
}

/// Starts the plant; it publishes state 0 until a controller shows up. With `--plant-cmd`,
/// that command instead, by `sh -c 'exec CMD "$@"'` with the same flags appended (`exec`: the
/// signals that stop the plant reach the command itself, not a shell waiting for it).
pub(super) fn spawn_plant(
    job: &Job,
    topo: &Topology,
    bins: &NodeBinaries,
) -> anyhow::Result<Child> {
    let args = plant_args(job, topo)?;
    let Some(cmd) = &job.args.plant_cmd else {
        return Child::spawn_with("plant", &bins.plant, &args, &job.dir, job.args.realtime);
    };
    let sh: Vec<String> = ["-c".into(), format!("exec {cmd} \"$@\""), "plant".into()]
        .into_iter()
        .chain(args)
        .collect();
    Child::spawn_with(
        "plant",
        std::path::Path::new("/bin/sh"),
        &sh,
        &job.dir,
        job.args.realtime,
    )
}

/// Host mode (`live --robots`): a one-robot node's flags `argv` (which start with `--robot
/// NAME`) serving `robots` (`A,B,...`) instead, and dialling the extra front-door sessions
/// `peers` (one per robot beyond the first).
fn hosting(mut argv: Vec<String>, robots: &str, peers: &[u16]) -> Vec<String> {
    if argv.first().map(String::as_str) == Some("--robot") && argv.len() > 1 {
        argv[0] = "--robots".into();
        argv[1] = robots.into();
    }
    for p in peers {
        argv.extend(["--connect".into(), endpoint(*p)]);
    }
    argv
}

/// Host mode: starts one `tilting-plant --robots ROBOTS` with the flags of `job` (every robot
/// runs them), its output `plant.json` and `plant.log` in `job.dir`.
pub(super) fn spawn_plant_host(
    job: &Job,
    topo: &Topology,
    bins: &NodeBinaries,
    robots: &str,
) -> anyhow::Result<Child> {
    let args = hosting(plant_args(job, topo)?, robots, &[]);
    Child::spawn_with("plant", &bins.plant, &args, &job.dir, job.args.realtime)
}

/// Host mode: starts one `tilting-controller --robots ROBOTS`, dialling the plant, the first
/// robot's front-door session and the others' (`taps`).
pub(super) fn spawn_controller_host(
    job: &Job,
    topo: &Topology,
    bins: &NodeBinaries,
    robots: &str,
    taps: &[u16],
) -> anyhow::Result<Child> {
    let args = hosting(controller_args(job, topo), robots, taps);
    controller_child(job, bins, &args)
}

impl Topology {
    /// Host mode: the front-door session of robot `robot` listening on `port` (the first
    /// robot's is [`Topology::front_door_sessions`]'), a loopback peer dialling the plant.
    pub(super) fn tap_session(&self, robot: &str, port: u16) -> ZenohArgs {
        ZenohArgs::new(robot, &[&endpoint(port)], &[&endpoint(self.plant_port)])
    }

    /// Host mode: the endpoints as robot `port`'s summary records them (its front door's).
    pub(super) fn endpoints_of_tap(&self, port: u16) -> Endpoints {
        Endpoints {
            planner: endpoint(port),
            ..self.endpoints()
        }
    }

    /// The first robot's front-door port.
    pub(super) fn front_door_port(&self) -> u16 {
        self.my_port
    }
}

/// Starts the controller; the plant starts its clock when the controller's token appears.
pub(super) fn spawn_controller(
    job: &Job,
    topo: &Topology,
    bins: &NodeBinaries,
) -> anyhow::Result<Child> {
    controller_child(job, bins, &controller_args(job, topo))
}

/// The controller child with flags `args`, its output in `job.dir`.
fn controller_child(job: &Job, bins: &NodeBinaries, args: &[String]) -> anyhow::Result<Child> {
    Child::spawn_with(
        "controller",
        &bins.controller,
        args,
        &job.dir,
        job.args.realtime,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LiveArgs;
    use clap::Parser as _;
    use tilting_controller::node::ControllerArgs;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        live: LiveArgs,
    }

    /// `--delay 25` (s, each way) at 1 kHz with the default --max-age (10 periods): no torque
    /// could come back in time, so the run is refused before anything starts, naming the
    /// flags; a jitter that only makes the mean round trip too long is a warning.
    #[test]
    fn a_round_trip_longer_than_max_age_is_refused_or_warned_about() {
        let live = |argv: &[&str]| Cli::try_parse_from(argv).unwrap().live;
        let args = live(&["x", "--delay", "25"]);
        let Err(e) = crate::check(&args) else {
            panic!("--delay 25 accepted")
        };
        let m = e.to_string();
        assert!(
            m.contains("--delay") && m.contains("--max-age 10") && m.contains("[0, 0.005] s"),
            "{m}"
        );
        let args = live(&["x", "--delay", "0.004", "--jitter", "exp:0.002"]);
        let job = crate::check(&args).unwrap();
        let w = job.link_warning.expect("a warning");
        assert!(w.contains("--max-age 10") && w.contains("--delay"), "{w}");
        let args = live(&["x", "--delay", "0.004"]);
        assert_eq!(crate::check(&args).unwrap().link_warning, None);
    }

    /// The children parse the flags `live` hands them into what `live` was given: the link,
    /// the law, `--predict`, the rate, the duration and the age rule (the controller from the
    /// run's robot file).
    #[test]
    fn the_children_read_what_live_was_given() {
        let dir = std::env::temp_dir().join(format!("tilting-nodes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let argv = [
            "tilting",
            "--out",
            dir.to_str().unwrap(),
            "--delay",
            "0.002",
            "--torque-jitter",
            "exp:0.0005",
            "--state-loss",
            "0.1",
            "--seed",
            "7",
            "--max-age",
            "3",
            "--predict",
            "0.004",
            "--kp",
            "60",
            "--kd",
            "12",
            "--reference",
            "sinusoid:0.2,4",
            "--torque-limit",
            "5",
            "--energy-avg=0.1875",
            "--rate",
            "500",
            "--duration",
            "2.5",
            "--measure",
            "angles",
            "--encoder-counts",
            "4096",
            "--estimator",
            "fd",
        ];
        let live = Cli::try_parse_from(argv).unwrap().live;
        let job = crate::check(&live).unwrap();
        // The flags over an empty file, as `robot::parse` merges them.
        let cmd = <Cli as clap::CommandFactory>::command();
        let m = cmd.clone().try_get_matches_from(argv).unwrap();
        let mut merged = RobotFile::empty(&dir.join("given.toml"));
        merged.override_with(&m, &cmd).unwrap();
        let file = run_file(&job, Some(&merged)).unwrap();
        std::fs::write(&file.path, file.to_toml_string()).unwrap();
        let topo = Topology::ports(&job).unwrap();
        let once = |bin: &'static str, v: Vec<String>| std::iter::once(bin.to_owned()).chain(v);
        // The plant reads its network and sensors from the run file, as its binary does.
        let argv_plant: Vec<std::ffi::OsString> =
            once("tilting-plant", plant_args(&job, &topo).unwrap())
                .map(Into::into)
                .collect();
        let plant = PlantArgs::from_argv(&argv_plant).unwrap();
        assert_eq!(plant.network, live.network);
        assert_eq!(plant.zenoh.robot, live.robot);
        assert_eq!((plant.rate, plant.duration), (500.0, Some(2.5)));
        assert_eq!((plant.max_age, plant.torque_limit), (3, 5.0));
        let argv: Vec<std::ffi::OsString> =
            once("tilting-controller", controller_args(&job, &topo))
                .map(Into::into)
                .collect();
        let ctl: ControllerArgs = robot_file::parse_node(&argv).unwrap();
        assert_eq!(ctl.predict, live.predict);
        assert_eq!(ctl.estimator, live.estimator);
        assert_eq!(plant.imperfect, live.imperfect);
        let cfg = ctl.control_config().unwrap();
        assert_eq!((cfg.law, cfg.params), (job.reference, job.params().0));
        let _ = std::fs::remove_dir_all(&dir);
        // Each node runs with the id `live` chose and pins the other's (and so does the
        // recorder, with `job.ids`); the two ids differ.
        let (p, c) = (job.ids.plant.unwrap(), job.ids.controller.unwrap());
        assert_ne!(p, c);
        assert_eq!(
            (plant.zenoh.zenoh_id, plant.controller_id),
            (Some(p), Some(c))
        );
        assert_eq!((ctl.zenoh.zenoh_id, ctl.plant_id), (Some(c), Some(p)));
    }
}
