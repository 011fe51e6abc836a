//! The flags of `tilting-plant` and their validation.

use super::*;

/// How plant time advances.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "lowercase")]
pub enum ClockMode {
    /// Paced by the wall clock, one period per `1/rate` s.
    Realtime,
    /// One period per torque answer: deterministic.
    Lockstep,
}

/// How host mode (`--robots`) paces its robots in real time ([`super::host`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum HostPacing {
    /// A pacing thread per robot.
    Each,
    /// One pacing thread for every robot.
    One,
}

/// Flags of `tilting-plant`.
#[derive(Debug, Clone, clap::Parser)]
#[command(
    allow_negative_numbers = true,
    name = "tilting-plant",
    version,
    about = "Simulated tilting plant: integrates the hybrid dynamics in real time (or in lockstep) \
             and publishes its state over zenoh",
    after_help = "Exit codes: 0 run completed or stopped, 1 error, 3 the model faulted (fall, contact loss). \
                  A JSON summary is printed on stdout at the end."
)]
pub struct PlantArgs {
    /// Zenoh and naming flags.
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    /// Host mode: several robots from this one process ([`super::host`]).
    #[command(flatten)]
    pub host: tilting_net::HostArgs,
    /// Host mode (--robots) in real time: `each`, a pacing thread per robot, each sleeping to
    /// its own deadlines; or `one`, one thread that wakes once per period and steps every
    /// robot in turn (one wake-up and one --spin-us per period for all)
    #[arg(long, value_enum, default_value_t = HostPacing::Each, requires = "robots")]
    pub host_pacing: HostPacing,
    /// Network impairments emulated by the plant: states and torques cross links with these
    /// delays and losses, drawn from --seed as in `tilting simulate`. In lockstep the run is
    /// the same as `simulate` with the same flags, bit for bit; in real time the plant delays
    /// and drops the messages on the wall clock.
    #[command(flatten)]
    pub network: tilting_link::NetworkArgs,
    /// The robot's imperfections (both clocks): the published state is the measured one, the
    /// torque is applied through the actuator, the arm mass is off by --mass-error; the noise
    /// draws from --seed (its own stream), exactly as in `tilting simulate` with the same flags.
    #[command(flatten)]
    pub imperfect: crate::imperfect::ImperfectArgs,
    /// Pace plant time by the wall clock (realtime) or by the controller's answers (lockstep)
    #[arg(long, value_enum, default_value_t = ClockMode::Realtime)]
    pub clock: ClockMode,
    /// Control rate (Hz): one PlantState per period 1/rate
    #[arg(long, default_value_t = 1000.0, value_name = "HZ")]
    pub rate: f64,
    /// Control period (s), instead of --rate (to match `simulate --control-period` exactly)
    #[arg(long, value_name = "SECONDS", conflicts_with = "rate")]
    pub period: Option<f64>,
    /// Realtime clock: apply the newest torque received as long as it answers a state at most
    /// this many periods old (0 = only the answer to the current state, the strict rule)
    #[arg(long, default_value_t = DEFAULT_MAX_AGE, value_name = "PERIODS")]
    pub max_age: u64,
    /// The watchdog and the safe mode ([`crate::safe`]).
    #[command(flatten)]
    pub safe: crate::safe::SafeArgs,
    /// Lockstep clock: wait this long for a torque, then apply the safe mode for that period
    #[arg(long, default_value_t = 1000, value_name = "MS")]
    pub lockstep_timeout_ms: u64,
    /// Stop after this much plant time (s); default: run until Ctrl-C
    #[arg(long, value_name = "SECONDS")]
    pub duration: Option<f64>,
    /// Initial contact mode: flat, left or right
    #[arg(long, default_value_t = paper::ORBIT_MODE)]
    pub mode: Mode,
    /// Initial state alpha,beta,alpha_dot,beta_dot (rad, rad/s) [default: the start of the
    /// paper's tilting orbit, `tilting_plant::paper::orbit_x0`]
    #[arg(long, value_name = "A,B,AD,BD", value_parser = crate::parse_x0, allow_hyphen_values = true)]
    pub x0: Option<[f64; 4]>,
    /// Landing impact law: paper, striking-edge or physical [default: the params file's
    /// `impact`, else paper]
    #[arg(long, value_name = "LAW")]
    pub impact: Option<ImpactLaw>,
    /// The model's parameter file.
    #[command(flatten)]
    pub params: crate::ParamsArgs,
    /// Relative tolerance of the integrator (the absolute one is rtol/100, as in `simulate`)
    #[arg(long, default_value_t = Tolerance::default().rtol)]
    pub rtol: f64,
    /// Refuse commanded torques larger than this (N m): they are counted as dropped and logged
    /// [default: 10 times the largest torque of the paper's orbit, 116.5]
    #[arg(long, value_name = "NM", allow_negative_numbers = true)]
    pub max_torque: Option<f64>,
    /// Hard torque limit (N m) applied by the plant; 0 = none
    #[arg(long, default_value_t = 0.0, value_name = "NM")]
    pub torque_limit: f64,
    /// Record the run into this file: MCAP (states, applied torques, events, status; JSON for
    /// Foxglove and PlotJuggler plus the wire bytes), or for a name ending in `.csv` one row per
    /// period: seq,t,mode,alpha,beta,alpha_dot,beta_dot,tau (the torque applied)
    #[arg(long, value_name = "FILE.mcap|FILE.csv")]
    pub record: Option<PathBuf>,
    /// Start at once instead of waiting for a controller (its liveliness token or an answer)
    #[arg(long)]
    pub no_wait: bool,
    /// The controller's zenoh id (its `--zenoh-id`), if known before it starts: torques are
    /// believed only from that session, from the first one on, and the pin never lapses
    /// [default: pin the session of the first believed torque]
    #[arg(long, value_name = "HEX", value_parser = tilting_net::parse_source_id)]
    pub controller_id: Option<tilting_proto::SourceId>,
    /// Publish an extra state at each mode transition (same `seq` as its period, its own time)
    /// and switch to its answer at once (real time: if it comes within half a period)
    #[arg(long)]
    pub sample_on_event: bool,
    /// Realtime clock: busy-wait this long before each deadline (µs) [default: 50; 0 in host
    /// mode (--robots), where N robots would spin N times as long per period]
    #[arg(long, value_name = "US")]
    pub spin_us: Option<u64>,
    /// Realtime clock: try SCHED_FIFO at this priority for the pacing thread (needs privileges)
    #[arg(long, value_name = "1-99")]
    pub rt_priority: Option<i32>,
    /// Be a ROS 2 robot too (docs/ros2.md): the state on /<robot>/joint_states, the mode on
    /// /<robot>/contact_mode, events, faults and the safe mode on /rosout (from a thread of
    /// their own: the loop never waits for them), and the arm torque accepted as
    /// std_msgs/msg/Float64MultiArray on /<robot>/effort_command. zenoh (a bare --ros2):
    /// rmw_zenoh's conventions on this session; dds: over DDS for a stock ROS 2 (also the URDF
    /// on /<robot>/robot_description; ROS_AUTOMATIC_DISCOVERY_RANGE honoured); both
    #[arg(long, value_name = "zenoh|dds|both", num_args = 0..=1, default_missing_value = "zenoh",
          value_parser = parse_route)]
    pub ros2: Option<tilting_ros2::Route>,
    /// ROS 2 domain id of --ros2 [default: ROS_DOMAIN_ID, else 0]
    #[arg(long, value_name = "0-232", requires = "ros2")]
    pub ros_domain: Option<u32>,
    /// With --ros2 and --zenoh-config (the secure deployment, where the router's ACL lets only
    /// the controller's certificate publish torques): accept /<robot>/effort_command anyway
    #[arg(long, requires = "ros2")]
    pub ros2_allow_commands: bool,
    /// A robot file (TOML): the defaults of the flags of its [network] (the emulated link and
    /// --seed) and [sensors] (the imperfections), and its parameters ([plant], else [robot])
    /// as --params; a flag given as well overrides its key. `tilting live` hands the plant its
    /// run's robot.toml, with only the wiring (session, ports, ids, rate, start) as flags
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot_file: Option<PathBuf>,
}

