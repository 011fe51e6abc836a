//! The robot file (feature `clap`): one TOML file that describes a robot and how it runs, taken
//! by every command (`tilting live robot.toml`, `simulate`, `plan orbit`, `config`; `identify
//! --out` writes into one). Its sections:
//!
//! | section | what it holds | its keys |
//! |---|---|---|
//! | `[robot]` | the robot's parameters (the controller's model) | the keys of a parameter file (`m_f`, `l`, `i_f`, `impact`, `restitution`, `contact_dwell`, ...), or `params = "file.toml"` |
//! | `[plant]` | the robot a simulation runs when it is not the model | the same |
//! | `[prior]` | the builder's prior for `identify` | the same |
//! | `[law]` | the law and its reference | the flags of the law: `law`, `kp`, `kd`, `k`, `energy_avg`, `reference`, `torque_limit`, `orbit_peak`, `orbit_start`, `orbit_steepness`, `plan`, `from_orbit` |
//! | `[run]` | the start and the length of a run | `x0`, `mode`, `duration`, `control_period`, `rtol` |
//! | `[network]` | the network between the nodes | `delay`, `jitter`, `loss`, `loss_burst` (each also `state_`, `torque_`), `seed`, `max_age`, `predict`, `sample_on_event` |
//! | `[sensors]` | what the plant measures and the controller estimates | `measure`, `noise_alpha`, ..., `encoder_counts`, `torque_saturation`, `torque_lag`, `mass_error`, `estimator` |
//! | `[deploy]` | how `live` runs it | `name`, `rate`, `realtime`, `secure`, `certs`, `out`, `csv`, `port`, `plant_cmd`, `foxglove`, `ros2`, `ros_domain` |
//!
//! Every key outside the parameter tables is the flag of the same name with `-` for `_`
//! (`[network] max_age = 60` is `--max-age 60`; `[deploy] name` is `--robot`): a command reads
//! the keys it has flags for, as the defaults of those flags, so a flag given as well overrides
//! the single key, and the file's values go through the flags' own parsers (the same run, bit for
//! bit). [`RobotFile::load`] refuses an unknown section or key and a bad value, naming
//! `section.key` and the allowed range. Paths (`law.plan`, `deploy.certs`, `deploy.out`, a
//! table's `params`) are relative to the file.

use clap::{ArgMatches, Args, FromArgMatches as _};
use std::path::{Path, PathBuf};
use tilting_controller::{EstimatorArgs, LawArgs, LawSpec};
use tilting_link::NetworkArgs;
use tilting_plant::imperfect::ImperfectArgs;
use tilting_plant::robot_file::{self as rf, FlagDefault, PARAMS_SECTIONS};
use tilting_plant::{Mode, Params};

/// The sections of a robot file, in the order `tilting config` prints them.
pub const SECTIONS: [&str; 8] = [
    "robot", "plant", "prior", "law", "run", "network", "sensors", "deploy",
];

/// `[law]`: the law and its reference.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct LawSection {
    /// The law's flags.
    #[command(flatten)]
    pub law: LawArgs,
    /// Take the law from a plan (`tilting plan orbit --json > plan.json`)
    #[arg(long, value_name = "PLAN.json")]
    pub plan: Option<PathBuf>,
    /// Take E_av from the smallest periodic orbit of the loop without adaptation
    #[arg(long)]
    pub from_orbit: bool,
}

/// `[run]`: the start and the length of a run.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct RunSection {
    /// Initial state alpha,beta,alpha_dot,beta_dot (rad, rad, rad/s, rad/s)
    #[arg(long, value_name = "A,B,AD,BD", value_parser = tilting_plant::parse_x0, allow_hyphen_values = true)]
    pub x0: Option<[f64; 4]>,
    /// Initial mode: flat, left or right
    #[arg(long, value_name = "MODE")]
    pub mode: Option<Mode>,
    /// Run length (s)
    #[arg(long, allow_negative_numbers = true)]
    pub duration: Option<f64>,
    /// Zero-order-hold period of the controller in `simulate` (s); 0 for continuous coupling
    #[arg(long, allow_negative_numbers = true)]
    pub control_period: Option<f64>,
    /// Relative tolerance of the integrator
    #[arg(long, allow_negative_numbers = true)]
    pub rtol: Option<f64>,
}

