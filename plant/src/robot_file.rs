//! The robot file, as far as the model and the nodes need it: a TOML file of sections
//! (`[robot]`, `[plant]`, `[prior]`, `[law]`, `[run]`, `[network]`, `[sensors]`, `[deploy]`) whose
//! keys are the flags of the commands and nodes, spelled with `_` for `-` (`[law] kd = 14.14` is
//! `--kd 14.14`). The full format and its checks are `tilting_sim::robot`; this module holds
//! what the nodes below it share:
//!
//! - a parameter table of a robot file is a parameter file: [`params_from_file`] reads
//!   `FILE.toml` (its `[robot]` table when it is a robot file) and `FILE.toml#plant` (the table
//!   `plant`); a table may name a parameter file instead of holding the keys (`params = "x.toml"`,
//!   relative to the robot file);
//! - (feature `clap`) [`apply`]: the keys of some sections become the defaults of the flags of
//!   the same name, so a flag given on the command line overrides a single key, and a value is
//!   parsed by the flag's own parser (a file and the same flags give the same values, bit for
//!   bit).

use crate::params::{read_text, ConfigError};
use crate::Params;
use std::path::{Path, PathBuf};

/// The sections of a robot file that hold parameters (as a parameter file does).
pub const PARAMS_SECTIONS: [&str; 3] = ["robot", "plant", "prior"];

/// The section a parameter file's `--params` reads from a robot file.
pub const DEFAULT_PARAMS_SECTION: &str = "robot";

/// Splits `FILE.toml#table` into the file and the table; a path without `#`, or one that
/// exists as written, is the file itself.
pub fn split_table(path: &Path) -> (PathBuf, Option<String>) {
    let text = path.to_string_lossy();
    match text.rsplit_once('#') {
        Some((file, table))
            if !path.exists() && !table.is_empty() && !table.contains(['/', '\\']) =>
        {
            (PathBuf::from(file), Some(table.to_owned()))
        }
        _ => (path.to_path_buf(), None),
    }
}

/// Is this TOML document a robot file (it has a table named like one of its sections)? A
/// parameter file has no tables.
pub fn is_robot_file(doc: &toml::Table) -> bool {
    doc.values().any(|v| v.is_table())
}

/// The parameters in `path`: a parameter file; a robot file's `[robot]` table; or, as
/// `FILE.toml#table`, that table of a robot file. A table `{ params = "x.toml" }` names a
/// parameter file, relative to the robot file. Missing keys keep the paper's values; the result
/// is validated.
pub fn params_from_file(path: &Path) -> Result<Params, ConfigError> {
    let (file, table) = split_table(path);
    let text = read_text(&file)?;
    let parse_err = |message: String| ConfigError::Parse {
        what: path.display().to_string(),
        message,
    };
    let doc: toml::Table = toml::from_str(&text).map_err(|e| parse_err(e.to_string()))?;
    if table.is_none() && !is_robot_file(&doc) {
        return Params::from_toml_str(&text).map_err(|e| match e {
            ConfigError::Parse { message, .. } => parse_err(message),
            other => other,
        });
    }
    let name = table.as_deref().unwrap_or(DEFAULT_PARAMS_SECTION);
    let Some(section) = doc.get(name) else {
        if table.is_none() {
            // A robot file without `[robot]`: the paper's robot.
            return Ok(Params::default());
        }
        return Err(parse_err(format!("the robot file has no `[{name}]` table")));
    };
    let section = section
        .as_table()
        .ok_or_else(|| parse_err(format!("`{name}` must be a table of parameters")))?;
    params_of_table(section, name, &file)
}

/// The parameters of one table of the robot file `file` (section `name`).
pub fn params_of_table(
    table: &toml::Table,
    name: &str,
    file: &Path,
) -> Result<Params, ConfigError> {
    let parse_err = |message: String| ConfigError::Parse {
        what: format!("{}, [{name}]", file.display()),
        message,
    };
    if let Some(v) = table.get("params") {
        let Some(p) = v.as_str().filter(|_| table.len() == 1) else {
            return Err(parse_err(format!(
                "`{name}.params` must be the only key of [{name}] and a file name \
                 (a parameter file, relative to the robot file), or give the keys themselves"
            )));
        };
        // A parameter file, not another robot file (no chains of files).
        let dir = file.parent().unwrap_or(Path::new(""));
        let path = dir.join(p);
        return Params::from_toml_str(&read_text(&path)?).map_err(|e| match e {
            ConfigError::Parse { message, .. } => ConfigError::Parse {
                what: path.display().to_string(),
                message,
            },
            other => other,
        });
    }
    let p: Params = toml::Value::Table(table.clone())
        .try_into()
        .map_err(|e: toml::de::Error| parse_err(e.to_string().trim_end().to_owned()))?;
    p.validate().map_err(|e| match e {
        ConfigError::OutOfRange {
            field,
            value,
            allowed,
        } => parse_err(format!(
            "invalid `{name}.{field}` = {value}: must be {allowed}"
        )),
        other => other,
    })?;
    Ok(p)
}