/// Allowed control periods (s): 100 us (10 kHz; a faster loop spends its period in the
/// integrator and zenoh) to 10 s.
pub const PERIOD_RANGE: (f64, f64) = (tilting_proto::plausible::MIN_PERIOD, 10.0);
/// Most periods in one run (`--duration` / period).
pub const MAX_PERIODS: f64 = 1e9;
/// The default bound on commanded torques (N m): ten times the largest torque along the
/// paper's stabilised orbit ([`paper::ORBIT_MAX_TORQUE`], 11.65 N m). A physically plausible
/// command of this machine is well inside it; a 1e9 N m "command" is not.
pub const DEFAULT_MAX_TORQUE: f64 = 10.0 * paper::ORBIT_MAX_TORQUE;

/// The default `--max-age` (periods): 10, i.e. 10 ms at 1 kHz. A torque answers the state it
/// was computed from; a round trip of a few periods (a busy LAN, Wi-Fi) keeps the loop running,
/// and one older than this is not used (the watchdog then counts, and the safe mode follows
/// after `--watchdog` periods).
pub const DEFAULT_MAX_AGE: u64 = 10;

/// The busy-wait before each real-time deadline of one robot (µs, `--spin-us`'s default).
pub const DEFAULT_SPIN_US: u64 = 50;

