//! `tilting live --robots A,B,...`: host mode (issue 32) live. ONE plant process
//! (`tilting-plant --robots A,B,...`) and ONE controller process (`tilting-controller --robots
//! A,B,...`) serve every robot, each over its own keys `tilting/{name}/...`; the planner's
//! publisher and the recorder stay in-process, one front-door session per robot (its own
//! recorder, reference publisher and liveliness watch, as a one-robot run has), so each robot's
//! recording, status line, orbit verdict, report and `summary.json` are the one-robot run's,
//! in `OUT/{name}/`. The hosts' own output (`plant.json`, `plant.log`, `controller.json`,
//! `controller.log`, one summary line per robot) and the run's `robot.toml` (which both hosts
//! read: every robot runs the same law, model, link and sensors) are in `OUT/`.
//!
//! One recorder per robot (not one for all): a robot's recording is then the file a one-robot
//! run writes (`run.mcap` with that robot's five topics), which every tool reads as it is
//! (`replay`, `info`, the figures), and a robot whose messages misbehave fills only its own
//! refusal counters. The cost is a zenoh session per robot in the front door, each dialled by
//! the controller host; the plant host and the controller host keep one session each.
//!
//! The run fails (its exit code) if any robot fails: the worst ending of the robots, a failed
//! run (1) before a fault (3) before a lost orbit (4).
//!
//! Refused at the start, naming the flags: `--secure` (a certificate names one robot and its
//! access control allows that robot's keys only; a host would need one identity for all its
//! robots, which `tilting certs` does not make), `--plant-cmd` (an external plant serves one
//! robot), `--ros2` (one ROS 2 robot per plant process) and `--foxglove` (one robot per
//! server).

use super::monitor::{self, End, Signals, Watch};
use super::nodes::{self, Topology};
use super::report::{self, Ending};
use super::shutdown::{self, Stopped};
use super::tap::Tap;
use super::{check, Job, LiveArgs};
use crate::record::Recorder;
use crate::LiveError;
use anyhow::anyhow;
use std::time::Duration;
use tilting_controller::node::ControllerSummary;
use tilting_launch::{Child, NodeBinaries, PortLease};
use tilting_net::HostedSummary;
use tilting_plant::node::PlantSummary;
use tilting_sim::robot::RobotFile;

