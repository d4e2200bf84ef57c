//! Every type of the workspace has a name of its own: no two items declared at a module's top
//! level (`struct`, `enum`, `trait`, `type`, public or not) share a name, in any crate, so a name
//! read anywhere says which type it is. Associated types (`type Cell;` inside a trait or an
//! impl) are indented and live in their trait's namespace: they are not counted.

use std::collections::BTreeMap;
use std::fs;

use crate::workspace::{root, sources, CRATES};

/// The name a line declares, if it starts (unindented) a `struct`, `enum`, `trait` or `type`
/// item, with or without a visibility.
fn declared(line: &str) -> Option<&str> {
    let mut rest = line;
    if let Some(after) = rest.strip_prefix("pub") {
        rest = after;
        if rest.starts_with('(') {
            rest = &rest[rest.find(')')? + 1..];
        }
        rest = rest.strip_prefix(' ')?;
    }
    let rest = ["struct ", "enum ", "trait ", "type "]
        .iter()
        .find_map(|keyword| rest.strip_prefix(keyword))?;
    let end = rest
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(rest.len());
    Some(&rest[..end]).filter(|name| !name.is_empty())
}

#[test]
fn declared_recognises_items_and_leaves_associated_types() {
    assert_eq!(declared("pub struct RunReport {"), Some("RunReport"));
    assert_eq!(
        declared("pub(crate) enum Lanes<const N: usize> {"),
        Some("Lanes")
    );
    assert_eq!(
        declared("pub(super) struct KnownStages<K>(PhantomData<K>);"),
        Some("KnownStages")
    );
    assert_eq!(declared("trait ChartKernel {"), Some("ChartKernel"));
    assert_eq!(declared("type Output = BufWriter<File>;"), Some("Output"));
    assert_eq!(declared("    type Cell: Clone;"), None);
    assert_eq!(declared("pub fn structure(&self) {"), None);
    assert_eq!(declared("// struct Commented"), None);
}

#[test]
fn every_type_of_the_workspace_has_a_name_of_its_own() {
    let mut declarations: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut files = 0;
    for krate in CRATES {
        for path in sources(&root(krate)) {
            files += 1;
            let text = fs::read_to_string(&path).expect("a readable source");
            for (number, line) in text.lines().enumerate() {
                if let Some(name) = declared(line) {
                    let place = format!("{}:{}", path.display(), number + 1);
                    declarations
                        .entry(name.to_string())
                        .or_default()
                        .push(place);
                }
            }
        }
    }
    // The scan saw the workspace (about 200 files and 150 types), the core's own among them.
    assert!(files > 150, "only {files} source files read");
    assert!(
        declarations.len() > 120,
        "only {} types",
        declarations.len()
    );
    assert!(declarations.contains_key("MechanicalSystem"));
    let repeated: Vec<String> = declarations
        .iter()
        .filter(|(_, places)| places.len() > 1)
        .map(|(name, places)| format!("{name}: {}", places.join(", ")))
        .collect();
    assert!(
        repeated.is_empty(),
        "types declared more than once:\n{}",
        repeated.join("\n")
    );
}
