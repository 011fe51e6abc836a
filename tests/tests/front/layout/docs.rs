//! The docs' facts: what a doc states about the code is checked against the code, so a fact that
//! drifts fails here (the minimum Rust version, the message sizes, every flag of a `tilting`
//! command line, every file and link).

use super::*;

/// The Markdown files a reader meets: the README, `docs/` (the guide included), the dated
/// decision records under `bench/`, and the READMEs of the examples, `third_party/` and the
/// figures' assets.
fn doc_files() -> Vec<PathBuf> {
    fn md_under(dir: &Path, out: &mut Vec<PathBuf>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                md_under(&p, out);
            } else if p.extension().is_some_and(|x| x == "md") {
                out.push(p);
            }
        }
    }
    let root = workspace_root();
    let mut files = vec![
        root.join("README.md"),
        root.join("examples/python/README.md"),
        root.join("third_party/README.md"),
        root.join("viz/assets/README.md"),
    ];
    md_under(&root.join("docs"), &mut files);
    if let Ok(entries) = std::fs::read_dir(root.join("bench")) {
        files.extend(
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "md")),
        );
    }
    files.sort();
    files
}

fn read_doc(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn rel(path: &Path) -> String {
    path.strip_prefix(workspace_root())
        .unwrap_or(path)
        .display()
        .to_string()
}

/// A doc's fenced code blocks (their lines) and its prose (the rest), apart.
fn split_fences(text: &str) -> (Vec<String>, String) {
    let (mut code, mut prose, mut inside) = (Vec::new(), String::new(), false);
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            inside = !inside;
            prose.push('\n');
        } else if inside {
            code.push(line.to_string());
            prose.push('\n');
        } else {
            prose.push_str(line);
            prose.push('\n');
        }
    }
    (code, prose)
}

/// The inline code spans of prose (`` `x` `` and ``` ``x`` ```), newlines folded to spaces.
fn code_spans(prose: &str) -> Vec<String> {
    code_spans_at(prose)
        .into_iter()
        .map(|(_, _, s)| s)
        .collect()
}

/// [`code_spans`] with where each starts and ends (the backticks included).
fn code_spans_at(prose: &str) -> Vec<(usize, usize, String)> {
    let b = prose.as_bytes();
    let (mut spans, mut i) = (Vec::new(), 0);
    while i < b.len() {
        if b[i] != b'`' {
            i += 1;
            continue;
        }
        let ticks = b[i..].iter().take_while(|&&c| c == b'`').count();
        let fence = "`".repeat(ticks);
        let start = i + ticks;
        match prose[start..].find(&fence) {
            Some(len) => {
                let end = start + len + ticks;
                spans.push((i, end, prose[start..start + len].replace('\n', " ")));
                i = end;
            }
            None => i = start,
        }
    }
    spans
}

/// `"1.88"` out of `rust-version = "1.88"` in the workspace's Cargo.toml.
fn rust_version() -> String {
    let manifest = read_doc(&workspace_root().join("Cargo.toml"));
    manifest
        .lines()
        .find_map(|l| {
            let v = l.trim().strip_prefix("rust-version")?;
            Some(
                v.trim()
                    .trim_start_matches('=')
                    .trim()
                    .trim_matches('"')
                    .to_string(),
            )
        })
        .expect("Cargo.toml has a rust-version")
}

/// The version numbers (`1.88`, `1.88.0`) a doc gives as Rust's minimum: the last version
/// before each "or newer"/"or later" whose preceding words name Rust.
fn rust_minimums(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for marker in [" or newer", " or later"] {
        for (at, _) in text.match_indices(marker) {
            let mut from = at.saturating_sub(48);
            while !text.is_char_boundary(from) {
                from -= 1;
            }
            let before = &text[from..at];
            if !before.contains("Rust") {
                continue;
            }
            let version: String = before
                .rsplit(|c: char| !(c.is_ascii_digit() || c == '.'))
                .next()
                .unwrap_or("")
                .trim_matches('.')
                .to_string();
            if version.contains('.') {
                found.push(version);
            }
        }
    }
    found
}

