//! Host mode (issue 32): one node process serving several robots over one zenoh session, each
//! robot its own keys `tilting/{name}/...`, its own state and its own summary. `--robots a,b,c`
//! of `tilting-plant` and `tilting-controller`.

use tilting_proto::Keys;

/// Most robots one host process serves (`--robots`).
pub const MAX_HOSTED: usize = 32;

/// The `--robots` flag of the nodes' host mode.
#[derive(Debug, Clone, Default, PartialEq, Eq, clap::Args)]
pub struct HostArgs {
    /// Host mode: serve these robots (1 to 32 distinct names, comma-separated, each with its
    /// own keys tilting/NAME/...) from this one process and its one zenoh session, instead of
    /// the one robot of --robot. Each robot keeps its own state, faults and summary (one JSON
    /// line each, `{"robot": NAME, "summary": ...}`)
    #[arg(
        long,
        value_name = "A,B,...",
        value_delimiter = ',',
        conflicts_with = "robot"
    )]
    pub robots: Vec<String>,
}

impl HostArgs {
    /// Whether host mode is on (`--robots` given).
    pub fn hosting(&self) -> bool {
        !self.robots.is_empty()
    }

    /// The keys of each hosted robot, in the order given; an error naming `--robots` and its
    /// range for a count outside 1 to [`MAX_HOSTED`], an invalid name or a name given twice.
    pub fn keys(&self) -> anyhow::Result<Vec<Keys>> {
        hosted_keys(&self.robots)
    }
}

/// The keys of robots `names` (host mode's `--robots`): 1 to [`MAX_HOSTED`] distinct valid
/// names, else an error naming `--robots`, the range and the offending name.
pub fn hosted_keys(names: &[String]) -> anyhow::Result<Vec<Keys>> {
    anyhow::ensure!(
        (1..=MAX_HOSTED).contains(&names.len()),
        "invalid --robots: {} names, allowed 1 to {MAX_HOSTED}",
        names.len()
    );
    let mut keys: Vec<Keys> = Vec::with_capacity(names.len());
    for name in names {
        let k = Keys::new(name).map_err(|e| anyhow::anyhow!("invalid --robots: {e}"))?;
        anyhow::ensure!(
            keys.iter().all(|o| o.robot() != k.robot()),
            "invalid --robots: robot {name:?} given twice (each robot once, 1 to {MAX_HOSTED} \
             distinct names)"
        );
        keys.push(k);
    }
    Ok(keys)
}

/// Host mode's check of `--zenoh-config` (`zenoh`): a configuration with a TLS identity (a
/// `connect_certificate` or `listen_certificate`, as `tilting certs` writes for the secure
/// deployment) is one robot's node, its certificate named `{robot}-{node}` and the access
/// control allowing that robot's keys only, so the other robots' messages would be denied:
/// refused, naming both flags. A configuration without one (or none) passes.
pub fn check_hosted_config(zenoh: &crate::ZenohArgs) -> anyhow::Result<()> {
    let Some(path) = &zenoh.zenoh_config else {
        return Ok(());
    };
    let config = crate::config_from_file(path)
        .map_err(|e| anyhow::anyhow!("--zenoh-config {}: {e}", path.display()))?;
    for field in ["connect_certificate", "listen_certificate"] {
        let key = format!("transport/link/tls/{field}");
        let json = config.get_json(&key).unwrap_or_default();
        let named = serde_json::from_str::<Option<String>>(&json).is_ok_and(|f| f.is_some());
        anyhow::ensure!(
            !named,
            "`--robots` (host mode) does not take `--zenoh-config` {} with a TLS identity \
             ({key}): a certificate of `tilting certs` is one robot's node and its access \
             control allows that robot's keys only; run one node per secure robot",
            path.display()
        );
    }
    Ok(())
}

/// One hosted robot's summary line: the robot's name and its node's summary.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HostedSummary<S> {
    /// The robot's name (its keys are `tilting/{robot}/...`).
    pub robot: String,
    /// The node's summary for this robot, as a one-robot node prints it.
    pub summary: S,
}

impl<S: serde::de::DeserializeOwned> HostedSummary<S> {
    /// Every line of `stdout` that parses as a hosted summary, in order.
    pub fn all_from_stdout(stdout: &str) -> Vec<Self> {
        stdout
            .lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn robots_are_refused_out_of_range_twice_or_badly_named() {
        let k = hosted_keys(&names(&["a", "b_2", "c-3"])).unwrap();
        let got: Vec<&str> = k.iter().map(|k| k.robot()).collect();
        assert_eq!(got, ["a", "b_2", "c-3"]);
        let e = hosted_keys(&[]).unwrap_err().to_string();
        assert!(e.contains("--robots") && e.contains("1 to 32"), "{e}");
        let many: Vec<String> = (0..=MAX_HOSTED).map(|i| format!("r{i}")).collect();
        let e = hosted_keys(&many).unwrap_err().to_string();
        assert!(e.contains("33 names") && e.contains("1 to 32"), "{e}");
        assert!(hosted_keys(&many[..MAX_HOSTED]).is_ok());
        let e = hosted_keys(&names(&["a", "b", "a"]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--robots") && e.contains("\"a\" given twice"),
            "{e}"
        );
        let e = hosted_keys(&names(&["a", "b/c"])).unwrap_err().to_string();
        assert!(e.contains("--robots"), "{e}");
    }

    #[test]
    fn a_summary_line_reads_back() {
        let s = HostedSummary {
            robot: "a".into(),
            summary: [1.5f64, 0.1],
        };
        let text = format!("noise\n{}\n", serde_json::to_string(&s).unwrap());
        assert_eq!(HostedSummary::<[f64; 2]>::all_from_stdout(&text), [s]);
    }
}