/// `[network]`: the network between the nodes, and how the loop copes with it.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct NetworkSection {
    /// The emulated link.
    #[command(flatten)]
    pub network: NetworkArgs,
    /// The oldest torque the plant applies (periods)
    #[arg(long, value_name = "PERIODS")]
    pub max_age: Option<u64>,
    /// Prediction over the delay.
    #[command(flatten)]
    pub predict: tilting_controller::predict::PredictArgs,
    /// An extra state at each mode transition
    #[arg(long)]
    pub sample_on_event: bool,
}

/// `[sensors]`: what the plant measures and the controller estimates.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct SensorsSection {
    /// Sensors and actuator.
    #[command(flatten)]
    pub imperfect: ImperfectArgs,
    /// The controller's estimator.
    #[command(flatten)]
    pub estimator: EstimatorArgs,
}

/// Highest `SCHED_FIFO` priority of `realtime`.
const MAX_RT: i64 = 99;

/// `[deploy]`: how `live` runs the robot.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct DeploySection {
    /// The robot's name in its keys (`--robot`)
    #[arg(long = "robot", value_name = "NAME")]
    pub name: Option<String>,
    /// Control rate of the plant (Hz)
    #[arg(long, value_name = "HZ", allow_negative_numbers = true)]
    pub rate: Option<f64>,
    /// SCHED_FIFO priority of the plant and the controller (1-99)
    #[arg(long, value_name = "1-99", allow_negative_numbers = true)]
    pub realtime: Option<i64>,
    /// Mutual TLS and access control
    #[arg(long)]
    pub secure: bool,
    /// The certificates of `tilting certs`
    #[arg(long, value_name = "DIR")]
    pub certs: Option<PathBuf>,
    /// The output directory
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// CSV files beside the recording
    #[arg(long)]
    pub csv: bool,
    /// The plant's port on 127.0.0.1
    #[arg(long, value_name = "PORT")]
    pub port: Option<u16>,
    /// A command in place of `tilting-plant`
    #[arg(long, value_name = "CMD")]
    pub plant_cmd: Option<String>,
    /// Serve the run to Foxglove on this address
    #[arg(long, value_name = "ADDR")]
    pub foxglove: Option<std::net::SocketAddr>,
    /// The plant as a ROS 2 node too: zenoh, dds or both
    #[arg(long, value_name = "zenoh|dds|both", value_parser = ["zenoh", "dds", "both"])]
    pub ros2: Option<String>,
    /// The ROS 2 domain (0-232)
    #[arg(long, value_name = "0-232", value_parser = clap::value_parser!(u32).range(0..=232))]
    pub ros_domain: Option<u32>,
}

/// The flags of one section (`None` for a parameter section).
pub fn section_command(section: &str) -> Option<clap::Command> {
    let name = SECTIONS.iter().find(|&&s| s == section)?;
    let c = clap::Command::new(*name).no_binary_name(true);
    Some(match section {
        "law" => LawSection::augment_args(c),
        "run" => RunSection::augment_args(c),
        "network" => NetworkSection::augment_args(c),
        "sensors" => SensorsSection::augment_args(c),
        "deploy" => DeploySection::augment_args(c),
        _ => return None,
    })
}

/// The keys of a section, as the file spells them.
pub fn section_keys(section: &str) -> Vec<String> {
    let Some(cmd) = section_command(section) else {
        return Vec::new();
    };
    cmd.get_arguments()
        .filter_map(|a| a.get_long())
        .map(|l| match (section, l) {
            ("deploy", "robot") => "name".to_owned(),
            _ => l.replace('-', "_"),
        })
        .collect()
}

