//! A cloud killed while it records (`kill -9`, no chance to write a footer): the recording keeps
//! every chunk it had closed. `edge replay` republishes them into a second cloud with a warning,
//! `recover` rewrites them as a finished file that our strict reader takes, and so does the
//! official Python `mcap` reader, which decodes every message with its recovered schema.

use crate::peer_python;
use crate::support::{Proc, start_router};
use risktwin_protos::recording::{CHUNK_WALL, RecordedMessage, RecordingError, read_messages, salvage_messages};
use risktwin_transport::wall_clock::unix_ns;
use std::collections::BTreeMap;
use std::process::Command;
use std::time::{Duration, Instant};

const STEP: Duration = Duration::from_secs(60);
const SITE: &str = "crash";
const VEHICLE: &str = "veh-k";
/// The cloud is killed once this many of the vehicle's states (50 Hz) are readable in its file:
/// 2 s of them, so at least two chunks closed on the 1 s clock (at ~30 kB/s the 1 MiB bound
/// alone would close none in this test).
const STATES_BEFORE_KILL: usize = 100;
/// ... and once the newest readable message is this old: the chunk the cloud has open then holds
/// about this much data, which the kill takes with it (killing right after a chunk closed would
/// leave nothing to lose).
const OPEN_CHUNK_AGE: Duration = Duration::from_millis(500);
/// How often the growing file is read while waiting for those states.
const POLL: Duration = Duration::from_millis(50);
/// What a loaded 2-core machine may add to the open chunk's 1 s (the cloud's ingest running
/// behind its receive stamps, the chunk's compression and write).
const LOSS_SLACK: Duration = Duration::from_secs(1);

const COUNT_MESSAGES: &str = r#"
import json, sys
from collections import Counter
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
topics = Counter()
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    summary = reader.get_summary()
    for schema, channel, message, proto in reader.iter_decoded_messages():
        topics[channel.topic] += 1
print(json.dumps({"topics": topics, "statistics_messages": summary.statistics.message_count}))
"#;

fn utf8(path: &std::path::Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}

/// The vehicle's state messages among `messages`.
fn states(messages: &[RecordedMessage]) -> Vec<&RecordedMessage> {
    let topic = format!("risktwin/v1/{SITE}/{VEHICLE}/state");
    messages.iter().filter(|m| m.topic == topic).collect()
}

/// Messages per topic, as JSON.
fn per_topic(messages: &[RecordedMessage]) -> serde_json::Value {
    let mut counts = BTreeMap::<&str, u64>::new();
    for m in messages {
        *counts.entry(&m.topic).or_default() += 1;
    }
    serde_json::json!(counts)
}

