//! The workspace's sources, for the tests that read them (`layers`, `names`).

use std::fs;
use std::path::{Path, PathBuf};

/// The crates of the workspace, as source directories relative to the core's manifest.
pub const CRATES: &[&str] = &[
    "src",
    "../geomint-api/src",
    "../geomint-py/src",
    "../../src",
];

/// The source directory of crate `dir` (one of [`CRATES`]).
pub fn root(dir: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(dir)
}

/// Every `.rs` file under `dir`.
pub fn sources(dir: &Path) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in fs::read_dir(dir).expect("a source directory") {
            let path = entry.expect("a directory entry").path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, &mut out);
    out
}