#[test]
fn the_docs_name_the_minimum_rust_version_of_cargo_toml() {
    let want = rust_version();
    let mut bad = Vec::new();
    let mut readme_says = false;
    for path in doc_files() {
        for got in rust_minimums(&read_doc(&path)) {
            if rel(&path) == "README.md" {
                readme_says = true;
            }
            if got != want && got.trim_end_matches(".0") != want {
                bad.push(format!("{}: Rust {got} or newer", rel(&path)));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "Cargo.toml's rust-version is {want}, but:\n{}",
        bad.join("\n")
    );
    assert!(
        readme_says,
        "the README names no minimum Rust version (\"Rust {want} or newer\")"
    );
}

/// Each message's encoded size: `(name, bytes)`; `Status` without its fault text (its docs
/// give `170 + n`).
fn message_sizes() -> Vec<(&'static str, usize)> {
    use tilting_tests::tilting_proto::{
        codec, ModeEvent, PlantState, Reference, Status, TorqueCommand,
    };
    let state = PlantState::full(0, 0.0, [0.0; 4], 0);
    let torque = TorqueCommand { seq: 0, tau: 0.0 };
    let event = ModeEvent {
        seq: 0,
        time: 0.0,
        from: 0,
        to: 1,
        x_before: [0.0; 4],
        x_after: [0.0; 4],
    };
    let reference = Reference {
        kind: Reference::HOLD,
        amplitude: 0.0,
        omega: 0.0,
        kp: 0.0,
        kd: 0.0,
        k: 0.0,
        energy_avg: 0.0,
        torque_limit: 0.0,
    };
    vec![
        ("PlantState", codec::encode(&state).len()),
        ("TorqueCommand", codec::encode(&torque).len()),
        ("ModeEvent", codec::encode(&event).len()),
        ("Reference", codec::encode(&reference).len()),
        ("Status", codec::encode(&Status::default()).len()),
    ]
}

/// The sizes a doc states right after a message's name: `PlantState — 50 bytes`,
/// `` `PlantState` (50 bytes) ``, `PlantState is 50 bytes`, `Status — 170 + n bytes`.
fn stated_sizes(text: &str, name: &str) -> Vec<usize> {
    let mut found = Vec::new();
    for (at, _) in text.match_indices(name) {
        let before = text[..at].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let mut rest = &text[at + name.len()..];
        if rest.starts_with(|c: char| c.is_alphanumeric() || c == '_') {
            continue;
        }
        rest = rest.trim_start_matches('`');
        let Some(rest) = [" — ", " - ", " (", ": ", " is ", ", ", " of "]
            .iter()
            .find_map(|p| rest.strip_prefix(p))
        else {
            continue;
        };
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        let after = &rest[digits.len()..];
        if !digits.is_empty()
            && [" bytes", "-byte", " + n bytes"]
                .iter()
                .any(|u| after.starts_with(u))
        {
            found.push(digits.parse().expect("digits"));
        }
    }
    found
}

#[test]
fn the_docs_name_the_message_sizes_proto_encodes() {
    let sizes = message_sizes();
    let mut bad = Vec::new();
    let mut stated = BTreeSet::new();
    for path in doc_files() {
        // Prose only: a code block may show an old peer's size in its error message.
        let (_, text) = split_fences(&read_doc(&path));
        for &(name, size) in &sizes {
            for got in stated_sizes(&text, name) {
                stated.insert(name);
                if got != size {
                    bad.push(format!(
                        "{}: {name} is said to be {got} bytes; proto encodes {size}",
                        rel(&path)
                    ));
                }
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    for (name, _) in sizes {
        assert!(
            stated.contains(name),
            "no doc states the size of {name} (docs/protocol.md's heading did)"
        );
    }
}

#[test]
fn the_size_reader_sees_the_forms_the_docs_use() {
    assert_eq!(
        stated_sizes("### PlantState — 50 bytes", "PlantState"),
        [50]
    );
    assert_eq!(
        stated_sizes("a `PlantState` (49 bytes) and", "PlantState"),
        [49]
    );
    assert_eq!(stated_sizes("### Status — 170 + n bytes", "Status"), [170]);
    assert!(stated_sizes("`PlantState` gains the byte at offset 49", "PlantState").is_empty());
    assert!(stated_sizes("PlantStates, 49 bytes", "PlantState").is_empty());
    assert_eq!(
        rust_minimums("the Rust toolchain (1.88 or newer)"),
        ["1.88"]
    );
    assert_eq!(rust_minimums("Rust 1.85 or newer"), ["1.85"]);
    assert!(rust_minimums("rmw_zenoh_cpp 0.2.4 or later").is_empty());
}

/// The binaries a doc's command line may start.
const BINARIES: [&str; 5] = [
    "tilting",
    "tilting-plant",
    "tilting-controller",
    "tilting-planner",
    "tilting-router",
];

/// The command lines of the docs that run one of [`BINARIES`]: `(doc, binary, the words
/// after it)`. Code blocks (continuation lines joined; `$T` is `tilting`) and inline code
/// spans; a line is cut at a comment and at `&&`, `;`, `|` and redirections.
fn command_lines() -> Vec<(String, String, Vec<String>)> {
    let mut out = Vec::new();
    for path in doc_files() {
        let (code, prose) = split_fences(&read_doc(&path));
        let mut lines = Vec::new();
        let mut joined = String::new();
        for line in code {
            let line = line.split(" # ").next().unwrap_or("").to_string();
            if let Some(head) = line.trim_end().strip_suffix('\\') {
                joined.push_str(head);
                joined.push(' ');
                continue;
            }
            joined.push_str(&line);
            lines.push(std::mem::take(&mut joined));
        }
        lines.extend(code_spans(&prose));
        for line in lines {
            // A quoted argument is one word of the shell, another program's command line
            // (`--plant-cmd "python3 -m tilting_mujoco --clock lockstep"`): not this one's flags.
            let line: String = line
                .split('"')
                .enumerate()
                .map(|(i, s)| if i % 2 == 0 { s } else { "QUOTED" })
                .collect();
            for part in line.split(['|', ';', '>', '<']).flat_map(|p| p.split("&&")) {
                let words: Vec<&str> = part.split_whitespace().collect();
                if words.contains(&"cargo") {
                    continue; // `cargo run -p tilting-planner --example ...`: a package
                }
                let Some(at) = words.iter().position(|w| {
                    let w = if *w == "$T" { "tilting" } else { w };
                    let name = w.rsplit('/').next().unwrap_or(w);
                    BINARIES.contains(&name) && (w == name || w.contains('/'))
                }) else {
                    continue;
                };
                let bin = if words[at] == "$T" {
                    "tilting"
                } else {
                    words[at].rsplit('/').next().expect("name")
                };
                out.push((
                    rel(&path),
                    bin.to_string(),
                    words[at + 1..].iter().map(|w| w.to_string()).collect(),
                ));
            }
        }
    }
    out
}

/// A command's subcommands and long flags.
type Help = (BTreeSet<String>, BTreeSet<String>);

/// `binary [path...] --help`: its subcommands (the lines `  name  text`) and its long flags.
fn help(bin: &Path, path: &[String]) -> Help {
    let out = Command::new(bin)
        .args(path)
        .arg("--help")
        .output()
        .expect("run --help");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{} {} --help failed: {}",
        bin.display(),
        path.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    let subcommands = text
        .lines()
        .filter_map(|l| {
            let name = l.strip_prefix("  ")?;
            let word: String = name
                .chars()
                .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '-')
                .collect();
            (!word.is_empty()
                && name.starts_with(|c: char| c.is_ascii_lowercase())
                && name[word.len()..].starts_with("  "))
            .then_some(word)
        })
        .collect();
    let flags = text
        .match_indices("--")
        .map(|(i, _)| {
            text[i..]
                .chars()
                .skip(2)
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect::<String>()
        })
        .filter(|f| !f.is_empty())
        .map(|f| format!("--{f}"))
        .collect();
    (subcommands, flags)
}

#[test]
fn every_flag_a_doc_gives_a_tilting_command_exists() {
    let mut cache: BTreeMap<(String, Vec<String>), Help> = BTreeMap::new();
    let mut bad = BTreeSet::new();
    let mut checked = 0;
    for (doc, bin, words) in command_lines() {
        let exe = tilting_tests::bin(&bin);
        // The subcommand path: the leading words that name a subcommand at each level.
        let mut path = Vec::new();
        for w in &words {
            let (subs, _) = cache
                .entry((bin.clone(), path.clone()))
                .or_insert_with(|| help(&exe, &path));
            if subs.contains(w.as_str()) {
                path.push(w.clone());
            } else {
                break;
            }
        }
        let (_, flags) = cache
            .entry((bin.clone(), path.clone()))
            .or_insert_with(|| help(&exe, &path))
            .clone();
        for w in &words {
            let w = w.trim_matches(|c: char| "[](){}'\",.:`".contains(c));
            let Some(name) = w.strip_prefix("--") else {
                continue;
            };
            let flag: String = name
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect();
            if flag.is_empty() || flag.ends_with('-') {
                continue; // `--state-...`: a family, not a flag
            }
            checked += 1;
            if !flags.contains(&format!("--{flag}")) {
                bad.insert(format!("{doc}: `{bin} {}` has no --{flag}", path.join(" ")));
            }
        }
    }
    assert!(
        checked > 100,
        "only {checked} flags found in the docs' command lines"
    );
    assert!(
        bad.is_empty(),
        "flags the docs give that the binaries do not take:\n{}",
        bad.into_iter().collect::<Vec<_>>().join("\n")
    );
}

/// GitHub's anchor of a heading: lower case, punctuation but `-` and `_` dropped, spaces to `-`.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// The anchors of a Markdown file's headings (outside code blocks), with GitHub's `-1`, `-2`
/// suffixes for repeated ones.
fn anchors(text: &str) -> BTreeSet<String> {
    let (_, prose) = split_fences(text);
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    for line in prose.lines() {
        let Some(h) = line.strip_prefix('#') else {
            continue;
        };
        let a = anchor(h.trim_start_matches('#'));
        let n = seen.entry(a.clone()).or_insert(0);
        out.insert(if *n == 0 {
            a.clone()
        } else {
            format!("{a}-{n}")
        });
        *n += 1;
    }
    out
}

/// The targets of a doc's Markdown links and images (`[text](target)`), outside code.
fn link_targets(prose: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (at, _) in prose.match_indices("](") {
        let rest = &prose[at + 2..];
        if let Some(end) = rest.find(')') {
            let target = rest[..end].split_whitespace().next().unwrap_or("");
            out.push(target.to_string());
        }
    }
    out
}

/// Docs linked before their file lands (another engineer writes them); the exception lapses
/// by itself once the file exists.
const PENDING: [&str; 1] = ["docs/mujoco.md"];

#[test]
fn every_file_and_link_a_doc_names_exists() {
    let root = workspace_root();
    let top: BTreeSet<String> = std::fs::read_dir(&root)
        .expect("workspace root")
        .flatten()
        .filter(|e| e.path().is_dir())
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| !n.starts_with('.') && n != "target")
        .collect();
    let mut bad = Vec::new();
    for path in doc_files() {
        let text = read_doc(&path);
        let dir = path.parent().expect("doc dir");
        let (_, prose) = split_fences(&text);
        // Links: a file that exists, an anchor its headings make.
        for target in link_targets(&prose) {
            if target.contains("://") || target.starts_with("mailto:") || target.is_empty() {
                continue;
            }
            let (file, frag) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let linked = if file.is_empty() {
                path.clone()
            } else {
                dir.join(file)
            };
            let linked_rel = rel(&std::fs::canonicalize(&linked).unwrap_or(linked.clone()));
            if !linked.exists() {
                let pending = PENDING.iter().any(|p| root.join(p) == normalize(&linked));
                if !pending {
                    bad.push(format!("{}: link to a missing file: {target}", rel(&path)));
                }
                continue;
            }
            if let Some(frag) = frag {
                if linked.extension().is_some_and(|x| x == "md")
                    && !anchors(&read_doc(&linked)).contains(frag)
                {
                    bad.push(format!(
                        "{}: {target}: {linked_rel} has no heading with the anchor #{frag}",
                        rel(&path)
                    ));
                }
            }
        }
        // Repository paths named in code spans (`tests/tests/front/layout.rs`, `bench/soak.sh`); not
        // in the dated records under bench/, which name the files of their day.
        let dated = path.starts_with(root.join("bench"));
        for (start, end, span) in code_spans_at(&prose).into_iter().filter(|_| !dated) {
            // `[`docs/design.md`](https://...)`: another repository's file.
            if prose[..start].ends_with('[') && prose[end..].starts_with("](http") {
                continue;
            }
            let p = span.trim().trim_end_matches(['.', ',', ':']);
            let p = p.split(':').next().unwrap_or(p); // `file.rs:120`
            let Some((first, _)) = p.split_once('/') else {
                continue;
            };
            // A file (`x.rs`) or a directory (`plant/src/node`, `bench/`), not a key expression
            // (`controller/torque`): the last part has an extension or the path names a
            // directory of ours.
            let last = p.trim_end_matches('/').rsplit('/').next().unwrap_or("");
            let looks_like_file = last.contains('.') || p.ends_with('/') || p.contains("/src/");
            if !top.contains(first)
                || !looks_like_file
                || p.contains(|c: char| c.is_whitespace() || "<>*${}|[]()".contains(c))
            {
                continue;
            }
            if !root.join(p).exists() {
                bad.push(format!("{}: `{p}` does not exist", rel(&path)));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Every `--test NAME` that a doc (but the dated records under bench/), `.ci/run` or a bench
/// script gives is a test target of the workspace: the test files merge into a few binaries
/// (issue 30), and a doc naming a target that went would have its reader run nothing.
#[test]
fn every_test_target_a_doc_names_exists() {
    let root = workspace_root();
    let targets: BTreeSet<String> = packages()
        .iter()
        .flat_map(|p| p["targets"].as_array().expect("targets").clone())
        .filter(|t| {
            t["kind"]
                .as_array()
                .is_some_and(|k| k.iter().any(|k| k == "test"))
        })
        .map(|t| t["name"].as_str().expect("a target's name").to_owned())
        .collect();
    let mut files: Vec<PathBuf> = doc_files()
        .into_iter()
        .filter(|p| !p.starts_with(root.join("bench")))
        .collect();
    files.push(root.join(".ci/run"));
    for e in std::fs::read_dir(root.join("bench"))
        .expect("bench/")
        .flatten()
    {
        if e.path().extension().is_some_and(|x| x == "sh") {
            files.push(e.path());
        }
    }
    let (mut named, mut bad) = (0, Vec::new());
    for path in files {
        let text = read_doc(&path);
        for (at, flag) in text.match_indices("--test ") {
            let name: String = text[at + flag.len()..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || "_-".contains(*c))
                .collect();
            if name.is_empty() {
                continue;
            }
            named += 1;
            if !targets.contains(&name) {
                bad.push(format!("{}: `--test {name}` is no test target", rel(&path)));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    // docs/ros2.md names the binary of its tests: the scan sees what the docs write.
    assert!(named > 0, "no `--test NAME` found in the docs");
}

/// `a/b/../c` as `a/c` (the linked file may not exist, so no canonicalize).
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            std::path::Component::ParentDir => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            c => out.push(c),
        }
    }
    out
}

/// The README and the guide are for users: no commit hashes, no issue numbers of a tracker
/// that is not in the repository.
#[test]
fn the_readme_and_the_guide_carry_no_commit_hashes_or_issue_numbers() {
    let root = workspace_root();
    let mut files = vec![root.join("README.md")];
    files.extend(
        doc_files()
            .into_iter()
            .filter(|p| p.starts_with(root.join("docs/guide"))),
    );
    let mut bad = Vec::new();
    for path in files {
        let text = read_doc(&path);
        for word in text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')) {
            let hexish = (7..=40).contains(&word.len())
                && word
                    .chars()
                    .all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase())
                && word.chars().any(|c| c.is_ascii_digit())
                && word.chars().any(|c| c.is_ascii_alphabetic());
            if hexish {
                bad.push(format!("{}: commit hash? {word}", rel(&path)));
            }
        }
        let lower = text.to_lowercase();
        for (at, _) in lower.match_indices("issue") {
            let rest = lower[at + 5..].trim_start_matches('s').trim_start();
            if rest.starts_with(|c: char| c.is_ascii_digit() || c == '#') {
                bad.push(format!(
                    "{}: issue number: {}",
                    rel(&path),
                    &text[at..at + 12]
                ));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The README's two command lines are the ones a newcomer types, and CI runs the second.
#[test]
fn the_readme_gives_the_two_commands_and_ci_runs_its_test_command() {
    let root = workspace_root();
    let (code, _) = split_fences(&read_doc(&root.join("README.md")));
    for line in [
        "cargo build --release --workspace && ./target/release/tilting live --duration 20",
        "cargo test --workspace --release",
    ] {
        assert!(
            code.iter().any(|l| l.trim() == line),
            "the README's code blocks lack the command line `{line}`"
        );
    }
    let ci = read_doc(&root.join(".ci/run"));
    assert!(
        ci.lines()
            .any(|l| l.trim() == "cargo test --workspace --release"),
        ".ci/run no longer runs the README's test command `cargo test --workspace --release`"
    );
}
