//! The worker against planted bad input, and replay of its own recording.

use super::*;
use crate::test_fixtures::state;
use risktwin_align::IngestConfig;
use risktwin_protos::encode;
use risktwin_protos::recording::{Recorder, read_messages};
use risktwin_transport::EdgeStream;
use std::io::Cursor;

type Message = (String, EdgeStream, String, Vec<u8>, i64);

/// Three vehicles at 50 Hz for 4 s with a 2–5 ms delay and 30 ms clock offsets, plus planted
/// bad input: garbage, a NaN field, a duplicate, a source mismatch.
fn fleet() -> Vec<Message> {
    let mut msgs = Vec::new();
    for v in 0..3u64 {
        let source = format!("veh-{v}");
        let topic = format!("risktwin/v1/test/{source}/state");
        for seq in 0..200u64 {
            let t = 1_000_000_000 + seq as i64 * 20_000_000;
            let sample = state(&source, seq, t + 30_000_000 * v as i64);
            let receive = t + 2_000_000 + ((seq * 7 + v) % 4) as i64 * 1_000_000;
            msgs.push((source.clone(), EdgeStream::State, topic.clone(), encode(&sample), receive));
        }
    }
    let t0 = 2_000_000_000;
    msgs.push(("veh-0".into(), EdgeStream::State, "risktwin/v1/test/veh-0/state".into(), vec![0xff; 17], t0));
    let mut nan = state("veh-1", 500, t0);
    nan.speed_mps = f64::NAN;
    msgs.push(("veh-1".into(), EdgeStream::State, "risktwin/v1/test/veh-1/state".into(), encode(&nan), t0));
    msgs.push((
        "veh-2".into(),
        EdgeStream::State,
        "risktwin/v1/test/veh-2/state".into(),
        encode(&state("veh-2", 10, t0)),
        t0 + 1,
    ));
    msgs.push((
        "veh-0".into(),
        EdgeStream::State,
        "risktwin/v1/test/veh-0/state".into(),
        encode(&state("veh-9", 600, t0)),
        t0 + 2,
    ));
    msgs.sort_by_key(|m| m.4);
    msgs
}

#[test]
fn bad_input_is_counted_by_reason_and_the_worker_goes_on() {
    let mut w: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
    for (source, stream, topic, bytes, receive) in fleet() {
        w.handle(&source, stream, &topic, &bytes, receive, |_| {}).expect("no recorder, no I/O error");
    }
    let s = w.stats();
    assert_eq!(s.received, 604);
    assert_eq!(s.accepted, 600, "{s:?}");
    assert_eq!(s.dropped.get("malformed"), Some(&1));
    assert_eq!(s.dropped.get("invalid-field"), Some(&1));
    assert_eq!(s.dropped.get("duplicate"), Some(&1));
    assert_eq!(s.dropped.get("source-mismatch"), Some(&1));
    assert_eq!(s.received, s.accepted + s.dropped_total(), "nothing lost silently");
    assert!(s.snapshots > 70, "20 Hz ticks over ~4 s: {}", s.snapshots);
}

#[test]
fn replaying_the_recording_reproduces_the_snapshots() {
    let recorder = Recorder::new(Cursor::new(Vec::new())).expect("recorder");
    let mut live: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), Some(recorder));
    let mut live_digest = SnapshotDigest::default();
    for (source, stream, topic, bytes, receive) in fleet() {
        live.handle(&source, stream, &topic, &bytes, receive, |s| live_digest.add(s)).expect("record");
    }
    let (stats, writer) = live.finish().expect("recording closes");
    assert_eq!(stats.recorded, stats.accepted);
    let recorder_bytes = writer.expect("the recorder's buffer").0.into_inner();
    let recorded = read_messages(&recorder_bytes).expect("a valid recording");
    assert_eq!(recorded.len(), 600, "only accepted messages are recorded");

    let mut replay: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
    let mut replay_digest = SnapshotDigest::default();
    for m in &recorded {
        let mut parts = m.topic.rsplit('/');
        let stream = parts.next().and_then(EdgeStream::from_chunk).expect("known stream");
        let source = parts.next().expect("source segment");
        replay
            .handle(source, stream, &m.topic, &m.data, m.log_time_ns as i64, |s| replay_digest.add(s))
            .expect("no I/O");
    }
    assert!(live_digest.count() > 70, "snapshots: {}", live_digest.count());
    assert_eq!(live_digest.count(), stats.snapshots);
    assert_eq!(live_digest, replay_digest, "replay yields the live snapshots");
}
