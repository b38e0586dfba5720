//! Files named on the command line, read with a bound: a file larger than its kind can be (or
//! one that never ends, such as `/dev/zero` or a FIFO) is an input error naming its size, not a
//! process that eats memory until the kernel kills it.

use crate::error::{CliError, CliResult};
use std::io::Read;
use std::path::Path;

/// Spec files, run and sweep configs: JSON objects of a few dozen fields.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// The bytes of `path`, at most `max`; `what` names the file in errors (`spec`, `config`, …).
pub fn read_bounded(path: &Path, max: u64, what: &str) -> CliResult<Vec<u8>> {
    let cannot = |e: std::io::Error| CliError::input(format!("cannot read {what}{}: {e}", path.display()));
    let too_large = |bytes: u64| {
        CliError::input(format!("{what}{}: {bytes} bytes, more than the {max} it may have", path.display()))
    };
    let file = std::fs::File::open(path).map_err(cannot)?;
    let size = file.metadata().map_err(cannot)?.len();
    if size > max {
        return Err(too_large(size));
    }
    let mut bytes = Vec::new();
    file.take(max + 1).read_to_end(&mut bytes).map_err(cannot)?;
    if bytes.len() as u64 > max {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_bounded`] as UTF-8 text.
pub fn read_text_bounded(path: &Path, max: u64, what: &str) -> CliResult<String> {
    String::from_utf8(read_bounded(path, max, what)?)
        .map_err(|e| CliError::input(format!("cannot read {what}{}: not UTF-8: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_the_bound_is_refused_with_its_size_and_one_within_is_read() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("f.json");
        std::fs::write(&path, b"{}").expect("write");
        assert_eq!(read_text_bounded(&path, 2, "spec ").expect("within"), "{}");
        let e = read_bounded(&path, 1, "spec ").unwrap_err().to_string();
        assert!(e.contains("f.json: 2 bytes, more than the 1"), "{e}");
        // A file that never ends stops at the bound.
        let e = read_bounded(Path::new("/dev/zero"), 10, "").unwrap_err().to_string();
        assert!(e.contains("11 bytes"), "{e}");
        std::fs::write(&path, [0xff, 0xfe]).expect("write");
        assert!(read_text_bounded(&path, 10, "").unwrap_err().to_string().contains("not UTF-8"));
    }
}
