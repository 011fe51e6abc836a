//! The robot file at the front door (`tilting_sim::robot` is the format): a command that takes
//! one (`tilting live ROBOT.toml`, `simulate`, `plan orbit`, `plan reach`, `config`) is parsed
//! twice, the second time with the file's keys as the defaults of its flags, so a flag given on
//! the command line overrides a single key and every flag works as before without a file. The
//! merged file (the file with the flags given over it) is kept for the command: `tilting config`
//! prints it and `tilting live` writes it into its run directory (`robot.toml`).

use crate::CommandError;
use clap::{ArgMatches, Command};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use tilting_sim::robot::RobotFile;

/// The id of the positional robot file of a command that takes one.
pub const ROBOT_FILE_ID: &str = "robot_file";

/// The merged robot file of this invocation (set by [`parse`]).
static MERGED: OnceLock<RobotFile> = OnceLock::new();

/// The robot file this invocation was given, with the flags given over it; an empty file (every
/// value its default) with the flags when none was given, and `None` before [`parse`].
pub fn merged() -> Option<&'static RobotFile> {
    MERGED.get()
}

/// The chain of subcommand names down to the leaf, and the leaf's matches.
fn leaf(m: &ArgMatches) -> (Vec<String>, &ArgMatches) {
    let mut names = Vec::new();
    let mut cur = m;
    while let Some((name, sub)) = cur.subcommand() {
        names.push(name.to_owned());
        cur = sub;
    }
    (names, cur)
}

/// `cmd` with `f` applied to its subcommand at `path`.
fn with_leaf(
    cmd: Command,
    path: &[String],
    f: &dyn Fn(Command) -> Result<Command, String>,
) -> Result<Command, String> {
    let Some((head, rest)) = path.split_first() else {
        return f(cmd);
    };
    let Some(sub) = cmd.find_subcommand(head).cloned() else {
        return Ok(cmd);
    };
    let sub = with_leaf(sub, rest, f)?;
    Ok(cmd.mut_subcommand(head, move |_| sub))
}

/// The leaf command at `path`.
fn leaf_command(cmd: &Command, path: &[String]) -> Option<Command> {
    let mut cur = cmd.clone();
    for p in path {
        cur = cur.find_subcommand(p)?.clone();
    }
    Some(cur)
}

/// The robot file a leaf's matches name, if it takes one and one is given.
fn robot_file_of(m: &ArgMatches) -> Option<PathBuf> {
    m.try_get_one::<PathBuf>(ROBOT_FILE_ID)
        .ok()
        .flatten()
        .cloned()
}

/// Parses the command line as [`clap::Parser::parse`] does, with the robot file's keys as the
/// defaults of the flags when the command is given one; a bad file is refused with exit code 2,
/// naming the key.
pub fn parse<C: clap::Parser>() -> C {
    let argv: Vec<std::ffi::OsString> = std::env::args_os().collect();
    match parse_from::<C>(&argv) {
        Ok(c) => c,
        Err(Failure::Clap(e)) => e.exit(),
        Err(Failure::File(e)) => {
            eprintln!("error: {e}");
            std::process::exit(2)
        }
    }
}

/// Why [`parse_from`] failed.
#[derive(Debug)]
pub enum Failure {
    /// The flags (clap's message and exit code).
    Clap(clap::Error),
    /// The robot file.
    File(String),
}

/// [`parse`] of `argv` (its first item the program's name).
pub fn parse_from<C: clap::Parser>(argv: &[std::ffi::OsString]) -> Result<C, Failure> {
    let base = C::command();
    let first = base
        .clone()
        .try_get_matches_from(argv)
        .map_err(Failure::Clap)?;
    let (path, leaf_m) = leaf(&first);
    let file = robot_file_of(leaf_m);
    let (cmd, robot) = match &file {
        None => (base, RobotFile::empty(Path::new("robot.toml"))),
        Some(f) => {
            let robot = RobotFile::load(f).map_err(Failure::File)?;
            let cmd = with_leaf(base, &path, &|c| robot.apply(c)).map_err(Failure::File)?;
            (cmd, robot)
        }
    };
    let matches = cmd
        .clone()
        .try_get_matches_from(argv)
        .map_err(Failure::Clap)?;
    let (_, leaf_m) = leaf(&matches);
    let mut merged = robot;
    if let Some(leaf_cmd) = leaf_command(&cmd, &path) {
        merged
            .override_with(leaf_m, &leaf_cmd)
            .map_err(Failure::File)?;
    }
    let _ = MERGED.set(merged);
    C::from_arg_matches(&matches).map_err(Failure::Clap)
}