/// A TOML value as the text a flag takes: numbers as Rust prints them (the shortest text that
/// reads back the same `f64`), booleans, strings as they are, and arrays of numbers
/// comma-separated (`x0 = [0, 1.5, 0, 0]` is `--x0 0,1.5,0,0`); `None` for tables and other
/// arrays.
pub fn flag_text(v: &toml::Value) -> Option<String> {
    match v {
        toml::Value::String(s) => Some(s.clone()),
        toml::Value::Integer(i) => Some(i.to_string()),
        toml::Value::Float(f) => Some(f.to_string()),
        toml::Value::Boolean(b) => Some(b.to_string()),
        toml::Value::Array(a) => a
            .iter()
            .map(|x| match x {
                toml::Value::Integer(i) => Some(i.to_string()),
                toml::Value::Float(f) => Some(f.to_string()),
                _ => None,
            })
            .collect::<Option<Vec<_>>>()
            .map(|v| v.join(",")),
        _ => None,
    }
}

/// The flag a key of a section sets: `--{key}` with `-` for `_`, except `[deploy] name`
/// (`--robot`, the robot's name in its keys).
pub fn flag_of(section: &str, key: &str) -> String {
    match (section, key) {
        ("deploy", "name") => "robot".to_owned(),
        _ => key.replace('_', "-"),
    }
}

/// The keys whose values are files, relative to the robot file (made absolute when applied).
pub const PATH_KEYS: [(&str, &str); 3] = [("law", "plan"), ("deploy", "certs"), ("deploy", "out")];

/// Reads a robot file as a TOML document (one bounded read).
pub fn read_doc(path: &Path) -> Result<toml::Table, String> {
    let text = read_text(path).map_err(|e| e.to_string())?;
    toml::from_str(&text).map_err(|e| {
        format!(
            "cannot parse the robot file {}: {}",
            path.display(),
            e.to_string().trim_end()
        )
    })
}

/// The robot file's directory, absolute when it can be made so.
fn base_dir(file: &Path) -> PathBuf {
    let dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
    let dir = if dir.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        dir
    };
    std::fs::canonicalize(&dir).unwrap_or(dir)
}

/// What one section key sets: the flag's long name and its text.
#[derive(Debug, Clone, PartialEq)]
pub struct FlagDefault {
    /// `section.key`, as the file spells it.
    pub key: String,
    /// The flag's long name (no dashes).
    pub flag: String,
    /// The value as the flag's text.
    pub text: String,
}

/// The flag defaults of the sections `sections` of the robot document `doc` read from `file`:
/// a parameter section becomes `--params FILE#robot` (`--plant-params FILE#plant`); path keys
/// are made absolute (relative to the file).
pub fn flag_defaults(
    doc: &toml::Table,
    file: &Path,
    sections: &[&str],
) -> Result<Vec<FlagDefault>, String> {
    let abs_file = base_dir(file).join(file.file_name().unwrap_or_default());
    let mut out = Vec::new();
    for &section in sections {
        let Some(v) = doc.get(section) else { continue };
        let Some(table) = v.as_table() else {
            return Err(format!(
                "`{section}` in {} must be a table ([{section}])",
                file.display()
            ));
        };
        if let Some(flag) = match section {
            "robot" => Some("params"),
            "plant" => Some("plant-params"),
            _ => None,
        } {
            out.push(FlagDefault {
                key: format!("[{section}]"),
                flag: flag.to_owned(),
                text: format!("{}#{section}", abs_file.display()),
            });
            continue;
        }
        if PARAMS_SECTIONS.contains(&section) {
            continue;
        }
        for (key, value) in table {
            let Some(mut text) = flag_text(value) else {
                return Err(format!(
                    "invalid `{section}.{key}` in {}: must be a number, a boolean, a string or \
                     an array of numbers",
                    file.display()
                ));
            };
            if PATH_KEYS.contains(&(section, key.as_str())) {
                text = base_dir(file).join(&text).display().to_string();
            }
            out.push(FlagDefault {
                key: format!("{section}.{key}"),
                flag: flag_of(section, key),
                text,
            });
        }
    }
    Ok(out)
}