/// Longest busy-wait before a deadline (µs).
pub const MAX_SPIN_US: u64 = 1000;

/// `--ros2`'s value (clap's error then names the flag and the allowed routes).
fn parse_route(s: &str) -> Result<tilting_ros2::Route, String> {
    s.parse()
}

impl PlantArgs {
    /// The ROS 2 domain of `--ros2`: `--ros-domain`, else `ROS_DOMAIN_ID`, else 0 (0 to 232).
    pub fn ros_domain(&self) -> anyhow::Result<u32> {
        let env = std::env::var("ROS_DOMAIN_ID").ok();
        tilting_ros2::domain_id(self.ros_domain, env.as_deref()).map_err(anyhow::Error::msg)
    }

    /// The bound on commanded torques (N m): `--max-torque`, or [`DEFAULT_MAX_TORQUE`].
    pub fn max_torque(&self) -> f64 {
        self.max_torque.unwrap_or(DEFAULT_MAX_TORQUE)
    }

    /// The busy-wait before each real-time deadline (ns): `--spin-us`, else
    /// [`DEFAULT_SPIN_US`], or 0 in host mode (`--robots`: measured on 2 cores with 8 robots
    /// at 1 kHz, 0.3-0.5 % of periods missed without the spin, 0.7-0.9 % with 50 us each).
    pub fn spin_ns(&self) -> u64 {
        let default = if self.host.hosting() {
            0
        } else {
            DEFAULT_SPIN_US
        };
        self.spin_us.unwrap_or(default) * 1000
    }

    /// The control period (s).
    pub fn period(&self) -> f64 {
        self.period.unwrap_or(1.0 / self.rate)
    }

