//! The layout of the workspace, checked against the Cargo manifests and the sources:
//!
//! - `docs/architecture.md` lists every crate, and its generated table equals what the
//!   manifests say (`TILTING_BLESS=1` rewrites the table instead of failing);
//! - every build of any subset of the workspace resolves the same features for every
//!   third-party crate (the `workspace-hack` crate's job), so no command rebuilds zenoh;
//! - no non-test function is longer than [`MAX_FN_LINES`] lines unless a `// long:` comment
//!   just above it says why;
//! - the docs' facts: the minimum Rust version they name is Cargo.toml's `rust-version`, the
//!   message sizes are what `tilting_proto::codec` encodes, every `--flag` of a `tilting ...`
//!   (or node binary) command line is in that command's `--help`, every link and every
//!   repository path they name exists (anchors included), and the README and the guide carry
//!   no commit hashes or issue numbers.
//!
//! These read `cargo metadata` and `cargo tree`, offline: they compile nothing, except the flag
//! check, which runs the built binaries (`tilting_tests::bin` builds them first).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use tilting_tests::workspace_root;

const BEGIN: &str =
    "<!-- BEGIN GENERATED: crates (tests/tests/front/layout.rs; TILTING_BLESS=1 to rewrite) -->";
const END: &str = "<!-- END GENERATED: crates -->";

/// Runs `cargo ARGS` in the workspace (`metadata`, `tree`: offline, compiling nothing) and
/// returns its stdout. It takes a `realtime_turn`: `cargo tree` over the workspace's subsets
/// fills a core for seconds, and the loops of this binary's other modules would miss deadlines
/// beside it (in a binary of its own, before issue 30's merge, it never ran beside them).
fn cargo(args: &[&str]) -> String {
    let _turn = tilting_tests::realtime_turn();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(args)
        .current_dir(workspace_root())
        .output()
        .expect("cannot run cargo");
    assert!(
        out.status.success(),
        "cargo {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8 from cargo")
}

/// The workspace's packages from `cargo metadata --no-deps`.
fn packages() -> Vec<Value> {
    let text = cargo(&[
        "metadata",
        "--format-version",
        "1",
        "--no-deps",
        "--offline",
    ]);
    let meta: Value = serde_json::from_str(&text).expect("cargo metadata is JSON");
    meta["packages"].as_array().expect("packages").clone()
}

/// How many workspace crates stand below `name` on its longest dependency chain (plumbing
/// excluded): the table lists the wire format first and the front door last.
fn depth(pkgs: &[Value], name: &str) -> usize {
    let Some(p) = pkgs.iter().find(|p| p["name"] == name) else {
        return 0;
    };
    p["dependencies"]
        .as_array()
        .expect("deps")
        .iter()
        .filter(|d| d["path"].is_string() && d["name"] != "workspace-hack" && d["kind"].is_null())
        .map(|d| 1 + depth(pkgs, d["name"].as_str().expect("dep name")))
        .max()
        .unwrap_or(0)
}

