//! Hostile CommonRoad files on every `--commonroad` command: nested too deep for a recursive
//! parser, too many nodes, too large. Each is `error: …` naming the file and the limit, exit 2;
//! never a stack overflow (exit 134) or a panic.

use crate::support::{assert_input_error, write_file};
use tempfile::tempdir;

/// Every command that reads a CommonRoad file named on the command line.
fn commands(file: &str) -> Vec<Vec<String>> {
    let lines: [&[&str]; 6] = [
        &["criticality", "--commonroad", file, "--format", "json"],
        &["simulate", "--commonroad", file, "--format", "json"],
        &["risk-field", "--commonroad", file, "--format", "json"],
        &["import", "commonroad", file, "--out", "out.mcap", "--format", "json"],
        &["scene", "run", "--commonroad", file],
        &["scene", "authority", "--commonroad", file],
    ];
    lines.iter().map(|l| l.iter().map(|s| s.to_string()).collect()).collect()
}

fn refused_everywhere(dir: &std::path::Path, file: &str, needle: &str) {
    for args in commands(file) {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let line = assert_input_error(dir, &args, needle);
        assert!(line.contains(file), "{args:?}: the error does not name {file}: {line}");
        assert!(!dir.join("out.mcap").exists(), "{args:?} wrote its output for a refused file");
    }
}

#[test]
fn xml_nested_20000_levels_deep_is_an_input_error() {
    let dir = tempdir().unwrap();
    let depth = 20_000;
    let text =
        format!(r#"<commonRoad timeStepSize="0.1">{}{}</commonRoad>"#, "<a>".repeat(depth), "</a>".repeat(depth));
    write_file(dir.path(), "deep.xml", &text);
    refused_everywhere(dir.path(), "deep.xml", "nested deeper than");
}

#[test]
fn too_many_elements_are_an_input_error() {
    let dir = tempdir().unwrap();
    // Four million empty elements in 16 MB: under the size limit, over the node limit.
    let text = format!(r#"<commonRoad timeStepSize="0.1">{}</commonRoad>"#, "<a/>".repeat(4_000_001));
    write_file(dir.path(), "wide.xml", &text);
    let line = assert_input_error(dir.path(), &["criticality", "--commonroad", "wide.xml"], "more than");
    assert!(line.contains("nodes"), "{line}");
}

#[test]
fn a_file_over_the_size_limit_is_refused_before_parsing() {
    let dir = tempdir().unwrap();
    let path = dir.path().join("huge.xml");
    // Sparse: 17 MiB of (mostly absent) zeros, over the 16 MiB limit.
    let file = std::fs::File::create(&path).unwrap();
    file.set_len(17 << 20).unwrap();
    let line = assert_input_error(dir.path(), &["criticality", "--commonroad", "huge.xml"], "huge.xml");
    assert!(line.contains("bytes"), "{line}");
    assert_input_error(dir.path(), &["simulate", "--commonroad", "huge.xml"], "bytes");
}