/// Applies `defaults` to `cmd`: each becomes the default value of the flag of its name, checked
/// by the flag's own parser first (an error names the key, the flag and the parser's allowed
/// values). A default whose flag `cmd` lacks is skipped when `strict` is false, refused when
/// it is true.
#[cfg(feature = "clap")]
pub fn apply(
    mut cmd: clap::Command,
    defaults: &[FlagDefault],
    file: &Path,
    strict: bool,
) -> Result<clap::Command, String> {
    // Not built: `mut_arg` on a built command mixes up its arguments.
    for d in defaults {
        let Some(arg) = cmd
            .get_arguments()
            .find(|a| a.get_long() == Some(d.flag.as_str()))
        else {
            if strict {
                return Err(format!(
                    "`{}` in {}: `{}` has no flag --{}",
                    d.key,
                    file.display(),
                    cmd.get_name(),
                    d.flag
                ));
            }
            continue;
        };
        if let Err(msg) = check_value(arg, &d.text) {
            return Err(format!(
                "invalid `{}` = {:?} in {} (as --{}): {msg}",
                d.key,
                d.text,
                file.display(),
                d.flag
            ));
        }
        let id = arg.get_id().clone();
        // clap keeps defaults as `&'static str` without its `string` feature: a few short
        // strings per process.
        let text: &'static str = Box::leak(d.text.clone().into_boxed_str());
        cmd = cmd.mut_arg(id, |a| a.default_value(text));
    }
    Ok(cmd)
}

/// The flag of a node binary that names its robot file (`tilting-controller --robot-file
/// RUN/robot.toml`): `tilting live` hands its children the run's robot file instead of its keys
/// spelled out again as flags.
pub const NODE_FILE_FLAG: &str = "robot-file";

/// The sections a node reads from its robot file (a key whose flag the node lacks is left out).
pub const NODE_SECTIONS: [&str; 7] = [
    "robot", "plant", "law", "run", "network", "sensors", "deploy",
];

/// Why [`parse_node`] failed.
#[cfg(feature = "clap")]
#[derive(Debug)]
pub enum NodeArgsError {
    /// The flags (clap's message and exit code).
    Clap(clap::Error),
    /// The robot file.
    File(String),
}

/// Parses a node's command line `argv` (its first item the program's name) as `C`, with the
/// keys of the robot file of its `--robot-file` (if given) as the defaults of its flags of the
/// same names ([`apply`], not strict: a file describes more than one node needs); a flag given
/// as well overrides the key.
#[cfg(feature = "clap")]
pub fn parse_node<C: clap::Parser>(argv: &[std::ffi::OsString]) -> Result<C, NodeArgsError> {
    parse_node_with(argv, &|d| d)
}

/// [`parse_node`] with the file's flag defaults passed through `select` first (a node that
/// takes only some keys of a section, or a parameter table under another flag).
#[cfg(feature = "clap")]
pub fn parse_node_with<C: clap::Parser>(
    argv: &[std::ffi::OsString],
    select: &dyn Fn(Vec<FlagDefault>) -> Vec<FlagDefault>,
) -> Result<C, NodeArgsError> {
    let base = C::command();
    let first = base
        .clone()
        .try_get_matches_from(argv)
        .map_err(NodeArgsError::Clap)?;
    let file = base
        .get_arguments()
        .find(|a| a.get_long() == Some(NODE_FILE_FLAG))
        .and_then(|a| first.get_raw(a.get_id().as_str()))
        .and_then(|mut r| r.next_back())
        .map(PathBuf::from);
    let cmd = match &file {
        None => base,
        Some(f) => {
            let doc = read_doc(f).map_err(NodeArgsError::File)?;
            let defaults = flag_defaults(&doc, f, &NODE_SECTIONS).map_err(NodeArgsError::File)?;
            apply(base, &select(defaults), f, false).map_err(NodeArgsError::File)?
        }
    };
    let matches = cmd
        .try_get_matches_from(argv)
        .map_err(NodeArgsError::Clap)?;
    C::from_arg_matches(&matches).map_err(NodeArgsError::Clap)
}

/// [`parse_node`] of this process's command line; a bad flag exits as clap does, a bad robot
/// file with code 2 and its message.
#[cfg(feature = "clap")]
pub fn parse_node_args<C: clap::Parser>() -> C {
    exit_on_error(parse_node::<C>(&std::env::args_os().collect::<Vec<_>>()))
}