/// The flags host mode cannot honour, each as (its name, whether it is given).
fn unsupported(args: &LiveArgs) -> [(&'static str, bool); 4] {
    [
        ("--secure", args.secure),
        ("--plant-cmd", args.plant_cmd.is_some()),
        ("--ros2", args.ros2.ros2.is_some()),
        ("--foxglove", args.foxglove.foxglove.is_some()),
    ]
}

/// The robots of `--robots` (1 to [`tilting_net::MAX_HOSTED`] distinct valid names), or a
/// usage error naming the flag and the range; and a flag host mode cannot honour refused,
/// naming both flags.
pub fn check_robots(args: &LiveArgs) -> Result<Vec<tilting_proto::Keys>, LiveError> {
    // `--robots ""` names no robot (clap reads it as one empty name).
    let names: Vec<String> = if args.robots.iter().all(String::is_empty) {
        Vec::new()
    } else {
        args.robots.clone()
    };
    let keys = tilting_net::hosted_keys(&names)
        .map_err(|e| LiveError::Usage(anyhow!("{e}").context("live")))?;
    if let Some((flag, _)) = unsupported(args).into_iter().find(|u| u.1) {
        let why = match flag {
            "--secure" => {
                "a certificate of `tilting certs` names one robot and its access control allows \
                 that robot's keys only; run each secure robot with its own `tilting live \
                 --secure`"
            }
            "--plant-cmd" => "an external plant serves one robot",
            "--ros2" => "one ROS 2 robot per plant process",
            _ => "a Foxglove server shows one robot",
        };
        return Err(LiveError::Usage(anyhow!(
            "`--robots` (host mode) does not take `{flag}`: {why}"
        )));
    }
    Ok(keys)
}

/// One robot of the run: its flags (its name, its directory) and what they resolve to.
struct Robot {
    args: LiveArgs,
}

/// `tilting live --robots`: checks the flags, runs every robot from one plant host and one
/// controller host until `--duration` s of plant time (or Ctrl-C), and writes each robot's
/// recording, report and summary into `OUT/{name}/`; the worst robot's ending.
pub fn run(args: &LiveArgs, robot: Option<&RobotFile>) -> Result<(), LiveError> {
    let keys = check_robots(args)?;
    let base = check(args)?;
    let robots: Vec<Robot> = keys
        .iter()
        .map(|k| Robot {
            args: LiveArgs {
                robot: k.robot().to_owned(),
                robots: Vec::new(),
                out: Some(base.dir.join(k.robot())),
                ..args.clone()
            },
        })
        .collect();
    // Each robot's job: the base's law, link and zenoh ids (the hosts have one session
    // each), its own keys and directory.
    let jobs: Vec<Job> = robots
        .iter()
        .zip(&keys)
        .map(|(r, k)| Job {
            args: &r.args,
            keys: k.clone(),
            reference: base.reference,
            impairment: base.impairment,
            link_warning: base.link_warning.clone(),
            dir: base.dir.join(k.robot()),
            ids: base.ids,
        })
        .collect();
    let bins = NodeBinaries::next_to_current_exe().map_err(LiveError::Failed)?;
    // The run's directory and robot file, which both hosts read, and each robot's (as a
    // one-robot run leaves them).
    for job in std::iter::once(&base).chain(&jobs) {
        super::prepare(job, robot)?;
    }
    let rt = tilting_net::runtime().map_err(LiveError::Failed)?;
    let signals = Signals::start(&rt);
    let endings = rt
        .block_on(live(&base, &jobs, &bins, signals))
        .map_err(LiveError::Failed)?;
    let said: Vec<String> = jobs
        .iter()
        .zip(&endings)
        .map(|(j, e)| format!("{} {}", j.keys.robot(), word(*e)))
        .collect();
    eprintln!("live: robots: {}", said.join(", "));
    super::ending_result(worst(&endings), &base.dir)
}

/// The run's ending: the worst of the robots' (a failed run, then a fault, then a lost orbit;
/// clean only when every robot's is).
fn worst(endings: &[Ending]) -> Ending {
    [Ending::Failed, Ending::Fault, Ending::OrbitLost]
        .into_iter()
        .find(|w| endings.contains(w))
        .unwrap_or(Ending::Clean)
}

/// The front-door ports: the first robot's is the topology's, the others' reserved here
/// (held by the leases for the run).
fn tap_ports(topo: &Topology, n: usize) -> anyhow::Result<(Vec<u16>, Vec<PortLease>)> {
    let leases = (1..n)
        .map(|_| tilting_launch::reserve_port())
        .collect::<anyhow::Result<Vec<_>>>()?;
    let ports = std::iter::once(topo.front_door_port())
        .chain(leases.iter().map(PortLease::port))
        .collect();
    Ok((ports, leases))
}

/// Opens each robot's front door (its session on its port, its recorder's subscribers, its
/// reference publisher) and waits for every robot's state 0; `Some(end)` if the run ended
/// first.
async fn open_front_doors(
    jobs: &[Job<'_>],
    recorders: &[Recorder],
    ports: &[u16],
    topo: &Topology,
    plant: &mut Child,
    signals: &Signals,
) -> anyhow::Result<(Vec<Tap>, Option<End>)> {
    let mut taps = Vec::with_capacity(jobs.len());
    for ((job, recorder), &port) in jobs.iter().zip(recorders).zip(ports) {
        let session = topo.tap_session(job.keys.robot(), port);
        taps.push(Tap::open(&session, None, &job.keys, recorder, job.reference.to_wire()).await?);
    }
    for recorder in recorders {
        let end = monitor::wait_for_first_state(recorder, plant, signals).await;
        if end.is_some() {
            return Ok((taps, end));
        }
    }
    Ok((taps, None))
}

/// Runs the hosts and every robot's front door: spawn, record, monitor, shut down,
/// summarise each robot; each robot's ending.
async fn live(
    base: &Job<'_>,
    jobs: &[Job<'_>],
    bins: &NodeBinaries,
    signals: Signals,
) -> anyhow::Result<Vec<Ending>> {
    let force = signals.force();
    let topo = Topology::ports(base)?;
    let (ports, _leases) = tap_ports(&topo, jobs.len())?;
    let recorders = jobs
        .iter()
        .map(Job::recorder)
        .collect::<anyhow::Result<Vec<_>>>()?;
    let list = jobs
        .iter()
        .map(|j| j.keys.robot())
        .collect::<Vec<_>>()
        .join(",");
    super::announce(base);
    eprintln!(
        "live: host mode: {} robots ({list}) from one plant and one controller process; each \
         robot's recording and report in {}/NAME/",
        jobs.len(),
        base.dir.display()
    );
    let (scenario, check) = base.nominal().await?;

    // Spawn the plant host, each robot's front door, and once every robot's state 0 reached
    // it, the controller host.
    let fox =
        crate::foxglove::LiveServer::start(&base.args.foxglove, &base.keys, base.plant_params())
            .await;
    let mut plant = nodes::spawn_plant_host(base, &topo, bins, &list)?;
    let (taps, early_end) =
        open_front_doors(jobs, &recorders, &ports, &topo, &mut plant, &signals).await?;
    let mut controller = match early_end {
        None => Some(nodes::spawn_controller_host(
            base,
            &topo,
            bins,
            &list,
            &ports[1..],
        )?),
        Some(_) => None,
    };
    let end = match early_end {
        Some(end) => end,
        None => {
            let watches = watches(jobs, &recorders, &taps, check, &fox);
            let children = monitor::Children {
                plant: &mut plant,
                controller: controller.as_mut(),
                router: None,
            };
            monitor::monitor(&watches, children, &signals, base.args.duration).await
        }
    };

    // Shut down the hosts, then each robot's front door and recording; summarise each robot.
    let (problems, stopped) = stop_hosts(base, &end, &mut plant, controller.as_mut(), &force).await;
    let ended = Ended {
        end,
        problems,
        stopped,
        plants: HostedSummary::all_from_stdout(&plant.stdout()),
        controllers: controller
            .as_ref()
            .map_or_else(Vec::new, |c| HostedSummary::all_from_stdout(&c.stdout())),
        scenario,
        check,
    };
    let mut endings = Vec::with_capacity(jobs.len());
    for (((job, recorder), tap), &port) in jobs.iter().zip(recorders).zip(taps).zip(&ports) {
        let closed = tap.close().await;
        let outcome = ended.outcome(
            job.keys.robot(),
            recorder,
            closed,
            topo.endpoints_of_tap(port),
        );
        eprintln!("live: robot {}:", job.keys.robot());
        endings.push(report::summarise(
            job,
            &ended.scenario,
            ended.check,
            outcome,
        )?);
    }
    Ok(endings)
}

/// What the status lines watch: each robot's recording and front door, named.
fn watches<'a>(
    jobs: &'a [Job<'_>],
    recorders: &'a [Recorder],
    taps: &'a [Tap],
    check: Option<super::orbit::OrbitCheck>,
    fox: &'a crate::foxglove::LiveServer,
) -> Vec<Watch<'a>> {
    jobs.iter()
        .zip(recorders)
        .zip(taps)
        .map(|((job, recorder), tap)| Watch {
            recorder,
            tap,
            check,
            impaired: job.impairment.is_some(),
            foxglove: fox,
            robot: Some(job.keys.robot()),
        })
        .collect()
}