/// The section and key a flag (its long name) sets, if a robot file has it: `--kd` is
/// `law.kd`, `--robot` is `deploy.name`, `--params` is `[robot]`, `--plant-params` `[plant]`.
pub fn key_of_flag(long: &str) -> Option<(&'static str, String)> {
    match long {
        "params" => return Some(("robot", "params".into())),
        "plant-params" => return Some(("plant", "params".into())),
        _ => {}
    }
    SECTIONS.iter().find_map(|&s| {
        let cmd = section_command(s)?;
        let has = cmd.get_arguments().any(|a| a.get_long() == Some(long));
        has.then(|| {
            let key = match (s, long) {
                ("deploy", "robot") => "name".to_owned(),
                _ => long.replace('-', "_"),
            };
            (s, key)
        })
    })
}

/// Keys whose values are arrays of numbers in the file (a flag's `A,B,...`).
const ARRAY_KEYS: [&str; 2] = ["x0", "orbit_start"];

/// A flag's text as the TOML value of `key`: an integer, a float, a boolean, an array of
/// numbers for `x0` and `orbit_start`, else a string (so is an integer above `i64::MAX`).
pub fn value_of_text(key: &str, text: &str) -> toml::Value {
    if ARRAY_KEYS.contains(&key) {
        let nums: Option<Vec<toml::Value>> = text
            .split(',')
            .map(|p| p.trim().parse::<f64>().ok().map(toml::Value::Float))
            .collect();
        if let Some(v) = nums {
            return toml::Value::Array(v);
        }
    }
    if let Ok(i) = text.parse::<i64>() {
        return toml::Value::Integer(i);
    }
    if text.parse::<u64>().is_ok() {
        // Above a TOML integer (a `--seed` up to 2^64 - 1): as the text, which the flag reads,
        // not as a float that would round it.
        return toml::Value::String(text.to_owned());
    }
    if let Ok(f) = text.parse::<f64>() {
        if f.is_finite() {
            return toml::Value::Float(f);
        }
    }
    match text {
        "true" => toml::Value::Boolean(true),
        "false" => toml::Value::Boolean(false),
        _ => toml::Value::String(text.to_owned()),
    }
}

/// A robot file: its path and its checked TOML document.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotFile {
    /// Where it was read from (paths in it are relative to its directory).
    pub path: PathBuf,
    /// The document: the tables of [`SECTIONS`].
    pub doc: toml::Table,
}

impl RobotFile {
    /// Reads and checks a robot file.
    pub fn load(path: &Path) -> Result<Self, String> {
        let doc = rf::read_doc(path)?;
        let f = Self {
            path: path.to_path_buf(),
            doc,
        };
        f.check()?;
        Ok(f)
    }