/// Flags of `tilting config`.
#[derive(Debug, Clone, clap::Args)]
pub struct ConfigArgs {
    /// The robot file (TOML; docs/guide/robot-file.md) [default: none, every key its default]
    #[arg(value_name = "ROBOT.toml")]
    pub robot_file: Option<PathBuf>,
    /// The robot's parameters from this file, inline in [robot]
    #[arg(long, value_name = "FILE.toml")]
    pub params: Option<PathBuf>,
    /// The simulated robot's parameters from this file, inline in [plant]
    #[arg(long, value_name = "FILE.toml")]
    pub plant_params: Option<PathBuf>,
    /// `[law]`.
    #[command(flatten)]
    pub law: tilting_sim::robot::LawSection,
    /// `[run]`.
    #[command(flatten)]
    pub run: tilting_sim::robot::RunSection,
    /// `[network]`.
    #[command(flatten)]
    pub network: tilting_sim::robot::NetworkSection,
    /// `[sensors]`.
    #[command(flatten)]
    pub sensors: tilting_sim::robot::SensorsSection,
    /// `[deploy]`.
    #[command(flatten)]
    pub deploy: tilting_sim::robot::DeploySection,
    /// Write the merged file here instead of printing it (not `--out`: that is `[deploy]
    /// out`, the run directory, a key of the file)
    #[arg(long, value_name = "FILE.toml")]
    pub write: Option<PathBuf>,
}

/// `tilting config`: the robot file with the flags given over it, checked, as TOML (on stdout,
/// or into `--write`).
pub fn config(args: &ConfigArgs) -> Result<(), CommandError> {
    let merged = merged().cloned().ok_or_else(|| {
        CommandError::Failed(anyhow::anyhow!("config: not parsed by robot::parse"))
    })?;
    merged
        .check()
        .map_err(|e| CommandError::Usage(anyhow::anyhow!(e)))?;
    let text = merged.to_toml_string();
    match &args.write {
        Some(out) => std::fs::write(out, &text).map_err(|e| {
            CommandError::Failed(anyhow::anyhow!("cannot write {}: {e}", out.display()))
        }),
        None => crate::commands::print_stdout(&text),
    }
}

/// Writes `params` into the robot file `out` as its `[robot]` table, keeping its other tables;
/// `Ok(false)` when `out` is not a robot file (a parameter file or none: the caller writes a
/// parameter file, as before).
pub fn write_params_into(out: &Path, params: &tilting_plant::Params) -> Result<bool, String> {
    if !out.is_file() {
        return Ok(false);
    }
    let Ok(doc) = tilting_plant::robot_file::read_doc(out) else {
        return Ok(false);
    };
    if !tilting_plant::robot_file::is_robot_file(&doc) {
        return Ok(false);
    }
    let mut robot = RobotFile {
        path: out.to_path_buf(),
        doc,
    };
    robot.check()?;
    robot.set_params("robot", params);
    std::fs::write(out, robot.to_toml_string())
        .map_err(|e| format!("cannot write {}: {e}", out.display()))?;
    Ok(true)
}

/// The builder's prior of a robot file `out` (its `[prior]` table), if it is one and has it.
pub fn prior_of(out: &Path) -> Option<PathBuf> {
    let doc = tilting_plant::robot_file::read_doc(out).ok()?;
    doc.get("prior")?.as_table()?;
    Some(PathBuf::from(format!("{}#prior", out.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, clap::Parser)]
    struct Cli {
        #[command(subcommand)]
        cmd: Sub,
    }

    #[derive(Debug, clap::Subcommand)]
    enum Sub {
        Live(Box<tilting_live::LiveArgs>),
    }

    fn live(argv: &[&str]) -> Result<tilting_live::LiveArgs, Failure> {
        let argv: Vec<std::ffi::OsString> = std::iter::once("tilting")
            .chain(argv.iter().copied())
            .map(Into::into)
            .collect();
        parse_from::<Cli>(&argv).map(|c| match c.cmd {
            Sub::Live(a) => *a,
        })
    }

    #[test]
    fn a_flag_overrides_a_key() {
        let dir = std::env::temp_dir().join(format!("tilting-robot-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("r.toml");
        std::fs::write(
            &f,
            "[law]\nkd = 12\nk = 300\nenergy_avg = 19.5\n[network]\ndelay = 0.002\n\
             [deploy]\nrate = 500\nname = \"r1\"\nsecure = true\n[run]\nduration = 3\n",
        )
        .unwrap();
        let p = f.to_str().unwrap();
        let a = live(&["live", p]).unwrap();
        assert_eq!(a.law.law.kd, Some(12.0));
        assert_eq!(a.law.law.k, Some(300.0));
        assert_eq!(a.network.delay, Some(0.002));
        assert_eq!((a.rate, a.duration), (500.0, 3.0));
        assert_eq!(a.robot, "r1");
        assert!(a.secure);
        let b = live(&["live", p, "--kd", "13.5", "--rate", "250"]).unwrap();
        assert_eq!(
            (b.law.law.kd, b.law.law.k, b.rate),
            (Some(13.5), Some(300.0), 250.0)
        );
        // Without a file, the flags are as before.
        let c = live(&["live", "--kd", "13.5"]).unwrap();
        assert_eq!(
            (c.law.law.kd, c.law.law.k, c.rate),
            (Some(13.5), None, 1000.0)
        );
        // A bad key is refused naming it.
        std::fs::write(&f, "[law]\nkd = -3\n").unwrap();
        match live(&["live", p]) {
            Err(Failure::File(e)) => assert!(e.contains("`law.kd`"), "{e}"),
            other => panic!("{other:?}"),
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
