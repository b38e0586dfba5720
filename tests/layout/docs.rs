//! The repository paths that README.md and docs/*.md name.
//!
//! A path is named in a link (`[text](path)`, relative to the document) or in a code span
//! (`` `cloud/src/network/mod.rs` ``, found over the whole paragraph, so a span may wrap): a
//! span's first word whose first segment is a top-level entry of the repository and which
//! either ends in a file extension or continues into an entry of that folder
//! (`transport/link/…`, a Zenoh setting, is not a path of ours), or a span that ends in `.rs`
//! or `.proto` and starts with the name of a folder of ours (`network/receive.rs`: then some
//! tracked file must end with it). A placeholder (`<site>`, `*`, `{a,b}`) ends the part
//! checked, and `:line`, `::item` or `#anchor` suffixes are not part of the path. A path exists
//! when git tracks it, or a file below it.

use std::path::{Component, Path, PathBuf};

/// One path a document names.
#[derive(Debug)]
pub struct Named {
    pub doc: String,
    pub line: usize,
    pub path: String,
}

/// The tracked files of the repository, and what a path must be to be one of them.
pub struct Tracked<'a> {
    pub files: &'a [String],
}

impl Tracked<'_> {
    /// Whether `path` is a tracked file or has one below it.
    fn has(&self, path: &str) -> bool {
        let path = path.trim_end_matches('/');
        let folder = format!("{path}/");
        !path.is_empty() && self.files.iter().any(|f| f == path || f.starts_with(&folder))
    }

    /// The top-level entries.
    fn top(&self) -> Vec<&str> {
        let mut top: Vec<&str> = self.files.iter().filter_map(|f| f.split('/').next()).collect();
        top.dedup();
        top
    }
}

/// Every path `text` (the document `doc_path`, relative to the repository) names that does not exist.
pub fn missing_paths(doc_path: &str, text: &str, tracked: &Tracked) -> Vec<Named> {
    let top = tracked.top();
    let doc_dir = Path::new(doc_path).parent().unwrap_or(Path::new(""));
    let mut missing = Vec::new();
    for (first_line, paragraph) in paragraphs(text) {
        let line_of = |at: usize| first_line + paragraph[..at].matches('\n').count();
        for (at, target) in link_targets(&paragraph) {
            let resolved = normalised(&doc_dir.join(target));
            if !tracked.has(&resolved) {
                missing.push(Named { doc: doc_path.to_owned(), line: line_of(at), path: target.to_owned() });
            }
        }
        for (at, span) in code_spans(&paragraph) {
            let Some(path) = span.split_whitespace().next().map(clean) else { continue };
            let mut segments = path.split('/');
            let (first, second) = (segments.next().unwrap_or(""), segments.next().unwrap_or(""));
            let has_extension = Path::new(&path).extension().is_some();
            let checked = if top.contains(&first) {
                path.contains('/')
                    && (has_extension || second.is_empty() || tracked.has(&format!("{first}/{second}")))
                    && !tracked.has(&path)
            } else {
                let folder_of_ours = tracked.files.iter().any(|f| f.contains(&format!("/{first}/")));
                let suffix = format!("/{path}");
                path.contains('/')
                    && folder_of_ours
                    && (path.ends_with(".rs") || path.ends_with(".proto"))
                    && !tracked.files.iter().any(|f| f.ends_with(&suffix))
            };
            if checked {
                missing.push(Named { doc: doc_path.to_owned(), line: line_of(at), path });
            }
        }
    }
    missing
}

/// The paragraphs of `text` outside code fences, each with the number of its first line.
fn paragraphs(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let (mut in_fence, mut current, mut start) = (false, String::new(), 1);
    for (n, line) in text.lines().enumerate() {
        let fence = line.trim_start().starts_with("```");
        if fence || in_fence || line.trim().is_empty() {
            if !current.is_empty() {
                out.push((start, std::mem::take(&mut current)));
            }
            in_fence ^= fence;
            continue;
        }
        if current.is_empty() {
            start = n + 1;
        } else {
            current.push('\n');
        }
        current.push_str(line);
    }
    if !current.is_empty() {
        out.push((start, current));
    }
    out
}

/// `path` with its `.` and `..` components taken out.
fn normalised(path: &Path) -> String {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::Normal(p) => out.push(p),
            _ => {}
        }
    }
    out.to_string_lossy().into_owned()
}

/// The relative targets of the markdown links in `text` (web links and anchors left out),
/// each with its byte offset.
fn link_targets(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(at) = text[from..].find("](").map(|a| from + a) {
        let start = at + 2;
        let end = text[start..].find(')').map_or(text.len(), |e| start + e);
        let target = text[start..end].split('#').next().unwrap_or("").trim();
        if !target.is_empty() && !target.contains("://") && !target.starts_with("mailto:") {
            out.push((start, target));
        }
        from = end;
    }
    out
}

/// The code spans of `text` (between backticks), each with its byte offset.
fn code_spans(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut offset = 0;
    for (i, part) in text.split('`').enumerate() {
        if i % 2 == 1 {
            out.push((offset, part));
        }
        offset += part.len() + 1;
    }
    out
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
        assert_eq!(link_targets("see [cli](cli.md#x) and [web](https://a.b/c)"), [(10, "cli.md")]);
        assert_eq!(code_spans("a `x/y.rs` b\n`z`"), [(3, "x/y.rs"), (14, "z")]);
        assert_eq!(normalised(Path::new("docs/../README.md")), "README.md");
    }

    #[test]
    fn a_moved_file_a_wrapped_span_and_a_folder_that_is_gone_are_missing() {
        let files: Vec<String> = ["README.md", "docs/cli.md", "policy/src/lib.rs", "cloud/src/network/receive/mod.rs"]
            .map(str::to_owned)
            .into();
        let tracked = Tracked { files: &files };
        let text = "See `policy/src/lib.rs`, `policy/signature.rs` and\n`network/receive.rs`, not `transport/link/tx`.\n\nA span that wraps: `cloud/src/network/receive.rs\n` and [cli](cli.md), [gone](gone.md).\n";
        let missing: Vec<(usize, String)> =
            missing_paths("docs/x.md", text, &tracked).into_iter().map(|m| (m.line, m.path)).collect();
        assert_eq!(
            missing,
            [
                (1, "policy/signature.rs".to_owned()),
                (2, "network/receive.rs".to_owned()),
                (5, "gone.md".to_owned()),
                (4, "cloud/src/network/receive.rs".to_owned())
            ]
        );
    }
}
