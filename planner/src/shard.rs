//! Splitting a sweep into shards, and putting the shards back together.
//!
//! A sweep is a list of independent **units** (one value of `k`, one row of a gain grid, one
//! point of a margins map), numbered `0..total` in the order of the whole run's report. Shard
//! `I/N` owns the units `j` with `j % N == I` (strided, so that the slow and the fast corners
//! of a grid spread over the shards). A unit's result depends only on its coordinates and the
//! sweep's inputs (every random stream is seeded from those, never from the order of
//! execution), so the shards of one sweep, gathered by unit number ([`gather`]), equal the
//! whole run bit for bit, however many there are and wherever they ran.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// Shard `index` of `count` (0-based: `0 <= index < count`), written `I/N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Shard {
    /// Which shard, `0..count`.
    pub index: usize,
    /// How many shards the sweep is split into, at least 1.
    pub count: usize,
}

/// Most shards of one sweep.
pub const MAX_SHARDS: usize = 1_000_000;

/// A shard that cannot be, or shards that do not make one sweep.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShardError {
    /// Not of the form `I/N`.
    #[error("invalid `--shard` = {0:?}: expected I/N with integers 0 <= I < N, e.g. 0/4")]
    Syntax(String),
    /// `N` is 0 or too large.
    #[error("invalid `--shard` = {index}/{count}: N must be in 1..={MAX_SHARDS}")]
    Count {
        /// `I`.
        index: usize,
        /// `N`.
        count: usize,
    },
    /// `I` is not below `N`.
    #[error(
        "invalid `--shard` = {index}/{count}: the shard index I must be in 0..={} (I/N is 0-based)",
        count - 1
    )]
    Index {
        /// `I`.
        index: usize,
        /// `N`.
        count: usize,
    },
    /// A shard file that cannot be read, is not one, or is not of the others' sweep (the
    /// message names the files and, for grids, the first field that differs).
    #[error("{0}")]
    File(String),
    /// Shards of different splits were given together.
    #[error("shard {a} and shard {b} split the sweep differently (N = {} and {})", a.count, b.count)]
    Split {
        /// One shard.
        a: Shard,
        /// Another, with another `N`.
        b: Shard,
    },
    /// The same shard was given twice.
    #[error("shard {0} is given twice")]
    Duplicate(Shard),
    /// Some shards are missing: the merge would not be the whole sweep.
    #[error("shards missing: {missing} of {count} (have {have}); a merge needs every shard")]
    Missing {
        /// The missing indices, e.g. `1, 3`.
        missing: String,
        /// `N`.
        count: usize,
        /// How many were given.
        have: usize,
    },
    /// A shard carries a unit it does not own, one twice, or the wrong number of units.
    #[error("shard {shard} is corrupt: {why}")]
    Corrupt {
        /// The shard.
        shard: Shard,
        /// What is wrong.
        why: String,
    },
}

impl Shard {
    /// The whole sweep: shard `0/1`.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Shard `index/count`, checked.
    pub fn new(index: usize, count: usize) -> Result<Self, ShardError> {
        if count == 0 || count > MAX_SHARDS {
            return Err(ShardError::Count { index, count });
        }
        if index >= count {
            return Err(ShardError::Index { index, count });
        }
        Ok(Shard { index, count })
    }

    /// Whether unit `j` belongs to this shard.
    pub fn owns(&self, j: usize) -> bool {
        j % self.count == self.index
    }

    /// The units of a sweep of `total` this shard owns, in order.
    pub fn units(&self, total: usize) -> std::iter::StepBy<std::ops::Range<usize>> {
        (self.index..total.max(self.index)).step_by(self.count)
    }

    /// How many of `total` units this shard owns.
    pub fn len(&self, total: usize) -> usize {
        self.units(total).len()
    }

