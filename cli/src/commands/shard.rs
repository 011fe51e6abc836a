//! `--shard I/N` of the sweeps (`plan margins`, `plan bifurcation`, `plan gains`) and
//! `tilting plan merge`: a job array of any batch scheduler runs one shard per task, each
//! printing a shard file (JSON), and `merge` puts the files back together into the JSON the
//! unsharded command prints (`--json`), bit for bit. The splitting and the shard files are
//! `tilting_planner::shard`'s; this module holds the flags and the merge command.

use super::{emit, usage};
use crate::CommandError;
use clap::Args;
use serde::Serialize;
use std::path::PathBuf;
pub use tilting_planner::shard::{parts, read_all, Shards};
use tilting_planner::shard::{Shard, ShardError, ShardFile};

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

/// Prints shard `shard` of `command`'s sweep over `grid`, with its results `part`, as a shard
/// file (one JSON line on stdout, [`ShardFile`]).
pub fn emit_shard(
    command: &str,
    shard: Shard,
    grid: &impl Serialize,
    part: &impl Serialize,
) -> Result<(), CommandError> {
    let file =
        ShardFile::new(command, shard, grid, part).map_err(|e| CommandError::Failed(e.into()))?;
    emit(true, &file, String::new)
}

/// Flags of `tilting plan merge`.
#[derive(Debug, Clone, Args)]
pub struct MergeArgs {
    /// The shard files of one sweep (every shard I/N of one N, each once, in any order)
    #[arg(required = true, value_name = "SHARD.json")]
    pub files: Vec<PathBuf>,
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
