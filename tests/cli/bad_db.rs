//! `--db` files that are not scenario libraries: input errors naming the file, and the file left
//! exactly as it was (a user's foreign database must never be written to).

use crate::support::{assert_input_error, generate};
use std::path::Path;
use tempfile::tempdir;

/// A real 1024-byte SQLite database (page size 512) holding one foreign table,
/// `CREATE TABLE invoices(n INTEGER)` with one row, as written by `sqlite3` 3.x; stored as its
/// non-zero runs (offset, bytes) to keep the fixture readable.
const FOREIGN_SQLITE: &[(usize, &[u8])] = &[
    (0x000, b"SQLite format 3\x00\x02\x00\x01\x01\x00@  \x00\x00\x00\x02\x00\x00\x00\x02"),
    (0x02b, b"\x01\x00\x00\x00\x04"),
    (0x03b, b"\x01"),
    (0x05f, b"\x02\x00.c\x01\r\x00\x00\x00\x01\x01\xc2\x00\x01\xc2"),
    (
        0x1c2,
        b"<\x01\x06\x17\x1d\x1d\x01Mtableinvoicesinvoices\x02CREATE TABLE invoices(n INTEGER)\r\x00\x00\x00\x01\x01\xfc\x00\x01\xfc",
    ),
    (0x3fc, b"\x02\x01\x02\t"),
];

fn foreign_sqlite() -> Vec<u8> {
    let mut bytes = vec![0u8; 1024];
    for (offset, run) in FOREIGN_SQLITE {
        bytes[*offset..offset + run.len()].copy_from_slice(run);
    }
    bytes
}

/// Deterministic pseudo-random bytes (xorshift64), so a failure reproduces.
fn random_bytes(n: usize) -> Vec<u8> {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 24) as u8
        })
        .collect()
}

/// Writes `bytes` as `dir/name`, checks `generate` and `rank` (and `simulate --db`) refuse it with
/// `needle` and the file name, and that the file is unchanged afterwards.
fn refused_untouched(dir: &Path, name: &str, bytes: &[u8], needle: &str) {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let commands: [&[&str]; 3] = [
        &["scenarios", "generate", "--kind", "cut-in", "--count", "3", "--db", name, "--format", "json"],
        &["scenarios", "rank", "--db", name, "--format", "json"],
        &["simulate", "--db", name, "--id", "abc", "--format", "json"],
    ];
    for args in commands {
        let line = assert_input_error(dir, args, needle);
        assert!(line.contains(name), "the error does not name {name}: {line}");
        assert_eq!(std::fs::read(&path).unwrap(), bytes, "{args:?} changed {name}");
    }
}

#[test]
fn random_bytes_are_not_a_database() {
    let dir = tempdir().unwrap();
    refused_untouched(dir.path(), "random.db", &random_bytes(4096), "not a SQLite database");
}

#[test]
fn text_file_is_not_a_database() {
    let dir = tempdir().unwrap();
    refused_untouched(dir.path(), "notes.db", b"shopping list: milk, eggs\n", "not a SQLite database");
}

#[test]
fn sqlite_magic_followed_by_garbage_is_not_a_database() {
    let dir = tempdir().unwrap();
    let mut bytes = b"SQLite format 3\x00".to_vec();
    bytes.extend(random_bytes(4080));
    refused_untouched(dir.path(), "magic.db", &bytes, "not a SQLite database");
}

#[test]
fn foreign_sqlite_database_is_not_a_library() {
    let dir = tempdir().unwrap();
    // The foreign table is named so the user sees what the file holds.
    refused_untouched(dir.path(), "invoices.db", &foreign_sqlite(), "invoices");
    assert_input_error(dir.path(), &["scenarios", "rank", "--db", "invoices.db"], "not a RiskTwin scenario library");
}

#[test]
fn reading_commands_never_create_a_database() {
    let dir = tempdir().unwrap();
    let line = assert_input_error(dir.path(), &["scenarios", "rank", "--db", "absent.db"], "absent.db");
    assert!(line.contains("no scenario library"), "{line}");
    assert_input_error(dir.path(), &["simulate", "--db", "absent.db", "--id", "abc"], "absent.db");
    assert_input_error(dir.path(), &["risk-field", "--db", "absent.db", "--id", "abc"], "absent.db");
    assert!(!dir.path().join("absent.db").exists(), "a reading command created the database");
}

#[test]
fn unknown_id_is_named() {
    let dir = tempdir().unwrap();
    generate(dir.path(), "lib.db", 3, 1);
    let line = assert_input_error(dir.path(), &["simulate", "--db", "lib.db", "--id", "nonexistent"], "'nonexistent'");
    assert!(line.contains("lib.db"), "{line}");
    assert_input_error(dir.path(), &["risk-field", "--db", "lib.db", "--id", "nonexistent"], "'nonexistent'");
}
