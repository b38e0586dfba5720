//! The repository's layout holds what its docs promise: every path the docs name exists, and no
//! crate's files import each other in a circle (docs/architecture.md).

mod docs;
mod imports;

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The files git tracks, relative to the root (with those added but not committed yet).
fn tracked_files() -> Vec<String> {
    let out = Command::new("git")
        .args(["ls-files", "--cached", "--others", "--exclude-standard"])
        .current_dir(root())
        .output()
        .expect("git runs");
    assert!(
        out.status.success(),
        "git ls-files (the test reads a git checkout): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("paths are UTF-8").lines().map(str::to_owned).collect()
}

#[test]
fn every_repository_path_the_docs_name_exists() {
    let files = tracked_files();
    let docs: Vec<&String> = files
        .iter()
        .filter(|f| *f == "README.md" || (f.starts_with("docs/") && f.ends_with(".md") && !f[5..].contains('/')))
        .collect();
    assert!(docs.len() > 10, "README.md and docs/*.md are found: {docs:?}");
    let tracked = docs::Tracked { files: &files };
    let mut missing = Vec::new();
    for doc in docs {
        let text = std::fs::read_to_string(root().join(doc)).expect("a tracked doc reads");
        missing.extend(docs::missing_paths(doc, &text, &tracked));
    }
    let listed: Vec<String> = missing.iter().map(|m| format!("{}:{}: {}", m.doc, m.line, m.path)).collect();
    assert!(listed.is_empty(), "paths named in the docs that do not exist:\n{}", listed.join("\n"));
}

#[test]
fn no_crate_imports_in_a_circle_among_its_files() {
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).expect("the workspace manifest reads");
    let members = manifest.split("members = [").nth(1).and_then(|m| m.split(']').next()).expect("members listed");
    let mut circles = Vec::new();
    let mut crates = 0;
    for member in members.split(',').map(|m| m.trim().trim_matches('"')).filter(|m| !m.is_empty()) {
        for root_file in ["src/lib.rs", "src/main.rs"] {
            let path = root().join(member).join(root_file);
            if !path.exists() {
                continue;
            }
            crates += 1;
            let krate = imports::Crate::read(&path);
            for circle in imports::circles(&krate.imports()) {
                let files: Vec<String> = circle
                    .iter()
                    .map(|m| krate.modules[m].strip_prefix(root()).unwrap().display().to_string())
                    .collect();
                circles.push(files.join(" <-> "));
            }
        }
    }
    assert!(crates >= 14, "every member's crate roots read: {crates}");
    assert!(circles.is_empty(), "files that import each other in a circle:\n{}", circles.join("\n"));
}