/// Stops the plant host, then the controller host (`force()`: kill at once), shows the logs
/// of one that failed; the run's problems and the exit statuses.
async fn stop_hosts(
    base: &Job<'_>,
    end: &End,
    plant: &mut Child,
    mut controller: Option<&mut Child>,
    force: &dyn Fn() -> bool,
) -> (Vec<String>, Stopped) {
    let mut problems = Vec::new();
    let stopped = shutdown::stop_children(
        end,
        plant,
        controller.as_deref_mut(),
        force,
        base.args.duration,
        &mut problems,
    );
    tokio::time::sleep(Duration::from_millis(150)).await;
    let controller = controller.map(|c| &*c);
    shutdown::show_failed_logs(plant, controller);
    problems.extend(shutdown::fallback_problems(&base.dir, plant, controller));
    (problems, stopped)
}

/// How the hosts ended, shared by every robot's summary.
struct Ended {
    /// Why the monitoring ended.
    end: End,
    /// The run's problems (the hosts'), one sentence each.
    problems: Vec<String>,
    /// The hosts' exit statuses.
    stopped: Stopped,
    /// The plant host's summary lines, one per robot.
    plants: Vec<HostedSummary<PlantSummary>>,
    /// The controller host's.
    controllers: Vec<HostedSummary<ControllerSummary>>,
    /// The nominal run.
    scenario: tilting_sim::Scenario,
    /// The orbit check, if the law has an orbit.
    check: Option<super::orbit::OrbitCheck>,
}