    /// An empty robot file (every value its default) that would live at `path`.
    pub fn empty(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
            doc: toml::Table::new(),
        }
    }

    /// Checks every section and key: unknown ones are refused, and every value is checked by
    /// its flag's parser and by the library's own checks; an error names `section.key` and the
    /// allowed values.
    pub fn check(&self) -> Result<(), String> {
        let file = self.path.display();
        for (name, v) in &self.doc {
            if !SECTIONS.contains(&name.as_str()) {
                return Err(format!(
                    "unknown section `[{name}]` in the robot file {file}: allowed {}",
                    SECTIONS.join(", ")
                ));
            }
            let Some(table) = v.as_table() else {
                return Err(format!(
                    "`{name}` in the robot file {file} must be a table ([{name}])"
                ));
            };
            if PARAMS_SECTIONS.contains(&name.as_str()) {
                rf::params_of_table(table, name, &self.path).map_err(|e| e.to_string())?;
                continue;
            }
            let keys = section_keys(name);
            if let Some(k) = table.keys().find(|k| !keys.contains(k)) {
                return Err(format!(
                    "unknown key `{name}.{k}` in the robot file {file}: [{name}] takes {}",
                    keys.join(", ")
                ));
            }
        }
        self.check_values()
    }

    /// The values: each section parsed by its flags' parsers, then the library's checks.
    fn check_values(&self) -> Result<(), String> {
        let keyed = |section: &str, msg: String| name_key(section, msg, &self.path);
        if let Some(m) = self.section_matches("law")? {
            let s = LawSection::from_arg_matches(&m).map_err(|e| e.to_string())?;
            s.law
                .over(LawSpec::default())
                .validate()
                .map_err(|e| keyed("law", e.to_string()))?;
            if let Some([b, bd]) = s.law.orbit_start {
                tilting_controller::law::check_orbit_start([b, bd])
                    .map_err(|e| keyed("law", e.to_string()))?;
            }
        }
        if let Some(m) = self.section_matches("run")? {
            let s = RunSection::from_arg_matches(&m).map_err(|e| e.to_string())?;
            let layer = crate::ScenarioFile {
                x0: s.x0,
                mode: s.mode,
                duration: s.duration,
                control_period: s.control_period,
                rtol: s.rtol,
                ..Default::default()
            };
            let sc = crate::Scenario::resolve(&[&layer]);
            if s.x0.is_some() || s.mode.is_some() || s.duration.is_some() || s.rtol.is_some() {
                sc.validate().map_err(|e| keyed("run", e.to_string()))?;
            } else if let Some(p) = s.control_period {
                let lone = crate::ScenarioFile {
                    control_period: Some(p),
                    ..Default::default()
                };
                crate::Scenario::resolve(&[&lone])
                    .validate()
                    .map_err(|e| keyed("run", e.to_string()))?;
            }
        }
        let net = match self.section_matches("network")? {
            Some(m) => NetworkSection::from_arg_matches(&m).map_err(|e| e.to_string())?,
            None => NetworkSection::default(),
        };
        let max_age = net.max_age.unwrap_or(10);
        if max_age > MAX_AGE {
            return Err(keyed(
                "network",
                format!("invalid `--max-age` = {max_age}: allowed 0 to {MAX_AGE} periods"),
            ));
        }
        net.network
            .impairment(max_age)
            .map_err(|e| keyed("network", e.to_string()))?;
        if let Some(m) = self.section_matches("sensors")? {
            let s = SensorsSection::from_arg_matches(&m).map_err(|e| e.to_string())?;
            s.imperfect
                .imperfections(net.network.seed)
                .map_err(|e| keyed("sensors", e.to_string()))?;
        }
        if let Some(m) = self.section_matches("deploy")? {
            let s = DeploySection::from_arg_matches(&m).map_err(|e| e.to_string())?;
            s.check().map_err(|e| keyed("deploy", e))?;
        }
        Ok(())
    }

    /// A section's keys parsed by its flags (as defaults, each checked by its flag's parser);
    /// `None` when the file has no such section.
    fn section_matches(&self, section: &str) -> Result<Option<ArgMatches>, String> {
        if !self.doc.contains_key(section) {
            return Ok(None);
        }
        let defaults = rf::flag_defaults(&self.doc, &self.path, &[section])?;
        let cmd = section_command(section).expect("a flag section");
        let cmd = rf::apply(cmd, &defaults, &self.path, true)?;
        cmd.try_get_matches_from(Vec::<String>::new())
            .map(Some)
            .map_err(|e| e.to_string())
    }

    /// The `[law]` keys over the paper's law ([`LawSpec::default`]); `None` without a `[law]`
    /// table. A live run's directory holds the law it ran this way ([`Self::set_law`]).
    pub fn law(&self) -> Result<Option<LawSpec>, String> {
        let Some(m) = self.section_matches("law")? else {
            return Ok(None);
        };
        let s = LawSection::from_arg_matches(&m).map_err(|e| e.to_string())?;
        Ok(Some(s.law.over(LawSpec::default())))
    }

    /// The flag defaults of every section ([`rf::flag_defaults`]).
    pub fn defaults(&self) -> Result<Vec<FlagDefault>, String> {
        rf::flag_defaults(&self.doc, &self.path, &SECTIONS)
    }

    /// `cmd` with the file's keys as the defaults of its flags of the same names (a key whose
    /// flag `cmd` lacks is left out: the file describes more than one command needs).
    pub fn apply(&self, cmd: clap::Command) -> Result<clap::Command, String> {
        rf::apply(cmd, &self.defaults()?, &self.path, false)
    }

    /// Sets one key (a flag given on the command line over the file).
    pub fn set(&mut self, section: &str, key: &str, value: toml::Value) {
        let t = self
            .doc
            .entry(section.to_owned())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let Some(t) = t.as_table_mut() {
            if PARAMS_SECTIONS.contains(&section) {
                t.clear();
            }
            t.insert(key.to_owned(), value);
        }
    }

    /// Sets `[law]` to the resolved law `law`, every key given (a torque limit of 0 for none;
    /// `law` only when not the paper's), through the serde form the file's `[law]` keys share
    /// with [`LawArgs`]; `from_orbit` goes (its E_av is now the `energy_avg` key). Read back
    /// by [`LawSection`]'s flags, `LawArgs::over(anything)` is `law`, bit for bit.
    pub fn set_law(&mut self, law: &LawSpec) -> Result<(), String> {
        let keys = toml::Table::try_from(LawArgs::from(*law))
            .map_err(|e| format!("the law {law} as TOML: {e}"))?;
        if let Some(t) = self.doc.get_mut("law").and_then(|v| v.as_table_mut()) {
            t.remove("from_orbit");
        }
        for (key, value) in keys {
            self.set("law", &key, value);
        }
        Ok(())
    }

    /// Sets a parameter section to these parameters, inline.
    pub fn set_params(&mut self, section: &str, params: &Params) {
        let table: toml::Table =
            toml::from_str(&params.to_toml_string()).expect("parameters serialize as TOML");
        self.doc
            .insert(section.to_owned(), toml::Value::Table(table));
    }

    /// The flags given on the command line (`matches`, the command's own) over the file: each
    /// flag a robot file has a key for replaces that key. Paths become absolute; `--params`
    /// and `--plant-params` put the file's parameters inline.
    pub fn override_with(
        &mut self,
        matches: &ArgMatches,
        cmd: &clap::Command,
    ) -> Result<(), String> {
        for arg in cmd.get_arguments() {
            let id = arg.get_id().as_str();
            if matches.value_source(id) != Some(clap::parser::ValueSource::CommandLine) {
                continue;
            }
            let Some(long) = arg.get_long() else { continue };
            let Some((section, key)) = key_of_flag(long) else {
                continue;
            };
            let text = if arg.get_action().takes_values() {
                let Some(raw) = matches.get_raw(id).and_then(|mut r| r.next_back()) else {
                    continue;
                };
                raw.to_string_lossy().into_owned()
            } else {
                matches.get_flag(id).to_string()
            };
            if key == "params" {
                let p = Params::from_toml_file(Path::new(&text))
                    .map_err(|e| format!("--{long} {text}: {e}"))?;
                self.set_params(section, &p);
                continue;
            }
            let value = if rf::PATH_KEYS.contains(&(section, key.as_str())) {
                let p = PathBuf::from(&text);
                toml::Value::String(std::path::absolute(&p).unwrap_or(p).display().to_string())
            } else {
                value_of_text(&key, &text)
            };
            self.set(section, &key, value);
        }
        Ok(())
    }

    /// The document as TOML, its sections in the order of [`SECTIONS`].
    pub fn to_toml_string(&self) -> String {
        let mut out = String::new();
        for s in SECTIONS {
            let Some(t) = self.doc.get(s).and_then(|v| v.as_table()) else {
                continue;
            };
            if !out.is_empty() {
                out.push('\n');
            }
            let mut one = toml::Table::new();
            one.insert(s.to_owned(), toml::Value::Table(t.clone()));
            out.push_str(&toml::to_string(&one).expect("a TOML table serializes"));
        }
        out
    }
}