    /// Whether this shard owns none of `total` units.
    pub fn is_empty(&self, total: usize) -> bool {
        self.len(total) == 0
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = ShardError;

    /// Parses `I/N` (0-based `I`).
    fn from_str(s: &str) -> Result<Self, ShardError> {
        let syntax = || ShardError::Syntax(s.to_string());
        let (i, n) = s.trim().split_once('/').ok_or_else(syntax)?;
        let i: usize = i.trim().parse().map_err(|_| syntax())?;
        let n: usize = n.trim().parse().map_err(|_| syntax())?;
        Shard::new(i, n)
    }
}

/// Runs this shard's units of a sweep of `total` on all cores: `f(j)` for each unit `j` it
/// owns, with `j`, in unit order.
pub fn run<T: Send>(
    shard: Shard,
    total: usize,
    f: impl Fn(usize) -> T + Sync + Send,
) -> Vec<(usize, T)> {
    let units: Vec<usize> = shard.units(total).collect();
    units.par_iter().map(|&j| (j, f(j))).collect()
}

/// The whole sweep of `total` units from its shards (in any order): every shard of one split
/// exactly once, each carrying exactly the units it owns. Nothing is returned unless the
/// result is whole.
pub fn gather<T>(total: usize, parts: Vec<(Shard, Vec<(usize, T)>)>) -> Result<Vec<T>, ShardError> {
    let Some(&(first, _)) = parts.first() else {
        return Err(ShardError::Missing {
            missing: "all".into(),
            count: 0,
            have: 0,
        });
    };
    let count = first.count;
    let mut seen = vec![false; count];
    for (s, _) in &parts {
        if s.count != count {
            return Err(ShardError::Split { a: first, b: *s });
        }
        if s.index >= count {
            return Err(ShardError::Index {
                index: s.index,
                count,
            });
        }
        if std::mem::replace(&mut seen[s.index], true) {
            return Err(ShardError::Duplicate(*s));
        }
    }
    if seen.iter().any(|s| !s) {
        let missing: Vec<String> = (0..count)
            .filter(|&i| !seen[i])
            .take(20)
            .map(|i| i.to_string())
            .collect();
        return Err(ShardError::Missing {
            missing: missing.join(", "),
            count,
            have: parts.len(),
        });
    }
    let mut out: Vec<Option<T>> = (0..total).map(|_| None).collect();
    for (s, units) in parts {
        let corrupt = |why: String| ShardError::Corrupt { shard: s, why };
        if units.len() != s.len(total) {
            return Err(corrupt(format!(
                "{} units, its share of {total} is {}",
                units.len(),
                s.len(total)
            )));
        }
        for (j, v) in units {
            if j >= total || !s.owns(j) {
                return Err(corrupt(format!("unit {j} is not its own (of {total})")));
            }
            if out[j].replace(v).is_some() {
                return Err(corrupt(format!("unit {j} is given twice")));
            }
        }
    }
    // Every shard carried exactly its share, without repeats: every unit is there.
    Ok(out.into_iter().flatten().collect())
}

/// The first place where two JSON values differ, as a path (`delays`, `criteria.tilts`,
/// `delays[2]`), or `None` when they are equal. Used to name what differs between the grids of
/// two shards.
pub fn first_difference(a: &serde_json::Value, b: &serde_json::Value) -> Option<String> {
    use serde_json::Value;
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| match (x.get(k), y.get(k)) {
                (Some(u), Some(v)) => first_difference(u, v).map(|p| {
                    if p.is_empty() || p.starts_with('[') {
                        format!("{k}{p}")
                    } else {
                        format!("{k}.{p}")
                    }
                }),
                _ => Some(k.clone()),
            })
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (u, v))| first_difference(u, v).map(|p| format!("[{i}]{p}"))),
        _ if a == b => None,
        _ => Some(String::new()),
    }
}

// The shard files of `--shard I/N` and `tilting plan merge`.

/// The format tag of a shard file.
pub const FORMAT: &str = "tilting-shard/1";

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
    pub grid: serde_json::Value,
    /// The shard's results (the command's own form).
    pub part: serde_json::Value,
}

impl ShardFile {
    /// The file of `shard` of `command` over `grid`, with its results `part`.
    pub fn new(
        command: &str,
        shard: Shard,
        grid: &impl Serialize,
        part: &impl Serialize,
    ) -> Result<Self, serde_json::Error> {
        Ok(ShardFile {
            format: FORMAT.into(),
            command: command.into(),
            shard,
            grid: serde_json::to_value(grid)?,
            part: serde_json::to_value(part)?,
        })
    }
}

fn file_error(message: String) -> ShardError {
    ShardError::File(message)
}

/// The shards of one sweep, read and checked to belong together: one command, one grid, one
/// `N`. The shards' results are for the command to gather.
pub struct Shards {
    /// The command (`plan margins`, ...).
    pub command: String,
    /// The grid they share.
    pub grid: serde_json::Value,
    /// Each shard and its results, in the order given.
    pub parts: Vec<(Shard, serde_json::Value)>,
}

fn read_file(path: &Path) -> Result<ShardFile, ShardError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| file_error(format!("cannot read shard file {}: {e}", path.display())))?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
        file_error(format!(
            "{} is not a shard file (not one JSON object: {e}); was its shard run to the end?",
            path.display()
        ))
    })?;
    if v.get("format").and_then(serde_json::Value::as_str) != Some(FORMAT) {
        return Err(file_error(format!(
            "{} is not a shard file of this version (no \"format\": \"{FORMAT}\"); shard \
             files come from a sweep run with --shard I/N",
            path.display()
        )));
    }
    serde_json::from_value(v)
        .map_err(|e| file_error(format!("{} is not a valid shard file: {e}", path.display())))
}

