//! A cloud recording into rotating segments (`--record-dir`, a half-second age bound) while a
//! vehicle drives: it rotates several times; every segment is a finished MCAP file that our
//! strict reader and the official Python `mcap` reader open; the catalogue's counts equal the
//! cloud's summary; `recordings export` of a span across segments gives exactly the messages of
//! that span; and `edge replay` of that span republishes them into a second cloud.

use crate::peer_python;
use crate::support::{Proc, run_json, start_router};
use risktwin_protos::recording::{RecordedMessage, read_messages};
use serde_json::Value;
use std::collections::BTreeMap;
use std::process::Command;
use std::time::Duration;

const STEP: Duration = Duration::from_secs(60);
const SITE: &str = "rot";
const VEHICLE: &str = "veh-r";

/// Per file: messages the decoder yields and the statistics record's count.
const COUNT_MESSAGES: &str = r#"
import json, sys
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
out = []
for path in sys.argv[1:]:
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        decoded = sum(1 for _ in reader.iter_decoded_messages())
        out.append([decoded, reader.get_summary().statistics.message_count])
print(json.dumps(out))
"#;

fn utf8(path: &std::path::Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}

fn u64_of(v: &Value) -> u64 {
    v.as_u64().unwrap_or_else(|| panic!("not a count: {v}"))
}

#[test]
fn a_rotating_recording_is_catalogued_opens_in_python_and_exports_and_replays_a_span() {
    // The outside peer first: without it the test fails here, before any process is started.
    let python = peer_python::python(&["mcap==1.6.0", "mcap-protobuf-support==0.6.0"]);
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let segs = dir.path().join("segs");
    let client = ["--mode", "client", "--connect", locator.as_str()];
    let record = ["cloud", "--roles", "ingest", "--record-dir", utf8(&segs), "--segment-s", "0.5"];
    let mut cloud = Proc::spawn("cloud", &[&record[..], &client].concat());
    cloud.wait_line(STEP, |l| l == "ready");
    let vehicle = ["edge", "vehicle", "--id", VEHICLE, "--site", SITE, "--duration", "2.5"];
    let sent = Proc::spawn("vehicle", &[&vehicle[..], &client].concat()).exit_json(STEP);
    cloud.terminate();
    let summary = cloud.exit_json(STEP);
    let rotation = &summary["segments"];
    let closed = u64_of(&rotation["segments_closed"]);
    assert!(closed >= 4, "at least three rotations in 2.5 s at 0.5 s: {rotation}");
    assert_eq!(rotation["segments_opened"], rotation["segments_closed"], "{rotation}");
    assert_eq!(rotation["segments_deleted"], 0, "{rotation}");
    assert_eq!(summary["total_dropped"], 0, "{summary}");
    assert_eq!(summary["received"][VEHICLE]["state"], sent["sent"]["state"], "{summary}\n{sent}");

    // Every segment is finished and opens in our strict reader and in the official one.
    let list = run_json(&["recordings", "list", utf8(&segs), "--format", "json"]);
    let rows = list["segments"].as_array().expect("segments");
    assert_eq!(rows.len() as u64, closed, "{list}");
    assert_eq!(list["recordings"][0]["risktwin_version"], env!("CARGO_PKG_VERSION"), "{list}");
    let config: Value = serde_json::from_str(list["recordings"][0]["config"].as_str().expect("config")).expect("JSON");
    assert_eq!(config["segment_s"], 0.5, "{config}");
    let files: Vec<_> = rows.iter().map(|r| segs.join(r["file"].as_str().expect("file"))).collect();
    let mut all: Vec<RecordedMessage> = Vec::new();
    for (row, file) in rows.iter().zip(&files) {
        assert_eq!(row["status"], "finished", "{row}");
        let messages = read_messages(&std::fs::read(file).expect("a segment")).expect("a finished segment");
        assert_eq!(messages.len() as u64, u64_of(&row["messages"]), "{row}");
        all.extend(messages);
    }
    let out = Command::new(&python).arg("-c").arg(COUNT_MESSAGES).args(&files).output().expect("python runs");
    assert!(out.status.success(), "python mcap reader failed: {}", String::from_utf8_lossy(&out.stderr));
    let python_counts: Vec<[u64; 2]> = serde_json::from_slice(&out.stdout).expect("one JSON line from python");
    let catalogued: Vec<[u64; 2]> = rows.iter().map(|r| [u64_of(&r["messages"]); 2]).collect();
    assert_eq!(python_counts, catalogued, "decoded and statistics counts per segment");

    // The catalogue's counts per source and stream are the summary's.
    let query = run_json(&["recordings", "query", utf8(&segs), "--format", "json"]);
    let mut per_stream = BTreeMap::<String, BTreeMap<String, u64>>::new();
    for segment in query["segments"].as_array().expect("segments") {
        for s in segment["streams"].as_array().expect("streams") {
            let (source, stream) = (s["source"].as_str().expect("an edge"), s["stream"].as_str().expect("a stream"));
            *per_stream.entry(source.into()).or_default().entry(stream.into()).or_default() += u64_of(&s["messages"]);
        }
    }
    assert_eq!(serde_json::json!(per_stream), summary["received"], "catalogue against summary");
    assert_eq!(query["messages"], summary["recorded"], "{query}");
    assert_eq!(rotation["messages"], summary["recorded"], "{rotation}");

    // A span from inside the second segment to inside the second-to-last: exported, it is
    // exactly the messages of the span.
    let time = |i: usize, k: &str| u64_of(&rows[i][k]);
    let (from, to) = (time(1, "start_log_ns") + 1, time(rows.len() - 2, "end_log_ns"));
    let in_span: Vec<RecordedMessage> = all.iter().filter(|m| (from..to).contains(&m.log_time_ns)).cloned().collect();
    let span = ["--from", &from.to_string(), "--to", &to.to_string(), "--source", VEHICLE].map(str::to_owned);
    let span: Vec<&str> = span.iter().map(String::as_str).collect();
    let out = dir.path().join("span.mcap");
    let export = [&["recordings", "export", utf8(&segs), "--out", utf8(&out), "--format", "json"][..], &span];
    let exported = run_json(&export.concat());
    assert_eq!(u64_of(&exported["messages"]), in_span.len() as u64, "{exported}");
    assert!(u64_of(&exported["segments_read"]) >= 2, "a span across segments: {exported}");
    let back = read_messages(&std::fs::read(&out).expect("the export")).expect("a finished export");
    assert_eq!(back, in_span, "the export is the span's messages, in order");

    // The same span replayed across the segments into a second cloud.
    let mut replayed =
        Proc::spawn("replayed cloud", &[&["cloud", "--roles", "ingest", "--replay-time"][..], &client].concat());
    replayed.wait_line(STEP, |l| l == "ready");
    let replay = [&["edge", "replay", utf8(&segs), "--speed", "0", "--connect", &locator][..], &span].concat();
    let published = Proc::spawn("replay", &replay).exit_json(STEP);
    assert_eq!(u64_of(&published["published"]), in_span.len() as u64, "{published}");
    replayed.terminate();
    let received = replayed.exit_json(STEP);
    router.terminate();
    assert_eq!(received["total_received"], published["published"], "{received}");
    assert_eq!(received["total_dropped"], 0, "{received}");
}
