//! Rotation, catalogue and retention against real files in a temporary folder.

use super::*;
use risktwin_protos::recording::{Recorder, read_messages, salvage_messages};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::time::Duration;

fn provenance() -> Provenance {
    Provenance { risktwin_version: "0.1.0".into(), git_commit: "abc".into(), config: r#"{"args":[]}"#.into() }
}

fn config(dir: &Path) -> RotationConfig {
    RotationConfig {
        dir: dir.to_path_buf(),
        segment_bytes: u64::MAX,
        segment_age: Duration::from_secs(3600),
        retain_age: None,
        retain_bytes: None,
        provenance: provenance(),
    }
}

const TOPICS: [&str; 3] = ["risktwin/v1/s/veh-1/state", "risktwin/v1/s/veh-2/can", "risktwin/v1/s/cloud/risk_report"];

/// Records `segments` segments of 10 messages each (rotating by hand, as the timer would once
/// due) and finishes: the summary and the messages written, by log time.
fn record(config: RotationConfig, segments: u64) -> (SegmentsSummary, u64) {
    let (mut segs, file) = Segments::start(config).expect("start");
    let mut rec: Recorder<BufWriter<File>> = Recorder::live(file).expect("recorder");
    let mut t = 1_000u64;
    for s in 0..segments {
        if s > 0 {
            assert!(segs.due(rec.segment_messages()) || s > 0);
            segs.rotate(|next| Ok(rec.rotate(next)?)).expect("rotate");
        }
        for i in 0..10u64 {
            let channel = rec.channel(TOPICS[(i % 3) as usize], "risktwin.v1.VehicleState").expect("channel");
            rec.write(channel, t, t, &[i as u8; 50]).expect("write");
            t += 10;
        }
    }
    let (file, stats) = rec.finish_segment().expect("finish");
    (segs.finish(file, stats).expect("finish segments"), t)
}

#[test]
fn a_rotated_recording_is_catalogued_segment_by_segment_with_its_counts() {
    let dir = tempfile::tempdir().expect("dir");
    let (summary, _) = record(config(dir.path()), 4);
    assert_eq!((summary.segments_opened, summary.segments_closed, summary.segments_deleted), (4, 4, 0));
    assert_eq!(summary.messages, 40);
    let catalogue = Catalogue::open(dir.path()).expect("the catalogue");
    let rows = catalogue.all_segments().expect("rows");
    assert_eq!(rows.len(), 4);
    let mut bytes = 0;
    for (i, row) in rows.iter().enumerate() {
        assert!(row.closed && row.file.starts_with(&format!("seg-{:06}-", i + 1)), "{row:?}");
        let first = 1_000 + 100 * i as u64;
        assert_eq!((row.start_log_ns, row.end_log_ns, row.messages), (Some(first), Some(first + 90), Some(10)));
        let file = std::fs::read(dir.path().join(&row.file)).expect("segment");
        assert_eq!(row.bytes, Some(file.len() as u64));
        assert_eq!(read_messages(&file).expect("finished").len(), 10);
        bytes += file.len() as u64;
        let streams = catalogue.streams(row.seq).expect("streams");
        let edge: Vec<_> = streams.iter().map(|s| (s.source.as_deref(), s.stream.as_deref(), s.messages)).collect();
        assert_eq!(edge, vec![(None, None, 3), (Some("veh-1"), Some("state"), 4), (Some("veh-2"), Some("can"), 3)]);
    }
    assert_eq!(summary.bytes_written, bytes);
    // The span [1150, 1250) touches segments 2 and 3; veh-2 only in them too.
    let seqs = |source, range| -> Vec<u64> {
        catalogue.segments(source, range).expect("query").iter().map(|r| r.seq).collect()
    };
    assert_eq!(seqs(None, 1_150..1_250), vec![2, 3]);
    assert_eq!(seqs(Some("veh-2"), 1_150..1_250), vec![2, 3]);
    assert_eq!(seqs(Some("veh-9"), 0..u64::MAX), Vec::<u64>::new());
    let recordings = catalogue.recordings().expect("recordings");
    assert_eq!(recordings.len(), 1);
    assert_eq!(recordings[0].provenance, provenance());

    // A second recording in the same folder numbers on.
    let (again, _) = record(config(dir.path()), 1);
    assert_eq!(again.recording_id, 2);
    let last = Catalogue::open(dir.path()).expect("catalogue").all_segments().expect("rows");
    assert_eq!(last.last().map(|r| r.seq), Some(5));
}

#[test]
fn a_segment_is_due_by_size_or_age_once_it_holds_a_message() {
    let dir = tempfile::tempdir().expect("dir");
    let mut by_size = config(dir.path());
    by_size.segment_bytes = 1;
    let (segs, mut file) = Segments::start(by_size).expect("start");
    assert!(!segs.due(0), "an empty segment is never due");
    assert!(!segs.due(1), "nothing written yet");
    std::io::Write::write_all(&mut file, b"MCAP").expect("write");
    std::io::Write::flush(&mut file).expect("flush");
    assert!(segs.due(1), "one byte reached");
    let dir = tempfile::tempdir().expect("dir");
    let mut by_age = config(dir.path());
    by_age.segment_age = Duration::ZERO;
    let (segs, _file) = Segments::start(by_age).expect("start");
    assert!(segs.due(1));
    let (segs, _file) = Segments::start(config(dir.path())).expect("start");
    assert!(!segs.due(1_000), "neither bound reached");
}

#[test]
fn a_killed_recorder_leaves_its_segment_catalogued_unfinished_and_readable() {
    let dir = tempfile::tempdir().expect("dir");
    let (segs, file) = Segments::start(config(dir.path())).expect("start");
    let mut rec = Recorder::live(file).expect("recorder");
    let channel = rec.channel(TOPICS[0], "risktwin.v1.VehicleState").expect("channel");
    rec.write(channel, 5, 5, &[1; 20]).expect("write");
    rec.flush().expect("chunk closed");
    // The process dies: nothing is finished or booked.
    std::mem::forget(rec);
    drop(segs);
    let rows = Catalogue::open(dir.path()).expect("catalogue").all_segments().expect("rows");
    assert_eq!(rows.len(), 1);
    assert!(!rows[0].closed && rows[0].messages.is_none(), "{:?}", rows[0]);
    let bytes = std::fs::read(dir.path().join(&rows[0].file)).expect("segment");
    let (messages, unfinished) = salvage_messages(&bytes).expect("readable");
    assert_eq!((messages.len(), unfinished.is_some()), (1, true));
    // Any span includes it: what it holds is known only by reading it.
    let catalogue = Catalogue::open(dir.path()).expect("catalogue");
    assert_eq!(catalogue.segments(Some("nobody"), 0..1).expect("query").len(), 1);
}

#[test]
fn retention_deletes_the_oldest_closed_segments_beyond_the_size_or_age_bound() {
    let dir = tempfile::tempdir().expect("dir");
    let mut by_size = config(dir.path());
    by_size.retain_bytes = Some(1);
    let (summary, _) = record(by_size, 4);
    // Every bound is passed: all but the last segment go, the last closed one stays.
    assert_eq!((summary.segments_closed, summary.segments_deleted), (4, 3));
    let rows = Catalogue::open(dir.path()).expect("catalogue").all_segments().expect("rows");
    assert_eq!(rows.iter().map(|r| r.seq).collect::<Vec<_>>(), vec![4]);
    let files: Vec<_> = std::fs::read_dir(dir.path())
        .expect("dir")
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| is_segment_name(n))
        .collect();
    assert_eq!(files, vec![rows[0].file.clone()], "the deleted segments' files are gone");
    assert!(summary.bytes_deleted > 0);

    let dir = tempfile::tempdir().expect("dir");
    let mut by_age = config(dir.path());
    by_age.retain_age = Some(Duration::from_secs(3600));
    let (kept, _) = record(by_age.clone(), 3);
    assert_eq!(kept.segments_deleted, 0, "nothing is an hour old");
    by_age.retain_age = Some(Duration::ZERO);
    let (aged, _) = record(by_age, 2);
    assert_eq!(aged.segments_deleted, 4, "the three older ones and this recording's first");
}

