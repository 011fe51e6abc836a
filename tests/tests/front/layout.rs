//! The layout of the workspace, checked against the Cargo manifests and the sources:
//!
//! - `docs/architecture.md` lists every crate, and its generated table equals what the
//!   manifests say (`TILTING_BLESS=1` rewrites the table instead of failing);
//! - every build of any subset of the workspace resolves the same features for every
//!   third-party crate (the `workspace-hack` crate's job), so no command rebuilds zenoh;
//! - no non-test function is longer than [`MAX_FN_LINES`] lines unless a `// long:` comment
//!   just above it says why (a table, such as the DOP853 tableau);
//! - the front door stays thin: `cli/src` holds fewer than [`MAX_CLI_LINES`] non-test lines;
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
/// The excuse is for a table (the DOP853 tableau), not for a function that does several steps.
const MAX_FN_LINES: usize = 100;

/// Non-test lines allowed in `cli/src` (every line of its `.rs` files but `tests.rs` files and
/// what follows a top-level `#[cfg(test)]`): the front door parses, calls a library, prints.
const MAX_CLI_LINES: usize = 3000;

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
        } else if name.ends_with(".rs") && name != "tests.rs" {
            // A `tests.rs` is a module's unit tests moved out of its file (`#[cfg(test)] mod
            // tests;`): test code, as the `#[cfg(test)]` that ends the scan of a file.
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
        // The signature ends at the first line ending in `{` (a body), `;` (a declaration) or
        // `}` (a body on the signature's line: `fn f() {}`).
        let sig_end = lines[i..]
            .iter()
            .find(|x| x.ends_with('{') || x.ends_with(';') || x.ends_with('}'));
        if !is_fn || sig_end.is_none_or(|x| !x.ends_with('{')) {
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
    // A one-line body before a long method: one line, not the span to the method's closing
    // brace (at the same indentation).
    let body = "        let x = 1;\n".repeat(MAX_FN_LINES);
    let text = format!(
        "impl P for () {{\n    fn a(&self) {{}}\n}}\nimpl Q {{\n    fn c() {{\n{body}    }}\n}}\n"
    );
    let found = long_functions(&text);
    assert_eq!(found, vec![(5, "c".to_owned(), MAX_FN_LINES + 2)]);
}

/// Non-test lines of a source file: all of them up to a top-level `#[cfg(test)]`.
fn non_test_lines(text: &str) -> usize {
    text.lines().take_while(|l| *l != "#[cfg(test)]").count()
}

#[test]
fn the_front_door_stays_thin() {
    let src = workspace_root().join("cli/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    assert!(
        files.len() > 5,
        "found only {} files in cli/src",
        files.len()
    );
    let lines: usize = files
        .iter()
        .map(|f| non_test_lines(&std::fs::read_to_string(f).expect("read source")))
        .sum();
    assert!(
        non_test_lines("fn a() {}\n#[cfg(test)]\nmod tests {}\n") == 1,
        "the count stops at the test module"
    );
    assert!(
        lines < MAX_CLI_LINES,
        "cli/src holds {lines} non-test lines, at most {} allowed: move validation and logic \
         into the library crates where their types live (issue 30)",
        MAX_CLI_LINES - 1
    );
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

// The docs' facts: docs.rs.
mod docs;
