//! No module imports one that imports it back: the top-level modules of every crate of the
//! workspace, read from their source, form layers (a graph without a cycle). An edge is a path
//! in code (comments aside) that names another top-level module of the same crate — `crate::x`,
//! `$crate::x`, or `super::x` from a top-level module's own file. The test names the modules of
//! each cycle, and one path of the cycle with a file that makes each edge.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::Path;

use crate::workspace::{root, sources, CRATES};

/// The top-level module a file belongs to (`None` for the crate root's own file), and whether
/// the file is that module's own (where `super::` names the crate root).
fn module_of(root: &Path, file: &Path) -> Option<(String, bool)> {
    let relative = file.strip_prefix(root).ok()?;
    let parts: Vec<&str> = relative.iter().filter_map(|p| p.to_str()).collect();
    match parts.as_slice() {
        [single] if *single == "lib.rs" || *single == "main.rs" => None,
        [single] => Some((single.trim_end_matches(".rs").to_string(), true)),
        [dir, rest @ ..] => Some((dir.to_string(), rest == ["mod.rs"])),
        [] => None,
    }
}

/// The names that follow `prefix` in `line` (identifiers only).
fn names_after<'a>(line: &'a str, prefix: &str) -> Vec<&'a str> {
    line.match_indices(prefix)
        .filter(|(at, _)| {
            // `crate::` preceded by an identifier character is another path (`$crate` aside).
            let before = line[..*at].chars().next_back();
            prefix.starts_with('$') || !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
        })
        .map(|(at, _)| {
            let rest = &line[at + prefix.len()..];
            let end = rest
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            &rest[..end]
        })
        .collect()
}

/// The graph of a crate's top-level modules: module → (module it names → a file that does).
fn graph(root: &Path) -> BTreeMap<String, BTreeMap<String, String>> {
    let files = sources(root);
    let modules: BTreeSet<String> = files
        .iter()
        .filter_map(|f| module_of(root, f).map(|(m, _)| m))
        .collect();
    let mut edges: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for file in &files {
        let Some((module, own)) = module_of(root, file) else {
            continue;
        };
        let text = fs::read_to_string(file).expect("a readable source file");
        for line in text.lines() {
            let code = line.split("//").next().unwrap_or("");
            let mut named = names_after(code, "crate::");
            if own {
                named.extend(names_after(code, "super::"));
            }
            for target in named {
                if target != module && modules.contains(target) {
                    edges
                        .entry(module.clone())
                        .or_default()
                        .entry(target.to_string())
                        .or_insert_with(|| file.display().to_string());
                }
            }
        }
    }
    edges
}

/// A cycle through `start`, if there is one: the modules in order, back to `start`.
fn cycle_through(
    edges: &BTreeMap<String, BTreeMap<String, String>>,
    start: &str,
) -> Option<Vec<String>> {
    let mut path = vec![start.to_string()];
    let mut seen = BTreeSet::new();
    fn walk(
        edges: &BTreeMap<String, BTreeMap<String, String>>,
        start: &str,
        path: &mut Vec<String>,
        seen: &mut BTreeSet<String>,
    ) -> bool {
        let here = path.last().expect("a path").clone();
        for next in edges.get(&here).into_iter().flat_map(|e| e.keys()) {
            if next == start {
                path.push(next.clone());
                return true;
            }
            if seen.insert(next.clone()) {
                path.push(next.clone());
                if walk(edges, start, path, seen) {
                    return true;
                }
                path.pop();
            }
        }
        false
    }
    walk(edges, start, &mut path, &mut seen).then_some(path)
}

#[test]
fn no_module_imports_one_that_imports_it_back() {
    let mut cycles = Vec::new();
    let mut modules_seen = 0;
    for dir in CRATES {
        let edges = graph(&root(dir));
        modules_seen += edges.len();
        let mut reported = BTreeSet::new();
        for start in edges.keys() {
            if reported.contains(start) {
                continue;
            }
            if let Some(cycle) = cycle_through(&edges, start) {
                let steps: Vec<String> = cycle
                    .windows(2)
                    .map(|w| format!("{} → {} ({})", w[0], w[1], edges[&w[0]][&w[1]]))
                    .collect();
                reported.extend(cycle.iter().cloned());
                cycles.push(format!("in {dir}: {}", steps.join(", ")));
            }
        }
    }
    // The scan found the workspace's modules (a wrong path would find none and pass).
    assert!(
        modules_seen >= 20,
        "only {modules_seen} modules with imports found"
    );
    assert!(
        cycles.is_empty(),
        "modules that import each other:\n{}",
        cycles.join("\n")
    );
}
