//! The docs state the current truth: every source file of the workspace is named
//! in docs/ARCHITECTURE.md (in its crate's section), every repository path the
//! docs cite exists, and docs/PERFORMANCE.md keeps to its size rules.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

/// Most lines docs/PERFORMANCE.md may have.
const PERFORMANCE_MAX_LINES: usize = 300;
/// Most rows its table of experiments not kept may have.
const NOT_KEPT_MAX_ROWS: usize = 20;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).expect("readable source folder") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The part of ARCHITECTURE.md under the `## name` heading, up to the next `## `.
fn section<'a>(doc: &'a str, name: &str) -> Option<&'a str> {
    let start = doc.find(&format!("\n## {name}\n"))? + 1;
    let rest = &doc[start..];
    let end = rest[3..].find("\n## ").map_or(rest.len(), |e| e + 4);
    Some(&rest[..end])
}

/// Whether `section` names the file at `rel` (its path under `src/`): the path
/// itself in backquotes, or, for a file in a folder, a line naming the folder
/// (`aff/`) and the file; `mod.rs` and `lib.rs` by the `*/mod.rs` or `lib.rs` row.
fn names(section: &str, rel: &str) -> bool {
    if section.contains(&format!("`{rel}`")) {
        return true;
    }
    let (folder, file) = match rel.rsplit_once('/') {
        Some((folder, file)) => (Some(folder), file),
        None => (None, rel),
    };
    if file == "mod.rs" {
        return section.contains("`*/mod.rs`") || folder.is_some_and(|f| section.contains(&format!("`{f}/`")));
    }
    match folder {
        None => false,
        Some(folder) => section
            .lines()
            .any(|line| line.contains(&format!("`{folder}/`")) && line.contains(&format!("`{file}`"))),
    }
}

#[test]
fn every_source_file_is_named_in_architecture() {
    let root = root();
    let doc = fs::read_to_string(root.join("docs/ARCHITECTURE.md")).expect("docs/ARCHITECTURE.md");
    let mut missing = Vec::new();
    for parent in ["crates", "apps"] {
        for krate in fs::read_dir(root.join(parent)).expect("crate folder") {
            let krate = krate.expect("entry").path();
            let src = krate.join("src");
            if !src.is_dir() {
                continue;
            }
            let name = krate
                .file_name()
                .and_then(|n| n.to_str())
                .expect("crate name")
                .to_owned();
            let heading = format!("{parent}/{name}");
            let Some(text) = section(&doc, &name).or_else(|| section(&doc, &heading)) else {
                missing.push(format!("no section '## {name}' or '## {heading}'"));
                continue;
            };
            let mut files = Vec::new();
            rust_files(&src, &mut files);
            for file in files {
                let rel = file
                    .strip_prefix(&src)
                    .expect("under src")
                    .to_string_lossy()
                    .replace('\\', "/");
                if !names(text, &rel) {
                    missing.push(format!("{heading}/src/{rel}"));
                }
            }
        }
    }
    assert!(
        missing.is_empty(),
        "files not named in docs/ARCHITECTURE.md: {missing:#?}"
    );
}

/// Repository paths cited in a doc: backquoted or linked tokens that start with
/// a top-level folder of the workspace and name no placeholder.
fn cited_paths(text: &str) -> BTreeSet<String> {
    const TOP: [&str; 8] = [
        "docs/", "scripts/", "crates/", "apps/", "scenes/", "fuzz/", ".ci/", "tests/",
    ];
    let mut out = BTreeSet::new();
    for token in text.split(|c: char| c.is_whitespace() || matches!(c, '`' | '(' | ')' | '[' | ']' | ',' | ';' | '"')) {
        let token = token.trim_end_matches(['.', ':']);
        if !TOP.iter().any(|top| token.starts_with(top)) {
            continue;
        }
        if token.contains(['*', '{', '<', '|', '$']) || token.ends_with('/') {
            continue;
        }
        let last = token.rsplit('/').next().unwrap_or(token);
        if last.contains('.') {
            out.insert(token.to_owned());
        }
    }
    out
}

#[test]
fn every_cited_repository_file_exists() {
    let root = root();
    let mut docs = vec![root.join("README.md")];
    for entry in fs::read_dir(root.join("docs")).expect("docs/") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "md") {
            docs.push(path);
        }
    }
    let mut broken = Vec::new();
    for doc in &docs {
        let text = fs::read_to_string(doc).expect("readable doc");
        for cited in cited_paths(&text) {
            if !root.join(&cited).exists() {
                broken.push(format!("{}: {cited}", doc.file_name().unwrap().to_string_lossy()));
            }
        }
    }
    assert!(broken.is_empty(), "docs cite files that do not exist: {broken:#?}");
}

#[test]
fn cited_paths_finds_paths_and_skips_placeholders() {
    let found = cited_paths("see `docs/A.md`, [b](scripts/b.sh). and crates/*/src or docs/ or `apps/x/{a,b}.rs`");
    assert_eq!(
        found.into_iter().collect::<Vec<_>>(),
        vec!["docs/A.md".to_owned(), "scripts/b.sh".to_owned()]
    );
}

#[test]
fn names_accepts_paths_and_folder_rows_only() {
    let section =
        "| `geom/ray.rs` | rays |\n| `aff/` | `tokens.rs`, `parser.rs` |\n| `lib.rs`, `*/mod.rs` | modules |\n";
    assert!(names(section, "geom/ray.rs"));
    assert!(names(section, "aff/parser.rs"));
    assert!(names(section, "kd/mod.rs"));
    assert!(!names(section, "geom/aabb.rs"));
    assert!(!names(section, "bvh/parser.rs"));
    assert!(!names(section, "ray.rs"));
}

#[test]
fn performance_doc_keeps_its_size_rules() {
    let text = fs::read_to_string(root().join("docs/PERFORMANCE.md")).expect("docs/PERFORMANCE.md");
    let lines = text.lines().count();
    assert!(
        lines <= PERFORMANCE_MAX_LINES,
        "docs/PERFORMANCE.md has {lines} lines (at most {PERFORMANCE_MAX_LINES})"
    );
    let table = text
        .split("\n## Tried and not kept")
        .nth(1)
        .expect("a 'Tried and not kept' section");
    let rows = table
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| what"))
        .count();
    assert!(
        rows <= NOT_KEPT_MAX_ROWS,
        "{rows} experiments not kept (at most {NOT_KEPT_MAX_ROWS})"
    );
    for phrase in ["this morning", "yesterday", "today", "this session", "in a calmer hour"] {
        assert!(
            !text.to_lowercase().contains(phrase),
            "docs/PERFORMANCE.md reads like a diary: '{phrase}'"
        );
    }
}
