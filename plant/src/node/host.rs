//! Host mode of the plant node (`--robots a,b,c`, issue 32): one process, one zenoh session
//! and one tokio runtime serve several robots, each with its own keys `tilting/{name}/...`,
//! its own [`super::control_loop`] on a pacing thread of its own, its own faults and its own
//! summary line ([`tilting_net::HostedSummary`]). A robot that faults ends its own run only.
//!
//! Pacing in real time (`--host-pacing`): `each`, one thread per robot, each sleeping to its
//! own deadlines, so a robot's period never waits for another's step; or `one`, one thread
//! that wakes at each deadline and steps every robot in turn
//! (`control_loop::Loop::run_all_realtime`): one wake-up and one spin per period for all, the
//! robots' steps (about a microsecond each on the orbit) in series. Lockstep always runs a
//! thread per robot.

use super::PlantArgs;
use std::path::{Path, PathBuf};

/// The host mode's flags that cannot be served per robot: an error naming the flag.
pub fn check(args: &PlantArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        !(args.host_pacing == super::HostPacing::One && args.clock == super::ClockMode::Lockstep),
        "--host-pacing one paces by the wall clock: --clock realtime only (in lockstep each \
         robot waits for its own answers, on a thread of its own)"
    );
    anyhow::ensure!(
        args.ros2.is_none(),
        "--robots (host mode) does not take --ros2: one ROS 2 robot per tilting-plant"
    );
    tilting_net::check_hosted_config(&args.zenoh)
}

/// Robot `robot`'s `--record` file in host mode: `name` with `-{robot}` before its extension
/// (`run/plant.csv` -> `run/plant-a.csv`; the extension picks the format, as for one robot).
pub fn record_path(path: &Path, robot: &str) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let name = match path.extension() {
        Some(ext) => format!("{stem}-{robot}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{robot}"),
    };
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_robot_records_into_its_own_file() {
        assert_eq!(
            record_path(Path::new("run/plant.csv"), "a"),
            Path::new("run/plant-a.csv")
        );
        assert_eq!(
            record_path(Path::new("/x/run.mcap"), "rb_2"),
            Path::new("/x/run-rb_2.mcap")
        );
        assert_eq!(record_path(Path::new("log"), "b"), Path::new("log-b"));
    }
}
