//! Damaged and unfinished recordings at the command line: a length field that cannot be true is
//! `error:` and exit 2 (never an abort), `recover` rewrites what is readable, and a killed
//! `scenarios generate` keeps the batches it committed.

use crate::support::{assert_input_error, assert_no_panic, ok_json, risktwin, shown};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// `risktwin import commonroad` of the two-car fixture: a finished recording.
fn recording(dir: &Path) -> PathBuf {
    let xml = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/two_cars.xml");
    let out = dir.join("two_cars.mcap");
    let (xml, path) = (xml.to_str().expect("utf-8"), out.to_str().expect("utf-8"));
    ok_json(dir, &["import", "commonroad", xml, "--out", path, "--format", "json"]);
    out
}

/// The byte offset of the first chunk record, walking the records from the magic.
fn first_chunk(bytes: &[u8]) -> usize {
    let mut at = 8;
    while bytes[at] != 0x06 {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().expect("8 bytes"));
        at += 9 + len as usize;
    }
    at
}

/// A copy of `path` whose first chunk claims 2^56 more bytes (one bit of its length's top byte):
/// about 72 PB, what made the reader abort.
fn flipped_copy(dir: &Path, path: &Path) -> (PathBuf, usize) {
    let mut bytes = std::fs::read(path).expect("read");
    let at = first_chunk(&bytes);
    bytes[at + 8] ^= 0x01;
    let out = dir.join("flipped.mcap");
    std::fs::write(&out, bytes).expect("write");
    (out, at)
}

#[test]
fn a_flipped_length_byte_is_an_input_error_for_criticality_and_replay() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (flipped, at) = flipped_copy(dir.path(), &recording(dir.path()));
    let path = flipped.to_str().expect("utf-8");
    let needle = format!("record at byte {at} claims");
    assert_input_error(dir.path(), &["criticality", "--mcap", path], &needle);
    // The replay connects to Zenoh first (peer mode, no router needed): its logs may share stderr.
    let out = risktwin(dir.path(), &["edge", "replay", path, "--speed", "0", "--wait-for-cloud-s", "0"]);
    assert_no_panic(&out);
    assert_eq!(out.status.code(), Some(2), "{}", shown(&out));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.lines().any(|l| l.starts_with("error: ") && l.contains(&needle)), "{}", shown(&out));
}

#[test]
fn recover_keeps_a_finished_file_whole_and_refuses_one_with_nothing_readable() {
    let dir = tempfile::tempdir().expect("temp dir");
    let rec = recording(dir.path());
    let out = dir.path().join("out.mcap");
    let (rec_s, out_s) = (rec.to_str().expect("utf-8"), out.to_str().expect("utf-8"));
    let report = ok_json(dir.path(), &["recover", rec_s, "--out", out_s, "--format", "json"]);
    let whole = risktwin_protos::recording::read_messages(&std::fs::read(&rec).expect("read")).expect("finished");
    let again = risktwin_protos::recording::read_messages(&std::fs::read(&out).expect("read")).expect("finished");
    assert_eq!(report["messages"], whole.len() as u64);
    assert_eq!(report["unfinished"], false);
    assert_eq!(again, whole, "the same messages, in a finished file");
    // Cut inside its only chunk: nothing complete is left.
    let bytes = std::fs::read(&rec).expect("read");
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..first_chunk(&bytes) + 100]).expect("write");
    let fresh = dir.path().join("fresh.mcap");
    assert_input_error(
        dir.path(),
        &["recover", cut.to_str().expect("utf-8"), "--out", fresh.to_str().expect("utf-8")],
        "nothing readable",
    );
    assert!(!fresh.exists(), "no empty file is left to be taken for a recovery");
    let recovered = std::fs::read(&out).expect("read");
    assert_input_error(dir.path(), &["recover", cut.to_str().expect("utf-8"), "--out", out_s], "nothing readable");
    assert_eq!(std::fs::read(&out).expect("read"), recovered, "a refused recovery leaves an existing OUT alone");
    assert_no_stray_files(dir.path(), &["two_cars.mcap", "out.mcap", "cut.mcap"]);
}

/// Fails when `dir` holds anything but `names` (a temporary file left behind).
fn assert_no_stray_files(dir: &Path, names: &[&str]) {
    let mut found: Vec<String> = std::fs::read_dir(dir)
        .expect("list")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    found.sort();
    let mut want: Vec<String> = names.iter().map(|n| n.to_string()).collect();
    want.sort();
    assert_eq!(found, want, "files in {}", dir.display());
}

#[test]
fn recover_refuses_to_write_over_its_own_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let rec = recording(dir.path());
    let original = std::fs::read(&rec).expect("read");
    let link = dir.path().join("link.mcap");
    std::os::unix::fs::symlink(&rec, &link).expect("symlink");
    let rec_s = rec.to_str().expect("utf-8");
    // The same path, and another name of the same file.
    for out in [rec_s, link.to_str().expect("utf-8")] {
        assert_input_error(dir.path(), &["recover", rec_s, "--out", out], "is the recording itself");
        assert_eq!(std::fs::read(&rec).expect("read"), original, "--out {out}: the recording is unchanged");
    }
    assert_no_stray_files(dir.path(), &["two_cars.mcap", "link.mcap"]);
}

/// Rows of `table` in the library at `db`, or `None` while it cannot be read yet.
fn rows(db: &Path, table: &str) -> Option<i64> {
    let conn = rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY).ok()?;
    conn.busy_timeout(Duration::from_secs(1)).ok()?;
    conn.query_row(&format!("SELECT COUNT(*) FROM {table}"), [], |r| r.get(0)).ok()
}

#[test]
fn a_killed_scenarios_generate_keeps_its_committed_batches() {
    let dir = tempfile::tempdir().expect("temp dir");
    let db = dir.path().join("lib.db");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_risktwin"))
        .args(["scenarios", "generate", "--kind", "all", "--count", "2000", "--seed", "3", "--db"])
        .arg(&db)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(120);
    let committed = loop {
        match rows(&db, "scenarios") {
            Some(n) if n > 0 => break n,
            _ if Instant::now() > deadline => {
                let _ = child.kill();
                panic!("no batch committed in 120 s");
            }
            // Polling the database is the wait: its interval, not a guess at how long it takes.
            _ => std::thread::sleep(Duration::from_millis(20)),
        }
    };
    child.kill().expect("kill -9");
    let status = child.wait().expect("wait");
    assert!(!status.success(), "killed before the end: {status:?}");
    let (scenarios, outcomes) = (rows(&db, "scenarios").expect("readable"), rows(&db, "outcomes").expect("readable"));
    assert!(scenarios >= committed && scenarios < 10_000, "{scenarios} scenarios kept");
    assert_eq!(scenarios % 64, 0, "whole batches of 64: {scenarios}");
    assert_eq!(outcomes, scenarios, "every kept scenario has its outcome");
    let ranked = ok_json(
        dir.path(),
        &["scenarios", "rank", "--db", db.to_str().expect("utf-8"), "--top", "1000000", "--format", "json"],
    );
    assert_eq!(ranked.as_array().map(Vec::len), Some(scenarios as usize), "the library reads back");
}