/// Largest `max_age` (periods), as the plant allows.
pub const MAX_AGE: u64 = 1000;

impl DeploySection {
    /// The checks of `live` on these values.
    fn check(&self) -> Result<(), String> {
        if let Some(rate) = self.rate {
            let (lo, hi) = (1.0 / 10.0, 1.0 / tilting_proto::plausible::MIN_PERIOD);
            if !(rate.is_finite() && (lo..=hi).contains(&rate)) {
                return Err(format!(
                    "invalid `--rate` = {rate}: allowed {lo} to {hi} Hz"
                ));
            }
        }
        if let Some(p) = self.realtime.filter(|p| !(1..=MAX_RT).contains(p)) {
            return Err(format!("invalid `--realtime` = {p}: allowed 1 to {MAX_RT}"));
        }
        if self.port == Some(0) {
            return Err(
                "invalid `--port` = 0: allowed 1 to 65535 (omit it for a free port)".into(),
            );
        }
        if let Some(n) = &self.name {
            tilting_proto::Keys::new(n).map_err(|e| format!("invalid `--robot` = {n}: {e}"))?;
        }
        if self.plant_cmd.as_ref().is_some_and(|c| c.trim().is_empty()) {
            return Err("invalid `--plant-cmd` = \"\": give a command".into());
        }
        Ok(())
    }
}

