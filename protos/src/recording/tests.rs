//! The recorder: round trips, chunk bounds, replay-time attachments, rotation.

use super::*;
use crate::decode;
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::telemetry::{Frame, Header};

fn state(seq: u64) -> VehicleStateSample {
    VehicleStateSample {
        header: Header {
            source: "veh-1".into(),
            seq,
            capture_time_ns: 1_000 * seq as i64,
            publish_time_ns: 1_001 * seq as i64,
            frame: Frame::World,
        },
        pose: Pose::new(seq as f64, 2.0, 0.1),
        velocity: Vec2::new(20.0, 0.0),
        speed_mps: 20.0,
        accel_mps2: -1.5,
        yaw_rate_radps: 0.01,
        steer_rad: 0.02,
        footprint: Footprint::new(4.5, 1.8),
    }
}

#[test]
fn round_trip_through_a_file_and_schema_mismatch_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("r.mcap");
    let mut rec =
        Recorder::new(std::io::BufWriter::new(std::fs::File::create(&path).expect("create"))).expect("recorder");
    for seq in 0..100 {
        rec.record("risktwin/v1/site/veh-1/state", 10 * seq, &state(seq)).expect("record");
    }
    assert!(matches!(
        rec.channel("risktwin/v1/site/veh-1/state", "risktwin.v1.CanFrame"),
        Err(RecordingError::SchemaChanged { .. })
    ));
    rec.finish().expect("finish");
    let bytes = std::fs::read(&path).expect("read");
    let msgs = read_messages(&bytes).expect("valid recording");
    assert_eq!(msgs.len(), 100);
    for (seq, m) in msgs.iter().enumerate() {
        assert_eq!(m.schema_name, "risktwin.v1.VehicleState");
        assert_eq!(m.log_time_ns, 10 * seq as u64);
        let back: VehicleStateSample = decode(&m.data).expect("decodes");
        assert_eq!(format!("{back:?}"), format!("{:?}", state(seq as u64)));
    }
    // A truncated file is an error to the strict reader, not a panic.
    let truncated = read_messages(&bytes[..bytes.len() / 2]);
    assert!(truncated.is_err(), "a recording cut in half is refused: {:?}", truncated.map(|m| m.len()));
    let (kept, unfinished) = salvage_messages(&bytes[..bytes.len() / 2]).expect("salvaged");
    // The second half is the summary (it repeats the large schema): every message is kept.
    assert!(unfinished.is_some(), "a cut file is reported");
    assert_eq!(kept, msgs, "the messages before the cut");
    assert!(read_messages(b"not an mcap file").is_err());

    // The streaming cursor over the file itself agrees with the collected read.
    let mut cursor = MessageCursor::new(std::fs::File::open(&path).expect("open"));
    let mut n = 0;
    while let Some(m) = cursor.next_message() {
        let m = m.expect("a whole message");
        assert_eq!((m.topic, m.data), (msgs[n].topic.as_str(), msgs[n].data.as_slice()));
        assert_eq!(m.log_time_ns, msgs[n].log_time_ns);
        n += 1;
    }
    assert_eq!(n, 100);
    let mut cut = MessageCursor::new(&bytes[..bytes.len() / 2]);
    let mut read = 0;
    while let Some(m) = cut.next_message() {
        m.expect("the messages before the cut");
        read += 1;
    }
    assert_eq!(read, kept.len(), "the cursor keeps what the collected read keeps");
    assert!(cut.unfinished().is_some(), "the cursor reports a truncated file");
}

/// `n` state messages written by `rec`, its finished bytes.
fn written(mut rec: Recorder<std::io::Cursor<Vec<u8>>>, n: u64) -> Vec<u8> {
    for seq in 0..n {
        rec.record("risktwin/v1/site/veh-1/state", 10 * seq, &state(seq)).expect("record");
    }
    rec.finish_into_inner().expect("finish").into_inner()
}

fn chunks(bytes: &[u8]) -> usize {
    mcap::Summary::read(bytes).expect("summary").expect("a summary").chunk_indexes.len()
}

#[test]
fn an_offline_recording_has_no_wall_bound_and_its_bytes_follow_its_input() {
    let offline = || Recorder::new(std::io::Cursor::new(Vec::new())).expect("recorder");
    assert_eq!(offline().wall_bound(), None, "offline chunks close by size only");
    let live = Recorder::live(std::io::Cursor::new(Vec::new())).expect("recorder");
    assert_eq!(live.wall_bound(), Some(CHUNK_WALL));
    let (a, b) = (written(offline(), 200), written(offline(), 200));
    assert_eq!(a, b, "the same messages, the same bytes");
    assert_eq!(chunks(&a), 1, "200 small messages fit one 1 MiB chunk");
    // A bound that is always due closes a chunk at every second write (the first write after
    // the bound): what an offline recorder given a wall bound does once a slow machine
    // crosses it, other bytes for the same input.
    let bounded = Recorder::new(std::io::Cursor::new(Vec::new())).expect("recorder").with_wall_bound(Duration::ZERO);
    let bounded = written(bounded, 200);
    assert_eq!(chunks(&bounded), 100, "two messages a chunk");
    assert_eq!(read_messages(&bounded).expect("finished"), read_messages(&a).expect("finished"));
}