impl Ended {
    /// Robot `name`'s outcome: the hosts' ending with its own summaries, its closed
    /// recording (a failed recording is a problem of this robot) and front door.
    fn outcome(
        &self,
        name: &str,
        recorder: Recorder,
        closed: super::tap::Closed,
        endpoints: super::summary::Endpoints,
    ) -> report::Outcome {
        let mut problems = self.problems.clone();
        let (dropped, view) = super::close_recorder(recorder, &mut problems);
        report::Outcome {
            end: self.end.clone(),
            problems,
            stopped: Stopped {
                plant: self.stopped.plant,
                controller: self.stopped.controller,
            },
            plant: mine(name, &self.plants),
            controller: mine(name, &self.controllers),
            last_status: view.last_status.clone(),
            view,
            dropped,
            invalid: closed.invalid,
            planner: closed.planner,
            endpoints,
        }
    }
}

/// Robot `name`'s summary among a host's lines.
fn mine<S: Clone>(name: &str, all: &[HostedSummary<S>]) -> Option<S> {
    all.iter()
        .find(|s| s.robot == name)
        .map(|s| s.summary.clone())
}

/// A robot's ending in a word, for the run's last line.
fn word(e: Ending) -> &'static str {
    match e {
        Ending::Clean => "clean",
        Ending::Failed => "FAILED",
        Ending::Fault => "FAULT",
        Ending::OrbitLost => "ORBIT LOST",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Ending::*;

    /// One robot's failure fails the run whatever the others did, in the order of the exit
    /// codes' severity (1 failed, 3 fault, 4 orbit lost); clean only when all are.
    #[test]
    fn the_run_ends_as_its_worst_robot() {
        assert_eq!(worst(&[Clean, Clean, Clean]), Clean);
        assert_eq!(worst(&[Clean, OrbitLost, Clean]), OrbitLost);
        assert_eq!(worst(&[OrbitLost, Fault, Clean]), Fault);
        assert_eq!(worst(&[Fault, Clean, Failed, OrbitLost]), Failed);
        // Order of the robots does not matter.
        assert_eq!(worst(&[Clean, Clean, Fault]), worst(&[Fault, Clean, Clean]));
    }

    /// `--robots ""` names no robot; a flag host mode cannot serve is refused naming both.
    #[test]
    fn no_robot_and_unservable_flags_are_refused() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            live: LiveArgs,
        }
        let live = |argv: &[&str]| <Cli as clap::Parser>::try_parse_from(argv).unwrap().live;
        let e = check_robots(&live(&["x", "--robots", ""]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("--robots") && e.contains("0 names"), "{e}");
        let e = check_robots(&live(&["x", "--robots", "a,b", "--ros2"]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`--robots`") && e.contains("`--ros2`"), "{e}");
        let keys = check_robots(&live(&["x", "--robots", "a,b"])).unwrap();
        assert_eq!(
            keys.iter().map(|k| k.robot()).collect::<Vec<_>>(),
            ["a", "b"]
        );
    }
}