#[test]
fn foreign_damaged_or_altered_catalogues_are_refused_and_left_alone() {
    let dir = tempfile::tempdir().expect("dir");
    let missing = Catalogue::open(dir.path()).expect_err("no catalogue");
    assert!(matches!(missing, CatalogueError::Missing { .. }) && missing.blames_the_input(), "{missing}");
    let not_dir = Catalogue::open(&dir.path().join("nothing")).expect_err("no folder");
    assert!(matches!(not_dir, CatalogueError::NotAFolder { .. }), "{not_dir}");
    let path = dir.path().join(CATALOGUE_FILE);
    let refused = |what: &str| {
        let e = Catalogue::open(dir.path()).expect_err(what);
        assert!(e.blames_the_input(), "{what}: {e}");
        e.to_string()
    };
    std::fs::write(&path, b"not a database at all, just some text that is long enough").expect("write");
    assert!(refused("text").contains("not a SQLite database"));
    std::fs::remove_file(&path).expect("rm");
    rusqlite::Connection::open(&path).expect("sqlite").execute_batch("CREATE TABLE t (x);").expect("foreign");
    assert!(refused("foreign").contains("not a RiskTwin recordings catalogue"));
    std::fs::remove_file(&path).expect("rm");
    drop(Catalogue::create(dir.path()).expect("created"));
    let raw = rusqlite::Connection::open(&path).expect("sqlite");
    raw.pragma_update(None, "user_version", 9).expect("version");
    assert!(refused("newer").contains("schema version 9"));
    raw.pragma_update(None, "user_version", SCHEMA_VERSION).expect("version");
    raw.execute_batch("DROP INDEX segment_streams_source;").expect("altered");
    assert!(refused("altered").contains("wrong schema"));
    raw.execute_batch("CREATE INDEX segment_streams_source ON segment_streams(source);").expect("restored");
    raw.execute_batch(
        "INSERT INTO recordings VALUES (1, 0, 'v', 'c', '{}');
         INSERT INTO segments (seq, recording_id, file, opened_unix_ns) VALUES (1, 1, '../../etc/passwd', 0);",
    )
    .expect("a bad row");
    let catalogue = Catalogue::open(dir.path()).expect("the schema is right");
    let bad = catalogue.all_segments().expect_err("a row naming a file outside the folder");
    assert!(matches!(bad, CatalogueError::BadRow { seq: 1, .. }) && bad.blames_the_input(), "{bad}");
}