/// The parsed flags, or the exit of [`parse_node_args`]: a bad flag as clap exits, a bad robot
/// file with code 2 and its message.
#[cfg(feature = "clap")]
pub fn exit_on_error<C>(parsed: Result<C, NodeArgsError>) -> C {
    match parsed {
        Ok(c) => c,
        Err(NodeArgsError::Clap(e)) => e.exit(),
        Err(NodeArgsError::File(e)) => {
            eprintln!("error: {e}");
            std::process::exit(2)
        }
    }
}

/// Checks `text` with the value parser of `arg` (a switch takes `true` or `false`); the
/// parser's message without clap's decoration.
#[cfg(feature = "clap")]
fn check_value(arg: &clap::Arg, text: &str) -> Result<(), String> {
    if !arg.get_action().takes_values() {
        return match text {
            "true" | "false" => Ok(()),
            _ => Err("must be true or false".to_owned()),
        };
    }
    let probe = clap::Arg::new("value")
        .long("value")
        .value_parser(arg.get_value_parser().clone())
        .allow_hyphen_values(true);
    let check = clap::Command::new("check").arg(probe);
    match check.try_get_matches_from(["check", "--value", text]) {
        Ok(_) => Ok(()),
        Err(e) => {
            let msg = e.to_string();
            let msg: Vec<&str> = msg
                .lines()
                .map(|l| l.trim_start_matches("error: ").trim())
                .filter(|l| !l.is_empty() && !l.starts_with("For more information"))
                .collect();
            Err(msg.join(" ").replace("'--value <value>'", "the flag"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A directory removed at the end of the test.
    struct Dir(PathBuf);
    impl Dir {
        fn path(&self) -> &Path {
            &self.0
        }
    }
    impl Drop for Dir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_robot_file_is_a_parameter_file() {
        let dir = std::env::temp_dir().join(format!("tilting-robot-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let dir = Dir(dir);
        let f = write(
            dir.path(),
            "r.toml",
            "[robot]\nm_f = 0.85\nimpact = \"physical\"\n[plant]\nm_l = 1.1\n[law]\nkd = 12\n\
             [prior]\nparams = \"p.toml\"\n",
        );
        write(dir.path(), "p.toml", "l = 1.5\n");
        let p = params_from_file(&f).unwrap();
        assert_eq!((p.m_f, p.m_l), (0.85, 1.0));
        assert_eq!(p.impact, crate::ImpactLaw::Physical);
        let plant = params_from_file(Path::new(&format!("{}#plant", f.display()))).unwrap();
        assert_eq!((plant.m_f, plant.m_l), (1.0, 1.1));
        let prior = params_from_file(Path::new(&format!("{}#prior", f.display()))).unwrap();
        assert_eq!(prior.l, 1.5);
        // A plain parameter file reads as before.
        assert_eq!(params_from_file(&dir.path().join("p.toml")).unwrap().l, 1.5);
        // A bad value names the table and the key.
        let bad = write(dir.path(), "b.toml", "[robot]\nm_f = -1\n");
        let e = params_from_file(&bad).unwrap_err().to_string();
        assert!(e.contains("`robot.m_f` = -1"), "{e}");
        let e = params_from_file(Path::new(&format!("{}#prior", bad.display())))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no `[prior]`"), "{e}");
    }

    #[test]
    fn values_become_flag_text() {
        let doc: toml::Table =
            toml::from_str("[law]\nkd = 14.14\nk = 500\nreference = \"sinusoid:0.2,4\"\n[run]\nx0 = [0, 1.5705814493798966, 0, 0.498257789692]\n[deploy]\nname = \"r1\"\nsecure = true\n")
                .unwrap();
        let d = flag_defaults(&doc, Path::new("r.toml"), &["law", "run", "deploy"]).unwrap();
        let get = |k: &str| d.iter().find(|x| x.key == k).unwrap().clone();
        assert_eq!(get("law.kd").text, "14.14");
        assert_eq!(get("law.k").text, "500");
        assert_eq!(get("run.x0").text, "0,1.5705814493798966,0,0.498257789692");
        assert_eq!(
            (get("deploy.name").flag, get("deploy.name").text),
            ("robot".into(), "r1".into())
        );
        assert_eq!(get("deploy.secure").text, "true");
        // f64 text reads back the same bits.
        let x: f64 = 0.1 + 0.2;
        assert_eq!(
            flag_text(&toml::Value::Float(x))
                .unwrap()
                .parse::<f64>()
                .unwrap(),
            x
        );
    }
}
