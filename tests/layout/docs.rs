//! The repository paths that README.md and docs/*.md name.
//!
//! A path is named in a link (`[text](path)`, relative to the document) or in code spans
//! (`` `cloud/src/network/mod.rs` ``): a span's first word whose first two segments are a
//! folder of the repository and an entry in it (`transport/link/…`, a Zenoh setting, is not
//! a path of ours), or one that ends in `.rs` or `.proto` and starts with the name of a folder
//! of ours (`network/receive.rs`: then some file of the repository must end with it). A
//! placeholder (`<site>`, `*`, `{a,b}`) ends the part checked, and `:line`, `::item` or
//! `#anchor` suffixes are not part of the path.

use std::path::Path;

/// One path a document names.
#[derive(Debug)]
pub struct Named {
    pub doc: String,
    pub line: usize,
    pub path: String,
}

/// Every path `doc` (at `doc_path`, relative to the repository) names that does not exist.
pub fn missing_paths(root: &Path, doc_path: &str, text: &str, files: &[String]) -> Vec<Named> {
    let top: Vec<String> = std::fs::read_dir(root)
        .expect("the repository root reads")
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| !n.starts_with('.') || n == ".ci")
        .filter(|n| n != "target")
        .collect();
    let doc_dir = Path::new(doc_path).parent().unwrap_or(Path::new(""));
    let mut missing = Vec::new();
    let mut in_fence = false;
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        let named = |path: String| Named { doc: doc_path.to_owned(), line: n + 1, path };
        for target in link_targets(line) {
            let resolved = doc_dir.join(target);
            if !root.join(&resolved).exists() {
                missing.push(named(target.to_owned()));
            }
        }
        if in_fence {
            continue;
        }
        for span in code_spans(line) {
            let Some(path) = span.split_whitespace().next().map(clean) else { continue };
            let mut segments = path.split('/');
            let (first, second) = (segments.next().unwrap_or(""), segments.next().unwrap_or(""));
            let ours = top.iter().any(|t| t == first) && (second.is_empty() || root.join(first).join(second).exists());
            let folder_of_ours =
                files.iter().any(|f| f.starts_with(&format!("{first}/")) || f.contains(&format!("/{first}/")));
            if path.contains('/') && top.iter().any(|t| t == first) {
                if ours && !root.join(&path).exists() {
                    missing.push(named(path));
                }
            } else if path.contains('/') && folder_of_ours && (path.ends_with(".rs") || path.ends_with(".proto")) {
                let suffix = format!("/{path}");
                if !files.iter().any(|f| f.ends_with(&suffix) || *f == path) {
                    missing.push(named(path));
                }
            }
        }
    }
    missing
}

/// The relative targets of the markdown links on `line` (web links and anchors left out).
fn link_targets(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find("](") {
        let after = &rest[at + 2..];
        let end = after.find(')').unwrap_or(after.len());
        let target = after[..end].split('#').next().unwrap_or("").trim();
        if !target.is_empty() && !target.contains("://") && !target.starts_with("mailto:") {
            out.push(target);
        }
        rest = &after[end..];
    }
    out
}

/// The code spans of `line` (between single backticks).
fn code_spans(line: &str) -> Vec<&str> {
    line.split('`').skip(1).step_by(2).collect()
}

/// `path` up to its first placeholder, without a trailing `:line`, punctuation or `#anchor`.
fn clean(path: &str) -> String {
    let cut = path.find(['<', '*', '{', '[', '#', '$']).unwrap_or(path.len());
    let path = &path[..cut];
    let path = path.split("::").next().unwrap_or(path);
    let path = match path.rsplit_once(':') {
        Some((p, line)) if line.chars().all(|c| c.is_ascii_digit() || c == '-') => p,
        _ => path,
    };
    path.trim_end_matches([',', '.', ';', ')', ':']).to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placeholders_and_line_numbers_are_not_part_of_a_path() {
        assert_eq!(clean("cloud/src/network/mod.rs:120"), "cloud/src/network/mod.rs");
        assert_eq!(clean("risktwin/v1/<site>/state"), "risktwin/v1/");
        assert_eq!(clean("docs/cli.md#run"), "docs/cli.md");
        assert_eq!(link_targets("see [cli](cli.md#x) and [web](https://a.b/c)"), ["cli.md"]);
        assert_eq!(code_spans("a `x/y.rs` b `z`"), ["x/y.rs", "z"]);
    }
}