    pub(super) fn validate(&self) -> anyhow::Result<()> {
        let (lo, hi) = PERIOD_RANGE;
        match self.period {
            Some(h) => anyhow::ensure!(
                h.is_finite() && (lo..=hi).contains(&h),
                "invalid --period = {h}: allowed {lo} to {hi} s"
            ),
            None => anyhow::ensure!(
                self.rate.is_finite() && (1.0 / hi..=1.0 / lo).contains(&self.rate),
                "invalid --rate = {}: allowed {} to {} Hz",
                self.rate,
                1.0 / hi,
                1.0 / lo
            ),
        }
        let h = self.period();
        if let Some(d) = self.duration {
            anyhow::ensure!(
                d.is_finite() && d > 0.0 && d / h <= MAX_PERIODS,
                "invalid --duration = {d}: allowed a positive number of seconds, at most \
                 {MAX_PERIODS:e} periods ({} s at this rate)",
                MAX_PERIODS * h
            );
        }
        let imperfect = self.imperfections()?;
        if self.sample_on_event {
            anyhow::ensure!(
                self.network.impairment(self.max_age)?.is_none() && !imperfect.has_hardware(),
                "--sample-on-event is not combined with emulated links (--delay ...) or the \
                 robot's hardware (--noise-*, --encoder-counts, --torque-*) in the plant yet; \
                 `tilting simulate` combines it with the links"
            );
        }
        // Checked for both clocks: the same ranges and messages as `simulate`.
        self.network.impairment(self.max_age)?;
        if let Some(route) = self.ros2 {
            self.ros_domain()?;
            anyhow::ensure!(
                cfg!(feature = "dds") || !route.dds(),
                "--ros2 {route}: this tilting-plant was built without DDS (cargo feature `dds` \
                 of tilting-plant, on by default); allowed here: --ros2 zenoh"
            );
            #[cfg(feature = "dds")]
            if route.dds() {
                tilting_ros2::dds::DiscoveryRange::from_env().map_err(anyhow::Error::msg)?;
            }
            tilting_ros2::robot::Topics::new(&self.zenoh.robot).map_err(anyhow::Error::msg)?;
            anyhow::ensure!(
                self.zenoh.zenoh_config.is_none() || self.ros2_allow_commands,
                "--ros2 with --zenoh-config (the secure deployment): /<robot>/effort_command \
                 would accept torques from any ROS 2 node the router lets in, around the ACL \
                 that admits only the controller's certificate; pass --ros2-allow-commands to \
                 accept them anyway (and allow the ROS 2 keys in the router's ACL)"
            );
        }
        anyhow::ensure!(
            self.max_age <= 1000,
            "invalid --max-age = {}: allowed 0 to 1000 periods",
            self.max_age
        );
        self.safe.settings()?;
        anyhow::ensure!(
            self.torque_limit.is_finite() && self.torque_limit >= 0.0,
            "invalid --torque-limit = {}: allowed >= 0 N m (0 = none)",
            self.torque_limit
        );
        if let Some(m) = self.max_torque {
            anyhow::ensure!(
                m.is_finite() && m > 0.0,
                "invalid --max-torque = {m}: allowed a positive number of N m"
            );
        }
        anyhow::ensure!(
            self.rtol.is_finite() && (1e-13..=1e-3).contains(&self.rtol),
            "invalid --rtol = {}: allowed 1e-13 to 1e-3",
            self.rtol
        );
        anyhow::ensure!(
            (1..=60_000).contains(&self.lockstep_timeout_ms),
            "invalid --lockstep-timeout-ms = {}: allowed 1 to 60000 ms",
            self.lockstep_timeout_ms
        );
        let max_spin = (h * 1e6 / 2.0).min(MAX_SPIN_US as f64) as u64;
        if let Some(spin) = self.spin_us {
            anyhow::ensure!(
                spin <= max_spin,
                "invalid --spin-us = {spin}: allowed 0 to {max_spin} us (at most {MAX_SPIN_US} \
                 us and half a period)"
            );
        }
        if let Some(p) = self.rt_priority {
            anyhow::ensure!(
                (1..=99).contains(&p),
                "invalid --rt-priority = {p}: allowed 1 to 99"
            );
        }
        Ok(())
    }

    /// The robot's imperfections (validated), the noise seeded with `--seed`; the perfect robot
    /// without any imperfection flag.
    pub fn imperfections(&self) -> anyhow::Result<crate::imperfect::Imperfections> {
        Ok(self
            .imperfect
            .imperfections(self.network.seed)?
            .unwrap_or_default())
    }

    /// The simulator settings (the same convention as `simulate`: `atol = rtol / 100`), with
    /// `--mass-error` applied to the arm mass of `--params`.
    pub fn sim_config(&self) -> anyhow::Result<SimConfig> {
        let params = self.params.params()?;
        let params = params.with_impact(params.impact_or(self.impact));
        let params = self.imperfections()?.plant_params(&params);
        Ok(SimConfig {
            params,
            impact: params.impact,
            tol: Tolerance {
                rtol: self.rtol,
                atol: self.rtol * 1e-2,
            },
            ..SimConfig::default()
        })
    }
}

impl PlantArgs {
    /// The flags (long names) whose keys a plant reads from the `[network]` and `[sensors]`
    /// sections of its robot file: the emulated link's ([`tilting_link::NetworkArgs`]) and the
    /// sensors' ([`crate::imperfect::ImperfectArgs`]). `tilting live` hands an external plant
    /// (`--plant-cmd`) the same keys as these flags.
    pub fn file_flags() -> Vec<String> {
        use clap::Args as _;
        let own = clap::Command::new("plant");
        let own = crate::imperfect::ImperfectArgs::augment_args(
            tilting_link::NetworkArgs::augment_args(own),
        );
        own.get_arguments()
            .filter_map(|a| a.get_long().map(str::to_owned))
            .collect()
    }