#[test]
fn a_cloud_killed_while_recording_leaves_a_file_that_replays_recovers_and_opens_in_python() {
    // The outside peer first: without it the test fails here, before any process is started.
    let python = peer_python::python(&["mcap==1.6.0", "mcap-protobuf-support==0.6.0"]);
    let (router, locator) = start_router();
    let dir = tempfile::tempdir().expect("a temporary directory");
    let killed = dir.path().join("killed.mcap");
    let client = ["--mode", "client", "--connect", locator.as_str()];
    let mut cloud =
        Proc::spawn("cloud", &[&["cloud", "--roles", "ingest", "--record", utf8(&killed)][..], &client].concat());
    cloud.wait_line(STEP, |l| l == "ready");
    let mut edge = Proc::spawn("edge", &[&["edge", "vehicle", "--id", VEHICLE, "--site", SITE][..], &client].concat());
    edge.wait_line(STEP, |l| l == format!("edge {VEHICLE}: publishing"));

    // Read the growing file until its closed chunks hold enough states and the open one half a
    // second's worth, then kill the cloud.
    let deadline = Instant::now() + STEP;
    let seen_before_kill = loop {
        // Before the first chunk is closed the file has no complete message: an error, not yet.
        let bytes = std::fs::read(&killed).unwrap_or_default();
        if let Ok((messages, _)) = salvage_messages(&bytes) {
            let newest_ns = messages.iter().map(|m| m.log_time_ns).max().unwrap_or(u64::MAX);
            let open_for = Duration::from_nanos((unix_ns() as u64).saturating_sub(newest_ns));
            if states(&messages).len() >= STATES_BEFORE_KILL && open_for >= OPEN_CHUNK_AGE {
                break messages;
            }
        }
        assert!(Instant::now() < deadline, "{STATES_BEFORE_KILL} states not readable in {STEP:?}");
        std::thread::sleep(POLL);
    };
    cloud.kill();
    let killed_at_ns = unix_ns() as u64;
    let (status, _) = cloud.wait_exit(STEP);
    assert_eq!(status.code(), None, "the cloud died of the signal, without a summary");
    edge.terminate();
    // What it sent after the kill was never acknowledged: its summary, then exit 1.
    let (status, stdout) = edge.wait_exit(STEP);
    assert_eq!(status.code(), Some(1), "{stdout}\n{}", edge.drain_stderr());
    let sent: serde_json::Value = serde_json::from_str(&stdout).expect("the edge's summary");
    assert!(sent["undelivered"]["state"].as_u64().is_some_and(|n| n > 0), "{sent}");

    // The file as the kill left it: no footer, every closed chunk readable.
    let bytes = std::fs::read(&killed).expect("the killed cloud's recording");
    assert!(
        matches!(read_messages(&bytes), Err(RecordingError::Unfinished(_))),
        "the strict reader refuses the killed file"
    );
    let (salvaged, unfinished) = salvage_messages(&bytes).expect("the killed file is readable");
    let unfinished = unfinished.expect("the killed file is unfinished");
    assert_eq!(&salvaged[..seen_before_kill.len()], &seen_before_kill[..], "what was readable stays readable");
    let salvaged_states = states(&salvaged);
    let sent_states = sent["sent"]["state"].as_u64().expect("states sent");
    assert!(salvaged_states.len() as u64 <= sent_states, "{} states kept of {sent_states} sent", salvaged_states.len());
    // At most the open chunk is lost: the last state kept arrived within its 1 s of the kill.
    let last_ns = salvaged_states.last().expect("states kept").log_time_ns;
    let lost_s = killed_at_ns.saturating_sub(last_ns) as f64 * 1e-9;
    eprintln!(
        "killed: {} messages ({} states of {sent_states} sent) readable, last state {lost_s:.3} s before the kill; {}",
        salvaged.len(),
        salvaged_states.len(),
        unfinished
    );
    assert!(
        lost_s <= (CHUNK_WALL + LOSS_SLACK).as_secs_f64(),
        "the last kept state came {lost_s:.3} s before the kill"
    );

    // (1) The killed file replayed into a second cloud: a warning, every readable message.
    let mut replayed_cloud =
        Proc::spawn("replayed cloud", &[&["cloud", "--roles", "ingest", "--replay-time"][..], &client].concat());
    replayed_cloud.wait_line(STEP, |l| l == "ready");
    let mut replay = Proc::spawn("replay", &["edge", "replay", utf8(&killed), "--speed", "0", "--connect", &locator]);
    let published = replay.exit_json(STEP);
    let warning = format!("warning: {}: unfinished recording, read {} messages", utf8(&killed), salvaged.len());
    replay.wait_line(STEP, |l| l.starts_with(&warning));
    assert_eq!(published["published"].as_u64(), Some(salvaged.len() as u64), "{published}");
    assert_eq!(published["skipped"], 0);
    assert_eq!(published["by_key"], per_topic(&salvaged), "{published}");
    replayed_cloud.terminate();
    let received = replayed_cloud.exit_json(STEP);
    router.terminate();
    assert_eq!(received["total_dropped"], 0, "{received}");
    let source = sent["source"].as_str().expect("source in the edge summary");
    let replayed_states = received["received"][source]["state"].as_u64().unwrap_or(0);
    assert_eq!(replayed_states, salvaged_states.len() as u64, "{received}");
    assert!(replayed_states >= STATES_BEFORE_KILL as u64, "at least 2 s of 50 Hz states replayed: {received}");

    // (2) Recovered into a finished file that the strict reader takes: the same messages.
    let recovered = dir.path().join("recovered.mcap");
    let mut recover =
        Proc::spawn("recover", &["recover", utf8(&killed), "--out", utf8(&recovered), "--format", "json"]);
    let report = recover.exit_json(STEP);
    assert_eq!(report["unfinished"], true, "{report}");
    assert_eq!(report["messages"].as_u64(), Some(salvaged.len() as u64), "{report}");
    assert_eq!(report["lost_at_byte"].as_u64(), Some(unfinished.tail.at_byte), "{report}");
    let finished = read_messages(&std::fs::read(&recovered).expect("the recovered file")).expect("a finished file");
    assert_eq!(finished, salvaged, "recover keeps every readable message as it was");

    // (3) The official Python reader opens it and decodes every message.
    let out = Command::new(python).arg("-c").arg(COUNT_MESSAGES).arg(&recovered).output().expect("python runs");
    assert!(out.status.success(), "python mcap reader failed: {}", String::from_utf8_lossy(&out.stderr));
    let python_counts: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON line from python");
    assert_eq!(python_counts["statistics_messages"].as_u64(), Some(salvaged.len() as u64), "{python_counts}");
    assert_eq!(python_counts["topics"], per_topic(&salvaged), "{python_counts}");
}