/// The crate table of the architecture doc, from the manifests: one row per member, with its
/// directory, its description, and its dependencies inside and outside the workspace.
fn crate_table(pkgs: &[Value]) -> String {
    let root = workspace_root();
    let mut rows = Vec::new();
    for p in pkgs {
        let name = p["name"].as_str().expect("name");
        let manifest = PathBuf::from(p["manifest_path"].as_str().expect("manifest"));
        let dir = manifest
            .parent()
            .and_then(|d| d.strip_prefix(&root).ok())
            .map(|d| d.display().to_string())
            .unwrap_or_default();
        let desc = p["description"].as_str().unwrap_or("").replace('|', "\\|");
        let (mut inner, mut outer) = (BTreeSet::new(), BTreeSet::new());
        for d in p["dependencies"].as_array().expect("deps") {
            let dep = d["name"].as_str().expect("dep name");
            if dep == "workspace-hack" || d["kind"].as_str().is_some() {
                continue; // plumbing, and dev/build dependencies
            }
            let shown = if d["optional"].as_bool() == Some(true) {
                format!("({dep})")
            } else {
                dep.to_string()
            };
            if d["path"].is_string() {
                inner.insert(shown);
            } else {
                outer.insert(shown);
            }
        }
        if name == "workspace-hack" {
            outer = BTreeSet::from(["(generated)".to_string()]);
        }
        // Alphabetical, optional ones (in parentheses) among the others.
        let join = |s: BTreeSet<String>| {
            let mut v: Vec<String> = s.into_iter().collect();
            v.sort_by_key(|d| d.trim_matches(['(', ')']).to_string());
            v.join(", ")
        };
        rows.push((
            // Plumbing last.
            (
                if name == "workspace-hack" {
                    usize::MAX
                } else {
                    depth(pkgs, name)
                },
                name.to_string(),
            ),
            format!(
                "| `{name}` | `{dir}/` | {desc} | {} | {} |",
                join(inner),
                join(outer)
            ),
        ));
    }
    rows.sort();
    let mut t = String::from(
        "| crate | directory | what it holds | depends on (workspace) | depends on (third party) |\n\
         |---|---|---|---|---|\n",
    );
    for (_, r) in rows {
        t.push_str(&r);
        t.push('\n');
    }
    t.push_str(
        "\nA name in parentheses is an optional dependency (behind a feature, mostly `node`).\n",
    );
    t
}

#[test]
fn architecture_doc_lists_every_crate_as_the_manifests_say() {
    let pkgs = packages();
    let path = workspace_root().join("docs/architecture.md");
    let doc = std::fs::read_to_string(&path).expect("docs/architecture.md");
    let (Some(b), Some(e)) = (doc.find(BEGIN), doc.find(END)) else {
        panic!("docs/architecture.md lacks the generated crate table markers:\n{BEGIN}\n{END}");
    };
    let want = format!("{BEGIN}\n{}{END}", crate_table(&pkgs));
    let have = &doc[b..e + END.len()];
    if have != want {
        if std::env::var_os("TILTING_BLESS").is_some() {
            let new = format!("{}{want}{}", &doc[..b], &doc[e + END.len()..]);
            std::fs::write(&path, new).expect("write docs/architecture.md");
        } else {
            panic!(
                "docs/architecture.md's crate table is out of date with the Cargo.toml files; \
                 rerun with TILTING_BLESS=1 to rewrite it. Expected:\n{want}"
            );
        }
    }
    // The hand-drawn diagram above the table names every crate but the plumbing.
    let diagram = &doc[..b];
    for p in &pkgs {
        let name = p["name"].as_str().expect("name");
        if name == "workspace-hack" || name == "tilting" {
            continue;
        }
        assert!(
            diagram.contains(name),
            "the diagram in docs/architecture.md does not show `{name}`"
        );
    }
}

/// Third-party packages with their features, as `cargo tree` resolves them for `sel`.
fn resolved(sel: &[&str]) -> BTreeMap<String, String> {
    let mut args = vec![
        "tree",
        "--offline",
        "-e",
        "normal,build,dev",
        "--prefix",
        "none",
    ];
    args.extend(["-f", "{p} [{f}]"]);
    args.extend_from_slice(sel);
    let text = cargo(&args);
    let mut m = BTreeMap::new();
    for line in text.lines() {
        let line = line.trim_end_matches(" (*)").replace(" (proc-macro)", "");
        if line.is_empty() || line.contains("(/") {
            continue; // workspace members carry their path; their own features may differ
        }
        let (pkg, feats) = line.split_once(" [").unwrap_or((&line, ""));
        m.insert(pkg.to_string(), feats.to_string());
    }
    m
}

#[test]
fn every_build_resolves_the_same_third_party_features() {
    let all = resolved(&["--workspace"]);
    assert!(
        all.keys().any(|k| k.starts_with("zenoh v")),
        "zenoh not in the tree"
    );
    for p in packages() {
        let name = p["name"].as_str().expect("name");
        let one = resolved(&["-p", name]);
        for (pkg, feats) in &one {
            let ws = all
                .get(pkg)
                .unwrap_or_else(|| panic!("`-p {name}` builds {pkg}, the workspace does not"));
            assert_eq!(
                feats, ws,
                "`cargo build -p {name}` builds {pkg} with features [{feats}], the workspace with \
                 [{ws}]: it would rebuild it and everything above. Run `cargo hakari generate && \
                 cargo hakari manage-deps` (cargo install cargo-hakari)"
            );
        }
    }
}