#[test]
fn replay_time_attachments_round_trip_and_others_are_refused() {
    for t in [0, 1, -5, i64::MAX, 1_700_000_000_123_456_789] {
        assert_eq!(decode_replay_time(&encode_replay_time(t)), Some(t));
    }
    assert_eq!(decode_replay_time(b""), None);
    assert_eq!(decode_replay_time(b"rtlogt01short"), None);
    assert_eq!(decode_replay_time(b"somethingelse!!!"), None);
}

/// A recording rotated into three files: each is finished and holds its own messages, a channel
/// keeps its id in every file, and a span across them reads (and exports) as the messages of it.
#[test]
fn rotated_files_are_finished_and_a_span_across_them_reads_and_exports_as_one() {
    let dir = tempfile::tempdir().expect("temp dir");
    let paths: Vec<_> = (1..=3).map(|i| dir.path().join(format!("seg-{i}.mcap"))).collect();
    let create = |p: &std::path::PathBuf| std::io::BufWriter::new(std::fs::File::create(p).expect("create"));
    let mut rec = Recorder::live(create(&paths[0])).expect("recorder");
    let mut closed = Vec::new();
    for seq in 0..90u64 {
        if seq == 30 || seq == 60 {
            let (file, stats) = rec.rotate(create(&paths[(seq / 30) as usize])).expect("rotate");
            file.into_inner().expect("flushed");
            closed.push(stats);
        }
        let topic = if seq % 3 == 0 { "risktwin/v1/s/veh-2/state" } else { "risktwin/v1/s/veh-1/state" };
        rec.record(topic, 10 * seq, &state(seq)).expect("record");
    }
    assert_eq!(rec.segment_messages(), 30);
    let (file, stats) = rec.finish_segment().expect("finish");
    file.into_inner().expect("flushed");
    closed.push(stats);
    let mut all = Vec::new();
    for (i, path) in paths.iter().enumerate() {
        let bytes = std::fs::read(path).expect("read");
        let msgs = read_messages(&bytes).expect("every file is finished");
        let first = 300 * i as u64;
        assert_eq!(closed[i].messages, 30);
        assert_eq!(closed[i].log_time_ns, Some((first, first + 290)));
        let per_topic: u64 = closed[i].topics.iter().map(|t| t.messages).sum();
        assert_eq!(per_topic, 30, "{:?}", closed[i].topics);
        let summary = mcap::Summary::read(&bytes).expect("summary").expect("a summary");
        let ids: Vec<(u16, String)> = summary.channels.values().map(|c| (c.id, c.topic.clone())).collect();
        assert!(ids.contains(&(1, "risktwin/v1/s/veh-2/state".into())), "ids kept across files: {ids:?}");
        all.extend(msgs);
    }
    assert_eq!(all.len(), 90);

    // [295, 610) on veh-1 only: from the middle of the first file into the third.
    let keep = |t: &str| t.contains("veh-1");
    let expected: Vec<_> =
        all.iter().filter(|m| (295..610).contains(&m.log_time_ns) && keep(&m.topic)).cloned().collect();
    let span = || SpanCursor::new(paths.clone(), 295..610, Box::new(keep));
    let mut cursor = span();
    let mut read = Vec::new();
    let mut ids = std::collections::BTreeSet::new();
    while let Some(m) = cursor.next_message() {
        let m = m.expect("a message");
        ids.insert(m.channel_id);
        read.push((m.topic.to_owned(), m.log_time_ns, m.data.to_vec()));
    }
    assert_eq!(ids.len(), 1, "one span-wide id per topic: {ids:?}");
    let wanted: Vec<_> = expected.iter().map(|m| (m.topic.clone(), m.log_time_ns, m.data.clone())).collect();
    assert_eq!(read, wanted);
    assert!(cursor.unfinished().is_empty());
    let (bytes, exported) = export(&mut span(), std::io::Cursor::new(Vec::new())).expect("export");
    assert_eq!(exported.messages, expected.len() as u64);
    assert_eq!(read_messages(&bytes.into_inner()).expect("a finished export"), expected);
}

#[test]
fn a_span_reports_a_cut_file_and_goes_on_and_names_a_missing_one() {
    let dir = tempfile::tempdir().expect("temp dir");
    let whole = written(Recorder::new(std::io::Cursor::new(Vec::new())).expect("recorder"), 20);
    let (cut, empty, missing) = (dir.path().join("cut.mcap"), dir.path().join("empty.mcap"), dir.path().join("no"));
    std::fs::write(&cut, &whole[..whole.len() / 2]).expect("write");
    std::fs::write(&empty, &whole[..40]).expect("write");
    let mut cursor = SpanCursor::all(vec![empty.clone(), cut.clone(), missing]);
    let mut n = 0;
    let mut errors = Vec::new();
    while let Some(m) = cursor.next_message() {
        match m {
            Ok(_) => n += 1,
            Err(e) => errors.push(e.to_string()),
        }
    }
    assert_eq!(n, 20, "the cut file's messages");
    let lost: Vec<_> = cursor.unfinished().iter().map(|(p, u)| (p.clone(), u.messages)).collect();
    assert_eq!(lost, vec![(empty, 0), (cut, 20)]);
    assert_eq!(errors.len(), 1, "{errors:?}");
    assert!(errors[0].contains("no:"), "{errors:?}");
}