/// Reads the files and checks they are shards of one sweep (command, grid).
pub fn read_all(files: &[PathBuf]) -> Result<Shards, ShardError> {
    let mut first: Option<(&PathBuf, ShardFile)> = None;
    let mut parts = Vec::with_capacity(files.len());
    for path in files {
        let f = read_file(path)?;
        if let Some((p0, f0)) = &first {
            if f.command != f0.command {
                return Err(file_error(format!(
                    "{} is a shard of `{}`, {} of `{}`: shards of different sweeps do not merge",
                    path.display(),
                    f.command,
                    p0.display(),
                    f0.command
                )));
            }
            if let Some(field) = first_difference(&f0.grid, &f.grid) {
                return Err(file_error(format!(
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
    let (_, f0) = first.ok_or_else(|| file_error("no shard files given".into()))?;
    Ok(Shards {
        command: f0.command,
        grid: f0.grid,
        parts,
    })
}

/// The value at a path of [`first_difference`] (`delays[1]`, `criteria.tilts`), as JSON text.
fn lookup(v: &serde_json::Value, path: &str) -> String {
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
    cur.map_or("absent".into(), serde_json::Value::to_string)
}

/// Parses the parts as `T` (each a command's own form).
pub fn parts<T: serde::de::DeserializeOwned>(
    parts: Vec<(Shard, serde_json::Value)>,
) -> Result<Vec<(Shard, T)>, ShardError> {
    parts
        .into_iter()
        .map(|(s, v)| {
            serde_json::from_value(v)
                .map(|t| (s, t))
                .map_err(|e| file_error(format!("shard {s} is not a valid shard: {e}")))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_refuse_what_is_out_of_range() {
        assert_eq!("2/5".parse(), Ok(Shard { index: 2, count: 5 }));
        assert_eq!(" 0 / 1 ".parse(), Ok(Shard::WHOLE));
        let e = "5/5".parse::<Shard>().unwrap_err();
        assert_eq!(e, ShardError::Index { index: 5, count: 5 });
        assert!(e.to_string().contains("in 0..=4"), "{e}");
        assert!(matches!(
            "0/0".parse::<Shard>(),
            Err(ShardError::Count { .. })
        ));
        for bad in ["", "1", "a/2", "-1/2", "1/2/3", "1.5/2"] {
            assert!(
                matches!(bad.parse::<Shard>(), Err(ShardError::Syntax(_))),
                "{bad}"
            );
        }
    }

    /// Every unit lands in exactly one shard, for any split, and gathering the shards in any
    /// order gives back the units in order.
    #[test]
    fn shards_partition_and_gather_back() {
        for total in [0, 1, 7, 10] {
            for n in 1..=12 {
                let mut parts: Vec<(Shard, Vec<(usize, usize)>)> = (0..n)
                    .map(|i| {
                        let s = Shard::new(i, n).unwrap();
                        (s, s.units(total).map(|j| (j, 10 * j)).collect())
                    })
                    .collect();
                assert_eq!(parts.iter().map(|p| p.1.len()).sum::<usize>(), total);
                parts.reverse();
                let all = gather(total, parts).unwrap();
                assert_eq!(all, (0..total).map(|j| 10 * j).collect::<Vec<_>>());
            }
        }
    }

    #[test]
    fn incomplete_or_mixed_shards_are_refused() {
        let part = |i, n: usize, total| {
            let s = Shard::new(i, n).unwrap();
            (s, s.units(total).map(|j| (j, j)).collect::<Vec<_>>())
        };
        let missing = gather(10, vec![part(0, 3, 10), part(2, 3, 10)]).unwrap_err();
        assert!(missing.to_string().contains("missing: 1 of 3"), "{missing}");
        let twice = gather(10, vec![part(0, 2, 10), part(0, 2, 10), part(1, 2, 10)]);
        assert!(matches!(twice, Err(ShardError::Duplicate(_))));
        let split = gather(10, vec![part(0, 2, 10), part(1, 3, 10)]);
        assert!(matches!(split, Err(ShardError::Split { .. })));
        // A shard of a smaller sweep lacks units: corrupt, not silently short.
        let short = gather(10, vec![part(0, 2, 10), part(1, 2, 8)]);
        assert!(matches!(short, Err(ShardError::Corrupt { .. })));
    }

    #[test]
    fn differences_are_named_by_path() {
        let a = serde_json::json!({"delays": [0.0, 0.1], "criteria": {"tilts": 20}});
        let b = serde_json::json!({"delays": [0.0, 0.2], "criteria": {"tilts": 20}});
        let c = serde_json::json!({"delays": [0.0, 0.1], "criteria": {"tilts": 30}});
        assert_eq!(first_difference(&a, &a), None);
        assert_eq!(first_difference(&a, &b).as_deref(), Some("delays[1]"));
        assert_eq!(first_difference(&a, &c).as_deref(), Some("criteria.tilts"));
    }
}