#[test]
fn segment_names_sort_by_number_and_carry_the_utc_start() {
    let at = std::time::UNIX_EPOCH + Duration::from_secs(1_777_636_800 + 3_723);
    assert_eq!(segment_name(42, at), "seg-000042-20260501T130203Z.mcap");
    assert!(is_segment_name(&segment_name(1, std::time::SystemTime::now())));
    // Clocks outside 1970–9999 are clamped, never a panic.
    let before = std::time::UNIX_EPOCH - std::time::Duration::from_secs(1);
    assert_eq!(segment_name(1, before), "seg-000001-19700101T000000Z.mcap");
    let far = std::time::UNIX_EPOCH + std::time::Duration::from_secs(1 << 40);
    assert_eq!(segment_name(1, far), "seg-000001-99991231T235959Z.mcap");
    for bad in ["seg-1/../x.mcap", "x.mcap", "seg-1.db", "seg-..mcap"] {
        assert!(!is_segment_name(bad), "{bad}");
    }
}

#[test]
fn a_failed_booking_reaches_the_recorder_at_its_next_look_and_at_the_end() {
    let dir = tempfile::tempdir().expect("dir");
    let (mut segs, file) = Segments::start(config(dir.path())).expect("start");
    let mut rec: Recorder<BufWriter<File>> = Recorder::live(file).expect("recorder");
    let channel = rec.channel(TOPICS[0], "risktwin.v1.VehicleState").expect("channel");
    rec.write(channel, 5, 5, &[1; 20]).expect("write");
    // Another recorder took segment 2 in the catalogue: the keeper refuses to book ours over it.
    let raw = rusqlite::Connection::open(dir.path().join(CATALOGUE_FILE)).expect("sqlite");
    raw.execute(
        "INSERT INTO segments (seq, recording_id, file, opened_unix_ns) VALUES (2, 1, 'seg-000002-x.mcap', 0)",
        [],
    )
    .expect("a foreign row");
    // The keeper books in the background: the rotation itself or a later look reports it.
    let failed = segs.rotate(|next| Ok(rec.rotate(next)?)).err().or_else(|| {
        (0..200).find_map(|_| {
            std::thread::sleep(Duration::from_millis(10));
            segs.check().err()
        })
    });
    let failed = failed.expect("the keeper's failure within 2 s");
    assert!(failed.to_string().contains("segment 2 is already catalogued"), "{failed}");
    let (file, stats) = rec.finish_segment().expect("finish");
    let at_end = segs.finish(file, stats).expect_err("the end reports it too");
    assert!(matches!(at_end, SegmentError::KeeperGone), "{at_end}");
}