    /// Parses a plant's command line `argv` (its first item the program's name), with the keys
    /// of its `--robot-file` as the defaults of its flags: the emulated link's and the sensors'
    /// flags ([`tilting_link::NetworkArgs`], [`crate::imperfect::ImperfectArgs`]) and the
    /// parameters ([plant] if the file has it, else [robot]) as `--params`. The file's other
    /// keys (the law, the deployment, the controller's --sample-on-event) are not the plant's.
    /// A bad value is refused naming the key ([`crate::robot_file::apply`]).
    pub fn from_argv(
        argv: &[std::ffi::OsString],
    ) -> Result<Self, crate::robot_file::NodeArgsError> {
        let longs = Self::file_flags();
        crate::robot_file::parse_node_with(argv, &|defaults| {
            let has_plant = defaults.iter().any(|d| d.key == "[plant]");
            defaults
                .into_iter()
                .filter_map(|mut d| match d.key.as_str() {
                    "[plant]" => {
                        d.flag = "params".into();
                        Some(d)
                    }
                    "[robot]" => (!has_plant).then_some(d),
                    _ => longs.contains(&d.flag).then_some(d),
                })
                .collect()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    /// A plant given a robot file equals one given today's flags: its [network] and [sensors]
    /// keys are the flags' values, its parameters are [plant]'s (not [robot]'s); the keys that
    /// are not the plant's ([law], [deploy], the controller's `sample_on_event`) are left out;
    /// a flag given as well overrides its key; a bad value is refused naming its key.
    #[test]
    fn a_plant_from_a_robot_file_equals_one_from_flags() {
        let dir = std::env::temp_dir().join(format!("plant_robot_file_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("robot.toml");
        let text = "[robot]\nm_l = 0.3\n[plant]\nm_l = 0.25\n\
                    [network]\nstate_delay = 0.002\nloss = 0.1\nseed = 7\nsample_on_event = true\n\
                    [sensors]\nnoise_alpha = 0.001\nencoder_counts = 4096\n\
                    [law]\nkd = 14.0\n[deploy]\nrate = 500.0\n";
        std::fs::write(&file, text).unwrap();
        let argv = |extra: &[&str]| -> Vec<std::ffi::OsString> {
            ["tilting-plant"]
                .iter()
                .chain(extra)
                .map(Into::into)
                .collect()
        };
        let f = file.to_str().unwrap();
        let from_file = PlantArgs::from_argv(&argv(&["--robot-file", f])).unwrap();
        let from_flags = PlantArgs::try_parse_from(argv(&[
            "--state-delay=0.002",
            "--loss=0.1",
            "--seed=7",
            "--noise-alpha=0.001",
            "--encoder-counts=4096",
        ]))
        .unwrap();
        assert_eq!(from_file.network, from_flags.network);
        assert_eq!(from_file.imperfect, from_flags.imperfect);
        assert_eq!(from_file.params.load().unwrap().unwrap().m_l, 0.25);
        assert!(!from_file.sample_on_event);
        assert_eq!(from_file.rate, 1000.0);
        // Without [plant], [robot] is the plant's robot.
        let robot_only = dir.join("robot_only.toml");
        std::fs::write(&robot_only, "[robot]\nm_l = 0.3\n").unwrap();
        let a = PlantArgs::from_argv(&argv(&["--robot-file", robot_only.to_str().unwrap()]));
        assert_eq!(a.unwrap().params.load().unwrap().unwrap().m_l, 0.3);
        // A flag overrides its key.
        let over = PlantArgs::from_argv(&argv(&["--robot-file", f, "--seed", "9"])).unwrap();
        assert_eq!(over.network.seed, 9);
        assert_eq!(over.imperfect, from_flags.imperfect);
        // A bad value is refused naming the key.
        let bad = dir.join("bad.toml");
        std::fs::write(&bad, "[network]\nloss = \"lots\"\n").unwrap();
        match PlantArgs::from_argv(&argv(&["--robot-file", bad.to_str().unwrap()])) {
            Err(crate::robot_file::NodeArgsError::File(e)) => {
                assert!(e.contains("network.loss"), "{e}")
            }
            other => panic!("{other:?}"),
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn flags_parse_with_defaults() {
        let a = PlantArgs::try_parse_from(["tilting-plant"]).unwrap();
        assert_eq!(a.clock, ClockMode::Realtime);
        assert_eq!(a.period(), 0.001);
        assert_eq!(
            a.safe.settings().unwrap(),
            crate::safe::SafeSettings::default()
        );
        assert_eq!(a.mode, Mode::Left);
        assert_eq!(a.zenoh.robot, "demo");
        a.validate().unwrap();
        let a = PlantArgs::try_parse_from([
            "tilting-plant",
            "--clock",
            "lockstep",
            "--period",
            "0.002",
            "--x0",
            "-0.01,1.5,0,0",
            "--mode",
            "right",
            "--listen",
            "tcp/127.0.0.1:17999",
        ])
        .unwrap();
        assert_eq!(a.clock, ClockMode::Lockstep);
        assert_eq!(a.period(), 0.002);
        assert_eq!(a.x0, Some([-0.01, 1.5, 0.0, 0.0]));
        assert!(PlantArgs::try_parse_from(["tilting-plant", "--x0", "1,2,3"]).is_err());
        assert!(PlantArgs::try_parse_from(["tilting-plant", "--x0", "1,2,3,nan"]).is_err());
        assert!(
            PlantArgs::try_parse_from(["tilting-plant", "--rate", "1", "--period", "1"]).is_err()
        );
        let a = PlantArgs::try_parse_from(["tilting-plant", "--rate", "0"]).unwrap();
        assert!(a.validate().is_err());
    }

    #[test]
    fn out_of_range_flags_name_themselves_and_their_range() {
        // Each bad value is refused with the flag, the value as typed and the allowed range.
        for (flag, value, needle) in [
            ("--rate", "0", "invalid --rate = 0: allowed 0.1 to 10000 Hz"),
            ("--rate", "inf", "invalid --rate = inf"),
            ("--rate", "1e9", "invalid --rate = 1000000000"),
            (
                "--period",
                "0",
                "invalid --period = 0: allowed 0.0001 to 10 s",
            ),
            ("--duration", "-1", "invalid --duration = -1"),
            (
                "--spin-us",
                "1000000000",
                "invalid --spin-us = 1000000000: allowed 0 to 500 us",
            ),
            ("--watchdog", "0", "invalid `--watchdog` = 0"),
            ("--rtol", "1", "invalid --rtol = 1"),
            (
                "--rt-priority",
                "100",
                "invalid --rt-priority = 100: allowed 1 to 99",
            ),
            (
                "--noise-beta",
                "-1",
                "invalid `--noise-beta` = -1: allowed a standard deviation in rad in [0, 10]",
            ),
            (
                "--encoder-counts",
                "0",
                "invalid `--encoder-counts` = 0: allowed counts per revolution",
            ),
            (
                "--torque-lag",
                "-0.1",
                "invalid `--torque-lag` = -0.1: allowed a time constant in s in [0, 10]",
            ),
        ] {
            let a = PlantArgs::try_parse_from(["tilting-plant", flag, value])
                .unwrap_or_else(|e| panic!("{flag} {value}: {e}"));
            let err = a.validate().unwrap_err().to_string();
            assert!(err.contains(needle), "{flag} {value}: {err}");
        }
    }

    /// The impairment flags are checked for the real-time clock as for lockstep and
    /// `simulate`: the message names the flag and the allowed range; good values are accepted
    /// in real time.
    #[test]
    fn impairment_flags_are_validated_for_both_clocks() {
        for (extra, needle) in [
            (&["--delay", "-0.001"][..], "invalid `--delay` = -0.001"),
            (
                &["--torque-loss", "1.5"][..],
                "invalid `--torque-loss` = 1.5",
            ),
            (&["--loss", "2"][..], "a probability in [0, 1]"),
        ] {
            for clock in ["realtime", "lockstep"] {
                let mut argv = vec!["tilting-plant", "--clock", clock];
                argv.extend_from_slice(extra);
                let a = PlantArgs::try_parse_from(&argv).unwrap();
                let err = a.validate().unwrap_err().to_string();
                assert!(err.contains(needle), "{argv:?}: {err}");
            }
        }
        let e = PlantArgs::try_parse_from(["tilting-plant", "--jitter", "gamma:0.001"])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--jitter") && e.contains("unknown distribution"),
            "{e}"
        );
        let a = PlantArgs::try_parse_from([
            "tilting-plant",
            "--delay",
            "0.001",
            "--jitter",
            "exp:0.0005",
            "--loss",
            "0.1",
        ])
        .unwrap();
        a.validate().unwrap();
    }

    #[test]
    fn default_start_is_the_orbit() {
        let a = PlantArgs::try_parse_from(["tilting-plant"]).unwrap();
        assert_eq!(a.mode, paper::ORBIT_MODE);
        assert_eq!(a.x0, None); // resolved to paper::orbit_x0() by `run`
    }
}
