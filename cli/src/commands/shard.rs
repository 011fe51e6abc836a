//! `--shard I/N` of the sweeps (`plan margins`, `plan bifurcation`, `plan gains`) and
//! `tilting plan merge`: a job array of any batch scheduler runs one shard per task, each
//! printing a shard file (JSON), and `merge` puts the files back together into the JSON the
//! unsharded command prints (`--json`), bit for bit. The splitting is
//! `tilting_planner::shard`'s; this module holds the file format and the merge command.

use super::{emit, usage};
use crate::CommandError;
use clap::Args;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};
use tilting_planner::shard::{first_difference, Shard, ShardError};

/// The format tag of a shard file.
pub const FORMAT: &str = "tilting-shard/1";

/// `--shard I/N`: the flag of every sweep.
#[derive(Debug, Clone, Args)]
pub struct ShardArgs {
    /// Run only shard I of N (0-based, 0 <= I < N) and print it as a shard file (JSON) for
    /// `tilting plan merge`; shard I takes the points j with j mod N = I
    #[arg(long, value_name = "I/N", value_parser = parse_shard, allow_hyphen_values = true)]
    pub shard: Option<Shard>,
}

fn parse_shard(s: &str) -> Result<Shard, String> {
    s.parse().map_err(|e: ShardError| e.to_string())
}

/// One shard of a sweep, as printed by `--shard` and read by `merge`.
#[derive(Debug, Serialize, Deserialize)]
pub struct ShardFile {
    /// [`FORMAT`].
    pub format: String,
    /// The command whose sweep this is (`plan margins`, ...).
    pub command: String,
    /// Which shard.
    pub shard: Shard,
    /// Everything the sweep's points depend on: shards merge only with equal grids.
    pub grid: Value,
    /// The shard's results (the command's own form).
    pub part: Value,
}

impl ShardFile {
    /// The file of `shard` of `command` over `grid`, with its results `part`.
    pub fn new(
        command: &str,
        shard: Shard,
        grid: &impl Serialize,
        part: &impl Serialize,
    ) -> Result<Self, CommandError> {
        Ok(ShardFile {
            format: FORMAT.into(),
            command: command.into(),
            shard,
            grid: serde_json::to_value(grid).map_err(|e| CommandError::Failed(e.into()))?,
            part: serde_json::to_value(part).map_err(|e| CommandError::Failed(e.into()))?,
        })
    }

    /// Prints the file (one JSON line on stdout).
    pub fn emit(&self) -> Result<(), CommandError> {
        emit(true, self, String::new)
    }
}

/// Flags of `tilting plan merge`.
#[derive(Debug, Clone, Args)]
pub struct MergeArgs {
    /// The shard files of one sweep (every shard I/N of one N, each once, in any order)
    #[arg(required = true, value_name = "SHARD.json")]
    pub files: Vec<PathBuf>,
}

/// The shards of one sweep, read and checked to belong together: one command, one grid, one
/// `N`. The shards' results are for the command to gather.
pub struct Shards {
    /// The command (`plan margins`, ...).
    pub command: String,
    /// The grid they share.
    pub grid: Value,
    /// Each shard and its results, in the order given.
    pub parts: Vec<(Shard, Value)>,
}

fn read(path: &Path) -> Result<ShardFile, CommandError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| usage(format!("cannot read shard file {}: {e}", path.display())))?;
    let v: Value = serde_json::from_str(&text).map_err(|e| {
        usage(format!(
            "{} is not a shard file (not one JSON object: {e}); was its shard run to the end?",
            path.display()
        ))
    })?;
    if v.get("format").and_then(Value::as_str) != Some(FORMAT) {
        return Err(usage(format!(
            "{} is not a shard file of this version (no \"format\": \"{FORMAT}\"); shard \
             files come from a sweep run with --shard I/N",
            path.display()
        )));
    }
    serde_json::from_value(v)
        .map_err(|e| usage(format!("{} is not a valid shard file: {e}", path.display())))
}

/// Reads the files and checks they are shards of one sweep (command, grid).
pub fn read_all(files: &[PathBuf]) -> Result<Shards, CommandError> {
    let mut first: Option<(&PathBuf, ShardFile)> = None;
    let mut parts = Vec::with_capacity(files.len());
    for path in files {
        let f = read(path)?;
        if let Some((p0, f0)) = &first {
            if f.command != f0.command {
                return Err(usage(format!(
                    "{} is a shard of `{}`, {} of `{}`: shards of different sweeps do not merge",
                    path.display(),
                    f.command,
                    p0.display(),
                    f0.command
                )));
            }
            if let Some(field) = first_difference(&f0.grid, &f.grid) {
                return Err(usage(format!(
                    "{} and {} are shards of different grids (`{field}` differs: {} and {}); \
                     merge only the shards of one sweep",
                    p0.display(),
                    path.display(),
                    lookup(&f0.grid, &field),
                    lookup(&f.grid, &field),
                )));
            }
        }
        parts.push((f.shard, f.part.clone()));
        if first.is_none() {
            first = Some((path, f));
        }
    }
    let (_, f0) = first.ok_or_else(|| usage("no shard files given".into()))?;
    Ok(Shards {
        command: f0.command,
        grid: f0.grid,
        parts,
    })
}

/// The value at a path of [`first_difference`] (`delays[1]`, `criteria.tilts`), as JSON text.
fn lookup(v: &Value, path: &str) -> String {
    let mut cur = Some(v);
    for seg in path.split('.') {
        let (key, idx) = seg.split_once('[').unwrap_or((seg, ""));
        if !key.is_empty() {
            cur = cur.and_then(|c| c.get(key));
        }
        for i in idx.split('[').filter(|s| !s.is_empty()) {
            let i: usize = i.trim_end_matches(']').parse().unwrap_or(usize::MAX);
            cur = cur.and_then(|c| c.get(i));
        }
    }
    cur.map_or("absent".into(), Value::to_string)
}

/// Parses the parts as `T` (each a command's own form).
pub fn parts<T: serde::de::DeserializeOwned>(
    parts: Vec<(Shard, Value)>,
) -> Result<Vec<(Shard, T)>, CommandError> {
    parts
        .into_iter()
        .map(|(s, v)| {
            serde_json::from_value(v)
                .map(|t| (s, t))
                .map_err(|e| usage(format!("shard {s} is not a valid shard: {e}")))
        })
        .collect()
}

/// `tilting plan merge`: reads the shard files and prints the whole sweep's JSON.
pub fn merge(args: &MergeArgs) -> Result<(), CommandError> {
    let shards = read_all(&args.files)?;
    match shards.command.as_str() {
        super::margins::COMMAND => super::margins::merge(shards),
        super::plan::BIFURCATION => super::plan::merge_bifurcation(shards),
        super::plan::GAINS => super::plan::merge_gains(shards),
        other => Err(usage(format!("cannot merge shards of `{other}`"))),
    }
}
