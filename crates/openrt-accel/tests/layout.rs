//! The crate's layout: modules in folders by concept import each other
//! directly (never through the crate root's re-exports), and no module
//! imports another that imports it back, directly or through others.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Module path (`kd::tree`) of each source file, with its text outside
/// comments and unit tests.
fn modules(dir: &Path, prefix: &str, out: &mut BTreeMap<String, String>) {
    for entry in std::fs::read_dir(dir).expect("src is readable") {
        let path = entry.expect("a directory entry").path();
        let stem = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default()
            .to_string();
        if path.is_dir() {
            modules(&path, &format!("{prefix}{stem}::"), out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            let name = if stem == "mod" {
                prefix.trim_end_matches("::").to_string()
            } else {
                format!("{prefix}{stem}")
            };
            let text = std::fs::read_to_string(&path).expect("a source file");
            let code = text.split("#[cfg(test)]\nmod tests").next().unwrap_or_default();
            let code: String = code
                .lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .collect::<Vec<_>>()
                .join("\n");
            out.insert(name, code);
        }
    }
}

/// The modules each module names through `crate::a::b...` paths (the
/// longest prefix that is a module), and the root re-exports it uses.
fn graph() -> (BTreeMap<String, BTreeSet<String>>, Vec<String>) {
    let mut mods = BTreeMap::new();
    modules(&Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), "", &mut mods);
    let names: BTreeSet<String> = mods.keys().cloned().collect();
    let mut graph = BTreeMap::new();
    let mut through_root = Vec::new();
    for (name, code) in &mods {
        let mut deps = BTreeSet::new();
        for (i, _) in code.match_indices("crate::") {
            let rest = &code[i + 7..];
            let path: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let parts: Vec<&str> = path.split("::").filter(|p| !p.is_empty()).collect();
            let found = (1..=parts.len())
                .rev()
                .map(|k| parts[..k].join("::"))
                .find(|m| names.contains(m));
            match found {
                Some(m) => {
                    if m != *name && !name.starts_with(&format!("{m}::")) {
                        deps.insert(m);
                    }
                }
                None => {
                    if name != "lib" {
                        through_root.push(format!("{name}: crate::{path}"));
                    }
                }
            }
        }
        graph.insert(name.clone(), deps);
    }
    (graph, through_root)
}

#[test]
fn modules_import_each_other_directly() {
    let (_, through_root) = graph();
    assert!(
        through_root.is_empty(),
        "imports through the crate root: {through_root:#?}"
    );
}

/// Depth-first search from `n` for a back edge: the circle found, if any.
fn visit<'a>(
    n: &'a str,
    graph: &'a BTreeMap<String, BTreeSet<String>>,
    state: &mut BTreeMap<&'a str, u8>,
    path: &mut Vec<&'a str>,
) -> Option<Vec<String>> {
    state.insert(n, 1);
    path.push(n);
    for d in graph.get(n).into_iter().flatten() {
        match state.get(d.as_str()) {
            Some(1) => {
                let at = path.iter().position(|p| p == d).unwrap_or(0);
                return Some(path[at..].iter().map(|s| (*s).to_string()).collect());
            }
            Some(_) => {}
            None => {
                if let Some(c) = visit(d, graph, state, path) {
                    return Some(c);
                }
            }
        }
    }
    path.pop();
    state.insert(n, 2);
    None
}

#[test]
fn no_module_imports_itself_back() {
    let (graph, _) = graph();
    assert!(graph.len() > 30, "{} modules: the walk found too few", graph.len());
    let mut state = BTreeMap::new();
    for n in graph.keys() {
        if !state.contains_key(n.as_str()) {
            let cycle = visit(n, &graph, &mut state, &mut Vec::new());
            assert!(cycle.is_none(), "an import circle: {cycle:?}");
        }
    }
}