/// A library error about a section's values, with the key it is about: the first key of
/// `section` whose flag (`--max-age`) or name (`` `kd` ``) the message mentions.
fn name_key(section: &str, msg: String, file: &Path) -> String {
    let keys = section_keys(section);
    let pos = |k: &String| {
        let flag = format!("--{}", rf::flag_of(section, k));
        let flag_at = msg
            .find(&format!("`{flag}`"))
            .or_else(|| msg.find(&format!("{flag} ")));
        let name_at = msg.find(&format!("`{k}`"));
        flag_at.into_iter().chain(name_at).min()
    };
    let found = keys
        .iter()
        .filter_map(|k| pos(k).map(|p| (p, k)))
        .min_by_key(|(p, k)| (*p, std::cmp::Reverse(k.len())));
    match found {
        Some((_, k)) => format!(
            "invalid `{section}.{k}` in the robot file {}: {msg}",
            file.display()
        ),
        None => format!(
            "invalid [{section}] in the robot file {}: {msg}",
            file.display()
        ),
    }
}

/// The flags of every section as one command (`tilting config`'s), each flag once.
pub fn all_flags(cmd: clap::Command) -> clap::Command {
    let mut cmd = cmd;
    for s in SECTIONS {
        if let Some(sc) = section_command(s) {
            for a in sc.get_arguments() {
                cmd = cmd.arg(a.clone());
            }
        }
    }
    cmd
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> Result<RobotFile, String> {
        let doc = toml::from_str(text).map_err(|e: toml::de::Error| e.to_string())?;
        let f = RobotFile {
            path: PathBuf::from("robot.toml"),
            doc,
        };
        f.check()?;
        Ok(f)
    }

    #[test]
    fn a_robot_file_is_checked_naming_the_key() {
        file(
            "[robot]\nm_f = 0.85\nimpact = \"physical\"\nrestitution = 0.2\ni_f = 0.02\n\
             [law]\nkp = 100\nkd = 14.14\nk = 500\nreference = \"hold\"\n\
             [run]\nduration = 20\n[network]\ndelay = 0.025\npredict = 0.05\nmax_age = 60\n\
             [sensors]\nmeasure = \"angles\"\nnoise_alpha = 0.001\nencoder_counts = 4096\n\
             [deploy]\nname = \"r1\"\nrate = 1000\nrealtime = 20\nsecure = true\n",
        )
        .unwrap();
        for (text, want) in [
            ("[law]\nkdd = 3\n", "unknown key `law.kdd`"),
            ("[lw]\nkd = 3\n", "unknown section `[lw]`"),
            ("[law]\nkd = -3\n", "`law.kd`"),
            ("[law]\nreference = \"circle\"\n", "`law.reference`"),
            ("[robot]\nm_f = -1\n", "`robot.m_f` = -1"),
            ("[robot]\nmf = 1\n", "unknown field `mf`"),
            ("[network]\ndelay = -1\n", "`network.delay`"),
            ("[network]\nmax_age = 5000\n", "`network.max_age`"),
            ("[network]\nstate_loss = 2\n", "`network.state_loss`"),
            ("[sensors]\nnoise_alpha = -1\n", "`sensors.noise_alpha`"),
            ("[sensors]\nmeasure = \"all\"\n", "`sensors.measure`"),
            ("[run]\nduration = -2\n", "`run.duration`"),
            ("[deploy]\nrate = 1e9\n", "`deploy.rate`"),
            ("[deploy]\nrealtime = 120\n", "`deploy.realtime`"),
            ("[deploy]\nsecure = 3\n", "`deploy.secure`"),
            ("law = 3\n", "must be a table"),
        ] {
            let e = file(text).unwrap_err();
            assert!(e.contains(want), "{text}: {e}");
        }
        // The range is in the message too.
        let e = file("[law]\nkd = -3\n").unwrap_err();
        assert!(e.contains("-3") && e.contains("must be"), "{e}");
    }

    #[test]
    fn flags_and_keys_name_each_other() {
        assert_eq!(key_of_flag("kd"), Some(("law", "kd".into())));
        assert_eq!(key_of_flag("max-age"), Some(("network", "max_age".into())));
        assert_eq!(key_of_flag("robot"), Some(("deploy", "name".into())));
        assert_eq!(
            key_of_flag("noise-alpha"),
            Some(("sensors", "noise_alpha".into()))
        );
        assert_eq!(key_of_flag("json"), None);
        // Every flag of a section is in one section only.
        let mut seen = std::collections::BTreeSet::new();
        for s in SECTIONS {
            for k in section_keys(s) {
                assert!(seen.insert(k.clone()), "{s}.{k} twice");
            }
        }
        assert_eq!(
            value_of_text("x0", "0,1.5,0,0").to_string(),
            "[0.0, 1.5, 0.0, 0.0]"
        );
        assert_eq!(value_of_text("kd", "14.14"), toml::Value::Float(14.14));
        assert_eq!(
            value_of_text("loss_burst", "0.1,0.5").as_str(),
            Some("0.1,0.5")
        );
    }

    /// A resolved law written into `[law]` ([`RobotFile::set_law`]), printed, read back and
    /// checked, is the same law bit for bit through the flags' parsers, over a base that
    /// differs in every setting (so every setting comes from the file); a `from_orbit` it
    /// replaces is gone. Values that print long (1/3, 0.1 + 0.2) test the text's round trip.
    #[test]
    fn a_law_written_into_the_file_reads_back_the_same() {
        use tilting_controller::{LawKind, Trajectory};
        let sin = Trajectory::Sinusoid {
            amplitude: -0.33,
            omega: 1.0 / 3.0,
        };
        let specs = [
            LawSpec::default(),
            LawSpec::without_adaptation(),
            LawSpec {
                law: LawKind::ComputedTorque,
                kp: 60.0,
                kd: 0.1 + 0.2,
                k: 2500.0,
                energy_avg: 19.963439703027 * 3.0,
                torque_limit: Some(5.5),
                reference: sin,
                orbit_peak: None,
                orbit_start: None,
                orbit_steepness: None,
            },
            LawSpec {
                orbit_peak: Some(0.0413),
                ..LawSpec::default()
            },
            LawSpec {
                orbit_peak: Some(0.018),
                orbit_start: Some([1.5736, -0.1 / 3.0]),
                orbit_steepness: Some(-39.1),
                ..LawSpec::default()
            },
        ];
        let other = LawSpec {
            law: LawKind::ComputedTorque,
            kp: 1.0,
            kd: 2.0,
            k: 3.0,
            energy_avg: 4.0,
            torque_limit: Some(7.0),
            reference: Trajectory::Sinusoid {
                amplitude: 0.1,
                omega: 9.0,
            },
            orbit_peak: None,
            orbit_start: None,
            orbit_steepness: None,
        };
        for spec in specs {
            let mut f = file("[law]\nfrom_orbit = true\nkd = 3\n[deploy]\nrate = 500\n").unwrap();
            f.set_law(&spec).unwrap();
            let text = f.to_toml_string();
            let again = file(&text).unwrap();
            assert_eq!(again.doc, f.doc, "{text}");
            let m = again.section_matches("law").unwrap().unwrap();
            let s = LawSection::from_arg_matches(&m).unwrap();
            assert!(!s.from_orbit, "{text}");
            assert_eq!(s.law.over(other), spec, "{text}");
        }
    }

    /// The link's and the sensors' flags given to `tilting live`, merged into a robot file
    /// ([`RobotFile::override_with`]), printed and read back by a plant
    /// ([`rf::parse_node`] with `--robot-file`), are the flags' values bit for bit: every
    /// field set, with long-printing numbers and a seed above `i64::MAX` (no TOML integer).
    #[test]
    fn the_link_and_the_sensors_round_trip_through_the_file() {
        #[derive(clap::Parser)]
        struct Node {
            #[arg(long)]
            robot_file: Option<PathBuf>,
            #[command(flatten)]
            network: NetworkArgs,
            #[command(flatten)]
            imperfect: ImperfectArgs,
        }
        let flags = [
            "--delay=0.002",
            "--state-delay=0.1",
            "--torque-delay=0.30000000000000004",
            "--jitter=uniform:0.004",
            "--state-jitter=normal:0.3333333333333333",
            "--torque-jitter=exp:0.0005",
            "--loss=0.05",
            "--state-loss=0.5",
            "--torque-loss=0.125",
            "--loss-burst=0.01,0.25",
            "--state-loss-burst=0,1",
            "--torque-loss-burst=0.0000001,0.7",
            "--seed=18446744073709551615",
            "--noise-alpha=0.001",
            "--noise-beta=0.3333333333333333",
            "--noise-alpha-dot=0.25",
            "--noise-beta-dot=5e-300",
            "--encoder-counts=4096",
            "--torque-saturation=11.5",
            "--torque-lag=0.30000000000000004",
            "--mass-error=-0.1",
            "--measure=angles",
        ];
        let argv: Vec<&str> = std::iter::once("node").chain(flags).collect();
        let cmd = <Node as clap::CommandFactory>::command();
        let m = cmd.clone().try_get_matches_from(&argv).unwrap();
        let given = Node::from_arg_matches(&m).unwrap();
        assert_eq!(given.network.seed, u64::MAX);
        let dir = std::env::temp_dir().join(format!("tilting-robot-net-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("robot.toml");
        let mut f = RobotFile::empty(&path);
        f.override_with(&m, &cmd).unwrap();
        std::fs::write(&path, f.to_toml_string()).unwrap();
        let again = RobotFile::load(&path).unwrap();
        assert_eq!(again.doc, f.doc);
        let file_argv: Vec<std::ffi::OsString> = ["node", "--robot-file", path.to_str().unwrap()]
            .iter()
            .map(Into::into)
            .collect();
        let read: Node = rf::parse_node(&file_argv).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(read.network, given.network);
        assert_eq!(read.imperfect, given.imperfect);
        assert_ne!(read.imperfect, ImperfectArgs::default());
    }

    #[test]
    fn printed_and_read_back_is_the_same() {
        let f = file(
            "[deploy]\nrate = 500\n[law]\nkd = 12.5\norbit_start = [1.2, 0.5]\n[robot]\nl = 1.5\n",
        )
        .unwrap();
        let text = f.to_toml_string();
        assert!(
            text.find("[robot]").unwrap() < text.find("[law]").unwrap(),
            "{text}"
        );
        assert!(
            text.find("[law]").unwrap() < text.find("[deploy]").unwrap(),
            "{text}"
        );
        let again = file(&text).unwrap();
        assert_eq!(again.doc, f.doc);
    }
}
