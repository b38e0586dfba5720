//! Bounds on a CommonRoad document, checked before roxmltree sees it.
//!
//! roxmltree parses elements recursively (one `parse_element` → `parse_content` pair of frames
//! per level), so a file nested 20,000 levels deep overflows the main thread's 8 MiB stack and
//! aborts the process; its `nodes_limit` bounds memory but not depth. [`check_depth`] walks the
//! text once, without recursion, and refuses a document nested deeper than [`MAX_DEPTH`]
//! before the recursive parser runs. The limits leave wide room over real files: the 25 of
//! `data/commonroad/` nest at most 8 levels, the largest is 1.3 MB with about 92,000 elements.

use super::error::CommonRoadError;

/// The deepest element nesting accepted (real CommonRoad 2020a files nest 7 or 8 levels).
pub const MAX_DEPTH: usize = 64;
/// The largest document accepted, in bytes (12× the largest file of `data/commonroad/`).
pub const MAX_XML_BYTES: usize = 16 << 20;
/// The most XML nodes (elements and non-blank texts) accepted: a 16 MiB file of real
/// CommonRoad holds about 2 million; this bounds what a file of tiny elements costs in memory.
pub const MAX_NODES: u32 = 4_000_000;

/// Refuses a text longer than [`MAX_XML_BYTES`].
pub(super) fn check_size(text: &str) -> Result<(), CommonRoadError> {
    if text.len() > MAX_XML_BYTES {
        return Err(CommonRoadError::TooLarge { bytes: text.len() as u64, max: MAX_XML_BYTES as u64 });
    }
    Ok(())
}

/// Refuses a document whose elements nest deeper than [`MAX_DEPTH`], naming the line of the
/// first element too deep.
///
/// Counts start tags against end tags, skipping comments, CDATA sections, processing
/// instructions and declarations, and quoted attribute values (where `>` may stand). On
/// malformed text the count may be off, but never below what roxmltree would recurse: it
/// descends only on start tags that it too would descend on, and it stops at the first error.
pub(super) fn check_depth(text: &str) -> Result<(), CommonRoadError> {
    let bytes = text.as_bytes();
    let (mut depth, mut line, mut i) = (0usize, 1u32, 0usize);
    // Advances past the first `end` at or after `from`, counting lines; the end of the text if none.
    let skip_past = |from: usize, end: &[u8], line: &mut u32| -> usize {
        let stop =
            bytes[from..].windows(end.len()).position(|w| w == end).map_or(bytes.len(), |k| from + k + end.len());
        *line += bytes[from..stop].iter().filter(|&&b| b == b'\n').count() as u32;
        stop
    };
    while i < bytes.len() {
        match bytes[i] {
            b'\n' => {
                line += 1;
                i += 1;
            }
            b'<' => {
                let rest = &bytes[i..];
                if rest.starts_with(b"<!--") {
                    i = skip_past(i + 4, b"-->", &mut line);
                } else if rest.starts_with(b"<![CDATA[") {
                    i = skip_past(i + 9, b"]]>", &mut line);
                } else if rest.starts_with(b"<?") {
                    i = skip_past(i + 2, b"?>", &mut line);
                } else if rest.starts_with(b"<!") {
                    i = skip_past(i + 2, b">", &mut line);
                } else if rest.starts_with(b"</") {
                    depth = depth.saturating_sub(1);
                    i = skip_past(i + 2, b">", &mut line);
                } else {
                    let start_line = line;
                    let (end, self_closing) = start_tag_end(bytes, i + 1, &mut line);
                    if !self_closing {
                        depth += 1;
                        if depth > MAX_DEPTH {
                            return Err(CommonRoadError::TooDeep { line: start_line, max: MAX_DEPTH });
                        }
                    }
                    i = end;
                }
            }
            _ => i += 1,
        }
    }
    Ok(())
}

/// The position after the `>` that ends the start tag whose name begins at `from` (quoted
/// values skipped), and whether it was `/>`.
fn start_tag_end(bytes: &[u8], from: usize, line: &mut u32) -> (usize, bool) {
    let mut quote = None;
    for (k, &b) in bytes.iter().enumerate().skip(from) {
        if b == b'\n' {
            *line += 1;
        }
        match (quote, b) {
            (Some(q), _) if b == q => quote = None,
            (Some(_), _) => {}
            (None, b'"' | b'\'') => quote = Some(b),
            (None, b'>') => return (k + 1, k > from && bytes[k - 1] == b'/'),
            (None, _) => {}
        }
    }
    (bytes.len(), false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nested(depth: usize) -> String {
        format!("<commonRoad>{}{}</commonRoad>", "<a x='>'>".repeat(depth - 1), "</a>".repeat(depth - 1))
    }

    #[test]
    fn depth_at_the_limit_passes_and_one_more_is_refused_with_its_line() {
        assert!(check_depth(&nested(MAX_DEPTH)).is_ok());
        match check_depth(&format!("<!-- <a><a> -->\n{}", nested(MAX_DEPTH + 1))) {
            Err(CommonRoadError::TooDeep { line: 2, max: MAX_DEPTH }) => {}
            other => panic!("expected TooDeep at line 2, got {other:?}"),
        }
    }

    #[test]
    fn self_closing_tags_comments_and_cdata_do_not_nest() {
        let flat = format!(
            "<?xml version='1.0'?><r>{}<![CDATA[{}]]><!--{}--></r>",
            "<a/><b c=\"/>\"/>".repeat(10_000),
            "<a>".repeat(1000),
            "<a>".repeat(1000)
        );
        assert!(check_depth(&flat).is_ok());
    }

    #[test]
    fn twenty_thousand_levels_are_refused_without_recursion() {
        let text = format!("<r>{}{}</r>", "<a>".repeat(20_000), "</a>".repeat(20_000));
        assert!(matches!(check_depth(&text), Err(CommonRoadError::TooDeep { line: 1, .. })));
        // Unclosed tags count too: a truncated file is as deep as it opened.
        assert!(check_depth(&"<a>".repeat(MAX_DEPTH + 1)).is_err());
    }

    #[test]
    fn every_file_of_the_data_folder_is_within_the_limits() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../data/commonroad");
        let mut n = 0;
        for entry in std::fs::read_dir(dir).expect("data/commonroad") {
            let path = entry.expect("entry").path();
            if path.extension().is_some_and(|e| e == "xml") {
                let text = std::fs::read_to_string(&path).expect("readable");
                check_size(&text).expect("size");
                check_depth(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                n += 1;
            }
        }
        assert_eq!(n, 25);
    }
}
