//! `risktwin recordings …`, `cloud --record-dir` and `edge replay` of a folder refuse bad input
//! with exit 2 and one `error:` line, never a panic.

use crate::support::{assert_input_error, write_file};

#[test]
fn bad_folders_catalogues_spans_and_flags_exit_2() {
    let dir = tempfile::tempdir().expect("dir");
    let d = dir.path();
    std::fs::create_dir(d.join("empty")).expect("mkdir");
    std::fs::create_dir(d.join("text")).expect("mkdir");
    write_file(&d.join("text"), "catalogue.db", "this is not a SQLite database, only some text in a file");
    std::fs::create_dir(d.join("foreign")).expect("mkdir");
    let foreign = rusqlite::Connection::open(d.join("foreign/catalogue.db")).expect("sqlite");
    foreign.execute_batch("CREATE TABLE other (x INTEGER);").expect("a foreign table");
    drop(foreign);
    write_file(d, "plain.txt", "a file, not a folder");
    for (args, needle) in [
        (&["recordings", "list", "absent"][..], "absent: not a folder"),
        (&["recordings", "list", "plain.txt"], "plain.txt: not a folder"),
        (&["recordings", "list", "empty"], "no recordings catalogue"),
        (&["recordings", "query", "text"], "not a SQLite database"),
        (&["recordings", "query", "foreign", "--format", "json"], "not a RiskTwin recordings catalogue"),
        (&["recordings", "query", "empty", "--from", "10", "--to", "5"], "--from 10 must be less than --to 5"),
        (&["recordings", "query", "empty", "--source", "a/b"], "--source"),
        (&["recordings", "export", "empty", "--out", "x.mcap"], "no recordings catalogue"),
        (&["recordings", "export", "absent", "--out", "x.mcap"], "not a folder"),
        (&["recordings", "query", "empty", "--from", "x"], "invalid value"),
        (&["edge", "replay", "empty", "--speed", "0"], "no recordings catalogue"),
        (&["edge", "replay", "absent.mcap"], "cannot read absent.mcap"),
        (&["edge", "replay", "foreign", "--from", "3", "--to", "2"], "--from 3 must be less than --to 2"),
        (&["cloud", "--record", "a.mcap", "--record-dir", "segs"], "cannot be used with"),
        (&["cloud", "--segment-s", "1"], "--record-dir"),
        (&["cloud", "--record-dir", "segs", "--segment-s", "0"], "--segment-s 0 must lie in"),
        (&["cloud", "--record-dir", "segs", "--segment-mb=-1"], "--segment-mb -1 must lie in"),
        (&["cloud", "--record-dir", "segs", "--retain-s", "nan"], "--retain-s NaN must lie in"),
        (&["cloud", "--record-dir", "plain.txt"], "plain.txt"),
    ] {
        assert_input_error(d, args, needle);
    }
    assert!(!d.join("x.mcap").exists(), "a refused export leaves no file");
}