/// Longest non-test function, in lines from `fn` to its closing brace, allowed without a
/// `// long: <why>` comment on the lines just above it (attributes and doc comments between).
const MAX_FN_LINES: usize = 150;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().to_string();
        if p.is_dir() {
            // Test directories, build output, the separate benchmark workspace and the patched
            // third-party crates (upstream's code, upstream's conventions).
            if !matches!(
                name.as_str(),
                "target" | "tests" | "bench" | "third_party" | ".git"
            ) {
                rust_files(&p, out);
            }
        } else if name.ends_with(".rs") {
            out.push(p);
        }
    }
}

/// Functions of one rustfmt-formatted file longer than [`MAX_FN_LINES`] and not excused:
/// `(line, name, length)`. A function ends at the first line that is its indentation plus `}`;
/// a `#[cfg(test)]` item at the top level ends the scan (test modules come last here).
fn long_functions(text: &str) -> Vec<(usize, String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        if *l == "#[cfg(test)]" {
            break;
        }
        let t = l.trim_start();
        let indent = l.len() - t.len();
        let Some(at) = t.find("fn ") else { continue };
        let head = &t[..at];
        let is_fn = head.split_whitespace().all(|w| {
            matches!(w, "pub" | "async" | "const" | "unsafe" | "extern") || w.starts_with("pub(")
        });
        // The signature ends at the first line ending in `{` (a body) or `;` (a declaration).
        let sig_end = lines[i..]
            .iter()
            .find(|x| x.ends_with('{') || x.ends_with(';'));
        if !is_fn || sig_end.is_none_or(|x| x.ends_with(';')) {
            continue;
        }
        let name: String = t[at + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let close = format!("{}}}", " ".repeat(indent));
        let Some(len) = lines[i..].iter().position(|x| *x == close) else {
            continue; // a declaration without a body
        };
        let mut j = i;
        let mut excused = false;
        while j > 0 {
            j -= 1;
            let above = lines[j].trim_start();
            if above.starts_with("// long:") {
                excused = true;
                break;
            }
            if !(above.starts_with("#[") || above.starts_with("///") || above.starts_with("//")) {
                break;
            }
        }
        if len + 1 > MAX_FN_LINES && !excused {
            found.push((i + 1, name, len + 1));
        }
    }
    found
}

#[test]
fn the_length_rule_sees_a_long_function_and_its_excuse() {
    let body = "    let x = 1;\n".repeat(MAX_FN_LINES);
    let long = format!("pub fn big() {{\n{body}}}\n");
    assert_eq!(long_functions(&long).len(), 1);
    let excused = format!("// long: one table\n#[inline]\n{long}");
    assert!(long_functions(&excused).is_empty());
    let short = "fn small() {\n    1;\n}\n";
    assert!(long_functions(short).is_empty());
}

#[test]
fn no_function_is_long_without_a_reason() {
    let root = workspace_root();
    let mut files = Vec::new();
    rust_files(&root, &mut files);
    assert!(files.len() > 50, "found only {} source files", files.len());
    let mut bad = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).expect("read source");
        for (line, name, len) in long_functions(&text) {
            let rel = f.strip_prefix(&root).unwrap_or(&f).display().to_string();
            bad.push(format!("{rel}:{line} fn {name}: {len} lines"));
        }
    }
    assert!(
        bad.is_empty(),
        "functions over {MAX_FN_LINES} lines without a `// long: <why>` comment above:\n{}",
        bad.join("\n")
    );
}

// ---------------------------------------------------------------------------------------------
// The docs' facts: what a doc states about the code is checked against the code, so a fact that
// drifts fails here (the minimum Rust version, the message sizes, every flag of a `tilting`
// command line, every file and link).

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
